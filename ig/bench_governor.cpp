#include "ig/bench_governor.h"
#include "ig/json.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include <time.h>

#include "lod/governor.h"
#include "lod/heightfield.h"
#include "lod/roam.h"
#include "lod/terrain_grid.h"
#include "lod/triangle_slots.h"
#include "render/context.h"
#include "render/renderer.h"

namespace ig {
namespace {

using BenchClock = std::chrono::steady_clock;
constexpr double kSpacing_m = 30.0;

int64_t wallNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(BenchClock::now().time_since_epoch()).count();
}
// CPU time of the whole process (every thread: llvmpipe's rasterizer threads do the "GPU" work).
// Unlike wall time it does not grow while the process waits for a CPU another process holds.
int64_t cpuNs() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}
double processCpuMs() { return static_cast<double>(cpuNs()) * 1e-6; }
// The clock that frame work is measured with (--time): wall (default) or process CPU time.
bool gCpuClock = false;
int64_t nowNs() { return gCpuClock ? cpuNs() : wallNs(); }
int64_t readNs(const void*) { return nowNs(); }
double msBetween(int64_t a_ns, int64_t b_ns) { return static_cast<double>(b_ns - a_ns) * 1e-6; }

// The 1-minute load average (how busy the machine was: other processes' work shows up as
// frame time here). NaN if unreadable.
double loadAverage() {
  double v = std::nan("");
  if (FILE* f = std::fopen("/proc/loadavg", "r")) {
    if (std::fscanf(f, "%lf", &v) != 1) v = std::nan("");
    std::fclose(f);
  }
  return v;
}

// Nearest-rank percentile (as ig/stats.h's, whose header pulls in the service config).
double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto k = static_cast<size_t>(std::ceil(p / 100.0 * static_cast<double>(v.size())));
  return v[std::clamp<size_t>(k, 1, v.size()) - 1];
}

// The relief: the procedural mountains (2.5 km of relief) faded to 5 % of their height over
// the western third, so the plain has gentle hills and the east is high mountains.
struct Relief {
  std::vector<float> heights;
  int n = 0;
  double extent_m = 0.0;
  double maxHeight_m = 0.0;

  explicit Relief(int posts) : heights(static_cast<size_t>(posts) * static_cast<size_t>(posts)), n(posts) {
    lod::HeightfieldDesc d;
    d.seed = 20261123;
    d.postsX = d.postsY = posts;
    d.postSpacing_m = kSpacing_m;
    d.heightScale_m = 2500.0;
    lod::generateHeightfield(d, heights);
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        const double u = static_cast<double>(x) / (n - 1);
        double t = std::clamp((u - 0.35) / 0.25, 0.0, 1.0);
        t = t * t * (3.0 - 2.0 * t);
        heights[static_cast<size_t>(y) * static_cast<size_t>(n) + static_cast<size_t>(x)] *= static_cast<float>(0.1 + 0.9 * t);
      }
    extent_m = (n - 1) * kSpacing_m;
    maxHeight_m = static_cast<double>(*std::max_element(heights.begin(), heights.end()));
  }
  // Highest sample within radius_m of (x, y): the eye keeps clear of the ground nearby.
  double clearance(double x_m, double y_m, double radius_m) const {
    const int r = static_cast<int>(radius_m / kSpacing_m);
    const int cx = static_cast<int>(x_m / kSpacing_m), cy = static_cast<int>(y_m / kSpacing_m);
    float top = 0.0f;
    for (int y = std::max(0, cy - r); y <= std::min(n - 1, cy + r); ++y)
      for (int x = std::max(0, cx - r); x <= std::min(n - 1, cx + r); ++x)
        top = std::max(top, heights[static_cast<size_t>(y) * static_cast<size_t>(n) + static_cast<size_t>(x)]);
    return static_cast<double>(top);
  }
};

