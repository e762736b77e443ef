// The ROAM mesh kept by chunk (lod/terrain_chunks.h): a simulated vertex buffer that applies
// only the slots apply() lists always holds exactly the current leaves (plus degenerate slots),
// the ranges cull() draws hold every leaf emitVisible() finds, and the work per frame follows
// the change, along flights in every ROAM mode, with visit budgets, teleports (restarts from
// the base triangles), a log too small for an update, and a buffer too small for the mesh.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "lod/heightfield.h"
#include "lod/roam.h"
#include "terrain_fixtures.h"
#include "lod/terrain_chunks.h"

using namespace ig::lod;

namespace {

std::vector<float> fractal(int w, int h, uint32_t seed = 7) { return test::fractalHeights(w, h, seed); }

RoamView makeView(const glm::dvec3& eye, double heading_deg, double pitch_deg, double tolerance_px = 1.0) {
  return test::terrainView(eye, heading_deg, pitch_deg, tolerance_px, 720.0);
}

using Tri = std::array<std::pair<int, int>, 3>;
Tri canon(const RoamTriangle& t) {
  Tri r{{{t.v[0].x, t.v[0].y}, {t.v[1].x, t.v[1].y}, {t.v[2].x, t.v[2].y}}};
  std::sort(r.begin(), r.end());
  return r;
}

// What the GPU buffer would hold: each slot's triangle, or nothing (degenerate).
struct Buffer {
  std::vector<std::optional<Tri>> slots;
  explicit Buffer(size_t n) : slots(n) {}
  // Through forEachDirty, as igd writes the buffer.
  void apply(const Roam&, const TerrainChunks& chunks) {
    chunks.forEachDirty([&](uint32_t s, const RoamTriangle& t) { slots[s] = canon(t); },
                        [&](uint32_t s) { slots[s].reset(); });
  }
};

// A multiset of triangles as a sorted vector (std::multiset's node per triangle made the checks
// below the slowest tests under ASAN).
using Tris = std::vector<Tri>;
Tris sorted(Tris v) {
  std::sort(v.begin(), v.end());
  return v;
}
size_t countOf(const Tris& sortedTris, const Tri& t) {
  const auto [first, last] = std::equal_range(sortedTris.begin(), sortedTris.end(), t);
  return static_cast<size_t>(last - first);
}
Tris inBufferOf(const Buffer& buffer) {
  Tris v;
  for (const auto& s : buffer.slots)
    if (s) v.push_back(*s);
  return sorted(std::move(v));
}

Tris allLeaves(const Roam& roam) {
  std::vector<RoamTriangle> tris(roam.triangleCount());
  tris.resize(roam.emitTriangles(tris));
  Tris m;
  m.reserve(tris.size());
  for (const auto& t : tris) m.push_back(canon(t));
  return sorted(std::move(m));
}

// Checks one frame: the buffer's triangles in the drawn ranges are exactly the leaves of the
// chunks drawn (no duplicates, nothing stale), every visible leaf is drawn, and the whole
// buffer's live slots are the mesh.
// Near / far ranges seen over all frames of a test (cull with a reach): both must occur.
struct ReachCount {
  size_t nearRanges = 0, farRanges = 0;
};
ReachCount gReach;

void checkFrame(const Roam& roam, const TerrainChunks& chunks, const Buffer& buffer, const Camera& cam,
                const std::string& where) {
  std::string why;
  ASSERT_TRUE(chunks.validate(&why)) << where << ": " << why;
  ASSERT_EQ(inBufferOf(buffer), allLeaves(roam)) << where << ": the buffer is not the mesh";
  std::vector<TerrainDrawRange> ranges;
  const size_t drawnLive = chunks.cull(cam, ranges);
  Tris drawn;
  uint32_t last = 0;
  for (const TerrainDrawRange& r : ranges) {
    ASSERT_LE(r.first + r.count, chunks.capacity()) << where;
    for (uint32_t s = r.first; s < r.first + r.count; ++s)
      if (buffer.slots[s]) drawn.push_back(*buffer.slots[s]);
    last = std::max(last, r.first + r.count);
  }
  drawn = sorted(std::move(drawn));
  EXPECT_EQ(drawn.size(), drawnLive) << where << ": the live count of the drawn chunks";
  // Every leaf whose own box (its three vertices) meets the frustum is drawn.
  std::vector<RoamTriangle> tris(roam.triangleCount());
  tris.resize(roam.emitTriangles(tris));
  const Frustum frustum = makeFrustum(cam);
  size_t visible = 0;
  for (const RoamTriangle& t : tris) {
    Aabb box{roam.vertexPosition(t.v[0].x, t.v[0].y), roam.vertexPosition(t.v[0].x, t.v[0].y)};
    for (const RoamVertex& v : t.v) {
      box.min = glm::min(box.min, roam.vertexPosition(v.x, v.y));
      box.max = glm::max(box.max, roam.vertexPosition(v.x, v.y));
    }
    if (!frustum.intersects(Aabb{box.min - cam.eye_m, box.max - cam.eye_m})) continue;
    ++visible;
    ASSERT_TRUE(std::binary_search(drawn.begin(), drawn.end(), canon(t))) << where << ": a visible leaf is not in the drawn ranges";
  }
  EXPECT_GE(drawn.size(), visible);
  for (const TerrainDrawRange& r : ranges) {
    ASSERT_EQ(r.near, 1u) << where << ": without a reach every range is near";
  }
  // With a reach: the same slots, split into near and far ranges; a far range holds only
  // triangles wholly beyond the reach, and every triangle that comes closer is in a near one.
  {
    constexpr double kReach = 600.0;
    std::vector<TerrainDrawRange> split;
    EXPECT_EQ(chunks.cull(cam, split, kReach), drawnLive) << where;
    Tris drawnSplit;
    size_t nearRanges = 0;
    for (const TerrainDrawRange& r : split) {
      nearRanges += r.near;
      for (uint32_t s = r.first; s < r.first + r.count; ++s) {
        if (!buffer.slots[s]) continue;
        drawnSplit.push_back(*buffer.slots[s]);
        double closest = 1e300;
        for (const auto& [x, y] : *buffer.slots[s]) closest = std::min(closest, glm::length(roam.vertexPosition(x, y) - cam.eye_m));
        if (r.near == 0) {
          ASSERT_GE(closest, kReach) << where << ": a far range holds a triangle within the reach";
        }
      }
    }
    ASSERT_EQ(sorted(std::move(drawnSplit)), drawn) << where << ": the split ranges draw other triangles";
    gReach.nearRanges += nearRanges;
    gReach.farRanges += split.size() - nearRanges;
  }
  // Ranges never overlap: nothing is drawn twice.
  std::vector<TerrainDrawRange> sorted = ranges;
  std::sort(sorted.begin(), sorted.end(), [](auto a, auto b) { return a.first < b.first; });
  for (size_t i = 1; i < sorted.size(); ++i)
    ASSERT_LE(sorted[i - 1].first + sorted[i - 1].count, sorted[i].first) << where << ": overlapping ranges";
}

std::vector<RoamView> flight(double size_m) {
  std::vector<RoamView> path;
  glm::dvec3 eye{0.2 * size_m, 0.1 * size_m, 700.0};
  double heading = 20.0;
  for (int i = 0; i < 30; ++i) {
    eye += glm::dvec3(std::sin(heading * 0.0174533), std::cos(heading * 0.0174533), 0.0) * 90.0;
    path.push_back(makeView(eye, heading, -15.0));
  }
  for (int i = 0; i < 8; ++i) {  // hard turn
    heading += 30.0;
    eye += glm::dvec3(std::sin(heading * 0.0174533), std::cos(heading * 0.0174533), 0.0) * 90.0;
    path.push_back(makeView(eye, heading, -25.0));
  }
  path.push_back(makeView({0.8 * size_m, 0.85 * size_m, 900.0}, 225.0, -20.0));  // teleport
  for (int i = 1; i < 10; ++i) path.push_back(makeView({0.8 * size_m - 50.0 * i, 0.85 * size_m - 50.0 * i, 900.0 - 40.0 * i}, 225.0, -20.0));
  path.push_back(makeView({0.5 * size_m, 0.5 * size_m, 300.0}, 0.0, -89.0));  // looking straight down
  return path;
}

}  // namespace

