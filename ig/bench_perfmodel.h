// igbench perfmodel: the performance model of paper 002 (lod/perfmodel.h) against measured frame
// times, like the paper's Table 1. Calibrates the model on this GL implementation
// (render/perf_calibration.h; the sweeps below spread over the calibration's runs, so that the
// constants and the frames they predict share the phases of a shared machine, unless
// `calibrateFirst` or the cache), and for each scene size draws random boxes with the per-object
// command strategy and with the octree strategy (render/dynamic_pass.h), times frames (glFinish
// and a monotonic clock, median of repeats, the fastest of `sweeps` sweeps) and compares with the model's prediction from the
// frame's statistics (commands, submissions, triangles, fragments from the boxes' projected
// areas, frustum tests). Box sizes shrink with the count so the total coverage stays near
// `coverage` screens: few large boxes are fragment-bound, many small ones vertex/command-bound,
// the sizes between exercise the max() of (2).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ig {

struct PerfModelBenchOptions {
  std::vector<uint32_t> sizes;    // box counts; empty = 10 100 1000 10000 50000 100000 300000
  int width_px = 640;
  int height_px = 360;
  uint32_t fragmentWork = 8;      // material cost (extra shading iterations per fragment)
  double coverage = 0.8;          // total projected box area in screens
  int repeats = 7;                // timed frames per point (median)
  int sweeps = 0;                 // the sweep run this often (0: 5, --quick 1); a point's time is its fastest sweep's median
  uint32_t seed = 1;
  int calibrationRuns = 0;        // calibration runs, each constant their median (0: 5, --quick 1)
  bool calibrateFirst = false;    // every calibration run before the first sweep (default: the sweeps
                                  // spread over the runs, so that both share the machine's phases)
  std::string cachePath;          // calibration cache; "" = calibrate every run
  std::string calibrationTrace;   // CSV of every frame of the calibration's interleaved loads; "" = none
  bool quick = false;             // CI size: 10 100 1000 4000 boxes, 5 repeats, short calibration
  bool json = false;
};

int runPerfModelBench(const PerfModelBenchOptions& options);

}  // namespace ig
