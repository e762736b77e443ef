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
  std::vector<BoxItem> items;
  top_m_ = -std::numeric_limits<double>::infinity();
  for (size_t o = 0; o < scene.objects.size(); ++o) {
    const Object& object = scene.objects[o];
    if (object.visible.empty() || models_[object.model].empty()) continue;  // never present, or nothing to hit
    const Aabb box = sweptBox(object, scene.models[object.model]);
    if (!finite3(box.min) || !finite3(box.max)) continue;
    top_m_ = std::max(top_m_, box.max.z);
    items.push_back({box.min, box.max, static_cast<uint32_t>(o)});
  }
  buildBoxHierarchy(items, kLeafItems, objectNodes_, objects_);
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
  std::array<uint32_t, 128> stack;
  size_t top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const BoxNode& n = objectNodes_[stack[--top]];
    ++w.nodes;
    if (!segmentMeetsBox(from_m, d, std::min(best, 1.0), n.min, n.max)) continue;
    if (n.count == 0) {
      stack[top++] = n.first + 1;
      stack[top++] = n.first;
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
