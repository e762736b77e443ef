#include "io/modbus_link.h"

#include <arpa/inet.h>
#include <modbus.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <pthread.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <fcntl.h>
#include <optional>
#include <thread>

namespace ig::io {
namespace {

constexpr int kPollTimeout_ms = 100;       // how often the receive thread checks for stop()
constexpr uint32_t kByteTimeout_us = 250000;  // RTU: a master silent this long mid-frame: frame dropped
// TCP: a request not complete this long after its first byte closes the connection. The TCP
// side frames requests itself (MBAP length) from non-blocking sockets, so a master that stalls
// or trickles a frame byte by byte never holds the receive thread (libmodbus' modbus_receive
// would wait up to the byte timeout for every single byte).
constexpr int64_t kTcpFrameTimeout_ns = int64_t{kByteTimeout_us} * 1000;
constexpr int kMbapHeader = 7;          // transaction id, protocol id, length, unit id
constexpr int kMaxFramesPerWake = 16;   // per master, then the others get their turn
// RTU: a request not complete this long after its first byte plus the time its longest form
// (MODBUS_RTU_MAX_ADU_LENGTH bytes) takes on the line is dropped. The RTU side frames requests
// itself too (function code -> length), so a master that sends one byte just inside the byte
// timeout cannot hold the receive thread (and stop()) for the ~64 s such a frame lasts.
constexpr int64_t kRtuFrameSlack_ns = int64_t{kByteTimeout_us} * 1000;
constexpr uint32_t kResponseTimeout_us = 100000;  // libmodbus waits this for a reply it must skip (RTU)
constexpr int kBauds[] = {1200,   2400,   4800,   9600,   19200,  38400,  57600,
                          115200, 230400, 460800, 500000, 576000, 921600, 1000000};

std::string quoted(std::string_view s) {
  std::string r(1, '"');
  r.append(s).push_back('"');
  return r;
}

int64_t monotonicNow_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

void pauseBriefly() {
  timespec ts{0, kPollTimeout_ms * 1000000L};
  nanosleep(&ts, nullptr);
}

}  // namespace

bool parseModbusParity(std::string_view text, char& out) {
  if (text == "N" || text == "E" || text == "O") {
    out = text[0];
    return true;
  }
  return false;
}

bool validateModbusLinkConfig(const ModbusLinkConfig& c, ModbusTransport transport, LinkConfigError& error) {
  auto fail = [&](const std::string& key, const std::string& value, const std::string& why) {
    error = {"host.modbus." + key, value, why};
    return false;
  };
  if (c.unitId < 1 || c.unitId > 247) return fail("unit_id", std::to_string(c.unitId), "must be 1..247");
  if (c.wordOrder != modbus::WordOrder::LowFirst && c.wordOrder != modbus::WordOrder::HighFirst) {
    return fail("word_order", std::to_string(static_cast<int>(c.wordOrder)), "must be \"low_first\" or \"high_first\"");
  }
  if (transport == ModbusTransport::Tcp) {
    in_addr addr{};
    if (inet_pton(AF_INET, c.tcpAddress.c_str(), &addr) != 1) {
      return fail("tcp_address", quoted(c.tcpAddress), "not an IPv4 address (e.g. \"127.0.0.1\" or \"0.0.0.0\")");
    }
    if (c.tcpPort < 0 || c.tcpPort > 65535) return fail("tcp_port", std::to_string(c.tcpPort), "must be 0..65535");
    return true;
  }
  if (c.serialDevice.empty()) {
    return fail("serial_device", "\"\"", "modbus-rtu needs the serial device (e.g. \"/dev/ttyUSB0\")");
  }
  bool knownBaud = false;
  for (int b : kBauds) knownBaud = knownBaud || b == c.baud;
  if (!knownBaud) {
    return fail("baud", std::to_string(c.baud),
                "must be one of 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400, 460800, "
                "500000, 576000, 921600, 1000000");
  }
  if (c.parity != 'N' && c.parity != 'E' && c.parity != 'O') {
    return fail("parity", quoted(std::string(1, c.parity)), "must be \"N\", \"E\" or \"O\"");
  }
  if (c.dataBits != 7 && c.dataBits != 8) return fail("data_bits", std::to_string(c.dataBits), "must be 7 or 8");
  if (c.stopBits != 1 && c.stopBits != 2) return fail("stop_bits", std::to_string(c.stopBits), "must be 1 or 2");
  return true;
}

bool validateModbusLinkConfig(const ModbusLinkConfig& config, ModbusTransport transport, std::string& error) {
  LinkConfigError e;
  if (validateModbusLinkConfig(config, transport, e)) return true;
  error = e.message();
  return false;
}

struct ModbusLink::Impl {
  Impl(const ModbusLinkConfig& c, ModbusTransport t, const lod::Geodetic& origin, LinkCounters& k)
      : config(c), transport(t), enu(origin), counters(k), map(c.wordOrder) {
  }

