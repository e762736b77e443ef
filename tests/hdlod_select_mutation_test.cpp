// lod/hdlod_select: what a mutation pass over the selection found the other tests leave open
// (hdlod_tree_test and hard_cases_test still pass when it is changed). Pinned down here, from the
// contract in hdlod_select.h / hdlod_build.h: every bad camera field the header lists is
// rejected (field of view 180 and above, a non-positive aspect, a near plane at or behind the
// eye, an infinite far plane, NaN attitude, a bad window shift); selectAll() ignores r (no
// merged cluster, no coarser model version); a leaf drawn at a coarser model version counts that
// version's triangles in the stats; a cluster whose f_c has no steps is absent; records of
// another (larger) tree are stale and select nothing; presence read through the bucket table of
// a long step function is exact at and next to every bucket start; drawBound() / movingBound()
// are exactly the leaves plus merged clusters / the dynamic leaves; toleranceFromPixels()'s value;
// the stats' visited and culled counts (a moving object culled where it is at t); an empty scene
// selects nothing and is not reported as rejected.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "lod/hdlod_build.h"
#include "lod/hdlod_select.h"
#include "lod/hdlod_site.h"
#include "hdlod_fixtures.h"

using namespace ig::lod;
using namespace ig::lod::hdlod;

namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

using ig::lod::hdlod::test::placed;
using ig::lod::hdlod::test::viewOf;

Scene smallSite() {
  SiteParams p;
  p.scale = 0.05;
  p.loadsPerFloor = 40;
  std::string error;
  Scene s = makeConstructionSite(p, error);
  EXPECT_EQ(error, "");
  return s;
}

// A bumpy n x n grid of quads (2 n^2 triangles, more than modelLodMinTriangles): the build gives
// it coarser versions with growing eps.
Model bumpyGrid(int n) {
  Model m;
  m.name = "grid";
  for (int y = 0; y <= n; ++y)
    for (int x = 0; x <= n; ++x)
      m.positions.push_back(glm::vec3(static_cast<float>(x), static_cast<float>(y), static_cast<float>(0.3 * std::sin(1.7 * x) * std::cos(1.3 * y))));
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      const uint32_t a = static_cast<uint32_t>(y * (n + 1) + x), b = a + 1, c = a + static_cast<uint32_t>(n + 1), d = c + 1;
      m.indices.insert(m.indices.end(), {a, b, d, a, d, c});
    }
  m.box = Aabb{glm::dvec3(0, 0, -0.3), glm::dvec3(n, n, 0.3)};
  return m;
}

}  // namespace

// hdlod_select.h: a field of view outside (0, 180) degrees, a non-positive aspect, not
// 0 < near < far (an infinite far plane included: the camera must be finite), a NaN attitude
// angle or a window shift the camera validators refuse selects nothing and sets rejected, in
// both selections. BadInputSelectsNothing covers fov 0, near == far, NaN eye / heading / time.
TEST(HdlodSelectMutation, EveryBadCameraFieldIsRejected) {
  Scene s;
  s.duration_s = 10;
  s.models.push_back(makeBoxModel("b", {1, 1, 1}));
  s.objects.push_back(placed("A", 0, {0, 0, 0}, {{0, 10}}));
  const HdlodTree tree = buildHdlod(s);
  DrawList out(tree);
  SelectStats st;
  const SelectView good = viewOf({0, 0, 0}, 20, 5, 0.0);
  ASSERT_EQ(selectHdlod(tree, s, good, out, &st), 1u);
  ASSERT_FALSE(st.rejected);
  struct Case {
    const char* what;
    void (*bad)(SelectView&);
  };
  const Case cases[] = {
      {"fov 180", [](SelectView& v) { v.camera.fovY_deg = 180; }},
      {"fov 270", [](SelectView& v) { v.camera.fovY_deg = 270; }},
      {"fov -10", [](SelectView& v) { v.camera.fovY_deg = -10; }},
      {"aspect 0", [](SelectView& v) { v.camera.aspect = 0; }},
      {"aspect -1", [](SelectView& v) { v.camera.aspect = -1; }},
      {"aspect inf", [](SelectView& v) { v.camera.aspect = kInf; }},
      {"near 0", [](SelectView& v) { v.camera.near_m = 0; }},
      {"near -1", [](SelectView& v) { v.camera.near_m = -1; }},
      {"far inf", [](SelectView& v) { v.camera.far_m = kInf; }},
      {"far < near", [](SelectView& v) { v.camera.far_m = 0.05; }},
      {"pitch NaN", [](SelectView& v) { v.camera.pitch_deg = kNan; }},
      {"roll NaN", [](SelectView& v) { v.camera.roll_deg = kNan; }},
      {"time +inf", [](SelectView& v) { v.time_s = kInf; }},
      {"shiftX NaN", [](SelectView& v) { v.camera.shiftX = kNan; }},
      {"shiftY 1000", [](SelectView& v) { v.camera.shiftY = 1000; }},
  };
  for (const Case& c : cases) {
    SelectView v = good;
    c.bad(v);
    st = SelectStats{};
    EXPECT_EQ(selectHdlod(tree, s, v, out, &st), 0u) << c.what;
    EXPECT_TRUE(st.rejected) << c.what;
    EXPECT_EQ(st.draws, 0u) << c.what;
    st = SelectStats{};
    EXPECT_EQ(selectAll(tree, s, v, out, &st), 0u) << c.what;
    EXPECT_TRUE(st.rejected) << c.what;
  }
}

