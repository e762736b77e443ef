// lod/hdlod_build + hdlod_select + hdlod_site: f_c, gamma_c and delta_c on hand-made cases
// (f = 0, 0.5, 1; t = 0, T, before 0, after T); zero-triangle, degenerate and coincident objects;
// all-dynamic and one-object scenes; camera inside a box; NaN input; huge coordinates; the
// selection at r = 0 equals the present objects in the frustum; triangles fall as r grows.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
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

using ig::lod::hdlod::test::placed;
using ig::lod::hdlod::test::viewOf;

std::vector<uint32_t> sortedClusters(std::span<const Draw> d) {
  std::vector<uint32_t> ids;
  for (const Draw& x : d) ids.push_back(x.cluster);
  std::sort(ids.begin(), ids.end());
  return ids;
}

// Two objects of the same box, side by side: A present on [T/5, T], B on [3T/5, T].
Scene twoObjects(double T) {
  Scene s;
  s.duration_s = T;
  s.models.push_back(makeBoxModel("b", {1, 1, 1}));
  s.objects.push_back(placed("A", 0, {0, 0, 0}, {{0.2 * T, T}}));
  s.objects.push_back(placed("B", 0, {1.5, 0, 0}, {{0.6 * T, T}}));
  return s;
}

// The construction site at a small scale (lod/hdlod_site.h).
Scene smallSite(double scale, int loadsPerFloor) {
  SiteParams p;
  p.scale = scale;
  p.loadsPerFloor = loadsPerFloor;
  std::string error;
  Scene s = makeConstructionSite(p, error);
  EXPECT_EQ(error, "");
  return s;
}

}  // namespace

TEST(HdlodBuild, PresenceGammaAndDeltaOnAHandMadePair) {
  const double T = 100;
  const Scene s = twoObjects(T);
  const HdlodTree tree = buildHdlod(s);
  const Cluster& top = tree.clusters[tree.root];
  ASSERT_EQ(top.kind, ClusterKind::Group);
  ASSERT_EQ(top.childCount, 1u);
  const Cluster& c = tree.clusters[tree.childrenOf(top)[0]];
  ASSERT_EQ(c.kind, ClusterKind::Merged);
  ASSERT_EQ(c.childCount, 2u);
  // Equal weights: nobody before T/5, half until 3T/5, all after; t clamped to [0, T].
  EXPECT_EQ(clusterPresence(tree, c, -10), 0.0);
  EXPECT_EQ(clusterPresence(tree, c, 0), 0.0);
  EXPECT_EQ(clusterPresence(tree, c, 20), 0.5);
  EXPECT_EQ(clusterPresence(tree, c, 59.9), 0.5);
  EXPECT_EQ(clusterPresence(tree, c, 60), 1.0);
  EXPECT_EQ(clusterPresence(tree, c, T), 1.0);
  EXPECT_EQ(clusterPresence(tree, c, 1e9), 1.0);
  // gamma: each object is 0.5 away from f_c on [T/5, 3T/5).
  EXPECT_NEAR(c.gamma, 0.2, 1e-12);
  // delta = eps + w (1 - |2f - 1|): eps at f = 0 and 1, eps + w at f = 0.5.
  EXPECT_NEAR(clusterDelta(tree, c, 0), c.eps_m, 1e-12);
  EXPECT_NEAR(clusterDelta(tree, c, 30), c.eps_m + c.size_m, 1e-12);
  EXPECT_NEAR(clusterDelta(tree, c, T), c.eps_m, 1e-12);
  EXPECT_NEAR(c.size_m, glm::length(glm::dvec3(2.5, 1, 1)), 1e-6);
  // Leaves: f in {0, 1}, eps 0.
  const Cluster& b = tree.clusters[tree.objectCluster[1]];
  EXPECT_EQ(clusterPresence(tree, b, 30), 0.0);
  EXPECT_EQ(clusterPresence(tree, b, T), 1.0);
  EXPECT_EQ(clusterDelta(tree, b, T), 0.0);
}

TEST(HdlodBuild, PresenceZeroAndStepDistance) {
  const double T = 10;
  Scene s;
  s.duration_s = T;
  s.models.push_back(makeBoxModel("b", {1, 1, 1}));
  s.objects.push_back(placed("A", 0, {0, 0, 0}, {{2, 4}}));
  s.objects.push_back(placed("B", 0, {0.5, 0, 0}, {{3, 5}}));
  const HdlodTree tree = buildHdlod(s);
  const Cluster& c = tree.clusters[tree.childrenOf(tree.clusters[tree.root])[0]];
  EXPECT_EQ(clusterPresence(tree, c, 0), 0.0);  // exactly 0: nobody there
  EXPECT_EQ(clusterPresence(tree, c, 2.5), 0.5);
  EXPECT_EQ(clusterPresence(tree, c, 3.5), 1.0);
  EXPECT_EQ(clusterPresence(tree, c, 4.5), 0.5);
  EXPECT_EQ(clusterPresence(tree, c, 5), 0.0);
  EXPECT_EQ(clusterPresence(tree, c, T), 0.0);
  // Nothing selected at t = 0 however coarse r is: f_c == 0 skips the subtree.
  SelectStats st;
  DrawList out(tree);
  EXPECT_EQ(selectHdlod(tree, s, viewOf({0, 0, 0}, 50, 0, 1.0), out, &st), 0u);
  EXPECT_GE(st.absent, 1u);
  const double ta[] = {0, 5}, va[] = {0, 1}, tb[] = {0}, vb[] = {0.25};
  EXPECT_NEAR(stepDistance(ta, va, tb, vb, 10), 0.5 * 0.25 + 0.5 * 0.75, 1e-12);
  EXPECT_EQ(stepDistance(ta, va, ta, va, 10), 0.0);
}

TEST(HdlodSelect, HalfPresentClusterIsSkippedMostlyPresentIsDrawn) {
  const double T = 100;
  Scene s;
  s.duration_s = T;
  s.models.push_back(makeBoxModel("b", {1, 1, 1}));
  // Four coincident-ish boxes: present at t = 10 are one (f = 0.25) or three (f = 0.75).
  s.objects.push_back(placed("a", 0, {0, 0, 0}, {{1, T}}));  // pseudo-dynamic, like the others
  s.objects.push_back(placed("b", 0, {0.1, 0, 0}, {{5, T}}));
  s.objects.push_back(placed("c", 0, {0.2, 0, 0}, {{5, T}}));
  s.objects.push_back(placed("d", 0, {0.3, 0, 0}, {{20, T}}));
  const HdlodTree tree = buildHdlod(s);
  DrawList out(tree);
  SelectStats st;
  // Far away, coarse r: the top cluster is good enough.
  const size_t n = selectHdlod(tree, s, viewOf({0, 0, 0}, 1000, 10, 1.0), out, &st);
  ASSERT_EQ(n, 1u);
  EXPECT_EQ(tree.clusters[out.draws[0].cluster].kind, ClusterKind::Merged);
  EXPECT_NEAR(clusterPresence(tree, tree.clusters[out.draws[0].cluster], 10), 0.75, 1e-12);
  // At t = 2 only 'a' is present (f = 0.25 < 0.5): the good-enough cluster is skipped.
  EXPECT_EQ(selectHdlod(tree, s, viewOf({0, 0, 0}, 1000, 2, 1.0), out, &st), 0u);
  EXPECT_EQ(st.halfSkipped, 1u);
  // r = 0: exactly the present objects.
  EXPECT_EQ(selectHdlod(tree, s, viewOf({0, 0, 0}, 1000, 2, 0.0), out, &st), 1u);
  EXPECT_EQ(out.draws[0].cluster, tree.objectCluster[0]);
}

