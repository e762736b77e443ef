// lod/cells_cache: the LRU cache of resident cells with a byte budget.
//  - eviction follows LRU order (insert and touch refresh a cell), children before parents;
//  - cells drawn this frame and their ancestors are never evicted; the cache is never over budget
//    after evict() unless every remaining cell is pinned (reported), on a random streaming run;
//  - a full output span stops eviction and says so; remove() and re-insert keep the accounting;
//  - built from a CellTree; no allocation in insert/touch/evict.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <atomic>
#include <cstdlib>
#include <new>
#include <random>
#include <string>
#include <vector>

#include "lod/cells.h"
#include "lod/cells_cache.h"
#include "alloc_counter.h"

namespace {

using ig::lod::CellCache;
using ig::lod::kNoCell;

// A full octree of `levels` levels, breadth-first: parent of c > 0 is (c - 1) / 8.
std::vector<uint32_t> octreeParents(int levels) {
  uint32_t n = 0, layer = 1;
  for (int q = 0; q < levels; ++q, layer *= 8) n += layer;
  std::vector<uint32_t> p(n);
  p[0] = kNoCell;
  for (uint32_t c = 1; c < n; ++c) p[c] = (c - 1) / 8;
  return p;
}

std::vector<uint32_t> lru(const CellCache& cache) {
  std::vector<uint32_t> out(cache.cellCount());
  out.resize(cache.lruOrder(out));
  return out;
}

}  // namespace

TEST(CellCache, EvictsLeastRecentlyUsedChildrenFirst) {
  auto parent = octreeParents(2);  // root 0, children 1..8
  CellCache cache(parent, 1000);
  cache.insert(0, 100, 0);
  for (uint32_t c = 1; c <= 8; ++c) cache.insert(c, 100, 0);
  EXPECT_EQ(cache.usedBytes(), 900u);
  EXPECT_EQ(cache.residentCells(), 9u);
  // Inserting a child refreshes its parent: the root is the most recently used.
  EXPECT_EQ(lru(cache), (std::vector<uint32_t>{1, 2, 3, 4, 5, 6, 7, 8, 0}));
  cache.touch(3, 1);
  EXPECT_EQ(lru(cache), (std::vector<uint32_t>{1, 2, 4, 5, 6, 7, 8, 3, 0}));

  // Under budget: nothing goes.
  std::vector<uint32_t> out(16);
  auto s = cache.evict(1, out);
  EXPECT_EQ(s.evicted, 0u);
  EXPECT_FALSE(s.overBudget);

  // Budget 450: evict the 5 least recently used unpinned cells (3 and the root are pinned).
  cache.setBudgetBytes(450);
  s = cache.evict(1, out);
  EXPECT_EQ(std::vector<uint32_t>(out.begin(), out.begin() + s.evicted), (std::vector<uint32_t>{1, 2, 4, 5, 6}));
  EXPECT_EQ(s.usedBytes, 400u);
  EXPECT_FALSE(s.overBudget);
  EXPECT_FALSE(cache.contains(1));
  EXPECT_TRUE(cache.contains(7));

  // A new frame, nothing drawn, budget 50: children go before the root, then the root.
  cache.setBudgetBytes(50);
  s = cache.evict(2, out);
  EXPECT_EQ(std::vector<uint32_t>(out.begin(), out.begin() + s.evicted), (std::vector<uint32_t>{7, 8, 3, 0}));
  EXPECT_EQ(cache.usedBytes(), 0u);
  EXPECT_EQ(cache.residentCells(), 0u);
}

