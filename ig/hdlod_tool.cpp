#include "ig/hdlod_tool.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "lod/hdlod_build.h"
#include "lod/hdlod_cache.h"
#include "lod/hdlod_scene.h"
#include "lod/hdlod_site.h"

namespace ig {

ProgressBar::ProgressBar(std::string label, bool force) : label_(std::move(label)), enabled_(force || ::isatty(STDERR_FILENO) == 1) {}

ProgressBar::~ProgressBar() { finish(); }

void ProgressBar::update(double fraction, const char* stage) {
  if (!enabled_) return;
  const int pct = static_cast<int>(std::floor(std::clamp(fraction, 0.0, 1.0) * 100.0));
  if (pct == shown_ && stage_ == stage) return;
  shown_ = pct;
  stage_ = stage;
  constexpr int kWidth = 30;
  const int filled = pct * kWidth / 100;
  char bar[kWidth + 1];
  for (int i = 0; i < kWidth; ++i) bar[i] = i < filled ? '#' : '.';
  bar[kWidth] = '\0';
  std::fprintf(stderr, "\r%s [%s] %3d%% %-16s", label_.c_str(), bar, pct, stage);
  std::fflush(stderr);
  open_ = true;
}

void ProgressBar::finish() {
  if (open_) std::fprintf(stderr, "\n");
  open_ = false;
}

std::function<void(double, const char*)> ProgressBar::callback() {
  if (!enabled_) return {};
  return [this](double f, const char* stage) { update(f, stage); };
}

int runSiteTool(const SiteToolOptions& o) {
  namespace hd = lod::hdlod;
  hd::SiteParams p;
  p.scale = o.scale;
  p.seed = o.seed;
  p.floors = o.floors;
  p.bays = o.bays;
  p.duration_s = o.durationDays * 86400.0;
  p.origin_m = {o.originX_m, o.originY_m, o.originZ_m};
  if (!(o.durationDays > 0.0) || !std::isfinite(o.durationDays)) {
    std::fprintf(stderr, "igtool site: --days %g: must be > 0\n", o.durationDays);
    return 2;
  }
  hd::BuildConfig config;
  if (!hd::parseSimplifier(o.simplifier, config.simplifier)) {
    std::fprintf(stderr, "igtool site: --simplifier: unknown simplifier '%s' (meshoptimizer, openmesh, clustering)\n", o.simplifier.c_str());
    return 2;
  }
  std::string error;
  const hd::Scene scene = hd::makeConstructionSite(p, error);
  if (!error.empty()) {
    std::fprintf(stderr, "igtool site: %s\n", error.c_str());
    return 2;
  }
  std::error_code ec;
  std::filesystem::create_directories(std::filesystem::path(o.out) / "models", ec);
  if (ec) {
    std::fprintf(stderr, "igtool site: --out %s: cannot create the folder: %s\n", o.out.c_str(), ec.message().c_str());
    return 1;
  }
  const std::string schedule = o.out + "/site.sched";
  if (!hd::saveSchedule(scene, schedule, "models", error)) {
    std::fprintf(stderr, "igtool site: %s\n", error.c_str());
    return 1;
  }
  uint64_t triangles = 0;
  uint32_t counts[3] = {};
  for (const hd::Object& obj : scene.objects) {
    triangles += scene.models[obj.model].triangleCount();
    ++counts[static_cast<int>(hd::classify(obj, scene.duration_s))];
  }
  std::printf("igtool site: %s: %zu objects (%u static, %u pseudo-dynamic, %u dynamic), %zu models, %llu triangles, T = %g days\n",
              schedule.c_str(), scene.objects.size(), counts[0], counts[1], counts[2], scene.models.size(),
              static_cast<unsigned long long>(triangles), o.durationDays);
  if (!o.cache.empty()) {
    // Built from the schedule as written, so the cache matches what igd loads from it.
    const auto loaded = hd::loadSchedule(schedule, error);
    if (!loaded) {
      std::fprintf(stderr, "igtool site: %s\n", error.c_str());
      return 1;
    }
    ProgressBar bar("hdlod build", o.progress);
    config.progress = bar.callback();
    const auto t0 = std::chrono::steady_clock::now();
    const hd::HdlodTree tree = hd::buildHdlod(*loaded, config);
    bar.finish();
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    config.progress = nullptr;
    if (!hd::saveHdlodCache(o.cache, tree, hd::hdlodCacheKey(*loaded, config), error)) {
      std::fprintf(stderr, "igtool site: %s\n", error.c_str());
      return 1;
    }
    std::printf("igtool site: %s: %zu clusters (%u merged, %u model versions), built in %.1f s\n", o.cache.c_str(), tree.clusters.size(),
                tree.stats.mergedClusters, tree.stats.modelLods, s);
  }
  return 0;
}

}  // namespace ig