// selectAll() is the baseline without HDLOD: "every present object whose box is in the
// frustum (r is ignored)". With a tolerance that would make the top clusters good enough and
// every model version acceptable, it draws the same leaves, all at version 0, as with r = 0,
// and no merged cluster.
TEST(HdlodSelectMutation, SelectAllIgnoresTheTolerance) {
  const Scene s = smallSite();
  const HdlodTree tree = buildHdlod(s);
  ASSERT_GT(tree.stats.mergedClusters, 0u);
  ASSERT_GT(tree.modelLods.size(), 0u);  // versions exist to be (wrongly) chosen
  const Cluster& root = tree.clusters[tree.root];
  const glm::dvec3 centre = 0.5 * (root.box.min + root.box.max);
  const double R = 0.5 * glm::length(root.box.max - root.box.min);
  DrawList exact(tree), coarse(tree), hdlod(tree);
  for (const double t : {0.5 * s.duration_s, s.duration_s}) {
    SelectStats stExact, stCoarse;
    const size_t n0 = selectAll(tree, s, viewOf(centre, 3 * R, t, 0.0), exact, &stExact);
    const size_t n1 = selectAll(tree, s, viewOf(centre, 3 * R, t, 1.0), coarse, &stCoarse);
    ASSERT_GT(n0, 0u);
    ASSERT_EQ(n1, n0) << t;
    EXPECT_EQ(stCoarse.triangles, stExact.triangles) << t;
    for (size_t i = 0; i < n1; ++i) {
      EXPECT_EQ(coarse.draws[i].cluster, exact.draws[i].cluster) << i;
      EXPECT_EQ(coarse.draws[i].lod, 0u) << i;
      EXPECT_NE(tree.clusters[coarse.draws[i].cluster].kind, ClusterKind::Merged) << i;
    }
    // The same view through selectHdlod() does coarsen: the tolerance was not idle.
    SelectStats stHdlod;
    selectHdlod(tree, s, viewOf(centre, 3 * R, t, 1.0), hdlod, &stHdlod);
    EXPECT_LT(stHdlod.triangles, stExact.triangles) << t;
  }
}

