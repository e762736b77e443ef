// Frame governor: keeps a fixed frame rate by steering each layer's LOD knob (terrain pixel
// tolerance, forest near distance and shell layer count, HDLOD r, the cells' voxel budget) from a PREDICTION of the next frame's
// work, so detail drops before a frame overruns, not only after one. Issue 7 item 3; the time
// model follows paper 002 (shared/SEEDS.md: frame time = sum of per-phase costs linear in the
// work, calibrated on the machine), here fitted online by least squares with forgetting instead
// of a start-up calibration, so it tracks the machine's load as it changes.
//
// Pure: no clock, no GL, no threads, no allocation after construction. The caller measures and
// passes times in; deferrable work gets a deadline on the caller's clock (WorkBudget).
//
// Per frame (the service, or a test with a fake clock):
//   1. before the phases: knob(layer) for each layer's selection, workBudget(phase, start) for
//      deferrable work (ROAM refinement, paging), which stops when it expires;
//   2. after the frame: update(sample) with the measured phase times, the layers' loads
//      (triangles drawn) and the frame's work time. It returns the knobs for the next frame.
//
// Cost model, per present phase p (Input, Terrain, Forest, Hdlod, Submit, Gpu, Cells):
//     ms_p = a_p + sum over the layers l feeding p of b_pl * load_l / loadUnit_l
// (Terrain, Forest, Hdlod, Cells phases: their own layer; Submit and Gpu: every present layer;
// Input: a constant; ForestLayers, the forest's shell layers, is GPU fill and has no phase of
// its own: its "own" phase is Gpu), fitted by recursive least squares with forgetting factor `forgetting`, the
// covariance bounded (no wind-up while the load does not move); once a model has 10 samples its
// residuals are clipped at 4 times their smoothed size (an outlier frame moves it little),
// except in a frame whose load jumped by more than 1.5x (that residual is news, not noise).
// Slopes below 0 count as 0.
// Frame work = sum of phases + "other" (frame_ms minus the phases: present, report), smoothed, its
// change clipped as a phase residual is once 10 frames measured it (one stall is not a trend).
//
// Load prediction, per layer, at a knob value v' for the next frame:
//     load'_l = load_l * growth_l * (v' / v)^loadExponent_l
// growth_l = exp(clamp(trend_l, 0, 0.1) * trendHorizon_frames), trend_l the smoothed per-frame
// log change of the load not caused by the knob (only growth is anticipated, never a fall).
// A budget knob (GovKnob::loadBudget: the knob is the most load the layer may take, e.g. the
// cells' voxel budget) instead predicts load'_l = load_l * v' / v when raised (the layer takes
// up what it is given) and min(load_l, v') when lowered (a budget above the load does not bind:
// lowering it to the load changes nothing), with no growth (the budget bounds it); a decrease
// starts from min(v, load_l), so that a budget far above what the scene asked for is cut at once.
//
// Control law (B = frame budget; P(s) = predicted work with every adjustable layer's load
// multiplied by s, plus margin = marginSigmas * a robust scale of past prediction errors,
// 1.25 * smoothed |error| with each error clipped at 4 scales: heavy-tailed noise from a busy
// machine widens it less than an RMS would). The dead band is [bottom, top]: top =
// decreaseAbove * B less the spike headroom (what the largest recent spike, the maximum of
// (measured - predicted) over spikeWindow_frames, exceeds (1 - decreaseAbove) * B), bottom =
// increaseBelow * B, lowered only to keep the band at least half its configured width:
//   - the frame overran (frame_ms > B): EMERGENCY: s = clamp(solve(aim), emergencyMaxDecrease,
//     emergencyScale); no raise for holdAfterDecrease_frames; deferrable budgets *
//     emergencyDeferScale for emergencyFrames frames;
//   - warm-up (the first warmup_frames, no model yet): HOLD, but a frame above top is cut in
//     proportion, s = clamp(aim / frame_ms, maxDecrease, 1);
//   - P(1) > top: DECREASE to s = clamp(solve(aim), maxDecrease, 1); no raise for
//     holdAfterDecrease_frames;
//   - P(1) < bottom, no raise for raiseInterval_frames and no hold: INCREASE to
//     s = min(solve(aim), maxIncrease);
//   - otherwise HOLD (the dead band).
// aim = (top + bottom) / 2, the middle of the dead band; solve(aim) is the
// s with P(s) = aim (at least a quarter of the predicted frame counts as load-dependent, so an
// unfitted model still moves the knobs). A decision that moves no knob counts as HOLD. Each layer's knob moves by (v'/v) = s^(1 / loadExponent), clamped to
// [min, max] and rounded to `quantum` towards less detail (a quantised knob may step one quantum
// towards more detail when P after that step stays below aim). Layers at their bound in the
// wanted direction drop out and the others take up the slack. Bounded steps, the dead band and
// the rate limit on raises keep the knobs from oscillating.
//
// Load caps: besides the knobs, each decision gives every layer a cap on its next load, the last
// load grown by at most the frame's headroom to the band's top (loadCap()). Knobs act on the
// converged load; a layer that is still converging (ROAM after a jump, under its work budget)
// grows by itself for several frames, faster than the knobs can follow, and stops at the cap.
//
// Phase budgets: B * phaseShare_p, the shares renormalised over the present phases (a phase of
// an absent layer has budget 0 and no model, and its measurements are ignored). They bound the
// deferrable work of the layer phases (workBudget) and, with enforcePhaseBudgets, a layer whose
// own phase is predicted over its budget is decreased even when the frame fits (on a HOLD or
// DECREASE frame; an INCREASE frame raises as the frame allows, and a phase it pushes over its
// budget is cut back on the next frames).
//
// Bad measurements (NaN, infinite, negative) are ignored and counted (GovStats::ignored): a bad
// phase time skips that phase's model update; a bad load keeps the last good one; a bad frame
// time (and phases that cannot replace it) leaves the knobs where they are.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>

