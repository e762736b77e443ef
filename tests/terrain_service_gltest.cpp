// The service's ROAM terrain layer over frames of the real loop (fake clock, replayed host):
// Deferred updates converge to the enhMerge picture for a still eye, and with morph_s > 0
// merges morph out (lod::MorphOut) instead of popping, in both the tolerance-driven and the
// eye-driven case, and end on the converged picture.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "gl_fixture.h"
#include "ig/clock.h"
#include "render/image.h"

using namespace ig;

namespace {

struct Waypoint {
  double t_s;  // replay time from which this eyepoint holds
  glm::dvec3 eye_m;
  double pitch_deg;
};

struct RunResult {
  std::map<int64_t, render::Image> images;  // by frame number
  std::vector<std::map<std::string, std::string>> stats;
};

std::string snapshotName(int64_t frame) {
  char name[64];
  std::snprintf(name, sizeof name, "frame_%06lld.png", static_cast<long long>(frame));
  return name;
}

// A fake clock that asks for a config reload at its n-th frame deadline (0 = never), and
// holds each frame until the snapshot writer has started on the snapshot two frames back, so
// that none is dropped for want of a free image (the writer has three).
class TestClock final : public Clock {
 public:
  TestClock(ReloadSource* reload, int64_t atSleep, std::filesystem::path snapDir, const std::vector<int64_t>& snaps)
      : reload_(reload), atSleep_(atSleep), snapDir_(std::move(snapDir)), snaps_(snaps) {}
  int64_t now_ns() const override { return clock_.now_ns(); }
  void sleepUntil_ns(int64_t deadline_ns) override {
    clock_.sleepUntil_ns(deadline_ns);
    const int64_t frame = sleeps_++;  // the frame about to start
    if (reload_ && sleeps_ == atSleep_) reload_->requested = true;
    for (int64_t f : snaps_) {
      if (f > frame - 2) continue;
      for (int i = 0; i < 5000 && !std::filesystem::exists(snapDir_ / snapshotName(f)); ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }

 private:
  FakeClock clock_;
  ReloadSource* reload_;
  int64_t atSleep_, sleeps_ = 0;
  std::filesystem::path snapDir_;
  std::vector<int64_t> snaps_;
};

// Runs `frames` frames at 30 Hz over the waypoints (heading north) and reads back the
// snapshots of `snapshotFrames` (empty: every frame).
// `config` (optional) receives the service config before the run (a reload repeats it).
RunResult runPath(const SceneConfig& scene, const std::vector<Waypoint>& path, int64_t frames,
                  std::vector<int64_t> snapshotFrames, const std::string& tag, ReloadSource* reload = nullptr,
                  int64_t reloadAtFrame = 0, ServiceConfig* config = nullptr) {
  RunResult out;
  const auto dir =
      std::filesystem::temp_directory_path() / ("igd_terrain_gltest_" + tag + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  io::Recording rec;
  for (const Waypoint& w : path) {
    io::HostSample s;
    s.t_s = w.t_s;
    s.state = test::defaultHostAt(0.0);
    s.state.hostFrame = rec.samples.size() + 1;
    s.state.simTime_s = w.t_s;
    s.state.eyeEnu_m = w.eye_m;
    s.state.heading_deg = 0.0;
    s.state.pitch_deg = w.pitch_deg;
    s.state.roll_deg = 0.0;
    rec.samples.push_back(s);
  }
  std::string error;
  EXPECT_TRUE(io::saveRecording((dir / "path.rec").string(), rec, error)) << error;
  ServiceConfig cfg;
  SceneConfig unused;
  test::defaultConfigs(cfg, unused);
  cfg.host = HostSource::Replay;
  cfg.replayFile = (dir / "path.rec").string();
  cfg.frames = frames;
  cfg.rate_hz = 30;
  cfg.statsFile = (dir / "stats.csv").string();
  cfg.snapshotDir = (dir / "snap").string();
  if (snapshotFrames.empty())
    for (int64_t f = 0; f < frames; ++f) snapshotFrames.push_back(f);
  cfg.snapshotFrames = snapshotFrames;
  if (config) *config = cfg;
  auto service = Service::create(cfg, scene, error);
  EXPECT_TRUE(service) << error;
  if (!service) return out;
  TestClock clock(reload, reloadAtFrame, dir / "snap", snapshotFrames);
  std::atomic<bool> stop{false};
  EXPECT_EQ(service->run(clock, stop, reload), 0);
  service.reset();
  for (int64_t f : snapshotFrames)
    EXPECT_TRUE(render::readPng((dir / "snap" / snapshotName(f)).string(), out.images[f], error)) << error;
  out.stats = test::readStatsCsv(cfg.statsFile);
  std::filesystem::remove_all(dir);
  return out;
}

SceneConfig roamScene(double morph_s, TerrainLayerConfig::RoamMode mode, double tolerance_px) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain->lod = TerrainLayerConfig::Lod::Roam;
  scene.terrain->roamMode = mode;
  scene.terrain->tolerance_px = tolerance_px;
  scene.terrain->lodBudget_ms = 0.0;  // the fake clock does not move: converge every frame
  scene.terrain->morph_s = morph_s;
  return scene;
}

const Waypoint kLow{0.0, {0, -2500, 600}, -30.0};
constexpr double kMorph_s = 0.3;  // 9 frames at 30 Hz

}  // namespace

// Deferred (igd's default) and enhMerge draw the same picture for a still eye once converged,
// and Deferred then has nothing left to do.
TEST(TerrainService, DeferredConvergesToTheEnhMergePicture) {
  const std::vector<Waypoint> path = {kLow};
  const RunResult d = runPath(roamScene(0.0, TerrainLayerConfig::RoamMode::Deferred, 1.0), path, 6, {5}, "deferred");
  const RunResult e = runPath(roamScene(0.0, TerrainLayerConfig::RoamMode::EnhMerge, 1.0), path, 6, {5}, "enhmerge");
  ASSERT_EQ(d.stats.size(), 6u);
  ASSERT_EQ(e.stats.size(), 6u);
  const double td = std::stod(d.stats[5].at("triangles")), te = std::stod(e.stats[5].at("triangles"));
  // Both draw the chunks in view (lod/terrain_chunks.h); Deferred has refined beyond the view
  // too, so its chunks at the frustum's edges hold more. Measured: 5823 and 3991 (the visible
  // leaves alone: 3323 and 3471).
  EXPECT_GT(td, 0.9 * te);
  EXPECT_LT(td, 1.6 * te);
  EXPECT_LT(render::rmse(d.images.at(5), e.images.at(5)), 0.5);  // measured: 0
  for (size_t f = 2; f < 6; ++f) EXPECT_EQ(d.stats[f].at("uploads"), "0") << "frame " << f << ": still eye, converged";
}

// A sudden coarsening with the eye still (tolerance 1 -> 6 px applied by a reload: many
// merges in one frame) does not pop with morph_s > 0: the picture changes in small steps over
// morph_s and ends as the converged one; without morphing it changes in one step.
TEST(TerrainService, MergesMorphOutInsteadOfPopping) {
  const int64_t frames = 27, reloadAt = 10;  // frame 0's splits have morphed in by frame 9
  struct Run {
    double maxStep = 0.0;  // largest rmse between consecutive frames
    RunResult r;
  };
  auto run = [&](double morph_s, const char* tag) {
    Run out;
    const SceneConfig scene = roamScene(morph_s, TerrainLayerConfig::RoamMode::Deferred, 1.0);
    ReloadSource reload;
    ServiceConfig running;
    reload.load = [&](ServiceConfig& c, SceneConfig& s, std::string&) {
      c = running;
      s = scene;
      s.terrain->tolerance_px = 6.0;
      return true;
    };
    std::vector<int64_t> snaps;
    for (int64_t f = reloadAt - 1; f < frames; ++f) snaps.push_back(f);
    out.r = runPath(scene, {kLow}, frames, snaps, tag, &reload, reloadAt, &running);
    for (int64_t f = reloadAt; f < frames; ++f)
      out.maxStep = std::max(out.maxStep, render::rmse(out.r.images.at(f - 1), out.r.images.at(f)));
    return out;
  };
  const Run with = run(kMorph_s, "with"), without = run(0.0, "without");
  ASSERT_EQ(with.r.stats.size(), static_cast<size_t>(frames));
  ASSERT_EQ(without.r.stats.size(), static_cast<size_t>(frames));
  // The reload applied (the picture changed) early enough for the morph to finish before the end.
  int64_t applied = -1;
  for (int64_t f = reloadAt; f < frames && applied < 0; ++f)
    if (render::rmse(without.r.images.at(f - 1), without.r.images.at(f)) > 0.5) applied = f;
  ASSERT_GE(applied, reloadAt) << "the coarser tolerance was never applied";
  ASSERT_LT(applied, frames - 11) << "the reload thread was too slow for this test";
  EXPECT_GT(without.maxStep, 1.0) << "the coarsening must change the picture, or the test proves nothing";
  EXPECT_LT(with.maxStep, 0.4 * without.maxStep);  // measured: 0.98 against 3.95
  // After morph_s: the converged picture.
  EXPECT_LT(render::rmse(with.r.images.at(frames - 1), without.r.images.at(frames - 1)), 0.05);
}

// A fast climb (many merges in one frame): the first frame after it still draws the finer
// surface (ghosts), so it differs from the un-morphed one; after morph_s the picture is the
// converged one. (The picture before the climb is no reference: the climb itself changes it
// far more than any merge does.)
TEST(TerrainService, AClimbMorphsOutAndEndsConverged) {
  const Waypoint high{11.5 / 30.0, {0, -2500, 1500}, -30.0};
  const int64_t after = 12, mid = after + 4, done = after + 10;
  const SceneConfig withScene = roamScene(kMorph_s, TerrainLayerConfig::RoamMode::Deferred, 8.0);
  const SceneConfig withoutScene = roamScene(0.0, TerrainLayerConfig::RoamMode::Deferred, 8.0);
  const RunResult with = runPath(withScene, {kLow, high}, done + 1, {after - 1, after, mid, done}, "climb_with");
  const RunResult without = runPath(withoutScene, {kLow, high}, done + 1, {after - 1, after, mid, done}, "climb_without");
  EXPECT_LT(render::rmse(with.images.at(after - 1), without.images.at(after - 1)), 0.05);  // converged before
  const double first = render::rmse(with.images.at(after), without.images.at(after));
  EXPECT_GT(first, 1.0) << "the merged-away triangles must still be drawn right after the climb";  // measured: 4.0
  EXPECT_LT(render::rmse(with.images.at(mid), without.images.at(mid)), 0.9 * first);  // on the way (2.85)
  EXPECT_LT(render::rmse(with.images.at(done), without.images.at(done)), 0.05);
  // The climb leaves holes in the triangle slots; compaction brings the drawn range down with
  // the mesh (measured: 332 drawn triangles before, 264 after; 330 without compaction, which
  // kept the low view's high-water mark). Deterministic: fake clock, ROAM converged every frame.
  ASSERT_GT(with.stats.size(), static_cast<size_t>(done));
  const double before = std::stod(with.stats[after - 1].at("triangles")), end = std::stod(with.stats[done].at("triangles"));
  EXPECT_LT(end, 0.85 * before) << "drawn triangles before the climb " << before << ", after " << end;
}

namespace {
// A fake clock that calls `hook(n)` before the n-th frame of the service's life (counted from 0
// over every run: one sleep a frame).
class HookClock final : public Clock {
 public:
  explicit HookClock(std::function<void(int64_t)> hook) : hook_(std::move(hook)) {}
  int64_t now_ns() const override { return clock_.now_ns(); }
  void sleepUntil_ns(int64_t deadline_ns) override {
    clock_.sleepUntil_ns(deadline_ns);
    hook_(sleeps_++);
  }