// The scripted flight, one lap of lap_s seconds (fractions of the lap):
//   [0, .25)    plain, flying north                                  light
//   [.25, .40)  turning right towards the mountains in the east      ramp up
//   [.40, .55)  flying east towards them                             heavy
//   .55         jump back over the plain, flying north               step down
//   [.70, .85)  jump into the mountains, flying north                step up, heavy
//   [.85, 1)    pitching down 45 deg to look at the ground ahead     ramp down
// Segment of the lap at time t_s: 0 .. 5 in the order above.
int flightSegment(double t_s, double lap_s) {
  const double u = std::fmod(t_s, lap_s) / lap_s;
  return u < 0.25 ? 0 : u < 0.40 ? 1 : u < 0.55 ? 2 : u < 0.70 ? 3 : u < 0.85 ? 4 : 5;
}
// A jump of the eye (into segment 0 from 5, into 3 and into 4): the load steps, unpredictably.
bool flightStep(int frame, double rate_hz, double lap_s) {
  if (frame == 0) return false;
  const int a = flightSegment((frame - 1) / rate_hz, lap_s), b = flightSegment(frame / rate_hz, lap_s);
  return a != b && (b == 0 || b == 3 || b == 4);
}

lod::Camera flightCamera(const Relief& relief, double t_s, double lap_s, double aspect) {
  const double E = relief.extent_m;
  const double u = std::fmod(t_s, lap_s) / lap_s;
  const double speed = 120.0 * lap_s / 30.0;  // m/s: the same track whatever the lap length
  auto tau = [&](double from) { return (u - from) * lap_s; };
  double x = 0, y = 0, heading = 0, pitch = -4.0;
  const double aEndY = 0.15 * E + speed * 0.25 * lap_s;
  if (u < 0.25) {
    x = 0.2 * E, y = 0.15 * E + speed * tau(0.0);
  } else if (u < 0.40) {
    x = 0.2 * E, y = aEndY, heading = 90.0 * (u - 0.25) / 0.15;
  } else if (u < 0.55) {
    x = 0.2 * E + speed * tau(0.40), y = aEndY, heading = 90.0;
  } else if (u < 0.70) {
    x = 0.22 * E, y = 0.5 * E + speed * tau(0.55);
  } else if (u < 0.85) {
    x = 0.7 * E, y = 0.1 * E + speed * tau(0.70);
  } else {
    x = 0.7 * E, y = 0.1 * E + speed * 0.15 * lap_s;
    pitch = -4.0 - 41.0 * std::min(1.0, (u - 0.85) / 0.10);
  }
  lod::Camera c;
  c.eye_m = {x, y, relief.clearance(x, y, 600.0) + 120.0};
  c.heading_deg = heading;
  c.pitch_deg = pitch;
  c.fovY_deg = 45.0;
  c.aspect = aspect;
  c.near_m = 0.5;
  c.far_m = 100000.0;
  return c;
}

struct FrameRow {
  double ms = 0, predicted_ms = 0, tolerance_px = 0;
  uint64_t triangles = 0;
  bool overrun = false;
  bool afterStep = false;  // a jump of the eye in this frame or the three before
  double cpu_ms = 0;       // process CPU time over the frame (all threads)
  bool capped = false;     // ROAM stopped at the governor's load cap
  uint64_t drawnSlots = 0; // triangles submitted: the slots up to the high-water mark (freed ones degenerate)
  // Wall-clock phases of the frame (they add up to ms): ROAM update, emission and upload; draw
  // calls; glFinish. They tell which part of an overrun frame was not predicted.
  double terrain_ms = 0, submit_ms = 0, gpu_ms = 0;
};

// One configuration: its own ROAM, triangle slots and renderer (FBO + mapped vertex buffer).
struct Run {
  const Relief& relief;
  std::unique_ptr<lod::Roam> roam;
  std::unique_ptr<lod::TriangleSlots> slots;
  std::vector<lod::RoamTriangle> triangles;
  std::vector<uint32_t> added, addedSlots, freed;
  std::vector<uint32_t> movedFrom, movedTo;
  std::vector<lod::RoamTriangle> slotTriangle;  // the triangle in each slot, for compaction moves
  render::Renderer renderer;
  std::span<lod::TerrainVertex> gpu;
  lod::UnitCost opCost{2000.0};
  double meshPerVisible = 1.0;  // ROAM's mesh over the visible triangles, last frame
  std::vector<FrameRow> rows;

  explicit Run(const Relief& r) : relief(r) {}

