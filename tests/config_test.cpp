// Tests for ig/config: the shipped config files load with the expected values, and every kind of
// error names the right file, line, key and value without touching the output struct.
#include "ig/config.h"
#include "ig/app_common.h"
#include "ig/cli.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include <unistd.h>

namespace ig {
namespace {

namespace fs = std::filesystem;

const std::string kSourceDir = IG_SOURCE_DIR;

std::string normal(const fs::path& p) { return p.lexically_normal().string(); }

// A service config that passes validation; tests append or substitute keys.
constexpr const char* kMinimalService =
    "[host]\n"
    "source = \"none\"\n"
    "[scene]\n"
    "file = \"scenes/x.toml\"\n";

// Parses `text` as a service config that is expected to fail; returns the error.
ConfigError serviceError(const std::string& text) {
  ServiceConfig cfg;
  ConfigError error;
  EXPECT_FALSE(parseServiceConfig(text, "svc.toml", "/base", cfg, error)) << text;
  return error;
}

ConfigError sceneError(const std::string& text) {
  SceneConfig cfg;
  ConfigError error;
  EXPECT_FALSE(parseSceneConfig(text, "scene.toml", "/base", cfg, error)) << text;
  return error;
}

ServiceConfig parseServiceOk(const std::string& text, const std::string& baseDir = "/base") {
  ServiceConfig cfg;
  ConfigError error;
  EXPECT_TRUE(parseServiceConfig(text, "svc.toml", baseDir, cfg, error)) << error.what();
  return cfg;
}

SceneConfig parseSceneOk(const std::string& text, const std::string& baseDir = "/base") {
  SceneConfig cfg;
  ConfigError error;
  EXPECT_TRUE(parseSceneConfig(text, "scene.toml", baseDir, cfg, error)) << error.what();
  return cfg;
}

// ---- shipped files ---------------------------------------------------------------------------

TEST(ConfigShipped, ServiceConfigLoadsWithExpectedValues) {
  const std::string file = kSourceDir + "/config/igd.toml";
  const fs::path configDir = fs::path(kSourceDir) / "config";
  ServiceConfig cfg;
  ConfigError error;
  ASSERT_TRUE(loadServiceConfig(file, cfg, error)) << error.what();
  EXPECT_EQ(cfg.path, file);
  EXPECT_DOUBLE_EQ(cfg.rate_hz, 30.0);
  EXPECT_EQ(cfg.frames, 300);
  EXPECT_FALSE(cfg.freeRun);
  EXPECT_EQ(cfg.output, OutputMode::Headless);
  EXPECT_EQ(cfg.width_px, 960);
  EXPECT_EQ(cfg.height_px, 540);
  EXPECT_EQ(cfg.snapshotDir, normal(configDir / "../out/snapshots"));
  EXPECT_EQ(cfg.snapshotEvery, 60);
  EXPECT_TRUE(cfg.snapshotFrames.empty());
  EXPECT_EQ(cfg.statsFile, normal(configDir / "../out/frame_stats.csv"));
  EXPECT_EQ(cfg.statsFormat, StatsFormat::Csv);
  EXPECT_EQ(cfg.host, HostSource::Replay);
  EXPECT_EQ(cfg.replayFile, normal(configDir / "recordings/default.rec"));
  EXPECT_FALSE(cfg.replayLoop);
  EXPECT_EQ(cfg.sceneFile, normal(configDir / "scenes/default.toml"));
  EXPECT_DOUBLE_EQ(cfg.budgetFrame_ms, 0.0);
  EXPECT_EQ(cfg.budgetTriangles, 2'000'000);
  EXPECT_DOUBLE_EQ(cfg.watchdogInterval_s, 0.0);
}

TEST(ConfigShipped, DefaultSceneLoadsWithExpectedValues) {
  const std::string file = kSourceDir + "/config/scenes/default.toml";
  SceneConfig cfg;
  ConfigError error;
  ASSERT_TRUE(loadSceneConfig(file, cfg, error)) << error.what();
  EXPECT_EQ(cfg.path, file);
  EXPECT_EQ(cfg.name, "default");
  EXPECT_GE(cfg.originGeodetic[0], -90.0);
  EXPECT_LE(cfg.originGeodetic[0], 90.0);
  EXPECT_NE(cfg.originGeodetic[0], 0.0);  // set in the file, not the default
  ASSERT_TRUE(cfg.terrain.has_value());
  EXPECT_EQ(cfg.terrain->source, TerrainLayerConfig::Source::Procedural);
  EXPECT_EQ(cfg.terrain->seed, 20261123u);
  EXPECT_DOUBLE_EQ(cfg.terrain->size_m, 8192.0);
  EXPECT_DOUBLE_EQ(cfg.terrain->gridStep_m, 32.0);
  EXPECT_DOUBLE_EQ(cfg.terrain->heightScale_m, 600.0);
  EXPECT_EQ(cfg.terrain->offset_m, (std::array<double, 3>{-4096.0, -4096.0, 0.0}));
  EXPECT_EQ(cfg.terrain->chunkQuads, 64);
  EXPECT_FALSE(cfg.forest.has_value());
  EXPECT_FALSE(cfg.hdlod.has_value());
  EXPECT_TRUE(cfg.fog.enabled);
  EXPECT_DOUBLE_EQ(cfg.fog.visibility_m, 12000.0);
  EXPECT_GT(cfg.sun.elevation_deg, 0.0);
}

TEST(ConfigShipped, ServiceConfigPointsAtTheShippedScene) {
  ServiceConfig service;
  ConfigError error;
  ASSERT_TRUE(loadServiceConfig(kSourceDir + "/config/igd.toml", service, error)) << error.what();
  SceneConfig scene;
  EXPECT_TRUE(loadSceneConfig(service.sceneFile, scene, error)) << error.what();
  EXPECT_EQ(scene.name, "default");
}

// ---- defaults and accepted forms -------------------------------------------------------------

TEST(ConfigParse, MissingTablesKeepStructDefaults) {
  const ServiceConfig defaults;
  const ServiceConfig cfg = parseServiceOk(kMinimalService);
  EXPECT_EQ(cfg.path, "svc.toml");
  EXPECT_DOUBLE_EQ(cfg.rate_hz, defaults.rate_hz);
  EXPECT_EQ(cfg.frames, defaults.frames);
  EXPECT_EQ(cfg.output, defaults.output);
  EXPECT_EQ(cfg.width_px, defaults.width_px);
  EXPECT_EQ(cfg.height_px, defaults.height_px);
  EXPECT_EQ(cfg.statsFormat, defaults.statsFormat);
  EXPECT_EQ(cfg.budgetTriangles, defaults.budgetTriangles);
  EXPECT_EQ(cfg.host, HostSource::None);
  EXPECT_TRUE(cfg.replayFile.empty());
}

TEST(ConfigParse, AllServiceKeysAreRead) {
  const ServiceConfig cfg = parseServiceOk(
      "[frame]\nrate_hz = 120.5\nframes = 7\nfree_run = true\n"
      "[output]\nmode = \"osmesa\"\nwidth_px = 16\nheight_px = 16384\nmsaa = 4\nsnapshot_dir = \"snaps\"\n"
      "snapshot_every = 5\nsnapshot_frames = [0, 3, 9]\n"
      "[stats]\nfile = \"s.jsonl\"\nformat = \"jsonl\"\n"
      "[host]\nsource = \"replay\"\nreplay_file = \"r.rec\"\nreplay_loop = true\n"
      "[scene]\nfile = \"sc.toml\"\n"
      "[budget]\nframe_ms = 12.5\ntriangles = 1000\n"
      "[service]\nwatchdog_interval_s = 2.5\n");
  EXPECT_DOUBLE_EQ(cfg.rate_hz, 120.5);
  EXPECT_EQ(cfg.frames, 7);
  EXPECT_TRUE(cfg.freeRun);
  EXPECT_EQ(cfg.output, OutputMode::OSMesa);
  EXPECT_EQ(cfg.width_px, 16);
  EXPECT_EQ(cfg.height_px, 16384);
  EXPECT_EQ(cfg.msaa, 4);
  EXPECT_EQ(cfg.snapshotEvery, 5);
  EXPECT_EQ(cfg.snapshotFrames, (std::vector<int64_t>{0, 3, 9}));
  EXPECT_EQ(cfg.statsFormat, StatsFormat::JsonLines);
  EXPECT_EQ(cfg.host, HostSource::Replay);
  EXPECT_TRUE(cfg.replayLoop);
  EXPECT_DOUBLE_EQ(cfg.budgetFrame_ms, 12.5);
  EXPECT_EQ(cfg.budgetTriangles, 1000);
  EXPECT_DOUBLE_EQ(cfg.watchdogInterval_s, 2.5);
}

TEST(ConfigParse, IntegerAcceptedWhereFloatExpected) {
  const ServiceConfig service = parseServiceOk(std::string(kMinimalService) + "[frame]\nrate_hz = 60\n");
  EXPECT_DOUBLE_EQ(service.rate_hz, 60.0);
  const SceneConfig scene = parseSceneOk("[terrain]\nsize_m = 4096\noffset_m = [1, -2.5, 3]\n");
  ASSERT_TRUE(scene.terrain.has_value());
  EXPECT_DOUBLE_EQ(scene.terrain->size_m, 4096.0);
  EXPECT_EQ(scene.terrain->offset_m, (std::array<double, 3>{1.0, -2.5, 3.0}));
}

TEST(ConfigParse, EmptyTerrainTableEnablesLayerWithDefaults) {
  const SceneConfig cfg = parseSceneOk("[terrain]\n");
  ASSERT_TRUE(cfg.terrain.has_value());
  const TerrainLayerConfig defaults;
  EXPECT_EQ(cfg.terrain->seed, defaults.seed);
  EXPECT_DOUBLE_EQ(cfg.terrain->size_m, defaults.size_m);
  EXPECT_EQ(cfg.terrain->chunkQuads, defaults.chunkQuads);
  EXPECT_FALSE(cfg.forest.has_value());
  EXPECT_FALSE(cfg.hdlod.has_value());
}

TEST(ConfigParse, AbsentTerrainTableLeavesLayerDisabled) {
  const SceneConfig cfg = parseSceneOk("name = \"empty\"\n");
  EXPECT_EQ(cfg.name, "empty");
  EXPECT_FALSE(cfg.terrain.has_value());
}

TEST(ConfigParse, RangeBoundariesAreInclusiveWhereDocumented) {
  const ServiceConfig cfg = parseServiceOk(std::string(kMinimalService) +
                                           "[frame]\nrate_hz = 1000\n[output]\nwidth_px = 16384\n");
  EXPECT_DOUBLE_EQ(cfg.rate_hz, 1000.0);
  const SceneConfig scene = parseSceneOk(
      "[origin]\nlat_deg = -90\nlon_deg = 180\nheight_m = 100000\n"
      "[terrain]\nseed = 4294967295\nchunk_quads = 1024\n[sun]\ncolor = [0, 1, 0.5]\n");
  EXPECT_DOUBLE_EQ(scene.originGeodetic[0], -90.0);
  EXPECT_DOUBLE_EQ(scene.originGeodetic[1], 180.0);
  EXPECT_DOUBLE_EQ(scene.originGeodetic[2], 100000.0);
  ASSERT_TRUE(scene.terrain.has_value());
  EXPECT_EQ(scene.terrain->seed, 4294967295u);
  EXPECT_EQ(scene.terrain->chunkQuads, 1024);
}

// ---- paths ------------------------------------------------------------------------------------

TEST(ConfigPaths, RelativePathsResolvedAgainstBaseDir) {
  const ServiceConfig cfg = parseServiceOk(
      "[output]\nsnapshot_dir = \"snaps\"\n[stats]\nfile = \"../stats.csv\"\n"
      "[host]\nreplay_file = \"/abs/r.rec\"\n[scene]\nfile = \"scenes/a.toml\"\n",
      "/base/dir");
  EXPECT_EQ(cfg.snapshotDir, "/base/dir/snaps");
  EXPECT_EQ(cfg.statsFile, "/base/stats.csv");
  EXPECT_EQ(cfg.replayFile, "/abs/r.rec");  // absolute stays as written
  EXPECT_EQ(cfg.sceneFile, "/base/dir/scenes/a.toml");
}

TEST(ConfigPaths, DefaultPathsAreResolvedToo) {
  const ServiceConfig cfg = parseServiceOk(kMinimalService, "/cfg");
  EXPECT_EQ(cfg.snapshotDir, "/cfg/out/snapshots");
  EXPECT_EQ(cfg.statsFile, "/cfg/out/frame_stats.csv");
}

TEST(ConfigPaths, EmptyStatsFileMeansNoStatsFile) {
  const ServiceConfig cfg = parseServiceOk(std::string(kMinimalService) + "[stats]\nfile = \"\"\n", "/cfg");
  EXPECT_EQ(cfg.statsFile, "");
}

TEST(ConfigPaths, LayerFilesResolvedButNotRequiredToExist) {
  const SceneConfig cfg = parseSceneOk(
      "[terrain]\nlod = \"roam\"\n[forest]\nmap = \"trees/a.png\"\n[hdlod]\nschedule = \"/abs/h.sched\"\ncache = \"cache/h.bin\"\n", "/scenes");
  ASSERT_TRUE(cfg.forest.has_value());
  ASSERT_TRUE(cfg.hdlod.has_value());
  EXPECT_EQ(cfg.forest->map, "/scenes/trees/a.png");
  EXPECT_EQ(cfg.forest->assets, "");
  EXPECT_EQ(cfg.hdlod->schedule, "/abs/h.sched");
  EXPECT_EQ(cfg.hdlod->cache, "/scenes/cache/h.bin");
}

TEST(ConfigPaths, LoadResolvesAgainstTheFilesFolder) {
  const fs::path dir = fs::path(testing::TempDir()) / "ig_config_test_load";
  fs::create_directories(dir);
  const fs::path file = dir / "scene.toml";
  {
    std::ofstream out(file);
    out << "name = \"tmp\"\n[terrain]\nlod = \"block\"\n[forest]\nmap = \"trees.png\"\n";
  }
  SceneConfig cfg;
  ConfigError error;
  ASSERT_TRUE(loadSceneConfig(file.string(), cfg, error)) << error.what();
  ASSERT_TRUE(cfg.forest.has_value());
  EXPECT_EQ(cfg.forest->map, normal(dir / "trees.png"));
  fs::remove_all(dir);
}

// ---- errors -----------------------------------------------------------------------------------

TEST(ConfigErrors, UnknownKeyInKnownTable) {
  const ConfigError e = serviceError(std::string(kMinimalService) + "[frame]\nrate_hz = 30\nfps = 60\n");
  EXPECT_EQ(e.file, "svc.toml");
  EXPECT_EQ(e.line, 7);
  EXPECT_EQ(e.key, "frame.fps");
  EXPECT_EQ(e.value, "60");
  EXPECT_NE(e.message.find("unknown key"), std::string::npos) << e.message;
  EXPECT_NE(e.message.find("rate_hz, frames, free_run"), std::string::npos) << e.message;
}

TEST(ConfigErrors, UnknownTable) {
  const ConfigError e = serviceError(std::string(kMinimalService) + "\n[graphics]\nx = 1\n");
  EXPECT_EQ(e.line, 6);
  EXPECT_EQ(e.key, "graphics");
  EXPECT_EQ(e.value, "");  // a [table] header has no value text
  EXPECT_EQ(e.what().rfind("svc.toml:6: graphics: unknown table (known keys: ", 0), 0u) << e.what();
  EXPECT_NE(e.message.find("unknown table"), std::string::npos) << e.message;
  EXPECT_NE(e.message.find("frame, output, stats, host, scene, channel, budget, governor, service"), std::string::npos)
      << e.message;
}

TEST(ConfigErrors, UnknownTopLevelKeyInScene) {
  const ConfigError e = sceneError("name = \"a\"\nnmae = \"typo\"\n");
  EXPECT_EQ(e.file, "scene.toml");
  EXPECT_EQ(e.line, 2);
  EXPECT_EQ(e.key, "nmae");
  EXPECT_EQ(e.value, "\"typo\"");
  EXPECT_NE(e.message.find("unknown key"), std::string::npos);
}

TEST(ConfigErrors, FirstUnknownKeyInFileOrderIsReported) {
  const ConfigError e = sceneError("[sun]\nzenith = 1\nalbedo = 2\n");
  EXPECT_EQ(e.line, 2);
  EXPECT_EQ(e.key, "sun.zenith");
}

TEST(ConfigErrors, WrongTypeNamesExpectedType) {
  const ConfigError e = serviceError(std::string(kMinimalService) + "[output]\nwidth_px = \"wide\"\n");
  EXPECT_EQ(e.line, 6);
  EXPECT_EQ(e.key, "output.width_px");
  EXPECT_EQ(e.value, "\"wide\"");
  EXPECT_NE(e.message.find("expected an integer"), std::string::npos) << e.message;
}

TEST(ConfigErrors, FloatWhereIntegerExpectedIsWrongType) {
  const ConfigError e = serviceError(std::string(kMinimalService) + "[frame]\nframes = 2.5\n");
  EXPECT_EQ(e.key, "frame.frames");
  EXPECT_EQ(e.value, "2.5");
  EXPECT_NE(e.message.find("expected an integer"), std::string::npos) << e.message;
}

TEST(ConfigErrors, ValueWhereTableExpected) {
  const ConfigError e = serviceError("frame = 5\n[scene]\nfile = \"x\"\n");
  EXPECT_EQ(e.line, 1);
  EXPECT_EQ(e.key, "frame");
  EXPECT_EQ(e.value, "5");
  EXPECT_NE(e.message.find("expected a table"), std::string::npos) << e.message;
}

TEST(ConfigErrors, WrongTypeBoolean) {
  const ConfigError e = sceneError("[fog]\nenabled = \"yes\"\n");
  EXPECT_EQ(e.key, "fog.enabled");
  EXPECT_NE(e.message.find("boolean"), std::string::npos) << e.message;
}

TEST(ConfigErrors, OutOfRangeNamesTheRange) {
  ConfigError e = serviceError(std::string(kMinimalService) + "[frame]\nrate_hz = 0\n");
  EXPECT_EQ(e.line, 6);
  EXPECT_EQ(e.key, "frame.rate_hz");
  EXPECT_EQ(e.value, "0");
  EXPECT_NE(e.message.find("[0.01, 1000]"), std::string::npos) << e.message;

  e = serviceError(std::string(kMinimalService) + "[frame]\nrate_hz = 1000.5\n");
  EXPECT_EQ(e.value, "1000.5");

  e = serviceError(std::string(kMinimalService) + "[output]\nheight_px = 15\n");
  EXPECT_EQ(e.key, "output.height_px");
  EXPECT_EQ(e.value, "15");
  EXPECT_NE(e.message.find("[16, 16384]"), std::string::npos) << e.message;

  e = serviceError(std::string(kMinimalService) + "[output]\nmsaa = 3\n");
  EXPECT_EQ(e.key, "output.msaa");
  EXPECT_EQ(e.value, "3");
  EXPECT_NE(e.message.find("1, 2, 4 or 8"), std::string::npos) << e.message;
  e = serviceError(std::string(kMinimalService) + "[output]\nmsaa = 16\n");
  EXPECT_EQ(e.key, "output.msaa");
  EXPECT_NE(e.message.find("[1, 8]"), std::string::npos) << e.message;

  e = serviceError(std::string(kMinimalService) + "[output]\nmonitor = -1\n");
  EXPECT_EQ(e.key, "output.monitor");
  EXPECT_EQ(e.value, "-1");
  e = serviceError(std::string(kMinimalService) + "[output]\nfullscreen = 1\n");
  EXPECT_EQ(e.key, "output.fullscreen");

  e = serviceError(std::string(kMinimalService) + "[budget]\ntriangles = 999\n");
  EXPECT_EQ(e.key, "budget.triangles");
  EXPECT_NE(e.message.find(">= 1000"), std::string::npos) << e.message;

  e = sceneError("[origin]\nlat_deg = 90.5\n");
  EXPECT_EQ(e.key, "origin.lat_deg");
  EXPECT_NE(e.message.find("[-90, 90]"), std::string::npos) << e.message;

  e = sceneError("[terrain]\nseed = -1\n");
  EXPECT_EQ(e.key, "terrain.seed");

  e = sceneError("[terrain]\nseed = 4294967296\n");
  EXPECT_EQ(e.key, "terrain.seed");

  e = sceneError("[terrain]\nchunk_quads = 3\n");
  EXPECT_EQ(e.key, "terrain.chunk_quads");

  e = sceneError("[fog]\nvisibility_m = 0\n");
  EXPECT_EQ(e.key, "fog.visibility_m");
}

TEST(ConfigErrors, ArrayElementOutOfRangeNamesTheElement) {
  ConfigError e = serviceError(std::string(kMinimalService) + "[output]\nsnapshot_frames = [1, -2, 3]\n");
  EXPECT_EQ(e.line, 6);
  EXPECT_EQ(e.key, "output.snapshot_frames[1]");
  EXPECT_EQ(e.value, "-2");

  e = sceneError("[sun]\ncolor = [0.5, 1.5, 0.5]\n");
  EXPECT_EQ(e.key, "sun.color[1]");
  EXPECT_EQ(e.value, "1.5");
  EXPECT_NE(e.message.find("[0, 1]"), std::string::npos) << e.message;
}

TEST(ConfigErrors, ArrayOfWrongLength) {
  const ConfigError e = sceneError("[fog]\ncolor = [0.5, 0.5]\n");
  EXPECT_EQ(e.line, 2);
  EXPECT_EQ(e.key, "fog.color");
  EXPECT_EQ(e.value, "[0.5, 0.5]");
  EXPECT_NE(e.message.find("exactly 3"), std::string::npos) << e.message;
  EXPECT_NE(e.message.find("got 2 elements"), std::string::npos) << e.message;
}

TEST(ConfigErrors, TerrainGridRatioChecked) {
  ConfigError e = sceneError("[terrain]\nsize_m = 8192\ngrid_step_m = 0.5\n");
  EXPECT_EQ(e.line, 3);
  EXPECT_EQ(e.key, "terrain.grid_step_m");
  EXPECT_NE(e.message.find("[2, 8192]"), std::string::npos) << e.message;

  e = sceneError("[terrain]\nsize_m = 40\n");  // default grid step 32 -> 1.25 quads
  EXPECT_EQ(e.key, "terrain.size_m");
  EXPECT_EQ(e.line, 2);
}

TEST(ConfigErrors, NanAndInfinityRejected) {
  ConfigError e = serviceError(std::string(kMinimalService) + "[frame]\nrate_hz = nan\n");
  EXPECT_EQ(e.line, 6);
  EXPECT_EQ(e.key, "frame.rate_hz");
  EXPECT_EQ(e.value, "nan");
  EXPECT_NE(e.message.find("finite"), std::string::npos) << e.message;

  e = sceneError("[terrain]\noffset_m = [0, -inf, 0]\n");
  EXPECT_EQ(e.key, "terrain.offset_m[1]");
  EXPECT_EQ(e.value, "-inf");

  // Even where the range is one-sided, inf is not accepted.
  e = serviceError(std::string(kMinimalService) + "[service]\nwatchdog_interval_s = inf\n");
  EXPECT_EQ(e.key, "service.watchdog_interval_s");
}

TEST(ConfigErrors, BadEnumListsAllowedValues) {
  ConfigError e = serviceError(std::string(kMinimalService) + "[output]\nmode = \"fullscreen\"\n");
  EXPECT_EQ(e.line, 6);
  EXPECT_EQ(e.key, "output.mode");
  EXPECT_EQ(e.value, "\"fullscreen\"");
  EXPECT_NE(e.message.find("\"headless\", \"window\", \"osmesa\""), std::string::npos) << e.message;

  e = serviceError("[stats]\nformat = \"json\"\n[host]\nsource=\"none\"\n[scene]\nfile=\"x\"\n");
  EXPECT_EQ(e.key, "stats.format");
  EXPECT_NE(e.message.find("\"csv\", \"jsonl\""), std::string::npos) << e.message;

  e = sceneError("[terrain]\nsource = \"dted\"\n");
  EXPECT_EQ(e.key, "terrain.source");
  EXPECT_NE(e.message.find("\"procedural\""), std::string::npos) << e.message;
}

TEST(ConfigErrors, MissingRequiredSceneFile) {
  const ConfigError e = serviceError("[host]\nsource = \"none\"\n");
  EXPECT_EQ(e.line, 0);
  EXPECT_EQ(e.key, "scene.file");
  EXPECT_EQ(e.value, "");
  EXPECT_NE(e.message.find("required"), std::string::npos) << e.message;
}

TEST(ConfigErrors, EmptyRequiredPathRejected) {
  const ConfigError e = serviceError("[host]\nsource = \"none\"\n[scene]\nfile = \"\"\n");
  EXPECT_EQ(e.line, 4);
  EXPECT_EQ(e.key, "scene.file");
}

TEST(ConfigErrors, ReplayFileRequiredForReplaySource) {
  ConfigError e = serviceError("[host]\nsource = \"replay\"\n[scene]\nfile = \"x\"\n");
  EXPECT_EQ(e.key, "host.replay_file");
  EXPECT_EQ(e.line, 1);  // points at the [host] table
  // "replay" is the default source, so a file without [host] needs it too.
  e = serviceError("[scene]\nfile = \"x\"\n");
  EXPECT_EQ(e.key, "host.replay_file");
  EXPECT_EQ(e.line, 0);
}

TEST(ConfigErrors, LayerTablesAreChecked) {
  ConfigError e = sceneError("name = \"a\"\n[forest]\nnear_fade_end_m = 200\n");
  EXPECT_EQ(e.key, "forest.near_fade_end_m");  // not beyond near_fade_start_m (300)
  EXPECT_EQ(e.line, 3);
  e = sceneError("[forest]\narea_m = [0, 0, 1]\n");
  EXPECT_EQ(e.key, "forest.area_m");
  e = sceneError("[forest]\nlayers = 0\n");
  EXPECT_EQ(e.key, "forest.layers");
  e = sceneError("[hdlod]\nfiles = \"x\"\n");
  EXPECT_EQ(e.key, "hdlod.files");  // unknown key is reported before the missing one
  e = sceneError("[hdlod]\nsimplifier = \"qslim\"\n");
  EXPECT_EQ(e.key, "hdlod.simplifier");
  e = sceneError("[hdlod]\ntolerance_px = 0\n");
  EXPECT_EQ(e.key, "hdlod.tolerance_px");
  // An empty [hdlod] table is the synthetic construction site.
  const SceneConfig site = parseSceneOk("[hdlod]\n", "/scenes");
  ASSERT_TRUE(site.hdlod.has_value());
  EXPECT_EQ(site.hdlod->schedule, "");
  EXPECT_EQ(site.hdlod->siteScale, 0.25);
}

TEST(ConfigErrors, TomlSyntaxErrorHasLine) {
  const ConfigError e = serviceError("[frame]\nrate_hz = 30\nframes = \n[scene]\n");
  EXPECT_EQ(e.file, "svc.toml");
  EXPECT_EQ(e.line, 3);
  EXPECT_EQ(e.key, "");
  EXPECT_FALSE(e.message.empty());
}

TEST(ConfigErrors, DuplicateKeyIsSyntaxError) {
  const ConfigError e = sceneError("name = \"a\"\n\nname = \"b\"\n");
  EXPECT_EQ(e.line, 3);
}

TEST(ConfigErrors, MissingFile) {
  const std::string file = kSourceDir + "/config/does_not_exist.toml";
  ServiceConfig cfg;
  ConfigError error;
  EXPECT_FALSE(loadServiceConfig(file, cfg, error));
  EXPECT_EQ(error.file, file);
  EXPECT_EQ(error.line, 0);
  EXPECT_EQ(error.message, "cannot open: No such file or directory");
  EXPECT_EQ(error.what(), file + ": cannot open: No such file or directory");

  SceneConfig scene;
  EXPECT_FALSE(loadSceneConfig(file, scene, error));
  EXPECT_EQ(error.message, "cannot open: No such file or directory");
}

TEST(ConfigErrors, DirectoryIsNotAConfigFile) {
  ServiceConfig cfg;
  ConfigError error;
  EXPECT_FALSE(loadServiceConfig(kSourceDir + "/config", cfg, error));
  EXPECT_EQ(error.line, 0);
  EXPECT_EQ(error.message.rfind("cannot open: ", 0), 0u) << error.message;
}

TEST(ConfigErrors, OutputUntouchedOnFailure) {
  ServiceConfig service;
  service.width_px = 1234;
  service.sceneFile = "sentinel";
  service.path = "before";
  ConfigError error;
  // Valid keys before the bad one must not leak into `out`.
  EXPECT_FALSE(parseServiceConfig("[output]\nwidth_px = 640\n[scene]\nfile = \"s\"\n[frame]\nrate_hz = -1\n",
                                  "svc.toml", "/base", service, error));
  EXPECT_EQ(service.width_px, 1234);
  EXPECT_EQ(service.sceneFile, "sentinel");
  EXPECT_EQ(service.path, "before");
  EXPECT_EQ(error.key, "frame.rate_hz");

  SceneConfig scene;
  scene.name = "sentinel";
  EXPECT_FALSE(parseSceneConfig("name = \"new\"\n[terrain]\nseed = 5\n[fog]\nvisibility_m = nan\n", "scene.toml",
                                "/base", scene, error));
  EXPECT_EQ(scene.name, "sentinel");
  EXPECT_FALSE(scene.terrain.has_value());

  EXPECT_FALSE(loadSceneConfig("/nonexistent/scene.toml", scene, error));
  EXPECT_EQ(scene.name, "sentinel");
}

// ---- formatting -------------------------------------------------------------------------------

TEST(ConfigErrorFormat, WhatFormat) {
  ConfigError e{"a.toml", 12, "output.width_px", "\"wide\"", "wrong type"};
  EXPECT_EQ(e.what(), "a.toml:12: output.width_px = \"wide\": wrong type");
  e.line = 0;
  EXPECT_EQ(e.what(), "a.toml: output.width_px = \"wide\": wrong type");
  e.value = "";
  EXPECT_EQ(e.what(), "a.toml: output.width_px: wrong type");
  e.key = "";
  e.line = 3;
  EXPECT_EQ(e.what(), "a.toml:3: wrong type");
}

TEST(ConfigErrorFormat, WhatOfARealError) {
  const ConfigError e = serviceError(std::string(kMinimalService) + "[output]\nwidth_px = 99999\n");
  EXPECT_EQ(e.what(), "svc.toml:6: output.width_px = 99999: out of range (allowed range: [16, 16384])");
}

TEST(ConfigEnums, ToStringGivesTomlSpellings) {
  EXPECT_STREQ(toString(OutputMode::Headless), "headless");
  EXPECT_STREQ(toString(OutputMode::Window), "window");
  EXPECT_STREQ(toString(OutputMode::OSMesa), "osmesa");
  EXPECT_STREQ(toString(StatsFormat::Csv), "csv");
  EXPECT_STREQ(toString(StatsFormat::JsonLines), "jsonl");
  EXPECT_STREQ(toString(HostSource::None), "none");
  EXPECT_STREQ(toString(HostSource::Replay), "replay");
}

TEST(ConfigEnums, ToStringRoundTripsThroughTheParser) {
  for (OutputMode mode : {OutputMode::Headless, OutputMode::Window, OutputMode::OSMesa}) {
    const ServiceConfig cfg =
        parseServiceOk(std::string(kMinimalService) + "[output]\nmode = \"" + toString(mode) + "\"\n");
    EXPECT_EQ(cfg.output, mode);
  }
}

}  // namespace
}  // namespace ig

