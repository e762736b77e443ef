// HDLOD cluster-tree generation: paper 000, appendix 2 (see hdlod_build.h for the definitions).
#include "lod/hdlod_build.h"

#include "lod/hdlod_simplify.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <limits>
#include <numeric>

#include <glm/geometric.hpp>

namespace ig::lod::hdlod {
namespace {

constexpr uint32_t kNone = ~0u;
constexpr double kMinWeight_m = 1e-6;

// A scene model index as a vertex material (models past 65535 share the last).
uint16_t materialOf(size_t model) { return static_cast<uint16_t>(std::min<size_t>(model, 65535)); }
double diagonal(const Aabb& b) { return glm::length(b.max - b.min); }
Aabb unite(const Aabb& a, const Aabb& b) { return Aabb{glm::min(a.min, b.min), glm::max(a.max, b.max)}; }
glm::dvec3 centre(const Aabb& b) { return (b.min + b.max) * 0.5; }

// ---------------------------------------------------------------- step functions

struct Step {
  std::span<const double> times, values;
  size_t segmentAt(double t) const {
    const auto it = std::upper_bound(times.begin(), times.end(), t);
    return it == times.begin() ? 0 : static_cast<size_t>(it - times.begin()) - 1;
  }
};

struct Event {
  double t;
  double weight;
  int count;  // change in the members present (value > 0)
  int full;   // change in the members wholly present (value 1)
  uint32_t member;
  double value;  // the member's value from t on
};

// Whether sum(weights[i] * values[i]) >= total / 2, exactly: the sign of
// sum(weights[i] * (2 values[i] - 1)) (exact terms for values 0 and 1) summed without rounding
// (Shewchuk's non-overlapping partials; the largest one carries the sign).
bool atLeastHalf(std::span<const double> weights, std::span<const double> values, std::vector<double>& partials) {
  partials.clear();
  for (size_t i = 0; i < weights.size(); ++i) {
    double x = weights[i] * (2.0 * values[i] - 1.0);
    size_t kept = 0;
    for (double y : partials) {
      if (std::abs(x) < std::abs(y)) std::swap(x, y);
      const double hi = x + y, lo = y - (hi - x);
      if (lo != 0.0) partials[kept++] = lo;
      x = hi;
    }
    partials.resize(kept);
    partials.push_back(x);
  }
  for (size_t i = partials.size(); i-- > 0;)
    if (partials[i] != 0.0) return partials[i] > 0.0;
  return true;
}

// f(t) = sum of weight x value / total over the members' step functions (leaves: value 1 =
// present); with `any`, f = 1 while any member is present (value > 0: a group over merged
// clusters, whose values are fractions, counts each while any of its leaves is present).
// Exactly 0 when none is and 1 when all are wholly present.
void presenceOf(const HdlodTree& tree, std::span<const uint32_t> leaves, std::span<const double> weights, bool any,
                std::vector<double>& times, std::vector<double>& values, std::vector<Event>& events) {
  events.clear();
  double total = 0.0;
  for (size_t i = 0; i < leaves.size(); ++i) {
    const Cluster& c = tree.clusters[leaves[i]];
    total += weights[i];
    double prev = 0.0;
    for (uint32_t k = 0; k < c.stepCount; ++k) {
      const double v = tree.stepValues[c.stepBegin + k];
      if (v != prev)
        events.push_back({tree.stepTimes[c.stepBegin + k], weights[i] * (v - prev), (v > 0.0) - (prev > 0.0),
                          (v == 1.0) - (prev == 1.0), static_cast<uint32_t>(i), v});
      prev = v;
    }
  }
  std::sort(events.begin(), events.end(), [](const Event& a, const Event& b) { return a.t < b.t; });
  times.clear();
  values.clear();
  const int n = static_cast<int>(leaves.size());
  double w = 0.0;
  int count = 0, full = 0;
  size_t e = 0;
  // The members' values now, for the exact side of 1/2 (the running sum w drifts with rounding:
  // weights 0.1, 0.2, 0.3 in, 0.3 out left f = 0.4999999999999999 for 0.1 + 0.2 present, and the
  // cluster was skipped).
  std::vector<double> current(leaves.size(), 0.0), partials;
  auto value = [&] {
    if (count <= 0) return 0.0;
    if (any || full >= n) return 1.0;
    const double f = std::clamp(w / total, 0.0, 1.0);
    if (std::abs(f - 0.5) > 1e-6) return f;
    return atLeastHalf(weights, current, partials) ? std::max(f, 0.5) : std::min(f, std::nextafter(0.5, 0.0));
  };
  auto apply = [&](const Event& ev) {
    w += ev.weight;
    count += ev.count;
    full += ev.full;
    current[ev.member] = ev.value;
  };
  // Segment starting at 0 includes every event at 0.
  while (e < events.size() && events[e].t <= 0.0) {
    apply(events[e]);
    ++e;
  }
  times.push_back(0.0);
  values.push_back(value());
  while (e < events.size()) {
    const double t = events[e].t;
    while (e < events.size() && events[e].t == t) {
      apply(events[e]);
      ++e;
    }
    const double v = value();
    if (v != values.back()) {
      times.push_back(t);
      values.push_back(v);
    }
  }
}

// Leaf presence v_s as a step function (same rules as isPresent()).
void leafPresence(const Object& o, double T, std::vector<double>& times, std::vector<double>& values) {
  times.assign(1, 0.0);
  values.assign(1, 0.0);
  for (const Interval& iv : o.visible) {
    if (iv.appear_s >= T || iv.disappear_s <= 0.0) continue;
    const double a = std::max(iv.appear_s, 0.0);
    if (a <= 0.0) {
      values[0] = 1.0;
    } else {
      times.push_back(a);
      values.push_back(1.0);
    }
    if (iv.disappear_s < T) {
      times.push_back(iv.disappear_s);
      values.push_back(0.0);
    }
  }
}

// Integral of a step function over [0, x] given its prefix integrals.
double integralTo(const Step& f, std::span<const double> prefix, double x) {
  const size_t i = f.segmentAt(x);
  return prefix[i] + f.values[i] * (x - f.times[i]);
}

// ---------------------------------------------------------------- Hilbert curve

// 3D Hilbert index of integer coordinates with `bits` bits each (Skilling's transform).
uint64_t hilbertKey(uint32_t x, uint32_t y, uint32_t z, int bits) {
  uint32_t X[3] = {x, y, z};
  const uint32_t M = 1u << (bits - 1);
  for (uint32_t Q = M; Q > 1; Q >>= 1) {
    const uint32_t P = Q - 1;
    for (int i = 0; i < 3; ++i) {
      if (X[i] & Q) {
        X[0] ^= P;
      } else {
        const uint32_t t = (X[0] ^ X[i]) & P;
        X[0] ^= t;
        X[i] ^= t;
      }
    }
  }
  for (int i = 1; i < 3; ++i) X[i] ^= X[i - 1];
  uint32_t t = 0;
  for (uint32_t Q = M; Q > 1; Q >>= 1) {
    if (X[2] & Q) t ^= Q - 1;
  }
  for (auto& v : X) v ^= t;
  uint64_t key = 0;
  for (int b = bits - 1; b >= 0; --b) {
    for (int i = 0; i < 3; ++i) key = (key << 1) | ((X[i] >> b) & 1u);
  }
  return key;
}

// ---------------------------------------------------------------- point-triangle distance

glm::vec3 closestOnSegment(const glm::vec3& p, const glm::vec3& a, const glm::vec3& b) {
  const glm::vec3 ab = b - a;
  const float len2 = glm::dot(ab, ab);
  if (!(len2 > 0.0f)) return a;
  const float u = std::clamp(glm::dot(p - a, ab) / len2, 0.0f, 1.0f);
  return a + ab * u;
}

float distance2(const glm::vec3& a, const glm::vec3& b) {
  const glm::vec3 d = a - b;
  return glm::dot(d, d);
}

// Squared distance from p to triangle abc (Ericson, Real-Time Collision Detection 5.1.5);
// zero-area triangles fall back to their edges.
float pointTriangleDistance2(const glm::vec3& p, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::vec3 ab = b - a, ac = c - a, ap = p - a;
  const glm::vec3 n = glm::cross(ab, ac);
  const float nn = glm::dot(n, n);
  const float scale = std::max(glm::dot(ab, ab), glm::dot(ac, ac));
  if (!(nn > 1e-12f * scale * scale)) {
    return std::min({distance2(p, closestOnSegment(p, a, b)), distance2(p, closestOnSegment(p, b, c)),
                     distance2(p, closestOnSegment(p, c, a))});
  }
  const float d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0.0f && d2 <= 0.0f) return distance2(p, a);
  const glm::vec3 bp = p - b;
  const float d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0.0f && d4 <= d3) return distance2(p, b);
  const float vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0f && d1 >= 0.0f && d3 <= 0.0f) return distance2(p, a + ab * (d1 / (d1 - d3)));
  const glm::vec3 cp = p - c;
  const float d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0.0f && d5 <= d6) return distance2(p, c);
  const float vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0f && d2 >= 0.0f && d6 <= 0.0f) return distance2(p, a + ac * (d2 / (d2 - d6)));
  const float va = d3 * d6 - d5 * d4;
  if (va <= 0.0f && (d4 - d3) >= 0.0f && (d5 - d6) >= 0.0f) {
    return distance2(p, b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6))));
  }
  const float denom = 1.0f / (va + vb + vc);
  const float v = vb * denom, w = vc * denom;
  return distance2(p, a + ab * v + ac * w);
}

