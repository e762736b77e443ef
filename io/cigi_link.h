// CIGI 3.3 host link over UDP: igd is the IG. The host sends one message (datagram) per host
// frame: IG Control first, then Entity Control for the ownship, optionally View Control, View
// Definition, Celestial Sphere Control, Atmosphere Control (the visibility: igd's fog), HAT/HOT
// Requests and LOS Segment / Vector Requests. igd
// answers every frame with a Start of Frame, followed in the same datagram by the HAT/HOT and LOS
// responses due that frame.
//
// Two parts:
//  - CigiAssembler: pure (no sockets, no clock). Turns decoded messages into HostState: the
//    eyepoint, attitude, frustum, time and date, visibility, field by field, with the late / restart rule.
//    Shared by the live link and the pcap converter (io/pcap.h), so a capture replays exactly
//    what the live link would have rendered.
//  - CigiLink: the UDP transport. One receive thread (poll() with a 50 ms timeout so stop()
//    joins promptly); frameStarted() sends the Start of Frame from the frame loop's thread with
//    a non-blocking sendto (errors counted, never thrown, never blocking).
//  - CigiHatHotResponder: pure. The frame loop's side of HAT/HOT and LOS: one-shot and periodic
//    requests, answered from the scene's full-resolution terrain, a bounded number per frame.
//
// Conventions (docs/cigi.md has the full list):
//  - Entity attitude: CIGI body axes x forward, y right, z down; yaw = heading clockwise from
//    true north at the entity, then pitch (nose up +), then roll (right side down +).
//  - View Control offsets are in the entity's body axes (x forward, y right, z down, metres) and
//    its roll/pitch/yaw rotate the view relative to the entity body (same order).
//  - HostState heading/pitch/roll are relative to the scene's ENU axes (grid north at the scene
//    origin): the CIGI attitude is converted through ECEF, so far from the origin they differ
//    from the geodetic angles by the meridian convergence.
//  - Entity altitude is read as height above the WGS-84 ellipsoid (igd has no geoid model).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <thread>

#include <netinet/in.h>

#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

#include "io/cigi.h"
#include "io/host_state.h"
#include "io/link.h"
#include "lod/geo.h"
#include "lod/heightfield.h"

namespace ig::io {

// [host.cigi] in config/igd.toml. Field names are the TOML keys.
struct CigiLinkConfig {
  std::string bind_address = "0.0.0.0";  // IPv4 address to receive on
  int port = 8004;                       // IG receive port, 1..65535 (0: any free port; tests)
  std::string host_address;              // where Start of Frame goes; "" = the source address
                                         //   of the last valid host message
  int host_port = 8005;                  // Start of Frame destination port, 1..65535
                                         //   (0: the source port of the last valid host message)
  bool sync = false;                     // true: synchronous mode, the host paces igd's frames
  int entity_id = 0;                     // ownship Entity ID, 0..65535
  int view_id = 0;                       // View ID of igd's view, 0..65535
  int database = -1;                     // expected database number 0..127; -1 = any
  bool operator==(const CigiLinkConfig&) const = default;
};

// Checks ranges; on error returns false and sets `error` (its message() is e.g.
// "host.cigi.port = 70000: must be 1..65535"). The string form sets that message.
bool validateCigiLinkConfig(const CigiLinkConfig& config, LinkConfigError& error);
bool validateCigiLinkConfig(const CigiLinkConfig& config, std::string& error);

struct CigiAssemblerConfig {
  uint16_t entityId = 0;
  uint16_t viewId = 0;
  int database = -1;
};

class CigiAssembler {
 public:
  // A host frame number that goes back by this many frames or more is a host restart (the
  // message applies and the sequence starts over); a smaller step back is late (dropped).
  static constexpr uint32_t kRestartFrameGap = 1000;
  // ... and this many late messages in a row are a restart too (a host restarted soon after a
  // previous run), so a restarted host resumes within a few frames.
  static constexpr uint32_t kRestartAfterLate = 8;

