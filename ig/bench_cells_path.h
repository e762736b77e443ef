// The camera path of igbench cells (ig/bench_cells.cpp), shared with scripts/cells-ab: a slow
// fly-through of the 1,024 m cube, a turn, a teleport to the far corner at 2/3 of the frames, on.
// `static`: scripts/cells-ab compiles this header into two sides whose lod::Camera are different
// types (one side's lod/ is renamed), so each translation unit keeps its own copy.
#pragma once

#include <cmath>

#include "lod/view.h"

namespace ig {

[[maybe_unused]] static lod::Camera cellsPathCamera(int i, int frames) {
  lod::Camera cam;
  cam.fovY_deg = 60.0;
  cam.aspect = 16.0 / 9.0;
  cam.near_m = 0.5;
  cam.far_m = 5000.0;
  const double t = i / 60.0;
  if (i < 2 * frames / 3) {
    cam.eye_m = {200.0 + 40.0 * t, 150.0 + 25.0 * t, 400.0 + 5.0 * std::sin(t)};
    cam.heading_deg = 30.0 + 20.0 * std::sin(0.3 * t);
    cam.pitch_deg = -5.0;
  } else {
    const double s = t - 2.0 * frames / 3 / 60.0;
    cam.eye_m = {900.0 - 30.0 * s, 950.0 - 20.0 * s, 700.0};
    cam.heading_deg = 225.0;
    cam.pitch_deg = -15.0;
  }
  return cam;
}

}  // namespace ig
