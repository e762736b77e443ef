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

}  // namespace ig::lod
