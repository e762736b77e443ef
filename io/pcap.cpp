// Classic libpcap reader (https://www.tcpdump.org/manpages/pcap-savefile.5.html, link types
// from https://www.tcpdump.org/linktypes.html) and the CIGI capture -> recording converter.
#include "io/pcap.h"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <iterator>
#include <vector>

namespace ig::io {
namespace {

constexpr size_t kFileHeader = 24;
constexpr size_t kRecordHeader = 16;

uint16_t be16(const std::byte* p) {
  return static_cast<uint16_t>((std::to_integer<unsigned>(p[0]) << 8) | std::to_integer<unsigned>(p[1]));
}
uint32_t be32(const std::byte* p) { return (static_cast<uint32_t>(be16(p)) << 16) | be16(p + 2); }
uint32_t le32(const std::byte* p) {
  return std::to_integer<uint32_t>(p[0]) | (std::to_integer<uint32_t>(p[1]) << 8) |
         (std::to_integer<uint32_t>(p[2]) << 16) | (std::to_integer<uint32_t>(p[3]) << 24);
}

enum class Link { null, ethernet, rawIp, sll };

// Strips the link-layer header; returns the IPv4 packet or an empty span.
std::span<const std::byte> ipv4Payload(Link link, std::span<const std::byte> frame) {
  uint16_t etherType = 0;
  size_t at = 0;
  switch (link) {
    case Link::null: {
      if (frame.size() < 4) return {};
      // The address family in the capturing machine's byte order: AF_INET is 2 everywhere.
      const uint32_t family = le32(frame.data());
      if (family != 2 && be32(frame.data()) != 2) return {};
      return frame.subspan(4);
    }
    case Link::rawIp: return frame;
    case Link::sll:
      if (frame.size() < 16) return {};
      etherType = be16(frame.data() + 14);
      at = 16;
      break;
    case Link::ethernet:
      if (frame.size() < 14) return {};
      etherType = be16(frame.data() + 12);
      at = 14;
      for (int tags = 0; tags < 2 && (etherType == 0x8100 || etherType == 0x88a8); ++tags) {
        if (frame.size() < at + 4) return {};
        etherType = be16(frame.data() + at + 2);
        at += 4;
      }
      break;
  }
  if (etherType != 0x0800) return {};
  return frame.subspan(at);
}

// IPv4 + UDP headers; false if the packet is not a whole, unfragmented UDP datagram.
bool parseUdp(std::span<const std::byte> ip, UdpDatagram& d) {
  if (ip.size() < 20) return false;
  const unsigned vihl = std::to_integer<unsigned>(ip[0]);
  if ((vihl >> 4) != 4) return false;
  const size_t ihl = (vihl & 0x0f) * 4u;
  const size_t total = be16(ip.data() + 2);
  if (ihl < 20 || total < ihl || total > ip.size()) return false;
  const uint16_t frag = be16(ip.data() + 6);
  if ((frag & 0x2000) || (frag & 0x1fff)) return false;  // more fragments / not the first
  if (std::to_integer<unsigned>(ip[9]) != 17) return false;
  const std::span<const std::byte> udp = ip.subspan(ihl, total - ihl);
  if (udp.size() < 8) return false;
  const size_t udpLen = be16(udp.data() + 4);
  if (udpLen < 8 || udpLen > udp.size()) return false;
  d.srcIp = be32(ip.data() + 12);
  d.dstIp = be32(ip.data() + 16);
  d.srcPort = be16(udp.data());
  d.dstPort = be16(udp.data() + 2);
  d.payload = udp.subspan(8, udpLen - 8);
  return true;
}

}  // namespace

bool parsePcapUdp(std::span<const std::byte> file, const std::string& name,
                  const std::function<void(const UdpDatagram&)>& visit, std::string& error, PcapStats* stats) {
  PcapStats local;
  PcapStats& st = stats ? *stats : local;
  st = {};
  if (file.size() < kFileHeader) {
    error = name + ": not a pcap file (" + std::to_string(file.size()) + " bytes, shorter than the 24-byte header)";
    return false;
  }
  const uint32_t magicLe = le32(file.data());
  bool little = true, nanos = false;
  switch (magicLe) {
    case 0xa1b2c3d4: break;
    case 0xa1b23c4d: nanos = true; break;
    case 0xd4c3b2a1: little = false; break;
    case 0x4d3cb2a1: little = false, nanos = true; break;
    case 0x0a0d0d0a:
      error = name + ": is pcapng; convert it with 'tshark -F pcap -r " + name + " -w out.pcap' (or capture with dumpcap -P)";
      return false;
    default: {
      char hex[16];
      std::snprintf(hex, sizeof hex, "0x%08x", be32(file.data()));
      error = name + ": not a pcap file (magic " + hex + ")";
      return false;
    }
  }
  auto rd32 = [&](const std::byte* p) { return little ? le32(p) : be32(p); };
  const uint32_t linkType = rd32(file.data() + 20) & 0x0fffffffu;  // upper bits: FCS info
  Link link;
  switch (linkType) {
    case 0: link = Link::null; break;
    case 1: link = Link::ethernet; break;
    case 101:
    case 228: link = Link::rawIp; break;
    case 113: link = Link::sll; break;
    default:
      error = name + ": link type " + std::to_string(linkType) +
              " not supported (Ethernet 1, Linux cooked 113, raw IPv4 101/228, loopback 0)";
      return false;
  }
  size_t at = kFileHeader;
  while (at < file.size()) {
    if (file.size() - at < kRecordHeader) {
      error = name + ": record header at byte " + std::to_string(at) + " runs past the end of the file";
      return false;
    }
    const std::byte* h = file.data() + at;
    const uint32_t sec = rd32(h), frac = rd32(h + 4), capLen = rd32(h + 8), origLen = rd32(h + 12);
    at += kRecordHeader;
    if (capLen > file.size() - at) {
      error = name + ": record at byte " + std::to_string(at - kRecordHeader) + " claims " + std::to_string(capLen) +
              " bytes, past the end of the file";
      return false;
    }
    const std::span<const std::byte> frame = file.subspan(at, capLen);
    at += capLen;
    ++st.records;
    UdpDatagram d;
    if (capLen < origLen || !parseUdp(ipv4Payload(link, frame), d)) {
      ++st.skipped;
      continue;
    }
    d.time_s = static_cast<double>(sec) + static_cast<double>(frac) * (nanos ? 1e-9 : 1e-6);
    ++st.udp;
    visit(d);
  }
  return true;
}

bool cigiPcapToRecording(const std::string& pcapFile, uint16_t port, const lod::Geodetic& origin, Recording& out,
                         std::string& error, const CigiAssemblerConfig& cigi, LinkCountersSnapshot* counters) {
  std::ifstream in(pcapFile, std::ios::binary);
  if (!in) {
    error = pcapFile + ": cannot open: " + std::strerror(errno);
    return false;
  }
  std::vector<char> raw((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(raw.data()), raw.size());

  auto assembler = std::make_unique<CigiAssembler>(cigi, origin);
  LinkCounters c;
  Recording rec;
  double t0 = 0.0;
  bool first = true;
  const bool ok = parsePcapUdp(
      bytes, pcapFile,
      [&](const UdpDatagram& d) {
        if (d.dstPort != port) return;
        c.received.fetch_add(1, std::memory_order_relaxed);
        if (assembler->apply(d.payload, c) != CigiAssembler::Result::published) return;
        if (first) {
          t0 = d.time_s;
          first = false;
        }
        HostSample s;
        // Capture times can step back a little (multi-queue NICs): keep t_s non-decreasing.
        s.t_s = std::max(d.time_s - t0, rec.samples.empty() ? 0.0 : rec.samples.back().t_s);
        s.state = assembler->state();
        rec.samples.push_back(s);
      },
      error);
  if (counters) *counters = snapshot(c);
  if (!ok) return false;
  if (rec.samples.empty()) {
    const LinkCountersSnapshot s = snapshot(c);
    error = pcapFile + ": no CIGI host message to UDP port " + std::to_string(port) + " gave an eyepoint (" +
            std::to_string(s.received) + " datagrams to that port, " + std::to_string(s.malformed) + " malformed, " +
            std::to_string(s.accepted) + " accepted without an ownship Entity Control " + std::to_string(cigi.entityId) +
            ")";
    return false;
  }
  out = std::move(rec);
  return true;
}

}  // namespace ig::io
