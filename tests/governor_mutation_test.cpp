// Frame governor (lod/governor.h), from a mutation-testing pass over lod/governor.cpp: each test
// pins one detail of the documented control law that governor_test.cpp leaves open (a mutant
// of it passed every test there). Noise-free fake costs, so the decisions are exact:
//   - warm-up: a frame above the band is cut in proportion to the middle of the band, then holds;
//   - the bounds of one step (maxDecrease, also of a phase-budget cut) and the holds after a
//     decrease, an emergency or a phase-budget cut; emergencyFrames exactly;
//   - layers at their bound drop out of the solve; a decision that moves nothing is a Hold;
//   - slopes below 0 count as 0, and a quarter of the frame counts as load-dependent;
//   - quantised knobs: rounding towards less detail, the whole step of a coarse knob, the waits
//     of one-quantum raises (4 holds, doubled, at most 64; ended by a much lighter frame);
//   - budget knobs: a raise starts from the knob, a decrease from the load, their predictions;
//   - load trend: the knob's own effect removed, none for a budget knob;
//   - spikes: a load jump is not one, and one leaves the window after spikeWindow_frames;
//   - load caps: their value, kept over an invalid frame and a reload;
//   - bookkeeping: phase overruns, a NaN frame time is not a bad measurement, UnitCost's
//     smallest batch, validate()'s inclusive and exclusive bounds.
// One test found a deviation from governor.h, fixed with it: AnIncreaseThatMovedNothingDoesNotRestartTheRaiseInterval.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "lod/governor.h"

using namespace ig::lod;

namespace {

constexpr size_t kTerrain = static_cast<size_t>(GovLayer::Terrain);
constexpr size_t kForest = static_cast<size_t>(GovLayer::Forest);
constexpr size_t kCells = static_cast<size_t>(GovLayer::Cells);
constexpr size_t kLayers = static_cast<size_t>(GovLayer::ForestLayers);
constexpr size_t kInput = static_cast<size_t>(GovPhase::Input);
constexpr size_t kTerrainPhase = static_cast<size_t>(GovPhase::Terrain);
constexpr size_t kForestPhase = static_cast<size_t>(GovPhase::Forest);
constexpr size_t kSubmit = static_cast<size_t>(GovPhase::Submit);
constexpr size_t kGpu = static_cast<size_t>(GovPhase::Gpu);
constexpr size_t kCellsPhase = static_cast<size_t>(GovPhase::Cells);

GovernorConfig terrainConfig() {
  GovernorConfig c;
  c.rate_hz = 30.0;
  GovKnob& k = c.knobs[kTerrain];
  k.present = true;
  k.initial = 1.0;
  k.min = 1.0;
  k.max = 64.0;
  k.loadExponent = -2.0;
  return c;
}

// A terrain whose phases cost exactly a + b * triangles (no noise): the frame is
// 2.1 ms + 1.05e-4 ms per triangle (100k triangles: 12.6 ms).
struct ExactTerrain {
  double input_ms = 0.3;
  double terrain0_ms = 0.5, terrain1_ms = 2e-5;
  double submit0_ms = 0.3, submit1_ms = 0.5e-5;
  double gpu0_ms = 1.0, gpu1_ms = 8e-5;

