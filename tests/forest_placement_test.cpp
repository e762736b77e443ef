// Forest data (lod/forest.h): distribution map, deterministic placement, distance fades.
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "lod/forest.h"
#include "lod/forest_model.h"

namespace {
using namespace ig::lod;

TerrainGrid smallTerrain(int posts = 41) {
  TerrainGridDesc d;
  d.heights.postsX = d.heights.postsY = posts;
  d.heights.postSpacing_m = 32.0;
  d.heights.heightScale_m = 300.0;
  d.chunkQuads = 20;
  return TerrainGrid(d);
}

ForestMap smallMap() {
  ForestMapDesc d;
  d.width = d.height = 40;
  d.cell_m = 32.0;
  d.featureSize_m = 300.0;
  return generateForestMap(d);
}

TEST(ForestPlacement, DeterministicInsideMapNeverInGlades) {
  const TerrainGrid terrain = smallTerrain();
  const ForestMap map = smallMap();
  std::string err;
  ASSERT_TRUE(validateForestMap(map, err)) << err;
  int glades = 0;
  for (uint32_t g : map.gr) glades += (g >> 24) == 0;
  EXPECT_GT(glades, 0) << "the procedural map should have glades";
  EXPECT_LT(glades, static_cast<int>(map.gr.size()) / 2);

  std::vector<TreeInstance> a, b, c;
  TreePlacementDesc pd;
  pd.spacing_m = 5.0;
  ASSERT_TRUE(placeTrees(map, terrain, pd, a, err)) << err;
  ASSERT_TRUE(placeTrees(map, terrain, pd, b, err)) << err;
  pd.seed = 8;
  ASSERT_TRUE(placeTrees(map, terrain, pd, c, err)) << err;
  ASSERT_GT(a.size(), 20000u);
  ASSERT_EQ(a.size(), b.size());
  size_t same = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].base_m, b[i].base_m);
    ASSERT_EQ(a[i].rgba, b[i].rgba);
    ASSERT_EQ(a[i].model, b[i].model);
    if (i < c.size() && a[i].base_m == c[i].base_m) ++same;
  }
  EXPECT_LT(same, a.size() / 100) << "another seed must place other trees";
  int models[2] = {0, 0};
  for (const TreeInstance& t : a) {
    ASSERT_FALSE(map.isGlade(t.base_m.x, t.base_m.y));
    ASSERT_GE(t.base_m.x, 0.0);
    ASSERT_LT(t.base_m.x, map.extentEast_m());
    ASSERT_NEAR(t.base_m.z, terrain.heightAt(t.base_m.x, t.base_m.y), 1e-9);
    ASSERT_GT(t.normal.z, 0.0f);
    ASSERT_NEAR(glm::length(t.normal), 1.0f, 1e-4f);
    ASSERT_LT(t.model, 2);
    ++models[t.model];
  }
  EXPECT_GT(models[0], static_cast<int>(a.size()) / 3);
  EXPECT_GT(models[1], static_cast<int>(a.size()) / 3);
}

TEST(ForestPlacement, DensityIsFollowed) {
  const TerrainGrid terrain = smallTerrain();
  ForestMap map = smallMap();
  for (size_t i = 0; i < map.gr.size(); ++i) {
    map.gr[i] |= 0xFF000000u;  // no glades
    map.density[i] = (i % static_cast<size_t>(map.width)) < 20 ? 0.2f : 0.9f;  // west sparse
  }
  std::vector<TreeInstance> t;
  std::string err;
  ASSERT_TRUE(placeTrees(map, terrain, {}, t, err)) << err;
  size_t west = 0, east = 0;
  for (const TreeInstance& x : t) (x.base_m.x < 640.0 ? west : east)++;
  const double slots = 640.0 * 1280.0 / 36.0;
  EXPECT_NEAR(static_cast<double>(west) / slots, 0.2, 0.02);
  EXPECT_NEAR(static_cast<double>(east) / slots, 0.9, 0.02);
}

