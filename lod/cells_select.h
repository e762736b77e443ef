// Selection of a realization of hierarchical cells under a voxel budget and a byte budget
// (paper 003, sections 2.1 - 3; shared/seeds/003).
//
// A realization is a cut of the cell tree: every root-to-leaf path crosses exactly one of its
// cells, so its cells never overlap and together cover the scene, each at its own level of
// detail. Per cell and view:
//   live(c)  = the cell intersects the view frustum and V(c) > 0 (otherwise it costs nothing
//              and is never refined: "invisible cells at minimum quality");
//   e(c)     = the on-screen size of one of its voxels, in pixels (the paper's 1 / G):
//              voxelEdge_m(level) * viewportHeight_px / (2 tan(fovY / 2)) / max(distance(eye, box), near_m)
//              (0 when not live). A child's e is at most half its parent's.
//   cost(c)  = V(c) when live, else 0.
// Pre-selection: a cell with e(c) <= minVoxel_px (alpha: its voxels are already no larger than
// a pixel) is never refined, so cells finer than the client can show are never selected.
//
// Goal (the paper's Q = min over cells of the quality, V constraint and, for progressive loading,
// S constraint): among realizations whose live cells are resident, minimise
//     max e(c) over drawn cells  (make the largest on-screen voxel as small as possible)
// subject to  sum cost(c) <= voxelBudget  and  sum S(c) over cells requested this frame <= W.
//
// Method: a priority-driven greedy with split and merge queues. Priority: larger e first, ties
// by smaller cell index. From the root cut it refines the refinable cut cell of highest priority
// while the budget allows and stops at the first that does not fit. Each later frame starts from
// the last frame's cut and reaches the same result (tested: the same drawn cells as a selection
// from the root, every frame of random camera paths): it coarsens while over budget (lowest
// priority first), then takes the refinable cut cell of highest priority and splits it if it
// fits, merging mergeable cells (refined cells whose children are all in the cut) of lower
// priority to make room; before giving a cell up it merges every mergeable cell of lower
// priority. Cells that become invisible or sub-pixel are merged away.
//
// Cost per frame. The cut and the mergeable cells are kept as packed arrays (struct of arrays,
// float); each frame one vectorised pass over each re-evaluates e and the frustum (4 cells per
// SSE2 step, 8 per AVX2 step where the CPU has it, lane for lane the same operations and no FMA;
// every evaluation, evaluateCell() included, runs through that one routine, so all give the same
// bits). Then work is proportional to what changes: the queues hold only the
// candidates near where the greedy stopped last frame (e within a few percent), rebuilt from the
// packed arrays in a further band when the greedy runs past them; splits and merges update the
// arrays in place. The cheapest covers (below) are the one walk of the tree: a cut cell cut by
// the frustum boundary keeps a certificate (up to 7 children / grandchildren that are wholly
// inside, or live leaves, whose voxels already make mc = V); while those boxes keep their
// status (one vectorised test), its cover is not recomputed. A mergeable cell's children are all
// cut cells, so its cover needs no walk: each cut cell keeps its parent's slot in the mergeable
// arrays, and one pass over the cut sums the children's mc per mergeable cell.
//
// Exactness. Refining a cell never lowers the largest e but may lower the cost: a live cell cut
// by the frustum boundary costs all its voxels, its children outside the frustum cost nothing.
// So the greedy charges each cut cell its cheapest drawable cover
//     mc(c) = min(V(c), sum mc(children))   (children only when c may be refined and its live
//                                             children are resident; mc(c) = V(c) for a cell
//                                             wholly inside the frustum, by monotonicity)
// and draws a cut cell as that cover. With all cells resident the result is then optimal: the
// largest drawn e equals the brute-force minimum over all realizations of the pre-selected tree
// (tested on random trees up to 4 levels), because for any threshold t the cheapest realization
// with max e <= t is "refine every live cell with e > t, cover the rest cheapest", whose cost
// only grows as t falls. The result is the realization "refine every refinable cell of higher
// priority than the first that does not fit", whatever the last frame's cut.
//
// Residency (progressive loading). The caller passes each cell's residency. A live cell is drawn
// only when resident; a split whose live children are not all resident is blocked: the missing
// children are requested (in the order the greedy meets their parents, largest parent e first;
// while sum S <= W; a cell in flight is not requested again and costs no bytes), the voxels the split needs are reserved so that cells arriving in
// a later frame fit without starving, and the cell stays drawn until its children arrive. Once
// W is spent, the refinement stops at the next blocked split (the next frames fetch its cells). A
// drawn cell that stops being resident is replaced by its nearest resident ancestor. A cover
// through missing cells is unknown and costed as V; when the budget stops the greedy, the
// missing children of such cells are requested too, so streaming converges to the all-resident
// optimum. While the view stays still the largest drawn e never grows. Cells larger
// than W can never be requested (counted in `unfetchable`). Ancestors of drawn cells should stay
// resident (a merge into a missing ancestor is skipped).
//
// Two threads. With CellSelectorConfig::runner (ig/worker_pair.h) the per-frame passes over the
// packed arrays (re-evaluation and the eviction scan; costs, split candidates and cheapest covers;
// the draw list) are split into chunks of the cut that the caller's thread takes from the front
// and a helper from the back; the refinement itself stays on the caller. A chunk touches only its
// own cut cells and the cells below them (a cover walks only below its cut cell), worker 1 sums
// the mergeable cells' children into its own array, and every list a pass makes (evictions, split
// candidates, unknown covers, the draw list) is put back in chunk order, so the choices, the draw
// list and the requests are the same, bit for bit, as on one thread (tested with a runner that
// interleaves the two workers' chunks in every way the contract allows, and on real threads).
//
// Memory: everything is sized at construction from the tree: about 110 bytes per cell (a packed
// copy of the tree's fields the selection reads, 40; the packed cut and mergeable arrays, 45;
// the mergeable cells' child sums, 8 per inner cell; stamps and lists) plus queue capacity of 32
// bytes per cell that is touched only as used.
// select() does not allocate.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "lod/cells.h"
#include "lod/view.h"

