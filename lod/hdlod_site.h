// HDLOD, part 5: a synthetic skyscraper construction site, the 4D scene of paper 000's
// experiment (section 5: 56,157 objects — 498 static, 40,010 pseudo-dynamic, 15,649 dynamic —
// 4,260,057 triangles) from a few parameters. At scale 1 the defaults give about that mix:
//
// - static: ground tiles, site offices, the fence, the tower-crane masts;
// - pseudo-dynamic (installed by plan, floor after floor): columns, beams, slabs; facade panels
//   and windows three floors behind the structure; scaffolding put up with the structure and
//   taken down once the floor's facade is closed;
// - dynamic: material loads (staged on the ground, lifted to their floor by a crane, then gone),
//   crane jibs slewing, trucks driving the site road on their visits, excavators in the pit
//   during the first weeks.
//
// `scale` multiplies the number of floors and of vehicles (at least one each), so the object
// and triangle counts scale about linearly. Deterministic for a seed (own generator, no
// std::*_distribution). The site's centre is at `origin_m` (for huge-coordinate tests).
#pragma once

#include <cstdint>

#include <glm/vec3.hpp>

#include "lod/hdlod_scene.h"

namespace ig::lod::hdlod {

struct SiteParams {
  int floors = 62;            // at scale 1
  int bays = 10;              // structural bays per side (the tower is bays x bays)
  double bay_m = 6.0;
  double floor_m = 3.6;
  double scale = 1.0;         // > 0
  uint32_t seed = 1;
  double duration_s = 365.0 * 86400.0;  // T: one year
  int loadsPerFloor = 250;    // dynamic material loads per floor
  int trucks = 60;            // at scale 1
  int excavators = 8;         // at scale 1
  int cranes = 2;
  int columnSides = 24;       // detail of the round columns
  glm::dvec3 origin_m{0.0};
};

// Returns the scene; `error` names a bad parameter (then the scene is empty).
Scene makeConstructionSite(const SiteParams& params, std::string& error);

}  // namespace ig::lod::hdlod
