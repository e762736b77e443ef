// Near forest kd-tree (lod/forest_kdtree.h) and fins (lod/forest_fins.h), from a mutation-testing
// pass over lod/forest_kdtree.cpp and lod/forest_fins.cpp: each test pins one documented detail
// that forest_kdtree_test.cpp and forest_fins_test.cpp leave open (a mutant of it passed every
// test there, and forest_rays_test and hard_cases_test):
//   kd-tree
//   - build(): modelCount 1 ... 256 exactly; a side of exactly leafSize_m is not split; a leaf
//     size far below the forest's extent still gives a depth below kMaxDepth;
//   - packing: positions within half a quantisation step (region extent / 65535) per axis, both
//     normal components to the nearest 1/127;
//   - node boxes: tight in z (base z range + height / 2 -+ the sphere's radius), and an inner
//     node's box the union of its non-empty subtrees' (an empty leaf adds nothing);
//   - selection: d < fadeOutEnd strictly, the sphere of radius sqrt(crown^2 + (height/2)^2)
//     against the far plane, nodes outside the frustum not tested, each instance with its own
//     tree's colour, normal, model and decoded offset;
//   fins
//   - criticalAngle_deg in (0, 360) exclusive, an index equal to the vertex count is out of
//     range, an edge of three faces and flat ground (phi = 180 with criticalAngle 180) get no fin;
//   - the glade rule samples both endpoints and at most half a cell apart;
//   - tangent = unit (b - a); groups by tile, azimuth and elevation bin, both directions of a
//     line in one group;
//   - cone: an eye inside the sphere never rejects, the angle between the lines of C and Vc
//     (an eye on either side along the axis);
//   - selection: groups wholly nearer than FadeInStart are skipped, groups reaching beyond it
//     are not, nor groups between FadeOut and FarPlane.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "lod/forest_fins.h"
#include "lod/forest_kdtree.h"
#include "forest_fixtures.h"

using namespace ig::lod;

namespace {

// ---- kd-tree ---------------------------------------------------------------------------------

// The default tree: 25 m tall, crown radius 4 m: the sphere's radius.
const double kR = std::sqrt(4.0 * 4.0 + 12.5 * 12.5);

ForestKdParams oneModel() {
  ForestKdParams p;
  p.modelCount = 1;
  return p;
}

TreeInstance tree(double x, double y, double z = 0.0) {
  TreeInstance t;
  t.base_m = {x, y, z};
  return t;
}

struct Picked {
  std::vector<ForestInstance> inst, scratch;
  std::vector<ForestModelRange> models;
  size_t n = 0;
  ForestSelectStats stats;
  Picked(const ForestKdTree& kd, const Camera& cam, const NearFade& f)
      : inst(kd.trees().size() + 1), scratch(kd.trees().size() + 1), models(static_cast<size_t>(kd.params().modelCount)) {
    n = kd.select(cam, f, inst, scratch, models, &stats);
  }
  // Build indices of the trees drawn.
  std::vector<uint32_t> sources(const ForestKdTree& kd) const {
    std::vector<uint32_t> s;
    for (size_t i = 0; i < n; ++i) s.push_back(kd.sourceIndex()[inst[i].tree]);
    std::sort(s.begin(), s.end());
    return s;
  }
};

// Random trees over [x0, x0 + w] x [y0, y0 + h], z in [100, 180], with random normals, colours
// and models, none inside the optional hole.
std::vector<TreeInstance> randomTrees(uint32_t seed, size_t count, double x0, double y0, double w, double h, int models,
                                      Aabb hole = {glm::dvec3(0.0), glm::dvec3(0.0)}) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<TreeInstance> t;
  while (t.size() < count) {
    TreeInstance x = tree(x0 + w * u(rng), y0 + h * u(rng), 100.0 + 80.0 * u(rng));
    if (hole.contains({x.base_m.x, x.base_m.y, hole.min.z})) continue;
    x.normal = glm::vec3(static_cast<float>(1.2 * u(rng) - 0.6), static_cast<float>(1.2 * u(rng) - 0.6), 0.0f);
    x.normal.z = std::sqrt(1.0f - x.normal.x * x.normal.x - x.normal.y * x.normal.y);
    x.rgba = static_cast<uint32_t>(rng());
    x.model = static_cast<uint8_t>(rng() % static_cast<uint32_t>(models));
    t.push_back(x);
  }
  return t;
}

