// render/cells_pass on a real headless context, cells read back from a database file: a
// voxelized flat quad facing the camera renders with no holes inside its projection and nothing
// far outside it, near (3.6 px voxels) and far (sub-pixel voxels, 1 px points); coarser cells cover
// the same pixels as their descendants within a few %; an empty draw list leaves the frame
// identical to the background; the arena refuses an upload when full and evict() frees it
// (blocks merge back); the same scene 1e7 m from the origin renders the same image.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/matrix.hpp>
#include <glm/vec4.hpp>

#include "lod/cells_db.h"
#include "lod/cells_voxel.h"
#include "lod/view.h"
#include "render/cells_pass.h"
#include "headless_gl.h"
#include "render/context.h"
#include "render/image.h"
#include "render/renderer.h"

using namespace ig;

namespace {

constexpr int kW = 320, kH = 180;
constexpr double kPlaneY = 32.5;       // mid-voxel at every level: never on a voxel face
constexpr double kQuadLo = 16.5, kQuadHi = 47.5;
constexpr double kCoverLo = 16.0, kCoverHi = 48.0;  // the voxels' extent at 1, 2 and 4 m

struct Gl : test::HeadlessGl {
  Gl() : HeadlessGl(kW, kH) {}
};

render::Lighting light() {
  render::Lighting l;
  l.fog = false;
  l.fogColor = {0.2, 0.3, 0.4};
  return l;
}

// The quad's cells, written to a database file and opened again (the real path).
struct QuadDb {
  lod::CellDbFile db;
  std::string path;
  // The quad at `origin` + (16.5 .. 47.5); the root cube at `rootMin` with `levels` voxel levels
  // over `rootEdge` (default: a 64 m root at `origin`, 1 m voxels).
  explicit QuadDb(const glm::dvec3& origin) : QuadDb(origin, origin, 64.0, 6) {}
  QuadDb(const glm::dvec3& origin, const glm::dvec3& rootMin, double rootEdge, int levels) {
    lod::VoxelMesh m;
    lod::appendQuad(m, origin + glm::dvec3(kQuadLo, kPlaneY, kQuadLo), origin + glm::dvec3(kQuadHi, kPlaneY, kQuadLo),
                    origin + glm::dvec3(kQuadHi, kPlaneY, kQuadHi), origin + glm::dvec3(kQuadLo, kPlaneY, kQuadHi),
                    0xFF3060E0u);
    lod::VoxelizeConfig vc;
    vc.levels = levels;
    vc.boxMin_m = rootMin;
    vc.boxEdge_m = rootEdge;
    lod::VoxelPyramid p;
    std::string err;
    EXPECT_TRUE(lod::voxelize(m, vc, p, err)) << err;
    static int serial = 0;
    path = testing::TempDir() + "/cells_pass_" + std::to_string(::getpid()) + "_" + std::to_string(serial++) + ".ighc";
    EXPECT_TRUE(lod::writeCellDb(path, p, lod::CellBuildConfig{levels - 1, 2}, nullptr, err)) << err;
    EXPECT_TRUE(db.open(path, err)) << err;
  }
  ~QuadDb() { std::remove(path.c_str()); }
  const lod::CellTree& tree() const { return db.tree(); }
  std::vector<lod::CellPoint> points(uint32_t cell) const {
    std::vector<lod::CellPoint> pts;
    std::string err;
    EXPECT_EQ(lod::cellDbCrc32(db.payload(cell)), db.entries()[cell].crc32);
    EXPECT_TRUE(lod::decodeCell(tree(), cell, db.payload(cell), pts, err)) << err;
    return pts;
  }
  // Uploads every cell and returns the draw list of one level.
  std::vector<lod::CellDraw> level(render::CellsPass& pass, int q) const {
    std::vector<lod::CellDraw> draws;
    for (uint32_t c = tree().levelBegin(q); c < tree().levelBegin(q + 1); ++c) {
      if (!pass.resident(c)) {
        EXPECT_TRUE(pass.upload(c, points(c)));
      }
      draws.push_back({c, 0.0f});
    }
    return draws;
  }
};

lod::Camera facing(double distance_m, const glm::dvec3& origin = glm::dvec3(0.0)) {
  lod::Camera cam;
  cam.eye_m = origin + glm::dvec3(32.0, kPlaneY - distance_m, 32.0);
  cam.heading_deg = 0.0;  // north = +y
  cam.fovY_deg = 45.0;
  cam.aspect = static_cast<double>(kW) / kH;
  cam.near_m = 0.1;
  cam.far_m = 100000.0;
  return cam;
}

render::Image renderCells(Gl& gl, render::CellsPass* pass, const lod::Camera& cam, std::span<const lod::CellDraw> draws,
                          const render::Lighting& lighting = light()) {
  gl.renderer.beginFrame(cam, lighting);
  if (pass) pass->draw(gl.renderer, draws);
  gl.renderer.endFrame();
  gl.renderer.finish();
  render::Image img;
  gl.renderer.readPixels(img);
  EXPECT_EQ(gl.renderer.errors(), "");
  return img;
}

// Pixel rectangle (x0, y0, x1, y1; y down, as Image rows) of the square [lo, hi]^2 in x-z at the plane.
glm::dvec4 projectRect(const lod::Camera& cam, double lo, double hi) {
  const glm::dmat4 vp = lod::projection(cam) *
                        glm::dmat4(lod::viewRotation(cam));
  glm::dvec4 r(1e9, 1e9, -1e9, -1e9);
  for (int i = 0; i < 4; ++i) {
    const glm::dvec3 w(i & 1 ? hi : lo, kPlaneY, i & 2 ? hi : lo);
    const glm::dvec4 c = vp * glm::dvec4(w - cam.eye_m, 1.0);
    const double x = (0.5 + 0.5 * c.x / c.w) * kW, y = (0.5 - 0.5 * c.y / c.w) * kH;
    r = {std::min(r.x, x), std::min(r.y, y), std::max(r.z, x), std::max(r.w, y)};
  }
  return r;
}

bool isBackground(const render::Image& img, int x, int y) {
  const uint8_t* p = &img.rgba[(static_cast<size_t>(y) * kW + x) * 4];
  const auto near = [](uint8_t v, double f) { return std::abs(v - f * 255.0) <= 1.5; };
  return near(p[0], 0.2) && near(p[1], 0.3) && near(p[2], 0.4);
}

struct Coverage {
  int holes = 0, inside = 0, strays = 0, covered = 0;
};

// Holes: background pixels whose centre is inside the quad's projection shrunk by 1 px. Strays:
// covered pixels whose centre is outside the voxels' projection grown by `grow_px`.
Coverage coverage(const render::Image& img, const lod::Camera& cam, double grow_px) {
  const glm::dvec4 in = projectRect(cam, kQuadLo, kQuadHi), out = projectRect(cam, kCoverLo, kCoverHi);
  Coverage c;
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      const double px = x + 0.5, py = y + 0.5;
      const bool bg = isBackground(img, x, y);
      if (!bg) ++c.covered;
      if (px > in.x + 1 && px < in.z - 1 && py > in.y + 1 && py < in.w - 1) {
        ++c.inside;
        if (bg) ++c.holes;
      }
      if (!bg && (px < out.x - grow_px || px > out.z + grow_px || py < out.y - grow_px || py > out.w + grow_px)) ++c.strays;
    }
  }
  return c;
}

