// Shared by the dynamic octree's tests (perfmodel_test, dynamic_octree_mutation_test): a cube
// box, the 256 m root cube at the origin, and a wide camera.
#pragma once

#include <cstdint>

#include <glm/vec3.hpp>

#include "lod/dynamic_octree.h"
#include "lod/view.h"

namespace ig::lod::test {

// The box of half edge h around c.
inline Aabb cube(glm::dvec3 c, double h) { return {c - glm::dvec3(h), c + glm::dvec3(h)}; }

// A 256 m root cube at the origin, up to 2,000 objects.
inline OctreeConfig octreeConfig(uint32_t maxDepth, uint32_t occlusionMaxAge) {
  OctreeConfig c;
  c.bounds = cube(glm::dvec3(0.0), 128.0);
  c.maxDepth = maxDepth;
  c.maxObjects = 2000;
  c.occlusionMaxAge = occlusionMaxAge;
  return c;
}

// At the origin looking north (+y), 90 deg vertical field of view, 16:9.
inline Camera wideCamera() {
  Camera cam;
  cam.aspect = 16.0 / 9.0;
  cam.fovY_deg = 90.0;
  return cam;
}

}  // namespace ig::lod::test
