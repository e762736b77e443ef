// The forest pass (paper 004, shared/SEEDS.md section 004): far representation (shell layers
// and fins) and near representation (instanced 3D trees), drawn between Renderer::beginFrame
// and endFrame. It exists only when the scene has a forest (ig/forest_layer.h creates it).
//
// Far, shell layers: the terrain mesh of this frame (Renderer::terrainMeshVertexBuffer(), the
// same vertices the terrain pass draws, so the layers follow the terrain LOD) drawn once per
// layer with instancing; the vertex shader lifts layer i (0 = lowest) by (i + 1) / n * H.
//   colour rgb = 2 * T_i.rgb * Gr.rgb, a = 1 - (1 - T_i.a * Gr.a)^(1 / cos) * farAlpha(d)
// (the paper's a = T.a * Gr.a is the coverage of the slab seen along the layer normal; a ray at
// angle acos(cos) to the terrain normal, cos clamped to >= 0.05, crosses 1 / cos as much of the
// slab: Beer-Lambert. Without it distant forest seen at grazing angles is far too thin.)
// T_i is layer i of the layer texture (a horizontal slice of a forest tile, tiled over the
// ground), Gr the distribution map (rgb tint, a = density, 0 in glades) over the map's extent;
// outside it there is no forest (layers and fins are discarded there, as in a glade).
// Far, fins: two-sided vertical quads of height H on the fin edges (lod/forest_fins.h), only
// the groups selectFinGroups keeps;
//   colour rgb = 2 * S.rgb * Gr.rgb, a = S.a * Gr.a * farAlpha(d) * (1 - |dot(T, V)|)
// S is the fin texture (vertical slices), T the fin's tangent, V the unit view direction.
// Near: per model one instanced draw of the selected trees (lod/forest_kdtree.h: far to near,
// instance alpha nearAlpha(d)); the tree's colour is 2 * albedo * tint.
// Everything is lit by the sun with the terrain normal (and mildly by the model normal for the
// 3D trees, baked the same way into T and S), fogged like the terrain.
// Order: opaque trees (alpha 1, depth written), the fading trees (alpha < 1, blended, depth
// tested only: a tree fading out must not hide the layers fading in behind it), then layers,
// then fins (blended, depth tested only).
// The pass leaves the FBO, viewport, depth test, depth mask and cull state as it found them
// (blending off).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/forest.h"
#include "lod/forest_fins.h"
#include "lod/forest_kdtree.h"
#include "lod/forest_model.h"
#include "lod/terrain_chunks.h"
#include "render/image.h"

namespace ig::render {

class Renderer;

// Offline textures T (layers) and S (fins), rendered from the tree models.
struct ForestTextureDesc {
  int layers = 8;            // n shell layers, 1..32
  int size_px = 256;         // T: size x size per layer; S: size wide per slice
  double tile_m = 24.0;      // side of the square forest tile both textures repeat
  int treesPerTile = 14;     // trees planted in the tile (jittered grid, random model, yaw)
  int finSlices = 4;         // vertical slices in S (fins pick one by position)
  double finSliceDepth_m = 6.0;  // depth of forest each slice shows
  int supersample = 4;       // rendered at size * supersample, box-filtered: alpha = coverage
  uint32_t seed = 5;
};

struct ForestTextures {
  Image layers;          // (size * n) x size: layer i in columns [i * size, (i + 1) * size), top row north
  Image fins;            // (size * slices) x height_px: slice j in columns [j * size, ...), top row = tree top
  int layerCount = 0;
  int finSlices = 0;
  double tile_m = 0.0;
  double height_m = 0.0;  // H: height of the layer stack and of the fins
  // The tree spacing (placement slot) the tile was planted for: the layers stand for a forest of
  // one tree per spacing^2. Set by the caller that chose the density (igtool forest-textures
  // writes it to forest_textures.txt); 0 = unknown (assets written before it was recorded).
  double spacing_m = 0.0;
};

// Renders T and S from `models` with the current GL context (its own FBO; state restored).
// Lower layers are darker (the model shader's height darkening, as on the 3D trees). False with
// `error` for a bad description, no model or more than 256, an invalid model, or models of no
// height (H = 0): it never returns textures that validateForestTextures rejects.
bool renderForestTextures(std::span<const lod::TreeMesh> models, const ForestTextureDesc& desc, ForestTextures& out,
                          std::string& error);

// Checks sizes and metadata of textures read from files; error names the bad value.
bool validateForestTextures(const ForestTextures& t, std::string& error);

struct ForestPassDesc {
  lod::FarFade farFade;
  lod::NearFade nearFade;
  size_t maxInstances = 1u << 17;  // instance buffer size (trees drawn per frame at most)
  float yawJitter = 1.0f;          // per-tree yaw from a hash of the tree index (0: none)
};

struct ForestDrawStats {
  uint64_t trees = 0;
  uint64_t fins = 0;
  uint32_t layers = 0;
  uint64_t triangles = 0;
  uint32_t drawCalls = 0;
};

class ForestPass {
 public:
  ForestPass();
  ~ForestPass();
  ForestPass(const ForestPass&) = delete;
  ForestPass& operator=(const ForestPass&) = delete;

