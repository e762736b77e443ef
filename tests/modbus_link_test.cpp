// Modbus transports: config errors; the TCP server driven in-process by libmodbus as the master
// (both word orders, commit semantics on the wire, exceptions, several masters and reconnects,
// garbage, prompt stop); and real peers: mbpoll as the master over TCP on loopback and over
// RTU on a socat pty pair, including a malformed RTU frame (bad CRC) that must be counted.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <modbus.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "io/modbus_link.h"
#include "io/modbus_map.h"

extern char** environ;

using namespace ig::io;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

const ig::lod::Geodetic kOrigin{47.25, 11.5, 600.0};
constexpr auto kWait = 10s;  // generous: a loaded 2-core CI machine

class RecordingSink : public HostSink {
 public:
  void publish(const HostState& s) override {
    std::lock_guard<std::mutex> lock(mutex_);
    states_.push_back(s);
    cv_.notify_all();
  }
  bool waitFor(size_t n, std::chrono::milliseconds timeout = kWait) {
    std::unique_lock<std::mutex> lock(mutex_);
    return cv_.wait_for(lock, timeout, [&] { return states_.size() >= n; });
  }
  size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return states_.size();
  }
  HostState last() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return states_.back();
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<HostState> states_;
};

bool waitUntil(const std::function<bool()>& pred, std::chrono::milliseconds timeout = kWait) {
  const auto end = Clock::now() + timeout;
  while (Clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(5ms);
  }
  return pred();
}

// The values every test writes (units as in the map).
modbus::HoldingBlock makeSet(modbus::WordOrder order, uint32_t commit, double east = 1250.5) {
  HostState s;
  s.eyeEnu_m = {east, -830.25, 455.0};
  s.heading_deg = 135.0;
  s.pitch_deg = -9.5;
  s.roll_deg = 12.0;
  s.fovY_deg = 60.0;
  s.near_m = 0.5;
  s.far_m = 20000.0;
  s.simTime_s = 3600.25;
  s.hostFrame = 4242;
  s.timeOfDay_h = 13.5;
  modbus::HoldingBlock b{};
  modbus::encodeHostRegisters(s, commit, order, b);
  return b;
}

void expectSet(const HostState& s, double east = 1250.5) {
  EXPECT_DOUBLE_EQ(s.eyeEnu_m.x, east);
  EXPECT_DOUBLE_EQ(s.eyeEnu_m.y, -830.25);
  EXPECT_DOUBLE_EQ(s.eyeEnu_m.z, 455.0);
  EXPECT_DOUBLE_EQ(s.heading_deg, 135.0);
  EXPECT_DOUBLE_EQ(s.pitch_deg, -9.5);
  EXPECT_DOUBLE_EQ(s.roll_deg, 12.0);
  EXPECT_DOUBLE_EQ(s.fovY_deg, 60.0);
  EXPECT_DOUBLE_EQ(s.near_m, 0.5);
  EXPECT_DOUBLE_EQ(s.far_m, 20000.0);
  EXPECT_DOUBLE_EQ(s.simTime_s, 3600.25);
  EXPECT_EQ(s.hostFrame, 4242u);
  EXPECT_DOUBLE_EQ(s.timeOfDay_h, 13.5);
  // The geodetic eyepoint is the ENU one seen from the scene origin.
  const ig::lod::Geodetic g = ig::lod::EnuFrame(kOrigin).toGeodetic(s.eyeEnu_m);
  EXPECT_NEAR(s.lat_deg, g.lat_deg, 1e-12);
  EXPECT_NEAR(s.lon_deg, g.lon_deg, 1e-12);
  EXPECT_NEAR(s.height_m, g.height_m, 1e-6);
  EXPECT_GT(s.lat_deg, kOrigin.lat_deg - 0.1);
  EXPECT_LT(s.lat_deg, kOrigin.lat_deg);  // 830 m south of the origin
  EXPECT_GT(s.lon_deg, kOrigin.lon_deg);  // 1250 m east
}

// A started TCP link on a free port.
struct TcpFixture {
  explicit TcpFixture(modbus::WordOrder order = modbus::WordOrder::LowFirst) {
    ModbusLinkConfig c;
    c.tcpPort = 0;
    c.wordOrder = order;
    link = std::make_unique<ModbusLink>(c, ModbusTransport::Tcp, kOrigin);
    std::string error;
    started = link->start(sink, error);
    EXPECT_TRUE(started) << error;
    port = link->boundPort();
    EXPECT_NE(port, 0);
  }
  RecordingSink sink;
  std::unique_ptr<ModbusLink> link;
  bool started = false;
  uint16_t port = 0;
};