// "modelCount 1..256".
TEST(ForestKdTree, ModelCountIsOneTo256) {
  ForestKdTree kd;
  std::string err;
  ForestKdParams p;
  TreeInstance t = tree(0, 0);
  t.model = 255;
  p.modelCount = 256;
  EXPECT_TRUE(kd.build({&t, 1}, p, err)) << err;
  p.modelCount = 0;
  EXPECT_FALSE(kd.build({}, p, err));
  p.modelCount = 257;
  EXPECT_FALSE(kd.build({}, p, err));
}

// Split "while that side is longer than leafSize_m": leaves' sides lie in (L/2, L], a side of
// exactly L included.
TEST(ForestKdTree, ASideOfExactlyTheLeafSizeIsNotSplit) {
  ForestKdTree kd;
  std::string err;
  const std::vector<TreeInstance> one = {tree(0, 0), tree(256, 0), tree(100, 100)};
  ASSERT_TRUE(kd.build(one, oneModel(), err)) << err;
  ASSERT_EQ(kd.leaves().size(), 1u);
  EXPECT_DOUBLE_EQ(kd.leaves()[0].region.max.x - kd.leaves()[0].region.min.x, 256.0);
  const std::vector<TreeInstance> two = {tree(0, 0), tree(512, 0), tree(300, 200)};
  ASSERT_TRUE(kd.build(two, oneModel(), err)) << err;
  for (const ForestKdLeaf& leaf : kd.leaves()) {
    if (leaf.count == 0) continue;
    const double side = std::max(leaf.region.max.x - leaf.region.min.x, leaf.region.max.y - leaf.region.min.y);
    EXPECT_GT(side, 128.0);
    EXPECT_LE(side, 256.0);
  }
}

// A leaf size far below the forest's extent still builds a tree that select() can walk
// (kMaxDepth), and finds both trees.
TEST(ForestKdTree, ATinyLeafSizeKeepsTheDepthBounded) {
  ForestKdTree kd;
  std::string err;
  ForestKdParams p = oneModel();
  p.leafSize_m = 1e-60;
  const std::vector<TreeInstance> t = {tree(0, 0), tree(1000, 0)};
  ASSERT_TRUE(kd.build(t, p, err)) << err;
  EXPECT_LT(kd.depth(), ForestKdTree::kMaxDepth);
  Camera cam;
  cam.eye_m = {500, -2000, 10};
  cam.fovY_deg = 60.0;
  EXPECT_EQ(Picked(kd, cam, {3000.0, 4000.0}).n, 2u);
}

// "quantised to 16 bits per axis": min + q * step with step = extent / 65535, q rounded; the
// normal's two bytes rounded to 1/127.
TEST(ForestKdTree, PackingRoundsToTheNearestStep) {
  const auto trees = randomTrees(7, 500, 1000.0, 2000.0, 250.0, 240.0, 1);
  ForestKdTree kd;
  std::string err;
  ASSERT_TRUE(kd.build(trees, oneModel(), err)) << err;
  ASSERT_EQ(kd.leaves().size(), 1u);
  const ForestKdLeaf& leaf = kd.leaves()[0];
  for (uint32_t i = 0; i < kd.trees().size(); ++i) {
    const TreeInstance& src = trees[kd.sourceIndex()[i]];
    const glm::dvec3 p = kd.decode(i);
    for (int a = 0; a < 3; ++a) {
      const double ext = leaf.region.max[a] - leaf.region.min[a];
      ASSERT_LE(std::abs(p[a] - src.base_m[a]), 0.5 * ext / 65535.0 + 1e-4) << "tree " << i << " axis " << a;
    }
    ASSERT_LE(std::abs(kd.trees()[i].normal[0] / 127.0 - static_cast<double>(src.normal.x)), 0.5 / 127.0 + 1e-6) << i;
    ASSERT_LE(std::abs(kd.trees()[i].normal[1] / 127.0 - static_cast<double>(src.normal.y)), 0.5 / 127.0 + 1e-6) << i;
  }
}

// Recursion over the nodes: the union of the non-empty leaves' boxes below `node`.
bool unionBelow(const ForestKdTree& kd, uint32_t node, Aabb& out) {
  const ForestKdNode& n = kd.nodes()[node];
  if (n.isLeaf) {
    if (kd.leaves()[n.child].count == 0) return false;
    out = n.bounds;
    return true;
  }
  Aabb a, b;
  const bool ha = unionBelow(kd, n.child, a), hb = unionBelow(kd, n.child + 1, b);
  if (ha && hb) out = {glm::min(a.min, b.min), glm::max(a.max, b.max)};
  else if (ha) out = a;
  else if (hb) out = b;
  return ha || hb;
}