  // Start-up: programs, model buffers, the instance buffer, the Gr texture from `map`, T and S,
  // the fin vertex buffer from `fins` (may be null: no fins). GL context current.
  bool init(const ForestPassDesc& desc, const lod::ForestMap& map, const ForestTextures& textures,
            std::span<const lod::TreeMesh> models, const lod::FinSet* fins, std::string& error);

  // Per frame, between beginFrame and endFrame, in this order (a pass without a successful
  // init draws nothing).
  // Near trees: instances grouped per model (ForestKdTree::select output).
  void drawTrees(Renderer& r, std::span<const lod::ForestInstance> instances,
                 std::span<const lod::ForestModelRange> models);
  // Shell layers over the first `vertexCount` vertices of the terrain mesh buffer (positions
  // relative to `terrainOrigin_m`). `layers` = m of the n = layerCount() slabs of T (clamped to
  // n; 0: none): fewer layers are a coarser forest of the same height and density, not its lower
  // part. Drawn layer j stands for slabs [j n / m, (j + 1) n / m): at the top one's height, with
  // its slice, and as opaque as the group (Beer-Lambert: 1 - (1 - a)^(slabs / cos)); m = n draws
  // every slab as itself. The frame governor's knob for the layers' fill (ForestLayer).
  void drawLayers(Renderer& r, const glm::dvec3& terrainOrigin_m, size_t vertexCount, int layers);
  // The same over ranges of triangle slots (the terrain chunks in view, lod/terrain_chunks.h).
  // Both forms clamp to the terrain mesh buffer (Renderer::terrainMeshVertices()): slots past
  // its end are not drawn.
  void drawLayers(Renderer& r, const glm::dvec3& terrainOrigin_m, std::span<const lod::TerrainDrawRange> ranges,
                  int layers);
  // Fins of the given groups (selectFinGroups output: indices into fins->groups); an index out
  // of range is skipped, a group named more than once is drawn once.
  void drawFins(Renderer& r, std::span<const uint32_t> groups);

  // Makes the composited textures drawLayers needs for `layers` < layerCount() now (else on the
  // first draw with that count: ~10 ms for 256 px and 8 layers on llvmpipe). GL context current.
  void prepareLayers(int layers);
  // Replaces T and S (e.g. another layer count); false with `error` for invalid textures or for
  // another height_m or fin slice count than init's (the fin geometry is made with them).
  bool setTextures(const ForestTextures& textures, std::string& error);

  ForestDrawStats takeStats();
  int layerCount() const;
  uint64_t bufferBytes() const;
  void setFarFade(const lod::FarFade& f);
  void setNearFade(const lod::NearFade& f);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ig::render