namespace ig {
namespace {

TEST(ConfigTerrainLod, DemRoamAndBlockKeysParse) {
  SceneConfig cfg;
  ConfigError error;
  ASSERT_TRUE(parseSceneConfig("[terrain]\nsource = \"dem\"\nlod = \"roam\"\nfile = \"dem/a.hgt\"\n"
                               "spacing_m = 30\ntolerance_px = 0.5\nlod_budget_ms = 3\npng_scale_m = 0.1\nmorph_s = 0.4\n",
                               "scene.toml", "/base", cfg, error))
      << error.what();
  ASSERT_TRUE(cfg.terrain);
  EXPECT_EQ(cfg.terrain->source, TerrainLayerConfig::Source::Dem);
  EXPECT_EQ(cfg.terrain->lod, TerrainLayerConfig::Lod::Roam);
  EXPECT_EQ(cfg.terrain->file, "/base/dem/a.hgt");
  EXPECT_DOUBLE_EQ(cfg.terrain->demSpacing_m, 30.0);
  EXPECT_DOUBLE_EQ(cfg.terrain->tolerance_px, 0.5);
  EXPECT_DOUBLE_EQ(cfg.terrain->lodBudget_ms, 3.0);
  EXPECT_DOUBLE_EQ(cfg.terrain->pngScale_m, 0.1);
  EXPECT_DOUBLE_EQ(cfg.terrain->morph_s, 0.4);
  ASSERT_TRUE(parseSceneConfig("[terrain]\nlod = \"block\"\n", "scene.toml", "/base", cfg, error)) << error.what();
  EXPECT_EQ(cfg.terrain->lod, TerrainLayerConfig::Lod::Block);
  EXPECT_EQ(cfg.terrain->source, TerrainLayerConfig::Source::Procedural);
}

TEST(ConfigTerrainLod, ErrorsNameKeyAndValue) {
  ConfigError e = sceneError("[terrain]\nsource = \"dem\"\nlod = \"roam\"\n");
  EXPECT_EQ(e.key, "terrain.file");
  EXPECT_NE(e.message.find("needs the DEM file"), std::string::npos) << e.what();
  e = sceneError("[terrain]\nsource = \"dem\"\nfile = \"a.hgt\"\n");
  EXPECT_EQ(e.key, "terrain.lod");
  EXPECT_NE(e.message.find("\"roam\" or \"block\""), std::string::npos) << e.what();
  e = sceneError("[terrain]\nlod = \"vdpm\"\n");
  EXPECT_EQ(e.key, "terrain.lod");
  EXPECT_EQ(e.line, 2);
  EXPECT_EQ(e.value, "\"vdpm\"");
  e = sceneError("[terrain]\ntolerance_px = 0\n");
  EXPECT_EQ(e.key, "terrain.tolerance_px");
  e = sceneError("[terrain]\nmorph_s = -1\n");
  EXPECT_EQ(e.key, "terrain.morph_s");
  e = sceneError("[terrain]\ntolerance_px = nan\n");
  EXPECT_EQ(e.key, "terrain.tolerance_px");
}

TEST(ConfigTerrainLod, RoamModeParsesAndABadOneIsNamed) {
  SceneConfig cfg;
  ConfigError error;
  ASSERT_TRUE(parseSceneConfig("[terrain]\nlod = \"roam\"\n", "scene.toml", "/base", cfg, error)) << error.what();
  EXPECT_EQ(cfg.terrain->roamMode, TerrainLayerConfig::RoamMode::Deferred);  // the default
  ASSERT_TRUE(parseSceneConfig("[terrain]\nlod = \"roam\"\nroam_mode = \"enhmerge\"\n", "scene.toml", "/base", cfg, error))
      << error.what();
  EXPECT_EQ(cfg.terrain->roamMode, TerrainLayerConfig::RoamMode::EnhMerge);
  ASSERT_TRUE(parseSceneConfig("[terrain]\nroam_mode = \"deferred\"\n", "scene.toml", "/base", cfg, error)) << error.what();
  EXPECT_EQ(cfg.terrain->roamMode, TerrainLayerConfig::RoamMode::Deferred);
  ConfigError e = sceneError("[terrain]\nlod = \"roam\"\nroam_mode = \"mergequeue\"\n");
  EXPECT_EQ(e.key, "terrain.roam_mode");
  EXPECT_EQ(e.line, 3);
  EXPECT_EQ(e.value, "\"mergequeue\"");
  EXPECT_NE(e.message.find("\"deferred\", \"enhmerge\""), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("roam_mode"), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("mergequeue"), std::string::npos) << e.what();
  e = sceneError("[terrain]\nroam_mode = 1\n");
  EXPECT_EQ(e.key, "terrain.roam_mode");
}

}  // namespace
}  // namespace ig

