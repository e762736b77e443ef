// Procedural height field from a fixed seed: fractal value noise (fBm) sampled on integer
// grid posts. The same seed gives the same heights on every machine (integer hashing, no
// platform RNG), and heights depend only on the post index, never on where the terrain is
// placed, so a terrain moved 1,000 km renders the same.
#pragma once

#include <cstdint>
#include <span>

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

}  // namespace ig::lod
