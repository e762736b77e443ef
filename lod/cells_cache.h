// Memory budget for streamed hierarchical cells (paper 003, section 3: progressive loading keeps
// a working set of cells in client memory; shared/seeds/003): a least-recently-used cache of
// resident cells with a byte budget.
//
// The caller (the cells layer) inserts a cell when its bytes arrive, touches every cell it draws
// each frame, and calls evict() once per frame; it frees the evicted cells' GPU memory and sets
// their residency to Absent (lod/cells_select.h).
//
// Rules:
//  - Pinned (never evicted in frame f): cells touched in frame f and all their ancestors (the
//    selector merges into ancestors, which must stay resident).
//  - A cell with a resident child is not evicted before that child: insert() and touch() move the
//    cell and then each resident ancestor to the most-recently-used end, so in LRU order every
//    resident cell comes before its resident parent and one pass from the LRU end evicts
//    children before parents. The resident set stays closed under ancestors when cells arrive
//    parent first (as the selector requests them).
//  - evict() removes unpinned cells, least recently used first, until usedBytes() <= budget.
//    It stays over budget only when every remaining cell is pinned (reported in EvictStats).
//
// Memory: 33 bytes per cell, all allocated at construction; no member function allocates.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "lod/cells.h"

namespace ig::lod {

struct CellEvictStats {
  uint32_t evicted = 0;       // ids written to the output span
  bool overBudget = false;    // still over budget after evicting (every remaining cell pinned, or the span was full)
  bool spanFull = false;      // stopped because the output span was full: call again
  uint64_t usedBytes = 0;     // after evicting
};

class CellCache {
 public:
  // parent: one entry per cell, the parent's index or kNoCell (roots); indices < parent.size().
  CellCache(std::span<const uint32_t> parent, uint64_t budgetBytes);
  CellCache(const CellTree& tree, uint64_t budgetBytes);

  uint32_t cellCount() const { return static_cast<uint32_t>(parent_.size()); }
  uint64_t budgetBytes() const { return budget_; }
  void setBudgetBytes(uint64_t budget) { budget_ = budget; }
  uint64_t usedBytes() const { return used_; }
  uint32_t residentCells() const { return count_; }
  bool contains(uint32_t cell) const { return cell < cellCount() && resident_[cell] != 0; }
  uint32_t bytes(uint32_t cell) const { return bytes_[cell]; }

  // The cell's bytes arrived: it becomes resident (or its size is updated) and most recently used.
  // Does not evict (the caller calls evict() once per frame). cell < cellCount().
  void insert(uint32_t cell, uint32_t bytes, uint64_t frame);
  // The cell is drawn in `frame`: most recently used, and pinned with its ancestors for that frame.
  // Touching a cell that is not resident pins its resident ancestors only.
  void touch(uint32_t cell, uint64_t frame);
  // The caller dropped the cell (e.g. a failed upload). No effect if not resident.
  void remove(uint32_t cell);
  // Evicts until under budget (see the rules above); writes the evicted ids to `out`, least
  // recently used first.
  CellEvictStats evict(uint64_t frame, std::span<uint32_t> out);
  // Resident cells from least to most recently used (for tests and tools). Returns the count
  // written (at most out.size()).
  size_t lruOrder(std::span<uint32_t> out) const;
  bool pinned(uint32_t cell, uint64_t frame) const { return pinFrame_[cell] == frame; }

 private:
  static constexpr uint64_t kNever = ~uint64_t{0};
  void unlink(uint32_t c);
  void pushMru(uint32_t c);
  void refreshAncestors(uint32_t c, uint64_t pinFrame);

  std::vector<uint32_t> parent_;
  std::vector<uint32_t> prev_, next_;  // LRU list: head_ = least recently used
  std::vector<uint32_t> bytes_;
  std::vector<uint64_t> pinFrame_;
  std::vector<uint8_t> resident_;
  std::vector<uint32_t> residentChildren_;
  uint32_t head_ = kNoCell, tail_ = kNoCell;
  uint32_t count_ = 0;
  uint64_t used_ = 0;
  uint64_t budget_ = 0;
};

}  // namespace ig::lod