  GovSample of(double tris, double extra_ms = 0.0) const {
    GovSample s;
    s.phase_ms[kInput] = input_ms;
    s.phase_ms[kTerrainPhase] = terrain0_ms + terrain1_ms * tris;
    s.phase_ms[kSubmit] = submit0_ms + submit1_ms * tris;
    s.phase_ms[kGpu] = gpu0_ms + gpu1_ms * tris;
    s.load[kTerrain] = tris;
    s.frame_ms = s.phase_ms[kInput] + s.phase_ms[kTerrainPhase] + s.phase_ms[kSubmit] + s.phase_ms[kGpu] + extra_ms;
    return s;
  }
  // The triangles whose frame takes `ms`.
  double trisFor(double ms) const {
    return (ms - input_ms - terrain0_ms - submit0_ms - gpu0_ms) / (terrain1_ms + submit1_ms + gpu1_ms);
  }
  // The scene at the governor's tolerance: triangles = scene * tolerance^-2 (the exponent it is told).
  GovSample frame(const Governor& g, double scene, double extra_ms = 0.0) const {
    return of(scene * std::pow(g.knob(GovLayer::Terrain), -2.0), extra_ms);
  }
};

// The middle of the default dead band (no spike headroom): (decreaseAbove + increaseBelow) / 2 * B.
double bandMiddle(const GovernorConfig& c, const Governor& g) {
  return 0.5 * (c.decreaseAbove + c.increaseBelow) * g.frameBudget_ms();
}

// A forest shell-layer count (ForestLayers: GPU fill, whole numbers) as the only layer.
GovernorConfig layerCountConfig(double initial, double max) {
  GovernorConfig c;
  c.rate_hz = 30.0;
  GovKnob& k = c.knobs[kLayers];
  k.present = true;
  k.initial = initial;
  k.min = 1.0;
  k.max = max;
  k.loadExponent = 1.0;
  k.quantum = 1.0;
  k.loadUnit = 1.0;
  return c;
}

GovSample layerCountFrame(double layers, double base_ms, double perLayer_ms) {
  GovSample s;
  s.phase_ms[kInput] = 0.1;
  s.phase_ms[kSubmit] = 0.3;
  s.phase_ms[kGpu] = base_ms + perLayer_ms * layers;
  s.load[kLayers] = layers;
  return s;  // frame_ms: the sum of the phases
}

// A cells voxel budget (GovKnob::loadBudget) as the only layer.
GovernorConfig budgetConfig(double initial) {
  GovernorConfig c;
  c.rate_hz = 30.0;
  GovKnob& k = c.knobs[kCells];
  k.present = true;
  k.initial = initial;
  k.min = 1e4;
  k.max = 2e6;
  k.loadExponent = 1.0;
  k.loadUnit = 1e5;
  k.loadBudget = true;
  return c;
}

// The cells draw min(demand, budget) voxels; selection and splats linear in them.
GovSample cellsFrame(const Governor& g, double demand, double gpuPerVoxel_ms) {
  const double voxels = std::min(demand, g.knob(GovLayer::Cells));
  GovSample s;
  s.phase_ms[kInput] = 0.1;
  s.phase_ms[kCellsPhase] = 0.2 + 1e-6 * voxels;
  s.phase_ms[kSubmit] = 0.3;
  s.phase_ms[kGpu] = 1.0 + gpuPerVoxel_ms * voxels;
  s.load[kCells] = voxels;
  return s;
}

}  // namespace

// Warm-up (no model yet): a frame above the band's top, within the budget, is cut in proportion
// to the middle of the band, s = clamp(aim / frame_ms, maxDecrease, 1) (the margin is not taken
// off twice), and that decrease holds raises for holdAfterDecrease_frames like any other.
TEST(Governor, WarmupCutsAFrameAboveTheBandInProportionAndThenHolds) {
  const GovernorConfig c = terrainConfig();
  Governor g(c);
  const ExactTerrain w;
  const GovDecision& d = g.update(w.of(w.trisFor(30.0)));
  ASSERT_FALSE(d.overrun);
  ASSERT_GT(30.0, d.bandTop_ms);
  EXPECT_EQ(d.action, GovAction::Decrease);
  const double s = bandMiddle(c, g) / 30.0;  // 25 / 30
  EXPECT_NEAR(d.loadScale, s, 1e-12);
  EXPECT_NEAR(g.knob(GovLayer::Terrain), std::pow(s, -0.5), 1e-12);
  // Light frames after it: no raise during the hold, and one soon after it.
  int firstRaise = -1;
  for (int i = 1; i < c.holdAfterDecrease_frames + c.raiseInterval_frames + 1 && firstRaise < 0; ++i)
    if (g.update(w.of(10e3)).action == GovAction::Increase) firstRaise = i;
  EXPECT_GE(firstRaise, c.holdAfterDecrease_frames);
}

// The deferrable budgets shrink for exactly emergencyFrames frames after an overrun.
TEST(Governor, AnEmergencyShrinksDeferrableWorkForExactlyEmergencyFrames) {
  GovernorConfig c = terrainConfig();
  c.emergencyFrames = 5;
  Governor g(c);
  const ExactTerrain w;
  for (int i = 0; i < 60; ++i) g.update(w.frame(g, 100e3));
  const double full = g.phaseBudget_ms(GovPhase::Terrain);
  ASSERT_DOUBLE_EQ(g.deferrableBudget_ms(GovPhase::Terrain), full);
  ASSERT_EQ(g.update(w.frame(g, 100e3, 40.0)).action, GovAction::Emergency);
  int shrunk = g.deferrableBudget_ms(GovPhase::Terrain) < full ? 1 : 0;  // the frame after the overrun
  for (int i = 0; i < 20; ++i) {
    ASSERT_FALSE(g.update(w.frame(g, 100e3)).overrun);
    shrunk += g.deferrableBudget_ms(GovPhase::Terrain) < full ? 1 : 0;
  }
  EXPECT_EQ(shrunk, c.emergencyFrames);
}

