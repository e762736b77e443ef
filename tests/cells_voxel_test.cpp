// lod/cells_voxel: triangles -> voxel octree pyramid -> hierarchical cells. Box-counting
// dimension (~2 for a sphere and planes, ~3 for a filled cube, as the paper's Table 1), no holes
// (points sampled on every triangle lie in occupied voxels) and no stray voxels (every voxel
// touches the surface), colours, the cell tree's V and S against the pyramid, huge coordinates,
// degenerate and empty input, and bad input naming the value.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "lod/cells_voxel.h"

using namespace ig::lod;

namespace {

VoxelPyramid mustVoxelize(const VoxelMesh& mesh, const VoxelizeConfig& cfg) {
  VoxelPyramid p;
  std::string err;
  EXPECT_TRUE(voxelize(mesh, cfg, p, err)) << err;
  return p;
}

VoxelizeConfig unitBox(int levels, bool solid = false) {
  VoxelizeConfig c;
  c.levels = levels;
  c.boxMin_m = glm::dvec3(0.0);
  c.boxEdge_m = 1.0;
  c.solid = solid;
  return c;
}

bool occupied(const VoxelPyramid& p, int level, const glm::dvec3& point_m) {
  const double res = std::ldexp(1.0, level);
  const glm::dvec3 v = (point_m - p.boxMin_m) / p.boxEdge_m * res;
  const auto code = mortonEncode(static_cast<uint32_t>(v.x), static_cast<uint32_t>(v.y), static_cast<uint32_t>(v.z));
  const auto& codes = p.codes[static_cast<size_t>(level)];
  return std::binary_search(codes.begin(), codes.end(), code);
}

TEST(CellsVoxel, MortonRoundTripAndOctantBits) {
  std::mt19937 rng(3);
  for (int i = 0; i < 1000; ++i) {
    const glm::uvec3 v(rng() & 0x1FFFFF, rng() & 0x1FFFFF, rng() & 0x1FFFFF);
    EXPECT_EQ(mortonDecode(mortonEncode(v.x, v.y, v.z)), v);
  }
  EXPECT_EQ(mortonEncode(1, 0, 0), 1u);
  EXPECT_EQ(mortonEncode(0, 1, 0), 2u);
  EXPECT_EQ(mortonEncode(0, 0, 1), 4u);
  EXPECT_EQ(mortonEncode(2, 3, 1) >> 3, mortonEncode(1, 1, 0));  // parent = code >> 3
}

TEST(CellsVoxel, SphereDimensionIsAboutTwo) {
  VoxelMesh m;
  appendSphere(m, glm::dvec3(0.5), 0.4, 128, 0xFF0000FFu);
  const VoxelPyramid p = mustVoxelize(m, unitBox(8));
  ASSERT_EQ(p.levels(), 8);
  for (int l = 4; l < 8; ++l) {
    EXPECT_NEAR(p.dimension(l), 2.0, 0.08) << "level " << l << ": " << p.count(l) << " -> " << p.count(l + 1);
  }
  // Area 4 pi r^2 covered by voxels of edge 1/256: roughly 1.5 - 3 voxels per voxel area.
  const double area = 4.0 * 3.14159265358979 * 0.4 * 0.4 * 256.0 * 256.0;
  EXPECT_GT(static_cast<double>(p.count(8)), 1.2 * area);
  EXPECT_LT(static_cast<double>(p.count(8)), 3.5 * area);
  for (const uint32_t c : p.colors[8]) EXPECT_EQ(c, 0xFF0000FFu);
  for (const uint32_t c : p.colors[3]) EXPECT_EQ(c, 0xFF0000FFu);
}

// The paper's Table 1 (the bunny's BVO): level, voxel count, "approximate Hausdorff dimension".
// Its column is log M(eps) / log(1 / eps) = log2(N(l)) / l; D(l) = log2(N(l + 1) / N(l)) on the same
// counts gives 2.014, 2.049, 2.036, not the table's values.
TEST(CellsVoxel, BoxCountingDimensionReproducesTableOne) {
  VoxelPyramid p;
  p.codes.assign(11, {});
  const size_t counts[4] = {15100, 61010, 252388, 1034937};
  const double table[4] = {1.983, 1.987, 1.993, 1.998};
  for (int i = 0; i < 4; ++i) p.codes[static_cast<size_t>(7 + i)].resize(counts[i]);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(p.boxCountingDimension(7 + i), table[i], 0.0011) << "level " << 7 + i;
  EXPECT_NEAR(p.dimension(7), 2.014, 0.001);
  EXPECT_EQ(p.boxCountingDimension(0), 0.0);
  EXPECT_EQ(p.boxCountingDimension(3), 0.0);  // N = 0
  // A sphere smaller than the cube: H tends to 2 from below.
  VoxelMesh m;
  appendSphere(m, glm::dvec3(0.5), 0.2, 128, 0xFFFFFFFFu);
  const VoxelPyramid s = mustVoxelize(m, unitBox(9));
  for (int l = 6; l <= 9; ++l) {
    EXPECT_LT(s.boxCountingDimension(l), 2.0) << "level " << l;
    EXPECT_GT(s.boxCountingDimension(l), 1.7) << "level " << l;
  }
  EXPECT_GT(s.boxCountingDimension(9), s.boxCountingDimension(6));
}

TEST(CellsVoxel, PlanesDimensionIsTwo) {
  {
    VoxelMesh m;  // axis-aligned, off the voxel faces
    appendQuad(m, {0.05, 0.05, 0.5013}, {0.95, 0.05, 0.5013}, {0.95, 0.95, 0.5013}, {0.05, 0.95, 0.5013}, 0xFFFFFFFFu);
    const VoxelPyramid p = mustVoxelize(m, unitBox(9));
    for (int l = 6; l < 9; ++l) EXPECT_NEAR(p.dimension(l), 2.0, 0.05) << "level " << l;
    // One layer of voxels: exactly the columns the square covers.
    EXPECT_EQ(p.count(9), static_cast<size_t>(486 - 25 + 1) * (486 - 25 + 1));
  }
  {
    VoxelMesh m;  // tilted in two directions
    appendQuad(m, {0.05, 0.1, 0.2}, {0.9, 0.05, 0.35}, {0.95, 0.9, 0.8}, {0.1, 0.95, 0.65}, 0xFFFFFFFFu);
    const VoxelPyramid p = mustVoxelize(m, unitBox(9));
    for (int l = 6; l < 9; ++l) EXPECT_NEAR(p.dimension(l), 2.0, 0.08) << "level " << l;
  }
}

TEST(CellsVoxel, FilledCubeDimensionIsThreeHollowCubeTwo) {
  VoxelMesh m;
  appendBox(m, glm::dvec3(0.1), glm::dvec3(0.9), 0xFF00FF00u);
  const VoxelPyramid solid = mustVoxelize(m, unitBox(7, true));
  // Coarse levels see the cube's finite size (as the paper's table starts at level 7).
  for (int l = 5; l < 7; ++l) EXPECT_NEAR(solid.dimension(l), 3.0, 0.1) << "level " << l;
  // Every voxel whose centre is inside the cube is filled.
  for (int x = 0; x < 128; x += 7)
    for (int y = 0; y < 128; y += 5)
      for (int z = 0; z < 128; z += 3) {
        const glm::dvec3 c = (glm::dvec3(x, y, z) + 0.5) / 128.0;
        const bool inside = glm::all(glm::greaterThan(c, glm::dvec3(0.1))) && glm::all(glm::lessThan(c, glm::dvec3(0.9)));
        if (inside) {
          EXPECT_TRUE(occupied(solid, 7, c)) << x << " " << y << " " << z;
        }
      }
  const VoxelPyramid hollow = mustVoxelize(m, unitBox(7, false));
  for (int l = 5; l < 7; ++l) EXPECT_NEAR(hollow.dimension(l), 2.0, 0.1) << "level " << l;
  EXPECT_FALSE(occupied(hollow, 7, glm::dvec3(0.5)));
  EXPECT_TRUE(occupied(solid, 7, glm::dvec3(0.5)));
}

// Exact distance from p to triangle abc (closest point, Ericson's Real-Time Collision Detection 5.1.5).
double pointTriangleDistance(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return glm::length(p - a);
  const glm::dvec3 bp = p - b;
  const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return glm::length(p - b);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return glm::length(p - (a + d1 / (d1 - d3) * ab));
  const glm::dvec3 cp = p - c;
  const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return glm::length(p - c);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return glm::length(p - (a + d2 / (d2 - d6) * ac));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return glm::length(p - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b)));
  const double denom = 1.0 / (va + vb + vc);
  return glm::length(p - (a + ab * (vb * denom) + ac * (vc * denom)));
}

