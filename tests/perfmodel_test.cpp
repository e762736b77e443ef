// Paper 002, pure parts: memory model (1), time model (2), switching (5)/(6) with hysteresis,
// q* of (11) against a brute-force minimum of (7), the online fits of (8)-(10), and the
// single-reference octree with the expensive-node estimate of hidden objects.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "lod/dynamic_octree.h"
#include "lod/perfmodel.h"
#include "lod/view.h"
#include "octree_fixtures.h"
#include "perfmodel_fixtures.h"

using namespace ig::lod;

namespace {

using ig::lod::test::handConstants;

TEST(PerfModel, MemoryModelSumsEveryTerm) {
  const uint64_t tex[] = {1024}, buf[] = {64, 36}, desc[] = {16};
  MemoryModelInput in;
  in.vertices = 1000;
  in.indices = 3000;
  in.texCoords = 1000;
  in.normals = 1000;
  in.textureBytes = tex;
  in.bufferBytes = buf;
  in.descriptorBytes = desc;
  EXPECT_EQ(sceneMemoryBytes(in), 12000u + 12000u + 8000u + 12000u + 1024u + 100u + 16u);
  in.vertices = std::numeric_limits<uint64_t>::max() / 2;  // would wrap: saturates
  EXPECT_EQ(sceneMemoryBytes(in), std::numeric_limits<uint64_t>::max());
  EXPECT_EQ(sceneMemoryBytes(MemoryModelInput{}), 0u);
}

TEST(PerfModel, TimeModelOnHandMadeNumbers) {
  const PerfConstants c = handConstants();
  PassLoad s, h;
  s.triangles = 1200;     // vert 12000
  s.fragments = 5000;     // frag 5000
  s.stateChanges = 2;     // state 200
  s.commands = 100;       // 100000
  s.submissions = 1;      // 500
  s.frustumTests = 100;   // 2000
  h.occlusionTests = 10;  // 30000
  h.depthFragments = 4000;  // z-buffer 2000
  h.triangles = 120;      // 1200
  h.frustumTests = 8;     // 160
  TimeBreakdown b;
  EXPECT_DOUBLE_EQ(predictFrame_ns(c, s, h, &b), 10000 + 100500 + 2000 + 12000 + 160 + 30000 + 2000);
  EXPECT_EQ(b.boundS, 1);  // vertex
  EXPECT_EQ(b.boundH, 3);  // z-buffer
  EXPECT_DOUBLE_EQ(b.gpuS, 12000);
  // The max() is real: more fragments make the objects fragment-bound.
  s.fragments = 20000;
  EXPECT_DOUBLE_EQ(predictFrame_ns(c, s, h, &b), 10000 + 100500 + 2000 + 20000 + 160 + 30000 + 2000);
  EXPECT_EQ(b.boundS, 2);
  // Re-recorded objects cost t_r each.
  s.rerecorded = 10;
  EXPECT_DOUBLE_EQ(predictFrame_ns(c, s, h), 10000 + 100500 + 500 + 2000 + 20000 + 160 + 30000 + 2000);
  s.rerecorded = 0;
  // No overlap: the stages of each max() add up.
  PerfConstants serial = c;
  serial.overlap = 0.0;
  EXPECT_DOUBLE_EQ(predictFrame_ns(serial, s, h), 10000 + 100500 + 2000 + (20000 + 12000 + 200) + 160 + 30000 +
                                                      (2000 + 1200));
  serial.overlap = 0.5;
  EXPECT_DOUBLE_EQ(predictFrame_ns(serial, s, h),
                   10000 + 100500 + 2000 + (20000 + 0.5 * 12200) + 160 + 30000 + (2000 + 0.5 * 1200));
  // The rasterizer's triangles and edges belong to the fragment stage.
  PerfConstants raster = c;
  raster.rasterTri_ns = 5.0;  // objects 6000, hierarchy 600
  raster.edge_ns = 2.0;
  s.edgePx = 1000;            // 2000
  h.edgePx = 100;             // 200
  EXPECT_DOUBLE_EQ(predictFrame_ns(raster, s, h, &b), 10000 + 100500 + 2000 + (20000 + 6000 + 2000) + 160 + 30000 + 2000);
  EXPECT_EQ(b.boundS, 2);
  EXPECT_DOUBLE_EQ(b.fragS, 28000);
  EXPECT_DOUBLE_EQ(b.fragH, 800);
  // So does each draw command (a draw of its own in the rasterizer): 100 commands of the objects.
  raster.drawRaster_ns = 30.0;  // 3000
  h.commands = 4;               // t_c: 4000 in the hierarchy's T_buf; T_draw: 120 in its fragments
  EXPECT_DOUBLE_EQ(predictFrame_ns(raster, s, h, &b),
                   10000 + 100500 + 2000 + (20000 + 6000 + 2000 + 3000) + 160 + (30000 + 4000) + 2000);
  EXPECT_DOUBLE_EQ(b.fragS, 31000);
  EXPECT_DOUBLE_EQ(b.fragH, 800 + 120);
  // Only the triangles and commands that reach the rasterizer cost it T_rtri and T_draw: half of
  // the objects' (6000 + 3000 -> 4500), all of the hierarchy's (the default share 1).
  s.rasterShare = 0.5;
  EXPECT_DOUBLE_EQ(predictFrame_ns(raster, s, h, &b),
                   10000 + 100500 + 2000 + (20000 + 4500 + 2000) + 160 + (30000 + 4000) + 2000);
  EXPECT_DOUBLE_EQ(b.fragS, 26500);
  EXPECT_DOUBLE_EQ(b.vertS, 12000);  // set-up on the application side: every triangle
  s.rasterShare = 0.0;
  predictFrame_ns(raster, s, h, &b);
  EXPECT_DOUBLE_EQ(b.fragS, 22000);
  // Out of range or not finite: clamped, or unknown (every triangle reaches it).
  s.rasterShare = 3.0;
  predictFrame_ns(raster, s, h, &b);
  EXPECT_DOUBLE_EQ(b.fragS, 31000);
  s.rasterShare = -2.0;
  predictFrame_ns(raster, s, h, &b);
  EXPECT_DOUBLE_EQ(b.fragS, 22000);
  s.rasterShare = std::numeric_limits<double>::quiet_NaN();
  predictFrame_ns(raster, s, h, &b);
  EXPECT_DOUBLE_EQ(b.fragS, 31000);
  s.rasterShare = std::numeric_limits<double>::infinity();
  predictFrame_ns(raster, s, h, &b);
  EXPECT_DOUBLE_EQ(b.fragS, 31000);
  raster.drawRaster_ns = -1.0;  // invalid: the constants are rejected
  EXPECT_FALSE(valid(raster));
}

// A box smaller than a pixel covers a pixel centre with a probability of about its area.
TEST(PerfModel, BoxRasterShareByProjectedArea) {
  EXPECT_DOUBLE_EQ(boxRasterShare(0.25), 0.25);
  EXPECT_DOUBLE_EQ(boxRasterShare(1.0), 1.0);
  EXPECT_DOUBLE_EQ(boxRasterShare(40.0), 1.0);
  EXPECT_DOUBLE_EQ(boxRasterShare(0.0), 0.0);
  EXPECT_DOUBLE_EQ(boxRasterShare(-3.0), 0.0);
  EXPECT_DOUBLE_EQ(boxRasterShare(std::numeric_limits<double>::quiet_NaN()), 0.0);
  EXPECT_DOUBLE_EQ(boxRasterShare(std::numeric_limits<double>::infinity()), 1.0);
}

// A software rasterizer overlaps its stages only once a frame overflows its scene: the overlap
// of a frame grows from 0 at overlapTriangles towards w.
TEST(PerfModel, OverlapGrowsWithTheFrameBeyondOverlapTriangles) {
  PerfConstants c = handConstants();
  c.overlap = 0.8;
  EXPECT_DOUBLE_EQ(stageOverlap(c, 1000), 0.8);  // no threshold: the constant w (a GPU)
  c.overlapTriangles = 100000;
  EXPECT_DOUBLE_EQ(stageOverlap(c, 50000), 0.0);
  EXPECT_DOUBLE_EQ(stageOverlap(c, 100000), 0.0);
  EXPECT_DOUBLE_EQ(stageOverlap(c, 400000), 0.8 * 0.75);
  EXPECT_DOUBLE_EQ(stageOverlap(c, std::nan("")), 0.0);
  PassLoad s;
  s.triangles = 400000;  // vert 4e6
  s.fragments = 2e6;     // frag 2e6
  EXPECT_DOUBLE_EQ(predictFrame_ns(c, s, {}), 10000 + 4e6 + (1.0 - 0.6) * 2e6);
  s.triangles = 50000;   // vert 5e5: below the threshold the stages add up
  EXPECT_DOUBLE_EQ(predictFrame_ns(c, s, {}), 10000 + 5e5 + 2e6);
}

// The calibration's overlap line, fitted to two frames: from frames that a known line predicts,
// the line comes back; the fitted constants predict both frames; the cases without growth,
// without overlap, faster than even full overlap, and a NaN time.
TEST(PerfModel, FitOverlapRecoversTheLineThatPredictsItsFrames) {
  PerfConstants truth = handConstants();
  truth.overlap = 0.8;
  truth.overlapTriangles = 100000;
  OverlapSample small, large;
  small.load.triangles = 200000;  // vert 2e6
  small.load.fragments = 1.5e6;   // frag 1.5e6: the smaller stage
  large.load.triangles = 600000;  // vert 6e6
  large.load.fragments = 3e6;
  small.measured_ns = predictFrame_ns(truth, small.load, {});
  large.measured_ns = predictFrame_ns(truth, large.load, {});
  PerfConstants start = handConstants();
  start.overlap = 0.0;  // whatever it was: the fit sets both fields
  start.overlapTriangles = 12345;
  const PerfConstants fit = fitOverlap(start, small, large);
  EXPECT_NEAR(fit.overlap, 0.8, 1e-12);
  EXPECT_NEAR(fit.overlapTriangles, 100000, 1e-6);
  EXPECT_NEAR(predictFrame_ns(fit, small.load, {}), small.measured_ns, 1e-6);
  EXPECT_NEAR(predictFrame_ns(fit, large.load, {}), large.measured_ns, 1e-6);
  EXPECT_EQ(fit.tri_ns, start.tri_ns) << "only the overlap fields change";

  // The same overlap at both sizes: a constant w, no threshold.
  truth.overlap = 0.5;
  truth.overlapTriangles = 0;
  small.measured_ns = predictFrame_ns(truth, small.load, {});
  large.measured_ns = predictFrame_ns(truth, large.load, {});
  PerfConstants k = fitOverlap(start, small, large);
  EXPECT_NEAR(k.overlap, 0.5, 1e-12);
  EXPECT_EQ(k.overlapTriangles, 0.0);

  // Frames as slow as the stages' sum: no overlap.
  truth.overlap = 0.0;
  small.measured_ns = predictFrame_ns(truth, small.load, {});
  large.measured_ns = predictFrame_ns(truth, large.load, {});
  k = fitOverlap(start, small, large);
  EXPECT_EQ(k.overlap, 0.0);
  EXPECT_EQ(k.overlapTriangles, 0.0);

  // Faster than the full max(): w is clamped to 1. A NaN time counts as no overlap.
  small.measured_ns = large.measured_ns = 1000.0;
  k = fitOverlap(start, small, large);
  EXPECT_EQ(k.overlap, 1.0);
  small.measured_ns = large.measured_ns = std::nan("");
  k = fitOverlap(start, small, large);
  EXPECT_EQ(k.overlap, 0.0);
  EXPECT_TRUE(valid(k));

  // Fitted with other constants (a higher T_frag), the overlap changes so that the frames are
  // still predicted: what the calibration's second fit, over the median constants, is for.
  truth = handConstants();
  truth.overlap = 0.8;
  truth.overlapTriangles = 100000;
  small.measured_ns = predictFrame_ns(truth, small.load, {});
  large.measured_ns = predictFrame_ns(truth, large.load, {});
  PerfConstants other = handConstants();
  other.frag_ns = 1.2;
  other = fitOverlap(other, small, large);
  EXPECT_GT(other.overlap, 0.8);
  EXPECT_NEAR(predictFrame_ns(other, small.load, {}), small.measured_ns, 1e-6 * small.measured_ns);
  EXPECT_NEAR(predictFrame_ns(other, large.load, {}), large.measured_ns, 1e-6 * large.measured_ns);
}

// T_tri by the size of a submission (llvmpipe sets its vertex pipeline up per call: a box costs
// more in a call of a few boxes).
TEST(PerfModel, TriangleCostFollowsTheSubmissionSize) {
  PerfConstants c = handConstants();
  EXPECT_DOUBLE_EQ(triangleCost_ns(c, 12), 10);  // no table: tri_ns for every size
  c.triByDraw_ns = {80, 60, 50, 40, 30, 20, 10};
  ASSERT_TRUE(valid(c));
  EXPECT_DOUBLE_EQ(triangleCost_ns(c, 12), 80);
  EXPECT_DOUBLE_EQ(triangleCost_ns(c, 1), 80);  // below the table: its first entry
  EXPECT_DOUBLE_EQ(triangleCost_ns(c, 48), 50);
  EXPECT_NEAR(triangleCost_ns(c, 12 * std::sqrt(2.0)), 70, 1e-9);  // halfway in log2
  EXPECT_DOUBLE_EQ(triangleCost_ns(c, 768), 10);
  EXPECT_DOUBLE_EQ(triangleCost_ns(c, 1e9), 10);  // beyond it: the last entry
  EXPECT_DOUBLE_EQ(triangleCost_ns(c, 0), 10);    // size unknown: tri_ns
  EXPECT_DOUBLE_EQ(triangleCost_ns(c, std::nan("")), 10);
  // The same 1,200 triangles in 100 calls of one box, in 25 calls of four, in one call.
  PassLoad s;
  s.triangles = 1200;
  s.commands = 100;
  s.submissions = 100;
  TimeBreakdown b;
  predictFrame_ns(c, s, {}, &b);
  EXPECT_DOUBLE_EQ(b.vertS, 1200 * 80.0);
  s.submissions = 25;
  predictFrame_ns(c, s, {}, &b);
  EXPECT_DOUBLE_EQ(b.vertS, 1200 * 50.0);
  s.submissions = 1;
  predictFrame_ns(c, s, {}, &b);
  EXPECT_DOUBLE_EQ(b.vertS, 1200 * 10.0);
  s.submissions = 0;  // not counted: tri_ns
  predictFrame_ns(c, s, {}, &b);
  EXPECT_DOUBLE_EQ(b.vertS, 1200 * 10.0);
  // An entry that is not a finite number >= 0: the table counts as not measured, the
  // constants as invalid.
  c.triByDraw_ns[3] = std::nan("");
  EXPECT_FALSE(valid(c));
  EXPECT_DOUBLE_EQ(triangleCost_ns(c, 96), 10);
  c.triByDraw_ns[3] = -1.0;
  EXPECT_FALSE(valid(c));
  c.triByDraw_ns[3] = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(valid(c));
}

// t_c grows once a frame's commands no longer fit the caches: interpolated in log(commands)
// between the two measured sizes, constant outside.
TEST(PerfModel, CommandCostGrowsWithTheCommandsOfAFrame) {
  PerfConstants c = handConstants();  // t_c 1000
  EXPECT_DOUBLE_EQ(commandCost_ns(c, 1e6), 1000);  // not measured: one constant
  c.commandCount = 1000;
  c.commandLarge_ns = 3000;
  c.commandLargeCount = 100000;
  ASSERT_TRUE(valid(c));
  EXPECT_DOUBLE_EQ(commandCost_ns(c, 10), 1000);
  EXPECT_DOUBLE_EQ(commandCost_ns(c, 1000), 1000);
  EXPECT_NEAR(commandCost_ns(c, 10000), 2000, 1e-9);  // halfway in log
  EXPECT_DOUBLE_EQ(commandCost_ns(c, 100000), 3000);
  EXPECT_DOUBLE_EQ(commandCost_ns(c, 1e7), 3000);  // not extrapolated
  EXPECT_DOUBLE_EQ(commandCost_ns(c, std::nan("")), 1000);
  PassLoad s;
  s.commands = 10000;
  s.submissions = 1;
  TimeBreakdown b;
  predictFrame_ns(c, s, {}, &b);
  EXPECT_NEAR(b.bufS, 10000 * 2000.0 + 500.0, 1e-6);
  c.commandLargeCount = 500;  // not above commandCount: one constant
  EXPECT_DOUBLE_EQ(commandCost_ns(c, 10000), 1000);
  c.commandLarge_ns = std::nan("");
  EXPECT_FALSE(valid(c));
}

TEST(PerfModel, NanAndNegativeInputsCountAsZero) {
  const PerfConstants c = handConstants();
  PassLoad s;
  s.triangles = 1200;
  const double base = predictFrame_ns(c, s, {});
  PassLoad bad = s;
  bad.commands = std::nan("");
  bad.fragments = -5000;
  bad.submissions = std::numeric_limits<double>::infinity();
  bad.stateChanges = -1;
  EXPECT_DOUBLE_EQ(predictFrame_ns(c, bad, {}), base);
  PerfConstants badC = c;
  badC.tri_ns = std::nan("");
  EXPECT_FALSE(valid(badC));
  EXPECT_DOUBLE_EQ(predictFrame_ns(badC, s, {}), c.frame_ns);  // the NaN term counts as 0
  badC = c;
  badC.overlap = 1.5;
  EXPECT_FALSE(valid(badC));
  badC.overlap = 1.0;
  badC.cull_ns = -1.0;
  EXPECT_FALSE(valid(badC));
  badC = c;
  badC.edge_ns = std::nan("");
  EXPECT_FALSE(valid(badC));
  badC = c;
  badC.overlapTriangles = -1.0;
  EXPECT_FALSE(valid(badC));
  EXPECT_TRUE(valid(c));
  EXPECT_FALSE(valid(PerfConstants{}));  // T_tri and T_frag must be measured
}

// The return value is finite and >= 0 for any input: a finite count too large for the product
// with its cost (here 1e308 triangles at 10 ns) gave inf, and NaN where the stages' max() took
// inf from inf.
TEST(PerfModel, HugeFiniteCountsGiveAFiniteFrameTime) {
  const PerfConstants c = handConstants();
  PassLoad s;
  s.triangles = 1e308;
  TimeBreakdown b;
  const double t = predictFrame_ns(c, s, {}, &b);
  EXPECT_TRUE(std::isfinite(t)) << t;
  PassLoad big;
  big.triangles = 1e12;
  EXPECT_GT(t, predictFrame_ns(c, big, {}));  // still more than any real frame
  PassLoad h;
  h.depthFragments = 1e308;
  h.frustumTests = 1e308;
  const double th = predictFrame_ns(c, s, h, &b);
  EXPECT_TRUE(std::isfinite(th)) << th;
  EXPECT_GE(th, 0.0);
  for (PerfConstants k : {c, [&] { PerfConstants o = c; o.overlap = 0.5; return o; }()}) {
    const double tk = predictFrame_ns(k, s, h);
    EXPECT_TRUE(std::isfinite(tk) && tk > 0.0) << tk;
  }
}

TEST(PerfModel, ProjectedBoxArea) {
  // 90 degree fov, square 200 px viewport: 10 px per metre at 10 m.
  Camera cam;
  cam.fovY_deg = 90.0;
  cam.aspect = 1.0;
  cam.near_m = 0.1;
  cam.far_m = 1000.0;
  const glm::dmat4 vp = projection(cam) * glm::dmat4(viewRotation(cam));
  const auto box = test::boxCorners;
  EXPECT_NEAR(projectedBoxArea_px(vp, box({0, 10, 0}, {1, 0.001, 1}), 200, 200), 400.0, 4.0);
  EXPECT_NEAR(projectedBoxArea_px(vp, box({0, 10, 0}, {50, 0.001, 50}), 200, 200), 40000.0, 1e-6);  // clipped
  EXPECT_DOUBLE_EQ(projectedBoxArea_px(vp, box({0, -10, 0}, {1, 1, 1}), 200, 200), -1.0);          // behind
  EXPECT_NEAR(projectedBoxArea_px(vp, box({500, 10, 0}, {1, 0.001, 1}), 200, 200), 0.0, 1e-9);     // off screen
  EXPECT_DOUBLE_EQ(projectedBoxArea_px(vp, box({0, 10, 0}, {0, 0, 0}), 200, 200), 0.0);            // degenerate
}

ModeInputs inputs(double l5, double r5, double l6, double r6) {
  ModeInputs in;
  in.bufS_ns = l5;
  in.bufH_ns = r5;
  in.frameAll_ns = l6;
  in.frameVisible_ns = r6;
  return in;
}

TEST(PerfModel, ModeSwitchingFollowsConditions5And6WithHysteresis) {
  ModeSwitcher m({0.15, 3});
  // (5) holds: stay with per-object commands.
  for (int i = 0; i < 10; ++i) EXPECT_EQ(m.update(inputs(900, 1000, 0, 0)), DynamicMode::PerCommand);
  // (5) fails by less than the hysteresis: still per-object commands.
  for (int i = 0; i < 10; ++i) EXPECT_EQ(m.update(inputs(1100, 1000, 0, 0)), DynamicMode::PerCommand);
  EXPECT_EQ(m.switches(), 0u);
  // ... by more: octree.
  EXPECT_EQ(m.update(inputs(1200, 1000, 0, 0)), DynamicMode::Octree);
  EXPECT_EQ(m.switches(), 1u);
  // Noise around the threshold does not flip it back (no oscillation).
  for (int i = 0; i < 50; ++i) m.update(inputs(i % 2 ? 1100 : 900, 1000, 100, 100));
  EXPECT_EQ(m.mode(), DynamicMode::Octree);
  EXPECT_EQ(m.switches(), 1u);
  // (6) fails clearly: occlusion queries; not before minFrames.
  m.update(inputs(1200, 1000, 130, 100));
  EXPECT_EQ(m.mode(), DynamicMode::Occlusion);
  EXPECT_EQ(m.update(inputs(1200, 1000, 50, 100)), DynamicMode::Occlusion);  // within minFrames
  for (int i = 0; i < 3; ++i) m.update(inputs(1200, 1000, 90, 100));         // within hysteresis
  EXPECT_EQ(m.mode(), DynamicMode::Occlusion);
  EXPECT_EQ(m.update(inputs(1200, 1000, 80, 100)), DynamicMode::Octree);
  // NaN statistics keep the mode.
  for (int i = 0; i < 10; ++i) m.update(inputs(std::nan(""), 1000, std::nan(""), 100));
  EXPECT_EQ(m.mode(), DynamicMode::Octree);
  // Back to per-object commands when (5) holds clearly.
  for (int i = 0; i < 4; ++i) m.update(inputs(500, 1000, 100, 100));
  EXPECT_EQ(m.mode(), DynamicMode::PerCommand);
  EXPECT_EQ(m.switches(), 4u);
}

// Per-object commands hold (5), but the estimate finds hidden objects: straight to occlusion
// culling when the whole per-object frame costs more than the culled one (by the hysteresis);
// not while culling saves nothing, nor within minFrames.
TEST(PerfModel, ModeSwitchingLeavesPerObjectCommandsForOcclusionWhenObjectsAreHidden) {
  ModeSwitcher m({0.15, 3});
  // (6) fails, but T(S) - r5 + l5 = 10,000 - 1,000 + 900 = 9,900 <= 9,000 * 1.15.
  for (int i = 0; i < 10; ++i) EXPECT_EQ(m.update(inputs(900, 1000, 10000, 9000)), DynamicMode::PerCommand);
  EXPECT_EQ(m.update(inputs(900, 1000, 10000, 8700)), DynamicMode::PerCommand);  // 9,900 <= 10,005
  EXPECT_EQ(m.switches(), 0u);
  EXPECT_EQ(m.update(inputs(900, 1000, 10000, 8500)), DynamicMode::Occlusion);  // 9,900 > 9,775
  EXPECT_EQ(m.switches(), 1u);
  // Not within minFrames of the start (or of the last change).
  ModeSwitcher k({0.15, 3});
  for (int i = 0; i < 3; ++i) EXPECT_EQ(k.update(inputs(900, 1000, 10000, 5000)), DynamicMode::PerCommand);
  EXPECT_EQ(k.update(inputs(900, 1000, 10000, 5000)), DynamicMode::Occlusion);
  // Culling that saves nothing never starts from per-object commands, however the frames compare.
  ModeSwitcher n({0.15, 3});
  for (int i = 0; i < 10; ++i) EXPECT_EQ(n.update(inputs(1100, 1000, 0, 0)), DynamicMode::PerCommand);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(n.update(inputs(1100, 1000, 5000, 5000)), DynamicMode::PerCommand);
  EXPECT_EQ(n.switches(), 0u);
}

TEST(PerfModel, OptimalQMatchesBruteForceMinimum) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int interior = 0;
  for (int trial = 0; trial < 500; ++trial) {
    OcclusionCoefficients k;
    const uint32_t n0 = 1 + static_cast<uint32_t>(u(rng) * 3000);
    const double an_cn = 0.1 + 20 * u(rng), s1 = 50 * u(rng);
    k.cA = an_cn * n0;
    k.cB = an_cn * s1;
    k.sA = n0 + 1.0;
    k.s1 = s1;
    k.e0 = 1e6 * u(rng);
    k.p = 10 * u(rng);
    k.e1 = 1e5 * u(rng);
    OcclusionCosts t{100 + 2000 * u(rng), 500 + 5000 * u(rng), 1 + 50 * u(rng), trial % 2 ? -1.0 : 1000 + 5000 * u(rng)};
    double best = 1e300;
    uint32_t bestQ = 0;
    for (uint32_t q = 0; q <= n0; ++q) {
      const double tq = occlusionFrame_ns(k, t, q);
      if (tq < best) best = tq, bestQ = q;
    }
    double tOpt = 0;
    const uint32_t q = optimalQ(k, t, n0, &tOpt);
    EXPECT_LE(q, n0);
    EXPECT_NEAR(tOpt, best, 1e-9 * std::abs(best)) << "trial " << trial << " q " << q << " brute " << bestQ;
    const double qs = stationaryQ(k, t);
    if (qs > 1 && qs < n0 - 1) {
      ++interior;
      const double h = 1e-3;
      const double d = (occlusionFrame_ns(k, t, qs + h) - occlusionFrame_ns(k, t, qs - h)) / (2 * h);
      EXPECT_NEAR(d, 0.0, 1e-6 * (std::abs(occlusionFrame_ns(k, t, qs)) + 1.0));  // T'(q*) = 0
    }
  }
  EXPECT_GT(interior, 50);  // the stationary point was exercised, not only the bounds
  // (11) by hand: (a c s1 t_c + s1 t_s + e1 t_e) / (p t_e + t_c) - 1.
  OcclusionCoefficients k;
  k.cB = 2.0 * 10.0;  // a_n c_n = 2, s1 = 10
  k.s1 = 10.0;
  k.e1 = 1000.0;
  k.p = 5.0;
  const OcclusionCosts t{100.0, 400.0, 2.0};
  EXPECT_DOUBLE_EQ(stationaryQ(k, t), (20.0 * 100.0 + 10.0 * 400.0 + 1000.0 * 2.0) / (5.0 * 2.0 + 100.0) - 1.0);
  EXPECT_TRUE(std::isnan(stationaryQ(OcclusionCoefficients{}, OcclusionCosts{})));
  EXPECT_EQ(optimalQ(OcclusionCoefficients{}, OcclusionCosts{1, 1, 1}, 100), 0u);  // tests only cost
}

