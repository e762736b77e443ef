// The service with a live host link, using a scripted in-process link: accepted samples reach
// the frame loop and the recording; link loss is detected, reported per frame and cleared when
// the host returns; a synchronous link paces the frames; replaying the recording renders the
// same eyepoints. Real transports (CIGI, CAN, Modbus) have their own tests.
#include <gtest/gtest.h>

#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <mutex>
#include <thread>
#include <unistd.h>

#include "gl_fixture.h"
#include "ig/clock.h"
#include "io/replay.h"

using namespace ig;

namespace {

// A host that answers each Start of Frame: `script(frame)` says whether (and what) it sends.
// Publishing happens on the link's own thread, like a real transport.
class ScriptedLink final : public io::HostLink {
 public:
  using Script = std::function<bool(uint32_t igFrame, io::HostState& out)>;
  ScriptedLink(Script script, bool sync) : script_(std::move(script)), sync_(sync) {}
  ~ScriptedLink() override { stop(); }
  std::string_view name() const override { return "scripted"; }
  bool start(io::HostSink& sink, std::string&) override {
    sink_ = &sink;
    thread_ = std::thread([this] { run(); });
    return true;
  }
  void stop() override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
  }
  bool synchronous() const override { return sync_; }
  void frameStarted(const io::FrameStart& f) override {
    frameStarts.push_back(f);
    io::HostState s;
    if (!script_(f.igFrame, s)) return;
    ++counters_.received;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      queue_.push_back(s);
    }
    cv_.notify_all();
    // An asynchronous host's sample is in the mailbox before the next frame starts (the test
    // must not depend on thread timing); a synchronous frame loop waits for it by itself.
    if (!sync_) {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [&] { return queue_.empty() && !busy_; });
    }
  }
  std::vector<io::FrameStart> frameStarts;  // frame loop thread only

 private:
  void run() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      cv_.wait(lock, [&] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;
      const io::HostState s = queue_.front();
      queue_.erase(queue_.begin());
      busy_ = true;
      lock.unlock();
      ++counters_.accepted;
      sink_->publish(s);
      lock.lock();
      busy_ = false;
      cv_.notify_all();
    }
  }
  Script script_;
  bool sync_;
  io::HostSink* sink_ = nullptr;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<io::HostState> queue_;
  bool busy_ = false;
  bool stopping_ = false;
  std::thread thread_;
};

io::HostState stateFor(uint32_t frame) {
  io::HostState s = test::defaultHostAt(frame / 30.0);
  s.hostFrame = 1000 + frame;
  return s;
}

struct TempDir {
  std::filesystem::path path;
  explicit TempDir(const std::string& name)
      : path(std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()))) {
    std::filesystem::create_directories(path);
  }
  ~TempDir() { std::filesystem::remove_all(path); }
};

}  // namespace

