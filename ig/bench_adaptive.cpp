#include "ig/bench_adaptive.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "ig/clock.h"
#include "ig/json.h"

#include "ig/stats.h"
#include "render/context.h"
#include "render/dynamic_pass.h"
#include "render/perf_calibration.h"
#include "render/renderer.h"

namespace ig {
namespace {

using BenchClock = std::chrono::steady_clock;
constexpr int kModes = 4;  // percommand, octree, occlusion, adaptive
constexpr render::DynamicStrategy kStrategies[kModes] = {render::DynamicStrategy::PerCommand,
                                                         render::DynamicStrategy::Octree,
                                                         render::DynamicStrategy::Occlusion,
                                                         render::DynamicStrategy::Adaptive};

struct TraceRow {
  int frame = 0;
  const char* phase = "";
  uint32_t objects = 0;
  std::array<double, kModes> ms{};
  std::array<int, 3> adaptiveModes{};  // frames in each mode within the window
  uint32_t q = 0;
  uint64_t hidden = 0;
  lod::ModeInputs inputs;  // the adaptive pass's model terms on the window's last frame
};

}  // namespace

int runAdaptiveBench(const AdaptiveBenchOptions& o0) {
  AdaptiveBenchOptions o = o0;
  if (o.quick) {
    o.objects = std::min<uint32_t>(o.objects, 4000);
    o.framesPerPhase = std::min(o.framesPerPhase, 40);
    o.repeats = std::min(o.repeats, 2);
  }
  if (o.objects < 100 || o.objects > 1000000 || o.framesPerPhase < 10 || o.framesPerPhase > 100000 || o.window < 1 ||
      o.window > o.framesPerPhase || o.repeats < 1 || o.repeats > 20 || o.width_px < 16 || o.height_px < 16) {
    std::fprintf(stderr, "igbench adaptive: bad option (objects %u: 100 .. 1000000, frames per phase %d: >= 10, window %d: "
                 "1 .. frames per phase, repeats %d: 1 .. 20)\n",
                 o.objects, o.framesPerPhase, o.window, o.repeats);
    return 2;
  }
  std::string error;
  auto context = render::createContext(render::ContextKind::Headless, o.width_px, o.height_px, error);
  if (!context) {
    std::fprintf(stderr, "igbench adaptive: %s\n", error.c_str());
    return 3;
  }
  render::CalibrationOptions co;
  co.width_px = o.width_px;
  co.height_px = o.height_px;
  co.fragmentWork = 0;
  co.budget_s = o.quick ? 1.5 : 3.0;
  // Each constant the median of three runs: the choice between per-object commands and the
  // octree turns on t_s, t_c and T_draw, and one run on a shared machine measured t_s at 598 ns
  // where the runs around it measured 58 ... 184 (the adaptive pass then kept per-object commands
  // 17 % past the point where the octree was faster).
  co.runs = o.quick ? 1 : 3;
  render::CalibrationResult cal;
  std::string warning;
  if (!render::calibrate(o.cachePath, co, cal, error, &warning)) {
    std::fprintf(stderr, "igbench adaptive: %s\n", error.c_str());
    return 1;
  }
  if (!warning.empty()) std::fprintf(stderr, "igbench adaptive: calibration cache: %s\n", warning.c_str());

  render::Renderer renderer;
  if (!renderer.init(o.width_px, o.height_px, error)) {
    std::fprintf(stderr, "igbench adaptive: %s\n", error.c_str());
    return 3;
  }
  const uint32_t capacity = o.objects + 1024;
  lod::Camera cam;
  cam.aspect = static_cast<double>(o.width_px) / o.height_px;
  cam.near_m = 0.5;
  cam.far_m = 5000.0;
  render::Lighting light;
  light.fog = false;
  light.sunDirection = glm::normalize(glm::dvec3(0.3, -0.5, 0.8));

  const int phases = 3, frames = phases * o.framesPerPhase;
  const char* phaseNames[phases] = {"few-moving", "growing", "occluded"};
  // ms[rep][mode][frame]; the adaptive pass's choices per frame (the same in every repetition:
  // they depend on counts, not on the clock; checked below).
  std::vector<std::array<std::vector<double>, kModes>> ms(static_cast<size_t>(o.repeats));
  struct AdaptiveFrame {
    int mode = 0;
    uint32_t q = 0;
    uint64_t hidden = 0;
    lod::ModeInputs inputs;
  };
  std::vector<std::vector<AdaptiveFrame>> chosen(static_cast<size_t>(o.repeats));
  std::vector<uint32_t> objectsAt(static_cast<size_t>(frames));
  uint32_t switches = 0;
  // The application thread's CPU time per mode (until the GL calls return), summed over frames and repetitions.
  std::array<double, kModes> appCpu{};
  const auto t0 = BenchClock::now();
  for (int rep = 0; rep < o.repeats; ++rep) {
    // A fresh scene and fresh passes: every repetition replays the same animation.
    std::array<std::unique_ptr<render::DynamicPass>, kModes> passes;
    for (int m = 0; m < kModes; ++m) {
      render::DynamicPassConfig pc;
      pc.maxObjects = capacity;
      pc.bounds = {glm::dvec3(-128.0), glm::dvec3(128.0)};
      pc.octreeDepth = 6;
      pc.maxQueries = 8192;
      pc.constants = cal.constants;
      passes[m] = std::make_unique<render::DynamicPass>();
      if (!passes[m]->init(pc, error)) {
        std::fprintf(stderr, "igbench adaptive: %s\n", error.c_str());
        return 3;
      }
      passes[m]->setStrategy(kStrategies[m]);
      passes[m]->setOcclusionTests(8192);  // the fixed occlusion strategy tests every node it can
    }
    std::mt19937 rng(o.seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0), u01(0.0, 1.0);
    std::vector<render::DynamicObject> objs;
    objs.reserve(capacity);
    const auto randomBox = [&] {
      const double y = 30.0 + 80.0 * u01(rng);
      render::DynamicObject b;
      b.center_m = {0.62 * y * u(rng), y, 0.33 * y * u(rng)};
      b.halfSize_m = glm::dvec3(0.15 + 0.15 * u01(rng));
      b.yaw_deg = 180.0 * u(rng);
      b.rgba = 0xff000000u | (rng() & 0xffffffu);
      return b;
    };
    const auto addAll = [&](const render::DynamicObject& b) {
      for (auto& p : passes) p->add(b);
      objs.push_back(b);
    };
    const auto setAll = [&](uint32_t id, const render::DynamicObject& b) {
      for (auto& p : passes) p->set(id, b);
      objs[id] = b;
    };
    auto& repMs = ms[static_cast<size_t>(rep)];
    for (auto& v : repMs) v.reserve(static_cast<size_t>(frames));
    chosen[static_cast<size_t>(rep)].reserve(static_cast<size_t>(frames));
    // (At most the scene's final count: --objects may be below 300, and the growing phase adds
    // objects - fewMoving boxes.)
    const uint32_t fewMoving = std::min<uint32_t>(300, o.objects);
    for (int i = 0; i < 50; ++i) addAll(randomBox());
    for (int f = 0; f < frames; ++f) {
      const int phase = f / o.framesPerPhase;
      const int pf = f % o.framesPerPhase;
      // Scene edits (not timed; the same for every pass).
      if (phase == 0) {
        const uint32_t target = 50 + static_cast<uint32_t>((fewMoving - 50) * (pf + 1) / o.framesPerPhase);
        while (objs.size() < target) addAll(randomBox());
        for (uint32_t id = 0; id < objs.size(); ++id) {  // everything moves
          render::DynamicObject b = objs[id];
          b.center_m.x += 0.4 * std::sin(0.05 * f + id);
          b.center_m.z += 0.3 * std::cos(0.07 * f + id);
          b.yaw_deg = std::fmod(b.yaw_deg + 2.0, 360.0);
          setAll(id, b);
        }
      } else {
        if (phase == 1) {
          const uint32_t target =
              fewMoving + static_cast<uint32_t>(static_cast<uint64_t>(o.objects - fewMoving) * (pf + 1) / o.framesPerPhase);
          while (objs.size() < target) addAll(randomBox());
        } else if (pf % (o.framesPerPhase / 5) == 0 && pf / (o.framesPerPhase / 5) < 4) {
          // Walls just in front of the boxes, one after the other.
          const int w = pf / (o.framesPerPhase / 5);
          const double xs[4] = {-9.0, 9.0, 0.0, 0.0}, zs[4] = {0.0, 0.0, -6.0, 6.0};
          const glm::dvec3 half[4] = {{9.5, 0.5, 10.0}, {9.5, 0.5, 10.0}, {19.0, 0.5, 4.5}, {19.0, 0.5, 4.5}};
          addAll({{xs[w], 26.0, zs[w]}, half[w], 0.0, 0xff707070u});
        }
        // 1 % of the boxes move a little each frame.
        const auto n = static_cast<uint32_t>(objs.size());
        for (uint32_t id = static_cast<uint32_t>(f) % 100; id < n; id += 100) {
          if (objs[id].halfSize_m.x > 5.0) continue;  // walls stay
          render::DynamicObject b = objs[id];
          b.center_m.x += 0.05 * std::sin(0.1 * f + id);
          setAll(id, b);
        }
      }
      cam.heading_deg = 2.0 * std::sin(0.02 * f);
      // Draw the frame with every pass, rotating the order (also across repetitions).
      for (int k = 0; k < kModes; ++k) {
        const int m = (k + f + rep) % kModes;
        const auto a = BenchClock::now();
        const double c0 = threadCpuMs();
        renderer.beginFrame(cam, light);
        passes[m]->draw(renderer, static_cast<uint64_t>(f) + 1);
        renderer.endFrame();
        appCpu[m] += threadCpuMs() - c0;
        renderer.finish();
        repMs[m].push_back(std::chrono::duration<double, std::milli>(BenchClock::now() - a).count());
      }
      const render::DynamicFrameStats& as = passes[3]->stats();
      chosen[static_cast<size_t>(rep)].push_back(
          {static_cast<int>(as.mode), passes[3]->lastQ(), as.hiddenEstimate, passes[3]->lastModeInputs()});
      objectsAt[static_cast<size_t>(f)] = static_cast<uint32_t>(objs.size());
    }
    switches = passes[3]->modeSwitches();
  }
  const double wall_s = std::chrono::duration<double>(BenchClock::now() - t0).count();
  // Frames on which the adaptive pass chose another mode in some repetition than in the first.
  int modeDiffers = 0;
  for (int rep = 1; rep < o.repeats; ++rep)
    for (int f = 0; f < frames; ++f)
      modeDiffers += chosen[static_cast<size_t>(rep)][static_cast<size_t>(f)].mode != chosen[0][static_cast<size_t>(f)].mode;

  // Each frame's time per mode: the fastest of the repetitions (the machine's load only adds).
  std::array<std::vector<double>, kModes> all;
  for (int m = 0; m < kModes; ++m) {
    all[m].resize(static_cast<size_t>(frames));
    for (int f = 0; f < frames; ++f) {
      double best = ms[0][m][static_cast<size_t>(f)];
      for (int rep = 1; rep < o.repeats; ++rep) best = std::min(best, ms[static_cast<size_t>(rep)][m][static_cast<size_t>(f)]);
      all[m][static_cast<size_t>(f)] = best;
    }
  }
  // The spread between repetitions: median over frames and modes of (slowest - fastest) / fastest.
  std::vector<double> spread;
  if (o.repeats > 1) {
    for (int m = 0; m < kModes; ++m)
      for (int f = 0; f < frames; ++f) {
        double lo = all[m][static_cast<size_t>(f)], hi = lo;
        for (int rep = 0; rep < o.repeats; ++rep) hi = std::max(hi, ms[static_cast<size_t>(rep)][m][static_cast<size_t>(f)]);
        spread.push_back(100.0 * (hi - lo) / std::max(lo, 1e-9));
      }
  }
  const double spreadPct = median(spread);

  std::vector<TraceRow> trace;
  std::array<int, 3> modeFrames{};
  for (int w0 = 0; w0 + o.window <= frames; w0 += o.window) {
    TraceRow row;
    row.frame = w0 + o.window;
    row.phase = phaseNames[(row.frame - 1) / o.framesPerPhase];
    row.objects = objectsAt[static_cast<size_t>(row.frame - 1)];
    // The window's mean: a switch or a burst of tests costs what it costs (a median would hide
    // it); the repetitions have taken out the machine's noise already.
    for (int m = 0; m < kModes; ++m) {
      double sum = 0.0;
      for (int f = w0; f < w0 + o.window; ++f) sum += all[m][static_cast<size_t>(f)];
      row.ms[m] = sum / o.window;
    }
    for (int f = w0; f < w0 + o.window; ++f) {
      const AdaptiveFrame& a = chosen[0][static_cast<size_t>(f)];
      ++row.adaptiveModes[a.mode];
      row.q = std::max(row.q, a.q);
      row.hidden = std::max(row.hidden, a.hidden);
      row.inputs = a.inputs;
    }
    trace.push_back(row);
  }
  for (const AdaptiveFrame& a : chosen[0]) ++modeFrames[a.mode];

  // Ratios over windows (skip the first window: warm-up).
  double worst = 0.0, sumAdaptive = 0.0, sumBest = 0.0;
  int worstFrame = 0;
  for (size_t i = 1; i < trace.size(); ++i) {
    const TraceRow& r = trace[i];
    const double best = std::min({r.ms[0], r.ms[1], r.ms[2]});
    const double ratio = r.ms[3] / std::max(best, 1e-9);
    if (ratio > worst) worst = ratio, worstFrame = r.frame;
    sumAdaptive += r.ms[3];
    sumBest += best;
  }
  const double meanRatio = sumAdaptive / std::max(sumBest, 1e-9);
  std::array<double, kModes> mean{}, p99{};
  for (int m = 0; m < kModes; ++m) {
    double s = 0;
    for (double v : all[m]) s += v;
    mean[m] = s / static_cast<double>(std::max<size_t>(all[m].size(), 1));
    p99[m] = percentile(all[m], 99);
  }
  const char* names[kModes] = {"percommand", "octree", "occlusion", "adaptive"};
  // The device string (the calibration key: GL vendor, renderer and version, the CPU model) comes
  // from outside: escaped, and appended rather than printed into `buf` (a long one was cut off at
  // the buffer's size and left the JSON unterminated).
  std::string out = "{\"bench\":\"adaptive\",\"device\":" + jsonString(cal.key);
  char buf[512];
  std::snprintf(buf, sizeof buf,
                ",\"viewport\":[%d,%d],\"objects\":%u,\"frames\":%d,\"window\":%d,"
                "\"calibration_from_cache\":%s,\"calibration\":{\"frame_ns\":%.0f,\"tri_ns\":%.2f,\"frag_ns\":%.3f,"
                "\"command_ns\":%.0f,\"rerecord_ns\":%.0f,\"submit_ns\":%.0f,\"cull_ns\":%.1f,"
                "\"occlusion_test_ns\":%.0f,\"raster_tri_ns\":%.1f,\"edge_ns\":%.1f,\"draw_raster_ns\":%.1f,\"overlap\":%.2f,"
                "\"overlap_triangles\":%.0f},\"modes\":{",
                o.width_px, o.height_px, o.objects, frames, o.window, cal.fromCache ? "true" : "false",
                cal.constants.frame_ns, cal.constants.tri_ns, cal.constants.frag_ns, cal.constants.command_ns,
                cal.constants.rerecord_ns, cal.constants.submit_ns, cal.constants.cull_ns, cal.constants.occlusionTest_ns,
                cal.constants.rasterTri_ns, cal.constants.edge_ns, cal.constants.drawRaster_ns, cal.constants.overlap, cal.constants.overlapTriangles);
  out += buf;
  for (int m = 0; m < kModes; ++m) {
    std::snprintf(buf, sizeof buf, "%s\"%s\":{\"mean_ms\":%.3f,\"p99_ms\":%.3f,\"app_cpu_mean_ms\":%.3f}", m ? "," : "",
                  names[m], mean[m], p99[m], appCpu[m] / (static_cast<double>(frames) * o.repeats));
    out += buf;
  }
  std::snprintf(buf, sizeof buf,
                "},\"adaptive_worst_ratio\":%.3f,\"adaptive_worst_frame\":%d,\"adaptive_mean_ratio\":%.3f,"
                "\"adaptive_mode_frames\":{\"percommand\":%d,\"octree\":%d,\"occlusion\":%d},\"adaptive_switches\":%u,"
                "\"repeats\":%d,\"repeat_spread_pct_median\":%.1f,\"adaptive_mode_differs_frames\":%d,"
                "\"wall_s\":%.1f,\"trace\":[",
                worst, worstFrame, meanRatio, modeFrames[0], modeFrames[1], modeFrames[2], switches, o.repeats, spreadPct,
                modeDiffers, wall_s);
  out += buf;
  for (size_t i = 0; i < trace.size(); ++i) {
    const TraceRow& r = trace[i];
    const int dominant = static_cast<int>(std::max_element(r.adaptiveModes.begin(), r.adaptiveModes.end()) -
                                          r.adaptiveModes.begin());
    std::snprintf(buf, sizeof buf,
                  "%s{\"frame\":%d,\"phase\":\"%s\",\"objects\":%u,\"percommand_ms\":%.3f,\"octree_ms\":%.3f,"
                  "\"occlusion_ms\":%.3f,\"adaptive_ms\":%.3f,\"adaptive_mode\":\"%s\",\"q\":%u,\"hidden\":%llu,"
                  "\"cond5_percommand_ms\":%.3f,\"cond5_octree_ms\":%.3f,\"cond6_all_ms\":%.3f,\"cond6_visible_ms\":%.3f}",
                  i ? "," : "", r.frame, r.phase, r.objects, r.ms[0], r.ms[1], r.ms[2], r.ms[3],
                  lod::modeName(static_cast<lod::DynamicMode>(dominant)), r.q, static_cast<unsigned long long>(r.hidden),
                  (r.inputs.bufS_ns + r.inputs.fcS_ns) * 1e-6, (r.inputs.bufH_ns + r.inputs.fcH_ns) * 1e-6,
                  r.inputs.frameAll_ns * 1e-6, (r.inputs.frameVisible_ns + r.inputs.visTests_ns) * 1e-6);
    out += buf;
  }
  out += "]}\n";
  if (!o.tracePath.empty()) {
    FILE* f = std::fopen(o.tracePath.c_str(), "w");
    if (!f || std::fputs(out.c_str(), f) < 0) {
      std::fprintf(stderr, "igbench adaptive: --trace %s: cannot write\n", o.tracePath.c_str());
      if (f) std::fclose(f);
      return 1;
    }
    std::fclose(f);
  }
  if (o.json) {
    std::fputs(out.c_str(), stdout);
  } else {
    std::printf("adaptive: %u boxes, %d frames (%d per phase), %d repetitions (frame time = the fastest; median spread "
                "%.1f %%), %.1f s\n",
                o.objects, frames, o.framesPerPhase, o.repeats, spreadPct, wall_s);
    const lod::PerfConstants& k = cal.constants;
    std::printf("  constants: tri %.1f ns, frag %.2f ns, command %.0f ns, rerecord %.0f ns, submit %.0f ns, cull %.1f ns, "
                "occlusion test %.0f ns\n",
                k.tri_ns, k.frag_ns, k.command_ns, k.rerecord_ns, k.submit_ns, k.cull_ns, k.occlusionTest_ns);
    for (int m = 0; m < kModes; ++m) std::printf("  %-11s mean %8.3f ms  p99 %8.3f ms\n", names[m], mean[m], p99[m]);
    std::printf("  adaptive / best fixed: worst window %.3f (frame %d), mean %.3f (goal <= 1.10 and < 1)\n", worst,
                worstFrame, meanRatio);
    std::printf("  adaptive frames: percommand %d, octree %d, occlusion %d\n", modeFrames[0], modeFrames[1], modeFrames[2]);
  }
  return 0;
}

}  // namespace ig
