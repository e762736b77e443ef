// Modbus host link: igd as a Modbus TCP server ("modbus-tcp") or a Modbus RTU slave on a
// serial line ("modbus-rtu"), over libmodbus. The register map and the commit rule are in
// io/modbus_map.h (and docs/modbus.md); this is the thin transport around them.
//
// One receive thread, started in start() and joined in stop(). It waits on the listening
// socket and the connected masters (TCP, up to kMaxTcpClients at once; more are refused) or on
// the serial device (RTU) with a 100 ms poll timeout, so stop() returns within about 0.1 s.
// TCP masters are read from non-blocking sockets and their requests framed by the MBAP length,
// so a master that stalls or trickles a request, or that does not read its answers, never holds
// the thread: a request not complete 0.25 s after its first byte, or an answer the socket
// cannot take at once, closes that master's connection. The serial line is read the same way,
// its requests framed by their function code: a request with a gap of 0.25 s between two
// bytes, or not complete 0.25 s plus the time the longest request (256 bytes) takes at the
// configured baud rate after its first byte, is dropped; an answer the device cannot take at
// once is dropped. Each request is checked against the
// map (modbus::checkRequest), answered (libmodbus builds the reply or the exception), and a
// write that commits a set publishes one HostState to the sink, with the geodetic eyepoint
// computed from the ENU eyepoint and the scene origin.
//
// Counters: received = requests read (of any function, for this unit id), accepted = sets
// applied, malformed = frames that could not be read (bad CRC, a stall or trickle mid-frame) plus
// requests answered with an exception, outOfRange = fields rejected at commit, late = commits
// that repeated the applied COMMIT value, dropped = 0.
// TCP answers every unit id (as gateways and most TCP servers do); RTU answers only unit_id
// (and applies broadcast writes to unit 0 without answering). A serial device that goes away
// (USB adapter unplugged) is not reopened: restart the service.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "io/link.h"
#include "io/modbus_map.h"
#include "lod/geo.h"

namespace ig::io {

enum class ModbusTransport : uint8_t { Tcp, Rtu };

// [host.modbus] in the service config (shared by "modbus-tcp" and "modbus-rtu"). Field names
// follow the TOML keys (tcp_address -> tcpAddress).
struct ModbusLinkConfig {
  // TCP
  std::string tcpAddress = "127.0.0.1";  // IPv4 address to listen on; "0.0.0.0" = every interface
  int tcpPort = 1502;                    // 1..65535 in the TOML; 502 (the Modbus port) needs root.
                                         //   0 = any free port (in-process tests: boundPort())
  // Both: the RTU slave address (TCP ignores the unit id of requests)
  int unitId = 1;                        // 1..247
  // RTU
  std::string serialDevice;              // e.g. "/dev/ttyUSB0"; required for modbus-rtu
  int baud = 115200;                     // 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200,
                                         //   230400, 460800, 500000, 576000, 921600, 1000000
  char parity = 'N';                     // 'N', 'E' or 'O' (TOML: "N", "E", "O")
  int dataBits = 8;                      // 7 or 8
  int stopBits = 1;                      // 1 or 2
  // Both
  modbus::WordOrder wordOrder = modbus::WordOrder::LowFirst;  // "low_first" | "high_first"
  bool operator==(const ModbusLinkConfig&) const = default;
};

// Checks the fields the transport uses; on failure sets `error` naming the key and the value
// (its message() is e.g. "host.modbus.tcp_port = 70000: must be 0..65535"). The string form
// sets that message.
bool validateModbusLinkConfig(const ModbusLinkConfig& config, ModbusTransport transport, LinkConfigError& error);
bool validateModbusLinkConfig(const ModbusLinkConfig& config, ModbusTransport transport, std::string& error);
// TOML text -> field, for the config parser: "N"/"E"/"O" -> 'N'/'E'/'O'; false otherwise.
bool parseModbusParity(std::string_view text, char& out);

class ModbusLink final : public HostLink {
 public:
  static constexpr int kMaxTcpClients = 8;

  ModbusLink(const ModbusLinkConfig& config, ModbusTransport transport, const lod::Geodetic& origin);
  ~ModbusLink() override;
  ModbusLink(const ModbusLink&) = delete;
  ModbusLink& operator=(const ModbusLink&) = delete;

  std::string_view name() const override;  // "modbus-tcp" or "modbus-rtu"
  // Fails on a bad config value (validateModbusLinkConfig), "cannot listen on 127.0.0.1:1502:
  // Address already in use", or "cannot open serial device /dev/ttyUSB0: No such file or directory".
  bool start(HostSink& sink, std::string& error) override;
  void stop() override;
  // Stores the frame's status for the input registers (atomics only; never blocks).
  void frameStarted(const FrameStart& frame) override;

  // TCP: the port listened on (the kernel's choice when tcpPort = 0); 0 before start().
  uint16_t boundPort() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

std::unique_ptr<HostLink> makeModbusTcpLink(const ModbusLinkConfig& config, const lod::Geodetic& origin);
std::unique_ptr<HostLink> makeModbusRtuLink(const ModbusLinkConfig& config, const lod::Geodetic& origin);

}  // namespace ig::io
