// igbench forest: the near forest and the fins of paper 004 (lod/forest*) on a procedural
// terrain and distribution map: builds >= 1 M trees over 7.68 x 7.68 km (default), the kd-tree
// and the fins, then flies a low path over the forest and times, per frame, the near-tree
// selection (cull + gather + sort, one core). Reports cull_ms p50 / p99, trees drawn, fins drawn
// after tangent-cone rejection, and a sweep over near distances. No rendering yet: no frame
// time, PSNR or popping measure, no layers (see docs/forest.md).
#pragma once

#include <cstdint>

namespace ig {

struct ForestBenchOptions {
  int posts = 241;                 // terrain posts per side (32 m spacing: 7.68 km)
  double treeSpacing_m = 6.0;      // one placement slot per spacing^2 (density decides)
  double leafSize_m = 256.0;       // kd-tree leaf size
  double nearFadeStart_m = 300.0;  // near trees: alpha 1 up to here
  double nearFadeEnd_m = 500.0;    // ... 0 from here (the near range)
  double criticalAngle_deg = 175.0;  // fins where the dihedral angle through the ground is below
  double finAlphaThreshold = 0.05;   // cone rejection: groups with A below this everywhere
  int frames = 600;                // flight path length (60 Hz)
  uint32_t seed = 1;
  bool json = false;
};

int runForestBench(const ForestBenchOptions& options);

}  // namespace ig
