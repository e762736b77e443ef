// The forest pass on a real headless context (paper 004): trees and layers appear where the
// distribution map has density and nothing is drawn in glades (read back pixels, against the
// same frame without the forest); near (3D trees) and far (layers) each on their own; the
// offline textures T and S (coverage, lower layers darker); bad input named.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>

#include <unistd.h>

#include <EGL/egl.h>
#include <GL/glcorearb.h>

#include "ig/bench_forest.h"
#include "ig/forest_layer.h"
#include "ig/forest_tool.h"
#include "lod/heightfield.h"
#include "lod/terrain_grid.h"
#include "render/context.h"
#include "render/image.h"
#include "render/renderer.h"

using namespace ig;

namespace {

constexpr int kW = 160, kH = 120;
constexpr int kPosts = 33;  // 1024 m at 32 m
constexpr double kSpacing = 32.0;

struct World {
  std::unique_ptr<render::GlContext> ctx;
  render::Renderer renderer;
  render::Lighting lighting;
  std::vector<float> heights;
  size_t vertexCount = 0;
  std::string mapFile;
  glm::dvec3 origin{0.0};  // ENU of the terrain's sample (0, 0) and of the map's SW corner

  void setUp() {
    std::string error;
    ctx = render::createContext(render::ContextKind::Headless, kW, kH, error);
    ASSERT_TRUE(ctx) << error;
    ASSERT_TRUE(renderer.init(kW, kH, error)) << error;
    lod::HeightfieldDesc hd;
    hd.postsX = hd.postsY = kPosts;
    hd.postSpacing_m = kSpacing;
    hd.heightScale_m = 40.0;
    heights.resize(static_cast<size_t>(kPosts) * kPosts);
    lod::generateHeightfield(hd, heights);
    const size_t quads = static_cast<size_t>(kPosts - 1) * (kPosts - 1);
    ASSERT_TRUE(renderer.addTerrainMesh(quads * 6, 40.0, error)) << error;
    auto dst = renderer.terrainMeshVertices();
    const auto v = [&](int x, int y) { return lod::heightFieldVertex(heights, kPosts, kPosts, kSpacing, x, y); };
    for (int y = 0; y + 1 < kPosts; ++y)
      for (int x = 0; x + 1 < kPosts; ++x) {
        dst[vertexCount++] = v(x, y), dst[vertexCount++] = v(x + 1, y), dst[vertexCount++] = v(x + 1, y + 1);
        dst[vertexCount++] = v(x, y), dst[vertexCount++] = v(x + 1, y + 1), dst[vertexCount++] = v(x, y + 1);
      }
    // Map: 32 x 32 cells of 32 m; the western half (x < 16) is a glade, the east full density.
    render::Image map;
    map.width = map.height = 32;
    map.rgba.resize(32 * 32 * 4);
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x) {
        uint8_t* p = map.rgba.data() + (static_cast<size_t>(y) * 32 + static_cast<size_t>(x)) * 4;
        p[0] = 110, p[1] = 140, p[2] = 90, p[3] = x < 16 ? 0 : 255;
      }
    mapFile = (std::filesystem::temp_directory_path() / ("forest_gltest_map_" + std::to_string(getpid()) + ".png")).string();
    ASSERT_TRUE(render::writePng(mapFile, map, error)) << error;
  }
  ~World() {
    if (!mapFile.empty()) std::filesystem::remove(mapFile);
  }

  ForestGround ground() const { return {heights, kPosts, kPosts, kSpacing, origin}; }

  ForestLayerConfig config() const {
    ForestLayerConfig c;
    c.map = mapFile;
    c.layers = 4;
    c.spacing_m = 6.0;
    c.nearFadeStart_m = 300.0;
    c.nearFadeEnd_m = 500.0;
    return c;
  }

  render::Image frame(const lod::Camera& cam, ForestLayer* forest) {
    if (forest) forest->select(cam);
    renderer.beginFrame(cam, lighting);
    renderer.drawTerrainMesh(origin, vertexCount);
    if (forest) forest->draw(renderer, origin, vertexCount);
    renderer.endFrame();
    renderer.finish();
    render::Image img;
    renderer.readPixels(img);
    return img;
  }
};

// Straight down over the glade / forest border (x = 512 m), which is the image's vertical
// centre line: west (glade) on the left.
lod::Camera downCamera(double height_m) {
  lod::Camera c;
  c.eye_m = {512.0, 512.0, height_m};
  c.pitch_deg = -90.0;
  c.fovY_deg = 60.0;
  c.aspect = static_cast<double>(kW) / kH;
  c.near_m = 1.0;
  c.far_m = 20000.0;
  return c;
}

int channelDiff(const render::Image& a, const render::Image& b, int x, int y) {
  const size_t i = (static_cast<size_t>(y) * kW + static_cast<size_t>(x)) * 4;
  int d = 0;
  for (size_t k = 0; k < 3; ++k) d = std::max(d, std::abs(int{a.rgba[i + k]} - int{b.rgba[i + k]}));
  return d;
}

bool isSky(const render::Image& a, const render::Image& sky, int x, int y) { return channelDiff(a, sky, x, y) == 0; }

// Largest change in the glade half (left of x0) and the share of changed pixels (> 8 levels)
// in the forest half (right of x1), counting only pixels that show terrain.
void compareHalves(const render::Image& without, const render::Image& with, const render::Image& sky, int x0, int x1,
                   int& gladeMax, double& forestChanged) {
  gladeMax = 0;
  size_t changed = 0, total = 0;
  for (int y = 0; y < kH; ++y) {
    for (int x = 0; x < kW; ++x) {
      if (isSky(without, sky, x, y)) continue;
      const int d = channelDiff(without, with, x, y);
      if (x < x0) gladeMax = std::max(gladeMax, d);
      if (x >= x1) {
        ++total;
        changed += d > 8;
      }
    }
  }
  forestChanged = total ? static_cast<double>(changed) / static_cast<double>(total) : 0.0;
}

}  // namespace

TEST(ForestGL, NearTreesWhereTheMapHasDensityNothingInGlades) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  std::string error;
  auto forest = ForestLayer::create(w.config(), w.ground(), error);
  ASSERT_TRUE(forest) << error;
  EXPECT_GT(forest->stats().trees, 10000u);
  const lod::Camera cam = downCamera(250.0);
  const render::Image without = w.frame(cam, nullptr);
  const render::Image with = w.frame(cam, forest.get());
  const ForestLayerStats st = forest->stats();
  EXPECT_GT(st.treesDrawn, 500u);  // 3D trees under the camera (all nearer than 500 m)
  EXPECT_EQ(st.treesDropped, 0u);
  lod::Camera skyCam = cam;
  skyCam.pitch_deg = 90.0;
  const render::Image sky = w.frame(skyCam, nullptr);
  int gladeMax = 0;
  double forestChanged = 0.0;
  // The border column is x = 80; crowns (4 m) lean outwards by perspective: 10 px margin.
  compareHalves(without, with, sky, kW / 2 - 10, kW / 2 + 10, gladeMax, forestChanged);
  EXPECT_EQ(gladeMax, 0) << "something was drawn in the glade";
  EXPECT_GT(forestChanged, 0.5) << "trees should cover most of the forest half";
  EXPECT_EQ(w.renderer.errors(), "");
}