namespace ig {
namespace {
TEST(ConfigShipped, EverySceneInConfigScenesLoads) {
  int n = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kSourceDir + "/config/scenes")) {
    if (entry.path().extension() != ".toml") continue;
    SceneConfig cfg;
    ConfigError error;
    EXPECT_TRUE(loadSceneConfig(entry.path().string(), cfg, error)) << error.what();
    EXPECT_TRUE(cfg.terrain || cfg.hdlod) << entry.path() << " draws nothing";
    if (cfg.forest) {
      EXPECT_TRUE(cfg.terrain && cfg.terrain->lod != TerrainLayerConfig::Lod::Grid) << entry.path();
    }
    ++n;
  }
  EXPECT_GE(n, 5);
}
}  // namespace
}  // namespace ig

namespace ig {
namespace {
TEST(ConfigHostLinks, LinkTablesAreReadIntoTheLinkConfigs) {
  ServiceConfig cfg;
  ConfigError error;
  ASSERT_TRUE(parseServiceConfig(
      "[host]\nsource = \"cigi\"\nlink_timeout_s = 0.25\nrecord_file = \"rec/live.rec\"\n"
      "[host.cigi]\nbind_address = \"127.0.0.1\"\nport = 9004\nhost_address = \"10.0.0.2\"\nhost_port = 9005\n"
      "sync = true\nentity_id = 7\nview_id = 2\ndatabase = 3\n"
      "[host.can]\ninterface = \"can1\"\nbase_id = 0x200\nstale_ms = 50\n"
      "[host.modbus]\ntcp_address = \"0.0.0.0\"\ntcp_port = 5020\nunit_id = 9\nserial_device = \"/dev/ttyS1\"\n"
      "baud = 19200\nparity = \"E\"\ndata_bits = 7\nstop_bits = 2\nword_order = \"high_first\"\n"
      "[scene]\nfile = \"s.toml\"\n",
      "svc.toml", "/base", cfg, error))
      << error.what();
  EXPECT_EQ(cfg.host, HostSource::Cigi);
  EXPECT_DOUBLE_EQ(cfg.linkTimeout_s, 0.25);
  EXPECT_EQ(cfg.recordFile, "/base/rec/live.rec");
  EXPECT_EQ(cfg.cigi.bind_address, "127.0.0.1");
  EXPECT_EQ(cfg.cigi.port, 9004);
  EXPECT_EQ(cfg.cigi.host_address, "10.0.0.2");
  EXPECT_EQ(cfg.cigi.host_port, 9005);
  EXPECT_TRUE(cfg.cigi.sync);
  EXPECT_EQ(cfg.cigi.entity_id, 7);
  EXPECT_EQ(cfg.cigi.view_id, 2);
  EXPECT_EQ(cfg.cigi.database, 3);
  EXPECT_EQ(cfg.can.interface, "can1");
  EXPECT_EQ(cfg.can.baseId, 0x200u);
  EXPECT_EQ(cfg.can.stale_ms, 50);
  EXPECT_EQ(cfg.modbus.tcpAddress, "0.0.0.0");
  EXPECT_EQ(cfg.modbus.tcpPort, 5020);
  EXPECT_EQ(cfg.modbus.unitId, 9);
  EXPECT_EQ(cfg.modbus.serialDevice, "/dev/ttyS1");
  EXPECT_EQ(cfg.modbus.baud, 19200);
  EXPECT_EQ(cfg.modbus.parity, 'E');
  EXPECT_EQ(cfg.modbus.dataBits, 7);
  EXPECT_EQ(cfg.modbus.stopBits, 2);
  EXPECT_EQ(cfg.modbus.wordOrder, io::modbus::WordOrder::HighFirst);
  for (const char* source : {"can", "modbus-tcp", "modbus-rtu", "none", "replay"}) {
    ServiceConfig c;
    const std::string extra = std::string(source) == "replay" ? "replay_file = \"r.rec\"\n" : "";
    ASSERT_TRUE(parseServiceConfig(std::string("[host]\nsource = \"") + source + "\"\n" + extra +
                                       "[host.modbus]\nserial_device = \"/dev/ttyS0\"\n[scene]\nfile = \"s.toml\"\n",
                                   "svc.toml", "/base", c, error))
        << error.what();
    EXPECT_STREQ(toString(c.host), source);
  }
}

TEST(ConfigHostLinks, BadLinkValuesAreNamed) {
  ConfigError e = serviceError("[host]\nsource = \"cigi\"\n[host.cigi]\nport = 70000\n[scene]\nfile = \"s\"\n");
  EXPECT_EQ(e.key, "host.cigi.port");
  EXPECT_EQ(e.value, "70000");
  EXPECT_EQ(e.line, 4);
  e = serviceError("[host]\nsource = \"can\"\n[host.can]\nbase_id = 0x7FC\n[scene]\nfile = \"s\"\n");
  EXPECT_EQ(e.key, "host.can.base_id");
  EXPECT_EQ(e.value, "0x7FC");
  e = serviceError("[host]\nsource = \"modbus-tcp\"\n[host.modbus]\nword_order = \"middle\"\n[scene]\nfile = \"s\"\n");
  EXPECT_EQ(e.key, "host.modbus.word_order");
  EXPECT_NE(e.message.find("\"low_first\", \"high_first\""), std::string::npos) << e.message;
  e = serviceError("[host]\nsource = \"modbus-rtu\"\n[scene]\nfile = \"s\"\n");
  EXPECT_EQ(e.key, "host.modbus.serial_device");
  EXPECT_NE(e.message.find("modbus-rtu"), std::string::npos) << e.message;
  e = serviceError("[host]\nsource = \"replay\"\nreplay_file = \"a.rec\"\nrecord_file = \"b.rec\"\n[scene]\nfile = \"s\"\n");
  EXPECT_EQ(e.key, "host.record_file");
  EXPECT_NE(e.message.find("only live host links are recorded"), std::string::npos) << e.message;
  e = serviceError("[host]\nsource = \"cigi\"\nlink_timeout_s = 0\n[scene]\nfile = \"s\"\n");
  EXPECT_EQ(e.key, "host.link_timeout_s");
  e = serviceError("[host]\nsource = \"udp\"\n[scene]\nfile = \"s\"\n");
  EXPECT_NE(e.message.find("\"cigi\", \"can\", \"modbus-tcp\", \"modbus-rtu\""), std::string::npos) << e.message;
  e = serviceError("[host]\nsource = \"cigi\"\n[host.cigi]\nprot = 1\n[scene]\nfile = \"s\"\n");
  EXPECT_EQ(e.key, "host.cigi.prot");
}

// The links' own checks run in the loader too: an address that does not parse or a baud rate the
// serial line cannot take is a config error naming the line (exit 2, found by --check-config),
// not a start-up failure (exit 3) after "config OK".
TEST(ConfigHostLinks, LinkChecksRunWhenTheConfigIsLoaded) {
  ConfigError e = serviceError("[host]\nsource = \"cigi\"\n[host.cigi]\nbind_address = \"1.2.3\"\n[scene]\nfile = \"s\"\n");
  EXPECT_EQ(e.key, "host.cigi.bind_address");
  EXPECT_EQ(e.value, "\"1.2.3\"");
  EXPECT_EQ(e.line, 4);
  EXPECT_NE(e.message.find("not an IPv4 address"), std::string::npos) << e.message;
  e = serviceError("[host]\nsource = \"modbus-tcp\"\n[host.modbus]\ntcp_address = \"x\"\n[scene]\nfile = \"s\"\n");
  EXPECT_EQ(e.key, "host.modbus.tcp_address");
  EXPECT_EQ(e.line, 4);
  e = serviceError("[host]\nsource = \"modbus-rtu\"\n[host.modbus]\nserial_device = \"/dev/ttyS0\"\nbaud = 1201\n"
                   "[scene]\nfile = \"s\"\n");
  EXPECT_EQ(e.key, "host.modbus.baud");
  EXPECT_EQ(e.value, "1201");
  EXPECT_EQ(e.line, 5);
  EXPECT_NE(e.message.find("must be one of 1200"), std::string::npos) << e.message;
  // A value holding " = " or ": " does not confuse the key, the value or the reason.
  e = serviceError("[host]\nsource = \"cigi\"\n[host.cigi]\nhost_address = \"gw = a: b\"\n[scene]\nfile = \"s\"\n");
  EXPECT_EQ(e.key, "host.cigi.host_address");
  EXPECT_EQ(e.value, "\"gw = a: b\"");
  EXPECT_EQ(e.line, 4);
  EXPECT_EQ(e.message, "not an IPv4 address or known host name");
  e = serviceError("[host]\nsource = \"can\"\n[host.can]\ninterface = \"can: 0\"\n[scene]\nfile = \"s\"\n");
  EXPECT_EQ(e.key, "host.can.interface");
  EXPECT_EQ(e.line, 4);
  EXPECT_EQ(e.value, "\"can: 0\"");
  EXPECT_EQ(e.message, "must be a network interface name of 1..15 characters");
  // A link that is not the source is not checked (its table may hold another site's values).
  parseServiceOk("[host]\nsource = \"none\"\n[host.cigi]\nbind_address = \"1.2.3\"\n[scene]\nfile = \"s\"\n");
  parseServiceOk("[host]\nsource = \"modbus-rtu\"\n[host.modbus]\nserial_device = \"/dev/ttyS0\"\nbaud = 9600\n"
                 "[scene]\nfile = \"s\"\n");
}

// [forest] stands on the terrain mesh that lod = "roam" or "block" builds: with lod = "grid" (the
// default) or no [terrain], the scene is refused when it is loaded, naming the line.
TEST(ConfigScene, ForestNeedsATerrainMesh) {
  ConfigError e = sceneError("name = \"a\"\n[terrain]\nlod = \"grid\"\n[forest]\n");
  EXPECT_EQ(e.key, "terrain.lod");
  EXPECT_EQ(e.value, "\"grid\"");
  EXPECT_EQ(e.line, 3);
  EXPECT_NE(e.message.find("[forest] needs [terrain] with lod = \"roam\" or \"block\""), std::string::npos) << e.message;
  e = sceneError("name = \"a\"\n[terrain]\n[forest]\n");
  EXPECT_EQ(e.key, "terrain.lod");
  EXPECT_EQ(e.line, 2);
  e = sceneError("name = \"a\"\n[forest]\n");
  EXPECT_EQ(e.key, "forest");
  EXPECT_EQ(e.line, 2);
  EXPECT_EQ(parseSceneOk("[terrain]\nlod = \"roam\"\n[forest]\n").terrain->lod, TerrainLayerConfig::Lod::Roam);
}
}  // namespace
}  // namespace ig

