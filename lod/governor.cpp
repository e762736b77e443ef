// Frame governor (issue 7 item 3): see governor.h for the model and the control law.
#include "lod/governor.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>

namespace ig::lod {
namespace {

// Largest load growth per frame the trend extrapolates (10 %): a ramp of 10x in 3 s at 30 Hz is
// 2.6 % a frame; a step is not a trend (the emergency step handles it).
constexpr double kMaxTrend = 0.1;
constexpr double kInfinity = std::numeric_limits<double>::infinity();
// Load multipliers of knobs that stay where they are.
constexpr std::array<double, kGovLayers> kHeld = [] {
  std::array<double, kGovLayers> a{};
  a.fill(1.0);
  return a;
}();

bool goodMeasurement(double v) { return std::isfinite(v) && v >= 0.0; }

size_t idx(GovPhase p) { return static_cast<size_t>(p); }
size_t idx(GovLayer l) { return static_cast<size_t>(l); }

// Input, Submit and Gpu run every frame; the layer phases only with their layer.
bool alwaysPresent(GovPhase p) { return p == GovPhase::Input || p == GovPhase::Submit || p == GovPhase::Gpu; }

// The layer whose own phase p is (Terrain, Forest, Hdlod, Cells), or Count for Input and Submit
// (Gpu: ForestLayers, but Gpu is always present).
GovLayer phaseLayer(GovPhase p) {
  for (int l = 0; l < kGovLayers; ++l)
    if (layerPhase(static_cast<GovLayer>(l)) == p) return static_cast<GovLayer>(l);
  return GovLayer::Count;
}

// Does layer l's load drive phase p's cost?
bool feeds(GovLayer l, GovPhase p) {
  return p == GovPhase::Submit || p == GovPhase::Gpu || p == layerPhase(l);
}

std::string bad(const char* key, double value, const char* reason) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s = %g: %s", key, value, reason);
  return buf;
}

}  // namespace

const char* govPhaseName(GovPhase p) {
  switch (p) {
    case GovPhase::Input: return "input";
    case GovPhase::Terrain: return "terrain";
    case GovPhase::Forest: return "forest";
    case GovPhase::Hdlod: return "hdlod";
    case GovPhase::Submit: return "submit";
    case GovPhase::Gpu: return "gpu";
    case GovPhase::Cells: return "cells";
    case GovPhase::Count: break;
  }
  return "?";
}

const char* govLayerName(GovLayer l) {
  switch (l) {
    case GovLayer::Terrain: return "terrain";
    case GovLayer::Forest: return "forest";
    case GovLayer::Hdlod: return "hdlod";
    case GovLayer::Cells: return "cells";
    case GovLayer::ForestLayers: return "forest_layers";
    case GovLayer::Count: break;
  }
  return "?";
}

const char* govActionName(GovAction a) {
  switch (a) {
    case GovAction::Warmup: return "warmup";
    case GovAction::Hold: return "hold";
    case GovAction::Decrease: return "decrease";
    case GovAction::Increase: return "increase";
    case GovAction::Emergency: return "emergency";
    case GovAction::Invalid: return "invalid";
  }
  return "?";
}

// ---------------------------------------------------------------------------------------------
// Recursive least squares with forgetting.

ForgettingLeastSquares::ForgettingLeastSquares(int n, double lambda, double delta)
    : n_(n), lambda_(lambda) {
  assert(n >= 1 && n <= kMax && "ForgettingLeastSquares: n out of range");
  assert(lambda > 0.0 && lambda <= 1.0 && delta > 0.0);
  // EFRA bounds: sigma_min ~ beta / eta, sigma_max ~ eta / delta, eta = (1 - lambda) / lambda.
  const double eta = (1.0 - lambda) / lambda;
  beta_ = eta * 1e-4 * delta;
  delta2_ = eta / delta;
  for (int i = 0; i < n_; ++i) p_[static_cast<size_t>(i * kMax + i)] = delta;
}

double ForgettingLeastSquares::predict(const double* x) const {
  double y = 0.0;
  for (int i = 0; i < n_; ++i) y += theta_[static_cast<size_t>(i)] * x[i];
  return y;
}