  bool init(int width, int height, size_t capacity, std::string& error) {
    lod::RoamConfig rc;
    rc.maxTriangles = capacity;
    roam = std::make_unique<lod::Roam>(relief.heights, relief.n, relief.n, kSpacing_m, glm::dvec3(0.0), rc);
    slots = std::make_unique<lod::TriangleSlots>(capacity);
    triangles.resize(capacity);
    added.resize(capacity);
    addedSlots.resize(capacity);
    freed.resize(capacity);
    movedFrom.resize(lod::TriangleSlots::kCompactMovesPerFrame);
    movedTo.resize(lod::TriangleSlots::kCompactMovesPerFrame);
    slotTriangle.resize(capacity);
    if (!renderer.init(width, height, error) || !renderer.addTerrainMesh(capacity * 3, 2500.0, error)) return false;
    gpu = renderer.terrainMeshVertices();
    return true;
  }

  struct Phases {
    double terrain_ms = 0, submit_ms = 0, gpu_ms = 0, frame_ms = 0, cpu_ms = 0;
    uint64_t triangles = 0;
    bool capped = false;  // ROAM stopped at the triangle cap
    uint64_t drawnSlots = 0;
  };
  // One frame: ROAM update within `budget`, emit the visible triangles, upload what changed,
  // draw, glFinish. Wall-clock phase times. `visibleCap`: the governor's cap on the visible
  // triangles (+inf: none), turned into ROAM's mesh cap by the last frame's mesh / visible ratio.
  Phases frame(const lod::Camera& cam, double tolerance_px, lod::WorkBudget budget, int height_px,
               const render::Lighting& light, double visibleCap = std::numeric_limits<double>::infinity()) {
    Phases p;
    const double cpu0 = processCpuMs();
    const int64_t t0 = nowNs();
    lod::RoamView view;
    view.camera = cam;
    view.viewportHeight_px = height_px;
    view.tolerance_px = tolerance_px;
    view.maxOperations = budget.operations(nowNs(), opCost.ns());
    if (visibleCap < 1e18) view.maxTriangles = std::max<uint64_t>(2 * roam->baseTriangles(), static_cast<uint64_t>(visibleCap * meshPerVisible));
    const int64_t u0 = nowNs();
    const lod::RoamStats st = roam->update(view, lod::RoamMode::EnhMerge);
    opCost.observe(static_cast<uint64_t>(st.splits) + st.merges + st.enhMerges, nowNs() - u0);
    const size_t n = roam->emitVisible(cam, triangles);
    meshPerVisible = n > 0 ? std::max(1.0, static_cast<double>(st.triangles) / static_cast<double>(n)) : 1.0;
    // As the service: the buffer is drawn up to the slots' high-water mark (freed slots are
    // degenerate triangles); compaction moves the top triangles into the holes, so the drawn
    // range follows the mesh back down after a heavy view.
    const lod::TriangleSlots::Changes c = slots->update(std::span(triangles.data(), n), added, addedSlots, freed);
    auto write = [&](uint32_t slot, const lod::RoamTriangle& t) {
      slotTriangle[slot] = t;
      for (size_t k = 0; k < 3; ++k)
        gpu[slot * 3 + k] = lod::heightFieldVertex(relief.heights, relief.n, relief.n, kSpacing_m, t.v[k].x, t.v[k].y);
    };
    auto hide = [&](uint32_t slot) {
      for (size_t k = 0; k < 3; ++k) gpu[slot * 3 + k] = lod::TerrainVertex{};
    };
    for (size_t i = 0; i < c.freed; ++i) hide(freed[i]);
    for (size_t i = 0; i < c.added; ++i) write(addedSlots[i], triangles[added[i]]);
    const size_t moves = slots->compact(std::min(slots->holes(), movedFrom.size()), movedFrom, movedTo);
    for (size_t i = 0; i < moves; ++i) {
      write(movedTo[i], slotTriangle[movedFrom[i]]);
      hide(movedFrom[i]);
    }
    const int64_t t1 = nowNs();
    renderer.beginFrame(cam, light);
    // The ground detail terms whose reach every triangle drawn lies beyond are left out (the
    // distance from the eye to each triangle's box; the slots hold exactly these triangles).
    const double nearest_m = lod::nearestTriangleBox(std::span(triangles.data(), n), relief.heights, relief.n, relief.n,
                                                     kSpacing_m, cam.eye_m, render::kTerrainFineDetailReach_m);
    renderer.drawTerrainMesh(glm::dvec3(0.0), static_cast<size_t>(slots->highWater()) * 3, nearest_m);
    renderer.endFrame();
    const int64_t t2 = nowNs();
    renderer.finish();
    const int64_t t3 = nowNs();
    p.terrain_ms = msBetween(t0, t1);
    p.submit_ms = msBetween(t1, t2);
    p.gpu_ms = msBetween(t2, t3);
    p.frame_ms = msBetween(t0, t3);
    p.cpu_ms = processCpuMs() - cpu0;
    p.triangles = n;
    p.capped = st.triangleCapped;
    p.drawnSlots = slots->highWater();
    return p;
  }
};

