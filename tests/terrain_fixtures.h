// Shared by the terrain tests (roam_test, block_lod_test, terrain_chunks_test): a procedural DEM and a ROAM
// view with the usual test camera (60 deg vertical field of view, 16:9, near 1 m, far 100 km).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <map>
#include <span>
#include <tuple>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/block_lod.h"
#include "lod/heightfield.h"
#include "lod/roam.h"

namespace ig::lod::test {

// Every ROAM mode, and its name for test messages.
inline constexpr RoamMode kAllModes[] = {RoamMode::EnhMerge, RoamMode::MergeQueue, RoamMode::Rebuild, RoamMode::Deferred};
inline const char* modeName(RoamMode m) {
  switch (m) {
    case RoamMode::EnhMerge: return "EnhMerge";
    case RoamMode::MergeQueue: return "MergeQueue";
    case RoamMode::Rebuild: return "Rebuild";
    case RoamMode::Deferred: return "Deferred";
  }
  return "?";
}

// Mountainous fractal heights, w x h samples, rows south first.
inline std::vector<float> fractalHeights(int w, int h, uint32_t seed, double scale_m = 400.0, double spacing_m = 30.0) {
  HeightfieldDesc d;
  d.seed = seed;
  d.postsX = w;
  d.postsY = h;
  d.postSpacing_m = spacing_m;
  d.heightScale_m = scale_m;
  std::vector<float> hts(static_cast<size_t>(w) * static_cast<size_t>(h));
  generateHeightfield(d, hts);
  return hts;
}

inline RoamView terrainView(const glm::dvec3& eye, double heading_deg, double pitch_deg, double tolerance_px,
                            double viewportHeight_px) {
  RoamView v;
  v.camera.eye_m = eye;
  v.camera.heading_deg = heading_deg;
  v.camera.pitch_deg = pitch_deg;
  v.camera.fovY_deg = 60.0;
  v.camera.aspect = 16.0 / 9.0;
  v.camera.near_m = 1.0;
  v.camera.far_m = 100000.0;
  v.viewportHeight_px = viewportHeight_px;
  v.tolerance_px = tolerance_px;
  return v;
}

// Checks that the triangles (clamped to the DEM) tile [0, w-1] x [0, h-1]: positive area,
// areas sum to the rectangle, every edge inside the rectangle used by exactly two triangles
// with opposite directions (no holes, no overlaps, no T-junctions), boundary edges once.
inline ::testing::AssertionResult tilesDem(std::span<const RoamTriangle> tris, int w, int h) {
  std::map<std::tuple<int, int, int, int>, int> directed;
  int64_t area2 = 0;
  for (const auto& t0 : tris) {
    RoamTriangle t = t0;
    for (auto& v : t.v) {
      v.x = std::clamp(v.x, 0, w - 1);
      v.y = std::clamp(v.y, 0, h - 1);
    }
    const int64_t a = static_cast<int64_t>(t.v[1].x - t.v[0].x) * (t.v[2].y - t.v[0].y) -
                      static_cast<int64_t>(t.v[2].x - t.v[0].x) * (t.v[1].y - t.v[0].y);
    if (a <= 0) return ::testing::AssertionFailure() << "triangle with area*2 = " << a;
    area2 += a;
    for (int i = 0; i < 3; ++i) {
      const auto& p = t.v[i];
      const auto& q = t.v[(i + 1) % 3];
      ++directed[{p.x, p.y, q.x, q.y}];
    }
  }
  if (area2 != 2LL * (w - 1) * (h - 1)) return ::testing::AssertionFailure() << "area*2 " << area2;
  for (const auto& [e, n] : directed) {
    const auto [ax, ay, bx, by] = e;
    if (n != 1) return ::testing::AssertionFailure() << "edge used " << n << " times in one direction";
    const bool boundary = (ax == bx && (ax == 0 || ax == w - 1)) || (ay == by && (ay == 0 || ay == h - 1));
    const bool twin = directed.count({bx, by, ax, ay}) > 0;
    if (!boundary && !twin)
      return ::testing::AssertionFailure() << "interior edge (" << ax << "," << ay << ")-(" << bx << "," << by
                                           << ") has no twin: a crack or T-junction";
  }
  return ::testing::AssertionSuccess();
}

// Block LOD tests (block_lod_test, block_lod_mutation_test): a fractal DEM of w x h posts 30 m
// apart, heights up to 800 m, and a view with a 45 deg field of view, 16:9, 720 px high.
struct BlockDem {
  int w, h;
  std::vector<float> z;
  float at(int x, int y) const {  // clamped to the DEM
    x = std::clamp(x, 0, w - 1);
    y = std::clamp(y, 0, h - 1);
    return z[static_cast<size_t>(y) * static_cast<size_t>(w) + static_cast<size_t>(x)];
  }
};

inline BlockDem blockFractal(int w, int h, uint32_t seed = 7) {
  return BlockDem{w, h, fractalHeights(w, h, seed, 800.0, 30.0)};
}

inline RoamView blockViewAt(glm::dvec3 eye, double heading, double pitch, double tol) {
  RoamView v;
  v.camera.eye_m = eye;
  v.camera.heading_deg = heading;
  v.camera.pitch_deg = pitch;
  v.camera.fovY_deg = 45;
  v.camera.aspect = 16.0 / 9.0;
  v.viewportHeight_px = 720;
  v.tolerance_px = tol;
  return v;
}

// Every triangle block LOD emits for its current levels.
inline std::vector<RoamTriangle> blockTriangles(const BlockLod& b) {
  std::vector<RoamTriangle> out(b.triangleBound());
  out.resize(b.emitTriangles(out));
  return out;
}

// The mesh's leaf triangles as sorted vertex tuples (x0, y0, x1, y1, x2, y2): two meshes are
// the same triangulation when these are equal.
inline std::vector<std::tuple<int, int, int, int, int, int>> sortedTriangles(const Roam& roam) {
  std::vector<RoamTriangle> tris(roam.triangleCount());
  tris.resize(roam.emitTriangles(tris));
  std::vector<std::tuple<int, int, int, int, int, int>> out;
  for (const auto& t : tris) out.emplace_back(t.v[0].x, t.v[0].y, t.v[1].x, t.v[1].y, t.v[2].x, t.v[2].y);
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace ig::lod::test