namespace ig::lod {

enum class GovPhase : int { Input, Terrain, Forest, Hdlod, Submit, Gpu, Cells, Count };
inline constexpr int kGovPhases = static_cast<int>(GovPhase::Count);
// ForestLayers: how many of the forest's shell layers are drawn (a second forest knob; the
// layers are blended fill over most of the screen, on llvmpipe most of a forest frame).
enum class GovLayer : int { Terrain, Forest, Hdlod, Cells, ForestLayers, Count };
inline constexpr int kGovLayers = static_cast<int>(GovLayer::Count);
const char* govPhaseName(GovPhase p);  // "input", "terrain", "forest", "hdlod", "submit", "gpu", "cells"
const char* govLayerName(GovLayer l);  // "terrain", "forest", "hdlod", "cells", "forest_layers"
// The phase in which a layer's CPU work (selection, refinement) runs; the forest's shell layers
// have none (their cost is the GPU's fill): Gpu.
constexpr GovPhase layerPhase(GovLayer l) {
  return l == GovLayer::Cells          ? GovPhase::Cells
         : l == GovLayer::ForestLayers ? GovPhase::Gpu
                                       : static_cast<GovPhase>(static_cast<int>(l) + 1);
}

// One layer's LOD knob.
struct GovKnob {
  bool present = false;        // the scene has the layer; absent: no knob, no phase, no budget
  double initial = 1.0;        // value at start-up (the scene's setting); clamped to [min, max]
  double min = 1.0;            // bounds the governor never leaves (min < max, both > 0)
  double max = 16.0;
  // load ~ value^loadExponent (non-zero): terrain tolerance_px about -2 (-1 on rough relief),
  // HDLOD r about -2, forest near distance +2, forest layer count +1 (the load: layers drawn). Only the step size depends
  // on it: the loop is closed on the measured load, so a wrong exponent slows it, no more.
  double loadExponent = -2.0;
  double quantum = 0.0;        // > 0: the value is a multiple of this (1 for a layer count)
  double loadUnit = 1e5;       // scales the load for the cost model (1e5 triangles)
  // The knob is a budget in the load's own units (the most load the layer may take, e.g. the
  // cells' voxel budget; loadExponent must be 1): see "Load prediction" above.
  bool loadBudget = false;
};

struct GovernorConfig {
  double rate_hz = 30.0;             // frame rate; the period is 1000 / rate_hz ms
  double frameBudget_ms = 0.0;       // work budget per frame; 0 = the period
  double decreaseAbove = 0.85;       // decrease detail when predicted + margin > this * budget
  double increaseBelow = 0.65;       // raise it when below this * budget (< decreaseAbove)
  double marginSigmas = 2.0;         // margin = this * prediction error scale (>= 0)
  // Share of the budget per phase (Input, Terrain, Forest, Hdlod, Submit, Gpu, Cells),
  // renormalised over the present phases. >= 0, at least one present phase > 0.
  std::array<double, kGovPhases> phaseShare{0.05, 0.20, 0.15, 0.15, 0.10, 0.35, 0.10};
  bool enforcePhaseBudgets = false;  // also decrease a layer whose own phase exceeds its budget
  double maxDecrease = 0.5;          // smallest load multiplier of one decrease, in (0, 1)
  double maxIncrease = 1.10;         // largest load multiplier of one raise, > 1
  int raiseInterval_frames = 6;      // frames between raises (>= 1), counted from the last raise that moved a knob
  int holdAfterDecrease_frames = 30; // no raise for this many frames after a decrease (>= 0)
  double emergencyScale = 0.6;       // load multiplier at most, after an overrun, in (0, 1]
  double emergencyMaxDecrease = 0.25;  // ... and at least (the deepest cut), in (0, emergencyScale]
  int emergencyFrames = 15;          // deferrable budgets shrink for this many frames (>= 0)
  double emergencyDeferScale = 0.5;  // ... to this fraction, in (0, 1]
  double forgetting = 0.97;          // RLS forgetting factor per frame, in (0.5, 1]
  double errorSmoothing = 0.9;       // EWMA factor of the prediction error scale, in [0, 1)
  double trendHorizon_frames = 2.0;  // frames of load growth anticipated (>= 0)
  int warmup_frames = 3;             // frames only measured (knobs held unless above the band)
  // Spike headroom: the largest excess of a frame over its prediction in the last this many
  // frames (frames without a load jump; excesses above (1 - increaseBelow) * budget, which would
  // overrun from anywhere in the band, are not counted) lowers the top of the dead band by what
  // it exceeds the band's own headroom, (1 - decreaseAbove) * budget: a frame at the top plus the
  // spikes this machine produces stays within the budget. The band's bottom moves down with it
  // only where the band would shrink below half its width, so light scenes keep their detail.
  // Kept as the maxima of ten blocks of window / 10 frames. 0 = off (default: it costs detail
  // wherever the scene is heavy; docs/governor.md has the trade measured).
  int spikeWindow_frames = 0;
  std::array<GovKnob, kGovLayers> knobs{};  // Terrain, Forest, Hdlod, Cells, ForestLayers
};

inline constexpr double kGovNaN = std::numeric_limits<double>::quiet_NaN();

// What one frame measured. NaN = not measured; an absent phase or layer is ignored whatever it
// holds (0 is fine).
struct GovSample {
  std::array<double, kGovPhases> phase_ms{kGovNaN, kGovNaN, kGovNaN, kGovNaN, kGovNaN, kGovNaN, kGovNaN};
  std::array<double, kGovLayers> load{kGovNaN, kGovNaN, kGovNaN, kGovNaN, kGovNaN};  // per layer, e.g. triangles drawn
  double frame_ms = kGovNaN;  // the frame's whole work; NaN = the sum of the present phases
};

enum class GovAction : uint8_t { Warmup, Hold, Decrease, Increase, Emergency, Invalid };
const char* govActionName(GovAction a);

struct GovDecision {
  GovAction action = GovAction::Warmup;
  std::array<double, kGovLayers> knob{};  // values for the next frame (NaN for absent layers)
  double predicted_ms = 0.0;       // next frame's work at the new knobs (no margin)
  double predictedHeld_ms = 0.0;   // ... had the knobs stayed
  double margin_ms = 0.0;          // marginSigmas * robust error scale
  double spike_ms = 0.0;           // the largest excess over the prediction in the window (spikeWindow_frames)
  double bandTop_ms = 0.0;         // the dead band's top: decreaseAbove * budget, less the spike headroom
  double loadScale = 1.0;          // the common load multiplier s chosen (1: hold)
  bool overrun = false;            // the measured frame exceeded the budget
  // Per layer, the most load the next frame may take on (Governor::loadCap); +inf: no cap
  // (warm-up), NaN: absent layer.
  std::array<double, kGovLayers> loadCap{kGovNaN, kGovNaN, kGovNaN, kGovNaN, kGovNaN};
};

struct GovStats {
  int64_t frames = 0;
  int64_t overruns = 0;            // frames with frame_ms > budget
  int64_t emergencies = 0;
  int64_t decreases = 0, increases = 0;  // decisions that moved at least one knob
  int64_t ignored = 0;             // bad measurements (NaN, infinite, negative) ignored
  int64_t invalidFrames = 0;       // frames without a usable frame time
  std::array<int64_t, kGovLayers> directionChanges{};  // knob moves opposite to the previous move
  std::array<int64_t, kGovPhases> phaseOverruns{};     // phase time > its budget
  double errorScale_ms = 0.0;      // robust scale of (measured - predicted) frame work
  double spike_ms = 0.0;           // the largest (measured - predicted) in the window, see spikeWindow_frames
};

// Recursive least squares with exponential forgetting over at most kMax parameters, y ~ theta . x.
// The covariance update is EFRA (exponential forgetting and resetting): it stays between two
// bounds (about 1e-4 delta and delta) whatever the excitation, so a stationary stretch neither
// winds it up nor freezes a direction.
class ForgettingLeastSquares {
 public:
  static constexpr int kMax = 1 + kGovLayers;  // a constant and one slope per layer (Submit, Gpu)
  ForgettingLeastSquares() = default;
  // n in [1, kMax]; initial covariance delta * I; lambda in (0, 1].
  ForgettingLeastSquares(int n, double lambda, double delta = 10.0);
  // x: n values; non-finite input is the caller's bug. The residual is clipped to
  // +-maxError (robust against outliers: a preempted frame does not wreck the fit). A sample
  // whose update overflows (a huge finite x, x'Px = inf) is dropped: the fit stays as it was.
  void update(const double* x, double y, double maxError = std::numeric_limits<double>::infinity());
  double predict(const double* x) const;
  double theta(int i) const { return theta_[static_cast<size_t>(i)]; }
  int size() const { return n_; }
  int64_t samples() const { return samples_; }