TEST(CellsPassGl, NothingBeforeInitAndEmptyDrawIsBackground) {
  Gl gl;
  render::CellsPass pass;
  EXPECT_FALSE(pass.initialized());
  EXPECT_EQ(pass.bufferBytes(), 0u);
  EXPECT_FALSE(pass.upload(0, {}));
  QuadDb q(glm::dvec3(0.0));
  const lod::Camera cam = facing(60.0);
  const render::Image bg = renderCells(gl, nullptr, cam, {});
  std::string err;
  ASSERT_TRUE(pass.init(q.tree(), render::CellsPassConfig{}, err)) << err;
  EXPECT_EQ(pass.bufferBytes(), render::CellsPassConfig{}.arenaBytes);
  const auto draws = q.level(pass, 4);
  const render::Image empty = renderCells(gl, &pass, cam, {});
  ASSERT_EQ(empty.rgba.size(), bg.rgba.size());
  EXPECT_EQ(empty.rgba, bg.rgba);
  EXPECT_EQ(pass.lastStats().drawCalls, 0u);
  // Cells not resident are skipped and counted.
  pass.evictAll();
  const render::Image skipped = renderCells(gl, &pass, cam, draws);
  EXPECT_EQ(skipped.rgba, bg.rgba);
  EXPECT_EQ(pass.lastStats().notResident, draws.size());
  // Bad configs are refused naming the value.
  render::CellsPass bad;
  render::CellsPassConfig bc;
  bc.arenaBytes = 100;
  EXPECT_FALSE(bad.init(q.tree(), bc, err));
  EXPECT_NE(err.find("arenaBytes = 100"), std::string::npos) << err;
  // Above 2^31 points a cell's first point does not fit glMultiDrawArrays' GLint: refused before
  // any GL allocation.
  bc.arenaBytes = (uint64_t{1} << 35) + 256;
  err.clear();
  EXPECT_FALSE(bad.init(q.tree(), bc, err));
  EXPECT_NE(err.find("arenaBytes = 34359738624"), std::string::npos) << err;
  EXPECT_FALSE(bad.initialized());
  bc = {};
  bc.pointScale = std::nanf("");
  EXPECT_FALSE(bad.init(q.tree(), bc, err));
  EXPECT_NE(err.find("pointScale = nan"), std::string::npos) << err;
}

