// Single-reference octree for dynamic objects (paper 002, section 4, strategies 2 and 3): every
// object is stored in exactly one node, the deepest one whose cell contains the object's box
// whole (objects straddling a cell border stay in the parent; objects outside the root cell stay
// in the root). Moving an object touches only its old and its new node, which are marked dirty
// so the renderer rebuilds only their command ranges.
//
// Also the per-node occlusion state of strategy 3 and the estimate of hidden objects (paper 002,
// section 3): a node is "expensive" when it holds far more objects than the average non-empty
// node (or has an expensive child: propagated bottom-up); the visibility of expensive nodes is
// tested top-down, and the objects under nodes found hidden are the estimate.
//
// Pure: no GL, no clock (frame numbers are passed in). Node and object storage is reserved in
// init(); insert/move/remove allocate only when a node's object list outgrows what it ever held.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/view.h"

namespace ig::lod {

struct OctreeConfig {
  Aabb bounds;                  // root cell (world metres); objects outside it stay in the root
  uint32_t maxDepth = 6;        // root = depth 0
  uint32_t maxObjects = 1 << 16;  // object ids are 0 .. maxObjects-1
  double expensiveFactor = 4.0;   // expensive: own objects >= factor * average per non-empty node
  uint32_t expensiveMinObjects = 8;  // ... and at least this many; nodes with fewer objects in
                                     // their subtree are never test candidates
  uint32_t occlusionMaxAge = 8;      // an "occluded" result older than this many frames is ignored
  uint32_t maxNodes = 1 << 17;       // octants are not created beyond this (objects stay higher up)
};

class DynamicOctree {
 public:
  static constexpr uint32_t kNone = 0xffffffffu;

  struct Node {
    Aabb cell;                      // the octant
    Aabb bounds;                    // tight box of the objects of the whole subtree (valid after refresh)
    Aabb ownBounds;                 // tight box of this node's own objects
    uint32_t children[8];           // kNone where absent
    uint32_t parent = kNone;
    uint32_t depth = 0;
    uint32_t subtreeCount = 0;      // objects in this node and below
    std::vector<uint32_t> objects;  // object ids held by this node (single reference)
    bool dirty = false;             // objects added, removed or moved since the last clearDirty()
    bool boundsDirty = false;       // own objects changed since the last refresh()
    bool refreshQueued = false;     // refresh() scratch: in refreshList_
    bool expensive = false;
    // Occlusion state (strategy 3), written by the renderer through setOcclusionResult().
    bool occluded = false;
    bool queryPending = false;
    uint64_t resultFrame = 0;       // frame the result's query was issued in
    Aabb queryBounds;               // the box of the query in flight (bounds when it was issued)
    Aabb hiddenBounds;              // the box the "occluded" result was measured on: it holds
                                    // only while the node's bounds stay inside it (an object
                                    // moved or added into the node may be in view)
  };

  // Reserves storage. Returns false for a bad config (empty or non-finite bounds, maxDepth > 20).
  bool init(const OctreeConfig& config);
  const OctreeConfig& config() const { return config_; }

  // Adds object `id` with world box `box`. False if id is out of range, already present, or the
  // box is not finite (NaN, inf) or inverted.
  bool insert(uint32_t id, const Aabb& box);
  // Moves object `id` to `box`: only its old and new node become dirty (one node if it stays).
  // False if the object is absent or the box invalid (the object then keeps its old place).
  bool move(uint32_t id, const Aabb& box);
  bool remove(uint32_t id);
  bool contains(uint32_t id) const { return id < objects_.size() && objects_[id].node != kNone; }
  uint32_t nodeOf(uint32_t id) const { return id < objects_.size() ? objects_[id].node : kNone; }
  const Aabb& boxOf(uint32_t id) const { return objects_[id].box; }

  // Recomputes the bounds of dirty nodes and their ancestors and the expensive flags. Call once
  // a frame before culling (cost: dirty nodes x depth (log of that to order them), plus all nodes
  // when counts changed).
  void refresh();
  // Nodes marked dirty since the last clearDirty(), each once.
  std::span<const uint32_t> dirtyNodes() const { return dirtyList_; }
  void clearDirty();

