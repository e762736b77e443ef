// The service as a whole on a headless context: only the layers a scene names are built,
// bad host input is rejected without losing the last good eyepoint, the frame loop runs
// with a fake clock, and GL stays error-free.
#include <gtest/gtest.h>

#include <EGL/egl.h>
#include <GL/glcorearb.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <string>
#include <vector>
#include <thread>

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "gl_fixture.h"
#include "gl_objects.h"
#include "headless_gl.h"
#include "ig/clock.h"

using namespace ig;

TEST(ServiceGL, SceneWithoutTerrainBuildsNoPassAndNoBuffer) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain.reset();
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  EXPECT_TRUE(service->info().layers.empty());
  EXPECT_EQ(service->info().passes, 0u);
  EXPECT_EQ(service->info().gpuBufferBytes, 0u);
  EXPECT_EQ(service->info().threads, 1u);
  render::Image image;
  const FrameRecord r = service->renderOnce(test::defaultHostAt(5.0), &image);
  EXPECT_EQ(r.triangles, 0u);
  EXPECT_EQ(r.drawCalls, 0u);
  EXPECT_EQ(r.passes, 0u);
  // Only sky: every pixel has the background colour.
  for (size_t i = 4; i < image.rgba.size(); i += 4) ASSERT_EQ(image.rgba[i], image.rgba[0]);
}

// The same, asked of GL: a scene without layers compiles no program and creates no buffer, vertex
// array or texture (only the frame's FBO and its renderbuffers), before and after a frame.
TEST(ServiceGL, SceneWithoutLayersCreatesNoProgramBufferVertexArrayOrTexture) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain.reset();
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) service->renderOnce(test::defaultHostAt(5.0), nullptr);
    for (const char* isObject : {"glIsProgram", "glIsShader", "glIsBuffer", "glIsVertexArray", "glIsTexture"})
      EXPECT_EQ(test::liveGlObjects(isObject, 1024), 0) << isObject << (pass == 1 ? " after a frame" : " after create");
  }
}

TEST(ServiceGL, SceneWithTerrainBuildsExactlyOnePass) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  ASSERT_EQ(service->info().layers.size(), 1u);
  EXPECT_EQ(service->info().layers[0], "terrain");
  EXPECT_EQ(service->info().passes, 1u);
  EXPECT_GT(service->info().gpuBufferBytes, 1'000'000u);
  EXPECT_EQ(service->info().terrainTriangles, 2u * 256u * 256u);
}

TEST(ServiceGL, ForestNeedsAMeshTerrainAndBadForestInputIsNamed) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.forest = ForestLayerConfig{};  // the default scene's terrain is lod = "grid"
  std::string error;
  EXPECT_FALSE(Service::create(cfg, scene, error));
  EXPECT_NE(error.find("[forest] needs [terrain] with lod = \"roam\""), std::string::npos) << error;
  scene.terrain->lod = TerrainLayerConfig::Lod::Roam;
  scene.forest->map = "/nonexistent/forest_map.png";
  EXPECT_FALSE(Service::create(cfg, scene, error));
  EXPECT_NE(error.find("/nonexistent/forest_map.png"), std::string::npos) << error;
}

TEST(ServiceGL, MissingHdlodScheduleIsNamed) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.hdlod.emplace();
  scene.hdlod->schedule = "/nonexistent/site.sched";
  std::string error;
  EXPECT_FALSE(Service::create(cfg, scene, error));
  EXPECT_NE(error.find("/nonexistent/site.sched"), std::string::npos) << error;
}

TEST(ServiceGL, MissingReplayFileIsNamed) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  cfg.host = HostSource::Replay;
  cfg.replayFile = "/nonexistent/path.rec";
  std::string error;
  EXPECT_FALSE(Service::create(cfg, scene, error));
  EXPECT_NE(error.find("/nonexistent/path.rec"), std::string::npos) << error;
}

TEST(ServiceGL, NaNHostInputIsRejectedAndTheLastGoodEyepointKept) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  cfg.frames = 1;
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  FakeClock clock;
  std::atomic<bool> stop{false};

  io::HostState good = test::defaultHostAt(2.0);
  service->mailbox().publish(good);
  ASSERT_EQ(service->run(clock, stop), 0);
  EXPECT_EQ(service->currentHost().eyeEnu_m, good.eyeEnu_m);

  io::HostState bad = good;
  bad.eyeEnu_m.x = std::numeric_limits<double>::quiet_NaN();
  bad.hostFrame = 999;
  service->mailbox().publish(bad);
  ASSERT_EQ(service->run(clock, stop), 0);
  EXPECT_EQ(service->hostRejected(), 1u);
  EXPECT_EQ(service->currentHost().eyeEnu_m, good.eyeEnu_m);
  EXPECT_NE(service->currentHost().hostFrame, 999u);

  io::HostState badFov = good;
  badFov.fovY_deg = 0.0;
  EXPECT_FALSE(hostStateValid(badFov));
  io::HostState badClip = good;
  badClip.near_m = 100;
  badClip.far_m = 50;
  std::string why;
  EXPECT_FALSE(hostStateValid(badClip, &why));
  EXPECT_EQ(why.rfind("far_m", 0), 0u) << why;
}

// The host's time of day drives the sun (negative = none: the scene's fixed sun). NaN, infinity
// or 24 h and more are bad samples like a NaN eyepoint: rejected, the last good one kept.
// Accepted, a NaN time made the sun direction, colour, ambient light and fog colour NaN.
TEST(ServiceGL, NonFiniteOrOutOfRangeTimeOfDayIsRejected) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain.reset();
  cfg.frames = 1;
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  FakeClock clock;
  std::atomic<bool> stop{false};
  io::HostState good = test::defaultHostAt(2.0);
  good.timeOfDay_h = 10.5;
  service->mailbox().publish(good);
  ASSERT_EQ(service->run(clock, stop), 0);
  ASSERT_EQ(service->currentHost().timeOfDay_h, 10.5);
  uint64_t rejected = 0;
  for (const double tod : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                           -std::numeric_limits<double>::infinity(), 24.0, 1e300}) {
    SCOPED_TRACE(tod);
    io::HostState bad = good;
    bad.timeOfDay_h = tod;
    std::string why;
    EXPECT_FALSE(hostStateValid(bad, &why));
    EXPECT_EQ(why.rfind("tod_h", 0), 0u) << why;
    service->mailbox().publish(bad);
    ASSERT_EQ(service->run(clock, stop), 0);
    EXPECT_EQ(service->hostRejected(), ++rejected);
    EXPECT_EQ(service->currentHost().timeOfDay_h, 10.5);
  }
  io::HostState none = good;
  none.timeOfDay_h = -1.0;  // no time of day: valid
  EXPECT_TRUE(hostStateValid(none));
}

