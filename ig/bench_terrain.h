// igbench terrain: ROAM with enhMerge against its baselines (ROAM with diamond merges only,
// ROAM rebuilt every frame, block LOD) on a real DEM and a flight path that flies, turns hard
// and teleports; plus a tolerance sweep (what accuracy costs in time) rendered headless and
// compared with a full-resolution reference render of the same view.
#pragma once

#include <string>

namespace ig {

struct TerrainBenchOptions {
  std::string demFile = "data/N57E011.hgt";  // scripts/fetch-data fetches it
  int syntheticSamples = 0;                  // > 0: a procedural N x N field (30 m) instead of the file
  int frames = 240;                          // flight path length (60 Hz path time)
  int width_px = 1280, height_px = 720;
  bool render = true;                        // the sweep's render_ms / rmse / psnr (needs GL)
  bool json = false;
};

int runTerrainBench(const TerrainBenchOptions& options);

}  // namespace ig
