// Test helper, independent of lod/geo: an attitude given in the local level frame at geodetic
// (lat, lon) -- heading clockwise from true north there, pitch nose up, roll right wing down,
// 3-2-1 sequence -- re-expressed in the ENU axes of the scene origin (grid north), by explicit
// trigonometry on WGS-84 geodetic normals. Looking straight up or down, heading comes from the
// right axis (roll 0), as igd does. Degrees in and out; heading in [0, 360).
#pragma once

#include <cmath>

namespace ig::test {

struct SceneAttitude {
  double heading_deg, pitch_deg, roll_deg;
};

inline SceneAttitude sceneAttitude(double originLat_deg, double originLon_deg, double lat_deg, double lon_deg,
                                   double heading_deg, double pitch_deg, double roll_deg) {
  const double d = 3.14159265358979323846 / 180.0;
  const double cy = std::cos(heading_deg * d), sy = std::sin(heading_deg * d);
  const double cp = std::cos(pitch_deg * d), sp = std::sin(pitch_deg * d);
  const double cr = std::cos(roll_deg * d), sr = std::sin(roll_deg * d);
  // Body forward and right axes in the local north, east, down frame.
  const double fN = cy * cp, fE = sy * cp, fD = -sp;
  const double rN = cy * sp * sr - sy * cr, rE = sy * sp * sr + cy * cr, rD = cp * sr;
  // Local north, east, down at (lat, lon) in ECEF.
  const double sf = std::sin(lat_deg * d), cf = std::cos(lat_deg * d);
  const double sl = std::sin(lon_deg * d), cl = std::cos(lon_deg * d);
  auto toEcef = [&](double n, double e, double dn, double out[3]) {
    out[0] = -sf * cl * n - sl * e - cf * cl * dn;
    out[1] = -sf * sl * n + cl * e - cf * sl * dn;
    out[2] = cf * n - sf * dn;
  };
  double f[3], r[3];
  toEcef(fN, fE, fD, f);
  toEcef(rN, rE, rD, r);
  // The origin's east, north, up.
  const double sf0 = std::sin(originLat_deg * d), cf0 = std::cos(originLat_deg * d);
  const double sl0 = std::sin(originLon_deg * d), cl0 = std::cos(originLon_deg * d);
  auto toEnu = [&](const double v[3], double out[3]) {
    out[0] = -sl0 * v[0] + cl0 * v[1];
    out[1] = -sf0 * cl0 * v[0] - sf0 * sl0 * v[1] + cf0 * v[2];
    out[2] = cf0 * cl0 * v[0] + cf0 * sl0 * v[1] + sf0 * v[2];
  };
  double fe[3], re[3];
  toEnu(f, fe);
  toEnu(r, re);
  const double pitch = std::asin(std::fmax(-1.0, std::fmin(1.0, fe[2])));
  double heading = std::atan2(fe[0], fe[1]);
  if (std::hypot(fe[0], fe[1]) < 1e-9) heading = std::atan2(-re[1], re[0]);
  // Roll: the right axis against the level right direction (cos h, -sin h, 0) and the body's
  // up direction with zero roll, level right x forward.
  const double lr[3] = {std::cos(heading), -std::sin(heading), 0.0};
  const double up[3] = {lr[1] * fe[2] - lr[2] * fe[1], lr[2] * fe[0] - lr[0] * fe[2], lr[0] * fe[1] - lr[1] * fe[0]};
  const double roll = std::atan2(-(re[0] * up[0] + re[1] * up[1] + re[2] * up[2]),
                                 re[0] * lr[0] + re[1] * lr[1] + re[2] * lr[2]);
  double h = heading / d;
  if (h < 0.0) h += 360.0;
  if (h >= 360.0) h -= 360.0;
  return {h, pitch / d, roll / d};
}

// Difference of two headings in (-180, 180].
inline double headingDiff_deg(double a, double b) {
  double x = std::fmod(a - b, 360.0);
  if (x > 180.0) x -= 360.0;
  if (x <= -180.0) x += 360.0;
  return x;
}

}  // namespace ig::test