// A regular decrease (P(1) + margin above the band, no overrun) takes at most one maxDecrease
// step, s = clamp(solve(aim), maxDecrease, 1), and holds raises for holdAfterDecrease_frames.
TEST(Governor, ADecreaseIsBoundedByMaxDecreaseAndHoldsRaises) {
  GovernorConfig c = terrainConfig();
  c.maxDecrease = 0.9;
  Governor g(c);
  const ExactTerrain w;
  for (int i = 0; i < 100; ++i) g.update(w.frame(g, 150e3));  // 17.9 ms at 1 px: below the band
  ASSERT_DOUBLE_EQ(g.knob(GovLayer::Terrain), 1.0);
  // The scene grows to a 30 ms frame: above the band, within the budget.
  const GovDecision& d = g.update(w.frame(g, w.trisFor(30.0)));
  ASSERT_FALSE(d.overrun);
  EXPECT_EQ(d.action, GovAction::Decrease);
  EXPECT_DOUBLE_EQ(d.loadScale, c.maxDecrease);  // the model asks for more: one bounded step
  EXPECT_NEAR(g.knob(GovLayer::Terrain), std::pow(c.maxDecrease, -0.5), 1e-12);
  // The scene gets light at once: no raise during the hold, and one soon after it.
  int firstRaise = -1;
  for (int i = 1; i < c.holdAfterDecrease_frames + c.raiseInterval_frames + 1 && firstRaise < 0; ++i)
    if (g.update(w.frame(g, 10e3)).action == GovAction::Increase) firstRaise = i;
  EXPECT_GE(firstRaise, c.holdAfterDecrease_frames);
}

// "Layers at their bound in the wanted direction drop out and the others take up the slack": the
// terrain sits at its coarsest tolerance, the forest's near distance must take the whole cut, so
// the prediction at the new knobs lands on the aim (the middle of the band less the margin).
TEST(Governor, ALayerAtItsBoundDropsOutAndTheOthersTakeUpTheCut) {
  GovernorConfig c = terrainConfig();
  c.knobs[kTerrain].initial = c.knobs[kTerrain].max = 4.0;
  GovKnob& near = c.knobs[kForest];
  near.present = true;
  near.initial = near.max = 500.0;
  near.min = 50.0;
  near.loadExponent = 2.0;
  near.loadUnit = 1e4;
  c.raiseInterval_frames = 1000000;  // no raises: the terrain stays at its bound
  c.marginSigmas = 0.0;                // the aim is the middle of the band
  Governor g(c);
  auto frame = [&](double density, int i) {
    const double tris = (1.6e6 + 1e5 * (i % 3)) * std::pow(g.knob(GovLayer::Terrain), -2.0);  // ~100k
    const double d = g.knob(GovLayer::Forest);
    const double trees = density * (d / 500.0) * (d / 500.0);
    GovSample s;
    s.phase_ms[kInput] = 0.3;
    s.phase_ms[kTerrainPhase] = 0.5 + 2e-5 * tris;
    s.phase_ms[kForestPhase] = 0.2 + 2.0 * trees / 1e4;
    s.phase_ms[kSubmit] = 0.3 + 0.5e-5 * tris;
    s.phase_ms[kGpu] = 1.0 + 8e-5 * tris + 20.0 * trees / 1e4;
    s.load[kTerrain] = tris;
    s.load[kForest] = trees;
    return s;
  };
  for (int i = 0; i < 200; ++i) g.update(frame(3000.0 + 300.0 * (i % 4), i));  // ~19 .. 22 ms
  ASSERT_DOUBLE_EQ(g.knob(GovLayer::Terrain), 4.0);
  ASSERT_DOUBLE_EQ(g.knob(GovLayer::Forest), 500.0);
  ASSERT_GT(g.model(GovPhase::Gpu).theta(1), 0.0);  // the terrain's load costs something
  // More trees: above the band, within the budget.
  const GovDecision& d = g.update(frame(6000.0, 200));
  ASSERT_FALSE(d.overrun);
  ASSERT_EQ(d.action, GovAction::Decrease);
  ASSERT_GT(d.loadScale, c.maxDecrease);  // not clamped: the solve decides the step
  EXPECT_DOUBLE_EQ(g.knob(GovLayer::Terrain), 4.0);
  EXPECT_LT(g.knob(GovLayer::Forest), 500.0);
  EXPECT_NEAR(d.predicted_ms, bandMiddle(c, g) - d.margin_ms, 0.01);
}

