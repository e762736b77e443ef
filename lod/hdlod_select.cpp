// HDLOD selection: paper 000, appendix 1 (see hdlod_select.h for the rule).
#include "lod/hdlod_select.h"

#include <algorithm>
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

// Frustum planes with the plane-mask test: a box inside a plane's half-space passes the bit
// down cleared, so its descendants (whose boxes lie inside it) skip that plane. The outcome of
// each test is the same as Frustum::intersects().
struct Planes {
  glm::dvec4 p[6];
  // Eye-relative box; `mask` bits: planes still to test. Returns false when outside, else
  // updates mask.
  bool test(const glm::dvec3& lo, const glm::dvec3& hi, uint32_t& mask) const {
    for (uint32_t i = 0; i < 6; ++i) {
      if (!(mask & (1u << i))) continue;
      const glm::dvec4& q = p[i];
      const double far = q.x * (q.x >= 0 ? hi.x : lo.x) + q.y * (q.y >= 0 ? hi.y : lo.y) + q.z * (q.z >= 0 ? hi.z : lo.z) + q.w;
      if (far < 0.0) return false;
      const double near = q.x * (q.x >= 0 ? lo.x : hi.x) + q.y * (q.y >= 0 ? lo.y : hi.y) + q.z * (q.z >= 0 ? lo.z : hi.z) + q.w;
      if (near >= 0.0) mask &= ~(1u << i);
    }
    return true;
  }
};

double distance2ToBox(const Aabb& box, const glm::dvec3& p) {
  const glm::dvec3 d = glm::max(glm::max(box.min - p, p - box.max), glm::dvec3(0.0));
  return d.x * d.x + d.y * d.y + d.z * d.z;
}

struct Traversal {
  const HdlodTree& tree;
  const Scene& scene;
  Planes planes;
  glm::dvec3 eye;
  double t, r, r2;
  bool all;  // selectAll(): draw every present leaf in the frustum
  std::span<Draw> out;
  SelectStats stats;
  size_t written = 0;

  // f_c(t), t already clamped: the step functions are short (leaves: at most a few steps).
  double presence(const Cluster& c) const {
    if (c.stepCount == 0) return 0.0;
    const double* times = tree.stepTimes.data() + c.stepBegin;
    uint32_t i = 0;
    if (c.stepCount <= 16) {
      while (i + 1 < c.stepCount && times[i + 1] <= t) ++i;
    } else {
      const double* it = std::upper_bound(times, times + c.stepCount, t);
      i = it == times ? 0 : static_cast<uint32_t>(it - times) - 1;
    }
    return tree.stepValues[c.stepBegin + i];
  }

  bool inFrustum(const Aabb& box, uint32_t& mask) const { return mask == 0 || planes.test(box.min - eye, box.max - eye, mask); }

  void emit(uint32_t id, uint32_t lod, const glm::dmat4& m, uint32_t triangles) {
    if (written < out.size()) {
      Draw& d = out[written];
      d.cluster = id;
      d.lod = lod;
      d.model = m;
      ++written;
    } else {
      stats.overflow = true;
    }
    ++stats.draws;
    stats.triangles += triangles;
  }

  // A leaf: the coarsest version of its model whose eps < r * distance (0 = the model itself).
  void emitLeaf(uint32_t id, const Cluster& c, const Aabb& box, const glm::dmat4& m) {
    uint32_t lod = 0, triangles = c.triangles;
    if (!all && r > 0.0) {
      const auto lods = tree.lodsOf(c.mesh);
      if (!lods.empty()) {
        const double d2 = distance2ToBox(box, eye);
        for (size_t k = 0; k < lods.size(); ++k) {
          if (!(lods[k].eps_m * lods[k].eps_m < r2 * d2)) break;
          lod = static_cast<uint32_t>(k + 1);
          triangles = lods[k].triangles;
        }
      }
    }
    emit(id, lod, m, triangles);
  }

  void visit(uint32_t id, uint32_t mask) {
    const Cluster& c = tree.clusters[id];
    ++stats.visited;
    const double f = presence(c);
    if (f == 0.0) {
      ++stats.absent;
      return;
    }
    if (c.kind == ClusterKind::Dynamic) {
      // The swept box first (it holds the object at every time), then the box where it is now.
      if (!inFrustum(c.box, mask)) {
        ++stats.culled;
        return;
      }
      const Object& o = scene.objects[c.object];
      const glm::dmat4 m = objectMatrix(o, t, tree.duration_s);
      const Aabb box = transformBox(scene.models[o.model].box, m);
      if (!inFrustum(box, mask)) {
        ++stats.culled;
        return;
      }
      emitLeaf(id, c, box, m);
      return;
    }
    if (!inFrustum(c.box, mask)) {
      ++stats.culled;
      return;
    }
    if (c.kind == ClusterKind::Object) {
      emitLeaf(id, c, c.box, tree.leafMatrix[id]);
      return;
    }
    if (c.kind == ClusterKind::Merged && !all) {
      // delta < r * distance, squared (both sides >= 0; distance 0 is never good enough).
      const double delta = c.eps_m + c.size_m * (1.0 - std::abs(2.0 * f - 1.0));
      if (delta * delta < r2 * distance2ToBox(c.box, eye)) {
        if (f >= 0.5) {
          emit(id, 0, tree.leafMatrix[id], c.triangles);
        } else {
          ++stats.halfSkipped;
        }
        return;
      }
    }
    const uint32_t end = c.firstChild + c.childCount;
    // The children's records (two cache lines each) and matrices are requested together before
    // the first is visited, and each sibling's f_c steps while the one before it is visited: a
    // skipped subtree makes the next sibling a jump that the hardware prefetcher cannot guess,
    // and with cold caches (after a rendered frame) these misses were taken one after another.
    // -25..-35 % of the animation's cold selection time (docs/hdlod.md).
    for (uint32_t k = c.firstChild; k < end; ++k) {
      const uint32_t child = tree.children[k];
      const char* record = reinterpret_cast<const char*>(tree.clusters.data() + child);
      __builtin_prefetch(record);
      __builtin_prefetch(record + sizeof(Cluster) - 1);
      const char* matrix = reinterpret_cast<const char*>(tree.leafMatrix.data() + child);
      __builtin_prefetch(matrix);
      __builtin_prefetch(matrix + sizeof(glm::dmat4) - 1);
    }
    for (uint32_t k = c.firstChild; k < end; ++k) {
      if (k + 1 < end) {
        const Cluster& next = tree.clusters[tree.children[k + 1]];
        __builtin_prefetch(tree.stepTimes.data() + next.stepBegin);
        __builtin_prefetch(tree.stepValues.data() + next.stepBegin);
      }
      visit(tree.children[k], mask);
    }
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
  const Frustum fr = makeFrustum(view.camera);
  Planes planes;
  for (int i = 0; i < 6; ++i) planes.p[i] = fr.planes[static_cast<size_t>(i)];
  const double r = view.tolerance_rad > 0.0 ? view.tolerance_rad : 0.0;
  Traversal tr{tree, scene, planes, view.camera.eye_m, clampTime(view.time_s, tree.duration_s), r, r * r, all, out, SelectStats{}, 0};
  tr.visit(tree.root, 0x3fu);
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
