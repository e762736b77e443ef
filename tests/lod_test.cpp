// lod/: geodesy, view maths, reverse-Z precision, height field and terrain grid, including
// the hard cases (huge coordinates, poles, camera inside a box, NaN, near 0.1 m / far 100 km).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "lod/geo.h"
#include "lod/heightfield.h"
#include "lod/sun.h"
#include "lod/terrain_grid.h"
#include "lod/view.h"

using namespace ig::lod;

TEST(Geo, GeodeticEcefRoundTripIncludingPolesAndAntimeridian) {
  const Geodetic cases[] = {{0, 0, 0},       {46.5, 7.9, 1200},  {89.9999, 45, 10},  {-90, 0, 0},
                            {-33.9, 179.999, -50}, {60, -180, 35000}, {10, 20, 400000}};
  for (const auto& g : cases) {
    const Geodetic r = ecefToGeodetic(geodeticToEcef(g));
    EXPECT_NEAR(r.lat_deg, g.lat_deg, 1e-9) << g.lat_deg << "," << g.lon_deg;
    if (std::abs(g.lat_deg) < 90) {
      EXPECT_NEAR(std::remainder(r.lon_deg - g.lon_deg, 360.0), 0.0, 1e-9);
    }
    EXPECT_NEAR(r.height_m, g.height_m, 1e-4);
  }
}

TEST(Geo, EcefOfKnownPoint) {
  // Equator / prime meridian is on the x axis at the semi-major axis.
  const glm::dvec3 p = geodeticToEcef({0, 0, 0});
  EXPECT_DOUBLE_EQ(p.x, 6378137.0);
  EXPECT_NEAR(p.y, 0.0, 1e-9);
  EXPECT_NEAR(p.z, 0.0, 1e-9);
}

TEST(Geo, EnuAxesAndHugeOffsets) {
  const EnuFrame f({46.5, 7.9, 500});
  // 1,000 km east then back: millimetre round trip.
  const glm::dvec3 far{1.0e6, -2.0e5, 300.0};
  const glm::dvec3 back = f.toEnu(f.toEcef(far));
  EXPECT_NEAR(back.x, far.x, 1e-6);
  EXPECT_NEAR(back.y, far.y, 1e-6);
  EXPECT_NEAR(back.z, far.z, 1e-6);
  // A point north of the origin has a larger latitude; up raises the height.
  EXPECT_GT(f.toGeodetic({0, 1000, 0}).lat_deg, 46.5);
  EXPECT_GT(f.toGeodetic({1000, 0, 0}).lon_deg, 7.9);
  EXPECT_NEAR(f.toGeodetic({0, 0, 100}).height_m, 600.0, 1e-6);
}

TEST(View, HeadingPitchRollConventions) {
  Camera c;
  c.heading_deg = 90;  // looking east
  glm::dmat3 r = viewRotation(c);
  const glm::dvec3 east_in_cam = r * glm::dvec3(1, 0, 0);
  EXPECT_NEAR(east_in_cam.z, -1.0, 1e-12);  // forward is -z in camera space
  c.heading_deg = 0;
  c.pitch_deg = 30;  // nose up: world up appears tilted back, a point ahead-and-up is centred
  r = viewRotation(c);
  const glm::dvec3 ahead_up = r * glm::dvec3(0, std::cos(M_PI / 6), std::sin(M_PI / 6));
  EXPECT_NEAR(ahead_up.x, 0, 1e-12);
  EXPECT_NEAR(ahead_up.y, 0, 1e-12);
  c.pitch_deg = 0;
  c.roll_deg = 20;  // right wing down: the camera's right axis dips, so world up leans left
  r = viewRotation(c);
  EXPECT_LT((r * glm::dvec3(0, 0, 1)).x, -0.3);
}

TEST(View, ReverseZMapsNearToOneAndFarToZero) {
  EXPECT_NEAR(reverseZDepth(0.1, 100000.0, 0.1), 1.0, 1e-12);
  EXPECT_NEAR(reverseZDepth(0.1, 100000.0, 100000.0), 0.0, 1e-12);
  const glm::dmat4 p = reverseZProjection(45, 1.5, 0.1, 100000.0);
  const glm::dvec4 clip = p * glm::dvec4(0, 0, -50.0, 1);
  EXPECT_NEAR(clip.z / clip.w, reverseZDepth(0.1, 100000.0, 50.0), 1e-12);
}