namespace ig::lod {

struct CellView {
  Camera camera;                    // eye in the tree's frame (ENU, double), attitude, fovY, aspect, near/far
  double viewportHeight_px = 1080;  // > 0
  double minVoxel_px = 1.0;         // alpha of the pre-selection, >= 0
  uint64_t voxelBudget = 1000000;   // sum V over drawn cells never exceeds it
  uint64_t byteBudget = 1 << 20;    // W: sum S over cells requested this frame never exceeds it
  // A hard stop for the refinement, e.g. a deadline on the caller's clock (lod/ reads no clock):
  // polled after every kCellStopPoll candidates the refinement examined (splits, blocked splits)
  // and every kCellStopPoll merges of cells that left the view or became sub-pixel (before the
  // refinement; stopped there, the rest wait for the next frames and nothing is refined); once it
  // returns true the refinement ends there, as at maxOperations: the cut stays a valid
  // realization within both budgets, the draw list and the requests so far are complete, and the
  // next frames go on from it (CellSelectStats::stopped). The passes over the cut and the
  // coarsening to the voxel budget are not stopped. nullptr: never.
  bool (*stop)(void* context) = nullptr;
  void* stopContext = nullptr;
};

// Candidates between two polls of CellView::stop: one costs ~0.1 ... 0.5 us (a blocked split
// waits on the tree's memory), so 32 keep a stop within ~15 us of its deadline.
inline constexpr uint32_t kCellStopPoll = 32;

enum class Residency : uint8_t {
  Absent = 0,    // not in memory and not requested
  InFlight = 1,  // requested, not yet arrived (not requested again, counts no bytes this frame)
  Resident = 2,  // in memory, drawable
};

struct CellDraw {
  uint32_t cell = kNoCell;
  float voxel_px = 0.0f;  // e(cell) this frame
};

// Runs a pass of the selection split into chunks on two threads (ig/worker_pair.h has the
// implementation; lod/ itself starts no thread). The contract: forEach(n, fn, ctx) calls
// fn(ctx, chunk, worker) exactly once for every chunk in [0, n) and returns when every call has
// returned; worker 0 is the calling thread and takes chunks from the front in increasing order,
// worker 1 takes them from the back in decreasing order (it may take none); calls with the same
// worker never overlap. The selection puts each pass's outputs back in chunk order, so its
// choices, draw list and requests are the same, bit for bit, as on one thread.
class ChunkRunner {
 public:
  using ChunkFn = void (*)(void* ctx, uint32_t chunk, uint32_t worker);
  virtual ~ChunkRunner() = default;
  virtual void forEach(uint32_t chunks, ChunkFn fn, void* ctx) = 0;
};

struct CellSelectorConfig {
  // Splits + merges per frame after which the refinement examines no further split (the cut stays
  // valid when it stops). The merges that keep the budget (coarsening when over it, room for the
  // split under way) are never held back, so a frame's splits stay <= it, its merges need not.
  uint32_t maxOperations = 1u << 30;
  // The per-frame passes over the cut (re-evaluation and eviction scan; costs and cheapest
  // covers; the draw list) run on this runner when set (it must outlive the selector), in
  // chunks of `chunkCells` cut cells (rounded up to a multiple of 8). Null: all on the caller.
  ChunkRunner* runner = nullptr;
  uint32_t chunkCells = 1024;
};

struct CellSelectStats {
  bool valid = false;            // false: the view was rejected (NaN, bad fov/near/far/viewport); nothing changed or drawn
  bool feasible = true;          // false: no drawable realization fits the voxel budget; nothing drawn
  bool drawTruncated = false;    // the draw span was too small (use drawBound())
  bool capped = false;           // maxOperations (or heap capacity, or CellView::stop) stopped the refinement
  bool stopped = false;          // CellView::stop did (capped is set too)
  uint32_t drawnCells = 0;       // entries written to the draw span
  uint32_t cutCells = 0;         // cells of the realization, live or not
  uint64_t drawnVoxels = 0;      // sum V of drawn cells, <= voxelBudget
  uint64_t reservedVoxels = 0;   // budget held for blocked splits (cells requested or in flight)
  float maxVoxel_px = 0.0f;      // the realization's quality: the largest e among drawn cells
  uint32_t requestedCells = 0;   // entries written to the request span
  uint64_t requestedBytes = 0;   // sum S of requested cells, <= byteBudget
  uint32_t blockedSplits = 0;    // splits waiting for cells not resident
  uint32_t unfetchable = 0;      // wanted cells with S > byteBudget (can never be requested)
  uint32_t splits = 0, merges = 0;
};

// e(c) and live(c) for one cell and view, computed as select() does (full frustum test). For
// tests and tools; select() evaluates cells incrementally.
struct CellEval {
  bool live = false;
  float voxel_px = 0.0f;
};
CellEval evaluateCell(const CellTree& tree, uint32_t cell, const CellView& view);
// Whether select() accepts the view (finite eye, 0 < fovY < 180, aspect > 0, 0 < near < far,
// window shift within lod::kMaxWindowShift (not NaN), viewport > 0, minVoxel_px >= 0).
bool validCellView(const CellView& view);

class CellSelector {
 public:
  // The tree must outlive the selector. Starts from the root cut.
  explicit CellSelector(const CellTree& tree, const CellSelectorConfig& config = {});