// "Slopes below 0 count as 0", and "at least a quarter of the predicted frame counts as
// load-dependent, so an unfitted model still moves the knobs": every phase here gets cheaper
// as the load grows (the load follows the scene, not the knob), so the fitted slopes are all
// negative. The prediction is then the intercepts alone, and with no load-dependent part left
// the frames above the band still cut the knob (by the deepest regular step).
TEST(Governor, NegativeSlopesCountAsZeroAndAQuarterOfTheFrameStillMovesTheKnob) {
  GovernorConfig c = terrainConfig();
  c.knobs[kTerrain].max = 1e9;  // room for every cut below
  Governor g(c);
  const double loads[3] = {0.5e5, 0.75e5, 1.0e5};
  auto frame = [&](int i) {
    const double x = loads[i % 3] / 1e5;
    GovSample s;
    s.phase_ms[kInput] = 0.3;
    s.phase_ms[kTerrainPhase] = 2.0 - 0.5 * x;
    s.phase_ms[kSubmit] = 1.0 - 0.2 * x;
    s.phase_ms[kGpu] = 31.0 - 4.0 * x;  // frame 29.6 .. 32 ms: above the band, within the budget
    s.load[kTerrain] = loads[i % 3];
    return s;
  };
  for (int i = 0; i < 29; ++i) g.update(frame(i));
  const double before = g.knob(GovLayer::Terrain);
  const GovDecision& d = g.update(frame(29));
  ASSERT_FALSE(d.overrun);
  // The fitted slopes are negative; the prediction is the sum of the intercepts.
  double intercepts = 0.0;
  for (GovPhase p : {GovPhase::Input, GovPhase::Terrain, GovPhase::Submit, GovPhase::Gpu}) {
    if (p != GovPhase::Input) {
      ASSERT_LT(g.model(p).theta(1), 0.0) << govPhaseName(p);
    }
    intercepts += std::max(0.0, g.model(p).theta(0));
  }
  EXPECT_NEAR(d.predictedHeld_ms, intercepts, 1e-9);
  EXPECT_EQ(d.action, GovAction::Decrease);
  EXPECT_DOUBLE_EQ(d.loadScale, c.maxDecrease);
  EXPECT_NEAR(g.knob(GovLayer::Terrain), before * std::pow(c.maxDecrease, -0.5), 1e-9 * before);
}

// A quantised knob too coarse for the step moves by the whole step, rounded, when that step is
// at least one quantum: 20 layers raised by maxIncrease are 22, not a one-quantum step to 21.
TEST(Governor, ACoarseKnobTakesTheWholeRaiseWhenItIsAtLeastOneQuantum) {
  const GovernorConfig c = layerCountConfig(20.0, 100.0);
  Governor g(c);
  double before = g.knob(GovLayer::ForestLayers);
  for (int i = 0; i < 20; ++i) {
    before = g.knob(GovLayer::ForestLayers);
    if (g.update(layerCountFrame(before, 2.0, 0.1)).action == GovAction::Increase) break;
  }
  ASSERT_DOUBLE_EQ(before, 20.0);
  EXPECT_DOUBLE_EQ(g.knob(GovLayer::ForestLayers), std::floor(20.0 * c.maxIncrease));
}

// enforcePhaseBudgets: a layer whose own phase is predicted 10 % over its budget, the frame well
// within the band, is cut (any excess counts), by one step bounded by maxDecrease; the decision
// is a Decrease and holds raises for holdAfterDecrease_frames like any other.
TEST(Governor, APhaseBudgetCutIsBoundedCountsAsADecreaseAndHolds) {
  GovernorConfig c = terrainConfig();
  c.enforcePhaseBudgets = true;
  c.maxDecrease = 0.95;
  Governor g(c);
  ExactTerrain w;
  w.terrain1_ms = 1e-4;
  w.gpu1_ms = 1e-5;
  const double budget = g.phaseBudget_ms(GovPhase::Terrain);
  const double scene = (1.1 * budget - w.terrain0_ms) / w.terrain1_ms;  // terrain phase: 1.1 x its budget at 1 px
  GovAction action = GovAction::Warmup;
  int frame = 0;
  for (; frame < 10 && g.knob(GovLayer::Terrain) == 1.0; ++frame) {
    const GovSample s = w.frame(g, scene);
    ASSERT_LT(s.frame_ms, 0.65 * g.frameBudget_ms());  // the frame fits
    action = g.update(s).action;
  }
  ASSERT_LT(frame, 10) << "the over-budget phase was never cut";
  EXPECT_EQ(action, GovAction::Decrease);
  EXPECT_NEAR(g.knob(GovLayer::Terrain), std::pow(c.maxDecrease, -0.5), 1e-12);
  EXPECT_EQ(g.stats().decreases, 1);
  int firstRaise = -1;
  for (int i = 1; i < c.holdAfterDecrease_frames + c.raiseInterval_frames + 1 && firstRaise < 0; ++i)
    if (g.update(w.frame(g, 10e3)).action == GovAction::Increase) firstRaise = i;
  EXPECT_GE(firstRaise, c.holdAfterDecrease_frames);
}

