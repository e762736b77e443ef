// lod/roam: ROAM with split / merge queues and enhMerge. Crack-freeness (validate) along a
// flight path in every mode, the error bound, interruption at any point, enhMerge vs single
// merges after a teleport, and the hard cases (flat, cliff, camera on a vertex / below the
// surface / NaN, huge coordinates, tiny and non-power-of-two DEMs, triangle cap, tiny pool).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include "lod/heightfield.h"
#include "lod/roam.h"
#include "terrain_fixtures.h"

using namespace ig::lod;
using ig::lod::test::tilesDem;

namespace {

// Every mode; Deferred refines the surroundings too (the others only the frustum).
using test::kAllModes;
using test::modeName;

std::vector<float> fractal(int w, int h, uint32_t seed = 7, double scale_m = 400.0, double spacing_m = 30.0) {
  return test::fractalHeights(w, h, seed, scale_m, spacing_m);
}

// Independent pseudo-random heights (no flat patches, so every diamond has an error).
std::vector<float> noise(int w, int h, uint32_t seed = 1) {
  std::vector<float> hts(static_cast<size_t>(w) * static_cast<size_t>(h));
  uint32_t s = seed * 2654435761u + 1u;
  for (float& v : hts) {
    s = s * 1664525u + 1013904223u;
    v = 100.0f + static_cast<float>(s >> 8) / static_cast<float>(1u << 24) * 50.0f;
  }
  return hts;
}

RoamConfig smallConfig(uint64_t maxTriangles = 200000) {
  RoamConfig c;
  c.maxTriangles = maxTriangles;
  return c;
}

RoamView makeView(const glm::dvec3& eye, double heading_deg, double pitch_deg, double tolerance_px = 2.0) {
  return test::terrainView(eye, heading_deg, pitch_deg, tolerance_px, 1080.0);
}

// A flight over a 257 x 257 terrain at 30 m spacing (7.7 km): straight and level, hard turns,
// a dive, and two teleports.
std::vector<RoamView> flightPath() {
  std::vector<RoamView> path;
  glm::dvec3 eye{1500.0, 800.0, 650.0};
  double heading = 10.0;
  for (int i = 0; i < 20; ++i) {  // cruise north-east
    eye += glm::dvec3(std::sin(heading * 0.0174533), std::cos(heading * 0.0174533), 0.0) * 60.0;
    path.push_back(makeView(eye, heading, -15.0));
  }
  for (int i = 0; i < 8; ++i) {  // hard right turn, 25 degrees a frame
    heading += 25.0;
    eye += glm::dvec3(std::sin(heading * 0.0174533), std::cos(heading * 0.0174533), 0.0) * 60.0;
    path.push_back(makeView(eye, heading, -15.0));
  }
  for (int i = 0; i < 6; ++i) {  // dive towards the ground
    eye.z -= 60.0;
    path.push_back(makeView(eye, heading, -35.0));
  }
  path.push_back(makeView({6500.0, 6500.0, 900.0}, 225.0, -20.0));  // teleport
  for (int i = 0; i < 5; ++i) path.push_back(makeView({6500.0 - 40.0 * i, 6500.0 - 40.0 * i, 900.0}, 225.0, -20.0));
  path.push_back(makeView({300.0, 7000.0, 500.0}, 135.0, -10.0));  // teleport
  path.push_back(makeView({300.0, 7000.0, 500.0}, 315.0, -10.0));  // turn around in one frame
  return path;
}

using test::sortedTriangles;

#define EXPECT_VALID(roam)                  \
  do {                                      \
    std::string why_;                       \
    EXPECT_TRUE((roam).validate(&why_)) << why_; \
  } while (0)

}  // namespace

TEST(Roam, GridLayoutForAnyDemSize) {
  struct Case {
    int w, h, maxLevel, base, px, py;
  };
  const Case cases[] = {{2, 2, 0, 2, 2, 2},     {3, 3, 2, 2, 3, 3},     {5, 5, 4, 2, 5, 5},
                        {17, 17, 8, 2, 17, 17}, {100, 37, 10, 16, 129, 65}, {9, 2, 0, 16, 9, 2}};
  for (const Case& c : cases) {
    const auto hts = fractal(c.w, c.h);
    const Roam roam(hts, c.w, c.h, 30.0, {0, 0, 0}, smallConfig(10000));
    EXPECT_EQ(roam.maxLevel(), c.maxLevel) << c.w << "x" << c.h;
    EXPECT_EQ(roam.baseTriangles(), static_cast<size_t>(c.base)) << c.w << "x" << c.h;
    EXPECT_EQ(roam.gridWidth(), c.px);
    EXPECT_EQ(roam.gridHeight(), c.py);
    EXPECT_EQ(roam.triangleCount(), roam.baseTriangles());
    EXPECT_VALID(roam);
  }
}

TEST(Roam, SmallDemsRefineToFullResolutionAndEmitTheDemExactly) {
  for (const auto& [w, h] : {std::pair{2, 2}, {3, 3}, {5, 5}, {17, 17}, {100, 37}}) {
    const double sp = 10.0;
    const auto hts = noise(w, h, 3);
    Roam roam(hts, w, h, sp, {0, 0, 0}, smallConfig(100000));
    // Straight down from high above the centre, zero tolerance: every diamond with an error
    // is split, and a noise field has an error everywhere inside the DEM.
    RoamView v = makeView({0.5 * (w - 1) * sp, 0.5 * (h - 1) * sp, 5000.0}, 0.0, -90.0, 0.0);
    for (RoamMode mode : kAllModes) {
      const RoamStats st = roam.update(v, mode);
      EXPECT_TRUE(st.finished);
      EXPECT_VALID(roam);
      EXPECT_EQ(roam.maxErrorPx(v), 0.0) << w << "x" << h << " " << modeName(mode);
      std::vector<RoamTriangle> tris(roam.triangleCount());
      const size_t n = roam.emitTriangles(tris);
      // Full resolution inside the DEM: 2 triangles a cell.
      EXPECT_EQ(n, 2u * static_cast<size_t>(w - 1) * static_cast<size_t>(h - 1)) << w << "x" << h << " " << modeName(mode);
      // Clamped positions cover exactly the DEM rectangle, counter-clockwise from above.
      double area = 0.0;
      for (size_t i = 0; i < n; ++i) {
        const glm::dvec3 a = roam.vertexPosition(tris[i].v[0].x, tris[i].v[0].y);
        const glm::dvec3 b = roam.vertexPosition(tris[i].v[1].x, tris[i].v[1].y);
        const glm::dvec3 c = roam.vertexPosition(tris[i].v[2].x, tris[i].v[2].y);
        const double cross = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
        EXPECT_GT(cross, 0.0);
        area += 0.5 * cross;
      }
      EXPECT_NEAR(area, (w - 1) * (h - 1) * sp * sp, 1e-6);
    }
  }
}

