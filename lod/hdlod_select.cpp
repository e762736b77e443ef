// HDLOD selection: paper 000, appendix 1 (see hdlod_select.h for the rule).
#include "lod/hdlod_select.h"

#include <cmath>

namespace ig::lod::hdlod {
namespace {

constexpr double kDeg = 3.14159265358979323846 / 180.0;

bool finite3(const glm::dvec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

bool validView(const SelectView& v) {
  const Camera& c = v.camera;
  return finite3(c.eye_m) && std::isfinite(c.heading_deg) && std::isfinite(c.pitch_deg) && std::isfinite(c.roll_deg) &&
         c.fovY_deg > 0.0 && c.fovY_deg < 180.0 && c.aspect > 0.0 && std::isfinite(c.aspect) && c.near_m > 0.0 &&
         c.far_m > c.near_m && std::isfinite(c.far_m) && std::isfinite(v.time_s) && !std::isnan(v.tolerance_rad);
}

struct Traversal {
  const HdlodTree& tree;
  const Scene& scene;
  Frustum frustum;
  glm::dvec3 eye;
  double t, r;
  bool all;  // selectAll(): draw every present leaf in the frustum
  std::span<Draw> out;
  SelectStats stats;
  size_t written = 0;

  bool inFrustum(const Aabb& box) const { return frustum.intersects(Aabb{box.min - eye, box.max - eye}); }

  void emit(uint32_t id, const glm::dmat4& m, uint32_t triangles) {
    if (written < out.size()) {
      out[written].cluster = id;
      out[written].model = m;
      ++written;
    } else {
      stats.overflow = true;
    }
    ++stats.draws;
    stats.triangles += triangles;
  }

  void visit(uint32_t id) {
    const Cluster& c = tree.clusters[id];
    ++stats.visited;
    const double f = clusterPresence(tree, c, t);
    if (f == 0.0) {
      ++stats.absent;
      return;
    }
    if (c.kind == ClusterKind::Dynamic) {
      const Object& o = scene.objects[c.object];
      const glm::dmat4 m = objectMatrix(o, t, tree.duration_s);
      if (!inFrustum(transformBox(scene.models[o.model].box, m))) {
        ++stats.culled;
        return;
      }
      emit(id, m, c.triangles);
      return;
    }
    if (!inFrustum(c.box)) {
      ++stats.culled;
      return;
    }
    if (c.kind == ClusterKind::Object) {
      emit(id, tree.leafMatrix[id], c.triangles);
      return;
    }
    if (c.kind == ClusterKind::Merged && !all) {
      const double delta = c.eps_m + c.size_m * (1.0 - std::abs(2.0 * f - 1.0));
      if (delta < r * distanceToBox(c.box, eye)) {
        if (f >= 0.5) {
          emit(id, tree.leafMatrix[id], c.triangles);
        } else {
          ++stats.halfSkipped;
        }
        return;
      }
    }
    for (uint32_t child : tree.childrenOf(c)) visit(child);
  }
};

size_t run(const HdlodTree& tree, const Scene& scene, const SelectView& view, std::span<Draw> out, SelectStats* stats,
           bool all) {
  if (!validView(view) || tree.root >= tree.clusters.size()) {
    if (stats) {
      *stats = SelectStats{};
      stats->rejected = !validView(view);
    }
    return 0;
  }
  Traversal tr{tree, scene, makeFrustum(view.camera), view.camera.eye_m, clampTime(view.time_s, tree.duration_s),
               view.tolerance_rad > 0.0 ? view.tolerance_rad : 0.0, all, out, SelectStats{}, 0};
  tr.visit(tree.root);
  if (stats) *stats = tr.stats;
  return tr.written;
}

}  // namespace

double toleranceFromPixels(double r_px, double fovY_deg, double viewportHeight_px) {
  return r_px * 2.0 * std::tan(0.5 * fovY_deg * kDeg) / viewportHeight_px;
}

size_t drawBound(const HdlodTree& tree) {
  size_t n = 0;
  for (const Cluster& c : tree.clusters) n += c.kind != ClusterKind::Group ? 1 : 0;
  return n;
}

size_t selectHdlod(const HdlodTree& tree, const Scene& scene, const SelectView& view, std::span<Draw> out,
                   SelectStats* stats) {
  return run(tree, scene, view, out, stats, false);
}

size_t selectAll(const HdlodTree& tree, const Scene& scene, const SelectView& view, std::span<Draw> out,
                 SelectStats* stats) {
  return run(tree, scene, view, out, stats, true);
}

}  // namespace ig::lod::hdlod
