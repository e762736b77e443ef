// Calibration of the paper 002 performance model on the current GL implementation. See
// perf_calibration.h.
#include "render/perf_calibration.h"

#include <sched.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>
#include <vector>

#include "render/dynamic_pass.h"
#include "render/gl.h"
#include "render/renderer.h"

namespace ig::render {
namespace {

using Clock = std::chrono::steady_clock;
// 2: measured with a settled heap (settleHeap) and with frag_block_px; version 1 caches hold a
// T_tri ten or more times too high. 3: the rasterizer's costs per triangle and per edge pixel
// instead of frag_block_px, T_tri from the application thread's side, overlap by frame size.
// 4: T_tri by the size of a submission (tri_ns_12 ... tri_ns_768), t_c by the commands of a
// frame (command_count, command_large_ns, command_large_count). 5: the rasterizer's cost per draw
// command (draw_raster_ns), taken out of raster_tri_ns. 6: the overlap (and the edges) with the
// share of the boxes that reach the rasterizer (lod::PassLoad::rasterShare). 7: edge_ns from
// whole frames (the application thread's part of larger boxes too). 8: T_tri by call size with
// every box of a call in its leaf (addCalibrationGrid; 7 measured mixed, more calls). 9: the
// overlap fitted again to the median constants of the runs (lod::fitOverlap). 10: each
// interleaved load timed in the frame after one of its own (9 timed it after another load's).
constexpr int kCacheVersion = 10;

struct Field {
  const char* name;
  double lod::PerfConstants::*member;
};
constexpr Field kFields[] = {
    {"frame_ns", &lod::PerfConstants::frame_ns},
    {"tri_ns", &lod::PerfConstants::tri_ns},
    {"frag_ns", &lod::PerfConstants::frag_ns},
    {"raster_tri_ns", &lod::PerfConstants::rasterTri_ns},
    {"edge_ns", &lod::PerfConstants::edge_ns},
    {"draw_raster_ns", &lod::PerfConstants::drawRaster_ns},
    {"depth_frag_ns", &lod::PerfConstants::depthFrag_ns},
    {"state_ns", &lod::PerfConstants::state_ns},
    {"command_ns", &lod::PerfConstants::command_ns},
    {"rerecord_ns", &lod::PerfConstants::rerecord_ns},
    {"submit_ns", &lod::PerfConstants::submit_ns},
    {"cull_ns", &lod::PerfConstants::cull_ns},
    {"occlusion_test_ns", &lod::PerfConstants::occlusionTest_ns},
    {"overlap", &lod::PerfConstants::overlap},
    {"overlap_triangles", &lod::PerfConstants::overlapTriangles},
    {"command_count", &lod::PerfConstants::commandCount},
    {"command_large_ns", &lod::PerfConstants::commandLarge_ns},
    {"command_large_count", &lod::PerfConstants::commandLargeCount},
};

// Every field of the cache in file order, by name: the scalars of kFields, then triByDraw_ns[i]
// as "tri_ns_" and the triangles of the call.
std::vector<std::pair<std::string, double*>> cacheFields(lod::PerfConstants& c) {
  std::vector<std::pair<std::string, double*>> f;
  for (const Field& k : kFields) f.emplace_back(k.name, &(c.*k.member));
  for (size_t i = 0; i < c.triByDraw_ns.size(); ++i) f.emplace_back("tri_ns_" + std::to_string(12u << i), &c.triByDraw_ns[i]);
  return f;
}

// CPU time of this thread (ms): the application side of a frame without the time other
// processes on a shared machine took the core away.
double threadMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

std::string glString(GLenum e) {
  const auto* s = reinterpret_cast<const char*>(gl.GetString(e));
  std::string r = s ? s : "?";
  for (char& c : r)
    if (c == '\n' || c == '|') c = ' ';
  return r;
}

// One measurement context: a renderer, a camera looking north from the origin, a light.
struct Bench {
  Renderer renderer;
  lod::Camera camera;
  Lighting light;
  uint64_t frame = 1;
  int reps = 7;
  int rounds = 3;
  Clock::time_point start = Clock::now();
  double budget_s = 3.0;

