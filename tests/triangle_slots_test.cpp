// Stable triangle slots: a simulated vertex buffer that applies only the reported changes
// always holds exactly the current triangles (plus degenerate free slots), and the changes
// are proportional to what changed.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <optional>
#include <random>
#include <set>
#include <vector>

#include "lod/triangle_slots.h"

using namespace ig::lod;

namespace {

RoamTriangle tri(int i) { return RoamTriangle{{{i, 0}, {i + 1, 0}, {i, 1}}}; }

using Tri = std::array<std::pair<int, int>, 3>;
Tri canon(const RoamTriangle& t) {
  Tri r{{{t.v[0].x, t.v[0].y}, {t.v[1].x, t.v[1].y}, {t.v[2].x, t.v[2].y}}};
  std::sort(r.begin(), r.end());
  return r;
}

struct Buffer {
  std::vector<std::optional<Tri>> slots;
  explicit Buffer(size_t n) : slots(n) {}
  void apply(const TriangleSlots::Changes& c, std::span<const RoamTriangle> tris, const std::vector<uint32_t>& addedT,
             const std::vector<uint32_t>& addedS, const std::vector<uint32_t>& freed) {
    for (size_t i = 0; i < c.freed; ++i) slots[freed[i]].reset();  // degenerate
    for (size_t i = 0; i < c.added; ++i) slots[addedS[i]] = canon(tris[addedT[i]]);
  }
  // A compaction move: the triangle goes to its new slot, the old one becomes degenerate.
  void move(size_t n, const std::vector<uint32_t>& from, const std::vector<uint32_t>& to) {
    for (size_t i = 0; i < n; ++i) {
      slots[to[i]] = slots[from[i]];
      slots[from[i]].reset();
    }
  }
  std::multiset<Tri> contents(uint32_t highWater) const {
    std::multiset<Tri> m;
    for (uint32_t s = 0; s < highWater; ++s)
      if (slots[s]) m.insert(*slots[s]);
    return m;
  }
};

}  // namespace

TEST(TriangleSlots, BufferAlwaysHoldsExactlyTheCurrentMesh) {
  constexpr size_t kCap = 500;
  TriangleSlots slots(kCap);
  Buffer buffer(kCap);
  std::vector<uint32_t> addedT(kCap), addedS(kCap), freed(kCap);
  std::mt19937 rng(42);
  std::set<int> current;
  for (int frame = 0; frame < 300; ++frame) {
    // Change a few triangles per frame, and everything now and then (a teleport).
    if (frame % 50 == 49) current.clear();
    for (int k = 0; k < 10; ++k) {
      const int id = static_cast<int>(rng() % 1000);
      if (current.count(id)) current.erase(id);
      else if (current.size() < 400) current.insert(id);
    }
    std::vector<RoamTriangle> tris;
    for (int id : current) tris.push_back(tri(id));
    std::shuffle(tris.begin(), tris.end(), rng);  // emit order must not matter
    const auto c = slots.update(tris, addedT, addedS, freed);
    ASSERT_FALSE(c.overflow);
    buffer.apply(c, tris, addedT, addedS, freed);
    std::multiset<Tri> want;
    for (const auto& t : tris) want.insert(canon(t));
    ASSERT_EQ(buffer.contents(slots.highWater()), want) << "frame " << frame;
    ASSERT_EQ(slots.live(), tris.size());
    ASSERT_LE(slots.highWater(), 410u);  // slots are reused, not leaked
  }
}

TEST(TriangleSlots, UnchangedMeshUploadsNothingAndOneChangeUploadsOne) {
  TriangleSlots slots(64);
  std::vector<uint32_t> a(64), s(64), f(64);
  std::vector<RoamTriangle> tris;
  for (int i = 0; i < 50; ++i) tris.push_back(tri(i));
  auto c = slots.update(tris, a, s, f);
  EXPECT_EQ(c.added, 50u);
  EXPECT_EQ(c.freed, 0u);
  c = slots.update(tris, a, s, f);
  EXPECT_EQ(c.added, 0u);
  EXPECT_EQ(c.freed, 0u);
  // The same triangle listed from another vertex is the same triangle.
  std::rotate(tris[7].v, tris[7].v + 1, tris[7].v + 3);
  tris[3] = tri(100);
  c = slots.update(tris, a, s, f);
  EXPECT_EQ(c.added, 1u);
  EXPECT_EQ(c.freed, 1u);
  EXPECT_EQ(s[0], f[0]) << "the freed slot is reused in the same frame";
}

