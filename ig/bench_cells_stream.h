// igbench cells, the parts with a real mesh, a real server and pictures (paper 003):
//  - the Stanford bunny (scripts/fetch-cells) built into a cell database (igtool cells-build);
//  - a PSNR sweep over voxel budgets: every cell resident, the splat image at each budget
//    against the full-detail image (every visible cell refined to the finest level);
//  - streaming through nginx (scripts/cells-server) at several channel rates: the viewer looks
//    at the bunny from afar until the picture is at full quality, teleports close and stands
//    still; seconds_to_full_quality is the wall time until the realization's largest on-screen
//    voxel equals the all-resident optimum at that view. Frames run in real time at `fps`, W =
//    rate / fps bytes per frame. The quality (largest voxel in px, and PSNR against the final
//    picture every few frames) is recorded over time for scripts/plot_cells.py.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ig {

struct CellsStreamBenchOptions {
  std::string mesh = "data/cells/src/bunny.obj";  // y-up OBJ
  double size_m = 10.0;                           // the mesh's largest extent
  int cellLevels = 7;                             // L
  int voxelDepth = 3;                             // d (finest voxels: size_m / 2^(L - 1 + d))
  int width_px = 640, height_px = 360;
  std::vector<double> rates_mbit{1.0, 10.0, 100.0};
  double fps = 30.0;
  double timeout_s = 60.0;                        // per phase and rate
  uint64_t voxelBudget = 400000;                  // while streaming
  std::vector<uint64_t> sweepBudgets{10000, 30000, 100000, 300000, 1000000};
  std::string serverScript = "scripts/cells-server";
  std::string workDir;                            // "" : a fresh folder under /tmp
  bool stream = true;                             // the nginx part
  bool quick = false;                             // 10 and 100 Mbit/s only, 3 sweep points
};

struct CellsQualitySample {
  double t_s = 0.0;         // since the teleport
  double maxVoxel_px = 0.0;
  double psnr_db = -1.0;    // -1: not measured at this sample
  uint64_t voxels = 0;
  uint64_t residentBytes = 0;
};

struct CellsStreamRun {
  double rate_mbit = 0.0;
  uint64_t wBytes = 0;
  double secondsToFullQuality = -1.0;   // -1: not reached within the timeout
  double warmupSeconds = 0.0;           // the far view, from nothing to full quality
  double targetVoxel_px = 0.0;          // the all-resident optimum at the near view
  bool qualityMonotonic = true;         // the largest voxel never grew while standing still
  uint64_t bytesPerFrameMax = 0;        // largest sum S requested in one frame (<= W)
  int budgetExceededFrames = 0;         // frames with drawn voxels > budget or requested bytes > W
  uint64_t arrivedBytes = 0, wireBytes = 0;
  uint64_t retries = 0, corrupt = 0, broken = 0;
  double effectiveMbit = 0.0;           // payload bits / s while streaming after the teleport
  std::vector<CellsQualitySample> curve;
};

struct CellsSweepRow {
  uint64_t budget = 0;
  uint64_t voxels = 0;
  double maxVoxel_px = 0.0, selectMs = 0.0, renderMs = 0.0, psnr_db = 0.0;
};

struct CellsStreamBenchResult {
  uint32_t cells = 0;
  int levels = 0;
  std::vector<double> dimension;        // per voxel level of the mesh's pyramid: log2 N(l+1) / N(l)
  std::vector<double> boxCounting;      // levels 1 .. L: log2 N(l) / l (the paper's Table 1)
  uint64_t fileBytes = 0;
  uint64_t fullVoxels = 0;              // drawn in the full-detail reference
  double fullRenderMs = 0.0;
  std::vector<CellsSweepRow> sweep;
  std::vector<CellsStreamRun> runs;
  std::string context;                  // the GL renderer string
};

// Runs the parts above. False with `error` naming the input (a missing mesh names
// scripts/fetch-cells), the server script or the GL context.
bool runCellsStreamBench(const CellsStreamBenchOptions& options, CellsStreamBenchResult& out, std::string& error);

// JSON fragments for igbench cells: "mesh":{...},"sweep":[...],"streaming":[...] (no braces).
std::string cellsStreamJson(const CellsStreamBenchResult& r);

}  // namespace ig