TEST(CellsVoxel, NoHolesAndNoStrayVoxels) {
  VoxelMesh m;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0.05, 0.95);
  for (int t = 0; t < 12; ++t) {
    const auto base = static_cast<uint32_t>(m.positions_m.size());
    for (int k = 0; k < 3; ++k) m.positions_m.push_back({u(rng), u(rng), u(rng)});
    m.indices.insert(m.indices.end(), {base, base + 1, base + 2});
  }
  const int L = 6;
  const VoxelPyramid p = mustVoxelize(m, unitBox(L));
  // No holes: points on every triangle are in occupied voxels.
  std::uniform_real_distribution<double> w(0.0, 1.0);
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    for (int s = 0; s < 400; ++s) {
      double a = w(rng), b = w(rng);
      if (a + b > 1.0) a = 1.0 - a, b = 1.0 - b;
      const glm::dvec3 q = m.positions_m[m.indices[t]] + a * (m.positions_m[m.indices[t + 1]] - m.positions_m[m.indices[t]]) +
                           b * (m.positions_m[m.indices[t + 2]] - m.positions_m[m.indices[t]]);
      EXPECT_TRUE(occupied(p, L, q));
    }
  }
  // No stray voxels: each voxel's centre is within half a voxel diagonal of some triangle.
  const double voxel = 1.0 / 64.0, reach = 0.5 * std::sqrt(3.0) * voxel * (1.0 + 1e-9);
  for (uint64_t code : p.codes[L]) {
    const glm::dvec3 ctr = (glm::dvec3(mortonDecode(code)) + 0.5) * voxel;
    double best = 1e30;
    for (size_t t = 0; t < m.indices.size(); t += 3)
      best = std::min(best, pointTriangleDistance(ctr, m.positions_m[m.indices[t]], m.positions_m[m.indices[t + 1]],
                                                  m.positions_m[m.indices[t + 2]]));
    EXPECT_LE(best, reach);
  }
  // Coarser levels are the parents of the finer.
  for (int l = 0; l < L; ++l)
    for (uint64_t code : p.codes[static_cast<size_t>(l) + 1]) {
      const auto& cc = p.codes[static_cast<size_t>(l)];
      EXPECT_TRUE(std::binary_search(cc.begin(), cc.end(), code >> 3));
    }
}

