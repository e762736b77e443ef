// igbench forest: paper 004's forest (lod/forest*, render/forest_pass, ig/forest_layer) on a
// real DEM: a posts x posts window (32 m posts, default 7.68 x 7.68 km) of the SRTM tile that
// scripts/fetch-data fetches (the window with the most relief and no sea, resampled
// bilinearly from the tile's 92.8 m posts), >= 1 M trees, the Scopia pine and cypress from
// scripts/fetch-forest (procedural models when absent; the JSON says which).
//
// Measures, on one core for the CPU parts:
//   cull_ms_p50 / p99        near-tree selection (cull + gather + sort) over a 600-frame loop
//   frame_ms_p50             whole frame (terrain + forest, glFinish) over a rendered flight
//   trees_drawn_p50, fins_drawn_p50, layers
//   popping_max              largest mean per-pixel change (mean |dRGB| in 8-bit levels) between
//                            consecutive frames of a slow straight approach (1 m per frame)
//                            through the transition band; popping_max_no_forest the same flight
//                            with the forest switched off; popping_p50 / popping_p50_no_forest
//                            the median frame-to-frame change of both; popping_steady_excess the
//                            median per-frame difference of the two (the forest's own detail
//                            moving), popping_spike the largest excursion above it;
//                            popping_max_hard_switch the flight with 0.1 m bands (not --quick)
//   transition_max / _p50    the transitions alone: the first camera of the approach held still
//                            while the fade bands move 1 m nearer per frame (no motion: every
//                            change is the transition's); transition_popped_max the largest share
//                            of pixels changing by more than 8 levels in one frame; both also
//                            for the hard switch (not --quick)
//   sweep                    per (layers, near distance): frame_ms (p50) and psnr_db against a
//                            reference that draws every tree within the far plane as a 3D model
//                            (offline, slow)
//   drawn_sweep              the frame governor's layer knob: layers_drawn = n/2, n/4 ... 1 of the
//                            main run's n layers (composited groups) at near 500 m: frame_ms, psnr_db,
//                            and what a switch from n layers changes in one view: switch_change
//                            (mean |dRGB|, as popping_*) and switch_popped (as transition_popped_*)
#pragma once

#include <cstdint>
#include <string>

#include "render/forest_pass.h"

namespace ig {

struct ForestBenchOptions {
  int posts = 241;                 // terrain posts per side (32 m spacing: 7.68 km)
  std::string dem = "data/N57E011.hgt";    // "" or missing file: procedural terrain
  std::string models = "data/forest/src";  // Scopia OBJ folder; missing: procedural models
  double treeSpacing_m = 6.0;      // one placement slot per spacing^2 (density decides)
  double leafSize_m = 256.0;       // kd-tree leaf size
  double nearFadeStart_m = 300.0;  // near trees: alpha 1 up to here
  double nearFadeEnd_m = 500.0;    // ... 0 from here (the near range)
  double criticalAngle_deg = 178.0;  // fins where the dihedral angle through the ground is below
                                     // (empirical, per terrain: the gentle Swedish relief needs 178)
  double finAlphaThreshold = 0.05;   // cone rejection: groups with A below this everywhere
  int layers = 8;                  // shell layers of the main run
  int frames = 600;                // culling loop length (60 Hz)
  int renderFrames = 90;           // rendered flight (frame_ms)
  int popFrames = 240;             // slow approach (popping)
  int width = 640, height = 360;   // render size
  uint32_t seed = 1;
  bool quick = false;              // CI: small forest, few frames, a small sweep (~10 s)
  bool renderSweep = true;         // false: no reference and no sweep images (CPU sweep only)
  std::string images;              // folder for sample images ("" = none)
  bool json = false;
};

int runForestBench(const ForestBenchOptions& options);

// The textures the benchmark bakes: forestTextureDesc (ig/forest_tool.h) for its tree spacing
// and layers, as igd's start-up textures (a 24 m tile held one tree at 40 m spacing: layers
// 2.8x as dense as the trees), 128 px per layer in --quick mode.
render::ForestTextureDesc forestBenchTextureDesc(const ForestBenchOptions& options);

}  // namespace ig
