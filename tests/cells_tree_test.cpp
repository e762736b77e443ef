// lod/cells: the hierarchical-cell tree. Layout (levels, child ranges, coordinates, boxes, edges
// per level) and validation of every rule build() enforces, each error naming the cell and value.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "lod/cells.h"

using namespace ig::lod;

namespace {

// Root with octants 0 and 7; octant 0 has children 1 and 2, octant 7 has child 4.
std::vector<CellDesc> smallTree() {
  return {
      {kNoCell, 0, 10, 100},  // 0 root
      {0, 0, 6, 50},          // 1
      {0, 7, 5, 40},          // 2
      {1, 1, 4, 20},          // 3
      {1, 2, 3, 20},          // 4
      {2, 4, 9, 30},          // 5
  };
}

TEST(CellTree, LayoutLevelsChildrenCoordinatesAndBoxes) {
  CellTree t;
  std::string err;
  CellTreeInfo info;
  info.rootMin_m = {100.0, -50.0, 10.0};
  info.rootEdge_m = 64.0;
  info.cellVoxelDepth = 3;
  ASSERT_TRUE(t.build(info, smallTree(), err)) << err;
  EXPECT_EQ(t.size(), 6u);
  EXPECT_EQ(t.levels(), 3);
  EXPECT_EQ(t.levelBegin(0), 0u);
  EXPECT_EQ(t.levelBegin(1), 1u);
  EXPECT_EQ(t.levelBegin(2), 3u);
  EXPECT_EQ(t.levelBegin(3), 6u);
  EXPECT_EQ(t.firstChild(0), 1u);
  EXPECT_EQ(t.childCount(0), 2u);
  EXPECT_EQ(t.firstChild(1), 3u);
  EXPECT_EQ(t.childCount(1), 2u);
  EXPECT_EQ(t.firstChild(2), 5u);
  EXPECT_EQ(t.childCount(2), 1u);
  EXPECT_EQ(t.childCount(3), 0u);
  EXPECT_EQ(t.parent(5), 2u);
  EXPECT_EQ(t.level(5), 2);
  EXPECT_EQ(t.coord(2), glm::uvec3(1, 1, 1));
  EXPECT_EQ(t.coord(3), glm::uvec3(1, 0, 0));
  EXPECT_EQ(t.coord(4), glm::uvec3(0, 1, 0));
  EXPECT_EQ(t.coord(5), glm::uvec3(2, 2, 3));
  EXPECT_DOUBLE_EQ(t.cellEdge_m(2), 16.0);
  EXPECT_DOUBLE_EQ(t.voxelEdge_m(2), 2.0);  // 64 / 2^(2 + 3)
  const Aabb b = t.box(5);
  EXPECT_EQ(b.min, glm::dvec3(132.0, -18.0, 58.0));
  EXPECT_EQ(b.max, glm::dvec3(148.0, -2.0, 74.0));
  EXPECT_EQ(t.totalVoxels(1), 11u);
  EXPECT_EQ(t.totalVoxels(2), 16u);
  EXPECT_EQ(t.totalBytes(), 260u);
  EXPECT_FALSE(t.isEmpty(0));
}

TEST(CellTree, EmptyCellsAreFlagged) {
  std::vector<CellDesc> cells = {{kNoCell, 0, 2, 10}, {0, 0, 0, 16}, {0, 3, 2, 10}, {1, 0, 0, 16}};
  CellTree t;
  std::string err;
  ASSERT_TRUE(t.build({}, cells, err)) << err;
  EXPECT_TRUE(t.isEmpty(1));
  EXPECT_TRUE(t.isEmpty(3));
  EXPECT_FALSE(t.isEmpty(2));
  EXPECT_EQ(t.flags(1) & kCellEmpty, kCellEmpty);
}

void expectRejected(const CellTreeInfo& info, const std::vector<CellDesc>& cells, const std::string& needle) {
  CellTree t;
  std::string err;
  EXPECT_FALSE(t.build(info, cells, err));
  EXPECT_NE(err.find(needle), std::string::npos) << "error: " << err << " (expected to contain: " << needle << ")";
  EXPECT_TRUE(t.empty());
}

TEST(CellTree, RejectsBadInputNamingTheCellAndValue) {
  CellTreeInfo ok;
  expectRejected(ok, {}, "no cells");
  {
    auto c = smallTree();
    c[0].parent = 3;
    expectRejected(ok, c, "cell 0");
  }
  {
    auto c = smallTree();
    c[3].parent = 7;
    expectRejected(ok, c, "cell 3: parent = 7");
  }
  {
    auto c = smallTree();
    c[2].octant = 9;
    expectRejected(ok, c, "cell 2: octant = 9");
  }
  {
    auto c = smallTree();
    c[2].octant = 0;  // same octant twice
    expectRejected(ok, c, "cell 2: octant 0 after octant 0");
  }
  {
    // Children of cell 2 before those of cell 1: not breadth-first.
    std::vector<CellDesc> c = {{kNoCell, 0, 10, 1}, {0, 0, 5, 1}, {0, 1, 5, 1}, {2, 0, 5, 1}, {1, 0, 5, 1}};
    expectRejected(ok, c, "cell 4: parent 1 after a child of cell 2");
  }
  {
    auto c = smallTree();
    c[0].voxels = 20;  // children hold 11
    expectRejected(ok, c, "cell 0: V = 20 but its children hold 11");
  }
  {
    std::vector<CellDesc> c = {{kNoCell, 0, 0, 1}, {0, 0, 5, 1}};
    expectRejected(ok, c, "cell 1: V = 5 inside an empty parent 0");
  }
  {
    CellTreeInfo bad;
    bad.rootEdge_m = 0.0;
    expectRejected(bad, smallTree(), "rootEdge_m = 0");
    bad.rootEdge_m = std::numeric_limits<double>::quiet_NaN();
    expectRejected(bad, smallTree(), "rootEdge_m = nan");
  }
  {
    CellTreeInfo bad;
    bad.rootMin_m.y = std::numeric_limits<double>::infinity();
    expectRejected(bad, smallTree(), "rootMin_m is not finite");
  }
  {
    CellTreeInfo bad;
    bad.cellVoxelDepth = 21;
    expectRejected(bad, smallTree(), "cellVoxelDepth = 21");
  }
  {
    // A chain deeper than kMaxCellLevels.
    std::vector<CellDesc> c = {{kNoCell, 0, 1, 1}};
    for (uint32_t i = 1; i <= kMaxCellLevels; ++i) c.push_back({i - 1, 0, 1, 1});
    expectRejected(ok, c, "at most 16 levels");
  }
}

TEST(CellTree, HugeCoordinatesKeepExactBoxes) {
  CellTree t;
  std::string err;
  CellTreeInfo info;
  info.rootMin_m = {1.0e7, -2.0e7, 5.0e6};
  info.rootEdge_m = 1024.0;
  ASSERT_TRUE(t.build(info, smallTree(), err)) << err;
  const Aabb b = t.box(5);
  EXPECT_EQ(b.min - info.rootMin_m, glm::dvec3(512.0, 512.0, 768.0));
  EXPECT_EQ(b.max - b.min, glm::dvec3(256.0));
}

}  // namespace
