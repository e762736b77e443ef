// Hard cases the other test files leave out (docs/hard_cases.md has the whole matrix): the near
// and far planes 0.1 m / 100 km on ROAM with the eye a decimetre above the ground; the terrain
// chunks (lod/terrain_chunks.h) at huge coordinates, with a NaN camera and with the eye inside a
// chunk's box; an HDLOD cluster exactly half present (f = 0.5); degenerate (zero-area) faces in
// the forest's fin rule and zero-volume boxes in the dynamic objects' octree.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "lod/dynamic_octree.h"
#include "lod/forest_fins.h"
#include "lod/hdlod_build.h"
#include "lod/hdlod_select.h"
#include "lod/roam.h"
#include "lod/terrain_chunks.h"
#include "terrain_fixtures.h"

using namespace ig::lod;

namespace {

constexpr RoamMode kAllModes[] = {RoamMode::EnhMerge, RoamMode::MergeQueue, RoamMode::Rebuild, RoamMode::Deferred};

RoamView viewWithPlanes(const glm::dvec3& eye, double heading_deg, double pitch_deg, double near_m, double far_m) {
  RoamView v = test::terrainView(eye, heading_deg, pitch_deg, 1.0, 1080.0);
  v.camera.near_m = near_m;
  v.camera.far_m = far_m;
  return v;
}

// A triangle cap far above what these small DEMs need, and far below the default 2^20 (the pool
// and the chunks' buffer are sized from it).
RoamConfig smallCap() {
  RoamConfig c;
  c.maxTriangles = 1u << 15;
  return c;
}

struct Ranges {
  std::vector<TerrainDrawRange> ranges;
  size_t triangles = 0;
  double nearest_m = 0.0;
};

Ranges cullOf(const TerrainChunks& chunks, const Camera& cam, double nearReach_m) {
  Ranges r;
  r.triangles = chunks.cull(cam, r.ranges, nearReach_m, &r.nearest_m);
  return r;
}

}  // namespace

// ROAM with the near plane at 0.1 m and the far plane at 100 km (the terrain tests use 1 m), the
// eye 0.1 m above a vertex and looking level, down and up: the update finishes, the mesh stays
// crack-free and the promised screen-space error bound holds (roam.h: maxErrorPx <= tolerance).
TEST(HardCases, RoamNearPlaneTenCentimetresFarPlaneOneHundredKilometres) {
  const int n = 65;
  const auto hts = test::fractalHeights(n, n, 21, 400.0, 30.0);
  for (RoamMode mode : kAllModes) {
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallCap());
    for (double pitch : {0.0, -89.0, 60.0}) {
      const RoamView v = viewWithPlanes(roam.vertexPosition(20, 33) + glm::dvec3(0, 0, 0.1), 70, pitch, 0.1, 1.0e5);
      const RoamStats st = roam.update(v, mode);
      EXPECT_TRUE(st.finished) << static_cast<int>(mode) << " pitch " << pitch;
      std::string why;
      EXPECT_TRUE(roam.validate(&why)) << why;
      const double err = roam.maxErrorPx(v);
      EXPECT_TRUE(std::isfinite(err)) << static_cast<int>(mode) << " pitch " << pitch;
      EXPECT_LE(err, 1.0) << static_cast<int>(mode) << " pitch " << pitch;
    }
  }
}

// Terrain chunks ~1e7 m from the origin (ECEF-like: a float's step is 1 m there): the same DEM
// and the same eye relative to it give the same slots, the same draw ranges (near marks
// included) and the same nearest distance as at the origin.
TEST(HardCases, TerrainChunksAtHugeCoordinatesCullTheSameRanges) {
  const int n = 129;
  const auto hts = test::fractalHeights(n, n, 4, 400.0, 30.0);
  const glm::dvec3 far{4.1e6, 1.0e7, 0.0};
  Roam r0(hts, n, n, 30.0, {0, 0, 0}, smallCap());
  Roam r1(hts, n, n, 30.0, far, smallCap());
  TerrainChunks c0(r0), c1(r1);
  for (const glm::dvec3& eye : {glm::dvec3(1500, 800, 650), glm::dvec3(1920, 1920, 200)}) {
    for (double heading : {0.0, 250.0}) {
      RoamView v = viewWithPlanes(eye, heading, -20, 0.1, 1.0e5);
      r0.update(v, RoamMode::EnhMerge);
      c0.apply();
      const Ranges a = cullOf(c0, v.camera, 500.0);
      v.camera.eye_m += far;
      r1.update(v, RoamMode::EnhMerge);
      c1.apply();
      const Ranges b = cullOf(c1, v.camera, 500.0);
      ASSERT_EQ(r0.triangleCount(), r1.triangleCount()) << heading;
      EXPECT_EQ(a.triangles, b.triangles) << heading;
      ASSERT_EQ(a.ranges.size(), b.ranges.size()) << heading;
      for (size_t i = 0; i < a.ranges.size(); ++i) {
        EXPECT_EQ(a.ranges[i].first, b.ranges[i].first) << i;
        EXPECT_EQ(a.ranges[i].count, b.ranges[i].count) << i;
        EXPECT_EQ(a.ranges[i].near, b.ranges[i].near) << i;
      }
      EXPECT_NEAR(a.nearest_m, b.nearest_m, 1e-6) << heading;
      EXPECT_GT(a.triangles, 0u);
    }
  }
  std::string why;
  EXPECT_TRUE(c1.validate(&why)) << why;
}

