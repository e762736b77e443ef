#include "lod/view.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace ig::lod {
namespace {
constexpr double kDeg = 3.14159265358979323846 / 180.0;
}

glm::dmat3 viewRotation(const Camera& cam) {
  const double h = cam.heading_deg * kDeg, p = cam.pitch_deg * kDeg, r = cam.roll_deg * kDeg;
  // Body axes in ENU: forward, right, up for heading h, pitch p, roll r.
  const glm::dvec3 fwd{std::sin(h) * std::cos(p), std::cos(h) * std::cos(p), std::sin(p)};
  const glm::dvec3 right0{std::cos(h), -std::sin(h), 0.0};
  const glm::dvec3 up0 = glm::cross(right0, fwd);
  const glm::dvec3 right = right0 * std::cos(r) - up0 * std::sin(r);
  const glm::dvec3 up = up0 * std::cos(r) + right0 * std::sin(r);
  // Rows of the world->camera matrix are the camera axes (x right, y up, z back).
  glm::dmat3 m;
  for (int c = 0; c < 3; ++c) {
    m[c][0] = right[c];
    m[c][1] = up[c];
    m[c][2] = -fwd[c];
  }
  return m;
}

glm::dmat4 reverseZProjection(double fovY_deg, double aspect, double near_m, double far_m) {
  const double f = 1.0 / std::tan(0.5 * fovY_deg * kDeg);
  glm::dmat4 m(0.0);
  m[0][0] = f / aspect;
  m[1][1] = f;
  m[2][2] = near_m / (far_m - near_m);
  m[3][2] = near_m * far_m / (far_m - near_m);
  m[2][3] = -1.0;
  return m;
}

glm::dmat4 projection(const Camera& cam) {
  glm::dmat4 m = reverseZProjection(cam.fovY_deg, cam.aspect, cam.near_m, cam.far_m);
  // x_ndc = (x / -z - shiftX) / halfWidth: the third column adds the shift times w = -z.
  const double halfH = std::tan(0.5 * cam.fovY_deg * kDeg), halfW = halfH * cam.aspect;
  m[2][0] = cam.shiftX / halfW;
  m[2][1] = cam.shiftY / halfH;
  return m;
}

bool validWindowShift(const Camera& cam) {
  return std::abs(cam.shiftX) <= kMaxWindowShift && std::abs(cam.shiftY) <= kMaxWindowShift;
}

bool setWindow(Camera& cam, const WindowAngles& w) {
  const double a[] = {w.left_deg, w.right_deg, w.bottom_deg, w.top_deg};
  for (double v : a)
    if (!(v > -90.0 && v < 90.0)) return false;  // NaN too
  if (!(w.left_deg < w.right_deg && w.bottom_deg < w.top_deg)) return false;
  const double l = std::tan(w.left_deg * kDeg), r = std::tan(w.right_deg * kDeg);
  const double b = std::tan(w.bottom_deg * kDeg), t = std::tan(w.top_deg * kDeg);
  cam.fovY_deg = 2.0 * std::atan(0.5 * (t - b)) / kDeg;
  cam.aspect = (r - l) / (t - b);
  cam.shiftX = 0.5 * (r + l);
  cam.shiftY = 0.5 * (t + b);
  return true;
}

double reverseZDepth(double near_m, double far_m, double d_m) {
  return (near_m * far_m / (far_m - near_m) - near_m / (far_m - near_m) * d_m) / d_m;
}

Frustum makeFrustum(const Camera& cam) {
  // Planes from the combined clip matrix (Gribb-Hartmann), with zero-to-one depth.
  const glm::dmat4 view(viewRotation(cam));
  const glm::dmat4 m = projection(cam) * view;
  auto row = [&](int i) { return glm::dvec4(m[0][i], m[1][i], m[2][i], m[3][i]); };
  Frustum fr;
  fr.planes[0] = row(3) + row(0);
  fr.planes[1] = row(3) - row(0);
  fr.planes[2] = row(3) + row(1);
  fr.planes[3] = row(3) - row(1);
  fr.planes[4] = row(3) - row(2);  // reverse-Z: depth <= 1 is the near side
  fr.planes[5] = row(2);           // depth >= 0 is the far side
  for (auto& p : fr.planes) {
    const double len = glm::length(glm::dvec3(p));
    p /= len;
  }
  return fr;
}

bool Frustum::intersects(const Aabb& b) const {
  for (const auto& p : planes) {
    // The box corner furthest along the plane normal.
    const glm::dvec3 v{p.x >= 0 ? b.max.x : b.min.x, p.y >= 0 ? b.max.y : b.min.y,
                       p.z >= 0 ? b.max.z : b.min.z};
    if (p.x * v.x + p.y * v.y + p.z * v.z + p.w < 0.0) return false;
  }
  return true;
}

double distanceToBox(const Aabb& box, const glm::dvec3& p) {
  const glm::dvec3 d = glm::max(glm::max(box.min - p, p - box.max), glm::dvec3(0.0));
  return glm::length(d);
}

}  // namespace ig::lod
