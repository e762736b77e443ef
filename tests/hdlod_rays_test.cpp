// lod/hdlod_rays: segment queries against the objects of a 4D scene at a schedule time. Hits on
// known boxes (top, bottom, from inside, through a shared edge), moving and turning objects,
// presence at t = 0 and T, huge coordinates, NaN input, degenerate triangles, and random
// segments against a brute-force test of every present triangle.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>

#include "lod/hdlod_rays.h"
#include "lod/hdlod_scene.h"
#include "segment_triangle.h"

using namespace ig::lod::hdlod;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

Object place(uint32_t model, glm::dvec3 at, double heading_deg = 0.0, std::vector<Interval> visible = {{-kInf, kInf}}) {
  Object o;
  o.name.push_back('o');
  o.model = model;
  o.visible = std::move(visible);
  o.path = {{0.0, at, heading_deg}};
  return o;
}

// One 10 x 6 x 4 m box standing at `at`.
Scene oneBox(glm::dvec3 at, double heading_deg = 0.0) {
  Scene s;
  s.duration_s = 100.0;
  s.models.push_back(makeBoxModel("box", {10.0, 6.0, 4.0}));
  s.objects.push_back(place(0, at, heading_deg));
  return s;
}

// The first hit by brute force: every triangle of every present object, in world coordinates.
bool bruteForce(const Scene& s, glm::dvec3 from, glm::dvec3 to, double t_s, double& tHit) {
  tHit = kInf;
  for (const Object& o : s.objects) {
    if (!isPresent(o, t_s, s.duration_s)) continue;
    const glm::dmat4 m = objectMatrix(o, t_s, s.duration_s);
    const Model& model = s.models[o.model];
    // (Only a speed-up: an object whose box misses the segment's box has no triangle it meets.)
    const ig::lod::Aabb box = transformBox(model.box, m);
    const glm::dvec3 lo = glm::min(from, to), hi = glm::max(from, to);
    if (box.max.x < lo.x || box.max.y < lo.y || box.max.z < lo.z || box.min.x > hi.x || box.min.y > hi.y || box.min.z > hi.z)
      continue;
    for (size_t k = 0; k + 2 < model.indices.size(); k += 3) {
      glm::dvec3 v[3];
      for (int j = 0; j < 3; ++j) v[j] = glm::dvec3(m * glm::dvec4(glm::dvec3(model.positions[model.indices[k + j]]), 1.0));
      double t = 0.0;
      if (ig::test::segmentTriangle(from, to, v[0], v[1], v[2], t)) tHit = std::min(tHit, t);
    }
  }
  return tHit < kInf;
}

}  // namespace

TEST(HdlodRays, HitsTheTopFromAboveAndTheBottomFromBelow) {
  const Scene s = oneBox({100.0, 50.0, 10.0});
  const SceneRays rays(s);
  ASSERT_FALSE(rays.empty());
  EXPECT_EQ(rays.triangles(), 12u);
  RayHit hit;
  ASSERT_TRUE(rays.intersect({101.0, 49.0, 30.0}, {101.0, 49.0, 0.0}, 0.0, hit));
  EXPECT_NEAR(hit.point_m.z, 14.0, 1e-9);
  EXPECT_NEAR(hit.t, 16.0 / 30.0, 1e-12);
  EXPECT_NEAR(hit.normal.z, 1.0, 1e-12);  // faces the start
  ASSERT_TRUE(rays.intersect({101.0, 49.0, 0.0}, {101.0, 49.0, 30.0}, 0.0, hit));
  EXPECT_NEAR(hit.point_m.z, 10.0, 1e-9);
  EXPECT_NEAR(hit.normal.z, -1.0, 1e-12);
  // Beside the box, and a segment that stops short of it: no hit.
  EXPECT_FALSE(rays.intersect({106.0, 49.0, 30.0}, {106.0, 49.0, 0.0}, 0.0, hit));
  EXPECT_FALSE(rays.intersect({101.0, 49.0, 30.0}, {101.0, 49.0, 14.5}, 0.0, hit));
  // The top's diagonal (the edge two triangles share) is hit, not slipped through.
  ASSERT_TRUE(rays.intersect({100.0, 50.0, 30.0}, {100.0, 50.0, 0.0}, 0.0, hit));
  EXPECT_NEAR(hit.point_m.z, 14.0, 1e-9);
}

