#include "lod/cells_voxel.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vector_relational.hpp>

namespace ig::lod {
namespace {

constexpr double kPi = 3.14159265358979323846;

uint64_t part1by2(uint32_t v) {
  uint64_t x = v & 0x1FFFFFu;
  x = (x | x << 32) & 0x1F00000000FFFFull;
  x = (x | x << 16) & 0x1F0000FF0000FFull;
  x = (x | x << 8) & 0x100F00F00F00F00Full;
  x = (x | x << 4) & 0x10C30C30C30C30C3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}
uint32_t compact1by2(uint64_t x) {
  x &= 0x1249249249249249ull;
  x = (x ^ (x >> 2)) & 0x10C30C30C30C30C3ull;
  x = (x ^ (x >> 4)) & 0x100F00F00F00F00Full;
  x = (x ^ (x >> 8)) & 0x1F0000FF0000FFull;
  x = (x ^ (x >> 16)) & 0x1F00000000FFFFull;
  x = (x ^ (x >> 32)) & 0x1FFFFFull;
  return static_cast<uint32_t>(x);
}

// The colour carried in the low bits of a packed voxel (Morton code << colourBits | colour): RGB888
// when the code leaves room (3 levels + 24 <= 64, i.e. up to 13 levels), else RGB565 (14..16
// levels). RGBA8 (0xAABBGGRR) <-> RGB565:
uint32_t toRgb565(uint32_t rgba) {
  const uint32_t r = rgba & 0xFF, g = (rgba >> 8) & 0xFF, b = (rgba >> 16) & 0xFF;
  return (r >> 3) << 11 | (g >> 2) << 5 | (b >> 3);
}
void addRgb565(uint32_t c, std::array<uint64_t, 3>& sum) {
  const uint32_t r = (c >> 11) & 31, g = (c >> 5) & 63, b = c & 31;
  sum[0] += (r << 3) | (r >> 2);
  sum[1] += (g << 2) | (g >> 4);
  sum[2] += (b << 3) | (b >> 2);
}
void addPacked(uint32_t c, int colourBits, std::array<uint64_t, 3>& sum) {
  if (colourBits == 16) return addRgb565(c, sum);
  for (int ch = 0; ch < 3; ++ch) sum[static_cast<size_t>(ch)] += (c >> (8 * ch)) & 0xFF;
}
uint32_t rgbaFromSum(const std::array<uint64_t, 3>& sum, uint64_t n) {
  const auto ch = [&](int i) { return static_cast<uint32_t>((sum[static_cast<size_t>(i)] + n / 2) / n); };
  return ch(0) | ch(1) << 8 | ch(2) << 16 | 0xFF000000u;
}
uint32_t meanColor(uint32_t a, uint32_t b, uint32_t c) {
  uint32_t out = 0;
  for (int s = 0; s < 32; s += 8) out |= (((a >> s) & 0xFF) + ((b >> s) & 0xFF) + ((c >> s) & 0xFF) + 1) / 3 << s;
  return out;
}

// Triangle / axis-aligned cube overlap (separating axes, Akenine-Moller), the cube centred at
// the origin with half edge h, the triangle already translated.
bool triCubeOverlap(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, double h) {
  for (int i = 0; i < 3; ++i) {
    if (std::min({a[i], b[i], c[i]}) > h || std::max({a[i], b[i], c[i]}) < -h) return false;
  }
  const glm::dvec3 e[3] = {b - a, c - b, a - c};
  const glm::dvec3 n = glm::cross(e[0], e[1]);
  const double r0 = h * (std::abs(n.x) + std::abs(n.y) + std::abs(n.z));
  if (std::abs(glm::dot(n, a)) > r0) return false;
  for (const auto& ed : e) {
    for (int i = 0; i < 3; ++i) {
      glm::dvec3 axis(0.0);
      axis[(i + 1) % 3] = -ed[(i + 2) % 3];
      axis[(i + 2) % 3] = ed[(i + 1) % 3];
      const double pa = glm::dot(axis, a), pb = glm::dot(axis, b), pc = glm::dot(axis, c);
      const double r = h * (std::abs(axis.x) + std::abs(axis.y) + std::abs(axis.z));
      if (std::min({pa, pb, pc}) > r || std::max({pa, pb, pc}) < -r) return false;
    }
  }
  return true;
}

int clampi(double v, int lo, int hi) {
  if (!(v > lo)) return lo;
  if (v > hi) return hi;
  return static_cast<int>(v);
}

// Emits every voxel (finest level, voxel units) the triangle touches.
void voxelizeTriangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, int res, uint32_t colour,
                      int colourBits, std::vector<uint64_t>& out) {
  const glm::dvec3 lo = glm::min(a, glm::min(b, c)), hi = glm::max(a, glm::max(b, c));
  int ilo[3], ihi[3];
  for (int i = 0; i < 3; ++i) {
    ilo[i] = clampi(std::floor(lo[i]), 0, res - 1);
    ihi[i] = clampi(std::floor(hi[i]), 0, res - 1);
  }
  const glm::dvec3 n = glm::cross(b - a, c - a);
  int k = 2;
  if (std::abs(n.x) >= std::abs(n.y) && std::abs(n.x) >= std::abs(n.z)) k = 0;
  else if (std::abs(n.y) >= std::abs(n.z)) k = 1;
  const int u = (k + 1) % 3, v = (k + 2) % 3;
  const double nk = n[k];
  for (int iu = ilo[u]; iu <= ihi[u]; ++iu) {
    for (int iv = ilo[v]; iv <= ihi[v]; ++iv) {
      int k0 = ilo[k], k1 = ihi[k];
      if (nk != 0.0) {
        // The plane's k over the column's square, clipped to the triangle's k range.
        const double d = glm::dot(n, a);
        double zmin = hi[k], zmax = lo[k];
        for (int corner = 0; corner < 4; ++corner) {
          const double pu = iu + (corner & 1), pv = iv + (corner >> 1);
          const double z = (d - n[u] * pu - n[v] * pv) / nk;
          zmin = std::min(zmin, z);
          zmax = std::max(zmax, z);
        }
        k0 = std::max(k0, clampi(std::floor(zmin), 0, res - 1));
        k1 = std::min(k1, clampi(std::floor(zmax), 0, res - 1));
      }
      for (int ik = k0; ik <= k1; ++ik) {
        int idx[3];
        idx[k] = ik;
        idx[u] = iu;
        idx[v] = iv;
        const glm::dvec3 ctr(idx[0] + 0.5, idx[1] + 0.5, idx[2] + 0.5);
        if (!triCubeOverlap(a - ctr, b - ctr, c - ctr, 0.5)) continue;
        out.push_back(mortonEncode(static_cast<uint32_t>(idx[0]), static_cast<uint32_t>(idx[1]),
                                   static_cast<uint32_t>(idx[2])) << colourBits | colour);
      }
    }
  }
}

struct Crossing {
  uint64_t column;
  double z;
  uint32_t colour;
};

// Fills the inside of a closed mesh: rays along +z through each column's centre (nudged off the
// grid so that they miss edges and vertices placed on it), inside between crossings 2i and 2i+1.
void fillSolid(const std::vector<glm::dvec3>& p, const std::vector<uint32_t>& idx,
               const std::vector<uint32_t>& colour, int colourBits, int res, std::vector<uint64_t>& out) {
  constexpr double kDx = 0.5 + 1.234567e-6, kDy = 0.5 + 2.345678e-6;
  std::vector<Crossing> cross;
  for (size_t t = 0; t + 2 < idx.size(); t += 3) {
    const glm::dvec3 &a = p[idx[t]], &b = p[idx[t + 1]], &c = p[idx[t + 2]];
    const double area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if (area == 0.0) continue;
    const int x0 = clampi(std::floor(std::min({a.x, b.x, c.x}) - kDx), 0, res - 1);
    const int x1 = clampi(std::ceil(std::max({a.x, b.x, c.x}) - kDx), 0, res - 1);
    const int y0 = clampi(std::floor(std::min({a.y, b.y, c.y}) - kDy), 0, res - 1);
    const int y1 = clampi(std::ceil(std::max({a.y, b.y, c.y}) - kDy), 0, res - 1);
    for (int x = x0; x <= x1; ++x) {
      for (int y = y0; y <= y1; ++y) {
        const double px = x + kDx, py = y + kDy;
        const double w0 = ((b.x - px) * (c.y - py) - (b.y - py) * (c.x - px)) / area;
        const double w1 = ((c.x - px) * (a.y - py) - (c.y - py) * (a.x - px)) / area;
        const double w2 = 1.0 - w0 - w1;
        if (w0 < 0.0 || w1 < 0.0 || w2 < 0.0) continue;
        cross.push_back({static_cast<uint64_t>(x) << 32 | static_cast<uint32_t>(y), w0 * a.z + w1 * b.z + w2 * c.z,
                         colour[t / 3]});
      }
    }
  }
  std::sort(cross.begin(), cross.end(),
            [](const Crossing& l, const Crossing& r) { return l.column != r.column ? l.column < r.column : l.z < r.z; });
  for (size_t i = 0; i < cross.size();) {
    size_t j = i;
    while (j < cross.size() && cross[j].column == cross[i].column) ++j;
    const auto x = static_cast<uint32_t>(cross[i].column >> 32), y = static_cast<uint32_t>(cross[i].column);
    for (size_t m = i; m + 1 < j; m += 2) {
      const int z0 = clampi(std::ceil(cross[m].z - 0.5), 0, res);
      const int z1 = clampi(std::floor(cross[m + 1].z - 0.5), -1, res - 1);
      for (int z = z0; z <= z1; ++z) out.push_back(mortonEncode(x, y, static_cast<uint32_t>(z)) << colourBits | cross[m].colour);
    }
    i = j;
  }
}

}  // namespace

