// Block LOD (lod/block_lod.h), from a mutation-testing pass over lod/block_lod.cpp: each test pins
// one documented detail that block_lod_test.cpp leaves open (a mutant of it passed every test
// there):
//   - the selection rule exactly: per block the coarsest level k with
//     error_m(k) * viewportHeight / (2 tan(fovY / 2)) / distance(eye, box) <= tolerance (a tie
//     included), the box being the block's samples' box clamped to the DEM, culled when outside
//     the frustum, and maxErrorPx the largest projected error among the visible blocks;
//   - maxErrorPx with the eye inside a block's box (finest level, error 0: no infinite pixels);
//   - a camera that is not finite (eye, fovY, window shift) culls nothing and takes the
//     coarsest level everywhere; a NaN tolerance takes the coarsest level but still culls;
//   - level errors are exact: 0 on flat terrain also for blocks cut by the DEM's edge;
//   - vertexPosition() clamps coordinates east / north of the DEM to its edge.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
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

namespace {

// The documented rule, from the DEM's samples: block (bx, by) covers samples [bx B, (bx + 1) B]
// (clamped to the DEM); its box spans them and their heights (relative to the origin).
struct Reference {
  const BlockDem& dem;
  int B;
  double spacing;

  Aabb box(int bx, int by) const {
    float lo = dem.at(bx * B, by * B), hi = lo;
    for (int y = by * B; y <= (by + 1) * B; ++y)
      for (int x = bx * B; x <= (bx + 1) * B; ++x) lo = std::min(lo, dem.at(x, y)), hi = std::max(hi, dem.at(x, y));
    const double x0 = std::min(bx * B, dem.w - 1) * spacing, x1 = std::min((bx + 1) * B, dem.w - 1) * spacing;
    const double y0 = std::min(by * B, dem.h - 1) * spacing, y1 = std::min((by + 1) * B, dem.h - 1) * spacing;
    return {{x0, y0, static_cast<double>(lo)}, {x1, y1, static_cast<double>(hi)}};
  }
  static double scale(const RoamView& v) {
    return v.viewportHeight_px / (2.0 * std::tan(0.5 * v.camera.fovY_deg * 3.14159265358979323846 / 180.0));
  }
  static double projected(double e, double scale, double d) {
    return e <= 0.0 ? 0.0 : (d > 0.0 ? e * scale / d : std::numeric_limits<double>::infinity());
  }
  // Checks every block's level (-1: culled) and maxErrorPx against the rule.
  void check(const BlockLod& b, const BlockLodStats& st, const RoamView& v, const glm::dvec3& origin) const {
    const glm::dvec3 eye = v.camera.eye_m - origin;
    Camera rel = v.camera;
    rel.eye_m = eye;
    const Frustum f = makeFrustum(rel);
    const double s = scale(v);
    double maxPx = 0.0;
    uint32_t visible = 0;
    for (int by = 0; by < b.blocksY(); ++by)
      for (int bx = 0; bx < b.blocksX(); ++bx) {
        const Aabb bb = box(bx, by);
        if (!f.intersects({bb.min - eye, bb.max - eye})) {
          EXPECT_EQ(b.level(bx, by), -1) << bx << "," << by;
          continue;
        }
        ++visible;
        const double d = distanceToBox(bb, eye);
        int k = b.levels() - 1;
        while (k > 0 && !(projected(b.levelError_m(bx, by, k), s, d) <= v.tolerance_px)) --k;
        EXPECT_EQ(b.level(bx, by), k) << bx << "," << by << " tolerance " << v.tolerance_px;
        maxPx = std::max(maxPx, projected(b.levelError_m(bx, by, k), s, d));
      }
    EXPECT_EQ(st.blocksVisible, visible);
    EXPECT_EQ(st.maxErrorPx, maxPx);
  }
};

}  // namespace