TEST(HdlodRays, FromInsideABoxTheFarWallIsHit) {
  const Scene s = oneBox({0.0, 0.0, 0.0});
  const SceneRays rays(s);
  RayHit hit;
  ASSERT_TRUE(rays.intersect({0.0, 0.0, 2.0}, {20.0, 0.0, 2.0}, 0.0, hit));
  EXPECT_NEAR(hit.point_m.x, 5.0, 1e-9);
  EXPECT_NEAR(hit.normal.x, -1.0, 1e-12);
  // A segment lying in the plane of a face: the face is not hit (parallel); the walls it crosses are.
  ASSERT_TRUE(rays.intersect({-20.0, 0.0, 4.0}, {20.0, 0.0, 4.0}, 0.0, hit));
  EXPECT_NEAR(hit.point_m.x, -5.0, 1e-9);
}

TEST(HdlodRays, MovingAndTurningObjectsAreWhereTheScheduleHasThemAtT) {
  Scene s;
  s.duration_s = 10.0;
  s.models.push_back(makeBoxModel("beam", {20.0, 1.0, 1.0}));  // long along x at heading 0
  Object o = place(0, {0.0, 0.0, 0.0});
  o.path = {{0.0, {0.0, 0.0, 0.0}, 0.0}, {10.0, {100.0, 0.0, 0.0}, 90.0}};
  s.objects.push_back(o);
  const SceneRays rays(s);
  RayHit hit;
  // t = 5: at x = 50, heading 45 deg (clockwise): the beam runs from its centre (50, 0) towards
  // south-east and north-west. Its centre is hit, a point 8 m east of it is not, (55, -5) is.
  ASSERT_TRUE(rays.intersect({50.0, 0.0, 10.0}, {50.0, 0.0, -1.0}, 5.0, hit));
  EXPECT_NEAR(hit.point_m.z, 1.0, 1e-9);
  EXPECT_FALSE(rays.intersect({0.0, 0.0, 10.0}, {0.0, 0.0, -1.0}, 5.0, hit));  // it has left x = 0
  EXPECT_FALSE(rays.intersect({58.0, 0.0, 10.0}, {58.0, 0.0, -1.0}, 5.0, hit));
  EXPECT_TRUE(rays.intersect({55.0, -5.0, 10.0}, {55.0, -5.0, -1.0}, 5.0, hit));  // on the diagonal
  EXPECT_FALSE(rays.intersect({55.0, 5.0, 10.0}, {55.0, 5.0, -1.0}, 5.0, hit));
  // t = 0 and T: the keyframes themselves; beyond T holds the last one; NaN reads as 0.
  EXPECT_TRUE(rays.intersect({9.0, 0.0, 10.0}, {9.0, 0.0, -1.0}, 0.0, hit));
  EXPECT_FALSE(rays.intersect({9.0, 0.0, 10.0}, {9.0, 0.0, -1.0}, 10.0, hit));
  EXPECT_TRUE(rays.intersect({100.0, 9.0, 10.0}, {100.0, 9.0, -1.0}, 10.0, hit));
  EXPECT_TRUE(rays.intersect({100.0, 9.0, 10.0}, {100.0, 9.0, -1.0}, 1e9, hit));
  EXPECT_TRUE(rays.intersect({9.0, 0.0, 10.0}, {9.0, 0.0, -1.0}, kNaN, hit));
  // The normal turns with the object: a side wall at T faces -x (heading 90: the beam along y).
  ASSERT_TRUE(rays.intersect({90.0, 0.0, 0.5}, {110.0, 0.0, 0.5}, 10.0, hit));
  EXPECT_NEAR(hit.point_m.x, 99.5, 1e-9);
  EXPECT_NEAR(hit.normal.x, -1.0, 1e-9);
}

