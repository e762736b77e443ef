// lod/roam: what a mutation pass found roam_test leaves open (it still passes when roam.cpp is
// changed). Pinned down here, from roam.h:
//   - the pool: 2 * maxTriangles + the base triangles by default, raised to 2 * base;
//   - the selection rule exactly: errorPx = e * viewportHeight / (2 tan(fovY / 2)) / distance to
//     the diamond's box, split if > tolerance, merged if <= (ties included, in every mode);
//     infinity with the eye in the box, which holds all the geometry below it; tolerance 0
//     splits only diamonds with an error;
//   - the caps: a split that fits exactly is made (triangles and pool), the view lowers but
//     cannot raise the configured cap, a capped mesh keeps the largest errors split, and
//     stats.maxErrorPx stays an upper bound (capped, interrupted, just enhMerged);
//   - the bookkeeping: nodes freed and created vertices balance the node count, removed vertices
//     are what a coarsening removes, one enhMerge per top-most subtree, Deferred visits are nodes
//     examined + created + freed and no operation starts without a visit left, maxVisits and stop
//     are Deferred only, the leaf log replays to the current leaves (or says it cannot);
//   - Deferred: lateness keeps every leaf within the tolerance and saves examinations, a restart
//     refines the view first; splitEnds and leafAt at the padded grid's edges; nearestTriangleBox
//     goes on while the distance equals `enough`.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "lod/roam.h"
#include "terrain_fixtures.h"

using namespace ig::lod;

namespace {

using test::kAllModes;
using test::modeName;

RoamConfig cap(uint64_t triangles) {
  RoamConfig c;
  c.maxTriangles = triangles;
  return c;
}

RoamView makeView(const glm::dvec3& eye, double heading_deg, double pitch_deg, double tolerance_px) {
  return test::terrainView(eye, heading_deg, pitch_deg, tolerance_px, 1080.0);
}

// A few views over a 129 x 129 DEM 30 m apart: cruise, a hard turn, a climb and a teleport.
std::vector<RoamView> shortFlight(double tolerance_px) {
  std::vector<RoamView> path;
  for (int i = 0; i < 6; ++i) path.push_back(makeView({600.0 + 80.0 * i, 500.0 + 60.0 * i, 450.0}, 40.0, -20.0, tolerance_px));
  for (int i = 0; i < 4; ++i) path.push_back(makeView({1080.0, 860.0, 450.0 + 150.0 * i}, 40.0 + 45.0 * i, -25.0, tolerance_px));
  path.push_back(makeView({3300.0, 3400.0, 500.0}, 225.0, -20.0, tolerance_px));  // teleport
  path.push_back(makeView({3250.0, 3350.0, 500.0}, 225.0, -20.0, tolerance_px));
  return path;
}

using test::sortedTriangles;

std::set<std::pair<int, int>> meshVertices(const Roam& roam) {
  std::vector<RoamTriangle> tris(roam.triangleCount());
  tris.resize(roam.emitTriangles(tris));
  std::set<std::pair<int, int>> out;
  for (const auto& t : tris)
    for (const auto& v : t.v) out.emplace(v.x, v.y);
  return out;
}

bool hasVertex(const Roam& roam, int x, int y) { return meshVertices(roam).count({x, y}) > 0; }

#define EXPECT_VALID(roam)                       \
  do {                                           \
    std::string why_;                            \
    EXPECT_TRUE((roam).validate(&why_)) << why_; \
  } while (0)

// 65 x 65 samples 10 m apart, all 100 m high but one 108 m spike: the only diamonds with an
// error are the spike's own (error 8 m), its ancestors (8 m) and its descendants (4 m). With
// `dip`, sample (60, 60) is 90 m deep, far from the spike: the heights no longer fall on the
// 16-bit steps of the height ranges.
struct SpikeDem {
  static constexpr int kN = 65;
  static constexpr double kSpacing = 10.0;
  int sx, sy;
  std::vector<float> z;
  SpikeDem(int x, int y, bool dip = false) : sx(x), sy(y), z(static_cast<size_t>(kN) * kN, 100.0f) {
    z[static_cast<size_t>(y) * kN + static_cast<size_t>(x)] = 108.0f;
    if (dip) z[static_cast<size_t>(60) * kN + 60] = 90.0f;
  }
};

// errorPx of a diamond with error e at distance d for view v, as roam.h defines it, with the same
// arithmetic as the library (the field of view read at run time, so tan is not folded at compile time).
double errorPx(double e, const RoamView& v, double d) {
  volatile double fovY = v.camera.fovY_deg;
  const double scale = v.viewportHeight_px / (2.0 * std::tan(0.5 * fovY * (3.14159265358979323846 / 180.0)));
  return e * scale / d;
}

}  // namespace