 private:
  FakeClock clock_;
  std::function<void(int64_t)> hook_;
  int64_t sleeps_ = 0;
};
}  // namespace

// A second run() (tests run the service again; the replay restarts for it) starts its slot times
// at 0 again. The geomorphs started in the last frame of the first run (a descent: many splits)
// held start times near its end, so in the second run they stood still at their start heights
// (rewritten every frame) until its time caught up: morph_s after the start they must be done.
TEST(TerrainService, MorphsOfAFirstRunEndInASecondRun) {
  const int64_t frames = 24;
  ServiceConfig cfg;
  SceneConfig unused;
  test::defaultConfigs(cfg, unused);
  const auto dir = std::filesystem::temp_directory_path() / ("igd_terrain_gltest_rerun_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  cfg.frames = frames;
  cfg.rate_hz = 30;
  cfg.statsFile = (dir / "stats.csv").string();
  std::string error;
  auto service = Service::create(cfg, roamScene(kMorph_s, TerrainLayerConfig::RoamMode::Deferred, 1.0), error);
  ASSERT_TRUE(service) << error;
  auto at = [](const glm::dvec3& eye_m) {
    io::HostState s = test::defaultHostAt(0.0);
    s.eyeEnu_m = eye_m;
    s.heading_deg = 0.0;
    s.pitch_deg = -30.0;
    s.roll_deg = 0.0;
    return s;
  };
  service->mailbox().publish(at({0, -2500, 1500}));
  HookClock clock([&](int64_t frame) {
    if (frame == frames - 1) service->mailbox().publish(at(kLow.eye_m));  // the first run's last frame
  });
  std::atomic<bool> stop{false};
  ASSERT_EQ(service->run(clock, stop), 0);
  const std::vector<std::map<std::string, std::string>> first = test::readStatsCsv(cfg.statsFile);
  ASSERT_EQ(first.size(), static_cast<size_t>(frames));
  ASSERT_GT(std::stod(first.back().at("uploads")), 0.0) << "the descent must change the mesh";
  ASSERT_EQ(service->run(clock, stop), 0);
  const std::vector<std::map<std::string, std::string>> second = test::readStatsCsv(cfg.statsFile);
  ASSERT_EQ(second.size(), static_cast<size_t>(frames));
  EXPECT_GT(std::stod(second[0].at("uploads")), 0.0) << "the morphs go on in the second run";
  // morph_s = 9 frames: from frame 12 on the still eye's mesh is done.
  for (size_t f = 12; f < second.size(); ++f)
    EXPECT_EQ(second[f].at("uploads"), "0") << "frame " << f << " of the second run: morphs still running";
  service.reset();
  std::filesystem::remove_all(dir);
}

// A far plane that culls the whole terrain for a frame (thick fog, a host's View Definition)
// and then moves out again: the mesh drawn afterwards is whole, the picture the one a fresh
// service draws.
TEST(TerrainService, FarPlaneThatCulledEverythingLeavesNoHoles) {
  for (const auto mode : {TerrainLayerConfig::RoamMode::Deferred, TerrainLayerConfig::RoamMode::EnhMerge}) {
    SCOPED_TRACE(static_cast<int>(mode));
    const SceneConfig scene = roamScene(0.0, mode, 1.0);
    ServiceConfig cfg;
    SceneConfig unused;
    test::defaultConfigs(cfg, unused);
    cfg.width_px = 320;
    cfg.height_px = 180;
    std::string error;
    auto a = Service::create(cfg, scene, error);
    ASSERT_TRUE(a) << error;
    auto b = Service::create(cfg, scene, error);
    ASSERT_TRUE(b) << error;
    io::HostState h = test::defaultHostAt(0.0);
    h.eyeEnu_m = kLow.eye_m;
    h.heading_deg = 0.0;
    h.pitch_deg = -10.0;
    h.roll_deg = 0.0;
    h.far_m = 100000.0;
    render::Image first, again, fresh;
    a->renderOnce(h, &first);
    io::HostState shut = h;
    shut.far_m = 50.0;
    const FrameRecord r0 = a->renderOnce(shut, nullptr);
    EXPECT_EQ(r0.triangles, 0u);
    const FrameRecord ra = a->renderOnce(h, &again);
    const FrameRecord rb = b->renderOnce(h, &fresh);
    EXPECT_GT(ra.triangles, 0u);
    EXPECT_LT(render::fractionDifferent(again, fresh, 8), 0.001) << "triangles " << ra.triangles << " vs " << rb.triangles;
    EXPECT_LT(render::fractionDifferent(again, first, 8), 0.001);
  }
}
