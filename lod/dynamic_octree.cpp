// Single-reference octree and the expensive-node estimate of hidden objects (paper 002).
#include "lod/dynamic_octree.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

namespace ig::lod {
namespace {

bool finiteBox(const Aabb& b) {
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(b.min[i]) || !std::isfinite(b.max[i]) || b.min[i] > b.max[i]) return false;
  return true;
}
bool inside(const Aabb& outer, const Aabb& b) {
  return b.min.x >= outer.min.x && b.min.y >= outer.min.y && b.min.z >= outer.min.z && b.max.x <= outer.max.x &&
         b.max.y <= outer.max.y && b.max.z <= outer.max.z;
}
// Empty: +inf ... -inf, so that growing it by any finite box gives that box (with +-1e300 a box
// beyond 1e300 came out loose: DynamicOctree.BoundsAreTightForBoxesBeyondOneE300).
Aabb emptyBox() {
  constexpr double inf = std::numeric_limits<double>::infinity();
  return {glm::dvec3(inf), glm::dvec3(-inf)};
}
// True if the box (eye-relative) lies wholly inside the frustum: every node below it is drawn.
bool insideFrustum(const Frustum& f, const Aabb& b) {
  for (const auto& p : f.planes) {
    // The box corner nearest along the plane normal.
    const glm::dvec3 v{p.x >= 0 ? b.min.x : b.max.x, p.y >= 0 ? b.min.y : b.max.y, p.z >= 0 ? b.min.z : b.max.z};
    if (p.x * v.x + p.y * v.y + p.z * v.z + p.w < 0.0) return false;
  }
  return true;
}
// Traversal states (queueHidden_): drawn normally, drawn under a node found hidden (estimate
// only: its objects are counted), or only counted (under a node skipped as hidden).
constexpr uint8_t kVisibleWalk = 0, kUnderHidden = 1, kCountOnly = 2;
bool isEmpty(const Aabb& b) { return b.min.x > b.max.x; }
void grow(Aabb& a, const Aabb& b) {
  a.min = glm::min(a.min, b.min);
  a.max = glm::max(a.max, b.max);
}

}  // namespace

bool DynamicOctree::init(const OctreeConfig& config) {
  if (!finiteBox(config.bounds) || config.maxDepth > 20 || config.maxObjects == 0 || config.maxNodes == 0) return false;
  const glm::dvec3 size = config.bounds.max - config.bounds.min;
  if (!(size.x > 0.0 && size.y > 0.0 && size.z > 0.0)) return false;
  config_ = config;
  nodes_.clear();
  nodes_.reserve(config.maxNodes);
  objects_.assign(config.maxObjects, ObjectRec{});
  dirtyList_.clear();
  dirtyList_.reserve(nodes_.capacity());
  refreshList_.clear();
  refreshList_.reserve(nodes_.capacity());
  queue_.reserve(nodes_.capacity());
  queueHidden_.reserve(nodes_.capacity());
  others_.reserve(nodes_.capacity());
  expensive_.reserve(nodes_.capacity());
  Node root;
  std::fill(std::begin(root.children), std::end(root.children), kNone);
  root.cell = config.bounds;
  root.bounds = root.ownBounds = emptyBox();
  nodes_.push_back(std::move(root));
  objectCount_ = 0;
  nonEmpty_ = 0;
  return true;
}

uint32_t DynamicOctree::child(uint32_t n, uint32_t octant) {
  if (nodes_[n].children[octant] != kNone) return nodes_[n].children[octant];
  const Aabb& c = nodes_[n].cell;
  const glm::dvec3 mid = 0.5 * (c.min + c.max);
  Node k;
  std::fill(std::begin(k.children), std::end(k.children), kNone);
  for (int i = 0; i < 3; ++i) {
    const bool hi = (octant >> i) & 1u;
    k.cell.min[i] = hi ? mid[i] : c.min[i];
    k.cell.max[i] = hi ? c.max[i] : mid[i];
  }
  k.parent = n;
  k.depth = nodes_[n].depth + 1;
  k.bounds = k.ownBounds = emptyBox();
  const auto id = static_cast<uint32_t>(nodes_.size());
  nodes_.push_back(std::move(k));
  nodes_[n].children[octant] = id;
  return id;
}

uint32_t DynamicOctree::place(const Aabb& box) {
  uint32_t n = 0;
  while (nodes_[n].depth < config_.maxDepth) {
    const Aabb& c = nodes_[n].cell;
    const glm::dvec3 mid = 0.5 * (c.min + c.max);
    uint32_t octant = 0;
    bool straddles = false;
    for (int i = 0; i < 3; ++i) {
      if (box.min[i] >= mid[i]) {
        octant |= 1u << i;
      } else if (box.max[i] > mid[i]) {
        straddles = true;
      }
    }
    if (straddles || !inside(c, box)) break;
    if (nodes_[n].children[octant] == kNone && nodes_.size() >= config_.maxNodes) break;
    n = child(n, octant);
  }
  return n;
}