// "Nodes keep a tight box of their trees grown by the largest model's crown radius and height":
// a leaf's z range is its trees' sphere range, an inner node's box the union of its non-empty
// subtrees (a glade's empty leaf adds nothing, e.g. the origin).
TEST(ForestKdTree, NodeBoxesAreTight) {
  // 1,000 x 700 m (corner trees fix the rectangle): leaves of 250 x 175 m, four of them in the
  // glade.
  const Aabb glade{{5240, 3160, 0}, {5760, 3540, 1000}};
  auto trees = randomTrees(3, 3000, 5000.0, 3000.0, 1000.0, 700.0, 2, glade);
  trees.push_back(tree(5000, 3000, 120));
  trees.push_back(tree(6000, 3700, 150));
  ForestKdTree kd;
  std::string err;
  ForestKdParams p;
  ASSERT_TRUE(kd.build(trees, p, err)) << err;
  const double tol = 1e-5 * kR + 2e-3;
  size_t empty = 0;
  for (const ForestKdNode& node : kd.nodes()) {
    if (!node.isLeaf) continue;
    const ForestKdLeaf& leaf = kd.leaves()[node.child];
    if (leaf.count == 0) {
      ++empty;
      continue;
    }
    double z0 = 1e300, z1 = -1e300;
    for (uint32_t i = leaf.first; i < leaf.first + leaf.count; ++i) {
      z0 = std::min(z0, trees[kd.sourceIndex()[i]].base_m.z);
      z1 = std::max(z1, trees[kd.sourceIndex()[i]].base_m.z);
    }
    EXPECT_NEAR(node.bounds.min.z, z0 + 12.5 - kR, tol);
    EXPECT_NEAR(node.bounds.max.z, z1 + 12.5 + kR, tol);
    EXPECT_NEAR(node.bounds.min.x, leaf.region.min.x - kR, tol);
    EXPECT_NEAR(node.bounds.max.y, leaf.region.max.y + kR, tol);
  }
  ASSERT_GT(empty, 0u) << "the glade should leave an empty leaf";
  for (uint32_t i = 0; i < kd.nodes().size(); ++i) {
    Aabb u;
    if (kd.nodes()[i].isLeaf || !unionBelow(kd, i, u)) continue;
    EXPECT_EQ(kd.nodes()[i].bounds.min, u.min) << "node " << i;
    EXPECT_EQ(kd.nodes()[i].bounds.max, u.max) << "node " << i;
  }
}

Camera lookingEast() {
  Camera cam;
  cam.heading_deg = 90.0;
  return cam;
}

// "its distance d = |base - eye| is below near.fadeOutEnd_m".
TEST(ForestKdTree, ATreeExactlyAtTheRangeIsNotDrawn) {
  ForestKdTree kd;
  std::string err;
  const std::vector<TreeInstance> t = {tree(100, 0)};
  ASSERT_TRUE(kd.build(t, oneModel(), err)) << err;
  EXPECT_EQ(Picked(kd, lookingEast(), {50.0, 100.0}).n, 0u);
  EXPECT_EQ(Picked(kd, lookingEast(), {50.0, 100.01}).n, 1u);
}

// The bounding sphere: centre base + (0, 0, height/2), radius sqrt(crown^2 + (height/2)^2), tested
// against the far plane too. Two trees on the view axis just inside and just beyond it.
TEST(ForestKdTree, TheSphereOfTheLargestModelMeetsTheFarPlane) {
  ForestKdTree kd;
  std::string err;
  const std::vector<TreeInstance> t = {tree(0, 100 + kR - 0.05, -12.5), tree(0, 100 + kR + 0.05, -12.5)};
  ASSERT_TRUE(kd.build(t, oneModel(), err)) << err;
  Camera cam;  // at the origin looking north
  cam.near_m = 0.5;
  cam.far_m = 100.0;
  const Picked p(kd, cam, {1000.0, 2000.0});
  EXPECT_EQ(p.sources(kd), std::vector<uint32_t>{0});
}

