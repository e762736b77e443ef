// Reload planning (which changed keys apply between frames), the status report and the
// real-time settings of the render thread.
#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <cstdlib>
#include <limits>
#include <sstream>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include "ig/clock.h"
#include "ig/host_input.h"
#include "ig/realtime.h"
#include "ig/reload.h"
#include "ig/status.h"
#include "ig/systemd.h"
#include "io/replay.h"

namespace {

bool has(const std::vector<std::string>& v, const std::string& key) {
  return std::find(v.begin(), v.end(), key) != v.end();
}

struct Configs {
  ig::ServiceConfig c;
  ig::SceneConfig s;
  Configs() { s.terrain.emplace(); }
};

TEST(Reload, NothingChangedAppliesNothing) {
  Configs run, next;
  ig::ServiceConfig mc;
  ig::SceneConfig ms;
  const ig::ReloadPlan p = ig::planReload(run.c, run.s, next.c, next.s, mc, ms);
  EXPECT_TRUE(p.applied.empty());
  EXPECT_TRUE(p.needRestart.empty());
  EXPECT_TRUE(mc == run.c);
  EXPECT_TRUE(ms == run.s);
}

TEST(Reload, ReloadableKeysAreTakenOthersKept) {
  Configs run, next;
  run.c.snapshotEvery = 60;
  next.c.snapshotEvery = 10;
  next.c.budgetFrame_ms = 20.0;
  next.c.linkTimeout_s = 3.0;
  next.s.fog.visibility_m = 3000.0;
  next.s.terrain->tolerance_px = 2.5;
  next.c.width_px = 640;          // needs a restart
  next.c.rate_hz = 50.0;          // needs a restart
  next.c.msaa = 4;                // needs a restart (named, not "other keys")
  next.c.fullscreen = true;       // needs a restart (the window is made at start-up)
  next.c.monitor = 1;             // needs a restart
  next.s.terrain->seed = 99;      // terrain data: needs a restart
  ig::ServiceConfig mc;
  ig::SceneConfig ms;
  const ig::ReloadPlan p = ig::planReload(run.c, run.s, next.c, next.s, mc, ms);
  EXPECT_TRUE(has(p.applied, "output.snapshot_every"));
  EXPECT_TRUE(has(p.applied, "budget.frame_ms"));
  EXPECT_TRUE(has(p.applied, "host.link_timeout_s"));
  EXPECT_TRUE(has(p.applied, "scene.fog"));
  EXPECT_TRUE(has(p.applied, "scene.terrain.tolerance_px"));
  EXPECT_TRUE(has(p.needRestart, "output.width_px"));
  EXPECT_TRUE(has(p.needRestart, "frame.rate_hz"));
  EXPECT_TRUE(has(p.needRestart, "output.msaa"));
  EXPECT_TRUE(has(p.needRestart, "output.fullscreen"));
  EXPECT_TRUE(has(p.needRestart, "output.monitor"));
  EXPECT_FALSE(mc.fullscreen);
  EXPECT_EQ(mc.msaa, run.c.msaa);
  EXPECT_TRUE(has(p.needRestart, "scene.terrain (data, lod, size or placement)"));
  EXPECT_EQ(mc.snapshotEvery, 10);
  EXPECT_EQ(mc.budgetFrame_ms, 20.0);
  EXPECT_EQ(ms.fog.visibility_m, 3000.0);
  EXPECT_EQ(ms.terrain->tolerance_px, 2.5);
  EXPECT_EQ(mc.width_px, run.c.width_px);   // running value kept
  EXPECT_EQ(mc.rate_hz, run.c.rate_hz);
  EXPECT_EQ(ms.terrain->seed, run.s.terrain->seed);
}

TEST(Reload, SnapshotsCannotBeSwitchedOnWithoutARestart) {
  Configs run, next;
  next.c.snapshotEvery = 5;  // the snapshot thread does not exist
  ig::ServiceConfig mc;
  ig::SceneConfig ms;
  const ig::ReloadPlan p = ig::planReload(run.c, run.s, next.c, next.s, mc, ms);
  EXPECT_FALSE(has(p.applied, "output.snapshot_every"));
  EXPECT_EQ(p.needRestart.size(), 1u);
  EXPECT_EQ(mc.snapshotEvery, 0);
}

// Snapshots on at start-up, switched off by one reload: a later reload may switch them on again
// (igd.toml: snapshot_every reloads "if snapshots were on at start-up"); never on at start-up, not.
TEST(Reload, SnapshotsOnAtStartUpCanBeSwitchedOnAgain) {
  Configs run, next;
  next.c.snapshotEvery = 5;  // the running config has none: an earlier reload switched them off
  ig::ServiceConfig mc;
  ig::SceneConfig ms;
  ig::ReloadPlan p = ig::planReload(run.c, run.s, next.c, next.s, mc, ms, true);
  EXPECT_TRUE(has(p.applied, "output.snapshot_every"));
  EXPECT_TRUE(p.needRestart.empty());
  EXPECT_EQ(mc.snapshotEvery, 5);
  p = ig::planReload(run.c, run.s, next.c, next.s, mc, ms, false);
  EXPECT_FALSE(has(p.applied, "output.snapshot_every"));
  EXPECT_EQ(mc.snapshotEvery, 0);
}

TEST(Reload, AddingALayerNeedsARestart) {
  Configs run, next;
  run.s.terrain.reset();
  ig::ServiceConfig mc;
  ig::SceneConfig ms;
  const ig::ReloadPlan p = ig::planReload(run.c, run.s, next.c, next.s, mc, ms);
  EXPECT_TRUE(has(p.needRestart, "scene.terrain (added or removed)"));
  EXPECT_FALSE(ms.terrain.has_value());
}

std::string slurp(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

TEST(Status, ReportCoversTheIntervalAndReplacesTheFile) {
  const auto dir = std::filesystem::temp_directory_path() / ("igd_status_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string file = (dir / "status.json").string();
  ig::StatusReporter r(file, 1.0, 10.0);
  r.start(0);
  for (int i = 0; i < 10; ++i) {
    ig::FrameTiming t;
    t.frame = i;
    t.work_ms = i == 9 ? 90.0 : 5.0 + i;  // one slow frame
    t.overrun = i == 9;
    t.phase_ms[static_cast<size_t>(ig::Phase::Lod)] = 1.0 + i;
    r.addFrame(t, 1000);
  }
  EXPECT_FALSE(r.due(999'999'999));
  EXPECT_TRUE(r.due(1'000'000'000));
  ig::StatusContext ctx;
  ctx.rate_hz = 10.0;
  ctx.budgetFrame_ms = 100.0;
  ctx.hostSource = "cigi";
  ctx.hostLost = true;
  ctx.lastReloadError = "scene.toml:3: fog.visibility_m = -5: \"must be > 0\"";
  const std::string line = r.report(1'000'000'000, ctx);
  EXPECT_NE(line.find("frame 9"), std::string::npos) << line;
  EXPECT_NE(line.find("overruns 1 (1 in last 1.0 s)"), std::string::npos) << line;
  EXPECT_NE(line.find("host cigi LOST"), std::string::npos) << line;
  const std::string json = slurp(file);
  EXPECT_EQ(json, r.json());
  EXPECT_NE(json.find("\"work_ms_max\":90.000"), std::string::npos) << json;
  EXPECT_NE(json.find("\"work_ms_p50\":9.000"), std::string::npos) << json;
  EXPECT_NE(json.find("\"lod\":10.000"), std::string::npos) << json;
  EXPECT_NE(json.find("\\\"must be > 0\\\""), std::string::npos) << "quotes escaped: " << json;
  EXPECT_EQ(json.find("hat_hot"), std::string::npos) << "no HAT/HOT counters from a link without them: " << json;
  EXPECT_FALSE(std::filesystem::exists(file + ".tmp"));
  // The next interval starts empty.
  ctx.haveLink = true;
  ctx.link.received = 7;
  ctx.haveHatHot = true;
  ctx.hatHot = {6, 5, 1, 2, 4, 3, 1, 7};
  r.report(2'000'000'000, ctx);
  EXPECT_NE(r.json().find("\"dropped\":0},\"hat_hot\":{\"requests\":6,\"answered\":5,\"refused\":1,\"deferred\":2},"
                          "\"los\":{\"requests\":4,\"answered\":3,\"refused\":1,\"deferred\":7}},"),
            std::string::npos)
      << "HAT/HOT and LOS counters in \"host\", after \"link\": " << r.json();
  EXPECT_NE(r.json().find("\"interval\":{\"seconds\":1.000,\"frames\":0"), std::string::npos) << r.json();
  EXPECT_NE(r.json().find("\"frames\":10,\"overruns\":1"), std::string::npos) << r.json();
  EXPECT_NE(r.json().find("\"governor\":null"), std::string::npos) << r.json();
  EXPECT_EQ(r.report(3'000'000'000, ctx).find("detail"), std::string::npos);
  // With the governor: the detail it gives each layer the scene has, in the line and the file.
  ctx.haveGovernor = true;
  ctx.terrainTolerance_px = 4.0;
  ctx.forestNear_m = std::numeric_limits<double>::quiet_NaN();  // no [forest]
  ctx.hdlodTolerance_px = std::numeric_limits<double>::quiet_NaN();
  ctx.cellsVoxelBudget = 12000.0;
  ctx.forestLayers = std::numeric_limits<double>::quiet_NaN();
  ctx.governorDecreases = 3;
  const std::string governed = r.report(4'000'000'000, ctx);
  EXPECT_NE(governed.find("; detail: terrain 4.00 px, cells 12000 voxels"), std::string::npos) << governed;
  EXPECT_NE(r.json().find("\"governor\":{\"terrain_tolerance_px\":4.000,\"forest_near_m\":null,"
                          "\"hdlod_tolerance_px\":null,\"cells_voxel_budget\":12000.000,\"forest_layers\":null,\"decreases\":3,"),
            std::string::npos)
      << r.json();
  std::filesystem::remove_all(dir);
}

// A reload that changes service.status_file or status_interval_s reconfigures the reporter: the
// totals (frames, overruns) must not restart at 0.
TEST(Status, ReconfigureKeepsTheTotals) {
  ig::StatusReporter r("", 1.0, 10.0);
  r.start(0);
  for (int i = 0; i < 10; ++i) {
    ig::FrameTiming t;
    t.frame = i;
    t.work_ms = 5.0;
    t.overrun = i == 3;
    r.addFrame(t, 100);
  }
  r.report(1'000'000'000, ig::StatusContext{});
  r.reconfigure("", 0.5, 10.0);
  EXPECT_FALSE(r.due(1'400'000'000));
  EXPECT_TRUE(r.due(1'500'000'000));
  ig::FrameTiming t;
  t.frame = 10;
  r.addFrame(t, 100);
  r.report(1'500'000'000, ig::StatusContext{});
  EXPECT_NE(r.json().find("\"frames\":11,\"overruns\":1"), std::string::npos) << r.json();
  // A reporter created after frames ran (a reload switched it on) starts from the given totals.
  ig::StatusReporter late("", 1.0, 10.0);
  late.setTotals(500, 7, 2);
  late.start(0);
  late.addFrame(t, 100);
  late.report(1'000'000'000, ig::StatusContext{});
  EXPECT_NE(late.json().find("\"frames\":501,\"overruns\":7,\"missed_slots\":2"), std::string::npos) << late.json();
}

// A reload that moves the status file removes the old one (it would say "running" forever).
TEST(Status, ReconfigureToAnotherFileRemovesTheOldOne) {
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("igd_status_move_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string a = (dir / "a.json").string(), b = (dir / "b.json").string();
  ig::StatusReporter r(a, 1.0, 10.0);
  r.start(0);
  ig::FrameTiming t;
  r.addFrame(t, 100);
  r.report(1'000'000'000, ig::StatusContext{});
  EXPECT_TRUE(std::filesystem::exists(a));
  r.reconfigure(b, 1.0, 10.0);
  EXPECT_FALSE(std::filesystem::exists(a));
  r.addFrame(t, 100);
  r.report(2'000'000'000, ig::StatusContext{});
  EXPECT_TRUE(std::filesystem::exists(b));
  r.reconfigure(b, 0.5, 10.0);  // the same file: kept
  EXPECT_TRUE(std::filesystem::exists(b));
  std::filesystem::remove_all(dir);
}

// service.watchdog_interval_s not below systemd's WatchdogSec would let systemd kill igd between
// two pings: half of WatchdogSec is used instead, and the log says so.
TEST(Systemd, WatchdogIntervalNotBelowWatchdogSecIsReplaced) {
  ::setenv("WATCHDOG_USEC", "2000000", 1);
  ::setenv("WATCHDOG_PID", std::to_string(::getpid()).c_str(), 1);
  const ig::SystemdNotifier tooLong(5.0);
  const ig::SystemdNotifier fine(0.5);
  const ig::SystemdNotifier automatic(0.0);
  ::unsetenv("WATCHDOG_USEC");
  ::unsetenv("WATCHDOG_PID");
  EXPECT_EQ(tooLong.watchdogInterval_ns(), 1'000'000'000);
  EXPECT_NE(tooLong.warning().find("service.watchdog_interval_s = 5"), std::string::npos) << tooLong.warning();
  EXPECT_NE(tooLong.warning().find("WatchdogSec (2 s)"), std::string::npos) << tooLong.warning();
  EXPECT_EQ(fine.watchdogInterval_ns(), 500'000'000);
  EXPECT_TRUE(fine.warning().empty()) << fine.warning();
  EXPECT_EQ(automatic.watchdogInterval_ns(), 1'000'000'000);
  EXPECT_TRUE(automatic.warning().empty());
}

// A free-running loop (--free-run) or a host that paces the frames faster than the configured
// rate runs more frames in an interval than the reporter's buffer holds (4 intervals at the
// rate): the percentiles may come from the frames kept, but the interval's maximum must cover
// every frame, or a slow frame late in the interval goes unreported.
TEST(Status, WorkMaxCoversEveryFrameOfTheInterval) {
  ig::StatusReporter r("", 1.0, 10.0);  // room for about 4 x 10 frames
  r.start(0);
  for (int i = 0; i < 200; ++i) {
    ig::FrameTiming t;
    t.frame = i;
    t.work_ms = i == 199 ? 90.0 : 5.0;
    t.phase_ms[static_cast<size_t>(ig::Phase::Lod)] = t.work_ms;
    r.addFrame(t, 100);
  }
  r.report(1'000'000'000, ig::StatusContext{});
  EXPECT_NE(r.json().find("\"frames\":200,"), std::string::npos) << r.json();
  EXPECT_NE(r.json().find("\"lod\":90.000"), std::string::npos) << r.json();
  EXPECT_NE(r.json().find("\"work_ms_max\":90.000"), std::string::npos) << r.json();
  // The next interval's maximum starts again.
  ig::FrameTiming t;
  t.frame = 200;
  t.work_ms = 4.0;
  r.addFrame(t, 100);
  r.report(2'000'000'000, ig::StatusContext{});
  EXPECT_NE(r.json().find("\"work_ms_max\":4.000"), std::string::npos) << r.json();
}

// [service] status_interval_s = 3600 at frame.rate_hz = 1000 (both allowed): the reporter kept
// every frame's work time of 4 intervals, twice (230 MB, locked with lock_memory). Its memory is
// bounded now, and the interval's percentiles still cover every frame of it.
TEST(Status, MemoryIsBoundedAtTheHighestRateAndLongestInterval) {
  ig::StatusReporter r("", 3600.0, 1000.0);
  EXPECT_LT(r.reservedBytes(), size_t{2} << 20);
  r.reconfigure("", 3600.0, 1000.0);
  EXPECT_LT(r.reservedBytes(), size_t{2} << 20);
}

// More frames in an interval than the reporter keeps exactly: p50 and p99 are those of every
// frame of the interval (before, those of the first frames kept: the slow second half of the
// interval was missing from both).
TEST(Status, PercentilesCoverEveryFrameBeyondTheFramesKept) {
  ig::StatusReporter r("", 1.0, 10.0);  // keeps about 4 x 10 frames exactly
  r.start(0);
  // 96 frames of 5 ms, then 300 of 12 ms and 4 of 250 ms (the 1 % above the p99).
  int64_t frame = 0;
  auto add = [&](int n, double ms) {
    for (int i = 0; i < n; ++i) {
      ig::FrameTiming t;
      t.frame = frame++;
      t.work_ms = ms;
      r.addFrame(t, 100);
    }
  };
  add(96, 5.0);
  add(300, 12.0);
  add(4, 250.0);
  r.report(1'000'000'000, ig::StatusContext{});
  EXPECT_NE(r.json().find("\"frames\":400,"), std::string::npos) << r.json();
  EXPECT_NE(r.json().find("\"work_ms_p50\":12.000,\"work_ms_p99\":12.000,\"work_ms_max\":250.000"), std::string::npos)
      << r.json();
  add(392, 3.0);
  add(8, 40.0);  // 2 %: the p99
  r.report(2'000'000'000, ig::StatusContext{});
  EXPECT_NE(r.json().find("\"work_ms_p50\":3.000,\"work_ms_p99\":40.000,\"work_ms_max\":40.000"), std::string::npos)
      << r.json();
  // Within 0.1 % for values that do not fall on the histogram's bins.
  add(1000, 7.654321);
  r.report(3'000'000'000, ig::StatusContext{});
  const size_t at = r.json().find("\"work_ms_p50\":");
  ASSERT_NE(at, std::string::npos);
  EXPECT_NEAR(std::stod(r.json().substr(at + 14)), 7.654321, 7.654321e-3) << r.json();
  // An interval within the frames kept is exact.
  add(10, 7.654321);
  r.report(4'000'000'000, ig::StatusContext{});
  EXPECT_NE(r.json().find("\"work_ms_p50\":7.654,"), std::string::npos) << r.json();
}

// service.watchdog_interval_s accepts any value in 0 ..= 3600: a tiny one (below a nanosecond)
// must ping at every call, not switch the watchdog off (systemd would then kill igd after
// WatchdogSec).
TEST(Systemd, ATinyWatchdogIntervalStillPings) {
  ::setenv("WATCHDOG_USEC", "2000000", 1);
  ::setenv("WATCHDOG_PID", std::to_string(::getpid()).c_str(), 1);
  ig::SystemdNotifier tiny(1e-10);
  ::unsetenv("WATCHDOG_USEC");
  ::unsetenv("WATCHDOG_PID");
  EXPECT_TRUE(tiny.watchdogEnabled()) << tiny.watchdogInterval_ns();
  EXPECT_GT(tiny.watchdogInterval_ns(), 0);
  EXPECT_TRUE(tiny.watchdog(1'000'000'000));
  EXPECT_TRUE(tiny.watchdog(1'000'000'001));
}

// WATCHDOG_USEC is parsed by libsystemd as any value below 2^64 - 1: a huge one (garbage, or a
// watchdog of centuries) must not overflow the nanosecond interval (signed overflow, and a
// negative interval switched the watchdog off).
TEST(Systemd, AHugeWatchdogUsecDoesNotOverflow) {
  ::setenv("WATCHDOG_USEC", "100000000000000000", 1);  // 1e17 us: 1e20 ns is beyond int64_t
  ::setenv("WATCHDOG_PID", std::to_string(::getpid()).c_str(), 1);
  ig::SystemdNotifier huge(0.0);
  const ig::SystemdNotifier withInterval(0.5);
  ::unsetenv("WATCHDOG_USEC");
  ::unsetenv("WATCHDOG_PID");
  EXPECT_TRUE(huge.watchdogEnabled()) << huge.watchdogInterval_ns();
  EXPECT_GT(huge.watchdogInterval_ns(), 1'000'000'000'000'000'000) << huge.watchdogInterval_ns();
  EXPECT_TRUE(huge.watchdog(0));  // the first call pings
  EXPECT_EQ(withInterval.watchdogInterval_ns(), 500'000'000);
  EXPECT_TRUE(withInterval.warning().empty()) << withInterval.warning();
}

TEST(Status, UnwritableFileIsReportedNotFatal) {
  // Below a regular file: no folder can be made there, not even by root.
  const auto dir = std::filesystem::temp_directory_path() / ("igd_status_file_" + std::to_string(::getpid()));
  { std::ofstream(dir.string()) << "x"; }
  const std::string path = (dir / "status.json").string();
  ig::StatusReporter r(path, 1.0, 10.0);
  r.start(0);
  const std::string line = r.report(1'000'000'000, ig::StatusContext{});
  EXPECT_FALSE(line.empty());
  EXPECT_NE(r.fileError().find(path), std::string::npos) << r.fileError();
  std::filesystem::remove(dir);
}

// The report's folder is made when missing (as the stats' and the snapshots' are), and a knob
// that is not finite is null: JSON has no inf (written as "inf", the file did not parse).
TEST(Status, MissingFolderIsMadeAndNonFiniteKnobsAreNull) {
  const auto dir = std::filesystem::temp_directory_path() / ("igd_status_new_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  const std::string file = (dir / "run" / "status.json").string();
  ig::StatusReporter r(file, 1.0, 10.0);
  r.start(0);
  ig::StatusContext ctx;
  ctx.haveGovernor = true;
  ctx.terrainTolerance_px = std::numeric_limits<double>::infinity();
  ctx.forestNear_m = -std::numeric_limits<double>::infinity();
  ctx.hdlodTolerance_px = 2.0;
  (void)r.report(1'000'000'000, ctx);
  EXPECT_EQ(r.fileError(), "");
  const std::string json = slurp(file);
  EXPECT_EQ(json, r.json());
  EXPECT_NE(json.find("\"terrain_tolerance_px\":null"), std::string::npos) << json;
  EXPECT_NE(json.find("\"forest_near_m\":null"), std::string::npos) << json;
  EXPECT_NE(json.find("\"hdlod_tolerance_px\":2.000"), std::string::npos) << json;
  EXPECT_EQ(json.find("inf"), std::string::npos) << json;
  EXPECT_FALSE(std::filesystem::exists(file + ".tmp"));
  std::filesystem::remove_all(dir);
}

TEST(Realtime, AffinityToOneCpuAndBack) {
  ig::RealtimeSettings s;
  s.cpus = {0};
  std::string error;
  ASSERT_TRUE(ig::applyRealtime(s, error)) << error;
  EXPECT_NE(ig::describeScheduling().find("CPUs 0"), std::string::npos) << ig::describeScheduling();
  ig::normalScheduling();
  EXPECT_EQ(ig::describeScheduling().find("CPUs 0,"), std::string::npos);
}

TEST(Realtime, UnknownCpuIsNamed) {
  ig::RealtimeSettings s;
  s.cpus = {0, 1000};
  std::string error;
  EXPECT_FALSE(ig::applyRealtime(s, error));
  EXPECT_NE(error.find("service.cpu_affinity = [0, 1000]"), std::string::npos) << error;
  EXPECT_NE(error.find("CPU 1000"), std::string::npos) << error;
}

TEST(Realtime, FifoPriorityAppliesOrSaysWhyNot) {
  ig::RealtimeSettings s;
  s.priority = 5;
  std::string error;
  if (ig::applyRealtime(s, error)) {
    EXPECT_NE(ig::describeScheduling().find("SCHED_FIFO 5"), std::string::npos);
    ig::normalScheduling();
    EXPECT_NE(ig::describeScheduling().find("SCHED_OTHER"), std::string::npos);
  } else {
    EXPECT_NE(error.find("service.realtime_priority = 5"), std::string::npos) << error;
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// HostInput's recorder times (ig/host_input.h): samples published before the frame loop starts
// (a host already streaming while igd starts up) are stamped 0, and samples published after
// setTimeBase count from the loop's start, so that replaying the recording feeds each frame
// the sample it had live.
TEST(HostInputRecorder, SamplesBeforeTheLoopGetZeroAndLoopTimesAreKept) {
  const std::string file =
      (std::filesystem::temp_directory_path() / ("igd_host_input_rec_" + std::to_string(::getpid()) + ".rec")).string();
  ig::io::LatestValueMailbox<ig::io::HostState> mailbox;
  ig::FakeClock startClock(1'000'000'000);
  ig::HostInput input(mailbox, startClock);
  std::string error;
  ASSERT_TRUE(input.start(nullptr, file, 1.0, error)) << error;
  ig::io::HostState s;
  // The host streams at 10 Hz during a 2 s start-up (warm-up frame, shader compiles ...).
  for (int i = 0; i < 20; ++i) {
    s.hostFrame = static_cast<uint64_t>(i);
    input.publish(s);
    startClock.advance_ns(100'000'000);
  }
  // The frame loop starts; its clock is the same monotonic time base.
  ig::FakeClock loopClock(startClock.now_ns());
  input.setTimeBase(loopClock, loopClock.now_ns());
  for (int i = 20; i < 40; ++i) {
    s.hostFrame = static_cast<uint64_t>(i);
    input.publish(s);
    loopClock.advance_ns(100'000'000);
  }
  input.stop();
  ig::io::Recording rec;
  ASSERT_TRUE(ig::io::loadRecording(file, rec, error)) << error;
  std::filesystem::remove(file);
  ASSERT_EQ(rec.samples.size(), 40u);
  for (size_t i = 0; i < 20; ++i) EXPECT_EQ(rec.samples[i].t_s, 0.0) << "pre-loop sample " << i;
  for (size_t i = 20; i < 40; ++i)
    EXPECT_NEAR(rec.samples[i].t_s, 0.1 * static_cast<double>(i - 20), 1e-6) << "loop sample " << i;
  // Replay frame 0 (t = 0) renders the newest pre-loop sample, as the live frame 0 did.
  EXPECT_EQ(ig::io::sampleAt(rec, 0.0).state.hostFrame, 20u);
}

// A recording that cannot be written fails at start-up with an error naming the file, instead
// of running for hours into a file that stays empty. /dev/full fails every write with ENOSPC.
TEST(HostInputRecorder, AFileThatCannotBeWrittenFailsAtOpen) {
  ASSERT_TRUE(std::filesystem::exists("/dev/full"));  // Linux always has it
  ig::HostRecorder rec;
  std::string error;
  EXPECT_FALSE(rec.open("/dev/full", error));
  EXPECT_NE(error.find("/dev/full"), std::string::npos) << error;
  ig::io::LatestValueMailbox<ig::io::HostState> mailbox;
  ig::FakeClock clock;
  ig::HostInput input(mailbox, clock);
  error.clear();
  EXPECT_FALSE(input.start(nullptr, "/dev/full", 1.0, error));
  EXPECT_NE(error.find("host.record_file"), std::string::npos) << error;
}

// A link that binds a UDP port on 127.0.0.1 when it starts (like the CIGI link) and publishes
// one sample from start() itself, before start() returns.
class UdpPortLink final : public ig::io::HostLink {
 public:
  explicit UdpPortLink(uint16_t port) : port_(port) {}
  ~UdpPortLink() override { stop(); }
  std::string_view name() const override { return "udp"; }
  bool start(ig::io::HostSink& sink, std::string& error) override {
    fd_ = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(port_);
    if (fd_ < 0 || bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
      error = "cannot bind 127.0.0.1:" + std::to_string(port_) + ": " + std::strerror(errno);
      stop();
      return false;
    }
    ig::io::HostState s;
    s.hostFrame = 4711;
    sink.publish(s);
    return true;
  }
  void stop() override {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  uint16_t port_;
  int fd_ = -1;
};

// igd started while the port of its host link is in use fails at start-up; the recording of
// the previous run (same record_file) must still be there: the file is created only once the
// link runs. A start that succeeds then replaces it, keeping the samples published meanwhile.
TEST(HostInputRecorder, AFailedLinkStartLeavesThePreviousRecordingAlone) {
  const std::string file =
      (std::filesystem::temp_directory_path() / ("igd_host_rec_keep_" + std::to_string(::getpid()) + ".rec")).string();
  const std::string previous = "igd-recording 1\n0 1 0 1 2 3 the previous run's samples\n";
  {
    std::ofstream out(file, std::ios::binary);
    out << previous;
  }
  auto contents = [&] {
    std::ifstream in(file, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  };
  // Hold a port busy.
  const int busy = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(busy, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(bind(busy, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  socklen_t len = sizeof a;
  ASSERT_EQ(getsockname(busy, reinterpret_cast<sockaddr*>(&a), &len), 0);
  const uint16_t port = ntohs(a.sin_port);
  ig::io::LatestValueMailbox<ig::io::HostState> mailbox;
  ig::FakeClock clock;
  std::string error;
  {
    ig::HostInput input(mailbox, clock);
    EXPECT_FALSE(input.start(std::make_unique<UdpPortLink>(port), file, 1.0, error));
    EXPECT_NE(error.find("Address already in use"), std::string::npos) << error;
    EXPECT_EQ(input.recorder(), nullptr);
  }
  ::close(busy);
  EXPECT_EQ(contents(), previous);
  // Now the port is free: the start succeeds and the file is a new recording holding the sample
  // the link published while starting.
  {
    ig::HostInput input(mailbox, clock);
    ASSERT_TRUE(input.start(std::make_unique<UdpPortLink>(port), file, 1.0, error)) << error;
    input.stop();
  }
  ig::io::Recording rec;
  ASSERT_TRUE(ig::io::loadRecording(file, rec, error)) << error;
  std::filesystem::remove(file);
  ASSERT_EQ(rec.samples.size(), 1u);
  EXPECT_EQ(rec.samples[0].state.hostFrame, 4711u);
}

// Before the host's first message the link is not "lost" for [host] link_timeout_s after the
// start (docs/cigi.md: Start of Frame reports Operate / status 0 then, Standby / status 1 after).
TEST(HostInputRecorder, NoHostYetIsLostOnlyAfterTheLinkTimeout) {
  struct SilentLink final : ig::io::HostLink {
    std::string_view name() const override { return "silent"; }
    bool start(ig::io::HostSink&, std::string&) override { return true; }
    void stop() override {}
  };
  ig::io::LatestValueMailbox<ig::io::HostState> mailbox;
  ig::FakeClock clock;
  ig::HostInput input(mailbox, clock);
  std::string error;
  ASSERT_TRUE(input.start(std::make_unique<SilentLink>(), "", 1.0, error)) << error;
  EXPECT_FALSE(input.updateLost());
  clock.advance_ns(900'000'000);
  EXPECT_FALSE(input.updateLost());
  clock.advance_ns(200'000'000);
  EXPECT_TRUE(input.updateLost());
  input.stop();
}

// Samples whose write fails after a good start (the disk fills up during the run) are counted
// as lost, not as recorded: igd's "recorded N host samples" must not claim what is not in the
// file. The file size limit (RLIMIT_FSIZE, SIGXFSZ ignored) makes writes past 2 KiB fail with
// EFBIG; both are put back afterwards.
TEST(HostInputRecorder, WriteErrorsDuringTheRunAreLostSamplesNotRecordedOnes) {
  const std::string file =
      (std::filesystem::temp_directory_path() / ("igd_host_rec_full_" + std::to_string(::getpid()) + ".rec")).string();
  rlimit old{};
  ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &old), 0);
  struct sigaction ignore {}, oldAction {};
  ignore.sa_handler = SIG_IGN;
  sigemptyset(&ignore.sa_mask);
  ASSERT_EQ(sigaction(SIGXFSZ, &ignore, &oldAction), 0);
  rlimit small = old;
  small.rlim_cur = 2048;
  ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
  ig::HostRecorder rec;
  std::string error;
  const bool opened = rec.open(file, error);
  constexpr uint64_t kSamples = 200;  // about 20 KiB of lines
  for (uint64_t i = 0; opened && i < kSamples; ++i) {
    ig::io::HostSample s;
    s.t_s = 0.01 * static_cast<double>(i);
    s.state.hostFrame = i;
    rec.append(s);
  }
  rec.close();
  setrlimit(RLIMIT_FSIZE, &old);
  sigaction(SIGXFSZ, &oldAction, nullptr);
  const auto size = std::filesystem::file_size(file);
  std::filesystem::remove(file);
  ASSERT_TRUE(opened) << error;
  EXPECT_LE(size, 2048u);
  EXPECT_LT(rec.written(), kSamples) << "the file holds " << size << " bytes";
  EXPECT_EQ(rec.written() + rec.failed(), kSamples);
  EXPECT_NE(rec.firstError().find(file), std::string::npos) << rec.firstError();
}
