// igd: the image generator service. See README.md and `igd --help`.
#include "ig/cli.h"

#include <atomic>
#include <csignal>
#include <cstdio>

#include "ig/app_common.h"
#include "ig/clock.h"
#include "ig/realtime.h"
#include "ig/service.h"

namespace {
std::atomic<bool> gStop{false};
ig::ReloadSource gReload;
void onSignal(int) { gStop.store(true); }
void onHangup(int) { gReload.requested.store(true); }
}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "igd - real-time image generator for training simulators.\n"
      "Each frame it takes the eyepoint and simulation time from the host (or a recorded host\n"
      "replay), selects terrain detail within the frame budget and renders with OpenGL 4.5\n"
      "through EGL: headless (off-screen, snapshots to PNG), in a window, or via OSMesa.\n"
      "With [governor] enabled = true in the config it steers each layer's detail (terrain and\n"
      "HDLOD pixel tolerance, forest 3D-tree distance and shell layers, cells voxel budget)\n"
      "to hold the rate.\n"
      "It runs at a fixed rate with absolute deadlines, writes one stats line per frame, and\n"
      "talks to systemd (READY, WATCHDOG, STATUS) when started as a service. SIGTERM/SIGINT stop it\n"
      "cleanly; SIGHUP (systemctl reload igd) re-reads the configs between two frames: light, fog,\n"
      "terrain tolerance, the frame budget, the layers' time and voxel budgets, the governor,\n"
      "snapshots, status and link timeout change at once, other keys (budget.triangles too) are\n"
      "named in the log as needing a restart. Exit codes: 0 ok, 1 run-time failure, 2 bad config or option, 3 start-up failure."};
  std::string configFile = "config/igd.toml";
  ig::Overrides o;
  bool checkOnly = false;
  app.add_option("-c,--config", configFile, "Service config (TOML); every key is documented in config/igd.toml")
      ->capture_default_str();
  app.add_option("--frames", o.frames, "Render this many frames, then exit (0 = until SIGTERM); overrides frame.frames");
  app.add_flag("--free-run", o.freeRun,
               "Do not sleep between frames (offline replay, tests); simulation time still steps 1/rate_hz");
  app.add_option("--output", o.output, "Output: headless | window | osmesa; overrides output.mode");
  app.add_option("--width", o.width_px, "Frame width in pixels; overrides output.width_px");
  app.add_option("--height", o.height_px, "Frame height in pixels; overrides output.height_px");
  app.add_option("--stats", o.statsFile, "Per-frame stats file ('' = none); overrides stats.file");
  app.add_option("--status-file", o.statusFile,
                 "JSON health report, replaced every service.status_interval_s ('' = none); overrides service.status_file");
  app.add_option("--stats-format", o.statsFormat, "csv | jsonl; overrides stats.format");
  app.add_option("--snapshot-dir", o.snapshotDir, "Folder for snapshot PNGs; overrides output.snapshot_dir");
  app.add_option("--snapshot-every", o.snapshotEvery, "Write a snapshot every N frames (0 = never); overrides output.snapshot_every");
  app.add_option("--scene", o.sceneFile, "Scene config (TOML); overrides scene.file");
  app.add_option("--replay", o.replayFile, "Host recording to replay; sets host.source = replay (and records nothing: host.record_file is for live links)");
  app.add_flag("--check-config", checkOnly, "Load and validate the configs, print a summary, exit");
  if (const auto rc = ig::parseCommandLine(app, argc, argv)) return *rc;

  ig::ServiceConfig config;
  ig::SceneConfig scene;
  std::string error;
  if (!ig::loadConfigs(configFile, o, config, scene, error)) {
    std::fprintf(stderr, "igd: %s\n", error.c_str());
    return 2;
  }
  if (checkOnly) {
    std::printf("igd: config OK: %s (scene '%s' from %s; layers:%s%s%s%s)\n", config.path.c_str(), scene.name.c_str(),
                scene.path.c_str(), scene.terrain ? " terrain" : "", scene.forest ? " forest" : "",
                scene.hdlod ? " hdlod" : "", scene.cells ? " cells" : "");
    return 0;
  }

  struct sigaction sa {};
  sa.sa_handler = onSignal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);
  struct sigaction hup {};
  hup.sa_handler = onHangup;
  sigemptyset(&hup.sa_mask);
  sigaction(SIGHUP, &hup, nullptr);
  // Re-reads the same files with the same command-line overrides.
  gReload.load = [&configFile, &o](ig::ServiceConfig& c, ig::SceneConfig& s, std::string& e) {
    return ig::loadConfigs(configFile, o, c, s, e);
  };

  // Before the GL context: Mesa's per-frame allocations reuse freed memory (ig/realtime.h).
  ig::keepFreedMemory();
  auto service = ig::Service::create(config, scene, error);
  if (!service) {
    std::fprintf(stderr, "igd: start-up failed: %s\n", error.c_str());
    return 3;
  }
  const ig::ServiceInfo& info = service->info();
  std::string layers;
  for (const auto& l : info.layers) layers += " " + l;
  std::fprintf(stderr, "igd: %s\nigd: scene '%s': layers:%s; %u pass(es), %.1f MiB GPU buffers, %u thread(s)\n",
               info.context.c_str(), scene.name.c_str(), layers.empty() ? " (none)" : layers.c_str(), info.passes,
               static_cast<double>(info.gpuBufferBytes) / (1024.0 * 1024.0), info.threads);
  if (!info.hdlodDescription.empty())
    std::fprintf(stderr, "igd: hdlod: %s, ready in %.0f ms\n", info.hdlodDescription.c_str(), info.hdlodBuild_ms);
  if (!info.cellsDescription.empty()) std::fprintf(stderr, "igd: %s\n", info.cellsDescription.c_str());
  if (!info.queriesDescription.empty()) std::fprintf(stderr, "igd: host queries (HAT/HOT, LOS) meet: %s\n", info.queriesDescription.c_str());
  if (!info.scheduling.empty()) std::fprintf(stderr, "igd: render thread: %s\n", info.scheduling.c_str());
  if (!info.terrainSource.empty())
    std::fprintf(stderr, "igd: terrain: %s, built in %.0f ms (load, LOD precomputation, upload)\n",
                 info.terrainSource.c_str(), info.terrainBuild_ms);
  std::fprintf(stderr, "igd: %dx%d at %.2f Hz%s, %s\n", config.width_px, config.height_px, config.rate_hz,
               config.freeRun ? " (free-run)" : "",
               config.frames > 0 ? (std::to_string(config.frames) + " frames").c_str() : "until SIGTERM");

  ig::MonotonicClock clock;
  const int rc = service->run(clock, gStop, &gReload);
  const ig::RunSummary s = service->summary();
  std::fprintf(stderr,
               "igd: %lld frames, work p50 %.2f ms p99 %.2f ms max %.2f ms, overruns %lld, missed slots %lld, "
               "triangles p50 %llu, host samples rejected %llu%s%s\n",
               static_cast<long long>(s.frames), s.workMs_p50, s.workMs_p99, s.workMs_max,
               static_cast<long long>(s.overruns), static_cast<long long>(s.missedSlots),
               static_cast<unsigned long long>(s.triangles_p50),
               static_cast<unsigned long long>(service->hostRejected()),
               config.statsFile.empty() ? "" : ", stats: ", config.statsFile.c_str());
  return rc;
}
