// A scene without a [forest] table runs no forest work: the service builds no forest layer, no
// forest pass, no forest buffer, no texture and no thread (paper 004 is opt-in per scene).
#include <gtest/gtest.h>

#include <EGL/egl.h>
#include <GL/glcorearb.h>

#include "gl_fixture.h"
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
