// Stable slots for a triangle list that changes a little every frame (ROAM, block LOD), so a
// renderer uploads only what changed: each triangle keeps its slot in the vertex buffer while
// it stays in the mesh; a triangle that appears takes a free slot; a slot whose triangle left
// is freed (the renderer makes it degenerate). Frame-to-frame work and uploads are
// proportional to the change, not to the mesh.
//
// New triangles take the lowest free slot, the high-water mark (the range a renderer draws)
// falls when the top slots are free, and compact() moves the triangles of the top slots into
// the holes below, a bounded number per frame: after a heavy view the drawn range follows the
// mesh back down instead of staying at its largest (freed slots still cost vertex work).
//
// Pure bookkeeping: an open-addressing hash table and a heap of free slots allocated at
// construction; update() and compact() do not allocate.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "lod/roam.h"

namespace ig::lod {

class TriangleSlots {
 public:
  static constexpr uint32_t kNone = 0xFFFFFFFFu;
  // Moves per frame the service and igbench give compact(): 4,096 triangles (~400 KB of
  // vertices) at most, so a frame after a heavy view pays a bounded upload.
  static constexpr size_t kCompactMovesPerFrame = 4096;

  explicit TriangleSlots(size_t capacity);

  struct Changes {
    size_t added = 0;   // triangles written to addedTriangles / addedSlots
    size_t freed = 0;   // slots written to freedSlots
    bool overflow = false;  // more triangles than capacity: the extra ones were not placed
  };
  // Matches this frame's triangles against the last frame's. Writes the triangles that need a
  // slot (index into `triangles`) and the slot each got, and the slots that became free.
  // Apply freed slots first (make them degenerate), then the added ones: a freed slot may be
  // reused in the same frame. Each span must have room for `capacity()` entries.
  Changes update(std::span<const RoamTriangle> triangles, std::span<uint32_t> addedTriangles,
                 std::span<uint32_t> addedSlots, std::span<uint32_t> freedSlots);

  // Moves up to `maxMoves` triangles from the highest slots into the lowest free ones, while
  // there are free slots below the high-water mark. Writes each move's old slot to `from` and
  // new slot to `to` (each span must hold maxMoves entries): the renderer copies the triangle
  // and makes the old slot degenerate (it now lies at or above highWater(), so it is not drawn
  // anyway). A move is not a change of the mesh (no morph, no triangle left). Returns the moves.
  // Call after update() and after applying its changes.
  size_t compact(size_t maxMoves, std::span<uint32_t> from, std::span<uint32_t> to);
  // Free slots below the high-water mark (what compact() can remove).
  size_t holes() const { return highWater_ - live_; }

  // The slot holding triangle t (any vertex order), or kNone. O(1).
  uint32_t slotOf(const RoamTriangle& t) const;

  size_t capacity() const { return capacity_; }
  // One past the highest slot in use: the range a renderer draws.
  uint32_t highWater() const { return highWater_; }
  size_t live() const { return live_; }

 private:
  static uint64_t key(const RoamTriangle& t);
  size_t find(uint64_t k) const;  // table index holding k, or of the empty entry for it
  void erase(size_t index);
  uint32_t takeLowestFree();  // kNone when no free slot lies below the high-water mark
  void shrink();              // lower the high-water mark past free top slots

  struct Entry {
    uint64_t key;
    uint32_t slot;
    uint32_t frame;  // last frame this triangle was seen
  };
  size_t capacity_;
  std::vector<Entry> table_;  // power-of-two size >= 2 * capacity; key 0 = empty
  std::vector<uint32_t> freeSlots_;  // min-heap; entries >= highWater_ are stale (dropped when met)
  std::vector<uint32_t> slotEntry_;  // slot -> table index, kNone when free
  uint32_t highWater_ = 0;
  uint32_t frame_ = 0;
  size_t live_ = 0;
};

}  // namespace ig::lod
