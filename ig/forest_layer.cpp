// The forest layer (paper 004, shared/SEEDS.md section 004). See forest_layer.h.
#include "ig/forest_layer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

#include "ig/forest_tool.h"
#include "ig/scene_surfaces.h"
#include "render/image.h"
#include "render/renderer.h"

namespace ig {
namespace {

bool loadMapPng(const std::string& file, double cell_m, const glm::dvec2& origin, lod::ForestMap& map,
                std::string& error) {
  render::Image img;
  if (!render::readPng(file, img, error)) {
    error = "forest.map: " + error;
    return false;
  }
  map = {};
  map.width = img.width;
  map.height = img.height;
  map.cell_m = cell_m;
  map.origin_m = origin;
  const size_t n = static_cast<size_t>(img.width) * static_cast<size_t>(img.height);
  map.density.resize(n);
  map.gr.resize(n);
  for (int y = 0; y < img.height; ++y) {
    for (int x = 0; x < img.width; ++x) {
      const uint8_t* p = img.rgba.data() + (static_cast<size_t>(img.height - 1 - y) * static_cast<size_t>(img.width) +
                                            static_cast<size_t>(x)) * 4;
      const size_t i = static_cast<size_t>(y) * static_cast<size_t>(img.width) + static_cast<size_t>(x);
      map.density[i] = static_cast<float>(p[3]) / 255.0f;
      map.gr[i] = p[0] | static_cast<uint32_t>(p[1]) << 8 | static_cast<uint32_t>(p[2]) << 16 | (p[3] ? 255u : 0u) << 24;
    }
  }
  if (!lod::validateForestMap(map, error)) {
    error = "forest.map '" + file + "': " + error;
    return false;
  }
  return true;
}

// Cuts `map` to its first cellsX x cellsY cells from the SW corner (row 0 is the south row).
// An image larger than the forest area would plant trees beyond the area, which is clipped to
// the terrain: there they stood on the height field's clamped edge, off the terrain.
void cropMap(lod::ForestMap& map, int cellsX, int cellsY) {
  const int w = std::clamp(cellsX, 1, map.width), h = std::clamp(cellsY, 1, map.height);
  if (w == map.width && h == map.height) return;
  std::vector<float> density(static_cast<size_t>(w) * static_cast<size_t>(h));
  std::vector<uint32_t> gr(density.size());
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const size_t from = static_cast<size_t>(y) * static_cast<size_t>(map.width) + static_cast<size_t>(x);
      const size_t to = static_cast<size_t>(y) * static_cast<size_t>(w) + static_cast<size_t>(x);
      density[to] = map.density[from];
      gr[to] = map.gr[from];
    }
  map.width = w;
  map.height = h;
  map.density = std::move(density);
  map.gr = std::move(gr);
}

}  // namespace

ForestLayer::~ForestLayer() = default;