// f_c >= 0.5 decides exactly: weights 0.1, 0.2, 0.3 (box diagonals), any two of which outweigh
// the third (0.1 + 0.2 > 0.3 for the doubles). The running sum of the members' rises and falls
// drifted: 0.2, 0.3, 0.1 in, then 0.3 out left f = 0.4999999999999999 with 0.1 + 0.2 present, and
// the good-enough cluster was skipped. Every order in and out: drawn iff two or three present.
TEST(HdlodSelect, PresenceFractionAtHalfIsExactForUnequalWeights) {
  const double T = 10, w[3] = {0.1, 0.2, 0.3};
  int order[3] = {0, 1, 2};
  std::vector<std::array<int, 3>> orders;
  do orders.push_back({order[0], order[1], order[2]});
  while (std::next_permutation(order, order + 3));
  for (const auto& in : orders)
    for (const auto& out : orders) {
      Scene s;
      s.duration_s = T;
      for (int i = 0; i < 3; ++i) {
        Model m = makeBoxModel("m" + std::to_string(i), {w[i], 0, 0});
        m.box = Aabb{glm::dvec3(-0.5 * w[i], 0, 0), glm::dvec3(0.5 * w[i], 0, 0)};  // diagonal exactly w[i]
        s.models.push_back(m);
      }
      double appear[3], leave[3];
      for (int k = 0; k < 3; ++k) {
        appear[in[static_cast<size_t>(k)]] = 1.0 + k;
        leave[out[static_cast<size_t>(k)]] = 5.0 + k;
      }
      for (uint32_t i = 0; i < 3; ++i) s.objects.push_back(placed("o" + std::to_string(i), i, {0, 0, 0}, {{appear[i], leave[i]}}));
      const HdlodTree tree = buildHdlod(s);
      for (uint32_t i = 0; i < 3; ++i) ASSERT_EQ(tree.clusters[tree.objectCluster[i]].size_m, w[i]);
      DrawList list(tree);
      for (const double t : {1.5, 2.5, 3.5, 5.5, 6.5}) {
        int present = 0;
        for (int i = 0; i < 3; ++i) present += appear[i] <= t && t < leave[i];
        SelectStats st;
        const size_t n = selectHdlod(tree, s, viewOf({0, 0, 0}, 1000, t, 1.0), list, &st);
        EXPECT_EQ(n, present >= 2 ? 1u : 0u) << "in " << in[0] << in[1] << in[2] << " out " << out[0] << out[1] << out[2]
                                             << " t " << t << " present " << present;
      }
    }
}

TEST(HdlodBuild, ZeroTriangleAndDegenerateObjects) {
  Scene s;
  s.duration_s = 10;
  s.models.push_back(Model{"empty", {}, {}, {}});
  Model degenerate{"degenerate", {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {0, 0, 0}}, {0, 1, 2, 0, 3, 0, 1, 1, 1}, {}};
  s.models.push_back(degenerate);
  s.models.push_back(makeBoxModel("box", {1, 1, 1}));
  computeModelBoxes(s);
  s.objects.push_back(placed("e", 0, {0, 0, 0}, {{0, 10}}));
  s.objects.push_back(placed("d", 1, {0, 0, 0}, {{0, 10}}));
  s.objects.push_back(placed("b", 2, {0.5, 0, 0}, {{0, 10}}));
  ASSERT_EQ(validateScene(s), "");
  const HdlodTree tree = buildHdlod(s);
  EXPECT_EQ(tree.stats.emptyObjects, 1u);
  EXPECT_EQ(tree.objectCluster[0], ~0u);
  for (const Cluster& c : tree.clusters) {
    EXPECT_TRUE(std::isfinite(c.eps_m));
    EXPECT_TRUE(std::isfinite(c.size_m));
  }
  DrawList out(tree);
  const size_t n = selectHdlod(tree, s, viewOf({0, 0, 0}, 20, 5, 0.0), out);
  EXPECT_EQ(sortedClusters({out.draws.data(), n}), (std::vector<uint32_t>{tree.objectCluster[1], tree.objectCluster[2]}));
  // Only empty objects: no tree, nothing selected.
  Scene only;
  only.duration_s = 1;
  only.models.push_back(Model{"empty", {}, {}, {}});
  only.objects.push_back(placed("e", 0, {0, 0, 0}, {{0, 1}}));
  const HdlodTree none = buildHdlod(only);
  EXPECT_EQ(none.root, ~0u);
  EXPECT_EQ(selectHdlod(none, only, viewOf({0, 0, 0}, 20, 0, 0.0), out), 0u);
}

TEST(HdlodBuild, SampledHausdorffHandCases) {
  const std::vector<glm::vec3> tri = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}};
  const std::vector<uint32_t> idx = {0, 1, 2};
  const std::vector<glm::vec3> samples = {{0.5f, 0.5f, 1.0f}, {0.2f, 0.2f, -0.5f}, {4, 0, 0}};
  EXPECT_NEAR(sampledHausdorff(samples, tri, idx), 2.0, 1e-6);  // (4,0,0) is 2 from the corner
  EXPECT_EQ(sampledHausdorff({}, tri, idx), 0.0);
  EXPECT_TRUE(std::isinf(sampledHausdorff(samples, tri, {})));
  // A zero-area triangle is measured as its edges.
  const std::vector<glm::vec3> line = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  const std::vector<glm::vec3> above = {{1.5f, 0, 3}};
  EXPECT_NEAR(sampledHausdorff(above, line, idx), 3.0, 1e-6);
}