// "A decision that moves no knob counts as HOLD": the finest tolerance already, a light scene.
TEST(Governor, ARaiseThatMovesNoKnobIsAHold) {
  Governor g(terrainConfig());
  const ExactTerrain w;
  for (int i = 0; i < 100; ++i) {
    const GovAction a = g.update(w.frame(g, 10e3)).action;
    ASSERT_TRUE(a == GovAction::Hold || a == GovAction::Warmup) << i << ": " << govActionName(a);
  }
  EXPECT_EQ(g.stats().increases, 0);
  EXPECT_DOUBLE_EQ(g.knob(GovLayer::Terrain), 1.0);
}

// loadCap: the last load grown by the frame's headroom to the band's top, less the margin
// (max(1, (bandTop - margin) / frame_ms)); an invalid frame and a reload keep the caps.
TEST(Governor, LoadCapIsTheLoadGrownToTheBandTopLessTheMarginAndIsKept) {
  const GovernorConfig c = terrainConfig();
  Governor g(c);
  const ExactTerrain w;
  GovSample s;
  for (int i = 0; i < 40; ++i) g.update(s = w.frame(g, 100e3));
  const GovDecision& d = g.lastDecision();
  ASSERT_GT(d.margin_ms, 0.0);
  const double cap = s.load[kTerrain] * (d.bandTop_ms - d.margin_ms) / s.frame_ms;
  ASSERT_GT(cap, s.load[kTerrain]);
  EXPECT_NEAR(g.loadCap(GovLayer::Terrain), cap, 1e-9 * cap);
  GovSample invalid;  // no frame time and not every phase: nothing learnt
  ASSERT_EQ(g.update(invalid).action, GovAction::Invalid);
  EXPECT_NEAR(g.loadCap(GovLayer::Terrain), cap, 1e-9 * cap);
  g.reconfigure(c);  // SIGHUP with the same config: the layer stays, so does its cap
  EXPECT_NEAR(g.loadCap(GovLayer::Terrain), cap, 1e-9 * cap);
}

// Spikes: a frame whose load jumped (here 2x, above the 1.5x that counts as a jump) explains its
// excess over the prediction: not a spike. The same excess at a steady load is one.
TEST(Governor, ALoadJumpIsNotASpike) {
  GovernorConfig c = terrainConfig();
  c.spikeWindow_frames = 60;
  Governor g(c);
  const ExactTerrain w;
  for (int i = 0; i < 100; ++i) g.update(w.frame(g, 100e3));  // the first frames' errors have left the window
  ASSERT_LT(g.stats().spike_ms, 0.01);
  const GovDecision& jump = g.update(w.frame(g, 200e3));  // 12.6 -> 23.1 ms
  ASSERT_FALSE(jump.overrun);
  EXPECT_LT(g.stats().spike_ms, 0.01);
  for (int i = 0; i < 100; ++i) g.update(w.frame(g, 100e3));
  g.update(w.frame(g, 100e3, 8.0));  // the same load, 8 ms more: a spike
  EXPECT_NEAR(g.stats().spike_ms, 8.0, 0.1);
}

// The spike window: a spike counts for spikeWindow_frames frames (its own and the ones after),
// then it has left the window.
TEST(Governor, ASpikeLeavesTheWindowAfterSpikeWindowFrames) {
  GovernorConfig c = terrainConfig();
  c.spikeWindow_frames = 10;  // ten blocks of one frame
  Governor g(c);
  const ExactTerrain w;
  for (int i = 0; i < 100; ++i) g.update(w.frame(g, 100e3));
  g.update(w.frame(g, 100e3, 5.0));
  int seen = g.stats().spike_ms > 4.9 ? 1 : 0;
  for (int i = 0; i < 30; ++i) {
    g.update(w.frame(g, 100e3));
    seen += g.stats().spike_ms > 4.9 ? 1 : 0;
  }
  EXPECT_EQ(seen, c.spikeWindow_frames);
  EXPECT_LT(g.stats().spike_ms, 0.01);
}

