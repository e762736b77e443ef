// Block LOD (regular decimation with crack-fixing fans), the baseline for ROAM: the emitted
// mesh tiles the DEM exactly (no holes, no overlaps, no T-junctions) for any mix of levels,
// levels follow the error rule, and hard cases (flat, cliffs, tiny and odd DEMs, camera on
// or under the surface, NaN) behave.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <vector>

#include "lod/block_lod.h"
#include "lod/heightfield.h"
#include "terrain_fixtures.h"

using namespace ig::lod;
using ig::lod::test::tilesDem;

using ig::lod::test::BlockDem;
using ig::lod::test::blockFractal;
using ig::lod::test::blockTriangles;
using ig::lod::test::blockViewAt;

TEST(BlockLod, MixedLevelsTileTheDemWithoutCracks) {
  const BlockDem d = blockFractal(257, 257);
  BlockLod b(d.z, d.w, d.h, 30.0, {0, 0, 0}, {32});
  // Looking straight down from high enough to see every block; flat valley floors and rough
  // mountains give each block a different level.
  for (auto v : {blockViewAt({3840, 3840, 60000}, 0, -90, 1.0), blockViewAt({3840, 3840, 12000}, 0, -90, 0.25),
                 blockViewAt({3840, 3840, 12000}, 0, -90, 2.0)}) {
    const BlockLodStats st = b.update(v);
    EXPECT_EQ(st.blocksVisible, 64u);
    const auto tris = blockTriangles(b);
    EXPECT_EQ(tris.size(), st.triangles);
    EXPECT_TRUE(tilesDem(tris, d.w, d.h));
  }
  int lo = 99, hi = -1;
  for (int y = 0; y < b.blocksY(); ++y)
    for (int x = 0; x < b.blocksX(); ++x) {
      lo = std::min(lo, b.level(x, y));
      hi = std::max(hi, b.level(x, y));
    }
  EXPECT_LT(lo, hi) << "the low view must mix levels for the crack test to mean something";
}

TEST(BlockLod, LevelIsTheCoarsestWithinTolerance) {
  const BlockDem d = blockFractal(129, 129);
  BlockLod b(d.z, d.w, d.h, 30.0, {0, 0, 0}, {16});
  const RoamView v = blockViewAt({-2000, 1900, 1500}, 90, -20, 2.0);
  const BlockLodStats st = b.update(v);
  for (int by = 0; by < b.blocksY(); ++by)
    for (int bx = 0; bx < b.blocksX(); ++bx) {
      const int k = b.level(bx, by);
      if (k < 0) continue;
      // Error non-decreasing with k, and the chosen level is within tolerance unless finest.
      for (int j = 1; j < b.levels(); ++j) ASSERT_GE(b.levelError_m(bx, by, j), b.levelError_m(bx, by, j - 1));
      EXPECT_EQ(b.levelError_m(bx, by, 0), 0.0);
    }
  EXPECT_LE(st.maxErrorPx, 2.0);
  EXPECT_GT(st.blocksVisible, 0u);
}

TEST(BlockLod, FlatTerrainUsesTheCoarsestLevelEverywhere) {
  BlockDem d{65, 65, std::vector<float>(65 * 65, 120.0f)};
  BlockLod b(d.z, d.w, d.h, 10.0, {0, 0, 0}, {16});
  const BlockLodStats st = b.update(blockViewAt({320, 320, 20000}, 0, -90, 0.5));
  EXPECT_EQ(st.blocksVisible, 16u);
  for (int by = 0; by < b.blocksY(); ++by)
    for (int bx = 0; bx < b.blocksX(); ++bx)
      if (b.level(bx, by) >= 0) {
        EXPECT_EQ(b.level(bx, by), b.levels() - 1);
      }
  EXPECT_EQ(st.triangles, 2u * st.blocksVisible);
  EXPECT_TRUE(tilesDem(blockTriangles(b), d.w, d.h));
}

TEST(BlockLod, CliffBlocksStayFineAndTheRestIsCoarse) {
  BlockDem d{129, 129, std::vector<float>(129 * 129, 0.0f)};
  for (int y = 0; y < 129; ++y)
    for (int x = 70; x < 129; ++x) d.z[static_cast<size_t>(y) * 129 + x] = 500.0f;  // vertical step at x = 69..70
  BlockLod b(d.z, d.w, d.h, 10.0, {0, 0, 0}, {16});
  b.update(blockViewAt({640, 640, 20000}, 0, -90, 1.0));
  EXPECT_EQ(b.level(4, 3), 0);                  // the block holding the step (x 64..80)
  EXPECT_EQ(b.level(0, 0), b.levels() - 1);     // flat
  EXPECT_EQ(b.level(7, 7), b.levels() - 1);     // flat plateau
  EXPECT_TRUE(tilesDem(blockTriangles(b), d.w, d.h));
}