// The selection rule exactly, for every block, on DEMs cut by their edges (50 x 40 and 129 x 129
// samples, 16-quad blocks), from eyes high and low, inside and beyond the DEM on every side
// (the boxes of the east / north blocks are clamped to the DEM), looking down and across.
TEST(BlockLod, EveryBlockTakesTheCoarsestLevelWithinToleranceOfItsBox) {
  const glm::dvec3 origin{500.0, -300.0, 10.0};
  for (auto [w, h] : {std::pair{50, 40}, std::pair{129, 129}}) {
    const BlockDem d = blockFractal(w, h, 11);
    const int B = 16;
    BlockLod lod(d.z, d.w, d.h, 30.0, origin, {B});
    const Reference ref{d, B, 30.0};
    const double W = (w - 1) * 30.0, H = (h - 1) * 30.0;
    int views = 0;
    for (const glm::dvec3 eye : {glm::dvec3(0.5 * W, 0.5 * H, 900.0), glm::dvec3(W + 200.0, 0.4 * H, 700.0),
                                 glm::dvec3(0.3 * W, H + 150.0, 650.0), glm::dvec3(-250.0, -250.0, 800.0),
                                 glm::dvec3(0.7 * W, 0.2 * H, 1500.0)}) {
      for (const double heading : {0.0, 90.0, 200.0, 300.0}) {
        for (const double pitch : {-90.0, -30.0}) {
          for (const double tol : {0.5, 2.0, 8.0}) {
            const RoamView v = blockViewAt(origin + eye, heading, pitch, tol);
            const BlockLodStats st = lod.update(v);
            SCOPED_TRACE(testing::Message() << w << "x" << h << " eye " << eye.x << "," << eye.y << "," << eye.z
                                            << " heading " << heading << " pitch " << pitch << " tol " << tol);
            ref.check(lod, st, v, origin);
            ++views;
          }
        }
      }
    }
    EXPECT_EQ(views, 120);
  }
}

// "error ... <= tolerance_px": a block whose coarsest level projects to exactly the tolerance
// takes that level.
TEST(BlockLod, ALevelExactlyAtTheToleranceIsTaken) {
  const BlockDem d = blockFractal(129, 129);
  const int B = 16;
  BlockLod b(d.z, d.w, d.h, 30.0, {0, 0, 0}, {B});
  const Reference ref{d, B, 30.0};
  RoamView v = blockViewAt({1900, 1900, 2500}, 0, -90, 1.0);
  // The block under the eye, at its coarsest level: its pixels there become the tolerance.
  const int bx = 1900 / 30 / B, by = 1900 / 30 / B, top = b.levels() - 1;
  ASSERT_GT(b.levelError_m(bx, by, top), b.levelError_m(bx, by, top - 1));
  const double px = Reference::projected(b.levelError_m(bx, by, top), Reference::scale(v),
                                         distanceToBox(ref.box(bx, by), v.camera.eye_m));
  ASSERT_GT(px, 0.0);
  v.tolerance_px = px;
  const BlockLodStats st = b.update(v);
  EXPECT_EQ(b.level(bx, by), top);
  ref.check(b, st, v, {0, 0, 0});
}

// With the eye inside a block's box (on the surface) that block draws its finest level, whose
// error is 0: the largest projected error is that of the other blocks, not infinite.
TEST(BlockLod, MaxErrorPxIsFiniteWithTheEyeInsideABlock) {
  const BlockDem d = blockFractal(129, 129);
  BlockLod b(d.z, d.w, d.h, 30.0, {0, 0, 0}, {16});
  const glm::dvec3 onSurface = b.vertexPosition(40, 70) + glm::dvec3(0.25, 0.5, 1.0);
  const BlockLodStats st = b.update(blockViewAt(onSurface, 30, -5, 1.0));
  ASSERT_EQ(b.level(40 / 16, 70 / 16), 0);
  EXPECT_TRUE(std::isfinite(st.maxErrorPx));
  EXPECT_LE(st.maxErrorPx, 1.0);
}