// "Nodes are culled against the frustum ... first": looking away from every tree in range, no
// tree is tested.
TEST(ForestKdTree, TreesOfNodesOutsideTheFrustumAreNotTested) {
  const auto trees = randomTrees(5, 400, -100.0, 20.0, 200.0, 180.0, 1);
  ForestKdTree kd;
  std::string err;
  ASSERT_TRUE(kd.build(trees, oneModel(), err)) << err;
  Camera cam;
  cam.eye_m = {0, 0, 140};
  const Picked ahead(kd, cam, {500.0, 600.0});
  EXPECT_GT(ahead.n, 0u);
  EXPECT_GT(ahead.stats.treesTested, 0u);
  cam.heading_deg = 180.0;
  const Picked away(kd, cam, {500.0, 600.0});
  EXPECT_EQ(away.n, 0u);
  EXPECT_EQ(away.stats.treesTested, 0u);
}

// Each instance carries its own tree's colour, normal and model, and its decoded eye-relative
// position.
TEST(ForestKdTree, InstancesCarryTheirTreesData) {
  const auto trees = randomTrees(9, 600, 0.0, 0.0, 500.0, 500.0, 3);
  ForestKdTree kd;
  std::string err;
  ForestKdParams p;
  p.modelCount = 3;
  ASSERT_TRUE(kd.build(trees, p, err)) << err;
  Camera cam;
  cam.eye_m = {250, -50, 200};
  cam.pitch_deg = -20.0;
  cam.fovY_deg = 60.0;
  const Picked sel(kd, cam, {500.0, 700.0});
  ASSERT_GT(sel.n, 100u);
  for (size_t i = 0; i < sel.n; ++i) {
    const ForestInstance& x = sel.inst[i];
    const PackedTree& t = kd.trees()[x.tree];
    ASSERT_EQ(x.rgba, t.rgba) << i;
    ASSERT_EQ(x.normal[0], t.normal[0]) << i;
    ASSERT_EQ(x.normal[1], t.normal[1]) << i;
    ASSERT_EQ(x.model, t.model) << i;
    const glm::vec3 rel = kd.decodeRelative(x.tree, cam.eye_m);
    ASSERT_EQ(x.offset_m[0], rel.x) << i;
    ASSERT_EQ(x.offset_m[1], rel.y) << i;
    ASSERT_EQ(x.offset_m[2], rel.z) << i;
  }
}

// ---- fins ------------------------------------------------------------------------------------

// A crest: the faces (a, b, c) and (b, a, d), counter-clockwise from above, falling 10 m to 20 m
// either side of the edge a -> b (phi about 127 degrees). Appended to `pos` and `tri`.
void crest(glm::dvec3 a, glm::dvec3 b, std::vector<glm::dvec3>& pos, std::vector<uint32_t>& tri) {
  const glm::dvec3 dir = glm::normalize(b - a), left(-dir.y, dir.x, 0.0), mid = 0.5 * (a + b);
  const auto base = static_cast<uint32_t>(pos.size());
  pos.insert(pos.end(), {a, b, mid + 20.0 * left - glm::dvec3(0, 0, 10), mid - 20.0 * left - glm::dvec3(0, 0, 10)});
  tri.insert(tri.end(), {base, base + 1, base + 2, base + 1, base, base + 3});
}

TEST(ForestFins, ParametersAndIndicesAtTheirBounds) {
  std::vector<glm::dvec3> pos;
  std::vector<uint32_t> tri;
  crest({0, 0, 10}, {10, 0, 10}, pos, tri);
  FinSet set;
  std::string err;
  FinParams p;
  ASSERT_TRUE(buildFins(pos, tri, nullptr, p, set, err)) << err;
  EXPECT_EQ(set.fins.size(), 1u);
  p.criticalAngle_deg = 360.0;  // "in (0, 360)"
  EXPECT_FALSE(buildFins(pos, tri, nullptr, p, set, err));
  tri[5] = static_cast<uint32_t>(pos.size());  // one past the last vertex
  EXPECT_FALSE(buildFins(pos, tri, nullptr, {}, set, err));
}

// "edges of more than two faces get no fin"; "phi = 180 on flat ground", and a fin needs
// phi < criticalAngle_deg.
TEST(ForestFins, NoFinOnAnEdgeOfThreeFacesNorOnFlatGroundAtACriticalAngleOf180) {
  std::vector<glm::dvec3> pos;
  std::vector<uint32_t> tri;
  crest({0, 0, 10}, {10, 0, 10}, pos, tri);
  pos.push_back({5, -5, -30});
  tri.insert(tri.end(), {1, 0, 4});  // a third face on the edge
  FinSet set;
  std::string err;
  ASSERT_TRUE(buildFins(pos, tri, nullptr, {}, set, err)) << err;
  EXPECT_TRUE(set.fins.empty());
  const std::vector<float> flat(25, 3.0f);
  makeGridMesh(flat, 5, 5, 10.0, {0, 0, 0}, pos, tri);
  FinParams p;
  p.criticalAngle_deg = 180.0;
  ASSERT_TRUE(buildFins(pos, tri, nullptr, p, set, err)) << err;
  EXPECT_GT(set.edgesTested, 0u);
  EXPECT_TRUE(set.fins.empty());
}

