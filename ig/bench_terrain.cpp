#include "ig/bench_terrain.h"
#include "ig/json.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "ig/clock.h"
#include "ig/roam_deadline.h"
#include "ig/stats.h"
#include "io/dem.h"
#include "lod/block_lod.h"
#include "lod/heightfield.h"
#include "lod/roam.h"
#include "lod/terrain_grid.h"
#include "lod/triangle_slots.h"
#include "render/context.h"
#include "render/image.h"
#include "render/renderer.h"

namespace ig {
namespace {

using BenchClock = std::chrono::steady_clock;
double msSince(BenchClock::time_point t0) { return std::chrono::duration<double, std::milli>(BenchClock::now() - t0).count(); }

// The hard end of a budgeted Deferred update, as igd sets it (ig::RoamDeadline on this clock).
MonotonicClock deadlineClock;

// The height field the bench runs on: decoded into memory, or mapped from the raw cache.
struct Field {
  io::Dem decoded;     // when not mapped (rows already flipped: south first)
  io::MappedDem mapped;
  std::span<const float> heights;
  int width = 0, height = 0;
  double spacing_m = 0.0;
  float lo = 0.0f, hi = 0.0f;
};

struct PathFrame {
  lod::Camera camera;
  bool teleport = false;
};

// The centre of the most rugged of 8 x 8 blocks of the DEM (the largest max - min height; the
// first of equal ones), in metres from its south-west corner. A real DEM is often sea or plain
// where the old fixed start flew (N57E011 at 0.55, 0.3 of its extent: the Kattegat, a sweep from
// 2,451 to 72 triangles with every tolerance within 0.03 of the same 0.07 RMSE); the tolerance
// sweep and the flight mean something over relief. Heights are sampled on a grid of at most
// ~256 x 256 posts a block.
glm::dvec2 mostRuggedBlock(const Field& f) {
  constexpr int kBlocks = 8;
  double best = -1.0;
  glm::dvec2 centre{0.5 * (f.width - 1) * f.spacing_m, 0.5 * (f.height - 1) * f.spacing_m};
  for (int by = 0; by < kBlocks; ++by)
    for (int bx = 0; bx < kBlocks; ++bx) {
      const int x0 = bx * (f.width - 1) / kBlocks, x1 = (bx + 1) * (f.width - 1) / kBlocks;
      const int y0 = by * (f.height - 1) / kBlocks, y1 = (by + 1) * (f.height - 1) / kBlocks;
      const int step = std::max(1, std::max(x1 - x0, y1 - y0) / 256);
      float lo = std::numeric_limits<float>::infinity(), hi = -lo;
      for (int y = y0; y <= y1; y += step)
        for (int x = x0; x <= x1; x += step) {
          const float h = f.heights[static_cast<size_t>(y) * static_cast<size_t>(f.width) + static_cast<size_t>(x)];
          lo = std::min(lo, h);
          hi = std::max(hi, h);
        }
      if (static_cast<double>(hi - lo) > best) {
        best = static_cast<double>(hi - lo);
        centre = {0.5 * (x0 + x1) * f.spacing_m, 0.5 * (y0 + y1) * f.spacing_m};
      }
    }
  return centre;
}

// Flies north-north-east 120 m above the DEM's highest point, turns hard (90 deg/s) in the
// middle third, teleports at 2/3 and flies on. A synthetic DEM (mountains everywhere) starts at
// 0.55, 0.3 of its extent and teleports to 0.9, 0.85 heading 200 deg (the flight of every
// measurement before 2026-12-07 in docs/terrain.md). A DEM file starts 2 km before the centre of
// its most rugged block (mostRuggedBlock: the reference view at a quarter of the frames looks
// at it) and teleports to the farthest of the points 0.1 / 0.9, 0.15 / 0.85 of its extent,
// heading for its centre.
std::vector<PathFrame> flightPath(const Field& f, int frames, double aspect, bool seekRelief) {
  std::vector<PathFrame> path;
  const double extentX = (f.width - 1) * f.spacing_m, extentY = (f.height - 1) * f.spacing_m;
  double heading = 20.0;
  const double kDegToRad = 3.14159265358979323846 / 180.0;
  glm::dvec3 eye{0.55 * extentX, 0.3 * extentY, static_cast<double>(f.hi) + 120.0};
  if (seekRelief) {
    const glm::dvec2 c = mostRuggedBlock(f) - 2000.0 * glm::dvec2(std::sin(heading * kDegToRad), std::cos(heading * kDegToRad));
    eye.x = std::clamp(c.x, 0.05 * extentX, 0.95 * extentX);
    eye.y = std::clamp(c.y, 0.05 * extentY, 0.95 * extentY);
  }
  constexpr double kDt = 1.0 / 60.0, kSpeed = 250.0;
  for (int i = 0; i < frames; ++i) {
    PathFrame p;
    if (i == 2 * frames / 3) {
      glm::dvec2 to{0.9 * extentX, 0.85 * extentY};
      if (seekRelief) {
        double farthest = -1.0;
        for (const double fx : {0.1, 0.9})
          for (const double fy : {0.15, 0.85}) {
            const glm::dvec2 q{fx * extentX, fy * extentY};
            if (const double d = glm::length(q - glm::dvec2(eye)); d > farthest) farthest = d, to = q;
          }
        const glm::dvec2 toCentre = glm::dvec2(0.5 * extentX, 0.5 * extentY) - to;
        heading = std::atan2(toCentre.x, toCentre.y) / kDegToRad;
      } else {
        heading = 200.0;
      }
      eye = {to.x, to.y, eye.z};
      p.teleport = true;
    } else if (i > frames / 3 && i < 2 * frames / 3) {
      heading += 90.0 * kDt;
    }
    const double h = heading * kDegToRad;
    eye += glm::dvec3(std::sin(h), std::cos(h), 0.0) * (kSpeed * kDt);
    p.camera.eye_m = eye;
    p.camera.heading_deg = heading;
    p.camera.pitch_deg = -8.0;
    p.camera.fovY_deg = 45.0;
    p.camera.aspect = aspect;
    p.camera.near_m = 0.5;
    p.camera.far_m = 100000.0;
    path.push_back(p);
  }
  return path;
}

// Changed triangles between frames (what a renderer must upload): sorted keys, merge diff.
uint64_t triangleKey(const lod::RoamTriangle& t) {
  uint64_t k[3];
  for (int i = 0; i < 3; ++i)
    k[i] = (static_cast<uint64_t>(static_cast<uint32_t>(t.v[i].x)) << 16) ^ static_cast<uint32_t>(t.v[i].y);
  std::sort(k, k + 3);
  return (k[0] * 0x9E3779B97F4A7C15ull) ^ (k[1] * 0xC2B2AE3D27D4EB4Full) ^ (k[2] * 0x165667B19E3779F9ull);
}
uint64_t changedTriangles(const std::vector<uint64_t>& prev, std::vector<uint64_t>& cur) {
  std::sort(cur.begin(), cur.end());
  uint64_t added = 0;
  size_t i = 0, j = 0;
  while (j < cur.size()) {
    if (i < prev.size() && prev[i] < cur[j]) ++i;
    else if (i < prev.size() && prev[i] == cur[j]) ++i, ++j;
    else ++added, ++j;
  }
  return added;
}

struct MethodResult {
  std::string name;
  bool ran = false;
  double updateP50 = 0, updateP99 = 0, teleport = 0, maxErrorPx = 0, emitP50 = 0, startupMs = 0;
  double cpuP50 = 0, cpuP99 = 0;  // thread CPU time of the update
  uint64_t trianglesP50 = 0, uploadsP50 = 0;
  uint64_t visibleP50 = 0;  // triangles in the view frustum (what is drawn)
  // Deferred under a visit budget.
  double visitsP50 = 0, pendingP99 = 0, maxErrorUnfinishedPx = 0;
  int unfinishedFrames = 0;
  double nsPerVisit = 0;  // Deferred under a time budget: the rate estimate at the end of the flight
  size_t boundsBytes = 0, poolBytes = 0;
};

lod::RoamView viewFor(const lod::Camera& cam, int height_px, double tolerance_px, uint32_t maxVisits = 0) {
  lod::RoamView v;
  v.camera = cam;
  v.viewportHeight_px = height_px;
  v.tolerance_px = tolerance_px;
  v.maxVisits = maxVisits;
  return v;
}

struct UpdateResult {
  uint64_t triangles;
  double maxErrorPx;
  bool finished = true;
  double visits = 0, pending = 0;
};

// Flies the path with one method. `update(view, frame)` runs the method's LOD step (timed);
// `visible(camera, out, uploads)` writes what is drawn (timed as the emit) and returns how many.
// Uploads (triangles new since the previous frame) are counted every eighth frame from the
// drawn lists, unless `visible` sets `uploads` itself (>= 0: the slots it would write this
// frame; `out` is then not read).
template <class Update, class Visible, class ExactError>
MethodResult fly(const char* name, const std::vector<PathFrame>& path, int height_px, double tolerance_px,
                 Update update, Visible visible, ExactError exactError) {
  TerrainFlightSamples s;
  std::vector<double> uploads;
  std::vector<lod::RoamTriangle> out;
  std::vector<uint64_t> prev, cur;
  MethodResult r;
  r.name = name;
  r.ran = true;
  for (size_t i = 0; i < path.size(); ++i) {
    const PathFrame& f = path[i];
    const lod::RoamView view = viewFor(f.camera, height_px, tolerance_px);
    const double c0 = threadCpuMs();
    const auto t0 = BenchClock::now();
    const UpdateResult u = update(view, i);
    const double t = msSince(t0);
    // The first frame builds the mesh from the base triangles (the start-up): reported apart.
    if (i == 0) r.startupMs = t;
    s.addUpdate(i, t, threadCpuMs() - c0, static_cast<double>(u.triangles), u.visits, u.pending);
    if (f.teleport) r.teleport = t;
    if (u.finished) {
      r.maxErrorPx = std::max(r.maxErrorPx, u.maxErrorPx);
    } else {
      ++r.unfinishedFrames;
      if (i % 8 == 0) r.maxErrorUnfinishedPx = std::max(r.maxErrorUnfinishedPx, exactError(view));
    }
    const auto t1 = BenchClock::now();
    double written = -1.0;
    const size_t n = visible(f.camera, out, written);
    s.addEmit(i, msSince(t1), static_cast<double>(n));
    if (written >= 0.0) {
      if (i % 8 == 0 && i > 0) uploads.push_back(written);
    } else if (i % 8 == 7 || (i % 8 == 0 && i > 0)) {
      cur.clear();
      for (size_t k = 0; k < n; ++k) cur.push_back(triangleKey(out[k]));
      if (i % 8 == 0) uploads.push_back(static_cast<double>(changedTriangles(prev, cur)));
      else std::sort(cur.begin(), cur.end());
      prev.swap(cur);
    }
  }
  r.updateP50 = percentile(s.update_ms, 50);
  r.updateP99 = percentile(s.update_ms, 99);
  r.cpuP50 = percentile(s.cpu_ms, 50);
  r.cpuP99 = percentile(s.cpu_ms, 99);
  r.emitP50 = percentile(s.emit_ms, 50);
  r.trianglesP50 = static_cast<uint64_t>(percentile(s.triangles, 50));
  r.uploadsP50 = uploads.empty() ? 0 : static_cast<uint64_t>(percentile(uploads, 50));
  r.visibleP50 = static_cast<uint64_t>(percentile(s.visible, 50));
  r.visitsP50 = percentile(s.visits, 50);
  r.pendingP99 = percentile(s.pending, 99);
  return r;
}

lod::RoamConfig roamConfig(lod::RoamMode mode) {
  // Deferred refines the whole surroundings (4-7x the triangles of the view-culled mesh), so
  // it gets room for 8 M; the view-culled modes stay well under the default 1 M.
  lod::RoamConfig config;
  if (mode == lod::RoamMode::Deferred) config.maxTriangles = 8u << 20;
  return config;
}

MethodResult flyRoam(const lod::Roam& bounds, const std::vector<PathFrame>& path, lod::RoamMode mode, const char* name,
                     int height_px, double tolerance_px, uint32_t visits, double lateness = 0.0, double budget_ms = 0.0) {
  lod::Roam roam(bounds, roamConfig(mode));
  double nsPerVisit = 100.0;  // budget_ms > 0: smoothed as igd's TerrainMeshLayer does
  RoamDeadline deadline;
  // Deferred runs as igd runs it without geomorphing: the mesh kept in the vertex buffer by
  // chunk, so between updates a frame touches the changed leaves and the chunk boxes (a
  // visible-leaf walk, 0.2 s a frame at 16385^2, would also evict everything the next update
  // reads, and igd does not do it).
  std::unique_ptr<lod::TerrainChunks> chunks;
  std::vector<lod::TerrainDrawRange> ranges;
  if (mode == lod::RoamMode::Deferred) chunks = std::make_unique<lod::TerrainChunks>(roam);
  MethodResult r = fly(
      name, path, height_px, tolerance_px,
      [&](lod::RoamView v, size_t frame) {
        // The first frame is the start-up (the IG positions before running in real time):
        // unbudgeted. Later frames run under the visit budget.
        if (frame > 0) {
          v.maxVisits = budget_ms > 0.0 ? static_cast<uint32_t>(std::clamp(budget_ms * 1e6 / nsPerVisit, 256.0, 1e9)) : visits;
        }
        v.lateness = lateness;
        const auto t0 = BenchClock::now();
        if (frame > 0 && budget_ms > 0.0) deadline.arm(v, deadlineClock, deadlineClock.now_ns(), budget_ms);
        const lod::RoamStats st = roam.update(v, mode);
        if (frame > 0 && st.visits >= 256)
          nsPerVisit = lod::budgetRate(nsPerVisit, msSince(t0) * 1e6 / static_cast<double>(st.visits));
        return UpdateResult{st.triangles, st.maxErrorPx, st.finished, static_cast<double>(st.visits),
                            static_cast<double>(st.pending)};
      },
      [&](const lod::Camera& cam, std::vector<lod::RoamTriangle>& out, double& uploads) -> size_t {
        if (chunks) {  // igd's path: replay ROAM's changes into the slots, cull the chunks
          uploads = static_cast<double>(chunks->apply().dirty);
          return chunks->cull(cam, ranges);
        }
        out.resize(roam.triangleCount());
        return roam.emitVisible(cam, out);
      },
      [&](const lod::RoamView& v) { return roam.maxErrorPx(v); });
  r.boundsBytes = roam.boundsBytes();
  r.poolBytes = roam.poolBytes();
  r.nsPerVisit = nsPerVisit;
  return r;
}

MethodResult flyBlock(const Field& dem, const std::vector<PathFrame>& path, int height_px, double tolerance_px) {
  lod::BlockLod block(dem.heights, dem.width, dem.height, dem.spacing_m, {0, 0, 0});
  return fly(
      "block", path, height_px, tolerance_px,
      [&](const lod::RoamView& v, size_t) {
        const lod::BlockLodStats st = block.update(v);
        return UpdateResult{st.triangles, st.maxErrorPx};
      },
      [&](const lod::Camera&, std::vector<lod::RoamTriangle>& out, double&) {
        out.resize(block.triangleBound());
        out.resize(block.emitTriangles(out));
        return out.size();
      },
      [&](const lod::RoamView&) { return 0.0; });
}

// Teleport: converged at the eye before the jump, then at the new eye. Merges alone
// (MergeQueue) and enhMerge (EnhMerge) do it in one unbudgeted update; Deferred under a visit
// budget restarts from the base triangles and converges over several updates, visible leaves
// first. The exact visible error is measured after each update (not timed).
struct TeleportResult {
  double jump_km = 0, mergeMs = 0, enhMergeMs = 0, firstFrameMs = 0, frameMsMax = 0, visibleMs = 0, finishedMs = 0;
  int framesToVisible = -1, framesToFinished = -1;
  uint64_t mergeOps = 0, enhMergeOps = 0;
};

// Deferred converges at the new eye under a fixed number of visits an update, or (budget_ms > 0)
// under a time budget (visits from the measured rate, from the flight's ns_per_visit; the
// deadline as a hard stop).
TeleportResult teleport(const lod::Roam& bounds, const std::vector<PathFrame>& path, int height_px, uint32_t visits,
                        double lateness, int maxFrames, double budget_ms, double ns_per_visit) {
  TeleportResult r;
  size_t at = 0;
  while (at < path.size() && !path[at].teleport) ++at;
  if (at == 0 || at >= path.size()) return r;
  const lod::RoamView before = viewFor(path[at - 1].camera, height_px, 1.0);
  const lod::RoamView after = viewFor(path[at].camera, height_px, 1.0);
  r.jump_km = glm::length(after.camera.eye_m - before.camera.eye_m) / 1000.0;
  for (const lod::RoamMode mode : {lod::RoamMode::MergeQueue, lod::RoamMode::EnhMerge}) {
    lod::Roam roam(bounds, roamConfig(mode));
    roam.update(before, mode);
    const auto t0 = BenchClock::now();
    const lod::RoamStats st = roam.update(after, mode);
    (mode == lod::RoamMode::MergeQueue ? r.mergeMs : r.enhMergeMs) = msSince(t0);
    (mode == lod::RoamMode::MergeQueue ? r.mergeOps : r.enhMergeOps) = st.merges + st.enhMerges;
  }
  lod::Roam roam(bounds, roamConfig(lod::RoamMode::Deferred));
  lod::RoamView v0 = before;
  v0.lateness = lateness;
  roam.update(v0, lod::RoamMode::Deferred);
  lod::RoamView v = after;
  v.maxVisits = visits;
  v.lateness = lateness;
  double total = 0;
  double nsPerVisit = ns_per_visit > 0.0 ? ns_per_visit : 100.0;
  RoamDeadline deadline;
  for (int f = 1; f <= maxFrames; ++f) {
    if (budget_ms > 0.0) v.maxVisits = static_cast<uint32_t>(std::clamp(budget_ms * 1e6 / nsPerVisit, 256.0, 1e9));
    const auto t0 = BenchClock::now();
    if (budget_ms > 0.0) deadline.arm(v, deadlineClock, deadlineClock.now_ns(), budget_ms);
    const lod::RoamStats st = roam.update(v, lod::RoamMode::Deferred);
    const double t = msSince(t0);
    if (budget_ms > 0.0 && st.visits >= 256) nsPerVisit = lod::budgetRate(nsPerVisit, t * 1e6 / static_cast<double>(st.visits));
    total += t;
    if (f == 1) r.firstFrameMs = t;
    r.frameMsMax = std::max(r.frameMsMax, t);
    // The exact visible error walks every leaf: every 4th update (and the last), so that the
    // walk does not leave every update cold caches (frames_to_visible is rounded up to it).
    if (r.framesToVisible < 0 && (f % 4 == 0 || st.finished) && roam.maxErrorPx(after) <= v.tolerance_px + 1e-9) {
      r.framesToVisible = f;
      r.visibleMs = total;
    }
    if (st.finished) {
      r.framesToFinished = f;
      r.finishedMs = total;
      if (r.framesToVisible < 0) r.framesToVisible = f, r.visibleMs = total;
      break;
    }
  }
  return r;
}

struct SweepRow {
  double tolerance = 0, updateMs = 0, renderMs = 0, rmse = 0, psnr = 0;
  uint64_t triangles = 0;
};

struct RasterResult {
  bool ran = false;
  double rasterMs = 0, trianglesPerS = 0, frameMsP50 = 0, updateMsP50 = 0, emitMsP50 = 0, uploadMsP50 = 0,
         drawMsP50 = 0, ratio = 0;
  // lod::TerrainChunks: chunk size, mesh in the buffer, slots written and drawn a frame.
  int chunkSide = 0;
  size_t chunks = 0, meshTriangles = 0;
  double dirtySlotsP50 = 0, drawnSlotsP50 = 0, drawnLiveP50 = 0, rangesP50 = 0;
  uint64_t triangles = 0;
};

std::string num(double v, int decimals = 4) {
  if (!std::isfinite(v)) return "null";
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", decimals, v);
  return b;
}

bool loadField(const TerrainBenchOptions& o, Field& f, std::string& demName, bool& fromCache, std::string& cacheFile,
               std::string& error) {
  if (o.syntheticSamples > 0) {
    // Stress case: a mountainous procedural field of the size asked for (the real SRTM tile
    // is 1201 wide and mostly flat coast), 2500 m of relief at 30 m.
    lod::HeightfieldDesc d;
    d.seed = 20261123;
    d.postsX = d.postsY = o.syntheticSamples;
    d.postSpacing_m = 30.0;
    d.heightScale_m = 2500.0;
    demName = "procedural:" + std::to_string(o.syntheticSamples);
    if (!o.cacheDir.empty()) {
      std::error_code ec;
      std::filesystem::create_directories(o.cacheDir, ec);
      cacheFile = (std::filesystem::path(o.cacheDir) / ("synthetic-" + std::to_string(o.syntheticSamples) + "-" +
                                                        std::to_string(d.seed) + ".igdem")).string();
      std::string why;
      if (io::mapDemCache(cacheFile, f.mapped, why)) {
        fromCache = true;
      } else {
        std::vector<float> h(static_cast<size_t>(d.postsX) * static_cast<size_t>(d.postsY));
        lod::generateHeightfield(d, h);
        if (!io::writeDemCache(cacheFile, h, d.postsX, d.postsY, 30.0, 0, 0, error) ||
            !io::mapDemCache(cacheFile, f.mapped, error))
          return false;
      }
      f.heights = f.mapped.heights_m();
      f.width = f.height = o.syntheticSamples;
      f.spacing_m = 30.0;
      return true;
    }
    f.decoded.width = f.decoded.height = o.syntheticSamples;
    f.decoded.spacing_m = 30.0;
    f.decoded.heights_m.resize(static_cast<size_t>(d.postsX) * static_cast<size_t>(d.postsY));
    lod::generateHeightfield(d, f.decoded.heights_m);
  } else if (!o.cacheDir.empty()) {
    io::DemCacheInfo info;
    if (!io::loadDemCached(o.demFile, o.cacheDir, {}, f.mapped, info, error)) return false;
    fromCache = info.fromCache;
    cacheFile = info.cacheFile;
    f.heights = f.mapped.heights_m();
    f.width = f.mapped.width();
    f.height = f.mapped.height();
    f.spacing_m = o.demSpacing_m > 0 ? o.demSpacing_m : f.mapped.spacing_m() > 0 ? f.mapped.spacing_m() : 30.0;
    return true;
  } else {
    if (!io::loadDem(o.demFile, {}, f.decoded, error)) return false;
    io::flipRows(f.decoded);  // files store north first; the LOD grids want y northwards
  }
  f.heights = f.decoded.heights_m;
  f.width = f.decoded.width;
  f.height = f.decoded.height;
  f.spacing_m = o.demSpacing_m > 0 ? o.demSpacing_m : f.decoded.spacing_m > 0 ? f.decoded.spacing_m : 30.0;
  return true;
}

}  // namespace

void TerrainFlightSamples::addUpdate(size_t frame, double ms, double cpuMs, double tris, double nodeVisits,
                                     double pendingNodes) {
  if (frame == 0) return;  // the start-up
  update_ms.push_back(ms);
  cpu_ms.push_back(cpuMs);
  triangles.push_back(tris);
  visits.push_back(nodeVisits);
  pending.push_back(pendingNodes);
}

void TerrainFlightSamples::addEmit(size_t frame, double ms, double visibleTris) {
  if (frame == 0) return;
  emit_ms.push_back(ms);
  visible.push_back(visibleTris);
}

int runTerrainBench(const TerrainBenchOptions& o) {
  Field dem;
  std::string error, demName = o.demFile, cacheFile;
  bool fromCache = false;
  const auto tLoad = BenchClock::now();
  if (!loadField(o, dem, demName, fromCache, cacheFile, error)) {
    std::fprintf(stderr, "igbench terrain: %s (scripts/fetch-data fetches the default DEM)\n", error.c_str());
    return 2;
  }
  const double loadMs = msSince(tLoad);
  {
    const auto [lo, hi] = std::minmax_element(dem.heights.begin(), dem.heights.end());
    dem.lo = *lo;
    dem.hi = *hi;
  }
  const uint64_t samples = static_cast<uint64_t>(dem.width) * static_cast<uint64_t>(dem.height);
  const uint64_t full = 2ull * static_cast<uint64_t>(dem.width - 1) * static_cast<uint64_t>(dem.height - 1);
  // Above 4097^2 the slow baselines (a rebuild per frame; block LOD's finest-level buffers) are
  // left out; above 2049^2 the full-resolution reference render is (it would not fit).
  const bool large = samples > 4097ull * 4097ull;
  const bool renderSweep = o.render && o.baselines && full <= 8400000ull;
  const double aspect = static_cast<double>(o.width_px) / o.height_px;
  const auto path = flightPath(dem, o.frames, aspect, o.syntheticSamples <= 0);

  // The bounds are precomputed once; every mesh below shares them.
  const auto tBounds = BenchClock::now();
  const lod::Roam bounds(dem.heights, dem.width, dem.height, dem.spacing_m, {0, 0, 0}, lod::RoamConfig{.maxTriangles = 1024});
  const double boundsMs = msSince(tBounds);

  std::vector<MethodResult> methods;
  std::vector<std::string> skipped;
  if (o.baselines) {
    methods.push_back(flyRoam(bounds, path, lod::RoamMode::EnhMerge, "roam_enhmerge", o.height_px, 1.0, 0));
    methods.push_back(flyRoam(bounds, path, lod::RoamMode::MergeQueue, "roam_merge", o.height_px, 1.0, 0));
  } else {
    skipped.insert(skipped.end(), {"roam_enhmerge", "roam_merge"});
  }
  if (!large && o.baselines) methods.push_back(flyRoam(bounds, path, lod::RoamMode::Rebuild, "roam_rebuild", o.height_px, 1.0, 0));
  else skipped.push_back("roam_rebuild");
  if (!large && o.baselines) methods.push_back(flyBlock(dem, path, o.height_px, 1.0));
  else skipped.push_back("block");
  methods.push_back(flyRoam(bounds, path, lod::RoamMode::Deferred, "roam_deferred", o.height_px, 1.0, o.deferredVisits, o.lateness, o.budget_ms));
  const MethodResult& deferred = methods.back();

  const TeleportResult tp = teleport(bounds, path, o.height_px, o.teleportVisits, o.lateness, o.teleportMaxFrames,
                                     o.teleportBudget_ms, deferred.nsPerVisit);

  // Equal error (1 px) at the reference view: triangles each method needs.
  const lod::Camera refCam = path[static_cast<size_t>(o.frames / 4)].camera;
  uint64_t roamEqual = 0, blockEqual = 0;
  double blockBuildMs = 0.0;
  {
    lod::Roam refRoam(bounds, lod::RoamConfig{});
    refRoam.update(viewFor(refCam, o.height_px, 1.0), lod::RoamMode::Rebuild);
    std::vector<lod::RoamTriangle> tris(refRoam.triangleCount());
    roamEqual = refRoam.emitTriangles(tris);
    // Block LOD at every size: its per-block error tables are O(samples x levels) to build (the
    // time is reported), and update() counts the triangles without emitting them.
    const auto tBlock = BenchClock::now();
    lod::BlockLod refBlock(dem.heights, dem.width, dem.height, dem.spacing_m, {0, 0, 0});
    blockBuildMs = msSince(tBlock);
    blockEqual = refBlock.update(viewFor(refCam, o.height_px, 1.0)).triangles;
  }

  std::unique_ptr<render::GlContext> context;
  std::unique_ptr<render::Renderer> renderer;
  render::Image reference, image;
  render::Lighting light;
  light.sunDirection = glm::normalize(glm::dvec3(-0.5, 0.6, 0.6));
  light.fogVisibility_m = 60000.0;
  std::vector<lod::TerrainVertex> vertices;
  std::string contextName = "none";
  // Triangle slots of the frame experiment: the whole Deferred mesh (lod::TerrainChunks keeps
  // every leaf in the buffer, and draws the chunks in view).
  const size_t rasterCapacity = static_cast<size_t>(roamConfig(lod::RoamMode::Deferred).maxTriangles) / 2 * 3;
  auto vertexAt = [&](int x, int y) { return lod::heightFieldVertex(dem.heights, dem.width, dem.height, dem.spacing_m, x, y); };
  // Median of 5 draws (upload + draw + glFinish): one frame alone is too noisy here.
  auto renderMesh = [&](std::span<const lod::RoamTriangle> list, render::Image& out) {
    vertices.clear();
    for (const auto& t : list)
      for (const auto& v : t.v) vertices.push_back(vertexAt(v.x, v.y));
    std::vector<double> times;
    for (int i = 0; i < 5; ++i) {
      renderer->beginFrame(refCam, light);
      const auto t0 = BenchClock::now();
      renderer->drawTerrainMesh({0, 0, 0}, vertices);
      renderer->endFrame();
      renderer->finish();
      times.push_back(msSince(t0));
    }
    renderer->readPixels(out);
    return percentile(times, 50);
  };
  if (o.render) {
    context = render::createContext(render::ContextKind::Headless, o.width_px, o.height_px, error);
    renderer = std::make_unique<render::Renderer>();
    const size_t capacity = std::max<size_t>(renderSweep ? full : 0, o.rasterFrames > 0 ? rasterCapacity : size_t{1} << 16);
    if (!context || !renderer->init(o.width_px, o.height_px, error) ||
        !renderer->addTerrainMesh(capacity * 3, static_cast<double>(dem.hi - dem.lo), error)) {
      std::fprintf(stderr, "igbench terrain: %s\n", error.c_str());
      return 3;
    }
    contextName = context->description();
  }
  if (renderSweep) {
    // Reference: every DEM sample (full resolution).
    std::vector<lod::RoamTriangle> all;
    all.reserve(full);
    for (int y = 0; y + 1 < dem.height; ++y)
      for (int x = 0; x + 1 < dem.width; ++x) {
        all.push_back({{{x, y}, {x + 1, y}, {x + 1, y + 1}}});
        all.push_back({{{x, y}, {x + 1, y + 1}, {x, y + 1}}});
      }
    renderMesh(all, reference);
    if (const char* dump = std::getenv("IGBENCH_DUMP_REFERENCE")) render::writePng(dump, reference, error);
  }

  // Sweep: what accuracy costs in time.
  const double tolerances[] = {0.5, 1.0, 2.0, 4.0, 8.0};
  std::vector<SweepRow> sweep;
  for (double tol : tolerances) {
    if (!o.baselines) break;
    SweepRow row;
    row.tolerance = tol;
    lod::Roam roam(bounds, lod::RoamConfig{});
    std::vector<double> ms;
    for (size_t i = 0; i <= static_cast<size_t>(o.frames / 4); ++i) {  // fly to the reference view
      const auto t0 = BenchClock::now();
      roam.update(viewFor(path[i].camera, o.height_px, tol), lod::RoamMode::EnhMerge);
      ms.push_back(msSince(t0));
    }
    row.updateMs = percentile(ms, 50);
    std::vector<lod::RoamTriangle> list(roam.triangleCount());
    list.resize(roam.emitTriangles(list));
    row.triangles = list.size();
    if (renderSweep) {
      row.renderMs = renderMesh(list, image);
      row.rmse = render::rmse(image, reference);
      row.psnr = render::psnrDb(image, reference);  // at most 99 (identical), as every benchmark reports it
    }
    sweep.push_back(row);
  }

  // The terrain frame (Deferred under its budget: update, emit the visible leaves, write what
  // changed into the mapped buffer, draw, glFinish) against the rasterizer's limit: the same
  // number of triangles, static in the buffer, drawn with glFinish.
  RasterResult raster;
  if (o.render && o.rasterFrames > 0) {
    const size_t start = static_cast<size_t>(o.frames / 4);
    const size_t count = std::min<size_t>(static_cast<size_t>(o.rasterFrames), path.size() - start - 1);
    lod::Roam roam(bounds, roamConfig(lod::RoamMode::Deferred));
    // Start-up at the path's first view, then the flight up to `start` untimed, so that the
    // timed frames change the mesh as a steady flight does (a fresh schedule has nothing due
    // for the first hundred metres).
    lod::RoamView startView = viewFor(path[0].camera, o.height_px, 1.0);
    startView.lateness = o.lateness;
    roam.update(startView, lod::RoamMode::Deferred);
    // The mesh lives in the vertex buffer by chunk (lod/terrain_chunks.h): a frame writes the
    // slots ROAM changed and draws the chunks inside the frustum.
    lod::TerrainChunksConfig chunkConfig;
    chunkConfig.capacityTriangles = rasterCapacity;
    lod::TerrainChunks chunks(roam, chunkConfig);
    std::vector<lod::RoamTriangle> tris(roam.nodeCapacity() / 2 + 16);
    std::vector<lod::TerrainDrawRange> ranges;
    const std::span<lod::TerrainVertex> gpu = renderer->terrainMeshVertices();
    auto writeDirty = [&] {
      chunks.forEachDirty(
          [&](uint32_t s, const lod::RoamTriangle& t) {
            for (size_t v = 0; v < 3; ++v) gpu[s * 3 + v] = vertexAt(t.v[v].x, t.v[v].y);
          },
          [&](uint32_t s) {
            for (size_t v = 0; v < 3; ++v) gpu[s * 3 + v] = lod::TerrainVertex{};
          });
    };
    chunks.apply();  // start-up: every leaf
    writeDirty();
    for (size_t k = 1; k <= start; ++k) {
      lod::RoamView fv = viewFor(path[k].camera, o.height_px, 1.0, o.deferredVisits);
      fv.lateness = o.lateness;
      roam.update(fv, lod::RoamMode::Deferred);
      chunks.apply();
      writeDirty();
    }
    std::vector<double> frameMs, updateMs, emitMs, uploadMs, drawMs, dirty, drawnSlots, drawnLive, rangeCount;
    size_t lastN = 0;
    for (size_t k = 1; k <= count; ++k) {
      const lod::Camera& cam = path[start + k].camera;
      const auto t0 = BenchClock::now();
      lod::RoamView fv = viewFor(cam, o.height_px, 1.0, o.deferredVisits);
      fv.lateness = o.lateness;
      roam.update(fv, lod::RoamMode::Deferred);
      const auto t1 = BenchClock::now();
      const lod::TerrainChunks::Changes c = chunks.apply();
      double nearest_m = 0.0;
      const size_t live = chunks.cull(cam, ranges, render::kTerrainDetailReach_m, &nearest_m);
      const auto t2 = BenchClock::now();
      writeDirty();
      const auto t3 = BenchClock::now();
      renderer->beginFrame(cam, light);
      renderer->drawTerrainMeshRanges({0, 0, 0}, ranges, nearest_m);
      renderer->endFrame();
      renderer->finish();
      const auto t4 = BenchClock::now();
      auto d = [](auto a, auto b) { return std::chrono::duration<double, std::milli>(b - a).count(); };
      frameMs.push_back(d(t0, t4));
      updateMs.push_back(d(t0, t1));
      emitMs.push_back(d(t1, t2));
      uploadMs.push_back(d(t2, t3));
      drawMs.push_back(d(t3, t4));
      double slotsDrawn = 0;
      for (const lod::TerrainDrawRange& r : ranges) slotsDrawn += r.count;
      dirty.push_back(static_cast<double>(c.dirty));
      drawnSlots.push_back(slotsDrawn);
      drawnLive.push_back(static_cast<double>(live));
      rangeCount.push_back(static_cast<double>(ranges.size()));
    }
    // The reference is what ROAM emits for the view: the visible leaves, packed, static.
    lastN = std::min(roam.emitVisible(path[start + count].camera, tris), rasterCapacity);
    raster.chunkSide = chunks.chunkSide();
    raster.chunks = chunks.chunkCount();
    raster.meshTriangles = chunks.liveTriangles();
    raster.dirtySlotsP50 = percentile(dirty, 50);
    raster.drawnSlotsP50 = percentile(drawnSlots, 50);
    raster.drawnLiveP50 = percentile(drawnLive, 50);
    raster.rangesP50 = percentile(rangeCount, 50);
    if (count > 0 && lastN > 0) {
      // Static: the last frame's visible triangles packed at the front of the buffer, shaded as
      // the frame shades them: the triangles within the ground detail's reach first, drawn with
      // the detail variant for their nearest box, the rest without the detail terms (as
      // drawTerrainMeshRanges draws the near and far chunk ranges; one draw with nearest_m = 0
      // would pay for both noise terms on every fragment, which the frame does not).
      const lod::Camera& cam = path[start + count].camera;
      const auto nearBox = [&](std::span<const lod::RoamTriangle> t, double enough) {
        return lod::nearestTriangleBox(t, dem.heights, dem.width, dem.height, dem.spacing_m, cam.eye_m, enough);
      };
      const auto farBegin = std::stable_partition(tris.begin(), tris.begin() + static_cast<std::ptrdiff_t>(lastN),
                                                  [&](const lod::RoamTriangle& t) {
                                                    return nearBox({&t, 1}, render::kTerrainDetailReach_m) <
                                                           render::kTerrainDetailReach_m;
                                                  });
      const auto nearCount = static_cast<uint32_t>(farBegin - tris.begin());
      const double nearest_m = nearBox({tris.data(), nearCount}, render::kTerrainFineDetailReach_m);
      std::vector<lod::TerrainDrawRange> staticRanges;
      if (nearCount > 0) staticRanges.push_back({0, nearCount, 1});
      if (lastN > nearCount) staticRanges.push_back({nearCount, static_cast<uint32_t>(lastN) - nearCount, 0});
      for (size_t i = 0; i < lastN; ++i)
        for (size_t v = 0; v < 3; ++v) gpu[i * 3 + v] = vertexAt(tris[i].v[v].x, tris[i].v[v].y);
      std::vector<double> times;
      for (int i = 0; i < 5; ++i) {
        const auto t0 = BenchClock::now();  // as the frame's draw_ms: from beginFrame to glFinish
        renderer->beginFrame(cam, light);
        renderer->drawTerrainMeshRanges({0, 0, 0}, staticRanges, nearest_m);
        renderer->endFrame();
        renderer->finish();
        times.push_back(msSince(t0));
      }
      raster.ran = true;
      raster.rasterMs = percentile(times, 50);
      raster.triangles = lastN;
      raster.trianglesPerS = raster.rasterMs > 0 ? static_cast<double>(lastN) / (raster.rasterMs / 1000.0) : 0.0;
      // Frames and the static draw have nearly the same triangle count (consecutive frames).
      raster.ratio = raster.rasterMs > 0 ? percentile(frameMs, 50) / raster.rasterMs : 0.0;
      raster.frameMsP50 = percentile(frameMs, 50);
      raster.updateMsP50 = percentile(updateMs, 50);
      raster.emitMsP50 = percentile(emitMs, 50);
      raster.uploadMsP50 = percentile(uploadMs, 50);
      raster.drawMsP50 = percentile(drawMs, 50);
    }
  }

  if (o.json) {
    // The strings from outside (paths, the GL renderer) are appended, not printed into `b`: a
    // long path cut off at its size left the JSON unterminated.
    std::string j = "{\"suite\":\"terrain\",\"dem\":" + jsonString(demName);
    char b[512];
    std::snprintf(b, sizeof b,
                  ",\"samples\":%llu,\"width\":%d,\"height\":%d,\"spacing_m\":%.3f,"
                  "\"relief_m\":%.1f,\"load_ms\":%.1f,\"dem_mapped\":%s,\"dem_from_cache\":%s,\"dem_cache\":",
                  static_cast<unsigned long long>(samples), dem.width, dem.height, dem.spacing_m,
                  static_cast<double>(dem.hi - dem.lo), loadMs, o.cacheDir.empty() ? "false" : "true",
                  fromCache ? "true" : "false");
    j += b;
    j += jsonString(cacheFile) + ",";
    std::snprintf(b, sizeof b, "\"bounds_ms\":%.1f,\"bounds_bytes\":%zu,", boundsMs, bounds.boundsBytes());
    j += b;
    std::snprintf(b, sizeof b, "\"frames\":%d,\"renderer\":", o.frames);
    j += b;
    j += jsonString(contextName);
    std::snprintf(b, sizeof b, ",\"tolerance_px\":1.0,\"deferred_visits\":%u,\"deferred_budget_ms\":%.3f,\"deferred_lateness\":%.3f,\"methods\":{",
                  o.deferredVisits, o.budget_ms, o.lateness);
    j += b;
    for (size_t i = 0; i < methods.size(); ++i) {
      const MethodResult& m = methods[i];
      j += (i ? ",\"" : "\"") + m.name + "\":{";
      j += "\"update_ms_p50\":" + num(m.updateP50) + ",\"update_ms_p99\":" + num(m.updateP99) +
           ",\"update_cpu_ms_p50\":" + num(m.cpuP50) + ",\"update_cpu_ms_p99\":" + num(m.cpuP99) +
           ",\"startup_update_ms\":" + num(m.startupMs, 2) +
           ",\"teleport_update_ms\":" + num(m.teleport) + ",\"emit_visible_ms_p50\":" + num(m.emitP50) +
           ",\"triangles_p50\":" + std::to_string(m.trianglesP50) + ",\"visible_triangles_p50\":" +
           std::to_string(m.visibleP50) + ",\"max_error_px\":" + num(m.maxErrorPx) +
           ",\"uploads_p50\":" + std::to_string(m.uploadsP50) + ",\"unfinished_frames\":" + std::to_string(m.unfinishedFrames);
      if (m.name == "roam_deferred") {
        j += ",\"visits_p50\":" + num(m.visitsP50, 0) + ",\"pending_p99\":" + num(m.pendingP99, 0) +
             ",\"max_error_px_unfinished\":" + num(m.maxErrorUnfinishedPx);
      }
      if (m.name != "block") {
        j += ",\"bounds_bytes\":" + std::to_string(m.boundsBytes) +
             ",\"pool_bytes\":" + std::to_string(m.poolBytes);
      }
      j += "}";
    }
    j += "},\"methods_skipped\":[";
    for (size_t i = 0; i < skipped.size(); ++i) j += (i ? ",\"" : "\"") + skipped[i] + "\"";
    j += "],\"teleport\":{\"jump_km\":" + num(tp.jump_km, 3) + ",\"merge_ms\":" + num(tp.mergeMs) +
         ",\"enhmerge_ms\":" + num(tp.enhMergeMs) + ",\"merge_ops\":" + std::to_string(tp.mergeOps) +
         ",\"enhmerge_ops\":" + std::to_string(tp.enhMergeOps) + ",\"deferred_visits\":" + std::to_string(o.teleportVisits) +
         ",\"deferred_budget_ms\":" + num(o.teleportBudget_ms, 3) +
         ",\"deferred_first_frame_ms\":" + num(tp.firstFrameMs) + ",\"deferred_frame_ms_max\":" + num(tp.frameMsMax) +
         ",\"deferred_frames_to_visible\":" + std::to_string(tp.framesToVisible) +
         ",\"deferred_visible_ms\":" + num(tp.visibleMs) + ",\"deferred_frames_to_finished\":" +
         std::to_string(tp.framesToFinished) + ",\"deferred_finished_ms\":" + num(tp.finishedMs) +
         ",\"first_frame_speedup_vs_merge\":" + num(tp.firstFrameMs > 0 ? tp.mergeMs / tp.firstFrameMs : 0.0, 2) +
         ",\"visible_speedup_vs_merge\":" + num(tp.visibleMs > 0 ? tp.mergeMs / tp.visibleMs : 0.0, 2) + "}";
    j += ",\"raster\":{\"ran\":" + std::string(raster.ran ? "true" : "false") + ",\"triangles\":" +
         std::to_string(raster.triangles) + ",\"raster_ms\":" + num(raster.rasterMs) + ",\"triangles_per_s\":" +
         num(raster.trianglesPerS, 0) + ",\"frame_ms_p50\":" + num(raster.frameMsP50) + ",\"update_ms_p50\":" +
         num(raster.updateMsP50) + ",\"emit_ms_p50\":" + num(raster.emitMsP50) + ",\"upload_ms_p50\":" +
         num(raster.uploadMsP50) + ",\"draw_ms_p50\":" + num(raster.drawMsP50) +
         ",\"chunk_side\":" + std::to_string(raster.chunkSide) + ",\"chunks\":" + std::to_string(raster.chunks) +
         ",\"mesh_triangles\":" + std::to_string(raster.meshTriangles) + ",\"dirty_slots_p50\":" + num(raster.dirtySlotsP50, 0) +
         ",\"drawn_slots_p50\":" + num(raster.drawnSlotsP50, 0) + ",\"drawn_live_p50\":" + num(raster.drawnLiveP50, 0) +
         ",\"draw_ranges_p50\":" + num(raster.rangesP50, 0) + "},\"frame_vs_raster_ratio\":" +
         num(raster.ratio, 3);
    std::snprintf(b, sizeof b, ",\"block_triangles_at_equal_error\":%llu,\"roam_triangles_at_equal_error\":%llu,"
                  "\"block_build_ms\":%.1f,\"sweep_rendered\":%s,\"sweep\":[",
                  static_cast<unsigned long long>(blockEqual), static_cast<unsigned long long>(roamEqual), blockBuildMs,
                  renderSweep ? "true" : "false");
    j += b;
    for (size_t i = 0; i < sweep.size(); ++i) {
      const SweepRow& s = sweep[i];
      std::snprintf(b, sizeof b, "%s{\"tolerance_px\":%.2f,\"triangles\":%llu,\"update_ms\":%.4f,", i ? "," : "",
                    s.tolerance, static_cast<unsigned long long>(s.triangles), s.updateMs);
      j += b;
      // Not rendered (--no-render, or a DEM too large to render the reference): null, not a
      // perfect-looking 0 RMSE at 0 dB.
      if (renderSweep) {
        std::snprintf(b, sizeof b, "\"render_ms\":%.3f,\"rmse\":%.4f,\"psnr_db\":%.3f}", s.renderMs, s.rmse, s.psnr);
        j += b;
      } else {
        j += "\"render_ms\":null,\"rmse\":null,\"psnr_db\":null}";
      }
    }
    j += "]}";
    std::printf("%s\n", j.c_str());
  } else {
    std::printf("terrain suite: %s (%dx%d samples, %.1f m, %.0f m relief, loaded in %.0f ms%s), %d-frame flight with a teleport\n",
                demName.c_str(), dem.width, dem.height, dem.spacing_m, static_cast<double>(dem.hi - dem.lo), loadMs,
                fromCache ? ", mapped from cache" : "", o.frames);
    std::printf("  %-14s %9s %9s %9s %11s %9s %10s %9s %8s %8s %10s\n", "method", "upd p50", "upd p99", "cpu p99",
                "teleport ms", "emit p50", "tris p50", "visible", "max err", "uploads", "unfinished");
    for (const auto& m : methods)
      std::printf("  %-14s %9.3f %9.3f %9.3f %11.3f %9.3f %10llu %9llu %8.2f %8llu %10d\n", m.name.c_str(), m.updateP50,
                  m.updateP99, m.cpuP99, m.teleport, m.emitP50, static_cast<unsigned long long>(m.trianglesP50),
                  static_cast<unsigned long long>(m.visibleP50), m.maxErrorPx,
                  static_cast<unsigned long long>(m.uploadsP50), m.unfinishedFrames);
    std::printf("  roam_deferred: %s %.2f (visits p50 %.0f), pending p99 %.0f, bounds %.0f ms / %.0f MB, pool %.0f MB reserved\n",
                o.budget_ms > 0 ? "budget ms" : "visits an update", o.budget_ms > 0 ? o.budget_ms : o.deferredVisits, deferred.visitsP50, deferred.pendingP99, boundsMs,
                static_cast<double>(deferred.boundsBytes) / 1e6, static_cast<double>(deferred.poolBytes) / 1e6);
    std::printf("  teleport %.1f km: merges alone %.1f ms, enhMerge %.1f ms; Deferred (%u visits): first frame %.2f ms, "
                "max %.2f ms, visible converged after %d frames (%.1f ms), finished after %d (%.1f ms)\n",
                tp.jump_km, tp.mergeMs, tp.enhMergeMs, o.teleportVisits, tp.firstFrameMs, tp.frameMsMax,
                tp.framesToVisible, tp.visibleMs, tp.framesToFinished, tp.finishedMs);
    if (raster.ran)
      std::printf("  frame vs raster: frame p50 %.2f ms (update %.2f, emit %.2f, upload %.2f, draw %.2f) for %llu "
                  "triangles; static draw %.2f ms (%.1f M triangles/s): ratio %.2f\n"
                  "    chunks of %d samples (%zu), mesh %zu triangles in the buffer; a frame writes %.0f slots, draws %.0f "
                  "slots (%.0f live) in %.0f ranges\n",
                  raster.frameMsP50, raster.updateMsP50, raster.emitMsP50, raster.uploadMsP50, raster.drawMsP50,
                  static_cast<unsigned long long>(raster.triangles), raster.rasterMs, raster.trianglesPerS / 1e6, raster.ratio,
                  raster.chunkSide, raster.chunks, raster.meshTriangles, raster.dirtySlotsP50, raster.drawnSlotsP50,
                  raster.drawnLiveP50, raster.rangesP50);
    std::printf("  at 1 px: block LOD %llu triangles, ROAM %llu (%.2fx); block LOD tables built in %.0f ms\n",
                static_cast<unsigned long long>(blockEqual), static_cast<unsigned long long>(roamEqual),
                blockEqual ? static_cast<double>(roamEqual) / static_cast<double>(blockEqual) : 0.0, blockBuildMs);
    std::printf("  sweep (ROAM enhMerge): tol px, triangles, update ms, render ms, rmse, psnr dB\n");
    for (const auto& s : sweep)
      std::printf("    %5.2f %9llu %9.3f %9.2f %8.3f %7.2f\n", s.tolerance, static_cast<unsigned long long>(s.triangles),
                  s.updateMs, s.renderMs, s.rmse, s.psnr);
  }
  return 0;
}

}  // namespace ig