TEST(Roam, FlightPathStaysCrackFreeWithinToleranceInEveryMode) {
  const int n = 257;
  const auto hts = fractal(n, n);
  for (RoamMode mode : kAllModes) {
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
    uint64_t maxTris = 0, sumTris = 0, maxOps = 0, sumOps = 0;
    const auto path = flightPath();
    for (size_t f = 0; f < path.size(); ++f) {
      const RoamStats st = roam.update(path[f], mode);
      ASSERT_TRUE(st.finished);
      EXPECT_FALSE(st.poolExhausted);
      EXPECT_FALSE(st.triangleCapped);
      std::string why;
      ASSERT_TRUE(roam.validate(&why)) << modeName(mode) << " frame " << f << ": " << why;
      const double worst = roam.maxErrorPx(path[f]);
      EXPECT_LE(worst, path[f].tolerance_px) << modeName(mode) << " frame " << f;
      EXPECT_LE(worst, st.maxErrorPx + 1e-9) << "stats bound below the real maximum";
      EXPECT_EQ(st.triangles, roam.triangleCount());
      const uint64_t ops = st.splits + st.merges + st.enhMerges;
      maxTris = std::max(maxTris, st.triangles);
      sumTris += st.triangles;
      maxOps = std::max(maxOps, ops);
      sumOps += ops;
    }
    EXPECT_GT(maxTris, 1000u);  // the view really refines
    std::printf("[ flight ] %-10s frames %zu  triangles avg %llu max %llu  ops avg %llu max %llu\n", modeName(mode),
                path.size(), static_cast<unsigned long long>(sumTris / path.size()), static_cast<unsigned long long>(maxTris),
                static_cast<unsigned long long>(sumOps / path.size()), static_cast<unsigned long long>(maxOps));
  }
}