TEST(HdlodRays, PresenceAtTheEndsOfTime) {
  Scene s = oneBox({0.0, 0.0, 0.0});
  s.duration_s = 10.0;
  s.objects[0].visible = {{5.0, 10.0}};  // reaches T: present at T
  s.models.push_back(makeBoxModel("early", {2.0, 2.0, 2.0}));
  s.objects.push_back(place(1, {30.0, 0.0, 0.0}, 0.0, {{0.0, 1.0}}));  // starts at 0: present at 0
  const SceneRays rays(s);
  RayHit hit;
  const glm::dvec3 a0{0.0, 0.0, 10.0}, a1{0.0, 0.0, -1.0}, b0{30.0, 0.0, 10.0}, b1{30.0, 0.0, -1.0};
  EXPECT_FALSE(rays.intersect(a0, a1, 0.0, hit));
  EXPECT_FALSE(rays.intersect(a0, a1, 4.999, hit));
  EXPECT_TRUE(rays.intersect(a0, a1, 5.0, hit));
  EXPECT_TRUE(rays.intersect(a0, a1, 10.0, hit));
  EXPECT_TRUE(rays.intersect(b0, b1, 0.0, hit));
  EXPECT_TRUE(rays.intersect(b0, b1, -5.0, hit));  // clamped to 0
  EXPECT_FALSE(rays.intersect(b0, b1, 1.0, hit));
  // Never present: not indexed.
  s.objects[1].visible.clear();
  const SceneRays none(s);
  EXPECT_FALSE(none.intersect(b0, b1, 0.0, hit));
}

TEST(HdlodRays, HugeCoordinatesKeepMillimetres) {
  // An object 10,000 km from the scene's origin (positions are doubles; the triangle test runs
  // in model space).
  const glm::dvec3 at{1e7 + 0.123, -1e7 + 0.456, 1000.0};
  const Scene s = oneBox(at, 33.0);
  const SceneRays rays(s);
  RayHit hit;
  ASSERT_TRUE(rays.intersect(at + glm::dvec3(0.2, 0.1, 100.0), at + glm::dvec3(0.2, 0.1, -10.0), 0.0, hit));
  EXPECT_NEAR(hit.point_m.z, 1004.0, 1e-6);
  EXPECT_NEAR(hit.point_m.x, at.x + 0.2, 1e-6);
  // A long oblique segment from the origin region.
  const glm::dvec3 from = at + glm::dvec3(-3000.0, 0.0, 3002.0), to = at + glm::dvec3(0.0, 0.0, 2.0);
  ASSERT_TRUE(rays.intersect(from, to, 0.0, hit));
  double tRef = 0.0;
  ASSERT_TRUE(bruteForce(s, from, to, 0.0, tRef));
  EXPECT_NEAR(hit.t * glm::length(to - from), tRef * glm::length(to - from), 1e-4);
}

