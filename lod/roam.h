// Continuous terrain LOD: ROAM, "Real-time Optimally Adapting Meshes" (M. Duchaineau et al.,
// IEEE Visualization 1997): a binary tree of right isosceles triangles over a height field,
// refined by forced splits and coarsened by diamond merges driven by split / merge priority
// queues; plus enhMerge from "continuous LOD for terrain" (Graphicon 2002, shared/seeds/001):
// merge ANY previously split triangle in one step, destroying its whole subtree and collapsing
// neighbours as needed so the mesh stays crack-free. enhMerge makes low-coherence frames (fast
// motion, hard turns, teleports) cheap instead of costing a chain of single merges or a rebuild.
//
// Grid. The DEM (width x height samples, row-major, row = north index y) is covered by a grid
// of base squares of side S = 2^k samples, S the largest power of two <= min(width, height) - 1,
// as many squares as needed to cover the DEM (rootsX x rootsY). Each square is two base
// triangles (level 0). Grid vertices east of the DEM (x > width - 1) or north of it
// (y > height - 1) are CLAMPED to the nearest edge sample, in position and in height:
// vertexPosition() maps them onto the DEM border, so the emitted mesh covers exactly the DEM
// rectangle (triangles wholly outside it become zero-area and are not emitted).
// Levels: a level-L triangle splits at its hypotenuse midpoint into two level-(L+1) triangles;
// the finest level is 2k (legs of one sample).
//
// Bounds (constructor, O(vertices)). Every grid vertex that is not a base-square corner is the
// split vertex of exactly one diamond (the two same-level triangles sharing a hypotenuse), so
// bounds are stored per vertex: a nested error e(D) = max(|h(v) - (h(a) + h(b)) / 2|,
// e(child diamonds)) (a parent's bound is >= its children's) and a nested height range of all
// geometry its descendants can emit, quantised to 16 bits (8 bytes a vertex in all). The
// diamond's box has an xy half-size of 3h (square diamonds, half side h) or 2h (diamonds with
// an axis-aligned hypotenuse of half length h), which contains the boxes of all its
// descendant diamonds, so box(child) is inside box(parent).
//
// Selection rule. For a view, a diamond's projected error is
//     errorPx(D) = e(D) * viewportHeight_px / (2 tan(fovY / 2)) / distance(eye, box(D))
// with errorPx = infinity when the eye is in the box (distance 0) and e(D) > 0, 0 when e(D) = 0,
// 0 when the box is outside the view frustum, and 0 for non-finite input (a NaN camera refines
// nothing). Because e and the boxes are nested, errorPx(parent) >= errorPx(child): the
// refined mesh for a tolerance is unique. A triangle is split if errorPx of its diamond is
// > tolerance_px (and the triangle count / pool allow it, highest errorPx first); a split
// triangle whose errorPx <= tolerance_px is merged. After a finished update without the
// triangle cap binding, every leaf has errorPx <= tolerance_px (or is at the finest level).
//
// Cost. EnhMerge, MergeQueue and Rebuild scan the live nodes once per update in pool order
// (O(nodes), a priority each), plus O(log n) per split / merge: the scan dominates for large
// meshes (a 1 px view of a 16385^2 DEM, ~580k triangles: ~30 ms). Deferred re-examines only
// the nodes whose decision may have changed (a schedule keyed by eye travel), O(due log n),
// and can run under a budget of node visits (RoamView::maxVisits) with a bounded lateness
// (RoamView::lateness) that keeps nodes near their threshold from being looked at every frame.
// docs/terrain.md describes the modes and the benchmark.
//
// Memory. The Roam object keeps a pointer to the caller's heights: they must stay alive and
// unchanged while the object lives. Every buffer (node pool, queues, stacks) is allocated in
// the constructor (the pool is calloc'd: pages are committed as the mesh first grows into
// them); update() (but see RoamMode::Deferred) and emit*() do not allocate.
// validate() is a debug tool and allocates.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/view.h"