  enum class Result {
    malformed,  // could not be decoded: nothing applied (++malformed)
    late,       // host frame (or timestamp) went back: nothing applied (++late)
    accepted,   // applied, but no ownship position known yet: nothing to publish (++accepted)
    published,  // applied; state() is a complete sample (++accepted)
  };

  CigiAssembler(const CigiAssemblerConfig& config, const lod::Geodetic& origin);

  // Decodes and applies one datagram. Counts malformed, outOfRange, late and accepted (not
  // received) in `counters`. Allocation-free.
  Result apply(std::span<const std::byte> datagram, LinkCounters& counters);

  const HostState& state() const { return state_; }
  bool hasPosition() const { return hasLat_ && hasLon_ && hasAlt_; }
  // From the last applied IG Control.
  uint32_t lastHostFrame() const { return lastFrame_; }
  cigi::IgMode hostIgMode() const { return hostMode_; }
  // Database number for Start of Frame: the configured one, else the last one the host asked
  // for (0 until it asks).
  int8_t database() const { return database_; }
  const cigi::HostMessage& lastMessage() const { return msg_; }
  // The last applied message's HAT/HOT requests, each with its rejected fields (counted in
  // outOfRange; such a request is answered Valid = false).
  struct HatHotJobs {
    std::span<const cigi::HatHotRequest> requests;
    std::span<const uint32_t> bad;  // cigi::HatHotField bits | kHatHotUnknownEntity
  };
  HatHotJobs hatHotJobs() const {
    return {std::span(msg_.hatHotRequests.data(), msg_.hatHotCount), std::span(hatHotBad_.data(), msg_.hatHotCount)};
  }
  // Atmosphere Control's visibility range is clamped to this (a host's 0 or "unlimited").
  static constexpr double kMinVisibility_m = io::kMinVisibility_m, kMaxVisibility_m = io::kMaxVisibility_m;
  // A request in entity coordinates for another entity than the ownship (igd knows only it).
  static constexpr uint32_t kHatHotUnknownEntity = 1u << 8;
  // The same for LOS Segment / Vector Requests.
  struct LosJobs {
    std::span<const cigi::LosRequest> requests;
    std::span<const uint32_t> bad;  // cigi::LosField bits | kLosUnknownEntity
  };
  LosJobs losJobs() const {
    return {std::span(msg_.losRequests.data(), msg_.losCount), std::span(losBad_.data(), msg_.losCount)};
  }
  // A point (source, destination or response) in entity coordinates of another entity than the ownship.
  static constexpr uint32_t kLosUnknownEntity = 1u << 16;

 private:
  bool isLate(const cigi::IgControl& ig);
  void applyEntity(const cigi::EntityControl& e, LinkCounters& counters);
  void applyView(const cigi::ViewControl& v, LinkCounters& counters);
  void applyViewDefinition(const cigi::ViewDefinition& d, LinkCounters& counters);
  void applyCelestial(const cigi::CelestialSphereControl& c, LinkCounters& counters);
  void applyAtmosphere(const cigi::AtmosphereControl& a, LinkCounters& counters);
  void checkHatHot(LinkCounters& counters);
  void checkLos(LinkCounters& counters);
  void computeEye();

  CigiAssemblerConfig config_;
  lod::EnuFrame enu_;
  cigi::HostMessage msg_;
  HostState state_;

  bool started_ = false;
  uint32_t lastFrame_ = 0;
  uint64_t frame64_ = 0;         // host frame, unwrapped
  bool haveTimestamp_ = false;
  uint32_t lastTimestamp_ = 0;
  int64_t timestamp64_ = 0;      // 10 us ticks, unwrapped
  uint32_t lateInARow_ = 0;
  cigi::IgMode hostMode_ = cigi::IgMode::standby;
  int8_t database_ = 0;