// RoamConfig::nodeCapacity: 0 = 2 * maxTriangles + the base triangles; raised to 2 * base.
TEST(RoamMutation, PoolCapacityFollowsTheConfig) {
  const auto hts = test::fractalHeights(100, 37, 3);
  const Roam roam(hts, 100, 37, 30.0, {0, 0, 0}, cap(1000));
  ASSERT_EQ(roam.baseTriangles(), 16u);
  EXPECT_EQ(roam.nodeCapacity(), 2 * 1000u + 16u);
  RoamConfig tiny = cap(1000);
  tiny.nodeCapacity = 3;
  Roam small(hts, 100, 37, 30.0, {0, 0, 0}, tiny);
  EXPECT_GE(small.nodeCapacity(), 2 * small.baseTriangles());
  const RoamStats st = small.update(makeView({1500, 500, 400}, 30, -20, 1.0), RoamMode::EnhMerge);
  EXPECT_TRUE(st.poolExhausted);
  EXPECT_LE(small.nodeCount(), small.nodeCapacity());
  EXPECT_VALID(small);
}

// The selection rule exactly, for a square diamond (box half size 3h) and an axis diamond (2h):
// with the eye level with the spike, east of the box, the spike's vertex is in the mesh iff
// errorPx > tolerance, i.e. iff the eye is nearer than e * scale / tolerance.
TEST(RoamMutation, SplitDistanceFollowsTheErrorAndTheBox) {
  struct Case {
    int x, y, boxEastX;  // spike sample; east edge of its diamond's box (samples)
  };
  // (20, 20): square diamond, half side 4, box x in [8, 32]; (20, 16): axis diamond with a
  // horizontal hypotenuse of half length 4, box x in [12, 28].
  for (const Case& c : {Case{20, 20, 32}, Case{20, 16, 28}}) {
    const SpikeDem dem(c.x, c.y);
    for (RoamMode mode : kAllModes) {
      RoamView v = makeView({0, 0, 0}, 270.0, 0.0, 20.0);  // looking west, at the box
      const double threshold = 8.0 * errorPx(1.0, v, 1.0) / v.tolerance_px;  // ~374 m
      for (const auto& [factor, split] : {std::pair{0.98, true}, {1.02, false}, {0.9, true}, {1.1, false}}) {
        Roam roam(dem.z, SpikeDem::kN, SpikeDem::kN, SpikeDem::kSpacing, {0, 0, 0}, cap(100000));
        v.camera.eye_m = {c.boxEastX * SpikeDem::kSpacing + factor * threshold, c.y * SpikeDem::kSpacing, 104.0};
        const RoamStats st = roam.update(v, mode);
        EXPECT_TRUE(st.finished);
        EXPECT_EQ(hasVertex(roam, c.x, c.y), split) << "spike (" << c.x << "," << c.y << ") " << modeName(mode)
                                                    << " at " << factor << " x the split distance";
        EXPECT_VALID(roam);
      }
    }
  }
}

