// Forest fins (lod/forest_fins.h): the dihedral-angle rule, glades, tangent-cone rejection.
#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "lod/forest_fins.h"
#include "forest_fixtures.h"

namespace {
using namespace ig::lod;

TEST(ForestFins, DihedralAngleConvention) {
  const glm::dvec3 a(0, 0, 0), b(0, 10, 0);
  // Faces (a, b, c) west and (b, a, d) east of the edge.
  EXPECT_NEAR(dihedralThroughGround_deg(a, b, {-10, 5, 0}, {10, 5, 0}), 180.0, 1e-9);    // flat
  EXPECT_NEAR(dihedralThroughGround_deg(a, b, {-10, 5, -10}, {10, 5, -10}), 90.0, 1e-9);  // 45 deg crest
  EXPECT_NEAR(dihedralThroughGround_deg(a, b, {-10, 5, 10}, {10, 5, 10}), 270.0, 1e-9);   // 45 deg valley
  EXPECT_NEAR(dihedralThroughGround_deg(a, b, {-10, 5, 0}, {10, 5, -10}), 135.0, 1e-9);   // slope break down
  EXPECT_TRUE(std::isnan(dihedralThroughGround_deg(a, b, {0, 5, 0}, {10, 5, 0})));       // degenerate face
}

// Heights: a sharp east-west crest along row 10 and a valley along row 30, flat elsewhere.
std::vector<float> crestValley(int n) {
  std::vector<float> h(static_cast<size_t>(n) * n, 0.0f);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      float z = 0.0f;
      if (y == 10) z = 20.0f;
      if (y == 30) z = -20.0f;
      h[static_cast<size_t>(y) * n + x] = z;
    }
  }
  return h;
}

TEST(ForestFins, OnlyWhereTheAngleRuleAllows) {
  const int n = 41;
  std::vector<glm::dvec3> pos;
  std::vector<uint32_t> tri;
  makeGridMesh(crestValley(n), n, n, 20.0, {0, 0, 0}, pos, tri);
  FinSet set;
  std::string err;
  FinParams p;
  p.criticalAngle_deg = 170.0;
  ASSERT_TRUE(buildFins(pos, tri, nullptr, p, set, err)) << err;
  EXPECT_EQ(set.edgesTested, static_cast<uint64_t>(3 * 40 * 40 - 2 * 40));  // interior edges
  ASSERT_FALSE(set.fins.empty());
  for (const Fin& f : set.fins) {
    EXPECT_LT(f.phi_deg, 170.0f);
    // Convex edges only: the crest row (y = 200 m, phi 90) and the valley rims (580, 620 m, phi 135).
    EXPECT_EQ(f.a_m.y, f.b_m.y);
    if (f.a_m.y == 200.0) {
      EXPECT_NEAR(f.phi_deg, 90.0, 1e-4);
    } else {
      EXPECT_TRUE(f.a_m.y == 580.0 || f.a_m.y == 620.0) << f.a_m.y;
      EXPECT_NEAR(f.phi_deg, 135.0, 1e-4);
    }
  }
  EXPECT_EQ(set.fins.size(), 120u);  // diagonals and cross edges touching these rows are flat
  EXPECT_EQ(set.edgesBelowAngle, set.fins.size());
  // A critical angle of 200 takes every edge but the concave ones (rows 180, 220, 600 m; 225-270).
  p.criticalAngle_deg = 200.0;
  FinSet all;
  ASSERT_TRUE(buildFins(pos, tri, nullptr, p, all, err)) << err;
  EXPECT_EQ(all.fins.size(), set.edgesTested - 120);
  for (const Fin& f : all.fins) EXPECT_LT(f.phi_deg, 200.0f);
  // Groups partition the fins, cones hold their tangents.
  size_t covered = 0;
  for (const FinGroup& g : all.groups) {
    ASSERT_EQ(g.first, covered);
    covered += g.count;
    for (uint32_t i = g.first; i < g.first + g.count; ++i) {
      const double c = std::abs(glm::dot(g.axis, glm::dvec3(all.fins[i].tangent)));
      ASSERT_LE(std::acos(std::min(1.0, c)), g.halfAngle_rad);
      ASSERT_TRUE(g.bounds.contains(all.fins[i].a_m) && g.bounds.contains(all.fins[i].b_m + glm::dvec3(0, 0, p.finHeight_m)));
    }
  }
  EXPECT_EQ(covered, all.fins.size());
}

