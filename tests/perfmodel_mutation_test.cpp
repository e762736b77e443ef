// Performance model of paper 002 (lod/perfmodel.h), from a mutation-testing pass over
// lod/perfmodel.cpp: each test pins one documented detail that perfmodel_test.cpp leaves open (a
// mutant of it passed every test there). Hand-made numbers, brute force for q*:
//   - memory model (1): a product that just fits is exact, one more byte saturates;
//   - valid(): every constant >= 0 (T_z included), T_frag > 0;
//   - t_c: one constant when commandLargeCount is not above commandCount or commandLarge_ns is
//     not measured;
//   - time model (2): each set's T_buf with its own occlusion tests, re-recorded objects and
//     t_c(its commands), its own T_tri by its submissions, its own rasterShare;
//   - the overlap is that of the whole frame (objects and hierarchy), w for a frame of no
//     triangles, and a frame time is never negative, whatever the overlap;
//   - projected area on a viewport that is not square (x by width, clipped to width);
//   - switching (5)/(6): strict inequalities at the hysteresis bounds, T_fc on both sides of (5),
//     T_vis(H) in (6), the hysteresis of Octree -> Occlusion;
//   - q*: tq_ns = 0 is a free test (only < 0 means t_c), NaN for a denominator 0, T(n0) compared
//     where the fitted T(q) is not convex;
//   - fits: a count of exactly 1e12 is taken.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "lod/perfmodel.h"
#include "lod/view.h"
#include "perfmodel_fixtures.h"

using namespace ig::lod;
using ig::lod::test::handConstants;