 private:
  int n_ = 1;
  double lambda_ = 1.0, beta_ = 0.0, delta2_ = 0.0;
  std::array<double, kMax> theta_{};
  std::array<double, kMax * kMax> p_{};
  int64_t samples_ = 0;
};

// Where a deferrable algorithm reads the time: the caller's clock behind a function pointer
// (lod/ never reads a clock itself). now_ns == nullptr: no source (poll() never expires).
struct TimeSource {
  int64_t (*now_ns)(const void* context) = nullptr;
  const void* context = nullptr;
};

// Time budget of deferrable work (ROAM refinement, paging): an absolute deadline on the
// caller's monotonic clock. Default: unlimited. Copyable, no allocation.
class WorkBudget {
 public:
  static constexpr int64_t kNever = std::numeric_limits<int64_t>::max();
  WorkBudget() = default;
  // Ends at deadline_ns; poll() reads `source` every `stride` calls (a clock read costs ~20 ns).
  WorkBudget(int64_t deadline_ns, TimeSource source, uint32_t stride = 16)
      : deadline_ns_(deadline_ns), source_(source), stride_(stride == 0 ? 1 : stride) {}
  bool unlimited() const { return deadline_ns_ == kNever; }
  int64_t deadline_ns() const { return deadline_ns_; }
  bool expired(int64_t now_ns) const { return now_ns >= deadline_ns_; }
  double remaining_ms(int64_t now_ns) const;  // >= 0; +inf when unlimited
  // For loops that poll: true once the deadline has passed (stays true). Reads the source on
  // the first call and then every stride-th call.
  bool poll();
  // For algorithms budgeted in operations (RoamView::maxOperations): how many operations of
  // nsPerOperation fit in the time left, clamped to [minOperations, 1e9]; 0 when unlimited.
  uint32_t operations(int64_t now_ns, double nsPerOperation, uint32_t minOperations = 64) const;

