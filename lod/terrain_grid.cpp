#include "lod/terrain_grid.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include <glm/geometric.hpp>

namespace ig::lod {
namespace {

// Normal at post (x, y) from central differences over the neighbouring posts; on the border,
// where one neighbour is the post itself, over the one spacing there is (a plane keeps its
// normal up to the edge).
template <class Height>
glm::dvec3 centralNormal(const Height& h, int x, int y, int width, int height, double spacing_m) {
  const int x0 = std::max(x - 1, 0), x1 = std::min(x + 1, width - 1);
  const int y0 = std::max(y - 1, 0), y1 = std::min(y + 1, height - 1);
  const double dx = x1 > x0 ? (h(x0, y) - h(x1, y)) / (x1 - x0) : 0.0;
  const double dy = y1 > y0 ? (h(x, y0) - h(x, y1)) / (y1 - y0) : 0.0;
  return glm::normalize(glm::dvec3(dx, dy, spacing_m));
}

}  // namespace

TerrainVertex heightFieldVertex(std::span<const float> heights_m, int width, int height, double spacing_m, int x, int y) {
  auto h = [&](int i, int j) {
    i = std::clamp(i, 0, width - 1);
    j = std::clamp(j, 0, height - 1);
    return static_cast<double>(heights_m[static_cast<size_t>(j) * static_cast<size_t>(width) + static_cast<size_t>(i)]);
  };
  x = std::clamp(x, 0, width - 1);
  y = std::clamp(y, 0, height - 1);
  const glm::dvec3 n = centralNormal(h, x, y, width, height, spacing_m);
  TerrainVertex v{};
  v.position[0] = static_cast<float>(x * spacing_m);
  v.position[1] = static_cast<float>(y * spacing_m);
  v.position[2] = static_cast<float>(h(x, y));
  v.normal[0] = static_cast<float>(n.x);
  v.normal[1] = static_cast<float>(n.y);
  v.normal[2] = static_cast<float>(n.z);
  return v;
}

TerrainGrid::TerrainGrid(const TerrainGridDesc& desc) : desc_(desc) {
  const HeightfieldDesc& hf = desc.heights;
  assert(desc.chunkQuads >= 1 && "TerrainGrid: chunkQuads must be >= 1");
  heights_m_.resize(static_cast<size_t>(hf.postsX) * static_cast<size_t>(hf.postsY));
  generateHeightfield(hf, heights_m_);

  const int quadsX = hf.postsX - 1, quadsY = hf.postsY - 1;
  const int cq = desc.chunkQuads;
  const double s = hf.postSpacing_m;
  auto h = [&](int x, int y) {
    x = std::clamp(x, 0, hf.postsX - 1);
    y = std::clamp(y, 0, hf.postsY - 1);
    return static_cast<double>(heights_m_[static_cast<size_t>(y) * hf.postsX + x]);
  };

  for (int cy = 0; cy < quadsY; cy += cq) {
    for (int cx = 0; cx < quadsX; cx += cq) {
      TerrainChunk c{};
      c.quadsX = std::min(cq, quadsX - cx);
      c.quadsY = std::min(cq, quadsY - cy);
      c.origin_m = desc.offset_m + glm::dvec3(cx * s, cy * s, 0.0);
      c.firstVertex = static_cast<uint32_t>(vertices_.size());
      c.firstIndex = static_cast<uint32_t>(indices_.size());
      double zMin = 1e300, zMax = -1e300;
      for (int y = 0; y <= c.quadsY; ++y) {
        for (int x = 0; x <= c.quadsX; ++x) {
          const int gx = cx + x, gy = cy + y;
          const double z = h(gx, gy);
          // Central differences over neighbouring posts give a crack-free shared normal.
          const glm::dvec3 n = centralNormal(h, gx, gy, hf.postsX, hf.postsY, s);
          TerrainVertex v{};
          v.position[0] = static_cast<float>(x * s);
          v.position[1] = static_cast<float>(y * s);
          v.position[2] = static_cast<float>(z);
          v.normal[0] = static_cast<float>(n.x);
          v.normal[1] = static_cast<float>(n.y);
          v.normal[2] = static_cast<float>(n.z);
          vertices_.push_back(v);
          zMin = std::min(zMin, z);
          zMax = std::max(zMax, z);
        }
      }
      const auto pitch = static_cast<uint32_t>(c.quadsX + 1);
      for (uint32_t y = 0; y < static_cast<uint32_t>(c.quadsY); ++y) {
        for (uint32_t x = 0; x < static_cast<uint32_t>(c.quadsX); ++x) {
          const uint32_t i0 = y * pitch + x, i1 = i0 + 1, i2 = i0 + pitch, i3 = i2 + 1;
          indices_.insert(indices_.end(), {i0, i1, i3, i0, i3, i2});
        }
      }
      c.indexCount = static_cast<uint32_t>(indices_.size()) - c.firstIndex;
      c.bounds.min = c.origin_m + glm::dvec3(0.0, 0.0, zMin);
      c.bounds.max = c.origin_m + glm::dvec3(c.quadsX * s, c.quadsY * s, zMax);
      chunks_.push_back(c);
    }
  }
}

uint64_t TerrainGrid::totalTriangles() const {
  uint64_t n = 0;
  for (const auto& c : chunks_) n += triangleCount(c);
  return n;
}

double TerrainGrid::heightAt(double east_m, double north_m) const {
  const HeightfieldDesc& hf = desc_.heights;
  const double fx = std::clamp((east_m - desc_.offset_m.x) / hf.postSpacing_m, 0.0, hf.postsX - 1.0);
  const double fy = std::clamp((north_m - desc_.offset_m.y) / hf.postSpacing_m, 0.0, hf.postsY - 1.0);
  if (!std::isfinite(fx) || !std::isfinite(fy)) return desc_.offset_m.z;
  const int x0 = std::min(static_cast<int>(fx), hf.postsX - 2);
  const int y0 = std::min(static_cast<int>(fy), hf.postsY - 2);
  const double tx = fx - x0, ty = fy - y0;
  auto h = [&](int x, int y) { return static_cast<double>(heights_m_[static_cast<size_t>(y) * hf.postsX + x]); };
  const double a = h(x0, y0) + (h(x0 + 1, y0) - h(x0, y0)) * tx;
  const double b = h(x0, y0 + 1) + (h(x0 + 1, y0 + 1) - h(x0, y0 + 1)) * tx;
  return desc_.offset_m.z + a + (b - a) * ty;
}

size_t TerrainGrid::select(const Frustum& frustum, const glm::dvec3& eye_m, uint64_t maxTriangles,
                           std::span<uint32_t> out) const {
  assert(out.size() >= chunks_.size() && "TerrainGrid::select: output span too small");
  size_t n = 0;
  for (size_t i = 0; i < chunks_.size(); ++i) {
    const Aabb rel{chunks_[i].bounds.min - eye_m, chunks_[i].bounds.max - eye_m};
    if (frustum.intersects(rel)) out[n++] = static_cast<uint32_t>(i);
  }
  // Nearest first (front-to-back also helps early depth rejection); in place, no allocation.
  std::sort(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(n), [&](uint32_t a, uint32_t b) {
    return distanceToBox(chunks_[a].bounds, eye_m) < distanceToBox(chunks_[b].bounds, eye_m);
  });
  uint64_t triangles = 0;
  size_t kept = 0;
  while (kept < n && triangles + triangleCount(chunks_[out[kept]]) <= maxTriangles) {
    triangles += triangleCount(chunks_[out[kept]]);
    ++kept;
  }
  return kept;
}

}  // namespace ig::lod