// Simulation time drives the [hdlod] schedule: time_offset_s + time_scale * t, clamped to
// [0, T]. A host time far beyond the schedule (finite, so accepted) holds it at T, one far
// before it at 0, even where the mapping overflows a double (it selected nothing: the site
// vanished).
TEST(ServiceGL, HdlodScheduleHoldsItsEndsForHostTimesFarOutside) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain.reset();
  scene.hdlod.emplace();
  scene.hdlod->siteScale = 0.02;
  scene.hdlod->timeOffset_s = -39729052800.0;  // config/scenes/construction_site.toml
  scene.hdlod->timeScale = 1103760.0;
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  io::HostState h = test::defaultHostAt(0.0);
  h.eyeEnu_m = {0.0, -400.0, 250.0};  // south of the site, looking north and down at it
  h.heading_deg = 0.0;
  h.pitch_deg = -30.0;
  h.roll_deg = 0.0;
  auto trianglesAt = [&](double simTime_s) {
    h.simTime_s = simTime_s;
    EXPECT_TRUE(hostStateValid(h)) << simTime_s;
    return service->renderOnce(h, nullptr).triangles;
  };
  const uint64_t atEnd = trianglesAt(1e6);      // schedule time > T: T
  const uint64_t atStart = trianglesAt(-1e6);   // schedule time < 0: 0
  ASSERT_GT(atEnd, 0u);
  ASSERT_NE(atEnd, atStart);                    // the site is built over the year
  EXPECT_EQ(trianglesAt(1e303), atEnd);         // time_scale * t overflows to +inf
  EXPECT_EQ(trianglesAt(-1e303), atStart);      // ... to -inf
  EXPECT_EQ(trianglesAt(std::numeric_limits<double>::max()), atEnd);
  EXPECT_EQ(trianglesAt(1e6), atEnd);           // and back
}

TEST(ServiceGL, EyepointInsideTerrainAndAtExtremeClipPlanesRendersWithoutGlErrors) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  io::HostState h = test::defaultHostAt(0.0);
  for (double z : {-50.0, 0.0, 5.0, 1.0e5}) {  // under, on, just above the ground, very high
    for (double pitch : {-90.0, 0.0, 90.0}) {
      h.eyeEnu_m.z = z;
      h.pitch_deg = pitch;
      h.near_m = 0.1;
      h.far_m = 100000.0;
      const FrameRecord r = service->renderOnce(h, nullptr);
      EXPECT_LE(r.triangles, service->info().terrainTriangles);
    }
  }
}

// [fog] cull: in thick fog nothing beyond the opaque distance is drawn, and the picture is the
// one drawn with the host's far plane to within one colour level (the fog lets less than 1/1024
// through there). The default scene at 800 m visibility, looking level and down from the
// built-in circuit.
TEST(ServiceGL, FogCullDrawsLessAndThePictureStaysTheSame) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.fog.enabled = true;
  scene.fog.visibility_m = 800.0;
  ASSERT_NEAR(render::fogOpaqueDistance_m(scene.fog.visibility_m), 1417.5, 0.5);  // 1.77 x
  std::string error;
  SceneConfig open = scene;
  open.fog.cull = false;
  auto culled = Service::create(cfg, scene, error);
  ASSERT_TRUE(culled) << error;
  auto full = Service::create(cfg, open, error);
  ASSERT_TRUE(full) << error;
  uint64_t culledTriangles = 0, fullTriangles = 0;
  for (double t : {5.0, 40.0}) {
    for (double pitch : {0.0, -10.0}) {
      io::HostState h = test::defaultHostAt(t);
      h.pitch_deg = pitch;
      h.far_m = 100000.0;
      render::Image a, b;
      const FrameRecord ra = culled->renderOnce(h, &a);
      const FrameRecord rb = full->renderOnce(h, &b);
      ASSERT_EQ(a.rgba.size(), b.rgba.size());
      int worst = 0;
      size_t differ = 0;
      for (size_t i = 0; i < a.rgba.size(); ++i) {
        const int d = std::abs(int{a.rgba[i]} - int{b.rgba[i]});
        worst = std::max(worst, d);
        differ += d != 0;
      }
      EXPECT_LE(worst, 1) << "t " << t << " pitch " << pitch;
      EXPECT_LT(differ, a.rgba.size() / 100) << "t " << t << " pitch " << pitch;
      EXPECT_LT(ra.triangles, rb.triangles) << "t " << t << " pitch " << pitch;
      // What the stats report: the far plane each frame was drawn with, and the fog's visibility.
      EXPECT_EQ(ra.far_m, render::fogOpaqueDistance_m(800.0));
      EXPECT_EQ(rb.far_m, 100000.0);
      EXPECT_EQ(ra.fogVisibility_m, 800.0);
      EXPECT_EQ(rb.fogVisibility_m, 800.0);
      culledTriangles += ra.triangles;
      fullTriangles += rb.triangles;
    }
  }
  // Thick fog: well under two thirds of what the host's 100 km far plane draws (0.57 when written).
  EXPECT_LT(3 * culledTriangles, 2 * fullTriangles);
}