void ForgettingLeastSquares::update(const double* x, double y, double maxError) {
  const auto at = [](int i, int j) { return static_cast<size_t>(i * kMax + j); };
  std::array<double, kMax> px{};
  double r = 0.0;
  for (int i = 0; i < n_; ++i) {
    for (int j = 0; j < n_; ++j) px[static_cast<size_t>(i)] += p_[at(i, j)] * x[j];
    r += x[i] * px[static_cast<size_t>(i)];
  }
  // A sample so large that x'Px overflows (a glitched count of 1e200: finite, so not a bad
  // measurement) would write NaN into P and theta for good: it is dropped.
  if (!std::isfinite(r)) return;
  const double err = std::clamp(y - predict(x), -maxError, maxError);
  // EFRA (exponential forgetting and resetting, Salgado, Goodwin & Middleton 1988):
  //   P' = P / lambda - P x x' P / (1 + x' P x) + beta I - delta2 P^2
  // keeps P between two bounds whatever the excitation: no wind-up while the load does not
  // move, and no direction frozen by a long stationary stretch.
  std::array<double, kMax * kMax> next{};
  for (int i = 0; i < n_; ++i)
    for (int j = 0; j < n_; ++j) {
      double p2 = 0.0;
      for (int k = 0; k < n_; ++k) p2 += p_[at(i, k)] * p_[at(k, j)];
      next[at(i, j)] = p_[at(i, j)] / lambda_ - px[static_cast<size_t>(i)] * px[static_cast<size_t>(j)] / (1.0 + r) +
                       (i == j ? beta_ : 0.0) - delta2_ * p2;
    }
  std::array<double, kMax> theta = theta_;
  for (int i = 0; i < n_; ++i) theta[static_cast<size_t>(i)] += px[static_cast<size_t>(i)] / (1.0 + r) * err;
  for (int i = 0; i < n_; ++i) {
    if (!std::isfinite(theta[static_cast<size_t>(i)])) return;
    for (int j = 0; j < n_; ++j)
      if (!std::isfinite(next[at(i, j)])) return;
  }
  theta_ = theta;
  for (int i = 0; i < n_; ++i)
    for (int j = 0; j < n_; ++j) p_[at(i, j)] = 0.5 * (next[at(i, j)] + next[at(j, i)]);
  ++samples_;
}

// ---------------------------------------------------------------------------------------------
// Deferrable work.

double WorkBudget::remaining_ms(int64_t now_ns) const {
  if (unlimited()) return std::numeric_limits<double>::infinity();
  return now_ns >= deadline_ns_ ? 0.0 : static_cast<double>(deadline_ns_ - now_ns) * 1e-6;
}

bool WorkBudget::poll() {
  if (expired_) return true;
  if (unlimited() || source_.now_ns == nullptr) return false;
  if (calls_++ % stride_ == 0) expired_ = source_.now_ns(source_.context) >= deadline_ns_;
  return expired_;
}

uint32_t WorkBudget::operations(int64_t now_ns, double nsPerOperation, uint32_t minOperations) const {
  if (unlimited()) return 0;
  const double left_ns = now_ns >= deadline_ns_ ? 0.0 : static_cast<double>(deadline_ns_ - now_ns);
  const double per = nsPerOperation > 0.0 && std::isfinite(nsPerOperation) ? nsPerOperation : 1.0;
  return static_cast<uint32_t>(std::clamp(left_ns / per, static_cast<double>(minOperations), 1e9));
}

void UnitCost::observe(uint64_t units, int64_t elapsed_ns) {
  if (units < minUnits_ || elapsed_ns < 0) return;
  ns_ = smoothing_ * ns_ + (1.0 - smoothing_) * static_cast<double>(elapsed_ns) / static_cast<double>(units);
}

// ---------------------------------------------------------------------------------------------
// Governor.