void DynamicOctree::markDirty(uint32_t n) {
  Node& node = nodes_[n];
  node.boundsDirty = true;
  if (!node.dirty) {
    node.dirty = true;
    dirtyList_.push_back(n);
  }
}

void DynamicOctree::attach(uint32_t id, uint32_t n) {
  ObjectRec& o = objects_[id];
  o.node = n;
  o.slot = static_cast<uint32_t>(nodes_[n].objects.size());
  if (nodes_[n].objects.empty()) ++nonEmpty_;
  nodes_[n].objects.push_back(id);
  for (uint32_t a = n; a != kNone; a = nodes_[a].parent) ++nodes_[a].subtreeCount;
  markDirty(n);
  countsChanged_ = true;
}

void DynamicOctree::detach(uint32_t id) {
  ObjectRec& o = objects_[id];
  const uint32_t n = o.node;
  std::vector<uint32_t>& list = nodes_[n].objects;
  const uint32_t last = list.back();
  list[o.slot] = last;
  objects_[last].slot = o.slot;
  list.pop_back();
  if (list.empty()) --nonEmpty_;
  for (uint32_t a = n; a != kNone; a = nodes_[a].parent) --nodes_[a].subtreeCount;
  o.node = kNone;
  markDirty(n);
  countsChanged_ = true;
}

bool DynamicOctree::insert(uint32_t id, const Aabb& box) {
  if (id >= objects_.size() || objects_[id].node != kNone || !finiteBox(box)) return false;
  objects_[id].box = box;
  attach(id, place(box));
  ++objectCount_;
  return true;
}

bool DynamicOctree::move(uint32_t id, const Aabb& box) {
  if (!contains(id) || !finiteBox(box)) return false;
  objects_[id].box = box;
  const uint32_t n = place(box);
  if (n == objects_[id].node) {
    markDirty(n);  // same node: its command range still needs the new matrix
    return true;
  }
  detach(id);
  attach(id, n);
  return true;
}

bool DynamicOctree::remove(uint32_t id) {
  if (!contains(id)) return false;
  detach(id);
  --objectCount_;
  return true;
}

void DynamicOctree::clearDirty() {
  for (uint32_t n : dirtyList_) nodes_[n].dirty = false;
  dirtyList_.clear();
}

void DynamicOctree::refresh() {
  // Own bounds of dirty nodes, then subtree bounds of them and their ancestors, deepest first.
  refreshList_.clear();
  for (uint32_t n : dirtyList_) {
    Node& node = nodes_[n];
    if (!node.boundsDirty) continue;
    node.boundsDirty = false;
    node.ownBounds = emptyBox();
    for (uint32_t id : node.objects) grow(node.ownBounds, objects_[id].box);
    for (uint32_t a = n; a != kNone && !nodes_[a].refreshQueued; a = nodes_[a].parent) {
      nodes_[a].refreshQueued = true;  // (its ancestors are queued then too)
      refreshList_.push_back(a);
    }
  }
  // Bottom-up: children are created after parents, so in decreasing index order.
  std::sort(refreshList_.begin(), refreshList_.end(), std::greater<uint32_t>());
  for (uint32_t n : refreshList_) {
    Node& node = nodes_[n];
    node.bounds = node.ownBounds;
    for (uint32_t c : node.children)
      if (c != kNone && !isEmpty(nodes_[c].bounds)) grow(node.bounds, nodes_[c].bounds);
    node.refreshQueued = false;
  }
  if (countsChanged_) {
    // Expensive nodes: own objects far above the average per non-empty node, propagated upwards.
    const double avg = nonEmpty_ ? static_cast<double>(objectCount_) / nonEmpty_ : 0.0;
    const double threshold = std::max(config_.expensiveFactor * avg, static_cast<double>(config_.expensiveMinObjects));
    for (Node& node : nodes_) node.expensive = static_cast<double>(node.objects.size()) >= threshold;
    for (size_t i = nodes_.size(); i-- > 1;)
      if (nodes_[i].expensive) nodes_[nodes_[i].parent].expensive = true;
    countsChanged_ = false;
  }
}

bool DynamicOctree::checkInvariant() const {
  std::vector<uint32_t> seen(objects_.size(), 0);
  uint64_t total = 0;
  for (size_t n = 0; n < nodes_.size(); ++n) {
    const Node& node = nodes_[n];
    for (size_t s = 0; s < node.objects.size(); ++s) {
      const uint32_t id = node.objects[s];
      if (id >= objects_.size() || objects_[id].node != n || objects_[id].slot != s) return false;
      if (++seen[id] != 1) return false;
    }
    total += node.objects.size();
    uint64_t sub = node.objects.size();
    for (uint32_t c : node.children)
      if (c != kNone) sub += nodes_[c].subtreeCount;
    if (sub != node.subtreeCount) return false;
  }
  for (size_t id = 0; id < objects_.size(); ++id)
    if ((objects_[id].node != kNone) != (seen[id] == 1)) return false;
  return total == objectCount_;
}

void DynamicOctree::setQueryPending(uint32_t n, bool pending) {
  Node& node = nodes_[n];
  node.queryPending = pending;
  if (pending) node.queryBounds = node.bounds;
}

