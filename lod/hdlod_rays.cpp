#include "lod/hdlod_rays.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>

namespace ig::lod::hdlod {
namespace {

constexpr uint32_t kLeafItems = 4;

bool finite3(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

struct Item {
  glm::dvec3 min, max, centre;
  uint32_t id;
};

// Builds the hierarchy over items[begin, end) at nodes.back(); the leaves' items go to `order`.
template <typename Node>
void build(std::vector<Node>& nodes, std::vector<Item>& items, size_t begin, size_t end, std::vector<uint32_t>& order) {
  const size_t at = nodes.size();
  nodes.emplace_back();
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  glm::dvec3 clo = lo, chi = hi;
  for (size_t i = begin; i < end; ++i) {
    lo = glm::min(lo, items[i].min);
    hi = glm::max(hi, items[i].max);
    clo = glm::min(clo, items[i].centre);
    chi = glm::max(chi, items[i].centre);
  }
  nodes[at].min = lo;
  nodes[at].max = hi;
  if (end - begin <= kLeafItems) {
    nodes[at].first = static_cast<uint32_t>(order.size());
    nodes[at].count = static_cast<uint32_t>(end - begin);
    for (size_t i = begin; i < end; ++i) order.push_back(items[i].id);
    return;
  }
  const glm::dvec3 extent = chi - clo;
  const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
  const size_t mid = begin + (end - begin) / 2;
  std::nth_element(items.begin() + static_cast<std::ptrdiff_t>(begin), items.begin() + static_cast<std::ptrdiff_t>(mid),
                   items.begin() + static_cast<std::ptrdiff_t>(end), [axis](const Item& a, const Item& b) {
                     return a.centre[axis] < b.centre[axis] || (a.centre[axis] == b.centre[axis] && a.id < b.id);
                   });
  build(nodes, items, begin, mid, order);
  nodes[at].first = static_cast<uint32_t>(nodes.size());
  nodes[at].count = 0;
  build(nodes, items, mid, end, order);
}

}  // namespace

SceneRays::SceneRays(const Scene& scene) {
  if (!validateScene(scene).empty()) return;
  scene_ = &scene;
  models_.reserve(scene.models.size());
  for (const Model& model : scene.models) {
    models_.emplace_back(model.positions.empty() ? nullptr : &model.positions[0].x, model.positions.size(),
                         sizeof(glm::vec3), model.indices);
    triangles_ += models_.back().triangles();
    degenerate_ += models_.back().degenerateTriangles();
  }
  std::vector<Item> items;
  top_m_ = -std::numeric_limits<double>::infinity();
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    const Object& object = scene.objects[o];
    if (object.visible.empty() || models_[object.model].empty()) continue;  // never present, or nothing to hit
    const Aabb box = sweptBox(object, scene.models[object.model]);
    if (!finite3(box.min) || !finite3(box.max)) continue;
    top_m_ = std::max(top_m_, box.max.z);
    items.push_back({box.min, box.max, (box.min + box.max) * 0.5, static_cast<uint32_t>(o)});
  }
  if (items.empty()) return;
  objectNodes_.reserve(2 * items.size() / kLeafItems + 1);
  build(objectNodes_, items, 0, items.size(), objects_);
}

bool SceneRays::intersect(const glm::dvec3& from_m, const glm::dvec3& to_m, double t_s, RayHit& hit,
                          RayWork* work) const {
  if (empty() || !finite3(from_m) || !finite3(to_m)) return false;
  const glm::dvec3 d = to_m - from_m;
  if (!finite3(d)) return false;
  const Scene& scene = *scene_;
  double best = std::numeric_limits<double>::infinity();
  bool found = false;
  RayWork w;
  std::array<uint32_t, 128> stack{};
  size_t top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const Node& n = objectNodes_[stack[--top]];
    ++w.nodes;
    if (!segmentMeetsBox(from_m, d, std::min(best, 1.0), n.min, n.max)) continue;
    if (n.count == 0) {
      stack[top++] = n.first;
      stack[top++] = static_cast<uint32_t>(&n - objectNodes_.data()) + 1;
      continue;
    }
    for (uint32_t i = n.first; i < n.first + n.count; ++i) {
      const uint32_t o = objects_[i];
      const Object& object = scene.objects[o];
      if (!isPresent(object, t_s, scene.duration_s)) continue;
      const Model& model = scene.models[object.model];
      const glm::dmat4 m = objectMatrix(object, t_s, scene.duration_s);
      const Aabb at = transformBox(model.box, m);
      if (!segmentMeetsBox(from_m, d, std::min(best, 1.0), at.min, at.max)) continue;
      // Into model space: the position is a translation and a turn about z (rotation only).
      const glm::dmat3 r(m);
      const glm::dmat3 rt = glm::transpose(r);
      const glm::dvec3 lo = rt * (from_m - glm::dvec3(m[3])), ld = rt * d;
      glm::dvec3 normal;
      if (models_[object.model].intersect(lo, ld, best, normal, w)) {
        found = true;
        hit.t = best;
        hit.normal = r * normal;
        hit.object = o;
      }
    }
  }
  if (found) hit.point_m = from_m + d * hit.t;
  if (work) {
    work->nodes += w.nodes;
    work->triangles += w.triangles;
  }
  return found;
}

}  // namespace ig::lod::hdlod