// A NaN camera makes ROAM fall back to its base triangles (roam.h); the chunks follow: every
// base triangle in a slot, the chunks consistent, and a cull with that camera neither crashes
// nor reports a NaN distance or more triangles than are live. A finite camera afterwards draws
// as before.
TEST(HardCases, TerrainChunksFollowANaNCameraBackToTheBaseMesh) {
  const int n = 65;
  const auto hts = test::fractalHeights(n, n, 2, 400.0, 30.0);
  Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallCap());
  TerrainChunks chunks(roam);
  const RoamView good = viewWithPlanes({900, 900, 300}, 20, -20, 0.1, 1.0e5);
  roam.update(good, RoamMode::EnhMerge);
  chunks.apply();
  const Ranges before = cullOf(chunks, good.camera, 500.0);
  ASSERT_GT(roam.triangleCount(), roam.baseTriangles());
  RoamView bad = good;
  bad.camera.eye_m.x = std::numeric_limits<double>::quiet_NaN();
  roam.update(bad, RoamMode::EnhMerge);
  chunks.apply();
  EXPECT_EQ(roam.triangleCount(), roam.baseTriangles());
  EXPECT_EQ(chunks.liveTriangles(), roam.baseTriangles());
  std::string why;
  EXPECT_TRUE(chunks.validate(&why)) << why;
  const Ranges nan = cullOf(chunks, bad.camera, 500.0);
  EXPECT_LE(nan.triangles, chunks.liveTriangles());
  EXPECT_FALSE(std::isnan(nan.nearest_m));
  roam.update(good, RoamMode::EnhMerge);
  chunks.apply();
  EXPECT_TRUE(chunks.validate(&why)) << why;
  const Ranges after = cullOf(chunks, good.camera, 500.0);
  EXPECT_EQ(after.triangles, before.triangles);
  EXPECT_EQ(after.nearest_m, before.nearest_m);
}

// The eye inside a chunk's box (on the ground, 0.1 m near plane), looking level, down and up:
// the chunk under the eye is drawn (the nearest drawn chunk is at distance 0) and its range is
// marked near.
TEST(HardCases, TerrainChunksEyeInsideAChunkDrawsItAsNearest) {
  const int n = 65;
  const auto hts = test::fractalHeights(n, n, 9, 400.0, 30.0);
  Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallCap());
  TerrainChunks chunks(roam);
  const glm::dvec3 eye = roam.vertexPosition(30, 30) + glm::dvec3(0, 0, 0.1);
  for (double pitch : {0.0, -90.0, 90.0}) {
    const RoamView v = viewWithPlanes(eye, 45, pitch, 0.1, 1.0e5);
    roam.update(v, RoamMode::EnhMerge);
    chunks.apply();
    const Ranges r = cullOf(chunks, v.camera, 1.0);
    EXPECT_EQ(r.nearest_m, 0.0) << pitch;
    bool anyNear = false;
    for (const TerrainDrawRange& x : r.ranges) anyNear = anyNear || x.near == 1u;
    EXPECT_TRUE(anyNear) << pitch;
  }
}

// f = 0.5 exactly (paper 000: draw g_c when f_c(t) >= 0.5, skip below): two equal boxes, one
// present at t = 30, far away with a coarse r: the merged cluster is drawn, not skipped; at a
// time with f = 0 nothing is drawn.
TEST(HardCases, HdlodExactlyHalfPresentGoodEnoughClusterIsDrawn) {
  using namespace ig::lod::hdlod;
  const double T = 100;
  Scene s;
  s.duration_s = T;
  s.models.push_back(makeBoxModel("b", {1, 1, 1}));
  for (int i = 0; i < 2; ++i) {
    Object o;
    o.name = i == 0 ? "A" : "B";
    o.model = 0;
    o.path.push_back({0.0, glm::dvec3(1.5 * i, 0, 0), 0.0});
    o.visible = {{i == 0 ? 20.0 : 60.0, T}};
    s.objects.push_back(o);
  }
  const HdlodTree tree = buildHdlod(s);
  DrawList out(tree);
  SelectStats st;
  SelectView v;
  v.camera.eye_m = {0, -1000, 0};
  v.camera.fovY_deg = 60;
  v.camera.aspect = 1.0;
  v.camera.near_m = 0.1;
  v.camera.far_m = 1e5;
  v.tolerance_rad = 1.0;
  v.time_s = 30;
  ASSERT_EQ(selectHdlod(tree, s, v, out, &st), 1u);
  const Cluster& c = tree.clusters[out.draws[0].cluster];
  EXPECT_EQ(c.kind, ClusterKind::Merged);
  EXPECT_EQ(clusterPresence(tree, c, 30), 0.5);
  EXPECT_EQ(st.halfSkipped, 0u);
  v.time_s = 0;  // t = 0: nobody present yet
  EXPECT_EQ(selectHdlod(tree, s, v, out, &st), 0u);
  v.time_s = T;  // t = T: both present
  ASSERT_EQ(selectHdlod(tree, s, v, out, &st), 1u);
  EXPECT_EQ(tree.clusters[out.draws[0].cluster].kind, ClusterKind::Merged);
}