  // Last good value of every field (kept when a new value is rejected).
  double lat_deg_ = 0, lon_deg_ = 0, alt_m_ = 0;
  bool hasLat_ = false, hasLon_ = false, hasAlt_ = false;
  double roll_deg_ = 0, pitch_deg_ = 0, yaw_deg_ = 0;
  double viewOffset_m_[3] = {0, 0, 0};        // body x forward, y right, z down
  double viewRoll_deg_ = 0, viewPitch_deg_ = 0, viewYaw_deg_ = 0;
  double near_m_, far_m_, top_deg_, bottom_deg_;
  std::array<uint32_t, cigi::HostMessage::kMaxHatHotRequests> hatHotBad_{};
  std::array<uint32_t, cigi::HostMessage::kMaxLosRequests> losBad_{};
  // Left/right edges; before the host's first left/right the window is as wide as the output's
  // aspect ratio and centred (HostState::windowWidth_tan = 0).
  double left_deg_ = 0, right_deg_ = 0;
  bool hasLeftRight_ = false;
};

// Eye position and attitude from an entity pose and a view offset (pure; used by the
// assembler, exposed for tests). Positions in ECEF; angles in degrees; offsets in body axes.
struct EyePose {
  glm::dvec3 ecef_m{0.0};
  glm::dvec3 forwardEcef{0.0}, rightEcef{0.0}, downEcef{0.0};  // view axes, unit vectors
};
EyePose cigiEyePose(const lod::Geodetic& entity, double yaw_deg, double pitch_deg, double roll_deg,
                    const glm::dvec3& offsetBody_m, double viewYaw_deg, double viewPitch_deg, double viewRoll_deg);

// ---------------------------------------------------------------------------------------------
// HAT/HOT (docs/cigi.md "HAT/HOT"): what the frame loop answers.

// One request handed from the receive thread to the frame loop.
struct HatHotJob {
  cigi::HatHotRequest request;
  uint32_t bad = 0;  // rejected fields (CigiAssembler::hatHotJobs): answered Valid = false
};

// What HAT/HOT and LOS requests are answered against: the terrain grid and the scene's objects
// and trees standing on it (either may be null). Material codes in the extended responses:
// io::SurfaceMaterial (0 terrain, 1 object, 2 tree).
struct QueryScene {
  QueryScene(const lod::HeightGrid* terrain_ = nullptr, const SceneSurfaces* objects_ = nullptr)  // NOLINT: implicit
      : terrain(terrain_), objects(objects_) {}
  const lod::HeightGrid* terrain = nullptr;
  const SceneSurfaces* objects = nullptr;
};
constexpr uint32_t kMaterialTerrain = kSurfaceTerrain;
constexpr uint32_t kMaterialObject = kSurfaceObject;
constexpr uint32_t kMaterialTree = kSurfaceTree;

struct HatHotAnswer {
  bool valid = false;
  uint32_t materialCode = kMaterialTerrain;  // what the surface found is
  uint32_t work = 0;                         // grid samples, object nodes and triangles examined: the answer's cost
  double hat_m = 0.0;               // altitude - HOT
  double hot_m = 0.0;               // terrain height above the WGS-84 ellipsoid
  float normalAzimuth_deg = 0.0f;   // surface normal: from true north, clockwise, [-180, 180]
  float normalElevation_deg = 90.0f;  // above the local horizontal
};

// The answer to one valid request (pure). The point: geodetic lat/lon(/alt), or the offset in
// the ownship's body axes from the ownship (`host`'s ownship fields; invalid without them). The
// terrain is the scene's local ENU plane at `enu`: the point goes to ENU through ECEF, the grid
// is sampled there (lod::sampleGround, bilinear) and the surface point goes back to geodetic,
// twice (the second pass at the terrain's height, so the answer does not depend on the
// requested altitude). Objects (scene.objects): the surface is the first one a vertical line
// meets going down to the terrain, from the requested point for HAT and extended requests (the
// surface under the point: a helicopter under a bridge gets the ground), from above every
// object for HOT (the highest surface: a roof). Invalid: no terrain, a point outside it, a
// non-finite result.
HatHotAnswer computeHatHot(const cigi::HatHotRequest& request, const lod::EnuFrame& enu, double originHeight_m,
                           const QueryScene& scene, const HostState* host);

// ---------------------------------------------------------------------------------------------
// Line of sight (docs/cigi.md "Line of sight").

// One LOS request handed from the receive thread to the frame loop.
struct LosJob {
  cigi::LosRequest request;
  uint32_t bad = 0;  // rejected fields (CigiAssembler::losJobs): answered Valid = false
};

struct LosAnswer {
  bool valid = false;               // the segment / vector meets the terrain or an object
  uint32_t materialCode = kMaterialTerrain;  // what it met
  bool visible = false;             // segment: the destination is visible (no terrain before it)
  double range_m = 0.0;             // source -> first intersection
  double lat_deg = 0.0;             // the intersection: geodetic, or x/y/z offsets in the ownship's
  double lon_deg = 0.0;             //   body axes when the request asks for entity response
  double alt_m = 0.0;               //   coordinates
  float normalAzimuth_deg = 0.0f;   // surface normal there: from true north, clockwise, [-180, 180]
  float normalElevation_deg = 90.0f;  // above the local horizontal
  uint32_t cells = 0;               // grid cells, object hierarchy nodes and triangles examined: the answer's cost
};

// The answer to one valid LOS request (pure): the first intersection of the segment (source ->
// destination), or of the vector (from the source along azimuth / elevation, between the minimum
// and maximum range), with the terrain surface computeHatHot samples (lod::intersectGround on
// the grid in the ENU plane at `enu`) and with the scene's objects and trees (scene.objects),
// whichever is nearer the source. Points in entity coordinates are offsets in the ownship's body axes
// (`host`'s ownship fields; invalid without them). Invalid: no terrain, no intersection, a
// non-finite result. A segment's Visible: no intersection before its destination (1 mm).
LosAnswer computeLos(const cigi::LosRequest& request, const lod::EnuFrame& enu, const QueryScene& scene,
                     const HostState* host);

// The frame loop's HAT/HOT and LOS state: periodic requests and the queue of answers still to
// send. Fixed capacity, no allocation after construction, frame thread only (counters readable
// from any thread). HAT/HOT IDs and LOS IDs are separate name spaces.
class CigiHatHotResponder {
 public:
  static constexpr size_t kMaxPeriodic = 64;         // periodic requests held at once (both kinds)
  static constexpr size_t kMaxPending = 256;         // answers waiting for a frame (both kinds)
  static constexpr size_t kMaxAnswersPerFrame = 32;  // responses per frame, at most ...
  // ... and at most this many bytes, so that Start of Frame + answers fit one 1,472-byte UDP
  // payload (an Ethernet frame without IP fragmentation): 32 HAT/HOT Extended Responses (40
  // bytes) fit, 25 LOS Extended Responses (56 bytes) do.
  static constexpr size_t kMaxDatagramBytes = 1472;
  static constexpr size_t kMaxBytesPerFrame = kMaxDatagramBytes - cigi::kStartOfFrameSize;
  // An answer's work: a LOS ray walks the grid cells it crosses (up to width + height: 32,770 on
  // a 16385-post DEM) and the objects' and trees' nodes, tree boxes and triangles it examines; a
  // HAT/HOT answer samples the grid twice and examines the objects under its point. Once a
  // frame's answers have done this much work the rest wait for the next frame (deferred), so a
  // frame spends at most this plus one answer (one is always answered: the queue moves on).
  static constexpr uint32_t kMaxQueryWorkPerFrame = 16384;

