// Shared by the HDLOD selection tests (hdlod_tree_test, hdlod_select_mutation_test): an object
// standing still at a position, and a view looking north at a target.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/hdlod_scene.h"
#include "lod/hdlod_select.h"

namespace ig::lod::hdlod::test {

// An object of `model` at `pos` (heading 0), present on `visible`.
inline Object placed(const std::string& name, uint32_t model, glm::dvec3 pos, std::vector<Interval> visible) {
  Object o;
  o.name = name;
  o.model = model;
  o.path.push_back({0.0, pos, 0.0});
  o.visible = std::move(visible);
  return o;
}

// Looks north at `target` from `distance` south of it, level; 60 deg, square, near 0.1 m,
// far 1e7 m; schedule time t, tolerance r (radians).
inline SelectView viewOf(glm::dvec3 target, double distance, double t, double r) {
  SelectView v;
  v.camera.eye_m = target - glm::dvec3(0, distance, 0);
  v.camera.fovY_deg = 60;
  v.camera.aspect = 1.0;
  v.camera.near_m = 0.1;
  v.camera.far_m = 1e7;
  v.time_s = t;
  v.tolerance_rad = r;
  return v;
}

}  // namespace ig::lod::hdlod::test