TEST(CellCache, PinnedCellsSurviveAndOverBudgetIsReported) {
  auto parent = octreeParents(3);  // 73 cells
  CellCache cache(parent, 250);
  cache.insert(0, 100, 0);
  cache.insert(1, 100, 0);
  cache.insert(9, 100, 0);   // child of 1
  cache.insert(10, 100, 0);  // child of 1
  cache.insert(2, 100, 0);
  // Frame 5 draws 9: 9, 1 and 0 are pinned; 10 and 2 can go. Budget 250 < the 300 pinned bytes.
  cache.touch(9, 5);
  EXPECT_TRUE(cache.pinned(9, 5));
  EXPECT_TRUE(cache.pinned(1, 5));
  EXPECT_TRUE(cache.pinned(0, 5));
  EXPECT_FALSE(cache.pinned(10, 5));
  std::vector<uint32_t> out(8);
  auto s = cache.evict(5, out);
  EXPECT_EQ(s.evicted, 2u);
  EXPECT_TRUE(s.overBudget);  // everything left is pinned
  EXPECT_FALSE(s.spanFull);
  EXPECT_EQ(s.usedBytes, 300u);
  EXPECT_TRUE(cache.contains(9) && cache.contains(1) && cache.contains(0));
  EXPECT_FALSE(cache.contains(10) || cache.contains(2));
  // The next frame draws nothing: the pins expire and the cache gets under budget, child first.
  s = cache.evict(6, out);
  EXPECT_FALSE(s.overBudget);
  EXPECT_EQ(s.evicted, 1u);
  EXPECT_EQ(out[0], 9u);
  // Touching a cell that is not resident pins its resident ancestors.
  cache.setBudgetBytes(0);
  cache.touch(20, 7);  // child of 2, which is gone; its grandparent 0 is resident
  s = cache.evict(7, out);
  EXPECT_TRUE(cache.contains(0));
  EXPECT_FALSE(cache.contains(1));
  EXPECT_TRUE(s.overBudget);
}

TEST(CellCache, FullSpanRemoveAndReinsert) {
  auto parent = octreeParents(2);
  CellCache cache(parent, 0);
  for (uint32_t c = 0; c <= 8; ++c) cache.insert(c, 10 + c, 0);
  std::vector<uint32_t> out(3);
  auto s = cache.evict(1, out);
  EXPECT_EQ(s.evicted, 3u);
  EXPECT_TRUE(s.spanFull);
  EXPECT_TRUE(s.overBudget);
  cache.remove(8);
  cache.remove(8);  // no effect
  cache.insert(5, 100, 1);  // re-insert with a new size: accounting follows
  uint64_t sum = 0;
  for (uint32_t c : lru(cache)) sum += cache.bytes(c);
  EXPECT_EQ(cache.usedBytes(), sum);
  EXPECT_EQ(cache.usedBytes(), 14u + 100u + 16u + 17u + 10u);  // 4, 5 (resized), 6, 7, root
  out.resize(16);
  s = cache.evict(2, out);
  EXPECT_FALSE(s.spanFull);
  EXPECT_EQ(cache.usedBytes(), 0u);
}

