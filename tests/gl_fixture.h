// Shared set-up for GL tests (*_gltest): the default configs loaded from the source tree at a
// small resolution, and helpers to render one frame with the default host recording.
#pragma once

#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "ig/app_common.h"
#include "ig/service.h"
#include "io/replay.h"

namespace ig::test {

inline const std::string kSource = IG_SOURCE_DIR;

// The default service + scene config, headless, 320x180, no files written, host none.
inline void defaultConfigs(ServiceConfig& service, SceneConfig& scene) {
  Overrides o;
  o.width_px = 320;
  o.height_px = 180;
  std::string error;
  ASSERT_TRUE(loadConfigs(kSource + "/config/igd.toml", o, service, scene, error)) << error;
  service.host = HostSource::None;
  service.statsFile = "";
  service.snapshotEvery = 0;
  service.snapshotFrames.clear();
}

inline io::HostState defaultHostAt(double t_s) {
  io::Recording rec;
  std::string error;
  EXPECT_TRUE(io::loadRecording(kSource + "/config/recordings/default.rec", rec, error)) << error;
  return io::sampleAt(rec, t_s).state;
}

// The rows of a stats CSV file as column name -> value.
inline std::vector<std::map<std::string, std::string>> readStatsCsv(const std::string& file) {
  std::vector<std::map<std::string, std::string>> rows;
  std::ifstream in(file);
  std::string line;
  const auto split = [](const std::string& l) {
    std::vector<std::string> f;
    for (size_t a = 0, b; a <= l.size(); a = b + 1) {
      b = std::min(l.find(',', a), l.size());
      f.push_back(l.substr(a, b - a));
    }
    return f;
  };
  if (!std::getline(in, line)) return rows;
  const std::vector<std::string> header = split(line);
  while (std::getline(in, line)) {
    const std::vector<std::string> f = split(line);
    std::map<std::string, std::string> row;
    for (size_t i = 0; i < header.size() && i < f.size(); ++i) row[header[i]] = f[i];
    rows.push_back(std::move(row));
  }
  return rows;
}

}  // namespace ig::test