  // Lower quartile of the wall time (ms) of a frame drawing `draw`, after one warm-up frame:
  // on a shared machine preemption only ever adds time, the quartile is the undisturbed cost.
  double median(const std::function<void()>& draw) {
    if (overBudget()) reps = 3, rounds = 1;
    std::vector<double> ms;
    for (int i = 0; i <= reps; ++i) {
      const auto t0 = Clock::now();
      renderer.beginFrame(camera, light);
      draw();
      renderer.endFrame();
      renderer.finish();
      if (i > 0) ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
      ++frame;
    }
    std::sort(ms.begin(), ms.end());
    return ms[ms.size() / 4];
  }
  bool overBudget() const { return std::chrono::duration<double>(Clock::now() - start).count() > 0.5 * budget_s; }
  // Median of the slope (ns per unit) between two loads measured alternately.
  double slope(const std::function<void()>& low, double lowUnits, const std::function<void()>& high, double highUnits) {
    std::vector<double> s;
    for (int k = 0; k < rounds; ++k) {
      const double a = median(low), b = median(high);
      s.push_back((b - a) * 1e6 / (highUnits - lowUnits));
    }
    std::sort(s.begin(), s.end());
    return s[s.size() / 2];
  }
};

// Brings the C heap into the state of a process that has run a while. glibc trims the top of
// its heap (brk) on free() above M_TRIM_THRESHOLD, 128 KiB until the process first frees a
// block large enough to have been mmap-ed; from then on the threshold is twice that block.
// llvmpipe allocates and frees memory in every draw, so in a fresh process each draw pays brk
// calls and page faults (profiled: 7 to 10 us per 12-triangle box instead of about 1 us). The
// service and the benchmarks free large blocks all the time (and reach the steady state within
// their first frames), so the calibration measures in it too: one 16 MiB block, freed.
void settleHeap() {
  constexpr size_t kBytes = size_t{16} << 20;
  auto block = std::make_unique<char[]>(kBytes);
  volatile char* touch = block.get();
  touch[0] = 1;  // an allocation with a visible store is not elided
}

// The CPU cost of recording one command: an 84-byte record (instance + indirect command)
// written to memory, timed directly. The floor of t_c and t_s when frame slopes drown in noise.
double recordFloor_ns() {
  struct Record {
    float instance[16];
    uint32_t command[5];
  };
  constexpr size_t kN = 1 << 16;
  std::vector<Record> dst(kN);
  Record src{};
  double best = 1e300;
  for (int k = 0; k < 5; ++k) {
    const auto t0 = Clock::now();
    for (size_t i = 0; i < kN; ++i) {
      src.command[4] = static_cast<uint32_t>(i);
      dst[i] = src;
    }
    best = std::min(best, std::chrono::duration<double, std::nano>(Clock::now() - t0).count() / kN);
  }
  volatile uint32_t sink = dst[kN / 2].command[4];
  (void)sink;
  return best;
}

bool makePass(DynamicPass& pass, uint32_t maxObjects, uint32_t depth, double bounds_m, uint32_t work,
              std::string& error) {
  DynamicPassConfig c;
  c.testMinObjects = 1;  // every node may be tested, every frame
  c.resultMaxAge = 0;
  c.maxObjects = maxObjects;
  c.octreeDepth = depth;
  c.bounds = {glm::dvec3(-bounds_m), glm::dvec3(bounds_m)};
  c.maxQueries = maxObjects;
  c.fragmentWork = work;
  return pass.init(c, error);
}

}  // namespace

void addCalibrationGrid(DynamicPass& pass, uint32_t nodes, int perNode) {
  constexpr double kTinyHalf_m = 0.005;
  // The lattice is centred on the leaf (offsets -0.6, -0.2, 0.2, 0.6 from its centre): from the
  // centre on (0 ... 1.2) its fourth row lay outside the 2 m leaf, in the next one, and the
  // leaves held mixed counts (64 a leaf: 1,397 leaves instead of 900).
  const auto at = [](int i) { return -0.6 + 0.4 * i; };
  uint32_t k = 0;
  for (int layer = 0; layer < 4 && k < nodes; ++layer)
    for (int zi = -6; zi < 6 && k < nodes; ++zi)
      for (int xi = -14; xi < 14 && k < nodes; ++xi, ++k)
        for (int j = 0; j < perNode; ++j)
          pass.add({{2.0 * xi + 1.0 + at(j % 4), 41.0 + 2.0 * layer + at(j / 16), 2.0 * zi + 1.0 + at((j / 4) % 4)},
                    glm::dvec3(kTinyHalf_m), 0.0, 0xffffffffu});
}

namespace {
// The CPU side of the key: the processor model, how many CPUs this process may use and
// llvmpipe's LP_NUM_THREADS. The command costs (t_c, t_s, T_state) are CPU work on any device,
// and on llvmpipe every constant is: a cache from before a VM resize, a new cpu_affinity or
// another LP_NUM_THREADS would predict the wrong frame times.
std::string cpuKey() {
  std::string model = "?";
  std::ifstream info("/proc/cpuinfo");
  for (std::string line; std::getline(info, line);) {
    if (line.rfind("model name", 0) == 0) {
      const size_t start = line.find_first_not_of(" \t", line.find(':') + 1);
      if (line.find(':') != std::string::npos && start != std::string::npos) model = line.substr(start);
      break;
    }
  }
  cpu_set_t set;
  CPU_ZERO(&set);
  const int cpus = sched_getaffinity(0, sizeof set, &set) == 0 ? CPU_COUNT(&set) : 0;
  const char* lp = std::getenv("LP_NUM_THREADS");
  return "cpu=" + model + " x" + std::to_string(cpus) + (lp != nullptr ? std::string("|LP_NUM_THREADS=") + lp : "");
}
}  // namespace

std::string calibrationKey(const CalibrationOptions& o) {
  return glString(GL_VENDOR) + "|" + glString(GL_RENDERER) + "|" + glString(GL_VERSION) + "|" + cpuKey() +
         "|work=" + std::to_string(o.fragmentWork) + "|" + std::to_string(o.width_px) + "x" + std::to_string(o.height_px);
}

bool readCalibrationCache(const std::string& path, const std::string& key, lod::PerfConstants& out, std::string& why) {
  std::ifstream in(path);
  if (!in) {
    why = path + ": cannot open";
    return false;
  }
  std::string line;
  bool haveVersion = false, haveKey = false;
  lod::PerfConstants c;
  const auto fields = cacheFields(c);
  std::vector<bool> seen(fields.size(), false);
  int lineNo = 0;
  while (std::getline(in, line)) {
    ++lineNo;
    if (line.empty() || line[0] == '#') continue;
    const size_t sp = line.find(' ');
    const std::string name = line.substr(0, sp), value = sp == std::string::npos ? "" : line.substr(sp + 1);
    const std::string where = path + ":" + std::to_string(lineNo) + ": ";
    if (name == "version") {
      if (value != std::to_string(kCacheVersion)) return why = where + "version " + value + " (expected " + std::to_string(kCacheVersion) + ")", false;
      haveVersion = true;
      continue;
    }
    if (name == "key") {
      if (value != key) return why = where + "key '" + value + "' is not this device's '" + key + "'", false;
      haveKey = true;
      continue;
    }
    const auto f = std::find_if(fields.begin(), fields.end(), [&](const auto& x) { return x.first == name; });
    if (f == fields.end()) return why = where + "unknown field '" + name + "'", false;
    const auto i = static_cast<size_t>(f - fields.begin());
    if (seen[i]) return why = where + name + " repeated", false;
    char* end = nullptr;
    const double v = std::strtod(value.c_str(), &end);
    if (value.empty() || end == value.c_str() || *end != '\0' || !std::isfinite(v) || v < 0.0)
      return why = where + name + " = '" + value + "': not a finite number >= 0", false;
    *f->second = v;
    seen[i] = true;
  }
  if (!haveVersion || !haveKey) return why = path + ": no version or key line", false;
  for (size_t i = 0; i < fields.size(); ++i)
    if (!seen[i]) return why = path + ": " + fields[i].first + " missing", false;
  if (!lod::valid(c)) return why = path + ": constants out of range", false;
  out = c;
  return true;
}

bool writeCalibrationCache(const std::string& path, const std::string& key, const lod::PerfConstants& c,
                           std::string& error) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::trunc);
    if (!f) return error = tmp + ": cannot write", false;
    f << "# igd performance-model calibration (paper 002, render/perf_calibration.h); rewritten when stale\n";
    f << "version " << kCacheVersion << "\nkey " << key << "\n";
    char buf[96];
    lod::PerfConstants copy = c;
    for (const auto& [name, value] : cacheFields(copy)) {
      std::snprintf(buf, sizeof buf, "%s %.9g\n", name.c_str(), *value);
      f << buf;
    }
    if (!f.flush()) return error = tmp + ": write failed", false;
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) return error = path + ": cannot replace", false;
  return true;
}

