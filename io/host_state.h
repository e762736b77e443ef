// What the host simulator tells the IG each frame. Plain struct, every field with its unit
// and frame. The frame loop copies the latest one out of the mailbox at the start of a frame.
#pragma once

#include <cstdint>

#include <glm/vec3.hpp>

namespace ig::io {

// The largest fog visibility igd takes (HostState::visibility_m, the scene's [fog] visibility_m),
// metres: 10,000 km, beyond which the fog shows nothing on any scene.
inline constexpr double kMaxVisibility_m = 1e7;
// The smallest: a host's 0 (nothing visible) or anything below 1 m is drawn at 1 m.
inline constexpr double kMinVisibility_m = 1.0;

struct HostState {
  uint64_t hostFrame = 0;            // host's own frame counter
  double simTime_s = 0.0;            // simulation time, seconds since scenario start
  glm::dvec3 eyeEnu_m{0.0};          // eyepoint in the scene's local ENU frame (x east, y north, z up)
  double lat_deg = 0.0;              // eyepoint, WGS-84 geodetic (filled from eyeEnu_m by the IG
  double lon_deg = 0.0;              //   when the source gives only ENU)
  double height_m = 0.0;             //   ellipsoid height
  double heading_deg = 0.0;          // clockwise from north
  double pitch_deg = 0.0;            // nose up positive
  double roll_deg = 0.0;             // right wing down positive
  double fovY_deg = 45.0;            // vertical field of view: the window's height, 2 tan(fovy/2) = tan(top) - tan(bottom)
  // Off-axis window (CIGI View Definition's left/right/bottom/top; lod::Camera's shiftX/shiftY):
  // the window's centre right of and above the view axis, in tangent units, and its width
  // tan(right) - tan(left). 0, 0, 0 = a symmetric window as wide as the output's aspect ratio.
  double windowShiftX = 0.0;
  double windowShiftY = 0.0;
  double windowWidth_tan = 0.0;      // 0 = from the output's width / height
  double near_m = 0.1;               // near clip plane
  double far_m = 100000.0;           // far clip plane
  // Date and time for the sun (CIGI Celestial Sphere Control). Negative time / zero date = not
  // given by the host: the scene's own sun applies.
  double timeOfDay_h = -1.0;         // UTC hours, 0 <= h < 24
  int32_t dateYmd = 0;               // UTC date as YYYYMMDD, e.g. 20260621
  // Meteorological visibility for the fog (CIGI Atmosphere Control's visibility range, the
  // Modbus register visibility_m, the CAN signal Visibility), metres; the links clamp it to
  // [kMinVisibility_m, kMaxVisibility_m] (a recording may hold 0 < v < 1: drawn as it is).
  // <= 0 = not given by the host: the scene's own [fog] applies.
  double visibility_m = -1.0;
  // The ownship the eye follows, as the CIGI host gave it (Entity Control): WGS-84 position and
  // attitude in its local level frame (yaw clockwise from true north). HAT/HOT requests in
  // entity coordinates are relative to it. hasOwnship is false for other sources.
  bool hasOwnship = false;
  double ownshipLat_deg = 0.0, ownshipLon_deg = 0.0, ownshipAlt_m = 0.0;
  double ownshipYaw_deg = 0.0, ownshipPitch_deg = 0.0, ownshipRoll_deg = 0.0;
};

}  // namespace ig::io