// A libmodbus master connected to the link.
struct Master {
  explicit Master(uint16_t port) {
    ctx = modbus_new_tcp("127.0.0.1", port);
    modbus_set_response_timeout(ctx, 5, 0);
    connected = modbus_connect(ctx) == 0;
    EXPECT_TRUE(connected) << modbus_strerror(errno);
  }
  ~Master() {
    modbus_close(ctx);
    modbus_free(ctx);
  }
  Master(const Master&) = delete;
  Master& operator=(const Master&) = delete;
  int write(uint16_t address, std::span<const uint16_t> regs) {
    return modbus_write_registers(ctx, address, static_cast<int>(regs.size()), regs.data());
  }
  modbus::IgStatus status(modbus::WordOrder order) {
    modbus::InputBlock in{};
    EXPECT_EQ(modbus_read_input_registers(ctx, 0, modbus::kInputCount, in.data()), modbus::kInputCount)
        << modbus_strerror(errno);
    return modbus::decodeStatusRegisters(in, order);
  }
  modbus_t* ctx = nullptr;
  bool connected = false;
};

struct ProcessResult {
  int exitCode = -1;  // -1: killed on timeout
  std::string output;
};

// Runs argv[0] (searched on PATH) with stdout and stderr captured; kills it after `timeout`.
ProcessResult run(const std::vector<std::string>& args, std::chrono::milliseconds timeout = kWait) {
  ProcessResult r;
  int pipeFds[2];
  if (pipe2(pipeFds, O_CLOEXEC) != 0) return r;
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, pipeFds[1], 1);
  posix_spawn_file_actions_adddup2(&actions, pipeFds[1], 2);
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  close(pipeFds[1]);
  if (rc != 0) {
    close(pipeFds[0]);
    r.output = "cannot run " + args[0];
    return r;
  }
  const auto end = Clock::now() + timeout;
  char buf[4096];
  bool killed = false;
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - Clock::now()).count();
    if (left <= 0) {
      kill(pid, SIGKILL);
      killed = true;
      break;
    }
    pollfd p{pipeFds[0], POLLIN, 0};
    if (poll(&p, 1, static_cast<int>(left)) <= 0) continue;
    const ssize_t n = read(pipeFds[0], buf, sizeof buf);
    if (n <= 0) break;
    r.output.append(buf, static_cast<size_t>(n));
  }
  close(pipeFds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  if (!killed && WIFEXITED(status)) r.exitCode = WEXITSTATUS(status);
  return r;
}

// mbpoll's read output lines "[ref]: \tvalue" -> values in order.
std::vector<long long> mbpollValues(const std::string& out) {
  std::vector<long long> v;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] != '[') continue;
    const size_t colon = line.find("]:");
    if (colon == std::string::npos) continue;
    v.push_back(std::atoll(line.c_str() + colon + 2));
  }
  return v;
}

// The 13 values of a set as mbpoll arguments.
std::vector<std::string> setArgs(uint32_t commit) {
  return {"1250.5", "-830.25", "455", "135", "-9.5", "12", "60", "0.5", "20000", "3600.25", "4242", "13.5",
          std::to_string(commit)};
}

