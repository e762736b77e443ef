// Near-forest kd-tree (lod/forest_kdtree.h): leaves, conservative culling, far-to-near order,
// fades per tree, hard cameras, empty forest, huge coordinates.
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "lod/forest_kdtree.h"

namespace {
using namespace ig::lod;

std::vector<TreeInstance> forest(glm::dvec3 offset = glm::dvec3(0.0)) {
  TerrainGridDesc d;
  d.heights.postsX = d.heights.postsY = 49;
  d.heights.postSpacing_m = 32.0;
  d.heights.heightScale_m = 300.0;
  d.chunkQuads = 16;
  const TerrainGrid terrain(d);
  ForestMapDesc md;
  md.width = md.height = 48;  // 1536 m
  md.featureSize_m = 300.0;
  const ForestMap map = generateForestMap(md);
  std::vector<TreeInstance> t;
  std::string err;
  TreePlacementDesc pd;
  pd.spacing_m = 6.0;
  pd.modelCount = 3;
  EXPECT_TRUE(placeTrees(map, terrain, pd, t, err)) << err;
  for (TreeInstance& x : t) x.base_m += offset;
  return t;
}

ForestKdParams params() {
  ForestKdParams p;
  p.modelCount = 3;
  return p;
}

struct Selection {
  std::vector<ForestInstance> inst, scratch;
  std::vector<ForestModelRange> models;
  size_t n = 0;
  ForestSelectStats stats;
  Selection(const ForestKdTree& kd, const Camera& cam, const NearFade& f, size_t cap)
      : inst(cap), scratch(cap), models(static_cast<size_t>(kd.params().modelCount)) {
    n = kd.select(cam, f, inst, scratch, models, &stats);
  }
  std::set<uint32_t> trees() const {
    std::set<uint32_t> s;
    for (size_t i = 0; i < n; ++i) s.insert(inst[i].tree);
    return s;
  }
};

std::set<uint32_t> bruteForce(const ForestKdTree& kd, const Camera& cam, const NearFade& f) {
  std::set<uint32_t> s;
  const auto planes = ForestKdTree::eyeRelativePlanes(cam);
  for (uint32_t i = 0; i < kd.trees().size(); ++i) {
    if (kd.treeAccepted(kd.decodeRelative(i, cam.eye_m), planes, static_cast<float>(f.fadeOutEnd_m))) s.insert(i);
  }
  return s;
}

TEST(ForestKdTree, EveryTreeInExactlyOneLeafOfBoundedSize) {
  const auto trees = forest();
  ASSERT_GT(trees.size(), 40000u);
  ForestKdTree kd;
  std::string err;
  ASSERT_TRUE(kd.build(trees, params(), err)) << err;
  ASSERT_EQ(kd.trees().size(), trees.size());
  std::vector<int> seen(trees.size(), 0);
  for (uint32_t s : kd.sourceIndex()) ++seen[s];
  for (int c : seen) ASSERT_EQ(c, 1);
  // Leaf ranges tile [0, n) in order; leaves are empty or (L/2, L] on their longer side.
  uint32_t next = 0;
  const double L = kd.params().leafSize_m;
  size_t nonEmpty = 0;
  for (const ForestKdLeaf& leaf : kd.leaves()) {
    ASSERT_EQ(leaf.first, next);
    next += leaf.count;
    if (leaf.count == 0) continue;
    ++nonEmpty;
    const double side = std::max(leaf.region.max.x - leaf.region.min.x, leaf.region.max.y - leaf.region.min.y);
    EXPECT_GT(side, 0.5 * L);
    EXPECT_LE(side, L);
    for (uint32_t i = leaf.first; i < leaf.first + leaf.count; ++i) {
      const TreeInstance& src = trees[kd.sourceIndex()[i]];
      ASSERT_TRUE(leaf.region.contains(src.base_m));
      ASSERT_EQ(kd.leafOf(i), static_cast<uint32_t>(&leaf - kd.leaves().data()));
      const glm::dvec3 p = kd.decode(i);
      ASSERT_LT(glm::length(p - src.base_m), 0.01) << "16-bit position within a leaf";
      ASSERT_EQ(kd.trees()[i].model, src.model);
      ASSERT_EQ(kd.trees()[i].rgba, src.rgba);
      ASSERT_NEAR(kd.trees()[i].normal[0] / 127.0, src.normal.x, 0.01);
    }
  }
  EXPECT_EQ(next, trees.size());
  EXPECT_GE(nonEmpty, 30u);
  // Every node box holds its trees' bounding spheres.
  const double r = std::sqrt(16.0 + 12.5 * 12.5);
  for (const ForestKdNode& node : kd.nodes()) {
    if (!node.isLeaf) continue;
    const ForestKdLeaf& leaf = kd.leaves()[node.child];
    for (uint32_t i = leaf.first; i < leaf.first + leaf.count; ++i) {
      const glm::dvec3 c = trees[kd.sourceIndex()[i]].base_m + glm::dvec3(0, 0, 12.5);
      ASSERT_TRUE(node.bounds.contains(c - r) && node.bounds.contains(c + r));
    }
  }
}

Camera randomCamera(std::mt19937& rng, const ForestKdTree& kd) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Camera cam;
  const ForestKdLeaf& any = kd.leaves()[kd.leaves().size() / 2];
  cam.eye_m = {u(rng) * 1600.0 - 30.0, u(rng) * 1600.0 - 30.0, any.region.min.z + 5.0 + u(rng) * 400.0};
  cam.heading_deg = u(rng) * 360.0;
  cam.pitch_deg = -60.0 + u(rng) * 70.0;
  cam.roll_deg = -10.0 + 20.0 * u(rng);
  cam.fovY_deg = 30.0 + 40.0 * u(rng);
  cam.near_m = 0.5;
  cam.far_m = 200.0 + 5000.0 * u(rng);
  return cam;
}