TEST(PerfModel, FitsRecoverKnownCoefficients) {
  OcclusionCoefficients truth;
  truth.cA = 5000;
  truth.cB = 300;
  truth.sA = 801;
  truth.s1 = 60;
  truth.e0 = 2e6;
  truth.p = 40;
  truth.e1 = 1.5e5;
  OcclusionFits fits(1.0);
  OcclusionCoefficients k;
  EXPECT_FALSE(fits.solve(k));
  const double qs[] = {0, 1, 3, 7, 15, 31, 63, 127, 255};
  for (int rep = 0; rep < 3; ++rep) {
    for (double q : qs) {
      const double l = std::log1p(q);
      ASSERT_TRUE(fits.add(q, truth.cA - truth.cB * l + q, truth.sA - truth.s1 * l, truth.e0 + truth.p * q - truth.e1 * l));
    }
    if (rep == 0) {
      EXPECT_TRUE(fits.solve(k));
    }
  }
  ASSERT_TRUE(fits.solve(k));
  EXPECT_NEAR(k.cA, truth.cA, 1e-6 * truth.cA);
  EXPECT_NEAR(k.cB, truth.cB, 1e-6 * truth.cA);
  EXPECT_NEAR(k.sA, truth.sA, 1e-6 * truth.sA);
  EXPECT_NEAR(k.s1, truth.s1, 1e-6 * truth.sA);
  EXPECT_NEAR(k.e0, truth.e0, 1e-6 * truth.e0);
  EXPECT_NEAR(k.p, truth.p, 1e-6 * truth.p + 1e-6);
  EXPECT_NEAR(k.e1, truth.e1, 1e-6 * truth.e0);
  // Bad samples are refused and change nothing.
  EXPECT_FALSE(fits.add(std::nan(""), 1, 1, 1));
  EXPECT_FALSE(fits.add(1, -1, 1, 1));
  EXPECT_FALSE(fits.add(1, 1, std::numeric_limits<double>::infinity(), 1));
  OcclusionCoefficients k2;
  ASSERT_TRUE(fits.solve(k2));
  EXPECT_DOUBLE_EQ(k2.e1, k.e1);
  // Two distinct q cannot determine three unknowns.
  OcclusionFits two;
  for (int i = 0; i < 10; ++i) two.add(i % 2 ? 4.0 : 9.0, 10, 10, 10);
  EXPECT_FALSE(two.solve(k2));
}