// A facade: panels with a window 4-8 cm in front of each. Removing a window moves the surface
// by centimetres but turns a window into panel on screen; merged clusters are simplified per
// material, so every point of every colour of a cluster's children lies within eps_c of the
// cluster's geometry of the same colour (the sampled distance the builder itself measures, here
// against the drawn triangles only).
TEST(HdlodBuild, MergedClustersKeepEveryColourWithinEps) {
  Scene s;
  s.duration_s = 10;
  s.models.push_back(makeBoxModel("facade_panel", {2.0, 0.08, 3.0}));
  s.models.push_back(makeBoxModel("window", {1.2, 0.04, 1.6}));
  for (int i = 0; i < 8; ++i) {
    for (int k = 0; k < 8; ++k) {
      const std::string id = std::to_string(i) + "_" + std::to_string(k);
      s.objects.push_back(placed("p" + id, 0, {2.0 * i, 0, 3.0 * k}, {}));
      s.objects.push_back(placed("w" + id, 1, {2.0 * i, -0.06, 3.0 * k + 0.7}, {}));
    }
  }
  BuildConfig config;
  config.strictHausdorff = true;  // against the drawn triangles only (no collapsed segments)
  const HdlodTree tree = buildHdlod(s, config);
  int checked = 0, fine = 0;
  for (const Cluster& c : tree.clusters) {
    if (c.kind != ClusterKind::Merged) continue;
    const ClusterMesh& mesh = tree.meshes[c.mesh];
    for (uint16_t material = 0; material < 2; ++material) {
      // The children's triangles of this material and their samples (vertices, centroids),
      // relative to the cluster's origin.
      std::vector<glm::vec3> samples;
      for (uint32_t k : tree.childrenOf(c)) {
        const Cluster& child = tree.clusters[k];
        std::vector<glm::vec3> tri;
        if (child.kind == ClusterKind::Object) {
          if (child.mesh != material) continue;
          const Model& m = s.models[child.mesh];
          for (uint32_t i : m.indices) {
            tri.push_back(glm::vec3(glm::dvec3(tree.leafMatrix[k] * glm::dvec4(glm::dvec3(m.positions[i]), 1.0)) - mesh.origin_m));
          }
        } else {
          const ClusterMesh& cm = tree.meshes[child.mesh];
          for (size_t t = 0; t < cm.materials.size(); ++t) {
            if (cm.materials[t] != material) continue;
            for (int v = 0; v < 3; ++v) tri.push_back(glm::vec3(glm::dvec3(cm.positions[cm.indices[3 * t + v]]) + cm.origin_m - mesh.origin_m));
          }
        }
        for (size_t t = 0; t + 2 < tri.size(); t += 3) {
          samples.insert(samples.end(), {tri[t], tri[t + 1], tri[t + 2], (tri[t] + tri[t + 1] + tri[t + 2]) / 3.0f});
        }
      }
      if (samples.empty()) continue;
      std::vector<uint32_t> same;
      for (size_t t = 0; t < mesh.materials.size(); ++t) {
        if (mesh.materials[t] == material) same.insert(same.end(), {mesh.indices[3 * t], mesh.indices[3 * t + 1], mesh.indices[3 * t + 2]});
      }
      double d = sampledHausdorff(samples, mesh.positions, same);
      // A colour with nothing left is measured as half the cluster's diagonal.
      if (same.empty()) d = 0.5 * c.size_m;
      EXPECT_LE(d, c.eps_m + 1e-3) << "cluster level " << c.level << " material " << material;
      ++checked;
      fine += c.eps_m < 0.6 ? 1 : 0;  // finer than a window's half width: windows must stay windows
    }
  }
  EXPECT_GT(checked, 20);
  EXPECT_GT(fine, 10);
}

TEST(HdlodBuild, CoincidentObjectsMergeIntoOneSmallCluster) {
  Scene s;
  s.duration_s = 10;
  s.models.push_back(makeBoxModel("b", {1, 1, 1}));
  for (int i = 0; i < 100; ++i) s.objects.push_back(placed(std::to_string(i), 0, {0, 0, 0}, {{0, 10}}));
  const HdlodTree tree = buildHdlod(s);
  const Cluster& top = tree.clusters[tree.childrenOf(tree.clusters[tree.root])[0]];
  EXPECT_EQ(top.kind, ClusterKind::Merged);
  EXPECT_LE(top.triangles, 12u);  // duplicates removed
  EXPECT_LT(top.eps_m, 1.0);
  DrawList out(tree);
  EXPECT_EQ(selectHdlod(tree, s, viewOf({0, 0, 0}, 20, 5, 0.0), out), 100u);
  SelectStats st;
  EXPECT_EQ(selectHdlod(tree, s, viewOf({0, 0, 0}, 1e4, 5, 0.01), out, &st), 1u);
  EXPECT_LE(st.triangles, 12u);
}

TEST(HdlodSelect, AllDynamicScene) {
  const double T = 60;
  Scene s;
  s.duration_s = T;
  s.models.push_back(makeBoxModel("truck", {2, 5, 3}));
  for (int i = 0; i < 40; ++i) {
    Object o;
    o.name = std::to_string(i);  // (GCC 12 -O3 warns falsely on "t" + string)
    o.model = 0;
    o.visible.push_back({i * 1.0, i + 10.0});
    o.path.push_back({0, {i * 10.0, 0, 0}, 0});
    o.path.push_back({T, {i * 10.0, 100, 0}, 90});
    s.objects.push_back(o);
  }
  const HdlodTree tree = buildHdlod(s);
  EXPECT_EQ(tree.stats.dynamicObjects, 40u);
  EXPECT_EQ(tree.stats.mergedClusters, 0u);
  DrawList out(tree);
  for (double t : {-1.0, 0.0, 15.5, T, 2 * T}) {
    SelectView v = viewOf({200, 50, 0}, 2000, t, 1.0);
    const size_t n = selectHdlod(tree, s, v, out);
    size_t expected = 0;
    for (const Object& o : s.objects) expected += isPresent(o, t, T) ? 1 : 0;
    ASSERT_EQ(n, expected) << t;
    for (size_t i = 0; i < n; ++i) {
      const Cluster& c = tree.clusters[out.draws[i].cluster];
      ASSERT_EQ(c.kind, ClusterKind::Dynamic);
      EXPECT_EQ(*out.draws[i].model, objectMatrix(s.objects[c.object], t, T));
      EXPECT_EQ(out.draws[i].model, &out.moving[i]);  // the matrices live in the caller's span
    }
  }
  // Room for 3 moving matrices: 3 draws written, the rest counted and flagged.
  EXPECT_EQ(movingBound(tree), 40u);
  SelectStats st;
  std::vector<Draw> draws(drawBound(tree));
  std::vector<glm::dmat4> three(3);
  EXPECT_EQ(selectHdlod(tree, s, viewOf({200, 50, 0}, 2000, 15.5, 1.0), draws, three, &st), 3u);
  EXPECT_TRUE(st.overflow);
  EXPECT_EQ(st.draws, 10u);  // present at 15.5 s: objects 6 ... 15
  for (size_t i = 0; i < 3; ++i) EXPECT_EQ(draws[i].model, &three[i]);
}

