// LRU cache of resident hierarchical cells with a byte budget (lod/cells_cache.h; paper 003).
#include "lod/cells_cache.h"

#include <cassert>

namespace ig::lod {

namespace {
std::vector<uint32_t> parentsOf(const CellTree& tree) {
  std::vector<uint32_t> p(tree.size());
  for (uint32_t c = 0; c < tree.size(); ++c) p[c] = tree.parent(c);
  return p;
}
}  // namespace

CellCache::CellCache(std::span<const uint32_t> parent, uint64_t budgetBytes)
    : parent_(parent.begin(), parent.end()),
      prev_(parent.size(), kNoCell),
      next_(parent.size(), kNoCell),
      bytes_(parent.size(), 0),
      pinFrame_(parent.size(), kNever),
      resident_(parent.size(), 0),
      residentChildren_(parent.size(), 0),
      budget_(budgetBytes) {
  for (size_t c = 0; c < parent_.size(); ++c) assert(parent_[c] == kNoCell || parent_[c] < parent_.size());
}

CellCache::CellCache(const CellTree& tree, uint64_t budgetBytes) : CellCache(parentsOf(tree), budgetBytes) {}

void CellCache::unlink(uint32_t c) {
  uint32_t p = prev_[c], n = next_[c];
  if (p != kNoCell)
    next_[p] = n;
  else
    head_ = n;
  if (n != kNoCell)
    prev_[n] = p;
  else
    tail_ = p;
  prev_[c] = next_[c] = kNoCell;
}

void CellCache::pushMru(uint32_t c) {
  prev_[c] = tail_;
  next_[c] = kNoCell;
  if (tail_ != kNoCell)
    next_[tail_] = c;
  else
    head_ = c;
  tail_ = c;
}

// Moves each resident ancestor of c to the most-recently-used end (nearest first), so that every
// resident cell stays before its resident parent in LRU order; pins them for `pinFrame` unless
// it is kNever.
void CellCache::refreshAncestors(uint32_t c, uint64_t pinFrame) {
  for (uint32_t a = parent_[c]; a != kNoCell; a = parent_[a]) {
    if (pinFrame != kNever) pinFrame_[a] = pinFrame;
    if (resident_[a]) {
      unlink(a);
      pushMru(a);
    }
  }
}

void CellCache::insert(uint32_t cell, uint32_t bytes, uint64_t frame) {
  assert(cell < cellCount());
  (void)frame;
  if (resident_[cell]) {
    used_ -= bytes_[cell];
    unlink(cell);
  } else {
    resident_[cell] = 1;
    ++count_;
    if (parent_[cell] != kNoCell) ++residentChildren_[parent_[cell]];
  }
  bytes_[cell] = bytes;
  used_ += bytes;
  pushMru(cell);
  refreshAncestors(cell, kNever);
}

void CellCache::touch(uint32_t cell, uint64_t frame) {
  assert(cell < cellCount() && frame != kNever);
  pinFrame_[cell] = frame;
  if (resident_[cell]) {
    unlink(cell);
    pushMru(cell);
  }
  refreshAncestors(cell, frame);
}

void CellCache::remove(uint32_t cell) {
  assert(cell < cellCount());
  if (!resident_[cell]) return;
  unlink(cell);
  resident_[cell] = 0;
  --count_;
  used_ -= bytes_[cell];
  bytes_[cell] = 0;
  if (parent_[cell] != kNoCell) --residentChildren_[parent_[cell]];
}

CellEvictStats CellCache::evict(uint64_t frame, std::span<uint32_t> out) {
  CellEvictStats s;
  uint32_t c = head_;
  while (used_ > budget_ && c != kNoCell) {
    uint32_t n = next_[c];
    if (pinFrame_[c] != frame && residentChildren_[c] == 0) {
      if (s.evicted == out.size()) {
        s.spanFull = true;
        break;
      }
      out[s.evicted++] = c;
      remove(c);
    }
    c = n;
  }
  s.usedBytes = used_;
  s.overBudget = used_ > budget_;
  return s;
}

size_t CellCache::lruOrder(std::span<uint32_t> out) const {
  size_t k = 0;
  for (uint32_t c = head_; c != kNoCell && k < out.size(); c = next_[c]) out[k++] = c;
  return k;
}

}  // namespace ig::lod