TEST(ForestPlacement, BadInputNamesTheValue) {
  const TerrainGrid terrain = smallTerrain();
  ForestMap map = smallMap();
  std::vector<TreeInstance> t;
  std::string err;
  TreePlacementDesc pd;
  pd.spacing_m = 0.0;
  EXPECT_FALSE(placeTrees(map, terrain, pd, t, err));
  EXPECT_NE(err.find("spacing_m"), std::string::npos) << err;
  pd.spacing_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(placeTrees(map, terrain, pd, t, err));
  pd = {};
  pd.modelCount = 0;
  EXPECT_FALSE(placeTrees(map, terrain, pd, t, err));
  EXPECT_NE(err.find("modelCount = 0"), std::string::npos) << err;
  map.density[5] = 1.5f;
  EXPECT_FALSE(validateForestMap(map, err));
  EXPECT_NE(err.find("density[5]"), std::string::npos) << err;
  map.density[5] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(placeTrees(map, terrain, {}, t, err));
  EXPECT_TRUE(t.empty());
  map.density.pop_back();
  EXPECT_FALSE(validateForestMap(map, err));
  EXPECT_NE(err.find("expected 1600"), std::string::npos) << err;
  ForestMap empty;
  EXPECT_FALSE(validateForestMap(empty, err));
}

TEST(ForestFades, ContinuousAtEveryBandEdge) {
  const FarFade far{400.0, 600.0, 6000.0, 8000.0};
  const NearFade nearF{350.0, 650.0};
  std::string err;
  ASSERT_TRUE(validateForestFades(far, nearF, err)) << err;
  const double eps = 1e-7;
  for (double e : {far.fadeInStart_m, far.fadeInEnd_m, far.fadeOut_m, far.farPlane_m}) {
    EXPECT_NEAR(farAlpha(far, e - eps), farAlpha(far, e + eps), 1e-6) << "far edge " << e;
    EXPECT_NEAR(farAlpha(far, e), farAlpha(far, e + eps), 1e-6) << "far edge " << e;
  }
  for (double e : {nearF.fadeOutStart_m, nearF.fadeOutEnd_m}) {
    EXPECT_NEAR(nearAlpha(nearF, e - eps), nearAlpha(nearF, e + eps), 1e-6) << "near edge " << e;
    EXPECT_NEAR(nearAlpha(nearF, e), nearAlpha(nearF, e - eps), 1e-6) << "near edge " << e;
  }
  EXPECT_EQ(farAlpha(far, 0.0), 0.0);
  EXPECT_EQ(farAlpha(far, 500.0), 0.5);
  EXPECT_EQ(farAlpha(far, 3000.0), 1.0);
  EXPECT_EQ(farAlpha(far, 7000.0), 0.5);
  EXPECT_EQ(farAlpha(far, 1e9), 0.0);
  EXPECT_EQ(nearAlpha(nearF, 0.0), 1.0);
  EXPECT_EQ(nearAlpha(nearF, 500.0), 0.5);
  EXPECT_EQ(nearAlpha(nearF, 1e9), 0.0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(farAlpha(far, nan), 0.0);
  EXPECT_EQ(nearAlpha(nearF, nan), 0.0);
  // Sampled everywhere: no jump larger than the slope allows.
  double prevF = farAlpha(far, 0.0), prevN = nearAlpha(nearF, 0.0);
  for (double d = 0.5; d < 9000.0; d += 0.5) {
    ASSERT_LE(std::abs(farAlpha(far, d) - prevF), 0.5 / 200.0 + 1e-12) << d;
    ASSERT_LE(std::abs(nearAlpha(nearF, d) - prevN), 0.5 / 300.0 + 1e-12) << d;
    prevF = farAlpha(far, d);
    prevN = nearAlpha(nearF, d);
  }
  // Equal bands cross-fade: near + far = 1 through the band.
  const NearFade same{far.fadeInStart_m, far.fadeInEnd_m};
  for (double d = 300.0; d < 700.0; d += 7.0) EXPECT_NEAR(nearAlpha(same, d) + farAlpha(far, d), 1.0, 1e-12);
}

TEST(ForestFades, ValidationRejectsBadBands) {
  std::string err;
  EXPECT_FALSE(validateForestFades({400, 400, 6000, 8000}, {300, 500}, err));  // empty band: a step
  EXPECT_FALSE(validateForestFades({400, 600, 6000, 6000}, {300, 500}, err));
  EXPECT_FALSE(validateForestFades({400, 600, 6000, 8000}, {500, 500}, err));
  EXPECT_FALSE(validateForestFades({400, 600, 6000, 8000}, {700, 900}, err));  // no overlap
  EXPECT_NE(err.find("does not overlap"), std::string::npos) << err;
  EXPECT_FALSE(validateForestFades({400, 600, 6000, 8000}, {100, 300}, err));
  EXPECT_FALSE(validateForestFades({std::numeric_limits<double>::quiet_NaN(), 600, 6000, 8000}, {300, 500}, err));
  EXPECT_NE(err.find("FadeInStart"), std::string::npos) << err;
  EXPECT_TRUE(validateForestFades({400, 600, 600, 8000}, {300, 500}, err)) << err;
}

}  // namespace