// The frame governor's forest knob: the distance up to which 3D trees are drawn. A shorter one
// draws fewer trees (about with the square of the distance); bands that would no longer be valid
// are refused and the last ones kept.
TEST(ForestGL, NearDistanceScalesTheTreeBandAndRefusesAnInvalidOne) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  std::string error;
  auto forest = ForestLayer::create(w.config(), w.ground(), error);
  ASSERT_TRUE(forest) << error;
  EXPECT_EQ(forest->nearDistance(), 500.0);
  lod::Camera cam = downCamera(120.0);
  cam.pitch_deg = -20.0;  // looking over the forest half, trees from near to far
  cam.heading_deg = 90.0;
  cam.eye_m = {600.0, 512.0, 120.0};
  w.frame(cam, forest.get());
  const uint32_t full = forest->stats().treesDrawn;
  ASSERT_TRUE(forest->setNearDistance(250.0));
  EXPECT_EQ(forest->nearDistance(), 250.0);
  w.frame(cam, forest.get());
  const uint32_t half = forest->stats().treesDrawn;
  EXPECT_GT(full, 200u);
  EXPECT_LT(half, full * 2 / 3) << full << " -> " << half;
  EXPECT_GT(half, 0u);
  // Beyond the layers' fade-out (6000 m) the fade-in band would pass it: refused, 250 m kept.
  EXPECT_FALSE(forest->setNearDistance(7000.0));
  EXPECT_EQ(forest->nearDistance(), 250.0);
  EXPECT_FALSE(forest->setNearDistance(std::numeric_limits<double>::quiet_NaN()));
  EXPECT_EQ(forest->nearDistance(), 250.0);
  ASSERT_TRUE(forest->setNearDistance(500.0));
  w.frame(cam, forest.get());
  EXPECT_EQ(forest->stats().treesDrawn, full);  // back to the scene's band, the same trees
  EXPECT_EQ(w.renderer.errors(), "");
}

TEST(ForestGL, FarLayersWhereTheMapHasDensityNothingInGlades) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  std::string error;
  auto forest = ForestLayer::create(w.config(), w.ground(), error);
  ASSERT_TRUE(forest) << error;
  const lod::Camera cam = downCamera(2500.0);  // beyond the near range: layers only
  const render::Image without = w.frame(cam, nullptr);
  const render::Image with = w.frame(cam, forest.get());
  const ForestLayerStats st = forest->stats();
  EXPECT_EQ(st.treesDrawn, 0u);
  EXPECT_EQ(st.layers, 4);
  lod::Camera skyCam = cam;
  skyCam.pitch_deg = 90.0;
  const render::Image sky = w.frame(skyCam, nullptr);
  int gladeMax = 0;
  double forestChanged = 0.0;
  // 1 px is ~25 m here; Gr is filtered over half a cell (16 m) at the border: 2 px margin.
  compareHalves(without, with, sky, kW / 2 - 2, kW / 2 + 2, gladeMax, forestChanged);
  EXPECT_EQ(gladeMax, 0) << "layers drawn in the glade";
  EXPECT_GT(forestChanged, 0.5) << "layers should tint the forest half";

  // Beyond the far plane (8 km) the forest is gone: the frame equals the one without it.
  forest->enableParts(true, true, true);
  const lod::Camera farCam = downCamera(9000.0);
  const render::Image farWithout = w.frame(farCam, nullptr);
  const render::Image farWith = w.frame(farCam, forest.get());
  EXPECT_EQ(render::rmse(farWithout, farWith), 0.0);
  EXPECT_EQ(w.renderer.errors(), "");
}

// The frame governor's second forest knob: how many shell layers are drawn. Fewer layers are a
// coarser forest of the same height and density (each drawn layer as thick as the slabs it
// stands for), not the lower part of it: the mean colour over the forest stays near the full
// count's, far nearer than the terrain without the forest; the glade stays untouched, and all
// layers again draw the very same frame.
TEST(ForestGL, FewerLayersDrawTheSameForestCoarser) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  std::string error;
  auto forest = ForestLayer::create(w.config(), w.ground(), error);
  ASSERT_TRUE(forest) << error;
  EXPECT_EQ(forest->layersDrawn(), 4);
  lod::Camera cam = downCamera(1500.0);
  cam.pitch_deg = -50.0;  // oblique: rays cross several slabs
  cam.heading_deg = 90.0;
  cam.eye_m = {-200.0, 512.0, 1500.0};
  const render::Image without = w.frame(cam, nullptr);
  const render::Image full = w.frame(cam, forest.get());
  EXPECT_EQ(forest->stats().layers, 4);
  lod::Camera skyCam = cam;
  skyCam.pitch_deg = 90.0;
  const render::Image sky = w.frame(skyCam, nullptr);
  // Mean |a - b| over the pixels that show terrain.
  auto meanDiff = [&](const render::Image& a, const render::Image& b) {
    double sum = 0.0;
    size_t n = 0;
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        if (isSky(without, sky, x, y)) continue;
        sum += channelDiff(a, b, x, y);
        ++n;
      }
    return n ? sum / static_cast<double>(n) : 0.0;
  };
  const double forestEffect = meanDiff(without, full);
  EXPECT_GT(forestEffect, 5.0);
  for (int m : {2, 1}) {
    forest->setLayersDrawn(m);
    EXPECT_EQ(forest->layersDrawn(), m);
    const render::Image coarse = w.frame(cam, forest.get());
    EXPECT_EQ(forest->stats().layers, m);
    const double d = meanDiff(full, coarse);
    EXPECT_LT(d, 0.35 * forestEffect) << m << " layers: mean change " << d << " against the forest's " << forestEffect;
    EXPECT_GT(d, 0.0) << m << " layers drew the same frame as 4";
    // Straight down over the glade border: nothing in the glade, the forest half tinted.
    const lod::Camera down = downCamera(2500.0);
    const render::Image downWithout = w.frame(down, nullptr);
    const render::Image downWith = w.frame(down, forest.get());
    lod::Camera downSky = down;
    downSky.pitch_deg = 90.0;
    const render::Image downSkyImg = w.frame(downSky, nullptr);
    int gladeMax = 0;
    double forestChanged = 0.0;
    compareHalves(downWithout, downWith, downSkyImg, kW / 2 - 2, kW / 2 + 2, gladeMax, forestChanged);
    EXPECT_EQ(gladeMax, 0) << m << " layers drawn in the glade";
    EXPECT_GT(forestChanged, 0.5) << m << " layers should tint the forest half";
  }
  forest->setLayersDrawn(99);  // clamped to the textures' 4
  EXPECT_EQ(forest->layersDrawn(), 4);
  EXPECT_EQ(render::rmse(w.frame(cam, forest.get()), full), 0.0);
  forest->setLayersDrawn(0);  // all
  EXPECT_EQ(forest->layersDrawn(), 4);
  EXPECT_EQ(w.renderer.errors(), "");
}

