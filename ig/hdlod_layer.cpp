#include "ig/hdlod_layer.h"

#include <chrono>
#include <cmath>
#include <cstdio>

#include "ig/hdlod_tool.h"
#include "ig/scene_surfaces.h"
#include "lod/hdlod_site.h"
#include "render/hdlod_pass.h"
#include "render/renderer.h"

namespace ig {

namespace hd = lod::hdlod;

std::unique_ptr<HdlodLayer> HdlodLayer::create(const HdlodLayerConfig& config, std::string& error) {
  if (!(config.tolerance_px >= 0.0) || !std::isfinite(config.tolerance_px)) {
    error = "[hdlod] tolerance_px = " + std::to_string(config.tolerance_px) + ": must be a finite number >= 0";
    return nullptr;
  }
  if (!std::isfinite(config.timeOffset_s) || !std::isfinite(config.timeScale)) {
    error = "[hdlod] time_offset_s / time_scale: must be finite";
    return nullptr;
  }
  if (config.octreeDepth < 0 || config.octreeDepth > 6) {
    error = "[hdlod] octree_depth = " + std::to_string(config.octreeDepth) + ": must be 0..6";
    return nullptr;
  }
  hd::BuildConfig build;
  if (!hd::parseSimplifier(config.simplifier, build.simplifier)) {
    error = "[hdlod] simplifier = '" + config.simplifier + "': must be meshoptimizer, openmesh or clustering";
    return nullptr;
  }
  std::unique_ptr<HdlodLayer> layer(new HdlodLayer);
  layer->config_ = config;
  layer->tolerance_px_ = config.tolerance_px;
  if (!config.schedule.empty()) {
    auto scene = hd::loadSchedule(config.schedule, error);
    if (!scene) return nullptr;
    layer->scene_ = std::move(*scene);
  } else {
    hd::SiteParams p;
    p.scale = config.siteScale;
    p.seed = config.siteSeed;
    p.origin_m = {config.siteX_m, config.siteY_m, config.siteZ_m};
    layer->scene_ = hd::makeConstructionSite(p, error);
    if (!error.empty()) {
      error = "[hdlod] site: " + error;
      return nullptr;
    }
  }
  ProgressBar bar("hdlod build", config.progress);
  build.progress = bar.callback();
  const auto t0 = std::chrono::steady_clock::now();
  layer->tree_ = hd::loadOrBuildHdlod(layer->scene_, build, config.cache, layer->outcome_, layer->cacheNote_);
  layer->buildSeconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  bar.finish();
  layer->draws_ = hd::DrawList(layer->tree_);  // sized once: select() writes into it
  return layer;
}

bool HdlodLayer::Surfaces::intersect(const glm::dvec3& from_m, const glm::dvec3& to_m, io::SurfaceMask mask,
                                     io::SurfaceHit& hit, uint32_t* work) const {
  if (!(mask & io::surfaceBit(io::kSurfaceObject))) return false;
  hd::RayHit h;
  hd::RayWork w;
  const bool found = rays.intersect(from_m, to_m, time_s, h, &w);
  return toSurfaceHit(found, h, w, io::kSurfaceObject, hit, work);
}

HdlodLayer::~HdlodLayer() = default;

bool HdlodLayer::initRender(std::string& error) {
  pass_ = std::make_unique<render::HdlodPass>();
  return pass_->init(tree_, scene_, config_.octreeDepth, error);
}

double HdlodLayer::scheduleTime(double simulationTime_s) const {
  return hd::clampTime(config_.timeOffset_s + config_.timeScale * simulationTime_s, scene_.duration_s);
}

void HdlodLayer::select(const lod::Camera& camera, double simulationTime_s, int viewportHeight_px) {
  hd::SelectView v;
  v.camera = camera;
  // Clamped here, not only in the selection: a finite host time far beyond the schedule can
  // overflow time_offset_s + time_scale * t to +-inf, which the selection rejects as bad input
  // (nothing drawn) instead of holding the schedule at T (or 0).
  v.time_s = scheduleTime(simulationTime_s);
  v.tolerance_rad = hd::toleranceFromPixels(tolerance_px_, camera.fovY_deg, std::max(1, viewportHeight_px));
  stats_.scheduleTime_s = v.time_s;
  surfaces_.time_s = v.time_s;
  drawCount_ = hd::selectHdlod(tree_, scene_, v, draws_->draws, draws_->moving, &stats_.select);
}

void HdlodLayer::draw(render::Renderer& renderer) {
  if (!pass_) return;
  pass_->draw(renderer, {draws_->draws.data(), drawCount_});
  const render::HdlodPassStats& s = pass_->lastStats();
  stats_.matrixUpdates = s.matrixUpdates;
  stats_.movedAcross = s.movedAcross;
  stats_.added = s.added;
  stats_.removed = s.removed;
  stats_.multiDraws = s.multiDraws;
}

uint64_t HdlodLayer::gpuBytes() const { return pass_ ? pass_->bufferBytes() : 0; }

std::string HdlodLayer::describe() const {
  char buf[512];
  std::snprintf(buf, sizeof buf, "hdlod: %s, %zu objects, %zu clusters, tree %s in %.2f s%s%s",
                config_.schedule.empty() ? "synthetic site" : config_.schedule.c_str(), scene_.objects.size(), tree_.clusters.size(),
                hd::cacheOutcomeName(outcome_), buildSeconds_, cacheNote_.empty() ? "" : ": ", cacheNote_.c_str());
  return buf;
}

}  // namespace ig