  ModbusLinkConfig config;
  ModbusTransport transport;
  lod::EnuFrame enu;
  LinkCounters& counters;
  modbus::HostRegisterMap map;

  modbus_t* ctx = nullptr;
  modbus_mapping_t* mapping = nullptr;
  int listenFd = -1;
  // A connected TCP master: its non-blocking socket and the request being received.
  struct Client {
    int fd = -1;
    int have = 0;            // bytes of the current request in buf
    int64_t started_ns = 0;  // when its first byte arrived
    uint8_t buf[MODBUS_TCP_MAX_ADU_LENGTH] = {};
  };
  std::array<Client, kMaxTcpClients> clients{};
  HostSink* sink = nullptr;
  std::thread thread;
  std::atomic<bool> stopping{false};
  std::atomic<uint16_t> port{0};
  // Written by the frame loop (frameStarted), read by the receive thread.
  std::atomic<uint32_t> igFrame{0}, lastHostFrame{0};
  std::atomic<bool> hostLost{false};
  // RTU: the request being received from the serial line.
  struct RtuRequest {
    int have = 0;            // bytes in buf
    int64_t started_ns = 0;  // first byte
    int64_t last_ns = 0;     // latest byte
    uint8_t buf[MODBUS_RTU_MAX_ADU_LENGTH] = {};
  } rtuRx;
  int64_t rtuFrameLimit_ns = 0;  // kRtuFrameSlack_ns + the longest request's time on the line

  std::span<uint16_t, modbus::kHoldingCount> holding() {
    return std::span<uint16_t, modbus::kHoldingCount>(mapping->tab_registers, modbus::kHoldingCount);
  }
  std::span<uint16_t, modbus::kInputCount> input() {
    return std::span<uint16_t, modbus::kInputCount>(mapping->tab_input_registers, modbus::kInputCount);
  }