TEST(ForestKdTree, CullingIsConservativeAndOrderedFarToNear) {
  const auto trees = forest();
  ForestKdTree kd;
  std::string err;
  ASSERT_TRUE(kd.build(trees, params(), err)) << err;
  std::mt19937 rng(3);
  const NearFade fade{250.0, 450.0};
  size_t total = 0;
  for (int k = 0; k < 60; ++k) {
    const Camera cam = randomCamera(rng, kd);
    Selection sel(kd, cam, fade, trees.size());
    const auto expect = bruteForce(kd, cam, fade);
    ASSERT_EQ(sel.trees(), expect) << "camera " << k;
    ASSERT_EQ(sel.stats.dropped, 0u);
    total += sel.n;
    // Double-precision check on the original positions (a margin for quantisation).
    const Frustum fr = makeFrustum(cam);
    const auto drawn = sel.trees();
    std::set<uint32_t> drawnSrc;
    for (uint32_t t : drawn) drawnSrc.insert(kd.sourceIndex()[t]);
    const double R = std::sqrt(16.0 + 12.5 * 12.5);
    for (uint32_t i = 0; i < trees.size(); ++i) {
      const glm::dvec3 rel = trees[i].base_m - cam.eye_m;
      if (glm::length(rel) > fade.fadeOutEnd_m - 0.05) continue;
      const glm::dvec3 c = rel + glm::dvec3(0, 0, 12.5);
      bool inside = true;
      for (const auto& p : fr.planes) inside = inside && glm::dot(glm::dvec3(p), c) + p.w >= -R + 0.05;
      if (inside) {
        ASSERT_TRUE(drawnSrc.count(i)) << "tree " << i << " missed, camera " << k;
      }
    }
    // Per model: a contiguous range, far to near, alpha from the fade.
    uint32_t first = 0;
    for (size_t m = 0; m < sel.models.size(); ++m) {
      ASSERT_EQ(sel.models[m].first, first);
      first += sel.models[m].count;
      float prevD = std::numeric_limits<float>::infinity();
      for (uint32_t i = sel.models[m].first; i < sel.models[m].first + sel.models[m].count; ++i) {
        const ForestInstance& x = sel.inst[i];
        ASSERT_EQ(x.model, m);
        const float d = std::sqrt(x.offset_m[0] * x.offset_m[0] + x.offset_m[1] * x.offset_m[1] + x.offset_m[2] * x.offset_m[2]);
        ASSERT_LE(d, prevD + 450.0f / 65535.0f * 1.01f) << "far to near";
        prevD = std::min(prevD, d);
        ASSERT_NEAR(x.alpha, nearAlpha(fade, static_cast<double>(d)), 1e-5);
        if (i > sel.models[m].first) {
          ASSERT_GE(x.key, sel.inst[i - 1].key);
        }
      }
    }
    ASSERT_EQ(first, sel.n);
  }
  EXPECT_GT(total, 5000u) << "the random cameras should see trees";
}