  // One frame. `residency`: one entry per cell, or empty (every cell resident). Writes the drawn
  // cells (live, resident; in the order of the packed cut, not sorted) to `draw` and the cells to
  // fetch to `requests`, in the order the greedy met them (the blocked splits' children by their
  // parent's e, largest first, then the unknown covers' children); not sorted by their own e. No
  // allocation.
  CellSelectStats select(const CellView& view, std::span<const Residency> residency, std::span<CellDraw> draw,
                         std::span<uint32_t> requests);

  size_t drawBound() const { return tree_.size(); }
  // Every cell of the last realization (live or not, covers expanded), depth-first. Returns the
  // count (never more than out.size() written). For tests and tools.
  size_t realization(std::span<uint32_t> out) const;
  // The cheapest cover of cell c (the fewest voxels that draw its live part: V if it is drawn
  // itself) as the last select() counted it: cut and mergeable cells, and the cells it costed;
  // -1 for the others. For tests.
  int64_t countedCost(uint32_t c) const;
  // Back to the root cut (e.g. after a scene change).
  void reset();

 private:
  // Cell states. kMergeable: refined and every child in the cut (the merge candidates).
  enum : uint8_t { kBelow = 0, kCut = 1, kRefined = 2, kMergeable = 3 };
  struct HeapEntry {
    float e;
    uint32_t cell;
    uint32_t first = 0;  // split candidates: the cell's first child (prefetched before its turn)
  };
  // Frame constants in float, shared with evaluateCell() so that both give the same bits.
  struct ViewConsts {
    std::array<float, 6> nx{}, ny{}, nz{}, w{}, pos{}, neg{};  // planes; pos / neg: sums of positive / negative normal components
    float rx = 0, ry = 0, rz = 0;                            // root corner - eye
    float k = 0;                                             // e = edge * k / max(distance, near)
    float near = 0;
    // The same, each in 4 lanes (loaded, not broadcast, per quad): planes (6 each of nx, ny, nz,
    // w, pos, neg), then rx, ry, rz, k, near.
    alignas(16) std::array<std::array<float, 4>, 41> lanes{};
  };
  // A set of cells with their evaluation (struct of arrays, padded to 4 lanes): the cut, or the
  // mergeable cells. Each frame one pass over it re-evaluates every member.
  struct CellSet {
    std::vector<uint32_t> cell, voxels, mc;
    std::vector<float> x, y, z, edge, e;  // x, y, z: the box's lowest corner relative to the root corner
    std::vector<uint8_t> flags;           // kLive | kInside | kHasChildren
    std::vector<uint64_t> cert;           // a certificate that mc = V (see makeCertificate), or 0
    std::vector<uint32_t> up;             // the cut: the parent's slot in the mergeable cells, or kNoCell
    std::vector<uint32_t> first;          // the first child (the split heap's entries carry it)
    uint32_t n = 0;
    void allocate(size_t capacity);
  };
  struct Ev {
    float e;
    uint8_t flags;
  };

