// ig/scene_surfaces.h with the real indices behind the layers' surfaces: a tree (lod/forest_rays)
// in front of a tower (lod/hdlod_rays). Line of sight stops at whichever comes first, with its
// material and the distance along the whole segment; height queries see the tower and never
// the tree; the CIGI answers (io/cigi_link.h) carry material code 2 for the tree.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include <glm/geometric.hpp>

#include "ig/scene_surfaces.h"
#include "io/cigi_link.h"
#include "lod/forest_kdtree.h"
#include "lod/forest_model.h"
#include "lod/forest_rays.h"
#include "lod/hdlod_rays.h"
#include "lod/hdlod_scene.h"

using namespace ig;
namespace hd = ig::lod::hdlod;

namespace {

// A 20 m pine at (0, 0, 0) and a 10 x 10 x 40 m tower centred at (30, 0, 0), on flat ground z = 0.
struct Scene {
  hd::Scene scene;
  hd::SceneRays objectRays;
  std::vector<lod::TreeMesh> models{lod::makeProceduralTree(lod::ProceduralTree::Pine, 20.0)};
  lod::ForestKdTree kd;
  lod::ForestRays treeRays;

  struct Objects final : io::SceneSurfaces {
    const hd::SceneRays* rays = nullptr;
    bool intersect(const glm::dvec3& a, const glm::dvec3& b, io::SurfaceMask m, io::SurfaceHit& hit, uint32_t* work) const override {
      if (!(m & io::surfaceBit(io::kSurfaceObject))) return false;
      hd::RayHit h;
      hd::RayWork w;
      const bool found = rays->intersect(a, b, 0.0, h, &w);
      if (work) *work += w.nodes + w.triangles;
      if (found) hit = {h.t, h.point_m, h.normal, io::kSurfaceObject};
      return found;
    }
    double top_m() const override { return rays->top_m(); }
  } objects;
  struct Trees final : io::SceneSurfaces {
    const lod::ForestRays* rays = nullptr;
    bool intersect(const glm::dvec3& a, const glm::dvec3& b, io::SurfaceMask m, io::SurfaceHit& hit, uint32_t* work) const override {
      if (!(m & io::surfaceBit(io::kSurfaceTree))) return false;
      lod::TreeHit h;
      lod::RayWork w;
      const bool found = rays->intersect(a, b, h, &w);
      if (work) *work += w.nodes + w.triangles;
      if (found) hit = {h.t, h.point_m, h.normal, io::kSurfaceTree};
      return found;
    }
    double top_m() const override { return rays->top_m(); }
  } trees;
  SurfaceSet both;

  Scene() {
    scene.duration_s = 1.0;
    scene.models = {hd::makeBoxModel("tower", {10.0, 10.0, 40.0})};
    hd::Object tower;
    tower.name = "tower";
    tower.visible = {{0.0, 1.0}};
    tower.path = {{0.0, {30.0, 0.0, 0.0}, 0.0}};
    scene.objects = {tower};
    objectRays = hd::SceneRays(scene);
    lod::ForestKdParams p;
    p.modelCount = 1;
    p.treeHeight_m = 1.1 * static_cast<double>(models[0].height_m);
    p.crownRadius_m = 1.1 * static_cast<double>(models[0].radius_m);
    std::string err;
    lod::TreeInstance t;
    EXPECT_TRUE(kd.build(std::vector<lod::TreeInstance>{t}, p, err)) << err;
    treeRays = lod::ForestRays(kd, models, 0.0f);
    objects.rays = &objectRays;
    trees.rays = &treeRays;
    both.add(&trees);
    both.add(&objects);
  }
  Scene(const Scene&) = delete;
};

}  // namespace