TEST(BlockLod, SmallAndOddDemsAndHardCameras) {
  for (auto [w, h] : {std::pair{2, 2}, std::pair{3, 3}, std::pair{5, 5}, std::pair{17, 17}, std::pair{100, 37}}) {
    const BlockDem d = blockFractal(w, h);
    BlockLod b(d.z, d.w, d.h, 30.0, {1.0e6, -2.0e6, 0.0}, {8});
    const glm::dvec3 o{1.0e6, -2.0e6, 0.0};
    const glm::dvec3 onVertex = b.vertexPosition(1, 1);
    const glm::dvec3 below = o + glm::dvec3(15, 15, -100);
    for (const RoamView& v : {blockViewAt(onVertex, 0, -30, 1.0), blockViewAt(below, 30, 10, 1.0),
                              blockViewAt(o + glm::dvec3(NAN, 0, 0), 0, 0, 1.0), blockViewAt(o + glm::dvec3(0, 0, 5e4), 0, -90, 0.5)}) {
      b.update(v);
      const auto tris = blockTriangles(b);
      // Every block is drawn except those culled; with the camera looking straight down from
      // high up, or NaN (nothing culled), the mesh covers the whole DEM.
      if (!std::isfinite(v.camera.eye_m.x) || v.camera.pitch_deg == -90) {
        EXPECT_TRUE(tilesDem(tris, w, h)) << w << "x" << h;
      }
    }
    // The camera exactly on a vertex is inside that vertex's blocks: they take the finest level
    // (or, on a DEM so small that every level draws the same clamped mesh, any level: all exact).
    b.update(blockViewAt(onVertex, 0, -30, 1.0));
    EXPECT_EQ(b.levelError_m(0, 0, b.level(0, 0)), 0.0) << w << "x" << h;
    if (b.levelError_m(0, 0, b.levels() - 1) > 0.0) {
      EXPECT_EQ(b.level(0, 0), 0) << w << "x" << h;
    }
  }
}

// Huge coordinates (ECEF-like, ~1e7 m, where a float's step is 1 m): the same DEM and the same
// eye relative to it choose the same level for every block, also with the eye inside a block's
// box (on the surface) and looking straight down, and the vertices keep their place.
TEST(BlockLod, HugeCoordinatesChooseTheSameLevels) {
  const BlockDem d = blockFractal(129, 129);
  const glm::dvec3 far{2441.0 * 4096.0, -1220.0 * 4096.0, 0.0};  // ~(1e7, -5e6): exact in double
  BlockLod a(d.z, d.w, d.h, 30.0, {0, 0, 0}, {16}), b(d.z, d.w, d.h, 30.0, far, {16});
  const glm::dvec3 onSurface = a.vertexPosition(40, 70) + glm::dvec3(0.25, 0.5, 1.0);
  int compared = 0;
  for (const RoamView& v : {blockViewAt({-2000, 1900, 1500}, 90, -20, 2.0), blockViewAt(onSurface, 30, -5, 1.0),
                            blockViewAt({1900, 1900, 3000}, 0, -90, 0.5), blockViewAt({1234.5, 321.25, 900}, 200, -35, 4.0)}) {
    a.update(v);
    RoamView w = v;
    w.camera.eye_m += far;
    b.update(w);
    for (int by = 0; by < a.blocksY(); ++by)
      for (int bx = 0; bx < a.blocksX(); ++bx) {
        ASSERT_EQ(a.level(bx, by), b.level(bx, by)) << bx << "," << by << " eye " << v.camera.eye_m.x;
        compared += a.level(bx, by) >= 0;
      }
    const auto ta = blockTriangles(a), tb = blockTriangles(b);
    ASSERT_EQ(ta.size(), tb.size());
  }
  EXPECT_GT(compared, 100);
  EXPECT_EQ(b.vertexPosition(10, 20) - far, a.vertexPosition(10, 20));
}