// A glitched count (finite but absurd: 1e200 tests in a frame) must not poison the sums: q^2
// overflowed to inf and, with forgetting, stayed inf, so solve() failed for the rest of the run.
TEST(PerfModel, FitsRefuseAHugeCountAndKeepSolving) {
  OcclusionFits fits(0.98);
  const auto sample = [&](double q) {
    const double l = std::log1p(q);
    return fits.add(q, 5000 - 300 * l + q, 801 - 60 * l, 2e6 + 40 * q - 1.5e5 * l);
  };
  for (int rep = 0; rep < 5; ++rep)
    for (double q : {0.0, 1.0, 3.0, 7.0, 15.0, 31.0, 63.0}) ASSERT_TRUE(sample(q));
  OcclusionCoefficients before;
  ASSERT_TRUE(fits.solve(before));
  EXPECT_FALSE(fits.add(1e200, 1e200, 1.0, 1e200));
  EXPECT_FALSE(fits.add(1e160, 10.0, 1.0, 10.0));
  for (double q : {0.0, 1.0, 3.0, 7.0}) ASSERT_TRUE(sample(q));
  OcclusionCoefficients k;
  ASSERT_TRUE(fits.solve(k));
  EXPECT_NEAR(k.e1, 1.5e5, 1.0);
  EXPECT_NEAR(k.p, 40.0, 1e-3);
  EXPECT_NEAR(k.cB, 300.0, 1e-3);
}