// A host's visibility (CIGI Atmosphere Control) turns the fog on in a scene without fog, with
// the scene's fog colour, and culls like the scene's own fog: the same picture, byte for byte,
// as the scene with [fog] at that visibility. NaN, infinite or above 1e7 m is a bad sample,
// rejected with the last good one kept; <= 0 is "not given".
TEST(ServiceGL, HostVisibilityFogsTheSceneAndABadOneIsRejected) {
  ServiceConfig cfg;
  SceneConfig clear, foggy;
  test::defaultConfigs(cfg, clear);
  clear.fog.enabled = false;
  foggy = clear;
  foggy.fog.enabled = true;
  foggy.fog.visibility_m = 800.0;
  std::string error;
  auto host = Service::create(cfg, clear, error);
  ASSERT_TRUE(host) << error;
  auto own = Service::create(cfg, foggy, error);
  ASSERT_TRUE(own) << error;
  io::HostState h = test::defaultHostAt(40.0);
  render::Image clearImage, hostImage, ownImage;
  const FrameRecord rClear = host->renderOnce(h, &clearImage);
  const FrameRecord rOwn = own->renderOnce(h, &ownImage);
  h.visibility_m = 800.0;
  const FrameRecord rHost = host->renderOnce(h, &hostImage);
  EXPECT_EQ(hostImage.rgba, ownImage.rgba);
  EXPECT_NE(hostImage.rgba, clearImage.rgba);
  EXPECT_EQ(rHost.triangles, rOwn.triangles);
  EXPECT_LT(rHost.triangles, rClear.triangles);
  EXPECT_TRUE(std::isnan(rClear.fogVisibility_m));  // no fog: nan in the stats
  EXPECT_EQ(rHost.fogVisibility_m, 800.0);
  EXPECT_EQ(rHost.far_m, rOwn.far_m);
  // The host's visibility wins over the scene's own fog, too.
  h.visibility_m = 20000.0;
  render::Image thin;
  own->renderOnce(h, &thin);
  EXPECT_NE(thin.rgba, ownImage.rgba);

  cfg.frames = 1;
  auto service = Service::create(cfg, clear, error);
  ASSERT_TRUE(service) << error;
  FakeClock clock;
  std::atomic<bool> stop{false};
  io::HostState good = test::defaultHostAt(2.0);
  good.visibility_m = 1500.0;
  service->mailbox().publish(good);
  ASSERT_EQ(service->run(clock, stop), 0);
  ASSERT_EQ(service->currentHost().visibility_m, 1500.0);
  uint64_t rejected = 0;
  for (const double v : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                         -std::numeric_limits<double>::infinity(), 1.5e7}) {
    SCOPED_TRACE(v);
    io::HostState bad = good;
    bad.visibility_m = v;
    std::string why;
    EXPECT_FALSE(hostStateValid(bad, &why));
    EXPECT_EQ(why.rfind("visibility_m", 0), 0u) << why;
    service->mailbox().publish(bad);
    ASSERT_EQ(service->run(clock, stop), 0);
    EXPECT_EQ(service->hostRejected(), ++rejected);
    EXPECT_EQ(service->currentHost().visibility_m, 1500.0);
  }
  io::HostState none = good;
  none.visibility_m = 0.0;  // not given: valid
  EXPECT_TRUE(hostStateValid(none));
}

// Two services in one process (tests, igbench side by side) each draw with their own GL context:
// a service created second made its context current, and the first one's GL calls went there,
// onto the second's objects of the same names (a ROAM mesh drew the other mesh's buffer). The
// first service's picture is the same before the second exists, while it exists, and after it
// is destroyed.
TEST(ServiceGL, TwoServicesInOneProcessEachDrawWithTheirOwnContext) {
  ServiceConfig cfg;
  SceneConfig roam;
  test::defaultConfigs(cfg, roam);
  roam.terrain->lod = TerrainLayerConfig::Lod::Roam;
  roam.terrain->lodBudget_ms = 0.0;
  SceneConfig other = roam;
  other.terrain->seed = roam.terrain->seed + 1;  // another relief: another mesh in the same buffer names
  std::string error;
  auto a = Service::create(cfg, roam, error);
  ASSERT_TRUE(a) << error;
  const io::HostState h = test::defaultHostAt(3.0);
  render::Image alone, beside, after, second;
  a->renderOnce(h, &alone);
  {
    auto b = Service::create(cfg, other, error);
    ASSERT_TRUE(b) << error;
    b->renderOnce(h, &second);
    EXPECT_NE(second.rgba, alone.rgba);  // the other relief
    b->renderOnce(h, &beside);
    EXPECT_EQ(beside.rgba, second.rgba);
    a->renderOnce(h, &beside);
    EXPECT_EQ(beside.rgba, alone.rgba);
  }  // b goes while a's context is current: b deletes its own objects, not a's of the same names
  a->renderOnce(h, &after);
  EXPECT_EQ(after.rgba, alone.rgba);
}