TEST(View, ReverseZFloatDepthSeparatesSurfacesFarAway) {
  // Near 0.1 m / far 100 km: two surfaces 5 m apart at 50 km must get different float32
  // depths. A conventional 24-bit depth buffer cannot separate them (shown for contrast).
  const double n = 0.1, f = 100000.0;
  const float a = static_cast<float>(reverseZDepth(n, f, 50000.0));
  const float b = static_cast<float>(reverseZDepth(n, f, 50005.0));
  EXPECT_GT(a, b);
  auto conventional24 = [&](double d) {
    const double z = (f + n) / (f - n) - 2.0 * f * n / ((f - n) * d);  // NDC [-1, 1]
    return static_cast<uint32_t>(std::llround((z * 0.5 + 0.5) * 16777215.0));
  };
  EXPECT_EQ(conventional24(50000.0), conventional24(50005.0));
}

TEST(View, FrustumCullsBehindAndKeepsCameraInsideBox) {
  Camera c;
  c.heading_deg = 0;  // looking north
  const Frustum fr = makeFrustum(c);
  const Aabb ahead{{-10, 100, -10}, {10, 120, 10}};
  const Aabb behind{{-10, -120, -10}, {10, -100, 10}};
  const Aabb around{{-1, -1, -1}, {1, 1, 1}};  // camera inside the box
  const Aabb beyondFar{{-10, 200000, -10}, {10, 200010, 10}};
  EXPECT_TRUE(fr.intersects(ahead));
  EXPECT_FALSE(fr.intersects(behind));
  EXPECT_TRUE(fr.intersects(around));
  EXPECT_FALSE(fr.intersects(beyondFar));
  EXPECT_DOUBLE_EQ(distanceToBox(around, {0, 0, 0}), 0.0);
  EXPECT_DOUBLE_EQ(distanceToBox(ahead, {0, 0, 0}), 100.0);
}

// An off-axis window (a display channel's): its four corners project to NDC -1 / +1, and the
// symmetric window gives back today's projection exactly.
TEST(View, OffAxisWindowCornersProjectToNdcEdges) {
  constexpr double kRad = M_PI / 180.0;
  Camera c;
  const WindowAngles w{-10.0, 50.0, -5.0, 20.0};
  ASSERT_TRUE(setWindow(c, w));
  EXPECT_NEAR(2.0 * std::tan(0.5 * c.fovY_deg * kRad), std::tan(20.0 * kRad) - std::tan(-5.0 * kRad), 1e-12);
  const glm::dmat4 p = projection(c);
  const double xs[2] = {std::tan(w.left_deg * kRad), std::tan(w.right_deg * kRad)};
  const double ys[2] = {std::tan(w.bottom_deg * kRad), std::tan(w.top_deg * kRad)};
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j < 2; ++j) {
      const glm::dvec4 clip = p * glm::dvec4(xs[i] * 30.0, ys[j] * 30.0, -30.0, 1.0);  // 30 m away
      EXPECT_NEAR(clip.x / clip.w, i == 0 ? -1.0 : 1.0, 1e-12) << i << j;
      EXPECT_NEAR(clip.y / clip.w, j == 0 ? -1.0 : 1.0, 1e-12) << i << j;
      EXPECT_NEAR(clip.z / clip.w, reverseZDepth(c.near_m, c.far_m, 30.0), 1e-12);
    }
  }
  Camera sym;
  ASSERT_TRUE(setWindow(sym, {-40.0, 40.0, -25.0, 25.0}));
  EXPECT_DOUBLE_EQ(sym.shiftX, 0.0);
  EXPECT_NEAR(sym.fovY_deg, 50.0, 1e-12);
  EXPECT_EQ(projection(sym), reverseZProjection(sym.fovY_deg, sym.aspect, sym.near_m, sym.far_m));
  // Bad windows leave the camera alone.
  Camera bad = sym;
  EXPECT_FALSE(setWindow(bad, {10.0, -10.0, -5.0, 5.0}));
  EXPECT_FALSE(setWindow(bad, {-10.0, 10.0, -5.0, std::nan("")}));
  EXPECT_FALSE(setWindow(bad, {-90.0, 10.0, -5.0, 5.0}));
  EXPECT_EQ(bad.fovY_deg, sym.fovY_deg);
  bad.shiftX = std::nan("");
  EXPECT_FALSE(validWindowShift(bad));
  bad.shiftX = 2.0 * kMaxWindowShift;
  EXPECT_FALSE(validWindowShift(bad));
  EXPECT_TRUE(validWindowShift(sym));
}