namespace {

TEST(ForestHeightField, OnTheGridTrianglesAndPlacement) {
  // 3 x 3 posts at 10 m, a saddle so bilinear and triangle interpolation differ.
  const std::vector<float> h = {0, 10, 0, 10, 0, 10, 0, 10, 0};
  const ForestHeightField f{h, 3, 3, 10.0, glm::dvec3(100.0, 200.0, 5.0)};
  EXPECT_DOUBLE_EQ(f.heightAt(100.0, 200.0), 5.0);  // post (0, 0)
  EXPECT_DOUBLE_EQ(f.heightAt(110.0, 200.0), 15.0); // post (1, 0)
  EXPECT_DOUBLE_EQ(f.heightAt(120.0, 220.0), 5.0);  // post (2, 2)
  // Quad (0, 0): diagonal (0,0)-(1,1) with both ends 0 -> 0 on it (bilinear would give 5).
  EXPECT_DOUBLE_EQ(f.heightAt(105.0, 205.0), 5.0);
  // Below the diagonal: plane through (0,0,0) (10,0,10) (10,10,0): z = x - y.
  EXPECT_NEAR(f.heightAt(108.0, 202.0), 5.0 + 8.0 - 2.0, 1e-12);
  // Above: plane through (0,0,0) (10,10,0) (0,10,10): z = y - x.
  EXPECT_NEAR(f.heightAt(102.0, 208.0), 5.0 + 8.0 - 2.0, 1e-12);
  // Outside clamps; NaN gives the origin height.
  EXPECT_DOUBLE_EQ(f.heightAt(-1e9, 200.0), 5.0);
  EXPECT_DOUBLE_EQ(f.heightAt(std::nan(""), 200.0), 5.0);

  ForestMap map;
  map.width = map.height = 2;
  map.cell_m = 10.0;
  map.origin_m = {100.0, 200.0};
  map.density.assign(4, 1.0f);
  map.gr.assign(4, 0xFF406030u);
  TreePlacementDesc pd;
  pd.spacing_m = 2.0;
  std::vector<TreeInstance> trees;
  std::string error;
  ASSERT_TRUE(placeTrees(map, f, pd, trees, error)) << error;
  ASSERT_EQ(trees.size(), 100u);  // density 1: every slot
  for (const TreeInstance& t : trees) EXPECT_DOUBLE_EQ(t.base_m.z, f.heightAt(t.base_m.x, t.base_m.y));

  const ForestHeightField tiny{h, 1, 1, 10.0, glm::dvec3(0.0)};
  EXPECT_FALSE(placeTrees(map, tiny, pd, trees, error));
  EXPECT_NE(error.find("1 x 1"), std::string::npos) << error;
  EXPECT_TRUE(trees.empty());
  const ForestHeightField flat{h, 3, 3, 0.0, glm::dvec3(0.0)};
  EXPECT_FALSE(placeTrees(map, flat, pd, trees, error));
  EXPECT_NE(error.find("spacing_m = 0"), std::string::npos) << error;
}

TEST(ForestModel, ProceduralTreesAreValidAndSized) {
  for (ProceduralTree kind : {ProceduralTree::Pine, ProceduralTree::Cypress}) {
    TreeMesh m = makeProceduralTree(kind, 20.0, 6);
    std::string error;
    EXPECT_TRUE(validateTreeMesh(m, error)) << error;
    EXPECT_NEAR(m.height_m, 20.0f, 1e-4f);
    EXPECT_GT(m.radius_m, 1.0f);
    EXPECT_LT(m.radius_m, 5.0f);
    m.indices.push_back(static_cast<uint32_t>(m.vertices.size()));  // not a whole triangle
    EXPECT_FALSE(validateTreeMesh(m, error));
    m.indices.push_back(0);
    m.indices.push_back(0);
    EXPECT_FALSE(validateTreeMesh(m, error));
    EXPECT_NE(error.find(">= vertex count"), std::string::npos) << error;
    m.indices.resize(m.indices.size() - 3);
    m.vertices[0].position[2] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_FALSE(validateTreeMesh(m, error));
    EXPECT_NE(error.find("vertex 0"), std::string::npos) << error;
  }
  TreeMesh empty;
  std::string error;
  EXPECT_FALSE(validateTreeMesh(empty, error));
}

}  // namespace