// ---- octree ----------------------------------------------------------------------------------

using ig::lod::test::cube;
using ig::lod::test::wideCamera;

bool containedIn(const Aabb& outer, const Aabb& b) {
  return b.min.x >= outer.min.x && b.min.y >= outer.min.y && b.min.z >= outer.min.z && b.max.x <= outer.max.x &&
         b.max.y <= outer.max.y && b.max.z <= outer.max.z;
}

TEST(DynamicOctree, SingleReferenceUnderInsertMoveRemove) {
  DynamicOctree t;
  OctreeConfig c;
  c.bounds = cube(glm::dvec3(0.0), 128.0);
  c.maxDepth = 6;
  c.maxObjects = 5000;
  ASSERT_TRUE(t.init(c));
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0), u01(0.0, 1.0);
  for (uint32_t i = 0; i < 4000; ++i) ASSERT_TRUE(t.insert(i, cube({120 * u(rng), 120 * u(rng), 120 * u(rng)}, 0.1 + 3 * u01(rng))));
  EXPECT_FALSE(t.insert(3, cube({0, 0, 0}, 1)));      // already present
  EXPECT_FALSE(t.insert(6000, cube({0, 0, 0}, 1)));   // out of range
  EXPECT_FALSE(t.insert(4001, {{0, 0, 0}, {std::nan(""), 1, 1}}));
  EXPECT_FALSE(t.insert(4001, {{1, 1, 1}, {0, 0, 0}}));  // inverted
  ASSERT_TRUE(t.insert(4001, cube({1e6, 0, 0}, 1)));       // outside the root: stays in the root
  EXPECT_EQ(t.nodeOf(4001), 0u);
  t.refresh();
  t.clearDirty();
  for (int step = 0; step < 3000; ++step) {
    const auto id = static_cast<uint32_t>(rng() % 4000);
    if (!t.contains(id)) continue;
    if (step % 10 == 0) {
      const uint32_t n = t.nodeOf(id);
      ASSERT_TRUE(t.remove(id));
      ASSERT_EQ(t.dirtyNodes().size(), 1u);
      EXPECT_EQ(t.dirtyNodes()[0], n);
      t.refresh();
      t.clearDirty();
      continue;
    }
    const uint32_t before = t.nodeOf(id);
    const Aabb b = step % 2 ? cube({120 * u(rng), 120 * u(rng), 120 * u(rng)}, 0.5) : t.boxOf(id);
    ASSERT_TRUE(t.move(id, b));
    const uint32_t after = t.nodeOf(id);
    // Only the old and the new node are dirty.
    const auto dirty = t.dirtyNodes();
    EXPECT_LE(dirty.size(), 2u);
    for (uint32_t n : dirty) EXPECT_TRUE(n == before || n == after);
    EXPECT_EQ(dirty.size(), before == after ? 1u : 2u);
    t.refresh();
    t.clearDirty();
  }
  EXPECT_TRUE(t.checkInvariant());
  EXPECT_FALSE(t.move(4001, {{0, 0, 0}, {std::nan(""), 0, 0}}));
  // Every object lies inside its node's cell (the root excepted), and in the deepest such cell
  // its box fits into: no child of its node contains the box whole.
  for (uint32_t id = 0; id < 4000; ++id) {
    if (!t.contains(id)) continue;
    const auto& node = t.node(t.nodeOf(id));
    if (t.nodeOf(id) != 0) {
      EXPECT_TRUE(containedIn(node.cell, t.boxOf(id)));
    }
    for (uint32_t ch : node.children) {
      if (ch != DynamicOctree::kNone) {
        EXPECT_FALSE(containedIn(t.node(ch).cell, t.boxOf(id)));
      }
    }
    EXPECT_TRUE(containedIn(node.bounds, t.boxOf(id)));  // subtree bounds cover the object
  }
  // And they are tight: every node's bounds are the box of the objects below it, from scratch.
  std::vector<Aabb> tight(t.nodes().size(), Aabb{glm::dvec3(std::numeric_limits<double>::infinity()),
                                                  glm::dvec3(-std::numeric_limits<double>::infinity())});
  for (uint32_t id = 0; id <= 4001; ++id) {
    if (!t.contains(id)) continue;
    for (uint32_t n = t.nodeOf(id); n != DynamicOctree::kNone; n = t.node(n).parent) {
      tight[n].min = glm::min(tight[n].min, t.boxOf(id).min);
      tight[n].max = glm::max(tight[n].max, t.boxOf(id).max);
    }
  }
  size_t loose = 0;
  for (size_t n = 0; n < tight.size(); ++n) {
    if (t.node(static_cast<uint32_t>(n)).subtreeCount == 0) continue;
    if (t.node(static_cast<uint32_t>(n)).bounds.min != tight[n].min || t.node(static_cast<uint32_t>(n)).bounds.max != tight[n].max) ++loose;
  }
  EXPECT_EQ(loose, 0u) << "nodes whose bounds are not the box of their objects";
}