 private:
  int64_t deadline_ns_ = kNever;
  TimeSource source_{};
  uint32_t stride_ = 16, calls_ = 0;
  bool expired_ = false;
};

// Smoothed cost of one unit of deferrable work (ns per ROAM operation, per paged tile), from
// (units done, elapsed ns) pairs the caller measures. Batches below minUnits are ignored.
class UnitCost {
 public:
  explicit UnitCost(double initial_ns = 2000.0, double smoothing = 0.8, uint64_t minUnits = 16)
      : ns_(initial_ns), smoothing_(smoothing), minUnits_(minUnits) {}
  void observe(uint64_t units, int64_t elapsed_ns);
  double ns() const { return ns_; }

 private:
  double ns_, smoothing_;
  uint64_t minUnits_;
};

class Governor {
 public:
  // Empty string when the config is usable, else "key = value: reason" for the first bad key
  // (names as in [governor] of config/igd.toml).
  static std::string validate(const GovernorConfig& config);
  // Contract: validate(config) is empty.
  explicit Governor(const GovernorConfig& config);
  // Config reload (SIGHUP): budgets and limits change at once; fitted models, error estimate
  // and knob values are kept (knobs clamped into the new bounds; a layer that became present
  // starts at its initial value). Contract: validate(config) is empty.
  void reconfigure(const GovernorConfig& config);

