// Host links: how a host simulator's packets become HostState samples for the frame loop.
//
// Each link (CIGI over UDP, SocketCAN, Modbus TCP/RTU) is a thin transport around a pure
// decoder. The link owns one receive thread, started only when the [host] source names it (a
// service without a host link runs no link thread). It assembles the fields it receives into a
// complete HostState and hands it to the HostSink, which publishes it to the frame loop's
// latest-value mailbox and, when configured, appends it to a recording.
//
// Bad input never stops a link: a packet that cannot be decoded counts as `malformed`; a
// decoded field that is NaN or out of range is dropped on its own (the field keeps its last
// good value) and counts as `outOfRange`; the rest of the packet still applies.
#pragma once

#include <sys/resource.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>

#include <glm/vec3.hpp>

#include "io/host_state.h"

namespace ig::lod {
struct HeightGrid;
}

namespace ig::io {

// Counters per link. Written by the link's thread, read by the service for logs, status and
// the Start of Frame; monotonic for the life of the link.
struct LinkCounters {
  std::atomic<uint64_t> received{0};    // datagrams / CAN frames / Modbus requests read from the transport
  std::atomic<uint64_t> accepted{0};    // messages decoded and applied (possibly with some fields rejected)
  std::atomic<uint64_t> malformed{0};   // messages that could not be decoded (size, header, magic, sequence)
  std::atomic<uint64_t> outOfRange{0};  // fields rejected one by one: NaN, infinite or outside their range
  std::atomic<uint64_t> late{0};        // messages older than one already applied (timestamp or counter went back)
  std::atomic<uint64_t> dropped{0};     // complete samples overwritten before the frame loop read them, or lost sets
};

// A [host.<link>] value the link refuses, in parts so that the config loader can point at the
// key's line without parsing a message: key as the config file names it ("host.cigi.port"),
// value as written there (strings quoted), and why. message() is the one-line form,
// "host.cigi.port = 70000: must be 1..65535".
struct LinkConfigError {
  std::string key;
  std::string value;
  std::string reason;
  std::string message() const { return key + " = " + value + ": " + reason; }
};

struct LinkCountersSnapshot {
  uint64_t received = 0, accepted = 0, malformed = 0, outOfRange = 0, late = 0, dropped = 0;
};

// A link that answers terrain queries (CIGI HAT/HOT Requests): requests decoded, answers sent,
// requests refused (a full queue or too many periodic ones), and answer-frames waited (deferred);
// the same four for Line-of-Sight (LOS Segment / Vector) Requests.
struct HatHotCounters {
  uint64_t requests = 0, answered = 0, refused = 0, deferred = 0;
  uint64_t losRequests = 0, losAnswered = 0, losRefused = 0, losDeferred = 0;
};

inline LinkCountersSnapshot snapshot(const LinkCounters& c) {
  LinkCountersSnapshot s;
  s.received = c.received.load(std::memory_order_relaxed);
  s.accepted = c.accepted.load(std::memory_order_relaxed);
  s.malformed = c.malformed.load(std::memory_order_relaxed);
  s.outOfRange = c.outOfRange.load(std::memory_order_relaxed);
  s.late = c.late.load(std::memory_order_relaxed);
  s.dropped = c.dropped.load(std::memory_order_relaxed);
  return s;
}

// Where a link delivers complete host samples. Called from the link's thread; must be cheap
// and thread-safe (the service's sink copies into the mailbox and the recorder's queue).
class HostSink {
 public:
  virtual ~HostSink() = default;
  virtual void publish(const HostState& state) = 0;
};

// Scene geometry above the terrain that the host's terrain queries (CIGI HAT/HOT and line of
// sight) hit, where it is this frame: in igd the [hdlod] objects at the frame's schedule time
// (ig/hdlod_layer.h) and the [forest]'s trees (ig/forest_layer.h). Local ENU metres, like
// lod::HeightGrid. Read by the frame thread only.
// What a surface is (CIGI's material code in the extended responses).
enum SurfaceMaterial : uint32_t {
  kSurfaceTerrain = 0,  // the terrain grid
  kSurfaceObject = 1,   // a scene object: a building, slab, crane, vehicle ([hdlod])
  kSurfaceTree = 2,     // a tree's trunk or crown ([forest])
};
// Which surfaces a query meets: a mask of bits 1 << SurfaceMaterial. Height queries (HAT/HOT:
// what a vehicle stands on) meet terrain and objects: a vehicle drives among trees, not on their
// crowns. Sight queries (LOS) meet all three, or what the host's material mask names.
using SurfaceMask = uint32_t;
constexpr SurfaceMask surfaceBit(SurfaceMaterial m) { return SurfaceMask{1} << m; }
constexpr SurfaceMask kHeightSurfaces = surfaceBit(kSurfaceTerrain) | surfaceBit(kSurfaceObject);
constexpr SurfaceMask kSightSurfaces = kHeightSurfaces | surfaceBit(kSurfaceTree);
struct SurfaceHit {
  double t = 0.0;                    // along the segment, [0, 1]
  glm::dvec3 point_m{0.0};
  glm::dvec3 normal{0.0, 0.0, 1.0};  // unit, facing the segment's start
  uint32_t material = kSurfaceObject;
};
class SceneSurfaces {
 public:
  // The first intersection of the segment from -> to with the surfaces in `mask`;
  // `work` (may be null) adds the hierarchy nodes and triangles examined (the caller's
  // per-frame cap). False: none, or bad input.
  virtual bool intersect(const glm::dvec3& from_m, const glm::dvec3& to_m, SurfaceMask mask, SurfaceHit& hit,
                         uint32_t* work) const = 0;
  // No surface is higher than this (ENU metres), at any time.
  virtual double top_m() const = 0;