TEST(TerrainChunks, BufferHoldsTheMeshAndCullDrawsEveryVisibleLeafInEveryMode) {
  gReach = {};
  const int n = 257;
  const auto hts = fractal(n, n);
  const RoamMode modes[] = {RoamMode::EnhMerge, RoamMode::MergeQueue, RoamMode::Rebuild, RoamMode::Deferred};
  for (RoamMode mode : modes) {
    RoamConfig rc;
    rc.maxTriangles = 200000;
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, rc);
    TerrainChunksConfig cc;
    cc.chunkSide = 16;
    TerrainChunks chunks(roam, cc);
    Buffer buffer(chunks.capacity());
    const auto path = flight(30.0 * (n - 1));
    size_t rereads = 0, incremental = 0;
    for (size_t f = 0; f < path.size(); ++f) {
      RoamView v = path[f];
      if (mode == RoamMode::Deferred) v.maxVisits = 3000;  // budgeted: restarts on the teleport
      const RoamStats st = roam.update(v, mode);
      const TerrainChunks::Changes c = chunks.apply();
      buffer.apply(roam, chunks);
      EXPECT_EQ(c.dropped, 0u);
      EXPECT_EQ(chunks.liveTriangles(), allLeaves(roam).size());
      if (c.reread) ++rereads;
      else {
        ++incremental;
        // O(change): each leaf that came or went is one log entry, and packing touches at most
        // the chunks that changed.
        EXPECT_LE(c.dirty, c.added + c.removed + c.packedSlots) << "frame " << f;
      }
      // The whole check (buffer against the mesh, culling against every leaf) on every frame of
      // the modes igd runs (EnhMerge, Deferred), on every 3rd and the last of the others.
      const bool everyFrame = mode == RoamMode::EnhMerge || mode == RoamMode::Deferred;
      if (everyFrame || f % 3 == 0 || f + 1 == path.size()) {
        checkFrame(roam, chunks, buffer, v.camera, "mode " + std::to_string(static_cast<int>(mode)) + " frame " + std::to_string(f));
        if (::testing::Test::HasFatalFailure()) return;
      }
      (void)st;
    }
    if (mode == RoamMode::Rebuild) {
      EXPECT_EQ(rereads, path.size()) << "Rebuild restarts from the base every frame";
    } else {
      EXPECT_GT(incremental, path.size() / 2) << "the log, not re-reads, carries the flight";
    }
    std::printf("[ chunks ] mode %d: %zu re-reads, %zu incremental, %zu live, %zu slots in blocks\n",
                static_cast<int>(mode), rereads, incremental, chunks.liveTriangles(), chunks.slotsInUse());
  }
  // The flight passes within 600 m of ground and sees ground beyond it: cull() marked both.
  EXPECT_GT(gReach.nearRanges, 0u);
  EXPECT_GT(gReach.farRanges, 0u);
}

