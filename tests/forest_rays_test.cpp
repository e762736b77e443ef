// lod/forest_rays: segment queries against the near trees, each posed as the near pass draws it.
// The pose against the shader's formula, a trunk hit at a known distance, random segments
// through a small forest against a brute force over every tree's triangles (at the origin and
// 10,000 km out), NaN input, an empty forest, and the cost of a miss.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>

#include "lod/forest_kdtree.h"
#include "lod/forest_model.h"
#include "lod/forest_rays.h"
#include "segment_triangle.h"

using namespace ig::lod;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::vector<TreeMesh> models() {
  return {makeProceduralTree(ProceduralTree::Pine, 18.0), makeProceduralTree(ProceduralTree::Cypress, 12.0)};
}

ForestKdParams paramsFor(const std::vector<TreeMesh>& m) {
  ForestKdParams p;
  p.leafSize_m = 32.0;
  p.modelCount = static_cast<int>(m.size());
  for (const TreeMesh& t : m) {
    p.treeHeight_m = std::max(p.treeHeight_m, 1.1 * static_cast<double>(t.height_m));
    p.crownRadius_m = std::max(p.crownRadius_m, 1.1 * static_cast<double>(t.radius_m));
  }
  return p;
}

// `n` trees scattered over a 200 x 200 m square at `offset`, on gently rolling ground.
std::vector<TreeInstance> scatter(int n, glm::dvec3 offset, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<TreeInstance> trees;
  for (int i = 0; i < n; ++i) {
    TreeInstance t;
    const double x = 200.0 * u(rng), y = 200.0 * u(rng);
    t.base_m = offset + glm::dvec3(x, y, 3.0 * std::sin(0.05 * x) + 2.0 * std::cos(0.07 * y));
    t.model = static_cast<uint8_t>(i % 2);
    trees.push_back(t);
  }
  return trees;
}

// The first hit by brute force: every triangle of every tree, posed in world coordinates.
bool bruteForce(const ForestKdTree& kd, const std::vector<TreeMesh>& m, float jitter, glm::dvec3 from, glm::dvec3 to,
                double& tHit) {
  tHit = std::numeric_limits<double>::infinity();
  for (uint32_t i = 0; i < kd.trees().size(); ++i) {
    const TreeMesh& mesh = m[kd.trees()[i].model];
    const glm::dvec3 base = kd.decode(i);
    const TreePose pose = treePose(i, jitter);
    const double c = std::cos(pose.yaw_rad), s = std::sin(pose.yaw_rad);
    // Only a speed-up: trees whose bounding cylinder's box misses the segment's box.
    const double r = 1.2 * static_cast<double>(mesh.radius_m);
    if (std::max(from.x, to.x) < base.x - r || std::min(from.x, to.x) > base.x + r || std::max(from.y, to.y) < base.y - r ||
        std::min(from.y, to.y) > base.y + r)
      continue;
    for (size_t k = 0; k + 2 < mesh.indices.size(); k += 3) {
      glm::dvec3 v[3];
      for (int j = 0; j < 3; ++j) {
        const float* p = mesh.vertices[mesh.indices[k + static_cast<size_t>(j)]].position;
        const glm::dvec3 q(p[0], p[1], p[2]);
        v[j] = base + pose.scale * glm::dvec3(c * q.x - s * q.y, s * q.x + c * q.y, q.z);
      }
      double t = 0.0;
      if (ig::test::segmentTriangle(from, to, v[0], v[1], v[2], t)) tHit = std::min(tHit, t);
    }
  }
  return tHit < std::numeric_limits<double>::infinity();
}

}  // namespace

TEST(ForestRays, TreePoseIsTheShadersFormula) {
  // Jitter 0: no turn, no scale.
  EXPECT_EQ(treePose(123, 0.0f).yaw_rad, 0.0);
  EXPECT_EQ(treePose(123, 0.0f).scale, 1.0);
  // The shader: h = hash(i); yaw = (h & 0xffff) * 2 pi / 65536; scale = 1 + 0.2 ((h >> 16 & 0xff) / 255 - 0.5).
  // hash(0) = 0: yaw 0, scale 0.9.
  EXPECT_EQ(treePose(0, 1.0f).yaw_rad, 0.0);
  EXPECT_NEAR(treePose(0, 1.0f).scale, 0.9, 1e-7);
  double lo = 10.0, hi = 0.0, ylo = 10.0, yhi = -1.0;
  for (uint32_t i = 1; i < 2000; ++i) {
    const TreePose p = treePose(i, 1.0f);
    lo = std::min(lo, p.scale), hi = std::max(hi, p.scale);
    ylo = std::min(ylo, p.yaw_rad), yhi = std::max(yhi, p.yaw_rad);
  }
  EXPECT_GE(lo, 0.9 - 1e-6);
  EXPECT_LE(hi, 1.1 + 1e-6);
  EXPECT_LT(lo, 0.91);  // the range is used
  EXPECT_GT(hi, 1.09);
  EXPECT_GE(ylo, 0.0);
  EXPECT_LT(yhi, 2.0 * 3.14159265358979);
  EXPECT_GT(yhi, 6.2);
}

