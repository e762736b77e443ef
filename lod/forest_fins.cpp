// Forest fins (paper 004, shared/SEEDS.md section 004): the dihedral-angle rule on a half-edge
// twin table, the glade rule, tangent-cone groups and their early rejection. Rules in
// forest_fins.h.
#include "lod/forest_fins.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <glm/geometric.hpp>

namespace ig::lod {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

bool finite(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Tangent folded to the half-space of azimuth [0, 180) (the line matters, not its sign).
glm::dvec3 fold(glm::dvec3 t) {
  if (t.y < 0.0 || (t.y == 0.0 && t.x < 0.0)) t = -t;
  return t;
}

bool wholeEdgeInGlade(const ForestMap& map, const glm::dvec3& a, const glm::dvec3& b) {
  const double len = glm::length(glm::dvec2(b - a));
  const int steps = std::max(1, static_cast<int>(std::ceil(len / (0.5 * map.cell_m))));
  for (int i = 0; i <= steps; ++i) {
    const double t = static_cast<double>(i) / steps;
    if (!map.isGlade(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t)) return false;
  }
  return true;
}

}  // namespace

void makeGridMesh(std::span<const float> h, int postsX, int postsY, double s, const glm::dvec3& off,
                  std::vector<glm::dvec3>& positions, std::vector<uint32_t>& triangles) {
  positions.clear();
  triangles.clear();
  if (postsX < 2 || postsY < 2 || h.size() < static_cast<size_t>(postsX) * static_cast<size_t>(postsY)) return;
  positions.reserve(static_cast<size_t>(postsX) * postsY);
  for (int y = 0; y < postsY; ++y) {
    for (int x = 0; x < postsX; ++x) {
      positions.push_back(off + glm::dvec3(x * s, y * s, h[static_cast<size_t>(y) * postsX + x]));
    }
  }
  triangles.reserve(static_cast<size_t>(postsX - 1) * (postsY - 1) * 6);
  for (int y = 0; y + 1 < postsY; ++y) {
    for (int x = 0; x + 1 < postsX; ++x) {
      const auto v = static_cast<uint32_t>(y * postsX + x), px = static_cast<uint32_t>(postsX);
      // (x,y) (x+1,y) (x+1,y+1) and (x,y) (x+1,y+1) (x,y+1): counter-clockwise from above.
      triangles.insert(triangles.end(), {v, v + 1, v + px + 1, v, v + px + 1, v + px});
    }
  }
}

double dihedralThroughGround_deg(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, const glm::dvec3& d) {
  const glm::dvec3 c1 = glm::cross(b - a, c - a), c2 = glm::cross(a - b, d - b);
  const double l1 = glm::length(c1), l2 = glm::length(c2);
  const double scale = glm::length(b - a);
  if (!(l1 > 1e-12 * scale * scale) || !(l2 > 1e-12 * scale * scale)) return std::nan("");
  const glm::dvec3 n1 = c1 / l1, n2 = c2 / l2;
  const double theta = std::atan2(glm::length(glm::cross(n1, n2)), glm::dot(n1, n2)) / kDeg;
  // d below the plane of the first face: the edge is convex (a crest).
  return glm::dot(n1, d - a) < 0.0 ? 180.0 - theta : 180.0 + theta;
}

bool buildFins(std::span<const glm::dvec3> positions, std::span<const uint32_t> triangles, const ForestMap* map,
               const FinParams& p, FinSet& out, std::string& error) {
  out = FinSet{};
  if (!(p.criticalAngle_deg > 0.0 && p.criticalAngle_deg < 360.0)) {
    error = "fins: criticalAngle_deg = " + std::to_string(p.criticalAngle_deg) + ": outside (0, 360)";
    return false;
  }
  if (!(p.finHeight_m >= 0.0) || !std::isfinite(p.finHeight_m)) {
    error = "fins: finHeight_m = " + std::to_string(p.finHeight_m) + ": must be finite and >= 0";
    return false;
  }
  if (!(p.tileSize_m > 0.0) || !std::isfinite(p.tileSize_m)) {
    error = "fins: tileSize_m = " + std::to_string(p.tileSize_m) + ": must be finite and > 0";
    return false;
  }
  if (p.azimuthBins < 1 || p.azimuthBins > 360 || p.elevationBins < 1 || p.elevationBins > 180) {
    error = "fins: azimuthBins = " + std::to_string(p.azimuthBins) + ", elevationBins = " +
            std::to_string(p.elevationBins) + ": outside 1..360 / 1..180";
    return false;
  }
  if (triangles.size() % 3 != 0) {
    error = "fins: triangle index count " + std::to_string(triangles.size()) + " is not a multiple of 3";
    return false;
  }
  for (size_t i = 0; i < triangles.size(); ++i) {
    if (triangles[i] >= positions.size()) {
      error = "fins: index " + std::to_string(i) + " = " + std::to_string(triangles[i]) + ": >= vertex count " +
              std::to_string(positions.size());
      return false;
    }
  }
  if (map) {
    std::string e;
    if (!validateForestMap(*map, e)) {
      error = "fins: " + e;
      return false;
    }
  }
  // Half-edges: h = 3 t + k runs from triangles[h] to triangles[3 t + (k + 1) % 3]. Twins by
  // sorting the undirected keys; an edge with other than two half-edges is a boundary here.
  const size_t nh = triangles.size();
  auto from = [&](size_t h) { return triangles[h]; };
  auto to = [&](size_t h) { return triangles[h - h % 3 + (h % 3 + 1) % 3]; };
  std::vector<uint64_t> keys(nh);
  for (size_t h = 0; h < nh; ++h) {
    const uint64_t u = std::min(from(h), to(h)), v = std::max(from(h), to(h));
    keys[h] = u << 32 | v;
  }
  std::vector<uint32_t> order(nh);
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](uint32_t x, uint32_t y) { return keys[x] < keys[y] || (keys[x] == keys[y] && x < y); });

  std::vector<Fin> fins;
  for (size_t i = 0; i < nh;) {
    size_t j = i;
    while (j < nh && keys[order[j]] == keys[order[i]]) ++j;
    if (j - i == 2) {
      const uint32_t h1 = order[i], h2 = order[i + 1];
      if (from(h1) == to(h2) && to(h1) == from(h2)) {  // consistently oriented pair
        ++out.edgesTested;
        const glm::dvec3 a = positions[from(h1)], b = positions[to(h1)];
        const glm::dvec3 c = positions[triangles[h1 - h1 % 3 + (h1 % 3 + 2) % 3]];
        const glm::dvec3 d = positions[triangles[h2 - h2 % 3 + (h2 % 3 + 2) % 3]];
        const double phi = dihedralThroughGround_deg(a, b, c, d);
        if (phi < p.criticalAngle_deg && finite(a) && finite(b)) {  // NaN (degenerate) fails
          ++out.edgesBelowAngle;
          if (!map || !wholeEdgeInGlade(*map, a, b)) {
            Fin f;
            f.a_m = a;
            f.b_m = b;
            f.tangent = glm::vec3(glm::normalize(b - a));
            f.phi_deg = static_cast<float>(phi);
            fins.push_back(f);
          }
        }
      }
    }
    i = j;
  }
  if (fins.empty()) return true;

  // Group key: tile x, tile y, azimuth bin, elevation bin.
  glm::dvec2 lo(fins[0].a_m);
  for (const Fin& f : fins) lo = glm::min(lo, glm::min(glm::dvec2(f.a_m), glm::dvec2(f.b_m)));
  struct Keyed {
    uint64_t key;
    uint32_t fin;
  };
  std::vector<Keyed> keyed(fins.size());
  for (size_t i = 0; i < fins.size(); ++i) {
    const Fin& f = fins[i];
    const glm::dvec2 mid = 0.5 * (glm::dvec2(f.a_m) + glm::dvec2(f.b_m)) - lo;
    const auto tx = static_cast<uint64_t>(std::min(mid.x / p.tileSize_m, 65535.0));
    const auto ty = static_cast<uint64_t>(std::min(mid.y / p.tileSize_m, 65535.0));
    const glm::dvec3 t = fold(glm::dvec3(f.tangent));
    const double az = std::atan2(t.y, t.x) / kPi;  // [0, 1]
    const double el = std::asin(std::clamp(t.z, -1.0, 1.0)) / kPi + 0.5;  // [0, 1]
    const auto ab = static_cast<uint64_t>(std::min(az * p.azimuthBins, p.azimuthBins - 1.0));
    const auto eb = static_cast<uint64_t>(std::min(el * p.elevationBins, p.elevationBins - 1.0));
    keyed[i] = {ty << 48 | tx << 32 | ab << 16 | eb, static_cast<uint32_t>(i)};
  }
  std::stable_sort(keyed.begin(), keyed.end(), [](const Keyed& x, const Keyed& y) { return x.key < y.key; });
  out.fins.reserve(fins.size());
  const glm::dvec3 up(0.0, 0.0, p.finHeight_m);
  for (size_t i = 0; i < keyed.size();) {
    size_t j = i;
    while (j < keyed.size() && keyed[j].key == keyed[i].key) ++j;
    FinGroup g;
    g.first = static_cast<uint32_t>(out.fins.size());
    g.count = static_cast<uint32_t>(j - i);
    glm::dvec3 sum(0.0);
    const glm::dvec3 ref = fold(glm::dvec3(fins[keyed[i].fin].tangent));
    g.bounds = {fins[keyed[i].fin].a_m, fins[keyed[i].fin].a_m};
    for (size_t k = i; k < j; ++k) {
      const Fin& f = fins[keyed[k].fin];
      out.fins.push_back(f);
      glm::dvec3 t(f.tangent);
      if (glm::dot(t, ref) < 0.0) t = -t;
      sum += t;
      g.bounds.min = glm::min(g.bounds.min, glm::min(f.a_m, f.b_m));
      g.bounds.max = glm::max(g.bounds.max, glm::max(f.a_m, f.b_m) + up);
    }
    g.axis = glm::length(sum) > 1e-9 ? glm::normalize(sum) : ref;
    for (size_t k = i; k < j; ++k) {
      const double c = std::abs(glm::dot(g.axis, glm::dvec3(fins[keyed[k].fin].tangent)));
      // Float tangents: a small margin keeps the cone conservative.
      g.halfAngle_rad = std::max(g.halfAngle_rad, std::acos(std::min(c, 1.0)) + 1e-6);
    }
    g.centre_m = 0.5 * (g.bounds.min + g.bounds.max);
    g.radius_m = 0.5 * glm::length(g.bounds.max - g.bounds.min) * (1.0 + 1e-9) + 1e-6;
    out.groups.push_back(g);
    i = j;
  }
  return true;
}