TEST(HostInputGL, LiveSamplesAreRenderedRecordedAndReplayedIdentically) {
  TempDir dir("igd_host_input_gltest");
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  cfg.frames = 40;
  cfg.rate_hz = 30;
  cfg.statsFile = (dir.path / "live.csv").string();
  cfg.recordFile = (dir.path / "live.rec").string();
  cfg.snapshotFrames = {39};
  cfg.snapshotDir = (dir.path / "live").string();
  // Host sends on every other frame (15 Hz host, 30 Hz IG).
  auto link = std::make_unique<ScriptedLink>(
      [](uint32_t f, io::HostState& s) {
        if (f % 2 != 0) return false;
        s = stateFor(f);
        return true;
      },
      false);
  ScriptedLink* raw = link.get();
  std::string error;
  auto service = Service::create(cfg, scene, error, std::move(link));
  ASSERT_TRUE(service) << error;
  EXPECT_EQ(service->info().threads, 4u);  // render + link + recorder + snapshot writer
  FakeClock clock;
  std::atomic<bool> stop{false};
  ASSERT_EQ(service->run(clock, stop), 0);
  ASSERT_EQ(raw->frameStarts.size(), 40u);
  for (uint32_t f = 0; f < 40; ++f) EXPECT_EQ(raw->frameStarts[f].igFrame, f);
  // Frame f renders the sample sent at the Start of Frame of f-1 or f-2.
  const auto live = test::readStatsCsv(cfg.statsFile);
  ASSERT_EQ(live.size(), 40u);
  for (size_t f = 2; f < 40; ++f) {
    const uint64_t expected = 1000 + ((f - 1) & ~size_t{1});
    EXPECT_EQ(std::stoull(live[f].at("host_frame")), expected) << "frame " << f;
    EXPECT_EQ(live[f].at("host_lost"), "0");
  }
  EXPECT_EQ(raw->frameStarts[10].lastHostFrame, 1008u);

  io::Recording rec;
  ASSERT_TRUE(io::loadRecording(cfg.recordFile, rec, error)) << error;
  ASSERT_EQ(rec.samples.size(), 20u);
  for (size_t i = 0; i < rec.samples.size(); ++i) {
    EXPECT_EQ(rec.samples[i].state.hostFrame, 1000 + 2 * i);
    // Stamped at the Start of Frame it answered: slot 2i of the 30 Hz loop.
    EXPECT_NEAR(rec.samples[i].t_s, 2.0 * static_cast<double>(i) / 30.0, 1e-6);
  }

  // Replay it twice: the same host frame and eyepoint on every frame, and identical images.
  std::vector<std::vector<std::map<std::string, std::string>>> replays;
  std::vector<render::Image> images;
  for (int run = 0; run < 2; ++run) {
    ServiceConfig rc = cfg;
    rc.host = HostSource::Replay;
    rc.replayFile = cfg.recordFile;
    rc.recordFile = "";
    rc.statsFile = (dir.path / ("replay" + std::to_string(run) + ".csv")).string();
    rc.snapshotDir = (dir.path / ("replay" + std::to_string(run))).string();
    auto replay = Service::create(rc, scene, error);
    ASSERT_TRUE(replay) << error;
    FakeClock c2;
    ASSERT_EQ(replay->run(c2, stop), 0);
    replays.push_back(test::readStatsCsv(rc.statsFile));
    render::Image img;
    ASSERT_TRUE(render::readPng(rc.snapshotDir + "/frame_000039.png", img, error)) << error;
    images.push_back(std::move(img));
  }
  for (size_t f = 1; f < 40; ++f) {
    // Live frame f saw the sample sent at frame f-1 (odd f) or f-2; the replay feeds the
    // sample stamped at or before the slot: the one sent at f or f-1. One frame earlier.
    const auto& r0 = replays[0][f];
    EXPECT_EQ(r0.at("host_frame"), replays[1][f].at("host_frame"));
    EXPECT_EQ(r0.at("eye_east_m"), replays[1][f].at("eye_east_m"));
    EXPECT_EQ(std::stoull(r0.at("host_frame")), 1000 + (f & ~size_t{1})) << "frame " << f;
  }
  ASSERT_EQ(images[0].rgba.size(), images[1].rgba.size());
  EXPECT_TRUE(images[0].rgba == images[1].rgba) << "replays of one recording must be bit-identical";
}

TEST(HostInputGL, LinkLossIsReportedAndClearsWhenTheHostReturns) {
  TempDir dir("igd_link_loss_gltest");
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  cfg.frames = 90;
  cfg.rate_hz = 30;
  cfg.linkTimeout_s = 0.5;
  cfg.statsFile = (dir.path / "stats.csv").string();
  // The host talks for frames 0..29, is silent for 30..59, talks again from 60.
  auto link = std::make_unique<ScriptedLink>(
      [](uint32_t f, io::HostState& s) {
        if (f >= 30 && f < 60) return false;
        s = stateFor(f);
        return true;
      },
      false);
  ScriptedLink* raw = link.get();
  std::string error;
  auto service = Service::create(cfg, scene, error, std::move(link));
  ASSERT_TRUE(service) << error;
  FakeClock clock;
  std::atomic<bool> stop{false};
  ASSERT_EQ(service->run(clock, stop), 0);
  const auto rows = test::readStatsCsv(cfg.statsFile);
  ASSERT_EQ(rows.size(), 90u);
  // Last sample stamped at frame 29 (0.967 s); lost once more than 0.5 s passed: from frame
  // 45 (1.5 s) on, until the frame after the host's return at frame 60.
  for (size_t f = 0; f < 90; ++f) {
    const bool lost = f >= 45 && f <= 60;
    EXPECT_EQ(rows[f].at("host_lost"), lost ? "1" : "0") << "frame " << f;
    EXPECT_EQ(raw->frameStarts[f].hostLost, lost) << "frame " << f;
  }
  // The eyepoint held still while lost.
  EXPECT_EQ(rows[44].at("eye_east_m"), rows[59].at("eye_east_m"));
  EXPECT_EQ(std::stoull(rows[59].at("host_frame")), 1029u);
  EXPECT_EQ(std::stoull(rows[89].at("host_frame")), 1088u);
}

