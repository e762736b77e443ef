// Forest data for paper 004 (shared/SEEDS.md section 004): distribution map, deterministic tree
// placement and the distance fade functions.
#include "lod/forest.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace ig::lod {
namespace {

double unit(uint32_t h) { return (h >> 8) * (1.0 / 16777216.0); }  // [0, 1)

// Value noise on a lattice of period 1, smooth-step interpolated.
double valueNoise(uint32_t seed, double x, double y) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<uint32_t>(static_cast<int64_t>(fx)), iy = static_cast<uint32_t>(static_cast<int64_t>(fy));
  double tx = x - fx, ty = y - fy;
  tx = tx * tx * (3 - 2 * tx);
  ty = ty * ty * (3 - 2 * ty);
  const double a = unit(forestHash(seed, ix, iy)), b = unit(forestHash(seed, ix + 1, iy));
  const double c = unit(forestHash(seed, ix, iy + 1)), d = unit(forestHash(seed, ix + 1, iy + 1));
  return (a + (b - a) * tx) + ((c + (d - c) * tx) - (a + (b - a) * tx)) * ty;
}

double fbm(uint32_t seed, double x, double y) {
  double sum = 0, amp = 0.5, norm = 0;
  for (int o = 0; o < 4; ++o) {
    sum += amp * valueNoise(seed + static_cast<uint32_t>(o) * 977u, x, y);
    norm += amp;
    x *= 2.03;
    y *= 2.03;
    amp *= 0.5;
  }
  return sum / norm;
}

uint8_t toByte(double v) { return static_cast<uint8_t>(std::clamp(std::lround(v * 255.0), 0L, 255L)); }

}  // namespace

uint32_t forestHash(uint32_t a, uint32_t b, uint32_t c) {
  uint32_t h = a * 0x9E3779B1u ^ (b + 0x7F4A7C15u) * 0x85EBCA77u ^ (c + 0x165667B1u) * 0xC2B2AE3Du;
  h ^= h >> 15;
  h *= 0x2C1B3C6Du;
  h ^= h >> 12;
  h *= 0x297A2D39u;
  h ^= h >> 15;
  return h;
}

bool ForestMap::cellAt(double east_m, double north_m, int& cx, int& cy) const {
  const double fx = (east_m - origin_m.x) / cell_m, fy = (north_m - origin_m.y) / cell_m;
  if (!(fx >= 0.0 && fy >= 0.0 && fx < width && fy < height)) return false;  // NaN fails too
  cx = std::min(static_cast<int>(fx), width - 1);
  cy = std::min(static_cast<int>(fy), height - 1);
  return true;
}

bool ForestMap::isGlade(double east_m, double north_m) const {
  int cx = 0, cy = 0;
  if (!cellAt(east_m, north_m, cx, cy)) return true;
  return (gr[static_cast<size_t>(cy) * width + cx] >> 24) == 0;
}

float ForestMap::densityAt(double east_m, double north_m) const {
  int cx = 0, cy = 0;
  return cellAt(east_m, north_m, cx, cy) ? density[static_cast<size_t>(cy) * width + cx] : 0.0f;
}

uint32_t ForestMap::grAt(double east_m, double north_m) const {
  int cx = 0, cy = 0;
  return cellAt(east_m, north_m, cx, cy) ? gr[static_cast<size_t>(cy) * width + cx] : 0u;
}

