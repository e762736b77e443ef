// igbench fog: what fog culling ([fog] cull) buys and what it costs in the picture. The service
// renders frames of the built-in host replay at a sweep of visibilities, each frame twice, side
// by side: with the far plane at the fog's opaque distance (render::fogOpaqueDistance_m) and with
// the host's far plane. Per visibility: triangles and frame time (select + submit + glFinish) of
// both, their ratio, and how far the pictures differ (largest difference in 8-bit levels, pixels
// that differ, PSNR).
#pragma once

#include <string>
#include <vector>

namespace ig {

struct FogBenchOptions {
  std::string configFile = "config/igd.toml";
  std::string sceneFile = "config/scenes/forest_roam.toml";  // "" = the config's
  std::vector<double> visibilities_m{300.0, 800.0, 2000.0, 5000.0, 12000.0, 30000.0};
  int frames = 12;                  // replay samples per visibility, spread over the replay
  int width_px = 640, height_px = 360;
  bool json = false;
};

int runFogBench(const FogBenchOptions& options);

}  // namespace ig
