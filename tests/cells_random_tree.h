// Random cell trees for the selection's tests (tests/cells_select_test.cpp, tests/worker_pair_test.cpp):
// parents before children, leaves with random voxel counts (some empty), a parent's voxels
// between a sixth of its children's sum and that sum (octree images are monotone).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/cells.h"

namespace ig::lod::testing_trees {

struct TreeSpec {
  int levels = 4;
  int minChildren = 1;
  int maxChildren = 4;
  double leafEarly = 0.1;  // chance that a cell above the last level has no children
  double empty = 0.1;      // chance that a leaf is empty
  glm::dvec3 rootMin_m{0.0};
  double rootEdge_m = 8.0;
  int voxelDepth = 2;
};

inline CellTree randomTree(std::mt19937& rng, const TreeSpec& s) {
  std::vector<CellDesc> cells = {{kNoCell, 0, 0, 0}};
  std::vector<int> level = {0};
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (size_t i = 0; i < cells.size(); ++i) {
    if (level[i] + 1 >= s.levels || (i > 0 && u(rng) < s.leafEarly)) continue;
    const int k = s.minChildren + static_cast<int>(rng() % static_cast<uint32_t>(s.maxChildren - s.minChildren + 1));
    uint32_t mask = 0;
    while (std::popcount(mask) < k) mask |= 1u << (rng() % 8);
    for (uint8_t o = 0; o < 8; ++o) {
      if (!(mask & (1u << o))) continue;
      cells.push_back({static_cast<uint32_t>(i), o, 0, 0});
      level.push_back(level[i] + 1);
    }
  }
  // Voxels bottom-up: leaves random (some empty), a parent between 1 and its children's sum.
  std::vector<uint64_t> childSum(cells.size(), 0);
  std::vector<bool> hasChild(cells.size(), false);
  for (size_t i = cells.size(); i-- > 0;) {
    if (!hasChild[i]) {
      cells[i].voxels = u(rng) < s.empty ? 0 : 1 + static_cast<uint32_t>(rng() % 60);
    } else if (childSum[i] == 0) {
      cells[i].voxels = 0;
    } else {
      const uint64_t lo = std::max<uint64_t>(1, childSum[i] / 6);
      cells[i].voxels = static_cast<uint32_t>(lo + rng() % (childSum[i] - lo + 1));
    }
    cells[i].bytes = 16 + 3 * cells[i].voxels + static_cast<uint32_t>(rng() % 40);
    if (i > 0) {
      childSum[cells[i].parent] += cells[i].voxels;
      hasChild[cells[i].parent] = true;
    }
  }
  CellTree t;
  std::string err;
  CellTreeInfo info;
  info.rootMin_m = s.rootMin_m;
  info.rootEdge_m = s.rootEdge_m;
  info.cellVoxelDepth = s.voxelDepth;
  EXPECT_TRUE(t.build(info, cells, err)) << err;
  return t;
}


}  // namespace ig::lod::testing_trees