// A leaf is drawn with "the coarsest version of its model whose measured eps < r * distance":
// with r * distance between two versions' eps the draw names the coarser one, and the stats
// count that version's triangles (SelectStats::triangles: "of the selected draws"), not the
// model's.
TEST(HdlodSelectMutation, LeafAtACoarserVersionCountsThatVersionsTriangles) {
  Scene s;
  s.duration_s = 10;
  s.models.push_back(bumpyGrid(12));
  s.objects.push_back(placed("grid", 0, {0, 0, 0}, {{0, 10}}));
  const HdlodTree tree = buildHdlod(s);
  const uint32_t leaf = tree.objectCluster[0];
  ASSERT_NE(leaf, ~0u);
  const Cluster& c = tree.clusters[leaf];
  const auto lods = tree.lodsOf(c.mesh);
  ASSERT_GE(lods.size(), 2u);
  const SelectView base = viewOf(0.5 * (c.box.min + c.box.max), 50, 5, 0.0);
  const double d = distanceToBox(c.box, base.camera.eye_m);
  ASSERT_GT(d, 1.0);
  DrawList out(tree);
  SelectStats st;
  ASSERT_EQ(selectHdlod(tree, s, base, out, &st), 1u);
  EXPECT_EQ(out.draws[0].lod, 0u);
  EXPECT_EQ(st.triangles, c.triangles);
  for (size_t k = 0; k + 1 < lods.size(); ++k) {
    if (!(lods[k].eps_m < lods[k + 1].eps_m) || lods[k].triangles == c.triangles) continue;
    SelectView v = base;
    v.tolerance_rad = 0.5 * (lods[k].eps_m + lods[k + 1].eps_m) / d;  // eps_k < r d < eps_k+1
    ASSERT_EQ(selectHdlod(tree, s, v, out, &st), 1u) << k;
    EXPECT_EQ(out.draws[0].cluster, leaf);
    EXPECT_EQ(out.draws[0].lod, k + 1) << k;
    EXPECT_EQ(st.triangles, lods[k].triangles) << k;
  }
}

// f_c with no steps is 0 (clusterPresence), and f_c(t) == 0 skips the subtree: a leaf whose
// step function is emptied after the build is never drawn, at any time, in either selection.
TEST(HdlodSelectMutation, ALeafWithoutStepsIsAbsent) {
  Scene s;
  s.duration_s = 10;
  s.models.push_back(makeBoxModel("b", {1, 1, 1}));
  s.objects.push_back(placed("A", 0, {0, 0, 0}, {{0, 10}}));
  s.objects.push_back(placed("B", 0, {3, 0, 0}, {{0, 10}}));
  HdlodTree tree = buildHdlod(s);
  const uint32_t b = tree.objectCluster[1];
  tree.clusters[b].stepCount = 0;
  ASSERT_EQ(clusterPresence(tree, tree.clusters[b], 5), 0.0);
  ASSERT_TRUE(prepareSelection(tree));
  DrawList out(tree);
  for (const double t : {0.0, 5.0, 10.0}) {
    ASSERT_EQ(selectAll(tree, s, viewOf({1.5, 0, 0}, 30, t, 0.0), out), 1u) << t;
    EXPECT_EQ(out.draws[0].cluster, tree.objectCluster[0]) << t;
    ASSERT_EQ(selectHdlod(tree, s, viewOf({1.5, 0, 0}, 30, t, 0.0), out), 1u) << t;
    EXPECT_EQ(out.draws[0].cluster, tree.objectCluster[0]) << t;
  }
}

// Records are one per entry of `children`, then the root's (hdlod_build.h): records derived
// from another, larger tree are stale, and the selection selects nothing rather than walking
// them (UnpreparedOrBrokenTreesSelectNothing covers records that are too few).
TEST(HdlodSelectMutation, RecordsOfALargerTreeAreStale) {
  Scene two;
  two.duration_s = 10;
  two.models.push_back(makeBoxModel("b", {1, 1, 1}));
  two.objects.push_back(placed("A", 0, {0, 0, 0}, {{0, 10}}));
  two.objects.push_back(placed("B", 0, {1.5, 0, 0}, {{0, 10}}));
  Scene many = two;
  for (int i = 0; i < 6; ++i) many.objects.push_back(placed("C" + std::to_string(i), 0, {3.0 + 1.5 * i, 0, 0}, {{0, 10}}));
  const HdlodTree small = buildHdlod(two), large = buildHdlod(many);
  ASSERT_GT(large.children.size(), small.children.size());
  HdlodTree stale = small;
  stale.selectRecords = large.selectRecords;
  stale.selectSteps = large.selectSteps;
  DrawList out(stale);
  const SelectView v = viewOf({0.75, 0, 0}, 30, 5, 0.0);
  ASSERT_EQ(selectHdlod(small, two, v, out), 2u);
  EXPECT_EQ(selectHdlod(stale, two, v, out), 0u);
  EXPECT_EQ(selectAll(stale, two, v, out), 0u);
}