TEST(SurfaceSet, TheNearerOfTreeAndTowerWithItsMaterial) {
  const Scene s;
  io::SurfaceHit hit;
  uint32_t work = 0;
  // Level at 5 m from the west: the pine's crown or trunk first, well before the tower.
  ASSERT_TRUE(s.both.intersect({-50.0, 0.0, 5.0}, {50.0, 0.0, 5.0}, io::kSightSurfaces, hit, &work));
  EXPECT_EQ(hit.material, io::kSurfaceTree);
  EXPECT_LT(hit.point_m.x, 0.0);
  EXPECT_GT(hit.point_m.x, -10.0);
  EXPECT_NEAR(hit.t, (hit.point_m.x + 50.0) / 100.0, 1e-12);
  EXPECT_GT(work, 0u);
  // From between them, eastwards: the tower's west wall at x = 25, t along the whole segment.
  ASSERT_TRUE(s.both.intersect({10.0, 0.0, 5.0}, {50.0, 0.0, 5.0}, io::kSightSurfaces, hit, nullptr));
  EXPECT_EQ(hit.material, io::kSurfaceObject);
  EXPECT_NEAR(hit.point_m.x, 25.0, 1e-9);
  EXPECT_NEAR(hit.t, 15.0 / 40.0, 1e-12);
  // The same from the east: the tower (its east wall) is first; the tree behind it is not seen.
  ASSERT_TRUE(s.both.intersect({50.0, 0.0, 5.0}, {-50.0, 0.0, 5.0}, io::kSightSurfaces, hit, nullptr));
  EXPECT_EQ(hit.material, io::kSurfaceObject);
  EXPECT_NEAR(hit.point_m.x, 35.0, 1e-9);
  EXPECT_NEAR(hit.t, 15.0 / 100.0, 1e-12);
  // A mask without trees (a host's LOS material mask) sees through the pine to the tower.
  ASSERT_TRUE(s.both.intersect({-50.0, 0.0, 5.0}, {50.0, 0.0, 5.0}, io::surfaceBit(io::kSurfaceObject), hit, nullptr));
  EXPECT_EQ(hit.material, io::kSurfaceObject);
  EXPECT_NEAR(hit.point_m.x, 25.0, 1e-9);
  // Height queries: down through the pine finds nothing (trees are not ground); the tower's roof.
  EXPECT_FALSE(s.both.intersect({0.3, 0.2, 100.0}, {0.3, 0.2, 0.0}, io::kHeightSurfaces, hit, nullptr));
  EXPECT_TRUE(s.both.intersect({0.3, 0.2, 100.0}, {0.3, 0.2, 0.0}, io::kSightSurfaces, hit, nullptr));
  ASSERT_TRUE(s.both.intersect({31.0, 0.0, 100.0}, {31.0, 0.0, 0.0}, io::kHeightSurfaces, hit, nullptr));
  EXPECT_NEAR(hit.point_m.z, 40.0, 1e-9);
  EXPECT_NEAR(s.both.top_m(), std::max(s.objectRays.top_m(), s.treeRays.top_m()), 0.0);
  EXPECT_TRUE(SurfaceSet().empty());
  EXPECT_FALSE(SurfaceSet().intersect({0.0, 0.0, 5.0}, {1.0, 0.0, 5.0}, io::kSightSurfaces, hit, nullptr));
}

TEST(SurfaceSet, CigiAnswersCarryTheTreesMaterialCode) {
  const Scene s;
  // A flat terrain at z = 0 around the ENU origin: 3 x 3 posts 100 m apart.
  const std::vector<float> heights(9, 0.0f);
  const lod::HeightGrid grid{heights, 3, 3, 100.0, {-100.0, -100.0, 0.0}};
  const lod::Geodetic origin{46.5, 7.9, 0.0};
  const lod::EnuFrame enu(origin);
  io::cigi::LosRequest r;
  r.extended = true;
  const lod::Geodetic a = enu.toGeodetic({-50.0, 0.0, 5.0}), b = enu.toGeodetic({50.0, 0.0, 5.0});
  r.srcLat_deg = a.lat_deg, r.srcLon_deg = a.lon_deg, r.srcAlt_m = a.height_m;
  r.dstLat_deg = b.lat_deg, r.dstLon_deg = b.lon_deg, r.dstAlt_m = b.height_m;
  const io::LosAnswer los = io::computeLos(r, enu, io::QueryScene(&grid, &s.both), nullptr);
  ASSERT_TRUE(los.valid);
  EXPECT_FALSE(los.visible);
  EXPECT_EQ(los.materialCode, io::kMaterialTree);
  EXPECT_GT(los.range_m, 40.0);
  EXPECT_LT(los.range_m, 50.0);
  // HOT over the pine: the ground.
  io::cigi::HatHotRequest h;
  h.requestType = io::cigi::HatHotRequest::kExtended;
  const lod::Geodetic p = enu.toGeodetic({0.3, 0.2, 0.0});
  h.lat_deg = p.lat_deg, h.lon_deg = p.lon_deg, h.alt_m = 300.0;
  const io::HatHotAnswer hot = io::computeHatHot(h, enu, origin.height_m, io::QueryScene(&grid, &s.both), nullptr);
  ASSERT_TRUE(hot.valid);
  EXPECT_NEAR(hot.hot_m, 0.0, 0.01);
  EXPECT_EQ(hot.materialCode, io::kMaterialTerrain);
}