namespace ig::lod {

struct RoamConfig {
  // Hard cap on leaf triangles (the emitted mesh). RoamView::maxTriangles may lower it per frame.
  uint64_t maxTriangles = 1u << 20;
  // Bintree nodes in the pool (leaves and internal nodes). 0 = 2 * maxTriangles + the base
  // triangles, enough for any mesh within maxTriangles. Raised to at least 2 * base triangles.
  // When the pool is full, splitting stops (RoamStats::poolExhausted) and the mesh stays valid.
  size_t nodeCapacity = 0;
};

struct RoamView {
  Camera camera;                    // eye (ENU), attitude, fovY, frustum
  double viewportHeight_px = 1080;  // height of the viewport the mesh is drawn into
  double tolerance_px = 1.0;        // screen-space error target (> 0 for any coarsening)
  uint64_t maxTriangles = 0;        // triangle target for this frame; 0 = RoamConfig::maxTriangles
  uint32_t maxOperations = 0;       // work budget: splits + merges + enhMerges; 0 = unlimited
  // Deferred only: work budget in node visits (nodes examined + nodes created + nodes freed);
  // 0 = unlimited. An operation is started only while visits are left, so one update may
  // overshoot by one operation (a forced-split chain, or an enhMerge of a subtree). What is not
  // done stays queued and is done first by the next update; the mesh is valid at every stop.
  // With a budget, a jump that makes most of the mesh due (a teleport) restarts from the base
  // triangles and refines over several updates, visible leaves first.
  uint32_t maxVisits = 0;
  // Deferred with maxVisits only: a hard stop, e.g. a deadline on the caller's clock (lod/ keeps
  // no clock). Polled every kStopPollVisits visits; once it returns true the update stops as if
  // the visit budget had run out (the mesh is valid; what is left stays queued). A time budget
  // turned into maxVisits by a measured rate (budgetRate) holds on average; this holds it on the
  // frames whose visits cost more than the rate said (cache misses after a teleport, a busy
  // machine), to within one poll interval and one operation.
  bool (*stop)(void* context) = nullptr;
  void* stopContext = nullptr;
  // Deferred only, in [0, 0.5]: trades a few more triangles for fewer re-examinations. Split
  // and merge decisions are taken against tolerance_px * (1 - lateness), and a node is looked
  // at again after at least lateness * D metres of eye travel (D: the distance at which its
  // decision flips), so a decision may come up to that much travel late; errorPx of every
  // leaf still stays <= tolerance_px. 0 = exact (the mesh equals a fresh walk).
  double lateness = 0.0;
};

enum class RoamMode {
  EnhMerge,    // walk last frame's tree: enhMerge subtrees that became unnecessary, then split
  MergeQueue,  // classic ROAM: merge queue (one diamond at a time) + split queue
  Rebuild,     // start from the base triangles every frame, split by priority (no coherence)
  Deferred,    // EnhMerge with deferred priority recomputation: each node is re-examined only
               // when the eye has travelled far enough that its split / merge decision could
               // have changed (distance to a box is 1-Lipschitz in the eye position). Priorities
               // ignore the frustum, so turning the view costs nothing; the whole surroundings
               // are refined and emitVisible() culls what is drawn. The first Deferred update
               // (and one after the tolerance, viewport, field of view or lateness changed)
               // walks every node (under a visit budget: restarts from the base triangles) and
               // allocates the schedule; later ones touch only the due nodes, within
               // RoamView::maxVisits. The split queue persists between Deferred updates. The
               // schedule's buckets keep their capacity, but one that receives more entries than
               // ever before grows (amortised; the other modes never allocate in update()).
};

// The time per node visit a caller turns its time budget into RoamView::maxVisits with, updated
// after each update from the measured one: up at once when a frame was slower (a visit's cost
// varies with cache misses from frame to frame, and a budget must hold for the slow frames),
// down slowly (a fifth of the way) when it was faster.
inline double budgetRate(double previous_ns, double measured_ns) {
  if (!(measured_ns > 0.0) || !(measured_ns < 1e9)) return previous_ns;
  return measured_ns > previous_ns ? measured_ns : 0.8 * previous_ns + 0.2 * measured_ns;
}

inline constexpr uint32_t kStopPollVisits = 16;  // a visit can be a split (~1 us at 16385^2): 16 keep a stop within ~20 us

struct RoamStats {
  uint32_t splits = 0;       // diamond splits (a triangle and its base partner), forced included
  uint32_t merges = 0;       // single diamond merges (merge queue, or room for the triangle cap)
  uint32_t enhMerges = 0;    // enhMerge operations (each may free a whole subtree)
  uint32_t nodesFreed = 0;   // nodes returned to the pool by merges, enhMerges and rebuilds
  uint32_t nodesExamined = 0;  // nodes whose priority the update's walk or schedule looked at
  uint32_t visits = 0;       // node visits spent (Deferred's budget unit, RoamView::maxVisits; EnhMerge counts its walk)
  uint64_t pending = 0;      // Deferred: split-queue entries and due schedule entries left over
  uint64_t unscheduled = 0;  // Deferred: nodes this update changed that it ran out of time to
                             // schedule; the next update schedules them first
  bool restarted = false;    // Deferred with a visit budget: a teleport restarted from the base
  uint64_t triangles = 0;    // leaf triangles after the update
  bool finished = true;      // false: the work budget stopped it; the mesh is valid, and the
                             // next update resumes (Rebuild then continues instead of restarting)
  bool poolExhausted = false;  // a wanted split did not fit in the node pool
  bool triangleCapped = false; // a wanted split did not fit under maxTriangles
  double maxErrorPx = 0.0;   // upper bound on errorPx of the emitted leaves for this view
                             // (Deferred, unfinished: +infinity; use Roam::maxErrorPx)
};

struct RoamVertex {
  int32_t x = 0, y = 0;  // sample-grid coordinates; may lie east / north of the DEM (clamped)
};

struct RoamTriangle {
  RoamVertex v[3];  // counter-clockwise seen from above (+z)
};

// The smallest distance from `point` (relative to sample (0, 0)) to the boxes of the triangles,
// their corners at the height-field samples (clamped into the field, as heightFieldVertex places
// them): a lower bound on the distance to the triangles drawn from those samples. Stops once it
// is below `enough` (then returns a value below it). +inf without triangles.
double nearestTriangleBox(std::span<const RoamTriangle> triangles, std::span<const float> heights_m, int width, int height,
                          double spacing_m, const glm::dvec3& point, double enough);

class Roam {
 public:
  // heights_m: width * height samples, row-major (row = y, north); width, height >= 2;
  // spacing_m > 0 between samples; origin_m = ENU position of sample (0, 0) at height 0.
  // Heights must be finite. Start-up work: O(samples) time, 8 bytes per padded grid vertex.
  Roam(std::span<const float> heights_m, int width, int height, double spacing_m, const glm::dvec3& origin_m,
       const RoamConfig& config = {});
  // A second, independent mesh over the same heights, sharing `other`'s precomputed bounds
  // (no start-up work beyond the pool; the bounds live as long as any Roam using them).
  Roam(const Roam& other, const RoamConfig& config);
  Roam(const Roam&) = delete;
  Roam& operator=(const Roam&) = delete;