  // The knob value for this frame's selection (NaN for an absent layer).
  double knob(GovLayer l) const { return knob_[static_cast<size_t>(l)]; }
  // The most load (in the layer's own units: triangles drawn) layer l may take on in this frame:
  // the last frame's load grown by at most that frame's headroom, (band top - margin) / frame
  // work (GovDecision::bandTop_ms), and never below it. Knobs act on the converged load; a layer whose
  // load grows while its knob stands still (ROAM refining a new view under its work budget after
  // a jump, paging) grows faster than the knobs can follow, and stops here instead (ROAM: its
  // triangle cap, RoamView::maxTriangles, keeps the best mesh of that size). Proportional, with
  // no intercept: the least growth that any cost line through the last frame allows, so a badly
  // fitted model cannot loosen it, and it never removes what is drawn. +inf during warm-up;
  // NaN for an absent layer.
  double loadCap(GovLayer l) const { return lastDecision_.loadCap[static_cast<size_t>(l)]; }
  double frameBudget_ms() const { return budget_ms_; }
  double phaseBudget_ms(GovPhase p) const { return phaseBudget_ms_[static_cast<size_t>(p)]; }
  bool phasePresent(GovPhase p) const { return phasePresent_[static_cast<size_t>(p)]; }
  // Phase p's budget for deferrable work this frame: its phase budget, times
  // emergencyDeferScale for emergencyFrames frames after an overrun (what workBudget() counts
  // from; callers with their own clock, like igd's layers, take this). 0 for a phase without one.
  double deferrableBudget_ms(GovPhase p) const;
  // Deadline for phase p's deferrable work starting at phaseStart_ns: its phase budget (shrunk
  // after an overrun). Unlimited for a phase without a budget.
  WorkBudget workBudget(GovPhase p, int64_t phaseStart_ns, TimeSource source = {}) const;
  // The prediction made by the last update() for the frame now running (0 before the first).
  double predicted_ms() const { return lastDecision_.predicted_ms; }

