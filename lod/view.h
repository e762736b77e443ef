// View maths shared by every layer: camera attitude, reverse-Z projection, view frustum and
// bounding boxes, all in double on the CPU. Rendering is camera-relative: the GPU only ever
// sees (position - eye) in float, so precision does not depend on distance from the origin.
//
// Frames: world = local ENU (x east, y north, z up). Camera space = OpenGL eye space
// (x right, y up, looking down -z). Heading is clockwise from north, pitch nose-up positive,
// roll right-wing-down positive (aerospace convention, as CIGI).
#pragma once

#include <array>

#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

namespace ig::lod {

struct Aabb {
  glm::dvec3 min{0.0};
  glm::dvec3 max{0.0};
  bool contains(const glm::dvec3& p) const {
    return p.x >= min.x && p.y >= min.y && p.z >= min.z && p.x <= max.x && p.y <= max.y && p.z <= max.z;
  }
};

struct Camera {
  glm::dvec3 eye_m{0.0};     // ENU
  double heading_deg = 0.0;
  double pitch_deg = 0.0;
  double roll_deg = 0.0;
  double fovY_deg = 45.0;    // vertical field of view
  double aspect = 16.0 / 9.0;  // width / height
  double near_m = 0.1;
  double far_m = 100000.0;
};

// Rotation taking world (ENU) directions to camera-space directions.
glm::dmat3 viewRotation(const Camera& cam);
// Reverse-Z projection for glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE): depth 1 at near,
// 0 at far; use a float depth buffer cleared to 0 with depth test GL_GREATER.
glm::dmat4 reverseZProjection(double fovY_deg, double aspect, double near_m, double far_m);
// Depth-buffer value for a point at view distance d_m (for tests and analysis).
double reverseZDepth(double near_m, double far_m, double d_m);

// View frustum in eye-relative world coordinates (eye at the origin, world orientation).
// Plane: dot(n, p) + d >= 0 inside.
struct Frustum {
  std::array<glm::dvec4, 6> planes;  // left, right, bottom, top, near, far
  // True if the box (given relative to the eye) may be visible. Conservative.
  bool intersects(const Aabb& eyeRelative) const;
};
Frustum makeFrustum(const Camera& cam);

// Distance from p to the box (0 inside). Used by LOD rules ("camera inside the box").
double distanceToBox(const Aabb& box, const glm::dvec3& p);

}  // namespace ig::lod