// errorPx == tolerance_px is not split, and a split diamond at errorPx == tolerance_px is merged
// (split if > tolerance, merged if <=), whether the tolerance or the eye moved there.
TEST(RoamMutation, ErrorEqualToTheToleranceIsNotSplitAndIsMerged) {
  const SpikeDem dem(20, 20);
  const double boxEast_m = 320.0;  // the spike's diamond box: x in [80, 320] m
  for (RoamMode mode : kAllModes) {
    Roam roam(dem.z, SpikeDem::kN, SpikeDem::kN, SpikeDem::kSpacing, {0, 0, 0}, cap(100000));
    RoamView v = makeView({boxEast_m + 400.0, 200.0, 104.0}, 270.0, 0.0, 1.0);
    const double tie = errorPx(8.0, v, 400.0);  // errorPx of the spike's diamond
    v.tolerance_px = tie;
    roam.update(v, mode);
    EXPECT_FALSE(hasVertex(roam, 20, 20)) << modeName(mode) << ": split at errorPx == tolerance";
    v.tolerance_px = std::nextafter(tie, 0.0);
    roam.update(v, mode);
    EXPECT_TRUE(hasVertex(roam, 20, 20)) << modeName(mode) << ": not split at errorPx > tolerance";
    v.tolerance_px = tie;
    roam.update(v, mode);
    EXPECT_FALSE(hasVertex(roam, 20, 20)) << modeName(mode) << ": not merged at errorPx == tolerance";
    // The eye moves onto the threshold at a fixed tolerance (Deferred: the schedule brings the
    // diamond up again): from nearer (split) and from farther (not split).
    v.camera.eye_m.x = boxEast_m + 300.0;
    roam.update(v, mode);
    EXPECT_TRUE(hasVertex(roam, 20, 20)) << modeName(mode);
    v.camera.eye_m.x = boxEast_m + 400.0;
    roam.update(v, mode);
    EXPECT_FALSE(hasVertex(roam, 20, 20)) << modeName(mode) << ": not merged after moving onto the threshold";
    v.camera.eye_m.x = boxEast_m + 500.0;
    roam.update(v, mode);
    EXPECT_FALSE(hasVertex(roam, 20, 20)) << modeName(mode);
    v.camera.eye_m.x = boxEast_m + 400.0;
    roam.update(v, mode);
    EXPECT_FALSE(hasVertex(roam, 20, 20)) << modeName(mode) << ": split after moving onto the threshold";
    EXPECT_VALID(roam);
  }
}

// With the eye inside a diamond's box its errorPx is infinite: split whatever the tolerance.
// The box holds all the geometry the diamond's descendants can emit, so an eye on that surface
// (the flat ground beside the spike, the spike's top) is inside it too.
TEST(RoamMutation, EyeInsideTheBoxSplitsWhateverTheTolerance) {
  const SpikeDem dem(20, 20, true);
  // The spike's diamond covers [160, 240]^2 m, at 100 m but for the spike.
  for (const glm::dvec3 eye : {glm::dvec3(230.0, 190.0, 104.0), glm::dvec3(180.0, 200.0, 100.0), glm::dvec3(200.0, 200.0, 108.0)}) {
    for (RoamMode mode : kAllModes) {
      Roam roam(dem.z, SpikeDem::kN, SpikeDem::kN, SpikeDem::kSpacing, {0, 0, 0}, cap(100000));
      const RoamView v = makeView(eye, 0.0, -10.0, 1e12);
      EXPECT_TRUE(roam.update(v, mode).finished);
      EXPECT_TRUE(hasVertex(roam, 20, 20)) << modeName(mode) << " eye " << eye.x << "," << eye.y << "," << eye.z;
    }
  }
}

// Tolerance 0: every diamond with errorPx > 0 is split, none with errorPx 0 (flat ground, or
// outside the frustum in the modes that cull), and split ones at errorPx 0 are merged.
TEST(RoamMutation, ZeroToleranceSplitsOnlyDiamondsWithAnError) {
  const int n = 33;
  const std::vector<float> flat(static_cast<size_t>(n) * n, 50.0f);
  const SpikeDem dem(20, 20);
  for (RoamMode mode : kAllModes) {
    Roam level(flat, n, n, 10.0, {0, 0, 0}, cap(100000));
    const RoamStats st = level.update(makeView({160, 100, 80}, 0, -30, 0.0), mode);
    EXPECT_EQ(st.splits, 0u) << modeName(mode);
    EXPECT_EQ(level.triangleCount(), level.baseTriangles()) << modeName(mode);
    Roam roam(dem.z, SpikeDem::kN, SpikeDem::kN, SpikeDem::kSpacing, {0, 0, 0}, cap(100000));
    RoamView v = makeView({720.0, 200.0, 104.0}, 270.0, 0.0, 0.0);  // towards the spike
    roam.update(v, mode);
    EXPECT_TRUE(hasVertex(roam, 20, 20)) << modeName(mode);
    if (mode == RoamMode::Deferred) continue;  // ignores the frustum
    v.camera.heading_deg = 90.0;  // away from the DEM: every errorPx is 0
    roam.update(v, mode);
    EXPECT_EQ(roam.triangleCount(), roam.baseTriangles()) << modeName(mode);
    EXPECT_VALID(roam);
  }
}

