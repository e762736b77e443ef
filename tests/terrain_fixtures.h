// Shared by the terrain tests (roam_test, terrain_chunks_test): a procedural DEM and a ROAM
// view with the usual test camera (60 deg vertical field of view, 16:9, near 1 m, far 100 km).
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/heightfield.h"
#include "lod/roam.h"

namespace ig::lod::test {

// Mountainous fractal heights, w x h samples, rows south first.
inline std::vector<float> fractalHeights(int w, int h, uint32_t seed, double scale_m = 400.0, double spacing_m = 30.0) {
  HeightfieldDesc d;
  d.seed = seed;
  d.postsX = w;
  d.postsY = h;
  d.postSpacing_m = spacing_m;
  d.heightScale_m = scale_m;
  std::vector<float> hts(static_cast<size_t>(w) * static_cast<size_t>(h));
  generateHeightfield(d, hts);
  return hts;
}

inline RoamView terrainView(const glm::dvec3& eye, double heading_deg, double pitch_deg, double tolerance_px,
                            double viewportHeight_px) {
  RoamView v;
  v.camera.eye_m = eye;
  v.camera.heading_deg = heading_deg;
  v.camera.pitch_deg = pitch_deg;
  v.camera.fovY_deg = 60.0;
  v.camera.aspect = 16.0 / 9.0;
  v.camera.near_m = 1.0;
  v.camera.far_m = 100000.0;
  v.viewportHeight_px = viewportHeight_px;
  v.tolerance_px = tolerance_px;
  return v;
}

}  // namespace ig::lod::test
