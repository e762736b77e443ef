#include "lod/heightfield.h"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace ig::lod {
namespace {

uint32_t hash3(uint32_t seed, int32_t x, int32_t y) {
  uint32_t h = seed * 0x9E3779B9u;
  h ^= static_cast<uint32_t>(x) * 0x85EBCA6Bu;
  h = (h << 13) | (h >> 19);
  h ^= static_cast<uint32_t>(y) * 0xC2B2AE35u;
  h ^= h >> 16;
  h *= 0x7FEB352Du;
  h ^= h >> 15;
  h *= 0x846CA68Bu;
  h ^= h >> 16;
  return h;
}

double lattice(uint32_t seed, int32_t x, int32_t y) {
  return static_cast<double>(hash3(seed, x, y) & 0xFFFFFFu) / static_cast<double>(0xFFFFFF);
}

double fade(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }

// Smooth value noise in [0, 1].
double valueNoise(uint32_t seed, double x, double y) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<int32_t>(fx), iy = static_cast<int32_t>(fy);
  const double tx = fade(x - fx), ty = fade(y - fy);
  const double a = lattice(seed, ix, iy), b = lattice(seed, ix + 1, iy);
  const double c = lattice(seed, ix, iy + 1), d = lattice(seed, ix + 1, iy + 1);
  return (a + (b - a) * tx) + ((c + (d - c) * tx) - (a + (b - a) * tx)) * ty;
}

}  // namespace

size_t generateHeightfield(const HeightfieldDesc& desc, std::span<float> heights_m) {
  assert(desc.postsX >= 2 && desc.postsY >= 2 && "generateHeightfield: need at least 2x2 posts");
  const size_t count = static_cast<size_t>(desc.postsX) * static_cast<size_t>(desc.postsY);
  assert(heights_m.size() >= count && "generateHeightfield: output span too small");

  // Base wavelength ~2.5 km; 7 octaves down to ~20 m, clamped below by the post spacing.
  constexpr double kBaseWavelength_m = 2500.0;
  constexpr int kOctaves = 7;
  double norm = 0.0;  // sum of octave amplitudes
  for (int o = 0; o < kOctaves; ++o) norm += std::ldexp(1.0, -o);

  double lo = 1e300, hi = -1e300;
  for (int y = 0; y < desc.postsY; ++y) {
    for (int x = 0; x < desc.postsX; ++x) {
      double sum = 0.0, amplitude = 1.0;
      double fx = x * desc.postSpacing_m / kBaseWavelength_m;
      double fy = y * desc.postSpacing_m / kBaseWavelength_m;
      for (int o = 0; o < kOctaves; ++o) {
        const double n = valueNoise(desc.seed + static_cast<uint32_t>(o) * 7919u, fx, fy);
        // Ridged low octaves give mountain crests; smooth high octaves give texture.
        sum += amplitude * (o < 2 ? 1.0 - std::abs(2.0 * n - 1.0) : n);
        amplitude *= 0.5;
        fx *= 2.03;
        fy *= 2.03;
      }
      const double h = sum / norm;
      heights_m[static_cast<size_t>(y) * static_cast<size_t>(desc.postsX) + static_cast<size_t>(x)] =
          static_cast<float>(h);
      lo = std::min(lo, h);
      hi = std::max(hi, h);
    }
  }
  // Normalise to [0, heightScale_m] with a valley floor: the lowest 15 % is flattened.
  const double range = std::max(hi - lo, 1e-9);
  for (size_t i = 0; i < count; ++i) {
    double t = (static_cast<double>(heights_m[i]) - lo) / range;
    t = std::max(0.0, (t - 0.15) / 0.85);
    heights_m[i] = static_cast<float>(t * t * desc.heightScale_m);
  }
  return count;
}