  // One frame of LOD work (see the selection rule above). No allocation (Deferred: see RoamMode).
  RoamStats update(const RoamView& view, RoamMode mode);

  // Bound partner of emitTriangles: the number of leaf triangles (including zero-area ones
  // outside the DEM, so it is an upper bound on what emit writes).
  size_t triangleCount() const { return static_cast<size_t>(triangles_); }
  // Writes the leaf triangles with non-zero area after clamping; returns the number written.
  // out.size() must be >= triangleCount().
  size_t emitTriangles(std::span<RoamTriangle> out) const;
  // As emitTriangles, but only leaves whose box intersects the camera's frustum (xy: the
  // leaf's own extent; z: its parent diamond's nested height range, so no height look-ups).
  // A top-down walk that skips every subtree whose nested diamond box is outside the frustum:
  // the cost follows the visible part of the mesh, not all leaves.
  size_t emitVisible(const Camera& camera, std::span<RoamTriangle> out) const;
  // ENU position of grid vertex (x, y), with the clamping rule. Double precision.
  glm::dvec3 vertexPosition(int x, int y) const;

  // Exact maximum errorPx over the current leaves for a view (O(leaves); tests, analysis).
  double maxErrorPx(const RoamView& view) const;
  // Debug check of the whole structure: every interior leaf edge shared by exactly two leaves
  // (no T-junctions, no holes: leaf areas sum to the grid), neighbour levels differ by at most
  // one, partner / neighbour links symmetric, parent / child links and geometry consistent,
  // counters right. Allocates. Returns false and writes the first problem to *why.
  bool validate(std::string* why) const;