  static void makeConsts(const CellTree& tree, const CellView& view, ViewConsts& out);
  static void evalCells(const ViewConsts& vc, uint32_t n, const float* x, const float* y, const float* z,
                        const float* edge, const uint32_t* voxels, float* e, uint8_t* flags);
  static Ev evalOne(const CellTree& tree, const ViewConsts& vc, float edge, uint32_t c);
  friend CellEval evaluateCell(const CellTree& tree, uint32_t cell, const CellView& view);
  void evaluateSet(CellSet& set);
  void evaluateChildren(uint32_t c);
  void prefetchChildren(uint32_t c) const;
  Ev ev(uint32_t c);             // e and flags of any cell this frame (evaluated on demand)
  Ev evConst(uint32_t c) const;  // of a cell already evaluated this frame
  bool costed(uint32_t c) const { return node_[c].stamp == frame_ && (node_[c].flags & 8); }
  // mc(c) this frame; cells whose cheapest cover is unknown (children not resident) go to `unknown`.
  uint64_t cost(uint32_t c, std::vector<uint32_t>& unknown);
  uint64_t cost(uint32_t c) { return cost(c, unknownCover_); }
  uint64_t costConst(uint32_t c) const;
  // mc(c) from its children (c live, not wholly inside, refinable)
  uint64_t coverCost(uint32_t c, Ev evc, std::vector<uint32_t>& unknown);
  uint64_t coverCost(uint32_t c, Ev evc) { return coverCost(c, evc, unknownCover_); }
  uint64_t makeCertificate(uint32_t c);
  bool certificateHolds(const CellSet& set, uint32_t i) const;
  bool refinable(uint32_t c, Ev x) const;
  bool resident(uint32_t c) const { return residency_.empty() || residency_[c] == Residency::Resident; }
  bool drawable(uint32_t c, Ev x) const;
  bool childrenDrawable(uint32_t c);
  uint32_t insert(CellSet& set, uint32_t c, Ev x, uint64_t mc);
  void remove(CellSet& set, uint32_t c);  // writes its evaluation back to the per-cell arrays
  void setUp(uint32_t p, uint32_t slot);  // cut_.up of p's children that are in the cut
  void maybeMergeable(uint32_t p);        // p refined with every child cut: into the merge set
  void collapse(uint32_t a);              // a's subtree -> a in the cut (eviction repair)
  void split(uint32_t c);
  void merge(uint32_t p);  // and its parents that become mergeable but are not refinable (invisible, sub-pixel)
  bool request(uint32_t c);       // within W and the request span; false if it could not be sent
  void requestUnknownCovers();    // children of cells whose cheapest cover is unknown (not resident)
  void pushSplit(uint32_t c, float e);
  void pushMerge(uint32_t p, float e);
  bool splitTop(HeapEntry& top);  // the highest-priority refinable cut cell (rescans the cut below the window)
  bool mergeFront(float limit, HeapEntry& front);  // the lowest-priority mergeable cell if its e <= limit
  template <typename Emit>
  void emitCover(uint32_t c, bool liveOnly, Emit&& emit) const;

