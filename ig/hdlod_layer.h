// The [hdlod] scene layer (paper 000): a 4D scene — a schedule file, or the synthetic
// construction site — its HDLOD tree (from the cache file when it is current, else built and
// written there), per-frame selection for the eye and the simulation time, and the render pass.
//
// Use: create() at start-up (no GL: loads or builds), initRender() once the renderer exists,
// then per frame select(camera, t) (the lod phase) and draw(renderer) (the submit phase,
// between Renderer::beginFrame and endFrame). No allocation per frame.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "ig/config.h"
#include "io/link.h"
#include "lod/hdlod_build.h"
#include "lod/hdlod_cache.h"
#include "lod/hdlod_rays.h"
#include "lod/hdlod_scene.h"
#include "lod/hdlod_select.h"
#include "lod/view.h"

namespace ig {

namespace render {
class Renderer;
class HdlodPass;
}  // namespace render

// HdlodLayerConfig ([hdlod] scene keys) is in ig/config.h.

struct HdlodLayerStats {
  lod::hdlod::SelectStats select;
  double scheduleTime_s = 0.0;
  uint32_t matrixUpdates = 0, movedAcross = 0, added = 0, removed = 0, multiDraws = 0;
};

class HdlodLayer {
 public:
  // Loads the schedule (or generates the site) and loads or builds the tree. nullptr + error
  // (naming the file or option and the bad value) on failure.
  static std::unique_ptr<HdlodLayer> create(const HdlodLayerConfig& config, std::string& error);
  ~HdlodLayer();

  // The render pass (a GL context must be current).
  bool initRender(std::string& error);
  // Per frame: selection for the camera at simulation time t (seconds), viewport height in pixels.
  void select(const lod::Camera& camera, double simulationTime_s, int viewportHeight_px);
  // Per frame, after select(): draws the selection.
  void draw(render::Renderer& renderer);
  // The screen-space tolerance r of the next selections (the frame governor's; > 0). Starts at
  // the scene's tolerance_px.
  void setTolerance_px(double r) { tolerance_px_ = r; }
  double tolerance_px() const { return tolerance_px_; }

  // The objects as the host's terrain queries meet them (CIGI HAT/HOT and line of sight:
  // io::FrameStart::objects), where they are at the schedule time of the last select() or
  // setQueryTime() (time 0 before either). Every triangle of every present object at full
  // detail, not the LOD drawn. Empty until enableQueries() builds the index (the service does
  // when its host link answers queries: 7 ms for the site at scale 0.25).
  const io::SceneSurfaces& surfaces() const { return surfaces_; }
  void enableQueries() {
    if (surfaces_.rays.empty()) surfaces_.rays = lod::hdlod::SceneRays(scene_);
  }
  // The simulation time the queries answer for (select() sets it too): the frame loop sets this
  // frame's before the host link answers, ahead of the selection.
  void setQueryTime(double simulationTime_s) { surfaces_.time_s = scheduleTime(simulationTime_s); }
  const lod::hdlod::SceneRays& rays() const { return surfaces_.rays; }

  const HdlodLayerStats& stats() const { return stats_; }
  const lod::hdlod::Scene& scene() const { return scene_; }
  const lod::hdlod::HdlodTree& tree() const { return tree_; }
  lod::hdlod::CacheOutcome cacheOutcome() const { return outcome_; }
  const std::string& cacheNote() const { return cacheNote_; }
  double buildSeconds() const { return buildSeconds_; }
  uint64_t gpuBytes() const;
  // A one-line description for the start-up log.
  std::string describe() const;

 private:
  HdlodLayer() = default;
  // Schedule time for a simulation time: time_offset_s + time_scale * t, clamped to [0, T].
  double scheduleTime(double simulationTime_s) const;
  HdlodLayerConfig config_;
  double tolerance_px_ = 1.0;
  lod::hdlod::Scene scene_;
  lod::hdlod::HdlodTree tree_;
  lod::hdlod::CacheOutcome outcome_ = lod::hdlod::CacheOutcome::Disabled;
  std::string cacheNote_;
  double buildSeconds_ = 0.0;
  std::optional<lod::hdlod::DrawList> draws_;
  size_t drawCount_ = 0;
  std::unique_ptr<render::HdlodPass> pass_;
  HdlodLayerStats stats_;
  struct Surfaces final : io::SceneSurfaces {
    lod::hdlod::SceneRays rays;
    double time_s = 0.0;
    bool intersect(const glm::dvec3& from_m, const glm::dvec3& to_m, io::SurfaceMask mask, io::SurfaceHit& hit,
                   uint32_t* work) const override;
    double top_m() const override { return rays.top_m(); }
  };
  Surfaces surfaces_;
};

}  // namespace ig