TEST(ForestGL, TexturesCoverageAndLowerLayersDarker) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  const std::vector<lod::TreeMesh> models = proceduralTrees();
  render::ForestTextureDesc d;
  d.layers = 4;
  d.size_px = 64;
  d.treesPerTile = 16;
  render::ForestTextures t;
  std::string error;
  ASSERT_TRUE(render::renderForestTextures(models, d, t, error)) << error;
  ASSERT_TRUE(render::validateForestTextures(t, error)) << error;
  EXPECT_EQ(t.layers.width, 64 * 4);
  EXPECT_EQ(t.layers.height, 64);
  EXPECT_NEAR(t.height_m, 18.0 * 1.1, 0.1);
  // Per layer: coverage and mean brightness of the covered texels.
  std::vector<double> coverage, brightness;
  for (int l = 0; l < 4; ++l) {
    double a = 0, b = 0;
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x) {
        const uint8_t* p = t.layers.rgba.data() + (static_cast<size_t>(y) * 256 + static_cast<size_t>(l * 64 + x)) * 4;
        a += p[3] / 255.0;
        b += p[3] / 255.0 * (p[0] + p[1] + p[2]);
      }
    coverage.push_back(a / (64 * 64));
    brightness.push_back(a > 0 ? b / a : 0.0);
  }
  for (int l = 0; l < 4; ++l) EXPECT_GT(coverage[static_cast<size_t>(l)], 0.02) << "layer " << l;
  EXPECT_LT(coverage[3], 0.9);  // the tops leave gaps
  for (int l = 1; l < 4; ++l) EXPECT_GT(brightness[static_cast<size_t>(l)], brightness[static_cast<size_t>(l - 1)]) << l;
  // Fins: the bottom row (trunks and lowest branches) is partly covered, above the crowns nothing.
  double top = 0, lowHalf = 0;
  for (int x = 0; x < t.fins.width; ++x) {
    top += t.fins.rgba[static_cast<size_t>(x) * 4 + 3];
    for (int y = t.fins.height / 2; y < t.fins.height; ++y)
      lowHalf += t.fins.rgba[(static_cast<size_t>(y) * static_cast<size_t>(t.fins.width) + static_cast<size_t>(x)) * 4 + 3];
  }
  EXPECT_EQ(top, 0.0);
  EXPECT_GT(lowHalf, 0.0);

  // Bad input is named.
  d.layers = 0;
  EXPECT_FALSE(render::renderForestTextures(models, d, t, error));
  EXPECT_NE(error.find("layers = 0"), std::string::npos) << error;
  EXPECT_EQ(w.renderer.errors(), "");
}

TEST(ForestGL, BadConfigIsNamed) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  std::string error;
  ForestLayerConfig c = w.config();
  c.nearFadeEnd_m = c.nearFadeStart_m;  // a step
  EXPECT_FALSE(ForestLayer::create(c, w.ground(), error));
  EXPECT_NE(error.find("forest fades"), std::string::npos) << error;
  c = w.config();
  c.map = "/nonexistent/map.png";
  EXPECT_FALSE(ForestLayer::create(c, w.ground(), error));
  EXPECT_NE(error.find("forest.map"), std::string::npos) << error;
  c = w.config();
  c.assets = "/nonexistent";
  EXPECT_FALSE(ForestLayer::create(c, w.ground(), error));
  EXPECT_NE(error.find("forest.assets"), std::string::npos) << error;
  c = w.config();
  c.area_m = {5000, 5000, 6000, 6000};  // outside the terrain
  EXPECT_FALSE(ForestLayer::create(c, w.ground(), error));
  EXPECT_NE(error.find("forest.area_m"), std::string::npos) << error;
}

TEST(ForestGL, AssetsRoundTrip) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  const std::vector<lod::TreeMesh> models = proceduralTrees();
  render::ForestTextureDesc d;
  d.layers = 3;
  d.size_px = 32;
  render::ForestTextures t;
  std::string error;
  ASSERT_TRUE(render::renderForestTextures(models, d, t, error)) << error;
  const std::string dir = (std::filesystem::temp_directory_path() / ("forest_assets_" + std::to_string(getpid()))).string();
  ASSERT_TRUE(writeForestAssets(dir, models, t, error)) << error;
  std::vector<lod::TreeMesh> m2;
  render::ForestTextures t2;
  ASSERT_TRUE(readForestAssets(dir, m2, t2, error)) << error;
  std::filesystem::remove_all(dir);
  ASSERT_EQ(m2.size(), models.size());
  // Same triangles (vertices are renumbered in first-use order on reading).
  ASSERT_EQ(m2[0].indices.size(), models[0].indices.size());
  float worst = 0.0f;
  for (size_t i = 0; i < m2[0].indices.size(); ++i)
    for (int k = 0; k < 3; ++k)
      worst = std::max(worst, std::abs(m2[0].vertices[m2[0].indices[i]].position[k] -
                                       models[0].vertices[models[0].indices[i]].position[k]));
  EXPECT_LT(worst, 1e-3f);
  EXPECT_NEAR(m2[0].height_m, models[0].height_m, 1e-3);
  EXPECT_EQ(t2.layerCount, 3);
  EXPECT_EQ(t2.layers.rgba, t.layers.rgba);
  EXPECT_EQ(t2.fins.rgba, t.fins.rgba);
  EXPECT_NEAR(t2.tile_m, t.tile_m, 1e-9);
}

// Baked assets record the tree spacing they were planted for, and igd refuses them for a forest
// of another spacing (the layers would stand for the wrong density, silently: a 40 m forest
// with assets baked at 6 m drew layers 44x too dense), naming the file, both spacings and
// forest.spacing_m; within 10 % they are used. A file written before the spacing was recorded
// is still read (spacing unknown) and used with a warning; a bad spacing value is refused.
TEST(ForestGL, AssetsRecordTheirSpacingAndAnotherSpacingIsRefused) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  const std::vector<lod::TreeMesh> models = proceduralTrees();
  render::ForestTextureDesc d = forestTextureDesc(6.0, 2);
  d.size_px = 16;
  render::ForestTextures t;
  std::string error;
  ASSERT_TRUE(render::renderForestTextures(models, d, t, error)) << error;
  t.spacing_m = 6.0;
  const std::string dir =
      (std::filesystem::temp_directory_path() / ("forest_assets_spacing_" + std::to_string(getpid()))).string();
  const std::string meta = dir + "/forest_textures.txt";
  ASSERT_TRUE(writeForestAssets(dir, models, t, error)) << error;
  std::vector<lod::TreeMesh> m2;
  render::ForestTextures t2;
  ASSERT_TRUE(readForestAssets(dir, m2, t2, error)) << error;
  EXPECT_DOUBLE_EQ(t2.spacing_m, 6.0);
  ForestLayerConfig c = w.config();
  c.assets = dir;
  c.fins = false;
  c.spacing_m = 40.0;
  error.clear();
  EXPECT_FALSE(ForestLayer::create(c, w.ground(), error));
  for (const char* needle : {"forest_textures.txt", "6 m", "forest.spacing_m = 40 m", "--spacing 40"})
    EXPECT_NE(error.find(needle), std::string::npos) << needle << " not in: " << error;
  c.spacing_m = 6.5;  // 8 % off: used
  EXPECT_TRUE(ForestLayer::create(c, w.ground(), error)) << error;
  // An older file: no spacing_m line. Read, used with a warning naming the file and the key.
  std::string text;
  {
    std::ifstream in(meta);
    for (std::string line; std::getline(in, line);)
      if (line.rfind("spacing_m", 0) != 0) text += line + "\n";
  }
  { std::ofstream(meta) << text; }
  ASSERT_TRUE(readForestAssets(dir, m2, t2, error)) << error;
  EXPECT_EQ(t2.spacing_m, 0.0);
  c.spacing_m = 40.0;
  testing::internal::CaptureStderr();
  const bool created = ForestLayer::create(c, w.ground(), error) != nullptr;
  const std::string warning = testing::internal::GetCapturedStderr();
  EXPECT_TRUE(created) << error;
  EXPECT_NE(warning.find(meta), std::string::npos) << warning;
  EXPECT_NE(warning.find("forest.spacing_m = 40 m"), std::string::npos) << warning;
  // A spacing that is no number >= 0 is refused, naming the file.
  for (const char* bad : {"nan", "-6", "6x", "inf"}) {
    { std::ofstream(meta) << text << "spacing_m " << bad << "\n"; }
    EXPECT_FALSE(readForestAssets(dir, m2, t2, error)) << bad;
    EXPECT_NE(error.find(meta), std::string::npos) << error;
    EXPECT_NE(error.find(std::string("'") + bad + "'"), std::string::npos) << error;
  }
  std::filesystem::remove_all(dir);
  EXPECT_EQ(w.renderer.errors(), "");
}