  explicit CigiHatHotResponder(const lod::Geodetic& origin);

  // A new request, received before IG frame `igFrame`. Period 0: answered once, and it cancels
  // the periodic request with the same HAT/HOT ID. Period n (valid request): answered now and
  // every n-th IG frame after, replacing a periodic request with the same ID; with kMaxPeriodic
  // held already it is refused (counted) and answered once. A full queue refuses (counted,
  // not answered).
  void add(const HatHotJob& job, uint32_t igFrame);
  // The same for a LOS request (matched by LOS ID among the periodic LOS requests).
  void add(const LosJob& job, uint32_t igFrame);

  // This frame's responses in queue order, at most kMaxAnswersPerFrame and kMaxBytesPerFrame
  // bytes, until kMaxQueryWorkPerFrame work is spent (the rest wait for the next frame, counted
  // in deferred), encoded into `out`
  // (>= kMaxBytesPerFrame bytes). Returns the bytes.
  size_t answer(uint32_t igFrame, uint32_t lastHostFrame, const QueryScene& scene, const HostState* host,
                cigi::ByteOrder order, std::span<std::byte> out);

  // Nothing held: no periodic request and nothing queued.
  bool idle() const { return periodicCount_ == 0 && pendingCount_ == 0; }
  size_t periodicCount() const { return periodicCount_; }
  size_t pendingCount() const { return pendingCount_; }
  uint64_t answered() const { return answered_.load(std::memory_order_relaxed); }
  uint64_t refused() const { return refused_.load(std::memory_order_relaxed); }
  uint64_t deferred() const { return deferred_.load(std::memory_order_relaxed); }
  void countRefused(uint64_t n) { refused_.fetch_add(n, std::memory_order_relaxed); }
  // LOS answers sent, requests refused, answers deferred (summed over frames).
  uint64_t losAnswered() const { return losAnswered_.load(std::memory_order_relaxed); }
  uint64_t losRefused() const { return losRefused_.load(std::memory_order_relaxed); }
  uint64_t losDeferred() const { return losDeferred_.load(std::memory_order_relaxed); }
  void countLosRefused(uint64_t n) { losRefused_.fetch_add(n, std::memory_order_relaxed); }