std::string Governor::validate(const GovernorConfig& c) {
  if (!(std::isfinite(c.rate_hz) && c.rate_hz > 0.0 && c.rate_hz <= 1000.0))
    return bad("rate_hz", c.rate_hz, "out of range (> 0 and <= 1000)");
  if (!(std::isfinite(c.frameBudget_ms) && c.frameBudget_ms >= 0.0))
    return bad("frame_budget_ms", c.frameBudget_ms, "out of range (>= 0; 0 = the frame period)");
  if (!(c.increaseBelow > 0.0 && c.increaseBelow < c.decreaseAbove))
    return bad("increase_below", c.increaseBelow, "out of range (> 0 and < decrease_above)");
  if (!(c.decreaseAbove > 0.0 && c.decreaseAbove <= 1.5))
    return bad("decrease_above", c.decreaseAbove, "out of range (> increase_below and <= 1.5)");
  if (!(std::isfinite(c.marginSigmas) && c.marginSigmas >= 0.0 && c.marginSigmas <= 10.0))
    return bad("margin_sigmas", c.marginSigmas, "out of range (0 ..= 10)");
  double share = 0.0;
  for (int p = 0; p < kGovPhases; ++p) {
    const double s = c.phaseShare[static_cast<size_t>(p)];
    if (!(std::isfinite(s) && s >= 0.0)) {
      const std::string key = std::string("share_") + govPhaseName(static_cast<GovPhase>(p));
      return bad(key.c_str(), s, "out of range (>= 0)");
    }
    const bool present = alwaysPresent(static_cast<GovPhase>(p)) ||
                         c.knobs[static_cast<size_t>(phaseLayer(static_cast<GovPhase>(p)))].present;
    if (present) share += s;
  }
  if (!(share > 0.0)) return bad("share_*", share, "the present phases' shares sum to 0");
  if (!(c.maxDecrease > 0.0 && c.maxDecrease < 1.0)) return bad("max_decrease", c.maxDecrease, "out of range (> 0 and < 1)");
  if (!(c.maxIncrease > 1.0 && c.maxIncrease <= 4.0)) return bad("max_increase", c.maxIncrease, "out of range (> 1 and <= 4)");
  if (c.raiseInterval_frames < 1) return bad("raise_interval_frames", c.raiseInterval_frames, "out of range (>= 1)");
  if (c.holdAfterDecrease_frames < 0)
    return bad("hold_after_decrease_frames", c.holdAfterDecrease_frames, "out of range (>= 0)");
  if (!(c.emergencyScale > 0.0 && c.emergencyScale <= 1.0))
    return bad("emergency_scale", c.emergencyScale, "out of range (> 0 and <= 1)");
  if (!(c.emergencyMaxDecrease > 0.0 && c.emergencyMaxDecrease <= c.emergencyScale))
    return bad("emergency_max_decrease", c.emergencyMaxDecrease, "out of range (> 0 and <= emergency_scale)");
  if (c.emergencyFrames < 0) return bad("emergency_frames", c.emergencyFrames, "out of range (>= 0)");
  if (!(c.emergencyDeferScale > 0.0 && c.emergencyDeferScale <= 1.0))
    return bad("emergency_defer_scale", c.emergencyDeferScale, "out of range (> 0 and <= 1)");
  if (!(c.forgetting > 0.5 && c.forgetting <= 1.0)) return bad("forgetting", c.forgetting, "out of range (> 0.5 and <= 1)");
  if (!(c.errorSmoothing >= 0.0 && c.errorSmoothing < 1.0))
    return bad("error_smoothing", c.errorSmoothing, "out of range (>= 0 and < 1)");
  if (!(std::isfinite(c.trendHorizon_frames) && c.trendHorizon_frames >= 0.0 && c.trendHorizon_frames <= 100.0))
    return bad("trend_horizon_frames", c.trendHorizon_frames, "out of range (0 ..= 100)");
  if (c.warmup_frames < 0) return bad("warmup_frames", c.warmup_frames, "out of range (>= 0)");
  if (!(c.spikeWindow_frames >= 0 && c.spikeWindow_frames <= 1000000))
    return bad("spike_window_frames", c.spikeWindow_frames, "out of range (0 ..= 1000000)");
  for (int l = 0; l < kGovLayers; ++l) {
    const GovKnob& k = c.knobs[static_cast<size_t>(l)];
    if (!k.present) continue;
    const std::string n = govLayerName(static_cast<GovLayer>(l));
    if (!(std::isfinite(k.min) && k.min > 0.0)) return bad((n + ".min").c_str(), k.min, "out of range (> 0)");
    if (!(std::isfinite(k.max) && k.max > k.min)) return bad((n + ".max").c_str(), k.max, "out of range (> min)");
    if (!std::isfinite(k.initial)) return bad((n + ".initial").c_str(), k.initial, "not finite");
    if (!(std::isfinite(k.loadExponent) && k.loadExponent != 0.0 && std::abs(k.loadExponent) <= 8.0))
      return bad((n + ".load_exponent").c_str(), k.loadExponent, "out of range (non-zero, -8 ..= 8)");
    if (!(std::isfinite(k.quantum) && k.quantum >= 0.0 && k.quantum <= k.max - k.min))
      return bad((n + ".quantum").c_str(), k.quantum, "out of range (0 ..= max - min)");
    if (!(std::isfinite(k.loadUnit) && k.loadUnit > 0.0))
      return bad((n + ".load_unit").c_str(), k.loadUnit, "out of range (> 0)");
    if (k.loadBudget && k.loadExponent != 1.0)
      return bad((n + ".load_exponent").c_str(), k.loadExponent, "must be 1 for a budget knob (the load is at most the knob)");
  }
  return {};
}

Governor::Governor(const GovernorConfig& config) { configure(config, false); }

void Governor::reconfigure(const GovernorConfig& config) { configure(config, true); }

