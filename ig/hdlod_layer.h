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
#include "lod/hdlod_build.h"
#include "lod/hdlod_cache.h"
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
};

}  // namespace ig
