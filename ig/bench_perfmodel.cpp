#include "ig/bench_perfmodel.h"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "ig/clock.h"
#include "ig/json.h"
#include "ig/stats.h"
#include "lod/perfmodel.h"
#include "render/context.h"
#include "render/dynamic_pass.h"
#include "render/perf_calibration.h"
#include "render/renderer.h"

namespace ig {
namespace {

using BenchClock = std::chrono::steady_clock;

struct Point {
  uint32_t objects = 0;
  const char* strategy = "";
  double measured_ms = 0, predicted_ms = 0, error_pct = 0;
  double measuredQ1_ms = 0, errorQ1_pct = 0;  // lower quartile of the repeats (least disturbed)
  std::vector<double> sweep_ms;               // each sweep's median, in order (measured_ms: the fastest)
  double fragments = 0;
  double area_px = 0, sqrtArea_px = 0;  // sums over the boxes drawn: projected area, its square root
  double rasterShare = 1;               // the share of the boxes that reach the rasterizer (lod::PassLoad)
  double submit_ms = 0;  // median time until the GL calls returned (the rest is glFinish)
  double appCpu_ms = 0;  // median CPU time of this thread until the GL calls returned
  uint64_t samples = 0;  // samples that passed the depth test (GL_SAMPLES_PASSED, first warm-up frame)
  uint64_t triangles = 0;
  double vertex_ms = 0, fragment_ms = 0, commands_ms = 0;  // terms of (2): T_vert, T_frag, T_buf + T_fc
  const char* bound = "";
  lod::PassLoad load;  // the frame's statistics (the same every sweep), predicted once the constants are known
};

std::array<glm::dvec3, 8> eyeCorners(const render::DynamicObject& o, const glm::dvec3& eye) {
  const double a = o.yaw_deg * 0.017453292519943295;
  const glm::dvec3 ax(std::cos(a), std::sin(a), 0.0), ay(-std::sin(a), std::cos(a), 0.0);
  std::array<glm::dvec3, 8> c;
  for (int i = 0; i < 8; ++i) {
    const double sx = (i & 1) ? 1.0 : -1.0, sy = (i & 2) ? 1.0 : -1.0, sz = (i & 4) ? 1.0 : -1.0;
    c[static_cast<size_t>(i)] = o.center_m - eye + sx * o.halfSize_m.x * ax + sy * o.halfSize_m.y * ay +
                                glm::dvec3(0.0, 0.0, sz * o.halfSize_m.z);
  }
  return c;
}

const char* boundName(int b) {
  static const char* names[] = {"state", "vertex", "fragment", "zbuffer"};
  return names[std::clamp(b, 0, 3)];
}

}  // namespace

int runPerfModelBench(const PerfModelBenchOptions& o) {
  std::vector<uint32_t> sizes = o.sizes;
  if (sizes.empty()) {
    sizes = o.quick ? std::vector<uint32_t>{10, 100, 1000, 4000}
                    : std::vector<uint32_t>{10, 100, 1000, 10000, 50000, 100000, 300000};
  }
  for (uint32_t n : sizes) {
    if (n == 0 || n > 2000000) {
      std::fprintf(stderr, "igbench perfmodel: --sizes: %u: out of range (1 .. 2000000)\n", n);
      return 2;
    }
  }
  if (o.repeats < 1 || o.repeats > 1000 || !(o.coverage > 0.0 && o.coverage <= 20.0) || o.width_px < 16 ||
      o.height_px < 16) {
    std::fprintf(stderr, "igbench perfmodel: bad option (repeats %d, coverage %g, viewport %dx%d)\n", o.repeats,
                 o.coverage, o.width_px, o.height_px);
    return 2;
  }
  const int repeats = o.quick ? std::min(o.repeats, 5) : o.repeats;
  std::string error;
  auto context = render::createContext(render::ContextKind::Headless, o.width_px, o.height_px, error);
  if (!context) {
    std::fprintf(stderr, "igbench perfmodel: %s\n", error.c_str());
    return 3;
  }
  render::CalibrationOptions co;
  co.width_px = o.width_px;
  co.height_px = o.height_px;
  co.fragmentWork = o.fragmentWork;
  co.budget_s = o.quick ? 1.5 : 10.0;
  co.runs = o.calibrationRuns > 0 ? o.calibrationRuns : o.quick ? 1 : 5;
  // The trace file is opened first: a path that cannot be written fails before the minutes of
  // measuring, not after.
  std::vector<render::CalibrationFrame> calibrationFrames;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> traceFile(nullptr, &std::fclose);
  if (!o.calibrationTrace.empty()) {
    traceFile.reset(std::fopen(o.calibrationTrace.c_str(), "w"));
    if (!traceFile) {
      std::fprintf(stderr, "igbench perfmodel: cannot write the calibration trace %s: %s\n", o.calibrationTrace.c_str(),
                   std::strerror(errno));
      return 2;
    }
    co.trace = &calibrationFrames;
  }
  render::Renderer renderer;
  if (!renderer.init(o.width_px, o.height_px, error)) {
    std::fprintf(stderr, "igbench perfmodel: %s\n", error.c_str());
    return 3;
  }
  lod::Camera cam;
  cam.aspect = static_cast<double>(o.width_px) / o.height_px;
  cam.near_m = 0.5;
  cam.far_m = 5000.0;
  render::Lighting light;
  light.fog = false;
  light.sunDirection = glm::normalize(glm::dvec3(0.3, -0.5, 0.8));
  const uint32_t maxN = *std::max_element(sizes.begin(), sizes.end());
  render::DynamicPassConfig pc;
  pc.maxObjects = maxN;
  pc.bounds = {glm::dvec3(-128.0), glm::dvec3(128.0)};
  pc.octreeDepth = 6;
  pc.maxQueries = 16;
  pc.fragmentWork = o.fragmentWork;
  render::DynamicPass pass;
  if (!pass.init(pc, error)) {
    std::fprintf(stderr, "igbench perfmodel: %s\n", error.c_str());
    return 3;
  }
  const glm::dmat4 vp = lod::projection(cam) *
                        glm::dmat4(lod::viewRotation(cam));
  const double screen = static_cast<double>(o.width_px) * o.height_px;

  std::vector<Point> points;
  std::vector<render::DynamicObject> objs;
  objs.reserve(maxN);
  uint64_t frame = 1;
  double wall_s = 0.0;  // in the sweeps (the calibration's own time is cal.seconds)
  // The whole sweep is run `sweeps` times; a point's time is the fastest of its sweeps' medians
  // (the load of other processes on a shared machine comes in phases of seconds to minutes; the
  // calibration's lower quartiles measure the machine outside them as well). The sweeps are
  // spread over a measured calibration's runs (CalibrationOptions::afterRun), so that the
  // constants and the frames they predict come from the same minutes.
  const int sweeps = o.sweeps > 0 ? o.sweeps : o.quick ? 1 : 5;
  int sweepsDone = 0;
  const auto runSweep = [&] {
    const int sweep = sweepsDone++;
    const auto t0 = BenchClock::now();
    for (size_t sizeIndex = 0; sizeIndex < sizes.size(); ++sizeIndex) {
      const uint32_t n = sizes[sizeIndex];
      // Random boxes inside the view between 30 and 110 m, then scaled to the target coverage.
      std::mt19937 rng(o.seed + n);
      std::uniform_real_distribution<double> u(-1.0, 1.0), u01(0.0, 1.0);
      objs.clear();
      for (uint32_t i = 0; i < n; ++i) {
        const double y = 30.0 + 80.0 * u01(rng);
        render::DynamicObject ob;
        ob.center_m = {0.62 * y * u(rng), y, 0.33 * y * u(rng)};
        ob.halfSize_m = {0.5 + u01(rng), 0.5 + u01(rng), 0.5 + u01(rng)};
        ob.yaw_deg = 180.0 * u(rng);
        ob.rgba = 0xff000000u | (rng() & 0xffffffu);
        objs.push_back(ob);
      }
      double area1 = 0.0;
      for (const auto& ob : objs) area1 += std::max(0.0, lod::projectedBoxArea_px(vp, eyeCorners(ob, cam.eye_m), o.width_px, o.height_px));
      const double scale = std::sqrt(o.coverage * screen / std::max(area1, 1e-9));
      double areaSum = 0.0, sqrtSum = 0.0, reachSum = 0.0, edgeSum = 0.0;
      pass.clear();
      for (auto& ob : objs) {
        ob.halfSize_m *= scale;
        const double cap = 0.25 * ob.center_m.y / std::max({ob.halfSize_m.x, ob.halfSize_m.y, ob.halfSize_m.z});
        if (cap < 1.0) ob.halfSize_m *= cap;
        const double a = std::max(0.0, lod::projectedBoxArea_px(vp, eyeCorners(ob, cam.eye_m), o.width_px, o.height_px));
        areaSum += a;
        sqrtSum += std::sqrt(a);
        // Triangles that cover no pixel centre are dropped in set-up (lod::PassLoad::rasterShare).
        const double reach = lod::boxRasterShare(a);
        reachSum += reach;
        edgeSum += std::sqrt(a) * reach;
        pass.add(ob);
      }
      int strategyIndex = 0;
      for (render::DynamicStrategy s : {render::DynamicStrategy::PerCommand, render::DynamicStrategy::Octree}) {
        const size_t pointIndex = 2 * sizeIndex + static_cast<size_t>(strategyIndex++);
        pass.setStrategy(s);
        std::vector<double> ms, subMs, appMs;
        // llvmpipe runs the first frames after a calibration run (its large scenes freed) and
        // after a change of strategy slowly: 20 frames before a sweep's first point, 5 before the
        // others.
        const int warm = pointIndex == 0 ? 20 : 5;
        for (int r = 0; r < warm + repeats; ++r) {
          // The first warm-up frame counts the samples that pass the depth test (counting costs
          // the rasterizer time, so the timed frames do not); the next frame reads the count.
          pass.setMeasureSamples(r == 0);
          const double c0 = threadCpuMs();
          const auto a = BenchClock::now();
          renderer.beginFrame(cam, light);
          pass.draw(renderer, frame++);
          renderer.endFrame();
          const auto submitted = BenchClock::now();
          const double c1 = threadCpuMs();
          renderer.finish();
          if (r >= warm) {
            ms.push_back(std::chrono::duration<double, std::milli>(BenchClock::now() - a).count());
            subMs.push_back(std::chrono::duration<double, std::milli>(submitted - a).count());
            appMs.push_back(c1 - c0);
          }
        }
        // The frame's statistics: the pass's counters, the fragments that passed the depth test (a
        // GL_SAMPLES_PASSED count of an earlier frame of the same scene), the boxes' edges.
        const render::DynamicFrameStats& st = pass.stats();
        const double drawnShare = st.objects ? static_cast<double>(st.objectsDrawn) / st.objects : 0.0;
        lod::PassLoad load;
        load.triangles = static_cast<double>(st.triangles);
        load.fragments = static_cast<double>(pass.samplesPassed());
        load.edgePx = edgeSum * drawnShare;
        load.rasterShare = n ? reachSum / n : 1.0;
        load.stateChanges = 1;
        load.commands = st.commands;
        load.rerecorded = st.rerecorded;
        load.submissions = st.submissions;
        load.frustumTests = st.frustumTests;
        Point p;
        p.load = load;
        p.objects = n;
        p.strategy = render::strategyName(s);
        p.measured_ms = percentile(ms, 50);
        p.measuredQ1_ms = percentile(ms, 25);
        p.submit_ms = percentile(subMs, 50);
        p.appCpu_ms = percentile(appMs, 50);
        p.samples = static_cast<uint64_t>(load.fragments);
        p.fragments = load.fragments;
        p.area_px = areaSum * drawnShare;
        p.sqrtArea_px = sqrtSum * drawnShare;
        p.rasterShare = load.rasterShare;
        p.triangles = st.triangles;
        p.sweep_ms = {p.measured_ms};
        if (sweep == 0) {
          points.push_back(p);
          continue;
        }
        // A later sweep: the same scene and statistics; keep the faster median.
        Point& q = points[pointIndex];
        q.sweep_ms.push_back(p.measured_ms);
        if (p.measured_ms < q.measured_ms) {
          q.measured_ms = p.measured_ms;
          q.submit_ms = p.submit_ms;
          q.appCpu_ms = p.appCpu_ms;
        }
        q.measuredQ1_ms = std::min(q.measuredQ1_ms, p.measuredQ1_ms);
      }
    }
    wall_s += std::chrono::duration<double>(BenchClock::now() - t0).count();
  };
  // True once a calibration run has followed a sweep (a measured calibration of two runs or more).
  bool betweenSweeps = false;
  if (!o.calibrateFirst) co.afterRun = [&](int run, std::string&) {
    // The sweeps due after this run of the calibration's: spread evenly over its runs, rounded
    // (3 runs and 1 sweep: the sweep after the second run; the last run tops up to all of them).
    const int runs = std::clamp(co.runs, 1, 9);
    while (sweepsDone < (2 * (run + 1) * sweeps + runs) / (2 * runs)) runSweep();
    if (sweepsDone > 0 && run + 1 < runs) betweenSweeps = true;
    return true;
  };
  render::CalibrationResult cal;
  std::string warning;
  if (!render::calibrate(o.cachePath, co, cal, error, &warning)) {
    std::fprintf(stderr, "igbench perfmodel: %s\n", error.c_str());
    return 1;
  }
  if (traceFile) {
    std::fprintf(traceFile.get(), "run,repeat,load,timed,frame_ms,submit_ms,thread_ms\n");
    for (const render::CalibrationFrame& f : calibrationFrames)
      std::fprintf(traceFile.get(), "%d,%d,%s,%d,%.4f,%.4f,%.4f\n", f.run, f.repeat, f.load, f.timed ? 1 : 0, f.frame_ms,
                   f.submit_ms, f.thread_ms);
    if (std::fflush(traceFile.get()) != 0 || std::ferror(traceFile.get())) {
      std::fprintf(stderr, "igbench perfmodel: cannot write the calibration trace %s: %s\n", o.calibrationTrace.c_str(),
                   std::strerror(errno));
      return 2;
    }
    if (cal.fromCache)
      std::fprintf(stderr, "igbench perfmodel: the calibration came from the cache %s: the trace %s has no frames\n",
                   o.cachePath.c_str(), o.calibrationTrace.c_str());
  }
  if (!warning.empty()) std::fprintf(stderr, "igbench perfmodel: calibration cache: %s\n", warning.c_str());

  // The sweeps not yet run: all of them when the constants came from the cache or --calibrate-first.
  while (sweepsDone < sweeps) runSweep();
  const lod::PerfConstants& k = cal.constants;
  for (Point& p : points) {
    lod::TimeBreakdown tb;
    p.predicted_ms = lod::predictFrame_ns(k, p.load, {}, &tb) * 1e-6;
    p.error_pct = 100.0 * std::abs(p.predicted_ms - p.measured_ms) / std::max(p.measured_ms, 1e-9);
    p.errorQ1_pct = 100.0 * std::abs(p.predicted_ms - p.measuredQ1_ms) / std::max(p.measuredQ1_ms, 1e-9);
    p.vertex_ms = tb.vertS * 1e-6;
    p.fragment_ms = tb.fragS * 1e-6;
    p.commands_ms = (tb.bufS + tb.fcS) * 1e-6;
    p.bound = boundName(tb.boundS);
  }
  // How far the sweeps' medians of the same frames differ (0 with one sweep).
  std::vector<double> spreads;
  for (const Point& p : points) {
    const double slowest = *std::max_element(p.sweep_ms.begin(), p.sweep_ms.end());
    spreads.push_back(100.0 * (slowest - p.measured_ms) / std::max(p.measured_ms, 1e-9));
  }
  const double spreadMedian = spreads.empty() ? 0.0 : percentile(spreads, 50),
               spreadMax = spreads.empty() ? 0.0 : *std::max_element(spreads.begin(), spreads.end());
  std::vector<double> errs, errsQ1;
  for (const Point& p : points) errs.push_back(p.error_pct), errsQ1.push_back(p.errorQ1_pct);
  const double med = percentile(errs, 50), mx = *std::max_element(errs.begin(), errs.end());
  const double medQ1 = percentile(errsQ1, 50), mxQ1 = *std::max_element(errsQ1.begin(), errsQ1.end());

  // T_tri by the triangles of a submission (lod::PerfConstants::triByDraw_ns), as JSON and text.
  std::string byDrawJson = "{", byDrawText;
  for (size_t i = 0; i < k.triByDraw_ns.size(); ++i) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%s\"%u\":%.2f", i ? "," : "", 12u << i, k.triByDraw_ns[i]);
    byDrawJson += buf;
    std::snprintf(buf, sizeof buf, "%s%u: %.1f", i ? ", " : "", 12u << i, k.triByDraw_ns[i]);
    byDrawText += buf;
  }
  byDrawJson += "}";
  if (o.json) {
    std::printf("{\"bench\":\"perfmodel\",\"device\":\"%s\",\"viewport\":[%d,%d],\"fragment_work\":%u,\"coverage\":%g,"
                "\"repeats\":%d,\"calibration\":{\"from_cache\":%s,\"runs\":%d,\"between_sweeps\":%s,\"seconds\":%.3f,\"frame_ns\":%.1f,\"tri_ns\":%.3f,"
                "\"frag_ns\":%.4f,\"raster_tri_ns\":%.3f,\"edge_ns\":%.3f,\"draw_raster_ns\":%.1f,\"depth_frag_ns\":%.4f,\"state_ns\":%.1f,\"command_ns\":%.1f,\"rerecord_ns\":%.1f,"
                "\"submit_ns\":%.1f,\"cull_ns\":%.2f,\"occlusion_test_ns\":%.1f,\"overlap\":%.3f,\"overlap_triangles\":%.0f,\"command_count\":%.0f,\"command_large_ns\":%.1f,\"command_large_count\":%.0f,\"tri_ns_by_draw\":%s},\"points\":[",
                jsonEscape(cal.key).c_str(), o.width_px, o.height_px, o.fragmentWork, o.coverage, repeats,
                cal.fromCache ? "true" : "false", cal.fromCache ? 0 : co.runs, betweenSweeps ? "true" : "false", cal.seconds, k.frame_ns, k.tri_ns, k.frag_ns, k.rasterTri_ns, k.edge_ns, k.drawRaster_ns,
                k.depthFrag_ns, k.state_ns, k.command_ns, k.rerecord_ns, k.submit_ns, k.cull_ns, k.occlusionTest_ns, k.overlap, k.overlapTriangles,
                k.commandCount, k.commandLarge_ns, k.commandLargeCount, byDrawJson.c_str());
    for (size_t i = 0; i < points.size(); ++i) {
      const Point& p = points[i];
      std::string sweepList;
      for (size_t j = 0; j < p.sweep_ms.size(); ++j) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "%s%.4f", j ? "," : "", p.sweep_ms[j]);
        sweepList += buf;
      }
      std::printf("%s{\"objects\":%u,\"strategy\":\"%s\",\"measured_ms\":%.4f,\"predicted_ms\":%.4f,\"error_pct\":%.2f,"
                  "\"measured_q1_ms\":%.4f,\"error_q1_pct\":%.2f,\"triangles\":%llu,\"fragments\":%.0f,\"vertex_ms\":%.4f,"
                  "\"fragment_ms\":%.4f,\"commands_ms\":%.4f,\"bound\":\"%s\",\"raster_share\":%.3f,\"area_px\":%.0f,\"sqrt_area_px\":%.0f,\"submit_ms\":%.4f,\"app_cpu_ms\":%.4f,\"samples\":%llu,\"sweep_ms\":[%s]}",
                  i ? "," : "", p.objects, p.strategy, p.measured_ms, p.predicted_ms, p.error_pct, p.measuredQ1_ms, p.errorQ1_pct,
                  static_cast<unsigned long long>(p.triangles), p.fragments, p.vertex_ms, p.fragment_ms, p.commands_ms, p.bound,
                  p.rasterShare, p.area_px, p.sqrtArea_px, p.submit_ms, p.appCpu_ms, static_cast<unsigned long long>(p.samples),
                  sweepList.c_str());
    }
    std::printf("],\"error_pct_median\":%.2f,\"error_pct_max\":%.2f,\"error_q1_pct_median\":%.2f,"
                "\"error_q1_pct_max\":%.2f,\"sweeps\":%d,\"sweep_spread_pct_median\":%.2f,\"sweep_spread_pct_max\":%.2f,"
                "\"wall_s\":%.1f}\n",
                med, mx, medQ1, mxQ1, sweeps, spreadMedian, spreadMax, wall_s);
  } else {
    std::printf("perfmodel: %s, %dx%d, material work %u, calibration %s (%.1f s)\n", cal.key.c_str(), o.width_px,
                o.height_px, o.fragmentWork,
                cal.fromCache ? "from cache" : betweenSweeps ? "measured between the sweeps" : "measured before the sweeps",
                cal.seconds);
    std::printf("constants: frame %.0f ns, tri %.1f ns, frag %.2f ns, raster tri %.1f ns, edge %.1f ns, draw (rasterizer) %.0f ns, state %.0f ns, command %.0f ns, "
                "rerecord %.0f ns, submit %.0f ns, cull %.1f ns, occlusion test %.0f ns, overlap %.2f above %.0f triangles\n",
                k.frame_ns, k.tri_ns, k.frag_ns, k.rasterTri_ns, k.edge_ns, k.drawRaster_ns, k.state_ns, k.command_ns, k.rerecord_ns, k.submit_ns,
                k.cull_ns, k.occlusionTest_ns, k.overlap, k.overlapTriangles);
    std::printf("T_tri by the triangles of a submission (ns): %s; t_c %.0f ns with %.0f "
                "commands, %.0f ns with %.0f\n",
                byDrawText.c_str(), k.command_ns, k.commandCount, k.commandLarge_ns, k.commandLargeCount);
    std::printf("%9s %-11s %12s %12s %8s %12s %8s  %-8s %8s %8s %8s\n", "objects", "strategy", "measured ms", "predicted ms",
                "error %", "q1 ms", "error %", "bound", "vert ms", "frag ms", "cmd ms");
    for (const Point& p : points)
      std::printf("%9u %-11s %12.3f %12.3f %8.2f %12.3f %8.2f  %-8s %8.3f %8.3f %8.3f\n", p.objects, p.strategy, p.measured_ms,
                  p.predicted_ms, p.error_pct, p.measuredQ1_ms, p.errorQ1_pct, p.bound, p.vertex_ms, p.fragment_ms,
                  p.commands_ms);
    std::printf("error vs median: median %.2f %%, max %.2f %%; vs lower quartile: median %.2f %%, max %.2f %% "
                "(goal <= 5 %% / <= 10 %%); %d sweeps, their medians differ by %.1f %% (median) / %.1f %% (max); sweeps %.1f s\n",
                med, mx, medQ1, mxQ1, sweeps, spreadMedian, spreadMax, wall_s);
  }
  return 0;
}

}  // namespace ig