namespace ig {
namespace {

TEST(ConfigGovernor, KeysAreReadAndCrossChecked) {
  const ServiceConfig cfg = parseServiceOk(std::string(kMinimalService) +
                                           "[governor]\nenabled = true\ndecrease_above = 0.9\nincrease_below = 0.5\n"
                                           "spike_window_frames = 120\n"
                                           "[governor.terrain]\nmin_px = 0.5\nmax_px = 16\nload_exponent = -2\n",
                                           "/cfg");
  EXPECT_TRUE(cfg.governor.enabled);
  EXPECT_EQ(cfg.governor.decreaseAbove, 0.9);
  EXPECT_EQ(cfg.governor.increaseBelow, 0.5);
  EXPECT_EQ(cfg.governor.terrainMin_px, 0.5);
  EXPECT_EQ(cfg.governor.terrainMax_px, 16.0);
  EXPECT_EQ(cfg.governor.terrainLoadExponent, -2.0);
  EXPECT_EQ(cfg.governor.spikeWindow_frames, 120);
  ConfigError e = serviceError(std::string(kMinimalService) + "[governor]\ndecrease_above = 0.6\nincrease_below = 0.7\n");
  EXPECT_EQ(e.key, "governor.increase_below");
  EXPECT_NE(e.message.find("decrease_above"), std::string::npos) << e.what();
  e = serviceError(std::string(kMinimalService) + "[governor.terrain]\nmin_px = 40\nmax_px = 32\n");
  EXPECT_EQ(e.key, "governor.terrain.min_px");
  e = serviceError(std::string(kMinimalService) + "[governor]\nmax_increase = 0.9\n");
  EXPECT_EQ(e.key, "governor.max_increase");
  e = serviceError(std::string(kMinimalService) + "[governor.terrain]\nload_exponent = 2\n");
  EXPECT_EQ(e.key, "governor.terrain.load_exponent");
  e = serviceError(std::string(kMinimalService) + "[governor]\nspike_window_frames = -1\n");
  EXPECT_EQ(e.key, "governor.spike_window_frames");
  EXPECT_EQ(e.value, "-1");
}

// The parser's ranges must not let through what lod::Governor::validate refuses (|load_exponent|
// <= 8): igd --check-config said OK and igd then failed at start-up without naming the file.
TEST(ConfigGovernor, LoadExponentRangeMatchesTheGovernor) {
  ConfigError e = serviceError(std::string(kMinimalService) + "[governor.terrain]\nload_exponent = -9\n");
  EXPECT_EQ(e.key, "governor.terrain.load_exponent");
  EXPECT_EQ(e.value, "-9");
  e = serviceError(std::string(kMinimalService) + "[governor.hdlod]\nload_exponent = -9\n");
  EXPECT_EQ(e.key, "governor.hdlod.load_exponent");
  EXPECT_EQ(parseServiceOk(std::string(kMinimalService) + "[governor.terrain]\nload_exponent = -8\n").governor.terrainLoadExponent,
            -8.0);
}

// Tiny rates and huge budgets overflowed the int64 nanosecond periods and deadlines (rate_hz =
// 1e-300 ran with a negative period and negative missed slots).
TEST(ConfigErrors, ExtremeRatesAndBudgetsRejected) {
  ConfigError e = serviceError(std::string(kMinimalService) + "[frame]\nrate_hz = 1e-300\n");
  EXPECT_EQ(e.key, "frame.rate_hz");
  EXPECT_EQ(e.value, "1e-300");
  e = serviceError(std::string(kMinimalService) + "[budget]\nframe_ms = 1e300\n");
  EXPECT_EQ(e.key, "budget.frame_ms");
  e = serviceError(std::string(kMinimalService) + "[service]\nwatchdog_interval_s = 1e300\n");
  EXPECT_EQ(e.key, "service.watchdog_interval_s");
  EXPECT_EQ(parseServiceOk(std::string(kMinimalService) + "[frame]\nrate_hz = 0.01\n").rate_hz, 0.01);
}

// --replay on a config that records a live link: recording stays off (only live links are
// recorded); the recorder used to truncate the record file, often the very file being replayed.
TEST(ConfigOverrides, ReplayOverrideTurnsRecordingOff) {
  const fs::path dir = fs::temp_directory_path() / ("igd_cfg_override_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "scene.toml") << "name = \"x\"\n";
  std::ofstream(dir / "igd.toml") << "[host]\nsource = \"cigi\"\nrecord_file = \"run.rec\"\n"
                                     "[scene]\nfile = \"scene.toml\"\n";
  Overrides o;
  ServiceConfig service;
  SceneConfig scene;
  std::string error;
  ASSERT_TRUE(loadConfigs((dir / "igd.toml").string(), o, service, scene, error)) << error;
  EXPECT_EQ(service.recordFile, normal(dir / "run.rec"));
  o.replayFile = (dir / "run.rec").string();
  ASSERT_TRUE(loadConfigs((dir / "igd.toml").string(), o, service, scene, error)) << error;
  EXPECT_EQ(service.host, HostSource::Replay);
  EXPECT_EQ(service.replayFile, (dir / "run.rec").string());
  EXPECT_TRUE(service.recordFile.empty()) << service.recordFile;
  fs::remove_all(dir);
}

// A scene file that does not exist: the error names the path and where it came from (the
// service config's file and its scene.file key, or --scene), not only a path.
TEST(ConfigOverrides, MissingSceneFileNamesTheKeyAndTheServiceConfig) {
  const fs::path dir = fs::temp_directory_path() / ("igd_cfg_noscene_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "igd.toml") << "[host]\nsource = \"none\"\n[scene]\nfile = \"gone.toml\"\n";
  const std::string file = (dir / "igd.toml").string();
  ServiceConfig service;
  SceneConfig scene;
  std::string error;
  EXPECT_FALSE(loadConfigs(file, Overrides{}, service, scene, error));
  EXPECT_EQ(error, file + ": scene.file = \"" + normal(dir / "gone.toml") + "\": cannot open: No such file or directory");
  Overrides o;
  o.sceneFile = (dir / "other.toml").string();
  EXPECT_FALSE(loadConfigs(file, o, service, scene, error));
  EXPECT_EQ(error, "command line: --scene = " + *o.sceneFile + ": cannot open: No such file or directory");
  fs::remove_all(dir);
}

// The keys --scene, --replay and --snapshot-dir override refuse "" in the file; the options must
// too (a config error, exit 2, found by --check-config), not fail at start-up or open "".
TEST(ConfigOverrides, EmptyFileOverridesAreRefusedNamingTheOption) {
  const fs::path dir = fs::temp_directory_path() / ("igd_cfg_empty_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "scene.toml") << "name = \"x\"\n";
  std::ofstream(dir / "igd.toml") << "[host]\nsource = \"none\"\n[scene]\nfile = \"scene.toml\"\n";
  const std::string file = (dir / "igd.toml").string();
  for (const char* option : {"--scene", "--replay", "--snapshot-dir"}) {
    Overrides o;
    if (option == std::string("--scene")) o.sceneFile = "";
    if (option == std::string("--replay")) o.replayFile = "";
    if (option == std::string("--snapshot-dir")) o.snapshotDir = "";
    ServiceConfig service;
    SceneConfig scene;
    std::string error;
    EXPECT_FALSE(loadConfigs(file, o, service, scene, error)) << option;
    EXPECT_NE(error.find(std::string(option) + " = '': must not be empty"), std::string::npos) << option << ": " << error;
    EXPECT_TRUE(service == ServiceConfig{}) << option << ": the output was written";
  }
  ServiceConfig service;
  SceneConfig scene;
  std::string error;
  EXPECT_FALSE(loadConfigs("", Overrides{}, service, scene, error));
  EXPECT_NE(error.find("file name is empty"), std::string::npos) << error;
  fs::remove_all(dir);
}

// ig::parseCommandLine (igd, igtool, igbench): CLI11 2.1's Range lets NaN through, clamps an
// integer beyond int64 and reads "-1" as 2^64 - 1 for an unsigned option; each is a bad option
// (2), in subcommands too, while good values still parse.
TEST(CommandLine, NonFiniteAndOutOfRangeNumbersAreBadOptions) {
  struct Case {
    std::vector<std::string> args;
    std::optional<int> rc;
  };
  const std::vector<Case> cases = {
      {{"--rate", "nan"}, 2},        {{"--rate", "inf"}, 2},          {{"--rate", "1e999"}, 2},
      {{"--rate", "2.5"}, {}},       {{"--time", "nan"}, 2},          {{"--time", "-1e300"}, {}},
      {{"--frames", "99999999999999999999"}, 2},                      {{"--frames", "-5"}, {}},
      {{"--budget", "-1"}, 2},       {{"--budget", "18446744073709551616"}, 2},
      {{"--budget", "7"}, {}},       {{"sub", "--xyz", "0", "nan", "0"}, 2},
      {{"sub", "--xyz", "0", "1", "2"}, {}},                          {{"--rate", "abc"}, 2},
      // A decimal with leading zeros is decimal (base 0 read it as octal: 0300 = 192), also for
      // the option's own range check (017 as octal is 15, outside [16, 20]).
      {{"--frames", "0300"}, {}},    {{"--level", "017"}, {}},        {{"--level", "021"}, 2},
  };
  for (const Case& c : cases) {
    CLI::App app{"test"};
    double rate = 1.0, time_s = 0.0;
    int64_t frames = 0;
    uint64_t budget = 0;
    std::vector<double> xyz;
    app.add_option("--rate", rate)->check(CLI::Range(1.0, 100.0));
    app.add_option("--time", time_s);
    app.add_option("--frames", frames);
    app.add_option("--budget", budget);
    int level = 16;
    app.add_option("--level", level)->check(CLI::Range(16, 20));
    CLI::App* sub = app.add_subcommand("sub");
    sub->add_option("--xyz", xyz)->expected(3);
    std::vector<std::string> storage = {"prog"};
    storage.insert(storage.end(), c.args.begin(), c.args.end());
    std::vector<char*> argv;
    for (std::string& s : storage) argv.push_back(s.data());
    const std::optional<int> rc = parseCommandLine(app, static_cast<int>(argv.size()), argv.data());
    std::string joined;
    for (const auto& a : c.args) joined += a + " ";
    EXPECT_EQ(rc, c.rc) << joined;
    if (!c.rc && c.args[0] == "--rate") {
      EXPECT_EQ(rate, 2.5);
    }
    if (!c.rc && c.args[0] == "--budget") {
      EXPECT_EQ(budget, 7u);
    }
    if (!c.rc && c.args[0] == "--frames" && c.args[1] == "0300") {
      EXPECT_EQ(frames, 300);
    }
    if (!c.rc && c.args[0] == "--level") {
      EXPECT_EQ(level, 17);
    }
  }
}

TEST(ConfigGovernor, ForestNearDistanceBounds) {
  ServiceConfig cfg = parseServiceOk(std::string(kMinimalService) + "[governor.forest]\nmin_m = 50\nmax_m = 400\n", "/cfg");
  EXPECT_EQ(cfg.governor.forestMin_m, 50.0);
  EXPECT_EQ(cfg.governor.forestMax_m, 400.0);
  ConfigError e = serviceError(std::string(kMinimalService) + "[governor.forest]\nmin_m = 500\nmax_m = 400\n");
  EXPECT_EQ(e.key, "governor.forest.min_m");
  EXPECT_NE(e.message.find("max_m (400)"), std::string::npos) << e.what();
  e = serviceError(std::string(kMinimalService) + "[governor.forest]\nmin_m = 0\n");
  EXPECT_EQ(e.key, "governor.forest.min_m");
  EXPECT_EQ(e.value, "0");
  // The shell layer count's bounds.
  EXPECT_EQ(cfg.governor.forestMinLayers, 1);
  EXPECT_EQ(cfg.governor.forestMaxLayers, 0);
  cfg = parseServiceOk(std::string(kMinimalService) + "[governor.forest]\nmin_layers = 2\nmax_layers = 6\n", "/cfg");
  EXPECT_EQ(cfg.governor.forestMinLayers, 2);
  EXPECT_EQ(cfg.governor.forestMaxLayers, 6);
  e = serviceError(std::string(kMinimalService) + "[governor.forest]\nmin_layers = 7\nmax_layers = 6\n");
  EXPECT_EQ(e.key, "governor.forest.min_layers");
  EXPECT_NE(e.message.find("max_layers (6)"), std::string::npos) << e.what();
  e = serviceError(std::string(kMinimalService) + "[governor.forest]\nmin_layers = 0\n");
  EXPECT_EQ(e.key, "governor.forest.min_layers");
  EXPECT_EQ(e.value, "0");
  e = serviceError(std::string(kMinimalService) + "[governor.forest]\nmax_layers = 33\n");
  EXPECT_EQ(e.key, "governor.forest.max_layers");
}

TEST(ConfigGovernor, HdlodToleranceBounds) {
  ServiceConfig cfg = parseServiceOk(std::string(kMinimalService) + "[governor.hdlod]\nmin_px = 2\nmax_px = 8\nload_exponent = -1.5\n", "/cfg");
  EXPECT_EQ(cfg.governor.hdlodMin_px, 2.0);
  EXPECT_EQ(cfg.governor.hdlodMax_px, 8.0);
  EXPECT_EQ(cfg.governor.hdlodLoadExponent, -1.5);
  ConfigError e = serviceError(std::string(kMinimalService) + "[governor.hdlod]\nmin_px = 9\nmax_px = 8\n");
  EXPECT_EQ(e.key, "governor.hdlod.min_px");
  EXPECT_NE(e.message.find("max_px (8)"), std::string::npos) << e.what();
  e = serviceError(std::string(kMinimalService) + "[governor.hdlod]\nload_exponent = 1\n");
  EXPECT_EQ(e.key, "governor.hdlod.load_exponent");
  EXPECT_EQ(e.value, "1");
}

TEST(ConfigGovernor, CellsVoxelBudgetBounds) {
  ServiceConfig cfg = parseServiceOk(std::string(kMinimalService), "/cfg");
  EXPECT_EQ(cfg.governor.cellsMin_voxels, 10000u);
  EXPECT_EQ(cfg.governor.cellsMax_voxels, 0u);  // the scene's voxel_budget
  cfg = parseServiceOk(std::string(kMinimalService) + "[governor.cells]\nmin_voxels = 5000\nmax_voxels = 400000\n", "/cfg");
  EXPECT_EQ(cfg.governor.cellsMin_voxels, 5000u);
  EXPECT_EQ(cfg.governor.cellsMax_voxels, 400000u);
  ConfigError e = serviceError(std::string(kMinimalService) + "[governor.cells]\nmin_voxels = 500000\nmax_voxels = 400000\n");
  EXPECT_EQ(e.key, "governor.cells.min_voxels");
  EXPECT_NE(e.message.find("max_voxels (400000)"), std::string::npos) << e.what();
  e = serviceError(std::string(kMinimalService) + "[governor.cells]\nmin_voxels = 10\n");
  EXPECT_EQ(e.key, "governor.cells.min_voxels");
  EXPECT_EQ(e.value, "10");
  e = serviceError(std::string(kMinimalService) + "[governor.cells]\nmax_voxels = -1\n");
  EXPECT_EQ(e.key, "governor.cells.max_voxels");
  e = serviceError(std::string(kMinimalService) + "[governor.cells]\nmin_voxel = 5000\n");  // a misspelt key
  EXPECT_EQ(e.key, "governor.cells.min_voxel");
}

}  // namespace
}  // namespace ig

#include "ig/reload.h"
#include "ig/service.h"
#include "lod/view.h"

namespace ig {
namespace {

TEST(ConfigCells, KeysParseAndTheSourceIsResolved) {
  const SceneConfig cfg = parseSceneOk(
      "[cells]\nsource = \"db/bunny.ighc\"\norigin_m = [100, -2000.5, 1e6]\nvoxel_budget = 300000\n"
      "w_bytes = 65536\nmin_voxel_px = 2.5\ngpu_mb = 128\nmemory_mb = 48\npoint_scale = 1.5\nopen_timeout_s = 3\n"
      "select_threads = 2\n",
      "/scenes");
  ASSERT_TRUE(cfg.cells.has_value());
  const CellsLayerConfig& c = *cfg.cells;
  EXPECT_EQ(c.source, "/scenes/db/bunny.ighc");
  EXPECT_EQ(c.origin_m, (std::array<double, 3>{100.0, -2000.5, 1e6}));
  EXPECT_EQ(c.voxelBudget, 300000u);
  EXPECT_EQ(c.wBytes, 65536u);
  EXPECT_EQ(c.minVoxel_px, 2.5);
  EXPECT_EQ(c.gpu_mb, 128);
  EXPECT_EQ(c.memory_mb, 48);
  EXPECT_EQ(c.pointScale, 1.5);
  EXPECT_EQ(c.openTimeout_s, 3.0);
  EXPECT_EQ(c.selectThreads, 2);
  // A URL is kept as written; defaults elsewhere.
  const SceneConfig web = parseSceneOk("[cells]\nsource = \"http://127.0.0.1:8080/c/bunny.ighc\"\n", "/scenes");
  ASSERT_TRUE(web.cells.has_value());
  EXPECT_EQ(web.cells->source, "http://127.0.0.1:8080/c/bunny.ighc");
  EXPECT_EQ(web.cells->voxelBudget, CellsLayerConfig{}.voxelBudget);
  EXPECT_EQ(web.cells->selectThreads, 0);  // 0: by the machine's cores
  EXPECT_FALSE(parseSceneOk("[terrain]\n").cells.has_value());
}

TEST(ConfigCells, BadValuesAreRefusedNamingTheKey) {
  const std::string src = "[cells]\nsource = \"a.ighc\"\n";
  struct Case {
    std::string text, key, value;
  };
  const Case cases[] = {
      {"[cells]\nvoxel_budget = 1000\n", "cells.source", ""},  // required
      {"[cells]\nsource = \"\"\n", "cells.source", "\"\""},
      {"[cells]\nsource = \"https://example.com/a.ighc\"\n", "cells.source", "\"https://example.com/a.ighc\""},
      {src + "origin_m = [0, 0]\n", "cells.origin_m", "[0, 0]"},
      {src + "origin_m = [0, nan, 0]\n", "cells.origin_m[1]", "nan"},
      {src + "voxel_budget = 0\n", "cells.voxel_budget", "0"},
      {src + "voxel_budget = 1.5e3\n", "cells.voxel_budget", "1.5e3"},
      {src + "w_bytes = 100\n", "cells.w_bytes", "100"},
      {src + "min_voxel_px = -1\n", "cells.min_voxel_px", "-1"},
      {src + "gpu_mb = 0\n", "cells.gpu_mb", "0"},
      {src + "gpu_mb = 32769\n", "cells.gpu_mb", "32769"},  // over 2^31 points
      {src + "memory_mb = -5\n", "cells.memory_mb", "-5"},
      {src + "point_scale = 0\n", "cells.point_scale", "0"},
      {src + "open_timeout_s = 0\n", "cells.open_timeout_s", "0"},
      {src + "select_threads = 3\n", "cells.select_threads", "3"},
      {src + "select_threads = -1\n", "cells.select_threads", "-1"},
      {src + "select_budget_ms = -0.5\n", "cells.select_budget_ms", "-0.5"},
      {src + "select_budget_ms = nan\n", "cells.select_budget_ms", "nan"},
      {src + "budget = 5\n", "cells.budget", ""},
  };
  for (const Case& c : cases) {
    const ConfigError e = sceneError(c.text);
    EXPECT_EQ(e.key, c.key) << c.text << " -> " << e.what();
    if (!c.value.empty()) {
      EXPECT_EQ(e.value, c.value) << c.text << " -> " << e.what();
    }
    EXPECT_NE(e.what().find(c.key), std::string::npos) << e.what();
  }
}

// [channel]: the offset and the frustum parse; a bad value, a partial or reversed frustum and a
// frustum whose aspect ratio does not fit the output are refused naming the key and the value;
// a reload applies the channel, unless its frustum fits only a new output size.
TEST(ConfigChannel, KeysParseBadValuesAreNamedAndReloadApplies) {
  const std::string out = "[output]\nwidth_px = 800\nheight_px = 600\n";
  // (tan(36.5) + tan(10)) / (tan(20) + tan(18)) = 0.9163 / 0.6889 = 1.330: fits 800 x 600 (1.333).
  const std::string frustum = "left_deg = -10\nright_deg = 36.5\nbottom_deg = -18\ntop_deg = 20\n";
  const ServiceConfig cfg = parseServiceOk(std::string(kMinimalService) + out + "[channel]\nyaw_deg = -60\n" +
                                           "pitch_deg = 5\nroll_deg = 1.5\n" + frustum);
  EXPECT_EQ(cfg.channel.yaw_deg, -60.0);
  EXPECT_EQ(cfg.channel.pitch_deg, 5.0);
  EXPECT_EQ(cfg.channel.roll_deg, 1.5);
  ASSERT_TRUE(cfg.channel.frustum.has_value());
  EXPECT_EQ(cfg.channel.frustum->right_deg, 36.5);
  EXPECT_FALSE(parseServiceOk(kMinimalService).channel.frustum.has_value());

  ConfigError e = serviceError(std::string(kMinimalService) + "[channel]\nyaw_deg = 270\n");
  EXPECT_EQ(e.key, "channel.yaw_deg");
  EXPECT_EQ(e.value, "270");
  e = serviceError(std::string(kMinimalService) + "[channel]\npitch_deg = nan\n");
  EXPECT_EQ(e.key, "channel.pitch_deg");
  e = serviceError(std::string(kMinimalService) + "[channel]\nleft_deg = -90\nright_deg = 10\nbottom_deg = -5\ntop_deg = 5\n");
  EXPECT_EQ(e.key, "channel.left_deg");
  EXPECT_EQ(e.value, "-90");
  EXPECT_NE(e.message.find("(-90, 90)"), std::string::npos) << e.what();
  e = serviceError(std::string(kMinimalService) + "[channel]\nleft_deg = -10\nright_deg = 10\nbottom_deg = -5\n");
  EXPECT_EQ(e.key, "channel.top_deg");
  EXPECT_NE(e.message.find("all four"), std::string::npos) << e.what();
  e = serviceError(std::string(kMinimalService) + "[channel]\nleft_deg = 10\nright_deg = -10\nbottom_deg = -5\ntop_deg = 5\n");
  EXPECT_EQ(e.key, "channel.right_deg");
  EXPECT_EQ(e.value, "-10");
  EXPECT_NE(e.message.find("channel.left_deg (10)"), std::string::npos) << e.what();
  e = serviceError(std::string(kMinimalService) + out + "[channel]\nleft_deg = -10\nright_deg = 10\nbottom_deg = -10\ntop_deg = 10\n");
  EXPECT_EQ(e.key, "channel");
  EXPECT_NE(e.message.find("800 / 600"), std::string::npos) << e.what();

  // Reload: the channel applies; with a new output size (a restart) its new frustum waits too.
  ServiceConfig next = cfg;
  next.channel.yaw_deg = 60.0;
  ServiceConfig mc;
  SceneConfig ms;
  const SceneConfig scene;
  ReloadPlan p = planReload(cfg, scene, next, scene, mc, ms);
  EXPECT_EQ(mc.channel.yaw_deg, 60.0);
  EXPECT_EQ(joinKeys(p.applied), "channel");
  next.width_px = 600;
  next.channel.frustum->right_deg = 20.0;
  p = planReload(cfg, scene, next, scene, mc, ms);
  EXPECT_EQ(mc.channel, cfg.channel);
  EXPECT_NE(joinKeys(p.needRestart).find("channel (its frustum fits only the new output size)"), std::string::npos)
      << joinKeys(p.needRestart);
}

// The channel's offset turns the camera after the host's attitude, and its frustum wins over the
// host's field of view (the host's clip planes still apply).
TEST(ConfigChannel, TheOffsetTurnsTheCameraAndTheFrustumWins) {
  io::HostState host;
  host.fovY_deg = 30.0;
  host.near_m = 2.0;
  ChannelSettings ch;
  ch.yaw_deg = 90.0;
  lod::Camera c = cameraFor(host, ch, 800, 600);  // host heading 0 (north): the channel looks east
  EXPECT_NEAR(c.heading_deg, 90.0, 1e-9);
  EXPECT_NEAR(c.pitch_deg, 0.0, 1e-9);
  EXPECT_NEAR(c.roll_deg, 0.0, 1e-9);
  EXPECT_EQ(c.fovY_deg, 30.0);
  host.heading_deg = 30.0;
  host.pitch_deg = 10.0;  // nose up: a side channel sees the horizon tilted, not raised
  ch.yaw_deg = -90.0;
  c = cameraFor(host, ch, 800, 600);
  EXPECT_NEAR(c.heading_deg, 300.0, 1e-9);
  EXPECT_NEAR(c.pitch_deg, 0.0, 1e-9);
  EXPECT_NEAR(c.roll_deg, -10.0, 1e-9);
  // Straight up: the eyepoint pitched up 60 and the channel 30 more.
  host.heading_deg = 0.0;
  host.pitch_deg = 60.0;
  ch = {};
  ch.pitch_deg = 30.0;
  c = cameraFor(host, ch, 800, 600);
  EXPECT_NEAR(c.pitch_deg, 90.0, 1e-6);
  const glm::dmat3 r = lod::viewRotation(c);  // its camera still looks up with its top to the south
  EXPECT_NEAR((r * glm::dvec3(0, 0, 1)).z, -1.0, 1e-9);
  EXPECT_NEAR((r * glm::dvec3(0, -1, 0)).y, 1.0, 1e-6);
  // The frustum wins over the host's fov.
  ch = {};
  ch.frustum = lod::WindowAngles{-30.0, 30.0, -10.0, 30.0};
  c = cameraFor(host, ch, 800, 600);
  EXPECT_NE(c.fovY_deg, 30.0);
  EXPECT_GT(c.shiftY, 0.1);
  EXPECT_EQ(c.near_m, 2.0);
}

TEST(ConfigCells, ReloadAppliesTheBudgetsAndNamesTheRest) {
  const SceneConfig run = parseSceneOk("[cells]\nsource = \"a.ighc\"\nvoxel_budget = 100000\n");
  SceneConfig next = parseSceneOk("[cells]\nsource = \"a.ighc\"\nvoxel_budget = 50000\nw_bytes = 8192\n"
                                  "min_voxel_px = 2\nselect_budget_ms = 1.5\norigin_m = [1, 2, 3]\n");
  const ServiceConfig svc = parseServiceOk(kMinimalService);
  ServiceConfig mc;
  SceneConfig ms;
  ReloadPlan p = planReload(svc, run, svc, next, mc, ms);
  ASSERT_TRUE(ms.cells.has_value());
  EXPECT_EQ(ms.cells->voxelBudget, 50000u);
  EXPECT_EQ(ms.cells->wBytes, 8192u);
  EXPECT_EQ(ms.cells->minVoxel_px, 2.0);
  EXPECT_EQ(ms.cells->selectBudget_ms, 1.5);
  EXPECT_EQ(ms.cells->origin_m, run.cells->origin_m);  // needs a restart: the running value is kept
  EXPECT_EQ(joinKeys(p.applied),
            "scene.cells.voxel_budget, scene.cells.w_bytes, scene.cells.min_voxel_px, scene.cells.select_budget_ms");
  EXPECT_EQ(joinKeys(p.needRestart), "scene.cells (source, origin, memory, point scale or select threads)");
  next.cells.reset();
  p = planReload(svc, run, svc, next, mc, ms);
  EXPECT_EQ(joinKeys(p.needRestart), "scene.cells (added or removed)");
  EXPECT_TRUE(ms.cells.has_value());
}

}  // namespace
}  // namespace ig

namespace ig {
namespace {

// [stats] max_mb and keep (rotation of the stats file) are validated like the other numbers:
// NaN, negative and huge values are refused naming the key and the value; the defaults are
// those config/igd.toml documents.
TEST(ConfigErrors, StatsRotationKeysAreValidated) {
  struct Case {
    std::string text, key, value;
  };
  const Case cases[] = {
      {"[stats]\nmax_mb = nan\n", "stats.max_mb", "nan"},
      {"[stats]\nmax_mb = -1\n", "stats.max_mb", "-1"},
      {"[stats]\nmax_mb = 1e300\n", "stats.max_mb", "1e300"},
      {"[stats]\nmax_mb = inf\n", "stats.max_mb", "inf"},
      {"[stats]\nkeep = -1\n", "stats.keep", "-1"},
      {"[stats]\nkeep = 1001\n", "stats.keep", "1001"},
      {"[stats]\nkeep = 99999999999999\n", "stats.keep", "99999999999999"},
      {"[stats]\nkeep = 1.5\n", "stats.keep", "1.5"},
  };
  for (const Case& c : cases) {
    const ConfigError e = serviceError(std::string(kMinimalService) + c.text);
    EXPECT_EQ(e.key, c.key) << c.text << " -> " << e.what();
    EXPECT_EQ(e.value, c.value) << c.text << " -> " << e.what();
  }
  ServiceConfig cfg;
  ConfigError error;
  ASSERT_TRUE(parseServiceConfig(std::string(kMinimalService) + "[stats]\nmax_mb = 0.5\nkeep = 0\n", "svc.toml", "/base",
                                 cfg, error))
      << error.what();
  EXPECT_EQ(cfg.statsMax_mb, 0.5);
  EXPECT_EQ(cfg.statsKeep, 0);
  ASSERT_TRUE(parseServiceConfig(kMinimalService, "svc.toml", "/base", cfg, error)) << error.what();
  EXPECT_EQ(cfg.statsMax_mb, 64.0);
  EXPECT_EQ(cfg.statsKeep, 3);
}

}  // namespace
}  // namespace ig