  // Vertices created by splits during the last update() (a diamond split lists its vertex
  // once per half; at most kCreatedCapacity, the rest are not listed). For geomorphing.
  static constexpr size_t kCreatedCapacity = 1u << 16;
  std::span<const RoamVertex> createdVertices() const { return {created_.data(), createdCount_}; }
  // Vertices removed by merges and enhMerges during the last update() (one per merged
  // diamond; at most kCreatedCapacity). For morph-out (lod/geomorph.h MorphOut): such a vertex
  // pops from its true height onto the coarser surface unless the old triangles are kept
  // while it moves there.
  std::span<const RoamVertex> removedVertices() const { return {removed_.data(), removedCount_}; }
  // Height of the current mesh as drawn (leaf corners clamped onto the DEM, as emitTriangles'
  // triangles are drawn) at the point grid point (x, y) of the padded grid is drawn at (clamped
  // onto the DEM): the leaf holding it, interpolated linearly; O(levels). Where a vertex
  // removed by a merge now lies on the coarse surface.
  double meshHeight(int x, int y) const;
  // The leaf triangle of the current mesh holding point (x3 / 3, y3 / 3) of the padded grid
  // (thirds, so that triangle centroids are exact), as emitTriangles writes it; O(levels).
  RoamTriangle leafAt(int64_t x3, int64_t y3) const;

  // The hypotenuse ends of the diamond whose split creates grid vertex (x, y): the vertex
  // first appears at their midpoint height, which geomorphing starts from. False for
  // base-square corners (never created by a split) and vertices off the padded grid.
  bool splitEnds(int x, int y, RoamVertex& a, RoamVertex& b) const;

  // Leaf-change log, for renderers that keep the mesh in GPU memory and change only what ROAM
  // changed (lod/terrain_chunks.h). Off until enabled. Every update() appends, in order, each
  // node that became a leaf (a split's children, a merged diamond's halves) and, with
  // kLeafRemoved set, each that stopped being one (split or freed). A node id may appear
  // several times (pool pairs are reused); replaying the log in order and then reading each
  // node's current state gives the current leaves. `leafLogReset()` is true when the log does
  // not describe the change (the mesh restarted from the base triangles, the log filled up,
  // or it was just enabled): the consumer then reads all leaves again (emitLeafNodes).
  static constexpr uint32_t kLeafRemoved = 0x80000000u;
  void enableLeafLog(size_t capacity);
  std::span<const uint32_t> leafLog() const { return {leafLog_.data(), leafLogCount_}; }
  bool leafLogReset() const { return leafLogReset_; }
  void clearLeafLog() {
    leafLogCount_ = 0;
    leafLogReset_ = false;
  }
  // True when `node` is a live leaf with non-zero area once clamped onto the DEM (what
  // emitTriangles writes); then *out is its triangle as emitTriangles writes it.
  bool leafTriangle(uint32_t node, RoamTriangle* out) const;
  // Node ids of every leaf emitTriangles would write, in pool order; out.size() >= triangleCount().
  size_t emitLeafNodes(std::span<uint32_t> out) const;