double finViewAlpha(const glm::dvec3& tangent, const glm::dvec3& eye, const glm::dvec3& point) {
  const glm::dvec3 v = point - eye;
  const double l = glm::length(v);
  if (!(l > 0.0)) return 1.0;
  return 1.0 - std::abs(glm::dot(glm::normalize(tangent), v / l));
}

bool finGroupTransparent(const FinGroup& g, const glm::dvec3& eye, double alphaThreshold) {
  if (!(alphaThreshold > 0.0)) return false;
  const glm::dvec3 vc = g.centre_m - eye;
  const double dist = glm::length(vc);
  if (!(dist > g.radius_m)) return false;  // eye inside the sphere (or NaN)
  const double beta = std::asin(std::min(1.0, g.radius_m / dist));
  const double gamma = std::acos(std::min(1.0, std::abs(glm::dot(g.axis, vc / dist))));
  const double limit = std::acos(std::clamp(1.0 - alphaThreshold, -1.0, 1.0));
  return gamma + g.halfAngle_rad + beta + 1e-7 < limit;  // margin for acos rounding
}

size_t selectFinGroups(std::span<const FinGroup> groups, const Camera& cam, const FarFade& fade, double alphaThreshold,
                       std::span<uint32_t> out, FinSelectStats* stats) {
  FinSelectStats st;
  size_t n = 0;
  const bool ok = finite(cam.eye_m) && std::isfinite(cam.heading_deg + cam.pitch_deg + cam.roll_deg + cam.fovY_deg +
                                                     cam.aspect + cam.near_m + cam.far_m) &&
                  cam.near_m > 0.0 && cam.far_m > cam.near_m && validWindowShift(cam) && out.size() >= groups.size();
  if (ok) {
    const Frustum fr = makeFrustum(cam);
    for (size_t i = 0; i < groups.size(); ++i) {
      const FinGroup& g = groups[i];
      if (distanceToBox(g.bounds, cam.eye_m) >= fade.farPlane_m) continue;
      // Farthest corner nearer than FadeInStart: farAlpha is 0 over the whole group.
      const glm::dvec3 far = glm::max(glm::abs(g.bounds.min - cam.eye_m), glm::abs(g.bounds.max - cam.eye_m));
      if (glm::length(far) <= fade.fadeInStart_m) continue;
      if (!fr.intersects({g.bounds.min - cam.eye_m, g.bounds.max - cam.eye_m})) continue;
      ++st.groupsVisible;
      if (finGroupTransparent(g, cam.eye_m, alphaThreshold)) {
        ++st.groupsRejected;
        continue;
      }
      out[n++] = static_cast<uint32_t>(i);
      st.finsDrawn += g.count;
    }
  }
  if (stats) *stats = st;
  return n;
}

}  // namespace ig::lod
