// SocketCAN host link: a raw CAN socket (PF_CAN, SOCK_RAW, CAN_RAW) bound to one interface, a
// receive thread that feeds the frames of the map (io/can_map.h) into a CanSetAssembler and
// publishes every committed set to the HostSink.
//
// The socket has a receive filter for base_id..base_id+4 (11-bit) and CAN_RAW_ERR_FILTER for
// every error class, and accepts CAN FD frames (so an FD frame with a map id is counted as
// malformed instead of being dropped by the kernel unseen). Error frames are counted
// (busErrors()) and logged once per burst: the first error frame after one second without any
// is logged with its class bits, and the end of a burst with its count.
//
// The receive thread waits in poll() with a 20 ms timeout, so stop() returns within about
// 20 ms, and checks for a stale incomplete set on every wake-up. Timestamps are the monotonic
// clock at read time.
#pragma once

#include <atomic>
#include <memory>
#include <string>
#include <thread>

#include "io/can_map.h"
#include "io/link.h"
#include "lod/geo.h"

namespace ig::io {

class CanLink final : public HostLink {
 public:
  CanLink(const CanLinkConfig& config, const lod::Geodetic& origin);
  ~CanLink() override;
  CanLink(const CanLink&) = delete;
  CanLink& operator=(const CanLink&) = delete;

  std::string_view name() const override { return "can"; }
  // Errors: "host.can.interface = can9: no such CAN interface",
  // "host.can.interface = eth0: not a CAN interface", "cannot open a CAN socket for
  // host.can.interface = vcan0: Address family not supported by protocol", or a config range.
  bool start(HostSink& sink, std::string& error) override;
  void stop() override;

  // Error frames (CAN_ERR_FLAG) received since start.
  uint64_t busErrors() const { return busErrors_.load(std::memory_order_relaxed); }
  const CanLinkConfig& config() const { return config_; }

 private:
  void run(HostSink* sink);

  CanLinkConfig config_;
  lod::Geodetic origin_;
  int fd_ = -1;
  std::thread thread_;
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> busErrors_{0};
};

std::unique_ptr<HostLink> makeCanLink(const CanLinkConfig& config, const lod::Geodetic& origin);

}  // namespace ig::io
