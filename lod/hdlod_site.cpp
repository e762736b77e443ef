#include "lod/hdlod_site.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <glm/geometric.hpp>

namespace ig::lod::hdlod {
namespace {

constexpr double kPi = 3.14159265358979323846;

// splitmix64: the same numbers on every platform.
struct Rng {
  uint64_t s;
  uint64_t next() {
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double uniform() { return static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0); }
  double range(double a, double b) { return a + (b - a) * uniform(); }
};

uint32_t vtx(Model& m, const glm::dvec3& p) {
  m.positions.emplace_back(static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z));
  return static_cast<uint32_t>(m.positions.size() - 1);
}

void addBox(Model& m, const glm::dvec3& lo, const glm::dvec3& hi) {
  const uint32_t b = static_cast<uint32_t>(m.positions.size());
  for (int i = 0; i < 8; ++i) vtx(m, {(i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z});
  const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) m.indices.insert(m.indices.end(), {b + q[0], b + q[1], b + q[2], b + q[0], b + q[2], b + q[3]});
}

// A closed prism of `sides` around the segment a -> b.
void addTube(Model& m, const glm::dvec3& a, const glm::dvec3& b, double radius, int sides) {
  const glm::dvec3 axis = glm::normalize(b - a);
  const glm::dvec3 ref = std::abs(axis.z) < 0.9 ? glm::dvec3(0, 0, 1) : glm::dvec3(1, 0, 0);
  const glm::dvec3 u = glm::normalize(glm::cross(axis, ref)), v = glm::cross(axis, u);
  const uint32_t base = static_cast<uint32_t>(m.positions.size());
  const uint32_t n = static_cast<uint32_t>(sides);
  for (uint32_t i = 0; i < n; ++i) {
    const double ang = 2.0 * kPi * i / sides;
    const glm::dvec3 off = (u * std::cos(ang) + v * std::sin(ang)) * radius;
    vtx(m, a + off);
    vtx(m, b + off);
  }
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t j = (i + 1) % n;
    m.indices.insert(m.indices.end(), {base + 2 * i, base + 2 * j, base + 2 * j + 1, base + 2 * i, base + 2 * j + 1, base + 2 * i + 1});
  }
  for (uint32_t i = 1; i + 1 < n; ++i) {
    m.indices.insert(m.indices.end(), {base, base + 2 * (i + 1), base + 2 * i});
    m.indices.insert(m.indices.end(), {base + 1, base + 2 * i + 1, base + 2 * (i + 1) + 1});
  }
}

Model named(const char* name) {
  Model m;
  m.name = name;
  return m;
}

}  // namespace