// A BVH over triangles for nearest-distance queries with an early exit.
class TriangleBvh {
 public:
  TriangleBvh(std::span<const glm::vec3> positions, std::span<const uint32_t> indices)
      : positions_(positions), indices_(indices) {
    const uint32_t n = static_cast<uint32_t>(indices.size() / 3);
    order_.resize(n);
    std::iota(order_.begin(), order_.end(), 0u);
    centroids_.resize(n);
    for (uint32_t i = 0; i < n; ++i) {
      centroids_[i] = (vertex(i, 0) + vertex(i, 1) + vertex(i, 2)) / 3.0f;
    }
    if (n > 0) {
      nodes_.reserve(2 * static_cast<size_t>(n) / kLeafSize + 2);
      build(0, n);
    }
  }

  // Smallest distance from p to a triangle; returns as soon as a distance <= enough is found.
  float nearest(const glm::vec3& p, float enough, uint32_t* which = nullptr) const {
    if (nodes_.empty()) return std::numeric_limits<float>::infinity();
    float best2 = std::numeric_limits<float>::infinity();
    const float enough2 = enough * enough;
    uint32_t stack[64];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& node = nodes_[stack[--top]];
      if (boxDistance2(node, p) >= best2) continue;
      if (node.count > 0) {
        for (uint32_t i = node.first; i < node.first + node.count; ++i) {
          const uint32_t t = order_[i];
          const float d2 = pointTriangleDistance2(p, vertex(t, 0), vertex(t, 1), vertex(t, 2));
          if (d2 < best2) {
            best2 = d2;
            if (which) *which = t;
          }
        }
        if (best2 <= enough2) break;
        continue;
      }
      const uint32_t l = node.first, r = node.first + 1;
      const float dl = boxDistance2(nodes_[l], p), dr = boxDistance2(nodes_[r], p);
      // Push the farther child first so the nearer is visited next.
      if (dl < dr) {
        stack[top++] = r;
        stack[top++] = l;
      } else {
        stack[top++] = l;
        stack[top++] = r;
      }
    }
    return std::sqrt(best2);
  }

 private:
  static constexpr uint32_t kLeafSize = 4;
  struct Node {
    glm::vec3 lo, hi;
    uint32_t first = 0;  // leaf: first in order_; inner: left child (right = first + 1)
    uint32_t count = 0;  // leaf: triangles; inner: 0
  };

  glm::vec3 vertex(uint32_t t, int k) const { return positions_[indices_[3 * t + static_cast<uint32_t>(k)]]; }

  static float boxDistance2(const Node& n, const glm::vec3& p) {
    const glm::vec3 d = glm::max(glm::max(n.lo - p, p - n.hi), glm::vec3(0.0f));
    return glm::dot(d, d);
  }

  // Iterative top-down build (median split on the longest centroid axis).
  void build(uint32_t first, uint32_t count) {
    struct Task {
      uint32_t node, first, count;
    };
    std::vector<Task> tasks;
    nodes_.push_back({});
    tasks.push_back({0, first, count});
    while (!tasks.empty()) {
      const Task task = tasks.back();
      tasks.pop_back();
      glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
      glm::vec3 clo = lo, chi = hi;
      for (uint32_t i = task.first; i < task.first + task.count; ++i) {
        const uint32_t t = order_[i];
        for (int k = 0; k < 3; ++k) {
          lo = glm::min(lo, vertex(t, k));
          hi = glm::max(hi, vertex(t, k));
        }
        clo = glm::min(clo, centroids_[t]);
        chi = glm::max(chi, centroids_[t]);
      }
      nodes_[task.node].lo = lo;
      nodes_[task.node].hi = hi;
      if (task.count <= kLeafSize) {
        nodes_[task.node].first = task.first;
        nodes_[task.node].count = task.count;
        continue;
      }
      const glm::vec3 ext = chi - clo;
      const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
      const uint32_t half = task.count / 2;
      auto begin = order_.begin() + task.first;
      std::nth_element(begin, begin + half, begin + task.count, [&](uint32_t a, uint32_t b) {
        return centroids_[a][axis] < centroids_[b][axis] || (centroids_[a][axis] == centroids_[b][axis] && a < b);
      });
      const uint32_t left = static_cast<uint32_t>(nodes_.size());
      nodes_.push_back({});
      nodes_.push_back({});
      nodes_[task.node].first = left;
      nodes_[task.node].count = 0;
      tasks.push_back({left, task.first, half});
      tasks.push_back({left + 1, task.first + half, task.count - half});
    }
  }

  std::span<const glm::vec3> positions_;
  std::span<const uint32_t> indices_;
  std::vector<uint32_t> order_;
  std::vector<glm::vec3> centroids_;
  std::vector<Node> nodes_;
};