TEST(CellsVoxel, ColoursAveragePerVoxelAndLevel) {
  VoxelMesh m;  // red left half, blue right half of one plane
  appendQuad(m, {0.0, 0.0, 0.3}, {0.5, 0.0, 0.3}, {0.5, 1.0, 0.3}, {0.0, 1.0, 0.3}, 0xFF0000FFu);
  appendQuad(m, {0.5, 0.0, 0.3}, {1.0, 0.0, 0.3}, {1.0, 1.0, 0.3}, {0.5, 1.0, 0.3}, 0xFFFF0000u);
  const VoxelPyramid p = mustVoxelize(m, unitBox(4));
  const auto& codes = p.codes[4];
  for (size_t i = 0; i < codes.size(); ++i) {
    const glm::uvec3 v = mortonDecode(codes[i]);
    // Voxels are half-open along the bounding axes: the shared edge x = 0.5 falls in voxel 8.
    if (v.x <= 7) {
      EXPECT_EQ(p.colors[4][i], 0xFF0000FFu);
    } else if (v.x > 8) {
      EXPECT_EQ(p.colors[4][i], 0xFFFF0000u);
    } else {
      const uint32_t c = p.colors[4][i];
      EXPECT_GT(c & 0xFF, 0u);
      EXPECT_GT((c >> 16) & 0xFF, 0u);
    }
  }
  // Level 0: one voxel, the mean of both halves.
  ASSERT_EQ(p.count(0), 1u);
  const uint32_t c0 = p.colors[0][0];
  EXPECT_NEAR(static_cast<double>(c0 & 0xFF), 127.5, 16.0);
  EXPECT_NEAR(static_cast<double>((c0 >> 16) & 0xFF), 127.5, 16.0);
}