  bool open(std::string& error);
  void close();
  void runTcp();
  void runRtu();
  void readRtu(int fd);          // RTU: reads what the line has, answers each complete request
  void dropRtu(bool flush);      // RTU: a request that cannot complete: counted malformed
  bool readClient(Client& c);  // TCP: false: close this connection
  bool handleRequest(const uint8_t* req, int length);  // false: close this TCP connection
  void refreshStatus();
};

bool ModbusLink::Impl::open(std::string& error) {
  mapping = modbus_mapping_new_start_address(0, 0, 0, 0, 0, modbus::kHoldingCount, 0, modbus::kInputCount);
  if (mapping == nullptr) {
    error = std::string("modbus: cannot allocate the register map: ") + std::strerror(errno);
    return false;
  }
  modbus::encodeHostRegisters(map.state(), map.appliedCommit(), config.wordOrder, holding());
  refreshStatus();

  if (transport == ModbusTransport::Tcp) {
    const std::string where = config.tcpAddress + ":" + std::to_string(config.tcpPort);
    ctx = modbus_new_tcp(config.tcpAddress.c_str(), config.tcpPort);
    if (ctx == nullptr) {
      error = "cannot listen on " + where + ": " + modbus_strerror(errno);
      return false;
    }
    listenFd = modbus_tcp_listen(ctx, kMaxTcpClients);
    if (listenFd < 0) {
      error = "cannot listen on " + where + ": " + std::strerror(errno);
      return false;
    }
    // Non-blocking: a connection the master aborted between poll() and accept() must not
    // block the receive thread in accept().
    fcntl(listenFd, F_SETFL, fcntl(listenFd, F_GETFL) | O_NONBLOCK);
    sockaddr_in bound{};
    socklen_t len = sizeof bound;
    if (getsockname(listenFd, reinterpret_cast<sockaddr*>(&bound), &len) == 0) port = ntohs(bound.sin_port);
  } else {
    const std::string where = "serial device " + config.serialDevice;
    ctx = modbus_new_rtu(config.serialDevice.c_str(), config.baud, config.parity, config.dataBits, config.stopBits);
    if (ctx == nullptr) {
      error = "cannot open " + where + ": " + modbus_strerror(errno);
      return false;
    }
    if (modbus_set_slave(ctx, config.unitId) != 0 || modbus_connect(ctx) != 0) {
      error = "cannot open " + where + ": " + std::strerror(errno);
      return false;
    }
    modbus_set_error_recovery(ctx, MODBUS_ERROR_RECOVERY_PROTOCOL);
    // Non-blocking: the receive thread reads what the line has (see readRtu), and an answer the
    // device cannot take at once (a pty whose master does not read) is dropped, not waited for.
    const int fd = modbus_get_socket(ctx);
    fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK);
    const int64_t bitsPerChar = 1 + config.dataBits + (config.parity == 'N' ? 0 : 1) + config.stopBits;
    rtuFrameLimit_ns = kRtuFrameSlack_ns + MODBUS_RTU_MAX_ADU_LENGTH * bitsPerChar * 1000000000 / config.baud;
  }
  modbus_set_byte_timeout(ctx, 0, kByteTimeout_us);
  modbus_set_response_timeout(ctx, 0, kResponseTimeout_us);
  modbus_set_indication_timeout(ctx, 0, kPollTimeout_ms * 1000);
  return true;
}

void ModbusLink::Impl::close() {
  for (Client& c : clients) {
    if (c.fd >= 0) ::close(c.fd);
    c.fd = -1;
    c.have = 0;
  }
  if (listenFd >= 0) ::close(listenFd);
  listenFd = -1;
  if (ctx != nullptr) {
    if (transport == ModbusTransport::Rtu) {
      modbus_close(ctx);  // restores the serial settings and closes the device
    } else {
      modbus_set_socket(ctx, -1);  // its socket was a client's, closed above
    }
    modbus_free(ctx);
    ctx = nullptr;
  }
  if (mapping != nullptr) modbus_mapping_free(mapping);
  mapping = nullptr;
  port = 0;
}

void ModbusLink::Impl::refreshStatus() {
  modbus::IgStatus st;
  st.igFrame = igFrame.load(std::memory_order_relaxed);
  st.lastHostFrame = lastHostFrame.load(std::memory_order_relaxed);
  st.hostLost = hostLost.load(std::memory_order_relaxed);
  st.appliedCommit = map.appliedCommit();
  st.rejectedFields = map.lastRejectedMask();
  st.counters = snapshot(counters);
  modbus::encodeStatusRegisters(st, config.wordOrder, input());
}