// The mesh of `indices` with only the vertices they use.
void compactMesh(std::span<const glm::vec3> positions, std::span<const uint32_t> indices, ClusterMesh& mesh) {
  std::vector<uint32_t> used(positions.size(), kNone);
  mesh.positions.clear();
  mesh.indices.assign(indices.begin(), indices.end());
  for (uint32_t& i : mesh.indices) {
    if (used[i] == kNone) {
      used[i] = static_cast<uint32_t>(mesh.positions.size());
      mesh.positions.push_back(positions[i]);
    }
    i = used[i];
  }
}

// ---------------------------------------------------------------- the builder

class Builder {
 public:
  Builder(const Scene& scene, const BuildConfig& config) : scene_(scene), config_(config) {
    tree_.duration_s = scene.duration_s;
  }

  HdlodTree run() {
    const double T = scene_.duration_s;
    tree_.objectCluster.assign(scene_.objects.size(), kNone);
    std::vector<uint32_t> active, dynamic;
    std::vector<double> times, values;
    for (uint32_t i = 0; i < scene_.objects.size(); ++i) {
      const Object& o = scene_.objects[i];
      const Model& m = scene_.models[o.model];
      const ObjectClass cls = classify(o, T);
      if (m.triangleCount() == 0) {
        ++tree_.stats.emptyObjects;
        continue;
      }
      Cluster c;
      c.object = i;
      c.mesh = o.model;
      c.triangles = static_cast<uint32_t>(m.triangleCount());
      glm::dmat4 matrix(1.0);
      if (cls == ObjectClass::Dynamic) {
        ++tree_.stats.dynamicObjects;
        c.kind = ClusterKind::Dynamic;
        c.box = sweptBox(o, m);
      } else {
        ++(cls == ObjectClass::Static ? tree_.stats.staticObjects : tree_.stats.pseudoDynamicObjects);
        c.kind = ClusterKind::Object;
        matrix = objectMatrix(o, 0.0, T);
        c.box = transformBox(m.box, matrix);
      }
      c.size_m = diagonal(c.box);
      leafPresence(o, T, times, values);
      const uint32_t id = addCluster(c, times, values, matrix);
      tree_.objectCluster[i] = id;
      tree_.stats.leafTriangles += c.triangles;
      (c.kind == ClusterKind::Dynamic ? dynamic : active).push_back(id);
    }
    weight_.resize(tree_.clusters.size());
    for (size_t i = 0; i < tree_.clusters.size(); ++i) weight_[i] = std::max(tree_.clusters[i].size_m, kMinWeight_m);
    leaves_.resize(tree_.clusters.size());
    for (uint32_t id : active) leaves_[id] = {id};

    // The paper's three trees: static, pseudo-dynamic, dynamic.
    std::vector<uint32_t> statics, pseudo, tops;
    for (uint32_t id : active) {
      (classify(scene_.objects[tree_.clusters[id].object], T) == ObjectClass::Static ? statics : pseudo).push_back(id);
    }
    // Progress: the share of each stage is its share of the objects (model versions: 2 %).
    const double total = std::max<double>(1.0, static_cast<double>(active.size() + dynamic.size()));
    const double staticShare = 0.98 * static_cast<double>(statics.size()) / total;
    const double pseudoShare = 0.98 * static_cast<double>(pseudo.size()) / total;
    stage_ = "static";
    stageBase_ = 0.0;
    stageSpan_ = staticShare;
    if (!statics.empty()) tops.push_back(clusterStatic(std::move(statics)));
    stage_ = "pseudo-dynamic";
    stageBase_ = staticShare;
    stageSpan_ = pseudoShare;
    if (!pseudo.empty()) tops.push_back(clusterStatic(std::move(pseudo)));
    report(staticShare + pseudoShare, "dynamic");
    if (!dynamic.empty()) tops.push_back(groupDynamic(std::move(dynamic)));
    if (!tops.empty()) tree_.root = addGroup(tops, /*level=*/static_cast<uint16_t>(tree_.stats.levels + 1));
    report(0.98, "model versions");
    makeModelLods();
    reorderDepthFirst();
    report(1.0, "done");
    return std::move(tree_);
  }

 private:
  void report(double fraction, const char* stage) const {
    if (config_.progress) config_.progress(std::clamp(fraction, 0.0, 1.0), stage);
  }

  uint32_t addCluster(Cluster c, std::span<const double> times, std::span<const double> values, const glm::dmat4& matrix) {
    c.stepBegin = static_cast<uint32_t>(tree_.stepTimes.size());
    c.stepCount = static_cast<uint32_t>(times.size());
    tree_.stepTimes.insert(tree_.stepTimes.end(), times.begin(), times.end());
    tree_.stepValues.insert(tree_.stepValues.end(), values.begin(), values.end());
    tree_.clusters.push_back(c);
    tree_.leafMatrix.push_back(matrix);
    return static_cast<uint32_t>(tree_.clusters.size() - 1);
  }

  Step stepOf(uint32_t id) const {
    const Cluster& c = tree_.clusters[id];
    return {{tree_.stepTimes.data() + c.stepBegin, c.stepCount}, {tree_.stepValues.data() + c.stepBegin, c.stepCount}};
  }