// makeFrustum follows the shift: a point just inside each edge of an off-axis window is inside,
// just outside it is outside (with the shift ignored the right edge would sit at +30 deg).
TEST(View, OffAxisFrustumPlanesFollowTheWindow) {
  constexpr double kRad = M_PI / 180.0;
  Camera c;  // heading 0: looking north (+y), camera right = east (+x), up = +z
  const WindowAngles w{-10.0, 50.0, -5.0, 20.0};
  ASSERT_TRUE(setWindow(c, w));
  const Frustum fr = makeFrustum(c);
  auto at = [&](double right_deg, double up_deg) {  // 100 m ahead, in these directions
    return glm::dvec3(std::tan(right_deg * kRad) * 100.0, 100.0, std::tan(up_deg * kRad) * 100.0);
  };
  auto inside = [&](const glm::dvec3& q) { return fr.intersects({q, q}); };
  const double e = 0.05;  // degrees
  const double midX = 20.0, midY = 7.5;
  EXPECT_TRUE(inside(at(w.left_deg + e, midY)));
  EXPECT_FALSE(inside(at(w.left_deg - e, midY)));
  EXPECT_TRUE(inside(at(w.right_deg - e, midY)));
  EXPECT_FALSE(inside(at(w.right_deg + e, midY)));
  EXPECT_TRUE(inside(at(midX, w.bottom_deg + e)));
  EXPECT_FALSE(inside(at(midX, w.bottom_deg - e)));
  EXPECT_TRUE(inside(at(midX, w.top_deg - e)));
  EXPECT_FALSE(inside(at(midX, w.top_deg + e)));
  EXPECT_FALSE(inside(at(-20.0, midY)));  // inside a symmetric window of the same size
}

TEST(Heightfield, DeterministicPerSeedAndInRange) {
  HeightfieldDesc d;
  d.postsX = d.postsY = 65;
  d.heightScale_m = 600;
  std::vector<float> a(65 * 65), b(65 * 65), c(65 * 65);
  EXPECT_EQ(generateHeightfield(d, a), 65u * 65u);
  generateHeightfield(d, b);
  d.seed = 2;
  generateHeightfield(d, c);
  EXPECT_EQ(a, b);
  EXPECT_NE(a, c);
  float lo = 1e9f, hi = -1e9f;
  for (float h : a) {
    lo = std::min(lo, h);
    hi = std::max(hi, h);
  }
  EXPECT_FLOAT_EQ(lo, 0.0f);
  EXPECT_NEAR(hi, 600.0f, 1e-3f);
}

namespace {
TerrainGridDesc smallTerrain(glm::dvec3 offset) {
  TerrainGridDesc d;
  d.heights.postsX = d.heights.postsY = 101;  // 100 quads: chunks of 32 leave edge chunks of 4
  d.heights.postSpacing_m = 10;
  d.heights.heightScale_m = 300;
  d.offset_m = offset;
  d.chunkQuads = 32;
  return d;
}
}  // namespace

TEST(TerrainGrid, ChunksCoverTheGridWithEdgeChunks) {
  const TerrainGrid g(smallTerrain({0, 0, 0}));
  ASSERT_EQ(g.chunks().size(), 16u);
  EXPECT_EQ(g.totalTriangles(), 2u * 100u * 100u);
  EXPECT_EQ(g.chunks().back().quadsX, 4);
  for (const auto& c : g.chunks()) {
    EXPECT_EQ(c.indexCount, 6u * c.quadsX * c.quadsY);
    EXPECT_LE(c.bounds.min.z, c.bounds.max.z);
  }
  // Every index stays inside its chunk's vertex block.
  for (size_t i = 0; i < g.chunks().size(); ++i) {
    const auto& c = g.chunks()[i];
    const uint32_t nv = static_cast<uint32_t>((c.quadsX + 1) * (c.quadsY + 1));
    for (uint32_t k = 0; k < c.indexCount; ++k) ASSERT_LT(g.indices()[c.firstIndex + k], nv);
  }
}

TEST(TerrainGrid, HeightAtMatchesVerticesAndIgnoresPlacement) {
  const TerrainGrid a(smallTerrain({0, 0, 0}));
  const TerrainGrid far(smallTerrain({1.0e6, -3.0e6, 250.0}));
  // Vertex (x=3, y=2) of chunk 0.
  const auto& v = a.vertices()[2 * 33 + 3];
  EXPECT_NEAR(a.heightAt(30, 20), static_cast<double>(v.position[2]), 1e-4);
  EXPECT_NEAR(far.heightAt(1.0e6 + 30, -3.0e6 + 20), static_cast<double>(v.position[2]) + 250.0, 1e-4);
  // Vertex data is relative to the chunk: identical wherever the terrain is placed.
  ASSERT_EQ(a.vertices().size(), far.vertices().size());
  for (size_t i = 0; i < a.vertices().size(); ++i) ASSERT_EQ(a.vertices()[i].position[0], far.vertices()[i].position[0]);
  // Outside the grid and NaN input clamp instead of reading out of bounds.
  EXPECT_TRUE(std::isfinite(a.heightAt(-1e9, 1e9)));
  EXPECT_TRUE(std::isfinite(a.heightAt(std::nan(""), 0)));
}