 protected:
  ~SceneSurfaces() = default;
};

// What the frame loop tells a link at the start of every frame (CIGI answers with a Start of
// Frame packet; other links may ignore it).
struct FrameStart {
  uint32_t igFrame = 0;        // IG frame number, counts up from 0
  uint32_t lastHostFrame = 0;  // host frame number of the sample this frame renders
  double time_s = 0.0;         // IG time: seconds since the frame loop started (monotonic)
  bool hostLost = false;       // no valid host input for longer than [host] link_timeout_s
  bool overrun = false;        // the previous frame overran its budget
  const HostState* host = nullptr;            // the host sample this frame renders (nullptr: none yet)
  const lod::HeightGrid* terrain = nullptr;   // the scene's full-resolution terrain; nullptr: none
  const SceneSurfaces* objects = nullptr;     // the scene's objects above it this frame; nullptr: none
};

// Link receive threads run at nice +5: under a packet flood the render threads keep the CPU
// and the socket drops what the link cannot read (the frame loop wants only the newest
// sample anyway). Called by each link at the start of its receive thread.
inline void lowerLinkThreadPriority() {
  constexpr int kLinkNice = 5;
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), kLinkNice);
}

class HostLink {
 public:
  virtual ~HostLink() = default;
  virtual std::string_view name() const = 0;
  // Opens the transport and starts the receive thread. On failure returns false and sets
  // `error` naming the address/device and the reason; nothing is left running.
  virtual bool start(HostSink& sink, std::string& error) = 0;
  // Stops and joins the receive thread; closes the transport. Idempotent.
  virtual void stop() = 0;
  // Called by the frame loop once per frame, after input was read. Must not block.
  virtual void frameStarted(const FrameStart& /*frame*/) {}
  // true: the host drives the frame rate (CIGI synchronous mode): the frame loop waits for a
  // new host sample before each frame, up to one frame period.
  virtual bool synchronous() const { return false; }
  const LinkCounters& counters() const { return counters_; }
  // Link-specific counters for the exit line, e.g. " hat_hot_requests 3 ..." (with a leading
  // space); "" when there is nothing to add.
  virtual std::string extraCounters() const { return {}; }
  // A link that answers HAT/HOT Requests fills `out` and returns true (the status report then
  // carries them); the others return false.
  virtual bool hatHotCounters(HatHotCounters& /*out*/) const { return false; }

 protected:
  LinkCounters counters_;
};

}  // namespace ig::io
