// A scene without a [forest] table runs no forest work: the service builds no forest layer, no
// forest pass, no forest buffer, no texture and no thread (paper 004 is opt-in per scene).
#include <gtest/gtest.h>

#include <EGL/egl.h>
#include <GL/glcorearb.h>

#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <string>

#include "gl_fixture.h"
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
  using IsTexture = GLboolean (*)(GLuint);
  auto isTexture = reinterpret_cast<IsTexture>(eglGetProcAddress("glIsTexture"));
  ASSERT_NE(isTexture, nullptr);
  for (GLuint id = 1; id <= 4096; ++id) ASSERT_FALSE(isTexture(id)) << "texture " << id << " exists";
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