// A uniformly coloured mesh keeps its colour at every level (the voxelizer carried colours as
// RGB565: clay (200, 180, 160) came out (206, 182, 165), grey (7, 7, 7) as (0, 4, 0), green-
// tinted). Up to 13 levels the packed voxel has room for 24 bits; beyond, RGB565 (within 8).
TEST(CellsVoxel, UniformColoursAreKeptExactly) {
  for (const int L : {4, 13, 16}) {
    for (const uint32_t col : {0xFFA0B4C8u, 0xFF808080u, 0xFF070707u, 0xFF0000FFu}) {
      VoxelMesh m;
      const double e = 3.0 / (1 << L);  // a few voxels across at any level
      appendQuad(m, {0.3, 0.3, 0.5}, {0.3 + e, 0.3, 0.5}, {0.3 + e, 0.3 + e, 0.5}, {0.3, 0.3 + e, 0.5}, col);
      const VoxelPyramid p = mustVoxelize(m, unitBox(L));
      for (int l = 0; l <= L; ++l) {
        for (const uint32_t c : p.colors[static_cast<size_t>(l)]) {
          if (L <= 13) {
            ASSERT_EQ(c, col) << "levels " << L << " level " << l;
          } else {
            for (int ch = 0; ch < 3; ++ch)
              ASSERT_NEAR(static_cast<int>((c >> (8 * ch)) & 0xFF), static_cast<int>((col >> (8 * ch)) & 0xFF), 8)
                  << "levels " << L << " level " << l;
          }
        }
      }
    }
  }
}

TEST(CellsVoxel, CellTreeVoxelsAndBytesMatchThePyramid) {
  VoxelMesh m;
  appendSphere(m, glm::dvec3(0.3, 0.4, 0.5), 0.25, 48, 0xFFFFFFFFu);
  appendSphere(m, glm::dvec3(0.7, 0.6, 0.4), 0.2, 48, 0xFF808080u);
  const VoxelPyramid p = mustVoxelize(m, unitBox(7));
  CellTree t;
  std::string err;
  CellBuildConfig cfg;
  cfg.cellLevels = 5;
  cfg.cellVoxelDepth = 2;
  ASSERT_TRUE(buildCellTree(p, cfg, t, err)) << err;
  EXPECT_EQ(t.levels(), 5);
  size_t cells = 0;
  for (int q = 0; q < 5; ++q) {
    cells += p.count(q);
    EXPECT_EQ(t.levelBegin(q + 1) - t.levelBegin(q), p.count(q));
    EXPECT_EQ(t.totalVoxels(q), p.count(q + 2)) << "level " << q;  // V counts voxels of level q + d
  }
  EXPECT_EQ(t.size(), cells);
  EXPECT_DOUBLE_EQ(t.voxelEdge_m(4), p.boxEdge_m / 64.0);
  // S = 16 + masks (nodes of levels q, q + 1 inside) + 3 V; summed over a level.
  for (int q = 0; q < 5; ++q) {
    uint64_t bytes = 0;
    for (uint32_t c = t.levelBegin(q); c < t.levelBegin(q + 1); ++c) bytes += t.bytes(c);
    EXPECT_EQ(bytes, 16 * p.count(q) + p.count(q) + p.count(q + 1) + 3 * p.count(q + 2)) << "level " << q;
  }
  // Each cell's box holds its voxels: the cell's code equals its coordinates.
  for (uint32_t c = t.levelBegin(3); c < t.levelBegin(4); ++c) {
    const glm::uvec3 v = t.coord(c);
    EXPECT_EQ(p.codes[3][c - t.levelBegin(3)], mortonEncode(v.x, v.y, v.z));
  }
  // Every cell holds voxels; the depth limit is enforced.
  for (uint32_t c = 0; c < t.size(); ++c) EXPECT_FALSE(t.isEmpty(c));
  cfg.cellLevels = 7;
  EXPECT_FALSE(buildCellTree(p, cfg, t, err));
  EXPECT_NE(err.find("cellLevels - 1 + cellVoxelDepth = 8"), std::string::npos) << err;
}