// The occlusion tests' octree: 128 m cube, 5 levels, up to 2,000 objects.
OctreeConfig occlusionTestConfig(uint32_t maxAge) { return ig::lod::test::octreeConfig(5, maxAge); }

TEST(DynamicOctree, ExpensiveNodesAndTheHiddenEstimate) {
  DynamicOctree t;
  const OctreeConfig c = occlusionTestConfig(4);
  ASSERT_TRUE(t.init(c));
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  uint32_t id = 0;
  // Scattered boxes in front of the camera (+y), and a dense cluster of 500 in one leaf.
  for (; id < 300; ++id) t.insert(id, cube({60 * u(rng), 20 + 100 * std::abs(u(rng)), 40 * u(rng)}, 0.2));
  for (; id < 800; ++id) t.insert(id, cube({33 + 0.5 * u(rng), 97 + 0.5 * u(rng), 1 + 0.5 * u(rng)}, 0.05));
  t.refresh();
  const uint32_t cluster = t.nodeOf(500);
  EXPECT_TRUE(t.node(cluster).expensive);
  for (uint32_t a = cluster; a != DynamicOctree::kNone; a = t.node(a).parent) EXPECT_TRUE(t.node(a).expensive);
  EXPECT_FALSE(t.node(t.nodeOf(0)).expensive);

  const Camera cam = wideCamera();
  const Frustum f = makeFrustum(cam);
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.frame = 10;
  auto r = t.traverse(f, tr, draw, test);
  const uint64_t inView = r.objectsDrawn;
  EXPECT_GT(inView, 700u);
  EXPECT_EQ(r.hiddenObjects, 0u);
  ASSERT_GT(r.candidates, 0u);
  // Expensive nodes come first in the test list, top-down.
  EXPECT_TRUE(t.node(test[0]).expensive);
  bool sawCheap = false;
  for (uint32_t i = 0; i < r.candidates; ++i) {
    if (!t.node(test[i]).expensive) {
      sawCheap = true;
    } else {
      EXPECT_FALSE(sawCheap) << "expensive node after a cheap one";
    }
  }
  // The cluster's node is found hidden: estimate only (octree mode) keeps drawing it.
  t.setQueryPending(cluster, true);
  t.setOcclusionResult(cluster, false, 9);
  EXPECT_FALSE(t.node(cluster).queryPending);
  r = t.traverse(f, tr, draw, test);
  EXPECT_EQ(r.hiddenObjects, t.node(cluster).subtreeCount);
  bool drawn = false;
  for (uint32_t i = 0; i < r.drawn; ++i) drawn = drawn || draw[i] == cluster;
  EXPECT_TRUE(drawn);
  // With occlusion culling it is skipped, and re-tested first.
  tr.useOcclusion = true;
  r = t.traverse(f, tr, draw, test);
  drawn = false;
  for (uint32_t i = 0; i < r.drawn; ++i) drawn = drawn || draw[i] == cluster;
  EXPECT_FALSE(drawn);
  EXPECT_EQ(r.hiddenObjects, t.node(cluster).subtreeCount);
  // ... first of all candidates: a q that covers the re-tests keeps every hidden node culled.
  EXPECT_EQ(r.retests, 1u);
  EXPECT_EQ(test[0], cluster);
  EXPECT_GT(r.candidates, r.retests);
  EXPECT_EQ(r.objectsDrawn + r.hiddenObjects, inView);
  // An older result does not override a newer one; a stale one is ignored.
  t.setOcclusionResult(cluster, true, 5);
  EXPECT_TRUE(t.node(cluster).occluded);
  tr.frame = 9 + c.occlusionMaxAge + 1;
  r = t.traverse(f, tr, draw, test);
  EXPECT_EQ(r.hiddenObjects, 0u);
  EXPECT_EQ(r.objectsDrawn, inView);
  // The camera inside a node's box: that node is not a test candidate.
  Camera inside = cam;
  inside.eye_m = t.node(cluster).bounds.min + glm::dvec3(0.01);
  tr.eye_m = inside.eye_m;
  r = t.traverse(makeFrustum(inside), tr, draw, test);
  for (uint32_t i = 0; i < r.candidates; ++i) EXPECT_NE(test[i], cluster);
}

