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
  // Off-axis (asymmetric) window, for display channels that meet without a seam: the window's
  // centre in tangent units (the tangent of the angle from the view axis), right (x) and up (y).
  // 0, 0 = the symmetric view. fovY_deg and aspect keep giving the window's size:
  //   tan(top) - tan(bottom) = 2 tan(fovY/2),  tan(right) - tan(left) = aspect * 2 tan(fovY/2),
  //   tan(top) + tan(bottom) = 2 shiftY,       tan(right) + tan(left) = 2 shiftX,
  // so every LOD metric in pixels per tangent unit, viewportHeight / (2 tan(fovY/2)), holds
  // off-axis too (near the window's edges a pixel spans a smaller angle, never a larger one).
  double shiftX = 0.0;
  double shiftY = 0.0;
};

// The largest window shift a camera may have (|shiftX|, |shiftY|): tan(89.9 deg) ~ 573.
constexpr double kMaxWindowShift = 500.0;
// True when the shift is finite and within kMaxWindowShift (NaN is refused). Every validator of
// a Camera checks this next to its other fields.
bool validWindowShift(const Camera& cam);

// A window given by its four edge angles from the view axis (degrees; left/bottom negative when
// the edge is left of / below the axis), as CIGI View Definition and a display channel give it.
struct WindowAngles {
  double left_deg = -45.0, right_deg = 45.0, bottom_deg = -30.0, top_deg = 30.0;
  bool operator==(const WindowAngles&) const = default;
};
// Sets cam.fovY_deg, aspect, shiftX and shiftY from the edge angles. Needs each angle in
// (-90, 90), left < right and bottom < top (else the camera is left unchanged, returns false).
bool setWindow(Camera& cam, const WindowAngles& w);

// Rotation taking world (ENU) directions to camera-space directions.
glm::dmat3 viewRotation(const Camera& cam);
// Reverse-Z projection for glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE): depth 1 at near,
// 0 at far; use a float depth buffer cleared to 0 with depth test GL_GREATER. Symmetric.
glm::dmat4 reverseZProjection(double fovY_deg, double aspect, double near_m, double far_m);
// The camera's reverse-Z projection, off-axis when it has a window shift: the window's edges
// map to NDC x, y = -1 / +1. Every renderer and culler takes its projection from here.
glm::dmat4 projection(const Camera& cam);
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