struct Summary {
  double overrunPct = 0, p50 = 0, p99 = 0, max = 0, trianglesP50 = 0, tolP50 = 0, tolMax = 0;
  double cpuP50 = 0, cpuP99 = 0, cpuOverrunPct = 0;  // process CPU time per frame, frames with CPU > budget
  int64_t overruns = 0;
  int64_t overrunsAfterStep = 0;     // in the four frames from a jump of the eye
  int64_t overrunsAtCoarsest = 0;    // with the tolerance at its coarsest: nothing left to give
};

Summary summarize(const std::vector<FrameRow>& rows, double budget_ms) {
  std::vector<double> ms, tris, tol, cpu;
  Summary s;
  int64_t cpuOverruns = 0;
  for (const FrameRow& r : rows) {
    ms.push_back(r.ms);
    cpu.push_back(r.cpu_ms);
    cpuOverruns += r.cpu_ms > budget_ms ? 1 : 0;
    tris.push_back(static_cast<double>(r.triangles));
    tol.push_back(r.tolerance_px);
    s.overruns += r.overrun ? 1 : 0;
    s.overrunsAfterStep += r.overrun && r.afterStep ? 1 : 0;
  }
  s.overrunPct = rows.empty() ? 0.0 : 100.0 * static_cast<double>(s.overruns) / static_cast<double>(rows.size());
  s.p50 = percentile(ms, 50);
  s.p99 = percentile(ms, 99);
  s.max = percentile(ms, 100);
  s.trianglesP50 = percentile(tris, 50);
  s.tolP50 = percentile(tol, 50);
  s.tolMax = percentile(tol, 100);
  s.cpuP50 = percentile(cpu, 50);
  s.cpuP99 = percentile(cpu, 99);
  s.cpuOverrunPct = rows.empty() ? 0.0 : 100.0 * static_cast<double>(cpuOverruns) / static_cast<double>(rows.size());
  return s;
}

// scripts/plot_governor.py next to the working directory, or next to the executable's folder.
std::string plotScript() {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::is_regular_file("scripts/plot_governor.py", ec)) return "scripts/plot_governor.py";
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  for (fs::path dir = exe.parent_path(); !ec && !dir.empty() && dir != dir.parent_path(); dir = dir.parent_path())
    if (fs::is_regular_file(dir / "scripts/plot_governor.py", ec)) return (dir / "scripts/plot_governor.py").string();
  return {};
}

}  // namespace