TEST(TerrainChunks, ALogTooSmallForAnUpdateFallsBackToAReread) {
  const int n = 129;
  const auto hts = fractal(n, n, 3);
  Roam roam(hts, n, n, 30.0, {0, 0, 0});
  TerrainChunksConfig cc;
  cc.logCapacity = 64;  // far less than a flight frame changes
  cc.chunkSide = 8;
  TerrainChunks chunks(roam, cc);
  Buffer buffer(chunks.capacity());
  const auto path = flight(30.0 * (n - 1));
  size_t rereads = 0;
  for (size_t f = 0; f < path.size(); ++f) {
    roam.update(path[f], RoamMode::EnhMerge);
    rereads += chunks.apply().reread;
    buffer.apply(roam, chunks);
    checkFrame(roam, chunks, buffer, path[f].camera, "frame " + std::to_string(f));
    if (::testing::Test::HasFatalFailure()) return;
  }
  EXPECT_GT(rereads, 2u);
}

TEST(TerrainChunks, ABufferTooSmallDropsLeavesReportsItAndRecoversWhenTheMeshShrinks) {
  const int n = 257;
  const auto hts = fractal(n, n, 9);
  Roam roam(hts, n, n, 30.0, {0, 0, 0});
  TerrainChunksConfig cc;
  cc.capacityTriangles = 4096;
  cc.chunkSide = 32;
  TerrainChunks chunks(roam, cc);
  Buffer buffer(chunks.capacity());
  RoamView close = makeView({3800, 3800, 200}, 45, -20, 0.5);
  roam.update(close, RoamMode::EnhMerge);
  ASSERT_GT(roam.triangleCount(), chunks.capacity());
  const TerrainChunks::Changes c = chunks.apply();
  buffer.apply(roam, chunks);
  EXPECT_GT(c.dropped, 0u);
  EXPECT_TRUE(chunks.overflowed());
  EXPECT_LE(chunks.liveTriangles(), chunks.capacity());
  std::string why;
  EXPECT_TRUE(chunks.validate(&why)) << why;
  // Coarser: the mesh fits again and every leaf gets its slot (the next apply re-reads).
  RoamView far = makeView({3800, 3800, 6000}, 45, -20, 8.0);
  roam.update(far, RoamMode::EnhMerge);
  ASSERT_LT(roam.triangleCount(), chunks.capacity() / 2);
  const TerrainChunks::Changes c2 = chunks.apply();
  buffer.apply(roam, chunks);
  EXPECT_TRUE(c2.reread);
  EXPECT_EQ(c2.dropped, 0u);
  EXPECT_FALSE(chunks.overflowed());
  checkFrame(roam, chunks, buffer, far.camera, "after shrinking");
}

