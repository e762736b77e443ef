// CIGI 3.3 host link over UDP: igd is the IG. The host sends one message (datagram) per host
// frame: IG Control first, then Entity Control for the ownship, optionally View Control, View
// Definition and Celestial Sphere Control. igd answers every frame with a Start of Frame.
//
// Two parts:
//  - CigiAssembler: pure (no sockets, no clock). Turns decoded messages into HostState: the
//    eyepoint, attitude, frustum, time and date, field by field, with the late / restart rule.
//    Shared by the live link and the pcap converter (io/pcap.h), so a capture replays exactly
//    what the live link would have rendered.
//  - CigiLink: the UDP transport. One receive thread (poll() with a 50 ms timeout so stop()
//    joins promptly); frameStarted() sends the Start of Frame from the frame loop's thread with
//    a non-blocking sendto (errors counted, never thrown, never blocking).
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

 private:
  bool isLate(const cigi::IgControl& ig);
  void applyEntity(const cigi::EntityControl& e, LinkCounters& counters);
  void applyView(const cigi::ViewControl& v, LinkCounters& counters);
  void applyViewDefinition(const cigi::ViewDefinition& d, LinkCounters& counters);
  void applyCelestial(const cigi::CelestialSphereControl& c, LinkCounters& counters);
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
};

// Eye position and attitude from an entity pose and a view offset (pure; used by the
// assembler, exposed for tests). Positions in ECEF; angles in degrees; offsets in body axes.
struct EyePose {
  glm::dvec3 ecef_m{0.0};
  glm::dvec3 forwardEcef{0.0}, rightEcef{0.0}, downEcef{0.0};  // view axes, unit vectors
};
EyePose cigiEyePose(const lod::Geodetic& entity, double yaw_deg, double pitch_deg, double roll_deg,
                    const glm::dvec3& offsetBody_m, double viewYaw_deg, double viewPitch_deg, double viewRoll_deg);

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
};

std::unique_ptr<CigiLink> makeCigiLink(const CigiLinkConfig& config, const lod::Geodetic& origin);

// The host's requested IG mode (cigi::IgMode value) if `link` is a CIGI link that has received
// a valid IG Control; -1 otherwise. For status displays.
int cigiHostIgMode(const HostLink& link);

}  // namespace ig::io
