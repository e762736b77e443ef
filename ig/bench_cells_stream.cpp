#include "ig/bench_cells_stream.h"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <thread>

#include <glm/geometric.hpp>

#include "ig/cells_stream.h"
#include "ig/cells_tool.h"
#include "ig/stats.h"
#include "lod/cells_db.h"
#include "lod/cells_select.h"
#include "render/cells_pass.h"
#include "render/context.h"
#include "render/image.h"
#include "render/renderer.h"

namespace ig {
namespace {

using BenchClock = std::chrono::steady_clock;
double msSince(BenchClock::time_point t0) { return std::chrono::duration<double, std::milli>(BenchClock::now() - t0).count(); }
double sSince(BenchClock::time_point t0) { return std::chrono::duration<double>(BenchClock::now() - t0).count(); }

constexpr double kPi = 3.14159265358979323846;

lod::Camera lookAt(const glm::dvec3& eye, const glm::dvec3& target, int w, int h, double far_m) {
  lod::Camera c;
  c.eye_m = eye;
  const glm::dvec3 d = target - eye;
  c.heading_deg = std::atan2(d.x, d.y) * 180.0 / kPi;
  c.pitch_deg = std::atan2(d.z, std::hypot(d.x, d.y)) * 180.0 / kPi;
  c.fovY_deg = 50.0;
  c.aspect = static_cast<double>(w) / h;
  c.near_m = 0.1;
  c.far_m = far_m;
  return c;
}

// scripts/cells-server around one rate.
class Server {
 public:
  ~Server() { stop(); }
  bool start(const std::string& script, const std::string& root, const std::string& runDir, uint64_t rate,
             std::string& url, std::string& error) {
    script_ = script;
    runDir_ = runDir;
    const std::string cmd = script + " start --root '" + root + "' --port 0 --rate " + std::to_string(rate) +
                            " --dir '" + runDir + "' --owner " + std::to_string(::getpid()) + " 2>&1";
    FILE* p = popen(cmd.c_str(), "r");
    if (!p) {
      error = "cannot run " + script;
      return false;
    }
    std::string text;
    char buf[512];
    while (std::fgets(buf, sizeof buf, p)) text += buf;
    const int rc = pclose(p);
    started_ = true;
    const size_t at = text.find("http://");
    if (rc != 0 || at == std::string::npos) {
      error = script + " start failed (exit " + std::to_string(rc) + "): " + text;
      return false;
    }
    url = text.substr(at, text.find_first_of(" \n", at) - at);
    if (url.empty() || url.back() != '/') url += '/';
    return true;
  }
  void stop() {
    if (!started_) return;
    started_ = false;
    const std::string cmd = script_ + " stop --dir '" + runDir_ + "' >/dev/null 2>&1";
    if (std::system(cmd.c_str()) != 0) std::fprintf(stderr, "igbench cells: %s failed\n", cmd.c_str());
  }

 private:
  std::string script_, runDir_;
  bool started_ = false;
};

struct Gl {
  std::unique_ptr<render::GlContext> context;
  render::Renderer renderer;
  render::CellsPass pass;
  render::Lighting light;
  render::Image image;