TEST(ForestFins, NoneWhollyInGlades) {
  const int n = 41;
  std::vector<glm::dvec3> pos;
  std::vector<uint32_t> tri;
  test::finGridMesh(n, pos, tri);
  ForestMap map;
  map.width = map.height = 40;
  map.cell_m = 32.0;
  map.density.assign(1600, 1.0f);
  map.gr.assign(1600, 0xFF204020u);
  for (int y = 0; y < 40; ++y) {
    for (int x = 0; x < 20; ++x) map.gr[static_cast<size_t>(y) * 40 + x] = 0x00204020u;  // west half: glade
  }
  FinParams p;
  p.criticalAngle_deg = 178.0;
  FinSet noGlade, withGlade;
  std::string err;
  ASSERT_TRUE(buildFins(pos, tri, nullptr, p, noGlade, err)) << err;
  ASSERT_TRUE(buildFins(pos, tri, &map, p, withGlade, err)) << err;
  ASSERT_GT(noGlade.fins.size(), 100u);
  size_t wholly = 0;
  for (const Fin& f : noGlade.fins) wholly += std::max(f.a_m.x, f.b_m.x) < 640.0;
  ASSERT_GT(wholly, 20u);
  EXPECT_EQ(withGlade.fins.size(), noGlade.fins.size() - wholly);
  size_t touching = 0;
  for (const Fin& f : withGlade.fins) {
    EXPECT_GE(std::max(f.a_m.x, f.b_m.x), 640.0) << "a fin wholly in the glade";
    touching += std::min(f.a_m.x, f.b_m.x) < 640.0;
  }
  EXPECT_GT(touching, 0u) << "fins partly in a glade stay";
}

TEST(ForestFins, ConeRejectionIsConservative) {
  const int n = 65;
  std::vector<glm::dvec3> pos;
  std::vector<uint32_t> tri;
  test::finGridMesh(n, pos, tri);
  FinParams p;
  p.criticalAngle_deg = 178.0;
  p.tileSize_m = 128.0;
  FinSet set;
  std::string err;
  ASSERT_TRUE(buildFins(pos, tri, nullptr, p, set, err)) << err;
  ASSERT_GT(set.groups.size(), 50u);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  size_t rejected = 0, checked = 0;
  for (int k = 0; k < 200; ++k) {
    const glm::dvec3 eye(u(rng) * 8000.0 - 3000.0, u(rng) * 8000.0 - 3000.0, u(rng) * 600.0);
    const double thr = 0.02 + 0.3 * u(rng);
    for (const FinGroup& g : set.groups) {
      if (!finGroupTransparent(g, eye, thr)) continue;
      ++rejected;
      for (uint32_t i = g.first; i < g.first + g.count; ++i) {
        const Fin& f = set.fins[i];
        const glm::dvec3 up(0, 0, p.finHeight_m);
        for (const glm::dvec3& q : {f.a_m, f.b_m, f.a_m + up, f.b_m + up, 0.5 * (f.a_m + f.b_m + up)}) {
          ++checked;
          ASSERT_LT(finViewAlpha(glm::dvec3(f.tangent), eye, q), thr) << "group rejected with a visible fin";
        }
      }
    }
  }
  EXPECT_GT(rejected, 100u) << "the cone test should reject some groups";
  EXPECT_GT(checked, 1000u);
  // Eye inside a group's sphere: never rejected.
  EXPECT_FALSE(finGroupTransparent(set.groups[0], set.groups[0].centre_m, 0.9));
}

TEST(ForestFins, SelectionAndBadInput) {
  const int n = 33;
  HeightfieldDesc hd;
  hd.postsX = hd.postsY = n;
  std::vector<float> h(static_cast<size_t>(n) * n);
  generateHeightfield(hd, h);
  std::vector<glm::dvec3> pos;
  std::vector<uint32_t> tri;
  makeGridMesh(h, n, n, 32.0, {0, 0, 0}, pos, tri);
  FinSet set;
  std::string err;
  ASSERT_TRUE(buildFins(pos, tri, nullptr, {}, set, err)) << err;
  std::vector<uint32_t> out(set.groups.size());
  Camera cam;
  cam.eye_m = {-2000.0, 500.0, 300.0};
  cam.heading_deg = 90.0;
  cam.pitch_deg = -5.0;
  FinSelectStats st;
  const FarFade fade{400.0, 600.0, 6000.0, 8000.0};
  const size_t k = selectFinGroups(set.groups, cam, fade, 0.1, out, &st);
  EXPECT_GT(k, 0u);
  EXPECT_EQ(k + st.groupsRejected, st.groupsVisible);
  uint64_t fins = 0;
  for (size_t i = 0; i < k; ++i) fins += set.groups[out[i]].count;
  EXPECT_EQ(fins, st.finsDrawn);
  // Looking away: nothing. Beyond FarPlane: nothing. NaN camera: nothing.
  cam.heading_deg = 270.0;
  EXPECT_EQ(selectFinGroups(set.groups, cam, fade, 0.1, out), 0u);
  cam.heading_deg = 90.0;
  cam.eye_m.x = -9000.0;
  EXPECT_EQ(selectFinGroups(set.groups, cam, fade, 0.1, out), 0u);
  cam.eye_m.x = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(selectFinGroups(set.groups, cam, fade, 0.1, out), 0u);
  // Empty mesh: no fins, no groups.
  FinSet none;
  ASSERT_TRUE(buildFins({}, {}, nullptr, {}, none, err)) << err;
  EXPECT_TRUE(none.groups.empty());
  // Bad input names the value.
  EXPECT_FALSE(buildFins(pos, std::vector<uint32_t>{0, 1, 99999}, nullptr, {}, none, err));
  EXPECT_NE(err.find("99999"), std::string::npos) << err;
  FinParams bad;
  bad.criticalAngle_deg = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(buildFins(pos, tri, nullptr, bad, none, err));
  EXPECT_NE(err.find("criticalAngle_deg"), std::string::npos) << err;
}

}  // namespace