 private:
  struct Job {
    bool los = false;
    HatHotJob hatHot;
    LosJob losJob;
    uint16_t id() const { return los ? losJob.request.losId : hatHot.request.hatHotId; }
    uint8_t period() const { return los ? losJob.request.updatePeriod : hatHot.request.updatePeriod; }
    uint32_t bad() const { return los ? losJob.bad : hatHot.bad; }
    size_t responseSize() const;
  };
  struct Periodic {
    Job job;
    uint32_t nextDue = 0;  // IG frame
  };
  void addJob(const Job& job, uint32_t igFrame);
  bool push(const Job& job);
  void refuse(const Job& job) { job.los ? countLosRefused(1) : countRefused(1); }

  lod::EnuFrame enu_;
  double originHeight_m_;
  std::array<Periodic, kMaxPeriodic> periodic_{};
  size_t periodicCount_ = 0;
  std::array<Job, kMaxPending> pending_{};  // ring
  size_t pendingHead_ = 0, pendingCount_ = 0, pendingLos_ = 0;
  std::atomic<uint64_t> answered_{0}, refused_{0}, deferred_{0};
  std::atomic<uint64_t> losAnswered_{0}, losRefused_{0}, losDeferred_{0};
};

class CigiLink final : public HostLink {
 public:
  // IG Status codes igd sends in Start of Frame.
  static constexpr uint8_t kStatusNormal = 0;
  static constexpr uint8_t kStatusHostLost = 1;  // no valid host message for [host] link_timeout_s
  static constexpr uint8_t kStatusOverrun = 2;   // the previous frame overran its budget

  CigiLink(const CigiLinkConfig& config, const lod::Geodetic& origin);
  ~CigiLink() override;
  std::string_view name() const override { return "cigi"; }
  bool start(HostSink& sink, std::string& error) override;
  void stop() override;
  void frameStarted(const FrameStart& frame) override;
  bool synchronous() const override { return config_.sync; }

