// igbench hdlod: paper 000's Table 2 protocol on the synthetic construction site
// (lod/hdlod_site.h), selection only (no rendering yet: frame_ms and psnr_db come with the
// render slice). Builds the site and its HDLOD tree, then for each time (start, 1/3, 2/3, end
// of the schedule) and screen size of the scene (1/1, 1/4, 1/16 of the screen area) selects with
// HDLOD at r_px and without it (every present object in the frustum): triangles, draws and the
// median selection time. Then sweeps r (at 1/3 of the schedule, the paper's worst case, scene
// filling the screen). Then, unless disabled, builds the tree once per simplifier
// (lod/hdlod_simplify.h) and reports each one's build time, measured error and 1/16 ratio.
#pragma once

#include <cstdint>
#include <string>

namespace ig {

struct HdlodBenchOptions {
  double scale = 0.1;       // site scale: 1 = the paper's ~56k objects / ~4 M triangles
  uint32_t seed = 1;        // site generator seed
  int width_px = 1920, height_px = 1080;
  double fovY_deg = 45.0;
  double tolerance_px = 1.0;  // r for the cases
  int repeats = 31;         // selections per case (the median is reported)
  bool json = false;
  std::string simplifier = "meshoptimizer";  // parent geometry for the main run: meshoptimizer, openmesh, clustering
  bool compareSimplifiers = true;  // also build with each simplifier (field `simplifiers`)
};

int runHdlodBench(const HdlodBenchOptions& options);

}  // namespace ig