std::unique_ptr<ForestLayer> ForestLayer::create(const ForestLayerConfig& c, const ForestGround& g, std::string& error,
                                                 const std::vector<lod::TreeMesh>* modelsIn,
                                                 const render::ForestTextures* texturesIn) {
  std::unique_ptr<ForestLayer> layer(new ForestLayer());
  ForestLayer& f = *layer;
  f.config_ = c;
  if (g.width < 2 || g.height < 2 || g.heights_m.size() < static_cast<size_t>(g.width) * static_cast<size_t>(g.height) ||
      !(g.spacing_m > 0.0)) {
    error = "forest: the terrain height field (" + std::to_string(g.width) + " x " + std::to_string(g.height) +
            ") is too small for a forest";
    return nullptr;
  }
  // Area: the config's, clipped to the terrain.
  const double tx0 = g.origin_m.x, ty0 = g.origin_m.y;
  const double tx1 = tx0 + (g.width - 1) * g.spacing_m, ty1 = ty0 + (g.height - 1) * g.spacing_m;
  std::array<double, 4> a = c.area_m;
  if (a == std::array<double, 4>{0, 0, 0, 0}) a = {tx0, ty0, tx1, ty1};
  for (double v : a) {
    if (!std::isfinite(v)) {
      error = "forest.area_m: a value is not finite";
      return nullptr;
    }
  }
  a = {std::max(a[0], tx0), std::max(a[1], ty0), std::min(a[2], tx1), std::min(a[3], ty1)};
  if (!(a[2] - a[0] >= c.cell_m && a[3] - a[1] >= c.cell_m)) {
    error = "forest.area_m = [" + std::to_string(c.area_m[0]) + ", " + std::to_string(c.area_m[1]) + ", " +
            std::to_string(c.area_m[2]) + ", " + std::to_string(c.area_m[3]) +
            "]: less than one map cell inside the terrain";
    return nullptr;
  }
  if (!(c.spacing_m > 0.0) || (a[2] - a[0]) * (a[3] - a[1]) / (c.spacing_m * c.spacing_m) > 2e8) {
    error = "forest.spacing_m = " + std::to_string(c.spacing_m) + ": must be > 0 and give at most 2e8 slots over the " +
            std::to_string((a[2] - a[0]) * (a[3] - a[1]) / 1e6) + " km2 forest area (set forest.area_m)";
    return nullptr;
  }
  if (c.maxTrees < 1 || c.maxTrees > (1 << 22)) {
    error = "forest.max_trees = " + std::to_string(c.maxTrees) + ": outside 1..4194304";
    return nullptr;
  }

  // Map. Gr is one GL texture: at most kMaxMapSide cells a side (GL 4.5's least
  // GL_MAX_TEXTURE_SIZE), checked before a generated map is allocated.
  constexpr int kMaxMapSide = 16384;
  const double cellsX = std::floor((a[2] - a[0]) / c.cell_m), cellsY = std::floor((a[3] - a[1]) / c.cell_m);
  if (c.map.empty() && !(cellsX <= kMaxMapSide && cellsY <= kMaxMapSide)) {
    error = "forest.cell_m = " + std::to_string(c.cell_m) + ": the forest map would be " + std::to_string(cellsX) +
            " x " + std::to_string(cellsY) + " cells, more than " + std::to_string(kMaxMapSide) +
            " a side (raise forest.cell_m or set forest.area_m)";
    return nullptr;
  }
  if (c.map.empty()) {
    lod::ForestMapDesc md;
    md.seed = c.seed;
    md.cell_m = c.cell_m;
    md.width = static_cast<int>((a[2] - a[0]) / c.cell_m);
    md.height = static_cast<int>((a[3] - a[1]) / c.cell_m);
    md.origin_m = {a[0], a[1]};
    md.gladeFraction = c.gladeFraction;
    md.featureSize_m = c.featureSize_m;
    f.map_ = lod::generateForestMap(md);
    if (!lod::validateForestMap(f.map_, error)) return nullptr;
  } else {
    if (!loadMapPng(c.map, c.cell_m, {a[0], a[1]}, f.map_, error)) return nullptr;
    // The image's cells beyond the area (east, north) are not the forest's: cut to the area's
    // whole cells, as many as a generated map has (at least one: checked above).
    cropMap(f.map_, static_cast<int>(std::min(cellsX, 2.0e9)), static_cast<int>(std::min(cellsY, 2.0e9)));
    if (f.map_.width > kMaxMapSide || f.map_.height > kMaxMapSide) {
      error = "forest.map '" + c.map + "': " + std::to_string(f.map_.width) + " x " + std::to_string(f.map_.height) +
              " pixels, more than " + std::to_string(kMaxMapSide) + " a side";
      return nullptr;
    }
  }

  // Models and textures.
  std::vector<lod::TreeMesh> models;
  render::ForestTextures textures;
  if (modelsIn && !modelsIn->empty()) models = *modelsIn;
  if (texturesIn) textures = *texturesIn;
  if (!c.assets.empty() && (models.empty() || !texturesIn)) {
    std::vector<lod::TreeMesh> m;
    render::ForestTextures t;
    if (!readForestAssets(c.assets, m, t, error)) {
      error = "forest.assets: " + error;
      return nullptr;
    }
    if (models.empty()) models = std::move(m);
    if (!texturesIn) {
      // The layers stand for the density they were baked for: assets of another spacing would
      // draw a forest of the wrong density far away, silently (a training defect), so they are
      // refused at start-up. Assets that do not record it (older igtool) are used with a warning.
      const std::string meta = c.assets + "/forest_textures.txt";
      if (t.spacing_m == 0.0)
        std::fprintf(stderr,
                     "forest.assets '%s': warning: no spacing_m recorded (written by an older igtool "
                     "forest-textures): the layers may not match forest.spacing_m = %g m; rebake with igtool "
                     "forest-textures --spacing %g\n",
                     meta.c_str(), c.spacing_m, c.spacing_m);
      error = forestTexturesSpacingMismatch(t, c.spacing_m, "forest.assets '" + meta + "'");
      if (!error.empty()) return nullptr;
      textures = std::move(t);
    }
  }
  if (texturesIn) {
    error = forestTexturesSpacingMismatch(textures, c.spacing_m, "forest textures");
    if (!error.empty()) return nullptr;
  }
  if (models.empty()) models = proceduralTrees();
  if (textures.layerCount == 0) {
    // The tile holds tile^2 / spacing^2 trees (the forest at full density): at least 16, so that
    // a sparse forest's layers are as sparse as its trees (a 24 m tile holds at least one tree:
    // beyond 34 m spacing the layers stood for a denser forest than the one planted).
    const render::ForestTextureDesc td = forestTextureDesc(c.spacing_m, c.layers);
    if (!render::renderForestTextures(models, td, textures, error)) return nullptr;
    textures.spacing_m = c.spacing_m;
  }

  // Trees and kd-tree.
  lod::TreePlacementDesc pd;
  pd.seed = c.seed + 6;
  pd.spacing_m = c.spacing_m;
  pd.modelCount = static_cast<int>(models.size());
  lod::ForestHeightField hf{g.heights_m, g.width, g.height, g.spacing_m, g.origin_m};
  std::vector<lod::TreeInstance> trees;
  if (!lod::placeTrees(f.map_, hf, pd, trees, error)) return nullptr;
  lod::ForestKdParams kp;
  kp.leafSize_m = c.leafSize_m;
  kp.modelCount = pd.modelCount;
  float h = 0.0f, r = 0.0f;
  for (const lod::TreeMesh& m : models) h = std::max(h, m.height_m), r = std::max(r, m.radius_m);
  kp.treeHeight_m = 1.1 * static_cast<double>(h);  // the largest per-tree scale
  kp.crownRadius_m = 1.1 * static_cast<double>(r);
  if (!f.kd_.build(trees, kp, error)) return nullptr;
  f.stats_.trees = trees.size();
  trees = {};

  // Fins on the terrain posts covering the area.
  if (c.fins) {
    const int x0 = std::max(0, static_cast<int>(std::floor((a[0] - tx0) / g.spacing_m)));
    const int y0 = std::max(0, static_cast<int>(std::floor((a[1] - ty0) / g.spacing_m)));
    const int x1 = std::min(g.width - 1, static_cast<int>(std::ceil((a[2] - tx0) / g.spacing_m)));
    const int y1 = std::min(g.height - 1, static_cast<int>(std::ceil((a[3] - ty0) / g.spacing_m)));
    const int w = x1 - x0 + 1, hh = y1 - y0 + 1;
    std::vector<float> sub(static_cast<size_t>(w) * static_cast<size_t>(hh));
    for (int y = 0; y < hh; ++y)
      for (int x = 0; x < w; ++x)
        sub[static_cast<size_t>(y) * static_cast<size_t>(w) + static_cast<size_t>(x)] =
            g.heights_m[static_cast<size_t>(y0 + y) * static_cast<size_t>(g.width) + static_cast<size_t>(x0 + x)];
    std::vector<glm::dvec3> pos;
    std::vector<uint32_t> tri;
    lod::makeGridMesh(sub, w, hh, g.spacing_m, g.origin_m + glm::dvec3(x0 * g.spacing_m, y0 * g.spacing_m, 0.0), pos, tri);
    lod::FinParams fp;
    fp.criticalAngle_deg = c.criticalAngle_deg;
    fp.finHeight_m = textures.height_m;
    if (!lod::buildFins(pos, tri, &f.map_, fp, f.fins_, error)) {
      error = "forest fins: " + error;
      return nullptr;
    }
    f.stats_.fins = f.fins_.fins.size();
  }

  f.nearFade_ = {c.nearFadeStart_m, c.nearFadeEnd_m};
  f.farFade_ = {c.nearFadeStart_m, c.nearFadeEnd_m, c.fadeOut_m, c.farPlane_m};
  if (!lod::validateForestFades(f.farFade_, f.nearFade_, error)) {
    error = "forest fades: " + error;
    return nullptr;
  }
  render::ForestPassDesc pdesc;
  pdesc.farFade = f.farFade_;
  pdesc.nearFade = f.nearFade_;
  pdesc.maxInstances = static_cast<size_t>(c.maxTrees);
  if (!f.pass_.init(pdesc, f.map_, textures, models, c.fins ? &f.fins_ : nullptr, error)) return nullptr;
  f.yawJitter_ = pdesc.yawJitter;
  f.instances_.resize(static_cast<size_t>(c.maxTrees));
  f.scratch_.resize(static_cast<size_t>(c.maxTrees));
  f.modelRanges_.resize(models.size());
  f.models_ = std::move(models);  // for enableQueries()
  f.groups_.resize(f.fins_.groups.size());
  f.stats_.layers = f.pass_.layerCount();
  return layer;
}