std::vector<std::string> concat(std::vector<std::string> a, const std::vector<std::string>& b) {
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
TEST(ModbusConfig, ErrorsNameKeyAndValue) {
  auto error = [](ModbusLinkConfig c, ModbusTransport t) {
    std::string e;
    EXPECT_FALSE(validateModbusLinkConfig(c, t, e));
    return e;
  };
  ModbusLinkConfig ok;
  std::string e;
  EXPECT_TRUE(validateModbusLinkConfig(ok, ModbusTransport::Tcp, e)) << e;
  ok.serialDevice = "/dev/ttyUSB0";
  EXPECT_TRUE(validateModbusLinkConfig(ok, ModbusTransport::Rtu, e)) << e;

  ModbusLinkConfig c = ok;
  c.tcpPort = 70000;
  EXPECT_EQ(error(c, ModbusTransport::Tcp), "host.modbus.tcp_port = 70000: must be 0..65535");
  c = ok;
  c.tcpAddress = "localhost";
  EXPECT_EQ(error(c, ModbusTransport::Tcp),
            "host.modbus.tcp_address = \"localhost\": not an IPv4 address (e.g. \"127.0.0.1\" or \"0.0.0.0\")");
  c = ok;
  c.unitId = 0;
  EXPECT_EQ(error(c, ModbusTransport::Rtu), "host.modbus.unit_id = 0: must be 1..247");
  c = ok;
  c.baud = 12345;
  EXPECT_NE(error(c, ModbusTransport::Rtu).find("host.modbus.baud = 12345: must be one of"), std::string::npos);
  c = ok;
  c.parity = 'X';
  EXPECT_EQ(error(c, ModbusTransport::Rtu), "host.modbus.parity = \"X\": must be \"N\", \"E\" or \"O\"");
  c = ok;
  c.dataBits = 9;
  EXPECT_EQ(error(c, ModbusTransport::Rtu), "host.modbus.data_bits = 9: must be 7 or 8");
  c = ok;
  c.stopBits = 3;
  EXPECT_EQ(error(c, ModbusTransport::Rtu), "host.modbus.stop_bits = 3: must be 1 or 2");
  c = ok;
  c.serialDevice.clear();
  EXPECT_NE(error(c, ModbusTransport::Rtu).find("host.modbus.serial_device = \"\""), std::string::npos);
  // The TCP transport does not care about serial settings, and the reverse.
  c = ok;
  c.baud = 1;
  c.serialDevice.clear();
  EXPECT_TRUE(validateModbusLinkConfig(c, ModbusTransport::Tcp, e)) << e;

  char p = 0;
  EXPECT_TRUE(parseModbusParity("E", p));
  EXPECT_EQ(p, 'E');
  EXPECT_FALSE(parseModbusParity("even", p));
  EXPECT_EQ(makeModbusTcpLink(ok, kOrigin)->name(), "modbus-tcp");
  EXPECT_EQ(makeModbusRtuLink(ok, kOrigin)->name(), "modbus-rtu");
}

TEST(ModbusTcp, StartErrorsNameTheAddress) {
  TcpFixture first;
  ModbusLinkConfig c;
  c.tcpPort = first.port;
  ModbusLink second(c, ModbusTransport::Tcp, kOrigin);
  RecordingSink sink;
  std::string error;
  EXPECT_FALSE(second.start(sink, error));
  EXPECT_EQ(error, "cannot listen on 127.0.0.1:" + std::to_string(first.port) + ": Address already in use");
  c.tcpPort = 70000;
  ModbusLink third(c, ModbusTransport::Tcp, kOrigin);
  EXPECT_FALSE(third.start(sink, error));
  EXPECT_EQ(error, "host.modbus.tcp_port = 70000: must be 0..65535");

  c.serialDevice = "/nonexistent/ttyX";
  ModbusLink rtu(c, ModbusTransport::Rtu, kOrigin);
  EXPECT_FALSE(rtu.start(sink, error));
  EXPECT_EQ(error, "cannot open serial device /nonexistent/ttyX: No such file or directory");
  rtu.stop();  // idempotent after a failed start
}

class ModbusTcpOrders : public ::testing::TestWithParam<modbus::WordOrder> {};

TEST_P(ModbusTcpOrders, LibmodbusMasterWritesASetAndReadsStatus) {
  const modbus::WordOrder order = GetParam();
  TcpFixture f(order);
  ASSERT_TRUE(f.started);
  Master m(f.port);
  ASSERT_TRUE(m.connected);
  const modbus::HoldingBlock set = makeSet(order, 1);
  ASSERT_EQ(m.write(0, set), modbus::kHoldingCount) << modbus_strerror(errno);
  ASSERT_TRUE(f.sink.waitFor(1));
  expectSet(f.sink.last());

  f.link->frameStarted(FrameStart{77, 4242, 2.5, true, false});
  const modbus::IgStatus st = m.status(order);
  EXPECT_EQ(st.igFrame, 77u);
  EXPECT_EQ(st.lastHostFrame, 4242u);
  EXPECT_TRUE(st.hostLost);
  EXPECT_EQ(st.appliedCommit, 1u);
  EXPECT_EQ(st.rejectedFields, 0u);
  EXPECT_EQ(st.counters.received, 2u);  // the write and this read
  EXPECT_EQ(st.counters.accepted, 1u);
  EXPECT_EQ(st.counters.malformed, 0u);
  EXPECT_EQ(st.mapVersion, modbus::kMapVersion);

  // The holding registers read back as written.
  modbus::HoldingBlock back{};
  ASSERT_EQ(modbus_read_registers(m.ctx, 0, modbus::kHoldingCount, back.data()), modbus::kHoldingCount);
  EXPECT_EQ(back, set);

  // A NaN pitch is rejected on its own; the rest of the set applies.
  modbus::HoldingBlock bad = makeSet(order, 2, -100.0);
  modbus::writeF32(bad, modbus::slotAddress(modbus::Slot::Pitch), std::nanf(""), order);
  ASSERT_EQ(m.write(0, bad), modbus::kHoldingCount);
  ASSERT_TRUE(f.sink.waitFor(2));
  EXPECT_EQ(f.sink.last().eyeEnu_m.x, -100.0);
  EXPECT_EQ(f.sink.last().pitch_deg, -9.5);
  const modbus::IgStatus st2 = m.status(order);
  EXPECT_EQ(st2.counters.outOfRange, 1u);
  EXPECT_EQ(st2.rejectedFields, 1u << static_cast<int>(modbus::Slot::Pitch));
  EXPECT_EQ(f.link->counters().outOfRange.load(), 1u);
}

INSTANTIATE_TEST_SUITE_P(Both, ModbusTcpOrders,
                         ::testing::Values(modbus::WordOrder::LowFirst, modbus::WordOrder::HighFirst),
                         [](const auto& p) { return std::string(modbus::toString(p.param)); });

TEST(ModbusTcp, HalfWrittenSetIsNeverPublished) {
  const auto order = modbus::WordOrder::LowFirst;
  TcpFixture f(order);
  ASSERT_TRUE(f.started);
  Master m(f.port);
  ASSERT_TRUE(m.connected);
  const modbus::HoldingBlock set = makeSet(order, 5);
  ASSERT_EQ(m.write(0, std::span(set).first(12)), 12);
  // The link serves one request at a time: once this read is answered the write was handled.
  m.status(order);
  EXPECT_EQ(f.sink.size(), 0u);
  ASSERT_EQ(m.write(12, std::span(set).subspan(12, 12)), 12);
  m.status(order);
  EXPECT_EQ(f.sink.size(), 0u);
  // COMMIT alone, last: the whole set applies.
  ASSERT_EQ(m.write(24, std::span(set).subspan(24, 2)), 2);
  ASSERT_TRUE(f.sink.waitFor(1));
  expectSet(f.sink.last());
  // The same COMMIT again: a repeat, counted late, nothing published.
  ASSERT_EQ(m.write(24, std::span(set).subspan(24, 2)), 2);
  const modbus::IgStatus st = m.status(order);
  EXPECT_EQ(st.counters.late, 1u);
  EXPECT_EQ(st.counters.accepted, 1u);
  EXPECT_EQ(f.sink.size(), 1u);
}

TEST(ModbusTcp, UnknownRegistersAnswerIllegalDataAddress) {
  TcpFixture f;
  ASSERT_TRUE(f.started);
  Master m(f.port);
  ASSERT_TRUE(m.connected);
  const uint16_t one[2] = {1, 2};
  EXPECT_EQ(m.write(28, std::span<const uint16_t>(one, 1)), -1);
  EXPECT_EQ(errno, EMBXILADD);
  EXPECT_EQ(m.write(27, std::span<const uint16_t>(one, 2)), -1);
  EXPECT_EQ(errno, EMBXILADD);
  EXPECT_EQ(modbus_write_register(m.ctx, 100, 1), -1);
  EXPECT_EQ(errno, EMBXILADD);
  uint16_t regs[2];
  EXPECT_EQ(modbus_read_input_registers(m.ctx, 23, 2, regs), -1);
  EXPECT_EQ(errno, EMBXILADD);
  uint8_t bits[8];
  EXPECT_EQ(modbus_read_bits(m.ctx, 0, 1, bits), -1);
  EXPECT_EQ(errno, EMBXILADD);
  EXPECT_EQ(modbus_write_bit(m.ctx, 0, 1), -1);
  EXPECT_EQ(errno, EMBXILADD);
  // The connection still works and nothing was applied.
  const modbus::IgStatus st = m.status(modbus::WordOrder::LowFirst);
  EXPECT_EQ(st.counters.malformed, 6u);
  EXPECT_EQ(st.counters.accepted, 0u);
  EXPECT_EQ(f.sink.size(), 0u);
  // FC6 to COMMIT's low register commits (the registers already hold the start-up defaults).
  EXPECT_EQ(modbus_write_register(m.ctx, 24, 9), 1);
  ASSERT_TRUE(f.sink.waitFor(1));
  EXPECT_DOUBLE_EQ(f.sink.last().fovY_deg, 45.0);
}

TEST(ModbusTcp, SeveralMastersAndReconnects) {
  const auto order = modbus::WordOrder::LowFirst;
  TcpFixture f(order);
  ASSERT_TRUE(f.started);
  auto a = std::make_unique<Master>(f.port);
  Master b(f.port);
  Master c(f.port);
  ASSERT_TRUE(a->connected && b.connected && c.connected);
  EXPECT_EQ(a->write(0, makeSet(order, 1, 1.0)), modbus::kHoldingCount);
  EXPECT_EQ(b.write(0, makeSet(order, 2, 2.0)), modbus::kHoldingCount);
  EXPECT_EQ(c.write(0, makeSet(order, 3, 3.0)), modbus::kHoldingCount);
  ASSERT_TRUE(f.sink.waitFor(3));
  EXPECT_EQ(f.sink.last().eyeEnu_m.x, 3.0);
  a.reset();  // master a goes away ...
  Master again(f.port);  // ... and comes back
  ASSERT_TRUE(again.connected);
  EXPECT_EQ(again.write(0, makeSet(order, 4, 4.0)), modbus::kHoldingCount);
  ASSERT_TRUE(f.sink.waitFor(4));
  EXPECT_EQ(f.sink.last().eyeEnu_m.x, 4.0);
  EXPECT_EQ(b.status(order).counters.accepted, 4u);
  EXPECT_EQ(f.link->counters().malformed.load(), 0u);
}

TEST(ModbusTcp, GarbageIsCountedAndOthersAreServed) {
  TcpFixture f;
  ASSERT_TRUE(f.started);
  // A raw socket sends a frame with an unknown function code, then one cut short and left
  // hanging (the link drops that connection after its byte timeout).
  const int s = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(f.port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(connect(s, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  const uint8_t unknown[] = {0x00, 0x01, 0x00, 0x00, 0x00, 0x03, 0x01, 0x42, 0x99};
  ASSERT_EQ(send(s, unknown, sizeof unknown, MSG_NOSIGNAL), static_cast<ssize_t>(sizeof unknown));
  uint8_t reply[64];
  pollfd p{s, POLLIN, 0};
  ASSERT_EQ(poll(&p, 1, 10000), 1);
  const ssize_t n = recv(s, reply, sizeof reply, 0);
  ASSERT_EQ(n, 9);  // MBAP (7) + 0xC2 + exception 1 (illegal function)
  EXPECT_EQ(reply[7], 0xC2);
  EXPECT_EQ(reply[8], 0x01);
  const uint8_t cut[] = {0x00, 0x02, 0x00, 0x00, 0x00, 0x06, 0x01, 0x03, 0x00};
  ASSERT_EQ(send(s, cut, sizeof cut, MSG_NOSIGNAL), static_cast<ssize_t>(sizeof cut));
  EXPECT_TRUE(waitUntil([&] { return f.link->counters().malformed.load() == 2; }));
  // The link closed that connection.
  p = pollfd{s, POLLIN, 0};
  ASSERT_EQ(poll(&p, 1, 10000), 1);
  EXPECT_EQ(recv(s, reply, sizeof reply, 0), 0);
  close(s);
  Master m(f.port);
  ASSERT_TRUE(m.connected);
  EXPECT_EQ(m.write(0, makeSet(modbus::WordOrder::LowFirst, 1)), modbus::kHoldingCount);
  ASSERT_TRUE(f.sink.waitFor(1));
  expectSet(f.sink.last());
}

TEST(ModbusTcp, StopIsPromptWithMastersConnected) {
  TcpFixture f;
  ASSERT_TRUE(f.started);
  Master m(f.port);
  ASSERT_TRUE(m.connected);
  m.status(modbus::WordOrder::LowFirst);
  const auto t0 = Clock::now();
  f.link->stop();
  const double stop_s = std::chrono::duration<double>(Clock::now() - t0).count();
  EXPECT_LT(stop_s, 1.0);
  RecordProperty("stop_ms", static_cast<int>(stop_s * 1000));
  f.link->stop();  // idempotent
  // Restartable.
  std::string error;
  ASSERT_TRUE(f.link->start(f.sink, error)) << error;
  Master again(f.link->boundPort());
  EXPECT_TRUE(again.connected);
}

// A raw TCP connection to the link (for masters that misbehave).
int rawConnect(uint16_t port, int rcvbuf = 0) {
  const int s = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (rcvbuf > 0) setsockopt(s, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  EXPECT_EQ(connect(s, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
  return s;
}

TEST(ModbusTcp, TricklingMasterBlocksNeitherOthersNorStop) {
  TcpFixture f;
  ASSERT_TRUE(f.started);
  // FC16 with 120 registers (253 bytes), sent one byte every 100 ms: each byte within
  // libmodbus' byte timeout, the whole frame 25 s.
  std::vector<uint8_t> frame = {0x00, 0x01, 0x00, 0x00, 0x00, 247, 0x01, 0x10, 0x00, 0x00, 0x00, 120, 240};
  frame.resize(frame.size() + 240, 0);
  const int s = rawConnect(f.port);
  std::atomic<bool> done{false};
  std::thread trickle([&] {
    for (uint8_t b : frame) {
      if (done || send(s, &b, 1, MSG_NOSIGNAL) != 1) return;
      std::this_thread::sleep_for(100ms);
    }
  });
  std::this_thread::sleep_for(350ms);
  Master m(f.port);
  ASSERT_TRUE(m.connected);
  modbus_set_response_timeout(m.ctx, 1, 0);
  const auto t0 = Clock::now();
  m.status(modbus::WordOrder::LowFirst);  // answered while the other master trickles
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 0.5);
  // The trickler's request did not complete within 0.25 s: its connection was closed.
  EXPECT_TRUE(waitUntil([&] { return f.link->counters().malformed.load() == 1; }, 2000ms));
  const auto t1 = Clock::now();
  f.link->stop();
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t1).count(), 1.0);
  done = true;
  trickle.join();
  close(s);
}

TEST(ModbusTcp, MasterThatNeverReadsBlocksNeitherOthersNorStop) {
  TcpFixture f;
  ASSERT_TRUE(f.started);
  // Pipelined reads of the whole holding block; the answers are never read. Once the socket
  // buffers are full a blocking send would hold the receive thread for good.
  const int s = rawConnect(f.port, 4096);
  const uint8_t req[] = {0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x01, 0x03, 0x00, 0x00, 0x00, modbus::kHoldingCount};
  std::vector<uint8_t> burst;
  for (int i = 0; i < 256; ++i) burst.insert(burst.end(), req, req + sizeof req);
  const int flags = fcntl(s, F_GETFL);
  fcntl(s, F_SETFL, flags | O_NONBLOCK);
  const auto end = Clock::now() + 2s;
  size_t sent = 0;
  while (Clock::now() < end) {
    const ssize_t n = send(s, burst.data(), burst.size(), MSG_NOSIGNAL);
    if (n > 0) {
      sent += static_cast<size_t>(n);
    } else if (n < 0 && errno != EAGAIN) {
      break;  // the link closed this connection
    } else {
      std::this_thread::sleep_for(5ms);
    }
  }
  EXPECT_GT(sent, 100000u);
  Master m(f.port);
  ASSERT_TRUE(m.connected);
  modbus_set_response_timeout(m.ctx, 1, 0);
  const auto t0 = Clock::now();
  m.status(modbus::WordOrder::LowFirst);
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 0.5);
  const auto t1 = Clock::now();
  f.link->stop();
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t1).count(), 1.0);
  close(s);
}

TEST(ModbusTcp, PipelinedRequestsAreAllAnswered) {
  TcpFixture f;
  ASSERT_TRUE(f.started);
  // Three reads in one segment, then a write split across two segments: each is answered.
  const int s = rawConnect(f.port);
  std::vector<uint8_t> out;
  for (uint8_t tid = 1; tid <= 3; ++tid) {
    const uint8_t r[] = {0x00, tid, 0x00, 0x00, 0x00, 0x06, 0x01, 0x04, 0x00, 0x00, 0x00, 0x02};
    out.insert(out.end(), r, r + sizeof r);
  }
  ASSERT_EQ(send(s, out.data(), out.size(), MSG_NOSIGNAL), static_cast<ssize_t>(out.size()));
  const uint8_t w1[] = {0x00, 0x04, 0x00, 0x00, 0x00, 0x06, 0x01};
  const uint8_t w2[] = {0x06, 0x00, 0x00, 0x00, 0x07};  // FC6 register 0 = 7
  ASSERT_EQ(send(s, w1, sizeof w1, MSG_NOSIGNAL), static_cast<ssize_t>(sizeof w1));
  std::this_thread::sleep_for(50ms);
  ASSERT_EQ(send(s, w2, sizeof w2, MSG_NOSIGNAL), static_cast<ssize_t>(sizeof w2));
  std::vector<uint8_t> in;
  const size_t want = 3 * (9 + 4) + 12;
  const auto end = Clock::now() + kWait;
  while (in.size() < want && Clock::now() < end) {
    pollfd p{s, POLLIN, 0};
    if (poll(&p, 1, 100) <= 0) continue;
    uint8_t buf[256];
    const ssize_t n = recv(s, buf, sizeof buf, 0);
    if (n <= 0) break;
    in.insert(in.end(), buf, buf + n);
  }
  ASSERT_EQ(in.size(), want);
  for (uint8_t tid = 1; tid <= 3; ++tid) {
    EXPECT_EQ(in[(tid - 1) * 13 + 1], tid);
    EXPECT_EQ(in[(tid - 1) * 13 + 7], 0x04);
  }
  EXPECT_EQ(in[39 + 1], 0x04);
  EXPECT_EQ(in[39 + 7], 0x06);
  EXPECT_EQ(f.link->counters().received.load(), 4u);
  EXPECT_EQ(f.link->counters().malformed.load(), 0u);
  close(s);
}

// --- mbpoll as the master ----------------------------------------------------------------------

class MbpollTcp : public ::testing::TestWithParam<modbus::WordOrder> {};

TEST_P(MbpollTcp, WritesFloatsAndReadsStatus) {
  const modbus::WordOrder order = GetParam();
  const bool high = order == modbus::WordOrder::HighFirst;
  TcpFixture f(order);
  ASSERT_TRUE(f.started);
  const std::string port = std::to_string(f.port);
  // All 13 floats, COMMIT last, in one FC16 request; references are 1-based (ref 1 = address 0).
  std::vector<std::string> cmd = {"mbpoll", "-m", "tcp", "-p", port, "-a", "1", "-r", "1", "-t", "4:float", "-o", "5"};
  if (high) cmd.push_back("-B");
  cmd.insert(cmd.end(), {"127.0.0.1", "--"});
  ProcessResult r = run(concat(cmd, setArgs(1)));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("Written 13 references"), std::string::npos) << r.output;
  ASSERT_TRUE(f.sink.waitFor(1));
  expectSet(f.sink.last());
  EXPECT_EQ(f.link->counters().received.load(), 1u);  // one request carried the whole set

  // mbpoll reads the status block as 32-bit integers in the same word order.
  f.link->frameStarted(FrameStart{1234, 4242, 41.1, false, false});
  std::vector<std::string> read = {"mbpoll", "-m", "tcp", "-p", port, "-a", "1", "-r", "1", "-t", "3:int",
                                   "-c", "12", "-1", "-o", "5"};
  if (high) read.push_back("-B");
  read.push_back("127.0.0.1");
  r = run(read);
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const std::vector<long long> v = mbpollValues(r.output);
  ASSERT_EQ(v.size(), 12u) << r.output;
  EXPECT_EQ(v[0], 1234);  // ig_frame
  EXPECT_EQ(v[1], 4242);  // last_host_frame
  EXPECT_EQ(v[2], 0);     // host_lost
  EXPECT_EQ(v[3], 0x3F800000);  // applied_commit: 1.0f's bits, as written with -t 4:float
  EXPECT_EQ(v[4], 0);     // rejected_fields
  EXPECT_EQ(v[5], 2);     // received: the write and this read
  EXPECT_EQ(v[6], 1);     // accepted
  EXPECT_EQ(v[7], 0);     // malformed
  EXPECT_EQ(v[11], 2);    // map_version

  // Plain 16-bit reads (mbpoll -t 3) work too: ig_frame's two words.
  read = {"mbpoll", "-m", "tcp", "-p", port, "-r", "1", "-t", "3", "-c", "2", "-1", "-o", "5", "127.0.0.1"};
  r = run(read);
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const std::vector<long long> words = mbpollValues(r.output);
  ASSERT_EQ(words.size(), 2u) << r.output;
  EXPECT_EQ(words[high ? 1 : 0], 1234);
  EXPECT_EQ(words[high ? 0 : 1], 0);
}

