// Shared by the igd, igbench and igtool command lines: load the service config, apply the
// command-line overrides, load the scene. Errors name the file, key and value.
#pragma once

#include <optional>
#include <string>

#include "ig/config.h"

namespace ig {

struct Overrides {
  std::optional<int64_t> frames;
  bool freeRun = false;
  std::optional<std::string> output;       // headless | window | osmesa
  std::optional<int> width_px, height_px;
  std::optional<std::string> statsFile, statsFormat, snapshotDir, sceneFile, replayFile, statusFile;
  std::optional<int64_t> snapshotEvery;
};

// Loads both configs and applies overrides (validated like config values). Returns false
// with a printable error.
bool loadConfigs(const std::string& serviceFile, const Overrides& o, ServiceConfig& service, SceneConfig& scene,
                 std::string& error);

}  // namespace ig