// A 12 x 3 map of 32 m cells, all glade but cell (forestX, 1).
ForestMap gladeBut(int forestX) {
  ForestMap map;
  map.width = 12;
  map.height = 3;
  map.cell_m = 32.0;
  map.density.assign(36, 1.0f);
  map.gr.assign(36, 0x00204020u);
  map.gr[static_cast<size_t>(12 + forestX)] = 0xFF204020u;
  return map;
}

// "the glade mask at every sample along the edge, samples at most half a map cell apart,
// endpoints included": one forest cell in the middle of a long edge, or under its end b, keeps it.
TEST(ForestFins, TheGladeRuleSamplesEveryHalfCellAndBothEnds) {
  std::string err;
  FinSet set;
  {
    std::vector<glm::dvec3> pos;
    std::vector<uint32_t> tri;
    crest({16, 48, 10}, {304, 48, 10}, pos, tri);
    ASSERT_TRUE(buildFins(pos, tri, nullptr, {}, set, err)) << err;
    ASSERT_EQ(set.fins.size(), 1u);
    const ForestMap map = gladeBut(4);  // x in [128, 160)
    ASSERT_TRUE(buildFins(pos, tri, &map, {}, set, err)) << err;
    EXPECT_EQ(set.fins.size(), 1u) << "a 32 m forest cell under a 288 m edge";
    const ForestMap none = gladeBut(11);  // off the edge: wholly in glades
    ASSERT_TRUE(buildFins(pos, tri, &none, {}, set, err)) << err;
    EXPECT_TRUE(set.fins.empty());
  }
  std::vector<glm::dvec3> pos;
  std::vector<uint32_t> tri;
  crest({16, 48, 10}, {300, 48, 10}, pos, tri);
  const ForestMap map = gladeBut(9);  // x in [288, 320): only b
  ASSERT_TRUE(buildFins(pos, tri, &map, {}, set, err)) << err;
  EXPECT_EQ(set.fins.size(), 1u) << "the end b in the forest";
}

// "tangent: unit (b - a)"; both directions of one line fold to the same tangent bin: two parallel
// crests in one tile, one drawn west to east, one east to west, make one group.
TEST(ForestFins, TangentsRunFromAToBAndOppositeDirectionsShareAGroup) {
  std::vector<glm::dvec3> pos;
  std::vector<uint32_t> tri;
  crest({0, 0, 10}, {10, 0, 10}, pos, tri);
  crest({30, 0, 10}, {20, 0, 10}, pos, tri);
  FinSet set;
  std::string err;
  ASSERT_TRUE(buildFins(pos, tri, nullptr, {}, set, err)) << err;
  ASSERT_EQ(set.fins.size(), 2u);
  for (const Fin& f : set.fins) {
    const glm::dvec3 t = glm::normalize(f.b_m - f.a_m);
    EXPECT_NEAR(f.tangent.x, t.x, 1e-6);
    EXPECT_NEAR(f.tangent.y, t.y, 1e-6);
  }
  EXPECT_NE(set.fins[0].tangent.x, set.fins[1].tangent.x);
  EXPECT_EQ(set.groups.size(), 1u);
}

// Groups by ground tile (tileSize_m): the midpoints of a group's fins lie within one tile.
TEST(ForestFins, AGroupStaysInOneTile) {
  const int n = 41;
  std::vector<float> h(static_cast<size_t>(n) * n, 0.0f);
  for (int x = 0; x < n; ++x) h[static_cast<size_t>(10 * n + x)] = 20.0f;  // a crest along x
  std::vector<glm::dvec3> pos;
  std::vector<uint32_t> tri;
  makeGridMesh(h, n, n, 20.0, {0, 0, 0}, pos, tri);
  FinParams p;
  p.criticalAngle_deg = 170.0;
  p.tileSize_m = 128.0;
  FinSet set;
  std::string err;
  ASSERT_TRUE(buildFins(pos, tri, nullptr, p, set, err)) << err;
  ASSERT_GT(set.groups.size(), 4u);
  for (const FinGroup& g : set.groups) {
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    for (uint32_t i = g.first; i < g.first + g.count; ++i) {
      const glm::dvec3 m = 0.5 * (set.fins[i].a_m + set.fins[i].b_m);
      x0 = std::min(x0, m.x), x1 = std::max(x1, m.x), y0 = std::min(y0, m.y), y1 = std::max(y1, m.y);
    }
    EXPECT_LT(x1 - x0, p.tileSize_m);
    EXPECT_LT(y1 - y0, p.tileSize_m);
  }
}