namespace {
// Length of an RTU request (address, function, fields, CRC) from the bytes read so far, as a
// slave reads it: 0 while the function code or its byte count has not arrived yet. Functions
// the map does not serve count as address + function + CRC; checkRequest refuses them and the
// rest of such a frame is flushed.
int rtuRequestLength(const uint8_t* b, int have) {
  if (have < 2) return 0;
  switch (b[1]) {
    case 0x01: case 0x02: case 0x03: case 0x04: case 0x05: case 0x06: return 2 + 4 + 2;
    case 0x0F: case 0x10: return have < 7 ? 0 : 2 + 5 + b[6] + 2;     // start, count, byte count, data
    case 0x16: return 2 + 6 + 2;                                        // mask write register
    case 0x17: return have < 11 ? 0 : 2 + 9 + b[10] + 2;               // read/write multiple
    default: return 2 + 2;
  }
}

uint16_t rtuCrc(const uint8_t* p, int n) {
  uint16_t crc = 0xFFFF;
  for (int i = 0; i < n; ++i) {
    crc = static_cast<uint16_t>(crc ^ p[i]);
    for (int k = 0; k < 8; ++k) crc = (crc & 1) != 0 ? static_cast<uint16_t>((crc >> 1) ^ 0xA001) : static_cast<uint16_t>(crc >> 1);
  }
  return crc;
}
}  // namespace

void ModbusLink::Impl::dropRtu(bool flush) {
  counters.malformed.fetch_add(1, std::memory_order_relaxed);
  rtuRx.have = 0;
  if (flush) modbus_flush(ctx);  // resynchronise on the next frame
}

void ModbusLink::Impl::readRtu(int fd) {
  for (;;) {
    const int known = rtuRequestLength(rtuRx.buf, rtuRx.have);
    const int need = known > 0 ? known : (rtuRx.have < 2 ? 2 : rtuRx.buf[1] == 0x17 ? 11 : 7);
    if (need > MODBUS_RTU_MAX_ADU_LENGTH) return dropRtu(true);  // a byte count no request has
    const ssize_t n = ::read(fd, rtuRx.buf + rtuRx.have, static_cast<size_t>(need - rtuRx.have));
    if (n <= 0) {
      if (n < 0 && errno == EINTR) continue;
      return;  // EAGAIN: the line has nothing more now
    }
    const int64_t now = monotonicNow_ns();
    if (rtuRx.have == 0) rtuRx.started_ns = now;
    rtuRx.last_ns = now;
    rtuRx.have += static_cast<int>(n);
    if (known == 0 || rtuRx.have < known) continue;
    const int length = rtuRx.have;
    rtuRx.have = 0;
    // As libmodbus: a request for another slave (or that slave's answer) is ignored unread;
    // then the CRC.
    if (rtuRx.buf[0] != config.unitId && rtuRx.buf[0] != MODBUS_BROADCAST_ADDRESS) continue;
    const uint16_t crc = static_cast<uint16_t>(rtuRx.buf[length - 2] | (rtuRx.buf[length - 1] << 8));
    if (crc != rtuCrc(rtuRx.buf, length - 2)) return dropRtu(true);
    handleRequest(rtuRx.buf, length);
  }
}

bool ModbusLink::Impl::readClient(Client& c) {
  for (int frames = 0; frames < kMaxFramesPerWake;) {
    // The MBAP header first, then the rest its length field announces.
    int need = kMbapHeader;
    if (c.have >= kMbapHeader) need = 6 + ((c.buf[4] << 8) | c.buf[5]);
    const ssize_t n = ::recv(c.fd, c.buf + c.have, static_cast<size_t>(need - c.have), MSG_DONTWAIT);
    if (n == 0) return false;  // the master closed the connection
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) return true;
      if (errno != ECONNRESET) counters.malformed.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    if (c.have == 0) c.started_ns = monotonicNow_ns();
    c.have += static_cast<int>(n);
    if (c.have == kMbapHeader) {
      const int protocol = (c.buf[2] << 8) | c.buf[3], length = (c.buf[4] << 8) | c.buf[5];
      if (protocol != 0 || length < 2 || 6 + length > MODBUS_TCP_MAX_ADU_LENGTH) {
        counters.malformed.fetch_add(1, std::memory_order_relaxed);  // not Modbus TCP framing
        return false;
      }
    }
    if (c.have < kMbapHeader || c.have < 6 + ((c.buf[4] << 8) | c.buf[5])) continue;
    const int length = c.have;
    c.have = 0;
    ++frames;
    modbus_set_socket(ctx, c.fd);
    const bool keep = handleRequest(c.buf, length);
    modbus_set_socket(ctx, -1);
    if (!keep) return false;
  }
  return true;
}

