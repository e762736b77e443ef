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
// Method: a priority-driven greedy with split and merge queues, incremental from the last
// frame's cut. Each frame walks the cut from the root (evaluating e, frustum and residency),
// coarsens while over budget (smallest e first), then refines the cell with the largest e while
// the budget allows, merging cells of smaller e to make room; it stops at the first cell of
// largest e that does not fit. Cells that become invisible or sub-pixel are merged away.
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
// only grows as t falls.
//
// Residency (progressive loading). The caller passes each cell's residency. A live cell is drawn
// only when resident; a split whose live children are not all resident is blocked: the missing
// children are requested (largest e first, while sum S <= W; a cell in flight is not requested
// again and costs no bytes), the voxels the split needs are reserved so that cells arriving in
// a later frame fit without starving, and the cell stays drawn until its children arrive. A
// drawn cell that stops being resident is replaced by its nearest resident ancestor. A cover
// through missing cells is unknown and costed as V; when the budget stops the greedy, the
// missing children of such cells are requested too, so streaming converges to the all-resident
// optimum. While the view stays still the largest drawn e never grows. Cells larger
// than W can never be requested (counted in `unfetchable`). Ancestors of drawn cells should stay
// resident (a merge into a missing ancestor is skipped).
//
// Memory: everything is sized at construction from the tree (about 40 bytes per cell); select()
// does not allocate.
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
};

enum class Residency : uint8_t {
  Absent = 0,    // not in memory and not requested
  InFlight = 1,  // requested, not yet arrived (not requested again, counts no bytes this frame)
  Resident = 2,  // in memory, drawable
};

struct CellDraw {
  uint32_t cell = kNoCell;
  float voxel_px = 0.0f;  // e(cell) this frame
};

struct CellSelectorConfig {
  uint32_t maxOperations = 1u << 30;  // splits + merges per frame; the cut stays valid when it stops
};

struct CellSelectStats {
  bool valid = false;            // false: the view was rejected (NaN, bad fov/near/far/viewport); nothing changed or drawn
  bool feasible = true;          // false: no drawable realization fits the voxel budget; nothing drawn
  bool drawTruncated = false;    // the draw span was too small (use drawBound())
  bool capped = false;           // maxOperations (or heap capacity) stopped the refinement
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
// viewport > 0, minVoxel_px >= 0).
bool validCellView(const CellView& view);

class CellSelector {
 public:
  // The tree must outlive the selector. Starts from the root cut.
  explicit CellSelector(const CellTree& tree, const CellSelectorConfig& config = {});

  // One frame. `residency`: one entry per cell, or empty (every cell resident). Writes the drawn
  // cells (live, resident, in depth-first order) to `draw` and the cells to fetch, largest e
  // first, to `requests`. No allocation.
  CellSelectStats select(const CellView& view, std::span<const Residency> residency, std::span<CellDraw> draw,
                         std::span<uint32_t> requests);

  size_t drawBound() const { return tree_.size(); }
  // Every cell of the last realization (live or not, covers expanded), depth-first. Returns the
  // count (never more than out.size() written). For tests and tools.
  size_t realization(std::span<uint32_t> out) const;
  // Back to the root cut (e.g. after a scene change).
  void reset();

 private:
  enum : uint8_t { kBelow = 0, kCut = 1, kRefined = 2 };
  struct HeapEntry {
    float e;
    uint32_t cell;
  };

  bool live(uint32_t c) const { return (flags_[c] & 0x80) != 0; }
  bool resident(uint32_t c) const { return residency_.empty() || residency_[c] == Residency::Resident; }
  bool drawable(uint32_t c) const { return !live(c) || resident(c); }
  bool refinable(uint32_t c) const { return live(c) && tree_.childCount(c) > 0 && e_[c] > alpha_; }
  void evaluate(uint32_t c, uint8_t parentMask);
  void evaluateChildren(uint32_t c);
  uint64_t cost(uint32_t c);  // mc(c), memoised per frame; c evaluated
  bool childrenDrawable(uint32_t c) const;
  void collapse(uint32_t c);  // c and its subtree -> c in the cut
  bool walkCut();
  bool request(uint32_t c);       // within W and the request span; false if it could not be sent
  void requestUnknownCovers();    // children of cells whose cheapest cover is unknown (not resident)
  bool pushSplit(uint32_t c);
  bool pushMerge(uint32_t p);
  bool mergeCandidate(uint32_t p) const;
  uint64_t mergeSaving(uint32_t p);
  void merge(uint32_t p);
  template <typename Emit>
  void emitCover(uint32_t c, bool liveOnly, Emit&& emit) const;

  const CellTree& tree_;
  CellSelectorConfig config_;
  std::vector<uint8_t> state_, flags_;
  std::vector<uint32_t> evalStamp_, costStamp_;
  std::vector<float> e_;
  std::vector<uint64_t> mc_;
  std::vector<uint32_t> cutList_, unknownCover_, reqStamp_;
  std::vector<HeapEntry> splitHeap_, mergeHeap_;
  std::array<uint32_t, 8 * kMaxCellLevels + 8> stack_{};
  uint32_t frame_ = 0;
  std::span<const Residency> residency_;
  // This frame's view.
  std::array<glm::dvec4, 6> planes_{};
  glm::dvec3 rootRel_{0.0};
  double pxPerM_ = 0.0, near_m_ = 0.0;
  float alpha_ = 1.0f;
  uint64_t cost_ = 0;
  uint32_t forcedMerges_ = 0;
  std::span<uint32_t> reqOut_;
  uint32_t reqCount_ = 0, unfetchable_ = 0;
  uint64_t reqBytes_ = 0, W_ = 0;
};

}  // namespace ig::lod