TEST(CellsVoxel, HugeCoordinatesGiveTheSameVoxels) {
  VoxelMesh a, b;
  appendSphere(a, glm::dvec3(0.0), 30.0, 64, 0xFFFFFFFFu);
  const glm::dvec3 off(6.4e6, -3.2e6, 1.0e7);
  appendSphere(b, off, 30.0, 64, 0xFFFFFFFFu);
  VoxelizeConfig ca, cb;
  ca.levels = cb.levels = 7;
  ca.boxMin_m = glm::dvec3(-32.0);
  cb.boxMin_m = off - glm::dvec3(32.0);
  ca.boxEdge_m = cb.boxEdge_m = 64.0;
  const VoxelPyramid pa = mustVoxelize(a, ca), pb = mustVoxelize(b, cb);
  ASSERT_EQ(pa.count(7), pb.count(7));
  EXPECT_EQ(pa.codes[7], pb.codes[7]);
  // Fitted box too.
  VoxelizeConfig fit;
  fit.levels = 6;
  const VoxelPyramid pf = mustVoxelize(b, fit);
  EXPECT_GT(pf.count(6), 1000u);
  EXPECT_NEAR(pf.dimension(5), 2.0, 0.15);
}

// A mesh lying on the explicit box's max face (boxMin + edge, which voxelize() accepts as inside)
// is voxelized like the same mesh on the min face. With a box whose min and edge are not dyadic,
// (boxMin + edge - boxMin) * 2^L / edge rounds to 2^L + 6e-14: unclamped, the exact overlap test
// rejected the face for every voxel and the whole quad vanished (0 voxels, an empty pyramid).
TEST(CellsVoxel, MeshOnTheBoxMaxFaceIsVoxelized) {
  const double bmin = 802.8549152229671, edge = 3.1559393050519984, top = bmin + edge;
  const int L = 8;
  for (int axis = 0; axis < 3; ++axis) {
    VoxelPyramid lo, hi;
    for (const bool atTop : {false, true}) {
      VoxelMesh m;
      const auto P = [&](double s, double t) {
        glm::dvec3 q;
        q[axis] = atTop ? top : bmin;
        q[(axis + 1) % 3] = bmin + s * edge;
        q[(axis + 2) % 3] = bmin + t * edge;
        return q;
      };
      appendQuad(m, P(0.1, 0.1), P(0.9, 0.1), P(0.9, 0.9), P(0.1, 0.9), 0xFFFFFFFFu);
      VoxelizeConfig c;
      c.levels = L;
      c.boxMin_m = glm::dvec3(bmin);
      c.boxEdge_m = edge;
      (atTop ? hi : lo) = mustVoxelize(m, c);
    }
    ASSERT_GT(lo.count(L), 200u * 200u) << "axis " << axis;
    EXPECT_EQ(hi.count(L), lo.count(L)) << "axis " << axis;
    for (uint64_t code : hi.codes[L]) {
      ASSERT_EQ(mortonDecode(code)[axis], (1u << L) - 1) << "axis " << axis;
    }
    EXPECT_EQ(hi.count(0), 1u) << "axis " << axis;
  }
}

TEST(CellsVoxel, DegenerateAndEmptyInput) {
  VoxelMesh m;  // zero-area triangle (a segment) and a point triangle
  m.positions_m = {{0.1, 0.1, 0.1}, {0.9, 0.9, 0.9}, {0.5, 0.5, 0.5}, {0.3, 0.7, 0.2}};
  m.indices = {0, 1, 2, 3, 3, 3};
  const VoxelPyramid p = mustVoxelize(m, unitBox(5, true));
  EXPECT_GE(p.count(5), 32u);  // the diagonal crosses at least 32 voxels
  EXPECT_TRUE(occupied(p, 5, glm::dvec3(0.3, 0.7, 0.2)));
  EXPECT_NEAR(p.dimension(4), 1.0, 0.2);  // a curve

  VoxelMesh empty;
  const VoxelPyramid e = mustVoxelize(empty, unitBox(4));
  EXPECT_EQ(e.count(0), 0u);
  EXPECT_EQ(e.count(4), 0u);
  EXPECT_EQ(e.dimension(2), 0.0);
  CellTree t;
  std::string err;
  CellBuildConfig small;
  small.cellLevels = 3;
  EXPECT_FALSE(buildCellTree(e, small, t, err));
  EXPECT_NE(err.find("empty"), std::string::npos) << err;
}

