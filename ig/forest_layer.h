// The forest layer of the service (paper 004, shared/SEEDS.md section 004): built only when the
// scene has a [forest] table. Start-up: the distribution map (generated, or a PNG), the trees
// placed over the terrain's height field, the near kd-tree, the fins of the full-resolution
// terrain grid, the tree models and the textures T and S (an igtool forest-textures assets
// folder, or procedural models and textures rendered at start-up), and the GL pass. Per frame:
// select(camera) (near trees: cull, gather, sort; fin groups: frustum, range, tangent cones)
// then draw(renderer, ...) between beginFrame and endFrame, after the terrain. No allocation per
// frame, no thread.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "ig/config.h"
#include "io/link.h"
#include "lod/forest.h"
#include "lod/forest_fins.h"
#include "lod/forest_kdtree.h"
#include "lod/forest_model.h"
#include "lod/forest_rays.h"
#include "lod/view.h"
#include "render/forest_pass.h"

namespace ig {

namespace render {
class Renderer;
}

// ForestLayerConfig ([forest] scene keys) is in ig/config.h.

// The ground the forest stands on: the terrain's height field (the same posts the terrain mesh
// is made of), row-major, row = north.
struct ForestGround {
  std::span<const float> heights_m;
  int width = 0, height = 0;
  double spacing_m = 1.0;
  glm::dvec3 origin_m{0.0};  // ENU of sample (0, 0)
};

struct ForestLayerStats {
  uint64_t trees = 0;        // in the forest
  uint64_t fins = 0;         // fins built
  uint32_t treesDrawn = 0;   // last select
  uint64_t finsDrawn = 0;    // last select
  uint32_t finGroupsDrawn = 0;
  uint32_t treesDropped = 0; // no room in the instance buffer
  int layers = 0;
};

class ForestLayer {
 public:
  // Builds everything (GL context current). `models`/`textures` override the config's
  // (benchmarks); pass empty / null to use the config. Null and `error` on bad input, among it
  // a map of more than 16384 cells a side (Gr is one texture; checked before a generated map is
  // allocated).
  static std::unique_ptr<ForestLayer> create(const ForestLayerConfig& config, const ForestGround& ground,
                                             std::string& error, const std::vector<lod::TreeMesh>* models = nullptr,
                                             const render::ForestTextures* textures = nullptr);
  ~ForestLayer();

  // lod phase.
  void select(const lod::Camera& camera);
  // submit phase: trees, then layers over the terrain mesh (Renderer::terrainMeshVertexBuffer,
  // first `terrainVertexCount` vertices relative to `terrainOrigin_m`), then fins.
  void draw(render::Renderer& renderer, const glm::dvec3& terrainOrigin_m, size_t terrainVertexCount);
  // The same with the terrain mesh drawn as ranges of triangle slots (lod/terrain_chunks.h).
  void draw(render::Renderer& renderer, const glm::dvec3& terrainOrigin_m,
            std::span<const lod::TerrainDrawRange> terrainRanges);

  ForestLayerStats stats() const { return stats_; }
  uint64_t bufferBytes() const { return pass_.bufferBytes(); }

  // For benchmarks and tests.
  const lod::ForestKdTree& kdTree() const { return kd_; }
  // The trees as the host's line-of-sight queries meet them (CIGI LOS: io::FrameStart::objects):
  // every tree of the forest, posed as the near pass draws it (lod/forest_rays.h), for sight
  // queries only (HAT/HOT: a vehicle stands on the ground between the trees). Empty until
  // enableQueries() builds the index (the service does when its host link answers queries:
  // ~70 ms and ~23 bytes a tree for the default 1.2 M-tree forest). enableQueries(false) frees
  // what the index would be built from (the service does for any other host source).
  const io::SceneSurfaces& surfaces() const { return surfaces_; }
  void enableQueries(bool enable = true);
  const lod::FinSet& fins() const { return fins_; }
  const lod::ForestMap& map() const { return map_; }
  render::ForestPass& pass() { return pass_; }
  std::span<const lod::ForestInstance> selectedTrees() const { return std::span(instances_.data(), selected_); }
  std::span<const lod::ForestModelRange> selectedModels() const { return modelRanges_; }
  // Changes the fade bands (validated; false keeps the old ones) and the drawn parts.
  bool setFades(const lod::NearFade& nearFade, const lod::FarFade& farFade, std::string& error);
  // The 3D trees' near distance (the frame governor's knob): the near fade band and the shell
  // layers' fade-in band, which overlap it, scaled together so that the band ends at `end_m`
  // (the scene's bands at its near_fade_end_m). Returns false and keeps the bands when they
  // would no longer be valid (the fade-in would pass the layers' fade-out).
  bool setNearDistance(double end_m);
  double nearDistance() const { return nearFade_.fadeOutEnd_m; }
  // How many shell layers are drawn (the frame governor's second forest knob: the layers are
  // fill over most of the screen, the larger part of a forest frame): 1 ... layerCount(), the
  // scene's `layers` at start. Fewer layers draw the same forest coarser (ForestPass::drawLayers);
  // a value out of range is clamped; 0 = all (also after the textures change their count).
  void setLayersDrawn(int layers);
  // Prepares the counts in [least, most] (their textures made now, not on first use: the frame
  // governor's knob, whose first cut comes when a frame is already late). GL context current.
  void prepareLayersDrawn(int least, int most) {
    for (int n = std::max(least, 1); n <= most; ++n) pass_.prepareLayers(n);
  }
  int layersDrawn() const { return layersDrawn_ > 0 ? std::min(layersDrawn_, pass_.layerCount()) : pass_.layerCount(); }
  int layerCount() const { return pass_.layerCount(); }
  void enableParts(bool trees, bool layers, bool fins) {
    drawTrees_ = trees, drawLayers_ = layers, drawFins_ = fins;
  }

 private:
  ForestLayer() = default;
  ForestLayerConfig config_;
  lod::ForestMap map_;
  lod::ForestKdTree kd_;
  lod::FinSet fins_;
  lod::NearFade nearFade_;
  lod::FarFade farFade_;
  render::ForestPass pass_;
  std::vector<lod::ForestInstance> instances_, scratch_;
  std::vector<lod::ForestModelRange> modelRanges_;
  std::vector<uint32_t> groups_;
  size_t selected_ = 0, groupsSelected_ = 0;
  ForestLayerStats stats_;
  bool drawTrees_ = true, drawLayers_ = true, drawFins_ = true;
  int layersDrawn_ = 0;
  struct Surfaces final : io::SceneSurfaces {
    lod::ForestRays rays;
    bool intersect(const glm::dvec3& from_m, const glm::dvec3& to_m, io::SurfaceMask mask, io::SurfaceHit& hit,
                   uint32_t* work) const override;
    double top_m() const override { return rays.empty() ? -1e300 : rays.top_m(); }
  };
  Surfaces surfaces_;
  std::vector<lod::TreeMesh> models_;  // for enableQueries()
  float yawJitter_ = 1.0f;
};

}  // namespace ig
