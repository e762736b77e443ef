#include "ig/app_common.h"

namespace ig {

bool loadConfigs(const std::string& serviceFile, const Overrides& o, ServiceConfig& service, SceneConfig& scene,
                 std::string& error) {
  ConfigError ce;
  ServiceConfig s;
  // An empty name would fail below as "cannot open: No such file or directory", naming nothing.
  if (serviceFile.empty()) {
    error = "service config file name is empty ('')";
    return false;
  }
  if (!loadServiceConfig(serviceFile, s, ce)) {
    error = ce.what();
    return false;
  }
  auto bad = [&](const std::string& option, const std::string& value, const std::string& why) {
    error = "command line: " + option + " = " + value + ": " + why;
    return false;
  };
  // The config keys these override must not be empty either (scene.file, host.replay_file,
  // output.snapshot_dir): an empty one would pass --check-config and fail only at start-up (exit 3).
  if (o.sceneFile && o.sceneFile->empty()) return bad("--scene", "''", "must not be empty");
  if (o.replayFile && o.replayFile->empty()) return bad("--replay", "''", "must not be empty");
  if (o.snapshotDir && o.snapshotDir->empty()) return bad("--snapshot-dir", "''", "must not be empty");
  if (o.frames) {
    if (*o.frames < 0) return bad("--frames", std::to_string(*o.frames), "must be >= 0");
    s.frames = *o.frames;
  }
  if (o.freeRun) s.freeRun = true;
  if (o.output) {
    if (*o.output == "headless") s.output = OutputMode::Headless;
    else if (*o.output == "window") s.output = OutputMode::Window;
    else if (*o.output == "osmesa") s.output = OutputMode::OSMesa;
    else return bad("--output", *o.output, "expected one of headless, window, osmesa");
  }
  if (o.width_px) {
    if (*o.width_px < 16 || *o.width_px > 16384) return bad("--width", std::to_string(*o.width_px), "must be in [16, 16384]");
    s.width_px = *o.width_px;
  }
  if (o.height_px) {
    if (*o.height_px < 16 || *o.height_px > 16384) return bad("--height", std::to_string(*o.height_px), "must be in [16, 16384]");
    s.height_px = *o.height_px;
  }
  // A [channel] frustum was checked against the file's output size; a new size must fit it too.
  if ((o.width_px || o.height_px) && !channelAspectMismatch(s).empty())
    return bad(o.width_px ? "--width" : "--height", std::to_string(o.width_px ? s.width_px : s.height_px),
               s.path + ": [channel] " + channelAspectMismatch(s));
  if (o.statsFile) s.statsFile = *o.statsFile;
  if (o.statusFile) s.statusFile = *o.statusFile;
  if (o.statsFormat) {
    if (*o.statsFormat == "csv") s.statsFormat = StatsFormat::Csv;
    else if (*o.statsFormat == "jsonl") s.statsFormat = StatsFormat::JsonLines;
    else return bad("--stats-format", *o.statsFormat, "expected csv or jsonl");
  }
  if (o.snapshotDir) s.snapshotDir = *o.snapshotDir;
  if (o.snapshotEvery) {
    if (*o.snapshotEvery < 0) return bad("--snapshot-every", std::to_string(*o.snapshotEvery), "must be >= 0");
    s.snapshotEvery = *o.snapshotEvery;
  }
  if (o.sceneFile) s.sceneFile = *o.sceneFile;
  if (o.replayFile) {
    s.replayFile = *o.replayFile;
    s.host = HostSource::Replay;
    // Only live links are recorded (host.record_file). Left set, the recorder would truncate
    // that file, which is often the very recording being replayed.
    s.recordFile.clear();
  }
  SceneConfig sc;
  if (!loadSceneConfig(s.sceneFile, sc, ce)) {
    error = ce.what();
    // A scene file that cannot be opened or read: also name where its path came from (the
    // service config's scene.file or --scene), not only the path.
    if (ce.line == 0 && ce.key.empty()) {
      error = (o.sceneFile ? "command line: --scene = " + *o.sceneFile
                           : s.path + ": scene.file = \"" + s.sceneFile + "\"") +
              ": " + ce.message;
    }
    return false;
  }
  service = std::move(s);
  scene = std::move(sc);
  return true;
}

}  // namespace ig