// Every value of forest_textures.txt is one number and nothing else: 'tile_m 24abc' read as 24 m
// and 'layers 3 5' as 3 layers were accepted silently. Refused, naming the file, the line and the
// value. (Hand-made textures: no GL needed.)
TEST(ForestGL, AssetsWithTrailingJunkAfterAValueAreRefused) {
  const std::vector<lod::TreeMesh> models = proceduralTrees();
  render::ForestTextures t;
  t.layerCount = 2;
  t.finSlices = 1;
  t.tile_m = 24.0;
  t.height_m = 18.0;
  t.spacing_m = 6.0;
  t.layers = {16, 8, std::vector<uint8_t>(16 * 8 * 4, 200)};
  t.fins = {8, 8, std::vector<uint8_t>(8 * 8 * 4, 200)};
  const std::string dir =
      (std::filesystem::temp_directory_path() / ("forest_assets_junk_" + std::to_string(getpid()))).string();
  const std::string meta = dir + "/forest_textures.txt";
  std::string error;
  ASSERT_TRUE(writeForestAssets(dir, models, t, error)) << error;
  std::vector<std::string> lines;
  {
    std::ifstream in(meta);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
  }
  std::vector<lod::TreeMesh> m2;
  render::ForestTextures t2;
  ASSERT_TRUE(readForestAssets(dir, m2, t2, error)) << error;
  const std::pair<const char*, const char*> cases[] = {{"tile_m", "24abc"},   {"layers", "2 5"},  {"fin_slices", "1x"},
                                                       {"height_m", "18 m"}, {"layers", "2.5"}, {"spacing_m", "6 7"},
                                                       {"tile_m", ""}};
  for (const auto& [key, bad] : cases) {
    std::string text;
    size_t lineNo = 0;
    for (size_t i = 0; i < lines.size(); ++i) {
      if (lines[i].rfind(std::string(key) + " ", 0) == 0) {
        text += std::string(key) + " " + bad + "\n";
        lineNo = i + 1;
      } else {
        text += lines[i] + "\n";
      }
    }
    ASSERT_GT(lineNo, 0u) << key;
    { std::ofstream(meta) << text; }
    error.clear();
    EXPECT_FALSE(readForestAssets(dir, m2, t2, error)) << key << " " << bad;
    EXPECT_NE(error.find(meta), std::string::npos) << error;
    EXPECT_NE(error.find("line " + std::to_string(lineNo)), std::string::npos) << error;
    EXPECT_NE(error.find(std::string("'") + bad + "'"), std::string::npos) << error;
  }
  std::filesystem::remove_all(dir);
}

// igbench forest bakes its layers on the tile igd's start-up textures use (>= 4 spacings, whole
// trees within 10 % of the density): it kept a 24 m tile, which at 40 m spacing held one tree
// (layers 2.8x as dense as the forest it measured).
TEST(ForestGL, BenchTexturesHoldTheBenchSpacing) {
  for (const double spacing : {6.0, 40.0, 100.0}) {
    ForestBenchOptions o;
    o.treeSpacing_m = spacing;
    const render::ForestTextureDesc td = forestBenchTextureDesc(o);
    const render::ForestTextureDesc igd = forestTextureDesc(spacing, o.layers);
    EXPECT_GE(td.tile_m, 4.0 * spacing) << spacing;
    EXPECT_EQ(td.tile_m, igd.tile_m) << spacing;
    EXPECT_EQ(td.treesPerTile, igd.treesPerTile) << spacing;
    const double density = td.treesPerTile * spacing * spacing / (td.tile_m * td.tile_m);
    EXPECT_NEAR(density, 1.0, 0.1) << "spacing " << spacing << " m: " << td.treesPerTile << " trees on a "
                                   << td.tile_m << " m tile";
  }
}

// A face corner of a tree OBJ is the whole token: trailing junk ("f 1abc 2 3" read as "f 1 2 3")
// is refused with the file, the line and the token, like the other model loaders.
TEST(ForestGL, TreeObjRefusesJunkInFaceCorners) {
  const std::string file =
      (std::filesystem::temp_directory_path() / ("forest_tree_" + std::to_string(getpid()) + ".obj")).string();
  const std::string head = "v 0 0 0\nv 1 0 0\nv 0 0 1\nvn 0 1 0\n";
  lod::TreeMesh m;
  std::string error;
  for (const char* good : {"1 2 3", "1/1 2/2 3/3", "1//1 2//1 3//1", "1/1/1 2/2/1 3/3/1", "-3 -2 -1"}) {
    { std::ofstream(file) << head << "f " << good << "\n"; }
    EXPECT_TRUE(loadTreeObj(file, false, {}, m, error)) << good << ": " << error;
  }
  for (const char* bad : {"1abc", "1/2x", "1//1junk", "1//", "1/1/1/1", "1.5", "1//0"}) {
    { std::ofstream(file) << head << "f " << bad << " 2 3\n"; }
    error.clear();
    EXPECT_FALSE(loadTreeObj(file, false, {}, m, error)) << bad;
    EXPECT_NE(error.find(file), std::string::npos) << error;
    EXPECT_NE(error.find("line 5"), std::string::npos) << error;
    EXPECT_NE(error.find(std::string("'") + bad + "'"), std::string::npos) << error;
  }
  std::filesystem::remove(file);
}

// ForestPass::drawLayers draws ranges of triangle slots of the terrain mesh buffer that the
// caller hands in: ranges past the buffer's end (or whose vertex count overflows GLsizei) are
// clamped to the buffer, as the terrain pass clamps them, never drawn beyond it.
TEST(ForestGL, DrawLayersClampsRangesToTheTerrainBuffer) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  std::string error;
  auto forest = ForestLayer::create(w.config(), w.ground(), error);
  ASSERT_TRUE(forest) << error;
  render::ForestPass& pass = forest->pass();
  ASSERT_EQ(pass.layerCount(), 4);
  const auto slots = static_cast<uint32_t>(w.renderer.terrainMeshVertices().size() / 3);
  ASSERT_GT(slots, 100u);
  const lod::Camera cam = downCamera(2500.0);
  pass.takeStats();
  const auto layerTriangles = [&](std::span<const lod::TerrainDrawRange> ranges) {
    w.renderer.beginFrame(cam, w.lighting);
    pass.drawLayers(w.renderer, glm::dvec3(0.0), ranges, 4);
    w.renderer.endFrame();
    w.renderer.finish();
    return pass.takeStats().triangles;
  };
  const lod::TerrainDrawRange all{0, slots};
  EXPECT_EQ(layerTriangles(std::span(&all, 1)), uint64_t{slots} * 4);
  const lod::TerrainDrawRange huge{0, 0xFFFFFFFFu};  // 3 * count overflows GLsizei
  EXPECT_EQ(layerTriangles(std::span(&huge, 1)), uint64_t{slots} * 4);
  EXPECT_EQ(w.renderer.errors(), "");
  const lod::TerrainDrawRange past{slots, 10};
  EXPECT_EQ(layerTriangles(std::span(&past, 1)), 0u);
  const lod::TerrainDrawRange tail{slots - 4, 100};
  EXPECT_EQ(layerTriangles(std::span(&tail, 1)), 4u * 4);
  // Several ranges (the multi-draw path): inside, partly outside, wholly outside, overflowing.
  const lod::TerrainDrawRange mixed[] = {{0, 10}, {slots - 4, 100}, {slots + 100, 5}, {0xFFFFFFF0u, 0xFFFFFFFFu}};
  EXPECT_EQ(layerTriangles(mixed), uint64_t{10 + 4} * 4);
  // Draw calls as the terrain pass counts them, one per glMultiDrawArrays: one a layer.
  for (const auto& [ranges, calls] : {std::pair{std::span<const lod::TerrainDrawRange>(mixed), 4u},
                                      std::pair{std::span<const lod::TerrainDrawRange>(&all, 1), 1u}}) {
    w.renderer.beginFrame(cam, w.lighting);
    pass.drawLayers(w.renderer, glm::dvec3(0.0), ranges, 4);
    w.renderer.endFrame();
    w.renderer.finish();
    EXPECT_EQ(pass.takeStats().drawCalls, calls);
  }
  // The vertex-count form: more vertices than the buffer holds.
  w.renderer.beginFrame(cam, w.lighting);
  pass.drawLayers(w.renderer, glm::dvec3(0.0), size_t{slots} * 3 * 1000, 4);
  w.renderer.endFrame();
  w.renderer.finish();
  EXPECT_EQ(pass.takeStats().triangles, uint64_t{slots} * 4);
  EXPECT_EQ(w.renderer.errors(), "");
}