ForestMap generateForestMap(const ForestMapDesc& d) {
  ForestMap m;
  m.width = d.width;
  m.height = d.height;
  m.cell_m = d.cell_m;
  m.origin_m = d.origin_m;
  const size_t n = static_cast<size_t>(std::max(d.width, 0)) * static_cast<size_t>(std::max(d.height, 0));
  m.density.resize(n);
  m.gr.resize(n);
  const double k = d.cell_m / d.featureSize_m;
  // Glades: the cells where a second noise is lowest, exactly gladeFraction of them.
  std::vector<double> g(n);
  for (int y = 0; y < d.height; ++y) {
    for (int x = 0; x < d.width; ++x) g[static_cast<size_t>(y) * d.width + x] = fbm(d.seed ^ 0xA5A5A5u, (x + 0.5) * k * 0.7, (y + 0.5) * k * 0.7);
  }
  double gladeCut = -1.0;
  const auto nGlade = static_cast<size_t>(std::clamp(d.gladeFraction, 0.0, 1.0) * static_cast<double>(n));
  if (nGlade > 0) {
    std::vector<double> sorted = g;
    std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(nGlade - 1), sorted.end());
    gladeCut = sorted[nGlade - 1];
  }
  for (int y = 0; y < d.height; ++y) {
    for (int x = 0; x < d.width; ++x) {
      const double px = (x + 0.5) * k, py = (y + 0.5) * k;
      const size_t i = static_cast<size_t>(y) * d.width + x;
      const double dens = std::clamp(0.9 + 1.1 * (fbm(d.seed, px, py) - 0.5), 0.0, 1.0);
      const bool glade = g[i] <= gladeCut;
      const double t = fbm(d.seed ^ 0x5A5A5Au, px * 1.3, py * 1.3);
      const uint32_t r = toByte(0.35 + 0.5 * t), gg = toByte(0.45 + 0.35 * (1 - t)), b = toByte(0.3 + 0.2 * t);
      m.density[i] = static_cast<float>(dens);
      m.gr[i] = r | gg << 8 | b << 16 | (glade ? 0u : 255u) << 24;
    }
  }
  return m;
}

bool validateForestMap(const ForestMap& m, std::string& error) {
  if (m.width <= 0 || m.height <= 0) {
    error = "forest map: size " + std::to_string(m.width) + " x " + std::to_string(m.height) + ": must be positive";
    return false;
  }
  if (!(m.cell_m > 0.0) || !std::isfinite(m.cell_m)) {
    error = "forest map: cell_m = " + std::to_string(m.cell_m) + ": must be finite and > 0";
    return false;
  }
  if (!std::isfinite(m.origin_m.x) || !std::isfinite(m.origin_m.y)) {
    error = "forest map: origin_m is not finite";
    return false;
  }
  const size_t n = static_cast<size_t>(m.width) * static_cast<size_t>(m.height);
  if (m.density.size() != n || m.gr.size() != n) {
    error = "forest map: density has " + std::to_string(m.density.size()) + " and gr " + std::to_string(m.gr.size()) +
            " values, expected " + std::to_string(n);
    return false;
  }
  for (size_t i = 0; i < n; ++i) {
    if (!(m.density[i] >= 0.0f && m.density[i] <= 1.0f)) {
      error = "forest map: density[" + std::to_string(i) + "] = " + std::to_string(m.density[i]) + ": outside [0, 1]";
      return false;
    }
  }
  return true;
}

double ForestHeightField::heightAt(double east_m, double north_m) const {
  const double fx = std::clamp((east_m - origin_m.x) / spacing_m, 0.0, width - 1.0);
  const double fy = std::clamp((north_m - origin_m.y) / spacing_m, 0.0, height - 1.0);
  if (!std::isfinite(fx) || !std::isfinite(fy) || width < 2 || height < 2) return origin_m.z;
  const int x0 = std::min(static_cast<int>(fx), width - 2), y0 = std::min(static_cast<int>(fy), height - 2);
  const double tx = fx - x0, ty = fy - y0;
  auto h = [&](int x, int y) {
    return static_cast<double>(heights_m[static_cast<size_t>(y) * static_cast<size_t>(width) + static_cast<size_t>(x)]);
  };
  const double h00 = h(x0, y0), h11 = h(x0 + 1, y0 + 1);
  // Triangles (x,y) (x+1,y) (x+1,y+1) below the diagonal (tx >= ty) and (x,y) (x+1,y+1) (x,y+1).
  const double z = tx >= ty ? h00 + (h(x0 + 1, y0) - h00) * tx + (h11 - h(x0 + 1, y0)) * ty
                            : h00 + (h11 - h(x0, y0 + 1)) * tx + (h(x0, y0 + 1) - h00) * ty;
  return origin_m.z + z;
}