  // A group (dynamic group or virtual root): f = 1 while any member is present.
  uint32_t addGroup(std::span<const uint32_t> members, uint16_t level) {
    Cluster g;
    g.kind = ClusterKind::Group;
    g.level = level;
    g.box = tree_.clusters[members[0]].box;
    for (uint32_t m : members) g.box = unite(g.box, tree_.clusters[m].box);
    g.size_m = diagonal(g.box);
    g.firstChild = static_cast<uint32_t>(tree_.children.size());
    g.childCount = static_cast<uint32_t>(members.size());
    tree_.children.insert(tree_.children.end(), members.begin(), members.end());
    std::vector<double> ones(members.size(), 1.0);
    presenceOf(tree_, members, ones, /*any=*/true, times_, values_, events_);
    return addCluster(g, times_, values_, glm::dmat4(1.0));
  }

  uint32_t groupDynamic(std::vector<uint32_t> level) {
    auto firstAppear = [&](uint32_t id) {
      const Step s = stepOf(id);
      for (size_t k = 0; k < s.values.size(); ++k) {
        if (s.values[k] > 0.0) return s.times[k];
      }
      return std::numeric_limits<double>::infinity();
    };
    std::stable_sort(level.begin(), level.end(), [&](uint32_t a, uint32_t b) { return firstAppear(a) < firstAppear(b); });
    const size_t g = static_cast<size_t>(std::clamp(config_.dynamicGroupSize, 2, 65535));
    uint16_t depth = 1;
    while (level.size() > 1) {
      std::vector<uint32_t> next;
      for (size_t i = 0; i < level.size(); i += g) {
        const size_t n = std::min(g, level.size() - i);
        next.push_back(addGroup({level.data() + i, n}, depth));
      }
      level = std::move(next);
      ++depth;
    }
    if (tree_.clusters[level[0]].kind == ClusterKind::Dynamic) return addGroup({level.data(), 1}, 1);
    return level[0];
  }

  // Appends a cluster's geometry relative to `origin` (and each vertex's material).
  void appendGeometry(uint32_t id, const glm::dvec3& origin, std::vector<glm::vec3>& positions,
                      std::vector<uint32_t>& indices, std::vector<uint16_t>& materials) const {
    const Cluster& c = tree_.clusters[id];
    const uint32_t base = static_cast<uint32_t>(positions.size());
    if (c.kind == ClusterKind::Object) {
      const Model& m = scene_.models[c.mesh];
      const glm::dmat4& M = tree_.leafMatrix[id];
      for (const glm::vec3& p : m.positions) positions.push_back(glm::vec3(glm::dvec3(M * glm::dvec4(glm::dvec3(p), 1.0)) - origin));
      for (uint32_t i : m.indices) indices.push_back(base + i);
      materials.insert(materials.end(), m.triangleCount(), materialOf(c.mesh));
    } else {
      const ClusterMesh& mesh = tree_.meshes[c.mesh];
      const glm::dvec3 shift = mesh.origin_m - origin;
      for (const glm::vec3& p : mesh.positions) positions.push_back(glm::vec3(glm::dvec3(p) + shift));
      for (uint32_t i : mesh.indices) indices.push_back(base + i);
      materials.insert(materials.end(), mesh.materials.begin(), mesh.materials.end());
    }
  }

  uint32_t makeParent(std::span<const uint32_t> kids, uint16_t level, double eps_l) {
    Cluster p;
    p.kind = ClusterKind::Merged;
    p.level = level;
    p.box = tree_.clusters[kids[0]].box;
    double childEps = 0.0;
    for (uint32_t k : kids) {
      p.box = unite(p.box, tree_.clusters[k].box);
      childEps = std::max(childEps, tree_.clusters[k].eps_m);
    }
    p.size_m = diagonal(p.box);
    ClusterMesh mesh;
    mesh.origin_m = centre(p.box);
    childPositions_.clear();
    childIndices_.clear();
    childMaterials_.clear();
    for (uint32_t k : kids) appendGeometry(k, mesh.origin_m, childPositions_, childIndices_, childMaterials_);
    SimplifyParams sp;
    sp.simplifier = config_.simplifier;
    sp.gridOffset_m = anchor_ - mesh.origin_m;
    sp.sloppyAboveTriangles = config_.sloppyAboveTriangles;
    sp.maxSamples = static_cast<uint32_t>(std::max(1, config_.maxHausdorffSamples));
    // Per material: each material's triangles are simplified and measured on their own, so a
    // colour region never vanishes into a neighbour of another colour at a small geometric
    // distance (a window 12 cm in front of its facade panel), and eps_c bounds how far a point of
    // each colour moves (the appearance-aware Hausdorff distance).
    const double d = simplifyPerMaterial(eps_l, sp, 0.5 * p.size_m, mesh);
    p.eps_m = d + childEps;
    tree_.stats.simplifyErrorSum_m += d;
    tree_.stats.simplifyErrorMax_m = std::max(tree_.stats.simplifyErrorMax_m, d);
    if (eps_l > 0.0) {
      tree_.stats.simplifyRelativeSum += d / eps_l;
      tree_.stats.simplifyRelativeMax = std::max(tree_.stats.simplifyRelativeMax, d / eps_l);
    }
    p.triangles = static_cast<uint32_t>(mesh.indices.size() / 3);
    tree_.stats.mergedTriangles += p.triangles;
    p.mesh = static_cast<uint32_t>(tree_.meshes.size());
    tree_.meshes.push_back(std::move(mesh));

    // Leaves, f_c, gamma_c.
    std::vector<uint32_t> leaves;
    for (uint32_t k : kids) leaves.insert(leaves.end(), leaves_[k].begin(), leaves_[k].end());
    weights_.clear();
    for (uint32_t l : leaves) weights_.push_back(weight_[l]);
    presenceOf(tree_, leaves, weights_, /*any=*/false, times_, values_, events_);
    p.gamma = temporalError(leaves);

    p.firstChild = static_cast<uint32_t>(tree_.children.size());
    p.childCount = static_cast<uint32_t>(kids.size());
    tree_.children.insert(tree_.children.end(), kids.begin(), kids.end());
    glm::dmat4 translate(1.0);
    translate[3] = glm::dvec4(tree_.meshes.back().origin_m, 1.0);
    const uint32_t id = addCluster(p, times_, values_, translate);
    weight_.push_back(std::max(p.size_m, kMinWeight_m));
    leaves_.push_back(std::move(leaves));
    for (uint32_t k : kids) std::vector<uint32_t>().swap(leaves_[k]);
    ++tree_.stats.mergedClusters;
    return id;
  }