TEST(HdlodSelect, OneObjectScene) {
  Scene s;
  s.duration_s = 5;
  s.models.push_back(makeBoxModel("b", {1, 1, 1}));
  s.objects.push_back(placed("only", 0, {3, 4, 5}, {{0, 5}}));
  const HdlodTree tree = buildHdlod(s);
  DrawList out(tree);
  ASSERT_EQ(out.draws.size(), 1u);
  for (double r : {0.0, 1.0, 1e9}) {
    ASSERT_EQ(selectHdlod(tree, s, viewOf({3, 4, 5}, 30, 2, r), out), 1u) << r;
    EXPECT_EQ(out.draws[0].cluster, tree.objectCluster[0]);
    EXPECT_EQ((*out.draws[0].model)[3], glm::dvec4(3, 4, 5, 1));
  }
  // Looking away: culled.
  SelectView away = viewOf({3, 4, 5}, 30, 2, 0.0);
  away.camera.heading_deg = 180;
  SelectStats st;
  EXPECT_EQ(selectHdlod(tree, s, away, out, &st), 0u);
  EXPECT_EQ(st.culled, 1u);
}

TEST(HdlodSelect, CameraInsideABoxRefines) {
  const Scene s = smallSite(0.02, 5);
  ASSERT_FALSE(s.objects.empty());
  const HdlodTree tree = buildHdlod(s);
  DrawList out(tree);
  // Inside the tower at mid height, with an r so coarse that anything not containing the eye
  // is good enough.
  SelectView v = viewOf({0, 0, 2}, 0, s.duration_s, 1e6);
  SelectStats st;
  const size_t n = selectHdlod(tree, s, v, out, &st);
  ASSERT_GT(n, 0u);
  for (size_t i = 0; i < n; ++i) {
    const Cluster& c = tree.clusters[out.draws[i].cluster];
    if (c.kind == ClusterKind::Merged) {
      EXPECT_FALSE(c.box.contains(v.camera.eye_m)) << out.draws[i].cluster;
    }
  }
}

TEST(HdlodSelect, BadInputSelectsNothing) {
  const Scene s = twoObjects(10);
  const HdlodTree tree = buildHdlod(s);
  DrawList out(tree);
  SelectStats st;
  const SelectView good = viewOf({0, 0, 0}, 20, 10.0, 0.0);
  ASSERT_EQ(selectHdlod(tree, s, good, out, &st), 2u);
  EXPECT_FALSE(st.rejected);
  auto expectRejected = [&](SelectView v) {
    EXPECT_EQ(selectHdlod(tree, s, v, out, &st), 0u);
    EXPECT_TRUE(st.rejected);
    EXPECT_EQ(selectAll(tree, s, v, out, &st), 0u);
    EXPECT_TRUE(st.rejected);
  };
  SelectView v = good;
  v.camera.eye_m.x = kNan;
  expectRejected(v);
  v = good;
  v.camera.heading_deg = kNan;
  expectRejected(v);
  v = good;
  v.time_s = kNan;
  expectRejected(v);
  v = good;
  v.tolerance_rad = kNan;
  expectRejected(v);
  v = good;
  v.camera.fovY_deg = 0;
  expectRejected(v);
  v = good;
  v.camera.near_m = v.camera.far_m;
  expectRejected(v);
  v = good;
  v.camera.eye_m.y = std::numeric_limits<double>::infinity();
  expectRejected(v);
  // A negative r reads as 0; a span too small is filled and the rest counted.
  v = good;
  v.tolerance_rad = -1;
  EXPECT_EQ(selectHdlod(tree, s, v, out, &st), 2u);
  EXPECT_EQ(selectHdlod(tree, s, good, std::span<Draw>(out.draws.data(), 1), out.moving, &st), 1u);
  EXPECT_TRUE(st.overflow);
  EXPECT_EQ(st.draws, 2u);
  // r = +inf accepts any error: not rejected, and no more draws than a finite tolerance.
  v = good;
  v.tolerance_rad = std::numeric_limits<double>::infinity();
  const size_t coarsest = selectHdlod(tree, s, v, out, &st);
  EXPECT_FALSE(st.rejected);
  EXPECT_GE(coarsest, 1u);
  EXPECT_LE(coarsest, selectHdlod(tree, s, good, out, &st));
}

TEST(HdlodSite, CountsClassesAndBadParameters) {
  SiteParams p;
  p.scale = 0.05;
  std::string error;
  const Scene s = makeConstructionSite(p, error);
  ASSERT_EQ(error, "");
  EXPECT_EQ(validateScene(s), "");
  size_t count[3] = {0, 0, 0};
  for (const Object& o : s.objects) ++count[static_cast<int>(classify(o, s.duration_s))];
  EXPECT_GT(count[0], 300u);
  EXPECT_GT(count[1], 1500u);
  EXPECT_GT(count[2], 500u);
  // Deterministic.
  const Scene again = makeConstructionSite(p, error);
  ASSERT_EQ(again.objects.size(), s.objects.size());
  EXPECT_EQ(again.objects.back().path.back().position_m, s.objects.back().path.back().position_m);
  p.scale = kNan;
  EXPECT_TRUE(makeConstructionSite(p, error).objects.empty());
  EXPECT_NE(error.find("scale"), std::string::npos);
  p.scale = 1;
  p.floors = 0;
  makeConstructionSite(p, error);
  EXPECT_NE(error.find("floors = 0"), std::string::npos);
}

// The site at a few times: r = 0 selects exactly the present objects in the frustum (the same
// set as selectAll and as a brute-force check); with everything present and in view, the
// triangle count never rises as r grows; the build is deterministic.
TEST(HdlodSelect, SiteExactAtZeroAndMonotoneInR) {
  const Scene s = smallSite(0.05, 40);
  ASSERT_FALSE(s.objects.empty());
  const HdlodTree tree = buildHdlod(s);
  EXPECT_GT(tree.stats.mergedClusters, 10u);
  DrawList out(tree), all(tree);
  const Cluster& root = tree.clusters[tree.root];
  const glm::dvec3 centre = (root.box.min + root.box.max) * 0.5;
  const double R = 0.5 * glm::length(root.box.max - root.box.min);
  for (double f : {0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0}) {
    const double t = f * s.duration_s;
    for (double dist : {3.0 * R, 0.6 * R}) {  // all in view; partly in view
      const SelectView v = viewOf(centre, dist, t, 0.0);
      const size_t n = selectHdlod(tree, s, v, out);
      const size_t m = selectAll(tree, s, v, all);
      ASSERT_EQ(sortedClusters({out.draws.data(), n}), sortedClusters({all.draws.data(), m})) << f << " " << dist;
      const Frustum fr = makeFrustum(v.camera);
      std::vector<uint32_t> brute;
      for (uint32_t i = 0; i < s.objects.size(); ++i) {
        const Object& o = s.objects[i];
        if (tree.objectCluster[i] == ~0u || !isPresent(o, t, s.duration_s)) continue;
        const Aabb b = transformBox(s.models[o.model].box, objectMatrix(o, t, s.duration_s));
        if (fr.intersects(Aabb{b.min - v.camera.eye_m, b.max - v.camera.eye_m})) brute.push_back(tree.objectCluster[i]);
      }
      std::sort(brute.begin(), brute.end());
      EXPECT_EQ(sortedClusters({out.draws.data(), n}), brute) << f << " " << dist;
    }
  }
  // Monotone in r at the end of construction (all present), the whole site in view.
  uint64_t previous = std::numeric_limits<uint64_t>::max();
  for (double px : {0.0, 0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 64.0, 1e4}) {
    SelectStats st;
    selectHdlod(tree, s, viewOf(centre, 3.0 * R, s.duration_s, toleranceFromPixels(px, 60, 1000)), out, &st);
    EXPECT_LE(st.triangles, previous) << px;
    previous = st.triangles;
  }
  EXPECT_LT(previous, tree.stats.leafTriangles / 10);
  const HdlodTree again = buildHdlod(s);
  ASSERT_EQ(again.clusters.size(), tree.clusters.size());
  for (size_t i = 0; i < tree.clusters.size(); ++i) {
    ASSERT_EQ(again.clusters[i].eps_m, tree.clusters[i].eps_m);
    ASSERT_EQ(again.clusters[i].triangles, tree.clusters[i].triangles);
  }
}

