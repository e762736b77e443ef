#include "lod/mesh_rays.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>

#include <glm/geometric.hpp>

namespace ig::lod {
namespace {

constexpr uint32_t kLeafTriangles = 4;

bool finite3(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

}  // namespace

bool segmentMeetsBox(const glm::dvec3& o, const glm::dvec3& d, double tMax, const glm::dvec3& lo, const glm::dvec3& hi) {
  double t0 = 0.0, t1 = 0.0;
  return segmentMeetsBox(o, d, tMax, lo, hi, t0, t1);
}

bool segmentMeetsBox(const glm::dvec3& o, const glm::dvec3& d, double tMax, const glm::dvec3& lo, const glm::dvec3& hi,
                     double& t0, double& t1) {
  t0 = 0.0;
  t1 = tMax;
  for (int a = 0; a < 3; ++a) {
    if (d[a] == 0.0) {
      if (o[a] < lo[a] || o[a] > hi[a]) return false;
      continue;
    }
    const double inv = 1.0 / d[a];
    double ta = (lo[a] - o[a]) * inv, tb = (hi[a] - o[a]) * inv;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    if (t0 > t1) return false;
  }
  return true;
}

void buildBoxHierarchy(std::vector<BoxItem>& items, uint32_t leafItems, std::vector<BoxNode>& nodes,
                       std::vector<uint32_t>& order) {
  nodes.clear();
  order.clear();
  if (items.empty()) return;
  leafItems = std::max(leafItems, 1u);
  nodes.reserve(2 * items.size() / leafItems + 1);
  order.reserve(items.size());
  // Depth-first with an explicit stack of (node, begin, end).
  struct Range {
    uint32_t node;
    size_t begin, end;
  };
  std::vector<Range> todo;
  nodes.emplace_back();
  todo.push_back({0, 0, items.size()});
  const auto centre = [](const BoxItem& b, int axis) { return b.min[axis] + b.max[axis]; };
  while (!todo.empty()) {
    const Range r = todo.back();
    todo.pop_back();
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    glm::dvec3 clo = lo, chi = hi;
    for (size_t i = r.begin; i < r.end; ++i) {
      lo = glm::min(lo, items[i].min);
      hi = glm::max(hi, items[i].max);
      const glm::dvec3 c = items[i].min + items[i].max;
      clo = glm::min(clo, c);
      chi = glm::max(chi, c);
    }
    nodes[r.node].min = lo;
    nodes[r.node].max = hi;
    if (r.end - r.begin <= leafItems) {
      nodes[r.node].first = static_cast<uint32_t>(order.size());
      nodes[r.node].count = static_cast<uint32_t>(r.end - r.begin);
      for (size_t i = r.begin; i < r.end; ++i) order.push_back(items[i].id);
      continue;
    }
    const glm::dvec3 extent = chi - clo;
    const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
    const size_t mid = r.begin + (r.end - r.begin) / 2;
    std::nth_element(items.begin() + static_cast<std::ptrdiff_t>(r.begin), items.begin() + static_cast<std::ptrdiff_t>(mid),
                     items.begin() + static_cast<std::ptrdiff_t>(r.end), [axis, &centre](const BoxItem& x, const BoxItem& y) {
                       return centre(x, axis) < centre(y, axis) || (centre(x, axis) == centre(y, axis) && x.id < y.id);
                     });
    // The two children side by side.
    const uint32_t left = static_cast<uint32_t>(nodes.size());
    nodes.emplace_back();
    nodes.emplace_back();
    nodes[r.node].first = left;
    nodes[r.node].count = 0;
    todo.push_back({left + 1, mid, r.end});
    todo.push_back({left, r.begin, mid});
  }
}

MeshRays::MeshRays(const float* positions, size_t count, size_t stride, std::span<const uint32_t> indices) {
  auto vertex = [&](uint32_t i) {
    float p[3];
    std::memcpy(p, reinterpret_cast<const char*>(positions) + static_cast<size_t>(i) * stride, sizeof p);
    return glm::dvec3(p[0], p[1], p[2]);
  };
  std::vector<BoxItem> items;
  std::vector<Tri> tris;
  for (size_t k = 0; k + 2 < indices.size(); k += 3) {
    if (indices[k] >= count || indices[k + 1] >= count || indices[k + 2] >= count) {
      ++degenerate_;
      continue;
    }
    const glm::dvec3 a = vertex(indices[k]), b = vertex(indices[k + 1]), c = vertex(indices[k + 2]);
    const glm::dvec3 e1 = b - a, e2 = c - a;
    const double area2 = glm::length(glm::cross(e1, e2));
    if (!finite3(a) || !finite3(b) || !finite3(c) || !(area2 > 1e-12 * std::max(glm::dot(e1, e1), glm::dot(e2, e2)))) {
      ++degenerate_;
      continue;
    }
    items.push_back({glm::min(a, glm::min(b, c)), glm::max(a, glm::max(b, c)), static_cast<uint32_t>(tris.size())});
    tris.push_back({a, e1, e2});
  }
  std::vector<uint32_t> order;
  buildBoxHierarchy(items, kLeafTriangles, nodes_, order);
  tris_.reserve(order.size());
  for (uint32_t i : order) tris_.push_back(tris[i]);  // leaves index tris_ directly
}

bool MeshRays::intersect(const glm::dvec3& o, const glm::dvec3& d, double& tBest, glm::dvec3& normal, RayWork& work) const {
  if (nodes_.empty()) return false;
  bool found = false;
  std::array<uint32_t, 128> stack;
  size_t top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const BoxNode& n = nodes_[stack[--top]];
    ++work.nodes;
    if (!segmentMeetsBox(o, d, std::min(tBest, 1.0), n.min, n.max)) continue;
    if (n.count == 0) {
      stack[top++] = n.first + 1;
      stack[top++] = n.first;
      continue;
    }
    for (uint32_t k = n.first; k < n.first + n.count; ++k) {
      const Tri& tri = tris_[k];
      ++work.triangles;
      const glm::dvec3 p = glm::cross(d, tri.e2);
      const double det = glm::dot(tri.e1, p);
      if (!(std::abs(det) > 1e-12 * glm::length(tri.e1) * glm::length(tri.e2) * glm::length(d))) continue;  // parallel
      const double inv = 1.0 / det;
      const glm::dvec3 s = o - tri.a;
      const double u = glm::dot(s, p) * inv;
      if (u < 0.0 || u > 1.0) continue;
      const glm::dvec3 q = glm::cross(s, tri.e1);
      const double v = glm::dot(d, q) * inv;
      if (v < 0.0 || u + v > 1.0) continue;
      const double t = glm::dot(tri.e2, q) * inv;
      if (t < 0.0 || t > 1.0 || t >= tBest) continue;
      tBest = t;
      found = true;
      normal = glm::normalize(glm::cross(tri.e1, tri.e2));
      if (glm::dot(normal, d) > 0.0) normal = -normal;
    }
  }
  return found;
}

}  // namespace ig::lod
