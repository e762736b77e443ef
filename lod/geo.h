// WGS-84 geodetic <-> ECEF <-> local ENU (east, north, up) conversions, all in double, and
// attitudes from the local level frame at a point into the scene's ENU axes. Used to give the
// host both the geodetic and the local eyepoint (and attitude), and by tests of huge
// coordinates. Pure functions; no state.
#pragma once

#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

namespace ig::lod {

struct Geodetic {
  double lat_deg = 0.0;
  double lon_deg = 0.0;
  double height_m = 0.0;  // above the ellipsoid
};

glm::dvec3 geodeticToEcef(const Geodetic& g);
Geodetic ecefToGeodetic(const glm::dvec3& ecef_m);

// An attitude in degrees, 3-2-1 sequence: heading clockwise from north, then pitch nose up
// positive, then roll right wing down positive (io::HostState's fields).
struct Attitude {
  double heading_deg = 0.0;
  double pitch_deg = 0.0;
  double roll_deg = 0.0;
};

// Columns: north, east, down at geodetic (lat, lon), in ECEF.
glm::dmat3 nedToEcef(double lat_deg, double lon_deg);
// Columns: body x (forward), y (right), z (down) in the local NED frame for the 3-2-1 sequence
// (yaw = heading, pitch, roll; degrees).
glm::dmat3 bodyToNed(double yaw_deg, double pitch_deg, double roll_deg);

// The attitude whose forward and right axes are `forward` and `right` (unit, in ENU). Straight
// up or down (pitch +-90) the heading is taken from the right axis and the roll is 0, so the
// result still turns the camera exactly as the two axes say.
Attitude attitudeFromEnu(const glm::dvec3& forward, const glm::dvec3& right);
// A child rotation applied after a parent one, in the parent's body axes, both in the same local
// level frame: body axes = bodyToNed(parent) * bodyToNed(child). A display channel's fixed
// offset (yaw -60 deg = the left window) turns with the eyepoint this way.
Attitude composeAttitude(const Attitude& parent, const Attitude& child);

// Local tangent plane anchored at `origin`: x east, y north, z up (metres).
class EnuFrame {
 public:
  explicit EnuFrame(const Geodetic& origin);
  glm::dvec3 toEnu(const glm::dvec3& ecef_m) const;
  glm::dvec3 toEcef(const glm::dvec3& enu_m) const;
  Geodetic toGeodetic(const glm::dvec3& enu_m) const { return ecefToGeodetic(toEcef(enu_m)); }
  glm::dvec3 fromGeodetic(const Geodetic& g) const { return toEnu(geodeticToEcef(g)); }

  // Heading/pitch/roll relative to this frame's axes (grid north of the origin;
  // lod::viewRotation's convention) of a body whose forward and right axes are the given ECEF
  // unit vectors. Heading in [0, 360). Looking straight up or down, heading is taken from the
  // right axis (roll 0).
  Attitude attitudeFromEcef(const glm::dvec3& forwardEcef, const glm::dvec3& rightEcef) const;
  // An attitude given in the local level frame at geodetic (lat, lon) -- heading from TRUE
  // north there, pitch and roll against the local horizontal (CIGI, CAN) -- expressed in this
  // frame's axes. Identity at the origin; elsewhere heading differs by the meridian
  // convergence (about dlon * sin(lat)) and pitch/roll by the tilt of the local vertical.
  Attitude attitudeFromGeodetic(double lat_deg, double lon_deg, const Attitude& local) const;

 private:
  glm::dvec3 originEcef_m_;
  glm::dvec3 east_, north_, up_;
};

}  // namespace ig::lod