INSTANTIATE_TEST_SUITE_P(Both, MbpollTcp,
                         ::testing::Values(modbus::WordOrder::LowFirst, modbus::WordOrder::HighFirst),
                         [](const auto& p) { return std::string(modbus::toString(p.param)); });

TEST(MbpollTcp, ZeroBasedTwoStepCommitAndBadAddress) {
  TcpFixture f;
  ASSERT_TRUE(f.started);
  const std::string port = std::to_string(f.port);
  const std::vector<std::string> base = {"mbpoll", "-m", "tcp", "-p", port, "-0", "-t", "4:float", "-o", "5"};
  // The 12 fields at PDU address 0 (-0), without COMMIT: nothing applies.
  std::vector<std::string> fields = setArgs(0);
  fields.pop_back();
  ProcessResult r = run(concat(concat(base, {"-r", "0", "127.0.0.1", "--"}), fields));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  // COMMIT alone at address 24.
  r = run(concat(base, {"-r", "24", "127.0.0.1", "7"}));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  ASSERT_TRUE(f.sink.waitFor(1));
  EXPECT_EQ(f.sink.size(), 1u);
  expectSet(f.sink.last());
  // visibility_m at address 26 (after COMMIT), then a new COMMIT: it applies with it.
  r = run(concat(base, {"-r", "26", "127.0.0.1", "1500"}));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  EXPECT_EQ(f.sink.size(), 1u);
  r = run(concat(base, {"-r", "24", "127.0.0.1", "8"}));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  ASSERT_TRUE(f.sink.waitFor(2));
  EXPECT_EQ(f.sink.last().visibility_m, 1500.0);
  expectSet(f.sink.last());
  // A float at address 28 is outside the map: mbpoll reports the exception.
  r = run(concat(base, {"-r", "28", "127.0.0.1", "1"}));
  EXPECT_NE(r.exitCode, 0) << r.output;
  EXPECT_NE(r.output.find("Illegal data address"), std::string::npos) << r.output;
  EXPECT_TRUE(waitUntil([&] { return f.link->counters().malformed.load() == 1; }));
  EXPECT_EQ(f.sink.size(), 2u);
}

