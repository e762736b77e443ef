// igbench: benchmarks. Each suite prints one JSON object on stdout with --json (for scripts
// and side-by-side comparisons), or a human summary without it.
#include "ig/cli.h"
#include "ig/json.h"

#include <atomic>
#include <cstdio>
#include <cstdlib>

#include "ig/app_common.h"
#include "ig/bench_adaptive.h"
#include "ig/bench_cells.h"
#include "ig/bench_fog.h"
#include "ig/bench_forest.h"
#include "ig/bench_governor.h"
#include "ig/bench_hdlod.h"
#include "ig/bench_latency.h"
#include "ig/bench_queries.h"
#include "ig/bench_perfmodel.h"
#include "ig/bench_terrain.h"
#include "ig/clock.h"
#include "ig/realtime.h"
#include "ig/service.h"

namespace {

int runFrameSuite(const std::string& configFile, ig::Overrides o, bool json) {
  // For igd, 0 frames means "until SIGTERM"; a benchmark has no signal handling and loops its
  // replay, so it would render forever and report nothing.
  if (o.frames && *o.frames == 0) {
    std::fprintf(stderr, "igbench: command line: --frames = 0: must be >= 1\n");
    return 2;
  }
  // Free-run, no files: measure the work per frame, not the pacing sleep.
  o.freeRun = true;
  o.statsFile = "";
  o.snapshotEvery = 0;
  ig::ServiceConfig config;
  ig::SceneConfig scene;
  std::string error;
  if (!ig::loadConfigs(configFile, o, config, scene, error)) {
    std::fprintf(stderr, "igbench: %s\n", error.c_str());
    return 2;
  }
  config.snapshotFrames.clear();
  config.recordFile.clear();  // no files: a live link's recording is not overwritten by a benchmark
  config.replayLoop = true;
  auto service = ig::Service::create(config, scene, error);
  if (!service) {
    std::fprintf(stderr, "igbench: start-up failed: %s\n", error.c_str());
    return 3;
  }
  ig::MonotonicClock clock;
  std::atomic<bool> stop{false};
  if (service->run(clock, stop) != 0) return 1;
  const ig::RunSummary s = service->summary();
  const double period_ms = 1000.0 / config.rate_hz;
  if (json) {
    std::printf(
        "{\"suite\":\"frame\",\"scene\":\"%s\",\"renderer\":\"%s\",\"width_px\":%d,\"height_px\":%d,"
        "\"frames\":%lld,\"target_hz\":%.3f,\"period_ms\":%.3f,\"frame_ms_p50\":%.3f,\"frame_ms_p99\":%.3f,"
        "\"frame_ms_mean\":%.3f,\"frame_ms_max\":%.3f,\"overruns\":%lld,\"triangles_p50\":%llu,"
        "\"draw_calls_p50\":%u,\"phase_ms_p50\":{\"input\":%.3f,\"lod\":%.3f,\"submit\":%.3f,\"gpu_finish\":%.3f,"
        "\"present\":%.3f},\"layers\":%zu,\"passes\":%u}\n",
        ig::jsonEscape(scene.name).c_str(), ig::jsonEscape(service->info().context).c_str(), config.width_px, config.height_px,
        static_cast<long long>(s.frames), config.rate_hz, period_ms, s.workMs_p50, s.workMs_p99, s.workMs_mean,
        s.workMs_max, static_cast<long long>(s.overruns), static_cast<unsigned long long>(s.triangles_p50),
        s.drawCalls_p50, s.phaseMs_p50[0], s.phaseMs_p50[1], s.phaseMs_p50[2], s.phaseMs_p50[3], s.phaseMs_p50[4],
        service->info().layers.size(), service->info().passes);
  } else {
    std::printf("frame suite: scene '%s', %dx%d, %s\n", scene.name.c_str(), config.width_px, config.height_px,
                service->info().context.c_str());
    std::printf("  %lld frames; work per frame p50 %.2f ms, p99 %.2f ms, max %.2f ms (period %.2f ms at %.1f Hz)\n",
                static_cast<long long>(s.frames), s.workMs_p50, s.workMs_p99, s.workMs_max, period_ms, config.rate_hz);
    std::printf("  overruns %lld (%.1f %%), triangles p50 %llu, draw calls p50 %u\n", static_cast<long long>(s.overruns),
                s.frames ? 100.0 * static_cast<double>(s.overruns) / static_cast<double>(s.frames) : 0.0,
                static_cast<unsigned long long>(s.triangles_p50), s.drawCalls_p50);
    std::printf("  phase p50 ms: input %.3f, lod %.3f, submit %.3f, gpu_finish %.3f, present %.3f\n",
                s.phaseMs_p50[0], s.phaseMs_p50[1], s.phaseMs_p50[2], s.phaseMs_p50[3], s.phaseMs_p50[4]);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // As igd does, before any GL context: Mesa's per-frame allocations reuse freed memory instead of
  // page-faulting it in again every frame (ig/realtime.h). The benchmarks measure the service's
  // state, and the performance model's calibration runs in the state it predicts.
  ig::keepFreedMemory();
  CLI::App app{
      "igbench - benchmarks for the igd image generator.\n"
      "Run one suite at a time; with --json it prints exactly one JSON object on stdout.\n"
      "Compare variants side by side in one run (these machines are shared and noisy)."};
  app.require_subcommand(1);
  std::string configFile = "config/igd.toml";
  bool json = false;
  ig::Overrides o;
  o.frames = 240;

  CLI::App* frame = app.add_subcommand(
      "frame",
      "Render the configured scene headless for N frames with the built-in host replay, free-running,\n"
      "and report work time per frame (p50/p99/mean/max), overruns against the frame period,\n"
      "triangles and draw calls per frame, and the p50 of each phase (input, lod, submit,\n"
      "gpu_finish, present). JSON fields: suite, scene, renderer, width_px, height_px, frames,\n"
      "target_hz, period_ms, frame_ms_p50, frame_ms_p99, frame_ms_mean, frame_ms_max, overruns,\n"
      "triangles_p50, draw_calls_p50, phase_ms_p50{...}, layers, passes.");
  frame->add_option("-c,--config", configFile, "Service config (TOML)")->capture_default_str();
  frame->add_option("--frames", o.frames, "Frames to render (>= 1; default 240)");
  frame->add_option("--width", o.width_px, "Frame width in pixels (default: the config's)");
  frame->add_option("--height", o.height_px, "Frame height in pixels (default: the config's)");
  frame->add_option("--output", o.output, "Context: headless | osmesa | window");
  frame->add_option("--scene", o.sceneFile, "Scene config (default: the config's)");
  frame->add_flag("--json", json, "Print one JSON object instead of the human summary");
  ig::TerrainBenchOptions terrainOptions;
  bool noRender = false;
  CLI::App* terrain = app.add_subcommand(
      "terrain",
      "ROAM with enhMerge against ROAM with diamond merges only, ROAM rebuilt every frame and block\n"
      "LOD, at 1 px tolerance on a real DEM, along a flight path that flies, turns hard (90 deg/s)\n"
      "and teleports; then a tolerance sweep (0.5, 1, 2, 4, 8 px) rendered headless against a\n"
      "full-resolution reference render of the same view. JSON fields: dem, samples, methods\n"
      "{roam_enhmerge, roam_merge, roam_rebuild, block, roam_deferred (enhMerge with deferred\n"
      "priority recomputation, refining the surroundings regardless of view direction):\n"
      "update_ms_p50, update_ms_p99, teleport_update_ms, triangles_p50 (the whole mesh),\n"
      "visible_triangles_p50 (in the view frustum), max_error_px, uploads_p50 (triangles new since\n"
      "the last frame)}, block_triangles_at_equal_error, roam_triangles_at_equal_error, sweep [{tolerance_px,\n"
      "triangles, update_ms, render_ms, rmse, psnr_db}], and (docs/terrain.md) per method\n"
      "update_cpu_ms_p50/p99, startup_update_ms, unfinished_frames; teleport {...} (time to a valid\n"
      "mesh and to convergence, against merges alone), raster {...} and frame_vs_raster_ratio (the\n"
      "terrain frame against a static mesh of the same size), bounds_ms, dem_mapped.\n"
      "Run scripts/fetch-data first.");
  terrain->add_option("--dem", terrainOptions.demFile, "DEM file (.hgt, .tif, 16-bit .png)")->capture_default_str();
  terrain->add_option("--synthetic", terrainOptions.syntheticSamples,
                      "Use a procedural N x N mountainous field (30 m spacing) instead of --dem, e.g. 4097")
      ->check(CLI::Range(2, 16385));
  terrain->add_option("--frames", terrainOptions.frames, "Flight path frames")->capture_default_str()->check(CLI::Range(12, 100000));
  terrain->add_option("--width", terrainOptions.width_px, "Viewport width in pixels")->capture_default_str();
  terrain->add_option("--height", terrainOptions.height_px, "Viewport height in pixels")->capture_default_str();
  terrain->add_flag("--no-render", noRender, "Skip the sweep's rendering (render_ms, rmse, psnr_db = 0)");
  terrain->add_option("--dem-spacing", terrainOptions.demSpacing_m,
                      "Sample spacing of the DEM file in metres (PNGs carry none; default: the file's, else 30)")
      ->check(CLI::PositiveNumber);
  terrain->add_option("--visits", terrainOptions.deferredVisits, "roam_deferred: node visits per update (0 = unlimited)")
      ->capture_default_str();
  terrain->add_option("--budget-ms", terrainOptions.budget_ms,
                      "roam_deferred flight: time budget of an update in ms, turned into node visits by the measured\n"
                      "time per visit as igd does (0 = a fixed --visits)")
      ->capture_default_str()->check(CLI::Range(0.0, 1000.0));
  terrain->add_option("--teleport-budget-ms", terrainOptions.teleportBudget_ms,
                      "roam_deferred: time budget of an update while converging after the teleport, in ms\n"
                      "(0 = a fixed --teleport-visits)")
      ->capture_default_str()->check(CLI::Range(0.0, 1000.0));
  terrain->add_option("--teleport-visits", terrainOptions.teleportVisits,
                      "roam_deferred: node visits per update while converging after the teleport, with\n"
                      "--teleport-budget-ms 0")
      ->capture_default_str();
  terrain->add_option("--lateness", terrainOptions.lateness,
                      "roam_deferred: decision lateness (0 = exact; more = fewer re-examinations, more triangles)")
      ->capture_default_str()->check(CLI::Range(0.0, 0.5));
  terrain->add_option("--teleport-max-frames", terrainOptions.teleportMaxFrames, "Give up converging after this many updates")
      ->capture_default_str()->check(CLI::Range(1, 100000));
  terrain->add_option("--cache-dir", terrainOptions.cacheDir,
                      "Memory-mapped raw DEM cache folder (\"\" = decode every run, no mmap)")
      ->capture_default_str();
  terrain->add_option("--raster-frames", terrainOptions.rasterFrames, "Frames timed for frame_vs_raster_ratio (0 = skip)")
      ->capture_default_str()->check(CLI::Range(0, 100000));
  bool noBaselines = false;
  terrain->add_flag("--no-baselines", noBaselines, "Only roam_deferred, the teleport and the raster comparison (large DEMs)");
  terrain->add_flag("--json", terrainOptions.json, "Print one JSON object instead of the human summary");
  ig::LatencyBenchOptions latencyOptions;
  CLI::App* latency = app.add_subcommand(
      "latency",
      "Host-to-screen latency over a real CIGI link on loopback: a host thread sends IG Control +\n"
      "Entity Control at --host-rate while igd renders the configured scene headless at its frame\n"
      "rate; each host frame's send time is compared with the end of the first frame that used it.\n"
      "Then the CIGI decode rate on one core, and a flood run: a loopback sender pushes\n"
      "--flood-rate packets/s for --flood-seconds while igd renders, counting overruns.\n"
      "JSON fields: suite, renderer, width_px, height_px, rate_hz, period_ms, host_rate_hz, samples,\n"
      "latency_ms_p50, latency_ms_p99, latency_ms_max, render_ms_p50, render_ms_p99,\n"
      "latency_goal_ms (period + render p99), latency_run_overruns, host_messages_received,\n"
      "host_messages_accepted, decode_msgs_per_s, decode_msgs_per_s_swapped, flood_rate_pps,\n"
      "flood_seconds, flood_rate_achieved_pps, flood_frames, flood_overruns, flood_frame_ms_p99, flood_packets_sent,\n"
      "flood_packets_received, flood_packets_accepted.");
  latency->add_option("-c,--config", latencyOptions.configFile, "Service config (TOML)")->capture_default_str();
  latency->add_option("--host-rate", latencyOptions.hostRate_hz, "Host messages per second in the latency run")
      ->capture_default_str()->check(CLI::Range(1.0, 1000.0));
  latency->add_option("--seconds", latencyOptions.seconds, "Length of the latency run")
      ->capture_default_str()->check(CLI::Range(1.0, 3600.0));
  latency->add_option("--flood-rate", latencyOptions.floodRate_pps, "Packets per second in the flood run")
      ->capture_default_str()->check(CLI::Range(1.0, 1e7));
  latency->add_option("--flood-seconds", latencyOptions.floodSeconds, "Length of the flood run")
      ->capture_default_str()->check(CLI::Range(1.0, 3600.0));
  latency->add_option("--width", latencyOptions.width_px, "Frame width in pixels (default: the config's)");
  latency->add_option("--height", latencyOptions.height_px, "Frame height in pixels (default: the config's)");
  latency->add_flag("--json", latencyOptions.json, "Print one JSON object instead of the human summary");
  ig::QueriesBenchOptions queriesOptions;
  CLI::App* queries = app.add_subcommand(
      "queries",
      "The host's terrain queries (CIGI HAT/HOT and line of sight, docs/cigi.md) per kind of surface:\n"
      "a 4097 x 4097-post terrain grid, the construction site's objects, the default forest's trees.\n"
      "Random seeded queries, each timed alone. JSON fields: suite, queries, terrain_posts, objects,\n"
      "object_triangles, objects_index_ms, trees, forest_index_ms, forest_index_mb, and per kind\n"
      "(terrain_hot, terrain_los, objects_hot, objects_los, forest_los) us_p50, us_p99, us_mean,\n"
      "work_mean, work_max (the units the per-frame query work budget counts), hit_pct, ns_per_work.");
  queries->add_option("--queries", queriesOptions.queries, "Queries per kind")
      ->capture_default_str()->check(CLI::Range(1, 10000000));
  queries->add_option("--site-scale", queriesOptions.siteScale, "Construction site scale (1 = ~56k objects)")
      ->capture_default_str()->check(CLI::Range(0.001, 10.0));
  queries->add_option("--seed", queriesOptions.seed, "Seed of the random queries")->capture_default_str();
  queries->add_flag("--json", queriesOptions.json, "Print one JSON object instead of the human summary");
  ig::FogBenchOptions fogOptions;
  CLI::App* fog = app.add_subcommand(
      "fog",
      "What fog culling ([fog] cull) buys and costs: frames of the built-in replay rendered twice,\n"
      "side by side, at each visibility (given as the host's, as CIGI Atmosphere Control gives it):\n"
      "with the far plane where the fog is opaque (1.77 x the visibility) and with the host's far\n"
      "plane. JSON fields: suite, scene, renderer, width_px, height_px, frames, points\n"
      "[{visibility_m, cull_distance_m, triangles_cull, triangles_full, triangle_ratio,\n"
      "frame_ms_cull, frame_ms_full (p50; select + submit + glFinish), speedup (full / cull),\n"
      "max_diff_levels (8-bit), differ_pct (pixels with any difference), psnr_db_min}],\n"
      "speedup_min, speedup_max, max_diff_levels.");
  fog->add_option("-c,--config", fogOptions.configFile, "Service config (TOML)")->capture_default_str();
  fog->add_option("--scene", fogOptions.sceneFile, "Scene config (\"\" = the config's)")->capture_default_str();
  fog->add_option("--visibility", fogOptions.visibilities_m, "Visibilities to sweep (metres)")->capture_default_str();
  fog->add_option("--frames", fogOptions.frames, "Frames per visibility")->capture_default_str()->check(CLI::Range(1, 100000));
  fog->add_option("--width", fogOptions.width_px, "Frame width in pixels")->capture_default_str()->check(CLI::Range(16, 16384));
  fog->add_option("--height", fogOptions.height_px, "Frame height in pixels")->capture_default_str()->check(CLI::Range(16, 16384));
  fog->add_flag("--json", fogOptions.json, "Print one JSON object instead of the human summary");
  ig::HdlodBenchOptions hdlodOptions;
  CLI::App* hdlod = app.add_subcommand(
      "hdlod",
      "HDLOD (paper 000) on the synthetic construction site (columns, beams, slabs, facade panels\n"
      "installed floor by floor, scaffolding up and down, vehicles on paths): builds the 4D cluster\n"
      "tree (or loads it from --cache), then for each time (start, 1/3, 2/3, end, animation) and\n"
      "screen size of the scene (1/1, 1/4, 1/16) selects and renders with HDLOD at --tolerance and\n"
      "with full detail: triangles, draws, select_ms, frame_ms (glFinish) and the PSNR of the HDLOD\n"
      "image against the full one; then an r sweep. JSON fields: objects, triangles, build_s,\n"
      "cache_bytes, clusters, levels, cases [{time, screen, hdlod{triangles, draws, select_ms, select_cpu_ms,\n"
      "frame_ms}, full{...}, psnr_db}], sweep [{r_px, triangles, select_ms, frame_ms, psnr_db}],\n"
      "select_ms_max, select_cpu_ms_max, triangle_ratio_1_16_min, frame_ratio_end_1_16, psnr_db_min, two_thread_gain_max,\n"
      "simplifiers [{name, seconds, hausdorff_m, merged_triangles, triangle_ratio_1_16_min}] (docs/hdlod.md).");
  hdlod->add_option("--scale", hdlodOptions.scale, "Site scale: 1 = the paper's ~56k objects / ~4 M triangles")
      ->capture_default_str()->check(CLI::PositiveNumber);
  hdlod->add_option("--seed", hdlodOptions.seed, "Site generator seed")->capture_default_str();
  hdlod->add_option("--width", hdlodOptions.width_px, "Viewport width in pixels")->capture_default_str()
      ->check(CLI::Range(16, 16384));
  hdlod->add_option("--height", hdlodOptions.height_px, "Viewport height in pixels")->capture_default_str()
      ->check(CLI::Range(16, 16384));
  hdlod->add_option("--fov", hdlodOptions.fovY_deg, "Vertical field of view in degrees")->capture_default_str()
      ->check(CLI::Range(1.0, 179.0));
  hdlod->add_option("--tolerance", hdlodOptions.tolerance_px, "Screen-space tolerance r in pixels for the cases")
      ->capture_default_str()->check(CLI::Range(0.0, 1000.0));
  hdlod->add_option("--msaa", hdlodOptions.msaa,
                    "Samples per pixel (MSAA 1, 2, 4 or 8) of the HDLOD and the full-detail image alike")
      ->capture_default_str()
      ->check(CLI::IsMember({1, 2, 4, 8}));
  hdlod->add_option("--repeats", hdlodOptions.repeats, "Selections per case (the median is reported)")
      ->capture_default_str()->check(CLI::Range(1, 10000));
  hdlod->add_option("--simplifier", hdlodOptions.simplifier,
                    "Parent-cluster simplifier for the main run: meshoptimizer, openmesh, clustering")
      ->capture_default_str();
  bool noSimplifierCompare = false;
  hdlod->add_flag("--no-simplifier-compare", noSimplifierCompare,
                  "Skip building the tree once per simplifier (the simplifiers field; OpenMesh takes ~95 s at scale 1)");
  hdlod->add_option("--frames", hdlodOptions.frames, "Rendered frames per case (the median is reported)")
      ->capture_default_str()->check(CLI::Range(1, 1000));
  hdlod->add_option("--animation-frames", hdlodOptions.animationFrames,
                    "Frames of the animation case (schedule played from 0 to T)")
      ->capture_default_str()->check(CLI::Range(2, 1000000));
  bool hdlodNoRender = false;
  hdlod->add_flag("--no-render", hdlodNoRender, "Selection only: no GL context, no frame_ms / psnr_db");
  hdlod->add_flag("--quick", hdlodOptions.quick,
                  "CI: scale 0.05, at most 480x270, 5 repeats, 2 frames, 8 animation frames, no simplifier comparison");
  hdlod->add_option("--eps-per-size", hdlodOptions.epsPerSize,
                    "eps(l) / w(l): the simplification target against the cluster size")
      ->capture_default_str()->check(CLI::Range(1e-6, 1.0));
  hdlod->add_flag("--strict-hausdorff", hdlodOptions.strictHausdorff, "Measure eps_c against the drawn triangles only");
  hdlod->add_option("--compare-scale", hdlodOptions.compareScale,
                    "Site scale of the simplifier comparison (OpenMesh takes ~50 s at 0.25)")
      ->capture_default_str()->check(CLI::Range(0.001, 10.0));
  hdlod->add_option("--cache", hdlodOptions.cacheFile, "Load the tree from this cache file, or build it and write it there");
  hdlod->add_option("--images", hdlodOptions.imageDir, "Write the HDLOD and full PNG of every case into this existing folder");
  hdlod->add_flag("--progress", hdlodOptions.progress, "Build progress bar on stderr even when it is not a terminal");
  hdlod->add_flag("--json", hdlodOptions.json, "Print one JSON object instead of the human summary");
  ig::CellsBenchOptions cellsOptions;
  CLI::App* cells = app.add_subcommand(
      "cells",
      "Hierarchical cells (paper 003). (1) Selection on ~1 M cells of voxelized spheres: a camera\n"
      "path with a teleport, the best cut under a voxel budget and a byte budget W per frame\n"
      "(requested cells arrive --latency frames later, simulated), and a voxel-budget sweep, both\n"
      "replayed --repeats times (a frame's select time is the fastest of its replays). (2) The\n"
      "Stanford bunny (scripts/fetch-cells; run from the source tree): its cell database, a PSNR\n"
      "sweep of splat pictures against full detail, and streaming through a local nginx\n"
      "(scripts/cells-server) at --rates Mbit/s: seconds until full quality after a teleport. Exit 1\n"
      "if any frame went over a budget. JSON fields: cells, levels, dimension (growth log2 N(l+1)/N(l)),\n"
      "box_counting_dimension (log2 N(l) / l, the paper's Table 1), select_ms_p99\n"
      "(select_ms_p99_first_replay, replays_differ_frames: 0),\n"
      "voxels_drawn_p50, voxel_budget, budget_exceeded_frames, bytes_per_frame_max, w_bytes,\n"
      "select_sweep, frames_to_fill(_after_teleport), deadline {deadline_ms, select_ms_p99,\n"
      "stopped_frames, frames_to_fill, ...} (--deadline-ms), mesh {cells, levels, dimension,\n"
      "box_counting_dimension},\n"
      "sweep [{voxel_budget, psnr_db, ...}],\n"
      "streaming [{rate_mbit, seconds_to_full_quality, quality_monotonic, curve, ...}],\n"
      "seconds_to_full_quality {rate: s} (docs/cells.md; plot: scripts/plot_cells.py).");
  cells->add_option("--spheres", cellsOptions.spheres, "Procedural spheres in the 1024 m scene")
      ->capture_default_str()->check(CLI::Range(1, 1000000));
  cells->add_option("--levels", cellsOptions.cellLevels, "Cell levels L")->capture_default_str()->check(CLI::Range(1, 16));
  cells->add_option("--voxel-depth", cellsOptions.cellVoxelDepth,
                    "Voxel octree depth inside a cell (4: 16^3-voxel cells, 0.25 m voxels; the build needs ~5.2 GB of "
                    "memory, 3: 8^3 cells, 0.5 m, ~1.5 GB)")
      ->capture_default_str()->check(CLI::Range(0, 8));
  // At least 8: the budget sweep times every 4th frame but the first and the teleport's, and
  // needs one (with 3 ... 7 frames it had none and crashed).
  cells->add_option("--frames", cellsOptions.frames, "Camera path frames (60 Hz, teleport at 2/3)")
      ->capture_default_str()->check(CLI::Range(8, 1000000));
  cells->add_option("--height", cellsOptions.height_px, "Viewport height in pixels")->capture_default_str()
      ->check(CLI::Range(16, 16384));
  cells->add_option("--voxel-budget", cellsOptions.voxelBudget, "Voxels drawn per frame")->capture_default_str();
  cells->add_option("--w-bytes", cellsOptions.wBytes, "Bytes requested per frame (W)")->capture_default_str();
  cells->add_option("--latency", cellsOptions.latencyFrames, "Frames until a requested cell arrives")
      ->capture_default_str()->check(CLI::Range(0, 100000));
  cells->add_option("--max-ops", cellsOptions.maxOps, "Splits + merges per frame on the path (0: no cap)")
      ->capture_default_str();
  cells->add_option("--deadline-ms", cellsOptions.deadline_ms,
                    "The path again with each select() held to this time as igd's cells phase budget holds it (the "
                    "refinement stops early enough for what follows a stop): select time, stopped frames, frames "
                    "until the voxels drawn fill (0: skip)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1000.0));
  cells->add_option("--seed", cellsOptions.seed, "Scene seed")->capture_default_str();
  cells->add_option("--repeats", cellsOptions.repeats,
                    "Replays of the path and the sweep (same choices each time); a frame's select time is the "
                    "fastest of its replays")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  cells->add_option("--select-threads", cellsOptions.selectThreads,
                    "Threads for the selection's per-frame passes: 2 (the caller and one helper; every replay also "
                    "runs on one thread, reported as *_one_thread, and both must choose the same) or 1")
      ->capture_default_str()
      ->check(CLI::Range(1, 2));
  cells->add_flag("--json", cellsOptions.json, "Print one JSON object instead of the human summary");
  cells->add_flag("!--no-mesh", cellsOptions.withMesh,
                  "Selection only: skip the bunny (PSNR sweep with splats, streaming through nginx)");
  cells->add_option("--mesh", cellsOptions.mesh.mesh, "The real mesh (y-up OBJ; scripts/fetch-cells fetches the bunny)")
      ->capture_default_str();
  cells->add_flag("!--no-stream", cellsOptions.mesh.stream, "Skip streaming through nginx (keep the PSNR sweep)");
  cells->add_option("--rates", cellsOptions.mesh.rates_mbit, "Channel rates to stream at (Mbit/s)")
      ->capture_default_str()->check(CLI::PositiveNumber);
  cells->add_option("--stream-timeout", cellsOptions.mesh.timeout_s, "Give up on full quality after this many seconds")
      ->capture_default_str()->check(CLI::PositiveNumber);
  cells->add_option("--server-script", cellsOptions.mesh.serverScript, "scripts/cells-server (run from the source tree)")
      ->capture_default_str();
  cells->add_flag("--quick", cellsOptions.mesh.quick, "Streaming at 10 and 100 Mbit/s only, 3 sweep points (for tests)");
  cells->add_option("--dump-tree", cellsOptions.dumpTree,
                    "Write the cell tree (header + one CellDesc per cell) to this file and exit, for scripts/cells-ab "
                    "(the selection of two revisions side by side)");
  cells->add_option("--trace", cellsOptions.trace,
                    "Write a CSV, one row per path frame: select ms (fastest replay; two threads and one), cut cells, "
                    "drawn voxels, largest voxel px, splits, merges, blocked splits, requests, and the first deadline "
                    "replay's ms and stop");
  ig::ForestBenchOptions forestOptions;
  CLI::App* forest = app.add_subcommand(
      "forest",
      "Forest of paper 004 on a 7.68 km window of a real DEM (the SRTM tile scripts/fetch-data\n"
      "fetches; procedural relief without it) with >= 1 M trees and the real Scopia pine and cypress\n"
      "models (scripts/fetch-forest; procedural models without them): times kd-tree cull + gather +\n"
      "far-to-near sort along a low flight (one core), renders a flight (frame_ms), a slow approach\n"
      "through the near/far transition band (popping, against the same flight without the forest),\n"
      "and a sweep over layer counts and near distances against a reference drawing every tree in 3D.\n"
      "Exit 1 if any tree was dropped. JSON fields: trees, area_km2, cull_ms_p50, cull_ms_p99,\n"
      "trees_drawn_p50, layers, fins_drawn_p50, frame_ms_p50/p99, popping_max,\n"
      "popping_max_no_forest, popping_steady_excess, popping_spike, popping_max_hard_switch,\n"
      "sweep [{layers, near_m, frame_ms, psnr_db}], cull_sweep and more (docs/forest.md).");
  forest->add_option("--posts", forestOptions.posts, "Terrain posts per side, 32 m apart (241 = 7.68 km)")
      ->capture_default_str()->check(CLI::Range(2, 16385));
  forest->add_option("--dem", forestOptions.dem, "DEM file; missing = procedural relief")->capture_default_str();
  forest->add_option("--models", forestOptions.models, "Scopia OBJ folder from scripts/fetch-forest; missing = procedural models")
      ->capture_default_str();
  forest->add_option("--layers", forestOptions.layers, "Shell layers of the main run")->capture_default_str()->check(CLI::Range(1, 32));
  forest->add_option("--render-frames", forestOptions.renderFrames, "Rendered flight frames (frame_ms)")
      ->capture_default_str()->check(CLI::Range(1, 100000));
  forest->add_option("--pop-frames", forestOptions.popFrames, "Slow-approach frames (popping)")
      ->capture_default_str()->check(CLI::Range(2, 100000));
  forest->add_option("--width", forestOptions.width, "Render width in pixels")->capture_default_str()->check(CLI::Range(16, 8192));
  forest->add_option("--height", forestOptions.height, "Render height in pixels")->capture_default_str()->check(CLI::Range(16, 8192));
  forest->add_flag("--quick", forestOptions.quick, "CI mode, ~10 s: 2 km forest, 256x144, small sweep");
  bool forestNoSweep = false;
  forest->add_flag("--no-render-sweep", forestNoSweep, "Skip the 3D reference and the layers/near sweep");
  forest->add_option("--images", forestOptions.images, "Write sample frames into this folder");
  forest->add_option("--tree-spacing", forestOptions.treeSpacing_m,
                     "Metres between placement slots; the density map decides which are kept")
      ->capture_default_str()->check(CLI::PositiveNumber);
  forest->add_option("--leaf-size", forestOptions.leafSize_m, "kd-tree leaf size in metres")
      ->capture_default_str()->check(CLI::PositiveNumber);
  forest->add_option("--near-fade-start", forestOptions.nearFadeStart_m, "Near trees start fading out here (m)")
      ->capture_default_str()->check(CLI::PositiveNumber);
  forest->add_option("--near-fade-end", forestOptions.nearFadeEnd_m, "Near trees are gone from here (m)")
      ->capture_default_str()->check(CLI::PositiveNumber);
  forest->add_option("--critical-angle", forestOptions.criticalAngle_deg,
                     "Fins where the dihedral angle through the ground is below this (degrees; 178 suits gentle relief)")
      ->capture_default_str()->check(CLI::Range(0.001, 359.999));
  forest->add_option("--fin-alpha-threshold", forestOptions.finAlphaThreshold,
                     "Reject fin groups whose view alpha is below this everywhere")
      ->capture_default_str()->check(CLI::Range(0.000001, 1.0));
  forest->add_option("--frames", forestOptions.frames, "Flight length in frames (60 Hz)")
      ->capture_default_str()->check(CLI::Range(1, 1000000));
  forest->add_option("--seed", forestOptions.seed, "Forest seed")->capture_default_str();
  forest->add_flag("--json", forestOptions.json, "Print one JSON object instead of the human summary");
  ig::PerfModelBenchOptions perfOptions;
  std::string perfSizes;
  CLI::App* perf = app.add_subcommand(
      "perfmodel",
      "Paper 002's rendering performance model against measured frame times (its Table 1):\n"
      "calibrates T_frag, T_tri, T_state, t_c, t_s and the occlusion-test cost on this GL\n"
      "implementation and, between its runs, draws 10 ... 300,000 random boxes and compares\n"
      "predicted with measured frame time (glFinish, median of repeats, the fastest of --sweeps\n"
      "runs of the sweep). JSON:\n"
      "points [{objects, measured_ms, predicted_ms, error_pct}], error_pct_median, error_pct_max,\n"
      "sweep_spread_pct_median/max, the calibrated constants. Goal: median <= 5 %,\n"
      "max <= 10 %.");
  perf->add_option("--sizes", perfSizes, "Box counts, comma-separated (default 10,100,1000,10000,50000,100000,300000)");
  perf->add_option("--width", perfOptions.width_px, "Frame width in pixels")->capture_default_str()->check(CLI::Range(16, 8192));
  perf->add_option("--height", perfOptions.height_px, "Frame height in pixels")->capture_default_str()->check(CLI::Range(16, 8192));
  perf->add_option("--fragment-work", perfOptions.fragmentWork, "Extra shading iterations per fragment (material cost)")
      ->capture_default_str()->check(CLI::Range(0, 1000));
  perf->add_option("--coverage", perfOptions.coverage, "Total projected box area, in screens")
      ->capture_default_str()->check(CLI::PositiveNumber);
  perf->add_option("--repeats", perfOptions.repeats, "Timed frames per point (median)")->capture_default_str()->check(CLI::Range(1, 1000));
  perf->add_option("--sweeps", perfOptions.sweeps,
                   "Runs of the whole sweep; a point's time is the fastest of its sweeps' medians (default 5, "
                   "--quick 1)")
      ->check(CLI::Range(1, 100));
  perf->add_option("--seed", perfOptions.seed, "Scene seed")->capture_default_str();
  perf->add_option("--calibration-runs", perfOptions.calibrationRuns,
                   "Calibration runs; each constant is the median of the runs (default 5, --quick 1)")
      ->check(CLI::Range(1, 9));
  perf->add_flag("--calibrate-first", perfOptions.calibrateFirst,
                 "Run every calibration run before the first sweep (the order before 2026-12-08; default: the\n"
                 "sweeps spread over the calibration runs, so that both see the same minutes of a shared machine)");
  perf->add_option("--cache", perfOptions.cachePath, "Calibration cache file ('' = calibrate every run)");
  perf->add_option("--calibration-trace", perfOptions.calibrationTrace,
                   "Write every frame of the calibration's interleaved loads here (CSV: run, repeat, load,\n"
                   "timed, frame_ms, submit_ms, thread_ms), to see the noise behind a constant");
  perf->add_flag("--quick", perfOptions.quick, "CI size: 10 ... 4000 boxes, fewer repeats, short calibration");
  perf->add_flag("--json", perfOptions.json, "Print one JSON object instead of the human summary");
  ig::AdaptiveBenchOptions adaptiveOptions;
  CLI::App* adaptive = app.add_subcommand(
      "adaptive",
      "Paper 002's adaptive strategy against its three fixed strategies (per-object commands, octree\n"
      "of indirect commands, octree + occlusion queries) on one animation in which boxes are added,\n"
      "move and get hidden; all four drawn side by side every frame. JSON: modes {percommand, octree,\n"
      "occlusion, adaptive: {mean_ms, p99_ms}}, adaptive_worst_ratio, adaptive_mean_ratio, trace.\n"
      "Goal: adaptive never > 1.1x the best fixed strategy, better on average.");
  adaptive->add_option("--width", adaptiveOptions.width_px, "Frame width in pixels")->capture_default_str()->check(CLI::Range(16, 8192));
  adaptive->add_option("--height", adaptiveOptions.height_px, "Frame height in pixels")->capture_default_str()->check(CLI::Range(16, 8192));
  adaptive->add_option("--objects", adaptiveOptions.objects, "Boxes at the end of the growing phase")
      ->capture_default_str()->check(CLI::Range(100, 1000000));
  adaptive->add_option("--frames-per-phase", adaptiveOptions.framesPerPhase, "Frames of each animation phase")
      ->capture_default_str()->check(CLI::Range(10, 1000000));
  adaptive->add_option("--window", adaptiveOptions.window, "Frames per trace sample")->capture_default_str()->check(CLI::Range(1, 100000));
  adaptive->add_option("--seed", adaptiveOptions.seed, "Scene seed")->capture_default_str();
  adaptive->add_option("--repeats", adaptiveOptions.repeats,
                       "Replay the animation this often; each frame's time is the fastest of the replays")
      ->capture_default_str()
      ->check(CLI::Range(1, 20));
  adaptive->add_option("--cache", adaptiveOptions.cachePath, "Calibration cache file ('' = calibrate every run)");
  adaptive->add_option("--trace", adaptiveOptions.tracePath, "Also write the JSON here (input of scripts/plot_adaptive.py)");
  adaptive->add_flag("--quick", adaptiveOptions.quick, "CI size: 4000 boxes, 40 frames per phase");
  adaptive->add_flag("--json", adaptiveOptions.json, "Print one JSON object instead of the human summary");
  ig::GovernorBenchOptions govOptions;
  CLI::App* gov = app.add_subcommand(
      "governor",
      "The frame governor on a rendered flight whose triangle load swings 10x (plain, mountains,\n"
      "jumps between them): ROAM terrain at 960x540, once with the governor steering the pixel\n"
      "tolerance and once at a fixed tolerance, side by side. JSON: frames, overrun_pct,\n"
      "frame_ms_p50/p99, load_swing, fixed {...}, tolerance_trace. Goal: overruns <= 0.1 %.");
  gov->add_option("--samples", govOptions.samples, "Height-field posts per side (30 m apart)")
      ->capture_default_str()->check(CLI::Range(65, 16385));
  gov->add_option("--rate", govOptions.rate_hz, "Frame rate in Hz; the work budget is the period")
      ->capture_default_str()->check(CLI::Range(1.0, 1000.0));
  gov->add_option("--seconds", govOptions.seconds, "Flight length in seconds")->capture_default_str()->check(CLI::PositiveNumber);
  gov->add_option("--width", govOptions.width_px, "Frame width in pixels")->capture_default_str()->check(CLI::Range(16, 8192));
  gov->add_option("--height", govOptions.height_px, "Frame height in pixels")->capture_default_str()->check(CLI::Range(16, 8192));
  gov->add_option("--tolerance", govOptions.tolerance_px, "Fixed run's tolerance and the governed run's finest (px)")
      ->capture_default_str()->check(CLI::PositiveNumber);
  gov->add_option("--max-tolerance", govOptions.maxTolerance_px, "Governed run's coarsest tolerance (px)")
      ->capture_default_str()->check(CLI::PositiveNumber);
  gov->add_option("--lod-budget", govOptions.lodBudget_ms, "Fixed run's ROAM work budget in ms (0 = converge)")
      ->capture_default_str()->check(CLI::NonNegativeNumber);
  gov->add_option("--plot", govOptions.plotFile, "Write a PNG of the tolerance trace (scripts/plot_governor.py)");
  gov->add_flag("--quick", govOptions.quick, "CI size: 513 posts, one 6 s lap");
  gov->add_flag("--cpu-time", govOptions.cpuTime,
                "Measure frame work in process CPU time (all threads) instead of wall time, for shared machines");
  gov->add_option("--spike-window", govOptions.spikeWindow_frames,
                  "Governor's spike headroom: frames over which the largest excess over the prediction is kept (0 = off)")
      ->capture_default_str()->check(CLI::Range(0, 1000000));
  gov->add_flag("--no-load-cap", govOptions.noLoadCap,
                "Governed run without the governor's load cap (ROAM's triangle cap while it converges): knobs alone");
  gov->add_flag("--json", govOptions.json, "Print one JSON object instead of the human summary");
  if (const auto rc = ig::parseCommandLine(app, argc, argv)) return *rc;
  if (perf->parsed()) {
    for (size_t i = 0; i < perfSizes.size();) {
      size_t j = perfSizes.find(',', i);
      if (j == std::string::npos) j = perfSizes.size();
      const std::string item = perfSizes.substr(i, j - i);
      char* end = nullptr;
      const unsigned long v = std::strtoul(item.c_str(), &end, 10);
      if (item.empty() || *end != '\0' || v == 0 || v > 100000000ul) {
        std::fprintf(stderr, "igbench perfmodel: --sizes: '%s' is not a box count (1 ... 100000000)\n", item.c_str());
        return 2;
      }
      perfOptions.sizes.push_back(static_cast<uint32_t>(v));
      i = j + 1;
    }
    return ig::runPerfModelBench(perfOptions);
  }
  if (adaptive->parsed()) return ig::runAdaptiveBench(adaptiveOptions);
  if (gov->parsed()) return ig::runGovernorBench(govOptions);
  if (forest->parsed()) {
    forestOptions.renderSweep = !forestNoSweep;
    return ig::runForestBench(forestOptions);
  }
  if (cells->parsed()) return ig::runCellsBench(cellsOptions);
  if (hdlod->parsed()) {
    hdlodOptions.compareSimplifiers = !noSimplifierCompare;
    hdlodOptions.render = !hdlodNoRender;
    return ig::runHdlodBench(hdlodOptions);
  }
  if (latency->parsed()) return ig::runLatencyBench(latencyOptions);
  if (fog->parsed()) return ig::runFogBench(fogOptions);
  if (queries->parsed()) return ig::runQueriesBench(queriesOptions);
  if (terrain->parsed()) {
    terrainOptions.render = !noRender;
    terrainOptions.baselines = !noBaselines;
    return ig::runTerrainBench(terrainOptions);
  }

  if (frame->parsed()) return runFrameSuite(configFile, o, json);
  return 2;
}
