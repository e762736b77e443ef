// ig/cells_layer (the [cells] scene layer) on a real headless context, with a cell database of
// two voxelized spheres written to a temporary file: after some frames of the per-frame loop
// (receive -> select -> request -> draw -> drawn) the spheres are drawn where they project and
// nothing far outside, every frame within the voxel and byte budgets; origin_m moves the object
// (the same view relative to it renders the same image 1e6 m away, and the old place is empty);
// a missing, corrupt or unreachable source fails create() naming it; a W below the largest cell
// is refused naming w_bytes.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <thread>

#include "ig/cells_layer.h"
#include "ig/clock.h"
#include "lod/cells_db.h"
#include "lod/cells_voxel.h"
#include "cells_test_db.h"
#include "headless_gl.h"
#include "render/context.h"
#include "render/image.h"
#include "render/renderer.h"

using namespace ig;

namespace {

constexpr int kW = 320, kH = 180;
constexpr double kRadius = 20.0;
const glm::dvec3 kCentre(50.0, 50.0, 50.0);  // the large sphere, in the database's frame (root cube [0, 100]^3)

struct Db {
  std::string path;
  Db() {
    lod::VoxelMesh m;
    lod::appendSphere(m, kCentre, kRadius, 48, 0xFF2040E0u);
    lod::appendSphere(m, {80, 80, 80}, 8, 24, 0xFF10C020u);  // behind, partly hidden
    path = testing::TempDir() + "/cells_layer_" + std::to_string(::getpid()) + ".ighc";
    std::string err;
    EXPECT_TRUE(test::writeTestCellDb(m, path, nullptr, err)) << err;
  }
  ~Db() { std::remove(path.c_str()); }
};

const Db& db() {
  static const Db d;
  return d;
}

struct Gl : test::HeadlessGl {
  render::Lighting light;
  Gl() : HeadlessGl(kW, kH) {
    light.fog = false;
    light.fogColor = {0.2, 0.3, 0.4};
  }
  render::Image frame(const lod::Camera& cam, CellsLayer* layer, const Clock* clock = nullptr, double budget_ms = 0.0) {
    if (layer) layer->select(cam, kH, clock, budget_ms);
    renderer.beginFrame(cam, light);
    if (layer) layer->draw(renderer);
    renderer.endFrame();
    renderer.finish();
    render::Image img;
    renderer.readPixels(img);
    return img;
  }
};

// Looking north at the large sphere from 130 m, in the scene frame of a layer placed at `origin`.
lod::Camera camera(const glm::dvec3& origin) {
  lod::Camera c;
  c.eye_m = origin + kCentre + glm::dvec3(0.0, -130.0, 0.0);
  c.heading_deg = 0.0;
  c.pitch_deg = 0.0;
  c.fovY_deg = 60.0;
  c.aspect = static_cast<double>(kW) / kH;
  c.near_m = 0.5;
  c.far_m = 5000.0;
  return c;
}

CellsLayerConfig config(const glm::dvec3& origin) {
  CellsLayerConfig c;
  c.source = db().path;
  c.origin_m = {origin.x, origin.y, origin.z};
  c.voxelBudget = 20000;
  c.wBytes = 16384;
  c.minVoxel_px = 1.0;
  c.gpu_mb = 8;
  c.memory_mb = 4;
  return c;
}

std::unique_ptr<CellsLayer> makeLayer(const CellsLayerConfig& c) {
  std::string error;
  auto layer = CellsLayer::create(c, error);
  EXPECT_TRUE(layer) << error;
  if (layer) {
    EXPECT_TRUE(layer->initRender(error)) << error;
  }
  return layer;
}

// Frames until nothing is requested or in flight and the drawn set stays put (streaming done),
// checking the budgets every frame. Returns the last image.
render::Image converge(Gl& gl, CellsLayer& layer, const lod::Camera& cam, const CellsLayerConfig& c,
                       const Clock* clock = nullptr, double budget_ms = 0.0) {
  render::Image img;
  uint64_t lastArrived = ~uint64_t{0};
  int still = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (int frame = 0; frame < 3000 && still < 3; ++frame) {
    img = gl.frame(cam, &layer, clock, budget_ms);
    const CellsLayerStats& s = layer.stats();
    EXPECT_TRUE(s.select.valid);
    EXPECT_LE(s.select.drawnVoxels, c.voxelBudget) << "frame " << frame;
    EXPECT_LE(s.drawnPoints, c.voxelBudget) << "frame " << frame;
    EXPECT_LE(s.select.requestedBytes, c.wBytes) << "frame " << frame;
    // Settled: nothing asked for, waited for or still on its way (a cell in flight that no split
    // waits on, e.g. one the greedy stopped before, arrives later and changes the picture: on a
    // loaded machine the fetcher's worker can take longer than three frames).
    const bool idle = s.select.requestedCells == 0 && s.select.blockedSplits == 0 && !s.select.stopped &&
                      s.arrivedCells == lastArrived && s.inFlight == 0;
    still = idle ? still + 1 : 0;
    lastArrived = s.arrivedCells;
    if (std::chrono::steady_clock::now() - t0 > std::chrono::seconds(20)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));  // the fetcher's worker reads the file
  }
  EXPECT_EQ(still, 3) << "streaming did not settle";
  return img;
}

