// igbench adaptive: the adaptive strategy of paper 002 (render/dynamic_pass.h) against the three
// fixed strategies on one animation, rendered side by side: every animation frame is drawn by
// four passes holding identical scenes (per-object commands, octree, octree + occlusion queries,
// adaptive), in rotating order, each timed with glFinish and a monotonic clock, so all four see
// the same machine load. The animation (objects added over time, some moving):
//   phase "few-moving":  a few hundred boxes, all moving every frame (per-object commands win)
//   phase "growing":     static boxes added every frame up to `objects`, 1 % moving (octree wins)
//   phase "occluded":    walls added in front of the camera hide most boxes (occlusion wins)
// The whole animation is replayed `repeats` times with fresh passes, and each frame's time per
// mode is the fastest of the repetitions (a shared machine only adds time; the adaptive pass's
// choices depend on counts, not on the clock, so they repeat too: adaptive_mode_differs_frames).
// Reports mean and p99 frame ms per mode, a trace per window of `window` frames (mean ms of
// each mode, the adaptive mode, q, objects), adaptive_worst_ratio = max over windows (after the
// first) of adaptive / best fixed (window means), adaptive_mean_ratio = mean adaptive / mean of
// the best fixed mode per window. scripts/plot_adaptive.py plots the trace.
#pragma once

#include <cstdint>
#include <string>

namespace ig {

struct AdaptiveBenchOptions {
  int width_px = 480;
  int height_px = 270;
  uint32_t objects = 20000;       // boxes at the end of the growing phase
  int framesPerPhase = 100;
  int window = 10;                // frames per trace sample
  uint32_t seed = 1;
  int repeats = 3;                // the animation is replayed this often; each frame's time is the fastest
  std::string cachePath;          // calibration cache; "" = calibrate every run
  std::string tracePath;          // also write the JSON to this file (for the plot script)
  bool quick = false;             // CI size: 4000 boxes, 40 frames per phase, at most 2 repetitions
  bool json = false;
};

int runAdaptiveBench(const AdaptiveBenchOptions& options);

}  // namespace ig