// Long step functions (more than 16 steps) are read through a table of equal spans of [0, T];
// the presence there must equal isPresent() exactly at each span's start, where rounding may
// put t into the neighbouring span, and one ulp either side. Interval ends are placed on the
// span starts (b T / buckets) for several T.
TEST(HdlodSelectMutation, LongStepFunctionsAreExactAtEveryBucketStart) {
  size_t probes = 0;
  for (const double T : {1.0, 0.3, 7.3, 10.0 / 3.0, 3600.0, 86400.0 * 1.1, 1e6 / 7.0}) {
    Scene s;
    s.duration_s = T;
    s.models.push_back(makeBoxModel("b", {1, 1, 1}));
    // 2 k steps for k intervals: 20, 40, 80, 160 steps -> tables of 8, 16, 32, 64 buckets (and
    // multiples of them), the interval ends on span starts of each.
    std::vector<double> times;
    for (const int k : {10, 20, 40, 80}) {
      const int buckets = 2 * k;  // a multiple of the table's spans: every span start is an end
      std::vector<Interval> iv;
      for (int i = 0; i < k; ++i) {
        const double a = (2 * i + 1) * (T / buckets), b = i + 1 == k ? T : (2 * i + 2) * (T / buckets);
        iv.push_back({a, b});
        for (const double x : {a, b}) times.insert(times.end(), {x, std::nextafter(x, 0.0), std::nextafter(x, 2 * T)});
      }
      s.objects.push_back(placed("o" + std::to_string(k), 0, {3.0 * k, 0, 0}, iv));
    }
    for (int b = 0; b <= 256; ++b) {
      const double x = b * (T / 256);
      times.insert(times.end(), {x, std::nextafter(x, 0.0), std::nextafter(x, 2 * T)});
    }
    const HdlodTree tree = buildHdlod(s);
    for (uint32_t i = 0; i < s.objects.size(); ++i) ASSERT_GT(tree.clusters[tree.objectCluster[i]].stepCount, 16u);
    DrawList out(tree);
    for (const double t : times) {
      const size_t n = selectAll(tree, s, viewOf({120, 0, 0}, 500, t, 0.0), out);
      std::vector<uint32_t> got, want;
      for (size_t k = 0; k < n; ++k) got.push_back(out.draws[k].cluster);
      for (uint32_t i = 0; i < s.objects.size(); ++i)
        if (isPresent(s.objects[i], t, T)) want.push_back(tree.objectCluster[i]);
      std::sort(got.begin(), got.end());
      std::sort(want.begin(), want.end());
      ASSERT_EQ(got, want) << "T " << T << " t " << t;
      ++probes;
    }
  }
  EXPECT_GT(probes, 1000u);
}

// drawBound(): "the most draws any selection can produce (leaves + merged clusters)";
// movingBound(): the dynamic leaves. Both exactly, on the site (which has all three kinds): the
// DrawList is sized from them, and a bound that counts groups or static leaves as moving
// allocates for draws that cannot happen.
TEST(HdlodSelectMutation, BoundsCountExactlyLeavesMergedAndDynamic) {
  const Scene s = smallSite();
  const HdlodTree tree = buildHdlod(s);
  size_t leaves = 0, dynamic = 0;
  for (uint32_t c : tree.objectCluster) {
    if (c == ~0u) continue;
    ++leaves;
    dynamic += tree.clusters[c].kind == ClusterKind::Dynamic;
  }
  ASSERT_GT(dynamic, 0u);
  ASSERT_LT(dynamic, leaves);
  EXPECT_EQ(dynamic, tree.stats.dynamicObjects);
  EXPECT_EQ(drawBound(tree), leaves + tree.stats.mergedClusters);
  EXPECT_EQ(movingBound(tree), dynamic);
}