void DynamicOctree::setOcclusionResult(uint32_t n, bool visible, uint64_t issuedFrame) {
  Node& node = nodes_[n];
  const Aabb tested = node.queryPending ? node.queryBounds : node.bounds;
  node.queryPending = false;
  if (visible && issuedFrame < visibleValidFrom_) {
    // Measured before a new occluder: not a fresh "visible" (the node is tested again), but newer
    // than an older "hidden", which must not go on skipping a node seen since.
    if (node.occluded && issuedFrame >= node.resultFrame) node.occluded = false, node.resultFrame = 0;
    return;
  }
  if (issuedFrame >= node.resultFrame) {
    node.occluded = !visible;
    node.resultFrame = issuedFrame;
    if (!visible) node.hiddenBounds = tested;
  }
}

void DynamicOctree::clearOcclusion() {
  for (Node& n : nodes_) n.occluded = false, n.queryPending = false, n.resultFrame = 0;
}

void DynamicOctree::expireVisibleResults(uint64_t frame) {
  for (Node& n : nodes_)
    if (!n.occluded) n.resultFrame = 0;
  visibleValidFrom_ = std::max(visibleValidFrom_, frame);
}

DynamicOctree::TraversalResult DynamicOctree::traverse(const Frustum& frustum, const Traversal& t,
                                                       std::span<uint32_t> draw, std::span<uint32_t> test) {
  TraversalResult r;
  queue_.clear();
  queueHidden_.clear();
  others_.clear();
  expensive_.clear();
  if (nodes_.empty() || nodes_[0].subtreeCount == 0) return r;
  queue_.push_back(0);
  queueHidden_.push_back(kVisibleWalk);
  for (size_t head = 0; head < queue_.size(); ++head) {
    const uint32_t n = queue_[head];
    uint8_t state = queueHidden_[head];
    const Node& node = nodes_[n];
    const Aabb rel{node.bounds.min - t.eye_m, node.bounds.max - t.eye_m};
    ++r.frustumTests;
    if (!frustum.intersects(rel)) continue;
    // The estimate counts what culling would skip: the objects of the nodes the frustum would
    // draw, not those of a hidden node's octants outside the view.
    const auto countSkipped = [&] {
      if (insideFrustum(frustum, rel)) {
        r.hiddenObjects += node.subtreeCount;
        return;
      }
      r.hiddenObjects += node.objects.size();
      for (uint32_t c : node.children)
        if (c != kNone && nodes_[c].subtreeCount > 0) {
          queue_.push_back(c);
          queueHidden_.push_back(kCountOnly);
        }
    };
    if (state == kCountOnly) {
      countSkipped();
      continue;
    }
    // A box test is meaningful only when the whole box is in front of the near plane.
    const glm::dvec4& nearPlane = frustum.planes[4];
    bool testable = true;
    for (int c = 0; c < 8 && testable; ++c) {
      const glm::dvec3 p((c & 1) ? rel.max.x : rel.min.x, (c & 2) ? rel.max.y : rel.min.y, (c & 4) ? rel.max.z : rel.min.z);
      testable = glm::dot(glm::dvec3(nearPlane), p) + nearPlane.w > 0.0;
    }
    // A "hidden" result holds for the box it was measured on: an object moved or added into the
    // subtree since may reach out of it into view (then the node is tested again, not skipped).
    const bool hiddenHolds = node.occluded && node.resultFrame + config_.occlusionMaxAge >= t.frame &&
                             inside(node.hiddenBounds, node.bounds);
    if (testable && hiddenHolds) {
      if (t.useOcclusion) {
        if (!node.queryPending && r.candidates < test.size()) test[r.candidates++] = n;  // re-test it
        countSkipped();
        continue;
      }
      state = kUnderHidden;
    }
    if (state == kUnderHidden) r.hiddenObjects += node.objects.size();
    // Top-down: a node with a fresh "visible" result is not tested again until it is stale; its
    // children become the candidates instead.
    const bool freshVisible = node.resultFrame != 0 && !node.occluded && node.resultFrame + config_.occlusionMaxAge >= t.frame;
    if (testable && !node.queryPending && !freshVisible && n != 0) {
      if (node.expensive) {
        expensive_.push_back(n);
      } else if (!node.objects.empty() && node.subtreeCount >= config_.expensiveMinObjects) {
        others_.push_back(n);  // a test costs more than drawing a handful of objects
      }
    }
    if (!node.objects.empty() && r.drawn < draw.size()) {
      draw[r.drawn++] = n;
      r.objectsDrawn += node.objects.size();
    }
    for (uint32_t c : node.children)
      if (c != kNone && nodes_[c].subtreeCount > 0) {
        queue_.push_back(c);
        queueHidden_.push_back(state);
      }
  }
  // The re-tests of hidden nodes are in `test` already (written during the walk), then the rest.
  r.retests = r.candidates;
  for (const std::vector<uint32_t>* list : {&expensive_, &others_})
    for (uint32_t n : *list) {
      if (r.candidates >= test.size()) break;
      test[r.candidates++] = n;
    }
  return r;
}

}  // namespace ig::lod