  // After each frame: learn from the sample, choose the next frame's knobs.
  const GovDecision& update(const GovSample& sample);
  const GovDecision& lastDecision() const { return lastDecision_; }
  const GovStats& stats() const { return stats_; }
  const ForgettingLeastSquares& model(GovPhase p) const { return model_[static_cast<size_t>(p)]; }

 private:
  struct Prediction {
    double total_ms = 0.0;
    std::array<double, kGovLayers> variable_ms{};  // cost proportional to each layer's load
    std::array<double, kGovPhases> phase_ms{};
  };
  void configure(const GovernorConfig& config, bool keepState);
  int features(GovPhase p, const std::array<double, kGovLayers>& load, double* x) const;
  Prediction predict(const std::array<double, kGovLayers>& loadScale) const;
  double margin() const;      // see GovDecision::margin_ms
  double bandTop_ms() const;  // see GovDecision::bandTop_ms
  double spike() const;   // the largest excess in the spike window
  double solveScale(const Prediction& held, double aim_ms, const std::array<bool, kGovLayers>& movable) const;
  double quantise(GovLayer l, double v, bool towardsLess) const;
  void applyScale(double s, bool decrease, std::array<double, kGovLayers>& next) const;
  // The load multiplier that moving layer l's knob from its value now to v predicts.
  double knobLoadScale(size_t l, double v) const;
  // Per layer, the load multipliers of moving the knobs to `next` (1 where a knob stays).
  std::array<double, kGovLayers> knobLoadScales(const std::array<double, kGovLayers>& next) const;

  GovernorConfig config_;
  double budget_ms_ = 0.0;
  std::array<double, kGovPhases> phaseBudget_ms_{};
  std::array<bool, kGovPhases> phasePresent_{};
  std::array<bool, kGovLayers> layerPresent_{};
  std::array<ForgettingLeastSquares, kGovPhases> model_{};
  std::array<double, kGovLayers> knob_{};
  std::array<double, kGovLayers> load_{};      // last good load per layer
  std::array<double, kGovLayers> prevLoad_{};  // the one before (for the trend)
  std::array<double, kGovLayers> prevKnob_{};  // knob that produced prevLoad_
  std::array<double, kGovLayers> trend_{};     // smoothed log load change per frame, knob removed
  std::array<int, kGovLayers> lastDirection_{};  // +1 more detail, -1 less, 0 none yet
  // One-quantum raises of a coarse knob (a layer count): the frame of the last one, and how
  // many frames the next must wait (0: no wait). A raise taken back by a decrease within
  // holdAfterDecrease_frames doubles the wait (from 4 holds, at most 64): the model cannot tell
  // a step's cost from the fixed cost while the knob stands still, so it would retry in a cycle.
  // The wait ends when a raise holds for that long, or when frames become much lighter than the
  // one after which the failed raise was made (quantumFrom_ms_: its work): the scene changed.
  std::array<int64_t, kGovLayers> quantumRaiseFrame_{}, quantumWait_{};
  std::array<bool, kGovLayers> quantumPending_{};
  std::array<double, kGovLayers> quantumRaise_ms_{}, quantumFrom_ms_{};
  double other_ms_ = 0.0;       // frame work outside the modelled phases, smoothed
  double otherScale_ = 0.0;     // smoothed |residual| of other_ms_ (clips an outlier, as phaseScale_)
  int64_t otherSamples_ = 0;    // frames that measured it
  double errorScale_ = 0.0;     // 1.25 * smoothed |prediction error| (a robust sigma)
  std::array<double, 10> spikeBlocks_{};  // largest excess over the prediction per block of the window
  int64_t spikeFrames_ = 0;                // frames into the window's newest block
  std::array<double, kGovPhases> phaseScale_{};  // smoothed |residual| of each phase model
  bool havePrediction_ = false;
  int64_t framesSinceRaise_ = 0;
  int64_t hold_ = 0;            // frames left with no raise
  int64_t emergencyLeft_ = 0;   // frames left with shrunk deferrable budgets
  GovDecision lastDecision_;
  GovStats stats_;
};

}  // namespace ig::lod