  // Simplifies childPositions_ / childIndices_ material by material (childMaterials_) into
  // `mesh` (positions, indices, per-triangle materials); returns the largest measured error.
  double simplifyPerMaterial(double eps_l, const SimplifyParams& sp, double emptyError, ClusterMesh& mesh) {
    const size_t nt = childIndices_.size() / 3;
    materialOrder_.resize(nt);
    for (uint32_t t = 0; t < nt; ++t) materialOrder_[t] = t;
    std::stable_sort(materialOrder_.begin(), materialOrder_.end(),
                     [&](uint32_t a, uint32_t b) { return childMaterials_[a] < childMaterials_[b]; });
    mesh.positions.clear();
    mesh.indices.clear();
    mesh.materials.clear();
    double worst = 0.0;
    std::vector<uint32_t> remap(childPositions_.size(), kNone);
    for (size_t begin = 0; begin < nt;) {
      const uint16_t material = childMaterials_[materialOrder_[begin]];
      size_t end = begin;
      while (end < nt && childMaterials_[materialOrder_[end]] == material) ++end;
      partPositions_.clear();
      partIndices_.clear();
      for (size_t k = begin; k < end; ++k) {
        for (int c = 0; c < 3; ++c) {
          const uint32_t v = childIndices_[3 * materialOrder_[k] + c];
          if (remap[v] == kNone) {
            remap[v] = static_cast<uint32_t>(partPositions_.size());
            partPositions_.push_back(childPositions_[v]);
          }
          partIndices_.push_back(remap[v]);
        }
      }
      for (size_t k = begin; k < end; ++k) {
        for (int c = 0; c < 3; ++c) remap[childIndices_[3 * materialOrder_[k] + c]] = kNone;
      }
      SimplifiedMesh& simple = simplified_;
      simplifyMesh(partPositions_, partIndices_, eps_l, sp, simple);
      worst = std::max(worst, measuredError(partPositions_, partIndices_, simple, emptyError));
      tree_.stats.sloppyClusters += simple.sloppy ? 1u : 0u;
      ClusterMesh part;
      compactMesh(simple.positions, simple.indices, part);
      const uint32_t base = static_cast<uint32_t>(mesh.positions.size());
      mesh.positions.insert(mesh.positions.end(), part.positions.begin(), part.positions.end());
      for (uint32_t i : part.indices) mesh.indices.push_back(base + i);
      mesh.materials.insert(mesh.materials.end(), part.indices.size() / 3, material);
      begin = end;
    }
    return worst;
  }

  // The sampled one-sided Hausdorff distance from the input (every vertex and triangle centroid,
  // evenly strided down to the cap) to the simplified complex: the kept triangles plus, unless
  // strictHausdorff, the segments and points that collapsed triangles became. `emptyError` when
  // nothing is left.
  double measuredError(std::span<const glm::vec3> positions, std::span<const uint32_t> indices, SimplifiedMesh& simple,
                       double emptyError) {
    samples_.clear();
    // The surface is the triangles whose corners are three distinct points: one with coincident
    // corners draws nothing and the simplifier drops it (welded, it repeats an index), so its
    // corners are not sampled (nor is a vertex no triangle uses); else a material of only such
    // triangles, with nothing left, measured half the cluster's diagonal.
    const size_t nt = indices.size() / 3;
    surfaceVertex_.assign(positions.size(), 0);
    surfaceTriangles_.clear();
    for (size_t t = 0; t < nt; ++t) {
      const glm::vec3 &a = positions[indices[3 * t]], &b = positions[indices[3 * t + 1]], &c = positions[indices[3 * t + 2]];
      if (a == b || b == c || c == a) continue;
      surfaceTriangles_.push_back(static_cast<uint32_t>(t));
      for (int k = 0; k < 3; ++k) surfaceVertex_[indices[3 * t + static_cast<size_t>(k)]] = 1;
    }
    surfaceVertices_.clear();
    for (uint32_t v = 0; v < positions.size(); ++v) {
      if (surfaceVertex_[v]) surfaceVertices_.push_back(v);
    }
    const size_t total = surfaceVertices_.size() + surfaceTriangles_.size();
    const size_t cap = static_cast<size_t>(std::max(1, config_.maxHausdorffSamples));
    const size_t stride = std::max<size_t>(1, (total + cap - 1) / cap);
    for (size_t i = 0; i < total; i += stride) {
      if (i < surfaceVertices_.size()) {
        samples_.push_back(positions[surfaceVertices_[i]]);
      } else {
        const size_t t = surfaceTriangles_[i - surfaceVertices_.size()];
        samples_.push_back((positions[indices[3 * t]] + positions[indices[3 * t + 1]] + positions[indices[3 * t + 2]]) / 3.0f);
      }
    }
    tree_.stats.hausdorffSamples += samples_.size();
    if (!config_.strictHausdorff) simple.indices.insert(simple.indices.end(), simple.collapsed.begin(), simple.collapsed.end());
    double d = samples_.empty() ? 0.0 : simple.indices.empty() ? emptyError : sampledHausdorff(samples_, simple.positions, simple.indices);
    if (!std::isfinite(d)) d = emptyError;
    if (!config_.strictHausdorff) simple.indices.resize(simple.indices.size() - simple.collapsed.size());
    if (config_.twoSidedHausdorff && !simple.indices.empty() && indices.size() >= 3) {
      // The other direction: from the drawn triangles to the input. Their corners, and points
      // spread over each triangle (a barycentric grid of kBackGrid steps per edge, its edges'
      // and inner points) while the cap allows, else their centroids: a drawn triangle can
      // span a gap of the input (the sloppy grid joins a window frame's bars across the pane)
      // with its corners and centroid on the input and its edges far from it.
      samples_.clear();
      constexpr int kBackGrid = 4;
      constexpr size_t kBackPerTriangle = (kBackGrid + 1) * (kBackGrid + 2) / 2 - 3;
      const size_t snt = simple.indices.size() / 3;
      const size_t sstride = std::max<size_t>(1, (simple.positions.size() + cap - 1) / cap);
      for (size_t i = 0; i < simple.positions.size(); i += sstride) samples_.push_back(simple.positions[i]);
      const size_t room = cap > samples_.size() ? cap - samples_.size() : 0;
      const bool grid = snt * kBackPerTriangle <= room;
      const size_t tstride = grid ? 1 : std::max<size_t>(1, (snt + std::max<size_t>(room, 1) - 1) / std::max<size_t>(room, 1));
      for (size_t t = 0; t < snt; t += tstride) {
        const glm::vec3 a = simple.positions[simple.indices[3 * t]], b = simple.positions[simple.indices[3 * t + 1]],
                        c = simple.positions[simple.indices[3 * t + 2]];
        if (!grid) {
          samples_.push_back((a + b + c) / 3.0f);
          continue;
        }
        for (int i = 0; i <= kBackGrid; ++i) {
          for (int j = 0; i + j <= kBackGrid; ++j) {
            if (i == kBackGrid || j == kBackGrid || (i == 0 && j == 0)) continue;  // the corners
            const float u = static_cast<float>(i) / kBackGrid, v = static_cast<float>(j) / kBackGrid;
            samples_.push_back(a + (b - a) * u + (c - a) * v);
          }
        }
      }
      tree_.stats.hausdorffSamples += samples_.size();
      const double back = sampledHausdorff(samples_, positions, indices);
      if (std::isfinite(back)) d = std::max(d, back);
    }
    return d;
  }

