// lod/hdlod_cache + the parts of hdlod_build the cache and renderer rely on: a saved tree loads
// back equal (same selection); a corrupt, truncated, foreign, old-version or stale cache is
// detected (reason named) and loadOrBuildHdlod() rebuilds and rewrites it; a schedule written
// by saveSchedule() loads back into the same scene (same cache key); model versions (coarser
// with rising eps) and per-triangle materials; the build's progress callback.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "lod/hdlod_build.h"
#include "lod/hdlod_cache.h"
#include "lod/hdlod_select.h"
#include "lod/hdlod_site.h"

using namespace ig::lod;
using namespace ig::lod::hdlod;

namespace {

std::string tempPath(const std::string& name) { return std::string(IG_BINARY_DIR) + "/hdlod_cache_test_" + name; }

Scene smallSite(uint32_t seed = 1) {
  SiteParams p;
  p.scale = 0.03;
  p.seed = seed;
  p.loadsPerFloor = 20;
  p.bays = 4;
  p.trucks = 10;
  std::string error;
  Scene s = makeConstructionSite(p, error);
  EXPECT_EQ(error, "");
  // Without the ground (64 tiles of 512 triangles): the tests stay quick under sanitizers.
  std::erase_if(s.objects, [&](const Object& o) { return s.models[o.model].name == "ground_tile"; });
  return s;
}

std::vector<uint8_t> readAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void writeAll(const std::string& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

SelectView viewOf(const HdlodTree& t, double time, double r) {
  SelectView v;
  const Aabb& b = t.clusters[t.root].box;
  v.camera.eye_m = (b.min + b.max) * 0.5 + glm::dvec3(-250, -250, 120);
  v.camera.heading_deg = 45;
  v.camera.pitch_deg = -15;
  v.camera.fovY_deg = 45;
  v.camera.aspect = 16.0 / 9.0;
  v.camera.near_m = 0.5;
  v.camera.far_m = 5000;
  v.time_s = time;
  v.tolerance_rad = r;
  return v;
}

std::vector<std::pair<uint32_t, uint32_t>> selection(const HdlodTree& t, const Scene& s, const SelectView& v) {
  DrawList d(t);
  selectHdlod(t, s, v, d);
  std::vector<std::pair<uint32_t, uint32_t>> out;
  for (const Draw& x : d.selected()) out.emplace_back(x.cluster, x.lod);
  return out;
}

void expectSameTree(const HdlodTree& a, const HdlodTree& b) {
  ASSERT_EQ(a.clusters.size(), b.clusters.size());
  EXPECT_EQ(a.root, b.root);
  EXPECT_EQ(a.children, b.children);
  EXPECT_EQ(a.stepTimes, b.stepTimes);
  EXPECT_EQ(a.stepValues, b.stepValues);
  EXPECT_EQ(a.objectCluster, b.objectCluster);
  EXPECT_EQ(a.modelLodBegin, b.modelLodBegin);
  ASSERT_EQ(a.meshes.size(), b.meshes.size());
  for (size_t i = 0; i < a.meshes.size(); ++i) {
    EXPECT_EQ(a.meshes[i].positions, b.meshes[i].positions);
    EXPECT_EQ(a.meshes[i].indices, b.meshes[i].indices);
    EXPECT_EQ(a.meshes[i].materials, b.meshes[i].materials);
  }
  for (size_t i = 0; i < a.clusters.size(); ++i) {
    EXPECT_EQ(a.clusters[i].eps_m, b.clusters[i].eps_m);
    EXPECT_EQ(a.clusters[i].triangles, b.clusters[i].triangles);
    EXPECT_EQ(a.clusters[i].kind, b.clusters[i].kind);
  }
  EXPECT_EQ(a.stats.mergedTriangles, b.stats.mergedTriangles);
}

}  // namespace

TEST(HdlodCache, SavedTreeLoadsBackEqual) {
  const Scene s = smallSite();
  const HdlodTree tree = buildHdlod(s);
  const uint64_t key = hdlodCacheKey(s, BuildConfig{});
  const std::string path = tempPath("roundtrip.bin");
  std::string error;
  ASSERT_TRUE(saveHdlodCache(path, tree, key, error)) << error;
  HdlodTree loaded;
  ASSERT_TRUE(loadHdlodCache(path, key, loaded, error)) << error;
  expectSameTree(tree, loaded);
  for (double t : {0.0, 0.4 * s.duration_s, s.duration_s}) {
    EXPECT_EQ(selection(tree, s, viewOf(tree, t, 0.002)), selection(loaded, s, viewOf(loaded, t, 0.002)));
  }
  std::remove(path.c_str());
}

TEST(HdlodCache, CorruptCacheIsDetectedAndRebuilt) {
  const Scene s = smallSite();
  const BuildConfig config;
  const std::string path = tempPath("corrupt.bin");
  std::remove(path.c_str());
  CacheOutcome outcome;
  std::string note;
  const HdlodTree built = loadOrBuildHdlod(s, config, path, outcome, note);
  EXPECT_EQ(outcome, CacheOutcome::Built);
  EXPECT_EQ(note, "");
  const std::vector<uint8_t> good = readAll(path);
  ASSERT_GT(good.size(), 1000u);
  const uint64_t key = hdlodCacheKey(s, config);
  std::string error;
  HdlodTree t;

  // One flipped bit in the payload.
  std::vector<uint8_t> bad = good;
  bad[good.size() / 2] ^= 0x10;
  writeAll(path, bad);
  EXPECT_FALSE(loadHdlodCache(path, key, t, error));
  EXPECT_NE(error.find("checksum mismatch"), std::string::npos) << error;
  EXPECT_NE(error.find(path), std::string::npos) << error;
  EXPECT_TRUE(t.clusters.empty());
  HdlodTree again = loadOrBuildHdlod(s, config, path, outcome, note);
  EXPECT_EQ(outcome, CacheOutcome::Rebuilt);
  EXPECT_NE(note.find("checksum mismatch"), std::string::npos) << note;
  expectSameTree(built, again);
  EXPECT_EQ(readAll(path), good);  // rewritten
  again = loadOrBuildHdlod(s, config, path, outcome, note);
  EXPECT_EQ(outcome, CacheOutcome::Loaded);

  // Truncated, header only, empty, foreign bytes, another format version.
  bad.assign(good.begin(), good.begin() + static_cast<long>(good.size() - 100));
  writeAll(path, bad);
  EXPECT_FALSE(loadHdlodCache(path, key, t, error));
  EXPECT_NE(error.find("truncated"), std::string::npos) << error;
  bad.assign(good.begin(), good.begin() + 64);
  writeAll(path, bad);
  EXPECT_FALSE(loadHdlodCache(path, key, t, error));
  writeAll(path, {});
  EXPECT_FALSE(loadHdlodCache(path, key, t, error));
  EXPECT_NE(error.find("not an HDLOD cache"), std::string::npos) << error;
  bad.assign(5000, 0x41);
  writeAll(path, bad);
  EXPECT_FALSE(loadHdlodCache(path, key, t, error));
  EXPECT_NE(error.find("bad magic"), std::string::npos) << error;
  bad = good;
  bad[8] = static_cast<uint8_t>(kHdlodCacheVersion + 1);
  writeAll(path, bad);
  EXPECT_FALSE(loadHdlodCache(path, key, t, error));
  EXPECT_NE(error.find("version"), std::string::npos) << error;
  // A valid file (checksum right) with contents that do not hold together is refused by the
  // reference checks, not traversed: a child index out of range.
  HdlodTree broken = built;
  broken.children[0] = 1u << 30;
  ASSERT_TRUE(saveHdlodCache(path, broken, key, error)) << error;
  EXPECT_FALSE(loadHdlodCache(path, key, t, error));
  EXPECT_NE(error.find("inconsistent"), std::string::npos) << error;
  again = loadOrBuildHdlod(s, config, path, outcome, note);
  EXPECT_EQ(outcome, CacheOutcome::Rebuilt);
  EXPECT_TRUE(loadHdlodCache(path, key, t, error)) << error;

  std::remove((path + ".missing").c_str());
  EXPECT_FALSE(loadHdlodCache(path + ".missing", key, t, error));
  EXPECT_NE(error.find("missing"), std::string::npos) << error;
  std::remove(path.c_str());
}

TEST(HdlodCache, StaleCacheIsDetectedAndRebuilt) {
  const Scene s = smallSite();
  const std::string path = tempPath("stale.bin");
  std::remove(path.c_str());
  CacheOutcome outcome;
  std::string note;
  BuildConfig config;
  (void)loadOrBuildHdlod(s, config, path, outcome, note);
  EXPECT_EQ(outcome, CacheOutcome::Built);
  // Another build config.
  BuildConfig other = config;
  other.epsPerSize = config.epsPerSize * 0.5;
  EXPECT_NE(hdlodCacheKey(s, other), hdlodCacheKey(s, config));
  const HdlodTree rebuilt = loadOrBuildHdlod(s, other, path, outcome, note);
  EXPECT_EQ(outcome, CacheOutcome::Rebuilt);
  EXPECT_NE(note.find("stale"), std::string::npos) << note;
  EXPECT_GT(rebuilt.stats.mergedClusters, 0u);
  // Another scene: one object moved by a millimetre.
  Scene moved = s;
  moved.objects[7].path[0].position_m.x += 0.001;
  EXPECT_NE(hdlodCacheKey(moved, other), hdlodCacheKey(s, other));
  (void)loadOrBuildHdlod(moved, other, path, outcome, note);
  EXPECT_EQ(outcome, CacheOutcome::Rebuilt);
  EXPECT_NE(note.find("stale"), std::string::npos) << note;
  (void)loadOrBuildHdlod(moved, other, path, outcome, note);
  EXPECT_EQ(outcome, CacheOutcome::Loaded);
  // The progress callback is not part of the key.
  other.progress = [](double, const char*) {};
  EXPECT_EQ(hdlodCacheKey(moved, other), hdlodCacheKey(moved, BuildConfig(other)));
  std::remove(path.c_str());
}

TEST(HdlodCache, UnwritableCacheStillBuilds) {
  const Scene s = smallSite();
  // Below a regular file: no folder can be made there, not even by root.
  const std::string file = tempPath("not_a_folder");
  { std::ofstream(file) << "x"; }
  const std::string path = file + "/x/cache.bin";
  CacheOutcome outcome;
  std::string note;
  const HdlodTree t = loadOrBuildHdlod(s, BuildConfig{}, path, outcome, note);
  EXPECT_EQ(outcome, CacheOutcome::Built);
  EXPECT_NE(note.find(path), std::string::npos) << note;
  EXPECT_FALSE(t.clusters.empty());
  std::remove(file.c_str());
}

// The cache's folder is made when missing (a scene naming "../../out/x.hdlod" on a fresh
// checkout): the next start loads the tree instead of building it again.
TEST(HdlodCache, CacheInAFolderNotMadeYetIsWrittenAndLoaded) {
  const Scene s = smallSite();
  const std::string dir = tempPath("fresh_checkout");
  std::filesystem::remove_all(dir);
  const std::string path = dir + "/out/deeper/site.hdlod";
  CacheOutcome outcome;
  std::string note;
  (void)loadOrBuildHdlod(s, BuildConfig{}, path, outcome, note);
  EXPECT_EQ(outcome, CacheOutcome::Built) << note;
  EXPECT_TRUE(std::filesystem::exists(path)) << note;
  (void)loadOrBuildHdlod(s, BuildConfig{}, path, outcome, note);
  EXPECT_EQ(outcome, CacheOutcome::Loaded) << note;
  std::filesystem::remove_all(dir);
}

TEST(HdlodCache, ScheduleWrittenLoadsBackAsTheSameScene) {
  const Scene s = smallSite(3);
  const std::string dir = tempPath("schedule");
  std::filesystem::create_directories(dir + "/models");
  std::string error;
  ASSERT_TRUE(saveSchedule(s, dir + "/site.sched", "models", error)) << error;
  const auto loaded = loadSchedule(dir + "/site.sched", error);
  ASSERT_TRUE(loaded) << error;
  ASSERT_EQ(loaded->objects.size(), s.objects.size());
  EXPECT_EQ(hdlodCacheKey(*loaded, BuildConfig{}), hdlodCacheKey(s, BuildConfig{}));
  // Names with blanks are refused, naming them.
  Scene bad = s;
  bad.objects[0].name = "a b";
  EXPECT_FALSE(saveSchedule(bad, dir + "/bad.sched", "models", error));
  EXPECT_NE(error.find("'a b'"), std::string::npos) << error;
  std::filesystem::remove_all(dir);
}

TEST(HdlodBuild, ModelVersionsGetCoarserAndEveryTriangleHasAMaterial) {
  const Scene s = smallSite();
  std::vector<std::pair<double, const char*>> progress;
  BuildConfig config;
  config.progress = [&](double f, const char* stage) { progress.emplace_back(f, stage); };
  const HdlodTree t = buildHdlod(s, config);
  ASSERT_EQ(t.modelLodBegin.size(), s.models.size() + 1);
  EXPECT_GT(t.stats.modelLods, 0u);
  for (size_t m = 0; m < s.models.size(); ++m) {
    size_t previous = s.models[m].triangleCount();
    double eps = 0.0;
    for (const ModelLod& l : t.lodsOf(static_cast<uint32_t>(m))) {
      EXPECT_LT(l.triangles, previous) << s.models[m].name;
      EXPECT_GE(l.eps_m, eps) << s.models[m].name;
      EXPECT_EQ(t.meshes[l.mesh].indices.size(), 3u * l.triangles);
      previous = l.triangles;
      eps = l.eps_m;
    }
  }
  for (const ClusterMesh& mesh : t.meshes) {
    ASSERT_EQ(mesh.materials.size(), mesh.indices.size() / 3);
    for (uint16_t mat : mesh.materials) EXPECT_LT(mat, s.models.size());
  }
  // The crane mast (a lattice, 812 triangles) has versions down to its box.
  uint32_t mast = 0;
  while (s.models[mast].name != "crane_mast") ++mast;
  ASSERT_FALSE(t.lodsOf(mast).empty());
  EXPECT_EQ(t.lodsOf(mast).back().triangles, 12u);
  // Progress: rising, ends at 1 with "done".
  ASSERT_FALSE(progress.empty());
  for (size_t i = 1; i < progress.size(); ++i) EXPECT_GE(progress[i].first, progress[i - 1].first);
  EXPECT_EQ(progress.back().first, 1.0);
  EXPECT_STREQ(progress.back().second, "done");
}

TEST(HdlodSelect, LeavesUseACoarserVersionOnlyWithinTolerance) {
  const Scene s = smallSite();
  const HdlodTree t = buildHdlod(s);
  DrawList d(t);
  for (double r : {0.0, 0.0005, 0.002, 0.01}) {
    const SelectView v = viewOf(t, 0.5 * s.duration_s, r);
    const size_t n = selectHdlod(t, s, v, d);
    for (size_t i = 0; i < n; ++i) {
      const Cluster& c = t.clusters[d.draws[i].cluster];
      if (c.kind == ClusterKind::Merged) {
        EXPECT_EQ(d.draws[i].lod, 0u);
        continue;
      }
      const auto lods = t.lodsOf(c.mesh);
      ASSERT_LE(d.draws[i].lod, lods.size());
      if (d.draws[i].lod == 0) continue;
      EXPECT_GT(r, 0.0);
      const Aabb box = transformBox(s.models[c.mesh].box, *d.draws[i].model);
      EXPECT_LT(lods[d.draws[i].lod - 1].eps_m, r * distanceToBox(box, v.camera.eye_m) * (1.0 + 1e-9));
    }
  }
}

// A corrupt cache whose path happens to contain the word "missing" is still reported as a cache
// that existed and was rebuilt (the reason in the note), not as a first build.
TEST(HdlodCache, CorruptCacheUnderAFolderNamedMissingIsReportedAsRebuilt) {
  const Scene s = smallSite();
  const BuildConfig config;
  const std::string dir = tempPath("missing_parts");
  std::filesystem::create_directories(dir);
  const std::string path = dir + "/site.cache";
  writeAll(path, std::vector<uint8_t>(5000, 0x41));
  CacheOutcome outcome;
  std::string note;
  (void)loadOrBuildHdlod(s, config, path, outcome, note);
  EXPECT_EQ(outcome, CacheOutcome::Rebuilt);
  EXPECT_NE(note.find("bad magic"), std::string::npos) << note;
  std::filesystem::remove_all(dir);
}

// saveSchedule() either writes a file loadSchedule() reads back into the same scene or fails:
// a long object name (its `at` line was cut at 256 bytes, the next line glued to it) loads back;
// duplicate names (which loadSchedule() refuses) are refused when writing.
TEST(HdlodCache, ScheduleWithLongOrDuplicateNames) {
  Scene s;
  s.duration_s = 86400.0 * 365.0;
  s.models.push_back(makeBoxModel("box", {1, 2, 3}));
  Object o;
  o.name = std::string(200, 'n');
  o.model = 0;
  o.path.push_back({0.1234567890123, {1234567.123456789, -7654321.987654321, 123.456789012345}, 123.456789012345});
  o.path.push_back({1e5 + 0.123456789, {1234568.123456789, -7654322.987654321, 124.456789012345}, -98.7654321098765});
  o.visible.push_back({1000.123456789, 2e6 + 0.987654321});
  s.objects.push_back(o);
  ASSERT_EQ(validateScene(s), "");
  const std::string dir = tempPath("longnames");
  std::filesystem::create_directories(dir + "/models");
  std::string error;
  ASSERT_TRUE(saveSchedule(s, dir + "/a.sched", "models", error)) << error;
  const auto loaded = loadSchedule(dir + "/a.sched", error);
  ASSERT_TRUE(loaded) << error;
  EXPECT_EQ(hdlodCacheKey(*loaded, BuildConfig{}), hdlodCacheKey(s, BuildConfig{}));
  Scene twice = s;
  twice.objects.push_back(o);
  twice.objects.back().name = "x";
  twice.objects[0].name = "x";
  EXPECT_FALSE(saveSchedule(twice, dir + "/b.sched", "models", error));
  EXPECT_NE(error.find("'x'"), std::string::npos) << error;
  Scene models = s;
  models.models.push_back(makeBoxModel("box", {2, 2, 2}));
  EXPECT_FALSE(saveSchedule(models, dir + "/c.sched", "models", error));
  EXPECT_NE(error.find("'box'"), std::string::npos) << error;
  // Interval ends beyond the schedule may be infinite (validateScene allows them: present since
  // always / for ever); saveSchedule wrote them as "inf", which loadSchedule refused.
  Scene open = s;
  open.objects[0].visible = {{-std::numeric_limits<double>::infinity(), 10.0},
                             {20.0, std::numeric_limits<double>::infinity()}};
  ASSERT_EQ(validateScene(open), "");
  ASSERT_TRUE(saveSchedule(open, dir + "/d.sched", "models", error)) << error;
  const auto openLoaded = loadSchedule(dir + "/d.sched", error);
  ASSERT_TRUE(openLoaded) << error;
  ASSERT_EQ(openLoaded->objects.size(), 1u);
  EXPECT_EQ(openLoaded->objects[0].visible.size(), 2u);
  EXPECT_EQ(hdlodCacheKey(*openLoaded, BuildConfig{}), hdlodCacheKey(open, BuildConfig{}));
  for (double t : {0.0, 9.9, 10.0, 15.0, 20.0, open.duration_s})
    EXPECT_EQ(isPresent(openLoaded->objects[0], t, open.duration_s), isPresent(open.objects[0], t, open.duration_s)) << t;
  std::filesystem::remove_all(dir);
}

// A cache with the right key and checksum whose references into the scene are out of range (a
// forged or damaged file: the key only hashes the scene) is refused, naming the file and the bad
// index, and rebuilt: the loader checked the tree against itself but not against the scene, and
// selectHdlod() / the HDLOD pass then indexed scene.objects / the model ranges with it.
TEST(HdlodCache, CacheNamingObjectsOrModelsOutsideTheSceneIsRefusedAndRebuilt) {
  const Scene s = smallSite();
  const BuildConfig config;
  const std::string path = tempPath("outside.bin");
  std::remove(path.c_str());
  CacheOutcome outcome;
  std::string note, error;
  const HdlodTree built = loadOrBuildHdlod(s, config, path, outcome, note);
  ASSERT_EQ(outcome, CacheOutcome::Built);
  const uint64_t key = hdlodCacheKey(s, config);
  uint32_t dynamicLeaf = ~0u, objectLeaf = ~0u, mergedMesh = ~0u;
  for (uint32_t i = 0; i < built.clusters.size(); ++i) {
    const Cluster& c = built.clusters[i];
    if (c.kind == ClusterKind::Dynamic && dynamicLeaf == ~0u) dynamicLeaf = i;
    if (c.kind == ClusterKind::Object && objectLeaf == ~0u) objectLeaf = i;
    if (c.kind == ClusterKind::Merged && mergedMesh == ~0u && !built.meshes[c.mesh].materials.empty()) mergedMesh = c.mesh;
  }
  ASSERT_NE(dynamicLeaf, ~0u);
  ASSERT_NE(objectLeaf, ~0u);
  ASSERT_NE(mergedMesh, ~0u);
  const auto objects = static_cast<uint32_t>(s.objects.size());
  const auto models = static_cast<uint32_t>(s.models.size());
  struct Forgery {
    const char* what;
    std::function<void(HdlodTree&)> apply;
    std::string index;  // the bad value the error must name
  };
  const std::vector<Forgery> forgeries = {
      {"dynamic leaf's object = the object count", [&](HdlodTree& t) { t.clusters[dynamicLeaf].object = objects; },
       std::to_string(objects)},
      {"static leaf's object = -1", [&](HdlodTree& t) { t.clusters[objectLeaf].object = static_cast<uint32_t>(-1); },
       std::to_string(~0u)},
      {"leaf's model = the model count", [&](HdlodTree& t) { t.clusters[objectLeaf].mesh = models + 5; },
       std::to_string(models + 5)},
      {"a material past the models", [&](HdlodTree& t) { t.meshes[mergedMesh].materials[0] = static_cast<uint16_t>(models); },
       std::to_string(models)},
      {"an object leaf entry more than the scene's objects", [&](HdlodTree& t) { t.objectCluster.push_back(~0u); },
       std::to_string(objects + 1)},
  };
  for (const Forgery& f : forgeries) {
    HdlodTree forged = built;
    f.apply(forged);
    ASSERT_TRUE(saveHdlodCache(path, forged, key, error)) << error;
    const HdlodTree t = loadOrBuildHdlod(s, config, path, outcome, note);
    EXPECT_EQ(outcome, CacheOutcome::Rebuilt) << f.what;
    EXPECT_NE(note.find(path + ": HDLOD cache does not fit the scene"), std::string::npos) << f.what << ": " << note;
    EXPECT_NE(note.find(f.index), std::string::npos) << f.what << ": " << note;
    expectSameTree(built, t);
  }
  // The rewritten file is the scene's own again.
  (void)loadOrBuildHdlod(s, config, path, outcome, note);
  EXPECT_EQ(outcome, CacheOutcome::Loaded) << note;
  std::remove(path.c_str());
}
