// The composition root: builds only the layers the scene names, owns the GL context, the
// renderer, the host input and the frame loop, and runs frames.
//
// A frame, as data flows through it:
//   input   copy the newest HostState from the mailbox (replay feeds it by slot time)
//   lod     each layer the scene has selects what to draw for this eyepoint
//   submit  the renderer turns the selections into GL work
//   gpu     glFinish (timed with the monotonic clock)
//   present window swap, or snapshot read-back on snapshot frames
//   report  stats line, systemd watchdog
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "ig/clock.h"
#include "ig/config.h"
#include "ig/stats.h"
#include "io/host_state.h"
#include "io/link.h"
#include "io/mailbox.h"
#include "lod/terrain_grid.h"
#include "render/image.h"

namespace ig {

struct ServiceInfo {
  std::string context;               // GL context description
  std::vector<std::string> layers;   // layers built, e.g. {"terrain"}
  uint32_t passes = 0;               // render passes created
  uint64_t gpuBufferBytes = 0;       // bytes of GPU buffers uploaded for layers
  uint32_t threads = 1;              // threads the service runs (1 = render thread only)
  std::string scheduling;            // render thread: e.g. "SCHED_FIFO 40, CPUs 2" ([service])
  uint64_t terrainTriangles = 0;     // triangles in the whole terrain (0 = no terrain)
  std::string terrainSource;         // "procedural 257x257" or the DEM file with its size
  double terrainBuild_ms = 0.0;      // start-up time: load + LOD precomputation + upload
  std::string hdlodDescription;      // [hdlod]: objects, clusters, cache outcome
  double hdlodBuild_ms = 0.0;        // [hdlod]: schedule + tree (cache or build) + upload
  std::string cellsDescription;      // [cells]: source, cells, placement, budgets
  std::string queriesDescription;    // what the host's HAT/HOT and LOS answers meet (CIGI link only)
};

// The terrain grid a scene's [terrain] table describes.
lod::TerrainGridDesc terrainGridDesc(const TerrainLayerConfig& terrain);

// The camera for a host sample on this display channel: the host's eyepoint and clip planes; its
// attitude composed with the channel's offset (lod::composeAttitude); the channel's frustum when
// it has one, else the host's field of view and window (HostState::windowShiftX ...) with the
// output's aspect ratio unless the host gave the window's width.
lod::Camera cameraFor(const io::HostState& host, const ChannelSettings& channel, int width_px, int height_px);

// Why a host sample was rejected (kept the previous one).
bool hostStateValid(const io::HostState& s, std::string* why = nullptr);

// Config reload on request (igd: SIGHUP). When `requested` is set, the frame loop runs `load` on
// a short-lived thread (normal scheduling), so no frame waits for file I/O, and applies the
// result between two frames: reloadable keys take effect, keys that need a restart are named in
// the log and keep their running value, and a config with an error changes nothing.
struct ReloadSource {
  std::atomic<bool> requested{false};
  std::function<bool(ServiceConfig&, SceneConfig&, std::string&)> load;
};

class Service {
 public:
  // Validates data files, creates the GL context and every layer the scene names. Returns
  // nullptr and an error naming the input on failure.
  // A live host link ([host] source = cigi, can, modbus-*) is started here, so a port in use
  // or a missing device stops the service before it reports ready. `link` (tests) replaces
  // the one the config names.
  static std::unique_ptr<Service> create(const ServiceConfig& config, const SceneConfig& scene, std::string& error,
                                         std::unique_ptr<io::HostLink> link = nullptr);
  ~Service();

  // Runs the fixed-rate loop until `config.frames` frames, a window close, or `stop`.
  // Returns 0 on a clean exit, 3 when the stats file cannot be created or the GL context cannot be
  // made current on this thread (before the first frame),
  // 1 on a failure while running. `reload` (optional) is polled once per frame.
  int run(Clock& clock, const std::atomic<bool>& stop, ReloadSource* reload = nullptr);
  // 1 at start, +1 for every reload that was applied.
  int configGeneration() const;

  // Renders one frame for this host state outside the loop (igtool, tests). Optionally
  // reads back the image. Makes this service's GL context current first (so do run() and the
  // destructor): several services may live in one process; if it cannot, nothing is rendered
  // (an empty record and image, the reason on stderr).
  FrameRecord renderOnce(const io::HostState& host, render::Image* image);

  const ServiceInfo& info() const { return info_; }
  // Of every run() so far (frames, percentiles, overruns and missed slots alike).
  RunSummary summary() const;
  io::LatestValueMailbox<io::HostState>& mailbox() { return mailbox_; }
  uint64_t hostRejected() const { return hostRejected_; }
  // The live host link, or nullptr (replay, none).
  const io::HostLink* hostLink() const;
  // Clock time (of the clock given to run) at which the last run's frame loop started.
  int64_t loopStart_ns() const;
  bool hostLost() const;
  const io::HostState& currentHost() const { return host_; }

 private:
  Service();
  struct Impl;
  std::unique_ptr<Impl> impl_;
  ServiceInfo info_;
  io::LatestValueMailbox<io::HostState> mailbox_;
  io::HostState host_;
  uint64_t mailboxSequence_ = 0;
  uint64_t hostRejected_ = 0;
};

}  // namespace ig
