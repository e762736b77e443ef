// Geomorphing: a new vertex moves from its start height to its true height over morph_s,
// finished morphs expire, a full table lets vertices pop instead of failing, 0 s is off.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include "lod/geomorph.h"
#include "lod/heightfield.h"
#include "lod/roam.h"
#include "terrain_fixtures.h"

using namespace ig::lod;

TEST(Geomorph, MovesLinearlyToTheTrueHeightThenExpires) {
  Geomorph g(64, 0.5);
  g.start(10, 20, 100.0f, 2.0);
  EXPECT_TRUE(g.contains(10, 20));
  EXPECT_FALSE(g.contains(20, 10));
  EXPECT_FLOAT_EQ(g.height(10, 20, 200.0f, 2.0), 100.0f);
  EXPECT_FLOAT_EQ(g.height(10, 20, 200.0f, 2.25), 150.0f);
  EXPECT_FLOAT_EQ(g.height(10, 20, 200.0f, 2.5), 200.0f);
  EXPECT_FLOAT_EQ(g.height(10, 20, 200.0f, 9.0), 200.0f);
  EXPECT_FLOAT_EQ(g.height(11, 20, 200.0f, 2.0), 200.0f);  // not morphing: the true height
  g.start(10, 20, 0.0f, 2.1);                             // already morphing: unchanged
  EXPECT_FLOAT_EQ(g.height(10, 20, 200.0f, 2.25), 150.0f);
  EXPECT_TRUE(g.active(2.4));
  g.expire(2.4);
  EXPECT_EQ(g.size(), 1u);
  g.expire(2.5);
  EXPECT_EQ(g.size(), 0u);
  EXPECT_FALSE(g.contains(10, 20));
  EXPECT_FALSE(g.active(2.6));
}

TEST(Geomorph, ManyVerticesExpireSelectivelyAndAFullTablePops) {
  Geomorph g(100, 1.0);
  for (int i = 0; i < 100; ++i) g.start(i, -i, static_cast<float>(i), i < 50 ? 0.0 : 0.5);
  EXPECT_EQ(g.size(), 100u);
  g.start(1000, 1000, 5.0f, 0.5);  // over capacity: ignored, the vertex pops
  EXPECT_FALSE(g.contains(1000, 1000));
  g.expire(1.2);  // the first 50 finished at 1.0, the rest run until 1.5
  EXPECT_EQ(g.size(), 50u);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(g.contains(i, -i), i >= 50) << i;
  EXPECT_FLOAT_EQ(g.height(70, -70, 170.0f, 1.0), 120.0f);  // start 70, halfway to 170
}

TEST(Geomorph, ZeroTimeIsOff) {
  Geomorph g(16, 0.0);
  g.start(1, 1, 5.0f, 0.0);
  EXPECT_EQ(g.size(), 0u);
  EXPECT_FLOAT_EQ(g.height(1, 1, 9.0f, 0.0), 9.0f);
}