namespace {

template <class Ground>
bool placeTreesOn(const ForestMap& map, const Ground& terrain, const TreePlacementDesc& d,
                  std::vector<TreeInstance>& out, std::string& error) {
  out.clear();
  if (!validateForestMap(map, error)) return false;
  if (!(d.spacing_m > 0.0) || !std::isfinite(d.spacing_m)) {
    error = "tree placement: spacing_m = " + std::to_string(d.spacing_m) + ": must be finite and > 0";
    return false;
  }
  if (!(d.jitter >= 0.0 && d.jitter <= 1.0)) {
    error = "tree placement: jitter = " + std::to_string(d.jitter) + ": outside [0, 1]";
    return false;
  }
  if (d.modelCount < 1 || d.modelCount > 256) {
    error = "tree placement: modelCount = " + std::to_string(d.modelCount) + ": outside 1..256";
    return false;
  }
  const double slotsX = std::floor(map.extentEast_m() / d.spacing_m), slotsY = std::floor(map.extentNorth_m() / d.spacing_m);
  if (slotsX * slotsY > 2.0e9) {
    error = "tree placement: spacing_m = " + std::to_string(d.spacing_m) + ": too many slots for the map";
    return false;
  }
  const int nx = static_cast<int>(slotsX), ny = static_cast<int>(slotsY);
  out.reserve(static_cast<size_t>(0.8 * nx * ny));
  const double s = d.spacing_m, e = 0.5 * s;
  for (int y = 0; y < ny; ++y) {
    for (int x = 0; x < nx; ++x) {
      const auto ux = static_cast<uint32_t>(x), uy = static_cast<uint32_t>(y);
      const uint32_t h0 = forestHash(d.seed, ux, uy), h1 = forestHash(d.seed + 1, ux, uy);
      const uint32_t h2 = forestHash(d.seed + 2, ux, uy), h3 = forestHash(d.seed + 3, ux, uy);
      const double east = map.origin_m.x + (x + 0.5 + d.jitter * (unit(h0) - 0.5)) * s;
      const double north = map.origin_m.y + (y + 0.5 + d.jitter * (unit(h1) - 0.5)) * s;
      int cx = 0, cy = 0;
      if (!map.cellAt(east, north, cx, cy)) continue;
      const size_t ci = static_cast<size_t>(cy) * map.width + cx;
      const uint32_t gr = map.gr[ci];
      if ((gr >> 24) == 0 || unit(h2) >= static_cast<double>(map.density[ci])) continue;
      TreeInstance t;
      t.base_m = {east, north, terrain.heightAt(east, north)};
      const glm::dvec3 n = glm::normalize(glm::dvec3(terrain.heightAt(east - e, north) - terrain.heightAt(east + e, north),
                                                     terrain.heightAt(east, north - e) - terrain.heightAt(east, north + e),
                                                     2.0 * e));
      t.normal = glm::vec3(n);
      // Per-tree brightness variation of +-12 % on the tint.
      const double v = 0.88 + 0.24 * unit(h3 * 2654435761u);
      const auto ch = [&](int shift) { return static_cast<uint32_t>(toByte(((gr >> shift) & 255u) / 255.0 * v)) << shift; };
      t.rgba = ch(0) | ch(8) | ch(16) | 255u << 24;
      t.model = static_cast<uint8_t>(h3 % static_cast<uint32_t>(d.modelCount));
      out.push_back(t);
    }
  }
  return true;
}

}  // namespace

