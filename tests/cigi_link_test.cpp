// The CIGI link over real loopback UDP: a test socket plays the host, sends datagrams to the
// link and receives its Start of Frame. Waits poll the sink or the socket with generous
// deadlines (never fixed sleeps).
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <vector>

#include "io/cigi.h"
#include "io/cigi_link.h"

using namespace ig::io;
using namespace std::chrono_literals;

namespace {

const ig::lod::Geodetic kOrigin{57.7, 11.97, 100.0};

class TestSink : public HostSink {
 public:
  void publish(const HostState& s) override {
    std::lock_guard<std::mutex> lock(m_);
    states_.push_back(s);
    cv_.notify_all();
  }
  bool waitFor(size_t n, std::chrono::milliseconds timeout = 10s) {
    std::unique_lock<std::mutex> lock(m_);
    return cv_.wait_for(lock, timeout, [&] { return states_.size() >= n; });
  }
  HostState last() {
    std::lock_guard<std::mutex> lock(m_);
    return states_.back();
  }
  size_t count() {
    std::lock_guard<std::mutex> lock(m_);
    return states_.size();
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  std::vector<HostState> states_;
};

// Polls a condition until it holds or the deadline passes.
template <class F>
bool eventually(F f, std::chrono::milliseconds timeout = 10s) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    if (f()) return true;
    pollfd none{};
    poll(&none, 0, 5);
  }
  return f();
}

struct HostSocket {
  int fd = -1;
  uint16_t port = 0;
  HostSocket() {
    fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
    socklen_t len = sizeof a;
    getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
    port = ntohs(a.sin_port);
  }
  ~HostSocket() { close(fd); }
  void send(const std::vector<std::byte>& b, uint16_t to) const {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons(to);
    ASSERT_EQ(sendto(fd, b.data(), b.size(), 0, reinterpret_cast<sockaddr*>(&a), sizeof a),
              static_cast<ssize_t>(b.size()));
  }
  // Receives one datagram within the timeout; empty on timeout.
  std::vector<std::byte> receive(int timeout_ms = 10000) const {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, timeout_ms) <= 0) return {};
    std::vector<std::byte> b(65536);
    const ssize_t n = recv(fd, b.data(), b.size(), 0);
    b.resize(n > 0 ? static_cast<size_t>(n) : 0);
    return b;
  }
};

std::vector<std::byte> message(uint32_t frame, double lat, double lon, double alt, float yaw,
                               cigi::ByteOrder order = cigi::ByteOrder::big, uint16_t entityId = 0) {
  std::vector<std::byte> b(24 + 48);
  cigi::IgControl ig;
  ig.hostFrame = frame;
  ig.timestampValid = true;
  ig.timestamp_10us = frame * 1667;
  cigi::EntityControl e;
  e.entityId = entityId;
  e.lat_deg = lat;
  e.lon_deg = lon;
  e.alt_m = alt;
  e.yaw_deg = yaw;
  cigi::encode(ig, order, std::span(b).first(24));
  cigi::encode(e, order, std::span(b).subspan(24));
  return b;
}

CigiLinkConfig loopbackConfig(uint16_t hostPort) {
  CigiLinkConfig c;
  c.bind_address = "127.0.0.1";
  c.port = 0;  // any free port
  c.host_port = hostPort;
  return c;
}

}  // namespace

TEST(CigiLink, ReceivesMessagesAndAnswersWithStartOfFrame) {
  HostSocket host;
  auto link = makeCigiLink(loopbackConfig(0), kOrigin);  // reply to the sender's port
  TestSink sink;
  std::string e;
  ASSERT_TRUE(link->start(sink, e)) << e;
  ASSERT_NE(link->localPort(), 0);
  EXPECT_EQ(link->hostIgMode(), -1);

  // No host yet: frameStarted has nowhere to send and must not block or fail.
  FrameStart f;
  f.igFrame = 1;
  f.hostLost = true;
  link->frameStarted(f);
  EXPECT_EQ(link->startOfFramesSent(), 0u);

  host.send(message(41, kOrigin.lat_deg, kOrigin.lon_deg, 350.0, 90.0f, cigi::ByteOrder::little), link->localPort());
  ASSERT_TRUE(sink.waitFor(1));
  const HostState s = sink.last();
  EXPECT_EQ(s.hostFrame, 41u);
  EXPECT_NEAR(s.simTime_s, 41 * 1667e-5, 1e-9);
  EXPECT_NEAR(s.eyeEnu_m.z, 250.0, 1e-6);
  EXPECT_NEAR(s.heading_deg, 90.0, 1e-6);
  EXPECT_EQ(link->hostIgMode(), static_cast<int>(cigi::IgMode::operate));

  f.igFrame = 2;
  f.hostLost = false;
  f.time_s = 12.5;
  link->frameStarted(f);
  const auto sofBytes = host.receive();
  cigi::StartOfFrame sof;
  ASSERT_EQ(cigi::decodeStartOfFrame(sofBytes, sof), cigi::CigiStatus::ok);
  EXPECT_EQ(sofBytes.size(), cigi::kStartOfFrameSize);
  EXPECT_EQ(sof.igFrame, 2u);
  EXPECT_EQ(sof.lastHostFrame, 41u);
  EXPECT_EQ(sof.timestamp_10us, 1250000u);
  EXPECT_EQ(sof.igStatus, CigiLink::kStatusNormal);
  EXPECT_EQ(sof.igMode, cigi::IgMode::operate);

  // Host lost: status 1, Standby.
  f.igFrame = 3;
  f.hostLost = true;
  link->frameStarted(f);
  ASSERT_EQ(cigi::decodeStartOfFrame(host.receive(), sof), cigi::CigiStatus::ok);
  EXPECT_EQ(sof.igFrame, 3u);
  EXPECT_EQ(sof.igStatus, CigiLink::kStatusHostLost);
  EXPECT_EQ(sof.igMode, cigi::IgMode::standby);
  EXPECT_EQ(link->startOfFramesSent(), 2u);
  EXPECT_EQ(link->sendErrors(), 0u);

  const auto c = snapshot(link->counters());
  EXPECT_EQ(c.received, 1u);
  EXPECT_EQ(c.accepted, 1u);
  link->stop();
  link->stop();  // idempotent
}

