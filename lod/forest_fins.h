// Forest fins (paper 004, shared/SEEDS.md section 004): vertical two-sided quads of tree height
// standing on terrain edges, which fill the gaps the shell layers show at hill silhouettes and
// at grazing views.
//
// Fin rule (start-up). On a terrain triangle mesh (triangles counter-clockwise seen from above,
// so face normals point up), for every interior edge shared by exactly two faces the dihedral
// angle phi is measured THROUGH THE GROUND, in degrees:
//     phi = 180 on flat ground, phi < 180 on a convex edge (ridge, crest: where silhouettes
//     form), phi > 180 on a concave edge (valley);  phi = 180 -+ angle between the two normals.
// A fin is made where phi < criticalAngle_deg (empirical, per terrain; default 175). Boundary
// edges, edges of more than two faces and edges of degenerate (zero-area) faces get no fin.
// A fin lying wholly in glades (the glade mask at every sample along the edge, samples at most
// half a map cell apart, endpoints included) is dropped.
//
// Groups. Fins are grouped by ground tile (tileSize_m) and by tangent direction (the edge
// direction T folded to one half-space, binned by azimuth and elevation); each group keeps a
// bounding box (fin tops included), a bounding sphere and a tangent cone (axis C, half-angle
// alpha: every fin's line direction lies within alpha of C's line).
//
// View-angle alpha of a fin point: A = 1 - |dot(T, V)|, V the unit direction from the eye to
// the point. Group rejection (per frame): with Vc from the eye to the sphere centre, beta =
// asin(radius / |Vc|) and gamma the angle between the lines of C and Vc, every point of every
// fin in the group has line-angle(T, V) <= gamma + alpha + beta (the angle between lines is a
// metric), so the whole group is fully transparent (A < alphaThreshold everywhere) if
//     gamma + alpha + beta < acos(1 - alphaThreshold).
// Such a group is rejected early; an eye inside the sphere never rejects. This never rejects a
// fin point whose A >= alphaThreshold (tested). Groups outside the frustum, beyond FarPlane, or
// wholly nearer than FadeInStart (farAlpha = 0 there) are skipped too.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/forest.h"
#include "lod/view.h"

namespace ig::lod {

struct FinParams {
  double criticalAngle_deg = 175.0;  // phi below this gets a fin (see above), in (0, 360)
  double finHeight_m = 20.0;         // quad height (tree height)
  double tileSize_m = 256.0;         // spatial group size
  int azimuthBins = 12;              // tangent bins over 180 degrees of azimuth
  int elevationBins = 6;             // tangent bins over [-90, 90] degrees of elevation
};

struct Fin {
  glm::dvec3 a_m{0.0}, b_m{0.0};  // ENU ends of the terrain edge (the fin rises finHeight above)
  glm::vec3 tangent{1.0f, 0.0f, 0.0f};  // unit (b - a)
  float phi_deg = 180.0f;              // dihedral angle through the ground
};

struct FinGroup {
  Aabb bounds;                 // all fin quads of the group, ENU
  glm::dvec3 centre_m{0.0};    // bounding sphere
  double radius_m = 0.0;
  glm::dvec3 axis{1.0, 0.0, 0.0};  // tangent cone axis (unit)
  double halfAngle_rad = 0.0;
  uint32_t first = 0;          // into FinSet::fins
  uint32_t count = 0;
};

struct FinSet {
  std::vector<Fin> fins;        // in group order
  std::vector<FinGroup> groups;
  uint64_t edgesTested = 0;     // interior edges
  uint64_t edgesBelowAngle = 0; // fins before the glade rule
};

// Regular grid mesh of a height field (posts row-major, row = north), two triangles per quad,
// counter-clockwise from above. Positions are ENU: offset + (x * spacing, y * spacing, h).
void makeGridMesh(std::span<const float> heights_m, int postsX, int postsY, double spacing_m, const glm::dvec3& offset_m,
                  std::vector<glm::dvec3>& positions, std::vector<uint32_t>& triangles);

// Dihedral angle phi (degrees, through the ground) of the edge (a, b) shared by the faces
// (a, b, c) and (b, a, d), both counter-clockwise from above. NaN for a degenerate face.
double dihedralThroughGround_deg(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, const glm::dvec3& d);

// Finds the fins (rule above) with a half-edge twin table, drops those wholly in glades of
// `map` (pass nullptr for no glade rule) and groups them. Returns false with `error` for bad
// parameters or indices out of range.
bool buildFins(std::span<const glm::dvec3> positions, std::span<const uint32_t> triangles, const ForestMap* map,
               const FinParams& params, FinSet& out, std::string& error);

struct FinSelectStats {
  uint32_t groupsVisible = 0;   // in the frustum and the far range
  uint32_t groupsRejected = 0;  // of those, rejected by the tangent cone
  uint64_t finsDrawn = 0;       // fins of the accepted groups
};

// View alpha of a fin point (see above).
double finViewAlpha(const glm::dvec3& tangent, const glm::dvec3& eye_m, const glm::dvec3& point_m);
// True if the cone test proves the whole group transparent for this eye.
bool finGroupTransparent(const FinGroup& g, const glm::dvec3& eye_m, double alphaThreshold);

// Writes the indices of the groups to draw into `out` (needs groups.size() entries); returns
// the count. A NaN camera selects nothing. No allocation.
size_t selectFinGroups(std::span<const FinGroup> groups, const Camera& cam, const FarFade& fade, double alphaThreshold,
                       std::span<uint32_t> out, FinSelectStats* stats = nullptr);

}  // namespace ig::lod
