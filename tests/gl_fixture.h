// Shared set-up for GL tests (*_gltest): the default configs loaded from the source tree at a
// small resolution, and helpers to render one frame with the default host recording.
#pragma once

#include <gtest/gtest.h>

#include <string>

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

}  // namespace ig::test
