// WGS-84 conversions. ECEF -> geodetic uses Bowring's method with two refinement steps,
// accurate to well below a millimetre for heights from -10 km to 1000 km.
#include "lod/geo.h"

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

}  // namespace ig::lod
