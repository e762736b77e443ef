// Shared by the performance model's tests (perfmodel_test, perfmodel_mutation_test): hand-made
// calibration constants whose terms are easy to add up by hand.
#pragma once

#include <array>

#include <glm/vec3.hpp>

#include "lod/perfmodel.h"

namespace ig::lod::test {

// T_tri 10, T_frag 1, T_z 0.5, T_state 100, t_c 1,000, t_r 50, t_s 500, T_cull 20, T_vis 3,000 ns,
// 10,000 ns per frame, the stages overlapping fully (the paper's max()).
inline PerfConstants handConstants() {
  PerfConstants c;
  c.frame_ns = 10000;
  c.tri_ns = 10;
  c.frag_ns = 1;
  c.depthFrag_ns = 0.5;
  c.state_ns = 100;
  c.command_ns = 1000;
  c.rerecord_ns = 50;
  c.submit_ns = 500;
  c.cull_ns = 20;
  c.occlusionTest_ns = 3000;
  c.overlap = 1.0;
  return c;
}

// The 8 corners of the box with centre c and half extents h (for projectedBoxArea_px).
inline std::array<glm::dvec3, 8> boxCorners(glm::dvec3 c, glm::dvec3 h) {
  std::array<glm::dvec3, 8> p;
  for (int i = 0; i < 8; ++i)
    p[static_cast<size_t>(i)] = c + glm::dvec3((i & 1) ? h.x : -h.x, (i & 2) ? h.y : -h.y, (i & 4) ? h.z : -h.z);
  return p;
}

}  // namespace ig::lod::test