void Governor::configure(const GovernorConfig& c, bool keepState) {
  assert(validate(c).empty() && "Governor: invalid config (call Governor::validate first)");
  const std::array<bool, kGovLayers> wasPresent = layerPresent_;
  config_ = c;
  budget_ms_ = c.frameBudget_ms > 0.0 ? c.frameBudget_ms : 1000.0 / c.rate_hz;
  for (int l = 0; l < kGovLayers; ++l) layerPresent_[static_cast<size_t>(l)] = c.knobs[static_cast<size_t>(l)].present;
  double share = 0.0;
  for (int p = 0; p < kGovPhases; ++p) {
    const auto ph = static_cast<GovPhase>(p);
    const bool present = alwaysPresent(ph) || layerPresent_[static_cast<size_t>(phaseLayer(ph))];
    phasePresent_[static_cast<size_t>(p)] = present;
    if (present) share += c.phaseShare[static_cast<size_t>(p)];
  }
  for (int p = 0; p < kGovPhases; ++p) {
    const auto i = static_cast<size_t>(p);
    phaseBudget_ms_[i] = phasePresent_[i] ? budget_ms_ * c.phaseShare[i] / share : 0.0;
    // One parameter for the constant, one per layer feeding the phase.
    int n = 1;
    for (int l = 0; l < kGovLayers; ++l)
      if (layerPresent_[static_cast<size_t>(l)] && feeds(static_cast<GovLayer>(l), static_cast<GovPhase>(p))) ++n;
    if (!keepState || model_[i].size() != n || layerPresent_ != wasPresent)
      model_[i] = ForgettingLeastSquares(n, c.forgetting);
  }
  for (int l = 0; l < kGovLayers; ++l) {
    const auto i = static_cast<size_t>(l);
    const GovKnob& k = c.knobs[i];
    if (!k.present) {
      knob_[i] = kGovNaN;
      load_[i] = prevLoad_[i] = trend_[i] = 0.0;
      continue;
    }
    const double start = keepState && wasPresent[i] ? knob_[i] : k.initial;
    knob_[i] = std::clamp(start, k.min, k.max);
    if (!(keepState && wasPresent[i])) {
      load_[i] = prevLoad_[i] = trend_[i] = 0.0;
      prevKnob_[i] = knob_[i];
      lastDirection_[i] = 0;
      quantumRaiseFrame_[i] = quantumWait_[i] = 0;
      quantumPending_[i] = false;
      quantumRaise_ms_[i] = quantumFrom_ms_[i] = 0.0;
    }
  }
  if (!keepState) {
    // Prior on the prediction error: 5 % of the budget, so the first frames keep a margin.
    errorScale_ = 0.05 * budget_ms_;
    spikeBlocks_.fill(0.0);
    spikeFrames_ = 0;
    phaseScale_.fill(0.0);
    other_ms_ = 0.0;
    otherScale_ = 0.0;
    otherSamples_ = 0;
    havePrediction_ = false;
    framesSinceRaise_ = 0;
    hold_ = 0;
    emergencyLeft_ = 0;
    stats_ = {};
    lastDecision_ = {};
  }
  lastDecision_.knob = knob_;
  for (size_t l = 0; l < static_cast<size_t>(kGovLayers); ++l)
    if (!(keepState && wasPresent[l] && layerPresent_[l])) lastDecision_.loadCap[l] = layerPresent_[l] ? kInfinity : kGovNaN;
}

double Governor::deferrableBudget_ms(GovPhase p) const {
  return phaseBudget_ms_[idx(p)] * (emergencyLeft_ > 0 ? config_.emergencyDeferScale : 1.0);
}

WorkBudget Governor::workBudget(GovPhase p, int64_t phaseStart_ns, TimeSource source) const {
  const double ms = deferrableBudget_ms(p);
  if (!(ms > 0.0)) return {};
  // A budget past the end of the clock's range (validate() takes any finite frame_budget_ms) is no
  // limit: converting it to int64_t was undefined (x86: INT64_MIN, a deadline long past).
  const double ns = ms * 1e6;
  if (!(ns < static_cast<double>(WorkBudget::kNever) - static_cast<double>(phaseStart_ns))) return {};
  return WorkBudget(phaseStart_ns + static_cast<int64_t>(ns), source);
}

int Governor::features(GovPhase p, const std::array<double, kGovLayers>& load, double* x) const {
  int n = 0;
  x[n++] = 1.0;
  for (int l = 0; l < kGovLayers; ++l) {
    const auto i = static_cast<size_t>(l);
    if (layerPresent_[i] && feeds(static_cast<GovLayer>(l), p)) x[n++] = load[i] / config_.knobs[i].loadUnit;
  }
  return n;
}

Governor::Prediction Governor::predict(const std::array<double, kGovLayers>& loadScale) const {
  Prediction out;
  std::array<double, kGovLayers> load{};
  for (size_t l = 0; l < static_cast<size_t>(kGovLayers); ++l) {
    if (!layerPresent_[l]) continue;
    const double growth = std::exp(std::clamp(trend_[l], 0.0, kMaxTrend) * config_.trendHorizon_frames);
    load[l] = load_[l] * growth * loadScale[l];
  }
  double total = other_ms_;
  for (int p = 0; p < kGovPhases; ++p) {
    if (!phasePresent_[static_cast<size_t>(p)]) continue;
    const auto ph = static_cast<GovPhase>(p);
    const ForgettingLeastSquares& m = model_[static_cast<size_t>(p)];
    double x[ForgettingLeastSquares::kMax];
    features(ph, load, x);
    double y = m.theta(0);
    int k = 1;
    for (int l = 0; l < kGovLayers; ++l) {
      const auto i = static_cast<size_t>(l);
      if (!(layerPresent_[i] && feeds(static_cast<GovLayer>(l), ph))) continue;
      const double part = std::max(0.0, m.theta(k)) * x[k];
      out.variable_ms[i] += part;
      y += part;
      ++k;
    }
    out.phase_ms[static_cast<size_t>(p)] = std::max(0.0, y);
    total += std::max(0.0, y);
  }
  out.total_ms = std::max(0.0, total);
  return out;
}