// ForestPass::drawFins draws the fins of the groups it is given; a group named twice (or more
// entries than there are groups) draws that group once and stays inside the pass's arrays.
TEST(ForestGL, DrawFinsDrawsEachGivenGroupOnce) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  std::string error;
  auto forest = ForestLayer::create(w.config(), w.ground(), error);
  ASSERT_TRUE(forest) << error;
  const std::vector<lod::FinGroup>& groups = forest->fins().groups;
  ASSERT_FALSE(groups.empty());
  render::ForestPass& pass = forest->pass();
  const lod::Camera cam = downCamera(2500.0);
  pass.takeStats();
  const auto finsDrawn = [&](std::span<const uint32_t> g) {
    w.renderer.beginFrame(cam, w.lighting);
    pass.drawFins(w.renderer, g);
    w.renderer.endFrame();
    w.renderer.finish();
    return pass.takeStats().fins;
  };
  std::vector<uint32_t> once(groups.size());
  for (size_t i = 0; i < once.size(); ++i) once[i] = static_cast<uint32_t>(i);
  std::vector<uint32_t> repeated;
  for (int k = 0; k < 3; ++k) repeated.insert(repeated.end(), once.begin(), once.end());
  repeated.push_back(static_cast<uint32_t>(groups.size()));  // out of range: skipped
  repeated.push_back(0xFFFFFFFFu);
  const uint64_t all = finsDrawn(once);
  EXPECT_EQ(all, forest->fins().fins.size());
  EXPECT_EQ(finsDrawn(repeated), all);
  const std::vector<uint32_t> first(groups.size() + 8, 0u);
  EXPECT_EQ(finsDrawn(first), groups[0].count);
  EXPECT_EQ(finsDrawn(once), all);  // nothing left marked from the calls before
  EXPECT_EQ(w.renderer.errors(), "");
}

// The pass leaves the cull state and depth mask as it found them (render/forest_pass.h): a
// caller that draws with culling off or depth writes off keeps them off. Each draw switched
// both on at its end, whatever they were before.
TEST(ForestGL, DrawsLeaveCullStateAndDepthMaskAsFound) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  std::string error;
  auto forest = ForestLayer::create(w.config(), w.ground(), error);
  ASSERT_TRUE(forest) << error;
  using Cap = void (*)(GLenum);
  using IsEnabled = GLboolean (*)(GLenum);
  using Mask = void (*)(GLboolean);
  using GetBool = void (*)(GLenum, GLboolean*);
  const auto enable = reinterpret_cast<Cap>(eglGetProcAddress("glEnable"));
  const auto disable = reinterpret_cast<Cap>(eglGetProcAddress("glDisable"));
  const auto isEnabled = reinterpret_cast<IsEnabled>(eglGetProcAddress("glIsEnabled"));
  const auto depthMask = reinterpret_cast<Mask>(eglGetProcAddress("glDepthMask"));
  const auto getBool = reinterpret_cast<GetBool>(eglGetProcAddress("glGetBooleanv"));
  ASSERT_TRUE(enable && disable && isEnabled && depthMask && getBool);
  lod::Camera cam = downCamera(120.0);
  cam.eye_m = {700.3125, -300.4375, 120.0};  // south of the forest, looking north over it: trees, layers
  cam.pitch_deg = -8.0;
  forest->select(cam);
  ASSERT_FALSE(forest->selectedTrees().empty());
  std::vector<uint32_t> groups(forest->fins().groups.size());
  for (size_t i = 0; i < groups.size(); ++i) groups[i] = static_cast<uint32_t>(i);
  ASSERT_FALSE(groups.empty());
  render::ForestPass& pass = forest->pass();
  for (const bool cull : {false, true})
    for (const bool mask : {false, true}) {
      w.renderer.beginFrame(cam, w.lighting);
      w.renderer.drawTerrainMesh(w.origin, w.vertexCount);
      const auto set = [&] {
        if (cull) enable(GL_CULL_FACE);
        else disable(GL_CULL_FACE);
        depthMask(mask ? GL_TRUE : GL_FALSE);
      };
      const auto check = [&](const char* what) {
        GLboolean m = GL_FALSE;
        getBool(GL_DEPTH_WRITEMASK, &m);
        EXPECT_EQ(isEnabled(GL_CULL_FACE) == GL_TRUE, cull) << what << ": cull state changed (was " << cull << ")";
        EXPECT_EQ(m == GL_TRUE, mask) << what << ": depth mask changed (was " << mask << ")";
      };
      set();
      pass.drawTrees(w.renderer, forest->selectedTrees(), forest->selectedModels());
      check("drawTrees");
      set();
      pass.drawLayers(w.renderer, w.origin, w.vertexCount, forest->layerCount());
      check("drawLayers");
      set();
      pass.drawFins(w.renderer, groups);
      check("drawFins");
      enable(GL_CULL_FACE);
      depthMask(GL_TRUE);
      w.renderer.endFrame();
    }
  EXPECT_EQ(w.renderer.errors(), "");
}

// A pass whose init failed (or never ran) draws nothing instead of dereferencing its state.
TEST(ForestGL, UninitialisedPassDrawsNothing) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  render::ForestPass pass;
  w.renderer.beginFrame(downCamera(250.0), w.lighting);
  lod::ForestInstance inst{};
  const lod::ForestModelRange range{0, 1};
  pass.drawTrees(w.renderer, std::span(&inst, 1), std::span(&range, 1));
  pass.drawLayers(w.renderer, glm::dvec3(0.0), w.vertexCount, 4);
  const uint32_t group = 0;
  pass.drawFins(w.renderer, std::span(&group, 1));
  const render::RenderStats st = w.renderer.endFrame();
  EXPECT_EQ(st.triangles, 0u);
  EXPECT_EQ(st.drawCalls, 0u);
  EXPECT_EQ(pass.layerCount(), 0);
  EXPECT_EQ(w.renderer.errors(), "");
}