TEST(CellsPassGl, QuadHasNoHolesNearAndFar) {
  Gl gl;
  QuadDb q(glm::dvec3(0.0));
  render::CellsPass pass;
  std::string err;
  ASSERT_TRUE(pass.init(q.tree(), render::CellsPassConfig{}, err)) << err;
  const auto finest = q.level(pass, 4);
  for (double d : {60.0, 300.0}) {
    const lod::Camera cam = facing(d);
    const render::Image img = renderCells(gl, &pass, cam, finest);
    const Coverage c = coverage(img, cam, 2.0);
    EXPECT_GT(c.inside, d < 100 ? 10000 : 300) << d;
    EXPECT_EQ(c.holes, 0) << "distance " << d << " m: " << c.holes << " of " << c.inside << " pixels uncovered";
    EXPECT_EQ(c.strays, 0) << "distance " << d << " m";
    EXPECT_EQ(pass.lastStats().drawnCells, finest.size());
    EXPECT_EQ(pass.lastStats().drawnPoints, q.tree().totalVoxels(4));
    EXPECT_EQ(pass.lastStats().drawCalls, 1u);
    // The quad's colour (0xFF3060E0: R 0xE0, G 0x60, B 0x30; the voxelizer keeps 24-bit colour
    // up to 13 levels), unlit and without fog.
    const uint8_t* mid = &img.rgba[(static_cast<size_t>(kH / 2) * kW + kW / 2) * 4];
    EXPECT_NEAR(mid[0], 224, 1);
    EXPECT_NEAR(mid[1], 96, 1);
    EXPECT_NEAR(mid[2], 48, 1);
  }
}

TEST(CellsPassGl, CoarseCellsCoverAboutTheSamePixels) {
  Gl gl;
  QuadDb q(glm::dvec3(0.0));
  render::CellsPass pass;
  std::string err;
  ASSERT_TRUE(pass.init(q.tree(), render::CellsPassConfig{}, err)) << err;
  const lod::Camera cam = facing(60.0);
  int fine = 0;
  for (int level : {4, 3, 2}) {  // voxels of 1, 2, 4 m (3.6 - 14.1 px), centres 0, 0.5, 1.5 m behind the quad
    const auto draws = q.level(pass, level);
    const Coverage c = coverage(renderCells(gl, &pass, cam, draws), cam, 2.0);
    EXPECT_EQ(c.holes, 0) << "level " << level;
    EXPECT_EQ(c.strays, 0) << "level " << level;
    if (level == 4) fine = c.covered;
    // A voxel's centre lies up to half its edge behind the surface (here 1.5 m of 61.5 m for the
    // 4 m voxels), which shrinks its projection by that ratio per axis: 2 x 2.4 % in area.
    EXPECT_NEAR(c.covered, fine, 0.05 * fine) << "level " << level;
  }
}

