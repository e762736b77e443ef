#include "lod/sun.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace ig::lod {
namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

// Days from 1970-01-01 to a proleptic Gregorian date (H. Hinnant's days_from_civil).
int64_t daysFromCivil(int64_t y, int64_t m, int64_t d) {
  y -= m <= 2 ? 1 : 0;
  const int64_t era = (y >= 0 ? y : y - 399) / 400;
  const int64_t yoe = y - era * 400;
  const int64_t doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const int64_t doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + doe - 719468;
}
}  // namespace

// NOAA's solar calculator equations (Meeus, "Astronomical Algorithms", low-precision sun), on
// the Julian century since J2000: unlike Spencer's fractional-year series they do not drift
// with the calendar, about 0.01 degrees over 1901..2099 (ignoring UT1-UTC and delta T).
SunPosition sunPosition(int32_t dateYmd, double utc_h, double lat_deg, double lon_deg) {
  const int year = dateYmd / 10000, month = std::clamp((dateYmd / 100) % 100, 1, 12), day = dateYmd % 100;
  const double jd = static_cast<double>(daysFromCivil(year, month, day)) + 2440587.5 + utc_h / 24.0;
  const double t = (jd - 2451545.0) / 36525.0;  // Julian centuries since J2000.0
  const double l0 = std::fmod(280.46646 + t * (36000.76983 + t * 0.0003032), 360.0);  // mean longitude, deg
  const double m = (357.52911 + t * (35999.05029 - 0.0001537 * t)) * kDeg;            // mean anomaly
  const double e = 0.016708634 - t * (0.000042037 + 0.0000001267 * t);                // orbit eccentricity
  const double c = std::sin(m) * (1.914602 - t * (0.004817 + 0.000014 * t)) + std::sin(2 * m) * (0.019993 - 0.000101 * t) +
                   std::sin(3 * m) * 0.000289;  // equation of centre, deg
  const double omega = (125.04 - 1934.136 * t) * kDeg;
  const double lambda = (l0 + c - 0.00569 - 0.00478 * std::sin(omega)) * kDeg;  // apparent longitude
  const double eps0 = 23.0 + (26.0 + (21.448 - t * (46.815 + t * (0.00059 - t * 0.001813))) / 60.0) / 60.0;
  const double eps = (eps0 + 0.00256 * std::cos(omega)) * kDeg;  // corrected obliquity
  const double decl = std::asin(std::sin(eps) * std::sin(lambda));
  const double y = std::tan(eps / 2) * std::tan(eps / 2), l0r = l0 * kDeg;
  const double eqTime_min = 4.0 / kDeg *
                            (y * std::sin(2 * l0r) - 2 * e * std::sin(m) + 4 * e * y * std::sin(m) * std::cos(2 * l0r) -
                             0.5 * y * y * std::sin(4 * l0r) - 1.25 * e * e * std::sin(2 * m));
  const double trueSolar_min = utc_h * 60.0 + eqTime_min + 4.0 * lon_deg;
  const double hourAngle = (trueSolar_min / 4.0 - 180.0) * kDeg;
  const double lat = lat_deg * kDeg;
  const double cosZenith =
      std::clamp(std::sin(lat) * std::sin(decl) + std::cos(lat) * std::cos(decl) * std::cos(hourAngle), -1.0, 1.0);
  SunPosition p;
  p.elevation_deg = 90.0 - std::acos(cosZenith) / kDeg;
  // Azimuth from north, clockwise: the sun is east (90) before noon, west (270) after.
  const double east = -std::cos(decl) * std::sin(hourAngle);
  const double north = std::cos(lat) * std::sin(decl) - std::sin(lat) * std::cos(decl) * std::cos(hourAngle);
  p.azimuth_deg = std::fmod(std::atan2(east, north) / kDeg + 360.0, 360.0);
  return p;
}

double sunlightFraction(double elevation_deg) {
  const double t = std::clamp((elevation_deg + 4.0) / 10.0, 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

}  // namespace ig::lod