TEST(HdlodBuild, HugeCoordinatesKeepPrecision) {
  SiteParams p;
  p.scale = 0.02;
  p.loadsPerFloor = 5;
  p.origin_m = {4.1e6, -1.0e7, 300.0};
  std::string error;
  const Scene far = makeConstructionSite(p, error);
  p.origin_m = glm::dvec3(0.0);
  const Scene near = makeConstructionSite(p, error);
  const HdlodTree a = buildHdlod(far), b = buildHdlod(near);
  // Ties between equally distant neighbours may break differently at 1e7 m, so the trees are
  // compared in aggregate; the stored geometry must stay relative to each cluster's origin.
  ASSERT_GT(a.meshes.size(), 10u);
  EXPECT_NEAR(static_cast<double>(a.stats.mergedTriangles), static_cast<double>(b.stats.mergedTriangles),
              0.1 * static_cast<double>(b.stats.mergedTriangles));
  double epsA = 0, epsB = 0;
  for (const Cluster& c : a.clusters) epsA = std::max(epsA, c.eps_m);
  for (const Cluster& c : b.clusters) epsB = std::max(epsB, c.eps_m);
  EXPECT_NEAR(epsA, epsB, 0.25 * epsB);
  for (size_t i = 0; i < a.clusters.size(); ++i) {
    const Cluster& c = a.clusters[i];
    if (c.kind != ClusterKind::Merged) continue;
    const ClusterMesh& m = a.meshes[c.mesh];
    EXPECT_GT(m.origin_m.x, 0.9 * 4.1e6);
    EXPECT_EQ(a.leafMatrix[i][3], glm::dvec4(m.origin_m, 1.0));
    for (const glm::vec3& q : m.positions) {
      ASSERT_LE(glm::length(glm::dvec3(q)), 0.5 * c.size_m + c.eps_m + 1e-3) << i;
    }
  }
  // Selection at r = 0 near the far site matches the brute force count.
  DrawList out(a), all(a);
  const glm::dvec3 centre = (a.clusters[a.root].box.min + a.clusters[a.root].box.max) * 0.5;
  const SelectView v = viewOf(centre, 400, far.duration_s, 0.0);
  EXPECT_EQ(selectHdlod(a, far, v, out), selectAll(a, far, v, all));
}

// On the site: every draw's matrix is, bit for bit, the tree's (objects, merged clusters: leafMatrix) or the path's (dynamic
// objects), at times inside and outside [0, T] and going backwards.
TEST(HdlodSelect, SiteDrawMatricesMatchTheTree) {
  const Scene s = smallSite(0.05, 40);
  ASSERT_FALSE(s.objects.empty());
  const HdlodTree tree = buildHdlod(s);
  const Cluster& root = tree.clusters[tree.root];
  DrawList out(tree);
  const glm::dvec3 centre = (root.box.min + root.box.max) * 0.5;
  const double R = 0.5 * glm::length(root.box.max - root.box.min);
  const double T = s.duration_s;
  size_t merged = 0, dynamic = 0;
  for (double t : {0.5 * T, 0.25 * T, -T, 0.0, 0.6 * T, 2.0 * T, T, 0.1 * T, 0.9 * T}) {
    for (double px : {0.0, 1.0, 8.0}) {
      const SelectView v = viewOf(centre, 2.0 * R, t, toleranceFromPixels(px, 60, 1000));
      const size_t n = selectHdlod(tree, s, v, out);
      for (size_t k = 0; k < n; ++k) {
        const Draw& d = out.draws[k];
        const Cluster& c = tree.clusters[d.cluster];
        glm::dmat4 expected = tree.leafMatrix[d.cluster];
        if (c.kind == ClusterKind::Dynamic) {
          expected = objectMatrix(s.objects[c.object], t, T);
          ++dynamic;
        }
        merged += c.kind == ClusterKind::Merged;
        ASSERT_EQ(std::memcmp(d.model, &expected, sizeof expected), 0) << d.cluster << " t " << t << " px " << px;
      }
    }
  }
  EXPECT_GT(merged, 0u);
  EXPECT_GT(dynamic, 0u);
}

namespace {

// Appendix 1 of paper 000 written plainly over the clusters (hdlod_select.h states the rule):
// the traversal's records, float boxes and plane masks must decide every test as this does.
struct ReferenceSelection {
  const HdlodTree& tree;
  const Scene& scene;
  Frustum frustum;
  glm::dvec3 eye;
  double t, r2;
  std::vector<Draw> out;