TEST(Roam, AllModesConvergeToTheSameMesh) {
  // Errors and boxes are nested, so the refined mesh for a view is unique whatever the
  // history: coherent modes, flown along the path, must match a rebuild exactly.
  const int n = 129;
  const auto hts = fractal(n, n, 11);
  Roam a(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
  Roam b(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
  Roam c(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
  const auto path = flightPath();
  for (size_t f = 0; f < path.size(); f += 3) {
    RoamView v = path[f];
    v.camera.eye_m *= 0.5;  // the path is for a terrain twice as large
    a.update(v, RoamMode::EnhMerge);
    b.update(v, RoamMode::MergeQueue);
    c.update(v, RoamMode::Rebuild);
    const auto ta = sortedTriangles(a);
    EXPECT_EQ(ta, sortedTriangles(b)) << "frame " << f;
    EXPECT_EQ(ta, sortedTriangles(c)) << "frame " << f;
  }
}

TEST(Roam, InterruptedAtAnyPointStaysValidAndConverges) {
  const int n = 65;
  const auto hts = fractal(n, n, 5);
  const RoamView views[] = {makeView({600, 450, 500}, 30, -20, 1.0), makeView({1500, 1600, 400}, 200, -25, 1.0),
                            makeView({150, 1750, 700}, 120, -10, 3.0)};
  for (RoamMode mode : kAllModes) {
    // (Budgets 1 and 6: every single-operation stop, and stops between multi-operation steps.
    // Validating every 53rd call keeps this test a few seconds under ASAN.)
    for (uint32_t budget : {1u, 6u}) {
      Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
      Roam reference(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
      for (const RoamView& full : views) {
        reference.update(full, mode);
        RoamView v = full;
        v.maxOperations = budget;
        bool finished = false;
        int calls = 0;
        while (!finished && calls < 100000) {
          const RoamStats st = roam.update(v, mode);
          EXPECT_LE(st.splits + st.merges + st.enhMerges, budget);
          finished = st.finished;
          ++calls;
          if (calls % 53 == 1) {
            std::string why;
            ASSERT_TRUE(roam.validate(&why)) << modeName(mode) << " budget " << budget << " call " << calls << ": " << why;
          }
        }
        ASSERT_TRUE(finished) << modeName(mode) << " budget " << budget;
        EXPECT_VALID(roam);
        EXPECT_GT(calls, 1);
        EXPECT_EQ(roam.triangleCount(), reference.triangleCount()) << modeName(mode) << " budget " << budget;
        EXPECT_EQ(sortedTriangles(roam), sortedTriangles(reference));
      }
    }
  }
}

TEST(Roam, EnhMergeCollapsesATeleportInFewOperations) {
  const int n = 257;
  const auto hts = fractal(n, n, 9);
  const RoamView here = makeView({1000, 1000, 450}, 45, -20, 1.0);
  struct Teleport {
    RoamView there;
    uint32_t minRatio;  // merges (MergeQueue) / enhMerges (EnhMerge), deterministic
  };
  const Teleport teleports[] = {
      {makeView({6500, 6800, 500}, 225, -20, 1.0), 4},   // the other corner, looking back over the map
      {makeView({7000, 7000, 3000}, 45, -20, 1.0), 1000},  // looking off the map: everything collapses
  };
  for (const Teleport& t : teleports) {
    Roam enh(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
    Roam mq(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
    enh.update(here, RoamMode::EnhMerge);
    mq.update(here, RoamMode::MergeQueue);
    ASSERT_EQ(enh.triangleCount(), mq.triangleCount());
    const uint64_t before = enh.triangleCount();
    const RoamStats se = enh.update(t.there, RoamMode::EnhMerge);
    const RoamStats sm = mq.update(t.there, RoamMode::MergeQueue);
    EXPECT_VALID(enh);
    EXPECT_VALID(mq);
    EXPECT_EQ(sortedTriangles(enh), sortedTriangles(mq));
    EXPECT_EQ(se.merges, 0u);
    EXPECT_EQ(sm.enhMerges, 0u);
    EXPECT_GT(sm.merges, 1000u);
    // The same nodes go, and the same splits follow; enhMerge needs far fewer operations.
    EXPECT_EQ(se.nodesFreed, sm.nodesFreed);
    EXPECT_EQ(se.splits, sm.splits);
    EXPECT_GE(sm.merges, t.minRatio * se.enhMerges) << "merges " << sm.merges << " enhMerges " << se.enhMerges;
    std::printf("[ teleport ] %llu -> %llu triangles: MergeQueue %u merges + %u splits, EnhMerge %u enhMerges + %u splits, "
                "%u nodes freed\n", static_cast<unsigned long long>(before), static_cast<unsigned long long>(sm.triangles),
                sm.merges, sm.splits, se.enhMerges, se.splits, se.nodesFreed);
  }
}

TEST(Roam, FlatTerrainStaysAtTheBaseTriangles) {
  const int n = 65;
  const std::vector<float> hts(static_cast<size_t>(n) * n, 123.0f);
  for (RoamMode mode : kAllModes) {
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
    for (double tol : {1e-9, 0.5, 4.0}) {
      // On the surface, exactly on a vertex, looking along it and straight down.
      for (const RoamView& v : {makeView(roam.vertexPosition(32, 32), 0, 0, tol), makeView({900, 900, 2000}, 0, -90, tol)}) {
        const RoamStats st = roam.update(v, mode);
        EXPECT_TRUE(st.finished);
        EXPECT_EQ(st.splits, 0u);
        EXPECT_EQ(roam.triangleCount(), roam.baseTriangles()) << modeName(mode) << " tol " << tol;
        EXPECT_EQ(st.maxErrorPx, 0.0);
      }
    }
    EXPECT_VALID(roam);
  }
}

TEST(Roam, CliffIsRefinedAlongTheCliffOnly) {
  const int n = 129, cliffX = 64;  // heights 0 west of x = 64, 500 m from x = 64 east
  std::vector<float> hts(static_cast<size_t>(n) * n);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) hts[static_cast<size_t>(y) * n + x] = x >= cliffX ? 500.0f : 0.0f;
  for (RoamMode mode : kAllModes) {
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
    const RoamView v = makeView({1920, 1920, 20000}, 0, -90, 0.5);  // whole map in view
    const RoamStats st = roam.update(v, mode);
    EXPECT_TRUE(st.finished);
    EXPECT_VALID(roam);
    EXPECT_LE(roam.maxErrorPx(v), 0.5);
    std::vector<RoamTriangle> tris(roam.triangleCount());
    tris.resize(roam.emitTriangles(tris));
    size_t finest = 0, nearCliff = 0;
    for (const auto& t : tris) {
      const int minX = std::min({t.v[0].x, t.v[1].x, t.v[2].x}), maxX = std::max({t.v[0].x, t.v[1].x, t.v[2].x});
      const int minY = std::min({t.v[0].y, t.v[1].y, t.v[2].y}), maxY = std::max({t.v[0].y, t.v[1].y, t.v[2].y});
      const bool isFinest = (maxX - minX) + (maxY - minY) <= 2;  // legs of one sample
      finest += isFinest;
      if (isFinest) {
        // Finest triangles only where a finest diamond straddles the step.
        EXPECT_GE(maxX, cliffX - 2);
        EXPECT_LE(minX, cliffX + 1);
        nearCliff += (maxX >= cliffX - 1 && minX <= cliffX);
      }
    }
    EXPECT_GT(finest, 100u);             // the whole 128-sample cliff line at full resolution
    EXPECT_EQ(nearCliff, finest);
    EXPECT_LT(tris.size(), static_cast<size_t>(2 * 128 * 128) / 10);  // < 10 % of full resolution
  }
}

TEST(Roam, CameraOnAVertexAndBelowTheSurface) {
  const int n = 65;
  const auto hts = fractal(n, n, 21);
  for (RoamMode mode : kAllModes) {
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
    const RoamView onVertex = makeView(roam.vertexPosition(20, 33), 70, -5, 1.0);
    RoamStats st = roam.update(onVertex, mode);
    EXPECT_TRUE(st.finished);
    EXPECT_VALID(roam);
    EXPECT_LE(roam.maxErrorPx(onVertex), 1.0);  // the eye's surroundings are at the finest level
    const RoamView below = makeView(roam.vertexPosition(40, 40) - glm::dvec3(0, 0, 300), 10, 30, 1.0);
    st = roam.update(below, mode);
    EXPECT_TRUE(st.finished);
    EXPECT_VALID(roam);
    EXPECT_LE(roam.maxErrorPx(below), 1.0);
    EXPECT_TRUE(std::isfinite(st.maxErrorPx));
  }
}

TEST(Roam, HugeCoordinatesGiveTheSameTriangulation) {
  const int n = 129;
  const auto hts = fractal(n, n, 4);
  const glm::dvec3 far{4.1e6, 1.0e7, 0.0};
  for (RoamMode mode : kAllModes) {
    Roam near0(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
    Roam farAway(hts, n, n, 30.0, far, smallConfig());
    const auto path = flightPath();
    for (size_t f = 0; f < path.size(); f += 4) {
      RoamView v = path[f];
      v.camera.eye_m = glm::floor(v.camera.eye_m * 0.5 * 8.0) / 8.0;  // exact in double at 1e7
      near0.update(v, mode);
      v.camera.eye_m += far;
      farAway.update(v, mode);
      ASSERT_EQ(sortedTriangles(near0), sortedTriangles(farAway)) << modeName(mode) << " frame " << f;
    }
    const glm::dvec3 p = farAway.vertexPosition(10, 20) - far;
    EXPECT_EQ(p, near0.vertexPosition(10, 20));
  }
}

TEST(Roam, NonFiniteCameraRefinesNothingAndDoesNotCrash) {
  const int n = 65;
  const auto hts = fractal(n, n, 2);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (RoamMode mode : kAllModes) {
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
    roam.update(makeView({900, 900, 300}, 20, -20, 1.0), mode);
    ASSERT_GT(roam.triangleCount(), roam.baseTriangles());
    RoamView bad = makeView({nan, 900, 300}, 20, -20, 1.0);
    RoamStats st = roam.update(bad, mode);
    EXPECT_TRUE(st.finished);
    EXPECT_VALID(roam);
    EXPECT_EQ(roam.triangleCount(), roam.baseTriangles()) << modeName(mode);
    bad = makeView({900, 900, 300}, 20, -20, 1.0);
    bad.camera.fovY_deg = nan;
    st = roam.update(bad, mode);
    EXPECT_VALID(roam);
    EXPECT_EQ(roam.triangleCount(), roam.baseTriangles());
    bad.camera.fovY_deg = 60;
    bad.camera.heading_deg = std::numeric_limits<double>::infinity();
    roam.update(bad, mode);
    EXPECT_VALID(roam);
  }
}

TEST(Roam, TriangleCapIsRespectedAndLoweringItCoarsens) {
  const int n = 257;
  const auto hts = fractal(n, n, 8);
  for (RoamMode mode : kAllModes) {
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
    RoamView v = makeView({2000, 2000, 500}, 45, -20, 0.25);
    v.maxTriangles = 3000;
    RoamStats st = roam.update(v, mode);
    EXPECT_TRUE(st.finished);
    EXPECT_TRUE(st.triangleCapped);
    EXPECT_LE(st.triangles, 3000u);
    EXPECT_GT(st.triangles, 2900u);  // the cap is used, not just respected
    EXPECT_GT(st.maxErrorPx, 0.25);
    EXPECT_VALID(roam);
    const auto path = flightPath();
    for (size_t f = 0; f < path.size(); f += 2) {
      RoamView pv = path[f];
      pv.tolerance_px = 0.25;
      pv.maxTriangles = f < 20 ? 3000 : 1000;  // lowered mid-flight
      st = roam.update(pv, mode);
      EXPECT_TRUE(st.finished);
      EXPECT_LE(st.triangles, pv.maxTriangles) << modeName(mode) << " frame " << f;
      std::string why;
      ASSERT_TRUE(roam.validate(&why)) << why;
    }
  }
}

TEST(Roam, PoolExhaustionIsReportedAndTheMeshStaysValid) {
  const int n = 129;
  const auto hts = fractal(n, n, 6);
  for (RoamMode mode : kAllModes) {
    RoamConfig cfg;
    cfg.maxTriangles = 100000;
    cfg.nodeCapacity = 60;
    Roam roam(hts, n, n, 30.0, {0, 0, 0}, cfg);
    EXPECT_EQ(roam.nodeCapacity(), 60u);
    const auto path = flightPath();
    for (size_t f = 0; f < path.size(); f += 5) {
      RoamView v = path[f];
      v.camera.eye_m *= 0.5;
      const RoamStats st = roam.update(v, mode);
      EXPECT_TRUE(st.poolExhausted) << modeName(mode) << " frame " << f;
      EXPECT_LE(roam.nodeCount(), 60u);
      std::string why;
      ASSERT_TRUE(roam.validate(&why)) << why;
    }
  }
}

TEST(Roam, EmitVisibleCullsBehindTheCamera) {
  const int n = 129;
  const auto hts = fractal(n, n, 12);
  Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
  const RoamView v = makeView({1920, 200, 600}, 0, -15, 2.0);  // south edge, looking north
  roam.update(v, RoamMode::EnhMerge);
  std::vector<RoamTriangle> all(roam.triangleCount()), vis(roam.triangleCount());
  const size_t na = roam.emitTriangles(all);
  const size_t nv = roam.emitVisible(v.camera, vis);
  EXPECT_GT(nv, 0u);
  EXPECT_LE(nv, na);
  RoamView back = v;
  back.camera.heading_deg = 180;  // looking off the map
  back.camera.pitch_deg = 10;
  EXPECT_LT(roam.emitVisible(back.camera, vis), nv / 4);
}

// splitEnds() names the hypotenuse of the diamond that creates a vertex: checked against the
// real split of every internal node (the apex of each child is the midpoint of the parent's
// hypotenuse) by refining a small DEM to full resolution and looking at the emitted mesh:
// every vertex that is not a base corner is the midpoint of its ends, and in the refined
// mesh one end is the far end of one of the vertex's legs.
TEST(Roam, SplitEndsAreTheHypotenuseOfTheSplitThatCreatesAVertex) {
  const int n = 33;
  std::vector<float> z(static_cast<size_t>(n) * n);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) z[static_cast<size_t>(y) * n + x] = static_cast<float>((x * 7 + y * 13) % 17);
  Roam roam(z, n, n, 10.0, {0, 0, 0});
  RoamVertex a, b;
  EXPECT_FALSE(roam.splitEnds(0, 0, a, b));
  EXPECT_FALSE(roam.splitEnds(32, 32, a, b));
  ASSERT_TRUE(roam.splitEnds(16, 16, a, b));  // the root square's centre: its base diagonal
  EXPECT_EQ(std::abs(a.x - b.x), 32);
  EXPECT_EQ(std::abs(a.y - b.y), 32);
  for (int y = 0; y < n; ++y)
    for (int x = 0; x < n; ++x) {
      if (!roam.splitEnds(x, y, a, b)) continue;
      EXPECT_EQ(a.x + b.x, 2 * x);
      EXPECT_EQ(a.y + b.y, 2 * y);
    }
  // In any mesh, a leaf's hypotenuse is the diagonal of the diamond whose split would create
  // its midpoint: splitEnds(midpoint) must name exactly that edge. Check meshes of several
  // refinement levels so diamonds of every size and both diagonal directions occur.
  size_t checked = 0;
  for (double tol : {8.0, 2.0, 0.5, 0.1}) {
    RoamView v;
    v.camera.eye_m = {40, 60, 30};
    v.camera.heading_deg = 45;
    v.camera.pitch_deg = -30;
    v.tolerance_px = tol;
    v.viewportHeight_px = 1000;
    roam.update(v, RoamMode::Rebuild);
    std::vector<RoamTriangle> tris(roam.triangleCount());
    tris.resize(roam.emitTriangles(tris));
    for (const auto& t : tris) {
      for (int k = 0; k < 3; ++k) {
        const RoamVertex& p = t.v[k];
        const RoamVertex& q = t.v[(k + 1) % 3];
        const RoamVertex& r = t.v[(k + 2) % 3];
        if ((q.x - p.x) * (r.x - p.x) + (q.y - p.y) * (r.y - p.y) != 0) continue;  // p: the right angle
        if ((q.x + r.x) % 2 != 0 || (q.y + r.y) % 2 != 0) continue;  // finest level: no grid midpoint
        const int mx = (q.x + r.x) / 2, my = (q.y + r.y) / 2;
        ASSERT_TRUE(roam.splitEnds(mx, my, a, b)) << mx << "," << my;
        const bool match = (a.x == q.x && a.y == q.y && b.x == r.x && b.y == r.y) ||
                           (a.x == r.x && a.y == r.y && b.x == q.x && b.y == q.y);
        EXPECT_TRUE(match) << "midpoint (" << mx << "," << my << ") of (" << q.x << "," << q.y << ")-(" << r.x << ","
                           << r.y << ") but splitEnds gives (" << a.x << "," << a.y << ")-(" << b.x << "," << b.y << ")";
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 100u);
}

// Deferred priority recomputation must give exactly the mesh a fresh walk gives for the same
// view (the refined mesh is unique), whatever the history, while looking at far fewer nodes
// per frame on smooth flight.
TEST(Roam, DeferredMatchesAFreshWalkAndExaminesFewNodes) {
  const int n = 257;
  const auto hts = fractal(n, n, 3);
  Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallConfig(400000));
  const auto path = flightPath();
  uint64_t examinedSmooth = 0, nodesSmooth = 0;
  for (size_t f = 0; f < path.size(); ++f) {
    const RoamStats st = roam.update(path[f], RoamMode::Deferred);
    ASSERT_TRUE(st.finished);
    EXPECT_VALID(roam);
    if (f % 3 == 0 || f >= 34) {  // every third frame, and each teleport
      Roam fresh(hts, n, n, 30.0, {0, 0, 0}, smallConfig(400000));
      fresh.update(path[f], RoamMode::Deferred);
      ASSERT_EQ(sortedTriangles(roam), sortedTriangles(fresh)) << "frame " << f;
    }
    EXPECT_LE(roam.maxErrorPx(path[f]), path[f].tolerance_px);
    // Frames 1..19 cruise straight and level: the schedule's cost.
    if (f >= 1 && f < 20) {
      examinedSmooth += st.nodesExamined;
      nodesSmooth += roam.nodeCount();
    }
  }
  // Cruising 60 m a frame, a small share of the nodes is due each frame.
  EXPECT_LT(static_cast<double>(examinedSmooth), 0.25 * static_cast<double>(nodesSmooth))
      << examinedSmooth << " of " << nodesSmooth;
  // Turning on the spot costs nothing: priorities do not depend on the view direction.
  RoamView turn = path.back();
  for (int i = 1; i <= 12; ++i) {
    turn.camera.heading_deg += 30.0;
    const RoamStats st = roam.update(turn, RoamMode::Deferred);
    EXPECT_EQ(st.splits + st.merges + st.enhMerges, 0u) << "turn " << i;
    EXPECT_EQ(st.nodesExamined, 0u) << "turn " << i;
  }
  // A new tolerance invalidates the schedule: one full walk, then the right mesh.
  turn.tolerance_px = 4.0;
  roam.update(turn, RoamMode::Deferred);
  Roam fresh(hts, n, n, 30.0, {0, 0, 0}, smallConfig(400000));
  fresh.update(turn, RoamMode::Deferred);
  EXPECT_EQ(sortedTriangles(roam), sortedTriangles(fresh));
}

// emitVisible walks the tree and skips subtrees whose nested box is outside the frustum, and
// tests a leaf with its parent's height range: it must keep every leaf a flat filter (every
// leaf's own exact box against the frustum) keeps, and cull most of what that filter culls.
TEST(Roam, HierarchicalEmitVisibleKeepsWhatTheFlatFilterKeeps) {
  const int n = 129;
  const auto hts = fractal(n, n, 12, 900.0);
  Roam roam(hts, n, n, 30.0, {100.0, -50.0, 0.0}, smallConfig());
  const auto path = flightPath();
  for (size_t f = 0; f < path.size(); f += 5) {
    RoamView v = path[f];
    v.camera.eye_m = v.camera.eye_m * 0.5 + glm::dvec3(100.0, -50.0, 0.0);
    roam.update(v, RoamMode::Deferred);  // the whole surroundings: much to cull
    std::vector<RoamTriangle> all(roam.triangleCount()), vis(roam.triangleCount());
    all.resize(roam.emitTriangles(all));
    vis.resize(roam.emitVisible(v.camera, vis));
    const Frustum fr = makeFrustum(v.camera);
    std::vector<std::tuple<int, int, int, int, int, int>> flat, hier;
    for (const auto& t : all) {
      Aabb box{glm::dvec3(1e300), glm::dvec3(-1e300)};
      for (const auto& p : t.v) {
        const glm::dvec3 q = roam.vertexPosition(p.x, p.y) - v.camera.eye_m;
        box.min = glm::min(box.min, q);
        box.max = glm::max(box.max, q);
      }
      if (fr.intersects(box)) flat.emplace_back(t.v[0].x, t.v[0].y, t.v[1].x, t.v[1].y, t.v[2].x, t.v[2].y);
    }
    for (const auto& t : vis) hier.emplace_back(t.v[0].x, t.v[0].y, t.v[1].x, t.v[1].y, t.v[2].x, t.v[2].y);
    std::sort(flat.begin(), flat.end());
    std::sort(hier.begin(), hier.end());
    EXPECT_TRUE(std::includes(hier.begin(), hier.end(), flat.begin(), flat.end())) << "frame " << f;
    EXPECT_LE(hier.size(), flat.size() + (all.size() - flat.size()) / 10) << "frame " << f;  // culls >= 90 %
    EXPECT_LT(hier.size(), all.size()) << "frame " << f;
  }
}

// Deferred under a visit budget: every update stays within the budget (plus one operation),
// the mesh is valid at every stop, and once finished it is exactly the unbudgeted mesh. A
// teleport restarts from the base triangles and converges over several updates.
TEST(Roam, DeferredVisitBudgetIsRespectedAndConverges) {
  const int n = 129;
  const auto hts = fractal(n, n, 3, 900.0);
  Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallConfig(400000));
  Roam fresh(roam, smallConfig(400000));  // shares roam's bounds
  RoamView v = makeView({1900, 1900, 1000}, 30.0, -20.0, 1.0);
  v.maxVisits = 400;
  const uint32_t maxOp = 4 * static_cast<uint32_t>(roam.maxLevel() + 1) + 8;  // the longest forced-split chain
  int updates = 0;
  bool finished = false;
  uint64_t maxVisits = 0;
  while (!finished && updates < 2000) {
    const RoamStats st = roam.update(v, RoamMode::Deferred);
    finished = st.finished;
    maxVisits = std::max<uint64_t>(maxVisits, st.visits);
    EXPECT_LE(st.visits, v.maxVisits + maxOp) << "update " << updates;
    if (!st.finished) {
      EXPECT_TRUE(std::isinf(st.maxErrorPx));
    } else {
      EXPECT_EQ(st.pending, 0u) << "finished, yet work is reported left over";
    }
    if (updates % 7 == 0) {
      std::string why;
      ASSERT_TRUE(roam.validate(&why)) << "update " << updates << ": " << why;
    }
    ++updates;
  }
  ASSERT_TRUE(finished);
  EXPECT_GT(updates, 3);  // the budget really splits the work
  EXPECT_GT(maxVisits, 300u);
  RoamView u = v;
  u.maxVisits = 0;
  fresh.update(u, RoamMode::Deferred);
  EXPECT_EQ(sortedTriangles(roam), sortedTriangles(fresh));
  EXPECT_LE(roam.maxErrorPx(v), 1.0);
  // Fly on a little: the budget keeps up with smooth flight (finished again within a few updates).
  for (int i = 0; i < 10; ++i) {
    v.camera.eye_m += glm::dvec3(20.0, 10.0, 0.0);
    const RoamStats st = roam.update(v, RoamMode::Deferred);
    EXPECT_FALSE(st.restarted);
    EXPECT_LE(st.visits, v.maxVisits + maxOp);
    if (st.finished) {
      EXPECT_EQ(st.pending, 0u) << "fly-on update " << i;
    }
  }
  // Teleport: restart from the base (valid at once), then converge.
  v.camera.eye_m = {300, 300, 1000};
  RoamStats st = roam.update(v, RoamMode::Deferred);
  EXPECT_TRUE(st.restarted);
  EXPECT_VALID(roam);
  int frames = 1;
  while (!st.finished && frames < 2000) {
    st = roam.update(v, RoamMode::Deferred);
    EXPECT_FALSE(st.restarted);
    ++frames;
  }
  ASSERT_TRUE(st.finished);
  EXPECT_GT(frames, 1);
  EXPECT_VALID(roam);
  fresh.update(u, RoamMode::Deferred);
  u.camera = v.camera;
  fresh.update(u, RoamMode::Deferred);
  EXPECT_EQ(sortedTriangles(roam), sortedTriangles(fresh));
}

// RoamView::stop (a deadline on the caller's clock): the update ends within one poll interval
// and one operation of the poll that said stop, the mesh is valid at every stop, and updates
// that keep being stopped still converge to the fresh walk's mesh (with a teleport between).
TEST(Roam, StopHookEndsAnUpdateEarlyAndTheMeshStillConverges) {
  const int n = 129;
  const auto hts = fractal(n, n, 3, 900.0);
  Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallConfig(400000));
  Roam fresh(roam, smallConfig(400000));
  struct Polls {
    int calls = 0, stopAfter = 0;
  } polls;
  RoamView v = makeView({1900, 1900, 1000}, 30.0, -20.0, 1.0);
  v.maxVisits = 100000;  // the stop, not the visit budget, ends each update
  v.stop = [](void* c) {
    auto* p = static_cast<Polls*>(c);
    return ++p->calls > p->stopAfter;
  };
  v.stopContext = &polls;
  const uint32_t maxOp = 4 * static_cast<uint32_t>(roam.maxLevel() + 1) + 8;
  roam.update(v, RoamMode::Deferred);  // the first update restarts from the base
  int stopped = 0, leftUnscheduled = 0;
  auto run = [&](int limit) {
    RoamStats st;
    int updates = 0;
    do {
      polls = {0, 1 + updates % 4};  // stop at the 2nd ... 5th poll
      st = roam.update(v, RoamMode::Deferred);
      if (polls.calls > polls.stopAfter) {
        ++stopped;
        EXPECT_FALSE(st.finished);
        EXPECT_LE(st.visits, static_cast<uint32_t>(polls.calls + 1) * kStopPollVisits + maxOp) << "update " << updates;
      }
      EXPECT_LE(polls.calls, polls.stopAfter + 1) << "polled after it said stop";
      // Scheduling what the update changed is polled too: a stop may leave it to the next one.
      if (st.unscheduled > 0) {
        ++leftUnscheduled;
        EXPECT_FALSE(st.finished);
      }
      // Every 3rd update (and the last): with the stop point cycling every 4, every stop
      // position is validated (the whole check each update made this the slowest test).
      if (updates % 3 == 0 || st.finished) {
        std::string why;
        EXPECT_TRUE(roam.validate(&why)) << "update " << updates << ": " << why;
      }
      ++updates;
    } while (!st.finished && updates < limit);
    return st.finished;
  };
  ASSERT_TRUE(run(5000));
  EXPECT_GT(stopped, 10);
  EXPECT_GT(leftUnscheduled, 0);
  RoamView u = v;
  u.maxVisits = 0;
  u.stop = nullptr;
  fresh.update(u, RoamMode::Deferred);
  EXPECT_EQ(sortedTriangles(roam), sortedTriangles(fresh));
  // Teleport under the stop, then converge.
  v.camera.eye_m = {300, 300, 1000};
  ASSERT_TRUE(run(5000));
  u.camera = v.camera;
  fresh.update(u, RoamMode::Deferred);
  EXPECT_EQ(sortedTriangles(roam), sortedTriangles(fresh));
  // Without maxVisits the hook is not used: one unbudgeted update finishes.
  polls = {0, 0};
  v.maxVisits = 0;
  v.camera.eye_m = {3000, 3000, 700};
  EXPECT_TRUE(roam.update(v, RoamMode::Deferred).finished);
  EXPECT_EQ(polls.calls, 0);
}

// meshHeight and leafAt: on a mesh vertex the true height; inside a leaf the plane of that leaf.
TEST(Roam, MeshHeightAndLeafAt) {
  const int n = 65;
  const auto hts = fractal(n, n, 8, 700.0);
  Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
  roam.update(makeView({900, 900, 900}, 0.0, -30.0, 2.0), RoamMode::EnhMerge);
  std::vector<RoamTriangle> tris(roam.triangleCount());
  tris.resize(roam.emitTriangles(tris));
  ASSERT_GT(tris.size(), 50u);
  for (size_t i = 0; i < tris.size(); i += 7) {
    const RoamTriangle& t = tris[i];
    for (const auto& p : t.v) EXPECT_NEAR(roam.meshHeight(p.x, p.y), roam.vertexPosition(p.x, p.y).z, 1e-4);
    const RoamTriangle l = roam.leafAt(t.v[0].x + t.v[1].x + t.v[2].x, t.v[0].y + t.v[1].y + t.v[2].y);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(l.v[k].x, t.v[k].x);
      EXPECT_EQ(l.v[k].y, t.v[k].y);
    }
  }
}

// meshHeight on a DEM that is not 2^k + 1 samples a side: the height of the mesh as drawn (leaf
// corners clamped onto the DEM) at the point a padded-grid vertex is drawn at, which is where a
// vertex removed by a merge is drawn (MorphOut moves it there). Checked at every DEM sample
// against every drawn triangle holding it, and beyond the DEM against the clamped point.
TEST(Roam, MeshHeightIsTheDrawnSurfaceAtTheClampedPoint) {
  for (const auto& [w, h] : {std::pair{50, 40}, {40, 50}, {100, 37}}) {
    const auto hts = fractal(w, h, 5, 600.0);
    Roam roam(hts, w, h, 30.0, {0, 0, 0}, smallConfig());
    roam.update(makeView({(w - 1) * 30.0 - 200.0, (h - 1) * 30.0 - 300.0, 500.0}, 20.0, -40.0, 1.0), RoamMode::EnhMerge);
    std::vector<RoamTriangle> tris(roam.triangleCount());
    tris.resize(roam.emitTriangles(tris));
    ASSERT_GT(tris.size(), 100u);
    auto sample = [&](int x, int y) { return static_cast<double>(hts[static_cast<size_t>(y) * static_cast<size_t>(w) + static_cast<size_t>(x)]); };
    double worst = 0.0;
    int at[2] = {0, 0};
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const double m = roam.meshHeight(x, y);
        bool held = false;
        for (const RoamTriangle& t : tris) {
          int cx[3], cy[3];
          for (int k = 0; k < 3; ++k) {
            cx[k] = std::clamp(t.v[k].x, 0, w - 1);
            cy[k] = std::clamp(t.v[k].y, 0, h - 1);
          }
          const int64_t area = int64_t{cx[1] - cx[0]} * (cy[2] - cy[0]) - int64_t{cx[2] - cx[0]} * (cy[1] - cy[0]);
          const int64_t w0 = int64_t{cx[1] - x} * (cy[2] - y) - int64_t{cx[2] - x} * (cy[1] - y);
          const int64_t w1 = int64_t{cx[2] - x} * (cy[0] - y) - int64_t{cx[0] - x} * (cy[2] - y);
          const int64_t w2 = area - w0 - w1;
          if (area <= 0 || w0 < 0 || w1 < 0 || w2 < 0) continue;
          held = true;
          const double z = (static_cast<double>(w0) * sample(cx[0], cy[0]) + static_cast<double>(w1) * sample(cx[1], cy[1]) +
                            static_cast<double>(w2) * sample(cx[2], cy[2])) /
                           static_cast<double>(area);
          if (std::abs(z - m) > worst) {
            worst = std::abs(z - m);
            at[0] = x;
            at[1] = y;
          }
        }
        ASSERT_TRUE(held) << x << "," << y;
      }
    EXPECT_LT(worst, 1e-3) << w << " x " << h << ": meshHeight(" << at[0] << "," << at[1] << ") is off the drawn surface by " << worst << " m";
    for (int y = 0; y < roam.gridHeight(); y += 3)
      for (int x = 0; x < roam.gridWidth(); x += 3)
        if (x >= w || y >= h) {
          EXPECT_EQ(roam.meshHeight(x, y), roam.meshHeight(std::min(x, w - 1), std::min(y, h - 1))) << x << "," << y;
        }
  }
}

// nearestTriangleBox: a lower bound on the distance to triangles drawn from height-field samples
// (the service and igbench governor choose the terrain's detail variant with it).
TEST(Roam, NearestTriangleBoxIsTheDistanceToTheClosestBox) {
  // 4 x 4 samples, 10 m apart, all 5 m high except (3, 3) at 50 m.
  std::vector<float> h(16, 5.0f);
  h[15] = 50.0f;
  const std::vector<RoamTriangle> tris = {
      {{{0, 0}, {1, 0}, {0, 1}}},  // box [0, 10] x [0, 10] x [5, 5]
      {{{2, 2}, {3, 2}, {3, 3}}},  // box [20, 30] x [20, 30] x [5, 50]
  };
  const glm::dvec3 above(5.0, 5.0, 105.0);
  // 100 m down to the first box, but the second's top corner (20, 20, 50) is closer.
  EXPECT_DOUBLE_EQ(nearestTriangleBox(tris, h, 4, 4, 10.0, above, 0.0), std::sqrt(15.0 * 15.0 + 15.0 * 15.0 + 55.0 * 55.0));
  EXPECT_DOUBLE_EQ(nearestTriangleBox(std::span(tris).first(1), h, 4, 4, 10.0, above, 0.0), 100.0);
  // Only the second triangle: from (25, 25, 105) straight down to its top at 50 m.
  EXPECT_DOUBLE_EQ(nearestTriangleBox(std::span(tris).subspan(1), h, 4, 4, 10.0, {25.0, 25.0, 105.0}, 0.0), 55.0);
  // Inside a box: 0.
  EXPECT_DOUBLE_EQ(nearestTriangleBox(tris, h, 4, 4, 10.0, {25.0, 25.0, 20.0}, 0.0), 0.0);
  // Corners beyond the field are clamped onto its edge, as heightFieldVertex places them.
  const std::vector<RoamTriangle> outside = {{{{5, 5}, {6, 5}, {5, 6}}}};
  EXPECT_DOUBLE_EQ(nearestTriangleBox(outside, h, 4, 4, 10.0, {30.0, 30.0, 60.0}, 0.0), 10.0);
  // Stops once below `enough`; +inf without triangles.
  EXPECT_LT(nearestTriangleBox(tris, h, 4, 4, 10.0, above, 1000.0), 1000.0);
  EXPECT_TRUE(std::isinf(nearestTriangleBox({}, h, 4, 4, 10.0, above, 0.0)));
}


// validate() checks the bintree; this checks what is drawn: on DEMs whose padded grid reaches
// beyond them (clamped vertices, zero-area leaves dropped), along a flight in every mode.
TEST(Roam, EmittedMeshTilesTheDemWithoutCracksInEveryMode) {
  for (const auto& [w, h] : {std::pair{100, 37}, {6, 6}, {3, 9}}) {
    const auto hts = fractal(w, h, 3);
    const auto path = flightPath();
    for (RoamMode mode : kAllModes) {
      Roam roam(hts, w, h, 30.0, {0, 0, 0}, smallConfig());
      for (size_t f = 0; f < path.size(); f += 4) {
        RoamView v = path[f];
        v.camera.eye_m *= 0.4;
        v.tolerance_px = 0.5;
        roam.update(v, mode);
        std::vector<RoamTriangle> tris(roam.triangleCount());
        tris.resize(roam.emitTriangles(tris));
        ASSERT_TRUE(tilesDem(tris, w, h)) << w << "x" << h << " " << modeName(mode) << " frame " << f;
      }
    }
  }
}

// A still camera gives the same mesh update after update, with no work, also while the
// triangle cap binds (the dual-queue swaps must not oscillate).
TEST(Roam, StillCameraKeepsItsMeshUnderATriangleCap) {
  const int n = 129;
  const auto hts = fractal(n, n, 8);
  for (RoamMode mode : {RoamMode::EnhMerge, RoamMode::MergeQueue, RoamMode::Deferred}) {
    for (uint64_t cap : {uint64_t{0}, uint64_t{777}, uint64_t{2000}}) {
      Roam roam(hts, n, n, 30.0, {0, 0, 0}, smallConfig());
      RoamView v = makeView({1000, 1000, 400}, 45, -20, 0.25);
      v.maxTriangles = cap;
      roam.update(v, mode);
      roam.update(v, mode);
      const auto ref = sortedTriangles(roam);
      for (int i = 0; i < 4; ++i) {
        const RoamStats st = roam.update(v, mode);
        EXPECT_EQ(st.splits + st.merges + st.enhMerges, 0u) << modeName(mode) << " cap " << cap << " update " << i;
        EXPECT_EQ(sortedTriangles(roam), ref) << modeName(mode) << " cap " << cap << " update " << i;
      }
    }
  }
}
