// Shared by the forest's fin tests (forest_fins_test, forest_mutation_test).
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/forest_fins.h"
#include "lod/heightfield.h"

namespace ig::lod::test {

// An n x n grid of the default fractal relief, 32 m between posts, at the origin, as the mesh the
// fins are built from.
inline void finGridMesh(int n, std::vector<glm::dvec3>& pos, std::vector<uint32_t>& tri) {
  HeightfieldDesc hd;
  hd.postsX = hd.postsY = n;
  hd.postSpacing_m = 32.0;
  std::vector<float> h(static_cast<size_t>(n) * static_cast<size_t>(n));
  generateHeightfield(hd, h);
  makeGridMesh(h, n, n, 32.0, {0, 0, 0}, pos, tri);
}

}  // namespace ig::lod::test
