// igbench governor: the frame governor (lod/governor.h) on a real rendered replay whose load
// swings 10x. A procedural 30 m height field with a plain in the west and high mountains in the
// east, ROAM terrain (enhMerge, the service's path: stable triangle slots in the persistently
// mapped buffer), rendered headless at 960 x 540, and a scripted flight that cruises over the
// plain, turns towards the mountains (a ramp), flies over them, and jumps between the two
// (steps). The flight is rendered twice, frame by frame side by side in one process (each run
// its own ROAM, slots and renderer): once with the governor steering the pixel tolerance, once
// at a fixed tolerance (the scene's). Frame work = terrain (ROAM update within its work budget,
// visible-triangle emission, slot upload) + submit + GPU (glFinish), wall clock.
//
// JSON: frames, overruns, overrun_pct (work > budget), frame_ms_p50 / p99 / max, triangles_p50,
// tolerance_px_p50 / max, overruns_after_step (in the four frames from a jump of the eye: no
// prediction can see those), overruns_at_coarsest (with the tolerance already at its coarsest:
// nothing left to give), prediction_error_ms_p50 / p99, the governor's counters, load_swing
// (p99 / p1 of the triangle load at the fixed tolerance with every frame refined to convergence:
// a property of the flight, not of the machine), fixed (the same fields for the fixed run),
// load_avg_start / end and cpus (how busy the machine was: frame times are wall clock), and
// tolerance_trace (per frame: ms, predicted_ms, tolerance_px, triangles, fixed_ms,
// fixed_triangles). --plot writes a PNG of the trace with scripts/plot_governor.py.
#pragma once

#include <string>

namespace ig {

struct GovernorBenchOptions {
  int samples = 1025;              // height-field posts per side (30 m apart: 30.7 km)
  double rate_hz = 30.0;           // frame rate; the budget is the period
  double seconds = 60.0;           // flight length (two 30 s laps of the script)
  int width_px = 960, height_px = 540;
  double tolerance_px = 1.0;       // the fixed run's tolerance and the governed run's finest
  double maxTolerance_px = 32.0;   // the governed run's coarsest
  double lodBudget_ms = 0.0;       // the fixed run's ROAM work budget; 0 = converge every frame
  bool quick = false;              // CI size: 513 posts, one 6 s lap
  // Measure frame work (what the governor sees and overruns are judged by) in process CPU time
  // (all threads) instead of wall time: the work the frame needed, without the time it waited
  // for CPUs that other processes held. For a shared machine; production is wall time.
  bool cpuTime = false;
  // The governed run without the governor's load cap (ROAM's triangle cap): knobs alone, as
  // before the caps, for comparison.
  bool noLoadCap = false;
  int spikeWindow_frames = 0;      // the governor's spike headroom window; 0 = off
  bool json = false;
  std::string plotFile;            // "": no plot; else a PNG of the tolerance trace
};

int runGovernorBench(const GovernorBenchOptions& options);

}  // namespace ig
