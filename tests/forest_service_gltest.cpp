// A scene without a [forest] table runs no forest work: the service builds no forest layer, no
// forest pass, no forest buffer, no texture and no thread (paper 004 is opt-in per scene).
#include <gtest/gtest.h>

#include <EGL/egl.h>
#include <GL/glcorearb.h>

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <string>
#include <thread>

#include "gl_fixture.h"
#include "gl_objects.h"
#include "ig/clock.h"
#include "lod/terrain_grid.h"

using namespace ig;

TEST(ForestServiceGL, SceneWithoutForestBuildsNoForestPassBufferTextureOrThread) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  ASSERT_TRUE(scene.terrain.has_value());
  scene.forest.reset();
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  const ServiceInfo& info = service->info();
  ASSERT_EQ(info.layers.size(), 1u);
  EXPECT_EQ(info.layers[0].find("forest"), std::string::npos);
  EXPECT_EQ(info.passes, 1u);   // the terrain pass only
  EXPECT_EQ(info.threads, 1u);  // the render thread only
  // Exactly the terrain's vertex and index buffers.
  const lod::TerrainGrid grid(terrainGridDesc(*scene.terrain));
  EXPECT_EQ(info.gpuBufferBytes, grid.vertices().size_bytes() + grid.indices().size_bytes());
  render::Image image;
  service->renderOnce(test::defaultHostAt(5.0), &image);
  // The forest is the only part of igd that creates textures (T, S, Gr): none may exist.
  EXPECT_EQ(test::liveGlObjects("glIsTexture", 4096), 0);
}

// [governor.forest] min_m bounds the 3D trees' distance the governor gives, also when max_m is
// close above it: with min_m = 100, max_m = 150 and every frame over its budget the distance
// goes to 100 m, not to half of max_m (75 m, below the bound).
TEST(ForestServiceGL, GovernorKeepsTheForestNearDistanceWithinMinM) {
  const auto dir = std::filesystem::temp_directory_path() / ("igd_forest_service_gltest_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain->lod = TerrainLayerConfig::Lod::Roam;
  scene.forest = ForestLayerConfig{};
  scene.forest->area_m = {-1000.0, -1000.0, 1000.0, 1000.0};
  cfg.governor.enabled = true;
  cfg.governor.forestMin_m = 100.0;
  cfg.governor.forestMax_m = 150.0;
  cfg.budgetFrame_ms = 0.01;  // every frame overruns: every knob goes to its least detail
  cfg.freeRun = true;
  cfg.frames = 20;
  cfg.statsFile = (dir / "stats.csv").string();
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  MonotonicClock clock;
  std::atomic<bool> stop{false};
  ASSERT_EQ(service->run(clock, stop), 0);
  const auto rows = test::readStatsCsv(cfg.statsFile);
  ASSERT_EQ(rows.size(), 20u);
  for (const auto& row : rows) {
    const double near = std::stod(row.at("forest_near_m"));
    EXPECT_GE(near, 100.0) << "frame " << row.at("frame");
    EXPECT_LE(near, 150.0) << "frame " << row.at("frame");
  }
  EXPECT_EQ(std::stod(rows.back().at("forest_near_m")), 100.0);
  std::filesystem::remove_all(dir);
}

namespace {
// Textures that exist in the current context (names 1..4096).
int liveTextures() { return test::liveGlObjects("glIsTexture", 4096); }

// A fake clock (no time passes in a frame) that asks for a reload at its 3rd frame deadline,
// waits for the reload thread to read the configs, and at the first deadline after the reload was
// applied counts the textures (the render thread calls it: the context is current) and stops.
class ReloadOnceClock final : public Clock {
 public:
  ReloadOnceClock(ReloadSource& reload, const Service*& service, std::atomic<bool>& loaded, std::atomic<bool>& stop)
      : reload_(reload), service_(service), loaded_(loaded), stop_(stop) {}
  int64_t now_ns() const override { return clock_.now_ns(); }
  void sleepUntil_ns(int64_t deadline_ns) override {
    clock_.sleepUntil_ns(deadline_ns);
    ++sleeps_;
    if (service_->configGeneration() > 1) {
      if (texturesAfter < 0) texturesAfter = liveTextures();
      stop_ = true;
    } else if (sleeps_ == 3) {
      texturesBefore = liveTextures();
      reload_.requested = true;
    } else if (sleeps_ > 3) {
      for (int i = 0; i < 5000 && !loaded_; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
  int texturesBefore = -1, texturesAfter = -1;

 private:
  FakeClock clock_;
  ReloadSource& reload_;
  const Service*& service_;
  std::atomic<bool>& loaded_;
  std::atomic<bool>& stop_;
  int64_t sleeps_ = 0;
};
}  // namespace

// The governor's forest layer counts are made at start-up, not in the late frame that first
// needs one (Service::create: prepareLayersDrawn). A reload may widen them ([governor.forest]
// min_layers is reloadable): the new counts must be made by the reload, between two frames, too.
// Here the start-up config fixes the count at the scene's 4 (min_layers = 4: no knob, nothing
// made); the reload allows 1..4, so the composited textures of 1..3 layers must exist after it.
TEST(ForestServiceGL, AReloadThatWidensTheGovernorsForestLayersPreparesTheNewCounts) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain->lod = TerrainLayerConfig::Lod::Roam;
  scene.terrain->size_m = 2048.0;  // small and quick: 64 x 64 quads around the origin
  scene.terrain->offset_m = {-1024.0, -1024.0, 0.0};
  scene.forest = ForestLayerConfig{};
  scene.forest->area_m = {-300.0, -300.0, 300.0, 300.0};
  scene.forest->layers = 4;
  cfg.governor.enabled = true;
  cfg.governor.forestMinLayers = 4;
  cfg.frames = 100;  // a bound; the clock stops the run
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  std::atomic<bool> loaded{false}, stop{false};
  ReloadSource reload;
  reload.load = [&](ServiceConfig& c, SceneConfig& s, std::string&) {
    c = cfg;
    c.governor.forestMinLayers = 1;
    s = scene;
    loaded = true;
    return true;
  };
  const Service* running = service.get();
  ReloadOnceClock clock(reload, running, loaded, stop);
  ASSERT_EQ(service->run(clock, stop, &reload), 0);
  ASSERT_EQ(service->configGeneration(), 2);
  ASSERT_GE(clock.texturesBefore, 0);
  EXPECT_EQ(clock.texturesAfter - clock.texturesBefore, 3) << "layer counts 1..3 not made by the reload";
}