TEST(HostInputGL, SynchronousHostPacesTheFrames) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  cfg.frames = 20;
  cfg.rate_hz = 2;  // fallback pace when the host is silent: 0.5 s per frame
  TempDir dir("igd_sync_gltest");
  cfg.statsFile = (dir.path / "stats.csv").string();
  // Synchronous: the host answers each Start of Frame; the next frame waits for that answer.
  auto link = std::make_unique<ScriptedLink>(
      [](uint32_t f, io::HostState& s) {
        s = stateFor(f);
        return true;
      },
      true);
  std::string error;
  auto service = Service::create(cfg, scene, error, std::move(link));
  ASSERT_TRUE(service) << error;
  MonotonicClock clock;
  std::atomic<bool> stop{false};
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_EQ(service->run(clock, stop), 0);
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const auto rows = test::readStatsCsv(cfg.statsFile);
  ASSERT_EQ(rows.size(), 20u);
  // Every frame after the first renders the answer to the previous frame's Start of Frame.
  for (size_t f = 1; f < 20; ++f) EXPECT_EQ(std::stoull(rows[f].at("host_frame")), 1000 + f - 1) << "frame " << f;
  // Host-paced, not slot-paced: 20 frames at 2 Hz slots would take 9.5 s.
  EXPECT_LT(elapsed_s, 6.0);
}

// Synchronous host: the loop waits (up to a period) for the host's message *before* each frame
// (docs/cigi.md). The wait is not the frame's work: counted in it, every frame of a silent host
// was an overrun (work > period), the governor saw frames as slow as the period and the host was
// told "the previous frame overran" (IG Status 2). With a silent host every wait lasts a full
// period: the idle time between the end of one frame and the start of the next is at least a
// period (the condition variable waits at least its timeout on the monotonic clock).
TEST(HostInputGL, WaitingForASynchronousHostIsNotFrameWork) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  scene.terrain.reset();  // sky only: short frames
  cfg.frames = 4;
  cfg.rate_hz = 20;  // a silent host costs a 50 ms wait per frame
  TempDir dir("igd_sync_wait_gltest");
  cfg.statsFile = (dir.path / "stats.csv").string();
  auto link = std::make_unique<ScriptedLink>([](uint32_t, io::HostState&) { return false; }, true);
  std::string error;
  auto service = Service::create(cfg, scene, error, std::move(link));
  ASSERT_TRUE(service) << error;
  MonotonicClock clock;
  std::atomic<bool> stop{false};
  ASSERT_EQ(service->run(clock, stop), 0);
  const auto rows = test::readStatsCsv(cfg.statsFile);
  ASSERT_EQ(rows.size(), 4u);
  const double period_ms = 50.0;
  for (size_t f = 1; f < rows.size(); ++f) {
    const double idle_ms = std::stod(rows[f].at("t_ms")) - std::stod(rows[f - 1].at("t_ms")) -
                           std::stod(rows[f - 1].at("work_ms"));
    EXPECT_GE(idle_ms, period_ms - 0.01) << "frame " << f << ": the wait for the host is inside frame " << f - 1
                                         << " (input_ms " << rows[f - 1].at("input_ms") << ", work_ms "
                                         << rows[f - 1].at("work_ms") << ", overrun " << rows[f - 1].at("overrun")
                                         << ")";
  }
}

TEST(HostInputGL, RecordFileThatCannotBeWrittenIsNamed) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  cfg.recordFile = "/nonexistent-dir/x.rec";
  auto link = std::make_unique<ScriptedLink>([](uint32_t, io::HostState&) { return false; }, false);
  std::string error;
  EXPECT_FALSE(Service::create(cfg, scene, error, std::move(link)));
  EXPECT_NE(error.find("host.record_file '/nonexistent-dir/x.rec': cannot write"), std::string::npos) << error;
}

TEST(HostInputGL, HostTimeOfDayDrivesTheSun) {
  ServiceConfig cfg;
  SceneConfig scene;
  test::defaultConfigs(cfg, scene);
  std::string error;
  auto service = Service::create(cfg, scene, error);
  ASSERT_TRUE(service) << error;
  const auto meanLuma = [&](double tod_h, int32_t date) {
    io::HostState h = test::defaultHostAt(5.0);
    h.timeOfDay_h = tod_h;
    h.dateYmd = date;
    render::Image img;
    service->renderOnce(h, &img);
    double sum = 0;
    for (size_t i = 0; i < img.rgba.size(); i += 4) sum += img.rgba[i] + img.rgba[i + 1] + img.rgba[i + 2];
    return sum / static_cast<double>(img.rgba.size() / 4 * 3);
  };
  // The default scene sits at 46.5 N, 7.9 E (UTC+0:32 solar): noon is bright, midnight dark,
  // and no time of day keeps the scene's own sun.
  const double noon = meanLuma(11.5, 20260621), midnight = meanLuma(23.5, 20260621);
  const double sceneSun = meanLuma(-1.0, 0);
  EXPECT_GT(noon, 4.0 * midnight) << noon << " vs " << midnight;
  EXPECT_GT(noon, 60.0);
  EXPECT_LT(midnight, 30.0);
  EXPECT_GT(sceneSun, 60.0);
  // Winter noon is lower in the sky than summer noon: less light on the ground.
  EXPECT_LT(meanLuma(11.5, 20261221), noon);
}