  int maxLevel() const { return maxLevel_; }
  int gridWidth() const { return px_; }   // padded grid vertices per row
  int gridHeight() const { return py_; }
  size_t baseTriangles() const { return 2u * static_cast<size_t>(rootsX_) * static_cast<size_t>(rootsY_); }
  size_t nodeCount() const { return liveNodes_; }
  uint64_t triangleCap() const { return configMaxTriangles_; }  // RoamConfig::maxTriangles
  size_t nodeCapacity() const { return nodeCap_; }
  // Memory: the precomputed bounds (8 bytes a padded grid vertex, touched at start-up) and the
  // node pool (reserved address space; pages are committed as the mesh first grows into them).
  size_t boundsBytes() const { return bounds_->size() * sizeof(Bound); }
  size_t poolBytes() const { return nodeCap_ * sizeof(Node); }

 private:
  static constexpr uint32_t kNone = 0xFFFFFFFFu;

  struct Bound {
    float error_m;      // nested error of the diamond split at this vertex
    uint16_t zLo, zHi;  // nested height range, quantised (floor / ceil)
  };
  struct Node {
    uint32_t parent;    // kNone for base triangles
    uint32_t children;  // first of the two children (a pool pair), kNone for a leaf
    uint32_t partner;   // same-level node sharing the hypotenuse (diamond partner), or kNone
    uint32_t gen;       // bumped on allocation; makes queue entries of freed nodes stale
    int32_t ax, ay;     // apex (right angle)
    int32_t lx, ly;     // left end of the hypotenuse, seen from the apex
    int32_t rx, ry;     // right end of the hypotenuse
    Bound bound;        // copy of the diamond's bound (zero at the finest level): the
                        // per-frame walk then touches only the pool
    uint32_t sched;     // Deferred: bumped when (re)scheduled or freed; stale due entries differ
    uint8_t level;
    uint8_t free;       // 1 while in the free list
    uint8_t queued;     // 1 while the split queue holds an entry with this gen
    uint8_t pad;
  };
  struct QueueEntry {
    double priority;
    uint32_t node;
    uint32_t gen;
  };
  struct ViewState {
    glm::dvec3 eye_m{0.0};  // eye relative to origin_m
    Frustum frustum{};
    bool cullFrustum = true;  // false (Deferred): priorities by distance only
    double scale = 0.0;  // viewportHeight_px / (2 tan(fovY / 2))
    double tolerance_px = 0.0;
    double lateness = 0.0;  // Deferred (RoamView::lateness)
    bool valid = false;  // false for non-finite input: every priority is 0
  };
  enum class SplitResult { Done, Capped, PoolFull, Budget };