  static double distance2(const Aabb& b, const glm::dvec3& p) {
    const glm::dvec3 d = glm::max(glm::max(b.min - p, p - b.max), glm::dvec3(0.0));
    return d.x * d.x + d.y * d.y + d.z * d.z;
  }
  bool inView(const Aabb& b) const { return frustum.intersects(Aabb{b.min - eye, b.max - eye}); }
  void leaf(uint32_t id, const Cluster& c, const Aabb& box) {
    uint32_t lod = 0;
    const auto lods = tree.lodsOf(c.mesh);
    for (size_t k = 0; k < lods.size() && r2 > 0.0; ++k) {
      if (!(lods[k].eps_m * lods[k].eps_m < r2 * distance2(box, eye))) break;
      lod = static_cast<uint32_t>(k + 1);
    }
    out.push_back({id, lod, nullptr});
  }
  void visit(uint32_t id) {
    const Cluster& c = tree.clusters[id];
    const double f = clusterPresence(tree, c, t);
    if (f == 0.0 || !inView(c.box)) return;
    if (c.kind == ClusterKind::Dynamic) {
      const Object& o = scene.objects[c.object];
      const glm::dmat4 m = objectMatrix(o, t, tree.duration_s);
      const Aabb box = transformBox(scene.models[o.model].box, m);
      if (inView(box)) leaf(id, c, box);
      return;
    }
    if (c.kind == ClusterKind::Object) return leaf(id, c, c.box);
    if (c.kind == ClusterKind::Merged) {
      const double delta = clusterDelta(tree, c, t);
      if (delta * delta < r2 * distance2(c.box, eye)) {
        if (f >= 0.5) out.push_back({id, 0, nullptr});
        return;
      }
    }
    for (uint32_t child : tree.childrenOf(c)) visit(child);
  }
};

// Compares selectHdlod with the reference on `views`; returns the draws compared.
size_t expectSameAsReference(const HdlodTree& tree, const Scene& s, const std::vector<SelectView>& views) {
  DrawList out(tree);
  size_t compared = 0;
  for (size_t i = 0; i < views.size(); ++i) {
    const SelectView& v = views[i];
    const double r = std::max(v.tolerance_rad, 0.0);
    ReferenceSelection ref{tree, s, makeFrustum(v.camera), v.camera.eye_m, clampTime(v.time_s, s.duration_s), r * r, {}};
    ref.visit(tree.root);
    const size_t n = selectHdlod(tree, s, v, out);
    EXPECT_EQ(n, ref.out.size()) << "view " << i;
    for (size_t k = 0; k < std::min(n, ref.out.size()); ++k) {
      EXPECT_EQ(out.draws[k].cluster, ref.out[k].cluster) << "view " << i << " draw " << k;
      EXPECT_EQ(out.draws[k].lod, ref.out[k].lod) << "view " << i << " draw " << k;
      if (out.draws[k].cluster != ref.out[k].cluster) break;
    }
    compared += n;
  }
  return compared;
}

// Views of the site: random eyes in and around it looking anywhere, and eyes placed where the
// float boxes of the traversal leave a test undecided and the cluster record decides: the near
// plane through a cluster's face, the eye on a box corner, the eye at the distance where a
// merged cluster's delta or a model version's eps equals r x distance.
std::vector<SelectView> testViews(const HdlodTree& tree, const Scene& s, uint32_t seed) {
  uint32_t state = seed;
  auto next = [&] {
    state = state * 1664525u + 1013904223u;
    return (state >> 8) * (1.0 / 16777216.0);
  };
  const Cluster& root = tree.clusters[tree.root];
  const glm::dvec3 size = root.box.max - root.box.min;
  std::vector<SelectView> views;
  for (int i = 0; i < 480; ++i) {
    SelectView v;
    v.camera.fovY_deg = 20 + 100 * next();
    v.camera.aspect = 0.5 + 2 * next();
    v.camera.near_m = i % 7 == 0 ? 0.1 : 0.1 + 5 * next();
    v.camera.far_m = i % 5 == 0 ? 1e5 : v.camera.near_m + 3 * glm::length(size) * next();
    v.camera.heading_deg = 360 * next();
    v.camera.pitch_deg = -80 + 160 * next();
    v.camera.roll_deg = i % 3 == 0 ? 0.0 : 90 * next();
    v.time_s = (-0.1 + 1.2 * next()) * s.duration_s;
    v.tolerance_rad = toleranceFromPixels(i % 4 == 0 ? 0.0 : 30 * next() * next(), 60, 1000);
    const Cluster& c = tree.clusters[static_cast<size_t>(next() * static_cast<double>(tree.clusters.size()))];
    // Some at 0, at T and exactly at one of c's step times (the steps are half-open).
    if (i % 10 == 0) v.time_s = i % 20 == 0 ? 0.0 : s.duration_s;
    if (i % 5 == 4 && c.stepCount > 1) v.time_s = tree.stepTimes[c.stepBegin + 1 + static_cast<size_t>(next() * (c.stepCount - 1))];
    const auto lods = c.kind == ClusterKind::Object ? tree.lodsOf(c.mesh) : std::span<const ModelLod>{};
    const double r = v.tolerance_rad;
    double threshold = 0.0;  // distance at which c's test flips
    if (c.kind == ClusterKind::Merged && r > 0.0) threshold = clusterDelta(tree, c, v.time_s) / r;
    if (c.kind == ClusterKind::Object && r > 0.0 && !lods.empty()) threshold = lods[static_cast<size_t>(next() * static_cast<double>(lods.size()))].eps_m / r;
    if (i % 4 == 3 && threshold > 0.0) {
      v.camera.heading_deg = v.camera.pitch_deg = v.camera.roll_deg = 0.0;
      v.camera.near_m = 0.1;
      const glm::dvec3 mid = 0.5 * (c.box.min + c.box.max);
      v.camera.eye_m = {mid.x, c.box.min.y - threshold, mid.z};
    } else if (i % 3 == 1) {
      // Heading 0, level: the near plane is y = eye.y + near, here through the box's south face.
      v.camera.heading_deg = v.camera.pitch_deg = v.camera.roll_deg = 0.0;
      v.camera.eye_m = {c.box.min.x + (c.box.max.x - c.box.min.x) * next(), c.box.min.y - v.camera.near_m, c.box.min.z};
    } else if (i % 3 == 2) {
      v.camera.eye_m = i % 2 ? c.box.max : c.box.min;
    } else {
      v.camera.eye_m = root.box.min - 0.5 * size + 2.0 * size * glm::dvec3(next(), next(), next());
    }
    views.push_back(v);
  }
  return views;
}

}  // namespace

// The traversal (one 64-byte record per cluster with a widened float box, plane masks, distance
// bounds) selects exactly the draws, in the same order and with the same model versions, as
// the rule evaluated on the clusters' double boxes, on the site near the origin and 1e6 m away.
TEST(HdlodSelect, TraversalRecordsDecideExactlyAsTheClusters) {
  for (const glm::dvec3 origin : {glm::dvec3(0.0), glm::dvec3(1.0e6, -2.0e6, 300.0)}) {
    SiteParams p;
    p.scale = 0.05;
    p.loadsPerFloor = 40;
    p.origin_m = origin;
    std::string error;
    const Scene s = makeConstructionSite(p, error);
    ASSERT_EQ(error, "");
    const HdlodTree tree = buildHdlod(s);
    ASSERT_EQ(tree.selectRecords.size(), tree.children.size() + 1);
    EXPECT_GE(tree.selectWidenMin_m, 1e-4);
    EXPECT_LT(tree.selectWidenMax_m, 1e-2);
    EXPECT_GT(expectSameAsReference(tree, s, testViews(tree, s, 7)), 5000u) << origin.x;
  }
}