TEST(TerrainChunks, TinyAndNonPowerOfTwoDems) {
  for (auto [w, h] : {std::pair{2, 2}, std::pair{3, 2}, std::pair{100, 37}, std::pair{65, 130}}) {
    const auto hts = fractal(w, h, 5);
    Roam roam(hts, w, h, 30.0, {0, 0, 0});
    TerrainChunks chunks(roam);
    Buffer buffer(chunks.capacity());
    for (const RoamView& v : {makeView({15, 15, 50}, 0, -30, 0.5), makeView({900, 400, 80}, 200, -40, 0.5)}) {
      roam.update(v, RoamMode::EnhMerge);
      chunks.apply();
      buffer.apply(roam, chunks);
      checkFrame(roam, chunks, buffer, v.camera, std::to_string(w) + "x" + std::to_string(h));
      if (::testing::Test::HasFatalFailure()) return;
    }
  }
}

TEST(TerrainChunks, ShrinkingChunksArePackedSoDrawnSlotsFollowTheMesh) {
  const int n = 257;
  const auto hts = fractal(n, n, 13);
  Roam roam(hts, n, n, 30.0, {0, 0, 0});
  TerrainChunks chunks(roam, TerrainChunksConfig{.chunkSide = 32});
  Buffer buffer(chunks.capacity());
  // Low over one spot (dense), then climb away over many frames (the mesh thins out).
  size_t packed = 0;
  for (int i = 0; i <= 40; ++i) {
    const RoamView v = makeView({3800, 3800, 60.0 * std::pow(1.15, i)}, 45, -30, 0.5);
    roam.update(v, RoamMode::EnhMerge);
    packed += chunks.apply().packedChunks;
    buffer.apply(roam, chunks);
    checkFrame(roam, chunks, buffer, v.camera, "climb " + std::to_string(i));
    if (::testing::Test::HasFatalFailure()) return;
  }
  EXPECT_GT(packed, 0u);
  // Degenerate slots drawn stay bounded: a chunk holds at most 4 slots per live triangle, or
  // two of the smallest blocks.
  EXPECT_LE(chunks.slotsInUse(), 4 * chunks.liveTriangles() + 2 * TerrainChunks::kMinBlock * chunks.chunkCount());
}