bool sampleGround(const HeightGrid& g, double east_m, double north_m, GroundSample& out) {
  if (g.width < 2 || g.height < 2 || !(g.spacing_m > 0.0) ||
      g.heights_m.size() < static_cast<size_t>(g.width) * static_cast<size_t>(g.height))
    return false;
  const double fx = (east_m - g.origin_m.x) / g.spacing_m, fy = (north_m - g.origin_m.y) / g.spacing_m;
  // Written so that NaN fails too.
  if (!(fx >= 0.0 && fx <= g.width - 1.0 && fy >= 0.0 && fy <= g.height - 1.0)) return false;
  const int x0 = std::min(static_cast<int>(fx), g.width - 2), y0 = std::min(static_cast<int>(fy), g.height - 2);
  const double tx = fx - x0, ty = fy - y0;
  auto h = [&](int x, int y) {
    return static_cast<double>(g.heights_m[static_cast<size_t>(y) * static_cast<size_t>(g.width) + static_cast<size_t>(x)]);
  };
  const double h00 = h(x0, y0), h10 = h(x0 + 1, y0), h01 = h(x0, y0 + 1), h11 = h(x0 + 1, y0 + 1);
  const double a = h00 + (h10 - h00) * tx, b = h01 + (h11 - h01) * tx;
  out.height_m = g.origin_m.z + a + (b - a) * ty;
  // Gradient of the bilinear patch, per metre.
  const double dzdx = ((h10 - h00) * (1.0 - ty) + (h11 - h01) * ty) / g.spacing_m;
  const double dzdy = ((h01 - h00) * (1.0 - tx) + (h11 - h10) * tx) / g.spacing_m;
  const double len = std::sqrt(dzdx * dzdx + dzdy * dzdy + 1.0);
  out.normal = glm::dvec3(-dzdx / len, -dzdy / len, 1.0 / len);
  return true;
}