bool ModbusLink::Impl::handleRequest(const uint8_t* req, int length) {
  const bool rtu = transport == ModbusTransport::Rtu;
  counters.received.fetch_add(1, std::memory_order_relaxed);
  const int header = modbus_get_header_length(ctx);
  const int pduLength = length - header - (rtu ? 2 : 0);
  const std::span<const uint8_t> pdu(req + header, pduLength > 0 ? static_cast<size_t>(pduLength) : 0u);
  const modbus::RequestCheck check = modbus::checkRequest(pdu);
  const bool broadcast = rtu && req[0] == MODBUS_BROADCAST_ADDRESS;

  if (check.exception != modbus::Exception::None) {
    counters.malformed.fetch_add(1, std::memory_order_relaxed);
    // Discard the rest of a frame whose length libmodbus could not know before answering:
    // the master sends its next request only after the answer.
    // (TCP frames by the MBAP length: the whole request was read, nothing to discard.)
    if (check.flush && rtu) modbus_flush(ctx);
    int sent = 0;
    if (!broadcast) sent = modbus_reply_exception(ctx, req, static_cast<unsigned>(check.exception));
    return rtu || sent >= 0;
  }
  if (check.readsStatus) refreshStatus();
  const int sent = modbus_reply(ctx, req, length, mapping);
  if (check.writeCount > 0) {
    const modbus::WriteOutcome out = map.afterWrite(holding(), check.writeStart, check.writeCount);
    if (out.rejects.count > 0) counters.outOfRange.fetch_add(out.rejects.count, std::memory_order_relaxed);
    if (out.repeated) counters.late.fetch_add(1, std::memory_order_relaxed);
    if (out.committed) {
      HostState s = map.state();
      const lod::Geodetic g = enu.toGeodetic(s.eyeEnu_m);
      s.lat_deg = g.lat_deg;
      s.lon_deg = g.lon_deg;
      s.height_m = g.height_m;
      counters.accepted.fetch_add(1, std::memory_order_relaxed);
      sink->publish(s);
    }
  }
  return rtu || sent >= 0;
}