  double frame(const lod::Camera& cam, std::span<const lod::CellDraw> draw, bool read) {
    const auto t0 = BenchClock::now();
    renderer.beginFrame(cam, light);
    pass.draw(renderer, draw);
    renderer.endFrame();
    renderer.finish();
    const double ms = msSince(t0);
    if (read) renderer.readPixels(image);
    return ms;
  }
};

}  // namespace

bool runCellsStreamBench(const CellsStreamBenchOptions& o, CellsStreamBenchResult& out, std::string& error) {
  if (o.width_px < 16 || o.height_px < 16 || !(o.fps > 0.0) || !(o.timeout_s > 0.0) || o.rates_mbit.empty()) {
    error = "igbench cells: bad streaming options (size " + std::to_string(o.width_px) + "x" +
            std::to_string(o.height_px) + ", fps " + std::to_string(o.fps) + ", timeout " + std::to_string(o.timeout_s) +
            " s)";
    return false;
  }
  struct stat st {};
  if (::stat(o.mesh.c_str(), &st) != 0) {
    error = o.mesh + ": missing (run scripts/fetch-cells to fetch the Stanford bunny)";
    return false;
  }
  std::string work = o.workDir;
  if (work.empty()) {
    char tmpl[] = "/tmp/igbench-cells-XXXXXX";
    if (!::mkdtemp(tmpl)) {
      error = "cannot create a folder under /tmp";
      return false;
    }
    work = tmpl;
  }
  ::chmod(work.c_str(), 0755);  // nginx's workers read it

  // 1. The database.
  CellsBuildOptions b;
  b.input = o.mesh;
  b.size_m = o.size_m;
  b.yUp = true;
  b.cellLevels = o.cellLevels;
  b.voxelDepth = o.voxelDepth;
  b.out = work + "/bunny.ighc";
  {
    lod::VoxelMesh mesh;
    std::string source;
    if (!cellsBuildMesh(b, mesh, source, error)) return false;
    lod::VoxelizeConfig vc;
    vc.levels = o.cellLevels - 1 + o.voxelDepth;
    lod::VoxelPyramid pyramid;
    if (!lod::voxelize(mesh, vc, pyramid, error)) {
      error = source + ": " + error;
      return false;
    }
    for (int l = 0; l < pyramid.levels(); ++l) out.dimension.push_back(pyramid.dimension(l));
    for (int l = 1; l <= pyramid.levels(); ++l) out.boxCounting.push_back(pyramid.boxCountingDimension(l));
    lod::CellBuildConfig bc;
    bc.cellLevels = o.cellLevels;
    bc.cellVoxelDepth = o.voxelDepth;
    if (!lod::writeCellDb(b.out, pyramid, bc, nullptr, error)) return false;
  }
  ::chmod(b.out.c_str(), 0644);
  lod::CellDbFile db;
  if (!db.open(b.out, error)) return false;
  const lod::CellTree& tree = db.tree();
  out.cells = tree.size();
  out.levels = tree.levels();
  out.fileBytes = db.header().fileBytes;

  // 2. GL, every cell resident for the references and the sweep.
  Gl gl;
  gl.light.fog = false;
  gl.context = render::createContext(render::ContextKind::Headless, o.width_px, o.height_px, error);
  if (!gl.context || !gl.renderer.init(o.width_px, o.height_px, error)) return false;
  out.context = gl.context->description();
  uint64_t allPoints = 0;
  for (uint32_t c = 0; c < tree.size(); ++c) allPoints += tree.voxels(c);
  render::CellsPassConfig pc;
  pc.arenaBytes = std::max<uint64_t>(uint64_t{4} << 20, allPoints * render::CellsPass::kPointBytes * 2 + (1 << 20));
  if (!gl.pass.init(tree, pc, error)) return false;
  std::vector<lod::CellPoint> points;
  auto uploadAll = [&]() -> bool {
    for (uint32_t c = 0; c < tree.size(); ++c) {
      if (tree.voxels(c) == 0) continue;
      points.clear();
      const std::span<const uint8_t> payload = db.payload(c);
      if (lod::cellDbCrc32(payload) != db.entries()[c].crc32 || !lod::decodeCell(tree, c, payload, points, error) ||
          !gl.pass.upload(c, points)) {
        if (error.empty()) error = b.out + ": cell " + std::to_string(c) + " does not fit the arena";
        return false;
      }
    }
    return true;
  };
  if (!uploadAll()) return false;

  const lod::CellTreeInfo& info = tree.info();
  const glm::dvec3 centre = info.rootMin_m + glm::dvec3(0.5 * info.rootEdge_m);
  const double size = o.size_m;
  const lod::Camera nearCam =
      lookAt(centre + glm::dvec3(0.35 * size, -0.9 * size, 0.25 * size), centre, o.width_px, o.height_px, 100.0 * size);
  const lod::Camera farCam =
      lookAt(centre + glm::dvec3(-2.0 * size, 5.0 * size, 1.5 * size), centre, o.width_px, o.height_px, 100.0 * size);

  lod::CellView view;
  view.viewportHeight_px = o.height_px;
  view.minVoxel_px = 1.0;
  view.byteBudget = ~uint64_t{0};
  std::vector<lod::CellDraw> draw(tree.size());
  std::vector<uint32_t> requests(tree.size());
  lod::CellSelector selector(tree);
  auto selectAll = [&](const lod::Camera& cam, uint64_t budget, double alpha) {
    selector.reset();
    view.camera = cam;
    view.voxelBudget = budget;
    view.minVoxel_px = alpha;
    return selector.select(view, {}, draw, requests);
  };

  // Full detail: every visible cell down to the finest level.
  lod::CellSelectStats s = selectAll(nearCam, ~uint64_t{0}, 0.0);
  out.fullVoxels = s.drawnVoxels;
  std::vector<double> ms;
  for (int k = 0; k < 3; ++k) ms.push_back(gl.frame(nearCam, {draw.data(), s.drawnCells}, k == 2));
  out.fullRenderMs = percentile(ms, 50);
  const render::Image fullImage = gl.image;

  // 3. The sweep.
  std::vector<uint64_t> budgets = o.sweepBudgets;
  if (o.quick && budgets.size() > 3) budgets = {budgets.front(), budgets[budgets.size() / 2], budgets.back()};
  for (uint64_t budget : budgets) {
    CellsSweepRow row;
    row.budget = budget;
    std::vector<double> sel;
    for (int k = 0; k < 5; ++k) {
      const auto t0 = BenchClock::now();
      s = selectAll(nearCam, budget, 1.0);
      sel.push_back(msSince(t0));
    }
    row.selectMs = percentile(sel, 50);
    row.voxels = s.drawnVoxels;
    row.maxVoxel_px = static_cast<double>(s.maxVoxel_px);
    ms.clear();
    for (int k = 0; k < 3; ++k) ms.push_back(gl.frame(nearCam, {draw.data(), s.drawnCells}, k == 2));
    row.renderMs = percentile(ms, 50);
    row.psnr_db = render::psnrDb(gl.image, fullImage);
    out.sweep.push_back(row);
  }
  if (!o.stream) return true;

  // 4. Streaming through nginx. The targets: the all-resident optimum at each view.
  s = selectAll(farCam, o.voxelBudget, 1.0);
  const double targetFar = static_cast<double>(s.maxVoxel_px);
  s = selectAll(nearCam, o.voxelBudget, 1.0);
  const double targetNear = static_cast<double>(s.maxVoxel_px);
  gl.frame(nearCam, {draw.data(), s.drawnCells}, true);
  const render::Image finalImage = gl.image;

  std::vector<double> rates = o.rates_mbit;
  if (o.quick) rates.erase(std::remove_if(rates.begin(), rates.end(), [](double r) { return r < 10.0; }), rates.end());
  for (double mbit : rates) {
    CellsStreamRun run;
    run.rate_mbit = mbit;
    run.targetVoxel_px = targetNear;
    const uint64_t rate = static_cast<uint64_t>(mbit * 1e6 / 8.0);
    run.wBytes = static_cast<uint64_t>(static_cast<double>(rate) / o.fps);
    Server server;
    std::string base;
    if (!server.start(o.serverScript, work, work + "/nginx-" + std::to_string(rate), rate, base, error)) return false;
    CellStream stream;
    CellStreamOptions so;
    so.source = base + "bunny.ighc";
    so.memoryBudget_bytes = pc.arenaBytes / 2;
    if (!stream.open(so, error)) return false;
    gl.pass.evictAll();
    CellsPassSink sink(gl.pass);
    lod::CellSelector sel(stream.tree());
    lod::CellView v = view;
    v.minVoxel_px = 1.0;
    v.voxelBudget = o.voxelBudget;
    v.byteBudget = run.wBytes;
    const double period_s = 1.0 / o.fps;
    const int psnrEvery = std::max(1, static_cast<int>(o.fps / 4.0));
    auto phase = [&](const lod::Camera& cam, double target, bool record) -> double {
      v.camera = cam;
      const auto t0 = BenchClock::now();
      auto next = t0;
      double prev = 1e30;
      const uint64_t bytes0 = stream.stats().arrivedBytes;
      for (int i = 0;; ++i) {
        stream.receive(sink);
        const lod::CellSelectStats r = sel.select(v, stream.residency(), draw, requests);
        stream.request({requests.data(), r.requestedCells});
        run.bytesPerFrameMax = std::max(run.bytesPerFrameMax, r.requestedBytes);
        if (r.drawnVoxels > v.voxelBudget || r.requestedBytes > v.byteBudget) ++run.budgetExceededFrames;
        const bool read = record && i % psnrEvery == 0;
        gl.frame(cam, {draw.data(), r.drawnCells}, read);
        stream.drawn({draw.data(), r.drawnCells}, static_cast<uint64_t>(i) + (record ? 1000000u : 0u), sink);
        const double t = sSince(t0);
        const bool done = r.feasible && r.drawnCells > 0 && static_cast<double>(r.maxVoxel_px) <= target * (1.0 + 1e-6);
        if (record) {
          if (r.drawnCells > 0 && static_cast<double>(r.maxVoxel_px) > prev * (1.0 + 1e-6)) run.qualityMonotonic = false;
          if (r.drawnCells > 0) prev = static_cast<double>(r.maxVoxel_px);
          CellsQualitySample q;
          q.t_s = t;
          q.maxVoxel_px = static_cast<double>(r.maxVoxel_px);
          q.voxels = r.drawnVoxels;
          q.residentBytes = stream.stats().residentBytes;
          if (read || done) {
            if (!read) gl.renderer.readPixels(gl.image);
            q.psnr_db = render::psnrDb(gl.image, finalImage);
          }
          run.curve.push_back(q);
          if (done) {
            const double bits = 8.0 * static_cast<double>(stream.stats().arrivedBytes - bytes0);
            run.effectiveMbit = t > 0.0 ? bits / t / 1e6 : 0.0;
          }
        }
        if (done) return t;
        if (t > o.timeout_s) return -1.0;
        next += std::chrono::duration_cast<BenchClock::duration>(std::chrono::duration<double>(period_s));
        const auto now = BenchClock::now();
        if (next > now) std::this_thread::sleep_until(next);
        else next = now;
      }
    };
    run.warmupSeconds = phase(farCam, targetFar, false);
    run.secondsToFullQuality = phase(nearCam, targetNear, true);
    const CellStreamStats ss = stream.stats();
    const io::RangeFetcherStats fs = stream.fetchStats();
    run.arrivedBytes = ss.arrivedBytes;
    run.broken = ss.broken;
    run.wireBytes = fs.wireBytes;
    run.retries = fs.retries;
    run.corrupt = fs.corrupt;
    out.runs.push_back(std::move(run));
    server.stop();
  }
  // Leave the arena as the sweep had it (callers may render more).
  gl.pass.evictAll();
  return uploadAll();
}

std::string cellsStreamJson(const CellsStreamBenchResult& r) {
  std::string j;
  char buf[512];
  std::snprintf(buf, sizeof buf, "\"mesh\":{\"cells\":%u,\"levels\":%d,\"file_bytes\":%" PRIu64 ",\"dimension\":[",
                r.cells, r.levels, r.fileBytes);
  j += buf;
  for (size_t i = 0; i < r.dimension.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%s%.4f", i ? "," : "", r.dimension[i]);
    j += buf;
  }
  j += "],\"box_counting_dimension\":[";
  for (size_t i = 0; i < r.boxCounting.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%s%.4f", i ? "," : "", r.boxCounting[i]);
    j += buf;
  }
  std::snprintf(buf, sizeof buf, "],\"full_voxels\":%" PRIu64 ",\"full_render_ms\":%.3f},\"sweep\":[", r.fullVoxels,
                r.fullRenderMs);
  j += buf;
  for (size_t i = 0; i < r.sweep.size(); ++i) {
    const CellsSweepRow& s = r.sweep[i];
    std::snprintf(buf, sizeof buf,
                  "%s{\"voxel_budget\":%" PRIu64 ",\"voxels_drawn\":%" PRIu64
                  ",\"max_voxel_px\":%.4f,\"select_ms\":%.4f,\"render_ms\":%.3f,\"psnr_db\":%.3f}",
                  i ? "," : "", s.budget, s.voxels, s.maxVoxel_px, s.selectMs, s.renderMs, s.psnr_db);
    j += buf;
  }
  j += "],\"streaming\":[";
  for (size_t i = 0; i < r.runs.size(); ++i) {
    const CellsStreamRun& s = r.runs[i];
    std::snprintf(buf, sizeof buf,
                  "%s{\"rate_mbit\":%.3f,\"w_bytes\":%" PRIu64 ",\"seconds_to_full_quality\":%.3f,\"warmup_s\":%.3f,"
                  "\"target_voxel_px\":%.4f,\"quality_monotonic\":%s,\"bytes_per_frame_max\":%" PRIu64
                  ",\"budget_exceeded_frames\":%d,\"arrived_bytes\":%" PRIu64 ",\"wire_bytes\":%" PRIu64
                  ",\"retries\":%" PRIu64 ",\"corrupt\":%" PRIu64 ",\"broken\":%" PRIu64 ",\"effective_mbit\":%.3f,"
                  "\"curve\":[",
                  i ? "," : "", s.rate_mbit, s.wBytes, s.secondsToFullQuality, s.warmupSeconds, s.targetVoxel_px,
                  s.qualityMonotonic ? "true" : "false", s.bytesPerFrameMax, s.budgetExceededFrames, s.arrivedBytes,
                  s.wireBytes, s.retries, s.corrupt, s.broken, s.effectiveMbit);
    j += buf;
    for (size_t k = 0; k < s.curve.size(); ++k) {
      const CellsQualitySample& q = s.curve[k];
      std::snprintf(buf, sizeof buf, "%s[%.4f,%.4f,%.3f,%" PRIu64 "]", k ? "," : "", q.t_s, q.maxVoxel_px, q.psnr_db,
                    q.voxels);
      j += buf;
    }
    j += "]}";
  }
  j += "]";
  return j;
}

}  // namespace ig
