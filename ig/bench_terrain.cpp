#include "ig/bench_terrain.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#include "ig/stats.h"
#include "io/dem.h"
#include "lod/block_lod.h"
#include "lod/heightfield.h"
#include "lod/roam.h"
#include "render/context.h"
#include "render/image.h"
#include "render/renderer.h"

namespace ig {
namespace {

using BenchClock = std::chrono::steady_clock;
double msSince(BenchClock::time_point t0) { return std::chrono::duration<double, std::milli>(BenchClock::now() - t0).count(); }

struct PathFrame {
  lod::Camera camera;
  bool teleport = false;
};

// Flies north-north-east 120 m above the DEM's highest point, turns hard (90 deg/s) in the
// middle third, teleports to the north-east corner at 2/3 and flies on.
std::vector<PathFrame> flightPath(const io::Dem& dem, double spacing_m, int frames, double aspect) {
  std::vector<PathFrame> path;
  float top = dem.heights_m[0];
  for (float h : dem.heights_m) top = std::max(top, h);
  const double extentX = (dem.width - 1) * spacing_m, extentY = (dem.height - 1) * spacing_m;
  glm::dvec3 eye{0.55 * extentX, 0.3 * extentY, static_cast<double>(top) + 120.0};
  double heading = 20.0;
  constexpr double kDt = 1.0 / 60.0, kSpeed = 250.0;
  for (int i = 0; i < frames; ++i) {
    PathFrame f;
    if (i == 2 * frames / 3) {
      eye = {0.9 * extentX, 0.85 * extentY, eye.z};
      heading = 200.0;
      f.teleport = true;
    } else if (i > frames / 3 && i < 2 * frames / 3) {
      heading += 90.0 * kDt;
    }
    const double h = heading * 3.14159265358979323846 / 180.0;
    eye += glm::dvec3(std::sin(h), std::cos(h), 0.0) * (kSpeed * kDt);
    f.camera.eye_m = eye;
    f.camera.heading_deg = heading;
    f.camera.pitch_deg = -8.0;
    f.camera.fovY_deg = 45.0;
    f.camera.aspect = aspect;
    f.camera.near_m = 0.5;
    f.camera.far_m = 100000.0;
    path.push_back(f);
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
uint64_t changedTriangles(std::vector<uint64_t>& prev, std::vector<uint64_t>& cur) {
  std::sort(cur.begin(), cur.end());
  uint64_t added = 0;
  size_t i = 0, j = 0;
  while (j < cur.size()) {
    if (i < prev.size() && prev[i] < cur[j]) ++i;
    else if (i < prev.size() && prev[i] == cur[j]) ++i, ++j;
    else ++added, ++j;
  }
  prev.swap(cur);
  return added;
}

struct MethodResult {
  std::string name;
  double updateP50 = 0, updateP99 = 0, teleport = 0, maxErrorPx = 0;
  uint64_t trianglesP50 = 0, uploadsP50 = 0;
  uint64_t visibleP50 = 0;  // triangles in the view frustum (what is drawn)
};

lod::RoamView viewFor(const lod::Camera& cam, int height_px, double tolerance_px) {
  lod::RoamView v;
  v.camera = cam;
  v.viewportHeight_px = height_px;
  v.tolerance_px = tolerance_px;
  return v;
}

// Flies the path with one method. `update(view)` runs the method's LOD step (timed) and
// returns {triangles, maxErrorPx}; `emit(out)` writes its mesh for the upload count.
template <class Update, class Emit, class Visible>
MethodResult fly(const char* name, const std::vector<PathFrame>& path, int height_px, double tolerance_px,
                 Update update, Emit emit, Visible visible) {
  std::vector<double> ms, tris, uploads, visibleTris;
  std::vector<lod::RoamTriangle> out;
  std::vector<uint64_t> prev, cur;
  MethodResult r;
  r.name = name;
  for (const PathFrame& f : path) {
    const auto t0 = BenchClock::now();
    const auto [triangles, maxErrorPx] = update(viewFor(f.camera, height_px, tolerance_px));
    const double t = msSince(t0);
    ms.push_back(t);
    if (f.teleport) r.teleport = t;
    tris.push_back(static_cast<double>(triangles));
    r.maxErrorPx = std::max(r.maxErrorPx, maxErrorPx);
    emit(out);
    visibleTris.push_back(static_cast<double>(visible(f.camera, out)));
    cur.clear();
    for (const auto& tri : out) cur.push_back(triangleKey(tri));
    uploads.push_back(static_cast<double>(changedTriangles(prev, cur)));
  }
  r.updateP50 = percentile(ms, 50);
  r.updateP99 = percentile(ms, 99);
  r.trianglesP50 = static_cast<uint64_t>(percentile(tris, 50));
  r.uploadsP50 = static_cast<uint64_t>(percentile(uploads, 50));
  r.visibleP50 = static_cast<uint64_t>(percentile(visibleTris, 50));
  return r;
}

struct UpdateResult {
  uint64_t triangles;
  double maxErrorPx;
};

MethodResult flyRoam(const io::Dem& dem, double spacing_m, const std::vector<PathFrame>& path, lod::RoamMode mode,
                     const char* name, int height_px, double tolerance_px) {
  // Deferred refines the whole surroundings (4-7x the triangles of the view-culled mesh),
  // so it gets room for 8 M; the view-culled modes stay well under the default 1 M.
  lod::RoamConfig config;
  if (mode == lod::RoamMode::Deferred) config.maxTriangles = 8u << 20;
  lod::Roam roam(dem.heights_m, dem.width, dem.height, spacing_m, {0, 0, 0}, config);
  return fly(
      name, path, height_px, tolerance_px,
      [&](const lod::RoamView& v) {
        const lod::RoamStats st = roam.update(v, mode);
        return UpdateResult{st.triangles, st.maxErrorPx};
      },
      [&](std::vector<lod::RoamTriangle>& out) {
        out.resize(roam.triangleCount());
        out.resize(roam.emitTriangles(out));
      },
      [&](const lod::Camera& cam, std::vector<lod::RoamTriangle>& scratch) {
        scratch.resize(roam.triangleCount());
        return roam.emitVisible(cam, scratch);
      });
}

MethodResult flyBlock(const io::Dem& dem, double spacing_m, const std::vector<PathFrame>& path, int height_px,
                      double tolerance_px) {
  lod::BlockLod block(dem.heights_m, dem.width, dem.height, spacing_m, {0, 0, 0});
  return fly(
      "block", path, height_px, tolerance_px,
      [&](const lod::RoamView& v) {
        const lod::BlockLodStats st = block.update(v);
        return UpdateResult{st.triangles, st.maxErrorPx};
      },
      [&](std::vector<lod::RoamTriangle>& out) {
        out.resize(block.triangleBound());
        out.resize(block.emitTriangles(out));
      },
      [&](const lod::Camera&, std::vector<lod::RoamTriangle>& out) { return out.size(); });
}

struct SweepRow {
  double tolerance = 0, updateMs = 0, renderMs = 0, rmse = 0, psnr = 0;
  uint64_t triangles = 0;
};

std::string jsonEscape(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (c == '"' || c == '\\') o += '\\';
    o += c;
  }
  return o;
}

}  // namespace

int runTerrainBench(const TerrainBenchOptions& o) {
  io::Dem dem;
  std::string error;
  const auto tLoad = BenchClock::now();
  std::string demName = o.demFile;
  if (o.syntheticSamples > 0) {
    // Stress case: a mountainous procedural field of the size asked for (the real SRTM tile
    // is 1201 wide and mostly flat coast).
    lod::HeightfieldDesc d;
    d.seed = 20261123;
    d.postsX = d.postsY = o.syntheticSamples;
    d.postSpacing_m = 30.0;
    d.heightScale_m = 2500.0;
    dem.width = dem.height = o.syntheticSamples;
    dem.spacing_m = 30.0;
    dem.heights_m.resize(static_cast<size_t>(dem.width) * static_cast<size_t>(dem.height));
    lod::generateHeightfield(d, dem.heights_m);
    demName = "procedural:" + std::to_string(o.syntheticSamples);
  } else {
    if (!io::loadDem(o.demFile, {}, dem, error)) {
      std::fprintf(stderr, "igbench terrain: %s (scripts/fetch-data fetches the default DEM)\n", error.c_str());
      return 2;
    }
    io::flipRows(dem);  // files store north first; the LOD grids want y northwards
  }
  const double loadMs = msSince(tLoad);
  const double spacing = dem.spacing_m > 0 ? dem.spacing_m : 30.0;
  const double aspect = static_cast<double>(o.width_px) / o.height_px;
  const auto path = flightPath(dem, spacing, o.frames, aspect);

  std::vector<MethodResult> methods;
  methods.push_back(flyRoam(dem, spacing, path, lod::RoamMode::EnhMerge, "roam_enhmerge", o.height_px, 1.0));
  methods.push_back(flyRoam(dem, spacing, path, lod::RoamMode::MergeQueue, "roam_merge", o.height_px, 1.0));
  methods.push_back(flyRoam(dem, spacing, path, lod::RoamMode::Rebuild, "roam_rebuild", o.height_px, 1.0));
  methods.push_back(flyBlock(dem, spacing, path, o.height_px, 1.0));
  methods.push_back(flyRoam(dem, spacing, path, lod::RoamMode::Deferred, "roam_deferred", o.height_px, 1.0));

  // Equal error (1 px) at the reference view: triangles each method needs.
  const lod::Camera refCam = path[static_cast<size_t>(o.frames / 4)].camera;
  lod::Roam refRoam(dem.heights_m, dem.width, dem.height, spacing, {0, 0, 0});
  refRoam.update(viewFor(refCam, o.height_px, 1.0), lod::RoamMode::Rebuild);
  lod::BlockLod refBlock(dem.heights_m, dem.width, dem.height, spacing, {0, 0, 0});
  const lod::BlockLodStats blockStats = refBlock.update(viewFor(refCam, o.height_px, 1.0));
  std::vector<lod::RoamTriangle> tris(refRoam.triangleCount());
  const uint64_t roamEqual = refRoam.emitTriangles(tris);
  const uint64_t blockEqual = blockStats.triangles;

  // Sweep: what accuracy costs in time.
  const double tolerances[] = {0.5, 1.0, 2.0, 4.0, 8.0};
  std::vector<SweepRow> sweep;
  std::unique_ptr<render::GlContext> context;
  std::unique_ptr<render::Renderer> renderer;
  render::Image reference, image;
  render::Lighting light;
  light.sunDirection = glm::normalize(glm::dvec3(-0.5, 0.6, 0.6));
  light.fogVisibility_m = 60000.0;
  std::vector<lod::TerrainVertex> vertices;
  std::string contextName = "none";
  auto renderMesh = [&](std::span<const lod::RoamTriangle> list, render::Image& out) {
    vertices.clear();
    for (const auto& t : list)
      for (const auto& v : t.v) vertices.push_back(lod::heightFieldVertex(dem.heights_m, dem.width, dem.height, spacing, v.x, v.y));
    // Median of 5 draws (upload + draw + glFinish): one frame alone is too noisy here.
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
    const size_t full = 2ull * (dem.width - 1) * (dem.height - 1);
    float lo = dem.heights_m[0], hi = lo;
    for (float h : dem.heights_m) lo = std::min(lo, h), hi = std::max(hi, h);
    if (!context || !renderer->init(o.width_px, o.height_px, error) ||
        !renderer->addTerrainMesh(full * 3, static_cast<double>(hi - lo), error)) {
      std::fprintf(stderr, "igbench terrain: %s\n", error.c_str());
      return 3;
    }
    contextName = context->description();
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
  for (double tol : tolerances) {
    SweepRow row;
    row.tolerance = tol;
    lod::Roam roam(dem.heights_m, dem.width, dem.height, spacing, {0, 0, 0});
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
    if (o.render) {
      row.renderMs = renderMesh(list, image);
      row.rmse = render::rmse(image, reference);
      row.psnr = row.rmse > 0 ? 20.0 * std::log10(255.0 / row.rmse) : 99.0;
    }
    sweep.push_back(row);
  }

  if (o.json) {
    std::printf("{\"suite\":\"terrain\",\"dem\":\"%s\",\"samples\":%lld,\"width\":%d,\"height\":%d,\"spacing_m\":%.3f,"
                "\"load_ms\":%.1f,\"frames\":%d,\"renderer\":\"%s\",\"tolerance_px\":1.0,\"methods\":{",
                jsonEscape(demName).c_str(), static_cast<long long>(dem.width) * dem.height, dem.width, dem.height,
                spacing, loadMs, o.frames, jsonEscape(contextName).c_str());
    for (size_t i = 0; i < methods.size(); ++i) {
      const MethodResult& m = methods[i];
      std::printf("%s\"%s\":{\"update_ms_p50\":%.4f,\"update_ms_p99\":%.4f,\"teleport_update_ms\":%.4f,"
                  "\"triangles_p50\":%llu,\"visible_triangles_p50\":%llu,\"max_error_px\":%.4f,\"uploads_p50\":%llu}",
                  i ? "," : "", m.name.c_str(), m.updateP50, m.updateP99, m.teleport,
                  static_cast<unsigned long long>(m.trianglesP50), static_cast<unsigned long long>(m.visibleP50),
                  m.maxErrorPx, static_cast<unsigned long long>(m.uploadsP50));
    }
    std::printf("},\"block_triangles_at_equal_error\":%llu,\"roam_triangles_at_equal_error\":%llu,\"sweep\":[",
                static_cast<unsigned long long>(blockEqual), static_cast<unsigned long long>(roamEqual));
    for (size_t i = 0; i < sweep.size(); ++i) {
      const SweepRow& s = sweep[i];
      std::printf("%s{\"tolerance_px\":%.2f,\"triangles\":%llu,\"update_ms\":%.4f,\"render_ms\":%.3f,\"rmse\":%.4f,"
                  "\"psnr_db\":%.3f}",
                  i ? "," : "", s.tolerance, static_cast<unsigned long long>(s.triangles), s.updateMs, s.renderMs,
                  s.rmse, s.psnr);
    }
    std::printf("]}\n");
  } else {
    std::printf("terrain suite: %s (%dx%d samples, %.1f m, loaded in %.0f ms), %d-frame flight with a teleport\n",
                demName.c_str(), dem.width, dem.height, spacing, loadMs, o.frames);
    std::printf("  %-14s %10s %10s %12s %10s %10s %9s %10s\n", "method", "upd p50", "upd p99", "teleport ms",
                "tris p50", "visible", "max err", "uploads");
    for (const auto& m : methods)
      std::printf("  %-14s %10.3f %10.3f %12.3f %10llu %10llu %9.2f %10llu\n", m.name.c_str(), m.updateP50,
                  m.updateP99, m.teleport, static_cast<unsigned long long>(m.trianglesP50),
                  static_cast<unsigned long long>(m.visibleP50), m.maxErrorPx,
                  static_cast<unsigned long long>(m.uploadsP50));
    std::printf("  at 1 px: block LOD %llu triangles, ROAM %llu (%.2fx)\n", static_cast<unsigned long long>(blockEqual),
                static_cast<unsigned long long>(roamEqual),
                blockEqual ? static_cast<double>(roamEqual) / static_cast<double>(blockEqual) : 0.0);
    std::printf("  sweep (ROAM enhMerge): tol px, triangles, update ms, render ms, rmse, psnr dB\n");
    for (const auto& s : sweep)
      std::printf("    %5.2f %9llu %9.3f %9.2f %8.3f %7.2f\n", s.tolerance, static_cast<unsigned long long>(s.triangles),
                  s.updateMs, s.renderMs, s.rmse, s.psnr);
  }
  return 0;
}

}  // namespace ig