// renderForestTextures never reports success with textures validateForestTextures rejects: a
// tree model of no height (a valid mesh lying on the ground) or an infinite tile is refused
// with an error naming the value.
TEST(ForestGL, TexturesFromFlatModelsOrAnInfiniteTileFail) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  render::ForestTextureDesc d;
  d.layers = 2;
  d.size_px = 16;
  d.treesPerTile = 4;
  d.supersample = 1;
  std::string error;
  lod::TreeMesh flat;
  flat.name = "flat";
  const float pos[3][3] = {{0.0f, 0.0f, 0.0f}, {1.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}};
  for (const auto& p : pos) {
    lod::TreeVertex v{};
    for (int k = 0; k < 3; ++k) v.position[k] = p[k];
    v.normal[2] = 1.0f;
    v.rgba[1] = v.rgba[3] = 255;
    flat.vertices.push_back(v);
  }
  flat.indices = {0, 1, 2};
  lod::measureTree(flat);
  ASSERT_TRUE(lod::validateTreeMesh(flat, error)) << error;
  render::ForestTextures t;
  EXPECT_FALSE(render::renderForestTextures(std::span(&flat, 1), d, t, error))
      << "height_m = " << t.height_m << ", valid: " << render::validateForestTextures(t, error);
  EXPECT_NE(error.find("high"), std::string::npos) << error;
  const std::vector<lod::TreeMesh> models = proceduralTrees();
  d.tile_m = std::numeric_limits<double>::infinity();
  render::ForestTextures t2;
  EXPECT_FALSE(render::renderForestTextures(models, d, t2, error)) << "tile_m = " << t2.tile_m;
  EXPECT_NE(error.find("tile_m"), std::string::npos) << error;
  d.tile_m = 24.0;
  d.finSliceDepth_m = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(render::renderForestTextures(models, d, t2, error));
  EXPECT_EQ(w.renderer.errors(), "");
}

// No tree models at all: an error, not a division by zero while planting the tile.
TEST(ForestGL, TexturesWithoutModelsFail) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  render::ForestTextureDesc d;
  d.layers = 2;
  d.size_px = 16;
  render::ForestTextures t;
  std::string error;
  EXPECT_FALSE(render::renderForestTextures(std::span<const lod::TreeMesh>(), d, t, error));
  EXPECT_NE(error.find("tree models"), std::string::npos) << error;
  EXPECT_EQ(w.renderer.errors(), "");
}

// A generated map finer than one GL texture holds (more than 16384 cells a side) is refused with
// an error naming forest.cell_m before it is allocated: here 1e6 x 1e6 cells (4 TB of density
// alone) over a 1000 km terrain, with a placement spacing inside the slot limit.
TEST(ForestGL, MapTooLargeForOneTextureIsNamed) {
  const std::vector<float> heights(4, 0.0f);
  const ForestGround ground{heights, 2, 2, 1.0e6, glm::dvec3(0.0)};
  ForestLayerConfig c;
  c.cell_m = 1.0;
  c.spacing_m = 100.0;  // 1e8 slots
  std::string error;
  EXPECT_FALSE(ForestLayer::create(c, ground, error));
  EXPECT_NE(error.find("forest.cell_m"), std::string::npos) << error;
  EXPECT_NE(error.find("16384"), std::string::npos) << error;
}

// The forest stops at its map: with forest.area_m the eastern half of the terrain, the shell
// layers (drawn over the whole terrain mesh) leave the western half, outside the map, untouched
// (outside the map counts as a glade, lod/forest.h) instead of repeating the map's border cells.
TEST(ForestGL, LayersStopAtTheEdgeOfTheMap) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  ForestLayerConfig c = w.config();
  c.map = "";  // generated: forest up to the map's western border
  c.gladeFraction = 0.0;
  c.area_m = {512.0, 0.0, 1024.0, 1024.0};
  std::string error;
  auto forest = ForestLayer::create(c, w.ground(), error);
  ASSERT_TRUE(forest) << error;
  EXPECT_EQ(forest->map().origin_m.x, 512.0);
  const lod::Camera cam = downCamera(2500.0);  // layers only
  const render::Image without = w.frame(cam, nullptr);
  const render::Image with = w.frame(cam, forest.get());
  lod::Camera skyCam = cam;
  skyCam.pitch_deg = 90.0;
  const render::Image sky = w.frame(skyCam, nullptr);
  int outsideMax = 0;
  double forestChanged = 0.0;
  compareHalves(without, with, sky, kW / 2 - 2, kW / 2 + 2, outsideMax, forestChanged);
  EXPECT_EQ(outsideMax, 0) << "layers drawn west of the map";
  EXPECT_GT(forestChanged, 0.3) << "layers should tint the map's half";
  EXPECT_EQ(w.renderer.errors(), "");
}

// A distribution map image larger than the forest area (here 64 x 64 cells of 32 m, 2048 m, over
// a 1024 m terrain) is the area's forest, SW corner at the area's: no tree is planted beyond the
// area (beyond the terrain they stood on the height field's clamped edge, in the air), with the
// whole terrain as the area and with its eastern half.
TEST(ForestGL, AMapImageLargerThanTheAreaPlantsNoTreeOutsideIt) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  render::Image map;
  map.width = map.height = 64;
  map.rgba.assign(64 * 64 * 4, 255);
  const std::string file = w.mapFile + ".large.png";
  std::string error;
  ASSERT_TRUE(render::writePng(file, map, error)) << error;
  const std::array<double, 4> areas[] = {{0.0, 0.0, 0.0, 0.0}, {512.0, 0.0, 1024.0, 1024.0}};
  for (const std::array<double, 4>& area : areas) {
    ForestLayerConfig c = w.config();
    c.map = file;
    c.area_m = area;
    auto forest = ForestLayer::create(c, w.ground(), error);
    ASSERT_TRUE(forest) << error;
    const double x0 = area[2] > 0.0 ? area[0] : 0.0;
    EXPECT_LE(forest->map().extentEast_m(), 1024.0 - x0);
    EXPECT_LE(forest->map().extentNorth_m(), 1024.0);
    const lod::ForestKdTree& kd = forest->kdTree();
    ASSERT_GT(kd.trees().size(), 1000u);
    size_t outside = 0;
    glm::dvec2 most(0.0);
    for (uint32_t i = 0; i < kd.trees().size(); ++i) {
      const glm::dvec3 p = kd.decode(i);
      most = glm::max(most, glm::dvec2(p));
      outside += p.x < x0 - 1e-6 || p.y < -1e-6 || p.x > 1024.0 + 1e-6 || p.y > 1024.0 + 1e-6;
    }
    EXPECT_EQ(outside, 0u) << "of " << kd.trees().size() << " trees; farthest east / north " << most.x << ", "
                           << most.y << " m on a 1024 m terrain (area x from " << x0 << ")";
  }
  std::filesystem::remove(file);
  EXPECT_EQ(w.renderer.errors(), "");
}