TEST(HdlodRays, BadInputAndDegenerateTriangles) {
  Scene s = oneBox({0.0, 0.0, 0.0});
  // Two degenerate triangles in the model: a repeated vertex and three points on a line.
  Model& m = s.models[0];
  m.positions.push_back({0.0f, 0.0f, 9.0f});
  m.positions.push_back({1.0f, 0.0f, 9.0f});
  m.positions.push_back({2.0f, 0.0f, 9.0f});
  const uint32_t n = static_cast<uint32_t>(m.positions.size());
  m.indices.insert(m.indices.end(), {n - 3, n - 3, n - 2, n - 3, n - 2, n - 1});
  const SceneRays rays(s);
  EXPECT_EQ(rays.triangles(), 12u);
  EXPECT_EQ(rays.degenerateTriangles(), 2u);
  RayHit hit;
  EXPECT_FALSE(rays.intersect({1.0, 0.0, 20.0}, {1.0, 0.0, 8.5}, 0.0, hit));  // through the "line"
  EXPECT_FALSE(rays.intersect({kNaN, 0.0, 20.0}, {0.0, 0.0, 0.0}, 0.0, hit));
  EXPECT_FALSE(rays.intersect({0.0, 0.0, 20.0}, {0.0, kInf, 0.0}, 0.0, hit));
  EXPECT_FALSE(rays.intersect({0.0, 0.0, 2.0}, {0.0, 0.0, 2.0}, 0.0, hit));  // zero length, inside
  // An invalid scene (a NaN vertex): an empty index, never a hit.
  Scene bad = oneBox({0.0, 0.0, 0.0});
  bad.models[0].positions[0].x = std::numeric_limits<float>::quiet_NaN();
  const SceneRays empty(bad);
  EXPECT_TRUE(empty.empty());
  EXPECT_FALSE(empty.intersect({0.0, 0.0, 20.0}, {0.0, 0.0, -1.0}, 0.0, hit));
  const SceneRays defaulted;
  EXPECT_FALSE(defaulted.intersect({0.0, 0.0, 20.0}, {0.0, 0.0, -1.0}, 0.0, hit));
}

TEST(HdlodRays, RandomSegmentsMatchBruteForceAndMissesCostLittle) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Scene s;
  s.duration_s = 100.0;
  for (int k = 0; k < 5; ++k) s.models.push_back(makeBoxModel("m", {1.0 + 4.0 * u(rng), 1.0 + 4.0 * u(rng), 1.0 + 8.0 * u(rng)}));
  for (int i = 0; i < 1000; ++i) {
    Object o = place(static_cast<uint32_t>(i % 5), {400.0 * u(rng), 400.0 * u(rng), 2.0 * u(rng)}, 360.0 * u(rng));
    if (i % 3 == 0) o.visible = {{20.0 * u(rng), 50.0 + 50.0 * u(rng)}};
    if (i % 7 == 0) o.path.push_back({60.0, o.path[0].position_m + glm::dvec3(20.0 * u(rng), -20.0 * u(rng), 0.0), 360.0 * u(rng)});
    s.objects.push_back(o);
  }
  const SceneRays rays(s);
  int hits = 0;
  for (int q = 0; q < 300; ++q) {
    const glm::dvec3 from{400.0 * u(rng), 400.0 * u(rng), 15.0 * u(rng)};
    const glm::dvec3 to = from + glm::dvec3(80.0 * u(rng) - 40.0, 80.0 * u(rng) - 40.0, -15.0 * u(rng));
    const double t = 100.0 * u(rng);
    RayHit hit;
    double tRef = 0.0;
    const bool got = rays.intersect(from, to, t, hit), ref = bruteForce(s, from, to, t, tRef);
    ASSERT_EQ(got, ref) << "query " << q;
    if (got) {
      ++hits;
      EXPECT_NEAR(hit.t, tRef, 1e-9) << "query " << q;
      EXPECT_NEAR(glm::length(hit.normal), 1.0, 1e-9);
      EXPECT_LE(glm::dot(hit.normal, to - from), 0.0);
      EXPECT_TRUE(isPresent(s.objects[hit.object], t, s.duration_s));
    }
  }
  EXPECT_GT(hits, 30);
  // A segment far from every object visits the root only; one across the scene far fewer nodes
  // and triangles than the 1,000 objects' 12,000 triangles.
  RayWork miss;
  RayHit hit;
  EXPECT_FALSE(rays.intersect({-100.0, -100.0, 50.0}, {-50.0, -100.0, 50.0}, 50.0, hit, &miss));
  EXPECT_EQ(miss.nodes, 1u);
  EXPECT_EQ(miss.triangles, 0u);
  RayWork across;
  rays.intersect({0.0, 200.0, 1.0}, {400.0, 200.0, 1.0}, 50.0, hit, &across);
  EXPECT_LT(across.triangles, 1000u);
  EXPECT_GT(across.triangles, 0u);
}
