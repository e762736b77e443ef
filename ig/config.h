// Service and scene configuration: plain structs with in-class defaults, parsed and validated
// once at start-up from TOML. Every error names the file, line, key and bad value; nothing is
// half-applied (the output struct is written only on success).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "io/can_map.h"
#include "io/cigi_link.h"
#include "io/modbus_link.h"
#include "lod/view.h"

namespace ig {

enum class OutputMode { Headless, Window, OSMesa };
enum class StatsFormat { Csv, JsonLines };
enum class HostSource { None, Replay, Cigi, Can, ModbusTcp, ModbusRtu };

const char* toString(OutputMode mode);
const char* toString(StatsFormat format);
const char* toString(HostSource source);

// One configuration error. `line` is 0 when the error is not tied to a line (missing file,
// missing key). `what()` gives "file:line: key = value: message".
struct ConfigError {
  std::string file;
  int line = 0;
  std::string key;    // dotted path, e.g. "output.width_px"
  std::string value;  // the bad value as written in the file ("" when missing)
  std::string message;
  std::string what() const;
};

// [governor]: keeps the frame rate by steering LOD tolerances from a prediction of the next
// frame's work (lod/governor.h, docs/governor.md).
struct GovernorSettings {
  bool enabled = false;
  double decreaseAbove = 0.85;        // less detail when predicted + margin > this * budget
  double increaseBelow = 0.65;        // more detail when below this * budget
  double marginSigmas = 2.0;
  double maxDecrease = 0.5;           // smallest load multiplier of one decrease
  double maxIncrease = 1.1;           // largest load multiplier of one raise
  int raiseInterval_frames = 6;
  int holdAfterDecrease_frames = 30;
  int spikeWindow_frames = 0;         // spike headroom (lod::GovernorConfig::spikeWindow_frames); 0 = off
  double terrainMin_px = 0.0;         // [governor.terrain] min_px; 0 = the scene's tolerance_px
  double terrainMax_px = 32.0;
  double terrainLoadExponent = -1.5;
  double forestMin_m = 100.0;         // [governor.forest] min_m: the 3D trees' near distance
  double forestMax_m = 0.0;           // [governor.forest] max_m; 0 = the scene's near_fade_end_m
  int forestMinLayers = 1;            // [governor.forest] min_layers: shell layers drawn at least
  int forestMaxLayers = 0;            // [governor.forest] max_layers; 0 = the scene's layers
  double hdlodMin_px = 0.0;           // [governor.hdlod] min_px; 0 = the scene's tolerance_px
  double hdlodMax_px = 16.0;
  double hdlodLoadExponent = -2.0;
  uint64_t cellsMin_voxels = 10'000;  // [governor.cells] min_voxels
  uint64_t cellsMax_voxels = 0;       // [governor.cells] max_voxels; 0 = the scene's voxel_budget
  bool operator==(const GovernorSettings&) const = default;
};

// [channel]: this igd's display channel, one of several in a cabin (one igd per channel, all fed
// by the same host). The camera's attitude is the host eyepoint's composed with the offset:
// lod::composeAttitude({heading, pitch, roll}, {yaw_deg, pitch_deg, roll_deg}). The frustum,
// when given, wins over the host's field of view (CIGI View Definition, Modbus/CAN/replay fovy):
// it is the cabin's geometry; the host's near/far clip planes still apply.
struct ChannelSettings {
  double yaw_deg = 0.0;    // right positive, [-180, 180]
  double pitch_deg = 0.0;  // up positive, [-90, 90]
  double roll_deg = 0.0;   // right side down positive, [-180, 180]
  std::optional<lod::WindowAngles> frustum;  // left/right/bottom/top_deg; absent = the host's
  bool operator==(const ChannelSettings&) const = default;
};

// Service config (config/igd.toml): how the service runs, independent of what it draws.
struct ServiceConfig {
  std::string path;                          // file this was loaded from ("" = defaults)
  // [frame]
  double rate_hz = 60.0;                     // fixed frame rate; deadlines are absolute
  int64_t frames = 0;                        // frames to render, 0 = run until SIGTERM
  bool freeRun = false;                      // true: no sleeping, sim time still steps 1/rate_hz
  // [output]
  OutputMode output = OutputMode::Headless;
  int width_px = 1280;
  int height_px = 720;
  int msaa = 1;                              // samples per pixel: 1 (off), 2, 4 or 8
  bool fullscreen = false;                   // window mode: full screen on `monitor`
  int monitor = 0;                           // window mode: index of the X server's monitor
  std::string snapshotDir = "out/snapshots"; // resolved against the config file's folder
  int64_t snapshotEvery = 0;                 // write a PNG every N frames, 0 = never
  std::vector<int64_t> snapshotFrames;       // and at these frame numbers
  // [stats]
  std::string statsFile = "out/frame_stats.csv"; // "" = no stats file
  StatsFormat statsFormat = StatsFormat::Csv;
  double statsMax_mb = 64.0;                 // rotate the file at this size (MiB), 0 = no limit
  int statsKeep = 3;                         // old files kept (file.1 ... file.N), 0 = none
  // [host]
  HostSource host = HostSource::Replay;
  std::string replayFile;                    // timestamped text recording (io/replay.h)
  bool replayLoop = false;                   // restart the recording at its end
  double linkTimeout_s = 1.0;                // host lost after this long without valid input
  std::string recordFile;                    // "" = no recording; else accepted host samples go here
  io::CigiLinkConfig cigi;                   // [host.cigi]   when source = "cigi"
  io::CanLinkConfig can;                     // [host.can]    when source = "can"
  io::ModbusLinkConfig modbus;               // [host.modbus] when source = "modbus-tcp" / "modbus-rtu"
  // [scene]
  std::string sceneFile;
  // [channel]
  ChannelSettings channel;
  // [budget]
  double budgetFrame_ms = 0.0;               // work budget per frame, 0 = the whole period
  int64_t budgetTriangles = 2'000'000;       // triangles per frame for all layers together
  GovernorSettings governor;                 // [governor]
  // [service]
  double watchdogInterval_s = 0.0;           // 0 = half of systemd's WatchdogSec, if any
  int realtimePriority = 0;                  // 0 = normal scheduling; 1..99 = SCHED_FIFO (render thread)
  std::vector<int64_t> cpuAffinity;          // CPUs the render thread may run on; empty = any
  bool lockMemory = false;                   // mlockall: no page faults in the frame loop
  std::string statusFile;                    // JSON health report, rewritten every status_interval_s
  double statusInterval_s = 1.0;             // also the period of systemd STATUS= updates
  bool operator==(const ServiceConfig&) const = default;
};

struct TerrainLayerConfig {
  enum class Source { Procedural, Dem } source = Source::Procedural;
  enum class Lod { Grid, Roam, Block } lod = Lod::Grid;
  std::string file;                          // DEM (16-bit PNG, GeoTIFF, .hgt) when source = dem
  double demSpacing_m = 0.0;                 // sample spacing; 0 = from the file (PNG needs it)
  double pngScale_m = 1.0;                   // 16-bit PNG: height = offset + scale * value
  double pngOffset_m = 0.0;
  double tolerance_px = 1.0;                 // roam / block: screen-space error target
  double lodBudget_ms = 0.0;                 // roam: CPU time for mesh updates per frame, 0 = unlimited
  double morph_s = 0.0;                      // roam: geomorph time of new and removed vertices, 0 = off
  // roam: Deferred (work budgeted in node visits, persistent split queue) or EnhMerge (a walk
  // of the whole tree each frame, budgeted in operations); lod/roam.h RoamMode.
  enum class RoamMode { Deferred, EnhMerge } roamMode = RoamMode::Deferred;
  uint32_t seed = 1;
  double size_m = 8192.0;                    // square side
  double gridStep_m = 32.0;                  // post spacing
  double heightScale_m = 400.0;              // peak-to-valley of the procedural relief
  std::array<double, 3> offset_m{0, 0, 0};   // placement of the SW corner in local ENU
  int chunkQuads = 64;                       // quads per chunk side (one draw per chunk)
  bool operator==(const TerrainLayerConfig&) const = default;
};

// [forest]: a large forest (paper 004) on the terrain mesh (ig/forest_layer.h).
struct ForestLayerConfig {
  // Folder written by igtool forest-textures (tree LOD models, layers.png, fins.png,
  // forest_textures.txt). "" = procedural models, textures rendered at start-up.
  std::string assets;
  // Distribution map: RGBA PNG, rgb = tint Gr.rgb, a = density (0 = glade), row 0 = north,
  // one pixel per cell_m, south-west corner at the forest area's south-west corner; cells beyond
  // the area (east, north) are not used.
  // "" = generated from `seed`.
  std::string map;
  uint32_t seed = 1;
  double cell_m = 32.0;          // map cell
  double gladeFraction = 0.15;   // generated map: share of glades
  double featureSize_m = 600.0;  // generated map: size of density / glade blobs
  // Forest area [east0, north0, east1, north1] in scene ENU metres; all zero = the terrain's
  // extent. At most 2e8 placement slots.
  std::array<double, 4> area_m{0.0, 0.0, 0.0, 0.0};
  double spacing_m = 6.0;        // one placement slot per spacing^2 (kept with prob. density)
  int layers = 8;                // shell layers (procedural textures; assets carry their own)
  double nearFadeStart_m = 300.0;  // 3D trees opaque up to here; layers start fading in
  double nearFadeEnd_m = 500.0;    // 3D trees gone, layers fully in
  double fadeOut_m = 6000.0;       // layers and fins start fading out
  double farPlane_m = 8000.0;      // ... gone
  bool fins = true;
  double criticalAngle_deg = 175.0;  // fins on edges with a dihedral angle (through the ground) below
  double finAlphaThreshold = 0.05;   // fin groups whose view alpha stays below are skipped
  double leafSize_m = 256.0;         // kd-tree leaf size
  int maxTrees = 131072;             // 3D trees drawn per frame at most (instance buffer)
  bool operator==(const ForestLayerConfig&) const = default;
};

// [hdlod]: a 4D scene (paper 000) — objects that appear, vanish and move on a schedule.
struct HdlodLayerConfig {
  std::string schedule;             // schedule file (docs/hdlod.md); "" = the synthetic site below
  double siteScale = 0.25;          // synthetic construction site: 1 = the paper's ~56k objects
  uint32_t siteSeed = 1;
  double siteX_m = 0.0, siteY_m = 0.0, siteZ_m = 0.0;  // synthetic site: centre (local ENU)
  std::string cache;                // cache file of the built tree ("" = build at every start)
  std::string simplifier = "meshoptimizer";  // meshoptimizer | openmesh | clustering
  double tolerance_px = 1.0;        // r, screen-space pixels
  double timeOffset_s = 0.0;        // schedule time = timeOffset_s + timeScale * simulation time
  double timeScale = 1.0;
  int octreeDepth = 3;              // render/hdlod_pass.h
  bool progress = false;            // build progress bar even when stderr is not a terminal
  bool operator==(const HdlodLayerConfig&) const = default;
};

// [cells]: a hierarchical-cells database (paper 003, docs/cells.md) streamed from a file or an
// HTTP server and drawn as point splats within a voxel budget (ig/cells_layer.h).
struct CellsLayerConfig {
  std::string source;                          // database file (resolved against the scene's folder) or http://HOST:PORT/path
  std::array<double, 3> origin_m{0, 0, 0};     // where the database's root corner goes in scene ENU metres
  uint64_t voxelBudget = 2'000'000;            // voxels drawn per frame at most
  uint64_t wBytes = 1u << 20;                  // W: bytes requested per frame at most (cells larger are never fetched)
  double minVoxel_px = 1.0;                    // cells whose voxels are already this small are not refined
  int64_t gpu_mb = 64;                         // GPU point arena (16 B a point, a cell uses at most twice its size)
  int64_t memory_mb = 32;                      // decoded points kept resident (LRU over the least recently drawn)
  double pointScale = 1.0;                     // point side / voxel footprint
  double openTimeout_s = 10.0;                 // start-up: reading the header and index (http)
  int64_t selectThreads = 0;                   // the selection's per-frame passes on 1 or 2 threads (ig/worker_pair.h); 0: 2 with >= 4 cores
  double selectBudget_ms = 0.0;                // the selection's refinement stops there each frame; 0: the governor's cells phase budget, or none
  bool operator==(const CellsLayerConfig&) const = default;
};

struct SunConfig {
  double azimuth_deg = 135.0;                // clockwise from north
  double elevation_deg = 35.0;
  std::array<double, 3> color{1.0, 0.96, 0.88};
  double ambient = 0.25;                     // 0..1
  bool operator==(const SunConfig&) const = default;
};

struct FogConfig {
  bool enabled = true;
  double visibility_m = 20000.0;             // meteorological visibility (2 % contrast)
  std::array<double, 3> color{0.70, 0.78, 0.86};
  // Nothing beyond render::fogOpaqueDistance_m (1.77 x the visibility, where the fog is opaque to
  // a quarter of a colour level) is drawn: the camera's far plane moves in (what the layers select
  // by the frustum is not selected or uploaded either; deferred ROAM refines its surroundings
  // regardless of the view).
  bool cull = true;
  bool operator==(const FogConfig&) const = default;
};

// Scene config (config/scenes/*.toml): which layers exist and their data. A layer that is
// absent here is never constructed: no pass, no buffer, no thread.
struct SceneConfig {
  std::string path;
  std::string name = "unnamed";
  std::array<double, 3> originGeodetic{0, 0, 0};   // lat_deg, lon_deg, height_m of local ENU origin
  std::optional<TerrainLayerConfig> terrain;
  std::optional<ForestLayerConfig> forest;
  std::optional<HdlodLayerConfig> hdlod;
  std::optional<CellsLayerConfig> cells;
  SunConfig sun;
  FogConfig fog;
  bool operator==(const SceneConfig&) const = default;
};

// Parse + validate. On failure returns false, fills `error`, leaves `out` untouched.
// The channel frustum's aspect ratio, (tan(right) - tan(left)) / (tan(top) - tan(bottom)), must
// match the output's width_px / height_px within kChannelAspectTolerance (relative), or the picture
// would be stretched. Returns "" when it does (or there is no frustum), else the reason.
constexpr double kChannelAspectTolerance = 0.01;
std::string channelAspectMismatch(const ServiceConfig& config);

bool loadServiceConfig(const std::string& file, ServiceConfig& out, ConfigError& error);
bool loadSceneConfig(const std::string& file, SceneConfig& out, ConfigError& error);
// Same, from text (tests); `name` is used as the file name in errors and `baseDir` to resolve
// relative paths.
bool parseServiceConfig(const std::string& text, const std::string& name, const std::string& baseDir,
                        ServiceConfig& out, ConfigError& error);
bool parseSceneConfig(const std::string& text, const std::string& name, const std::string& baseDir,
                      SceneConfig& out, ConfigError& error);

}  // namespace ig