  // Coarser versions of the scene models that leaves use (see hdlod_build.h).
  void makeModelLods() {
    std::vector<uint8_t> used(scene_.models.size(), 0);
    for (const Cluster& c : tree_.clusters) {
      if (c.kind == ClusterKind::Object || c.kind == ClusterKind::Dynamic) used[c.mesh] = 1;
    }
    tree_.modelLodBegin.assign(1, 0);
    SimplifyParams sp;
    sp.simplifier = config_.simplifier == Simplifier::Clustering ? Simplifier::Meshoptimizer : config_.simplifier;
    sp.sloppyAboveTriangles = config_.sloppyAboveTriangles;
    sp.maxSamples = static_cast<uint32_t>(std::max(1, config_.maxHausdorffSamples));
    for (size_t m = 0; m < scene_.models.size(); ++m) {
      const Model& model = scene_.models[m];
      const size_t begin = tree_.modelLods.size();
      if (used[m] && model.triangleCount() > config_.modelLodMinTriangles) {
        const double diag = diagonal(model.box);
        for (int k = 0; k < config_.modelLodLevels; ++k) {
          const double eps = diag * std::exp2(k - 6);
          simplifyMesh(model.positions, model.indices, eps, sp, simplified_);
          addModelVersion(m, begin, model, /*box=*/false);
        }
        // Last, the model's box (12 triangles): thin or lattice parts that edge collapses keep.
        const Model box = makeBoxModel("", model.box.max - model.box.min);
        const glm::vec3 shift((model.box.min + model.box.max) * 0.5 - glm::dvec3(0, 0, 0.5 * (model.box.max.z - model.box.min.z)));
        simplified_.positions = box.positions;
        for (glm::vec3& v : simplified_.positions) v += shift;
        simplified_.indices = box.indices;
        simplified_.collapsed.clear();
        addModelVersion(m, begin, model, /*box=*/true);
      }
      tree_.modelLodBegin.push_back(static_cast<uint32_t>(tree_.modelLods.size()));
    }
  }

  // Measures simplified_ as a version of scene model m (whose versions start at modelLods[begin])
  // and keeps it when it is worth drawing. A leaf draws its version's triangles and nothing else,
  // so the version is measured against them alone: a part that vanished (recorded as a segment
  // in simplified_.collapsed for merged clusters) is an error of its whole extent here, not of
  // its thickness (the crane jib's lattice vanished and its counterweight alone claimed 0.8 m).
  // Versions already kept with no fewer triangles and no smaller eps are dropped (the selection
  // would never want them), so the eps rise and the triangle counts fall along the list; a
  // version then needs at most 3/4 of the triangles of the one before it (the box: fewer).
  void addModelVersion(size_t m, size_t begin, const Model& model, bool box) {
    ClusterMesh mesh;
    compactMesh(simplified_.positions, simplified_.indices, mesh);
    simplified_.positions = mesh.positions;
    simplified_.indices = mesh.indices;
    simplified_.collapsed.clear();
    const size_t triangles = mesh.indices.size() / 3;
    if (triangles == 0) return;
    const double d = measuredError(model.positions, model.indices, simplified_, 0.5 * diagonal(model.box));
    size_t keep = tree_.modelLods.size();
    while (keep > begin && tree_.modelLods[keep - 1].eps_m >= d && tree_.modelLods[keep - 1].triangles >= triangles) --keep;
    const size_t previous = keep > begin ? tree_.modelLods[keep - 1].triangles : model.triangleCount();
    if (box ? triangles >= previous : 4 * triangles > 3 * previous) return;
    assert(keep == begin || tree_.modelLods[keep - 1].eps_m < d);
    while (tree_.modelLods.size() > keep) {
      assert(tree_.modelLods.back().mesh + 1 == tree_.meshes.size());  // this model's versions are the last meshes
      tree_.meshes.pop_back();
      tree_.modelLods.pop_back();
      --tree_.stats.modelLods;
    }
    mesh.materials.assign(triangles, materialOf(m));
    tree_.modelLods.push_back({static_cast<uint32_t>(tree_.meshes.size()), static_cast<uint32_t>(triangles), d});
    tree_.meshes.push_back(std::move(mesh));
    ++tree_.stats.modelLods;
  }

  // Renumbers the clusters depth-first (pre-order from the root), children contiguous.
  void reorderDepthFirst() {
    const size_t n = tree_.clusters.size();
    if (tree_.root == kNone || n == 0) return;
    std::vector<uint32_t> order, stack{tree_.root};
    order.reserve(n);
    while (!stack.empty()) {
      const uint32_t id = stack.back();
      stack.pop_back();
      order.push_back(id);
      const auto kids = tree_.childrenOf(tree_.clusters[id]);
      for (size_t k = kids.size(); k-- > 0;) stack.push_back(kids[k]);
    }
    std::vector<uint32_t> newId(n, kNone);
    for (size_t i = 0; i < order.size(); ++i) newId[order[i]] = static_cast<uint32_t>(i);
    HdlodTree out;
    out.duration_s = tree_.duration_s;
    out.root = 0;
    out.clusters.reserve(order.size());
    out.leafMatrix.reserve(order.size());
    out.children.reserve(tree_.children.size());
    for (uint32_t old : order) {
      Cluster c = tree_.clusters[old];
      const auto kids = tree_.childrenOf(tree_.clusters[old]);
      c.firstChild = static_cast<uint32_t>(out.children.size());
      for (uint32_t k : kids) out.children.push_back(newId[k]);
      c.stepBegin = static_cast<uint32_t>(out.stepTimes.size());
      out.stepTimes.insert(out.stepTimes.end(), tree_.stepTimes.begin() + tree_.clusters[old].stepBegin,
                           tree_.stepTimes.begin() + tree_.clusters[old].stepBegin + c.stepCount);
      out.stepValues.insert(out.stepValues.end(), tree_.stepValues.begin() + tree_.clusters[old].stepBegin,
                            tree_.stepValues.begin() + tree_.clusters[old].stepBegin + c.stepCount);
      out.clusters.push_back(c);
      out.leafMatrix.push_back(tree_.leafMatrix[old]);
    }
    tree_.clusters = std::move(out.clusters);
    tree_.children = std::move(out.children);
    tree_.stepTimes = std::move(out.stepTimes);
    tree_.stepValues = std::move(out.stepValues);
    tree_.leafMatrix = std::move(out.leafMatrix);
    tree_.root = 0;
    for (uint32_t& c : tree_.objectCluster) {
      if (c != kNone) c = newId[c];
    }
  }