  // The UDP port actually bound (differs from config.port only when that is 0). 0 before start.
  uint16_t localPort() const { return localPort_; }
  // The IG mode the host asked for in its last valid IG Control; -1 before the first one.
  int hostIgMode() const { return hostMode_.load(std::memory_order_relaxed); }
  uint64_t startOfFramesSent() const { return sofSent_.load(std::memory_order_relaxed); }
  uint64_t sendErrors() const { return sendErrors_.load(std::memory_order_relaxed); }
  // HAT/HOT requests received (valid or not), answers sent, refused (over a capacity), deferred
  // (answers left for a later frame, summed over frames).
  uint64_t hatHotRequests() const { return hatHotRequests_.load(std::memory_order_relaxed); }
  uint64_t hatHotAnswered() const { return responder_.answered(); }
  uint64_t hatHotRefused() const { return responder_.refused(); }
  uint64_t hatHotDeferred() const { return responder_.deferred(); }
  // The same for LOS Segment / Vector Requests.
  uint64_t losRequests() const { return losRequests_.load(std::memory_order_relaxed); }
  uint64_t losAnswered() const { return responder_.losAnswered(); }
  uint64_t losRefused() const { return responder_.losRefused(); }
  uint64_t losDeferred() const { return responder_.losDeferred(); }
  std::string extraCounters() const override;
  bool hatHotCounters(HatHotCounters& out) const override {
    out = {hatHotRequests(), hatHotAnswered(), hatHotRefused(), hatHotDeferred(),
           losRequests(),    losAnswered(),    losRefused(),    losDeferred()};
    return true;
  }

  // Receive thread -> frame loop: HAT/HOT and LOS requests (single producer, single consumer).
  static constexpr size_t kHatHotQueue = 256;
  static constexpr size_t kLosQueue = 256;

 private:
  void run();
  void handleDatagram(const void* data, size_t size, int flags, sockaddr_in src);

  CigiLinkConfig config_;
  std::unique_ptr<CigiAssembler> assembler_;  // touched only by the receive thread
  HostSink* sink_ = nullptr;
  int fd_ = -1;
  uint16_t localPort_ = 0;
  std::thread thread_;
  std::atomic<bool> stopping_{false};
  std::unique_ptr<std::byte[]> rx_;           // one datagram, 64 KiB
  uint64_t fixedReply_ = 0;                   // host_address:host_port packed, 0 = reply to source
  std::atomic<uint64_t> reply_{0};            // (IPv4 << 16 | port) in network order parts; 0 = none
  std::atomic<uint32_t> lastHostFrame_{0};
  std::atomic<int> hostMode_{-1};
  std::atomic<int> database_{0};
  std::atomic<uint32_t> publishedSinceFrame_{0};
  std::atomic<uint64_t> sofSent_{0};
  std::atomic<uint64_t> sendErrors_{0};
  // HAT/HOT: a ring written by the receive thread (tail) and read by the frame loop (head).
  std::array<HatHotJob, kHatHotQueue> hatHotRing_{};
  std::atomic<size_t> hatHotHead_{0}, hatHotTail_{0};
  std::atomic<uint64_t> hatHotRequests_{0};
  std::array<LosJob, kLosQueue> losRing_{};
  std::atomic<size_t> losHead_{0}, losTail_{0};
  std::atomic<uint64_t> losRequests_{0};
  CigiHatHotResponder responder_;  // frame loop only
  std::array<std::byte, cigi::kStartOfFrameSize + CigiHatHotResponder::kMaxBytesPerFrame> tx_{};  // <= 1,472 bytes
};

std::unique_ptr<CigiLink> makeCigiLink(const CigiLinkConfig& config, const lod::Geodetic& origin);

// The host's requested IG mode (cigi::IgMode value) if `link` is a CIGI link that has received
// a valid IG Control; -1 otherwise. For status displays.
int cigiHostIgMode(const HostLink& link);

}  // namespace ig::io