  // Output: a live leaf with non-zero area once its corners are clamped onto the DEM.
  struct ClampedCorners {
    int ax, ay, lx, ly, rx, ry;
  };
  bool emittableLeaf(const Node& nd, ClampedCorners& c) const;
  // Calls f(node index, node) for every leaf emittable as a triangle, in index order.
  template <class F>
  void forEachLeaf(F&& f) const;
  uint32_t leafNodeAt(int64_t x3, int64_t y3) const;
  // Set-up.
  float heightAt(int x, int y) const;
  Bound diamondBound(const Node& n) const;
  void computeBounds();
  void resetToBase();
  // Structure.
  bool isLeaf(uint32_t n) const { return nodes_[n].children == kNone; }
  uint32_t legNode(uint32_t n, int side) const;  // same-level node across leg `side` (0 left)
  uint32_t coarseNeighbour(uint32_t n) const;     // level-1 leaf across the hypotenuse
  bool mergeable(uint32_t n) const;
  uint32_t allocPair();
  void freePair(uint32_t firstChild);
  void splitNode(uint32_t n);
  void splitDiamond(uint32_t n);
  SplitResult forcedSplit(uint32_t n);
  void mergeDiamond(uint32_t n);
  void collapse(uint32_t n);  // enhMerge
  // Priorities.
  ViewState makeViewState(const RoamView& view) const;
  double priority(const Node& n, const ViewState& vs) const;
  Aabb diamondBox(const Node& n) const;  // origin-relative
  // Queues (binary heaps over reserved storage).
  bool takeOp();
  // The visit budget is spent, or stop_ (polled every kStopPollVisits visits) says so; a stop
  // ends the budget for the rest of this update.
  bool outOfVisits();
  bool stopRequested();
  bool pollStop();  // asks stop_ now; true: out of time for the rest of this update
  // Schedules the nodes this or the last update touched that are not scheduled yet, polling
  // stop_ as the visits do; false: out of time, the rest stays pending for the next update.
  bool schedulePending();
  void dropPending();
  void pushSplit(uint32_t n, double p);
  void pushMerge(uint32_t n, double p);
  void considerLeaf(uint32_t n, double p);
  void pushParentMerges(uint32_t n);
  bool topSplit(QueueEntry* e);
  void popSplit();
  void clearSplitQueue();
  bool topMerge(QueueEntry* e);
  void compactSplit();
  void compactMerge();
  // Update phases; return false when the work budget ran out.
  bool walkEnhMerge();
  bool collectQueues();
  void collectMerges();  // mergeable diamonds into mergeQ_, once an update needs them
  bool mergeUnneeded();
  bool splitPhase();
  bool capPhase();
  // Deferred mode.
  struct DueEntry {
    uint64_t due_cm;  // eye travel (centimetres) at which the node must be re-examined
    uint32_t node;
    uint32_t tag;     // Node::sched when pushed; stale otherwise
  };
  // The schedule: a ring of 1 m buckets over the next 16 km of eye travel (a calendar queue).
  // The travel only grows, so the buckets behind it are drained in order; a node whose
  // decision is safe for longer than the horizon is simply looked at again after it (an early
  // look is always safe). Work per update is the entries due plus one bucket per metre
  // travelled, in contiguous memory, with no bursts from reorganising the queue.
  class DueQueue {
   public:
    static constexpr uint64_t kBucket_cm = 100;
    static constexpr uint64_t kBuckets = 16384;
    void clear(uint64_t now_cm);
    size_t size() const { return size_; }
    void push(DueEntry e);
    // Moves the entries due at `limit_cm` into `out`, at most `max` of them (more: returns
    // max + 1 and leaves the rest queued); returns how many.
    size_t popDue(uint64_t limit_cm, std::vector<DueEntry>& out, size_t max);
    // Entries (stale ones included) due at limit_cm, as popDue would take them: the buckets
    // before the one holding limit_cm whole, and that bucket's entries due by limit_cm; stops
    // counting above max. Touches the bucket sizes and the limit's own bucket.
    size_t countDue(uint64_t limit_cm, size_t max) const;

   private:
    std::vector<std::vector<DueEntry>> ring_ = std::vector<std::vector<DueEntry>>(kBuckets);
    uint64_t cursor_ = 0;  // bucket number of the oldest bucket not yet drained
    size_t size_ = 0;
  };
  bool deferredUpdate();
  void restartFromBase();
  double splitKey(const Node& n, double p) const;  // queue order: visible leaves first
  double slack(uint32_t n) const;  // eye travel before n's decision can change; 0 = act now
  void schedule(uint32_t n);
  void scheduleOne(uint32_t n);
  void scheduleAll();
  void logLeaf(uint32_t entry) {
    if (leafLogCount_ < leafLog_.size()) leafLog_[leafLogCount_++] = entry;
    else if (!leafLog_.empty()) leafLogReset_ = true;
  }
  void touch(uint32_t n) {
    if (trackTouched_) {
      if (touched_.size() < touched_.capacity()) touched_.push_back(n);
      else touchedOverflow_ = true;
    }
  }

