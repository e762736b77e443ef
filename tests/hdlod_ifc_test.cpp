// lod/hdlod_models (IFC through libassimp) on a real building: the FZK-Haus (KIT/IAI) from
// Debian's assimp-testmodels, fetched by scripts/fetch-ifc (ctest fixture ifc_models) into
// data/ifc/. Loaded directly and through a schedule that places four houses (one appearing
// half-way, one scaled): a sane house in metres with z up, a tree that selects the houses
// present at full detail near and coarser far away; bad IFC files refused naming the file.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <string>
#include <vector>

#include "lod/hdlod_build.h"
#include "lod/hdlod_scene.h"
#include "lod/hdlod_select.h"

using namespace ig::lod;
using namespace ig::lod::hdlod;

namespace {

const std::string kHaus = std::string(IG_SOURCE_DIR) + "/data/ifc/AC14-FZK-Haus.ifc";

std::string writeFile(const std::string& name, const std::string& bytes) {
  const std::string path = std::string(IG_BINARY_DIR) + "/hdlod_ifc_test_" + name;
  std::ofstream(path, std::ios::binary) << bytes;
  return path;
}

SelectView viewFrom(glm::dvec3 eye, double t, double r) {
  SelectView v;
  v.camera.eye_m = eye;  // looks north
  v.camera.fovY_deg = 60;
  v.camera.aspect = 16.0 / 9.0;
  v.camera.near_m = 0.1;
  v.camera.far_m = 1e5;
  v.time_s = t;
  v.tolerance_rad = r;
  return v;
}

}  // namespace

TEST(HdlodIfc, FzkHausLoadsAsAHouseInMetresZUp) {
  std::string error;
  const auto m = loadModelFile(kHaus, error);
  ASSERT_TRUE(m) << error << " (run scripts/fetch-ifc)";
  EXPECT_GT(m->triangleCount(), 1000u);
  for (uint32_t i : m->indices) ASSERT_LT(i, m->positions.size());
  const glm::dvec3 size = m->box.max - m->box.min;
  // A two-storey house: footprint ~10-20 m, under its gable roof ~7 m (z up: the file is
  // converted back from assimp's y up).
  EXPECT_GT(size.x, 5.0);
  EXPECT_LT(size.x, 25.0);
  EXPECT_GT(size.y, 5.0);
  EXPECT_LT(size.y, 25.0);
  EXPECT_GT(size.z, 4.0);
  EXPECT_LT(size.z, 12.0);
  EXPECT_LT(size.z, std::max(size.x, size.y));
}

TEST(HdlodIfc, ScheduleBuildsAndSelectsHouses) {
  const std::string text = "hdlod-schedule 1\n"
                           "duration_s 1000\n"
                           "model haus ifc " + kHaus + "\n"
                           "model big ifc " + kHaus + " scale 2\n"
                           "object h0 haus\nat h0 0 0 0 0 0\n"
                           "object h1 haus\nat h1 0 30 0 0 90\n"
                           "object h2 haus\nat h2 0 60 0 0 0\nvisible h2 500 1000\n"
                           "object h3 big\nat h3 0 100 0 0 0\n";
  std::string error;
  const auto s = parseSchedule(text, "street.sched", "", error);
  ASSERT_TRUE(s) << error;
  ASSERT_EQ(s->models.size(), 2u);
  const glm::dvec3 small = s->models[0].box.max - s->models[0].box.min;
  const glm::dvec3 big = s->models[1].box.max - s->models[1].box.min;
  EXPECT_NEAR(big.z, 2.0 * small.z, 1e-3 * big.z);
  const HdlodTree tree = buildHdlod(*s);
  ASSERT_NE(tree.root, ~0u);
  for (uint32_t c : tree.objectCluster) ASSERT_NE(c, ~0u);
  EXPECT_GT(tree.stats.mergedClusters, 0u);
  EXPECT_GT(tree.lodsOf(0).size(), 0u);  // simplified versions of the real model

  DrawList out(tree);
  auto drawn = [&](const SelectView& v, SelectStats& st) {
    const size_t n = selectHdlod(tree, *s, v, out, &st);
    std::vector<uint32_t> ids;
    for (size_t i = 0; i < n; ++i) ids.push_back(out.draws[i].cluster);
    return ids;
  };
  auto has = [](const std::vector<uint32_t>& ids, uint32_t c) { return std::find(ids.begin(), ids.end(), c) != ids.end(); };
  // r = 0 from 150 m south: exactly the present houses at full detail.
  SelectStats st;
  auto ids = drawn(viewFrom({50, -150, 5}, 100, 0.0), st);
  EXPECT_EQ(ids.size(), 3u);
  EXPECT_TRUE(has(ids, tree.objectCluster[0]));
  EXPECT_TRUE(has(ids, tree.objectCluster[1]));
  EXPECT_FALSE(has(ids, tree.objectCluster[2]));  // not yet present
  EXPECT_TRUE(has(ids, tree.objectCluster[3]));
  EXPECT_EQ(st.triangles, 3 * s->models[0].triangleCount());
  ids = drawn(viewFrom({50, -150, 5}, 700, 0.0), st);
  EXPECT_EQ(ids.size(), 4u);
  EXPECT_TRUE(has(ids, tree.objectCluster[2]));
  const uint64_t full = st.triangles;
  // One pixel of 1080 from 3 km: far fewer triangles, still something drawn.
  drawn(viewFrom({50, -3000, 5}, 700, toleranceFromPixels(1.0, 60, 1080)), st);
  EXPECT_GT(st.draws, 0u);
  EXPECT_GT(st.triangles, 0u);
  EXPECT_LT(st.triangles * 4, full);
}

TEST(HdlodIfc, BadIfcFilesAreRefusedNamingThem) {
  std::string error;
  const std::string garbage = writeFile("garbage.ifc", "this is not a building\n");
  EXPECT_FALSE(loadModelFile(garbage, error));
  EXPECT_NE(error.find(garbage), std::string::npos) << error;
  EXPECT_NE(error.find("not an IFC"), std::string::npos) << error;

  const std::string broken = writeFile("broken.ifc", "ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nENDSEC;\nDATA;\n#1=IFCWALL(;\n");
  EXPECT_FALSE(loadIfc(broken, error));
  EXPECT_NE(error.find(broken), std::string::npos) << error;

  const std::string missing = std::string(IG_BINARY_DIR) + "/hdlod_ifc_test_missing.ifc";
  EXPECT_FALSE(loadIfc(missing, error));
  EXPECT_NE(error.find(missing), std::string::npos) << error;

  // Through a schedule: file:line, the model and the IFC file.
  const auto s = parseSchedule("hdlod-schedule 1\nmodel h ifc " + broken + "\n", "bad.sched", "", error);
  EXPECT_FALSE(s);
  EXPECT_NE(error.find("bad.sched:2"), std::string::npos) << error;
  EXPECT_NE(error.find(broken), std::string::npos) << error;
  EXPECT_FALSE(parseSchedule("hdlod-schedule 1\nmodel h ifc " + kHaus + " scale -1\n", "bad.sched", "", error));
  EXPECT_NE(error.find("scale"), std::string::npos) << error;
  EXPECT_FALSE(parseSchedule("hdlod-schedule 1\nmodel h ifc " + kHaus + " scale 1e300\n", "bad.sched", "", error));
  EXPECT_NE(error.find("scale too large: 1e300"), std::string::npos) << error;
}