uint64_t mortonEncode(uint32_t x, uint32_t y, uint32_t z) { return part1by2(x) | part1by2(y) << 1 | part1by2(z) << 2; }
glm::uvec3 mortonDecode(uint64_t code) { return {compact1by2(code), compact1by2(code >> 1), compact1by2(code >> 2)}; }

double VoxelPyramid::dimension(int level) const {
  const double n0 = static_cast<double>(count(level)), n1 = static_cast<double>(count(level + 1));
  return n0 > 0.0 && n1 > 0.0 ? std::log2(n1 / n0) : 0.0;
}

double VoxelPyramid::boxCountingDimension(int level) const {
  const double n = static_cast<double>(count(level));
  return level > 0 && n > 0.0 ? std::log2(n) / level : 0.0;
}

void appendSphere(VoxelMesh& mesh, const glm::dvec3& center_m, double radius_m, int segments, uint32_t color) {
  segments = std::max(segments, 3);
  const int rings = std::max(segments / 2, 2);
  const auto base = static_cast<uint32_t>(mesh.positions_m.size());
  for (int r = 0; r <= rings; ++r) {
    const double th = kPi * r / rings;
    for (int s = 0; s <= segments; ++s) {
      const double ph = 2.0 * kPi * s / segments;
      mesh.positions_m.push_back(center_m + radius_m * glm::dvec3(std::sin(th) * std::cos(ph),
                                                                  std::sin(th) * std::sin(ph), std::cos(th)));
      mesh.colors.push_back(color);
    }
  }
  const auto row = static_cast<uint32_t>(segments + 1);
  for (uint32_t r = 0; r < static_cast<uint32_t>(rings); ++r) {
    for (uint32_t s = 0; s < static_cast<uint32_t>(segments); ++s) {
      const uint32_t i0 = base + r * row + s, i1 = i0 + 1, i2 = i0 + row, i3 = i2 + 1;
      mesh.indices.insert(mesh.indices.end(), {i0, i2, i1, i1, i2, i3});
    }
  }
}