TEST(TerrainChunks, RandomViewsBudgetsAndSmallBuffersMatchTheMesh) {
  // Random eyes (jumps, climbs, dives), budgets, log sizes and buffers that may be too small
  // for the mesh: after every apply() the buffer holds only current leaves, each once, exactly
  // liveTriangles() of them, all of them when nothing was dropped, and checkFrame's checks hold.
  const int n = 129;
  const auto hts = fractal(n, n, 21);
  const double size = 30.0 * (n - 1);
  size_t droppedFrames = 0, incremental = 0, packed = 0;
  for (uint32_t seed = 1; seed <= 12; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    RoamConfig rc;
    rc.maxTriangles = 60000;
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, rc);
    TerrainChunksConfig cc;
    cc.chunkSide = 8 << (rng() % 3);
    cc.capacityTriangles = seed % 3 == 0 ? 2048 + rng() % 6000 : 0;
    cc.logCapacity = seed % 4 == 0 ? 200 : (1u << 20);
    TerrainChunks chunks(roam, cc);
    Buffer buffer(chunks.capacity());
    const RoamMode mode = (seed % 2) ? RoamMode::Deferred : RoamMode::EnhMerge;
    glm::dvec3 eye{u(rng) * size, u(rng) * size, 100 + u(rng) * 1500};
    double heading = u(rng) * 360;
    for (int f = 0; f < 24; ++f) {
      if (rng() % 8 == 0) eye = {u(rng) * size, u(rng) * size, 50 + u(rng) * 2000};
      else eye += glm::dvec3((u(rng) - 0.5) * 400, (u(rng) - 0.5) * 400, (u(rng) - 0.5) * 200);
      eye.z = std::max(eye.z, 30.0);
      heading += (u(rng) - 0.5) * 90;
      RoamView v = makeView(eye, heading, -10 - u(rng) * 60, 0.5 + u(rng) * 3);
      if (mode == RoamMode::Deferred && rng() % 2) v.maxVisits = static_cast<uint32_t>(500 + rng() % 5000);
      roam.update(v, mode);
      const TerrainChunks::Changes c = chunks.apply();
      buffer.apply(roam, chunks);
      const std::string where = "seed " + std::to_string(seed) + " frame " + std::to_string(f);
      droppedFrames += c.dropped > 0;
      incremental += !c.reread;
      packed += c.packedChunks;
      std::string why;
      ASSERT_TRUE(chunks.validate(&why)) << where << ": " << why;
      if (c.dropped == 0) {
        checkFrame(roam, chunks, buffer, v.camera, where);
        if (::testing::Test::HasFatalFailure()) return;
        continue;
      }
      const Tris leaves = allLeaves(roam);
      const Tris inBuffer = inBufferOf(buffer);
      ASSERT_EQ(inBuffer.size(), chunks.liveTriangles()) << where;
      for (const Tri& t : inBuffer) {
        ASSERT_EQ(countOf(inBuffer, t), 1u) << where << ": a triangle in two slots";
        ASSERT_TRUE(std::binary_search(leaves.begin(), leaves.end(), t)) << where << ": a stale triangle in the buffer";
      }
      std::vector<TerrainDrawRange> ranges;
      chunks.cull(v.camera, ranges);
      for (const TerrainDrawRange& r : ranges) ASSERT_LE(r.first + r.count, chunks.capacity()) << where;
    }
  }
  std::printf("[ chunks ] random: %zu frames dropped leaves, %zu incremental, %zu packed\n", droppedFrames, incremental, packed);
  EXPECT_GT(droppedFrames, 0u);
  EXPECT_GT(incremental, 0u);
}

// A frame whose far plane culls the whole terrain (thick fog; a host's View Definition), then
// the far plane back: the buffer still holds the mesh and cull() draws every visible leaf.
TEST(TerrainChunks, AFrameThatSeesNothingLeavesTheBufferWhole) {
  const int n = 257;
  const auto hts = fractal(n, n);
  for (RoamMode mode : {RoamMode::EnhMerge, RoamMode::Deferred}) {
    SCOPED_TRACE(static_cast<int>(mode));
    RoamConfig rc;
    rc.maxTriangles = 200000;
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, rc);
    TerrainChunksConfig cc;
    cc.chunkSide = 16;
    TerrainChunks chunks(roam, cc);
    Buffer buffer(chunks.capacity());
    RoamView open = makeView({0.3 * 30.0 * (n - 1), 0.2 * 30.0 * (n - 1), 700.0}, 20.0, -10.0);
    RoamView shut = open;
    shut.camera.far_m = 50.0;
    int f = 0;
    for (const RoamView* v : {&open, &open, &shut, &shut, &open, &open}) {
      roam.update(*v, mode);
      chunks.apply();
      buffer.apply(roam, chunks);
      checkFrame(roam, chunks, buffer, v->camera, "frame " + std::to_string(f++));
      if (HasFatalFailure()) return;
    }
  }
}
