#include "io/can_link.h"

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>

namespace ig::io {
namespace {

constexpr int kPollTimeout_ms = 20;
constexpr int64_t kBurstGap_us = 1'000'000;  // error frames closer than this belong to one burst

int64_t monotonicNow_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

CanLink::CanLink(const CanLinkConfig& config, const lod::Geodetic& origin) : config_(config), origin_(origin) {}

CanLink::~CanLink() { stop(); }

bool CanLink::start(HostSink& sink, std::string& error) {
  stop();
  if (!validateCanLinkConfig(config_, error)) return false;
  const std::string key = "host.can.interface = " + config_.interface;
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    error = "cannot open a CAN socket for " + key + ": " + std::strerror(errno);
    return false;
  }
  auto fail = [&](const std::string& message) {
    error = message;
    ::close(fd);
    return false;
  };
  const unsigned ifindex = ::if_nametoindex(config_.interface.c_str());
  if (ifindex == 0) {
    if (errno == ENODEV || errno == ENXIO) return fail(key + ": no such CAN interface");
    return fail(key + ": " + std::strerror(errno));
  }
  // Only the map's ids (and error frames) reach the socket.
  can_filter filters[kCanFrameCount];
  for (int i = 0; i < kCanFrameCount; ++i) {
    filters[i].can_id = config_.baseId + static_cast<canid_t>(i);
    filters[i].can_mask = CAN_SFF_MASK | CAN_EFF_FLAG;  // 11-bit only; remote frames pass (malformed)
  }
  const can_err_mask_t errMask = CAN_ERR_MASK;
  const int on = 1;
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, filters, sizeof filters) < 0 ||
      ::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &errMask, sizeof errMask) < 0 ||
      ::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FD_FRAMES, &on, sizeof on) < 0)
    return fail("cannot set the CAN filters for " + key + ": " + std::strerror(errno));
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(ifindex);
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) < 0) {
    // Binding a CAN socket to an interface of another type fails with ENODEV (or EINVAL).
    if (errno == ENODEV || errno == EINVAL) return fail(key + ": not a CAN interface");
    return fail("cannot bind a CAN socket to " + key + ": " + std::strerror(errno));
  }
  fd_ = fd;
  stop_.store(false);
  thread_ = std::thread([this, &sink] { run(&sink); });
  return true;
}

void CanLink::stop() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
  if (fd_ >= 0) {
    ::close(fd_);
    fd_ = -1;
  }
}

void CanLink::run(HostSink* sink) {
  lowerLinkThreadPriority();
  CanSetAssembler assembler(config_, origin_, counters_);
  bool inBurst = false;
  int64_t lastError_us = 0;
  uint64_t burstCount = 0;
  canfd_frame raw{};
  while (!stop_.load(std::memory_order_relaxed)) {
    pollfd p{fd_, POLLIN, 0};
    const int n = ::poll(&p, 1, kPollTimeout_ms);
    const int64_t now_us = monotonicNow_us();
    if (inBurst && now_us - lastError_us > kBurstGap_us) {
      std::fprintf(stderr, "igd: can %s: bus error burst over: %llu error frames\n", config_.interface.c_str(),
                   static_cast<unsigned long long>(burstCount));
      inBurst = false;
    }
    if (n <= 0) {
      assembler.expire(now_us);
      continue;
    }
    if (!(p.revents & POLLIN)) {
      // The interface went down (ENETDOWN on the socket): clear the error and keep waiting, it
      // may come back; a short pause so that a lasting error does not spin.
      int soErr = 0;
      socklen_t len = sizeof soErr;
      ::getsockopt(fd_, SOL_SOCKET, SO_ERROR, &soErr, &len);
      ::poll(nullptr, 0, kPollTimeout_ms);
      assembler.expire(now_us);
      continue;
    }
    const ssize_t got = ::recv(fd_, &raw, sizeof raw, MSG_DONTWAIT);
    if (got < 0) continue;  // EAGAIN, ENETDOWN, ...: try again
    CanFrame frame;
    if (got == static_cast<ssize_t>(CAN_MTU)) {
      frame.len = raw.len > 8 ? 8 : raw.len;
    } else if (got == static_cast<ssize_t>(CANFD_MTU)) {
      frame.fd = true;
      frame.len = raw.len > 64 ? 64 : raw.len;
    } else {
      continue;  // not a CAN frame
    }
    frame.extended = (raw.can_id & CAN_EFF_FLAG) != 0;
    frame.remote = (raw.can_id & CAN_RTR_FLAG) != 0;
    frame.error = (raw.can_id & CAN_ERR_FLAG) != 0;
    frame.id = raw.can_id & (frame.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
    std::memcpy(frame.data.data(), raw.data, frame.len);
    if (frame.error) {
      busErrors_.fetch_add(1, std::memory_order_relaxed);
      if (!inBurst) {
        std::fprintf(stderr, "igd: can %s: bus error frame (class 0x%08x, data %02x %02x %02x %02x %02x %02x %02x %02x)\n",
                     config_.interface.c_str(), static_cast<unsigned>(raw.can_id & CAN_ERR_MASK), raw.data[0],
                     raw.data[1], raw.data[2], raw.data[3], raw.data[4], raw.data[5], raw.data[6], raw.data[7]);
        inBurst = true;
        burstCount = 0;
      }
      ++burstCount;
      lastError_us = now_us;
      continue;
    }
    HostState state;
    if (assembler.push(frame, now_us, state) == CanSetAssembler::Result::Committed) sink->publish(state);
  }
}

std::unique_ptr<HostLink> makeCanLink(const CanLinkConfig& config, const lod::Geodetic& origin) {
  return std::make_unique<CanLink>(config, origin);
}

}  // namespace ig::io