  // gamma_c = max over leaves of mean |f_c - v_s|, with the f_c in times_ / values_:
  // integral |f - v| = integral f + integral over {v = 1} of (1 - 2 f).
  double temporalError(std::span<const uint32_t> leaves) {
    const double T = scene_.duration_s;
    const Step f{times_, values_};
    prefix_.assign(times_.size() + 1, 0.0);
    for (size_t i = 0; i < times_.size(); ++i) {
      const double end = i + 1 < times_.size() ? times_[i + 1] : T;
      prefix_[i + 1] = prefix_[i] + values_[i] * (end - times_[i]);
    }
    const double totalF = prefix_[times_.size()];
    double worst = 0.0;
    for (uint32_t l : leaves) {
      const Step v = stepOf(l);
      double onF = 0.0, onLength = 0.0;
      for (size_t k = 0; k < v.times.size(); ++k) {
        if (v.values[k] <= 0.0) continue;
        const double a = v.times[k], b = k + 1 < v.times.size() ? v.times[k + 1] : T;
        onF += integralTo(f, prefix_, b) - integralTo(f, prefix_, a);
        onLength += b - a;
      }
      worst = std::max(worst, (totalF + onLength - 2.0 * onF) / T);
    }
    return std::clamp(worst, 0.0, 1.0);
  }

  // Appendix 2 over the static + pseudo-dynamic leaves; returns the root.
  uint32_t clusterStatic(std::vector<uint32_t> active) {
    Aabb scene = tree_.clusters[active[0]].box;
    std::vector<double> diags;
    for (uint32_t id : active) {
      scene = unite(scene, tree_.clusters[id].box);
      diags.push_back(tree_.clusters[id].size_m);
    }
    const double W = std::max(diagonal(scene) * (1.0 + 1e-9), 1e-6);
    anchor_ = scene.min;
    int L = config_.levels;
    if (L <= 0) {
      std::nth_element(diags.begin(), diags.begin() + static_cast<long>(diags.size() / 2), diags.end());
      const double median = std::max(diags[diags.size() / 2], W * 1e-6);
      L = 1 + static_cast<int>(std::ceil(std::log2(std::max(1.0, W / (2.0 * median)))));
    }
    L = std::clamp(L, 1, 40);
    levelsEstimate_ = L + 1;
    const int maxChildren = std::clamp(config_.maxChildren, 2, 65535);
    int l = 0;
    while (active.size() > 1) {
      ++l;
      const int lc = std::min(l, L);
      const double w = W * std::exp2(lc - L), eps = w * config_.epsPerSize, gamma = std::exp2(lc - L);
      const size_t before = active.size();
      active = clusterLevel(active, scene, static_cast<uint16_t>(l), w, eps, gamma, maxChildren);
      if (active.size() == before && l >= L) {
        // Cannot happen with the frozen thresholds (everything qualifies); kept as a guard.
        active = {makeParent(active, static_cast<uint16_t>(l + 1), eps)};
      }
    }
    tree_.stats.levels = std::max(tree_.stats.levels, static_cast<uint32_t>(l));
    return active[0];
  }