// A split that makes the mesh exactly maxTriangles leaves, or fills the pool exactly, is made.
TEST(RoamMutation, SplitsThatFitExactlyAreMade) {
  const int n = 129;
  const auto hts = test::fractalHeights(n, n, 8);
  const RoamView v = makeView({1000, 1000, 400}, 45, -20, 1.0);
  for (RoamMode mode : {RoamMode::EnhMerge, RoamMode::MergeQueue, RoamMode::Rebuild, RoamMode::Deferred}) {
    Roam free(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
    free.update(v, mode);
    const auto ref = sortedTriangles(free);
    Roam capped(hts, n, n, 30.0, {0, 0, 0}, cap(free.triangleCount()));
    RoamStats st = capped.update(v, mode);
    EXPECT_FALSE(st.triangleCapped) << modeName(mode);
    EXPECT_EQ(sortedTriangles(capped), ref) << modeName(mode);
    RoamView vc = v;
    vc.maxTriangles = free.triangleCount();
    Roam viewCapped(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
    st = viewCapped.update(vc, mode);
    EXPECT_FALSE(st.triangleCapped) << modeName(mode);
    EXPECT_EQ(sortedTriangles(viewCapped), ref) << modeName(mode);
    RoamConfig pool = cap(200000);
    pool.nodeCapacity = free.nodeCount();  // a fresh mesh only grows during its first update
    Roam pooled(hts, n, n, 30.0, {0, 0, 0}, pool);
    st = pooled.update(v, mode);
    EXPECT_FALSE(st.poolExhausted) << modeName(mode);
    EXPECT_EQ(sortedTriangles(pooled), ref) << modeName(mode);
  }
}

// RoamView::maxTriangles may lower RoamConfig::maxTriangles, not raise it; lowered under a still
// camera (no split wanted), the mesh is merged down to it and the cap is reported.
TEST(RoamMutation, ViewTriangleTargetLowersButCannotRaiseTheCap) {
  const int n = 129;
  const auto hts = test::fractalHeights(n, n, 8);
  for (RoamMode mode : kAllModes) {
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, cap(1000));
    RoamView v = makeView({1000, 1000, 400}, 45, -20, 0.25);
    v.maxTriangles = 5000;
    RoamStats st = roam.update(v, mode);
    EXPECT_TRUE(st.triangleCapped) << modeName(mode);
    EXPECT_LE(st.triangles, 1000u) << modeName(mode);
    EXPECT_EQ(roam.triangleCap(), 1000u);
    Roam still(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
    v.tolerance_px = 1.0;
    v.maxTriangles = 0;
    still.update(v, mode);
    const uint64_t full = still.triangleCount();
    ASSERT_GT(full, 1000u);
    v.maxTriangles = full / 2;
    st = still.update(v, mode);
    EXPECT_LE(st.triangles, full / 2) << modeName(mode);
    EXPECT_TRUE(st.triangleCapped) << modeName(mode);
    EXPECT_VALID(still);
  }
}

// maxVisits and stop are Deferred only: the other modes finish whatever they say.
TEST(RoamMutation, VisitBudgetAndStopAreDeferredOnly) {
  const int n = 129;
  const auto hts = test::fractalHeights(n, n, 8);
  for (RoamMode mode : {RoamMode::EnhMerge, RoamMode::MergeQueue, RoamMode::Rebuild}) {
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
    Roam reference(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
    RoamView v = makeView({1000, 1000, 400}, 45, -20, 1.0);
    reference.update(v, mode);
    v.maxVisits = 1;
    v.stop = [](void*) { return true; };
    EXPECT_TRUE(roam.update(v, mode).finished) << modeName(mode);
    EXPECT_EQ(sortedTriangles(roam), sortedTriangles(reference)) << modeName(mode);
  }
}

// Splits go highest errorPx first: under a cap of N triangles the mesh reaches at least the
// refined mesh of any tolerance T whose mesh has <= N triangles, so every leaf is within T.
TEST(RoamMutation, CappedMeshKeepsTheLargestErrorsSplit) {
  const int n = 129;
  const auto hts = test::fractalHeights(n, n, 8);
  const RoamView fine = makeView({1000, 1000, 400}, 45, -20, 0.25);
  for (RoamMode mode : {RoamMode::EnhMerge, RoamMode::MergeQueue, RoamMode::Rebuild}) {
    for (double t : {4.0, 2.0, 1.0}) {
      RoamView coarse = fine;
      coarse.tolerance_px = t;
      Roam free(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
      free.update(coarse, mode);
      Roam capped(hts, n, n, 30.0, {0, 0, 0}, cap(free.triangleCount()));
      const RoamStats st = capped.update(fine, mode);
      ASSERT_TRUE(st.triangleCapped);
      EXPECT_LE(capped.maxErrorPx(fine), t) << modeName(mode) << " T " << t;
      EXPECT_VALID(capped);
    }
  }
}

// RoamStats::maxErrorPx is an upper bound on errorPx of the leaves: also while the triangle cap
// binds (and is lowered), when the work budget interrupts an update, and in Deferred.
TEST(RoamMutation, StatsMaxErrorBoundsTheLeaves) {
  const int n = 129;
  const auto hts = test::fractalHeights(n, n, 8);
  for (RoamMode mode : kAllModes) {
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
    const auto path = shortFlight(0.5);
    for (size_t f = 0; f < path.size(); ++f) {
      RoamView v = path[f];
      v.maxTriangles = f < 6 ? 3000 : 1500;
      const RoamStats st = roam.update(v, mode);
      EXPECT_GE(st.maxErrorPx, roam.maxErrorPx(v)) << modeName(mode) << " capped, frame " << f;
    }
    Roam free(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
    for (size_t f = 0; f < path.size(); ++f) {
      const RoamStats st = free.update(path[f], mode);
      EXPECT_GE(st.maxErrorPx, free.maxErrorPx(path[f])) << modeName(mode) << " frame " << f;
    }
    Roam budget(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
    for (size_t f = 0; f < path.size(); ++f) {
      RoamView v = path[f];
      v.maxOperations = 7;
      for (int i = 0; i < 3; ++i) {
        const RoamStats st = budget.update(v, mode);
        EXPECT_GE(st.maxErrorPx, budget.maxErrorPx(v)) << modeName(mode) << " budget, frame " << f;
      }
    }
  }
}

// Nodes: after == before + 2 * created vertices (one per split half) - nodes freed; removed
// vertices: one per merged diamond, exactly the vertices a pure coarsening takes out of the mesh.
TEST(RoamMutation, NodesFreedAndVertexListsBalanceTheMesh) {
  const int n = 129;
  const auto hts = test::fractalHeights(n, n, 8);
  for (RoamMode mode : kAllModes) {
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
    for (const RoamView& v : shortFlight(1.0)) {
      const size_t before = roam.nodeCount();
      const RoamStats st = roam.update(v, mode);
      ASSERT_LT(roam.createdVertices().size(), Roam::kCreatedCapacity);
      EXPECT_EQ(roam.nodeCount() + st.nodesFreed, before + 2 * roam.createdVertices().size()) << modeName(mode);
      if (mode == RoamMode::MergeQueue) { EXPECT_EQ(roam.removedVertices().size(), st.merges); }
    }
    if (mode == RoamMode::Rebuild) continue;  // Rebuild starts from the base: nothing is merged
    // Pure coarsening: from near the ground to high above, looking off the DEM.
    roam.update(makeView({1900, 1900, 300}, 45, -20, 1.0), mode);
    const auto before = meshVertices(roam);
    const RoamStats st = roam.update(makeView({1900, 1900, 3000}, 45, 45, 1.0), mode);
    ASSERT_EQ(st.splits, 0u) << modeName(mode);
    ASSERT_GT(st.nodesFreed, 100u) << modeName(mode);
    const auto after = meshVertices(roam);
    std::set<std::pair<int, int>> gone, removed;
    for (const auto& p : before)
      if (!after.count(p)) gone.insert(p);
    for (const RoamVertex& r : roam.removedVertices()) EXPECT_TRUE(removed.emplace(r.x, r.y).second) << modeName(mode);
    EXPECT_EQ(removed, gone) << modeName(mode);
    // EnhMerge: only the top-most unneeded node of a subtree is enhMerged; looking off the DEM
    // that is the one base diamond (129 x 129: one base square).
    if (mode == RoamMode::EnhMerge) {
      EXPECT_EQ(roam.triangleCount(), roam.baseTriangles());
      EXPECT_EQ(st.enhMerges, 1u);
      EXPECT_EQ(st.merges, 0u);
    }
  }
}

// RoamView::maxVisits counts nodes examined + nodes created + nodes freed; RoamStats::visits is
// what an update under a visit budget spent (one that did not restart from the base triangles:
// the restart hands the pool back wholesale).
TEST(RoamMutation, DeferredVisitsAreNodesExaminedCreatedAndFreed) {
  const int n = 129;
  const auto hts = test::fractalHeights(n, n, 8);
  Roam roam(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
  int withCreated = 0, withFreed = 0;
  for (const RoamView& path : shortFlight(1.0)) {
    RoamView v = path;
    v.maxVisits = 300;
    for (int i = 0; i < 3; ++i) {
      const size_t before = roam.nodeCount();
      const RoamStats st = roam.update(v, RoamMode::Deferred);
      if (st.restarted) continue;
      const size_t created = 2 * roam.createdVertices().size();
      ASSERT_EQ(roam.nodeCount() + st.nodesFreed, before + created);
      EXPECT_EQ(st.visits, st.nodesExamined + created + st.nodesFreed);
      withCreated += created > 0;
      withFreed += st.nodesFreed > 0;
    }
  }
  EXPECT_GT(withCreated, 3);
  EXPECT_GT(withFreed, 2);
  // The same without a visit budget, whose first update and teleports walk every node (igd's
  // time per visit is learned from these counts, with or without a budget).
  {
    Roam open(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
    int walks = 0;
    for (const RoamView& path : shortFlight(1.0)) {
      const size_t before = open.nodeCount();
      const RoamStats st = open.update(path, RoamMode::Deferred);
      const size_t created = 2 * open.createdVertices().size();
      ASSERT_EQ(open.nodeCount() + st.nodesFreed, before + created);
      EXPECT_EQ(st.visits, st.nodesExamined + created + st.nodesFreed);
      walks += st.nodesExamined >= before;
    }
    EXPECT_GT(walks, 0);
  }
  // An operation starts only while visits are left: with maxVisits = 1 the one visit goes to
  // looking at a node and no split or merge ever starts; with more, an update without an
  // operation spends at most maxVisits.
  for (uint32_t budget : {1u, 2u, 3u}) {
    Roam small(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
    for (const RoamView& path : shortFlight(1.0)) {
      RoamView v = path;
      v.maxVisits = budget;
      for (int i = 0; i < 20; ++i) {
        const RoamStats st = small.update(v, RoamMode::Deferred);
        const uint32_t ops = st.splits + st.merges + st.enhMerges;
        if (budget == 1) {
          EXPECT_EQ(ops, 0u);
        }
        if (ops == 0) {
          EXPECT_LE(st.visits, budget);
        }
      }
    }
  }
}

// stats.maxErrorPx counts a diamond that enhMerge just made a leaf: a spike on the west border
// (a diamond without a partner), merged when the tolerance rises above its errorPx while its
// parent's stays above.
TEST(RoamMutation, StatsMaxErrorCountsALeafJustEnhMerged) {
  const SpikeDem dem(0, 20);  // vertical hypotenuse (0, 16)-(0, 24) on the border; box y in [120, 280] m
  for (RoamMode mode : {RoamMode::EnhMerge, RoamMode::Deferred}) {
    Roam roam(dem.z, SpikeDem::kN, SpikeDem::kN, SpikeDem::kSpacing, {0, 0, 0}, cap(100000));
    RoamView v = makeView({40.0, 0.0, 104.0}, 0.0, 0.0, 1.0);  // south of it, looking north
    const double p = errorPx(8.0, v, 120.0);  // its parent's box reaches y = 80 m: 1.5 p
    v.tolerance_px = 0.5 * p;
    roam.update(v, mode);
    ASSERT_TRUE(hasVertex(roam, 0, 20)) << modeName(mode);
    v.tolerance_px = 1.2 * p;
    const RoamStats st = roam.update(v, mode);
    ASSERT_FALSE(hasVertex(roam, 0, 20)) << modeName(mode);
    EXPECT_GE(st.enhMerges, 1u);
    EXPECT_DOUBLE_EQ(roam.maxErrorPx(v), p) << modeName(mode);
    EXPECT_GE(st.maxErrorPx, roam.maxErrorPx(v)) << modeName(mode);
  }
}

// The leaf log: replaying it and reading each logged node's state gives the current leaves;
// leafLogReset() when it cannot (just enabled, or the mesh restarted from the base).
TEST(RoamMutation, LeafLogReplaysToTheCurrentLeaves) {
  const int n = 129;
  const auto hts = test::fractalHeights(n, n, 8);
  for (RoamMode mode : kAllModes) {
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, cap(200000));
    roam.update(makeView({500, 500, 600}, 30, -20, 2.0), mode);
    roam.clearLeafLog();  // (the log is off: clearing it is allowed and changes nothing)
    roam.enableLeafLog(1u << 20);
    EXPECT_TRUE(roam.leafLogReset()) << modeName(mode) << ": just enabled";
    std::set<uint32_t> leaves;
    auto readAll = [&] {
      std::vector<uint32_t> ids(roam.triangleCount());
      ids.resize(roam.emitLeafNodes(ids));
      return std::set<uint32_t>(ids.begin(), ids.end());
    };
    int resets = 0;
    for (const RoamView& v : shortFlight(1.0)) {
      if (roam.leafLogReset()) {
        ++resets;
        leaves = readAll();
      } else {
        std::set<uint32_t> logged;
        for (uint32_t e : roam.leafLog()) logged.insert(e & ~Roam::kLeafRemoved);
        RoamTriangle t;
        for (uint32_t id : logged) {
          if (roam.leafTriangle(id, &t)) leaves.insert(id);
          else leaves.erase(id);
        }
        EXPECT_EQ(leaves, readAll()) << modeName(mode);
      }
      roam.clearLeafLog();
      roam.update(v, mode);
    }
    if (mode == RoamMode::Rebuild) { EXPECT_TRUE(roam.leafLogReset()) << "Rebuild restarts from the base"; }
    EXPECT_GE(resets, 1);
  }
}

// Deferred lateness trades triangles for re-examinations, never the tolerance: every leaf
// stays within tolerance_px, and smooth flight looks at fewer nodes than without lateness.
TEST(RoamMutation, DeferredLatenessKeepsEveryLeafWithinTheTolerance) {
  const int n = 129;
  const auto hts = test::fractalHeights(n, n, 8);
  uint64_t examined[2] = {0, 0};
  for (int late = 0; late < 2; ++late) {
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, cap(400000));
    for (int i = 0; i < 40; ++i) {
      RoamView v = makeView({600.0 + 40.0 * i, 500.0 + 30.0 * i, 450.0}, 40.0, -20.0, 1.0);
      v.lateness = late ? 0.5 : 0.0;
      const RoamStats st = roam.update(v, RoamMode::Deferred);
      ASSERT_TRUE(st.finished);
      EXPECT_LE(roam.maxErrorPx(v), v.tolerance_px) << "lateness " << v.lateness << " update " << i;
      if (i > 0) examined[late] += st.nodesExamined;
    }
  }
  EXPECT_LT(examined[1], examined[0]);
}

// splitEnds: false for vertices off the padded grid.
TEST(RoamMutation, SplitEndsIsFalseOffThePaddedGrid) {
  const auto hts = test::fractalHeights(100, 37, 3);
  const Roam roam(hts, 100, 37, 30.0, {0, 0, 0}, cap(1000));
  RoamVertex a, b;
  const int px = roam.gridWidth(), py = roam.gridHeight();
  EXPECT_TRUE(roam.splitEnds(px - 2, 1, a, b));
  EXPECT_FALSE(roam.splitEnds(px, 1, a, b));
  EXPECT_FALSE(roam.splitEnds(1, py, a, b));
  EXPECT_FALSE(roam.splitEnds(px + 1, py + 1, a, b));
  EXPECT_FALSE(roam.splitEnds(-1, 1, a, b));
  EXPECT_FALSE(roam.splitEnds(1, -1, a, b));
}

// leafAt: the leaf holding the point, also on the east and north edges of the padded grid.
TEST(RoamMutation, LeafAtHoldsPointsOnThePaddedGridsEdges) {
  const auto hts = test::fractalHeights(100, 37, 3);
  Roam roam(hts, 100, 37, 30.0, {0, 0, 0}, cap(100000));
  roam.update(makeView({2000, 500, 600}, 60, -30, 2.0), RoamMode::EnhMerge);
  const int64_t ex = 3 * static_cast<int64_t>(roam.gridWidth() - 1), ny = 3 * static_cast<int64_t>(roam.gridHeight() - 1);
  std::vector<std::pair<int64_t, int64_t>> points;
  for (int64_t t = 0; t <= ex; t += 7) points.emplace_back(t, ny);
  for (int64_t t = 0; t <= ny; t += 5) points.emplace_back(ex, t);
  for (const auto& [x3, y3] : points) {
    const RoamTriangle t = roam.leafAt(x3, y3);
    for (int k = 0; k < 3; ++k) {
      const RoamVertex& a = t.v[k];
      const RoamVertex& b = t.v[(k + 1) % 3];
      const int64_t side = (3 * int64_t{b.x} - 3 * int64_t{a.x}) * (y3 - 3 * int64_t{a.y}) -
                           (3 * int64_t{b.y} - 3 * int64_t{a.y}) * (x3 - 3 * int64_t{a.x});
      EXPECT_GE(side, 0) << "point (" << x3 << "/3, " << y3 << "/3) outside the leaf leafAt returns";
    }
  }
}

// nearestTriangleBox stops once the distance is below `enough`: equal to it is not below.
TEST(RoamMutation, NearestTriangleBoxGoesOnWhileTheDistanceEqualsEnough) {
  std::vector<float> h(16, 5.0f);
  h[15] = 50.0f;
  const std::vector<RoamTriangle> tris = {
      {{{0, 0}, {1, 0}, {0, 1}}},  // box [0, 10] x [0, 10] x [5, 5]: 100 m below the point
      {{{2, 2}, {3, 2}, {3, 3}}},  // box [20, 30] x [20, 30] x [5, 50]: nearer
  };
  const glm::dvec3 above(5.0, 5.0, 105.0);
  EXPECT_LT(nearestTriangleBox(tris, h, 4, 4, 10.0, above, 100.0), 100.0);
  EXPECT_DOUBLE_EQ(nearestTriangleBox(tris, h, 4, 4, 10.0, above, 100.0), std::sqrt(15.0 * 15.0 + 15.0 * 15.0 + 55.0 * 55.0));
}

// Deferred after a teleport under a visit budget refines visible leaves first: the view is
// within tolerance updates before the whole surroundings are.
TEST(RoamMutation, DeferredRestartRefinesTheViewFirst) {
  const int n = 129;
  const auto hts = test::fractalHeights(n, n, 3, 900.0);
  Roam roam(hts, n, n, 30.0, {0, 0, 0}, cap(400000));
  RoamView v = makeView({1900, 1900, 1000}, 30.0, -20.0, 1.0);
  v.maxVisits = 300;
  for (int i = 0; i < 2000 && !roam.update(v, RoamMode::Deferred).finished; ++i) {
  }
  v.camera.eye_m = {300, 300, 800};
  v.camera.heading_deg = 45.0;
  int viewDone = -1, updates = 0;
  RoamStats st = roam.update(v, RoamMode::Deferred);
  ASSERT_TRUE(st.restarted);
  for (; !st.finished && updates < 2000; ++updates) {
    if (viewDone < 0 && roam.maxErrorPx(v) <= v.tolerance_px) viewDone = updates;
    st = roam.update(v, RoamMode::Deferred);
  }
  ASSERT_TRUE(st.finished);
  std::printf("[ restart ] view within tolerance after %d updates, all after %d\n", viewDone, updates);
  ASSERT_GE(viewDone, 0) << "the view was within tolerance only once everything was";
  EXPECT_LE(viewDone + 4, updates);
}