TEST(CellsPassGl, ArenaFullThenEvictFrees) {
  Gl gl;
  QuadDb q(glm::dvec3(0.0));
  render::CellsPass pass;
  render::CellsPassConfig cfg;
  cfg.arenaBytes = 8192;  // 32 blocks of 16 points
  std::string err;
  ASSERT_TRUE(pass.init(q.tree(), cfg, err)) << err;
  EXPECT_EQ(pass.capacityBytes(), 8192u);
  const lod::CellTree& t = q.tree();
  ASSERT_GT(t.levelBegin(5) - t.levelBegin(4), 40u);
  std::vector<uint32_t> in;
  uint32_t refused = lod::kNoCell;
  for (uint32_t c = t.levelBegin(4); c < t.levelBegin(5); ++c) {
    ASSERT_LE(t.voxels(c), 16u);  // one block each
    if (!pass.upload(c, q.points(c))) {
      refused = c;
      break;
    }
    in.push_back(c);
  }
  EXPECT_EQ(in.size(), 32u);
  ASSERT_NE(refused, lod::kNoCell);
  EXPECT_FALSE(pass.resident(refused));
  EXPECT_EQ(pass.bytesUsed(), 8192u);
  pass.evict(in[7]);
  EXPECT_FALSE(pass.resident(in[7]));
  EXPECT_EQ(pass.bytesUsed(), 8192u - 256u);
  EXPECT_TRUE(pass.upload(refused, q.points(refused)));
  EXPECT_TRUE(pass.resident(refused));
  // Re-uploading a resident cell replaces it (no leak).
  EXPECT_TRUE(pass.upload(refused, q.points(refused)));
  EXPECT_EQ(pass.bytesUsed(), 8192u);
  // Everything evicted: the blocks merge back into one arena-sized block.
  pass.evictAll();
  EXPECT_EQ(pass.bytesUsed(), 0u);
  std::vector<lod::CellPoint> big(512);
  EXPECT_TRUE(pass.upload(0, big));
  EXPECT_EQ(pass.bytesUsed(), 8192u);
  pass.evict(0);
  big.resize(513);
  EXPECT_FALSE(pass.upload(0, big));  // larger than the arena
  EXPECT_FALSE(pass.upload(t.size(), q.points(1)));  // out of range
  EXPECT_EQ(pass.bytesUsed(), 0u);
  // Interleaved uploads and evictions of mixed sizes never lose space.
  std::vector<std::vector<lod::CellPoint>> sizes = {std::vector<lod::CellPoint>(5), std::vector<lod::CellPoint>(40),
                                                    std::vector<lod::CellPoint>(100), std::vector<lod::CellPoint>(16)};
  uint32_t seed = 11;
  for (int i = 0; i < 2000; ++i) {
    seed = seed * 1664525u + 1013904223u;
    const uint32_t c = (seed >> 8) % 64;
    if (pass.resident(c) && (seed & 1)) pass.evict(c);
    else pass.upload(c, sizes[(seed >> 4) % 4]);
    EXPECT_LE(pass.bytesUsed(), 8192u);
  }
  pass.evictAll();
  big.resize(512);
  EXPECT_TRUE(pass.upload(0, big));
}

// Camera inside the root cube, 10 m from the quad, which fills the view with 22 px points: covered
// to the frame's border (points whose centre lies just outside the view are kept); turned around,
// nothing behind the camera is drawn.
TEST(CellsPassGl, CameraInsideTheRootCube) {
  Gl gl;
  QuadDb q(glm::dvec3(0.0));
  render::CellsPass pass;
  std::string err;
  ASSERT_TRUE(pass.init(q.tree(), render::CellsPassConfig{}, err)) << err;
  const auto finest = q.level(pass, 4);
  lod::Camera cam = facing(10.0);
  ASSERT_TRUE(q.tree().box(0).contains(cam.eye_m));
  const render::Image img = renderCells(gl, &pass, cam, finest);
  int bg = 0;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) bg += isBackground(img, x, y) ? 1 : 0;
  EXPECT_EQ(bg, 0) << "background pixels (the frame's border?)";
  cam.heading_deg = 180.0;
  const render::Image back = renderCells(gl, &pass, cam, finest);
  EXPECT_EQ(back.rgba, renderCells(gl, nullptr, cam, {}).rgba);
}