TEST(ForestKdTree, StableForEqualKeys) {
  // Trees on one spot: equal keys keep kd order.
  std::vector<TreeInstance> t(50);
  for (size_t i = 0; i < t.size(); ++i) t[i].base_m = {100.0, 100.0, 0.0};
  ForestKdTree kd;
  std::string err;
  ASSERT_TRUE(kd.build(t, params(), err)) << err;
  Camera cam;
  cam.eye_m = {100.0, 50.0, 10.0};
  Selection sel(kd, cam, {100.0, 200.0}, 64);
  ASSERT_EQ(sel.n, 50u);
  for (size_t i = 1; i < sel.n; ++i) EXPECT_LT(sel.inst[i - 1].tree, sel.inst[i].tree);
}

TEST(ForestKdTree, HardCameras) {
  const auto trees = forest();
  ForestKdTree kd;
  std::string err;
  ASSERT_TRUE(kd.build(trees, params(), err)) << err;
  const NearFade fade{250.0, 450.0};
  // NaN anywhere in the camera: nothing.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (int field = 0; field < 4; ++field) {
    Camera cam;
    cam.eye_m = {700.0, 700.0, 200.0};
    if (field == 0) cam.eye_m.x = nan;
    if (field == 1) cam.heading_deg = nan;
    if (field == 2) cam.fovY_deg = nan;
    if (field == 3) cam.far_m = std::numeric_limits<double>::infinity();
    Selection sel(kd, cam, fade, trees.size());
    EXPECT_EQ(sel.n, 0u) << field;
  }
  Camera ok;
  ok.eye_m = {700.0, 700.0, 200.0};
  EXPECT_EQ(Selection(kd, ok, {1.0, std::numeric_limits<double>::quiet_NaN()}, 100).n, 0u);
  // Camera inside a leaf box, among the trees, looking level and straight down.
  const ForestKdLeaf* leaf = nullptr;
  for (const ForestKdLeaf& l : kd.leaves()) {
    if (l.count > 200) leaf = &l;
  }
  ASSERT_NE(leaf, nullptr);
  for (double pitch : {0.0, -90.0, 89.0}) {
    Camera cam;
    cam.eye_m = 0.5 * (leaf->region.min + leaf->region.max);
    cam.eye_m.z = leaf->region.min.z + 0.5 * (leaf->region.max.z - leaf->region.min.z);
    cam.pitch_deg = pitch;
    ASSERT_TRUE(leaf->region.contains(cam.eye_m));
    Selection sel(kd, cam, fade, trees.size());
    EXPECT_EQ(sel.trees(), bruteForce(kd, cam, fade)) << pitch;
    if (pitch == 0.0) {
      EXPECT_GT(sel.n, 100u);
    }
  }
}