namespace {

// Smallest root of a s^2 + b s + c in [0, len] (c > 0 at s = 0), or -1.
double firstRoot(double a, double b, double c, double len) {
  const double scale = std::abs(a) * len * len + std::abs(b) * len + std::abs(c);
  double r0 = -1.0, r1 = -1.0;
  if (std::abs(a) * len * len <= 1e-12 * scale) {  // linear (the ray is parallel to a ruling)
    if (b != 0.0) r0 = -c / b;
  } else {
    const double disc = b * b - 4.0 * a * c;
    if (disc < 0.0) return -1.0;
    const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
    r0 = q / a;
    if (q != 0.0) r1 = c / q;
    if (r1 < r0) std::swap(r0, r1);
    if (r0 < 0.0) r0 = r1;  // the first root is behind the start: take the second
  }
  return r0 >= 0.0 && r0 <= len ? r0 : -1.0;
}

// intersectGround, counting the cells it examines.
bool intersectGroundCounting(const HeightGrid& g, const glm::dvec3& from, const glm::dvec3& to, GroundHit& out,
                             uint32_t& visited) {
  if (g.width < 2 || g.height < 2 || !(g.spacing_m > 0.0) ||
      g.heights_m.size() < static_cast<size_t>(g.width) * static_cast<size_t>(g.height))
    return false;
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(from[i]) || !std::isfinite(to[i])) return false;
  // Grid units: x, y in posts from post (0, 0); z in metres above origin_m.z.
  const double x0 = (from.x - g.origin_m.x) / g.spacing_m, y0 = (from.y - g.origin_m.y) / g.spacing_m;
  const double z0 = from.z - g.origin_m.z;
  const double dx = (to.x - g.origin_m.x) / g.spacing_m - x0, dy = (to.y - g.origin_m.y) / g.spacing_m - y0;
  const double dz = (to.z - g.origin_m.z) - z0;
  if (!std::isfinite(x0) || !std::isfinite(y0) || !std::isfinite(dx) || !std::isfinite(dy) || !std::isfinite(dz))
    return false;
  // Clip t to the grid rectangle [0, width - 1] x [0, height - 1].
  double t0 = 0.0, t1 = 1.0;
  auto clip = [&](double p, double d, double hi) {
    if (d == 0.0) return p >= 0.0 && p <= hi;
    double a = (0.0 - p) / d, b = (hi - p) / d;
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
    return t0 <= t1;
  };
  if (!clip(x0, dx, g.width - 1.0) || !clip(y0, dy, g.height - 1.0)) return false;
  auto h = [&](int x, int y) {
    return static_cast<double>(g.heights_m[static_cast<size_t>(y) * static_cast<size_t>(g.width) + static_cast<size_t>(x)]);
  };
  auto cellOf = [](double p, int cells) { return static_cast<int>(std::clamp(std::floor(p), 0.0, cells - 1.0)); };
  // The cell holding the ground track just after t0 (the middle of a zero-length step stays put).
  const double tc = t0 + std::min(1e-9, 0.5 * (t1 - t0));
  int ix = cellOf(x0 + dx * tc, g.width - 1), iy = cellOf(y0 + dy * tc, g.height - 1);
  const int stepX = dx > 0.0 ? 1 : -1, stepY = dy > 0.0 ? 1 : -1;
  auto nextBoundary = [](int cell, int step, double p, double d) {
    if (d == 0.0) return HUGE_VAL;
    return ((step > 0 ? cell + 1.0 : static_cast<double>(cell)) - p) / d;
  };
  double tMaxX = nextBoundary(ix, stepX, x0, dx), tMaxY = nextBoundary(iy, stepY, y0, dy);
  const double tDeltaX = dx != 0.0 ? std::abs(1.0 / dx) : HUGE_VAL, tDeltaY = dy != 0.0 ? std::abs(1.0 / dy) : HUGE_VAL;
  double ta = t0;
  for (int steps = 0; steps <= g.width + g.height; ++steps) {
    ++visited;
    const double tb = std::min({tMaxX, tMaxY, t1});
    // The patch over cell (ix, iy): h00 + p u + q v + r u v with u, v in [0, 1]; along the
    // segment u = ua + du s, v = va + dv s, z = za + dz s with s = t - ta.
    const double h00 = h(ix, iy), h10 = h(ix + 1, iy), h01 = h(ix, iy + 1), h11 = h(ix + 1, iy + 1);
    const double p = h10 - h00, q = h01 - h00, r = h00 - h10 - h01 + h11;
    const double ua = x0 + dx * ta - ix, va = y0 + dy * ta - iy, za = z0 + dz * ta;
    // f(s) = z - height: c + b s + a s^2.
    const double c = za - (h00 + p * ua + q * va + r * ua * va);
    const double b = dz - (p * dx + q * dy + r * (ua * dy + va * dx));
    const double a = -r * dx * dy;
    double s = -1.0;
    if (c <= 0.0) {
      s = 0.0;  // on or below the surface where the segment enters this cell
    } else if (tb > ta) {
      s = firstRoot(a, b, c, tb - ta);
    }
    if (s >= 0.0) {
      const double t = std::clamp(ta + s, t0, t1);
      const glm::dvec3 point = from + (to - from) * t;
      GroundSample ground;
      if (!sampleGround(g, point.x, point.y, ground)) {
        // Rounding put the point a hair outside the grid: take the nearest grid point.
        const double ex = std::clamp(point.x, g.origin_m.x, g.origin_m.x + (g.width - 1) * g.spacing_m);
        const double ny = std::clamp(point.y, g.origin_m.y, g.origin_m.y + (g.height - 1) * g.spacing_m);
        if (!sampleGround(g, ex, ny, ground)) return false;
      }
      out.t = t;
      out.point_m = {point.x, point.y, ground.height_m};
      out.normal = ground.normal;
      return true;
    }
    if (tb >= t1) return false;
    if (tMaxX < tMaxY) {
      ix += stepX;
      tMaxX += tDeltaX;
    } else {
      iy += stepY;
      tMaxY += tDeltaY;
    }
    if (ix < 0 || iy < 0 || ix > g.width - 2 || iy > g.height - 2) return false;
    ta = tb;
  }
  return false;
}
}  // namespace

bool intersectGround(const HeightGrid& g, const glm::dvec3& from, const glm::dvec3& to, GroundHit& out,
                     uint32_t* cellsVisited) {
  uint32_t cells = 0;
  const bool hit = intersectGroundCounting(g, from, to, out, cells);
  if (cellsVisited) *cellsVisited = cells;
  return hit;
}

}  // namespace ig::lod