// No growth is anticipated for a budget knob (the budget bounds the load): demand rising 3 % a
// frame below the budget predicts the same with and without the trend horizon.
TEST(Governor, ABudgetKnobAnticipatesNoGrowth) {
  GovernorConfig c = budgetConfig(2e6);
  Governor g(c);
  c.trendHorizon_frames = 0.0;
  Governor flat(c);
  for (int i = 0; i < 120; ++i) {
    const double demand = 100e3 * std::pow(1.03, std::min(i, 60));
    const GovDecision& d = g.update(cellsFrame(g, demand, 2e-5));
    const GovDecision& df = flat.update(cellsFrame(flat, demand, 2e-5));
    ASSERT_DOUBLE_EQ(d.predictedHeld_ms, df.predictedHeld_ms) << i;
    ASSERT_DOUBLE_EQ(g.knob(GovLayer::Cells), flat.knob(GovLayer::Cells)) << i;
  }
}

// The trend is the load change NOT caused by the knob: a tolerance raised on a steady scene
// changes the load by exactly (v'/v)^loadExponent (the world's exponent is the one the governor
// is told), which is no trend. So a governor with the default trend horizon decides exactly as
// one without it.
TEST(Governor, TheKnobsOwnEffectOnTheLoadIsNoTrend) {
  GovernorConfig c = terrainConfig();
  c.knobs[kTerrain].initial = 8.0;  // coarse: light frames raise detail step by step
  Governor g(c);
  c.trendHorizon_frames = 0.0;
  Governor flat(c);
  const ExactTerrain w;
  int moves = 0;
  for (int i = 0; i < 400; ++i) {
    const double scene = 150e3;
    const double before = g.knob(GovLayer::Terrain);
    const GovDecision& d = g.update(w.frame(g, scene));
    const GovDecision& df = flat.update(w.frame(flat, scene));
    ASSERT_NEAR(d.predictedHeld_ms, df.predictedHeld_ms, 1e-9) << i;
    ASSERT_DOUBLE_EQ(g.knob(GovLayer::Terrain), flat.knob(GovLayer::Terrain)) << i;
    moves += g.knob(GovLayer::Terrain) != before ? 1 : 0;
  }
  EXPECT_GE(moves, 5);  // raised step by step
}

// A quantised tolerance (load falls as the value grows) rounds a decrease up, to less detail:
// 2 px cut by s = 25/30 is 2.19 px, drawn at 3 px, not rounded back to 2 (no cut at all).
TEST(Governor, AQuantisedToleranceRoundsADecreaseTowardsLessDetail) {
  GovernorConfig c = terrainConfig();
  c.knobs[kTerrain].initial = 2.0;
  c.knobs[kTerrain].quantum = 1.0;
  Governor g(c);
  const ExactTerrain w;
  const GovDecision& d = g.update(w.of(w.trisFor(30.0)));  // warm-up, above the band
  EXPECT_EQ(d.action, GovAction::Decrease);
  EXPECT_DOUBLE_EQ(g.knob(GovLayer::Terrain), 3.0);
}

// A budget knob: a raise starts from the knob (not from the load below it) and predicts that the
// layer takes up what it is given (load * v'/v): more work than with the knob held.
TEST(Governor, ABudgetKnobIsRaisedFromTheKnobAndPredictedToFillIt) {
  const GovernorConfig c = budgetConfig(1e6);
  Governor g(c);
  GovDecision d;
  for (int i = 0; i < 30 && d.action != GovAction::Increase; ++i) d = g.update(cellsFrame(g, 0.95e6, 2e-6));
  ASSERT_EQ(d.action, GovAction::Increase);
  EXPECT_DOUBLE_EQ(g.knob(GovLayer::Cells), 1e6 * c.maxIncrease);
  EXPECT_GT(d.predicted_ms, d.predictedHeld_ms + 0.01);
}

// A budget knob far above its load is cut from the load; lowering it to v' predicts the load
// min(load, v'), so the decrease lands on the aim like any other.
TEST(Governor, ABudgetKnobCutFromItsLoadIsPredictedAtTheAim) {
  const GovernorConfig c = budgetConfig(2e6);
  Governor g(c);
  for (int i = 0; i < 100; ++i) g.update(cellsFrame(g, 2e5, 9e-5));  // 19.8 ms
  ASSERT_DOUBLE_EQ(g.knob(GovLayer::Cells), 2e6);
  const GovDecision& d = g.update(cellsFrame(g, 3.1e5, 9e-5));  // ~30 ms
  ASSERT_FALSE(d.overrun);
  ASSERT_EQ(d.action, GovAction::Decrease);
  ASSERT_GT(d.loadScale, c.maxDecrease);
  EXPECT_LT(g.knob(GovLayer::Cells), 3.1e5);  // from the load, not from 2e6
  EXPECT_NEAR(d.predicted_ms, bandMiddle(c, g) - d.margin_ms, 0.01);
}

