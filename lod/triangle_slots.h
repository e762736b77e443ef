// Stable slots for a triangle list that changes a little every frame (ROAM, block LOD), so a
// renderer uploads only what changed: each triangle keeps its slot in the vertex buffer while
// it stays in the mesh; a triangle that appears takes a free slot; a slot whose triangle left
// is freed (the renderer makes it degenerate). Frame-to-frame work and uploads are
// proportional to the change, not to the mesh.
//
// Pure bookkeeping: an open-addressing hash table and free list allocated at construction;
// update() does not allocate.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "lod/roam.h"

namespace ig::lod {

class TriangleSlots {
 public:
  static constexpr uint32_t kNone = 0xFFFFFFFFu;

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

  // The slot holding triangle t (any vertex order), or kNone. O(1).
  uint32_t slotOf(const RoamTriangle& t) const;

  size_t capacity() const { return capacity_; }
  // One past the highest slot ever used: the range a renderer draws.
  uint32_t highWater() const { return highWater_; }
  size_t live() const { return live_; }

 private:
  static uint64_t key(const RoamTriangle& t);
  size_t find(uint64_t k) const;  // table index holding k, or of the empty entry for it
  void erase(size_t index);

  struct Entry {
    uint64_t key;
    uint32_t slot;
    uint32_t frame;  // last frame this triangle was seen
  };
  size_t capacity_;
  std::vector<Entry> table_;  // power-of-two size >= 2 * capacity; key 0 = empty
  std::vector<uint32_t> freeSlots_;
  std::vector<uint32_t> slotEntry_;  // slot -> table index, kNone when free
  uint32_t highWater_ = 0;
  uint32_t frame_ = 0;
  size_t live_ = 0;
};

}  // namespace ig::lod