// A time that is not a number starts no morph (now >= start + morph_s would never hold: the
// entry would never expire and hold its slot for good); the vertex pops to its height.
TEST(Geomorph, ANonFiniteTimeStartsNoMorph) {
  Geomorph g(4, 1.0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  g.start(1, 2, 10.0f, nan);
  g.startOut(3, 4, 10.0f, nan);
  g.start(5, 6, 10.0f, std::numeric_limits<double>::infinity());
  EXPECT_EQ(g.size(), 0u);
  EXPECT_FALSE(g.contains(1, 2));
  EXPECT_EQ(g.height(1, 2, 50.0f, 0.5), 50.0f);
  g.start(1, 2, 10.0f, 0.0);  // a finite time still starts one
  EXPECT_EQ(g.size(), 1u);
  g.expire(2.0);
  EXPECT_EQ(g.size(), 0u);
}

// Drawing at a time that is not a number (a one-off frame) gives the morph's end height, never
// a NaN vertex: the true height for a morph-in, the target for a morph-out.
TEST(Geomorph, ANonFiniteDrawTimeGivesTheEndHeight) {
  Geomorph g(16, 1.0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  g.start(1, 2, 10.0f, 0.0);
  g.startOut(3, 4, 5.0f, 0.0);
  EXPECT_EQ(g.height(1, 2, 50.0f, nan), 50.0f);
  EXPECT_EQ(g.height(3, 4, 30.0f, nan), 5.0f);
  EXPECT_EQ(g.progress(1, 2, nan), 1.0);
  EXPECT_EQ(g.height(1, 2, 50.0f, std::numeric_limits<double>::infinity()), 50.0f);
  EXPECT_EQ(g.height(1, 2, 50.0f, -std::numeric_limits<double>::infinity()), 10.0f);
  MorphOut m(16, 1.0);
  const RoamTriangle fine[1] = {{{{2, 2}, {0, 4}, {0, 0}}}};
  const RoamTriangle cover[1] = {{{{0, 0}, {4, 0}, {0, 4}}}};
  const RoamVertex removed[1] = {{2, 2}};
  const float target[1] = {7.0f};
  m.update(fine, cover, removed, target, 0.0);
  EXPECT_EQ(m.height(2, 2, 30.0f, nan), 7.0f);
}

TEST(Geomorph, OutMorphMovesFromTheTrueHeightToTheTarget) {
  Geomorph g(16, 1.0);
  g.startOut(3, 4, 10.0f, 5.0);
  EXPECT_FLOAT_EQ(g.height(3, 4, 30.0f, 5.0), 30.0f);   // starts at the true height
  EXPECT_FLOAT_EQ(g.height(3, 4, 30.0f, 5.5), 20.0f);
  EXPECT_FLOAT_EQ(g.height(3, 4, 30.0f, 6.0), 10.0f);   // ends on the target
  g.start(3, 4, 0.0f, 5.2);                              // already morphing: unchanged
  EXPECT_FLOAT_EQ(g.height(3, 4, 30.0f, 6.0), 10.0f);
}

namespace {

std::vector<RoamTriangle> meshOf(const Roam& roam) {
  std::vector<RoamTriangle> t(roam.triangleCount());
  t.resize(roam.emitTriangles(t));
  return t;
}
bool sameTri(const RoamTriangle& a, const RoamTriangle& b) {
  for (int i = 0; i < 3; ++i)
    if (a.v[i].x != b.v[i].x || a.v[i].y != b.v[i].y) return false;
  return true;
}
// a \ b (small meshes: quadratic is fine).
std::vector<RoamTriangle> minus(const std::vector<RoamTriangle>& a, const std::vector<RoamTriangle>& b) {
  std::vector<RoamTriangle> out;
  for (const auto& t : a) {
    bool found = false;
    for (const auto& u : b) found = found || sameTri(t, u);
    if (!found) out.push_back(t);
  }
  return out;
}
// Height of the triangle set at (x, y) (first triangle holding the point), vertex heights
// from `h`; NaN if none holds it.
template <class H>
double surfaceAt(std::span<const RoamTriangle> tris, double x, double y, H h) {
  for (const auto& t : tris) {
    const double ax = t.v[0].x, ay = t.v[0].y, bx = t.v[1].x, by = t.v[1].y, cx = t.v[2].x, cy = t.v[2].y;
    const double area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
    const double wa = ((bx - x) * (cy - y) - (by - y) * (cx - x)) / area;
    const double wb = ((cx - x) * (ay - y) - (cy - y) * (ax - x)) / area;
    const double wc = 1.0 - wa - wb;
    if (wa < -1e-9 || wb < -1e-9 || wc < -1e-9) continue;
    return wa * h(t.v[0]) + wb * h(t.v[1]) + wc * h(t.v[2]);
  }
  return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

// Merges morph out: right after the update the drawn surface (ghosts + the new mesh less the
// hidden covers) is the old surface at every removed vertex and ghost centroid (no pop),
// halfway it is the average, at the end the new coarse surface; then the covers are released.
TEST(MorphOut, MergesDoNotPop) {
  const int n = 33;
  HeightfieldDesc d;
  d.seed = 4;
  d.postsX = d.postsY = n;
  d.postSpacing_m = 30.0;
  d.heightScale_m = 600.0;
  std::vector<float> hts(static_cast<size_t>(n) * n);
  generateHeightfield(d, hts);
  auto trueH = [&](const RoamVertex& v) {
    return static_cast<double>(hts[static_cast<size_t>(std::clamp(v.y, 0, n - 1)) * n + static_cast<size_t>(std::clamp(v.x, 0, n - 1))]);
  };
  Roam roam(hts, n, n, 30.0, {0, 0, 0});
  RoamView v;
  v.camera.eye_m = {480, 480, 700};
  v.camera.pitch_deg = -89.0;
  v.camera.fovY_deg = 60.0;
  v.camera.aspect = 1.0;
  v.viewportHeight_px = 1080;
  v.tolerance_px = 1.0;
  // Deferred decides by distance alone: climbing straight up only coarsens (merges only).
  roam.update(v, RoamMode::Deferred);
  const auto before = meshOf(roam);
  v.camera.eye_m.z = 2500.0;
  const RoamStats st = roam.update(v, RoamMode::Deferred);
  ASSERT_EQ(st.splits, 0u);
  ASSERT_GT(st.enhMerges, 0u);
  const auto after = meshOf(roam);
  const auto left = minus(before, after), entered = minus(after, before);
  std::vector<float> targets;
  for (const RoamVertex& r : roam.removedVertices()) targets.push_back(static_cast<float>(roam.meshHeight(r.x, r.y)));
  ASSERT_GT(roam.removedVertices().size(), 10u);

  const double t0 = 10.0, morph = 0.5;
  MorphOut morphOut(4096, morph);
  std::vector<RoamTriangle> coverOf;
  for (const auto& t : left) coverOf.push_back(roam.leafAt(t.v[0].x + t.v[1].x + t.v[2].x, t.v[0].y + t.v[1].y + t.v[2].y));
  const MorphOut::Stats ms = morphOut.update(left, coverOf, roam.removedVertices(), targets, t0);
  EXPECT_EQ(ms.popped, 0u);
  EXPECT_EQ(ms.ghostsAdded, left.size());  // every triangle that left had a removed vertex
  ASSERT_TRUE(morphOut.active());
  std::vector<RoamTriangle> shown;
  for (const auto& t : after)
    if (!morphOut.hidden(t)) shown.push_back(t);
  EXPECT_EQ(shown.size(), after.size() - entered.size());  // every entered triangle is a cover
  auto drawnAt = [&](double x, double y, double now) {
    const double g = surfaceAt(morphOut.ghosts(), x, y, [&](const RoamVertex& w) {
      return static_cast<double>(morphOut.height(w.x, w.y, static_cast<float>(trueH(w)), now));
    });
    return std::isnan(g) ? surfaceAt(std::span<const RoamTriangle>(shown), x, y, trueH) : g;
  };
  double maxPop = 0.0;
  size_t samples = 0;
  auto check = [&](double x, double y) {
    const double oldH = surfaceAt(std::span<const RoamTriangle>(before), x, y, trueH);
    const double newH = surfaceAt(std::span<const RoamTriangle>(after), x, y, trueH);
    ASSERT_FALSE(std::isnan(oldH));
    maxPop = std::max(maxPop, std::abs(newH - oldH));
    EXPECT_NEAR(drawnAt(x, y, t0), oldH, 1e-3) << x << "," << y;
    EXPECT_NEAR(drawnAt(x, y, t0 + 0.5 * morph), 0.5 * (oldH + newH), 1e-3) << x << "," << y;
    EXPECT_NEAR(drawnAt(x, y, t0 + morph), newH, 1e-3) << x << "," << y;
    ++samples;
  };
  for (const RoamVertex& r : roam.removedVertices()) check(r.x, r.y);
  for (const auto& t : left) check((t.v[0].x + t.v[1].x + t.v[2].x) / 3.0, (t.v[0].y + t.v[1].y + t.v[2].y) / 3.0);
  EXPECT_GT(maxPop, 1.0) << "the merges must change the surface, or the test proves nothing";
  EXPECT_GT(samples, 20u);
  // The end: ghosts go, the covers are released for drawing.
  EXPECT_TRUE(morphOut.expire(t0 + 0.5 * morph).empty());
  const auto released = morphOut.expire(t0 + morph);
  EXPECT_EQ(released.size(), entered.size());
  EXPECT_FALSE(morphOut.active());
  for (const auto& t : after) EXPECT_FALSE(morphOut.hidden(t));
}

// A merge at a time that is not a number pops (like every start* at such a time): it adds no
// ghost and hides no cover, also where a ghost's vertex is still morphing out from an earlier
// merge (a cover ending at NaN would never be released).
TEST(MorphOut, ANonFiniteTimeAddsNoGhosts) {
  MorphOut m(64, 1.0);
  const RoamTriangle coarse{{{0, 0}, {4, 0}, {0, 4}}};
  const RoamTriangle fine[2] = {{{{2, 2}, {0, 4}, {0, 0}}}, {{{2, 2}, {0, 0}, {4, 0}}}};
  const RoamVertex removed[1] = {{2, 2}};
  const float target[1] = {5.0f};
  const RoamTriangle covers[2] = {coarse, coarse};
  m.update(fine, covers, removed, target, 0.0);  // (2, 2) morphs out until 1.0
  // Another region merges at NaN; a triangle that left there has (2, 2) as a corner.
  const RoamTriangle other{{{2, 2}, {4, 0}, {4, 4}}};
  const RoamTriangle otherCover{{{0, 4}, {4, 0}, {4, 4}}};
  const RoamVertex removed2[1] = {{3, 2}};
  const MorphOut::Stats st = m.update(std::span(&other, 1), std::span(&otherCover, 1), removed2, target,
                                      std::numeric_limits<double>::quiet_NaN());
  EXPECT_EQ(st.ghostsAdded, 0u);
  EXPECT_FALSE(m.hidden(otherCover));
  m.expire(2.0);
  EXPECT_FALSE(m.active());
  EXPECT_FALSE(m.hidden(otherCover));
}

// A cover that leaves the mesh before its morph ends (the eye came back) drops its ghosts.
TEST(MorphOut, ACoverThatLeavesDropsItsGhosts) {
  MorphOut m(64, 1.0);
  const RoamTriangle coarse{{{0, 0}, {4, 0}, {0, 4}}};
  const RoamTriangle fine[2] = {{{{2, 2}, {0, 4}, {0, 0}}}, {{{2, 2}, {0, 0}, {4, 0}}}};
  const RoamVertex removed[1] = {{2, 2}};
  const float target[1] = {5.0f};
  const RoamTriangle covers[2] = {coarse, coarse};
  const auto st = m.update(fine, covers, removed, target, 0.0);
  EXPECT_EQ(st.ghostsAdded, 2u);
  EXPECT_TRUE(m.hidden(coarse));
  const auto st2 = m.update(std::span(&coarse, 1), fine, {}, {}, 0.3);
  EXPECT_EQ(st2.ghostsDropped, 2u);
  EXPECT_FALSE(m.active());
  EXPECT_FALSE(m.hidden(coarse));
}

// A vertex a split adds starts at the height the surface drawn so far had there (lod/geomorph.h),
// also when a refinement adds several levels in one update (its split ends are new as well)
// and when its ends are still on their way from an earlier update: at the moment a morph
// starts, every vertex of the new mesh lies on the previously drawn surface (no pop).
TEST(Geomorph, SplitsOfSeveralLevelsInOneUpdateStartOnTheDrawnSurface) {
  const int n = 65;
  HeightfieldDesc d;
  d.seed = 5;
  d.postsX = n;
  d.postsY = n;
  d.postSpacing_m = 30.0;
  d.heightScale_m = 600.0;
  std::vector<float> hts(static_cast<size_t>(n) * n);
  generateHeightfield(d, hts);
  auto sample = [&](int x, int y) { return hts[static_cast<size_t>(std::clamp(y, 0, n - 1)) * n + std::clamp(x, 0, n - 1)]; };
  Roam cur(hts, n, n, 30.0, {0, 0, 0});
  Roam prev(cur, RoamConfig{});  // the mesh drawn before each update
  Geomorph g(1 << 16, 1.0);
  auto view = [](const glm::dvec3& eye) {
    RoamView v;
    v.camera.eye_m = eye;
    v.camera.pitch_deg = -60;
    v.camera.fovY_deg = 60;
    v.camera.aspect = 1.5;
    v.tolerance_px = 1.0;
    v.viewportHeight_px = 1000;
    return v;
  };
  // Height of the previously drawn surface at grid point (x, y): its leaf there, corners at
  // their drawn (morphing) heights.
  auto drawnBefore = [&](int x, int y, double now_s) {
    const RoamTriangle t = prev.leafAt(3 * int64_t{x}, 3 * int64_t{y});
    const double x0 = t.v[0].x, y0 = t.v[0].y;
    const double det = (t.v[1].x - x0) * (t.v[2].y - y0) - (t.v[2].x - x0) * (t.v[1].y - y0);
    const double w1 = ((x - x0) * (t.v[2].y - y0) - (t.v[2].x - x0) * (y - y0)) / det;
    const double w2 = ((t.v[1].x - x0) * (y - y0) - (x - x0) * (t.v[1].y - y0)) / det;
    const double w[3] = {1.0 - w1 - w2, w1, w2};
    double z = 0.0;
    for (int k = 0; k < 3; ++k) z += w[k] * static_cast<double>(g.height(t.v[k].x, t.v[k].y, sample(t.v[k].x, t.v[k].y), now_s));
    return z;
  };
  // A refinement from the base triangles, a closer look while those morphs run, a climb that
  // merges most of it away, and back down: vertices created again while their first morph
  // would still run start on the drawn surface as well.
  const RoamView views[] = {view({900, 900, 800}), view({1000, 950, 300}), view({1000, 950, 9000}), view({1000, 950, 300})};
  const double times[] = {0.0, 0.5, 0.6, 0.7};
  for (int u = 0; u < 4; ++u) {
    cur.update(views[u], RoamMode::EnhMerge);
    if (u != 2) {
      ASSERT_GT(cur.createdVertices().size(), 20u);
    } else {
      ASSERT_GT(cur.removedVertices().size(), 20u);
    }
    g.startSplits(cur, hts, n, n, times[u]);
    std::vector<RoamTriangle> tris(cur.triangleCount());
    tris.resize(cur.emitTriangles(tris));
    double worst = 0.0;
    for (const RoamTriangle& t : tris)
      for (const RoamVertex& p : t.v)
        worst = std::max(worst, std::abs(static_cast<double>(g.height(p.x, p.y, sample(p.x, p.y), times[u])) -
                                         drawnBefore(p.x, p.y, times[u])));
    EXPECT_LT(worst, 0.01) << "update " << u << ": a new vertex pops by " << worst << " m";
    // After morph_s every vertex is at its true height.
    for (const RoamTriangle& t : tris)
      for (const RoamVertex& p : t.v) EXPECT_EQ(g.height(p.x, p.y, sample(p.x, p.y), times[u] + 1.0), sample(p.x, p.y));
    prev.update(views[u], RoamMode::EnhMerge);
  }
}

namespace {

// The drawn surface of a mesh in padded-grid coordinates (lod/roam.h): corners clamped onto the
// w x h DEM, zero-area triangles not drawn, each corner at the height `h(padded corner)`. For a
// DEM point, every drawn triangle holding it is asked (so a crack, two heights at one point,
// shows as a range).
struct DrawnMesh {
  struct Tri {
    RoamVertex c[3];  // clamped
    double z[3];
  };
  std::vector<Tri> tris;
  std::vector<std::vector<uint32_t>> cells;  // per DEM cell: triangles whose box touches it
  int w = 0, h = 0;
  template <class H>
  DrawnMesh(std::span<const RoamTriangle> in, int w_, int h_, H height) : w(w_), h(h_) {
    cells.resize(static_cast<size_t>(w) * static_cast<size_t>(h));
    for (const RoamTriangle& t : in) {
      Tri d;
      for (int k = 0; k < 3; ++k) {
        d.c[k] = {std::clamp(t.v[k].x, 0, w - 1), std::clamp(t.v[k].y, 0, h - 1)};
        d.z[k] = height(t.v[k]);
      }
      const int64_t a = int64_t{d.c[1].x - d.c[0].x} * (d.c[2].y - d.c[0].y) - int64_t{d.c[2].x - d.c[0].x} * (d.c[1].y - d.c[0].y);
      if (a == 0) continue;
      const auto i = static_cast<uint32_t>(tris.size());
      tris.push_back(d);
      const int x0 = std::min({d.c[0].x, d.c[1].x, d.c[2].x}), x1 = std::max({d.c[0].x, d.c[1].x, d.c[2].x});
      const int y0 = std::min({d.c[0].y, d.c[1].y, d.c[2].y}), y1 = std::max({d.c[0].y, d.c[1].y, d.c[2].y});
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) cells[static_cast<size_t>(y) * static_cast<size_t>(w) + static_cast<size_t>(x)].push_back(i);
    }
  }
  // Lowest and highest drawn height at DEM point (x, y); NaN if no triangle holds it.
  std::pair<double, double> at(double x, double y) const {
    double lo = std::numeric_limits<double>::quiet_NaN(), hi = lo;
    const int cx = std::clamp(static_cast<int>(x), 0, w - 1), cy = std::clamp(static_cast<int>(y), 0, h - 1);
    for (uint32_t i : cells[static_cast<size_t>(cy) * static_cast<size_t>(w) + static_cast<size_t>(cx)]) {
      const Tri& t = tris[i];
      const double ax = t.c[0].x, ay = t.c[0].y, bx = t.c[1].x, by = t.c[1].y, qx = t.c[2].x, qy = t.c[2].y;
      const double area = (bx - ax) * (qy - ay) - (by - ay) * (qx - ax);
      const double wa = ((bx - x) * (qy - y) - (by - y) * (qx - x)) / area;
      const double wb = ((qx - x) * (ay - y) - (qy - y) * (ax - x)) / area;
      const double wc = 1.0 - wa - wb;
      if (wa < -1e-9 || wb < -1e-9 || wc < -1e-9) continue;
      const double z = wa * t.z[0] + wb * t.z[1] + wc * t.z[2];
      lo = std::isnan(lo) ? z : std::min(lo, z);
      hi = std::isnan(hi) ? z : std::max(hi, z);
    }
    return {lo, hi};
  }
};

RoamView morphView(const glm::dvec3& eye, double pitch_deg, double tolerance_px) {
  RoamView v;
  v.camera.eye_m = eye;
  v.camera.pitch_deg = pitch_deg;
  v.camera.fovY_deg = 60;
  v.camera.aspect = 1.5;
  v.tolerance_px = tolerance_px;
  v.viewportHeight_px = 1000;
  return v;
}

// Largest jump of the drawn surface at an update: at every vertex of the mesh drawn after it
// (its DEM point, clamped vertices included) the difference to the surface drawn just before,
// and the spread of heights the new mesh draws at one point (a crack). Checks crack-freedom
// (tilesDem) and that every vertex is at its true height morph_s later.
struct PopProbe {
  int w, hgt;
  std::vector<float> hts;
  Roam cur, prev;
  Geomorph g;
  double worstPop = 0.0, worstCrack = 0.0;
  size_t created = 0;
  PopProbe(int w_, int h_, uint32_t seed)
      : w(w_), hgt(h_), hts(ig::lod::test::fractalHeights(w_, h_, seed, 600.0)), cur(hts, w, hgt, 30.0, {0, 0, 0}),
        prev(cur, RoamConfig{}), g(1 << 16, 1.0) {}
  float sample(const RoamVertex& v) const {
    return hts[static_cast<size_t>(std::clamp(v.y, 0, hgt - 1)) * static_cast<size_t>(w) + static_cast<size_t>(std::clamp(v.x, 0, w - 1))];
  }
  std::vector<RoamTriangle> mesh(const Roam& r) const {
    std::vector<RoamTriangle> t(r.triangleCount());
    t.resize(r.emitTriangles(t));
    return t;
  }
  void step(const RoamView& view, RoamMode mode, double now_s, const char* what) {
    const auto before = mesh(prev);
    const DrawnMesh old(before, w, hgt, [&](const RoamVertex& p) { return static_cast<double>(g.height(p.x, p.y, sample(p), now_s)); });
    cur.update(view, mode);
    created += cur.createdVertices().size();
    g.startSplits(cur, hts, w, hgt, now_s);
    const auto after = mesh(cur);
    EXPECT_TRUE(ig::lod::test::tilesDem(after, w, hgt)) << what;
    const DrawnMesh now(after, w, hgt, [&](const RoamVertex& p) { return static_cast<double>(g.height(p.x, p.y, sample(p), now_s)); });
    double pop = 0.0, crack = 0.0;
    RoamVertex at{};
    for (const RoamTriangle& t : after)
      for (const RoamVertex& p : t.v) {
        const double x = std::clamp(p.x, 0, w - 1), y = std::clamp(p.y, 0, hgt - 1);
        const double z = static_cast<double>(g.height(p.x, p.y, sample(p), now_s));
        const auto [lo, hi] = old.at(x, y);
        ASSERT_FALSE(std::isnan(lo)) << what;
        const double d = std::max(std::abs(z - lo), std::abs(z - hi));
        if (d > pop) {
          pop = d;
          at = p;
        }
        const auto [nlo, nhi] = now.at(x, y);
        crack = std::max(crack, nhi - nlo);
      }
    EXPECT_LT(pop, 0.01) << what << " (" << w << " x " << hgt << "): vertex (" << at.x << "," << at.y << ") pops by " << pop << " m";
    EXPECT_LT(crack, 0.01) << what << " (" << w << " x " << hgt << "): a crack of " << crack << " m";
    worstPop = std::max(worstPop, pop);
    worstCrack = std::max(worstCrack, crack);
    for (const RoamTriangle& t : after)
      for (const RoamVertex& p : t.v) ASSERT_NEAR(g.height(p.x, p.y, sample(p), now_s + 1.0), sample(p), 1e-3) << what;
    prev.update(view, mode);
    g.expire(now_s);
  }
};

}  // namespace

// DEMs that are not 2^k + 1 samples a side: ROAM pads the grid and draws the vertices beyond
// the DEM clamped onto its east / north edge (lod/roam.h). Several padded vertices then share
// one drawn point, and a new vertex's drawn point need not be the midpoint of its split ends as
// drawn. At every update (first refinement, moves, a teleport, a tolerance change, a climb
// that merges and a descent that splits again) the drawn surface must not jump at any vertex,
// clamped ones included, and must not crack.
TEST(Geomorph, SplitsOnADemThatIsNot2kPlus1StartOnTheDrawnSurface) {
  struct Dem {
    int w, h;
  };
  for (const Dem dem : {Dem{50, 40}, Dem{33, 17}, Dem{34, 18}, Dem{18, 34}, Dem{40, 50}, Dem{2, 2}, Dem{2, 9}, Dem{3, 2}, Dem{5, 3}}) {
    SCOPED_TRACE(testing::Message() << dem.w << " x " << dem.h);
    PopProbe p(dem.w, dem.h, 7);
    const double ex = (dem.w - 1) * 30.0, ny = (dem.h - 1) * 30.0;  // the east and north edges
    p.step(morphView({ex - 100, ny - 150, 400}, -60, 1.0), RoamMode::EnhMerge, 0.0, "first refinement");
    p.step(morphView({ex - 40, ny - 60, 120}, -50, 1.0), RoamMode::EnhMerge, 0.3, "a closer look at the NE corner");
    p.step(morphView({ex - 40, ny - 60, 120}, -50, 0.3), RoamMode::EnhMerge, 0.4, "a finer tolerance");
    p.step(morphView({60, 60, 150}, -50, 0.5), RoamMode::EnhMerge, 0.5, "a teleport to the SW corner");
    p.step(morphView({ex - 10, 50, 100}, -40, 0.5), RoamMode::EnhMerge, 0.6, "a teleport to the SE corner");
    p.step(morphView({ex - 10, 50, 9000}, -89, 0.5), RoamMode::EnhMerge, 0.7, "a climb (merges)");
    p.step(morphView({50, ny - 10, 100}, -40, 0.5), RoamMode::EnhMerge, 0.8, "down at the NW corner");
    p.step(morphView({ex - 30, ny - 30, 60}, -30, 0.4), RoamMode::Deferred, 0.9, "Deferred at the NE corner");
    p.step(morphView({ex * 0.5, ny - 20, 80}, -30, 0.4), RoamMode::Deferred, 1.05, "Deferred along the north edge");
    if (dem.w > 3 && dem.h > 3) {
      EXPECT_GT(p.created, 100u) << "the views must refine, or the test proves nothing";
    }
  }
}

// Merges near the clamped east / north edge of a DEM that is not 2^k + 1 samples a side: right
// after the update the drawn surface (ghosts, then the new mesh less the hidden covers) is the
// surface drawn before at every removed vertex's point and every ghost's centroid (no pop), and
// at the end of the morph every removed vertex is on the new mesh as drawn (corners clamped
// onto the DEM, Roam::meshHeight), so the swap from the ghosts to the covers does not show.
TEST(MorphOut, MergesNearTheClampedEdgeDoNotPop) {
  struct Dem {
    int w, h;
  };
  for (const Dem dem : {Dem{50, 40}, Dem{40, 50}, Dem{34, 18}}) {
    SCOPED_TRACE(testing::Message() << dem.w << " x " << dem.h);
    const int w = dem.w, h = dem.h;
    const std::vector<float> hts = ig::lod::test::fractalHeights(w, h, 4, 600.0);
    auto trueH = [&](const RoamVertex& v) {
      return static_cast<double>(hts[static_cast<size_t>(std::clamp(v.y, 0, h - 1)) * static_cast<size_t>(w) +
                                     static_cast<size_t>(std::clamp(v.x, 0, w - 1))]);
    };
    Roam roam(hts, w, h, 30.0, {0, 0, 0});
    const glm::dvec3 eye{(w - 1) * 30.0 - 60.0, (h - 1) * 30.0 - 60.0, 150.0};
    RoamView v = morphView(eye, -89, 0.5);
    // Deferred decides by distance alone: climbing straight up only coarsens (merges only).
    roam.update(v, RoamMode::Deferred);
    std::vector<RoamTriangle> before(roam.triangleCount());
    before.resize(roam.emitTriangles(before));
    v.camera.eye_m.z = 1500.0;
    const RoamStats st = roam.update(v, RoamMode::Deferred);
    ASSERT_EQ(st.splits, 0u);
    ASSERT_GT(roam.removedVertices().size(), 10u);
    std::vector<RoamTriangle> after(roam.triangleCount());
    after.resize(roam.emitTriangles(after));
    const auto left = minus(before, after);
    std::vector<float> targets;
    for (const RoamVertex& r : roam.removedVertices()) targets.push_back(static_cast<float>(roam.meshHeight(r.x, r.y)));
    std::vector<RoamTriangle> coverOf;
    for (const auto& t : left) coverOf.push_back(roam.leafAt(t.v[0].x + t.v[1].x + t.v[2].x, t.v[0].y + t.v[1].y + t.v[2].y));
    const double t0 = 3.0, morph = 0.5;
    MorphOut morphOut(1 << 14, morph);
    const MorphOut::Stats ms = morphOut.update(left, coverOf, roam.removedVertices(), targets, t0);
    ASSERT_EQ(ms.popped, 0u);
    std::vector<RoamTriangle> shown;
    for (const auto& t : after)
      if (!morphOut.hidden(t)) shown.push_back(t);
    const DrawnMesh oldMesh(before, w, h, trueH), newMesh(after, w, h, trueH), shownMesh(shown, w, h, trueH);
    auto ghostsAt = [&](double now) {
      return DrawnMesh(morphOut.ghosts(), w, h, [&](const RoamVertex& q) {
        return static_cast<double>(morphOut.height(q.x, q.y, static_cast<float>(trueH(q)), now));
      });
    };
    const DrawnMesh ghostsStart = ghostsAt(t0), ghostsEnd = ghostsAt(t0 + morph);
    auto drawnAt = [&](double x, double y, double now) {
      const auto g = (now == t0 ? ghostsStart : ghostsEnd).at(x, y);
      return std::isnan(g.first) ? shownMesh.at(x, y) : g;
    };
    double worstStart = 0.0, worstEnd = 0.0, moved = 0.0;
    // The end is checked at the removed vertices: a ghost whose clamped triangle straddles two
    // clamped coarse triangles cannot match them inside with its corners alone.
    auto check = [&](double x, double y, bool vertex) {
      const auto o = oldMesh.at(x, y), n = newMesh.at(x, y);
      ASSERT_FALSE(std::isnan(o.first));
      ASSERT_FALSE(std::isnan(n.first));
      const auto s = drawnAt(x, y, t0), e = drawnAt(x, y, t0 + morph);
      worstStart = std::max({worstStart, std::abs(s.first - o.first), std::abs(s.second - o.second)});
      if (vertex) worstEnd = std::max({worstEnd, std::abs(e.first - n.first), std::abs(e.second - n.second)});
      moved = std::max(moved, std::abs(n.first - o.first));
    };
    for (const RoamVertex& r : roam.removedVertices()) check(std::clamp(r.x, 0, w - 1), std::clamp(r.y, 0, h - 1), true);
    for (const auto& t : left) {
      double x = 0.0, y = 0.0;
      for (const RoamVertex& q : t.v) {
        x += std::clamp(q.x, 0, w - 1) / 3.0;
        y += std::clamp(q.y, 0, h - 1) / 3.0;
      }
      check(x, y, false);
    }
    EXPECT_GT(moved, 1.0) << "the merges must change the surface, or the test proves nothing";
    EXPECT_LT(worstStart, 0.01) << "the drawn surface jumps at the merge";
    EXPECT_LT(worstEnd, 0.01) << "the ghosts do not end on the coarse surface as drawn: it jumps when the covers show";
  }
}
