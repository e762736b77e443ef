// Reload planning (which changed keys apply between frames), the status report and the
// real-time settings of the render thread.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <unistd.h>

#include "ig/realtime.h"
#include "ig/reload.h"
#include "ig/status.h"

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
  EXPECT_FALSE(std::filesystem::exists(file + ".tmp"));
  // The next interval starts empty.
  r.report(2'000'000'000, ctx);
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

TEST(Status, UnwritableFileIsReportedNotFatal) {
  ig::StatusReporter r("/nonexistent-dir/status.json", 1.0, 10.0);
  r.start(0);
  const std::string line = r.report(1'000'000'000, ig::StatusContext{});
  EXPECT_FALSE(line.empty());
  EXPECT_NE(r.fileError().find("/nonexistent-dir/status.json"), std::string::npos) << r.fileError();
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