// The quad seen obliquely near the right side of the frame (heading -36 deg, so that the
// quad's rows of voxels run both across and into the view there): off the view axis, neighbouring
// voxel centres project up to sqrt(1 + tan^2) of the face-on footprint apart (tan: the centre's
// X / depth, 0.74 at this frame's side), so points of the face-on size leave gaps between them.
// Holes: background pixels whose ray meets the quad at least 1 m inside its edges.
TEST(CellsPassGl, ObliqueQuadNearTheFrameSideHasNoHoles) {
  Gl gl;
  QuadDb q(glm::dvec3(0.0));
  render::CellsPass pass;
  std::string err;
  ASSERT_TRUE(pass.init(q.tree(), render::CellsPassConfig{}, err)) << err;
  const auto finest = q.level(pass, 4);
  for (const double side : {1.0, -1.0}) {  // right side, then mirrored: left side
    lod::Camera cam = facing(60.0);
    cam.heading_deg = -36.0 * side;
    cam.eye_m = glm::dvec3(32.0 + 3.7 * side, -39.0, 32.0);
    const render::Image img = renderCells(gl, &pass, cam, finest);
    const glm::dmat4 inv = glm::inverse(lod::projection(cam) *
                                        glm::dmat4(lod::viewRotation(cam)));
    int inside = 0, holes = 0, holesOuter = 0;
    for (int y = 0; y < kH; ++y) {
      for (int x = 0; x < kW; ++x) {
        const glm::dvec4 p = inv * glm::dvec4(2.0 * (x + 0.5) / kW - 1.0, 1.0 - 2.0 * (y + 0.5) / kH, 0.5, 1.0);
        const glm::dvec3 dir = glm::dvec3(p) / p.w;
        if (!(dir.y > 0.0)) continue;
        const glm::dvec3 hit = cam.eye_m + dir * ((kPlaneY - cam.eye_m.y) / dir.y);
        if (hit.x < kQuadLo + 1.0 || hit.x > kQuadHi - 1.0 || hit.z < kQuadLo + 1.0 || hit.z > kQuadHi - 1.0) continue;
        ++inside;
        if (isBackground(img, x, y)) {
          ++holes;
          if (side > 0 ? x > kW * 3 / 4 : x < kW / 4) ++holesOuter;
        }
      }
    }
    EXPECT_GT(inside, 3000) << "side " << side;
    EXPECT_EQ(holes, 0) << "side " << side << ": " << holes << " of " << inside << " pixels uncovered (" << holesOuter
                        << " in the outer quarter of the frame)";
  }
}

TEST(CellsPassGl, HugeCoordinatesRenderTheSame) {
  Gl gl;
  const glm::dvec3 far(1.0e7, -1.0e7, 1.0e4);
  QuadDb a(glm::dvec3(0.0)), b(far);
  render::CellsPass pa, pb;
  std::string err;
  ASSERT_TRUE(pa.init(a.tree(), render::CellsPassConfig{}, err)) << err;
  ASSERT_TRUE(pb.init(b.tree(), render::CellsPassConfig{}, err)) << err;
  const render::Image ia = renderCells(gl, &pa, facing(60.0), a.level(pa, 4));
  const render::Image ib = renderCells(gl, &pb, facing(60.0, far), b.level(pb, 4));
  EXPECT_LT(render::rmse(ia, ib), 0.5);
  EXPECT_EQ(coverage(ib, facing(60.0), 2.0).holes, 0);
}