// A tree whose derived records are missing or stale (not from buildHdlod or the cache loader)
// selects nothing rather than reading past them; a child listed twice is not a tree.
TEST(HdlodSelect, UnpreparedOrBrokenTreesSelectNothing) {
  const Scene s = twoObjects(100.0);
  HdlodTree tree = buildHdlod(s);
  DrawList out(tree);
  const SelectView v = viewOf({0.75, 0, 0}, 20, 100, 0.0);
  EXPECT_EQ(selectHdlod(tree, s, v, out), 2u);
  HdlodTree stale = tree;
  stale.selectRecords.pop_back();
  EXPECT_EQ(selectHdlod(stale, s, v, out), 0u);
  HdlodTree twice = tree;
  ASSERT_GE(twice.children.size(), 2u);
  twice.children[1] = twice.children[0];
  EXPECT_FALSE(prepareSelection(twice));
  EXPECT_TRUE(twice.selectRecords.empty());
  EXPECT_EQ(selectHdlod(twice, s, v, out), 0u);
  HdlodTree rootAsChild = tree;
  rootAsChild.children[0] = rootAsChild.root;
  EXPECT_FALSE(prepareSelection(rootAsChild));
  EXPECT_TRUE(prepareSelection(tree));
  EXPECT_EQ(selectHdlod(tree, s, v, out), 2u);
}

// Presence at the ends of time and at every breakpoint, for leaves with short and long step
// functions (inline steps, a scan, the bucket table): selectAll() draws exactly the objects that
// isPresent() says are present, at t = 0, T, every interval end, one ulp either side, and
// outside [0, T]. The virtual root over the pseudo-dynamic tree's top (a merged cluster whose f
// takes fractional values) must be present while any object is: counting the top's rises and
// falls instead of its presence made the root absent (nothing drawn) while objects were present.
TEST(HdlodSelect, PresenceAtEveryBreakpointMatchesIsPresent) {
  for (double T : {1.0, 7.3, 3600.0, 1e6}) {
    Scene s;
    s.duration_s = T;
    s.models.push_back(makeBoxModel("b", {1, 1, 1}));
    std::vector<double> probes{0.0, T, -1e-300, -1.0, std::nextafter(T, 2 * T), 2 * T, std::nextafter(T, 0.0)};
    for (int k : {1, 2, 5, 9, 20, 40}) {
      std::vector<Interval> iv;
      for (int i = 0; i < k; ++i) {
        const double a = T * (2 * i + 1) / (2 * k + 1), b = T * (2 * i + 2) / (2 * k + 1);
        iv.push_back({a, i + 1 == k ? T : b});  // the last one reaches T
        for (double t : {a, b}) probes.insert(probes.end(), {t, std::nextafter(t, 0.0), std::nextafter(t, 2 * T)});
      }
      s.objects.push_back(placed("o" + std::to_string(k), 0, {3.0 * k, 0, 0}, iv));
    }
    const HdlodTree tree = buildHdlod(s);
    DrawList out(tree);
    for (double t : probes) {
      SelectView v = viewOf({60, 0, 0}, 300, t, 0.0);
      const size_t n = selectAll(tree, s, v, out);
      std::vector<uint32_t> want;
      for (uint32_t i = 0; i < s.objects.size(); ++i)
        if (isPresent(s.objects[i], t, T)) want.push_back(tree.objectCluster[i]);
      std::sort(want.begin(), want.end());
      EXPECT_EQ(sortedClusters(out.selected()), want) << "T " << T << " t " << t << " n " << n;
      for (uint32_t i = 0; i < s.objects.size(); ++i)
        EXPECT_EQ(clusterPresence(tree, tree.clusters[tree.objectCluster[i]], t) == 1.0, isPresent(s.objects[i], t, T))
            << "T " << T << " t " << t << " object " << i;
    }
  }
}

// A model with a vertex no triangle uses still gets coarser versions (hdlod_build.h: up to
// modelLodLevels versions, then the box), with a measured eps that ignores the stray vertex.
TEST(HdlodBuild, ModelVersionsIgnoreUnreferencedVertices) {
  Scene s;
  s.duration_s = 10;
  Model tile;
  tile.name = "tile";
  const int n = 16;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) tile.positions.emplace_back(static_cast<float>(i), static_cast<float>(j), 0.0f);
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const uint32_t a = static_cast<uint32_t>(j * (n + 1) + i), b = a + 1, c = a + static_cast<uint32_t>(n + 1), d = c + 1;
      tile.indices.insert(tile.indices.end(), {a, b, d, a, d, c});
    }
  }
  Model stray = tile;
  stray.name = "stray";
  stray.positions.emplace_back(8.0f, 8.0f, 20.0f);  // used by no triangle
  s.models = {tile, stray};
  computeModelBoxes(s);
  s.objects.push_back(placed("a", 0, {0, 0, 0}, {{0, 10}}));
  s.objects.push_back(placed("b", 1, {100, 0, 0}, {{0, 10}}));
  ASSERT_EQ(validateScene(s), "");
  const HdlodTree tree = buildHdlod(s);
  const auto plain = tree.lodsOf(0), withStray = tree.lodsOf(1);
  ASSERT_GE(plain.size(), 1u);
  EXPECT_LE(plain[0].triangles, 8u);  // a flat tile: a few triangles
  ASSERT_EQ(withStray.size(), plain.size());
  for (size_t k = 0; k < plain.size(); ++k) {
    EXPECT_EQ(withStray[k].triangles, plain[k].triangles) << k;
    EXPECT_NEAR(withStray[k].eps_m, plain[k].eps_m, 1e-6) << k;
  }
}

// Triangles with coincident corners (zero area: nothing is drawn) are no surface the merged
// geometry must stay close to. The simplifier drops them (welded, they repeat an index); the
// measurement sampled their corners anyway, found nothing left of that material and set
// D = half the cluster's diagonal, so every cluster above such an object claimed an error of
// half its size (and was refined far deeper than needed).
TEST(HdlodBuild, PointLikeObjectsDoNotInflateTheError) {
  for (Simplifier sim : {Simplifier::Meshoptimizer, Simplifier::OpenMesh, Simplifier::Clustering}) {
    SCOPED_TRACE(simplifierName(sim));
    Scene s;
    s.duration_s = 10;
    s.models.push_back(makeBoxModel("box", {1, 1, 1}));
    s.models.push_back(Model{"point", {{0.2f, 0.3f, 0.4f}, {0.2f, 0.3f, 0.4f}, {0.2f, 0.3f, 0.4f}}, {0, 1, 2, 2, 1, 0}, {}});
    computeModelBoxes(s);
    s.objects.push_back(placed("a", 0, {0, 0, 0}, {{0, 10}}));
    s.objects.push_back(placed("b", 0, {1.5, 0, 0}, {{0, 10}}));
    s.objects.push_back(placed("p", 1, {0.75, 0, 0}, {{0, 10}}));
    ASSERT_EQ(validateScene(s), "");
    BuildConfig config;
    config.simplifier = sim;
    const HdlodTree tree = buildHdlod(s, config);
    ASSERT_GT(tree.stats.mergedClusters, 0u);
    for (const Cluster& c : tree.clusters) {
      if (c.kind == ClusterKind::Merged) {
        EXPECT_LE(c.eps_m, 0.1 * c.size_m) << c.size_m;
      }
    }
  }
}