bool isBackground(const render::Image& img, const render::Image& bg, int x, int y) {
  const size_t i = (static_cast<size_t>(y) * static_cast<size_t>(img.width) + static_cast<size_t>(x)) * 4;
  for (size_t k = 0; k < 3; ++k)
    if (std::abs(static_cast<int>(img.rgba[i + k]) - static_cast<int>(bg.rgba[i + k])) > 2) return false;
  return true;
}

// The large sphere's projection: a disc around the image centre.
struct Coverage {
  int inside = 0, insideCovered = 0, farOutsideCovered = 0;
};
Coverage coverage(const render::Image& img, const render::Image& bg) {
  const double pxPerM = kH / (2.0 * std::tan(30.0 * 3.14159265358979323846 / 180.0));
  const double r_px = pxPerM * kRadius / std::sqrt(130.0 * 130.0 - kRadius * kRadius);  // silhouette radius
  Coverage c;
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      const double d = std::hypot(x + 0.5 - kW / 2.0, y + 0.5 - kH / 2.0);
      const bool covered = !isBackground(img, bg, x, y);
      if (d < r_px - 2.0) {
        ++c.inside;
        c.insideCovered += covered ? 1 : 0;
      } else if (d > r_px + 4.0 && !(x > kW / 2 && y < kH / 2)) {  // the small sphere is up and right
        c.farOutsideCovered += covered ? 1 : 0;
      }
    }
  }
  return c;
}

}  // namespace

TEST(CellsLayerGL, LocalFileRendersTheObjectWithinTheBudgets) {
  Gl gl;
  const glm::dvec3 origin(300.0, -200.0, 10.0);
  CellsLayerConfig c = config(origin);
  c.voxelBudget = 6000;  // binds: the finest cells in view need more
  auto layer = makeLayer(c);
  ASSERT_TRUE(layer);
  EXPECT_EQ(layer->tree().info().rootMin_m, origin);
  // The fetcher's thread, and the selection's helper where the machine has 4 or more cores.
  EXPECT_EQ(layer->threads(), std::thread::hardware_concurrency() >= 4 ? 2u : 1u);
  EXPECT_GT(layer->gpuBytes(), 0u);
  const lod::Camera cam = camera(origin);
  const render::Image bg = gl.frame(cam, nullptr);
  const render::Image img = converge(gl, *layer, cam, c);
  const CellsLayerStats& s = layer->stats();
  EXPECT_GT(s.drawnCells, 0u);
  EXPECT_GT(s.fetchedBytes, 0u);
  EXPECT_EQ(s.broken, 0u);
  EXPECT_GT(s.residentBytes, 0u);
  EXPECT_LE(s.maxDrawnVoxels, c.voxelBudget);
  EXPECT_GT(s.drawnPoints, c.voxelBudget / 2);
  EXPECT_GT(s.select.maxVoxel_px, 1.0f);  // the budget, not min_voxel_px, stopped the refinement
  const Coverage cov = coverage(img, bg);
  ASSERT_GT(cov.inside, 1000);
  EXPECT_GE(cov.insideCovered, cov.inside * 97 / 100) << "holes in the sphere";
  EXPECT_EQ(cov.farOutsideCovered, 0) << "points far outside the sphere";
  EXPECT_NE(layer->summaryLine().find("cells drawn"), std::string::npos);
}

