// Procedural height field from a fixed seed: fractal value noise (fBm) sampled on integer
// grid posts. The same seed gives the same heights on every machine (integer hashing, no
// platform RNG), and heights depend only on the post index, never on where the terrain is
// placed, so a terrain moved 1,000 km renders the same.
#pragma once

#include <cstdint>
#include <span>

#include <glm/vec3.hpp>

namespace ig::lod {

struct HeightfieldDesc {
  uint32_t seed = 1;
  int postsX = 257;            // posts per row (quads + 1)
  int postsY = 257;
  double postSpacing_m = 32.0;
  double heightScale_m = 400.0;  // output heights lie in [0, heightScale_m]
};

// Fills heights_m (postsX * postsY, row-major, row = y) and returns the number written.
// Requires heights_m.size() >= postsX * postsY.
size_t generateHeightfield(const HeightfieldDesc& desc, std::span<float> heights_m);

// The terrain's full-resolution heights as the renderer draws them (the DEM or the procedural
// posts, not a LOD mesh): post (x, y) lies at ENU origin_m + (x * spacing_m, y * spacing_m,
// heights_m[y * width + x]); rows grow northwards. A view: the caller owns the heights.
struct HeightGrid {
  std::span<const float> heights_m;
  int width = 0, height = 0;   // posts per row / per column
  double spacing_m = 1.0;
  glm::dvec3 origin_m{0.0};    // ENU of post (0, 0); its z is added to every height
};

struct GroundSample {
  double height_m = 0.0;             // ENU up of the surface
  glm::dvec3 normal{0.0, 0.0, 1.0};  // unit normal of the surface, ENU
};

// Height at ENU (east, north) by bilinear interpolation between the four posts around it, and
// the normal of that bilinear surface there. Returns false (out untouched) for a point outside
// the grid (beyond the outer posts, or NaN) or a grid smaller than 2 x 2 posts. O(1), no
// allocation.
bool sampleGround(const HeightGrid& grid, double east_m, double north_m, GroundSample& out);

}  // namespace ig::lod