TEST(CigiLink, CountsMalformedLateAndDropped) {
  HostSocket host;
  auto link = makeCigiLink(loopbackConfig(0), kOrigin);
  TestSink sink;
  std::string e;
  ASSERT_TRUE(link->start(sink, e)) << e;
  auto bad = message(1, 57.7, 11.97, 100.0, 0.0f);
  bad[7] = std::byte{0x55};  // bad magic
  host.send(bad, link->localPort());
  host.send({}, link->localPort());  // empty datagram
  host.send(message(10, 57.7, 11.97, 100.0, 0.0f), link->localPort());
  host.send(message(11, 57.7, 11.97, 100.0, 0.0f), link->localPort());
  host.send(message(9, 57.7, 11.97, 100.0, 0.0f), link->localPort());  // late
  host.send(message(12, 57.7, 11.97, 100.0, 0.0f), link->localPort());
  ASSERT_TRUE(eventually([&] { return snapshot(link->counters()).received == 6; }));
  ASSERT_TRUE(sink.waitFor(3));
  const auto c = snapshot(link->counters());
  EXPECT_EQ(c.malformed, 2u);
  EXPECT_EQ(c.late, 1u);
  EXPECT_EQ(c.accepted, 3u);
  EXPECT_EQ(sink.last().hostFrame, 12u);
  // Three samples published before the first frame: two were never rendered.
  link->frameStarted(FrameStart{});
  EXPECT_EQ(snapshot(link->counters()).dropped, 2u);
  link->frameStarted(FrameStart{});
  EXPECT_EQ(snapshot(link->counters()).dropped, 2u);
}

TEST(CigiLink, FixedHostAddressGetsStartOfFrameBeforeAnyMessage) {
  HostSocket host;
  CigiLinkConfig cfg = loopbackConfig(host.port);
  cfg.host_address = "127.0.0.1";
  cfg.database = 4;
  auto link = makeCigiLink(cfg, kOrigin);
  TestSink sink;
  std::string e;
  ASSERT_TRUE(link->start(sink, e)) << e;
  FrameStart f;
  f.igFrame = 9;
  f.hostLost = true;
  link->frameStarted(f);
  cigi::StartOfFrame sof;
  ASSERT_EQ(cigi::decodeStartOfFrame(host.receive(), sof), cigi::CigiStatus::ok);
  EXPECT_EQ(sof.igFrame, 9u);
  EXPECT_EQ(sof.databaseNumber, 4);
  EXPECT_EQ(sof.igMode, cigi::IgMode::standby);
}

TEST(CigiLink, BindErrorNamesAddressAndReason) {
  HostSocket host;
  CigiLinkConfig cfg;
  cfg.bind_address = "127.0.0.1";
  cfg.port = host.port;  // already bound by the host socket
  auto link = makeCigiLink(cfg, kOrigin);
  TestSink sink;
  std::string e;
  EXPECT_FALSE(link->start(sink, e));
  EXPECT_EQ(e, "cannot bind 127.0.0.1:" + std::to_string(host.port) + ": Address already in use");
  cfg.port = 70000;
  auto bad = makeCigiLink(cfg, kOrigin);
  EXPECT_FALSE(bad->start(sink, e));
  EXPECT_EQ(e, "host.cigi.port = 70000: must be 1..65535");
}

TEST(CigiLink, StopJoinsPromptlyUnderAFlood) {
  HostSocket host;
  auto link = makeCigiLink(loopbackConfig(0), kOrigin);
  TestSink sink;
  std::string e;
  ASSERT_TRUE(link->start(sink, e)) << e;
  const auto m = message(1, 57.7, 11.97, 100.0, 0.0f);
  for (int i = 0; i < 2000; ++i) host.send(m, link->localPort());
  ASSERT_TRUE(sink.waitFor(1));
  const auto t0 = std::chrono::steady_clock::now();
  link->stop();
  const auto took = std::chrono::steady_clock::now() - t0;
  EXPECT_LT(took, 2s);  // one poll period (50 ms) plus at most 256 datagrams; generous
  EXPECT_GT(snapshot(link->counters()).received, 0u);
}

TEST(CigiLink, OwnshipAmongOtherEntities) {
  HostSocket host;
  CigiLinkConfig cfg = loopbackConfig(0);
  cfg.entity_id = 3;
  auto link = makeCigiLink(cfg, kOrigin);
  TestSink sink;
  std::string e;
  ASSERT_TRUE(link->start(sink, e)) << e;
  std::vector<std::byte> b = message(5, 57.7, 11.97, 1000.0, 10.0f);  // entity 0: not ours
  const auto own = message(5, 57.7, 11.97, 2000.0, 20.0f, cigi::ByteOrder::big, 3);
  b.insert(b.end(), own.begin() + 24, own.end());
  host.send(b, link->localPort());
  ASSERT_TRUE(sink.waitFor(1));
  EXPECT_NEAR(sink.last().height_m, 2000.0, 1e-6);
  EXPECT_NEAR(sink.last().heading_deg, 20.0, 1e-6);
}
