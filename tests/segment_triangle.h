// The tests' brute force for segment queries (lod/hdlod_rays, lod/forest_rays): where the segment
// from -> to meets the triangle v0 v1 v2, by Cramer's rule on from + t (to - from) = v0 + u (v1 - v0)
// + w (v2 - v0), independent of the Moller-Trumbore test the library uses.
#pragma once

#include <cmath>

#include <glm/glm.hpp>

namespace ig::test {

// t in [0, 1] of the hit (edges included, to 1e-12), or false.
inline bool segmentTriangle(const glm::dvec3& from, const glm::dvec3& to, const glm::dvec3& v0, const glm::dvec3& v1,
                            const glm::dvec3& v2, double& t) {
  const glm::dvec3 d = to - from, e1 = v1 - v0, e2 = v2 - v0, r = from - v0;
  const glm::dmat3 a(-d, e1, e2);
  if (std::abs(glm::determinant(a)) < 1e-12) return false;
  const glm::dvec3 x = glm::inverse(a) * r;  // (t, u, w)
  if (!(x.x >= 0.0 && x.x <= 1.0 && x.y >= -1e-12 && x.z >= -1e-12 && x.y + x.z <= 1.0 + 1e-12)) return false;
  t = x.x;
  return true;
}

}  // namespace ig::test