namespace {

// One run of the measurements (see perf_calibration.h) into `c`.
bool measure(const CalibrationOptions& o, int run, lod::PerfConstants& c, lod::OverlapSample (&overlapFrames)[2],
             std::string& error) {
  c = {};
  settleHeap();
  Bench b;
  b.budget_s = o.budget_s;
  if (!b.renderer.init(o.width_px, o.height_px, error)) return error = "calibration: " + error, false;
  b.camera.aspect = static_cast<double>(o.width_px) / o.height_px;
  b.camera.near_m = 0.1;
  b.camera.far_m = 10000.0;
  b.light.fog = false;
  const double pixels = static_cast<double>(o.width_px) * o.height_px;

  // T_frag: 1 and 4 full-screen boxes, far first, one per-object command each (measured with the
  // other small differences below, interleaved). The fixed cost of a frame is the intercept of
  // the same line: a frame that draws anything loads and stores its tiles, which an empty one
  // does not.
  DynamicPass full1, full4;
  for (int k : {1, 4}) {
    DynamicPass& pass = k == 1 ? full1 : full4;
    if (!makePass(pass, 64, 0, 1000.0, o.fragmentWork, error)) return false;
    pass.setStrategy(DynamicStrategy::PerCommand);
    for (int i = 0; i < k; ++i) {
      const double d = 50.0 - i;
      pass.add({{0.0, d, 0.0}, {3.0 * d, 0.4, 3.0 * d}, 0.0, 0xff8080ffu});
    }
  }
  {
    DynamicPass pass;
    if (!makePass(pass, 64, 0, 1000.0, o.fragmentWork, error)) return false;
    // Depth-only fragments of occlusion boxes over a depth buffer at the far plane.
    std::vector<lod::Aabb> boxes;
    for (int i = 0; i < 8; ++i) {
      const double d = 50.0 - i;
      boxes.push_back({{-3.0 * d, d - 0.4, -3.0 * d}, {3.0 * d, d + 0.4, 3.0 * d}});
    }
    c.depthFrag_ns = std::max(0.0, b.slope([&] { pass.drawDepthBoxes(b.renderer, std::span(boxes).first(1)); }, pixels,
                                           [&] { pass.drawDepthBoxes(b.renderer, boxes); }, 8.0 * pixels));
  }

  // Tiny (sub-pixel) boxes in front of the camera.
  // Tiny boxes spread over the whole view (a concentrated cloud costs llvmpipe more per
  // triangle). Not sub-pixel by orders of magnitude: llvmpipe handles those on a slower path
  // than the few-pixel boxes of large scenes.
  constexpr double kTinyHalf_m = 0.005;
  // In 2 m octree cells (bounds +-64 m): 14 x 8 cells across the view at y in [20, 22], so any
  // count of boxes fills the same 112 nodes and a slope over the count is per box, not per node.
  const auto tiny = [](uint32_t i, double y) {
    const auto jitter = [](uint32_t h) { return 0.8 * ((h >> 8) % 65536u / 32768.0 - 1.0); };
    const double x = -13.0 + 2.0 * (i % 14u) + jitter(i * 2654435761u);
    const double z = -7.0 + 2.0 * ((i / 14u) % 8u) + jitter(i * 2246822519u);
    return DynamicObject{{x, y + jitter(i * 3266489917u), z}, glm::dvec3(kTinyHalf_m), 0.0, 0xffffffffu};
  };
  // T_tri, t_c, t_s, T_state, T_rtri and T_edge come from differences of per-box costs, so the loads they
  // compare are measured interleaved (one frame of each per repeat) and see the same machine load.
  // `many`: the cost of a per-object command grows with the objects per frame (their data and
  // the command stream leave the caches), so t_c is measured with 20,000 boxes, a size where the
  // choice between the strategies matters, not with the few thousand that fit in L2.
  constexpr uint32_t kLow = 500, kHigh = 3000, kMany = 20000, kNodesHigh = 900, kLayered = 6000;
  DynamicPass low, high, many, nodesHigh, nodesDouble, layerOnly, layerSmall, layerMid;
  for (DynamicPass* p : {&low, &high, &layerOnly})
    if (!makePass(*p, kHigh + 1, 6, 64.0, o.fragmentWork, error)) return false;  // 2 m leaves
  for (DynamicPass* p : {&layerSmall, &layerMid})
    if (!makePass(*p, kLayered + 1, 6, 64.0, o.fragmentWork, error)) return false;
  if (!makePass(many, kMany, 6, 64.0, o.fragmentWork, error)) return false;
  for (uint32_t i = 0; i < kMany; ++i) many.add(tiny(i, 21.0));
  for (DynamicPass* p : {&nodesHigh, &nodesDouble})
    if (!makePass(*p, 4096, 6, 64.0, o.fragmentWork, error)) return false;
  for (uint32_t i = 0; i < kHigh; ++i) {
    if (i < kLow) low.add(tiny(i, 21.0));
    high.add(tiny(i, 21.0));
  }
  // The rasterizer's costs per triangle and per edge pixel: in front of one full-screen layer
  // (every tile has work in all three, so the tiles' fixed costs cancel), 6,000 boxes of a few
  // pixels (`layerSmall`, ~6 px) and of a few tens (`layerMid`, ~30 px) against the layer alone.
  // Only the part of the frame after the GL calls returned counts (the rasterizer's: these
  // frames are binned whole and rasterized at the finish), and the fragments are counted with
  // GL_SAMPLES_PASSED. Same boxes, same triangles: the difference of the two sizes is their edges
  // and fragments, the difference to the layer alone also their triangles.
  constexpr double kSmallHalf_m = 0.05, kMidHalf_m = 0.11;
  const glm::dmat4 vp = lod::projection(b.camera) *
                        glm::dmat4(lod::viewRotation(b.camera));
  // Sum over `boxes` of sqrt(projected area in px), weighted as lod::PassLoad::edgePx, and
  // their share that reaches the rasterizer (lod::PassLoad::rasterShare) in `share`.
  const auto edgeSum = [&](const std::vector<DynamicObject>& boxes, double* share = nullptr) {
    double q = 0.0, reach = 0.0;
    for (const DynamicObject& ob : boxes) {
      std::array<glm::dvec3, 8> corners;
      for (int k = 0; k < 8; ++k)
        corners[static_cast<size_t>(k)] = ob.center_m - b.camera.eye_m +
                                          ob.halfSize_m * glm::dvec3(k & 1 ? 1 : -1, k & 2 ? 1 : -1, k & 4 ? 1 : -1);
      const double a = std::max(0.0, lod::projectedBoxArea_px(vp, corners, o.width_px, o.height_px));
      const double r = lod::boxRasterShare(a);
      q += std::sqrt(a) * r;
      reach += r;
    }
    if (share) *share = boxes.empty() ? 1.0 : reach / static_cast<double>(boxes.size());
    return q;
  };
  double edgeSmall = 0.0, edgeMid = 0.0, shareSmall = 1.0;
  {
    const DynamicObject back{{0.0, 50.0, 0.0}, {150.0, 0.4, 150.0}, 0.0, 0xff8080ffu};
    std::vector<DynamicObject> smallBoxes, midBoxes;
    for (DynamicPass* p : {&layerOnly, &layerSmall, &layerMid}) {
      p->add(back);  // first: drawn behind everything
      p->setMeasureSamples(true);
    }
    for (uint32_t i = 0; i < kLayered; ++i) {
      DynamicObject ob = tiny(i, 21.0);
      ob.halfSize_m = glm::dvec3(kSmallHalf_m);
      smallBoxes.push_back(ob);
      ob.halfSize_m = glm::dvec3(kMidHalf_m);
      midBoxes.push_back(ob);
    }
    for (const DynamicObject& ob : smallBoxes) layerSmall.add(ob);
    for (const DynamicObject& ob : midBoxes) layerMid.add(ob);
    edgeSmall = edgeSum(smallBoxes, &shareSmall);  // ~6 px boxes: all of them reach the rasterizer
    edgeMid = edgeSum(midBoxes);
  }
  // One tiny box per octree leaf (2 m cells): one node range, one indirect call per box.
  const auto grid = [](DynamicPass& pass, uint32_t n, int perNode) { addCalibrationGrid(pass, n, perNode); };
  grid(nodesHigh, kNodesHigh, 1);
  grid(nodesDouble, kNodesHigh, 2);
  // T_tri by the size of a call: the same 900 leaves holding 1, 2, 4 ... 64 boxes each (one
  // instanced call of k boxes per node), against a frame without boxes. The application
  // thread's CPU time (llvmpipe shades, clips, sets up and bins on it; these boxes are culled
  // in set-up, so the rasterizer has nothing to do), so preemption does not count.
  constexpr size_t kSizes = lod::PerfConstants::kDrawSizes;
  std::array<std::unique_ptr<DynamicPass>, kSizes> perDraw;
  for (size_t i = 2; i < kSizes; ++i) {
    perDraw[i] = std::make_unique<DynamicPass>();
    if (!makePass(*perDraw[i], kNodesHigh << i, 6, 64.0, o.fragmentWork, error)) return false;
    grid(*perDraw[i], kNodesHigh, 1 << i);
  }
  DynamicPass empty;
  if (!makePass(empty, 1, 6, 64.0, o.fragmentWork, error)) return false;
  nodesHigh.setStrategy(DynamicStrategy::Octree);
  {
    // Whole frame (ms), and in `cpu` the part until the GL calls return (before glFinish).
    double cpuLast = 0.0, threadLast = 0.0;
    const auto frameMs = [&](DynamicPass& p, DynamicStrategy s, uint32_t stateChanges = 0) {
      p.setStrategy(s);
      const double thread0 = threadMs();
      const auto t0 = Clock::now();
      b.renderer.beginFrame(b.camera, b.light);
      if (stateChanges)
        p.drawStateChanges(b.renderer, stateChanges);
      else
        p.draw(b.renderer, b.frame++);
      b.renderer.endFrame();
      cpuLast = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
      threadLast = threadMs() - thread0;
      b.renderer.finish();
      return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    };
    // t_c and t_s are small next to a box, so each comes from one scene drawn both ways in
    // consecutive frames (same boxes, same fragments): `many` (20,000 boxes in 112 nodes) as
    // per-object commands and as node ranges differs by 19,888 commands, 111 submissions and
    // the frustum tests; `nodesHigh` (900 nodes of one box) by 899 submissions and the tests.
    // Each load's time is the lower quartile of its frames (preemption and the bursts of other
    // processes on a shared machine only add time, and they come in phases that cover several
    // consecutive repeats, which a median of paired differences does not survive).
    enum Load {
      kDouble, kManyOctree, kManyCommands, kNodesCommands, kNodesOctree, kState200, kState2000, kLayer, kLayerSmall,
      kLayerMid, kLayerSmallNodes, kFull1, kFull4, kEmpty, kDraw4, kLoads = kDraw4 + kSizes - 2
    };
    static constexpr const char* kLoadNames[] = {
        "nodes_2_boxes", "many_nodes", "many_commands", "nodes_commands", "nodes_1_box", "state_200",
        "state_2000", "layer", "layer_small", "layer_mid", "layer_small_nodes", "full_1", "full_4", "empty",
        "nodes_4_boxes", "nodes_8_boxes", "nodes_16_boxes", "nodes_32_boxes", "nodes_64_boxes"};
    static_assert(std::size(kLoadNames) == kLoads);
    std::vector<double> ms[kLoads], cpu[kLoads], fin[kLoads], thread[kLoads];
    double manyTests = 0.0, manyNodes = 112.0, nodeTests = 0.0;
    uint32_t smallDraws = kLayered + 1, smallNodeDraws = kLayered + 1;  // draws of `layerSmall` per object / in nodes
    const int reps = b.overBudget() || b.budget_s < 1.0 ? 5 : b.budget_s >= 8.0 ? 25 : 11;
    const auto keep = [&](Load l, double frame) {
      ms[l].push_back(frame), cpu[l].push_back(cpuLast), fin[l].push_back(frame - cpuLast), thread[l].push_back(threadLast);
    };
    // A frame of llvmpipe leaves work to the next one (its scene's bins are released and its
    // threads catch up while the next frame is set up): a full-screen layer drawn after 2,000
    // state changes took 8.5 ms (median) against 5.2 ms after a frame of itself. The scenes
    // modelled repeat from frame to frame, so each load is timed in the frame after one of its own.
    int repeat = 0;  // 0: warm-up (node ranges built, shaders compiled), not kept
    const auto steady = [&](Load l, DynamicPass& p, DynamicStrategy s, uint32_t stateChanges = 0) {
      for (int k = 0; k < 2; ++k) {
        const double t = frameMs(p, s, stateChanges);
        const bool timed = k == 1 && repeat > 0;
        if (o.trace) o.trace->push_back({run, repeat, kLoadNames[l], timed, t, cpuLast, threadLast});
        if (timed) keep(l, t);
      }
    };
    for (int r = 0; r <= reps; ++r) {
      repeat = r;
      // One vs two tiny boxes in each of the 900 nodes: the box of T_state's draws (and T_tri's
      // fallback when the table cannot be measured).
      steady(kDouble, nodesDouble, DynamicStrategy::Octree);
      steady(kManyOctree, many, DynamicStrategy::Octree);
      manyTests = many.stats().frustumTests, manyNodes = std::max(1u, many.stats().nodesDrawn);
      steady(kManyCommands, many, DynamicStrategy::PerCommand);
      steady(kNodesCommands, nodesHigh, DynamicStrategy::PerCommand);
      steady(kNodesOctree, nodesHigh, DynamicStrategy::Octree);
      nodeTests = nodesHigh.stats().frustumTests;
      // T_state: one tiny box per draw, a uniform change before each (200 vs 2000 draws).
      steady(kState200, low, DynamicStrategy::PerCommand, 200);
      steady(kState2000, low, DynamicStrategy::PerCommand, 2000);
      steady(kLayer, layerOnly, DynamicStrategy::PerCommand);
      steady(kLayerSmall, layerSmall, DynamicStrategy::PerCommand);
      smallDraws = layerSmall.stats().draws;
      layerSmall.setMeasureSamples(false);  // its count is the per-object frame's (the same fragments)
      steady(kLayerSmallNodes, layerSmall, DynamicStrategy::Octree);
      layerSmall.setMeasureSamples(r == 0);
      smallNodeDraws = layerSmall.stats().draws;
      steady(kLayerMid, layerMid, DynamicStrategy::PerCommand);
      steady(kFull1, full1, DynamicStrategy::PerCommand);
      steady(kFull4, full4, DynamicStrategy::PerCommand);
      steady(kEmpty, empty, DynamicStrategy::Octree);
      for (size_t i = 2; i < kSizes; ++i)
        steady(static_cast<Load>(kDraw4 + i - 2), *perDraw[i], DynamicStrategy::Octree);
      // Samples are counted in the warm-up frame only: counting costs the rasterizer time.
      if (r == 0)
        for (DynamicPass* p : {&layerOnly, &layerSmall, &layerMid}) p->setMeasureSamples(false);
    }
    const auto mid = [](std::vector<double> v) {
      std::sort(v.begin(), v.end());
      return v[v.size() / 2];
    };
    const auto quartile = [](std::vector<double> v) {
      std::sort(v.begin(), v.end());
      return v[v.size() / 4];
    };
    // Frame and CPU-side (until the GL calls return) differences between two loads, ns.
    const auto diff = [&](Load a, Load z) { return (quartile(ms[a]) - quartile(ms[z])) * 1e6; };
    const auto cpuDiff = [&](Load a, Load z) { return (quartile(cpu[a]) - quartile(cpu[z])) * 1e6; };
    // T_frag and the frame's fixed cost. A difference that comes out <= 0 (noise: a small
    // viewport, a slow build) falls back to the rasterizer's side of the same frames, then to
    // the median of three slopes measured apart; if that fails too, the constants are rejected.
    c.frag_ns = diff(kFull4, kFull1) / (3.0 * pixels);
    if (!(c.frag_ns > 0.0)) c.frag_ns = (quartile(fin[kFull4]) - quartile(fin[kFull1])) * 1e6 / (3.0 * pixels);
    if (!(c.frag_ns > 0.0))
      c.frag_ns = b.slope([&] { full1.draw(b.renderer, b.frame); }, pixels, [&] { full4.draw(b.renderer, b.frame); },
                          4.0 * pixels);
    c.frame_ns = std::max(0.0, quartile(ms[kFull1]) * 1e6 - std::max(0.0, c.frag_ns) * pixels);
    // T_tri: the application thread's side of an instanced tiny box (its 12 triangles shaded,
    // clipped, set up and binned; the rasterizer works at the finish, counted below). Noise: the
    // whole frame's difference, else an upper bound (the whole frame of `many` over its boxes).
    double perBox = cpuDiff(kDouble, kNodesOctree) / kNodesHigh;
    if (!(perBox > 0.0)) perBox = diff(kDouble, kNodesOctree) / kNodesHigh;
    if (!(perBox > 0.0)) perBox = quartile(ms[kManyOctree]) * 1e6 / kMany;
    // An instanced box: 12 triangles. A per-object command box: the same plus the command and a
    // frustum test. A node of one box: the box, its command, its submission.
    c.tri_ns = perBox / 12.0;
    // Frustum tests: per-object culling of boxes behind the camera.
    DynamicPass behindPass;
    if (!makePass(behindPass, kHigh, 6, 64.0, o.fragmentWork, error)) return false;
    behindPass.setStrategy(DynamicStrategy::PerCommand);
    const auto drawBehind = [&] { behindPass.draw(b.renderer, b.frame); };
    std::vector<double> sc;
    for (int k = 0; k < b.rounds; ++k) {
      behindPass.clear();
      for (uint32_t i = 0; i < kLow; ++i) behindPass.add(tiny(i, -20.0));
      const double a0 = b.median(drawBehind);
      for (uint32_t i = kLow; i < kHigh; ++i) behindPass.add(tiny(i, -20.0));
      const double z0 = b.median(drawBehind);
      sc.push_back((z0 - a0) * 1e6 / (kHigh - kLow));
    }
    c.cull_ns = std::max(0.0, mid(sc));
    {
      // The frustum test alone, timed directly: frame slopes of a few ns per box drown in noise.
      const lod::Frustum f = lod::makeFrustum(b.camera);
      double best = 1e300;
      uint32_t hits = 0;
      for (int k = 0; k < 5; ++k) {
        const auto t0 = Clock::now();
        for (uint32_t i = 0; i < 100000; ++i) {
          const glm::dvec3 p(0.001 * i - 50.0, 20.0 + 0.0001 * i, 0.0);
          hits += f.intersects({p - glm::dvec3(0.1), p + glm::dvec3(0.1)}) ? 1u : 0u;
        }
        best = std::min(best, std::chrono::duration<double, std::nano>(Clock::now() - t0).count() / 100000.0);
      }
      c.cull_ns = std::max(c.cull_ns, best);
      volatile uint32_t sink = hits;
      (void)sink;
    }
    // octree - per-object (nodesHigh) = (n - 1) t_s + (node tests - n) T_cull;
    // per-object - octree (many) = (N - nodes) t_c - (nodes - 1) t_s + (N - node tests) T_cull.
    // A difference that comes out <= 0 is noise: fall back to the same difference of the CPU
    // side (llvmpipe does the per-draw work on this thread), then to the cost of a record.
    const double nNodes = kNodesHigh, nMany = kMany;
    const auto submit = [&](double d) { return (d - (nodeTests - nNodes) * c.cull_ns) / (nNodes - 1.0); };
    c.submit_ns = submit(diff(kNodesOctree, kNodesCommands));
    if (!(c.submit_ns > 0.0)) c.submit_ns = submit(cpuDiff(kNodesOctree, kNodesCommands));
    if (!(c.submit_ns > 0.0)) c.submit_ns = recordFloor_ns();
    const auto command = [&](double d) {
      return (d + (manyNodes - 1.0) * c.submit_ns - (nMany - manyTests) * c.cull_ns) / (nMany - manyNodes);
    };
    c.commandCount = nMany;
    c.command_ns = command(diff(kManyCommands, kManyOctree));
    if (!(c.command_ns > 0.0)) c.command_ns = command(cpuDiff(kManyCommands, kManyOctree));
    if (!(c.command_ns > 0.0)) c.command_ns = recordFloor_ns();
    c.state_ns = std::max(0.0, diff(kState2000, kState200) / 1800.0 - perBox);
    // T_tri by submission size: k boxes in each of the 900 node draws, less the frame without
    // boxes and the nodes' own costs (a command, a submission, the frustum tests), per triangle.
    // A box costs less in a longer call, so the table is made non-increasing (pooled where noise
    // breaks that, as in isotonic regression). A value that comes out <= 0 (noise) takes its
    // neighbour's; if none is positive, no table (tri_ns for every draw).
    {
      const double base = quartile(thread[kEmpty]);
      const double nodes = (nNodes * (c.command_ns + c.submit_ns) + nodeTests * c.cull_ns) * 1e-6;
      for (size_t i = 0; i < kSizes; ++i) {
        const Load l = i == 0 ? kNodesOctree : i == 1 ? kDouble : static_cast<Load>(kDraw4 + i - 2);
        c.triByDraw_ns[i] = std::max(0.0, (quartile(thread[l]) - base - nodes) * 1e6 / (nNodes * 12.0 * (1u << i)));
      }
      for (size_t i = kSizes - 1; i-- > 0;)
        if (!(c.triByDraw_ns[i] > 0.0)) c.triByDraw_ns[i] = c.triByDraw_ns[i + 1];
      for (size_t i = 1; i < kSizes; ++i)
        if (!(c.triByDraw_ns[i] > 0.0)) c.triByDraw_ns[i] = c.triByDraw_ns[i - 1];
      // Pool adjacent violators: blocks of equal value, merged while a later block is higher.
      std::vector<std::pair<double, int>> blocks;  // (mean, entries)
      for (double v : c.triByDraw_ns) {
        blocks.push_back({v, 1});
        while (blocks.size() > 1 && blocks.back().first > blocks[blocks.size() - 2].first) {
          const auto [m, n] = blocks.back();
          blocks.pop_back();
          auto& prev = blocks.back();
          prev.first = (prev.first * prev.second + m * n) / (prev.second + n);
          prev.second += n;
        }
      }
      size_t at = 0;
      for (const auto& [m, n] : blocks)
        for (int j = 0; j < n; ++j) c.triByDraw_ns[at++] = m;
      // tri_ns: long draws (where the size of the draws is not known).
      if (c.triByDraw_ns.back() > 0.0) c.tri_ns = c.triByDraw_ns.back();
    }
    // T_edge and T_rtri from the layered loads (see above).
    {
      const auto finDiff = [&](Load a, Load z) { return (quartile(fin[a]) - quartile(fin[z])) * 1e6; };
      const double s0 = static_cast<double>(layerOnly.samplesPassed()), s1 = static_cast<double>(layerSmall.samplesPassed()),
                   s2 = static_cast<double>(layerMid.samplesPassed());
      const double edges = std::max(1.0, edgeMid - edgeSmall);
      const double edgeRaster = std::max(0.0, (finDiff(kLayerMid, kLayerSmall) - c.frag_ns * (s2 - s1)) / edges);
      // T_edge from whole frames: a larger box also costs the application thread more (llvmpipe
      // sets it up and bins it into more of its bins there), 20 ... 70 ns per edge pixel on top of
      // the rasterizer's 120 ... 200 here. The two sizes differ in nothing else (same boxes,
      // commands and triangles). Measured on the rasterizer's side only, frames of 1,000 ... 10,000
      // boxes of a few to ~25 px were predicted 10 ... 25 % too fast (2026-12-05).
      c.edge_ns = std::max(edgeRaster, (diff(kLayerMid, kLayerSmall) - c.frag_ns * (s2 - s1)) / edges);
      // T_draw: the small boxes as per-object commands (a draw each) against their node ranges
      // (~113 draws): same triangles, same fragments (the layer is drawn first either way).
      const double reached = std::max(shareSmall, 1e-3);
      c.drawRaster_ns = smallDraws > smallNodeDraws ? std::max(0.0, finDiff(kLayerSmall, kLayerSmallNodes) /
                                                                         (reached * static_cast<double>(smallDraws - smallNodeDraws)))
                                                    : 0.0;
      c.rasterTri_ns = std::max(0.0, (finDiff(kLayerSmall, kLayer) - c.frag_ns * (s1 - s0) - edgeRaster * edgeSmall -
                                      c.drawRaster_ns * kLayered * reached) /
                                         (12.0 * kLayered * reached));
    }
    // t_r: every object moved (in place) each frame in octree mode: its node range is rewritten.
    high.setStrategy(DynamicStrategy::Octree);
    const auto drawHigh = [&] { high.draw(b.renderer, b.frame); };
    const auto moveAll = [&] {
      for (uint32_t i = 0; i < kHigh; ++i) high.set(i, tiny(i, 21.0));
      high.draw(b.renderer, b.frame);
    };
    c.rerecord_ns = std::max(0.0, b.slope(drawHigh, 0.0, moveAll, kHigh));
    if (!(c.rerecord_ns > 0.0)) {
      // Noise ate the slope: time the CPU work of changing an object directly (octree move and
      // instance record; the range rewrite is a 64-byte copy on top).
      double best = 1e300;
      for (int k = 0; k < 3; ++k) {
        const auto t0 = Clock::now();
        for (uint32_t i = 0; i < kHigh; ++i) high.set(i, tiny(i, 21.0));
        best = std::min(best, std::chrono::duration<double, std::nano>(Clock::now() - t0).count() / kHigh);
      }
      c.rerecord_ns = best + recordFloor_ns();
      drawHigh();
    }
  }
  {
    // The occlusion test cost on the one-box nodes.
    DynamicPass& pass = nodesHigh;
    const auto draw = [&] { pass.draw(b.renderer, b.frame); };
    pass.setStrategy(DynamicStrategy::Occlusion);
    std::vector<double> sq;
    for (int k = 0; k < b.rounds; ++k) {
      pass.setOcclusionTests(0);
      const double a = b.median(draw);
      pass.setOcclusionTests(600);
      const double z = b.median(draw);
      sq.push_back((z - a) * 1e6 / 600.0);
    }
    std::sort(sq.begin(), sq.end());
    c.occlusionTest_ns = std::max(0.0, sq[sq.size() / 2]);
  }
  {
    // Overlap of the stages, by the size of the frame: boxes of a few pixels in the octree (the
    // vertex stage and the rasterizer both busy), 45,000 and 135,000 of them (llvmpipe begins
    // to overlap near 500,000 triangles, 40,000 boxes). Each frame's
    // overlap is what (2) without overlap over-predicts, as a share of the smaller stage; w and
    // overlapTriangles are the line w (1 - T0 / N_tri) through the two.
    constexpr uint32_t kBig[2] = {45000, 135000};
    constexpr double kBigHalf_m = 0.03;
    DynamicPass pass;
    if (!makePass(pass, kBig[1], 6, 64.0, o.fragmentWork, error)) return false;
    pass.setStrategy(DynamicStrategy::Octree);
    std::vector<DynamicObject> boxes;
    for (int k = 0; k < 2; ++k) {
      while (boxes.size() < kBig[k]) {
        DynamicObject ob = tiny(static_cast<uint32_t>(boxes.size()), 21.0);
        ob.halfSize_m = glm::dvec3(kBigHalf_m);
        boxes.push_back(ob);
        pass.add(ob);
      }
      // One frame counts the samples (counting costs time), then the timed ones.
      pass.setMeasureSamples(true);
      b.renderer.beginFrame(b.camera, b.light);
      pass.draw(b.renderer, b.frame++);
      b.renderer.endFrame();
      b.renderer.finish();
      pass.setMeasureSamples(false);
      const double ms = b.median([&] { pass.draw(b.renderer, b.frame); });
      const DynamicFrameStats& st = pass.stats();
      lod::PassLoad load;
      load.triangles = static_cast<double>(st.triangles);
      load.fragments = static_cast<double>(pass.samplesPassed());
      load.edgePx = edgeSum(boxes, &load.rasterShare);
      load.commands = st.commands;
      load.submissions = st.submissions;
      load.frustumTests = st.frustumTests;
      overlapFrames[k] = {load, ms * 1e6};
    }
    // t_c with many commands: the 135,000 boxes as per-object commands against the same in
    // their node ranges, alternately, the application thread's CPU time (the commands and their
    // records no longer fit the caches). Less the node ranges' submissions and the difference
    // in frustum tests, per command beyond the nodes.
    {
      std::vector<double> perObject, nodes;
      double nodeCount = 1.0, nodeTestCount = 0.0;
      for (int r = 0; r <= 3; ++r)
        for (DynamicStrategy s : {DynamicStrategy::Octree, DynamicStrategy::PerCommand}) {
          pass.setStrategy(s);
          const double t0 = threadMs();
          b.renderer.beginFrame(b.camera, b.light);
          pass.draw(b.renderer, b.frame++);
          b.renderer.endFrame();
          const double t = threadMs() - t0;
          b.renderer.finish();
          if (s == DynamicStrategy::Octree)
            nodeCount = std::max(1u, pass.stats().submissions), nodeTestCount = pass.stats().frustumTests;
          if (r > 0) (s == DynamicStrategy::Octree ? nodes : perObject).push_back(t);
        }
      pass.setStrategy(DynamicStrategy::Octree);
      std::sort(perObject.begin(), perObject.end());
      std::sort(nodes.begin(), nodes.end());
      const double n = kBig[1];
      const double large = ((perObject[0] - nodes[0]) * 1e6 + (nodeCount - 1.0) * c.submit_ns -
                            (n - nodeTestCount) * c.cull_ns) / (n - nodeCount);
      // Noise, or no growth seen: one constant t_c.
      c.commandLarge_ns = large > c.command_ns ? large : c.command_ns;
      c.commandLargeCount = large > c.command_ns ? n : 0.0;
    }
    c = lod::fitOverlap(c, overlapFrames[0], overlapFrames[1]);
  }
  const std::string e = glErrors();
  if (!e.empty()) return error = "calibration: GL errors " + e, false;
  if (!lod::valid(c)) {
    char buf[256];
    std::snprintf(buf, sizeof buf, "calibration: implausible constants (tri %.3g ns, frag %.3g ns, state %.3g ns)",
                  c.tri_ns, c.frag_ns, c.state_ns);
    error = buf;
    return false;
  }
  return true;
}

}  // namespace