TEST(TerrainGrid, SelectionIsFrustumCulled) {
  const TerrainGrid g(smallTerrain({0, 0, 0}));
  std::vector<uint32_t> out(g.chunks().size());
  Camera c;
  c.eye_m = {500, -50, 400};
  c.heading_deg = 0;
  c.pitch_deg = -30;
  const size_t n = g.select(makeFrustum(c), c.eye_m, UINT64_MAX, out);
  EXPECT_GT(n, 1u);
  EXPECT_LT(n, g.chunks().size());
  for (size_t i = 1; i < n; ++i)  // nearest first
    EXPECT_LE(distanceToBox(g.chunks()[out[i - 1]].bounds, c.eye_m), distanceToBox(g.chunks()[out[i]].bounds, c.eye_m));
  // A budget of one full chunk keeps exactly the nearest one.
  const uint32_t nearest = out[0];
  EXPECT_EQ(g.select(makeFrustum(c), c.eye_m, g.triangleCount(g.chunks()[nearest]), out), 1u);
  EXPECT_EQ(out[0], nearest);
  EXPECT_EQ(g.select(makeFrustum(c), c.eye_m, 0, out), 0u);
  c.heading_deg = 180;  // looking away from the terrain
  EXPECT_EQ(g.select(makeFrustum(c), c.eye_m, UINT64_MAX, out), 0u);
}

// Frames of reference for host links: a scene origin at a pole, across the antimeridian, and
// an eyepoint 10 km up all convert geodetic -> ENU -> geodetic without loss.
TEST(Geo, EnuAtThePolesAcrossTheAntimeridianAndAt10km) {
  struct Case {
    Geodetic origin, point;
  };
  const Case cases[] = {
      {{90, 0, 0}, {89.99, 0, 0}},          // north pole origin, 1.1 km along lon 0
      {{90, 0, 0}, {89.99, 90, 100}},       // ... and along lon 90
      {{-90, 0, 0}, {-89.95, -135, 2000}},  // south pole
      {{0, 180, 0}, {0.01, -179.99, 0}},    // across the antimeridian, ~1.1 km east, north
      {{52, -179.995, 0}, {52, 179.995, 0}},  // 690 m west across it
      {{46.5, 7.9, 500}, {46.5, 7.9, 10500}},  // straight up 10 km
      {{46.5, 7.9, 500}, {46.6, 8.0, 10000}},  // 10 km altitude, 13 km away
  };
  for (const Case& c : cases) {
    const EnuFrame f(c.origin);
    const glm::dvec3 enu = f.fromGeodetic(c.point);
    // The straight-line (ECEF) distance is preserved by the rotation.
    const double ecefDistance = glm::length(geodeticToEcef(c.point) - geodeticToEcef(c.origin));
    EXPECT_NEAR(glm::length(enu), ecefDistance, 1e-6) << c.origin.lat_deg << "," << c.origin.lon_deg;
    const Geodetic back = f.toGeodetic(enu);
    EXPECT_NEAR(back.lat_deg, c.point.lat_deg, 1e-9);
    EXPECT_NEAR(back.height_m, c.point.height_m, 1e-5);
    if (std::abs(c.point.lat_deg) < 90) {
      EXPECT_NEAR(std::remainder(back.lon_deg - c.point.lon_deg, 360.0), 0.0, 1e-9);
    }
  }
  // Across the antimeridian east stays continuous: 0.01 deg of longitude at the equator is
  // 1113.2 m east, not 40,000 km west.
  const glm::dvec3 e = EnuFrame({0, 180, 0}).fromGeodetic({0, -179.99, 0});
  EXPECT_NEAR(e.x, 1113.19, 0.01);
  const glm::dvec3 w = EnuFrame({52, -179.995, 0}).fromGeodetic({52, 179.995, 0});
  // The parallel at 52 deg has radius N cos(lat) = 3,934.9 km: 0.01 deg is 686.78 m.
  EXPECT_NEAR(w.x, -686.78, 0.01);
  EXPECT_NEAR(w.y, 0.0, 0.1);
  // 10 km straight up is +z only.
  const glm::dvec3 up = EnuFrame({46.5, 7.9, 500}).fromGeodetic({46.5, 7.9, 10500});
  EXPECT_NEAR(up.z, 10000.0, 1e-6);
  EXPECT_NEAR(up.x, 0.0, 1e-6);
  EXPECT_NEAR(up.y, 0.0, 1e-6);
  // At the north pole the frame is still orthonormal: two points on the same parallel, 90
  // degrees of longitude apart, are sqrt(2) times their horizontal distance from the pole apart.
  const EnuFrame pole({90, 0, 0});
  const glm::dvec3 a = pole.fromGeodetic({89.99, 0, 0}), b = pole.fromGeodetic({89.99, 90, 0});
  EXPECT_NEAR(a.z, b.z, 1e-9);
  EXPECT_NEAR(glm::length(a - b), std::sqrt(2.0) * std::hypot(a.x, a.y), 1e-6);
}

