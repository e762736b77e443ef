// Where the sun is: solar azimuth and elevation for a UTC date and time at a geodetic place
// (NOAA's solar calculator equations on the Julian century; about 0.01 degrees from an
// ephemeris over 1901..2099, plenty for lighting). Used when the host sends the date and time
// of day (CIGI Celestial Sphere Control).
#pragma once

#include <cstdint>

namespace ig::lod {

struct SunPosition {
  double azimuth_deg = 0.0;    // clockwise from true north, 0..360
  double elevation_deg = 0.0;  // above the horizon (no refraction); negative = below
};

// dateYmd: YYYYMMDD (year 1901..2099); utc_h: hours 0 <= h < 24.
SunPosition sunPosition(int32_t dateYmd, double utc_h, double lat_deg, double lon_deg);

// How much direct sunlight reaches the ground, 0 (night) .. 1 (sun 6 degrees up or higher),
// smooth through twilight from 4 degrees below the horizon.
double sunlightFraction(double elevation_deg);

}  // namespace ig::lod