TEST(ForestRays, ALevelRayStopsAtTheTrunk) {
  const std::vector<TreeMesh> m = models();
  TreeInstance t;
  t.base_m = {50.0, 40.0, 7.0};
  ForestKdTree kd;
  std::string err;
  ASSERT_TRUE(kd.build(std::vector<TreeInstance>{t}, paramsFor(m), err)) << err;
  const ForestRays rays(kd, m, 0.0f);  // no pose: the mesh as built
  ASSERT_FALSE(rays.empty());
  // 0.5 m above the foot, below the crown: the trunk prism, whose faces lie between its apothem
  // and its radius from the axis.
  double trunk = 0.0;
  for (const TreeVertex& v : m[0].vertices)
    if (v.position[2] < 0.6f) trunk = std::max(trunk, std::hypot(static_cast<double>(v.position[0]), static_cast<double>(v.position[1])));
  TreeHit hit;
  const glm::dvec3 from = kd.decode(0) + glm::dvec3(-30.0, 0.0, 0.5), to = from + glm::dvec3(60.0, 0.0, 0.0);
  ASSERT_TRUE(rays.intersect(from, to, hit));
  const double dist = kd.decode(0).x - hit.point_m.x;
  EXPECT_LE(dist, trunk + 1e-9);
  EXPECT_GE(dist, trunk * std::cos(3.14159265358979 / 8.0) - 1e-9);
  EXPECT_LT(hit.normal.x, -0.9);  // facing the start
  EXPECT_EQ(hit.tree, 0u);
  // Over the tree, beside it, and stopping short of it: nothing.
  EXPECT_FALSE(rays.intersect(from + glm::dvec3(0.0, 0.0, 40.0), to + glm::dvec3(0.0, 0.0, 40.0), hit));
  EXPECT_FALSE(rays.intersect(from + glm::dvec3(0.0, 20.0, 0.0), to + glm::dvec3(0.0, 20.0, 0.0), hit));
  EXPECT_FALSE(rays.intersect(from, from + glm::dvec3(20.0, 0.0, 0.0), hit));
}

TEST(ForestRays, RandomSegmentsMatchBruteForceNearAndFarFromTheOrigin) {
  const std::vector<TreeMesh> m = models();
  for (const glm::dvec3 offset : {glm::dvec3(0.0), glm::dvec3(4.1e6, -1.0e7, 3.0e5)}) {
    ForestKdTree kd;
    std::string err;
    ASSERT_TRUE(kd.build(scatter(150, offset, 5), paramsFor(m), err)) << err;
    const ForestRays rays(kd, m, 1.0f);
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    int hits = 0;
    for (int q = 0; q < 200; ++q) {
      const glm::dvec3 from = offset + glm::dvec3(200.0 * u(rng), 200.0 * u(rng), 2.0 + 25.0 * u(rng));
      const glm::dvec3 to = from + glm::dvec3(120.0 * u(rng) - 60.0, 120.0 * u(rng) - 60.0, -20.0 * u(rng));
      TreeHit hit;
      double tRef = 0.0;
      const bool got = rays.intersect(from, to, hit), ref = bruteForce(kd, m, 1.0f, from, to, tRef);
      ASSERT_EQ(got, ref) << "query " << q;
      if (!got) continue;
      ++hits;
      EXPECT_NEAR(hit.t * glm::length(to - from), tRef * glm::length(to - from), 1e-6) << "query " << q;
      EXPECT_NEAR(glm::length(hit.normal), 1.0, 1e-9);
      EXPECT_LE(glm::dot(hit.normal, to - from), 0.0);
    }
    EXPECT_GT(hits, 20);  // 31 of 200 at the time of writing
  }
}

TEST(ForestRays, BadInputEmptyForestAndTheCostOfAMiss) {
  const std::vector<TreeMesh> m = models();
  ForestKdTree kd;
  std::string err;
  ASSERT_TRUE(kd.build(scatter(150, glm::dvec3(0.0), 5), paramsFor(m), err)) << err;
  const ForestRays rays(kd, m, 1.0f);
  TreeHit hit;
  EXPECT_FALSE(rays.intersect({kNaN, 10.0, 5.0}, {100.0, 100.0, 5.0}, hit));
  EXPECT_FALSE(rays.intersect({0.0, 10.0, 5.0}, {std::numeric_limits<double>::infinity(), 100.0, 5.0}, hit));
  EXPECT_FALSE(rays.intersect({100.0, 100.0, 5.0}, {100.0, 100.0, 5.0}, hit));  // zero length
  // Far outside the forest: the root's box only.
  RayWork w;
  EXPECT_FALSE(rays.intersect({-500.0, -500.0, 5.0}, {-400.0, -500.0, 5.0}, hit, &w));
  EXPECT_EQ(w.nodes, 1u);
  EXPECT_EQ(w.triangles, 0u);
  // A forest without trees, and a default index.
  ForestKdTree none;
  ASSERT_TRUE(none.build(std::vector<TreeInstance>{}, paramsFor(m), err)) << err;
  EXPECT_FALSE(ForestRays(none, m, 1.0f).intersect({0.0, 0.0, 5.0}, {100.0, 100.0, 5.0}, hit));
  EXPECT_FALSE(ForestRays().intersect({0.0, 0.0, 5.0}, {100.0, 100.0, 5.0}, hit));
  // A model without a mesh is never hit.
  EXPECT_FALSE(ForestRays(kd, std::vector<TreeMesh>{}, 1.0f).intersect({0.0, 100.0, 5.0}, {200.0, 100.0, 5.0}, hit));
}
