// Camera-relative placement far from an origin: origin - eye in double, sent to a shader as a
// float and the float of what that float left out. The shader adds them as
//   precise vec3 rel = (aPosition + high) + low;
// so that a mesh whose vertices lie far from their origin (a DEM tile's are up to ~100 km from
// its south-west post) is placed to a fraction of a millimetre, not in the float's steps of the
// offset (7.8 mm at 120 km), which jump as the eye moves.
#pragma once

#include <glm/vec3.hpp>

namespace ig::render {

struct SplitOffset {
  glm::vec3 high{0.0f};  // d rounded to a float
  glm::vec3 low{0.0f};   // d - high, rounded to a float
};

// The float part is d rounded to 24 significant bits in double (Veltkamp's split), so it
// converts to float exactly: GCC 12 at -O3 folds the obvious d - double(float(d)) of a vector
// to 0.
inline SplitOffset splitOffset(const glm::dvec3& d) {
  const glm::dvec3 c = d * 536870913.0;  // 2^29 + 1: keeps 53 - 29 = 24 bits
  const glm::dvec3 high = c - (c - d);
  return {glm::vec3(high), glm::vec3(d - high)};
}

}  // namespace ig::render