// The cross-fade's far edge: a 3D tree that has faded out (alpha 1/512, as at 0.4 m before
// near_fade_end_m of a 200 m band) shows nothing, so the frame equals the layers alone. The
// fading trees wrote depth: every layer fragment behind them was rejected and the faded trees
// stayed visible as tree-shaped holes in the shell layers (which are fully in there), until
// they left the band and the holes popped shut.
TEST(ForestGL, FadedOutTreesLeaveTheLayersBehindThem) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  std::string error;
  auto forest = ForestLayer::create(w.config(), w.ground(), error);
  ASSERT_TRUE(forest) << error;
  lod::Camera cam = downCamera(120.0);
  cam.eye_m = {700.3125, -300.4375, 120.0};  // south of the forest, looking north over it
  cam.pitch_deg = -8.0;
  forest->select(cam);
  std::vector<lod::ForestInstance> faded(forest->selectedTrees().begin(), forest->selectedTrees().end());
  const std::vector<lod::ForestModelRange> ranges(forest->selectedModels().begin(), forest->selectedModels().end());
  ASSERT_GT(faded.size(), 200u);
  for (lod::ForestInstance& t : faded) t.alpha = 1.0f / 512.0f;
  const auto frame = [&](bool trees, bool layers) {
    w.renderer.beginFrame(cam, w.lighting);
    w.renderer.drawTerrainMesh(w.origin, w.vertexCount);
    if (trees) forest->pass().drawTrees(w.renderer, faded, ranges);
    if (layers) forest->pass().drawLayers(w.renderer, w.origin, w.vertexCount, forest->layerCount());
    w.renderer.endFrame();
    w.renderer.finish();
    render::Image img;
    w.renderer.readPixels(img);
    return img;
  };
  const render::Image terrain = frame(false, false), layers = frame(false, true), both = frame(true, true);
  EXPECT_GT(render::fractionDifferent(layers, terrain, 8), 0.05) << "the layers should show there";
  EXPECT_LT(render::fractionDifferent(both, layers, 2), 0.001) << "faded-out trees cut holes into the layers";
  EXPECT_EQ(w.renderer.errors(), "");
}

// A sparse forest's far representation is as sparse as its trees: seen straight down from
// 300 m over the full-density half of the map, the shell layers alone change the picture about
// as much as the 3D trees alone. The start-up textures planted a 24 m tile with at least one
// tree (of one model), so beyond ~34 m spacing the layers stood for a denser forest than the
// one planted: 2.1 times the trees' change at 24 m spacing, 7.7 times at 48 m.
TEST(ForestGL, SparseForestLayersAreAsDenseAsItsTrees) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  const auto meanChange = [](const render::Image& a, const render::Image& b) {
    double sum = 0.0;
    size_t n = 0;
    for (int y = 0; y < kH; ++y)
      for (int x = kW / 2 + 4; x < kW; ++x, ++n) sum += channelDiff(a, b, x, y);
    return sum / static_cast<double>(n);
  };
  std::string error;
  for (const double spacing : {24.0, 48.0}) {
    ForestLayerConfig c = w.config();
    c.spacing_m = spacing;
    c.fins = false;
    auto forest = ForestLayer::create(c, w.ground(), error);
    ASSERT_TRUE(forest) << error;
    const lod::Camera cam = downCamera(300.0);
    const render::Image none = w.frame(cam, nullptr);
    // Every tree as a 3D model, no layers; then the layers at full alpha, no trees.
    ASSERT_TRUE(forest->setFades({1999.0, 2000.0}, {1999.0, 2000.0, 6000.0, 8000.0}, error)) << error;
    forest->enableParts(true, false, false);
    const double trees = meanChange(w.frame(cam, forest.get()), none);
    ASSERT_TRUE(forest->setFades({1.0, 2.0}, {1.0, 2.0, 6000.0, 8000.0}, error)) << error;
    forest->enableParts(false, true, false);
    const double layers = meanChange(w.frame(cam, forest.get()), none);
    ASSERT_GT(trees, 0.2) << spacing;
    EXPECT_GT(layers / trees, 0.67) << "spacing " << spacing << " m: layers " << layers << ", trees " << trees;
    EXPECT_LT(layers / trees, 1.5) << "spacing " << spacing << " m: layers " << layers << ", trees " << trees;
  }
  EXPECT_EQ(w.renderer.errors(), "");
}

// setTextures may change the layer count (igbench forest sweeps it), not the height or the fin
// slice count the fin geometry was made with at init: those are refused, naming them.
TEST(ForestGL, SetTexturesKeepsTheFinGeometrysHeightAndSlices) {
  World w;
  ASSERT_NO_FATAL_FAILURE(w.setUp());
  const std::vector<lod::TreeMesh> models = proceduralTrees();
  render::ForestTextureDesc d;
  d.layers = 4;
  d.size_px = 32;
  d.treesPerTile = 4;
  d.supersample = 1;
  std::string error;
  render::ForestTextures t;
  ASSERT_TRUE(render::renderForestTextures(models, d, t, error)) << error;
  auto forest = ForestLayer::create(w.config(), w.ground(), error, &models, &t);
  ASSERT_TRUE(forest) << error;
  d.layers = 2;
  render::ForestTextures fewer;
  ASSERT_TRUE(render::renderForestTextures(models, d, fewer, error)) << error;
  EXPECT_TRUE(forest->pass().setTextures(fewer, error)) << error;
  EXPECT_EQ(forest->pass().layerCount(), 2);
  d.finSlices = 2;
  render::ForestTextures slices;
  ASSERT_TRUE(render::renderForestTextures(models, d, slices, error)) << error;
  EXPECT_FALSE(forest->pass().setTextures(slices, error));
  EXPECT_NE(error.find("2 fin slices"), std::string::npos) << error;
  d.finSlices = 4;
  std::vector<lod::TreeMesh> taller = models;
  for (lod::TreeMesh& m : taller) {
    for (lod::TreeVertex& v : m.vertices) v.position[2] *= 2.0f;
    lod::measureTree(m);
  }
  render::ForestTextures high;
  ASSERT_TRUE(render::renderForestTextures(taller, d, high, error)) << error;
  EXPECT_FALSE(forest->pass().setTextures(high, error));
  EXPECT_NE(error.find("height_m"), std::string::npos) << error;
  EXPECT_EQ(forest->pass().layerCount(), 2);  // the refused ones changed nothing
  EXPECT_EQ(w.renderer.errors(), "");
}

// Huge coordinates (ECEF-like, ~1e7 m east and north, where a float's step is 1 m): the same
// terrain, map and forest placed there and seen from the same eye relative to them draw the same
// picture as at the origin: 3D trees from above, layers from far above, trees, fins and layers
// from a low oblique eye, and trees close up.
TEST(ForestGL, SameForestTenThousandKilometresFromTheOrigin) {
  // A whole number of ground-detail periods (1024 m) and forest tiles (24 m), which are anchored
  // to the world; the eyes are not float values there: float world maths would move things.
  const glm::dvec3 far(3255.0 * 3072.0, -1628.0 * 3072.0, 0.0);
  lod::Camera down = downCamera(250.0), high = downCamera(2500.0), oblique = downCamera(120.0);
  down.eye_m += glm::dvec3(0.3125, -0.4375, 0.0);
  high.eye_m += glm::dvec3(0.3125, -0.4375, 0.0);
  oblique.eye_m = {700.3125, -300.4375, 120.0};
  oblique.pitch_deg = -8.0;
  lod::Camera low = oblique;  // among the trees: a float step (up to 0.5 m) would be pixels here
  low.eye_m = {600.3125, 500.4375, 75.0};
  low.heading_deg = 90.0;
  low.pitch_deg = -25.0;
  const lod::Camera cams[] = {down, high, oblique, low};
  std::vector<render::Image> images[2], without;  // without: far away, without the forest
  size_t treesDrawn[2] = {0, 0};
  for (int k = 0; k < 2; ++k) {
    World w;
    w.origin = k ? far : glm::dvec3(0.0);
    ASSERT_NO_FATAL_FAILURE(w.setUp());
    std::string error;
    auto forest = ForestLayer::create(w.config(), w.ground(), error);
    ASSERT_TRUE(forest) << error;
    for (lod::Camera cam : cams) {
      cam.eye_m += w.origin;
      images[k].push_back(w.frame(cam, forest.get()));
      treesDrawn[k] += forest->stats().treesDrawn;
      if (k == 1) without.push_back(w.frame(cam, nullptr));
    }
    EXPECT_EQ(w.renderer.errors(), "");
  }
  EXPECT_GT(treesDrawn[0], 500u);
  EXPECT_EQ(treesDrawn[0], treesDrawn[1]);
  for (size_t i = 0; i < std::size(cams); ++i) {
    // The forest shows there at all, and the same as at the origin.
    EXPECT_GT(render::fractionDifferent(images[1][i], without[i], 8), 0.03) << "camera " << i;
    EXPECT_LT(render::fractionDifferent(images[0][i], images[1][i], 2), 0.002) << "camera " << i;
  }
}