TEST(Sun, ElevationAtNoonMidnightAndEquinoxSunrise) {
  // Equinox 2026-03-20, equator, solar noon (~12:07 UTC at lon 0): nearly overhead.
  EXPECT_GT(sunPosition(20260320, 12.12, 0.0, 0.0).elevation_deg, 89.0);
  // Summer solstice at 52 N, lon 0, 12:02 UTC: 90 - 52 + 23.44 = 61.4 degrees, due south.
  const SunPosition june = sunPosition(20260621, 12.03, 52.0, 0.0);
  EXPECT_NEAR(june.elevation_deg, 61.44, 0.3);
  EXPECT_NEAR(june.azimuth_deg, 180.0, 2.0);
  // Winter solstice: 90 - 52 - 23.44 = 14.6 degrees.
  EXPECT_NEAR(sunPosition(20261221, 11.97, 52.0, 0.0).elevation_deg, 14.56, 0.3);
  // Midnight is night; sunrise at the equinox on the equator is due east.
  EXPECT_LT(sunPosition(20260621, 0.0, 52.0, 0.0).elevation_deg, -10.0);
  const SunPosition morning = sunPosition(20260320, 6.5, 0.0, 0.0);
  EXPECT_NEAR(morning.azimuth_deg, 90.0, 1.0);
  EXPECT_GT(morning.elevation_deg, 0.0);
  EXPECT_LT(morning.elevation_deg, 10.0);
  // Longitude shifts local noon: 90 E has its noon six hours earlier.
  EXPECT_NEAR(sunPosition(20260621, 6.03, 52.0, 90.0).elevation_deg, 61.44, 0.3);
  // Daylight fades smoothly through twilight.
  EXPECT_EQ(sunlightFraction(-10.0), 0.0);
  EXPECT_EQ(sunlightFraction(30.0), 1.0);
  EXPECT_GT(sunlightFraction(0.0), 0.2);
  EXPECT_LT(sunlightFraction(0.0), 0.8);
}

// At the north pole the sun's elevation is its declination, which is 0 at the equinox
// instants (USNO: 2024-03-20 03:06, 2026-03-20 14:46, 2026-09-23 00:05 UTC) and +-23.44 at
// the 2026 solstices (06-21 08:24, 12-21 20:50 UTC). sun.h promises about 0.2 degrees;
// Spencer's fractional-year series drifts by a day per century of the Julian leap rule and
// was ~0.4 degrees off in 2026.
TEST(Sun, DeclinationAtPublishedEquinoxesAndSolstices) {
  EXPECT_NEAR(sunPosition(20240320, 3.1, 90.0, 0.0).elevation_deg, 0.0, 0.2);
  EXPECT_NEAR(sunPosition(20260320, 14.0 + 46.0 / 60.0, 90.0, 0.0).elevation_deg, 0.0, 0.2);
  EXPECT_NEAR(sunPosition(20260923, 5.0 / 60.0, 90.0, 0.0).elevation_deg, 0.0, 0.2);
  EXPECT_NEAR(sunPosition(20260621, 8.4, 90.0, 0.0).elevation_deg, 23.44, 0.2);
  EXPECT_NEAR(sunPosition(20261221, 20.0 + 50.0 / 60.0, -90.0, 0.0).elevation_deg, 23.44, 0.2);
  // Equator, March 2026 equinox instant, at the subsolar longitude (noon there is
  // 14:46 UTC + equation of time -7.4 min -> lon ~ -39.5): the sun is overhead.
  EXPECT_GT(sunPosition(20260320, 14.0 + 46.0 / 60.0, 0.0, -39.6).elevation_deg, 89.6);
  // Across midnight at year end the sun moves continuously.
  const SunPosition a = sunPosition(20261231, 23.9999, 52.0, 0.0), b = sunPosition(20270101, 0.0, 52.0, 0.0);
  EXPECT_NEAR(a.elevation_deg, b.elevation_deg, 0.01);
  EXPECT_NEAR(a.azimuth_deg, b.azimuth_deg, 0.05);
}