bool placeTrees(const ForestMap& map, const TerrainGrid& terrain, const TreePlacementDesc& d,
                std::vector<TreeInstance>& out, std::string& error) {
  return placeTreesOn(map, terrain, d, out, error);
}

bool placeTrees(const ForestMap& map, const ForestHeightField& ground, const TreePlacementDesc& d,
                std::vector<TreeInstance>& out, std::string& error) {
  if (ground.width < 2 || ground.height < 2 ||
      ground.heights_m.size() < static_cast<size_t>(ground.width) * static_cast<size_t>(ground.height)) {
    out.clear();
    error = "tree placement: height field " + std::to_string(ground.width) + " x " + std::to_string(ground.height) +
            " with " + std::to_string(ground.heights_m.size()) + " samples: needs at least 2 x 2 posts, all present";
    return false;
  }
  if (!(ground.spacing_m > 0.0) || !std::isfinite(ground.spacing_m)) {
    out.clear();
    error = "tree placement: height field spacing_m = " + std::to_string(ground.spacing_m) + ": must be finite and > 0";
    return false;
  }
  return placeTreesOn(map, ground, d, out, error);
}

double farAlpha(const FarFade& f, double d) {
  if (!(d > f.fadeInStart_m) || d >= f.farPlane_m) return 0.0;  // NaN -> 0
  if (d < f.fadeInEnd_m) return (d - f.fadeInStart_m) / (f.fadeInEnd_m - f.fadeInStart_m);
  if (d <= f.fadeOut_m) return 1.0;
  return (f.farPlane_m - d) / (f.farPlane_m - f.fadeOut_m);
}

double nearAlpha(const NearFade& f, double d) {
  if (std::isnan(d) || d >= f.fadeOutEnd_m) return 0.0;
  if (d <= f.fadeOutStart_m) return 1.0;
  return (f.fadeOutEnd_m - d) / (f.fadeOutEnd_m - f.fadeOutStart_m);
}

bool validateForestFades(const FarFade& a, const NearFade& b, std::string& error) {
  const double v[6] = {a.fadeInStart_m, a.fadeInEnd_m, a.fadeOut_m, a.farPlane_m, b.fadeOutStart_m, b.fadeOutEnd_m};
  const char* names[6] = {"FadeInStart", "FadeInEnd", "FadeOut", "FarPlane", "near FadeOutStart", "near FadeOutEnd"};
  for (int i = 0; i < 6; ++i) {
    if (!std::isfinite(v[i]) || v[i] < 0.0) {
      error = std::string("forest fades: ") + names[i] + " = " + std::to_string(v[i]) + ": must be finite and >= 0";
      return false;
    }
  }
  if (!(a.fadeInStart_m < a.fadeInEnd_m && a.fadeInEnd_m <= a.fadeOut_m && a.fadeOut_m < a.farPlane_m)) {
    error = "forest fades: need FadeInStart < FadeInEnd <= FadeOut < FarPlane, got " + std::to_string(a.fadeInStart_m) +
            ", " + std::to_string(a.fadeInEnd_m) + ", " + std::to_string(a.fadeOut_m) + ", " + std::to_string(a.farPlane_m);
    return false;
  }
  if (!(b.fadeOutStart_m < b.fadeOutEnd_m)) {
    error = "forest fades: near FadeOutStart = " + std::to_string(b.fadeOutStart_m) + " must be < near FadeOutEnd = " +
            std::to_string(b.fadeOutEnd_m);
    return false;
  }
  if (!(b.fadeOutStart_m < a.fadeInEnd_m && b.fadeOutEnd_m > a.fadeInStart_m)) {
    error = "forest fades: near band [" + std::to_string(b.fadeOutStart_m) + ", " + std::to_string(b.fadeOutEnd_m) +
            "] does not overlap the far fade-in band [" + std::to_string(a.fadeInStart_m) + ", " +
            std::to_string(a.fadeInEnd_m) + "]";
    return false;
  }
  return true;
}

}  // namespace ig::lod
