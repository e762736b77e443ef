#include "lod/triangle_slots.h"

#include <algorithm>
#include <cassert>
#include <functional>

namespace ig::lod {

TriangleSlots::TriangleSlots(size_t capacity) : capacity_(capacity) {
  size_t n = 16;
  while (n < 2 * capacity) n <<= 1;
  table_.assign(n, Entry{0, kNone, 0});
  slotEntry_.assign(capacity, kNone);
  freeSlots_.reserve(capacity);
}

uint64_t TriangleSlots::key(const RoamTriangle& t) {
  // Order-independent key of the three vertices (a triangle is the same whatever vertex the
  // emitter lists first); never 0, which marks an empty table entry.
  uint64_t k[3];
  for (int i = 0; i < 3; ++i)
    k[i] = (static_cast<uint64_t>(static_cast<uint32_t>(t.v[i].x)) << 32) | static_cast<uint32_t>(t.v[i].y);
  std::sort(k, k + 3);
  uint64_t h = 0x9E3779B97F4A7C15ull;
  for (uint64_t v : k) {
    h ^= v + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
    h *= 0xBF58476D1CE4E5B9ull;
    h ^= h >> 31;
  }
  return h == 0 ? 1 : h;
}

size_t TriangleSlots::find(uint64_t k) const {
  const size_t mask = table_.size() - 1;
  size_t i = static_cast<size_t>(k) & mask;
  while (table_[i].key != 0 && table_[i].key != k) i = (i + 1) & mask;
  return i;
}

void TriangleSlots::erase(size_t i) {
  // Backward-shift deletion keeps linear probing correct without tombstones.
  const size_t mask = table_.size() - 1;
  size_t hole = i;
  for (size_t j = (i + 1) & mask; table_[j].key != 0; j = (j + 1) & mask) {
    const size_t home = static_cast<size_t>(table_[j].key) & mask;
    // Move j into the hole if its home is not cyclically in (hole, j].
    const bool between = hole <= j ? (home > hole && home <= j) : (home > hole || home <= j);
    if (!between) {
      table_[hole] = table_[j];
      slotEntry_[table_[hole].slot] = static_cast<uint32_t>(hole);
      hole = j;
    }
  }
  table_[hole] = Entry{0, kNone, 0};
}

uint32_t TriangleSlots::takeLowestFree() {
  while (!freeSlots_.empty()) {
    const uint32_t s = freeSlots_.front();
    std::pop_heap(freeSlots_.begin(), freeSlots_.end(), std::greater<>());
    freeSlots_.pop_back();
    // Free slots below the mark are all smaller than the stale ones above it: once the lowest
    // is stale, every entry is.
    if (s < highWater_) return s;
    freeSlots_.clear();
  }
  return kNone;
}

void TriangleSlots::shrink() {
  while (highWater_ > 0 && slotEntry_[highWater_ - 1] == kNone) --highWater_;
}

size_t TriangleSlots::compact(size_t maxMoves, std::span<uint32_t> from, std::span<uint32_t> to) {
  assert(from.size() >= maxMoves && to.size() >= maxMoves && "TriangleSlots::compact: spans must hold maxMoves entries");
  size_t moves = 0;
  shrink();
  while (moves < maxMoves && live_ < highWater_) {
    const uint32_t top = highWater_ - 1;  // in use (shrink)
    const uint32_t hole = takeLowestFree();
    if (hole == kNone) break;  // cannot happen while live_ < highWater_
    const uint32_t e = slotEntry_[top];
    table_[e].slot = hole;
    slotEntry_[hole] = e;
    slotEntry_[top] = kNone;
    from[moves] = top;
    to[moves] = hole;
    ++moves;
    --highWater_;
    shrink();
  }
  return moves;
}

uint32_t TriangleSlots::slotOf(const RoamTriangle& t) const {
  const uint64_t k = key(t);
  const Entry& e = table_[find(k)];
  return e.key == k ? e.slot : kNone;
}

TriangleSlots::Changes TriangleSlots::update(std::span<const RoamTriangle> triangles, std::span<uint32_t> addedTriangles,
                                             std::span<uint32_t> addedSlots, std::span<uint32_t> freedSlots) {
  assert(addedTriangles.size() >= capacity_ && addedSlots.size() >= capacity_ && freedSlots.size() >= capacity_ &&
         "TriangleSlots::update: output spans must hold capacity() entries");
  Changes c;
  ++frame_;
  // 1. Mark what stays; collect what is new (key lookups only, slots assigned after frees).
  for (size_t t = 0; t < triangles.size(); ++t) {
    const uint64_t k = key(triangles[t]);
    const size_t i = find(k);
    if (table_[i].key == k) {
      table_[i].frame = frame_;
    } else if (c.added < capacity_) {
      addedTriangles[c.added++] = static_cast<uint32_t>(t);
    } else {
      c.overflow = true;
    }
  }
  // 2. Free the slots of triangles that were not seen this frame.
  for (uint32_t s = 0; s < highWater_; ++s) {
    const uint32_t e = slotEntry_[s];
    if (e == kNone || table_[e].frame == frame_) continue;
    erase(e);
    slotEntry_[s] = kNone;
    freeSlots_.push_back(s);  // capacity reserved: no allocation
    std::push_heap(freeSlots_.begin(), freeSlots_.end(), std::greater<>());
    freedSlots[c.freed++] = s;
    --live_;
  }
  // 3. Place the new triangles: the lowest free slots first, then grow the high-water mark.
  size_t placed = 0;
  for (size_t a = 0; a < c.added; ++a) {
    const uint64_t k = key(triangles[addedTriangles[a]]);
    const size_t i = find(k);
    if (table_[i].key == k) continue;  // the same triangle twice in the input: one slot
    uint32_t slot = takeLowestFree();
    if (slot == kNone) {
      if (highWater_ >= capacity_) {
        c.overflow = true;
        break;
      }
      slot = highWater_++;
    }
    table_[i] = Entry{k, slot, frame_};
    slotEntry_[slot] = static_cast<uint32_t>(i);
    addedTriangles[placed] = addedTriangles[a];
    addedSlots[placed] = slot;
    ++live_;
    ++placed;
  }
  c.added = placed;
  shrink();
  return c;
}

}  // namespace ig::lod