// A fresh "visible" result keeps a node out of the tests (its children are tested instead)
// until it is stale. A new occluder makes every visible result stale at once: the nodes it may
// hide are tested in the next frame, not resultMaxAge frames later.
TEST(DynamicOctree, ANewOccluderExpiresVisibleResultsButNotHiddenOnes) {
  DynamicOctree t;
  const OctreeConfig c = occlusionTestConfig(8);
  ASSERT_TRUE(t.init(c));
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  uint32_t id = 0;
  for (; id < 400; ++id) t.insert(id, cube({60 * u(rng), 20 + 100 * std::abs(u(rng)), 40 * u(rng)}, 0.2));
  t.refresh();
  const Camera cam = wideCamera();
  const Frustum f = makeFrustum(cam);
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.frame = 10;
  tr.useOcclusion = true;
  auto r = t.traverse(f, tr, draw, test);
  ASSERT_GT(r.candidates, 2u);
  const std::vector<uint32_t> first(test.begin(), test.begin() + r.candidates);
  // Every candidate comes back: the first one hidden, the others visible.
  for (uint32_t n : first) t.setOcclusionResult(n, n != first[0], 10);
  const uint32_t hidden = first[0], visible = first[1];
  tr.frame = 11;
  r = t.traverse(f, tr, draw, test);
  const auto isCandidate = [&](uint32_t n) { return std::find(test.begin(), test.begin() + r.candidates, n) != test.begin() + r.candidates; };
  EXPECT_TRUE(isCandidate(hidden));    // hidden nodes are re-tested every frame
  EXPECT_FALSE(isCandidate(visible));  // a fresh visible result is not
  const uint64_t hiddenBefore = r.hiddenObjects;
  EXPECT_GT(hiddenBefore, 0u);
  // A test of `visible` is in flight when an occluder appears in frame 12.
  t.setQueryPending(visible, true);
  t.expireVisibleResults(12);
  t.setOcclusionResult(visible, true, 11);  // measured without the occluder: ignored
  EXPECT_FALSE(t.node(visible).queryPending);
  tr.frame = 12;
  r = t.traverse(f, tr, draw, test);
  EXPECT_TRUE(isCandidate(visible));  // stale now: tested again at once
  EXPECT_TRUE(isCandidate(hidden));
  EXPECT_EQ(r.hiddenObjects, hiddenBefore);  // hidden results stay
  // Results of tests issued from frame 12 on count again.
  t.setOcclusionResult(visible, true, 12);
  tr.frame = 13;
  r = t.traverse(f, tr, draw, test);
  EXPECT_FALSE(isCandidate(visible));
  t.setOcclusionResult(visible, false, 13);
  EXPECT_TRUE(t.node(visible).occluded);
}