int runGovernorBench(const GovernorBenchOptions& o0) {
  GovernorBenchOptions o = o0;
  gCpuClock = o.cpuTime;
  if (o.quick) {
    o.samples = std::min(o.samples, 513);
    o.seconds = std::min(o.seconds, 6.0);
  }
  auto badOption = [](const char* name, double v, const char* why) {
    std::fprintf(stderr, "igbench governor: %s = %g: %s\n", name, v, why);
    return 2;
  };
  if (!(o.samples >= 65 && o.samples <= 8193)) return badOption("--samples", o.samples, "out of range (65 ..= 8193)");
  if (!(o.rate_hz > 0.0 && o.rate_hz <= 1000.0)) return badOption("--rate", o.rate_hz, "out of range (> 0 and <= 1000)");
  if (!(o.seconds > 0.0 && o.seconds <= 3600.0)) return badOption("--seconds", o.seconds, "out of range (> 0 and <= 3600)");
  // No frame to measure: the summary would report 0 frames with 0 % overruns and 0 ms, a goal met.
  if (std::llround(o.seconds * o.rate_hz) < 1) return badOption("--seconds", o.seconds, "shorter than one frame at --rate");
  if (!(o.tolerance_px > 0.0 && std::isfinite(o.tolerance_px)))
    return badOption("--tolerance", o.tolerance_px, "out of range (> 0)");
  if (!(o.maxTolerance_px > o.tolerance_px && std::isfinite(o.maxTolerance_px)))
    return badOption("--max-tolerance", o.maxTolerance_px, "out of range (> --tolerance)");
  if (!(o.lodBudget_ms >= 0.0 && std::isfinite(o.lodBudget_ms)))
    return badOption("--lod-budget", o.lodBudget_ms, "out of range (>= 0)");
  if (o.width_px < 16 || o.height_px < 16 || o.width_px > 16384 || o.height_px > 16384)
    return badOption("--width/--height", o.width_px < 16 || o.width_px > 16384 ? o.width_px : o.height_px,
                     "out of range (16 ..= 16384)");

  const Relief relief(o.samples);
  const double aspect = static_cast<double>(o.width_px) / o.height_px;
  const double lap_s = o.quick ? 6.0 : 30.0;
  const int frames = static_cast<int>(std::llround(o.seconds * o.rate_hz));
  const size_t capacity = std::min<size_t>(size_t{1} << 20, 2ull * (o.samples - 1) * (o.samples - 1));

  std::string error;
  auto context = render::createContext(render::ContextKind::Headless, o.width_px, o.height_px, error);
  Run governed(relief), fixed(relief);
  if (!context || !governed.init(o.width_px, o.height_px, capacity, error) ||
      !fixed.init(o.width_px, o.height_px, capacity, error)) {
    std::fprintf(stderr, "igbench governor: %s\n", error.c_str());
    return 3;
  }
  render::Lighting light;
  light.sunDirection = glm::normalize(glm::dvec3(-0.5, 0.6, 0.6));
  light.fogVisibility_m = 60000.0;

  lod::GovernorConfig gc;
  gc.rate_hz = o.rate_hz;
  lod::GovKnob& knob = gc.knobs[static_cast<size_t>(lod::GovLayer::Terrain)];
  knob.present = true;
  knob.initial = o.tolerance_px;
  knob.min = o.tolerance_px;
  knob.max = o.maxTolerance_px;
  knob.loadExponent = -1.5;  // ROAM on this relief: triangles ~ tolerance^-1.2 ... -1.6
  knob.loadUnit = 1e5;
  gc.spikeWindow_frames = o.spikeWindow_frames;
  if (const std::string why = lod::Governor::validate(gc); !why.empty()) {
    std::fprintf(stderr, "igbench governor: governor config: %s\n", why.c_str());
    return 2;
  }
  lod::Governor governor(gc);
  const double budget_ms = governor.frameBudget_ms();

  // The flight's load at the fixed tolerance, every frame refined to convergence (ROAM only,
  // not timed): the swing of the replay, independent of how busy the machine is.
  std::vector<double> convergedLoad;
  {
    lod::RoamConfig rc;
    rc.maxTriangles = capacity;
    lod::Roam roam(relief.heights, relief.n, relief.n, kSpacing_m, glm::dvec3(0.0), rc);
    for (int f = 0; f < frames; ++f) {
      lod::RoamView view;
      view.camera = flightCamera(relief, f / o.rate_hz, lap_s, aspect);
      view.viewportHeight_px = o.height_px;
      view.tolerance_px = o.tolerance_px;
      roam.update(view, lod::RoamMode::EnhMerge);
      convergedLoad.push_back(static_cast<double>(roam.emitVisible(view.camera, fixed.triangles)));
    }
  }
  const double loadAvgStart = loadAverage();

  // One governed frame: the knob, the deferrable-work deadline and the load cap come from the
  // governor, which then learns from the frame.
  const auto governedFrame = [&](const lod::Camera& cam) {
    const lod::WorkBudget budget = governor.workBudget(lod::GovPhase::Terrain, nowNs(), {&readNs, nullptr});
    const Run::Phases g = governed.frame(cam, governor.knob(lod::GovLayer::Terrain), budget, o.height_px, light,
                                         o.noLoadCap ? std::numeric_limits<double>::infinity() : governor.loadCap(lod::GovLayer::Terrain));
    lod::GovSample s;
    s.phase_ms[static_cast<size_t>(lod::GovPhase::Input)] = 0.0;
    s.phase_ms[static_cast<size_t>(lod::GovPhase::Terrain)] = g.terrain_ms;
    s.phase_ms[static_cast<size_t>(lod::GovPhase::Submit)] = g.submit_ms;
    s.phase_ms[static_cast<size_t>(lod::GovPhase::Gpu)] = g.gpu_ms;
    s.load[static_cast<size_t>(lod::GovLayer::Terrain)] = static_cast<double>(g.triangles);
    s.frame_ms = g.frame_ms;
    governor.update(s);
    return g;
  };

  // Settle (not timed, not counted): both runs start from the first view refined and shaders
  // compiled; the fixed run converged at its tolerance, the governed one under its governor from
  // the first settle frame on, as in a service that has been running before the flight starts
  // (its cold start, the warm-up frames, is not what the swing replay measures).
  const lod::Camera first = flightCamera(relief, 0.0, lap_s, aspect);
  for (int i = 0; i < (o.quick ? 10 : 30); ++i) {
    governedFrame(first);
    fixed.frame(first, o.tolerance_px, {}, o.height_px, light);
  }

  std::vector<double> predictionError;
  for (int f = 0; f < frames; ++f) {
    const lod::Camera cam = flightCamera(relief, f / o.rate_hz, lap_s, aspect);
    const double tol = governor.knob(lod::GovLayer::Terrain);
    const double predicted = governor.predicted_ms();
    const Run::Phases g = governedFrame(cam);
    // The step frame and the three after it: ROAM under its work budget takes a few frames to
    // refine the new view, so the load of a jump arrives over those frames.
    bool afterStep = false;
    for (int k = 0; k <= 3 && k <= f; ++k) afterStep = afterStep || flightStep(f - k, o.rate_hz, lap_s);
    governed.rows.push_back({g.frame_ms, predicted, tol, g.triangles, g.frame_ms > budget_ms, afterStep, g.cpu_ms, g.capped,
                             g.drawnSlots, g.terrain_ms, g.submit_ms, g.gpu_ms});
    if (f > 0) predictionError.push_back(std::abs(g.frame_ms - predicted));
    // Fixed: the scene's tolerance and the service's ROAM work budget.
    const lod::WorkBudget fixedBudget =
        o.lodBudget_ms > 0 ? lod::WorkBudget(nowNs() + static_cast<int64_t>(o.lodBudget_ms * 1e6), {}) : lod::WorkBudget();
    const Run::Phases x = fixed.frame(cam, o.tolerance_px, fixedBudget, o.height_px, light);
    fixed.rows.push_back({x.frame_ms, 0.0, o.tolerance_px, x.triangles, x.frame_ms > budget_ms, afterStep, x.cpu_ms, false,
                          x.drawnSlots, x.terrain_ms, x.submit_ms, x.gpu_ms});
  }
  const std::string glErr = governed.renderer.errors() + fixed.renderer.errors();
  if (!glErr.empty()) {
    std::fprintf(stderr, "igbench governor: GL errors: %s\n", glErr.c_str());
    return 1;
  }

  Summary gs = summarize(governed.rows, budget_ms);
  int64_t cappedFrames = 0;
  for (const FrameRow& r : governed.rows) cappedFrames += r.capped ? 1 : 0;
  const Summary fs = summarize(fixed.rows, budget_ms);
  for (const FrameRow& r : governed.rows) gs.overrunsAtCoarsest += r.overrun && r.tolerance_px >= o.maxTolerance_px ? 1 : 0;
  const double loadAvgEnd = loadAverage();
  const double lightLoad = std::max(1.0, percentile(convergedLoad, 1)), heavyLoad = percentile(convergedLoad, 99);
  const double swing = heavyLoad / lightLoad;
  const lod::GovStats& st = governor.stats();

  if (o.json || !o.plotFile.empty()) {
    std::string json;
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "{\"suite\":\"governor\",\"renderer\":\"%s\",\"rate_hz\":%.3f,\"budget_ms\":%.3f,\"width\":%d,"
                  "\"height\":%d,\"samples\":%d,\"seconds\":%.2f,\"quick\":%s,\"time\":\"%s\",\"load_avg_start\":%s,"
                  "\"load_avg_end\":%s,\"cpus\":%u,",
                  jsonEscape(context->description()).c_str(), o.rate_hz, budget_ms, o.width_px, o.height_px, o.samples, o.seconds,
                  o.quick ? "true" : "false", o.cpuTime ? "cpu" : "wall", jsonNumber(loadAvgStart, 2).c_str(), jsonNumber(loadAvgEnd, 2).c_str(), std::thread::hardware_concurrency());
    json += buf;
    std::snprintf(buf, sizeof buf,
                  "\"frames\":%zu,\"overruns\":%lld,\"overrun_pct\":%.3f,\"frame_ms_p50\":%.3f,\"frame_ms_p99\":%.3f,"
                  "\"frame_ms_max\":%.3f,\"triangles_p50\":%.0f,\"tolerance_px_p50\":%.3f,\"tolerance_px_max\":%.3f,"
                  "\"overruns_after_step\":%lld,\"overruns_at_coarsest\":%lld,\"cpu_ms_p50\":%.3f,\"cpu_ms_p99\":%.3f,"
                  "\"cpu_overrun_pct\":%.3f,",
                  governed.rows.size(), static_cast<long long>(gs.overruns), gs.overrunPct, gs.p50, gs.p99, gs.max,
                  gs.trianglesP50, gs.tolP50, gs.tolMax, static_cast<long long>(gs.overrunsAfterStep),
                  static_cast<long long>(gs.overrunsAtCoarsest), gs.cpuP50, gs.cpuP99, gs.cpuOverrunPct);
    json += buf;
    std::snprintf(buf, sizeof buf,
                  "\"prediction_error_ms_p50\":%.3f,\"prediction_error_ms_p99\":%.3f,\"emergencies\":%lld,"
                  "\"decreases\":%lld,\"increases\":%lld,\"direction_changes\":%lld,\"load_swing\":%.2f,"
                  "\"load_light_triangles\":%.0f,\"load_heavy_triangles\":%.0f,\"load_cap\":%s,\"capped_frames\":%lld,"
                  "\"spike_window_frames\":%d,\"spike_ms\":%.3f,",
                  percentile(predictionError, 50), percentile(predictionError, 99),
                  static_cast<long long>(st.emergencies), static_cast<long long>(st.decreases),
                  static_cast<long long>(st.increases), static_cast<long long>(st.directionChanges[0]), swing,
                  lightLoad, heavyLoad, o.noLoadCap ? "false" : "true", static_cast<long long>(cappedFrames),
                  o.spikeWindow_frames, st.spike_ms);
    json += buf;
    std::snprintf(buf, sizeof buf,
                  "\"fixed\":{\"tolerance_px\":%.3f,\"frames\":%zu,\"overruns\":%lld,\"overrun_pct\":%.3f,"
                  "\"frame_ms_p50\":%.3f,\"frame_ms_p99\":%.3f,\"frame_ms_max\":%.3f,\"triangles_p50\":%.0f,"
                  "\"cpu_ms_p50\":%.3f,\"cpu_ms_p99\":%.3f,\"cpu_overrun_pct\":%.3f},",
                  o.tolerance_px, fixed.rows.size(), static_cast<long long>(fs.overruns), fs.overrunPct, fs.p50, fs.p99,
                  fs.max, fs.trianglesP50, fs.cpuP50, fs.cpuP99, fs.cpuOverrunPct);
    json += buf;
    json += "\"tolerance_trace\":[";
    for (size_t i = 0; i < governed.rows.size(); ++i) {
      const FrameRow& r = governed.rows[i];
      std::snprintf(buf, sizeof buf,
                    "%s{\"frame\":%zu,\"ms\":%.3f,\"predicted_ms\":%.3f,\"tolerance_px\":%.4f,\"triangles\":%llu,"
                    "\"fixed_ms\":%.3f,\"fixed_triangles\":%llu,\"cpu_ms\":%.3f,\"fixed_cpu_ms\":%.3f,\"capped\":%d,"
                    "\"drawn_slots\":%llu,\"fixed_drawn_slots\":%llu,\"terrain_ms\":%.3f,\"submit_ms\":%.3f,\"gpu_ms\":%.3f}",
                    i ? "," : "", i, r.ms, r.predicted_ms, r.tolerance_px, static_cast<unsigned long long>(r.triangles),
                    fixed.rows[i].ms, static_cast<unsigned long long>(fixed.rows[i].triangles), r.cpu_ms,
                    fixed.rows[i].cpu_ms, r.capped ? 1 : 0, static_cast<unsigned long long>(r.drawnSlots),
                    static_cast<unsigned long long>(fixed.rows[i].drawnSlots), r.terrain_ms, r.submit_ms, r.gpu_ms);
      json += buf;
    }
    json += "]}";
    if (o.json) std::printf("%s\n", json.c_str());
    if (!o.plotFile.empty()) {
      const std::string script = plotScript();
      if (script.empty()) {
        std::fprintf(stderr, "igbench governor: --plot %s: scripts/plot_governor.py not found (run from the source tree)\n",
                     o.plotFile.c_str());
        return 1;
      }
      const std::string dataFile = o.plotFile + ".json";
      FILE* out = std::fopen(dataFile.c_str(), "w");
      if (!out || std::fputs(json.c_str(), out) < 0 || std::fclose(out) != 0) {
        std::fprintf(stderr, "igbench governor: --plot %s: cannot write '%s'\n", o.plotFile.c_str(), dataFile.c_str());
        return 1;
      }
      // Debian's python3 (python3-matplotlib), not whatever python3 comes first in PATH.
      std::error_code ec;
      const std::string python = std::filesystem::exists("/usr/bin/python3", ec) ? "/usr/bin/python3" : "python3";
      const std::string cmd = python + " '" + script + "' '" + dataFile + "' '" + o.plotFile + "'";
      if (std::system(cmd.c_str()) != 0) {
        std::fprintf(stderr, "igbench governor: --plot %s: %s failed\n", o.plotFile.c_str(), script.c_str());
        return 1;
      }
      std::filesystem::remove(dataFile);
    }
  }
  if (!o.json) {
    std::printf("governor suite: %s, %d x %d, %d posts (%.1f km), %.0f Hz (budget %.1f ms), %zu frames, load swing %.1fx "
                "(%.0f .. %.0f triangles at %.2g px)\n",
                context->description().c_str(), o.width_px, o.height_px, o.samples, relief.extent_m / 1000.0, o.rate_hz,
                budget_ms, governed.rows.size(), swing, lightLoad, heavyLoad, o.tolerance_px);
    std::printf("  load average %.2f at the start, %.2f at the end (%u CPUs); frame work in %s\n", loadAvgStart,
                loadAvgEnd, std::thread::hardware_concurrency(),
                o.cpuTime ? "process CPU time (--cpu-time)" : "wall time: other processes' work inflates it");
    std::printf("  %-10s %9s %9s %9s %9s %11s %9s %9s %9s\n", "run", "overrun%", "ms p50", "ms p99", "ms max",
                "tris p50", "tol p50", "cpu p50", "cpu>B %");
    std::printf("  %-10s %9.2f %9.2f %9.2f %9.2f %11.0f %9.2f %9.2f %9.2f\n", "governed", gs.overrunPct, gs.p50, gs.p99,
                gs.max, gs.trianglesP50, gs.tolP50, gs.cpuP50, gs.cpuOverrunPct);
    std::printf("  %-10s %9.2f %9.2f %9.2f %9.2f %11.0f %9.2f %9.2f %9.2f\n", "fixed", fs.overrunPct, fs.p50, fs.p99,
                fs.max, fs.trianglesP50, fs.tolP50, fs.cpuP50, fs.cpuOverrunPct);
    std::printf("  governor: %lld emergencies, %lld decreases, %lld increases, %lld reversals, prediction error p50 "
                "%.2f ms\n",
                static_cast<long long>(st.emergencies), static_cast<long long>(st.decreases),
                static_cast<long long>(st.increases), static_cast<long long>(st.directionChanges[0]),
                percentile(predictionError, 50));
    std::printf("  governed overruns: %lld right after a jump of the eye, %lld at the coarsest tolerance (%.3g px)\n",
                static_cast<long long>(gs.overrunsAfterStep), static_cast<long long>(gs.overrunsAtCoarsest),
                o.maxTolerance_px);
  }
  return 0;
}

}  // namespace ig