void appendQuad(VoxelMesh& mesh, const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, const glm::dvec3& d,
                uint32_t color) {
  const auto base = static_cast<uint32_t>(mesh.positions_m.size());
  for (const auto& p : {a, b, c, d}) {
    mesh.positions_m.push_back(p);
    mesh.colors.push_back(color);
  }
  mesh.indices.insert(mesh.indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
}

void appendBox(VoxelMesh& mesh, const glm::dvec3& lo, const glm::dvec3& hi, uint32_t color) {
  const auto P = [&](int i) { return glm::dvec3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z); };
  appendQuad(mesh, P(0), P(2), P(3), P(1), color);  // -z
  appendQuad(mesh, P(4), P(5), P(7), P(6), color);  // +z
  appendQuad(mesh, P(0), P(1), P(5), P(4), color);  // -y
  appendQuad(mesh, P(2), P(6), P(7), P(3), color);  // +y
  appendQuad(mesh, P(0), P(4), P(6), P(2), color);  // -x
  appendQuad(mesh, P(1), P(3), P(7), P(5), color);  // +x
}

bool voxelize(const VoxelMesh& mesh, const VoxelizeConfig& config, VoxelPyramid& out, std::string& error) {
  out = VoxelPyramid{};
  char msg[256];
  if (config.levels < 1 || config.levels > kMaxVoxelLevels) {
    std::snprintf(msg, sizeof msg, "voxelize: levels = %d: allowed range 1..%d", config.levels, kMaxVoxelLevels);
    error = msg;
    return false;
  }
  if (mesh.indices.size() % 3 != 0) {
    std::snprintf(msg, sizeof msg, "voxelize: %zu indices: not a multiple of 3", mesh.indices.size());
    error = msg;
    return false;
  }
  if (!mesh.colors.empty() && mesh.colors.size() != mesh.positions_m.size()) {
    std::snprintf(msg, sizeof msg, "voxelize: %zu colours for %zu vertices: need one per vertex or none",
                  mesh.colors.size(), mesh.positions_m.size());
    error = msg;
    return false;
  }
  for (size_t i = 0; i < mesh.positions_m.size(); ++i) {
    const auto& p = mesh.positions_m[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      std::snprintf(msg, sizeof msg, "voxelize: vertex %zu = (%g, %g, %g): not finite", i, p.x, p.y, p.z);
      error = msg;
      return false;
    }
  }
  for (size_t i = 0; i < mesh.indices.size(); ++i) {
    if (mesh.indices[i] >= mesh.positions_m.size()) {
      std::snprintf(msg, sizeof msg, "voxelize: index %zu = %u: only %zu vertices", i, mesh.indices[i],
                    mesh.positions_m.size());
      error = msg;
      return false;
    }
  }
  // Bounds of the vertices that triangles use.
  glm::dvec3 lo(0.0), hi(0.0);
  for (size_t i = 0; i < mesh.indices.size(); ++i) {
    const auto& p = mesh.positions_m[mesh.indices[i]];
    lo = i == 0 ? p : glm::min(lo, p);
    hi = i == 0 ? p : glm::max(hi, p);
  }
  if (config.boxEdge_m > 0.0 || std::isnan(config.boxEdge_m)) {  // NaN: no box, not "fit one"
    if (!std::isfinite(config.boxEdge_m) || !std::isfinite(config.boxMin_m.x) || !std::isfinite(config.boxMin_m.y) ||
        !std::isfinite(config.boxMin_m.z)) {
      error = "voxelize: the box is not finite";
      return false;
    }
    out.boxMin_m = config.boxMin_m;
    out.boxEdge_m = config.boxEdge_m;
    const glm::dvec3 bmax = config.boxMin_m + glm::dvec3(config.boxEdge_m);
    if (!mesh.indices.empty() && (glm::any(glm::lessThan(lo, config.boxMin_m)) || glm::any(glm::greaterThan(hi, bmax)))) {
      std::snprintf(msg, sizeof msg, "voxelize: mesh bounds (%g, %g, %g)..(%g, %g, %g) outside the box (%g, %g, %g) + %g",
                    lo.x, lo.y, lo.z, hi.x, hi.y, hi.z, config.boxMin_m.x, config.boxMin_m.y, config.boxMin_m.z,
                    config.boxEdge_m);
      error = msg;
      return false;
    }
  } else {
    const double size = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    const double pad = size > 0.0 ? size * 1e-6 : 1.0;
    out.boxEdge_m = size + 2.0 * pad;
    out.boxMin_m = 0.5 * (lo + hi) - glm::dvec3(0.5 * out.boxEdge_m);
  }
  const int L = config.levels, res = 1 << L;
  const int colourBits = 3 * L + 24 <= 64 ? 24 : 16;
  const uint64_t colourMask = (uint64_t{1} << colourBits) - 1;
  const double toVoxel = res / out.boxEdge_m;

  // Clamped to [0, res]: the mesh lies in the box (checked above, or the fitted box holds it),
  // so anything outside is rounding, e.g. a vertex on the box's max face (boxMin + edge) mapping
  // to res + 1e-13, which the exact overlap test would then reject for every voxel (and a small
  // mesh far from the origin whose padding is under one ulp). Unclamped, such triangles vanish.
  std::vector<glm::dvec3> p(mesh.positions_m.size());
  for (size_t i = 0; i < p.size(); ++i)
    p[i] = glm::clamp((mesh.positions_m[i] - out.boxMin_m) * toVoxel, glm::dvec3(0.0), glm::dvec3(res));
  std::vector<uint32_t> triColor(mesh.indices.size() / 3);
  for (size_t t = 0; t < triColor.size(); ++t) {
    const auto col = [&](size_t k) { return mesh.colors.empty() ? 0xFFFFFFFFu : mesh.colors[mesh.indices[3 * t + k]]; };
    const uint32_t mean = meanColor(col(0), col(1), col(2));
    triColor[t] = colourBits == 24 ? mean & 0xFFFFFFu : toRgb565(mean);
  }
  std::vector<uint64_t> packed;  // Morton code << colourBits | colour
  for (size_t t = 0; t < triColor.size(); ++t)
    voxelizeTriangle(p[mesh.indices[3 * t]], p[mesh.indices[3 * t + 1]], p[mesh.indices[3 * t + 2]], res, triColor[t],
                     colourBits, packed);
  if (config.solid) fillSolid(p, mesh.indices, triColor, colourBits, res, packed);
  std::sort(packed.begin(), packed.end());

  out.codes.assign(static_cast<size_t>(L) + 1, {});
  out.colors.assign(static_cast<size_t>(L) + 1, {});
  auto& fineCodes = out.codes[static_cast<size_t>(L)];
  auto& fineColors = out.colors[static_cast<size_t>(L)];
  for (size_t i = 0; i < packed.size();) {
    const uint64_t code = packed[i] >> colourBits;
    std::array<uint64_t, 3> sum{};
    size_t j = i;
    for (; j < packed.size() && packed[j] >> colourBits == code; ++j)
      addPacked(static_cast<uint32_t>(packed[j] & colourMask), colourBits, sum);
    fineCodes.push_back(code);
    fineColors.push_back(rgbaFromSum(sum, j - i));
    i = j;
  }
  packed = {};
  for (int l = L - 1; l >= 0; --l) {
    const auto& fc = out.codes[static_cast<size_t>(l) + 1];
    const auto& fcol = out.colors[static_cast<size_t>(l) + 1];
    auto& cc = out.codes[static_cast<size_t>(l)];
    auto& ccol = out.colors[static_cast<size_t>(l)];
    for (size_t i = 0; i < fc.size();) {
      const uint64_t code = fc[i] >> 3;
      std::array<uint64_t, 3> sum{};
      size_t j = i;
      for (; j < fc.size() && fc[j] >> 3 == code; ++j)
        for (int ch = 0; ch < 3; ++ch) sum[static_cast<size_t>(ch)] += (fcol[j] >> (8 * ch)) & 0xFF;
      cc.push_back(code);
      ccol.push_back(rgbaFromSum(sum, j - i));
      i = j;
    }
  }
  error.clear();
  return true;
}