// r_px pixels at the centre of a viewport H pixels high with vertical field of view fov:
// r = r_px * 2 tan(fov / 2) / H (small angle).
TEST(HdlodSelectMutation, ToleranceFromPixelsValue) {
  EXPECT_NEAR(toleranceFromPixels(1.0, 90.0, 1000.0), 2.0 / 1000.0, 1e-15);
  EXPECT_NEAR(toleranceFromPixels(3.0, 60.0, 1080.0), 3.0 * 2.0 * std::tan(30.0 * M_PI / 180.0) / 1080.0, 1e-15);
  EXPECT_EQ(toleranceFromPixels(0.0, 60.0, 1080.0), 0.0);
}

// SelectStats: "visited: clusters whose f_c(t) was evaluated", "culled: skipped: outside the
// frustum". With everything present and in view, selectAll() evaluates every cluster. A moving
// object whose swept box is in view but which is elsewhere at t is culled (counted), not drawn;
// at the end of its path, in view, it is drawn.
TEST(HdlodSelectMutation, StatsCountVisitedClustersAndADynamicObjectCulledWhereItIsNow) {
  const double T = 10;
  Scene s;
  s.duration_s = T;
  s.models.push_back(makeBoxModel("b", {2, 2, 2}));
  for (int i = 0; i < 4; ++i) s.objects.push_back(placed("static" + std::to_string(i), 0, {1000.0 + 3 * i, 0, 0}, {{0, T}}));
  Object mover = placed("mover", 0, {0, 0, 0}, {{0, T}});
  mover.path.push_back({T, {1000, 20, 0}, 0.0});
  s.objects.push_back(mover);
  const HdlodTree tree = buildHdlod(s);
  ASSERT_EQ(tree.stats.dynamicObjects, 1u);
  const uint32_t dyn = tree.objectCluster[4];
  ASSERT_EQ(tree.clusters[dyn].kind, ClusterKind::Dynamic);
  DrawList out(tree);
  SelectStats st;
  // Everything in view (far enough south to see x = 0 ... 1010): every cluster visited.
  ASSERT_EQ(selectAll(tree, s, viewOf({505, 0, 0}, 3000, T, 0.0), out, &st), 5u);
  EXPECT_EQ(st.visited, tree.clusters.size());
  EXPECT_EQ(st.culled, 0u);
  // Looking at x ~ 1000 with a narrow view: the swept box (x 0 ... 1000) meets it.
  SelectView narrow = viewOf({1005, 0, 0}, 60, 0.0, 0.0);
  narrow.camera.fovY_deg = 30;
  ASSERT_TRUE(makeFrustum(narrow.camera).intersects(
      Aabb{tree.clusters[dyn].box.min - narrow.camera.eye_m, tree.clusters[dyn].box.max - narrow.camera.eye_m}));
  EXPECT_EQ(selectAll(tree, s, narrow, out, &st), 4u);  // t = 0: the mover is at x = 0
  EXPECT_EQ(st.culled, 1u);
  for (size_t i = 0; i < 4; ++i) EXPECT_NE(out.draws[i].cluster, dyn);
  narrow.time_s = T;  // at the end of its path, in view
  EXPECT_EQ(selectAll(tree, s, narrow, out, &st), 5u);
  EXPECT_EQ(st.culled, 0u);
}

// An empty scene (no objects: no root) is valid input: nothing is selected, and it is not
// reported as rejected (SelectStats::rejected is for the bad views hdlod_select.h lists).
TEST(HdlodSelectMutation, EmptySceneSelectsNothingWithoutRejecting) {
  Scene s;
  s.duration_s = 10;
  const HdlodTree tree = buildHdlod(s);
  DrawList out(tree);
  SelectStats st;
  st.rejected = true;
  EXPECT_EQ(selectHdlod(tree, s, viewOf({0, 0, 0}, 20, 5, 0.0), out, &st), 0u);
  EXPECT_FALSE(st.rejected);
  EXPECT_EQ(st.visited, 0u);
  st.rejected = true;
  EXPECT_EQ(selectAll(tree, s, viewOf({0, 0, 0}, 20, 5, 0.0), out, &st), 0u);
  EXPECT_FALSE(st.rejected);
}