// A "hidden" result holds for the box its query was drawn on: an object moved (or added) into the
// node that reaches outside that box is not skipped with it; the node is tested again instead.
TEST(DynamicOctree, AHiddenResultDoesNotHideAnObjectMovedOutsideTheTestedBox) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(occlusionTestConfig(8)));
  for (uint32_t id = 0; id < 20; ++id) ASSERT_TRUE(t.insert(id, cube({33.0 + 0.1 * id, 97.0, 1.0}, 0.05)));
  ASSERT_TRUE(t.insert(20, cube({-40.0, 60.0, 0.0}, 0.5)));  // elsewhere
  t.refresh();
  const uint32_t node = t.nodeOf(0);
  const Camera cam = wideCamera();
  const Frustum f = makeFrustum(cam);
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.frame = 10;
  tr.useOcclusion = true;
  t.setQueryPending(node, true);
  t.setOcclusionResult(node, false, 10);
  const auto drawn = [&](const DynamicOctree::TraversalResult& r, uint32_t n) {
    return std::find(draw.begin(), draw.begin() + r.drawn, n) != draw.begin() + r.drawn;
  };
  tr.frame = 11;
  auto r = t.traverse(f, tr, draw, test);
  EXPECT_FALSE(drawn(r, node));  // hidden
  // Object 20 moves into the node's cell, outside the box that was tested.
  ASSERT_TRUE(t.move(20, cube({35.5, 98.0, 2.0}, 0.2)));
  ASSERT_EQ(t.nodeOf(20), node);
  t.refresh();
  r = t.traverse(f, tr, draw, test);
  EXPECT_TRUE(drawn(r, node));
  EXPECT_EQ(r.hiddenObjects, 0u);
  EXPECT_NE(std::find(test.begin(), test.begin() + r.candidates, node), test.begin() + r.candidates);  // tested again
  // A test of the new box that says hidden holds again; one of a box the node has outgrown since
  // (its query in flight while the object moved in) does not.
  t.setQueryPending(node, true);
  t.setOcclusionResult(node, false, 11);
  tr.frame = 12;
  r = t.traverse(f, tr, draw, test);
  EXPECT_FALSE(drawn(r, node));
  t.setQueryPending(node, true);
  ASSERT_TRUE(t.move(20, cube({34.0, 99.5, 3.0}, 0.2)));
  t.refresh();
  t.setOcclusionResult(node, false, 12);
  tr.frame = 13;
  r = t.traverse(f, tr, draw, test);
  EXPECT_TRUE(drawn(r, node));
  // Moving out of the node (its box shrinks): the hidden result still holds.
  t.setQueryPending(node, true);
  t.setOcclusionResult(node, false, 13);
  ASSERT_TRUE(t.move(20, cube({-40.0, 60.0, 0.0}, 0.5)));
  t.refresh();
  tr.frame = 14;
  r = t.traverse(f, tr, draw, test);
  EXPECT_FALSE(drawn(r, node));
}

// A new occluder makes "visible" results of earlier tests stale, but a "visible" result is still
// newer than an older "hidden" one: the node is no longer skipped on the old result (it was seen
// after it), it is tested again.
TEST(DynamicOctree, AVisibleResultFromBeforeANewOccluderStillEndsAnOlderHiddenOne) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(occlusionTestConfig(8)));
  for (uint32_t id = 0; id < 20; ++id) ASSERT_TRUE(t.insert(id, cube({33.0 + 0.1 * id, 97.0, 1.0}, 0.05)));
  t.refresh();
  const uint32_t node = t.nodeOf(0);
  const Frustum f = makeFrustum(wideCamera());
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.useOcclusion = true;
  t.setQueryPending(node, true);
  t.setOcclusionResult(node, false, 5);  // hidden in frame 5
  t.setQueryPending(node, true);          // re-tested in frame 6 ...
  t.expireVisibleResults(7);              // ... a large object appears before frame 7 ...
  t.setOcclusionResult(node, true, 6);    // ... and the frame-6 test says visible
  tr.frame = 7;
  const auto r = t.traverse(f, tr, draw, test);
  EXPECT_NE(std::find(draw.begin(), draw.begin() + r.drawn, node), draw.begin() + r.drawn)
      << "skipped on the frame-5 result although the frame-6 test saw it";
  EXPECT_NE(std::find(test.begin(), test.begin() + r.candidates, node), test.begin() + r.candidates);
}