// Normals of a plane are the plane's normal on every post, the DEM's border rows and columns
// included: there the central difference has one neighbour (the other clamps onto the post
// itself) and must be taken over one spacing, not two. It halved the slope on the border
// (a lighter or darker stripe along the terrain's edge). TerrainGrid's vertices use the same
// rule as heightFieldVertex.
TEST(TerrainGrid, PlaneNormalsAreExactOnTheBorderToo) {
  const int w = 5, h = 4;
  const double spacing = 10.0;
  std::vector<float> z(static_cast<size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) z[static_cast<size_t>(y) * w + x] = static_cast<float>(0.2 * x * spacing - 0.5 * y * spacing);
  const glm::dvec3 expected = glm::normalize(glm::dvec3(-0.2, 0.5, 1.0));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const TerrainVertex v = heightFieldVertex(z, w, h, spacing, x, y);
      EXPECT_NEAR(v.normal[0], expected.x, 1e-5) << x << "," << y;
      EXPECT_NEAR(v.normal[1], expected.y, 1e-5) << x << "," << y;
      EXPECT_NEAR(v.normal[2], expected.z, 1e-5) << x << "," << y;
    }
  const TerrainGridDesc d = smallTerrain({0, 0, 0});
  const TerrainGrid g(d);
  std::vector<float> hts(static_cast<size_t>(d.heights.postsX) * static_cast<size_t>(d.heights.postsY));
  generateHeightfield(d.heights, hts);
  const TerrainChunk& c = g.chunks()[0];
  for (int y = 0; y <= c.quadsY; ++y)
    for (int x = 0; x <= c.quadsX; ++x) {
      const TerrainVertex a = g.vertices()[c.firstVertex + static_cast<size_t>(y) * static_cast<size_t>(c.quadsX + 1) + static_cast<size_t>(x)];
      const TerrainVertex b = heightFieldVertex(hts, d.heights.postsX, d.heights.postsY, d.heights.postSpacing_m, x, y);
      for (int i = 0; i < 3; ++i) ASSERT_NEAR(a.normal[i], b.normal[i], 1e-6) << x << "," << y;
    }
}

// ---------------------------------------------------------------------------------------------
// intersectGround: the first point of a segment on the bilinear surface sampleGround reports.

namespace {

struct Grid {
  std::vector<float> h;
  HeightGrid g;
  Grid(int w, int n, double spacing, glm::dvec3 origin, double (*z)(int, int)) {
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < w; ++x) h.push_back(static_cast<float>(z(x, y)));
    g = {h, w, n, spacing, origin};
  }
};

}  // namespace

TEST(IntersectGround, FlatGridAndSlopedPlaneAnalytic) {
  const Grid flat(11, 11, 10.0, {0.0, 0.0, 0.0}, [](int, int) { return 10.0; });
  GroundHit hit;
  ASSERT_TRUE(intersectGround(flat.g, {5.0, 5.0, 20.0}, {95.0, 95.0, 0.0}, hit));
  EXPECT_NEAR(hit.t, 0.5, 1e-12);
  EXPECT_NEAR(hit.point_m.x, 50.0, 1e-9);
  EXPECT_NEAR(hit.point_m.y, 50.0, 1e-9);
  EXPECT_DOUBLE_EQ(hit.point_m.z, 10.0);
  EXPECT_NEAR(hit.normal.z, 1.0, 1e-12);
  // z = 5 + 0.3 east + 0.1 north (grid-local, posts 4 m apart, origin moved): bilinear patches
  // reproduce the plane, so the hit solves 200 - 300 t = 5 + 0.3 (x(t) + 50) + 0.1 (y(t) + 60) + 100.
  const Grid plane(26, 31, 4.0, {-50.0, -60.0, 100.0}, [](int x, int y) { return 5.0 + 0.3 * 4 * x + 0.1 * 4 * y; });
  const glm::dvec3 a{-40.0, -50.0, 200.0}, b{45.0, 55.0, -100.0};
  ASSERT_TRUE(intersectGround(plane.g, a, b, hit));
  // f(t) = 200 - 300 t - [105 + 0.3 (10 + 85 t) + 0.1 (10 + 105 t)] = 91 - 336 t
  EXPECT_NEAR(hit.t, 91.0 / 336.0, 1e-9);
  GroundSample s;
  ASSERT_TRUE(sampleGround(plane.g, hit.point_m.x, hit.point_m.y, s));
  EXPECT_DOUBLE_EQ(hit.point_m.z, s.height_m);  // the same surface HAT/HOT samples
  EXPECT_NEAR(hit.point_m.z, (a + (b - a) * hit.t).z, 1e-6);
  const double len = std::sqrt(0.3 * 0.3 + 0.1 * 0.1 + 1.0);
  EXPECT_NEAR(hit.normal.x, -0.3 / len, 1e-6);
  EXPECT_NEAR(hit.normal.y, -0.1 / len, 1e-6);
}