// Degenerate (zero-area) faces get no fin (forest_fins.h), neither from collinear nor from
// coincident vertices, while the same crest with a proper face gets one.
TEST(HardCases, ForestFinsSkipEdgesOfDegenerateFaces) {
  const glm::dvec3 a{0, 0, 0}, b{10, 0, 0}, c{5, 5, -5};
  const std::vector<uint32_t> tri{0, 1, 2, 1, 0, 3};
  FinParams p;
  for (const glm::dvec3& d : {glm::dvec3(5, -5, -5), glm::dvec3(5, 0, 0), glm::dvec3(0, 0, 0), glm::dvec3(20, 0, 0)}) {
    const std::vector<glm::dvec3> pos{a, b, c, d};
    FinSet set;
    std::string err;
    ASSERT_TRUE(buildFins(pos, tri, nullptr, p, set, err)) << err;
    EXPECT_EQ(set.edgesTested, 1u);
    const bool proper = d.y != 0.0;
    EXPECT_EQ(set.fins.size(), proper ? 1u : 0u) << d.x << " " << d.y;
    for (const Fin& f : set.fins) EXPECT_TRUE(std::isfinite(f.phi_deg));
  }
}

// Zero-volume boxes (a point object, a flat decal) are valid boxes (dynamic_octree.h refuses
// only non-finite or inverted ones): they are placed, moved and drawn when in view, also on a
// cell's mid plane and ~1e7 m from the origin.
TEST(HardCases, DynamicOctreeZeroVolumeBoxesArePlacedAndDrawn) {
  for (const glm::dvec3 shift : {glm::dvec3(0.0), glm::dvec3(2441.0 * 4096.0, -1220.0 * 4096.0, 1196.0 * 4096.0)}) {
    DynamicOctree t;
    OctreeConfig cfg;
    cfg.bounds = {shift + glm::dvec3(-128.0), shift + glm::dvec3(128.0)};
    cfg.maxDepth = 5;
    cfg.maxObjects = 16;
    ASSERT_TRUE(t.init(cfg));
    const Aabb point{shift + glm::dvec3(10, 20, 5), shift + glm::dvec3(10, 20, 5)};
    const Aabb flat{shift + glm::dvec3(-30, 40, 0), shift + glm::dvec3(-20, 50, 0)};  // on the root's mid plane z = 0
    const Aabb onMid{shift + glm::dvec3(0.0), shift + glm::dvec3(0.0)};
    ASSERT_TRUE(t.insert(0, point));
    ASSERT_TRUE(t.insert(1, flat));
    ASSERT_TRUE(t.insert(2, onMid));
    EXPECT_TRUE(t.move(0, Aabb{shift + glm::dvec3(11, 20, 5), shift + glm::dvec3(11, 20, 5)}));
    EXPECT_TRUE(t.checkInvariant());
    t.refresh();
    for (uint32_t id = 0; id < 3; ++id) {
      ASSERT_TRUE(t.contains(id));
      const Aabb& cell = t.nodes()[t.nodeOf(id)].cell;
      EXPECT_TRUE(cell.contains(t.boxOf(id).min) && cell.contains(t.boxOf(id).max)) << id;
    }
    // Looking down on all three from above: every object is drawn.
    Camera cam;
    cam.eye_m = shift + glm::dvec3(0, 20, 200);
    cam.pitch_deg = -90;
    cam.fovY_deg = 90;
    cam.aspect = 1.0;
    cam.near_m = 0.1;
    cam.far_m = 1e5;
    std::vector<uint32_t> draw(t.nodes().size()), tests(t.nodes().size());
    DynamicOctree::Traversal tr;
    tr.frame = 1;
    tr.eye_m = cam.eye_m;
    const auto r = t.traverse(makeFrustum(cam), tr, draw, tests);
    EXPECT_EQ(r.objectsDrawn, 3u) << shift.x;
  }
}