double medianOfRuns(std::vector<double> v) {
  if (v.empty()) return 0.0;
  // Nearest rank: the lower middle of an even count (v[n / 2] took the upper one, the slower run
  // of two: the very run a slow phase of the machine covered).
  const auto k = static_cast<long>((v.size() - 1) / 2);
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[static_cast<size_t>(k)];
}

bool calibrate(const std::string& cachePath, const CalibrationOptions& o, CalibrationResult& out, std::string& error,
               std::string* warning) {
  if (o.width_px <= 0 || o.height_px <= 0 || o.width_px > 16384 || o.height_px > 16384) {
    error = "calibration: viewport " + std::to_string(o.width_px) + "x" + std::to_string(o.height_px) + ": out of range";
    return false;
  }
  if (!std::isfinite(o.budget_s) || o.budget_s <= 0.0) {
    error = "calibration: budget_s = " + std::to_string(o.budget_s) + ": must be > 0";
    return false;
  }
  out = {};
  out.key = calibrationKey(o);
  std::string why;
  if (!cachePath.empty() && !o.ignoreCache && readCalibrationCache(cachePath, out.key, out.constants, why)) {
    out.fromCache = true;
    return true;
  }
  const auto start = Clock::now();
  const int runs = std::clamp(o.runs, 1, 9);
  std::vector<lod::PerfConstants> measured(static_cast<size_t>(runs));
  std::vector<std::array<lod::OverlapSample, 2>> overlapFrames(static_cast<size_t>(runs));
  double hookSeconds = 0.0;  // in afterRun, not measuring
  for (size_t r = 0; r < measured.size(); ++r) {
    lod::OverlapSample frames[2];
    if (!measure(o, static_cast<int>(r), measured[r], frames, error)) return false;
    overlapFrames[r] = {frames[0], frames[1]};
    if (o.afterRun) {
      const auto hook = Clock::now();
      if (!o.afterRun(static_cast<int>(r), error)) return false;
      hookSeconds += std::chrono::duration<double>(Clock::now() - hook).count();
    }
  }
  // Each constant the median of the runs (each entry of the T_tri table too, which keeps it
  // non-increasing): a slow phase of a shared machine that covers one run does not decide it.
  lod::PerfConstants c = measured.front();
  const auto median = [&](const auto& get) {
    std::vector<double> v;
    for (lod::PerfConstants& m : measured) v.push_back(get(m));
    return medianOfRuns(std::move(v));
  };
  for (const Field& f : kFields) c.*f.member = median([&](lod::PerfConstants& m) -> double { return m.*f.member; });
  for (size_t i = 0; i < c.triByDraw_ns.size(); ++i)
    c.triByDraw_ns[i] = median([&](lod::PerfConstants& m) -> double { return m.triByDraw_ns[i]; });
  // The overlap fitted again with these constants, to the median of the runs' times for its two
  // frames (the same scenes every run), so that it agrees with the T_rtri, T_edge ... it is used
  // with (lod::fitOverlap).
  if (runs > 1) {
    lod::OverlapSample frames[2] = {overlapFrames[0][0], overlapFrames[0][1]};
    for (size_t k = 0; k < 2; ++k) {
      std::vector<double> times;
      for (const auto& f : overlapFrames) times.push_back(f[k].measured_ns);
      frames[k].measured_ns = medianOfRuns(std::move(times));
    }
    c = lod::fitOverlap(c, frames[0], frames[1]);
  }
  out.constants = c;
  out.seconds = std::chrono::duration<double>(Clock::now() - start).count() - hookSeconds;
  if (!cachePath.empty()) {
    std::string werr;
    if (!writeCalibrationCache(cachePath, out.key, c, werr) && warning) *warning = werr;
  }
  return true;
}

}  // namespace ig::render