TEST(IntersectGround, RidgeBlocksASegmentThatClearsTheFlat) {
  // Flat at 0 with a 50 m ridge along post column 5 (east 50 m).
  const Grid ridge(11, 11, 10.0, {0.0, 0.0, 0.0}, [](int x, int) { return x == 5 ? 50.0 : 0.0; });
  GroundHit hit;
  ASSERT_TRUE(intersectGround(ridge.g, {10.0, 50.0, 30.0}, {90.0, 50.0, 30.0}, hit));
  EXPECT_NEAR(hit.point_m.x, 46.0, 1e-9);  // 5 (x - 40) = 30 on the ridge's west slope
  EXPECT_NEAR(hit.t, 36.0 / 80.0, 1e-12);
  const Grid flat(11, 11, 10.0, {0.0, 0.0, 0.0}, [](int, int) { return 0.0; });
  EXPECT_FALSE(intersectGround(flat.g, {10.0, 50.0, 30.0}, {90.0, 50.0, 30.0}, hit));
  // A diagonal over the ridge: the bilinear patch is not a plane across the diagonal.
  ASSERT_TRUE(intersectGround(ridge.g, {12.0, 3.0, 40.0}, {88.0, 97.0, 40.0}, hit));
  EXPECT_NEAR(hit.point_m.z, 40.0, 1e-9);
  EXPECT_LT(hit.point_m.x, 50.0);
}

TEST(IntersectGround, ParallelBelowStartLeavingTheGridZeroLengthNaNAndHugeCoordinates) {
  const Grid flat(11, 11, 10.0, {0.0, 0.0, 0.0}, [](int, int) { return 10.0; });
  GroundHit hit;
  // Parallel to the ground, 0.5 m above it; on it: touches at the start.
  EXPECT_FALSE(intersectGround(flat.g, {1.0, 2.0, 10.5}, {99.0, 97.0, 10.5}, hit));
  ASSERT_TRUE(intersectGround(flat.g, {1.0, 2.0, 10.0}, {99.0, 97.0, 10.0}, hit));
  EXPECT_EQ(hit.t, 0.0);
  // Parallel to a sloped plane, 1 m above it.
  const Grid slope(11, 11, 10.0, {0.0, 0.0, 0.0}, [](int x, int) { return 2.0 * x; });
  EXPECT_FALSE(intersectGround(slope.g, {0.0, 50.0, 1.0}, {100.0, 50.0, 21.0}, hit));
  // Vertical: straight down onto the slope at east 33.
  ASSERT_TRUE(intersectGround(slope.g, {33.0, 40.0, 100.0}, {33.0, 40.0, -100.0}, hit));
  EXPECT_NEAR(hit.point_m.z, 6.6, 1e-9);
  // Starting below ground: the hit is the start.
  ASSERT_TRUE(intersectGround(flat.g, {50.0, 50.0, 5.0}, {60.0, 60.0, 50.0}, hit));
  EXPECT_EQ(hit.t, 0.0);
  EXPECT_DOUBLE_EQ(hit.point_m.z, 10.0);
  // Leaving the grid before it comes down to the ground: no hit.
  EXPECT_FALSE(intersectGround(flat.g, {50.0, 50.0, 30.0}, {250.0, 50.0, 0.0}, hit));
  // Entering the grid from outside, then down to the ground.
  ASSERT_TRUE(intersectGround(flat.g, {-50.0, 50.0, 30.0}, {50.0, 50.0, 0.0}, hit));
  EXPECT_NEAR(hit.t, 2.0 / 3.0, 1e-12);
  EXPECT_NEAR(hit.point_m.x, 50.0 / 3.0, 1e-9);
  // Missing the grid entirely.
  EXPECT_FALSE(intersectGround(flat.g, {-50.0, -50.0, 0.0}, {-10.0, 200.0, 0.0}, hit));
  // Zero length: above the ground no hit, below it a hit at t = 0.
  EXPECT_FALSE(intersectGround(flat.g, {50.0, 50.0, 11.0}, {50.0, 50.0, 11.0}, hit));
  ASSERT_TRUE(intersectGround(flat.g, {50.0, 50.0, 9.0}, {50.0, 50.0, 9.0}, hit));
  EXPECT_EQ(hit.t, 0.0);
  // NaN, infinities, huge coordinates.
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  hit.t = -7.0;
  EXPECT_FALSE(intersectGround(flat.g, {nan, 50.0, 30.0}, {50.0, 50.0, 0.0}, hit));
  EXPECT_FALSE(intersectGround(flat.g, {50.0, 50.0, 30.0}, {50.0, 50.0, -inf}, hit));
  EXPECT_FALSE(intersectGround(flat.g, {1e300, 50.0, 30.0}, {-1e300, 50.0, 0.0}, hit));
  EXPECT_FALSE(intersectGround(flat.g, {1e15, 1e15, 30.0}, {2e15, 1e15, 0.0}, hit));
  EXPECT_EQ(hit.t, -7.0);  // untouched
  ASSERT_TRUE(intersectGround(flat.g, {1e15, 1e15, 1e6}, {50.0, 50.0, -1e6}, hit));
  EXPECT_TRUE(std::isfinite(hit.point_m.x) && hit.point_m.x >= 0.0 && hit.point_m.x <= 100.0);
  EXPECT_TRUE(std::isfinite(hit.point_m.y) && hit.point_m.y >= 0.0 && hit.point_m.y <= 100.0);
  // A grid sampleGround refuses.
  const Grid tiny(1, 1, 10.0, {0.0, 0.0, 0.0}, [](int, int) { return 0.0; });
  EXPECT_FALSE(intersectGround(tiny.g, {0.0, 0.0, 1.0}, {0.0, 0.0, -1.0}, hit));
}