// Rounding towards less detail must not turn a raise into a cut: a layer count that starts off
// its quantum's grid (validate() takes any initial value within the bounds) only goes up while
// the frames are light.
TEST(Governor, ARaiseNeverLowersAnOffGridQuantisedKnob) {
  Governor g(layerCountConfig(2.5, 8.0));
  double prev = g.knob(GovLayer::ForestLayers);
  for (int i = 0; i < 200; ++i) {
    g.update(layerCountFrame(g.knob(GovLayer::ForestLayers), 2.0, 0.5));
    ASSERT_GE(g.knob(GovLayer::ForestLayers), prev) << i;
    prev = g.knob(GovLayer::ForestLayers);
  }
  EXPECT_DOUBLE_EQ(prev, 8.0);
  EXPECT_EQ(g.stats().decreases, 0);
}

namespace {

// Every one-quantum raise of the layer count stalls its first frame by 30 ms outside the phases
// (a pipeline built for the new count): an overrun that takes the raise back. The phases stay
// cheap, so the model keeps predicting that the raise fits and retries it whenever the wait of
// one-quantum raises allows. Returns the frames of the raises; the GPU costs base_ms +
// perLayer_ms a layer, and the stall comes `stallAfter` frames after the raise.
std::vector<int> stalledRaises(Governor& g, int frames, double base_ms, double perLayer_ms, int stallAfter = 1) {
  std::vector<int> raises;
  int lastRaise = -1000000;
  for (int i = 0; i < frames; ++i) {
    const double n = g.knob(GovLayer::ForestLayers);
    GovSample s = layerCountFrame(n, base_ms, perLayer_ms);
    s.frame_ms = s.phase_ms[kInput] + s.phase_ms[kSubmit] + s.phase_ms[kGpu] + (i == lastRaise + stallAfter ? 30.0 : 0.0);
    g.update(s);
    if (g.knob(GovLayer::ForestLayers) > n) raises.push_back(lastRaise = i);
  }
  return raises;
}

}  // namespace

// A one-quantum raise taken back within holdAfterDecrease_frames makes the next one wait: from 4
// holds, doubling, at most 64 holds (raises are tried every raiseInterval_frames, so each comes
// within that many frames after its wait).
TEST(Governor, OneQuantumRaisesTakenBackWaitFourHoldsDoublingToSixtyFour) {
  const GovernorConfig c = layerCountConfig(1.0, 8.0);
  Governor g(c);
  const std::vector<int> raises = stalledRaises(g, 7000, 14.0, 2.0);
  ASSERT_GE(raises.size(), 7u);
  const int hold = c.holdAfterDecrease_frames;
  int wait = 4 * hold;
  for (size_t k = 1; k < 7; ++k) {
    const int gap = raises[k] - raises[k - 1];
    EXPECT_GE(gap, wait) << "raise " << k;
    EXPECT_LT(gap, wait + c.raiseInterval_frames) << "raise " << k;
    wait = std::min(2 * wait, 64 * hold);
  }
}

// "Within holdAfterDecrease_frames" includes the last frame of the hold: a raise whose
// holdAfterDecrease_frames-th frame overruns is taken back within the hold (the next waits 4
// holds); one whose next frame overruns is not (the wait is over: no wait).
TEST(Governor, ARaiseTakenBackOnTheLastFrameOfTheHoldStillWaits) {
  const GovernorConfig c = layerCountConfig(1.0, 8.0);
  const int hold = c.holdAfterDecrease_frames;
  Governor within(c), after(c);
  // 1 layer: 16.4 ms (below the band), 2 layers: 22.4 ms (in it): the raise stays until the stall.
  const std::vector<int> a = stalledRaises(within, 400, 10.0, 6.0, hold);
  const std::vector<int> b = stalledRaises(after, 400, 10.0, 6.0, hold + 1);
  ASSERT_GE(a.size(), 2u);
  ASSERT_GE(b.size(), 2u);
  EXPECT_GE(a[1] - a[0], 4 * hold);
  EXPECT_LT(b[1] - b[0], 4 * hold);  // only the hold after the emergency and the raise interval
}