TEST(ServiceGL, RunWritesStatsAndSnapshotsWithAFakeClock) {
  const auto dir = std::filesystem::temp_directory_path() / ("igd_service_gltest_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  cfg.host = HostSource::Replay;
  cfg.replayFile = test::kSource + "/config/recordings/default.rec";
  cfg.frames = 12;
  cfg.rate_hz = 30;
  cfg.statsFile = (dir / "stats.jsonl").string();
  cfg.statsFormat = StatsFormat::JsonLines;
  cfg.snapshotDir = (dir / "snap").string();
  cfg.snapshotEvery = 5;
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  FakeClock clock;
  std::atomic<bool> stop{false};
  ASSERT_EQ(service->run(clock, stop), 0);
  EXPECT_EQ(clock.sleeps(), 12);  // paced: one absolute-deadline sleep per frame
  const RunSummary s = service->summary();
  EXPECT_EQ(s.frames, 12);
  EXPECT_EQ(s.overruns, 0);  // the fake clock does not move while the GPU works
  EXPECT_GT(s.triangles_p50, 0u);
  EXPECT_TRUE(std::filesystem::exists(dir / "snap" / "frame_000000.png"));
  EXPECT_TRUE(std::filesystem::exists(dir / "snap" / "frame_000010.png"));
  EXPECT_FALSE(std::filesystem::exists(dir / "snap" / "frame_000011.png"));
  std::ifstream in(dir / "stats.jsonl");
  std::string line;
  std::getline(in, line);
  EXPECT_NE(line.find("\"layers\":[\"terrain\"]"), std::string::npos) << line;
  int frames = 0;
  uint64_t lastHostFrame = 0;
  while (std::getline(in, line)) {
    ++frames;
    const auto pos = line.find("\"host_frame\":");
    ASSERT_NE(pos, std::string::npos);
    lastHostFrame = std::stoull(line.substr(pos + 13));
  }
  EXPECT_EQ(frames, 12);
  // Frame 11 at 30 Hz is replay time 0.3667 s: host frame 22 of the 60 Hz recording.
  EXPECT_EQ(lastHostFrame, 22u);
  std::filesystem::remove_all(dir);
}

// Snapshots are named by the stats' frame column (the slot number, which fixes the replay and
// simulation time), so a picture can be matched to its stats row and to the same picture of
// another run. After missed slots, a snapshot number that was skipped is taken by the first frame
// after it, under that frame's own number.
class LateOnceClock final : public Clock {
 public:
  explicit LateOnceClock(int lateSleep, int64_t late_ns) : lateSleep_(lateSleep), late_ns_(late_ns) {}
  int64_t now_ns() const override { return now_; }
  void sleepUntil_ns(int64_t deadline_ns) override {
    ++sleeps_;
    now_ = std::max(now_, deadline_ns) + (sleeps_ == lateSleep_ ? late_ns_ : 0);
  }

 private:
  int lateSleep_;
  int64_t late_ns_;
  int64_t now_ = 1'000'000'000;
  int sleeps_ = 0;
};

TEST(ServiceGL, SnapshotsAreNamedByTheStatsFrameNumber) {
  const auto dir = std::filesystem::temp_directory_path() / ("igd_service_gltest_snap_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  cfg.frames = 12;
  cfg.rate_hz = 30;
  cfg.statsFile = (dir / "stats.csv").string();
  cfg.snapshotDir = (dir / "snap").string();
  cfg.snapshotEvery = 5;
  cfg.snapshotFrames = {3, 4};
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  LateOnceClock clock(4, 3 * 33'333'334);  // the 4th frame wakes 3 periods late: slots are skipped
  std::atomic<bool> stop{false};
  ASSERT_EQ(service->run(clock, stop), 0);
  service.reset();  // the snapshot thread has written everything
  std::ifstream in(dir / "stats.csv");
  std::string line;
  std::getline(in, line);
  ASSERT_EQ(line.rfind("frame,", 0), 0u) << line;
  std::vector<int64_t> slots;
  while (std::getline(in, line)) slots.push_back(std::stoll(line.substr(0, line.find(','))));
  ASSERT_EQ(slots.size(), 12u);
  ASSERT_GT(slots.back(), 11) << "no slot was skipped";
  std::set<std::string> expected;
  int64_t prev = -1;
  for (int64_t slot : slots) {
    bool snap = false;
    for (int64_t f = prev + 1; f <= slot; ++f) snap = snap || f % 5 == 0 || f == 3 || f == 4;
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06lld.png", static_cast<long long>(slot));
    if (snap) expected.insert(name);
    prev = slot;
  }
  std::set<std::string> written;
  for (const auto& e : std::filesystem::directory_iterator(dir / "snap")) written.insert(e.path().filename().string());
  EXPECT_EQ(written, expected);
  std::filesystem::remove_all(dir);
}

namespace {
render::Image renderScene(const SceneConfig& scene, const io::HostState& host, FrameRecord* record = nullptr,
                          ServiceInfo* info = nullptr) {
  ServiceConfig cfg;
  SceneConfig unused;
  test::defaultConfigs(cfg, unused);
  std::string error;
  auto service = Service::create(cfg, scene, error);
  EXPECT_TRUE(service) << error;
  render::Image image;
  if (!service) return image;
  const FrameRecord r = service->renderOnce(host, &image);
  if (record) *record = r;
  if (info) *info = service->info();
  return image;
}
}  // namespace

TEST(ServiceGL, RoamAndBlockTerrainRenderCloseToTheFullGrid) {
  ServiceConfig cfg;
  SceneConfig grid;
  test::defaultConfigs(cfg, grid);
  const io::HostState host = test::defaultHostAt(5.0);
  FrameRecord full, roamRec, blockRec;
  const render::Image reference = renderScene(grid, host, &full);
  SceneConfig roam = grid, block = grid;
  roam.terrain->lod = TerrainLayerConfig::Lod::Roam;
  roam.terrain->tolerance_px = 1.0;
  block.terrain->lod = TerrainLayerConfig::Lod::Block;
  ServiceInfo info;
  const render::Image a = renderScene(roam, host, &roamRec, &info);
  EXPECT_EQ(info.passes, 1u);
  EXPECT_EQ(info.layers.at(0), "terrain (roam)");
  const render::Image b = renderScene(block, host, &blockRec);
  // Same picture within a few 8-bit levels at 1 px tolerance (320x180 here)...
  EXPECT_LT(render::rmse(a, reference), 4.0);
  EXPECT_LT(render::rmse(b, reference), 4.0);
  // ...with far fewer triangles than the full grid, and ROAM fewer than block LOD.
  EXPECT_GT(roamRec.triangles, 0u);
  EXPECT_LT(roamRec.triangles * 3, full.triangles);
  EXPECT_LT(roamRec.triangles, blockRec.triangles);
}

TEST(ServiceGL, DemTerrainFromAFileAndItsErrors) {
  const auto dir = std::filesystem::temp_directory_path() / ("igd_dem_gltest_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  // A 65 x 65 DEM: a wavy north-south ridge.
  std::vector<uint16_t> v(65 * 65);
  for (int y = 0; y < 65; ++y)
    for (int x = 0; x < 65; ++x)
      v[static_cast<size_t>(y) * 65 + x] =
          static_cast<uint16_t>(600.0 - 15.0 * std::abs(x - 32) + 150.0 * std::sin(x / 4.0) * std::cos(y / 6.0));
  {
    // As an SRTM .hgt file (big-endian int16, square); the readers have their own tests.
    std::vector<uint8_t> b(65 * 65 * 2);
    for (size_t i = 0; i < v.size(); ++i) {
      b[2 * i] = static_cast<uint8_t>(v[i] >> 8);
      b[2 * i + 1] = static_cast<uint8_t>(v[i] & 0xFF);
    }
    std::ofstream((dir / "ridge.hgt").string(), std::ios::binary).write(reinterpret_cast<const char*>(b.data()), 65 * 65 * 2);
  }
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain->source = TerrainLayerConfig::Source::Dem;
  scene.terrain->lod = TerrainLayerConfig::Lod::Roam;
  scene.terrain->file = (dir / "ridge.hgt").string();
  scene.terrain->demSpacing_m = 50.0;
  scene.terrain->offset_m = {-1600, -1600, 0};
  io::HostState h = test::defaultHostAt(0.0);
  h.eyeEnu_m = {0, -3000, 1500};
  h.heading_deg = 0;
  h.pitch_deg = -20;
  h.roll_deg = 0;
  FrameRecord r;
  const render::Image image = renderScene(scene, h, &r);
  EXPECT_GT(r.triangles, 8u);
  size_t ground = 0;
  for (size_t i = 0; i < image.rgba.size(); i += 4) ground += image.rgba[i] != image.rgba[0];
  EXPECT_GT(ground, image.rgba.size() / 4 / 10) << "the ridge must cover part of the view";

  scene.terrain->file = (dir / "missing.hgt").string();
  std::string error;
  EXPECT_FALSE(Service::create(cfg, scene, error));
  EXPECT_NE(error.find("terrain.file"), std::string::npos) << error;
  EXPECT_NE(error.find("missing.hgt"), std::string::npos) << error;
  std::filesystem::remove_all(dir);
}

// The terrain's shading (grass, rock, snow by height within the relief) depends on where a
// post lies within the DEM's relief, not on the DEM's datum: the same ridge stored 4000 m
// higher (a plateau DEM) and placed 4000 m lower is the same world and must look the same. The
// height scale was the relief (highest - lowest) but the heights were taken from 0, not from
// the lowest post, so the plateau rendered white with snow everywhere.
TEST(ServiceGL, DemShadingFollowsTheReliefNotTheDatum) {
  const auto dir = std::filesystem::temp_directory_path() / ("igd_dem_datum_gltest_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  auto writeRidge = [&](const std::string& name, int base) {
    std::vector<uint8_t> b(65 * 65 * 2);
    for (int y = 0; y < 65; ++y)
      for (int x = 0; x < 65; ++x) {
        const auto v = static_cast<uint16_t>(base + 600.0 - 15.0 * std::abs(x - 32) + 150.0 * std::sin(x / 4.0) * std::cos(y / 6.0));
        const size_t i = static_cast<size_t>(y) * 65 + static_cast<size_t>(x);
        b[2 * i] = static_cast<uint8_t>(v >> 8);
        b[2 * i + 1] = static_cast<uint8_t>(v & 0xFF);
      }
    std::ofstream((dir / name).string(), std::ios::binary).write(reinterpret_cast<const char*>(b.data()), 65 * 65 * 2);
  };
  writeRidge("low.hgt", 0);
  writeRidge("high.hgt", 4000);
  for (const auto lod : {TerrainLayerConfig::Lod::Roam, TerrainLayerConfig::Lod::Block}) {
    ServiceConfig cfg;
    SceneConfig scene;
    test::defaultConfigs(cfg, scene);
    scene.terrain->source = TerrainLayerConfig::Source::Dem;
    scene.terrain->lod = lod;
    scene.terrain->demSpacing_m = 50.0;
    io::HostState h = test::defaultHostAt(0.0);
    h.eyeEnu_m = {0, -3000, 1500};
    h.heading_deg = 0;
    h.pitch_deg = -20;
    h.roll_deg = 0;
    scene.terrain->file = (dir / "low.hgt").string();
    scene.terrain->offset_m = {-1600, -1600, 0};
    const render::Image low = renderScene(scene, h);
    scene.terrain->file = (dir / "high.hgt").string();
    scene.terrain->offset_m = {-1600, -1600, -4000};
    const render::Image high = renderScene(scene, h);
    size_t ground = 0;
    for (size_t i = 0; i < low.rgba.size(); i += 4) ground += low.rgba[i] != low.rgba[0];
    EXPECT_GT(ground, low.rgba.size() / 4 / 10) << "the ridge must cover part of the view";
    const double e = render::rmse(low, high);
    EXPECT_GE(e, 0.0);
    EXPECT_LT(e, 2.0) << (lod == TerrainLayerConfig::Lod::Roam ? "roam" : "block")
                      << ": per-pixel RMSE (8-bit levels) between the same ridge at two datums";
  }
  std::filesystem::remove_all(dir);
}

TEST(ServiceGL, RoamWritesOnlyChangedTrianglesToTheGpu) {
  const auto dir = std::filesystem::temp_directory_path() / ("igd_uploads_gltest_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain->lod = TerrainLayerConfig::Lod::Roam;
  cfg.host = HostSource::Replay;
  cfg.replayFile = test::kSource + "/config/recordings/default.rec";
  cfg.frames = 30;
  cfg.statsFile = (dir / "stats.csv").string();
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  FakeClock clock;
  std::atomic<bool> stop{false};
  ASSERT_EQ(service->run(clock, stop), 0);
  std::ifstream in(dir / "stats.csv");
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  for (size_t a = 0, b; a <= line.size(); a = b + 1) {
    b = std::min(line.find(',', a), line.size());
    header.push_back(line.substr(a, b - a));
  }
  const auto col = [&](const char* name) {
    return static_cast<size_t>(std::find(header.begin(), header.end(), name) - header.begin());
  };
  const size_t tri = col("triangles"), up = col("uploads");
  ASSERT_LT(up, header.size());
  std::vector<std::pair<double, double>> rows;  // triangles, uploads
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    for (size_t a = 0, b; a <= line.size(); a = b + 1) {
      b = std::min(line.find(',', a), line.size());
      f.push_back(line.substr(a, b - a));
    }
    rows.emplace_back(std::stod(f[tri]), std::stod(f[up]));
  }
  ASSERT_EQ(rows.size(), 30u);
  // The first frame writes the mesh; once the camera flies smoothly, a few per cent per frame.
  EXPECT_GT(rows[0].second, rows[0].first / 2);
  for (size_t i = 10; i < rows.size(); ++i) EXPECT_LT(rows[i].second, 0.1 * rows[i].first) << "frame " << i;
  std::filesystem::remove_all(dir);
}

namespace {
// A fake clock that asks for a config reload at its 5th frame deadline and, until the service
// has applied it, holds each later deadline until the reload thread has read the files.
class ReloadingClock final : public Clock {
 public:
  ReloadingClock(ReloadSource& reload, const Service*& service, std::atomic<bool>& loaded, std::atomic<bool>& stop,
                 std::filesystem::path statusFile)
      : reload_(reload), service_(service), loaded_(loaded), stop_(stop), statusFile_(std::move(statusFile)) {}
  int64_t now_ns() const override { return clock_.now_ns(); }
  void sleepUntil_ns(int64_t deadline_ns) override {
    clock_.sleepUntil_ns(deadline_ns);
    ++sleeps_;
    // The render thread calls this, so reading the service's generation here is race-free.
    if (service_->configGeneration() > 1) {
      stop_ = true;  // this frame is the last
    } else if (sleeps_ == 5) {
      statusBeforeReload = std::filesystem::exists(statusFile_);
      reload_.requested = true;
    } else if (sleeps_ > 5) {
      for (int i = 0; i < 5000 && !loaded_; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
  bool statusBeforeReload = false;

 private:
  FakeClock clock_;
  ReloadSource& reload_;
  const Service*& service_;
  std::atomic<bool>& loaded_;
  std::atomic<bool>& stop_;
  std::filesystem::path statusFile_;
  int64_t sleeps_ = 0;
};
}  // namespace

// A reload that switches the status file off (status_file = "" with no systemd to report to)
// removes the file, as one that moves it to another path does (ig/status.h): left behind, it
// would say "running" long after igd stopped.
TEST(ServiceGL, AReloadThatSwitchesTheStatusFileOffRemovesIt) {
  const auto dir = std::filesystem::temp_directory_path() / ("igd_service_status_off_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  cfg.frames = 200;  // a bound; the clock stops the run once the reload is applied
  cfg.rate_hz = 30;
  cfg.statusFile = (dir / "status.json").string();
  cfg.statusInterval_s = 0.05;  // a report every other frame
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  std::atomic<bool> loaded{false}, stop{false};
  ReloadSource reload;
  reload.load = [&](ServiceConfig& c, SceneConfig& s, std::string&) {
    c = cfg;
    c.statusFile = "";
    s = scene;
    loaded = true;
    return true;
  };
  const Service* running = service.get();
  ReloadingClock clock(reload, running, loaded, stop, cfg.statusFile);
  ASSERT_EQ(service->run(clock, stop, &reload), 0);
  EXPECT_EQ(service->configGeneration(), 2);
  EXPECT_TRUE(clock.statusBeforeReload);  // the report was there before the reload
  std::string left;
  if (std::ifstream in(cfg.statusFile); in) std::getline(in, left);
  EXPECT_FALSE(std::filesystem::exists(cfg.statusFile)) << "left behind: " << left;
  std::filesystem::remove_all(dir);
}

namespace {
// Threads of this process now (/proc/self/task).
int processThreads() {
  int n = 0;
  for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator("/proc/self/task")) ++n;
  return n;
}

// A fake clock that asks for a reload at its 3rd frame deadline and for a second one as soon as
// the first is applied, holding each deadline until the pending reload has read its files, and
// counts the process's threads between frames (the render thread calls it: no reload thread runs
// then, the one of an applied reload has been joined).
class TwoReloadsClock final : public Clock {
 public:
  TwoReloadsClock(ReloadSource& reload, const Service*& service, std::atomic<int>& loads, std::atomic<bool>& stop)
      : reload_(reload), service_(service), loads_(loads), stop_(stop) {}
  int64_t now_ns() const override { return clock_.now_ns(); }
  void sleepUntil_ns(int64_t deadline_ns) override {
    clock_.sleepUntil_ns(deadline_ns);
    ++sleeps_;
    const int64_t slot = sleeps_ - 1;  // the frame about to start (no missed slots)
    const int generation = service_->configGeneration();
    if (sleeps_ == 3) {
      threadsBefore = processThreads();
      reload_.requested = true;
      requestedAt_ = sleeps_;
    } else if (generation == 2 && offFrom < 0) {
      offFrom = slot;
      // The writer switched off finishes its queue on a thread of its own (the reload must not
      // cost a frame): wait for both to end, bounded.
      threadsWhileOff = processThreads();
      for (int i = 0; i < 5000 && threadsWhileOff != threadsBefore - 1; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        threadsWhileOff = processThreads();
      }
      reload_.requested = true;
      requestedAt_ = sleeps_;
    } else if (generation == 3 && onFrom < 0) {
      onFrom = slot;
      threadsWhileOn = processThreads();
    } else if (onFrom >= 0 && slot >= onFrom + 8) {
      stop_ = true;
    }
    // A reload asked for at an earlier deadline is load number `generation`: wait for its files.
    if (requestedAt_ > 0 && sleeps_ > requestedAt_ && generation < 3)
      for (int i = 0; i < 5000 && loads_ < generation; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  int threadsBefore = -1, threadsWhileOff = -1, threadsWhileOn = -1;
  int64_t offFrom = -1, onFrom = -1;

 private:
  FakeClock clock_;
  ReloadSource& reload_;
  const Service*& service_;
  std::atomic<int>& loads_;
  std::atomic<bool>& stop_;
  int64_t sleeps_ = 0;
  int64_t requestedAt_ = 0;
};
}  // namespace

// "An unused subsystem costs nothing" holds after a reload too: snapshots switched off by a
// reload release the snapshot thread, and a later reload may switch them on again (igd.toml:
// snapshot_every reloads "if snapshots were on at start-up"); the frames between write none.
TEST(ServiceGL, AReloadThatSwitchesSnapshotsOffReleasesTheirThreadAndOnAgainWorks) {
  const auto dir = std::filesystem::temp_directory_path() / ("igd_service_snap_reload_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain.reset();  // sky only: fast frames
  cfg.frames = 200;       // a bound; the clock stops the run
  cfg.rate_hz = 30;
  cfg.snapshotDir = (dir / "snap").string();
  cfg.snapshotEvery = 2;
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  EXPECT_EQ(service->info().threads, 2u);  // render + snapshot writer
  std::atomic<int> loads{0};
  std::atomic<bool> stop{false};
  ReloadSource reload;
  reload.load = [&](ServiceConfig& c, SceneConfig& s, std::string&) {
    c = cfg;
    c.snapshotEvery = loads == 0 ? 0 : 2;  // first reload: off; second: on again
    s = scene;
    ++loads;
    return true;
  };
  const Service* running = service.get();
  TwoReloadsClock clock(reload, running, loads, stop);
  ASSERT_EQ(service->run(clock, stop, &reload), 0);
  ASSERT_EQ(service->configGeneration(), 3);
  ASSERT_GE(clock.offFrom, 0);
  ASSERT_GE(clock.onFrom, 0);
  EXPECT_EQ(clock.threadsWhileOff, clock.threadsBefore - 1) << "the snapshot thread outlived snapshot_every = 0";
  EXPECT_EQ(clock.threadsWhileOn, clock.threadsBefore);
  int64_t writtenWhileOff = 0, writtenAfterOn = 0;
  for (int64_t f = clock.offFrom; f < clock.onFrom + 8; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%06lld.png", static_cast<long long>(f));
    if (!std::filesystem::exists(dir / "snap" / name)) continue;
    ++(f < clock.onFrom ? writtenWhileOff : writtenAfterOn);
  }
  EXPECT_EQ(writtenWhileOff, 0);
  EXPECT_GE(writtenAfterOn, 1) << "snapshots were not switched on again by the second reload";
  std::filesystem::remove_all(dir);
}

// The threads a service starts, counted by the kernel (not ServiceInfo::threads, which is the
// service's own account): with no layer, no snapshots, no status report, no host link and no
// recording, Service::create and a run start none besides what Mesa starts for any GL context
// (measured on a bare context of the same size), and the snapshot writer is exactly one more.
TEST(ServiceGL, UnusedSubsystemsStartNoThreads) {
  { test::HeadlessGl warm(320, 180); }  // Mesa's once-per-process threads, if any
  auto threadsOfABareContext = [] {
    const int before = processThreads();
    test::HeadlessGl gl(320, 180);
    return processThreads() - before;
  };
  const int mesa = threadsOfABareContext();
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain.reset();
  cfg.frames = 3;
  cfg.freeRun = true;
  ASSERT_TRUE(cfg.statusFile.empty());
  for (const bool snapshots : {false, true}) {
    SCOPED_TRACE(snapshots ? "with snapshots" : "without snapshots");
    const auto dir = std::filesystem::temp_directory_path() / ("igd_service_threads_" + std::to_string(::getpid()));
    ServiceConfig c = cfg;
    if (snapshots) {
      c.snapshotDir = (dir / "snap").string();
      c.snapshotFrames = {1};
    }
    const int before = processThreads();
    std::string error;
    auto service = Service::create(c, scene, error);
    ASSERT_TRUE(service) << error;
    EXPECT_EQ(processThreads() - before, mesa + (snapshots ? 1 : 0));
    EXPECT_EQ(service->info().threads, snapshots ? 2u : 1u);
    FakeClock clock;
    std::atomic<bool> stop{false};
    ASSERT_EQ(service->run(clock, stop), 0);
    EXPECT_EQ(processThreads() - before, mesa + (snapshots ? 1 : 0));
    service.reset();
    std::filesystem::remove_all(dir);
  }
}

namespace {
// A fake clock that makes the work of frame `spikeFrame` (counted from 1 by the sleeps) 100 ms
// long, asks for a reload at its 3rd deadline and holds later deadlines until it is read.
class SpikeAndReloadClock final : public Clock {
 public:
  SpikeAndReloadClock(ReloadSource& reload, std::atomic<bool>& loaded) : reload_(reload), loaded_(loaded) {}
  int64_t now_ns() const override {
    // The first call after the sleep is the frame's start; the next one is within its work.
    if (calls_++ == 1 && sleeps_ == 2) offset_ += 100'000'000;
    return clock_.now_ns() + offset_;
  }
  void sleepUntil_ns(int64_t deadline_ns) override {
    clock_.sleepUntil_ns(deadline_ns - offset_);
    ++sleeps_;
    calls_ = 0;
    if (sleeps_ == 3) reload_.requested = true;
    if (sleeps_ > 3)
      for (int i = 0; i < 5000 && !loaded_; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }

 private:
  FakeClock clock_;
  ReloadSource& reload_;
  std::atomic<bool>& loaded_;
  int sleeps_ = 0;
  mutable int calls_ = 0;
  mutable int64_t offset_ = 0;
};
}  // namespace

// The exit summary's percentiles cover the run's frames (up to SummaryCollector::kMaxCapacity),
// also after a reload that raises frame.frames: sized by the start-up frames = 10, they covered
// only the last 10 of the 40 frames, and frame 1's 100 ms spike was missing from p99 (which, at
// 40 frames, nearest rank, is the maximum).
TEST(ServiceGL, AReloadThatRaisesFramesKeepsTheSummaryOverEveryFrame) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  cfg.frames = 10;
  cfg.rate_hz = 5;  // 200 ms slots: the spike is no overrun
  cfg.statsFile = "";
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  std::atomic<bool> loaded{false}, stop{false};
  ReloadSource reload;
  reload.load = [&](ServiceConfig& c, SceneConfig& s, std::string&) {
    c = cfg;
    c.frames = 40;
    s = scene;
    loaded = true;
    return true;
  };
  SpikeAndReloadClock clock(reload, loaded);
  ASSERT_EQ(service->run(clock, stop, &reload), 0);
  EXPECT_EQ(service->configGeneration(), 2);
  const RunSummary s = service->summary();
  EXPECT_EQ(s.frames, 40);
  EXPECT_GE(s.workMs_max, 100.0);
  EXPECT_EQ(s.workMs_p99, s.workMs_max) << "p99 over the last 10 frames only";
}

namespace {
// A fake clock that reads systemd's notify socket (the test's own) at every sleep, keeping the
// longest time between two watchdog pings, and asks the loop to stop while it sleeps towards
// `stopFrom_ns` or later.
class NotifyWatchingClock final : public Clock {
 public:
  NotifyWatchingClock(int socket, std::atomic<bool>& stop, int64_t stopFrom_ns)
      : socket_(socket), stop_(stop), stopFrom_ns_(stopFrom_ns) {}
  int64_t now_ns() const override { return clock_.now_ns(); }
  void sleepUntil_ns(int64_t deadline_ns) override {
    drain();
    if (deadline_ns >= stopFrom_ns_) stop_ = true;
    clock_.sleepUntil_ns(deadline_ns);
  }
  // Pings sent since the last sleep are stamped with the time now (a frame takes no fake time).
  void drain() {
    char buf[512];
    for (ssize_t n; (n = ::recv(socket_, buf, sizeof buf - 1, MSG_DONTWAIT)) > 0;) {
      buf[n] = '\0';
      if (std::string(buf).find("WATCHDOG=1") == std::string::npos) continue;
      const int64_t now = clock_.now_ns();
      if (lastPing_ns >= 0) maxGap_ns = std::max(maxGap_ns, now - lastPing_ns);
      lastPing_ns = now;
      ++pings;
    }
  }
  int64_t lastPing_ns = -1, maxGap_ns = 0;
  int pings = 0;

 private:
  FakeClock clock_;
  int socket_;
  std::atomic<bool>& stop_;
  int64_t stopFrom_ns_;
};
}  // namespace

// frame.rate_hz goes down to 0.01 Hz (a 100 s period), and igd.service has WatchdogSec=5 and
// TimeoutStopSec=10. The loop pinged the watchdog once a frame and slept a whole period at once:
// at 0.1 Hz systemd killed igd for a missed watchdog every run, and a SIGTERM was seen only at
// the next slot, after systemd had given up and sent SIGKILL (no last stats line, status file
// left "running"). Slept in pieces, the pings keep within WatchdogSec and a stop request ends
// the wait without rendering the slot's frame.
TEST(ServiceGL, ALongPeriodPingsTheWatchdogAndSeesAStopWhileWaiting) {
  const std::string sock = (std::filesystem::temp_directory_path() / ("igd_notify_" + std::to_string(::getpid()))).string();
  std::filesystem::remove(sock);
  const int fd = ::socket(AF_UNIX, SOCK_DGRAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  ASSERT_LT(sock.size(), sizeof addr.sun_path);
  std::memcpy(addr.sun_path, sock.c_str(), sock.size());
  ASSERT_EQ(::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr), 0);
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain.reset();  // sky only
  cfg.frames = 3;
  cfg.rate_hz = 0.1;  // 10 s slots
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  std::atomic<bool> stop{false};
  constexpr int64_t kS = 1'000'000'000;
  const int64_t t0 = FakeClock().now_ns();
  NotifyWatchingClock clock(fd, stop, t0 + 15 * kS);  // SIGTERM 15 s in: while waiting for slot 2
  ::setenv("NOTIFY_SOCKET", sock.c_str(), 1);
  ::setenv("WATCHDOG_USEC", "5000000", 1);  // igd.service: WatchdogSec=5
  ::setenv("WATCHDOG_PID", std::to_string(::getpid()).c_str(), 1);
  const int rc = service->run(clock, stop);
  ::unsetenv("NOTIFY_SOCKET");
  ::unsetenv("WATCHDOG_USEC");
  ::unsetenv("WATCHDOG_PID");
  clock.drain();
  ::close(fd);
  std::filesystem::remove(sock);
  EXPECT_EQ(rc, 0);
  EXPECT_GE(clock.pings, 2);
  EXPECT_LT(clock.maxGap_ns, 5 * kS) << "systemd's watchdog (WatchdogSec=5) would have killed igd";
  EXPECT_EQ(service->summary().frames, 2) << "the frame of slot 2 was rendered after the stop request";
  EXPECT_LT(clock.now_ns(), t0 + 20 * kS) << "the stop request was seen only at slot 2";
}

namespace {
// A clock whose every reading is 50 ms after the previous one: at 30 Hz every frame overruns
// and skips slots.
class SlowWorkClock final : public Clock {
 public:
  int64_t now_ns() const override { return now_ += 50'000'000; }
  void sleepUntil_ns(int64_t deadline_ns) override { now_ = std::max(now_, deadline_ns); }

 private:
  mutable int64_t now_ = 1'000'000'000;
};
}  // namespace

// Service::summary() after several run() calls: its frames (and percentiles) are of every run,
// so its overruns and missed slots must be too (they were the last run's only).
TEST(ServiceGL, SummaryCountsTheOverrunsAndMissedSlotsOfEveryRun) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain.reset();
  cfg.frames = 3;
  cfg.rate_hz = 30;
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  std::atomic<bool> stop{false};
  SlowWorkClock clock;
  ASSERT_EQ(service->run(clock, stop), 0);
  const RunSummary first = service->summary();
  ASSERT_EQ(first.frames, 3);
  ASSERT_EQ(first.overruns, 3);
  ASSERT_GT(first.missedSlots, 0);
  ASSERT_EQ(service->run(clock, stop), 0);
  const RunSummary both = service->summary();
  EXPECT_EQ(both.frames, 6);
  EXPECT_EQ(both.overruns, 6);
  EXPECT_GT(both.missedSlots, first.missedSlots);
}