// The common load multiplier s of the movable layers that brings the prediction to aim_ms.
// At least a quarter of the frame is taken as variable when the movable layers have load, so an
// unfitted model (all constant) still moves the knobs; the loop corrects the step next frame.
double Governor::solveScale(const Prediction& held, double aim_ms, const std::array<bool, kGovLayers>& movable) const {
  double variable = 0.0, load = 0.0;
  for (size_t l = 0; l < static_cast<size_t>(kGovLayers); ++l)
    if (movable[l]) variable += held.variable_ms[l], load += load_[l];
  if (!(load > 0.0)) return 1.0;
  variable = std::max(variable, 0.25 * held.total_ms);
  if (!(variable > 0.0)) return 1.0;
  const double fixed = held.total_ms - variable;
  return (aim_ms - fixed) / variable;
}

double Governor::quantise(GovLayer l, double v, bool towardsLess) const {
  const GovKnob& k = config_.knobs[idx(l)];
  if (k.quantum > 0.0) {
    const double q = v / k.quantum;
    // Less detail is a larger value when the load falls with the value (tolerances).
    const double r = towardsLess ? (k.loadExponent < 0 ? std::ceil(q - 1e-9) : std::floor(q + 1e-9)) : std::round(q);
    v = r * k.quantum;
  }
  return std::clamp(v, k.min, k.max);
}

void Governor::applyScale(double s, bool decrease, std::array<double, kGovLayers>& next) const {
  for (int l = 0; l < kGovLayers; ++l) {
    const auto i = static_cast<size_t>(l);
    if (!layerPresent_[i]) continue;
    const GovKnob& k = config_.knobs[i];
    // A budget above the load does not bind: a decrease cuts from the load.
    const double from = k.loadBudget && decrease && load_[i] > 0.0 ? std::min(knob_[i], load_[i]) : knob_[i];
    const double v = from * std::pow(s, 1.0 / k.loadExponent);
    next[i] = quantise(static_cast<GovLayer>(l), v, true);
    // Rounding towards less detail must not turn a decrease into a raise or the reverse.
    const bool less = k.loadExponent < 0 ? next[i] > knob_[i] : next[i] < knob_[i];
    const bool more = k.loadExponent < 0 ? next[i] < knob_[i] : next[i] > knob_[i];
    if ((decrease && more) || (!decrease && less)) next[i] = knob_[i];
  }
}

double Governor::knobLoadScale(size_t l, double v) const {
  const GovKnob& k = config_.knobs[l];
  if (v == knob_[l]) return 1.0;
  if (!k.loadBudget) return std::pow(v / knob_[l], k.loadExponent);
  // A budget: raised, the layer takes up what it is given; lowered, only what is above the load
  // it drew goes.
  if (v > knob_[l] || !(load_[l] > 0.0)) return v / knob_[l];
  return std::min(1.0, v / load_[l]);
}

std::array<double, kGovLayers> Governor::knobLoadScales(const std::array<double, kGovLayers>& next) const {
  std::array<double, kGovLayers> scale = kHeld;
  for (size_t l = 0; l < static_cast<size_t>(kGovLayers); ++l)
    if (layerPresent_[l]) scale[l] = knobLoadScale(l, next[l]);
  return scale;
}

double Governor::margin() const { return config_.marginSigmas * errorScale_; }

double Governor::bandTop_ms() const {
  return config_.decreaseAbove * budget_ms_ - std::max(0.0, spike() - (1.0 - config_.decreaseAbove) * budget_ms_);
}

double Governor::spike() const { return *std::max_element(spikeBlocks_.begin(), spikeBlocks_.end()); }