void ForestLayer::enableQueries(bool enable) {
  if (enable && surfaces_.rays.empty()) surfaces_.rays = lod::ForestRays(kd_, models_, yawJitter_);
  models_ = {};
}

bool ForestLayer::Surfaces::intersect(const glm::dvec3& from_m, const glm::dvec3& to_m, io::SurfaceMask mask,
                                      io::SurfaceHit& hit, uint32_t* work) const {
  if (!(mask & io::surfaceBit(io::kSurfaceTree))) return false;
  lod::TreeHit h;
  lod::RayWork w;
  const bool found = rays.intersect(from_m, to_m, h, &w);
  return toSurfaceHit(found, h, w, io::kSurfaceTree, hit, work);
}

bool ForestLayer::setFades(const lod::NearFade& nearFade, const lod::FarFade& farFade, std::string& error) {
  if (!lod::validateForestFades(farFade, nearFade, error)) return false;
  nearFade_ = nearFade;
  farFade_ = farFade;
  pass_.setNearFade(nearFade);
  pass_.setFarFade(farFade);
  return true;
}

void ForestLayer::setLayersDrawn(int layers) { layersDrawn_ = std::max(layers, 0); }

bool ForestLayer::setNearDistance(double end_m) {
  if (end_m == nearFade_.fadeOutEnd_m) return true;
  const double k = end_m / config_.nearFadeEnd_m;
  if (!(std::isfinite(k) && k > 0.0)) return false;
  const lod::NearFade n{config_.nearFadeStart_m * k, config_.nearFadeEnd_m * k};
  const lod::FarFade f{n.fadeOutStart_m, n.fadeOutEnd_m, farFade_.fadeOut_m, farFade_.farPlane_m};
  std::string error;
  return setFades(n, f, error);
}