  std::span<const Node> nodes() const { return nodes_; }
  const Node& node(uint32_t i) const { return nodes_[i]; }
  uint32_t objectCount() const { return objectCount_; }
  uint32_t nonEmptyNodes() const { return nonEmpty_; }
  // Every stored object is in exactly one node and its node's list holds it once (test aid; O(n)).
  bool checkInvariant() const;

  // Per-frame traversal (breadth-first, top-down) of the nodes intersecting the frustum.
  struct Traversal {
    uint64_t frame = 0;          // current frame number (for the age of occlusion results)
    bool useOcclusion = false;   // skip subtrees whose last fresh result says occluded (else only
                                 // count their objects in hiddenObjects: the estimate alone)
    glm::dvec3 eye_m{0.0};
  };
  struct TraversalResult {
    uint32_t drawn = 0;          // nodes written to `draw` (non-empty, visible)
    uint32_t frustumTests = 0;   // node boxes tested against the frustum
    uint32_t candidates = 0;     // nodes written to `test`
    uint32_t retests = 0;        // of them, first: nodes known hidden, re-tested to stay culled
    uint64_t objectsDrawn = 0;   // objects in the drawn nodes
    uint64_t hiddenObjects = 0;  // objects under nodes found occluded that the frustum would draw
                                 // (the estimate: what occlusion culling skips; not those of
                                 // their octants outside the view)
  };
  // Writes the non-empty visible nodes to `draw` and the nodes whose visibility may be tested
  // this frame to `test`: with useOcclusion the nodes known hidden first (their re-tests keep
  // them culled: `retests` of them), then expensive nodes (top-down), then the other non-empty
  // nodes with at least expensiveMinObjects objects below them,
  // excluding nodes with a query in flight, nodes with a fresh "visible" result (so over a few
  // frames the tests move down the tree below visible nodes; hidden nodes are re-tested every
  // frame), and nodes whose box contains the eye or reaches behind the near plane (a box test
  // there says nothing). Both spans need nodes().size().
  TraversalResult traverse(const Frustum& frustum, const Traversal& t, std::span<uint32_t> draw,
                           std::span<uint32_t> test);
  // Query bookkeeping (strategy 3).
  // Marks a query in flight for `node`, on its current bounds (call after refresh()).
  void setQueryPending(uint32_t node, bool pending);
  // A query's result. A "hidden" one applies to the box the query was drawn with (the bounds
  // at setQueryPending; the current bounds if none is pending): once objects moved or added
  // into the node reach outside that box, traverse() no longer skips the node and tests it again.
  void setOcclusionResult(uint32_t node, bool visible, uint64_t issuedFrame);
  void clearOcclusion();
  // A new object that could hide others: every "visible" result is stale from now on (it was
  // measured without that object), so those nodes become test candidates again at once, and a
  // "visible" result of a test issued before `frame` is not taken as fresh when it arrives (it
  // still ends an older "hidden" result: the node is drawn and tested again). "Hidden" results
  // stay: hidden nodes are re-tested every frame anyway.
  void expireVisibleResults(uint64_t frame);

 private:
  struct ObjectRec {
    Aabb box;
    uint32_t node = kNone;
    uint32_t slot = 0;  // index in the node's object list
  };
  uint32_t place(const Aabb& box);  // the node for a box, creating octants on the way
  uint32_t child(uint32_t node, uint32_t octant);
  void attach(uint32_t id, uint32_t node);
  void detach(uint32_t id);
  void markDirty(uint32_t node);

  OctreeConfig config_;
  std::vector<Node> nodes_;
  std::vector<ObjectRec> objects_;
  std::vector<uint32_t> dirtyList_;
  std::vector<uint32_t> refreshList_;  // refresh() scratch: dirty nodes and their ancestors
  std::vector<uint32_t> queue_;     // traversal scratch
  std::vector<uint32_t> others_;    // traversal scratch: non-expensive candidates
  std::vector<uint32_t> expensive_; // traversal scratch: expensive candidates (after the re-tests)
  std::vector<uint8_t> queueHidden_;  // traversal scratch: the node's state (under a hidden node?)
  uint32_t objectCount_ = 0;
  uint32_t nonEmpty_ = 0;
  uint64_t visibleValidFrom_ = 0;  // "visible" results of tests issued earlier are ignored
  bool countsChanged_ = false;
};

}  // namespace ig::lod