const GovDecision& Governor::update(const GovSample& sample) {
  ++stats_.frames;
  const GovernorConfig& c = config_;

  // Measurements: keep the good ones, count the bad.
  std::array<bool, kGovPhases> phaseGood{};
  bool allPhasesGood = true;
  double phaseSum = 0.0;
  for (size_t p = 0; p < static_cast<size_t>(kGovPhases); ++p) {
    if (!phasePresent_[p]) continue;
    phaseGood[p] = goodMeasurement(sample.phase_ms[p]);
    if (phaseGood[p]) {
      phaseSum += sample.phase_ms[p];
      if (sample.phase_ms[p] > phaseBudget_ms_[p]) ++stats_.phaseOverruns[p];
    } else {
      ++stats_.ignored;
      allPhasesGood = false;
    }
  }
  std::array<double, kGovLayers> frameLoad = load_;
  for (size_t l = 0; l < static_cast<size_t>(kGovLayers); ++l) {
    if (!layerPresent_[l]) continue;
    if (goodMeasurement(sample.load[l])) frameLoad[l] = sample.load[l];
    else ++stats_.ignored;
  }
  double frame_ms = sample.frame_ms;
  if (!goodMeasurement(frame_ms)) {
    if (!std::isnan(frame_ms)) ++stats_.ignored;  // NaN means "not measured": use the phases
    frame_ms = allPhasesGood ? phaseSum : kGovNaN;
  }

  // A load jump (> 1.5x either way) explains a large residual: learn it in full.
  bool loadJump = false;
  for (size_t l = 0; l < static_cast<size_t>(kGovLayers); ++l)
    if (layerPresent_[l] && goodMeasurement(sample.load[l]) && prevLoad_[l] > 0.0 && sample.load[l] > 0.0)
      loadJump = loadJump || std::abs(std::log(sample.load[l] / prevLoad_[l])) > std::log(1.5);

  // Learn: phase models on this frame's loads, the unmodelled rest, the prediction error.
  for (int p = 0; p < kGovPhases; ++p) {
    const auto i = static_cast<size_t>(p);
    if (!phaseGood[i]) continue;
    double x[ForgettingLeastSquares::kMax];
    features(static_cast<GovPhase>(p), frameLoad, x);
    ForgettingLeastSquares& m = model_[i];
    const double residual = std::abs(sample.phase_ms[i] - m.predict(x));
    const bool settled = m.samples() >= 10 && !loadJump;
    const double clip = settled ? 4.0 * phaseScale_[i] + 0.005 * budget_ms_ : std::numeric_limits<double>::infinity();
    phaseScale_[i] = m.samples() == 0 ? 0.0 : 0.9 * phaseScale_[i] + 0.1 * std::min(residual, clip);
    m.update(x, sample.phase_ms[i], clip);
  }
  const bool frameGood = !std::isnan(frame_ms);
  if (frameGood && allPhasesGood) {
    // The unmodelled rest, clipped like a phase residual once settled: one stall outside the
    // phases (present blocked, the process suspended) must not stay in the prediction for the
    // frames after it (it would cut detail to the knobs' bounds; its own frame is an overrun,
    // which the emergency step answers).
    const double other = std::max(0.0, frame_ms - phaseSum);
    const double residual = std::abs(other - other_ms_);
    const bool settled = otherSamples_ >= 10 && !loadJump;
    const double clip = settled ? 4.0 * otherScale_ + 0.005 * budget_ms_ : std::numeric_limits<double>::infinity();
    otherScale_ = otherSamples_ == 0 ? 0.0 : 0.9 * otherScale_ + 0.1 * std::min(residual, clip);
    other_ms_ = otherSamples_ == 0 ? other : 0.8 * other_ms_ + 0.2 * std::clamp(other, other_ms_ - clip, other_ms_ + clip);
    ++otherSamples_;
  }
  if (frameGood && havePrediction_) {
    const double err = std::min(std::abs(frame_ms - lastDecision_.predicted_ms), 4.0 * errorScale_ + 0.01 * budget_ms_);
    errorScale_ = c.errorSmoothing * errorScale_ + (1.0 - c.errorSmoothing) * 1.25 * err;
    // Spikes: a load jump explains its excess (that is the emergency's business), noise does not.
    // One larger than the whole band's headroom, (1 - increaseBelow) * B, would overrun from
    // anywhere in the band (another process holding the cores for a while): not planned for.
    const double excess = frame_ms - lastDecision_.predicted_ms;
    const bool planned = !loadJump && excess <= (1.0 - c.increaseBelow) * budget_ms_;
    if (c.spikeWindow_frames > 0) {
      const int64_t block = std::max<int64_t>(1, c.spikeWindow_frames / static_cast<int64_t>(spikeBlocks_.size()));
      if (spikeFrames_ >= block) {  // the oldest block leaves the window
        std::rotate(spikeBlocks_.rbegin(), spikeBlocks_.rbegin() + 1, spikeBlocks_.rend());
        spikeBlocks_[0] = 0.0;
        spikeFrames_ = 0;
      }
      ++spikeFrames_;
      if (planned) spikeBlocks_[0] = std::max(spikeBlocks_[0], excess);
    }
  }
  stats_.errorScale_ms = errorScale_;
  stats_.spike_ms = spike();
  // Load trend, with the knob's own effect removed.
  for (size_t l = 0; l < static_cast<size_t>(kGovLayers); ++l) {
    if (!layerPresent_[l] || !goodMeasurement(sample.load[l])) continue;
    const double now = sample.load[l];
    if (c.knobs[l].loadBudget) {
      trend_[l] = 0.0;  // the budget bounds the load: no growth beyond it to anticipate
    } else if (now > 0.0 && prevLoad_[l] > 0.0) {
      const double r = std::log(now / prevLoad_[l]) - c.knobs[l].loadExponent * std::log(knob_[l] / prevKnob_[l]);
      trend_[l] = 0.5 * trend_[l] + 0.5 * r;
    }
    prevLoad_[l] = now;
    prevKnob_[l] = knob_[l];
  }
  load_ = frameLoad;

  GovDecision d;
  d.knob = knob_;
  if (!frameGood) {
    ++stats_.invalidFrames;
    d.action = GovAction::Invalid;
    const Prediction held = predict(kHeld);
    d.predicted_ms = d.predictedHeld_ms = held.total_ms;
    d.margin_ms = margin();
    d.loadCap = lastDecision_.loadCap;  // nothing learnt: the caps stand
    lastDecision_ = d;
    return lastDecision_;
  }
  d.overrun = frame_ms > budget_ms_;
  if (d.overrun) ++stats_.overruns;

  // Decide.
  const Prediction held = predict(kHeld);
  d.predictedHeld_ms = held.total_ms;
  d.margin_ms = margin();
  d.spike_ms = spike();
  const double withMargin = held.total_ms + d.margin_ms;
  // The dead band [bottom, top]: the spike headroom lowers its top, and its bottom with it only
  // where the band would otherwise shrink below half its width (a raise must not cross it).
  const double top = bandTop_ms();
  const double bottom = std::min(c.increaseBelow * budget_ms_, top - 0.5 * (c.decreaseAbove - c.increaseBelow) * budget_ms_);
  const double aim = 0.5 * (top + bottom) - d.margin_ms;
  d.bandTop_ms = top;
  ++framesSinceRaise_;
  if (hold_ > 0) --hold_;
  if (emergencyLeft_ > 0) --emergencyLeft_;

  // Waits of coarse knobs' one-quantum raises (see quantumWait_): over when the last raise held,
  // or when the frame is much lighter than the one that took a raise back.
  for (size_t l = 0; l < static_cast<size_t>(kGovLayers); ++l) {
    if (quantumPending_[l] && stats_.frames - quantumRaiseFrame_[l] > std::max(1, c.holdAfterDecrease_frames)) {
      quantumPending_[l] = false;
      quantumWait_[l] = 0;
    }
    if (quantumWait_[l] > 0 && frame_ms < 0.6 * quantumFrom_ms_[l]) quantumWait_[l] = 0;
  }

  // Movable layers: present, with load, and not at the bound in the wanted direction.
  auto movable = [&](bool decrease) {
    std::array<bool, kGovLayers> m{};
    for (size_t l = 0; l < static_cast<size_t>(kGovLayers); ++l) {
      if (!layerPresent_[l]) continue;
      const GovKnob& k = c.knobs[l];
      const bool lessIsUp = k.loadExponent < 0;
      const bool atLeast = lessIsUp ? knob_[l] >= k.max : knob_[l] <= k.min;  // least detail
      const bool atMost = lessIsUp ? knob_[l] <= k.min : knob_[l] >= k.max;   // most detail
      m[l] = decrease ? !atLeast : !atMost;
    }
    return m;
  };

  std::array<double, kGovLayers> next = knob_;
  double s = 1.0;
  if (stats_.frames <= c.warmup_frames && !d.overrun) {
    d.action = GovAction::Warmup;
    if (frame_ms > top) {
      // No model yet: a frame above the band is cut in proportion (the whole frame taken as load).
      d.action = GovAction::Decrease;
      s = std::clamp((aim + d.margin_ms) / frame_ms, c.maxDecrease, 1.0);
      applyScale(s, true, next);
      hold_ = c.holdAfterDecrease_frames;
    }
  } else if (d.overrun) {
    d.action = GovAction::Emergency;
    ++stats_.emergencies;
    s = std::clamp(solveScale(held, aim, movable(true)), c.emergencyMaxDecrease, c.emergencyScale);
    applyScale(s, true, next);
    hold_ = c.holdAfterDecrease_frames;
    emergencyLeft_ = c.emergencyFrames;
  } else if (withMargin > top) {
    d.action = GovAction::Decrease;
    s = std::clamp(solveScale(held, aim, movable(true)), c.maxDecrease, 1.0);
    applyScale(s, true, next);
    hold_ = c.holdAfterDecrease_frames;
  } else if (withMargin < bottom && hold_ == 0 && framesSinceRaise_ >= c.raiseInterval_frames) {
    d.action = GovAction::Increase;
    s = std::clamp(solveScale(held, aim, movable(false)), 1.0, c.maxIncrease);
    applyScale(s, false, next);
    // A quantised knob too coarse for the step: one quantum more detail if that still fits.
    for (size_t l = 0; l < static_cast<size_t>(kGovLayers); ++l) {
      const GovKnob& k = c.knobs[l];
      if (!layerPresent_[l] || k.quantum <= 0.0 || next[l] != knob_[l] || !movable(false)[l]) continue;
      if (stats_.frames - quantumRaiseFrame_[l] < quantumWait_[l]) continue;  // a recent one was taken back
      const double v = quantise(static_cast<GovLayer>(l), knob_[l] + (k.loadExponent < 0 ? -k.quantum : k.quantum), false);
      std::array<double, kGovLayers> step = knob_;
      step[l] = v;
      if (predict(knobLoadScales(step)).total_ms < aim) {
        next[l] = v;
        quantumRaiseFrame_[l] = stats_.frames;
        quantumPending_[l] = true;
        quantumRaise_ms_[l] = frame_ms;
      }
    }
  } else {
    d.action = GovAction::Hold;
  }

  // Phase budgets: a layer whose own phase is predicted over its budget gives up detail too.
  if (c.enforcePhaseBudgets && d.action != GovAction::Warmup && d.action != GovAction::Increase) {
    for (size_t l = 0; l < static_cast<size_t>(kGovLayers); ++l) {
      if (!layerPresent_[l]) continue;
      const size_t p = idx(layerPhase(static_cast<GovLayer>(l)));
      const GovKnob& k = c.knobs[l];
      std::array<double, kGovLayers> moved = knob_;
      moved[l] = next[l];
      const Prediction at = predict(knobLoadScales(moved));
      if (!(at.phase_ms[p] > phaseBudget_ms_[p]) || !(at.variable_ms[l] > 0.0)) continue;
      const double fixed = std::max(0.0, model_[p].theta(0));
      const double part = at.phase_ms[p] - fixed;  // this layer's share of its own phase
      if (!(part > 0.0)) continue;
      const double sl = std::clamp((phaseBudget_ms_[p] - fixed) / part, c.maxDecrease, 1.0);
      const double v = quantise(static_cast<GovLayer>(l), next[l] * std::pow(sl, 1.0 / k.loadExponent), true);
      if (v != next[l]) {
        next[l] = v;
        hold_ = c.holdAfterDecrease_frames;
        if (d.action == GovAction::Hold) d.action = GovAction::Decrease;
      }
    }
  }

  // Apply: count moves and reversals, predict the next frame at the chosen knobs.
  const std::array<double, kGovLayers> scale = knobLoadScales(next);
  bool raised = false, lowered = false;
  for (size_t l = 0; l < static_cast<size_t>(kGovLayers); ++l) {
    if (!layerPresent_[l] || next[l] == knob_[l]) continue;
    const GovKnob& k = c.knobs[l];
    const int dir = (k.loadExponent < 0) == (next[l] < knob_[l]) ? 1 : -1;
    if (lastDirection_[l] != 0 && dir != lastDirection_[l]) ++stats_.directionChanges[l];
    lastDirection_[l] = dir;
    if (dir < 0 && quantumPending_[l]) {
      // A one-quantum raise taken back within the hold: wait longer before the next.
      const int64_t hold = std::max(1, c.holdAfterDecrease_frames);
      quantumWait_[l] = std::min(std::max(4 * hold, 2 * quantumWait_[l]), 64 * hold);
      quantumFrom_ms_[l] = quantumRaise_ms_[l];
      quantumPending_[l] = false;
    }
    (dir > 0 ? raised : lowered) = true;
  }
  if (raised) ++stats_.increases;
  if (lowered) ++stats_.decreases;
  // A raise or decrease that moved nothing (every layer at its bound) is a hold.
  if (!raised && !lowered && (d.action == GovAction::Increase || d.action == GovAction::Decrease)) d.action = GovAction::Hold;
  // The raise interval counts from the last raise that moved a knob (a raise that moved nothing
  // is a hold: Governor.AnIncreaseThatMovedNothingDoesNotRestartTheRaiseInterval).
  if (d.action == GovAction::Increase) framesSinceRaise_ = 0;
  knob_ = next;
  d.knob = knob_;
  d.loadScale = s;
  d.predicted_ms = predict(scale).total_ms;
  // Load caps: this frame's loads, grown by at most the frame's headroom to the top of the dead
  // band. Proportional (no intercept): the least growth any cost line through this frame allows,
  // so a badly fitted model cannot loosen it; never below this frame's load.
  const double growth = frame_ms > 0.0 ? std::max(1.0, (top - d.margin_ms) / frame_ms) : kInfinity;
  for (size_t l = 0; l < static_cast<size_t>(kGovLayers); ++l) {
    if (!layerPresent_[l]) continue;
    d.loadCap[l] = stats_.frames <= c.warmup_frames || !(frameLoad[l] > 0.0) ? kInfinity : frameLoad[l] * growth;
  }
  havePrediction_ = true;
  lastDecision_ = d;
  return lastDecision_;
}

}  // namespace ig::lod
