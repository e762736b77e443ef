// Large continuous forests (paper 004, Graphicon 2006; shared/SEEDS.md section 004): the forest
// data shared by the far representation (shell layers and fins) and the near one (3D trees).
//
// - ForestMap: the distribution map over the terrain. Per cell: density in [0, 1] (trees per
//   placement slot), tint Gr.rgb and glade mask Gr.a (0 = glade, no trees, no fins). Generated
//   from a seed or filled from an image by the caller (validateForestMap checks it).
// - placeTrees: deterministic placement from the map over a terrain (same seed, same trees on
//   every machine: integer hashing, no platform RNG). One candidate per jittered grid slot of
//   `spacing_m`, kept with probability density (and never in a glade).
// - Distance fades (the documented fade functions, distances in metres from the eye):
//     far (layers and fins), FarFade {fadeInStart < fadeInEnd <= fadeOut < farPlane}:
//       farAlpha(d) = 0                                   d <= fadeInStart
//                   = (d - fadeInStart) / (fadeInEnd - fadeInStart)   up to fadeInEnd
//                   = 1                                   fadeInEnd <= d <= fadeOut
//                   = (farPlane - d) / (farPlane - fadeOut)           up to farPlane
//                   = 0                                   d >= farPlane
//     near (3D trees), NearFade {fadeOutStart < fadeOutEnd}:
//       nearAlpha(d) = 1 below fadeOutStart, linear down to 0 at fadeOutEnd, 0 beyond.
//   Both are continuous at every band edge (the bands are never empty: validateForestFades
//   rejects equal edges). The near fade-out band must overlap the far fade-in band
//   (fadeOutStart < fadeInEnd and fadeOutEnd > fadeInStart), so 3D trees fade out while the
//   layers fade in; with equal bands the two alphas sum to 1 (a cross-fade).
//   NaN distance gives alpha 0 (nothing drawn).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "lod/terrain_grid.h"

namespace ig::lod {

struct ForestMap {
  int width = 0;                  // cells per row
  int height = 0;                 // rows
  double cell_m = 32.0;           // cell edge
  glm::dvec2 origin_m{0.0, 0.0};  // ENU east/north of the SW corner of cell (0, 0)
  std::vector<float> density;     // width * height, row-major (row = north), in [0, 1]
  std::vector<uint32_t> gr;       // Gr as RGBA8 (r in the low byte); a = 0 marks a glade

  double extentEast_m() const { return width * cell_m; }
  double extentNorth_m() const { return height * cell_m; }
  // Cell under ENU (east, north), clamped into the map; false outside the map or NaN.
  bool cellAt(double east_m, double north_m, int& cx, int& cy) const;
  // Glade at (east, north)? Outside the map counts as a glade (no forest there).
  bool isGlade(double east_m, double north_m) const;
  float densityAt(double east_m, double north_m) const;  // 0 outside
  uint32_t grAt(double east_m, double north_m) const;    // 0 outside
};

struct ForestMapDesc {
  uint32_t seed = 1;
  int width = 240;               // cells
  int height = 240;
  double cell_m = 32.0;
  glm::dvec2 origin_m{0.0, 0.0};
  double gladeFraction = 0.15;  // share of the area in glades (exact up to ties), in [0, 1]
  double featureSize_m = 600.0;  // size of the density / glade blobs
};

// Procedural map: fBm value noise for density and tint, glades where a second noise is lowest.
ForestMap generateForestMap(const ForestMapDesc& desc);

// Checks a map made elsewhere (e.g. from an image): sizes, cell size, finite values in range.
// Returns false and sets `error` naming the bad field and value.
bool validateForestMap(const ForestMap& map, std::string& error);

struct TreeInstance {
  glm::dvec3 base_m{0.0};  // ENU position of the foot of the trunk
  glm::vec3 normal{0.0f, 0.0f, 1.0f};  // terrain normal at the foot (lights the tree)
  uint32_t rgba = 0;       // colour: Gr.rgb tint with a small per-tree variation, a = 255
  uint8_t model = 0;       // index of the 3D model
};

// A regular height field (e.g. a DEM) as the ground for placement: posts row-major (row =
// north), sample (x, y) at origin + (x * spacing, y * spacing, h). heightAt interpolates on the
// two triangles of each quad exactly as lod::makeGridMesh splits it ((x,y)-(x+1,y+1) diagonal),
// so a tree stands on the rendered full-resolution surface; clamps outside, NaN gives origin.z.
struct ForestHeightField {
  std::span<const float> heights_m;
  int width = 0, height = 0;
  double spacing_m = 1.0;
  glm::dvec3 origin_m{0.0};
  double heightAt(double east_m, double north_m) const;
};

struct TreePlacementDesc {
  uint32_t seed = 7;
  double spacing_m = 6.0;   // one candidate per spacing x spacing slot
  double jitter = 0.9;      // candidate offset within its slot, fraction of the slot (0..1)
  int modelCount = 2;       // models are picked uniformly, 1..256
};

// Places trees over the whole map, heights from `terrain` (heightAt, normal by central
// differences). Deterministic for a seed. Clears `out` first. Returns false with `error` for a
// bad description (spacing <= 0 or NaN, jitter outside [0, 1], modelCount outside 1..256) or
// an invalid map.
bool placeTrees(const ForestMap& map, const TerrainGrid& terrain, const TreePlacementDesc& desc,
                std::vector<TreeInstance>& out, std::string& error);
// The same on a height field (a DEM); also fails for a field smaller than 2 x 2 posts or with a
// spacing that is not finite and positive.
bool placeTrees(const ForestMap& map, const ForestHeightField& ground, const TreePlacementDesc& desc,
                std::vector<TreeInstance>& out, std::string& error);

struct FarFade {
  double fadeInStart_m = 400.0;
  double fadeInEnd_m = 600.0;
  double fadeOut_m = 6000.0;
  double farPlane_m = 8000.0;
};
struct NearFade {
  double fadeOutStart_m = 400.0;
  double fadeOutEnd_m = 600.0;
};

double farAlpha(const FarFade& f, double d_m);
double nearAlpha(const NearFade& f, double d_m);
// Checks ordering, finiteness and the overlap rule above; error names the bad value.
bool validateForestFades(const FarFade& far, const NearFade& near, std::string& error);

// Integer hash used for placement (exposed for tests and the procedural map).
uint32_t forestHash(uint32_t a, uint32_t b, uint32_t c);

}  // namespace ig::lod
