#include "ig/bench_fog.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>

#include "ig/app_common.h"
#include "ig/json.h"
#include "ig/service.h"
#include "io/replay.h"
#include "render/image.h"
#include "render/renderer.h"

namespace ig {
namespace {

struct Point {
  double visibility_m = 0, cullDistance_m = 0;
  double trianglesCull = 0, trianglesFull = 0;  // p50 over the frames
  double msCull = 0, msFull = 0;                // p50 frame time: select + submit + glFinish
  int maxDiff = 0;                              // largest channel difference, 8-bit levels
  double differPct = 0;                         // pixels with any difference, % (mean over frames)
  double psnrMin_db = 99.0;
};

}  // namespace

int runFogBench(const FogBenchOptions& opt) {
  Overrides o;
  o.width_px = opt.width_px;
  o.height_px = opt.height_px;
  o.statsFile = "";
  o.snapshotEvery = 0;
  if (!opt.sceneFile.empty()) o.sceneFile = opt.sceneFile;
  ServiceConfig config;
  SceneConfig scene;
  std::string error;
  if (!loadConfigs(opt.configFile, o, config, scene, error)) {
    std::fprintf(stderr, "igbench: %s\n", error.c_str());
    return 2;
  }
  for (double v : opt.visibilities_m) {
    if (!(v > 0.0 && v <= 1e7)) {
      std::fprintf(stderr, "igbench: --visibility %g: must be in (0, 1e7] metres\n", v);
      return 2;
    }
  }
  io::Recording rec;
  if (!io::loadRecording(config.replayFile, rec, error)) {
    std::fprintf(stderr, "igbench: %s\n", error.c_str());
    return 2;
  }
  config.host = HostSource::None;
  config.snapshotFrames.clear();
  config.recordFile.clear();
  scene.fog.enabled = true;
  SceneConfig open = scene;
  scene.fog.cull = true;
  open.fog.cull = false;
  auto culled = Service::create(config, scene, error);
  if (!culled) {
    std::fprintf(stderr, "igbench: start-up failed: %s\n", error.c_str());
    return 3;
  }
  auto full = Service::create(config, open, error);
  if (!full) {
    std::fprintf(stderr, "igbench: start-up failed: %s\n", error.c_str());
    return 3;
  }

  // Consecutive frames of steady flight: every 5th sample of the replay (1/12 s at 60 Hz) from
  // 2 s, wrapping around at its end.
  const double span_s = std::max(rec.duration_s() - 2.0, 1.0 / 12.0);
  const auto sample = [&](int k) { return io::sampleAt(rec, 2.0 + std::fmod(k * 5.0 / 60.0, span_s)).state; };
  const auto timed = [](Service& s, const io::HostState& h, uint64_t& triangles) {
    const auto t0 = std::chrono::steady_clock::now();
    triangles = s.renderOnce(h, nullptr).triangles;
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  };
  // Both services fly the whole sample path once, untimed, so that every point starts from the
  // state the flight leaves (ROAM's mesh depends on its history) and not the first from a fresh one.
  for (int k = 0; k < opt.frames + 3; ++k) {
    io::HostState h = sample(k);
    h.visibility_m = opt.visibilities_m.empty() ? -1.0 : opt.visibilities_m.front();
    culled->renderOnce(h, nullptr);
    full->renderOnce(h, nullptr);
  }
  std::vector<Point> points;
  render::Image a, b;
  for (double v : opt.visibilities_m) {
    Point p;
    p.visibility_m = v;
    p.cullDistance_m = render::fogOpaqueDistance_m(v);
    std::vector<double> msC, msF, triC, triF;
    double differ = 0;
    for (int k = -3; k < opt.frames; ++k) {  // 3 warm-up frames (the new visibility's first selections)
      io::HostState h = sample(std::max(k, 0) + 3);
      h.visibility_m = v;
      uint64_t tc = 0, tf = 0;
      double mc = 0, mf = 0;
      if (k % 2 == 0) {  // alternate the order: neither side always runs first
        mc = timed(*culled, h, tc);
        mf = timed(*full, h, tf);
      } else {
        mf = timed(*full, h, tf);
        mc = timed(*culled, h, tc);
      }
      if (k < 0) continue;
      msC.push_back(mc);
      msF.push_back(mf);
      triC.push_back(static_cast<double>(tc));
      triF.push_back(static_cast<double>(tf));
      // Converged: the pictures of the frame just timed, in the timed order, so that the service
      // timed first next frame is the one whose GL context is current (the switch is charged to
      // each side alike).
      if (k % 2 == 0) {
        culled->renderOnce(h, &a);
        full->renderOnce(h, &b);
      } else {
        full->renderOnce(h, &b);
        culled->renderOnce(h, &a);
      }
      for (size_t i = 0; i < a.rgba.size() && i < b.rgba.size(); ++i)
        p.maxDiff = std::max(p.maxDiff, std::abs(static_cast<int>(a.rgba[i]) - static_cast<int>(b.rgba[i])));
      differ += render::fractionDifferent(a, b, 0);
      p.psnrMin_db = std::min(p.psnrMin_db, render::psnrDb(a, b));
    }
    p.msCull = median(msC);
    p.msFull = median(msF);
    p.trianglesCull = median(triC);
    p.trianglesFull = median(triF);
    p.differPct = opt.frames > 0 ? 100.0 * differ / opt.frames : 0.0;
    points.push_back(p);
  }

  int worstDiff = 0;
  double speedupMin = 1e300, speedupMax = 0;
  for (const Point& p : points) {
    worstDiff = std::max(worstDiff, p.maxDiff);
    const double s = p.msCull > 0 ? p.msFull / p.msCull : 0.0;
    speedupMin = std::min(speedupMin, s);
    speedupMax = std::max(speedupMax, s);
  }
  if (opt.json) {
    std::printf("{\"suite\":\"fog\",\"scene\":%s,\"renderer\":%s,\"width_px\":%d,\"height_px\":%d,\"frames\":%d,\"points\":[",
                jsonString(scene.name).c_str(), jsonString(culled->info().context).c_str(), config.width_px,
                config.height_px, opt.frames);
    for (size_t i = 0; i < points.size(); ++i) {
      const Point& p = points[i];
      std::printf("%s{\"visibility_m\":%.1f,\"cull_distance_m\":%.1f,\"triangles_cull\":%.0f,\"triangles_full\":%.0f,"
                  "\"triangle_ratio\":%.4f,\"frame_ms_cull\":%.3f,\"frame_ms_full\":%.3f,\"speedup\":%.3f,"
                  "\"max_diff_levels\":%d,\"differ_pct\":%.4f,\"psnr_db_min\":%.2f}",
                  i ? "," : "", p.visibility_m, p.cullDistance_m, p.trianglesCull, p.trianglesFull,
                  p.trianglesFull > 0 ? p.trianglesCull / p.trianglesFull : 1.0, p.msCull, p.msFull,
                  p.msCull > 0 ? p.msFull / p.msCull : 0.0, p.maxDiff, p.differPct, p.psnrMin_db);
    }
    std::printf("],\"speedup_min\":%.3f,\"speedup_max\":%.3f,\"max_diff_levels\":%d}\n", speedupMin, speedupMax, worstDiff);
  } else {
    std::printf("fog suite: scene '%s', %dx%d, %s, %d frames per visibility\n", scene.name.c_str(), config.width_px,
                config.height_px, culled->info().context.c_str(), opt.frames);
    std::printf("  %12s %10s %14s %14s %10s %10s %8s %9s %8s %8s\n", "visibility m", "cull at m", "triangles cull",
                "triangles full", "ms cull", "ms full", "speedup", "max diff", "differ %", "PSNR dB");
    for (const Point& p : points)
      std::printf("  %12.0f %10.0f %14.0f %14.0f %10.3f %10.3f %8.2f %9d %8.3f %8.2f\n", p.visibility_m,
                  p.cullDistance_m, p.trianglesCull, p.trianglesFull, p.msCull, p.msFull,
                  p.msCull > 0 ? p.msFull / p.msCull : 0.0, p.maxDiff, p.differPct, p.psnrMin_db);
  }
  return 0;
}

}  // namespace ig