TEST(TriangleSlots, OverflowAndDuplicatesAreHandled) {
  TriangleSlots slots(4);
  std::vector<uint32_t> a(4), s(4), f(4);
  std::vector<RoamTriangle> tris{tri(0), tri(0), tri(1)};
  auto c = slots.update(tris, a, s, f);
  EXPECT_FALSE(c.overflow);
  EXPECT_EQ(c.added, 2u);  // the duplicate gets no second slot
  EXPECT_EQ(slots.live(), 2u);
  tris = {tri(0), tri(1), tri(2), tri(3), tri(4), tri(5)};
  c = slots.update(tris, a, s, f);
  EXPECT_TRUE(c.overflow);
  EXPECT_EQ(slots.live(), 4u);
  EXPECT_EQ(slots.highWater(), 4u);
}

TEST(TriangleSlots, NewTrianglesTakeTheLowestFreeSlotAndTheMarkFalls) {
  TriangleSlots slots(128);
  std::vector<uint32_t> a(128), s(128), f(128);
  std::vector<RoamTriangle> tris;
  for (int i = 0; i < 100; ++i) tris.push_back(tri(i));
  slots.update(tris, a, s, f);
  ASSERT_EQ(slots.highWater(), 100u);
  // The top ten leave: the drawn range ends below them.
  std::vector<RoamTriangle> fewer;
  for (int i = 0; i < 100; ++i)
    if (slots.slotOf(tri(i)) < 90) fewer.push_back(tri(i));
  auto c = slots.update(fewer, a, s, f);
  EXPECT_EQ(c.freed, 10u);
  EXPECT_EQ(slots.highWater(), 90u);
  EXPECT_EQ(slots.holes(), 0u);
  // Two holes in the middle; two new triangles fill them, lowest first.
  const uint32_t s20 = 20, s40 = 40;
  std::vector<RoamTriangle> next;
  for (const RoamTriangle& t : fewer)
    if (slots.slotOf(t) != s20 && slots.slotOf(t) != s40) next.push_back(t);
  c = slots.update(next, a, s, f);
  EXPECT_EQ(c.freed, 2u);
  EXPECT_EQ(slots.holes(), 2u);
  next.push_back(tri(500));
  c = slots.update(next, a, s, f);
  ASSERT_EQ(c.added, 1u);
  EXPECT_EQ(s[0], s20);
  next.push_back(tri(501));
  next.push_back(tri(502));
  c = slots.update(next, a, s, f);
  ASSERT_EQ(c.added, 2u);
  EXPECT_EQ(std::min(s[0], s[1]), s40);
  EXPECT_EQ(std::max(s[0], s[1]), 90u) << "no hole left: the range grows by one";
  EXPECT_EQ(slots.highWater(), 91u);
}