// The estimate of hidden objects counts what culling would skip: the objects of a hidden node's
// subtree that the frustum would draw, not those of its octants outside the view (the octree
// mode does not draw them anyway). Here one depth-1 node holds 20 boxes in view and 40 far to
// the side, out of the view; 100 more boxes elsewhere in view stay visible.
TEST(DynamicOctree, TheHiddenEstimateCountsOnlyObjectsTheFrustumWouldDraw) {
  DynamicOctree t;
  ASSERT_TRUE(t.init(occlusionTestConfig(8)));
  uint32_t id = 0;
  for (; id < 20; ++id) ASSERT_TRUE(t.insert(id, cube({20.0 + 0.1 * id, 60.0, 5.0}, 0.05)));
  for (; id < 60; ++id) ASSERT_TRUE(t.insert(id, cube({120.0, 5.0 + 0.1 * id, 5.0}, 0.05)));  // ~85 deg right
  for (; id < 160; ++id) ASSERT_TRUE(t.insert(id, cube({-20.0 - 0.1 * (id - 60), 60.0, -5.0}, 0.05)));
  t.refresh();
  uint32_t node = t.nodeOf(0);
  while (t.node(node).depth > 1) node = t.node(node).parent;
  ASSERT_EQ(t.node(node).subtreeCount, 60u);  // both groups of the +x+y+z octant
  const Frustum f = makeFrustum(wideCamera());
  std::vector<uint32_t> draw(t.nodes().size()), test(t.nodes().size());
  DynamicOctree::Traversal tr;
  tr.frame = 10;
  const auto clear = t.traverse(f, tr, draw, test);
  ASSERT_EQ(clear.objectsDrawn, 120u);  // the 40 to the side are frustum-culled
  t.setQueryPending(node, true);
  t.setOcclusionResult(node, false, 10);
  // Estimate only (octree mode): 20 of the 120 drawn objects would be skipped.
  auto r = t.traverse(f, tr, draw, test);
  EXPECT_EQ(r.objectsDrawn, 120u);
  EXPECT_EQ(r.hiddenObjects, 20u);
  // Occlusion culling skips them: drawn + hidden = what the frustum alone draws.
  tr.useOcclusion = true;
  r = t.traverse(f, tr, draw, test);
  EXPECT_EQ(r.objectsDrawn, 100u);
  EXPECT_EQ(r.hiddenObjects, 20u);
  EXPECT_EQ(r.objectsDrawn + r.hiddenObjects, clear.objectsDrawn);
}

TEST(DynamicOctree, RejectsBadConfig) {
  DynamicOctree t;
  OctreeConfig c;
  c.bounds = {{0, 0, 0}, {0, 1, 1}};
  EXPECT_FALSE(t.init(c));
  c.bounds = {{0, 0, 0}, {1, std::nan(""), 1}};
  EXPECT_FALSE(t.init(c));
  c.bounds = cube({0, 0, 0}, 1);
  c.maxDepth = 40;
  EXPECT_FALSE(t.init(c));
  c.maxDepth = 4;
  c.maxObjects = 0;
  EXPECT_FALSE(t.init(c));
  // Empty tree: traversal is empty.
  c.maxObjects = 10;
  ASSERT_TRUE(t.init(c));
  std::vector<uint32_t> d(4), q(4);
  const auto r = t.traverse(makeFrustum(Camera{}), {}, d, q);
  EXPECT_EQ(r.drawn, 0u);
  EXPECT_EQ(r.candidates, 0u);
}

}  // namespace

// Huge coordinates (ECEF-like, ~1e7 m: a float's step there is 1 m) and the camera inside a node:
// the same scene shifted by a whole number of 4,096 m (exact in double) puts every object in the
// same node and the same relative view draws the same nodes with the same objects, inside and
// outside the boxes.
TEST(DynamicOctree, HugeCoordinatesPlaceAndCullAsAtTheOrigin) {
  const glm::dvec3 shift(2441.0 * 4096.0, -1220.0 * 4096.0, 1196.0 * 4096.0);  // ~(1e7, -5e6, 4.9e6)
  DynamicOctree a, b;
  OctreeConfig ca = occlusionTestConfig(4), cb = ca;
  cb.bounds = {ca.bounds.min + shift, ca.bounds.max + shift};
  ASSERT_TRUE(a.init(ca));
  ASSERT_TRUE(b.init(cb));
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (uint32_t id = 0; id < 1500; ++id) {
    // Centres on a 1/64 m grid: exact in double after the shift, so both trees see the same boxes.
    const glm::dvec3 c = glm::round(glm::dvec3(120 * u(rng), 120 * u(rng), 120 * u(rng)) * 64.0) / 64.0;
    const double h = std::ldexp(1.0, -static_cast<int>(rng() % 6));
    ASSERT_TRUE(a.insert(id, cube(c, h)));
    ASSERT_TRUE(b.insert(id, cube(c + shift, h)));
  }
  a.refresh();
  b.refresh();
  ASSERT_EQ(a.nodes().size(), b.nodes().size());
  for (uint32_t id = 0; id < 1500; ++id) ASSERT_EQ(a.nodeOf(id), b.nodeOf(id)) << id;
  std::vector<uint32_t> drawA(a.nodes().size()), drawB(b.nodes().size()), testA(a.nodes().size()),
      testB(b.nodes().size());
  // Eyes outside the root, inside the root, inside a leaf's box (object 0's), looking around.
  const glm::dvec3 eyes[] = {{0, -200, 0}, {0.3, 0.7, -0.2}, glm::dvec3(a.boxOf(0).min) + glm::dvec3(0.01)};
  uint64_t totalDrawn = 0;
  for (const glm::dvec3& eye : eyes) {
    for (double heading = 0.0; heading < 360.0; heading += 45.0) {
      Camera cam = wideCamera();
      cam.eye_m = eye;
      cam.heading_deg = heading;
      cam.pitch_deg = 10.0;
      DynamicOctree::Traversal ta, tb;
      ta.frame = tb.frame = 3;
      ta.eye_m = eye;
      tb.eye_m = eye + shift;
      // The frustum is eye-relative: the same for both.
      const Frustum f = makeFrustum(cam);
      const auto ra = a.traverse(f, ta, drawA, testA);
      const auto rb = b.traverse(f, tb, drawB, testB);
      totalDrawn += ra.drawn;
      EXPECT_EQ(ra.drawn, rb.drawn) << heading;
      EXPECT_EQ(ra.objectsDrawn, rb.objectsDrawn) << heading;
      EXPECT_EQ(ra.candidates, rb.candidates) << heading;
      EXPECT_TRUE(std::equal(drawA.begin(), drawA.begin() + ra.drawn, drawB.begin())) << heading;
      EXPECT_TRUE(std::equal(testA.begin(), testA.begin() + ra.candidates, testB.begin())) << heading;
    }
  }
  EXPECT_GT(totalDrawn, 100u);
}
