// WGS-84 geodetic <-> ECEF <-> local ENU (east, north, up) conversions, all in double.
// Used to give the host both the geodetic and the local eyepoint, and by tests of huge
// coordinates. Pure functions; no state.
#pragma once

#include <glm/vec3.hpp>

namespace ig::lod {

struct Geodetic {
  double lat_deg = 0.0;
  double lon_deg = 0.0;
  double height_m = 0.0;  // above the ellipsoid
};

glm::dvec3 geodeticToEcef(const Geodetic& g);
Geodetic ecefToGeodetic(const glm::dvec3& ecef_m);

// Local tangent plane anchored at `origin`: x east, y north, z up (metres).
class EnuFrame {
 public:
  explicit EnuFrame(const Geodetic& origin);
  glm::dvec3 toEnu(const glm::dvec3& ecef_m) const;
  glm::dvec3 toEcef(const glm::dvec3& enu_m) const;
  Geodetic toGeodetic(const glm::dvec3& enu_m) const { return ecefToGeodetic(toEcef(enu_m)); }
  glm::dvec3 fromGeodetic(const Geodetic& g) const { return toEnu(geodeticToEcef(g)); }

 private:
  glm::dvec3 originEcef_m_;
  glm::dvec3 east_, north_, up_;
};

}  // namespace ig::lod
