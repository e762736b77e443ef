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

struct GroundHit {
  double t = 0.0;                    // along the segment: 0 at `from`, 1 at `to`
  glm::dvec3 point_m{0.0};           // ENU; z is sampleGround's height there
  glm::dvec3 normal{0.0, 0.0, 1.0};  // sampleGround's normal there
};

// The first point of the segment from -> to (ENU metres) on or below the surface sampleGround
// reports (the bilinear patches of the grid; outside the grid there is no surface). Exact: walks
// the cells the segment's ground track crosses (2D DDA) and solves the segment against each
// cell's bilinear patch (height along the segment is quadratic in t). A segment that starts on or
// below the surface hits at its start (t = 0, or where it enters the grid); a zero-length one
// hits only there. Returns false (out untouched) for no hit, a non-finite point or a grid
// sampleGround refuses. O(cells crossed) <= width + height, no allocation. `cellsVisited` (if
// given) gets the number of cells examined, the call's cost, whatever the result.
bool intersectGround(const HeightGrid& grid, const glm::dvec3& from, const glm::dvec3& to, GroundHit& out,
                     uint32_t* cellsVisited = nullptr);

}  // namespace ig::lod
