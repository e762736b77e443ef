#include "ig/reload.h"

namespace ig {
namespace {

// Takes `to.*field = from.*field` when they differ and records the key.
template <typename T, typename S>
void take(T& to, const T& from, S T::*field, const char* key, std::vector<std::string>& applied) {
  if (!(to.*field == from.*field)) {
    to.*field = from.*field;
    applied.emplace_back(key);
  }
}

template <typename T, typename S>
void check(const T& run, const T& next, S T::*field, const char* key, std::vector<std::string>& needRestart) {
  if (!(run.*field == next.*field)) needRestart.emplace_back(key);
}

}  // namespace

ReloadPlan planReload(const ServiceConfig& runC, const SceneConfig& runS, const ServiceConfig& newC,
                      const SceneConfig& newS, ServiceConfig& mergedC, SceneConfig& mergedS) {
  return planReload(runC, runS, newC, newS, mergedC, mergedS, runC.snapshotEvery > 0 || !runC.snapshotFrames.empty());
}

ReloadPlan planReload(const ServiceConfig& runC, const SceneConfig& runS, const ServiceConfig& newC,
                      const SceneConfig& newS, ServiceConfig& mergedC, SceneConfig& mergedS, bool snapshotsAvailable) {
  ReloadPlan plan;
  mergedC = runC;
  mergedS = runS;
  auto& a = plan.applied;
  auto& r = plan.needRestart;

  // Service keys that apply between frames.
  take(mergedC, newC, &ServiceConfig::frames, "frame.frames", a);
  take(mergedC, newC, &ServiceConfig::snapshotEvery, "output.snapshot_every", a);
  take(mergedC, newC, &ServiceConfig::snapshotFrames, "output.snapshot_frames", a);
  take(mergedC, newC, &ServiceConfig::linkTimeout_s, "host.link_timeout_s", a);
  take(mergedC, newC, &ServiceConfig::budgetFrame_ms, "budget.frame_ms", a);
  take(mergedC, newC, &ServiceConfig::statusFile, "service.status_file", a);
  take(mergedC, newC, &ServiceConfig::statusInterval_s, "service.status_interval_s", a);
  take(mergedC, newC, &ServiceConfig::governor, "governor", a);
  if (runC.governor.enabled != newC.governor.enabled) {
    mergedC.governor.enabled = runC.governor.enabled;
    r.emplace_back("governor.enabled");
    if (mergedC.governor == runC.governor) std::erase(a, std::string("governor"));
  }
  // Snapshots can be switched on only if the start-up config asked for them (the service made
  // the snapshot folder then); a reload that switches them off releases the snapshot thread, and
  // a later one may switch them on again.
  const bool hadSnapshots = runC.snapshotEvery > 0 || !runC.snapshotFrames.empty();
  const bool wantsSnapshots = newC.snapshotEvery > 0 || !newC.snapshotFrames.empty();
  if (!hadSnapshots && !snapshotsAvailable && wantsSnapshots) {
    mergedC.snapshotEvery = runC.snapshotEvery;
    mergedC.snapshotFrames = runC.snapshotFrames;
    std::erase(a, std::string("output.snapshot_every"));
    std::erase(a, std::string("output.snapshot_frames"));
    r.emplace_back("output.snapshot_every/snapshot_frames (snapshots were off at start-up)");
  }
  // The channel's offset and frustum apply from the next frame (a projector realigned without a
  // restart), unless its frustum only fits an output size that itself needs a restart.
  take(mergedC, newC, &ServiceConfig::channel, "channel", a);
  if (!channelAspectMismatch(mergedC).empty()) {
    mergedC.channel = runC.channel;
    std::erase(a, std::string("channel"));
    r.emplace_back("channel (its frustum fits only the new output size)");
  }
  // The rest need a restart.
  check(runC, newC, &ServiceConfig::rate_hz, "frame.rate_hz", r);
  check(runC, newC, &ServiceConfig::freeRun, "frame.free_run", r);
  check(runC, newC, &ServiceConfig::output, "output.mode", r);
  check(runC, newC, &ServiceConfig::width_px, "output.width_px", r);
  check(runC, newC, &ServiceConfig::height_px, "output.height_px", r);
  check(runC, newC, &ServiceConfig::msaa, "output.msaa", r);
  check(runC, newC, &ServiceConfig::fullscreen, "output.fullscreen", r);
  check(runC, newC, &ServiceConfig::monitor, "output.monitor", r);
  check(runC, newC, &ServiceConfig::snapshotDir, "output.snapshot_dir", r);
  check(runC, newC, &ServiceConfig::statsFile, "stats.file", r);
  check(runC, newC, &ServiceConfig::statsFormat, "stats.format", r);
  check(runC, newC, &ServiceConfig::statsMax_mb, "stats.max_mb", r);
  check(runC, newC, &ServiceConfig::statsKeep, "stats.keep", r);
  check(runC, newC, &ServiceConfig::host, "host.source", r);
  check(runC, newC, &ServiceConfig::replayFile, "host.replay_file", r);
  check(runC, newC, &ServiceConfig::replayLoop, "host.replay_loop", r);
  check(runC, newC, &ServiceConfig::recordFile, "host.record_file", r);
  check(runC, newC, &ServiceConfig::cigi, "host.cigi", r);
  check(runC, newC, &ServiceConfig::can, "host.can", r);
  check(runC, newC, &ServiceConfig::modbus, "host.modbus", r);
  check(runC, newC, &ServiceConfig::sceneFile, "scene.file", r);
  check(runC, newC, &ServiceConfig::budgetTriangles, "budget.triangles", r);
  check(runC, newC, &ServiceConfig::watchdogInterval_s, "service.watchdog_interval_s", r);
  check(runC, newC, &ServiceConfig::realtimePriority, "service.realtime_priority", r);
  check(runC, newC, &ServiceConfig::cpuAffinity, "service.cpu_affinity", r);
  check(runC, newC, &ServiceConfig::lockMemory, "service.lock_memory", r);

  // Scene: light and fog, and the terrain's error target and time budget, apply at once.
  take(mergedS, newS, &SceneConfig::sun, "scene.sun", a);
  take(mergedS, newS, &SceneConfig::fog, "scene.fog", a);
  if (runS.terrain && newS.terrain) {
    take(*mergedS.terrain, *newS.terrain, &TerrainLayerConfig::tolerance_px, "scene.terrain.tolerance_px", a);
    take(*mergedS.terrain, *newS.terrain, &TerrainLayerConfig::lodBudget_ms, "scene.terrain.lod_budget_ms", a);
  }
  check(runS, newS, &SceneConfig::name, "scene.name", r);
  check(runS, newS, &SceneConfig::originGeodetic, "scene.origin", r);
  if (runS.terrain.has_value() != newS.terrain.has_value()) {
    r.emplace_back("scene.terrain (added or removed)");
  } else if (runS.terrain && !(*mergedS.terrain == *newS.terrain)) {
    r.emplace_back("scene.terrain (data, lod, size or placement)");
  }
  check(runS, newS, &SceneConfig::forest, "scene.forest", r);
  check(runS, newS, &SceneConfig::hdlod, "scene.hdlod", r);
  // Cells: the budgets apply at once; the source, placement and memory need a restart.
  if (runS.cells && newS.cells) {
    take(*mergedS.cells, *newS.cells, &CellsLayerConfig::voxelBudget, "scene.cells.voxel_budget", a);
    take(*mergedS.cells, *newS.cells, &CellsLayerConfig::wBytes, "scene.cells.w_bytes", a);
    take(*mergedS.cells, *newS.cells, &CellsLayerConfig::minVoxel_px, "scene.cells.min_voxel_px", a);
    take(*mergedS.cells, *newS.cells, &CellsLayerConfig::selectBudget_ms, "scene.cells.select_budget_ms", a);
  }
  if (runS.cells.has_value() != newS.cells.has_value()) {
    r.emplace_back("scene.cells (added or removed)");
  } else if (runS.cells && !(*mergedS.cells == *newS.cells)) {
    r.emplace_back("scene.cells (source, origin, memory, point scale or select threads)");
  }

  // A key this function does not know yet must not be silently ignored.
  ServiceConfig c = mergedC;
  c.path = newC.path;
  SceneConfig s = mergedS;
  s.path = newS.path;
  if (r.empty() && !(c == newC)) r.emplace_back("service config (other keys)");
  if (r.empty() && !(s == newS)) r.emplace_back("scene config (other keys)");
  return plan;
}

std::string joinKeys(const std::vector<std::string>& keys) {
  if (keys.empty()) return "none";
  std::string out;
  for (const auto& k : keys) out += (out.empty() ? "" : ", ") + k;
  return out;
}

}  // namespace ig