TEST(CellsLayerGL, OriginMovesTheObjectEvenAMillionMetresAway) {
  Gl gl;
  const glm::dvec3 near(0.0), far(1e6, -1e6, 1e3);
  const CellsLayerConfig cn = config(near), cf = config(far);
  auto a = makeLayer(cn);
  auto b = makeLayer(cf);
  ASSERT_TRUE(a && b);
  const render::Image bg = gl.frame(camera(near), nullptr);
  const render::Image imgA = converge(gl, *a, camera(near), cn);
  const render::Image imgB = converge(gl, *b, camera(far), cf);
  EXPECT_GT(coverage(imgA, bg).insideCovered, 1000);
  // The same view relative to the object: the same picture.
  EXPECT_LT(render::fractionDifferent(imgA, imgB, 8), 0.002);
  // The moved layer seen from the old place: nothing there.
  const render::Image old = gl.frame(camera(near), b.get());
  EXPECT_EQ(render::fractionDifferent(old, bg, 2), 0.0);
  EXPECT_EQ(b->stats().drawnCells, 0u);
}

TEST(CellsLayerGL, TwoSelectThreadsDrawTheSamePicture) {
  Gl gl;
  const glm::dvec3 origin(0.0);
  CellsLayerConfig c1 = config(origin), c2 = c1;
  c1.selectThreads = 1;
  c2.selectThreads = 2;
  auto a = makeLayer(c1);
  auto b = makeLayer(c2);
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->threads(), 1u);
  EXPECT_EQ(b->threads(), 2u);
  EXPECT_NE(b->describe().find("2 select threads"), std::string::npos) << b->describe();
  const render::Image imgA = converge(gl, *a, camera(origin), c1);
  const render::Image imgB = converge(gl, *b, camera(origin), c2);
  EXPECT_EQ(a->stats().drawnCells, b->stats().drawnCells);
  EXPECT_EQ(a->stats().select.drawnVoxels, b->stats().select.drawnVoxels);
  EXPECT_EQ(render::fractionDifferent(imgA, imgB, 0), 0.0);
}

// A clock that moves 1 ms at every reading: every poll of the refinement's deadline finds it past.
class SteppingClock final : public Clock {
 public:
  int64_t now_ns() const override { return now_ += 1'000'000; }
  void sleepUntil_ns(int64_t) override {}

 private:
  mutable std::atomic<int64_t> now_{0};
};

// select() with a clock and a time budget (igd: the cells phase's): the refinement stops at the
// deadline, every frame stays within the budgets, the picture sharpens over more frames and ends
// the same as without a budget.
TEST(CellsLayerGL, ATimeBudgetStopsTheRefinementAndThePictureStillConverges) {
  Gl gl;
  const glm::dvec3 origin(0.0);
  const CellsLayerConfig c = config(origin);
  auto a = makeLayer(c);
  auto b = makeLayer(c);
  ASSERT_TRUE(a && b);
  SteppingClock clock;
  const render::Image imgA = converge(gl, *a, camera(origin), c, &clock, 0.5);
  const render::Image imgB = converge(gl, *b, camera(origin), c);
  EXPECT_GT(a->stats().stoppedFrames, 0u) << "the budget never stopped the refinement";
  EXPECT_EQ(b->stats().stoppedFrames, 0u);
  EXPECT_GT(a->stats().frames, b->stats().frames) << "stopped refinement needs more frames";
  EXPECT_EQ(a->stats().select.drawnVoxels, b->stats().select.drawnVoxels);
  EXPECT_EQ(render::fractionDifferent(imgA, imgB, 0), 0.0);
  const std::string line = a->summaryLine();
  EXPECT_NE(line.find("stopped at its time budget in " + std::to_string(a->stats().stoppedFrames) + " of "),
            std::string::npos)
      << line;
}

TEST(CellsLayerGL, BadSourceFailsNamingIt) {
  std::string error;
  CellsLayerConfig c = config(glm::dvec3(0.0));
  c.source = testing::TempDir() + "/no_such_cells.ighc";
  EXPECT_FALSE(CellsLayer::create(c, error));
  EXPECT_NE(error.find(c.source), std::string::npos) << error;
  EXPECT_NE(error.find("[cells] source"), std::string::npos) << error;

  // Not a database.
  c.source = testing::TempDir() + "/not_cells_" + std::to_string(::getpid()) + ".ighc";
  {
    std::ofstream f(c.source, std::ios::binary);
    f << std::string(4096, 'x');
  }
  error.clear();
  EXPECT_FALSE(CellsLayer::create(c, error));
  EXPECT_NE(error.find(c.source), std::string::npos) << error;
  std::remove(c.source.c_str());

  // Nobody listens (port 1 on loopback): the open times out naming the URL.
  c.source = "http://127.0.0.1:1/bunny.ighc";
  c.openTimeout_s = 0.3;
  error.clear();
  EXPECT_FALSE(CellsLayer::create(c, error));
  EXPECT_NE(error.find(c.source), std::string::npos) << error;

  // W below the database's largest cell: those cells could never be fetched.
  c = config(glm::dvec3(0.0));
  c.wBytes = 8;
  error.clear();
  EXPECT_FALSE(CellsLayer::create(c, error));
  EXPECT_NE(error.find("w_bytes = 8"), std::string::npos) << error;
}

