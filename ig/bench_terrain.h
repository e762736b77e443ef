// igbench terrain: ROAM with enhMerge against its baselines (ROAM with diamond merges only,
// ROAM rebuilt every frame, block LOD) and ROAM Deferred under a per-update visit budget, on a
// real DEM (or a synthetic mountainous one up to 16385 x 16385) and a flight path that flies,
// turns hard and teleports; a teleport experiment (frames and time to converge at the new
// eye); the terrain frame against the rasterizer's triangle-rate limit; and a tolerance sweep
// (what accuracy costs in time) rendered headless against a full-resolution reference render.
// docs/terrain.md explains every field.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace ig {

struct TerrainBenchOptions {
  std::string demFile = "data/N57E011.hgt";  // scripts/fetch-data fetches it
  int syntheticSamples = 0;                  // > 0: a procedural N x N mountainous field (30 m) instead of the file
  double demSpacing_m = 0.0;                 // > 0: sample spacing of the DEM file (PNGs carry none; default 30 m)
  int frames = 240;                          // flight path length (60 Hz path time)
  int width_px = 1280, height_px = 720;
  bool render = true;                        // sweep render_ms / rmse / psnr and the raster comparison (needs GL)
  bool json = false;
  uint32_t deferredVisits = 2000;            // roam_deferred: node visits per update (0 = unlimited)
  // roam_deferred flight: time budget of an update, turned into node visits by the measured,
  // smoothed time per visit, as igd does (lod_budget_ms); 0 = a fixed deferredVisits.
  double budget_ms = 0.8;
  // After the teleport, roam_deferred converges under this time budget an update (the goal's
  // 3 ms teleport frame), or with 0 under a fixed teleportVisits.
  double teleportBudget_ms = 3.0;
  uint32_t teleportVisits = 9000;
  double lateness = 0.05;                    // roam_deferred: RoamView::lateness (0 = exact, the fresh-walk mesh)
  int teleportMaxFrames = 1000;              // give up converging after this many updates
  std::string cacheDir = "out/dem-cache";    // memory-mapped raw DEM cache ("" = decode every time, no mmap)
  int rasterFrames = 24;                     // frames timed for frame_vs_raster_ratio (0 = skip)
  bool baselines = true;                     // false: only roam_deferred, the teleport and the raster comparison
};

int runTerrainBench(const TerrainBenchOptions& options);

// The per-frame samples of one method's flight, of which igbench terrain reports percentiles.
// Frame 0 builds the mesh from the base triangles (the start-up, reported apart as
// startup_update_ms): it is in none of them, so update_ms_*, triangles_p50,
// visible_triangles_p50, emit_visible_ms_p50, visits_p50 and pending_p99 cover the same frames.
struct TerrainFlightSamples {
  std::vector<double> update_ms, cpu_ms, triangles, visible, emit_ms, visits, pending;
  void addUpdate(size_t frame, double ms, double cpuMs, double tris, double nodeVisits, double pendingNodes);
  void addEmit(size_t frame, double ms, double visibleTris);
};

}  // namespace ig