namespace {

constexpr uint64_t kMax = std::numeric_limits<uint64_t>::max();

// (1) saturates at UINT64_MAX instead of wrapping: a product that still fits is exact.
TEST(PerfModel, MemoryModelIsExactUpToTheLastProductThatFits) {
  MemoryModelInput in;
  in.vertices = kMax / 12;  // 12 bytes each: kMax - 3
  EXPECT_EQ(sceneMemoryBytes(in), kMax - 3);
  in.vertices = kMax / 12 + 1;
  EXPECT_EQ(sceneMemoryBytes(in), kMax);
}

// "True if every constant is finite and >= 0 ... and T_tri, T_frag are > 0."
TEST(PerfModel, ValidRefusesEveryNegativeConstantAndAnUnmeasuredTfrag) {
  const PerfConstants c = handConstants();
  ASSERT_TRUE(valid(c));
  PerfConstants noFrag = c;
  noFrag.frag_ns = 0.0;
  EXPECT_FALSE(valid(noFrag));
  for (double PerfConstants::*m :
       {&PerfConstants::frame_ns, &PerfConstants::tri_ns, &PerfConstants::frag_ns, &PerfConstants::rasterTri_ns,
        &PerfConstants::edge_ns, &PerfConstants::drawRaster_ns, &PerfConstants::depthFrag_ns, &PerfConstants::state_ns,
        &PerfConstants::command_ns, &PerfConstants::commandCount, &PerfConstants::commandLarge_ns,
        &PerfConstants::commandLargeCount, &PerfConstants::rerecord_ns, &PerfConstants::submit_ns,
        &PerfConstants::cull_ns, &PerfConstants::occlusionTest_ns, &PerfConstants::overlapTriangles}) {
    PerfConstants bad = c;
    bad.*m = -1.0;
    EXPECT_FALSE(valid(bad)) << "a constant at -1 ns accepted";
  }
}

// "commandLargeCount <= commandCount: t_c is one constant"; "command_ns when the two are not
// measured".
TEST(PerfModel, CommandCostIsOneConstantUnlessBothLargeValuesAreMeasured) {
  PerfConstants c = handConstants();  // t_c 1,000
  c.commandCount = 1000;
  c.commandLargeCount = 1000;  // equal: not above commandCount
  c.commandLarge_ns = 3000;
  EXPECT_DOUBLE_EQ(commandCost_ns(c, 5000), 1000);
  EXPECT_DOUBLE_EQ(commandCost_ns(c, 1e6), 1000);
  c.commandLargeCount = 100000;
  c.commandLarge_ns = 0.0;  // not measured
  EXPECT_DOUBLE_EQ(commandCost_ns(c, 10000), 1000);
  EXPECT_DOUBLE_EQ(commandCost_ns(c, 1e6), 1000);
}

// T_buf = commands t_c(commands) + rerecorded t_r + submissions t_s + occlusionTests T_vis for
// each set, T_vert with T_tri by that set's triangles per submission, T_frag with its own
// rasterShare.
TEST(PerfModel, EachSetIsChargedItsOwnTerms) {
  PerfConstants c = handConstants();
  c.commandCount = 1000;  // t_c 1,000 up to 1,000 commands, 3,000 from 100,000 on: 2,000 at 10,000
  c.commandLarge_ns = 3000;
  c.commandLargeCount = 100000;
  c.triByDraw_ns = {80, 60, 50, 40, 30, 20, 10};
  c.rasterTri_ns = 5;
  ASSERT_TRUE(valid(c));
  PassLoad s, h;
  s.commands = 10;         // 10 x 1,000
  s.submissions = 1;       // 500; 1,200 triangles in one call: T_tri 10
  s.triangles = 1200;
  s.occlusionTests = 2;    // 6,000
  h.commands = 10000;      // 10,000 x 2,000
  h.rerecorded = 10;       // 500
  h.submissions = 100;     // 50,000; 12 triangles per call: T_tri 80
  h.triangles = 1200;
  h.rasterShare = 0.5;     // half of 1,200 x 5
  TimeBreakdown b;
  predictFrame_ns(c, s, h, &b);
  EXPECT_DOUBLE_EQ(b.bufS, 10000 + 500 + 6000);
  EXPECT_NEAR(b.bufH, 10000 * 2000.0 + 500 + 50000, 1e-4);
  EXPECT_DOUBLE_EQ(b.vertS, 1200 * 10.0);
  EXPECT_DOUBLE_EQ(b.vertH, 1200 * 80.0);
  EXPECT_DOUBLE_EQ(b.fragS, 1200 * 5.0);
  EXPECT_DOUBLE_EQ(b.fragH, 0.5 * 1200 * 5.0);
}

// The overlap is that of the frame: its triangles are those of the objects and the hierarchy.
TEST(PerfModel, TheOverlapCountsEveryTriangleOfTheFrame) {
  PerfConstants c = handConstants();
  c.overlap = 0.8;
  c.overlapTriangles = 100000;
  PassLoad s, h;
  s.triangles = 50000;   // vert 5e5 (below overlapTriangles on its own)
  s.fragments = 2e6;     // frag 2e6
  h.triangles = 350000;  // vert 3.5e6; the frame's 400,000: w = 0.8 * 0.75 = 0.6
  TimeBreakdown b;
  const double t = predictFrame_ns(c, s, h, &b);
  EXPECT_NEAR(b.gpuS, 2e6 + 0.4 * 5e5, 1e-6);
  EXPECT_NEAR(b.gpuH, 3.5e6, 1e-6);
  EXPECT_NEAR(t, 10000 + 2e6 + 0.4 * 5e5 + 3.5e6, 1e-6);
}

// "overlap when overlapTriangles is 0", also for a frame without triangles.
TEST(PerfModel, WithoutAThresholdTheOverlapIsWEvenForAFrameWithoutTriangles) {
  PerfConstants c = handConstants();
  c.overlap = 0.8;
  EXPECT_DOUBLE_EQ(stageOverlap(c, 0.0), 0.8);
  PassLoad s;
  s.stateChanges = 100;  // state 10,000
  s.fragments = 5000;    // frag 5,000
  TimeBreakdown b;
  predictFrame_ns(c, s, {}, &b);
  EXPECT_NEAR(b.gpuS, 10000 + 0.2 * 5000, 1e-9);
}

// "the return value is always finite and >= 0": also for an overlap outside [0, 1] (constants
// that valid() refuses).
TEST(PerfModel, AFrameTimeIsNeverNegativeWhateverTheOverlap) {
  PerfConstants c = handConstants();
  c.frame_ns = 0.0;
  c.overlap = 5.0;
  EXPECT_FALSE(valid(c));
  PassLoad h;
  h.stateChanges = 10;     // 1,000
  h.triangles = 100;       // 1,000
  h.fragments = 1000;      // 1,000
  h.depthFragments = 2000; // 1,000
  const double t = predictFrame_ns(c, {}, h);
  EXPECT_TRUE(std::isfinite(t)) << t;
  EXPECT_GE(t, 0.0);
}

// x by the viewport's width, clipped to it: a 400 x 200 viewport at 10 px per metre both ways.
TEST(PerfModel, ProjectedBoxAreaOnAViewportThatIsNotSquare) {
  Camera cam;
  cam.fovY_deg = 90.0;
  cam.aspect = 2.0;
  cam.near_m = 0.1;
  cam.far_m = 1000.0;
  const glm::dmat4 vp = projection(cam) * glm::dmat4(viewRotation(cam));
  const auto box = test::boxCorners;
  EXPECT_NEAR(projectedBoxArea_px(vp, box({0, 10, 0}, {1, 0.001, 1}), 400, 200), 400.0, 4.0);
  EXPECT_NEAR(projectedBoxArea_px(vp, box({15, 10, 0}, {1, 0.001, 1}), 400, 200), 400.0, 4.0);  // right half
  EXPECT_NEAR(projectedBoxArea_px(vp, box({0, 10, 0}, {50, 0.001, 50}), 400, 200), 80000.0, 1e-6);  // clipped
}

ModeInputs five(double bufS, double fcS, double bufH, double fcH) {
  ModeInputs in;
  in.bufS_ns = bufS;
  in.fcS_ns = fcS;
  in.bufH_ns = bufH;
  in.fcH_ns = fcH;
  return in;
}

ModeInputs six(double all, double visible, double tests) {
  ModeInputs in = five(1000, 0, 1000, 0);  // (5) neither holds clearly nor fails
  in.frameAll_ns = all;
  in.frameVisible_ns = visible;
  in.visTests_ns = tests;
  return in;
}

// h = 0.5 and no minimum frames: the bounds are exact in binary.
constexpr ModeSwitchConfig kHalf{0.5, 0};

// (5) fails when bufS + fcS > (bufH + fcH)(1 + h): strictly, with both culling terms.
TEST(PerfModel, Condition5ComparesBufferAndCullingOnBothSidesStrictly) {
  ModeSwitcher atBound(kHalf);
  EXPECT_EQ(atBound.update(five(1500, 0, 1000, 0)), DynamicMode::PerCommand);
  EXPECT_EQ(atBound.update(five(1501, 0, 1000, 0)), DynamicMode::Octree);
  ModeSwitcher objectCulling(kHalf);  // 1,000 + 600 > 1,000 * 1.5
  EXPECT_EQ(objectCulling.update(five(1000, 600, 1000, 0)), DynamicMode::Octree);
  ModeSwitcher nodeCulling(kHalf);  // 1,600 < (1,000 + 100) * 1.5
  EXPECT_EQ(nodeCulling.update(five(1600, 0, 1000, 100)), DynamicMode::PerCommand);
}

// Octree -> Occlusion when (6) fails: T(S) > (T(S_vis) + T_vis(H))(1 + h), strictly, with the
// tests' time, not inside the hysteresis.
TEST(PerfModel, Condition6CountsTheTestsAndKeepsItsHysteresis) {
  ModeSwitcher m(kHalf, DynamicMode::Octree);
  EXPECT_EQ(m.update(six(1400, 1000, 0)), DynamicMode::Octree);  // fails by less than h
  EXPECT_EQ(m.update(six(1500, 1000, 0)), DynamicMode::Octree);  // at the bound
  EXPECT_EQ(m.update(six(1600, 1000, 100)), DynamicMode::Octree);  // 1,600 < 1,100 * 1.5
  EXPECT_EQ(m.update(six(1501, 1000, 0)), DynamicMode::Occlusion);
  EXPECT_EQ(m.switches(), 1u);
}

// "tq_ns < 0 means same as tc_ns": 0 is a test that costs nothing.
TEST(PerfModel, AFreeOcclusionTestIsNotChargedTc) {
  OcclusionCoefficients k;
  k.cA = 100;
  k.cB = 10;
  k.sA = 11;
  k.s1 = 2;
  k.e0 = 1000;
  k.p = 1;
  k.e1 = 50;
  const OcclusionCosts t{100.0, 400.0, 2.0, 0.0};
  const double l = std::log1p(3.0);
  EXPECT_NEAR(occlusionFrame_ns(k, t, 3.0), (100 - 10 * l) * 100 + 3 * 0.0 + (11 - 2 * l) * 400 + (1000 + 3 - 50 * l) * 2,
              1e-9);
  // (10 t_c + 2 t_s + 50 t_e) / (p t_e + 0) - 1.
  EXPECT_DOUBLE_EQ(stationaryQ(k, t), (10.0 * 100 + 2.0 * 400 + 50.0 * 2) / (1.0 * 2) - 1.0);
}

// "NaN when the denominator p t_e + t_c is not > 0"; then T(0) and T(n0) decide: with no cost
// per test, more tests only save.
TEST(PerfModel, ADenominatorOfZeroGivesNoStationaryPointAndTheEndsDecide) {
  OcclusionCoefficients k;
  k.cA = 1000;
  k.cB = 10;
  k.sA = 101;
  k.s1 = 5;
  const OcclusionCosts t{100.0, 400.0, 2.0, 0.0};  // p = 0, tq = 0
  EXPECT_TRUE(std::isnan(stationaryQ(k, t)));
  k.p = -1.0;  // below 0
  EXPECT_TRUE(std::isnan(stationaryQ(k, t)));
  k.p = 0.0;
  double tn = 0;
  EXPECT_EQ(optimalQ(k, t, 500, &tn), 500u);
  EXPECT_DOUBLE_EQ(tn, occlusionFrame_ns(k, t, 500.0));
}

// Fitted coefficients can have any sign: T(q) is then not convex (q* may be a maximum) or falls
// all the way (p t_e + t_q < 0). The integer minimum over [0, n0] still comes out (brute force).
TEST(PerfModel, OptimalQMatchesBruteForceForFitsOfAnySign) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int atN0 = 0;
  for (int trial = 0; trial < 300; ++trial) {
    OcclusionCoefficients k;
    const uint32_t n0 = 1 + static_cast<uint32_t>((u(rng) + 1.0) * 1000);
    k.cA = 1e4 * u(rng);
    k.cB = 20 * u(rng);
    k.sA = n0 + 1.0;
    k.s1 = 50 * u(rng);
    k.e0 = 1e6 * u(rng);
    k.p = 10 * u(rng);
    k.e1 = 1e5 * u(rng);
    const OcclusionCosts t{1000 + 900 * u(rng), 3000 + 2500 * u(rng), 25 + 24 * u(rng), trial % 3 ? 100 + 100 * u(rng) : -1.0};
    double best = std::numeric_limits<double>::infinity();
    uint32_t bestQ = 0;
    for (uint32_t q = 0; q <= n0; ++q) {
      const double tq = occlusionFrame_ns(k, t, q);
      if (tq < best) best = tq, bestQ = q;
    }
    atN0 += bestQ == n0;
    double tOpt = 0;
    const uint32_t q = optimalQ(k, t, n0, &tOpt);
    EXPECT_LE(q, n0);
    EXPECT_NEAR(tOpt, best, 1e-9 * std::max(1.0, std::abs(best))) << "trial " << trial << " q " << q << " brute " << bestQ;
  }
  EXPECT_GT(atN0, 20);  // minima at the upper end were exercised
}

// "False ... above 1e12": 1e12 itself is a count.
TEST(PerfModel, FitsTakeACountOfExactlyOneE12) {
  OcclusionFits fits;
  EXPECT_TRUE(fits.add(1e12, 1e12, 1.0, 1e12));
  EXPECT_FALSE(fits.add(std::nextafter(1e12, 2e12), 1.0, 1.0, 1.0));
  EXPECT_DOUBLE_EQ(fits.samples(), 1.0);
}

}  // namespace