// "A camera that is not finite cannot cull or measure distances: every block, coarsest": a NaN
// eye height, a NaN field of view or a window shift beyond kMaxWindowShift. "A NaN tolerance
// takes the coarsest level too" but the camera is valid: blocks outside the view are culled.
TEST(BlockLod, ACameraThatIsNotFiniteDrawsEveryBlockCoarsest) {
  const BlockDem d = blockFractal(129, 129);
  BlockLod b(d.z, d.w, d.h, 30.0, {0, 0, 0}, {16});
  const int blocks = b.blocksX() * b.blocksY();
  RoamView eyeZ = blockViewAt({1900, 1900, 900}, 0, -30, 1.0);
  eyeZ.camera.eye_m.z = std::nan("");
  RoamView fov = blockViewAt({1900, 1900, 900}, 0, -30, 1.0);
  fov.camera.fovY_deg = std::nan("");
  RoamView shifted = blockViewAt({1900, 1900, 900}, 0, -30, 1.0);
  shifted.camera.shiftX = 2.0 * kMaxWindowShift;
  for (const RoamView& v : {eyeZ, fov, shifted}) {
    const BlockLodStats st = b.update(v);
    EXPECT_EQ(st.blocksVisible, static_cast<uint32_t>(blocks));
    for (int by = 0; by < b.blocksY(); ++by)
      for (int bx = 0; bx < b.blocksX(); ++bx) ASSERT_EQ(b.level(bx, by), b.levels() - 1) << bx << "," << by;
    EXPECT_TRUE(tilesDem(blockTriangles(b), d.w, d.h));
  }
  // A NaN tolerance from the DEM's west edge looking west: coarsest, and culled.
  const BlockLodStats away = b.update(blockViewAt({-3000, 1900, 2000}, 270, 10, std::nan("")));
  EXPECT_EQ(away.blocksVisible, 0u);
  const BlockLodStats down = b.update(blockViewAt({1920, 1920, 1500}, 0, -90, std::nan("")));
  EXPECT_GT(down.blocksVisible, 0u);
  for (int by = 0; by < b.blocksY(); ++by)
    for (int bx = 0; bx < b.blocksX(); ++bx)
      if (b.level(bx, by) >= 0) {
        ASSERT_EQ(b.level(bx, by), b.levels() - 1) << bx << "," << by;
      }
}

// Level errors are the exact error of the drawn (clamped) mesh: on flat terrain 0 at every level,
// also for the blocks cut by the DEM's east and north edges (whose clamped triangles include
// zero-area ones, which are not drawn and have no error), so every block is drawn coarsest.
TEST(BlockLod, FlatTerrainCutByTheDemEdgeHasNoErrorAtAnyLevel) {
  for (auto [w, h] : {std::pair{50, 40}, std::pair{20, 13}}) {
    BlockDem d{w, h, std::vector<float>(static_cast<size_t>(w) * h, 120.0f)};
    BlockLod b(d.z, d.w, d.h, 10.0, {0, 0, 0}, {16});
    for (int by = 0; by < b.blocksY(); ++by)
      for (int bx = 0; bx < b.blocksX(); ++bx)
        for (int k = 0; k < b.levels(); ++k) ASSERT_EQ(b.levelError_m(bx, by, k), 0.0) << w << "x" << h << " " << bx << "," << by << " k " << k;
    ASSERT_EQ(b.update(blockViewAt({100, 100, 5000}, 0, -90, 0.5)).blocksVisible, static_cast<uint32_t>(b.blocksX() * b.blocksY()));
    for (int by = 0; by < b.blocksY(); ++by)
      for (int bx = 0; bx < b.blocksX(); ++bx)
        if (b.level(bx, by) >= 0) {
          EXPECT_EQ(b.level(bx, by), b.levels() - 1);
        }
    EXPECT_TRUE(tilesDem(blockTriangles(b), w, h));
  }
}

// "Coordinates east / north of the DEM clamp to its edge" (the grid is padded to whole blocks).
TEST(BlockLod, VertexPositionsBeyondTheDemClampToItsEdge) {
  const BlockDem d = blockFractal(50, 40);
  const glm::dvec3 origin{1000.0, 2000.0, 5.0};
  BlockLod b(d.z, d.w, d.h, 30.0, origin, {16});
  EXPECT_EQ(b.vertexPosition(63, 10), b.vertexPosition(49, 10));
  EXPECT_EQ(b.vertexPosition(20, 47), b.vertexPosition(20, 39));
  EXPECT_EQ(b.vertexPosition(64, 64), b.vertexPosition(49, 39));
  EXPECT_EQ(b.vertexPosition(49, 39), origin + glm::dvec3(49 * 30.0, 39 * 30.0, static_cast<double>(d.at(49, 39))));
}
