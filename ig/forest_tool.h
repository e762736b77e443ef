// igtool forest-textures and the forest's asset files (paper 004, shared/SEEDS.md section 004).
//
// Source models: Wavefront OBJ (y up, centimetres, as in Sweet Home 3D's libraries: Scopia's
// pine and cypress in Debian's sweethome3d-furniture, CC-BY; scripts/fetch-forest extracts
// them). A material whose name contains "trunk" or "bark" (any case) gets bark colour, every
// other material foliage colour (the models' textures are JPEG, which igd does not decode).
// Faces with more than three vertices are fanned.
//
// igtool forest-textures writes into the output folder (the [forest] assets folder):
//   <model>.obj          the near LOD (meshoptimizer sloppy simplification to --triangles),
//                        z up, metres, foot at the origin, vertex colours ("v x y z r g b")
//   layers.png           T: n square horizontal slices side by side (lower layers darker)
//   fins.png             S: vertical slices side by side (top row = tree top)
//   forest_textures.txt  "layers N", "fin_slices N", "tile_m X", "height_m X", "spacing_m X" (the
//                        tree spacing the tile was planted for; files without it, written before
//                        it was recorded, read as 0 = unknown), "models a b"
// The textures are rendered from the high LOD (--bake-triangles) with render/forest_pass.h.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "lod/forest_model.h"
#include "render/forest_pass.h"

namespace ig {

struct TreeObjOptions {
  double height_m = 18.0;       // scaled to this height
  double radius_m = 0.0;        // crown radius; 0 = keep proportions
  uint8_t foliage[3] = {52, 86, 44};
  uint8_t bark[3] = {96, 70, 48};
};

// Reads an OBJ (source model or one written by writeTreeObj: vertex colours win over
// materials). `sourceUnits`: true for y-up centimetre source files (converted to z-up metres,
// recentred on the trunk foot and scaled by `o`); false for our own files (read as is).
bool loadTreeObj(const std::string& file, bool sourceUnits, const TreeObjOptions& o, lod::TreeMesh& out,
                 std::string& error);
bool writeTreeObj(const std::string& file, const lod::TreeMesh& mesh, std::string& error);

// Simplifies to about `targetTriangles` (meshoptimizer: simplify, then sloppy if still above),
// optimises for the vertex cache and fetch. A mesh already small enough is copied.
lod::TreeMesh simplifyTree(const lod::TreeMesh& mesh, size_t targetTriangles);

// The forest assets folder (see above). The reader refuses a spacing_m that is not a finite
// number >= 0, naming the file.
bool writeForestAssets(const std::string& dir, const std::vector<lod::TreeMesh>& models,
                       const render::ForestTextures& textures, std::string& error);
bool readForestAssets(const std::string& dir, std::vector<lod::TreeMesh>& models, render::ForestTextures& textures,
                      std::string& error);

// The two Scopia models (pine, cypress) from `sourceDir` (scripts/fetch-forest's
// data/forest/src), simplified to `triangles` (0 = full), or false with an error naming the
// missing file.
bool loadScopiaTrees(const std::string& sourceDir, size_t triangles, std::vector<lod::TreeMesh>& out,
                     std::string& error);
// Procedural pine and cypress (lod/forest_model.h), the fallback.
std::vector<lod::TreeMesh> proceduralTrees();

struct ForestTexturesOptions {
  std::string source = "data/forest/src";  // scripts/fetch-forest output
  std::string out = "data/forest";
  int layers = 8;
  int size_px = 256;
  double tile_m = 0.0;          // forest tile side; 0: the larger of 24 m and 4 spacing_m (>= 16 trees)
  double spacing_m = 6.0;       // forest placement slot: the tile gets tile^2 / spacing^2 trees
  int triangles = 300;          // near LOD per model
  int bakeTriangles = 20000;    // LOD the textures are rendered from
  bool procedural = false;      // use the procedural models (no download needed)
};

// The tile side forest-textures bakes on: tile_m, or when that is 0 the larger of 24 m and
// 4 spacing_m (as igd's start-up textures), so that the tile holds at least 16 trees.
double forestTextureTile_m(const ForestTexturesOptions& options);

// The bake of a forest of `spacing_m` slots (> 0): `tile_m` (0: the larger of 24 m and
// 4 spacing_m, >= 16 trees) planted with round(tile^2 / spacing^2) trees, at least one. igd's
// start-up textures, igtool forest-textures and igbench forest all bake with it, so that their
// layers stand for the density of the trees planted (a 24 m tile at 40 m spacing got one tree:
// layers 2.8x too dense).
render::ForestTextureDesc forestTextureDesc(double spacing_m, int layers, double tile_m = 0.0);

// How forest textures baked for `textures.spacing_m` fit a forest of `spacing_m`: "" when they
// match within 10 % (the layers' density within ~20 %) or the textures' spacing is unknown (0),
// else the refusal, naming `source`, both spacings and the config key forest.spacing_m.
std::string forestTexturesSpacingMismatch(const render::ForestTextures& textures, double spacing_m,
                                          const std::string& source);

// igtool forest-textures: 0 on success, 1 on failure (message on stderr), 2 bad options. The
// tile is planted with round(tile^2 / spacing^2) trees (at least one); a tile whose count
// misstates the density 1 / spacing^2 by more than 10 % (a 24 m tile at 40 m spacing planted
// one tree: layers 2.8x too dense) is refused, naming --tile and --spacing.
int runForestTextures(const ForestTexturesOptions& options);

}  // namespace ig