// A root cube of 64 km (a large scan's) and the quad 60 km from its SW corner, the eye 2.5 m from
// the quad: rootMin - eye was sent as one float (3.9 mm steps at 60 km), so that the splats moved
// in those steps as the eye moved. The same quad in a 64 m root beside it must give the same
// coverage, from an eyepoint 0.45 of a float step off the float grid, looking at a corner of the
// quad in a 5 degree field of view (a float step is ~3 px there).
TEST(CellsPassGl, AQuadFarFromItsRootMinIsPlacedAsNearIt) {
  Gl gl;
  const glm::dvec3 base(59968.0, 59968.0, 0.0);  // 937 * 64 m: the same 1 m voxel grid in both roots
  QuadDb nearRoot(base), farRoot(base, glm::dvec3(0.0), 65536.0, 16);
  ASSERT_EQ(farRoot.tree().info().rootEdge_m, 65536.0);
  render::CellsPass pa, pb;
  std::string err;
  ASSERT_TRUE(pa.init(nearRoot.tree(), render::CellsPassConfig{}, err)) << err;
  ASSERT_TRUE(pb.init(farRoot.tree(), render::CellsPassConfig{}, err)) << err;
  lod::Camera cam = facing(2.5, base);
  cam.eye_m += glm::dvec3(kQuadLo - 32.0 + 0.45 / 256.0, 0.45 / 256.0, kQuadLo - 32.0 + 0.45 / 256.0);
  cam.fovY_deg = 5.0;
  const render::Image ia = renderCells(gl, &pa, cam, nearRoot.level(pa, 4));
  const render::Image ib = renderCells(gl, &pb, cam, farRoot.level(pb, 14));
  EXPECT_GT(pa.lastStats().drawnPoints, 900u);
  EXPECT_EQ(pa.lastStats().drawnPoints, pb.lastStats().drawnPoints);
  // The same pixels covered (the two databases' voxel colours differ by a level or two).
  int bg = 0, differ = 0;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      bg += isBackground(ia, x, y) ? 1 : 0;
      differ += isBackground(ia, x, y) != isBackground(ib, x, y) ? 1 : 0;
    }
  EXPECT_EQ(differ, 0) << "pixels covered in one image only";
  // Not vacuous: the corner voxel's splat (at the largest point size) against the background.
  EXPECT_GT(bg, kW * kH / 10);
  EXPECT_LT(bg, kW * kH * 9 / 10);
}

// The time of day: the cells' colours are baked in daylight (igtool cells-build: 0.3 ambient +
// 0.7 sun), and the pass drew them so at night too (fog only), bright voxels in a dark scene. At
// night (the sun 30 degrees below the horizon, render::daylight as the service dims the frame)
// they must be darker by about the terrain's factor (a horizontal surface under the noon light
// here: ambient * 0.15 against ambient + (1 - ambient) * sun = 1); by day the image is unchanged.
TEST(CellsPassGl, CellsAreDimmedAtNightLikeTheTerrain) {
  Gl gl;
  QuadDb q(glm::dvec3(0.0));
  render::CellsPass pass;
  std::string err;
  ASSERT_TRUE(pass.init(q.tree(), render::CellsPassConfig{}, err)) << err;
  const auto draws = q.level(pass, 4);
  const lod::Camera cam = facing(60.0);
  const auto render = [&](const render::Lighting& l) { return renderCells(gl, &pass, cam, draws, l); };
  const render::Image plain = render(light());
  const render::Image noon = render(render::daylight(light(), 60.0));
  const render::Image night = render(render::daylight(light(), -30.0));
  EXPECT_EQ(noon.rgba, plain.rgba) << "daylight changed the image";
  double sumNoon = 0.0, sumNight = 0.0;
  int covered = 0;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      if (isBackground(noon, x, y)) continue;
      ++covered;
      for (size_t k = 0; k < 3; ++k) {
        const size_t i = (static_cast<size_t>(y) * kW + static_cast<size_t>(x)) * 4 + k;
        sumNoon += noon.rgba[i];
        sumNight += night.rgba[i];
      }
    }
  ASSERT_GT(covered, 1000);
  const render::Lighting full = light(), dark = render::daylight(light(), -30.0);
  const double terrain = dark.ambient / (full.ambient + (1.0 - full.ambient) * full.sunColor.x);
  const double cells = sumNight / sumNoon;
  EXPECT_GT(cells, 0.5 * terrain);
  EXPECT_LT(cells, 2.0 * terrain) << "cells at night: " << cells << " of noon, the terrain " << terrain;
}

}  // namespace