// The wait also ends "when frames become much lighter than the one after which the failed raise
// was made": the scene changed. After the first take-back the fixed GPU cost drops from 14 ms to
// 4 ms (16.4 ms frames become 6.4 ms ones): the next raise comes after the emergency's hold, not
// after 4 holds.
TEST(Governor, AMuchLighterFrameEndsTheWaitOfOneQuantumRaises) {
  const GovernorConfig c = layerCountConfig(1.0, 8.0);
  Governor g(c);
  int dropAt = 1000000;
  std::vector<int> raises;
  int lastRaise = -1000000;
  for (int i = 0; i < 400 && raises.size() < 2; ++i) {
    const double n = g.knob(GovLayer::ForestLayers);
    GovSample s = layerCountFrame(n, i >= dropAt ? 4.0 : 14.0, 2.0);
    s.frame_ms = s.phase_ms[kInput] + s.phase_ms[kSubmit] + s.phase_ms[kGpu] + (i == lastRaise + 1 ? 30.0 : 0.0);
    g.update(s);
    if (g.knob(GovLayer::ForestLayers) > n) raises.push_back(lastRaise = i);
    if (raises.size() == 1 && i == lastRaise + 1) dropAt = i + 1;  // right after the take-back
  }
  ASSERT_EQ(raises.size(), 2u);
  EXPECT_LT(raises[1] - raises[0], 4 * c.holdAfterDecrease_frames);
}

// Phase overruns count phases above their budget, not those below it.
TEST(Governor, PhaseOverrunsCountOnlyPhasesAboveTheirBudget) {
  Governor g(terrainConfig());
  ExactTerrain w;
  w.terrain1_ms = 0.0;
  w.terrain0_ms = 0.6 * g.phaseBudget_ms(GovPhase::Terrain);
  for (int i = 0; i < 10; ++i) g.update(w.frame(g, 10e3));
  EXPECT_EQ(g.stats().phaseOverruns[kTerrainPhase], 0);
  w.terrain0_ms = 1.01 * g.phaseBudget_ms(GovPhase::Terrain);
  for (int i = 0; i < 10; ++i) g.update(w.frame(g, 10e3));
  EXPECT_EQ(g.stats().phaseOverruns[kTerrainPhase], 10);
}

// frame_ms = NaN means "not measured: the sum of the phases" (GovSample), not a bad measurement.
TEST(Governor, ANaNFrameTimeIsNotABadMeasurement) {
  Governor g(terrainConfig());
  const ExactTerrain w;
  for (int i = 0; i < 10; ++i) {
    GovSample s = w.frame(g, 100e3);
    s.frame_ms = kGovNaN;
    EXPECT_NE(g.update(s).action, GovAction::Invalid);
  }
  EXPECT_EQ(g.stats().ignored, 0);
  EXPECT_EQ(g.stats().invalidFrames, 0);
  GovSample s = w.frame(g, 100e3);
  s.frame_ms = -1.0;  // a bad one is counted (and the phases stand in for it)
  g.update(s);
  EXPECT_EQ(g.stats().ignored, 1);
}

// "Batches below minUnits are ignored": a batch of exactly minUnits counts.
TEST(UnitCost, ABatchOfExactlyMinUnitsCounts) {
  UnitCost cost(2000.0, 0.5, 16);
  cost.observe(15, 15'000);
  EXPECT_DOUBLE_EQ(cost.ns(), 2000.0);
  cost.observe(16, 16'000);  // 1000 ns each
  EXPECT_DOUBLE_EQ(cost.ns(), 1500.0);
}

// validate()'s ranges at their ends: max_decrease in (0, 1), quantum in 0 ..= max - min.
TEST(Governor, ValidateTakesTheInclusiveEndsAndRefusesTheExclusiveOnes) {
  GovernorConfig c = terrainConfig();
  c.maxDecrease = 1.0;
  EXPECT_NE(Governor::validate(c).find("max_decrease = 1"), std::string::npos) << Governor::validate(c);
  c = terrainConfig();
  c.knobs[kTerrain].quantum = c.knobs[kTerrain].max - c.knobs[kTerrain].min;
  EXPECT_EQ(Governor::validate(c), "");
  c.knobs[kTerrain].quantum *= 1.001;
  EXPECT_NE(Governor::validate(c).find("terrain.quantum"), std::string::npos);
}

// "P(1) < bottom, no raise for raiseInterval_frames and no hold: INCREASE" and "a decision that
// moves no knob counts as HOLD". The code restarted the raise interval on every Increase
// decision, also one that moved nothing (here: every raiseInterval_frames while the one-quantum
// wait lasts), so the raise that the end of the wait allows came up to raiseInterval_frames - 1
// frames late: 121 frames after the last one, not 4 holds = 120, although no knob moved between.
TEST(Governor, AnIncreaseThatMovedNothingDoesNotRestartTheRaiseInterval) {
  const GovernorConfig c = layerCountConfig(1.0, 8.0);
  Governor g(c);
  const std::vector<int> raises = stalledRaises(g, 400, 14.0, 2.0);
  ASSERT_GE(raises.size(), 2u);
  EXPECT_EQ(raises[1] - raises[0], 4 * c.holdAfterDecrease_frames);  // is 121
}