// The level error of a block is the exact maximum vertical error of the block's mesh at that
// level against the DEM's samples (the selection rule and maxErrorPx rest on it): every sample
// under a triangle of a block whose neighbours are not coarser (no fans to a coarser edge) lies
// within the block's chosen-level error of the drawn (clamped) mesh. It was computed on the
// padded grid with every quad split along x = y, while the border ring is zipped along the
// other diagonal and blocks cut by the DEM's east / north edge are drawn clamped onto it: up to
// ~60 m more than the table said on these 30 m DEMs.
TEST(BlockLod, DrawnMeshStaysWithinTheLevelErrorOfItsBlock) {
  for (auto [w, h] : {std::pair{65, 65}, std::pair{50, 40}, std::pair{20, 13}, std::pair{27, 40}, std::pair{40, 27}}) {
    const BlockDem d = blockFractal(w, h, 11);
    const int B = 16;
    BlockLod b(d.z, d.w, d.h, 30.0, {0, 0, 0}, {B});
    auto z = [&](int x, int y) {
      return static_cast<double>(d.z[static_cast<size_t>(y) * static_cast<size_t>(w) + static_cast<size_t>(x)]);
    };
    for (const RoamView& v : {blockViewAt({960, 960, 40000}, 0, -90, 4.0), blockViewAt({960, 960, 40000}, 0, -90, 40.0),
                              blockViewAt({-500, 500, 800}, 90, -20, 2.0), blockViewAt({960, 960, 40000}, 0, -90, 1e9)}) {
      b.update(v);
      auto coarserNeighbour = [&](int bx, int by) {
        const int k = b.level(bx, by);
        for (auto [nx, ny] : {std::pair{bx - 1, by}, std::pair{bx + 1, by}, std::pair{bx, by - 1}, std::pair{bx, by + 1}})
          if (nx >= 0 && ny >= 0 && nx < b.blocksX() && ny < b.blocksY() && b.level(nx, ny) > k) return true;
        return false;
      };
      double worst = 0.0;
      int checked = 0;
      for (const RoamTriangle& t0 : blockTriangles(b)) {
        const int bx = (t0.v[0].x + t0.v[1].x + t0.v[2].x) / 3 / B, by = (t0.v[0].y + t0.v[1].y + t0.v[2].y) / 3 / B;
        ASSERT_LT(bx, b.blocksX());
        ASSERT_LT(by, b.blocksY());
        if (coarserNeighbour(bx, by)) continue;
        const double allowed = b.levelError_m(bx, by, b.level(bx, by));
        RoamTriangle t = t0;
        for (auto& p : t.v) {
          p.x = std::clamp(p.x, 0, w - 1);
          p.y = std::clamp(p.y, 0, h - 1);
        }
        const double x0 = t.v[0].x, y0 = t.v[0].y;
        const double den = (t.v[1].x - x0) * (t.v[2].y - y0) - (t.v[2].x - x0) * (t.v[1].y - y0);
        const int xl = std::min({t.v[0].x, t.v[1].x, t.v[2].x}), xh = std::max({t.v[0].x, t.v[1].x, t.v[2].x});
        const int yl = std::min({t.v[0].y, t.v[1].y, t.v[2].y}), yh = std::max({t.v[0].y, t.v[1].y, t.v[2].y});
        for (int y = yl; y <= yh; ++y)
          for (int x = xl; x <= xh; ++x) {
            const double w1 = ((x - x0) * (t.v[2].y - y0) - (t.v[2].x - x0) * (y - y0)) / den;
            const double w2 = ((t.v[1].x - x0) * (y - y0) - (x - x0) * (t.v[1].y - y0)) / den;
            if (w1 < -1e-9 || w2 < -1e-9 || w1 + w2 > 1 + 1e-9) continue;
            const double m = (1 - w1 - w2) * z(t.v[0].x, t.v[0].y) + w1 * z(t.v[1].x, t.v[1].y) + w2 * z(t.v[2].x, t.v[2].y);
            worst = std::max(worst, std::abs(m - z(x, y)) - allowed);
            ++checked;
          }
      }
      EXPECT_GT(checked, w * h / 4) << w << "x" << h << " tol " << v.tolerance_px;
      EXPECT_LE(worst, 1e-3) << w << "x" << h << " tol " << v.tolerance_px
                             << ": a sample lies this far (m) beyond its block's level error";
    }
  }
}

// An infinite tolerance (any error is acceptable) takes the coarsest level everywhere, but the
// camera is still valid: blocks outside the frustum are not drawn. It switched culling off
// and drew every block behind the camera too.
TEST(BlockLod, InfiniteToleranceStillCullsOutsideTheFrustum) {
  const BlockDem d = blockFractal(129, 129);
  BlockLod b(d.z, d.w, d.h, 30.0, {0, 0, 0}, {16});
  // West of the DEM looking west and up: nothing of the DEM is in view.
  const BlockLodStats away = b.update(blockViewAt({-3000, 1900, 2000}, 270, 10, INFINITY));
  EXPECT_EQ(away.blocksVisible, 0u);
  EXPECT_EQ(away.triangles, 0u);
  EXPECT_EQ(blockTriangles(b).size(), 0u);
  // Looking down on all of it: every block, each at its coarsest level.
  const BlockLodStats all = b.update(blockViewAt({1920, 1920, 60000}, 0, -90, INFINITY));
  EXPECT_EQ(all.blocksVisible, 64u);
  for (int by = 0; by < b.blocksY(); ++by)
    for (int bx = 0; bx < b.blocksX(); ++bx) EXPECT_EQ(b.level(bx, by), b.levels() - 1);
}