void ModbusLink::Impl::runTcp() {
  std::array<pollfd, kMaxTcpClients + 1> fds{};
  std::array<int, kMaxTcpClients + 1> slotOf{};  // fds[i] is clients[slotOf[i]] (i >= 1)
  auto drop = [](Client& c) {
    ::close(c.fd);
    c.fd = -1;
    c.have = 0;
  };
  while (!stopping.load(std::memory_order_relaxed)) {
    nfds_t n = 0;
    fds[n++] = pollfd{listenFd, POLLIN, 0};
    for (int i = 0; i < kMaxTcpClients; ++i) {
      if (clients[i].fd < 0) continue;
      slotOf[n] = i;
      fds[n++] = pollfd{clients[i].fd, POLLIN, 0};
    }
    const int ready = poll(fds.data(), n, kPollTimeout_ms);
    if (ready > 0) {
      for (nfds_t k = 1; k < n; ++k) {
        if ((fds[k].revents & (POLLIN | POLLHUP | POLLERR | POLLNVAL)) == 0) continue;
        Client& c = clients[slotOf[k]];
        if ((fds[k].revents & POLLNVAL) != 0 || !readClient(c)) drop(c);
      }
    }
    // A request left incomplete too long: the stream is out of step (or the master is gone).
    const int64_t now = monotonicNow_ns();
    for (Client& c : clients) {
      if (c.fd >= 0 && c.have > 0 && now - c.started_ns > kTcpFrameTimeout_ns) {
        counters.malformed.fetch_add(1, std::memory_order_relaxed);
        drop(c);
      }
    }
    if (ready > 0 && (fds[0].revents & POLLIN) != 0) {
      const int s = accept4(listenFd, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
      if (s < 0) {
        if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) pauseBriefly();  // don't spin
        continue;
      }
      Client* slot = nullptr;
      for (Client& c : clients) {
        if (c.fd < 0) {
          slot = &c;
          break;
        }
      }
      if (slot == nullptr) {
        ::close(s);  // kMaxTcpClients masters already connected
        continue;
      }
      const int one = 1;
      setsockopt(s, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
      slot->fd = s;
      slot->have = 0;
    }
  }
}

void ModbusLink::Impl::runRtu() {
  const int fd = modbus_get_socket(ctx);
  while (!stopping.load(std::memory_order_relaxed)) {
    pollfd p{fd, POLLIN, 0};
    const int ready = poll(&p, 1, kPollTimeout_ms);
    if (ready > 0 && (p.revents & POLLIN) != 0) {
      readRtu(fd);
    } else if (ready > 0) {
      pauseBriefly();  // hang-up on the line (a pty whose other side is closed): don't spin
    }
    // A request stalled mid-frame, or trickled slower than the line carries it: dropped.
    const int64_t now = monotonicNow_ns();
    if (rtuRx.have > 0 && (now - rtuRx.last_ns > int64_t{kByteTimeout_us} * 1000 || now - rtuRx.started_ns > rtuFrameLimit_ns))
      dropRtu(false);
  }
}

ModbusLink::ModbusLink(const ModbusLinkConfig& config, ModbusTransport transport, const lod::Geodetic& origin)
    : impl_(std::make_unique<Impl>(config, transport, origin, counters_)) {}

ModbusLink::~ModbusLink() { stop(); }

std::string_view ModbusLink::name() const {
  return impl_->transport == ModbusTransport::Tcp ? "modbus-tcp" : "modbus-rtu";
}

bool ModbusLink::start(HostSink& sink, std::string& error) {
  stop();
  Impl& m = *impl_;
  if (!validateModbusLinkConfig(m.config, m.transport, error)) return false;
  if (!m.open(error)) {
    m.close();
    return false;
  }
  m.sink = &sink;
  m.stopping = false;
  m.thread = std::thread([&m] {
    lowerLinkThreadPriority();
    pthread_setname_np(pthread_self(), "ig-modbus");
    if (m.transport == ModbusTransport::Tcp) {
      m.runTcp();
    } else {
      m.runRtu();
    }
  });
  return true;
}

void ModbusLink::stop() {
  Impl& m = *impl_;
  m.stopping = true;
  if (m.thread.joinable()) m.thread.join();
  m.close();
}

void ModbusLink::frameStarted(const FrameStart& frame) {
  impl_->igFrame.store(frame.igFrame, std::memory_order_relaxed);
  impl_->lastHostFrame.store(frame.lastHostFrame, std::memory_order_relaxed);
  impl_->hostLost.store(frame.hostLost, std::memory_order_relaxed);
}

uint16_t ModbusLink::boundPort() const { return impl_->port.load(); }

std::unique_ptr<HostLink> makeModbusTcpLink(const ModbusLinkConfig& config, const lod::Geodetic& origin) {
  return std::make_unique<ModbusLink>(config, ModbusTransport::Tcp, origin);
}

std::unique_ptr<HostLink> makeModbusRtuLink(const ModbusLinkConfig& config, const lod::Geodetic& origin) {
  return std::make_unique<ModbusLink>(config, ModbusTransport::Rtu, origin);
}

}  // namespace ig::io