TEST(IntersectGround, MatchesAFineMarchOnAFractalHeightfield) {
  HeightfieldDesc d;
  d.postsX = d.postsY = 33;
  d.postSpacing_m = 20.0;
  d.heightScale_m = 200.0;
  std::vector<float> h(33 * 33);
  generateHeightfield(d, h);
  const HeightGrid g{h, 33, 33, 20.0, {-320.0, -320.0, 0.0}};
  uint32_t state = 12345;
  auto rnd = [&](double lo, double hi) {
    state = state * 1664525u + 1013904223u;
    return lo + (hi - lo) * (state >> 8) / 16777216.0;
  };
  int hits = 0;
  for (int i = 0; i < 60; ++i) {
    const glm::dvec3 a{rnd(-400, 400), rnd(-400, 400), rnd(50, 260)}, b{rnd(-400, 400), rnd(-400, 400), rnd(-20, 200)};
    GroundHit hit;
    const bool got = intersectGround(g, a, b, hit);
    // March: the first sample on or below the surface (sampleGround), 4,000 steps.
    constexpr int kSteps = 4000;
    int first = -1;
    for (int k = 0; k <= kSteps && first < 0; ++k) {
      const glm::dvec3 p = a + (b - a) * (static_cast<double>(k) / kSteps);
      GroundSample s;
      if (sampleGround(g, p.x, p.y, s) && p.z <= s.height_m) first = k;
    }
    if (first >= 0) {
      ASSERT_TRUE(got) << i;
      EXPECT_LE(hit.t, first / static_cast<double>(kSteps) + 1e-9) << i;
      EXPECT_GE(hit.t, (first - 1) / static_cast<double>(kSteps) - 1e-9) << i;
      ++hits;
    }
    if (got) {
      GroundSample s;
      ASSERT_TRUE(sampleGround(g, hit.point_m.x, hit.point_m.y, s));
      const double z = (a + (b - a) * hit.t).z;
      const bool edge = std::abs(std::abs(hit.point_m.x) - 320.0) < 1e-6 || std::abs(std::abs(hit.point_m.y) - 320.0) < 1e-6;
      if (hit.t > 0.0 && !edge) {
        EXPECT_NEAR(z, s.height_m, 1e-6) << i;
      } else {
        EXPECT_LE(z, s.height_m + 1e-6) << i;  // started, or entered the grid, below the ground
      }
    }
  }
  EXPECT_GT(hits, 10);
}
