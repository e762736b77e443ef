// igbench latency: how long a host packet takes to reach the screen, how fast CIGI decodes,
// and whether a packet flood disturbs the frame rate. Runs the real service (default scene,
// headless) with a real CIGI link on loopback and a sender thread playing the host.
#pragma once

#include <string>

namespace ig {

struct LatencyBenchOptions {
  std::string configFile = "config/igd.toml";
  double hostRate_hz = 60.0;       // host message rate during the latency run
  double seconds = 10.0;           // latency run length
  double floodRate_pps = 100000;   // packets per second during the flood run
  double floodSeconds = 10.0;      // flood run length
  int width_px = 0, height_px = 0; // 0 = the config's
  bool json = false;
};

int runLatencyBench(const LatencyBenchOptions& options);

}  // namespace ig