  // The per-frame passes over the packed arrays, chunk by chunk, on worker 0 (the caller) or 1.
  // Worker 0 writes to the selector's own outputs (its chunks are a prefix, in order); worker 1
  // to its Part, with a mark per chunk, put back in chunk order after the pass.
  enum class Pass : uint8_t { Eval, Cost, Draw };
  struct Part {
    struct Mark {
      uint32_t chunk, evicted, splits, unknown, draw;
    };
    std::vector<Mark> marks;
    std::vector<uint32_t> evicted, unknown, covers;
    std::vector<HeapEntry> splits;
    std::vector<uint64_t> childSum;  // worker 1's; worker 0 adds to childSum_
    uint64_t cost = 0;
    CellDraw* out = nullptr;
    uint32_t cap = 0, written = 0, cutCells = 0;
    uint64_t drawnVoxels = 0;
    float maxE = 0.0f;
    bool truncated = false;
    void begin() {
      marks.clear();
      evicted.clear();
      unknown.clear();
      splits.clear();
      cost = 0;
      written = cutCells = 0;
      drawnVoxels = 0;
      maxE = 0.0f;
      truncated = false;
    }
  };
  void runPass(Pass pass);
  static void passChunk(void* self, uint32_t chunk, uint32_t worker);
  void evalChunk(uint32_t chunk, Part& part, bool mine);
  void costChunk(uint32_t begin, uint32_t end, Part& part, bool mine);
  void drawChunk(uint32_t begin, uint32_t end, Part& part);
  uint32_t chunkCells_ = 0;   // 0: one chunk per pass (no runner)
  uint32_t cutChunks_ = 0;    // this pass: chunks of the cut (Eval: then those of the mergeable cells)
  Pass pass_ = Pass::Eval;
  Part parts_[2];
  std::vector<CellDraw> drawBuf_;  // worker 1's draw list (capacity: the cut's)
  bool rootMissing_ = false;

  const CellTree& tree_;
  CellSelectorConfig config_;
  // Per cell, packed so that a cell's children (contiguous) share a few cache lines: the tree's
  // data the selection reads (copied at construction) and this frame's evaluation of cells that
  // are in neither set.
  struct Node {
    float x = 0, y = 0, z = 0;  // lowest corner relative to the root corner (as the sets hold it)
    uint32_t voxels = 0, firstChild = 0, slot = 0;
    float e = 0;             // valid when stamp == frame_
    uint32_t mc = 0;         // valid when stamp == frame_ and flags & kCosted
    uint32_t stamp = 0;
    uint8_t childCount = 0, level = 0, state = 0, flags = 0;
  };
  std::vector<Node> node_;
  std::vector<uint32_t> reqStamp_, popStamp_;
  std::vector<float> edgeF_;
  CellSet cut_, mergeable_;
  std::vector<uint32_t> scratch_, evicted_, unknownCover_;
  std::vector<uint64_t> childSum_;  // per mergeable slot: the sum of its children's mc this frame
  std::vector<HeapEntry> splitHeap_, mergeHeap_;
  uint32_t frame_ = 0;
  std::span<const Residency> residency_;
  ViewConsts vc_;
  float alpha_ = 1.0f;
  float splitFloor_ = 0.0f, mergeCeil_ = 0.0f;  // heap windows: every candidate with e >= floor / <= ceil is queued
  float lastT_ = 0.0f;                          // e of the last split candidate examined (next frame's window)
  uint64_t cost_ = 0;
  bool costsFresh_ = false;  // the sets' mc are this frame's (remove() may keep them)
  uint32_t forcedMerges_ = 0;
  std::span<uint32_t> reqOut_;
  uint32_t reqCount_ = 0, unfetchable_ = 0;
  uint64_t reqBytes_ = 0, W_ = 0, minBytes_ = 0;
};

}  // namespace ig::lod