bool buildCellTree(const VoxelPyramid& pyramid, const CellBuildConfig& config, CellTree& out, std::string& error) {
  char msg[256];
  const int L = config.cellLevels, d = config.cellVoxelDepth;
  if (L < 1 || L > kMaxCellLevels) {
    std::snprintf(msg, sizeof msg, "cells: cellLevels = %d: allowed range 1..%d", L, kMaxCellLevels);
    error = msg;
    return false;
  }
  if (d < 0 || d > 8) {
    std::snprintf(msg, sizeof msg, "cells: cellVoxelDepth = %d: allowed range 0..8", d);
    error = msg;
    return false;
  }
  if (pyramid.levels() < 0 || L - 1 + d > pyramid.levels()) {
    std::snprintf(msg, sizeof msg, "cells: cellLevels - 1 + cellVoxelDepth = %d: the voxel pyramid has %d levels",
                  L - 1 + d, pyramid.levels());
    error = msg;
    return false;
  }
  if (pyramid.count(0) == 0) {
    error = "cells: the voxel pyramid is empty (no triangle touched the box)";
    return false;
  }
  std::vector<size_t> offset(static_cast<size_t>(L) + 1, 0);
  for (int q = 0; q < L; ++q) offset[static_cast<size_t>(q) + 1] = offset[static_cast<size_t>(q)] + pyramid.count(q);
  const size_t n = offset[static_cast<size_t>(L)];
  std::vector<CellDesc> cells(n);
  std::vector<uint64_t> masks(n, 0), voxels(n, 0);
  for (int q = 0; q < L; ++q) {
    const auto& cc = pyramid.codes[static_cast<size_t>(q)];
    const size_t base = offset[static_cast<size_t>(q)];
    if (q > 0) {
      const auto& pc = pyramid.codes[static_cast<size_t>(q) - 1];
      size_t pi = 0;
      for (size_t i = 0; i < cc.size(); ++i) {
        while (pc[pi] != cc[i] >> 3) ++pi;
        cells[base + i].parent = static_cast<uint32_t>(offset[static_cast<size_t>(q) - 1] + pi);
        cells[base + i].octant = static_cast<uint8_t>(cc[i] & 7);
      }
    }
    for (int k = 0; k <= d; ++k) {
      const auto& lc = pyramid.codes[static_cast<size_t>(q + k)];
      size_t ci = 0;
      for (uint64_t code : lc) {
        const uint64_t cellCode = code >> (3 * k);
        while (cc[ci] != cellCode) ++ci;
        (k == d ? voxels : masks)[base + ci]++;
      }
    }
  }
  for (size_t i = 0; i < n; ++i) {
    cells[i].voxels = static_cast<uint32_t>(voxels[i]);
    cells[i].bytes = static_cast<uint32_t>(std::min<uint64_t>(16 + masks[i] + 3 * voxels[i], 0xFFFFFFFFu));
  }
  CellTreeInfo info;
  info.rootMin_m = pyramid.boxMin_m;
  info.rootEdge_m = pyramid.boxEdge_m;
  info.cellVoxelDepth = d;
  return out.build(info, cells, error);
}

}  // namespace ig::lod
