// igbench hdlod: paper 000's Table 2 protocol on the synthetic construction site
// (lod/hdlod_site.h). Builds the site and its HDLOD tree (or loads it from --cache), then for
// each time (start, 1/3, 2/3, end of the schedule, and "animation": the schedule played from 0
// to T over --animation-frames frames) and screen size of the scene (1/1, 1/4, 1/16 of the
// screen area) selects and renders with HDLOD at r_px and without it (every present object in
// the frustum at full detail): triangles, draws, the median selection time, the median frame
// time (selection + submission + glFinish, render/hdlod_pass.h) and the PSNR of the HDLOD image
// against the full one. Then sweeps r (at 1/3 of the schedule, the paper's worst case, scene
// filling the screen) with the same measures. Then, unless disabled, builds the tree once per
// simplifier (lod/hdlod_simplify.h) and reports each one's build time, measured error and 1/16
// ratio. --quick: a small site and image for CI (~10 s).
#pragma once

#include <cstdint>
#include <string>

namespace ig {

struct HdlodBenchOptions {
  double scale = 1.0;       // site scale: 1 = the paper's ~56k objects / ~4 M triangles
  uint32_t seed = 1;        // site generator seed
  int width_px = 1280, height_px = 720;
  double fovY_deg = 45.0;
  double tolerance_px = 1.0;  // r for the cases
  int msaa = 4;             // samples per pixel of both images (render::Renderer::init), as a cabin display renders
  int repeats = 21;         // selections per case (the median is reported)
  int frames = 5;           // rendered frames per case (the median is reported: ig::median, nearest rank)
  int animationFrames = 60; // frames of the "animation" case (0 to T)
  bool render = true;       // frame_ms and psnr_db (needs a GL context)
  bool quick = false;       // CI: scale 0.05, at most 480x270, 5 repeats, 2 frames, 8 animation frames, no simplifier comparison
  bool json = false;
  std::string simplifier = "meshoptimizer";  // parent geometry for the main run: meshoptimizer, openmesh, clustering
  double epsPerSize = 1.0 / 16.0;  // lod::hdlod::BuildConfig::epsPerSize: eps(l) / w(l)
  bool strictHausdorff = false;    // BuildConfig::strictHausdorff: eps_c against the drawn triangles only
  bool compareSimplifiers = true;  // also build with each simplifier (field `simplifiers`)
  double compareScale = 0.25;      // site scale of the simplifier comparison (OpenMesh is slow)
  std::string cacheFile;    // load the tree from this cache file, or build it and write it ("" = always build)
  std::string imageDir;     // write hdlod/full PNGs of every case here ("" = none)
  bool progress = false;    // progress bar on stderr even when it is not a terminal
};

int runHdlodBench(const HdlodBenchOptions& options);

}  // namespace ig