// Groups by tangent bin: a group's folded tangents lie within one azimuth bin (180 / azimuthBins
// degrees) and one elevation bin (180 / elevationBins).
TEST(ForestFins, AGroupStaysInOneTangentBin) {
  const int n = 33;
  std::vector<glm::dvec3> pos;
  std::vector<uint32_t> tri;
  test::finGridMesh(n, pos, tri);
  FinParams p;
  p.criticalAngle_deg = 178.0;
  p.tileSize_m = 4096.0;  // one tile
  p.azimuthBins = 12;
  p.elevationBins = 12;
  FinSet set;
  std::string err;
  ASSERT_TRUE(buildFins(pos, tri, nullptr, p, set, err)) << err;
  ASSERT_GT(set.groups.size(), 3u);
  const double pi = std::acos(-1.0);
  for (const FinGroup& g : set.groups) {
    double a0 = 1e300, a1 = -1e300, e0 = 1e300, e1 = -1e300;
    for (uint32_t i = g.first; i < g.first + g.count; ++i) {
      glm::dvec3 t(set.fins[i].tangent);
      if (t.y < 0.0 || (t.y == 0.0 && t.x < 0.0)) t = -t;
      const double az = std::atan2(t.y, t.x), el = std::asin(std::clamp(t.z, -1.0, 1.0));
      a0 = std::min(a0, az), a1 = std::max(a1, az), e0 = std::min(e0, el), e1 = std::max(e1, el);
    }
    EXPECT_LE(a1 - a0, pi / 12 + 1e-9);
    EXPECT_LE(e1 - e0, pi / 12 + 1e-9);
  }
}

FinGroup handGroup() {
  FinGroup g;
  g.bounds = {{-1, -1, -1}, {1, 1, 1}};
  g.centre_m = glm::dvec3(0.0);
  g.radius_m = 10.0;
  g.axis = {1, 0, 0};
  g.halfAngle_rad = 0.01;
  g.count = 1;
  return g;
}

// "an eye inside the sphere never rejects", whatever the threshold.
TEST(ForestFins, AnEyeInsideTheSphereNeverRejects) {
  EXPECT_FALSE(finGroupTransparent(handGroup(), {5, 0, 0}, 1.5));
  EXPECT_FALSE(finGroupTransparent(handGroup(), {0, 9.9, 0}, 1.5));
}

// gamma is the angle between the lines of C and Vc: an eye far out on either side along the
// axis sees the fins edge-on, and the group is rejected from both.
TEST(ForestFins, TheConeTestIsSymmetricAlongTheAxis) {
  FinGroup g = handGroup();
  g.radius_m = 1.0;
  EXPECT_TRUE(finGroupTransparent(g, {100, 0, 0}, 0.1));
  EXPECT_TRUE(finGroupTransparent(g, {-100, 0, 0}, 0.1));
  EXPECT_FALSE(finGroupTransparent(g, {0, 100, 0}, 0.1));
}

// "Groups ... wholly nearer than FadeInStart (farAlpha = 0 there) are skipped": one whose
// farthest corner is beyond FadeInStart is drawn.
TEST(ForestFins, OnlyGroupsWhollyNearerThanFadeInStartAreSkipped) {
  FinGroup across = handGroup(), inside = handGroup();
  across.bounds = {{-10, 390, 0}, {10, 410, 20}};  // 390 ... 410.6 m
  inside.bounds = {{-10, 100, 0}, {10, 120, 20}};  // 100 ... 122 m
  FinGroup fading = handGroup();  // between FadeOut and FarPlane: farAlpha > 0
  fading.bounds = {{-10, 6990, 0}, {10, 7010, 20}};
  const std::vector<FinGroup> groups = {across, inside, fading};
  std::vector<uint32_t> out(3);
  Camera cam;  // at the origin looking north
  const size_t n = selectFinGroups(groups, cam, FarFade{400.0, 600.0, 6000.0, 8000.0}, 0.0, out);
  ASSERT_EQ(n, 2u);
  EXPECT_EQ(out[0], 0u);
  EXPECT_EQ(out[1], 2u);
}

}  // namespace