TEST(ForestKdTree, FullOutputKeepsNearerTrees) {
  const auto trees = forest();
  ForestKdTree kd;
  std::string err;
  ASSERT_TRUE(kd.build(trees, params(), err)) << err;
  Camera cam;
  cam.eye_m = {700.0, 100.0, 350.0};
  cam.pitch_deg = -20.0;
  const NearFade fade{600.0, 900.0};
  Selection all(kd, cam, fade, trees.size());
  ASSERT_GT(all.n, 1000u);
  Selection some(kd, cam, fade, all.n / 4);
  EXPECT_EQ(some.n, all.n / 4);
  EXPECT_EQ(some.stats.dropped, all.n - all.n / 4);
  double meanAll = 0, meanSome = 0;
  for (size_t i = 0; i < all.n; ++i) meanAll += static_cast<double>(glm::length(glm::vec3(all.inst[i].offset_m[0], all.inst[i].offset_m[1], all.inst[i].offset_m[2])));
  for (size_t i = 0; i < some.n; ++i) meanSome += static_cast<double>(glm::length(glm::vec3(some.inst[i].offset_m[0], some.inst[i].offset_m[1], some.inst[i].offset_m[2])));
  EXPECT_LT(meanSome / static_cast<double>(some.n), meanAll / static_cast<double>(all.n));
}

TEST(ForestKdTree, EmptyForestAndBadInput) {
  ForestKdTree kd;
  std::string err;
  ASSERT_TRUE(kd.build({}, params(), err)) << err;
  EXPECT_EQ(kd.leaves().size(), 1u);
  EXPECT_EQ(kd.leaves()[0].count, 0u);
  Camera cam;
  EXPECT_EQ(Selection(kd, cam, {100.0, 200.0}, 10).n, 0u);
  EXPECT_EQ(Selection(kd, cam, {100.0, 200.0}, 0).n, 0u);

  std::vector<TreeInstance> t(3);
  t[1].base_m.y = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(kd.build(t, params(), err));
  EXPECT_NE(err.find("tree 1"), std::string::npos) << err;
  t[1].base_m.y = 0.0;
  t[2].model = 3;
  EXPECT_FALSE(kd.build(t, params(), err));
  EXPECT_NE(err.find("model = 3"), std::string::npos) << err;
  ForestKdParams p = params();
  p.leafSize_m = 0.0;
  EXPECT_FALSE(kd.build({}, p, err));
  EXPECT_NE(err.find("leafSize_m"), std::string::npos) << err;
}

TEST(ForestKdTree, HugeCoordinatesSelectTheSameTrees) {
  const glm::dvec3 far(4.1e6, -1.0e7, 3.0e5);  // ECEF-like: 4,100 km east, 10,000 km south
  const auto a = forest(), b = forest(far);
  ForestKdTree ka, kb;
  std::string err;
  ASSERT_TRUE(ka.build(a, params(), err)) << err;
  ASSERT_TRUE(kb.build(b, params(), err)) << err;
  std::mt19937 rng(11);
  for (int k = 0; k < 20; ++k) {
    Camera cam = randomCamera(rng, ka);
    Selection sa(ka, cam, {300.0, 500.0}, a.size());
    cam.eye_m += far;
    Selection sb(kb, cam, {300.0, 500.0}, b.size());
    std::set<uint32_t> srcA, srcB;
    for (uint32_t t : sa.trees()) srcA.insert(ka.sourceIndex()[t]);
    for (uint32_t t : sb.trees()) srcB.insert(kb.sourceIndex()[t]);
    // The same trees up to ones within millimetres of a boundary (rounding of the planes).
    size_t diff = 0;
    for (uint32_t t : srcA) diff += srcB.count(t) == 0;
    for (uint32_t t : srcB) diff += srcA.count(t) == 0;
    EXPECT_LE(diff, 2u + srcA.size() / 2000) << k;
    EXPECT_EQ(sb.trees(), bruteForce(kb, cam, {300.0, 500.0}));
  }
}

}  // namespace