namespace {

// Points spread over triangles (three corners per triangle): a barycentric grid of n steps per edge.
std::vector<glm::vec3> denseSamples(const std::vector<glm::vec3>& corners, int n) {
  std::vector<glm::vec3> out;
  for (size_t t = 0; t + 2 < corners.size(); t += 3) {
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; i + j <= n; ++j) {
        const float a = static_cast<float>(i) / static_cast<float>(n), b = static_cast<float>(j) / static_cast<float>(n);
        out.push_back(corners[t] + (corners[t + 1] - corners[t]) * a + (corners[t + 2] - corners[t]) * b);
      }
    }
  }
  return out;
}

// The distance between two triangle sets, both ways, over dense samples of each.
double denseTwoSided(const std::vector<glm::vec3>& a, const std::vector<glm::vec3>& b, int n) {
  std::vector<uint32_t> ia(a.size()), ib(b.size());
  for (uint32_t i = 0; i < ia.size(); ++i) ia[i] = i;
  for (uint32_t i = 0; i < ib.size(); ++i) ib[i] = i;
  return std::max(sampledHausdorff(denseSamples(a, n), b, ib), sampledHausdorff(denseSamples(b, n), a, ia));
}

}  // namespace

// A leaf drawn with a coarser version of its model draws that version's triangles and nothing
// else, so the eps the version claims (the selection uses it when eps < r * distance) must bound
// how far the drawn surface is from the model, both ways. The versions were measured against
// the vanished parts' segments too, which are never drawn: the crane jib (a 75 m lattice with a
// counterweight) had one version, the counterweight alone, claiming 0.83 m while the rest of
// the jib, 71 m of it, was not drawn (the jib vanished at 500 m at 1 px); the excavator's
// 4-triangle version claimed 1.1 m and was 4.9 m off. Every version is checked here against
// dense samples of both surfaces (1.5 x eps: the builder samples corners and centroids only).
TEST(HdlodBuild, ModelVersionsStayWithinTheirEpsOfTheModel) {
  const Scene s = smallSite(0.02, 2);
  const HdlodTree tree = buildHdlod(s);
  int checked = 0;
  for (uint32_t m = 0; m < s.models.size(); ++m) {
    const Model& model = s.models[m];
    std::vector<glm::vec3> full;
    for (uint32_t i : model.indices) full.push_back(model.positions[i]);
    for (const ModelLod& l : tree.lodsOf(m)) {
      const ClusterMesh& mesh = tree.meshes[l.mesh];
      std::vector<glm::vec3> drawn;
      for (uint32_t i : mesh.indices) drawn.push_back(mesh.positions[i]);
      const double d = denseTwoSided(full, drawn, 6);
      EXPECT_LE(d, 1.5 * l.eps_m + 1e-3) << model.name << ": version of " << l.triangles << " triangles, eps " << l.eps_m;
      ++checked;
    }
    if (model.name == "crane_jib") {
      // Its coarsest version spans the jib's length (its box), not only the counterweight.
      const auto lods = tree.lodsOf(m);
      ASSERT_FALSE(lods.empty());
      const ClusterMesh& coarsest = tree.meshes[lods.back().mesh];
      float lo = std::numeric_limits<float>::max(), hi = -lo;
      for (const glm::vec3& q : coarsest.positions) {
        lo = std::min(lo, q.y);
        hi = std::max(hi, q.y);
      }
      EXPECT_GE(static_cast<double>(hi - lo), 0.9 * (model.box.max.y - model.box.min.y));
    }
  }
  EXPECT_GT(checked, 10);
}

namespace {

// The triangles of material `material` of the objects under cluster `id` (three corners each),
// relative to `origin`.
void leafTriangles(const HdlodTree& tree, const Scene& s, uint32_t id, uint16_t material, const glm::dvec3& origin,
                   std::vector<glm::vec3>& out) {
  const Cluster& c = tree.clusters[id];
  if (c.kind == ClusterKind::Object) {
    if (c.mesh != material) return;
    const Model& m = s.models[c.mesh];
    for (uint32_t i : m.indices) out.push_back(glm::vec3(glm::dvec3(tree.leafMatrix[id] * glm::dvec4(glm::dvec3(m.positions[i]), 1.0)) - origin));
    return;
  }
  for (uint32_t k : tree.childrenOf(c)) leafTriangles(tree, s, k, material, origin, out);
}

}  // namespace

// Every point a merged cluster draws lies within eps_c of its objects' surface of the same colour
// (the paper's D_H, drawn -> objects). The builder measured that direction from the drawn
// triangles' corners and centroids only; the sloppy grid makes triangles that span gaps of the
// input (a window frame's bars joined across the pane) whose corners and centroid lie on the
// input and whose edges do not: a window cluster claimed 0.12 m and drew points 0.30 m from
// any window. Checked against dense samples of the drawn triangles (1.25 x eps).
TEST(HdlodBuild, MergedClustersDrawNothingFartherThanEpsFromTheirObjects) {
  const Scene s = smallSite(0.02, 2);
  const HdlodTree tree = buildHdlod(s);
  int checked = 0;
  for (uint32_t id = 0; id < tree.clusters.size(); ++id) {
    const Cluster& c = tree.clusters[id];
    if (c.kind != ClusterKind::Merged) continue;
    const ClusterMesh& mesh = tree.meshes[c.mesh];
    for (uint16_t material = 0; material < s.models.size(); ++material) {
      std::vector<glm::vec3> drawn;
      for (size_t t = 0; t < mesh.materials.size(); ++t) {
        if (mesh.materials[t] != material) continue;
        for (int v = 0; v < 3; ++v) drawn.push_back(mesh.positions[mesh.indices[3 * t + static_cast<size_t>(v)]]);
      }
      if (drawn.empty()) continue;
      std::vector<glm::vec3> objects;
      leafTriangles(tree, s, id, material, mesh.origin_m, objects);
      ASSERT_FALSE(objects.empty());
      std::vector<uint32_t> idx(objects.size());
      for (uint32_t i = 0; i < idx.size(); ++i) idx[i] = i;
      const double d = sampledHausdorff(denseSamples(drawn, 8), objects, idx);
      EXPECT_LE(d, 1.25 * c.eps_m + 1e-3) << "cluster " << id << " level " << c.level << " " << s.models[material].name << ", eps "
                                           << c.eps_m << ", " << drawn.size() / 3 << " triangles";
      ++checked;
    }
  }
  EXPECT_GT(checked, 100);
}