// An explicit box edge that is NaN is neither "<= 0: fit a box" nor a valid edge: refused as
// not finite (like an infinite one), never silently replaced by a fitted box.
TEST(CellsVoxel, NanBoxEdgeIsRefused) {
  VoxelPyramid p;
  std::string err;
  VoxelMesh m;
  appendQuad(m, {0.1, 0.1, 0.5}, {0.9, 0.1, 0.5}, {0.9, 0.9, 0.5}, {0.1, 0.9, 0.5}, 0xFFFFFFFFu);
  VoxelizeConfig c = unitBox(4);
  c.boxEdge_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(voxelize(m, c, p, err));
  EXPECT_NE(err.find("the box is not finite"), std::string::npos) << err;
  c.boxEdge_m = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(voxelize(m, c, p, err));
  EXPECT_NE(err.find("the box is not finite"), std::string::npos) << err;
}

TEST(CellsVoxel, RejectsBadInputNamingTheValue) {
  VoxelPyramid p;
  std::string err;
  VoxelMesh m;
  appendQuad(m, {0.1, 0.1, 0.5}, {0.9, 0.1, 0.5}, {0.9, 0.9, 0.5}, {0.1, 0.9, 0.5}, 0xFFFFFFFFu);
  VoxelizeConfig c = unitBox(0);
  EXPECT_FALSE(voxelize(m, c, p, err));
  EXPECT_NE(err.find("levels = 0"), std::string::npos) << err;
  c = unitBox(17);
  EXPECT_FALSE(voxelize(m, c, p, err));
  EXPECT_NE(err.find("levels = 17"), std::string::npos) << err;
  {
    VoxelMesh bad = m;
    bad.positions_m[2].y = std::numeric_limits<double>::quiet_NaN();
    EXPECT_FALSE(voxelize(bad, unitBox(4), p, err));
    EXPECT_NE(err.find("vertex 2"), std::string::npos) << err;
  }
  {
    VoxelMesh bad = m;
    bad.indices[4] = 99;
    EXPECT_FALSE(voxelize(bad, unitBox(4), p, err));
    EXPECT_NE(err.find("index 4 = 99"), std::string::npos) << err;
  }
  {
    VoxelMesh bad = m;
    bad.indices.pop_back();
    EXPECT_FALSE(voxelize(bad, unitBox(4), p, err));
    EXPECT_NE(err.find("not a multiple of 3"), std::string::npos) << err;
  }
  {
    VoxelMesh bad = m;
    bad.colors.pop_back();
    EXPECT_FALSE(voxelize(bad, unitBox(4), p, err));
    EXPECT_NE(err.find("3 colours for 4 vertices"), std::string::npos) << err;
  }
  {
    VoxelizeConfig small = unitBox(4);
    small.boxEdge_m = 0.5;
    EXPECT_FALSE(voxelize(m, small, p, err));
    EXPECT_NE(err.find("outside the box"), std::string::npos) << err;
  }
  {
    const VoxelPyramid ok = mustVoxelize(m, unitBox(4));
    CellTree t;
    CellBuildConfig cfg;
    cfg.cellLevels = 0;
    EXPECT_FALSE(buildCellTree(ok, cfg, t, err));
    EXPECT_NE(err.find("cellLevels = 0"), std::string::npos) << err;
    cfg.cellLevels = 2;
    cfg.cellVoxelDepth = 9;
    EXPECT_FALSE(buildCellTree(ok, cfg, t, err));
    EXPECT_NE(err.find("cellVoxelDepth = 9"), std::string::npos) << err;
  }
}

}  // namespace