  std::vector<uint32_t> clusterLevel(const std::vector<uint32_t>& active, const Aabb& scene, uint16_t level, double w,
                                     double eps, double gamma, int maxChildren) {
    const size_t n = active.size();
    // Hilbert order of the centres (16 bits per axis over the scene box).
    const glm::dvec3 ext = glm::max(scene.max - scene.min, glm::dvec3(1e-9));
    std::vector<std::pair<uint64_t, uint32_t>> order(n);
    for (size_t i = 0; i < n; ++i) {
      const glm::dvec3 u = glm::clamp((centre(tree_.clusters[active[i]].box) - scene.min) / ext, 0.0, 1.0) * 65535.0;
      order[i] = {hilbertKey(static_cast<uint32_t>(u.x), static_cast<uint32_t>(u.y), static_cast<uint32_t>(u.z), 16),
                  static_cast<uint32_t>(i)};
    }
    std::sort(order.begin(), order.end());

    // Uniform grid of cell w over the centres; each cell a range of `items` with a live count.
    auto cellCoord = [&](const glm::dvec3& c) {
      const glm::dvec3 g = glm::clamp(glm::floor((c - scene.min) / w), 0.0, 1048575.0);
      return glm::u64vec3(g);
    };
    auto cellKey = [](const glm::u64vec3& g) { return g.x | (g.y << 21) | (g.z << 42); };
    std::vector<std::pair<uint64_t, uint32_t>> items(n);
    for (size_t i = 0; i < n; ++i) items[i] = {cellKey(cellCoord(centre(tree_.clusters[active[i]].box))), static_cast<uint32_t>(i)};
    std::sort(items.begin(), items.end());
    std::vector<uint64_t> cellKeys;
    std::vector<uint32_t> cellStart, cellLive, slot(n), cellOfItem(n);
    for (size_t i = 0; i < n; ++i) {
      if (i == 0 || items[i].first != items[i - 1].first) {
        cellKeys.push_back(items[i].first);
        cellStart.push_back(static_cast<uint32_t>(i));
        cellLive.push_back(0);
      }
      ++cellLive.back();
      slot[items[i].second] = static_cast<uint32_t>(i);
      cellOfItem[items[i].second] = static_cast<uint32_t>(cellKeys.size() - 1);
    }
    auto removeItem = [&](uint32_t i) {
      const uint32_t cell = cellOfItem[i];
      const uint32_t last = cellStart[cell] + cellLive[cell] - 1;
      const uint32_t s = slot[i];
      const uint32_t moved = items[last].second;
      std::swap(items[s], items[last]);
      slot[moved] = s;
      slot[i] = last;
      --cellLive[cell];
    };

    std::vector<uint8_t> done(n, 0);
    std::vector<uint32_t> next;
    std::vector<std::pair<double, uint32_t>> candidates;
    std::vector<uint32_t> kids;
    const size_t perCell = static_cast<size_t>(std::max(1, config_.candidatesPerCell));
    size_t visited = 0;
    for (const auto& [key, rep] : order) {
      (void)key;
      if (config_.progress && (++visited & 255u) == 0) {
        const double inLevel = static_cast<double>(visited) / static_cast<double>(n);
        report(stageBase_ + stageSpan_ * std::min(1.0, (level - 1 + inLevel) / std::max(1, levelsEstimate_)), stage_);
      }
      if (done[rep]) continue;
      done[rep] = 1;
      removeItem(rep);
      const Cluster& rc = tree_.clusters[active[rep]];
      const glm::dvec3 rcen = centre(rc.box);
      const glm::i64vec3 g(cellCoord(rcen));
      candidates.clear();
      for (int dz = -1; dz <= 1; ++dz) {
        for (int dy = -1; dy <= 1; ++dy) {
          for (int dx = -1; dx <= 1; ++dx) {
            const glm::i64vec3 q = g + glm::i64vec3(dx, dy, dz);
            if (q.x < 0 || q.y < 0 || q.z < 0) continue;
            const uint64_t k = cellKey(glm::u64vec3(q));
            const auto it = std::lower_bound(cellKeys.begin(), cellKeys.end(), k);
            if (it == cellKeys.end() || *it != k) continue;
            const size_t cell = static_cast<size_t>(it - cellKeys.begin());
            const size_t m = std::min<size_t>(cellLive[cell], perCell);
            for (size_t j = 0; j < m; ++j) {
              const uint32_t i = items[cellStart[cell] + j].second;
              const double d = glm::length(centre(tree_.clusters[active[i]].box) - rcen);
              if (d <= w) candidates.emplace_back(d, i);
            }
          }
        }
      }
      std::sort(candidates.begin(), candidates.end());
      kids.assign(1, active[rep]);
      Aabb unionBox = rc.box;
      const Step rs = stepOf(active[rep]);
      for (const auto& [d, i] : candidates) {
        (void)d;
        if (static_cast<int>(kids.size()) >= maxChildren) break;
        const Aabb u = unite(unionBox, tree_.clusters[active[i]].box);
        if (diagonal(u) > w) continue;
        const Step cs = stepOf(active[i]);
        if (stepDistance(rs.times, rs.values, cs.times, cs.values, scene_.duration_s) > gamma) continue;
        unionBox = u;
        kids.push_back(active[i]);
        done[i] = 1;
        removeItem(i);
      }
      if (kids.size() == 1) {
        next.push_back(active[rep]);
      } else {
        next.push_back(makeParent(kids, level, eps));
      }
    }
    return next;
  }

  const Scene& scene_;
  const BuildConfig& config_;
  HdlodTree tree_;
  glm::dvec3 anchor_{0.0};                     // vertex-clustering grid corner of the tree being built
  std::vector<double> weight_;                 // per cluster (w_s for leaves)
  std::vector<std::vector<uint32_t>> leaves_;  // per active cluster: its leaf clusters
  std::vector<double> times_, values_, weights_, prefix_;
  std::vector<Event> events_;
  std::vector<glm::vec3> childPositions_, samples_;
  std::vector<uint32_t> childIndices_;
  std::vector<uint16_t> childMaterials_;
  std::vector<glm::vec3> partPositions_;
  std::vector<uint32_t> partIndices_, materialOrder_;
  std::vector<uint8_t> surfaceVertex_;                   // measuredError(): per input vertex
  std::vector<uint32_t> surfaceVertices_, surfaceTriangles_;
  const char* stage_ = "";
  double stageBase_ = 0.0, stageSpan_ = 0.0;
  int levelsEstimate_ = 1;
  SimplifiedMesh simplified_;
};

}  // namespace

double clusterPresence(const HdlodTree& tree, const Cluster& c, double t_s) {
  if (c.stepCount == 0) return 0.0;
  const double t = clampTime(t_s, tree.duration_s);
  const double* times = tree.stepTimes.data() + c.stepBegin;
  const double* end = times + c.stepCount;
  const double* it = std::upper_bound(times, end, t);
  const size_t i = it == times ? 0 : static_cast<size_t>(it - times) - 1;
  return tree.stepValues[c.stepBegin + i];
}

double clusterDelta(const HdlodTree& tree, const Cluster& c, double t_s) {
  const double f = clusterPresence(tree, c, t_s);
  return c.eps_m + c.size_m * (1.0 - std::abs(2.0 * f - 1.0));
}

double stepDistance(std::span<const double> timesA, std::span<const double> valuesA, std::span<const double> timesB,
                    std::span<const double> valuesB, double duration_s) {
  if (timesA.empty() || timesB.empty() || !(duration_s > 0.0)) return 0.0;
  size_t i = 0, j = 0;
  double t = 0.0, sum = 0.0;
  while (t < duration_s) {
    const double nextA = i + 1 < timesA.size() ? timesA[i + 1] : duration_s;
    const double nextB = j + 1 < timesB.size() ? timesB[j + 1] : duration_s;
    const double end = std::min({nextA, nextB, duration_s});
    sum += std::abs(valuesA[i] - valuesB[j]) * (end - t);
    t = end;
    if (nextA <= t && i + 1 < timesA.size()) ++i;
    if (nextB <= t && j + 1 < timesB.size()) ++j;
    if (end >= duration_s) break;
  }
  return sum / duration_s;
}

double sampledHausdorff(std::span<const glm::vec3> samples, std::span<const glm::vec3> positions,
                        std::span<const uint32_t> indices) {
  if (samples.empty()) return 0.0;
  if (indices.size() < 3) return std::numeric_limits<double>::infinity();
  const TriangleBvh bvh(positions, indices);
  float worst = 0.0f;
  for (const glm::vec3& s : samples) worst = std::max(worst, bvh.nearest(s, worst));
  return static_cast<double>(worst);
}

HdlodTree buildHdlod(const Scene& scene, const BuildConfig& config) {
  assert(validateScene(scene).empty());
  HdlodTree tree = Builder(scene, config).run();
  [[maybe_unused]] const bool tree_ok = prepareSelection(tree);
  assert(tree_ok);
  return tree;
}

}  // namespace ig::lod::hdlod