// RTU over a pty pair: the link on one end, mbpoll (and raw bytes) on the other.
class SocatPair {
 public:
  SocatPair() {
    char tmpl[] = "/tmp/igd-modbus-XXXXXX";
    dir_ = mkdtemp(tmpl) ? tmpl : "";
    a = dir_ + "/a";
    b = dir_ + "/b";
    std::vector<std::string> args = {"socat", "-d", "-d", "pty,raw,echo=0,link=" + a, "pty,raw,echo=0,link=" + b};
    std::vector<char*> argv;
    for (std::string& s : args) argv.push_back(s.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
    if (posix_spawnp(&pid_, "socat", &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
    struct stat st{};
    ready = pid_ > 0 && waitUntil([&] { return stat(a.c_str(), &st) == 0 && stat(b.c_str(), &st) == 0; });
  }
  ~SocatPair() {
    if (pid_ > 0) {
      kill(pid_, SIGTERM);
      waitpid(pid_, nullptr, 0);
    }
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  SocatPair(const SocatPair&) = delete;
  SocatPair& operator=(const SocatPair&) = delete;
  std::string a, b;
  bool ready = false;

 private:
  std::string dir_;
  pid_t pid_ = -1;
};

uint16_t crc16(const uint8_t* p, size_t n) {
  uint16_t crc = 0xFFFF;
  for (size_t i = 0; i < n; ++i) {
    crc ^= p[i];
    for (int k = 0; k < 8; ++k) crc = (crc & 1) ? static_cast<uint16_t>((crc >> 1) ^ 0xA001) : static_cast<uint16_t>(crc >> 1);
  }
  return crc;
}

TEST(MbpollRtu, WritesFloatsOverAPtyPairAndSurvivesABadCrc) {
  SocatPair pty;
  ASSERT_TRUE(pty.ready) << "socat did not create " << pty.a << " and " << pty.b;
  ModbusLinkConfig c;
  c.serialDevice = pty.a;
  c.unitId = 7;
  c.baud = 115200;
  c.wordOrder = modbus::WordOrder::HighFirst;
  ModbusLink link(c, ModbusTransport::Rtu, kOrigin);
  RecordingSink sink;
  std::string error;
  ASSERT_TRUE(link.start(sink, error)) << error;
  EXPECT_EQ(link.name(), "modbus-rtu");

  const std::vector<std::string> rtu = {"mbpoll", "-m", "rtu", "-b", "115200", "-P", "none", "-a", "7", "-o", "5"};
  ProcessResult r = run(concat(concat(rtu, {"-r", "1", "-t", "4:float", "-B", pty.b, "--"}), setArgs(1)));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  ASSERT_TRUE(sink.waitFor(1));
  expectSet(sink.last());

  // A frame for unit 7 with a bad CRC: counted as malformed, nothing applied, no crash.
  {
    const int fd = open(pty.b.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
    ASSERT_GE(fd, 0);
    uint8_t frame[] = {0x07, 0x06, 0x00, 0x18, 0x00, 0x05, 0x00, 0x00};
    const uint16_t crc = crc16(frame, 6);
    frame[6] = static_cast<uint8_t>((crc & 0xFF) ^ 0x5A);  // wrong on purpose
    frame[7] = static_cast<uint8_t>(crc >> 8);
    ASSERT_EQ(write(fd, frame, sizeof frame), static_cast<ssize_t>(sizeof frame));
    EXPECT_TRUE(waitUntil([&] { return link.counters().malformed.load() == 1; }))
        << "malformed = " << link.counters().malformed.load();
    close(fd);
  }
  EXPECT_EQ(sink.size(), 1u);

  // The link still answers: mbpoll reads the status block.
  link.frameStarted(FrameStart{99, 4242, 3.3, false, false});
  r = run(concat(rtu, {"-r", "1", "-t", "3:int", "-B", "-c", "12", "-1", pty.b}));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  const std::vector<long long> v = mbpollValues(r.output);
  ASSERT_EQ(v.size(), 12u) << r.output;
  EXPECT_EQ(v[0], 99);   // ig_frame
  EXPECT_EQ(v[6], 1);    // accepted
  EXPECT_EQ(v[7], 1);    // malformed: the bad CRC
  EXPECT_EQ(v[11], 2);   // map_version
  // A second set with a new COMMIT applies.
  std::vector<std::string> second = setArgs(2);
  second[0] = "-40";
  r = run(concat(concat(rtu, {"-r", "1", "-t", "4:float", "-B", pty.b, "--"}), second));
  ASSERT_EQ(r.exitCode, 0) << r.output;
  ASSERT_TRUE(sink.waitFor(2));
  EXPECT_EQ(sink.last().eyeEnu_m.x, -40.0);
  const auto t0 = Clock::now();
  link.stop();
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 1.0);
}

// A master on the serial line that sends a long request one byte every 100 ms (inside the 0.25 s
// byte timeout, the whole frame ~25 s): the link drops the request once it has taken longer than
// the line needs for any request, and stop() does not wait for the frame to end (systemd's
// TimeoutStopSec is 10 s).
TEST(ModbusRtu, TricklingMasterDoesNotHoldStop) {
  SocatPair pty;
  ASSERT_TRUE(pty.ready) << "socat did not create " << pty.a << " and " << pty.b;
  ModbusLinkConfig c;
  c.serialDevice = pty.a;
  c.unitId = 7;
  c.baud = 115200;
  ModbusLink link(c, ModbusTransport::Rtu, kOrigin);
  RecordingSink sink;
  std::string error;
  ASSERT_TRUE(link.start(sink, error)) << error;
  const int fd = open(pty.b.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
  ASSERT_GE(fd, 0);
  // FC16, 120 registers: address, function, start, count, byte count, 240 data bytes, CRC.
  std::vector<uint8_t> frame = {0x07, 0x10, 0x00, 0x00, 0x00, 120, 240};
  frame.resize(frame.size() + 240, 0);
  const uint16_t crc = crc16(frame.data(), frame.size());
  frame.push_back(static_cast<uint8_t>(crc & 0xFF));
  frame.push_back(static_cast<uint8_t>(crc >> 8));
  std::atomic<bool> done{false};
  std::atomic<int> sent{0};
  std::thread trickle([&] {
    for (uint8_t b : frame) {
      if (done || write(fd, &b, 1) != 1) return;
      ++sent;
      std::this_thread::sleep_for(100ms);
    }
  });
  EXPECT_TRUE(waitUntil([&] { return link.counters().malformed.load() >= 1; }, 3000ms))
      << "the trickled request was not dropped; " << sent.load() << " bytes sent";
  const auto t0 = Clock::now();
  link.stop();
  EXPECT_LT(std::chrono::duration<double>(Clock::now() - t0).count(), 1.0);
  EXPECT_LT(sent.load(), static_cast<int>(frame.size()));  // stop() did not wait for the frame
  done = true;
  trickle.join();
  close(fd);
  EXPECT_EQ(sink.size(), 0u);
}