namespace {

// The shell layers and fins over a flat 64 m patch whose south-west corner is at `base`, drawn
// with the terrain mesh's origin and the map's origin either beside the patch or 170 km from it
// (at 0: a DEM tile's mesh origin is its SW post, a forest map's its SW corner); one image a view.
render::Image layersAndFins(const glm::dvec2& base, bool farOrigins) {
  constexpr int kPatchPosts = 33;
  constexpr double kPatchSpacing = 2.0;
  std::string error;
  auto ctx = render::createContext(render::ContextKind::Headless, kW, kH, error);
  EXPECT_TRUE(ctx) << error;
  if (!ctx) return {};
  render::Renderer renderer;
  EXPECT_TRUE(renderer.init(kW, kH, error)) << error;
  // Textures tiled every 32 m (a power of two: the tile coordinates are exact for either origin).
  const std::vector<lod::TreeMesh> models = proceduralTrees();
  render::ForestTextureDesc td;
  td.layers = 4;
  td.size_px = 64;
  td.tile_m = 32.0;
  render::ForestTextures t;
  EXPECT_TRUE(render::renderForestTextures(models, td, t, error)) << error;
  // A uniform map of 128 x 128 cells of 1024 m, its SW corner at 0 (far) or 1024 m SW of the patch.
  lod::ForestMap map;
  map.width = map.height = 128;
  map.cell_m = 1024.0;
  map.origin_m = farOrigins ? glm::dvec2(0.0) : base - glm::dvec2(1024.0);
  map.density.assign(128 * 128, 1.0f);
  map.gr.assign(128 * 128, 0xFF6A8C5Au);
  const glm::dvec3 terrainOrigin = farOrigins ? glm::dvec3(0.0) : glm::dvec3(base, 0.0);
  // Fins: 1 m pieces of an east-west line 1 m inside the north edge, one group.
  lod::FinSet fins;
  for (int i = 0; i < 24; ++i) {
    lod::Fin f;
    f.a_m = {base.x + 20.0 + i, base.y + 63.0, 0.0};
    f.b_m = f.a_m + glm::dvec3(1.0, 0.0, 0.0);
    f.phi_deg = 90.0f;
    fins.fins.push_back(f);
  }
  lod::FinGroup g;
  g.bounds = {glm::dvec3(base.x + 20.0, base.y + 63.0, 0.0), glm::dvec3(base.x + 44.0, base.y + 63.0, t.height_m)};
  g.centre_m = 0.5 * (g.bounds.min + g.bounds.max);
  g.radius_m = 0.5 * glm::length(g.bounds.max - g.bounds.min);
  g.count = 24;
  fins.groups.push_back(g);
  render::ForestPassDesc pd;
  pd.farFade = {0.5, 1.0, 6000.0, 8000.0};
  pd.nearFade = {0.6, 0.9};
  render::ForestPass pass;
  EXPECT_TRUE(pass.init(pd, map, t, models, &fins, error)) << error;
  // The flat patch: vertices relative to the terrain origin.
  const std::vector<float> heights(static_cast<size_t>(kPatchPosts) * kPatchPosts, 0.0f);
  const size_t vertexCount = static_cast<size_t>(kPatchPosts - 1) * (kPatchPosts - 1) * 6;
  EXPECT_TRUE(renderer.addTerrainMesh(vertexCount, 1.0, error)) << error;
  const glm::vec3 shift(glm::dvec3(base, 0.0) - terrainOrigin);
  auto dst = renderer.terrainMeshVertices();
  size_t n = 0;
  const auto v = [&](int x, int y) {
    lod::TerrainVertex tv = lod::heightFieldVertex(heights, kPatchPosts, kPatchPosts, kPatchSpacing, x, y);
    for (int k = 0; k < 3; ++k) tv.position[k] += shift[k];
    return tv;
  };
  for (int y = 0; y + 1 < kPatchPosts; ++y)
    for (int x = 0; x + 1 < kPatchPosts; ++x) {
      dst[n++] = v(x, y), dst[n++] = v(x + 1, y), dst[n++] = v(x + 1, y + 1);
      dst[n++] = v(x, y), dst[n++] = v(x + 1, y + 1), dst[n++] = v(x, y + 1);
    }
  // An eyepoint 0.45 of a float step (1/128 m at 120 km) off the float grid, 0.4 H above the
  // ground, looking down 45 degrees at the lowest layer's edge along the patch's north border 3 m
  // away (layers against the background) in an 8 degree field of view.
  lod::Camera cam;
  const double off = 0.45 / 128.0;
  cam.eye_m = {base.x + 32.0 + off, base.y + 64.0 - 0.15 * t.height_m + off, 0.4 * t.height_m + off};
  cam.pitch_deg = -45.0;
  cam.fovY_deg = 8.0;
  cam.aspect = static_cast<double>(kW) / kH;
  cam.near_m = 0.1;
  cam.far_m = 5000.0;
  renderer.beginFrame(cam, render::Lighting{});
  renderer.drawTerrainMesh(terrainOrigin, vertexCount);
  pass.drawLayers(renderer, terrainOrigin, vertexCount, 4);
  const uint32_t group = 0;
  pass.drawFins(renderer, std::span(&group, 1));
  const render::ForestDrawStats st = pass.takeStats();
  EXPECT_EQ(st.layers, 4u);
  EXPECT_EQ(st.fins, 24u);
  renderer.endFrame();
  renderer.finish();
  render::Image img;
  renderer.readPixels(img);
  EXPECT_EQ(renderer.errors(), "");
  return img;
}

}  // namespace

// The layers are drawn over the terrain mesh, whose vertices lie up to a DEM tile's size from
// their origin (its SW post): the origin - eye offset was sent as one float (7.8 mm steps at
// 120 km), so that the layers moved in those steps as the eye moved and came apart from the
// terrain, which is placed to a fraction of a millimetre (seen here with the layers faded in from
// 0.5 m). The same layers drawn from an origin beside them must give the same picture. (The fins,
// relative to the map's SW corner, are drawn the same way; their texture is too soft for a float
// step to show.)
TEST(ForestGL, LayersFarFromTheirOriginArePlacedAsNearIt) {
  const glm::dvec2 base(120000.0, 120000.0);
  const render::Image nearImage = layersAndFins(base, false), farImage = layersAndFins(base, true);
  ASSERT_EQ(nearImage.width, kW);
  ASSERT_EQ(farImage.width, kW);
  EXPECT_LT(render::rmse(nearImage, farImage), 0.1);
  EXPECT_LT(render::fractionDifferent(nearImage, farImage, 2), 0.0005);
  // Not vacuous: the view shows the layers and the background beyond them.
  render::Image flat = nearImage;
  for (size_t i = 4; i < flat.rgba.size(); ++i) flat.rgba[i] = flat.rgba[i % 4];
  EXPECT_GT(render::rmse(nearImage, flat), 3.0);
}