  const float* heights_m_;
  int width_, height_;
  double spacing_m_;
  glm::dvec3 origin_m_;
  uint64_t configMaxTriangles_;
  int rootSide_ = 1, rootsX_ = 1, rootsY_ = 1, px_ = 2, py_ = 2, maxLevel_ = 0;
  float zMin_m_ = 0.0f;
  double zStep_m_ = 1.0;
  std::shared_ptr<std::vector<Bound>> bounds_;  // per padded grid vertex; shared by copies
  void setUpPool(const RoamConfig& config);
  // The pool: pairs (2i, 2i+1); the first pairs are base squares. calloc'd: the operating
  // system hands out zero pages as they are first touched, so a large pool costs nothing
  // until the mesh grows into it.
  struct FreeDeleter {
    void operator()(Node* p) const;
  };
  std::unique_ptr<Node[], FreeDeleter> nodes_;
  size_t nodeCap_ = 0;
  std::vector<uint32_t> freePairs_;
  std::vector<uint32_t> rootLeg_;  // per base triangle and leg side: same-level node or kNone
  uint32_t highPairs_ = 0;         // pairs ever handed out (bump allocator above the free list)
  size_t liveNodes_ = 0;
  uint64_t triangles_ = 0;
  std::vector<QueueEntry> splitQ_, mergeQ_;
  std::vector<uint32_t> leafLog_;  // enableLeafLog: node ids, kLeafRemoved for removals
  size_t leafLogCount_ = 0;
  bool leafLogReset_ = false;
  std::vector<RoamVertex> created_ = std::vector<RoamVertex>(kCreatedCapacity);
  size_t createdCount_ = 0;
  std::vector<RoamVertex> removed_ = std::vector<RoamVertex>(kCreatedCapacity);
  size_t removedCount_ = 0;
  bool splitHeap_ = true, mergeHeap_ = true;  // false while filled unordered (heapified lazily)
  bool mergesCollected_ = false;              // mergeQ_ holds every mergeable diamond
  std::vector<uint32_t> chain_;  // forced-split chain (at most maxLevel + 1 nodes)
  // Per-update state.
  ViewState vs_;
  RoamStats stats_;
  uint64_t opsLeft_ = 0;
  uint64_t capTriangles_ = 0;  // triangle cap of this update
  double maxSmallPx_ = 0.0;  // largest errorPx among leaves not queued for splitting
  bool resumeRebuild_ = false;
  uint64_t visitBudget_ = 0;   // Deferred visit budget of this update (max: none)
  uint64_t visitsUsed_ = 0;
  bool (*stop_)(void*) = nullptr;  // RoamView::stop of this update (with a visit budget only)
  void* stopContext_ = nullptr;
  uint64_t nextPoll_ = 0;          // visitsUsed_ at which stop_ is polled next
  bool stopFired_ = false;         // stop_ said stop during this update
  bool deferredQueue_ = false; // the split queue persists across Deferred updates
  // Deferred schedule (allocated by the first Deferred update).
  DueQueue dueQ_;
  size_t dueCapacity_ = 0;          // entries before the schedule is rebuilt (stale ones pile up)
  std::vector<uint32_t> touched_;   // nodes whose state changed during this update
  std::vector<uint32_t> recheck_;   // due nodes to look at again next update
  // touched_[pendingTouched_...] and recheck_[pendingRecheck_...]: not scheduled yet (an update
  // that ran out of time leaves them to the next).
  size_t pendingTouched_ = 0, pendingRecheck_ = 0;
  std::vector<DueEntry> due_;       // entries due this update
  bool trackTouched_ = false, touchedOverflow_ = false;
  bool scheduleValid_ = false;
  double travel_m_ = 0.0;           // eye travel summed over Deferred updates
  glm::dvec3 lastEye_m_{0.0};
  double lastScale_ = 0.0, lastTolerance_px_ = 0.0, lastLateness_ = 0.0;
};

}  // namespace ig::lod
