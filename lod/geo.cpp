// WGS-84 conversions. ECEF -> geodetic uses Bowring's method with two refinement steps,
// accurate to well below a millimetre for heights from -10 km to 1000 km.
#include "lod/geo.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace ig::lod {
namespace {
constexpr double kA = 6378137.0;                 // semi-major axis, m
constexpr double kF = 1.0 / 298.257223563;       // flattening
constexpr double kB = kA * (1.0 - kF);           // semi-minor axis, m
constexpr double kE2 = kF * (2.0 - kF);          // first eccentricity squared
constexpr double kEp2 = kE2 / (1.0 - kE2);       // second eccentricity squared
constexpr double kDeg = 3.14159265358979323846 / 180.0;
}  // namespace

glm::dvec3 geodeticToEcef(const Geodetic& g) {
  const double lat = g.lat_deg * kDeg, lon = g.lon_deg * kDeg;
  const double s = std::sin(lat), c = std::cos(lat);
  const double n = kA / std::sqrt(1.0 - kE2 * s * s);
  return {(n + g.height_m) * c * std::cos(lon), (n + g.height_m) * c * std::sin(lon),
          (n * (1.0 - kE2) + g.height_m) * s};
}

Geodetic ecefToGeodetic(const glm::dvec3& p) {
  const double lon = std::atan2(p.y, p.x);
  const double r = std::hypot(p.x, p.y);
  if (r < 1e-9) {  // on the polar axis
    const double lat = p.z >= 0 ? 90.0 : -90.0;
    return {lat, 0.0, std::abs(p.z) - kB};
  }
  double beta = std::atan2(p.z * kA, r * kB);  // parametric latitude, first guess
  double lat = 0.0;
  for (int i = 0; i < 3; ++i) {
    const double sb = std::sin(beta), cb = std::cos(beta);
    lat = std::atan2(p.z + kEp2 * kB * sb * sb * sb, r - kE2 * kA * cb * cb * cb);
    beta = std::atan2((1.0 - kF) * std::sin(lat), std::cos(lat));
  }
  const double s = std::sin(lat);
  const double n = kA / std::sqrt(1.0 - kE2 * s * s);
  // Height formula that stays accurate at all latitudes.
  const double h = r * std::cos(lat) + (p.z + kE2 * n * s) * s - n;
  return {lat / kDeg, lon / kDeg, h};
}

glm::dmat3 nedToEcef(double lat_deg, double lon_deg) {
  const double sf = std::sin(lat_deg * kDeg), cf = std::cos(lat_deg * kDeg);
  const double sl = std::sin(lon_deg * kDeg), cl = std::cos(lon_deg * kDeg);
  return glm::dmat3(glm::dvec3(-sf * cl, -sf * sl, cf), glm::dvec3(-sl, cl, 0), glm::dvec3(-cf * cl, -cf * sl, -sf));
}

namespace {
glm::dmat3 rotZ(double a) {
  const double c = std::cos(a), s = std::sin(a);
  return glm::dmat3(glm::dvec3(c, s, 0), glm::dvec3(-s, c, 0), glm::dvec3(0, 0, 1));
}
glm::dmat3 rotY(double a) {
  const double c = std::cos(a), s = std::sin(a);
  return glm::dmat3(glm::dvec3(c, 0, -s), glm::dvec3(0, 1, 0), glm::dvec3(s, 0, c));
}
glm::dmat3 rotX(double a) {
  const double c = std::cos(a), s = std::sin(a);
  return glm::dmat3(glm::dvec3(1, 0, 0), glm::dvec3(0, c, s), glm::dvec3(0, -s, c));
}
}  // namespace

glm::dmat3 bodyToNed(double yaw_deg, double pitch_deg, double roll_deg) {
  return rotZ(yaw_deg * kDeg) * rotY(pitch_deg * kDeg) * rotX(roll_deg * kDeg);
}

EnuFrame::EnuFrame(const Geodetic& origin) : originEcef_m_(geodeticToEcef(origin)) {
  const double lat = origin.lat_deg * kDeg, lon = origin.lon_deg * kDeg;
  east_ = {-std::sin(lon), std::cos(lon), 0.0};
  north_ = {-std::sin(lat) * std::cos(lon), -std::sin(lat) * std::sin(lon), std::cos(lat)};
  up_ = {std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon), std::sin(lat)};
}

glm::dvec3 EnuFrame::toEnu(const glm::dvec3& ecef_m) const {
  const glm::dvec3 d = ecef_m - originEcef_m_;
  return {glm::dot(d, east_), glm::dot(d, north_), glm::dot(d, up_)};
}

glm::dvec3 EnuFrame::toEcef(const glm::dvec3& enu_m) const {
  return originEcef_m_ + east_ * enu_m.x + north_ * enu_m.y + up_ * enu_m.z;
}

Attitude attitudeFromEnu(const glm::dvec3& f, const glm::dvec3& r) {
  const double pitch = std::asin(std::clamp(f.z, -1.0, 1.0));
  double heading = std::atan2(f.x, f.y);
  if (std::hypot(f.x, f.y) < 1e-9) heading = std::atan2(-r.y, r.x);  // straight up/down: from the right axis
  const glm::dvec3 right0{std::cos(heading), -std::sin(heading), 0.0};
  const glm::dvec3 up0 = glm::cross(right0, f);
  const double roll = std::atan2(-glm::dot(r, up0), glm::dot(r, right0));
  double heading_deg = heading / kDeg;
  if (heading_deg < 0.0) heading_deg += 360.0;
  if (heading_deg >= 360.0) heading_deg -= 360.0;
  return {heading_deg, pitch / kDeg, roll / kDeg};
}

Attitude composeAttitude(const Attitude& parent, const Attitude& child) {
  const glm::dmat3 m = bodyToNed(parent.heading_deg, parent.pitch_deg, parent.roll_deg) *
                       bodyToNed(child.heading_deg, child.pitch_deg, child.roll_deg);
  const auto enu = [](const glm::dvec3& ned) { return glm::dvec3(ned.y, ned.x, -ned.z); };
  return attitudeFromEnu(enu(m[0]), enu(m[1]));
}

Attitude EnuFrame::attitudeFromEcef(const glm::dvec3& forwardEcef, const glm::dvec3& rightEcef) const {
  const glm::dvec3 f{glm::dot(forwardEcef, east_), glm::dot(forwardEcef, north_), glm::dot(forwardEcef, up_)};
  const glm::dvec3 r{glm::dot(rightEcef, east_), glm::dot(rightEcef, north_), glm::dot(rightEcef, up_)};
  return attitudeFromEnu(f, r);
}

Attitude EnuFrame::attitudeFromGeodetic(double lat_deg, double lon_deg, const Attitude& local) const {
  const glm::dmat3 body = nedToEcef(lat_deg, lon_deg) * bodyToNed(local.heading_deg, local.pitch_deg, local.roll_deg);
  return attitudeFromEcef(body[0], body[1]);
}

}  // namespace ig::lod