Scene makeConstructionSite(const SiteParams& p, std::string& error) {
  Scene s;
  error.clear();
  if (!(p.scale > 0.0) || !std::isfinite(p.scale)) error = "scale = " + std::to_string(p.scale) + ": must be > 0";
  if (p.floors < 1 || p.floors > 1000) error = "floors = " + std::to_string(p.floors) + ": must be 1..1000";
  if (p.bays < 1 || p.bays > 100) error = "bays = " + std::to_string(p.bays) + ": must be 1..100";
  if (!(p.bay_m > 0.5) || !(p.floor_m > 1.0)) error = "bay_m / floor_m: must be > 0.5 / > 1 m";
  if (!(p.duration_s > 0.0) || !std::isfinite(p.duration_s)) error = "duration_s = " + std::to_string(p.duration_s) + ": must be > 0";
  if (p.loadsPerFloor < 0 || p.trucks < 0 || p.excavators < 0 || p.cranes < 0) error = "negative vehicle or load count";
  if (p.columnSides < 3 || p.columnSides > 256) error = "columnSides = " + std::to_string(p.columnSides) + ": must be 3..256";
  if (!std::isfinite(p.origin_m.x) || !std::isfinite(p.origin_m.y) || !std::isfinite(p.origin_m.z)) error = "origin_m: not finite";
  if (!error.empty()) return s;

  const double T = p.duration_s;
  s.duration_s = T;
  const int F = std::max(1, static_cast<int>(std::lround(p.floors * p.scale)));
  const int B = p.bays;
  const double bay = p.bay_m, fh = p.floor_m, half = 0.5 * B * bay;
  const double siteHalf = std::max(100.0, half + 60.0);
  auto scaled = [&](int n) { return n == 0 ? 0 : std::max(1, static_cast<int>(std::lround(n * p.scale))); };
  Rng rng{p.seed * 0x2545F4914F6CDD1Dull + 1};

  // ---- models
  auto addModel = [&](Model m) {
    s.models.push_back(std::move(m));
    return static_cast<uint32_t>(s.models.size() - 1);
  };
  Model ground = named("ground_tile");
  const double tile = 2.0 * siteHalf / 8.0;
  for (int y = 0; y <= 16; ++y) {
    for (int x = 0; x <= 16; ++x) vtx(ground, {tile * (x / 16.0 - 0.5), tile * (y / 16.0 - 0.5), 0.0});
  }
  for (uint32_t y = 0; y < 16; ++y) {
    for (uint32_t x = 0; x < 16; ++x) {
      const uint32_t a = y * 17 + x;
      ground.indices.insert(ground.indices.end(), {a, a + 1, a + 18, a, a + 18, a + 17});
    }
  }
  const uint32_t mGround = addModel(std::move(ground));
  Model office = named("office");
  addBox(office, {-6, -2.5, 0}, {6, 2.5, 3});
  for (int i = 0; i < 4; ++i) addBox(office, {-5 + 2.6 * i, -2.6, 1}, {-4 + 2.6 * i, -2.5, 2});
  const uint32_t mOffice = addModel(std::move(office));
  Model fence = named("fence");
  addBox(fence, {-1.25, -0.03, 0}, {1.25, 0.03, 2});
  const uint32_t mFence = addModel(std::move(fence));
  const double craneTop = F * fh + 20.0;
  Model mast = named("crane_mast");
  for (int k = 0; k < 4; ++k) {
    const double x = (k & 1) ? 1.0 : -1.0, y = (k & 2) ? 1.0 : -1.0;
    addTube(mast, {x, y, 0}, {x, y, craneTop}, 0.12, 6);
  }
  for (double z = 0; z < craneTop; z += 4.0) addTube(mast, {-1, -1, z}, {1, 1, z + 4.0}, 0.06, 4);
  const uint32_t mMast = addModel(std::move(mast));
  Model column = named("column");
  addTube(column, {0, 0, 0}, {0, 0, fh}, 0.3, p.columnSides);
  const uint32_t mColumn = addModel(std::move(column));
  Model beam = named("beam");  // an I-beam along x, one bay long, under the slab
  addBox(beam, {-0.5 * bay, -0.15, -0.04}, {0.5 * bay, 0.15, 0});
  addBox(beam, {-0.5 * bay, -0.02, -0.46}, {0.5 * bay, 0.02, -0.04});
  addBox(beam, {-0.5 * bay, -0.15, -0.5}, {0.5 * bay, 0.15, -0.46});
  const uint32_t mBeam = addModel(std::move(beam));
  Model slab = named("slab");
  addBox(slab, {-0.5 * bay, -0.5 * bay, -0.25}, {0.5 * bay, 0.5 * bay, 0});
  const uint32_t mSlab = addModel(std::move(slab));
  Model panel = named("facade_panel");  // half a bay wide, facing -y
  addBox(panel, {-0.25 * bay, -0.08, 0}, {0.25 * bay, 0, fh});
  const uint32_t mPanel = addModel(std::move(panel));
  Model window = named("window");
  {
    const double w = 0.25 * bay - 0.3;
    addBox(window, {-w, -0.2, 0.9}, {w, -0.08, 1.0});
    addBox(window, {-w, -0.2, fh - 0.6}, {w, -0.08, fh - 0.5});
    addBox(window, {-w, -0.2, 1.0}, {-w + 0.1, -0.08, fh - 0.6});
    addBox(window, {w - 0.1, -0.2, 1.0}, {w, -0.08, fh - 0.6});
    addBox(window, {-0.05, -0.2, 1.0}, {0.05, -0.08, fh - 0.6});
    addBox(window, {-w, -0.15, 1.0}, {w, -0.13, fh - 0.6});
  }
  const uint32_t mWindow = addModel(std::move(window));
  Model scaffold = named("scaffold");  // one bay of scaffolding, 1.2 m outside the facade (-y)
  {
    const double w = 0.5 * bay, y0 = -1.2, y1 = -2.2;
    for (double x : {-w, w}) {
      addTube(scaffold, {x, y0, 0}, {x, y0, fh}, 0.025, 6);
      addTube(scaffold, {x, y1, 0}, {x, y1, fh}, 0.025, 6);
    }
    addTube(scaffold, {-w, y1, 0.2}, {w, y1, fh - 0.2}, 0.025, 6);
    addTube(scaffold, {-w, y1, 1.0}, {w, y1, 1.0}, 0.025, 6);
    addBox(scaffold, {-w, y1, fh - 0.05}, {w, y0, fh});
  }
  const uint32_t mScaffold = addModel(std::move(scaffold));
  Model load = named("load");  // a pallet of bags
  addBox(load, {-0.6, -0.5, 0}, {0.6, 0.5, 0.05});
  for (double y : {-0.45, 0.0, 0.45}) addBox(load, {-0.6, y - 0.05, 0.05}, {0.6, y + 0.05, 0.15});
  for (int i = 0; i < 6; ++i) {
    const double x = -0.55 + 0.38 * (i % 3), y = (i < 3) ? -0.45 : 0.02;
    addBox(load, {x, y, 0.15}, {x + 0.35, y + 0.43, 0.55});
  }
  const uint32_t mLoad = addModel(std::move(load));
  Model truck = named("truck");
  addBox(truck, {-1.2, 2.0, 0.6}, {1.2, 4.0, 3.0});
  addBox(truck, {-1.25, -4.0, 1.0}, {1.25, 2.0, 2.4});
  for (double y : {3.2, -1.5, -3.0}) {
    for (double x : {-1.1, 1.1}) addTube(truck, {x - 0.2, y, 0.5}, {x + 0.2, y, 0.5}, 0.5, 12);
  }
  const uint32_t mTruck = addModel(std::move(truck));
  Model excavator = named("excavator");
  addBox(excavator, {-1.6, -2.4, 0}, {-0.9, 2.4, 0.9});
  addBox(excavator, {0.9, -2.4, 0}, {1.6, 2.4, 0.9});
  addBox(excavator, {-1.4, -1.6, 0.9}, {1.4, 1.6, 2.2});
  addBox(excavator, {-1.0, 0.0, 2.2}, {0.2, 1.4, 3.2});
  addTube(excavator, {0.5, 1.2, 1.8}, {0.5, 4.5, 3.5}, 0.25, 8);
  addTube(excavator, {0.5, 4.5, 3.5}, {0.5, 6.0, 0.8}, 0.2, 8);
  addBox(excavator, {0.0, 5.6, 0.0}, {1.0, 6.4, 0.8});
  const uint32_t mExcavator = addModel(std::move(excavator));
  Model jib = named("crane_jib");  // along +y from the mast top, counter-jib along -y
  for (double y = -15.0; y < 60.0; y += 3.0) {
    addTube(jib, {-0.8, y, 0}, {-0.8, y + 3.0, 0}, 0.06, 4);
    addTube(jib, {0.8, y, 0}, {0.8, y + 3.0, 0}, 0.06, 4);
    addTube(jib, {-0.8, y, 0}, {0.0, y + 1.5, 1.6}, 0.04, 4);
    addTube(jib, {0.8, y + 3.0, 0}, {0.0, y + 1.5, 1.6}, 0.04, 4);
  }
  addBox(jib, {-1.5, -15.0, -2.0}, {1.5, -11.0, 0.0});
  const uint32_t mJib = addModel(std::move(jib));
  computeModelBoxes(s);

  // ---- objects
  const glm::dvec3 O = p.origin_m;
  auto place = [&](const std::string& name, uint32_t model, const glm::dvec3& pos, double heading, double appear,
                   double disappear) {
    Object o;
    o.name = name;
    o.model = model;
    o.path.push_back({0.0, O + pos, heading});
    if (appear < disappear) o.visible.push_back({appear, disappear});
    s.objects.push_back(std::move(o));
    return s.objects.size() - 1;
  };
  // Static.
  for (int y = 0; y < 8; ++y) {
    for (int x = 0; x < 8; ++x) {
      place("ground_" + std::to_string(y * 8 + x), mGround, {-siteHalf + tile * (x + 0.5), -siteHalf + tile * (y + 0.5), 0}, 0, 0, T);
    }
  }
  for (int i = 0; i < 30; ++i) {
    place("office_" + std::to_string(i), mOffice, {-siteHalf + 10 + 13.0 * (i % 10), siteHalf - 12 - 6.0 * (i / 10), 0}, 0, 0, T);
  }
  const int fencePerSide = static_cast<int>(2.0 * siteHalf / 2.5);
  for (int side = 0; side < 4; ++side) {
    for (int i = 0; i < fencePerSide; ++i) {
      const double a = -siteHalf + 2.5 * (i + 0.5);
      const glm::dvec3 pos = side == 0 ? glm::dvec3(a, -siteHalf, 0) : side == 1 ? glm::dvec3(siteHalf, a, 0)
                                     : side == 2                    ? glm::dvec3(-a, siteHalf, 0)
                                                                    : glm::dvec3(-siteHalf, -a, 0);
      place("fence_" + std::to_string(side) + "_" + std::to_string(i), mFence, pos, 90.0 * side, 0, T);
    }
  }
  std::vector<glm::dvec3> craneBase;
  for (int c = 0; c < p.cranes; ++c) {
    const double a = 2.0 * kPi * (c + 0.25) / std::max(1, p.cranes);
    craneBase.push_back({(half + 8.0) * std::cos(a), (half + 8.0) * std::sin(a), 0});
    place("crane_mast_" + std::to_string(c), mMast, craneBase.back(), 0, 0, T);
  }

  // Pseudo-dynamic: floor k's structure during [s_k, s_k + P); its facade three floors later.
  const double P = 0.75 * T / F;
  auto floorStart = [&](int k) { return 0.05 * T + k * P; };
  auto clampT = [&](double t) { return std::min(t, 0.97 * T); };
  for (int k = 0; k < F; ++k) {
    const double z = k * fh, s0 = floorStart(k);
    const std::string fk = std::to_string(k);
    for (int j = 0; j <= B; ++j) {
      for (int i = 0; i <= B; ++i) {
        place("col_" + fk + "_" + std::to_string(i) + "_" + std::to_string(j), mColumn, {-half + i * bay, -half + j * bay, z}, 0,
              s0 + rng.range(0.0, 0.3) * P, 2.0 * T);
      }
    }
    for (int j = 0; j <= B; ++j) {
      for (int i = 0; i < B; ++i) {
        place("beamx_" + fk + "_" + std::to_string(i) + "_" + std::to_string(j), mBeam, {-half + (i + 0.5) * bay, -half + j * bay, z + fh},
              0, s0 + rng.range(0.3, 0.6) * P, 2.0 * T);
        place("beamy_" + fk + "_" + std::to_string(j) + "_" + std::to_string(i), mBeam, {-half + j * bay, -half + (i + 0.5) * bay, z + fh},
              90, s0 + rng.range(0.3, 0.6) * P, 2.0 * T);
      }
    }
    for (int j = 0; j < B; ++j) {
      for (int i = 0; i < B; ++i) {
        place("slab_" + fk + "_" + std::to_string(i) + "_" + std::to_string(j), mSlab, {-half + (i + 0.5) * bay, -half + (j + 0.5) * bay, z + fh},
              0, s0 + rng.range(0.6, 0.95) * P, 2.0 * T);
      }
    }
    // Facade: 2 panels and 2 windows per bay and side; scaffolding per bay and side.
    const double facade = clampT(floorStart(k + 3));
    for (int side = 0; side < 4; ++side) {
      const double heading = 90.0 * side;
      const double h = heading * kPi / 180.0;
      const glm::dvec3 along(std::cos(h), -std::sin(h), 0), out(-std::sin(h), -std::cos(h), 0);
      for (int i = 0; i < B; ++i) {
        const glm::dvec3 bayCentre = out * half + along * (-half + (i + 0.5) * bay) + glm::dvec3(0, 0, z);
        double closed = facade;
        for (int q = 0; q < 2; ++q) {
          const glm::dvec3 pos = bayCentre + along * ((q - 0.5) * 0.5 * bay);
          const std::string id = fk + "_" + std::to_string(side) + "_" + std::to_string(i) + "_" + std::to_string(q);
          const double tp = clampT(facade + rng.range(0.0, 0.5) * P), tw = clampT(tp + rng.range(0.2, 0.5) * P);
          closed = std::max(closed, tw);
          place("panel_" + id, mPanel, pos, heading, tp, 2.0 * T);
          place("window_" + id, mWindow, pos, heading, tw, 2.0 * T);
        }
        place("scaffold_" + fk + "_" + std::to_string(side) + "_" + std::to_string(i), mScaffold, bayCentre, heading,
              s0 + rng.range(0.0, 0.2) * P, clampT(closed + 0.3 * P + 0.001 * T));
      }
    }
  }

  // Dynamic: loads (staged, lifted to their floor), crane jibs, trucks, excavators.
  for (int k = 0; k < F; ++k) {
    const double s0 = floorStart(k), top = k * fh + fh;
    for (int i = 0; i < p.loadsPerFloor; ++i) {
      Object o;
      o.name = "load_" + std::to_string(k) + "_" + std::to_string(i);
      o.model = mLoad;
      const glm::dvec3 base = p.cranes > 0 ? craneBase[static_cast<size_t>(i % p.cranes)] : glm::dvec3(half + 10, 0, 0);
      const glm::dvec3 stage = base + glm::dvec3(rng.range(-8, 8), rng.range(-8, 8), 0);
      const glm::dvec3 target(rng.range(-half, half), rng.range(-half, half), top);
      const double a = s0 + rng.range(0.0, 0.9) * P, lift = a + rng.range(0.1, 0.4) * P, d = 0.01 * P;
      o.visible.push_back({a, lift + 3 * d});
      o.path.push_back({a, O + stage, rng.range(0, 360)});
      o.path.push_back({lift, O + stage, o.path.back().heading_deg});
      o.path.push_back({lift + d, O + glm::dvec3(stage.x, stage.y, top + 10), o.path.back().heading_deg});
      o.path.push_back({lift + 2 * d, O + glm::dvec3(target.x, target.y, top + 10), o.path.back().heading_deg});
      o.path.push_back({lift + 3 * d, O + target, o.path.back().heading_deg});
      s.objects.push_back(std::move(o));
    }
  }
  for (int c = 0; c < p.cranes; ++c) {
    Object o;
    o.name = "crane_jib_" + std::to_string(c);
    o.model = mJib;
    o.visible.push_back({0.0, 0.97 * T});
    const int keys = std::max(8, 4 * F);
    for (int i = 0; i < keys; ++i) o.path.push_back({T * i / keys, O + craneBase[static_cast<size_t>(c)] + glm::dvec3(0, 0, craneTop), rng.range(0, 360)});
    s.objects.push_back(std::move(o));
  }
  const int trucks = scaled(p.trucks);
  const double road = siteHalf - 8.0;
  const glm::dvec3 loop[] = {{-road, -road, 0}, {road, -road, 0}, {road, road - 30, 0}, {-road, road - 30, 0}};
  for (int i = 0; i < trucks; ++i) {
    Object o;
    o.name = "truck_" + std::to_string(i);
    o.model = mTruck;
    const int visits = 6;
    for (int v = 0; v < visits; ++v) {
      const double a = T * (v + rng.range(0.0, 0.8)) / visits, lap = 0.002 * T;
      o.visible.push_back({a, a + 4 * lap});
      for (int q = 0; q <= 4; ++q) {
        const glm::dvec3& from = loop[q % 4];
        const glm::dvec3& to = loop[(q + 1) % 4];
        const double heading = std::atan2(to.x - from.x, to.y - from.y) * 180.0 / kPi;
        o.path.push_back({a + q * lap, O + from, heading});
      }
    }
    s.objects.push_back(std::move(o));
  }
  const int excavators = scaled(p.excavators);
  for (int i = 0; i < excavators; ++i) {
    Object o;
    o.name = "excavator_" + std::to_string(i);
    o.model = mExcavator;
    o.visible.push_back({0.0, 0.06 * T});
    for (int q = 0; q < 20; ++q) {
      o.path.push_back({0.06 * T * q / 20, O + glm::dvec3(rng.range(-half, half), rng.range(-half, half), 0), rng.range(0, 360)});
    }
    s.objects.push_back(std::move(o));
  }
  return s;
}

}  // namespace ig::lod::hdlod
