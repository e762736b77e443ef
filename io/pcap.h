// Classic libpcap capture files (the format `dumpcap -P`, `tcpdump -w` and `tshark -F pcap`
// write) -> IPv4 UDP datagrams -> CIGI host samples -> a host recording.
//
// Supported: both byte orders, microsecond (magic a1b2c3d4) and nanosecond (a1b23c4d)
// timestamps; link types 0 (BSD loopback / null: 4-byte address family), 1 (Ethernet, with one
// or two 802.1Q / 802.1ad VLAN tags), 101 and 228 (raw IPv4), 113 (Linux cooked SLL). IPv4 only;
// fragmented datagrams (MF set or a fragment offset) are skipped, as are truncated captures
// (caplen < original length) and UDP datagrams whose lengths disagree. pcapng is refused with a
// message saying how to convert it (`tshark -F pcap -r in.pcapng -w out.pcap`).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>

#include "io/cigi_link.h"
#include "io/replay.h"
#include "lod/geo.h"

namespace ig::io {

struct UdpDatagram {
  double time_s = 0.0;        // capture time, seconds since the Unix epoch
  uint32_t srcIp = 0;         // host order
  uint32_t dstIp = 0;
  uint16_t srcPort = 0;
  uint16_t dstPort = 0;
  std::span<const std::byte> payload;  // valid only during the callback
};

struct PcapStats {
  uint64_t records = 0;       // pcap records read
  uint64_t udp = 0;           // IPv4 UDP datagrams delivered to the callback
  uint64_t skipped = 0;       // not IPv4 UDP, fragments, truncated or inconsistent records
};

// Parses a whole capture held in memory and calls `visit` for each IPv4 UDP datagram. Returns
// false with `error` ("<name>: ...") for a file that is not a classic pcap, an unsupported link
// type, or a record header that runs past the end of the file (records read before it were
// delivered).
bool parsePcapUdp(std::span<const std::byte> file, const std::string& name,
                  const std::function<void(const UdpDatagram&)>& visit, std::string& error,
                  PcapStats* stats = nullptr);

// Converts the CIGI host messages sent to UDP port `port` in a capture into a recording: each
// datagram goes through the same CigiAssembler as the live link, and every message that yields
// a complete host sample becomes one recording sample whose t_s is its capture time relative to
// the first such message. Fails (with `error` naming the file) on read/parse errors and when no
// message yields a sample. `counters` (optional) receives the assembler's counts.
bool cigiPcapToRecording(const std::string& pcapFile, uint16_t port, const lod::Geodetic& origin, Recording& out,
                         std::string& error, const CigiAssemblerConfig& cigi = {},
                         LinkCountersSnapshot* counters = nullptr);

}  // namespace ig::io