TEST(TriangleSlots, CompactionBringsTheDrawnRangeBackToTheMesh) {
  // A heavy view, then a light one that keeps a scattered tenth of it: without compaction the
  // renderer would draw up to the heavy view's mark; compact() moves the top triangles into the
  // holes, a bounded number per frame, and the buffer always holds exactly the mesh.
  constexpr size_t kCap = 4000, kMoves = 300;
  TriangleSlots slots(kCap);
  Buffer buffer(kCap);
  std::vector<uint32_t> addedT(kCap), addedS(kCap), freed(kCap), from(kMoves), to(kMoves);
  std::mt19937 rng(7);
  std::set<int> current;
  for (int i = 0; i < 3500; ++i) current.insert(i);
  auto frame = [&](int n) {
    std::vector<RoamTriangle> tris;
    for (int id : current) tris.push_back(tri(id));
    std::shuffle(tris.begin(), tris.end(), rng);
    const auto c = slots.update(tris, addedT, addedS, freed);
    ASSERT_FALSE(c.overflow);
    buffer.apply(c, tris, addedT, addedS, freed);
    const size_t moves = slots.compact(kMoves, from, to);
    ASSERT_LE(moves, kMoves);
    for (size_t i = 0; i < moves; ++i) {
      ASSERT_GE(from[i], slots.highWater()) << "a move empties a slot above the drawn range";
      ASSERT_LT(to[i], slots.highWater());
    }
    buffer.move(moves, from, to);
    std::multiset<Tri> want;
    for (const auto& t : tris) want.insert(canon(t));
    ASSERT_EQ(buffer.contents(slots.highWater()), want) << "frame " << n;
    ASSERT_EQ(slots.live(), tris.size());
    for (const auto& t : tris) {
      const uint32_t s = slots.slotOf(t);
      ASSERT_LT(s, slots.highWater());
      ASSERT_TRUE(buffer.slots[s] && *buffer.slots[s] == canon(t)) << "slotOf follows the moves, frame " << n;
    }
  };
  frame(0);
  ASSERT_EQ(slots.highWater(), 3500u);
  // Keep every tenth triangle: 350 live, holes everywhere below 3,500.
  for (int i = 0; i < 3500; ++i)
    if (i % 10 != 3) current.erase(i);
  int frames = 1;
  do frame(frames++);
  while (slots.holes() > 0 && frames < 100);
  EXPECT_EQ(slots.highWater(), 350u);
  EXPECT_EQ(slots.holes(), 0u);
  // The moves are bounded: about 315 of the 350 lay above slot 350, so two frames of 300.
  EXPECT_LE(frames, 1 + 2);
  // Then the mesh changes a little every frame, compaction keeps up.
  for (int n = 0; n < 200; ++n) {
    for (int k = 0; k < 20; ++k) {
      const int id = static_cast<int>(rng() % 5000);
      if (current.count(id)) current.erase(id);
      else current.insert(id);
    }
    frame(frames++);
    ASSERT_EQ(slots.holes(), 0u) << "frame " << frames;
  }
  // Compacting a full range moves nothing.
  EXPECT_EQ(slots.compact(kMoves, from, to), 0u);
}

TEST(TriangleSlots, RandomSequencesMatchAReferenceModel) {
  // Random meshes (growing past capacity, shrinking, duplicates, rotated vertex orders) with
  // partial compactions: the simulated buffer's [0, highWater) always holds exactly the
  // triangles that have a slot, each once, and every triangle without one is reported.
  for (uint32_t seed = 1; seed <= 20; ++seed) {
    std::mt19937 rng(seed);
    const size_t cap = 16 + rng() % 200;
    TriangleSlots slots(cap);
    Buffer buffer(cap);
    std::vector<uint32_t> addedT(cap), addedS(cap), freed(cap), from(cap), to(cap);
    std::set<int> current;
    for (int f = 0; f < 300; ++f) {
      const int changes = static_cast<int>(rng() % (f % 37 == 0 ? 300 : 20));
      for (int k = 0; k < changes; ++k) {
        const int id = static_cast<int>(rng() % (2 * cap + 10));
        if (current.count(id)) current.erase(id);
        else current.insert(id);
      }
      std::vector<RoamTriangle> tris;
      for (int id : current) {
        RoamTriangle t = tri(id);
        std::rotate(t.v, t.v + rng() % 3, t.v + 3);
        tris.push_back(t);
        if (rng() % 10 == 0) tris.push_back(tri(id));  // duplicate
      }
      std::shuffle(tris.begin(), tris.end(), rng);
      const auto c = slots.update(tris, addedT, addedS, freed);
      buffer.apply(c, tris, addedT, addedS, freed);
      const size_t moves = slots.compact(rng() % (cap + 1), from, to);
      buffer.move(moves, from, to);
      std::multiset<Tri> want;
      std::set<Tri> seen;
      for (const auto& t : tris) {
        if (!seen.insert(canon(t)).second) continue;
        const uint32_t s = slots.slotOf(t);
        if (s == TriangleSlots::kNone) {
          ASSERT_TRUE(c.overflow) << "seed " << seed << " frame " << f << ": a triangle without a slot, no overflow";
          continue;
        }
        ASSERT_LT(s, slots.highWater());
        ASSERT_TRUE(buffer.slots[s] && *buffer.slots[s] == canon(t)) << "seed " << seed << " frame " << f;
        want.insert(canon(t));
      }
      ASSERT_LE(slots.highWater(), cap);
      ASSERT_EQ(slots.live(), want.size()) << "seed " << seed << " frame " << f;
      ASSERT_EQ(buffer.contents(slots.highWater()), want) << "seed " << seed << " frame " << f;
    }
  }
}