// One cell of 131,072 points (two 256 x 256 voxel planes in a root-only database; 2 MiB in the
// arena): a 1 MB arena can never hold it. Before, initRender accepted it and every arrival of the
// cell evicted the unpinned cells to make room, failed, and fetched the cell again the next frame;
// now initRender refuses naming gpu_mb. A 4 MB arena draws it.
TEST(CellsLayerGL, AnArenaSmallerThanTheLargestCellIsRefusedNamingGpuMb) {
  lod::VoxelMesh m;
  for (double y : {100.5, 150.5})
    lod::appendQuad(m, {0.25, y, 0.25}, {255.75, y, 0.25}, {255.75, y, 255.75}, {0.25, y, 255.75}, 0xFF2040E0u);
  lod::VoxelizeConfig vc;
  vc.levels = 8;
  vc.boxMin_m = glm::dvec3(0.0);
  vc.boxEdge_m = 256.0;
  lod::VoxelPyramid pyramid;
  std::string error;
  ASSERT_TRUE(lod::voxelize(m, vc, pyramid, error)) << error;
  const std::string path = testing::TempDir() + "/cells_layer_big_" + std::to_string(::getpid()) + ".ighc";
  lod::CellTree tree;
  ASSERT_TRUE(lod::writeCellDb(path, pyramid, lod::CellBuildConfig{1, 8}, &tree, error)) << error;
  ASSERT_EQ(tree.size(), 1u);
  ASSERT_EQ(tree.voxels(0), 131072u);

  Gl gl;
  CellsLayerConfig c = config(glm::dvec3(0.0));
  c.source = path;
  c.voxelBudget = 1'000'000;
  c.wBytes = 1 << 24;
  c.memory_mb = 64;
  c.gpu_mb = 1;
  auto small = CellsLayer::create(c, error);
  ASSERT_TRUE(small) << error;
  EXPECT_FALSE(small->initRender(error));
  EXPECT_NE(error.find("gpu_mb = 1"), std::string::npos) << error;
  EXPECT_NE(error.find("131072 points"), std::string::npos) << error;
  EXPECT_EQ(small->gpuBytes(), 0u);

  c.gpu_mb = 4;
  auto layer = makeLayer(c);
  ASSERT_TRUE(layer);
  lod::Camera cam;
  cam.eye_m = {128.0, -200.0, 128.0};
  cam.fovY_deg = 60.0;
  cam.aspect = static_cast<double>(kW) / kH;
  cam.near_m = 0.5;
  cam.far_m = 5000.0;
  for (int frame = 0; frame < 200 && layer->stats().drawnCells == 0; ++frame) {
    gl.frame(cam, layer.get());
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_EQ(layer->stats().drawnPoints, 131072u);
  EXPECT_EQ(layer->stats().uploadFailures, 0u);
  std::remove(path.c_str());
}

// Reload (igd applies SIGHUP's voxel_budget, w_bytes, min_voxel_px through setBudgets): a lower
// voxel budget takes effect at the next frame and drops no resident cell; back at the old budget
// the same cells are drawn again without fetching anything.
TEST(CellsLayerGL, SetBudgetsTakesEffectAndKeepsTheResidentCells) {
  Gl gl;
  const glm::dvec3 origin(0.0);
  const CellsLayerConfig c = config(origin);
  auto layer = makeLayer(c);
  ASSERT_TRUE(layer);
  const lod::Camera cam = camera(origin);
  converge(gl, *layer, cam, c);
  const CellsLayerStats before = layer->stats();
  ASSERT_GT(before.drawnPoints, 2000u);
  layer->setBudgets(2000, c.wBytes, c.minVoxel_px);
  EXPECT_EQ(layer->voxelBudget(), 2000u);
  gl.frame(cam, layer.get());
  EXPECT_LE(layer->stats().drawnPoints, 2000u);
  EXPECT_EQ(layer->stats().residentCells, before.residentCells);
  EXPECT_EQ(layer->stats().residentBytes, before.residentBytes);
  layer->setBudgets(c.voxelBudget, c.wBytes, c.minVoxel_px);
  gl.frame(cam, layer.get());
  EXPECT_EQ(layer->stats().drawnPoints, before.drawnPoints);
  EXPECT_EQ(layer->stats().arrivedCells, before.arrivedCells);
}
