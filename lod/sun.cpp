#include "lod/sun.h"

#include <algorithm>
#include <cmath>

namespace ig::lod {
namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

int dayOfYear(int year, int month, int day) {
  static constexpr int kStart[12] = {0, 31, 59, 90, 120, 151, 181, 212, 243, 273, 304, 334};
  const bool leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
  return kStart[std::clamp(month, 1, 12) - 1] + day + (leap && month > 2 ? 1 : 0);
}
}  // namespace

SunPosition sunPosition(int32_t dateYmd, double utc_h, double lat_deg, double lon_deg) {
  const int year = dateYmd / 10000, month = (dateYmd / 100) % 100, day = dateYmd % 100;
  const bool leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
  // Fractional year (radians).
  const double g = 2.0 * kPi / (leap ? 366.0 : 365.0) * (dayOfYear(year, month, day) - 1 + (utc_h - 12.0) / 24.0);
  const double eqTime_min = 229.18 * (0.000075 + 0.001868 * std::cos(g) - 0.032077 * std::sin(g) -
                                      0.014615 * std::cos(2 * g) - 0.040849 * std::sin(2 * g));
  const double decl = 0.006918 - 0.399912 * std::cos(g) + 0.070257 * std::sin(g) - 0.006758 * std::cos(2 * g) +
                      0.000907 * std::sin(2 * g) - 0.002697 * std::cos(3 * g) + 0.00148 * std::sin(3 * g);
  const double trueSolar_min = utc_h * 60.0 + eqTime_min + 4.0 * lon_deg;
  const double hourAngle = (trueSolar_min / 4.0 - 180.0) * kDeg;
  const double lat = lat_deg * kDeg;
  const double cosZenith =
      std::clamp(std::sin(lat) * std::sin(decl) + std::cos(lat) * std::cos(decl) * std::cos(hourAngle), -1.0, 1.0);
  SunPosition p;
  p.elevation_deg = 90.0 - std::acos(cosZenith) / kDeg;
  // Azimuth from north, clockwise: the sun is east (90) before noon, west (270) after.
  const double az = std::atan2(std::sin(hourAngle),
                               std::cos(hourAngle) * std::sin(lat) - std::tan(decl) * std::cos(lat)) / kDeg + 180.0;
  p.azimuth_deg = std::fmod(az + 360.0, 360.0);
  return p;
}

double sunlightFraction(double elevation_deg) {
  const double t = std::clamp((elevation_deg + 4.0) / 10.0, 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

}  // namespace ig::lod