// A streaming run on a 4-level octree: each frame draws a random cut, inserts arrivals parent
// first, and evicts. After every evict: within budget or everything pinned; drawn cells and their
// ancestors resident; the resident set closed under ancestors; the byte count exact. No allocation.
TEST(CellCache, RandomStreamingRunKeepsTheRules) {
  auto parent = octreeParents(4);  // 585 cells
  const uint32_t n = static_cast<uint32_t>(parent.size());
  std::vector<uint32_t> size(n);
  std::mt19937 rng(42);
  for (auto& s : size) s = 100 + static_cast<uint32_t>(rng() % 900);
  CellCache cache(parent, 60000);
  std::vector<uint32_t> out(n), order(n), drawn;
  drawn.reserve(n);
  std::vector<uint8_t> resident(n, 0);
  long allocs = 0;
  int overBudgetFrames = 0;
  uint64_t evictedTotal = 0, drawnTotal = 0;
  for (uint64_t frame = 0; frame < 400; ++frame) {
    // Vary the budget: sometimes below what the drawn cells need.
    cache.setBudgetBytes(frame % 100 < 90 ? 60000 : 3000);
    drawn.clear();
    // Draw: walk down from the root, refining resident cells at random; request (insert) some
    // absent children, as arrivals.
    std::vector<uint32_t> stack = {0};
    if (!resident[0]) {
      cache.insert(0, size[0], frame);
      resident[0] = 1;
    }
    while (!stack.empty()) {
      uint32_t c = stack.back();
      stack.pop_back();
      uint32_t first = c * 8 + 1;
      bool refine = first < n && rng() % 3 != 0;
      bool all = refine;
      for (uint32_t k = 0; refine && k < 8; ++k) {
        if (!resident[first + k] && rng() % 2 == 0) {
          cache.insert(first + k, size[first + k], frame);
          resident[first + k] = 1;
        }
        all = all && resident[first + k];
      }
      if (all) {
        for (uint32_t k = 0; k < 8; ++k) stack.push_back(first + k);
      } else {
        drawn.push_back(c);
      }
    }
    gAllocs = 0;
    gCountAllocs = true;
    for (uint32_t c : drawn) cache.touch(c, frame);
    auto s = cache.evict(frame, out);
    gCountAllocs = false;
    allocs += gAllocs.load();
    evictedTotal += s.evicted;
    drawnTotal += drawn.size();
    for (uint32_t i = 0; i < s.evicted; ++i) {
      ASSERT_TRUE(resident[out[i]]);
      resident[out[i]] = 0;
      EXPECT_FALSE(cache.pinned(out[i], frame)) << "pinned cell " << out[i] << " evicted in frame " << frame;
    }
    // Rules.
    uint64_t sum = 0;
    bool allPinned = true;
    for (uint32_t c = 0; c < n; ++c) {
      ASSERT_EQ(cache.contains(c), resident[c] != 0) << c;
      if (!resident[c]) continue;
      sum += size[c];
      allPinned = allPinned && cache.pinned(c, frame);
      if (parent[c] != kNoCell) {
        ASSERT_TRUE(resident[parent[c]]) << "cell " << c << " without its parent";
      }
    }
    EXPECT_EQ(cache.usedBytes(), sum);
    EXPECT_FALSE(s.spanFull);
    if (s.overBudget) {
      ++overBudgetFrames;
      EXPECT_TRUE(allPinned) << "over budget in frame " << frame << " with unpinned cells";
    } else {
      EXPECT_LE(cache.usedBytes(), cache.budgetBytes());
    }
    for (uint32_t c : drawn)
      for (uint32_t a = c; a != kNoCell; a = parent[a]) ASSERT_TRUE(resident[a]) << "drawn " << c << " lost " << a;
    // LRU order: every resident cell before its resident parent.
    size_t m = cache.lruOrder(order);
    std::vector<uint32_t> pos(n, 0);
    for (size_t i = 0; i < m; ++i) pos[order[i]] = static_cast<uint32_t>(i);
    for (size_t i = 0; i < m; ++i) {
      uint32_t c = order[i];
      if (parent[c] != kNoCell) {
        ASSERT_LT(pos[c], pos[parent[c]]) << c;
      }
    }
  }
  EXPECT_EQ(allocs, 0);
  EXPECT_GT(overBudgetFrames, 0);  // the 3,000-byte frames cannot hold the drawn cells
  EXPECT_GT(evictedTotal, 1000u);
  EXPECT_GT(drawnTotal, 4000u);
  std::printf("400 frames: %llu cells drawn, %llu evicted, %d frames over budget (all pinned)\n",
              static_cast<unsigned long long>(drawnTotal), static_cast<unsigned long long>(evictedTotal),
              overBudgetFrames);  // the 3,000-byte frames cannot hold the drawn cells
}

TEST(CellCache, FromCellTree) {
  std::vector<ig::lod::CellDesc> d(9);
  d[0] = {kNoCell, 0, 1, 50};
  for (uint8_t k = 0; k < 8; ++k) d[1 + k] = {0, k, 1, 20};
  ig::lod::CellTree tree;
  std::string err;
  ASSERT_TRUE(tree.build({}, d, err)) << err;
  CellCache cache(tree, 100);
  EXPECT_EQ(cache.cellCount(), 9u);
  cache.insert(0, tree.bytes(0), 0);
  for (uint32_t c = 1; c <= 8; ++c) cache.insert(c, tree.bytes(c), 0);
  cache.touch(4, 1);
  std::vector<uint32_t> out(9);
  auto s = cache.evict(1, out);
  EXPECT_EQ(s.evicted, 6u);  // 210 -> 90 bytes; the root and cell 4 are pinned
  EXPECT_EQ(s.usedBytes, 90u);
  EXPECT_TRUE(cache.contains(4));
  EXPECT_TRUE(cache.contains(0));
  EXPECT_FALSE(s.overBudget);
}