void ForestLayer::select(const lod::Camera& cam) {
  lod::ForestSelectStats st;
  selected_ = drawTrees_ ? kd_.select(cam, nearFade_, instances_, scratch_, modelRanges_, &st) : 0;
  if (!drawTrees_) std::fill(modelRanges_.begin(), modelRanges_.end(), lod::ForestModelRange{});
  lod::FinSelectStats fs;
  groupsSelected_ = drawFins_ && !groups_.empty()
                        ? lod::selectFinGroups(fins_.groups, cam, farFade_, config_.finAlphaThreshold, groups_, &fs)
                        : 0;
  stats_.treesDrawn = static_cast<uint32_t>(selected_);
  stats_.treesDropped = st.dropped;
  stats_.finsDrawn = groupsSelected_ ? fs.finsDrawn : 0;
  stats_.finGroupsDrawn = static_cast<uint32_t>(groupsSelected_);
}

void ForestLayer::draw(render::Renderer& r, const glm::dvec3& terrainOrigin_m, size_t terrainVertexCount) {
  const lod::TerrainDrawRange all{0, static_cast<uint32_t>(terrainVertexCount / 3)};
  draw(r, terrainOrigin_m, std::span(&all, terrainVertexCount >= 3 ? 1 : 0));
}

void ForestLayer::draw(render::Renderer& r, const glm::dvec3& terrainOrigin_m,
                       std::span<const lod::TerrainDrawRange> terrainRanges) {
  if (drawTrees_) pass_.drawTrees(r, selectedTrees(), modelRanges_);
  if (drawLayers_) pass_.drawLayers(r, terrainOrigin_m, terrainRanges, layersDrawn());
  if (drawFins_) pass_.drawFins(r, std::span(groups_.data(), groupsSelected_));
  stats_.layers = drawLayers_ ? layersDrawn() : 0;
  pass_.takeStats();
}

}  // namespace ig
