// CIGI 3.3 codec: SISO-STD-013-2014 (Common Image Generator Interface ICD, version 3.3).
// Layouts are written in io/cigi.h next to each struct.
#include "io/cigi.h"

#include <bit>
#include <cassert>
#include <cmath>
#include <cstring>

namespace ig::io::cigi {
namespace {

constexpr bool kNativeLittle = std::endian::native == std::endian::little;

// Reads/writes multi-byte fields of one packet in a given byte order.
struct Cursor {
  const std::byte* p;
  bool swap;  // the message's order differs from this machine's

  uint8_t u8(size_t at) const { return std::to_integer<uint8_t>(p[at]); }
  uint16_t u16(size_t at) const {
    uint16_t v;
    std::memcpy(&v, p + at, 2);
    return swap ? __builtin_bswap16(v) : v;
  }
  uint32_t u32(size_t at) const {
    uint32_t v;
    std::memcpy(&v, p + at, 4);
    return swap ? __builtin_bswap32(v) : v;
  }
  float f32(size_t at) const { return std::bit_cast<float>(u32(at)); }
  double f64(size_t at) const {
    uint64_t v;
    std::memcpy(&v, p + at, 8);
    return std::bit_cast<double>(swap ? __builtin_bswap64(v) : v);
  }
};

struct Writer {
  std::byte* p;
  bool swap;

  void u8(size_t at, uint8_t v) const { p[at] = std::byte{v}; }
  void u16(size_t at, uint16_t v) const {
    if (swap) v = __builtin_bswap16(v);
    std::memcpy(p + at, &v, 2);
  }
  void u32(size_t at, uint32_t v) const {
    if (swap) v = __builtin_bswap32(v);
    std::memcpy(p + at, &v, 4);
  }
  void f32(size_t at, float v) const { u32(at, std::bit_cast<uint32_t>(v)); }
  void f64(size_t at, double v) const {
    uint64_t b = std::bit_cast<uint64_t>(v);
    if (swap) b = __builtin_bswap64(b);
    std::memcpy(p + at, &b, 8);
  }
};

bool swapFor(ByteOrder order) { return (order == ByteOrder::little) != kNativeLittle; }

Writer begin(std::span<std::byte> out, PacketId id, size_t size, ByteOrder order) {
  assert(out.size() >= size && "cigi::encode: output span too small");
  std::memset(out.data(), 0, size);
  Writer w{out.data(), swapFor(order)};
  w.u8(0, static_cast<uint8_t>(id));
  w.u8(1, static_cast<uint8_t>(size));
  return w;
}

size_t fixedSize(uint8_t id) {
  switch (static_cast<PacketId>(id)) {
    case PacketId::igControl: return kIgControlSize;
    case PacketId::entityControl: return kEntityControlSize;
    case PacketId::celestialSphereControl: return kCelestialSphereControlSize;
    case PacketId::atmosphereControl: return kAtmosphereControlSize;
    case PacketId::viewControl: return kViewControlSize;
    case PacketId::viewDefinition: return kViewDefinitionSize;
    case PacketId::hatHotRequest: return kHatHotRequestSize;
    case PacketId::startOfFrame: return kStartOfFrameSize;
    case PacketId::hatHotResponse: return kHatHotResponseSize;
    case PacketId::hatHotExtendedResponse: return kHatHotExtendedResponseSize;
    case PacketId::losSegmentRequest: return kLosSegmentRequestSize;
    case PacketId::losVectorRequest: return kLosVectorRequestSize;
    case PacketId::losResponse: return kLosResponseSize;
    case PacketId::losExtendedResponse: return kLosExtendedResponseSize;
  }
  return 0;
}

// Checks the framing every CIGI 3 message shares: first packet `first` (IG Control or Start of
// Frame) with version 3 and the magic; every packet inside the datagram with a sane size.
// Sets `swap` from the magic.
CigiStatus checkFraming(std::span<const std::byte> bytes, PacketId first, bool& swap) {
  if (bytes.empty()) return CigiStatus::empty;
  if (std::to_integer<uint8_t>(bytes[0]) != static_cast<uint8_t>(first)) return CigiStatus::firstNotControl;
  const size_t firstSize = fixedSize(static_cast<uint8_t>(first));
  if (bytes.size() < 2) return CigiStatus::packetOverrun;
  if (std::to_integer<uint8_t>(bytes[1]) != firstSize) return CigiStatus::badPacketSize;
  if (bytes.size() < firstSize) return CigiStatus::packetOverrun;
  if (std::to_integer<uint8_t>(bytes[2]) != kMajorVersion) return CigiStatus::badVersion;
  uint16_t magic;
  std::memcpy(&magic, bytes.data() + 6, 2);
  if (magic == kByteSwapMagic) {
    swap = false;
  } else if (magic == __builtin_bswap16(kByteSwapMagic)) {
    swap = true;
  } else {
    return CigiStatus::badMagic;
  }
  // Walk the rest: sizes and bounds only.
  size_t at = firstSize;
  while (at < bytes.size()) {
    if (bytes.size() - at < 2) return CigiStatus::packetOverrun;
    const uint8_t id = std::to_integer<uint8_t>(bytes[at]);
    const size_t size = std::to_integer<uint8_t>(bytes[at + 1]);
    if (size < 2) return CigiStatus::badPacketSize;
    const size_t want = fixedSize(id);
    if (want != 0 && size != want) return CigiStatus::badPacketSize;
    if (size > bytes.size() - at) return CigiStatus::packetOverrun;
    if (id == static_cast<uint8_t>(PacketId::igControl) || id == static_cast<uint8_t>(PacketId::startOfFrame))
      return CigiStatus::secondControl;
    at += size;
  }
  return CigiStatus::ok;
}

IgControl readIgControl(const Cursor& c) {
  IgControl p;
  p.majorVersion = c.u8(2);
  p.databaseNumber = static_cast<int8_t>(c.u8(3));
  const uint8_t b4 = c.u8(4);
  p.igMode = static_cast<IgMode>(b4 & 0x03);
  p.timestampValid = (b4 & 0x04) != 0;
  p.extrapolationEnable = (b4 & 0x08) != 0;
  p.minorVersion = static_cast<uint8_t>(b4 >> 4);
  p.hostFrame = c.u32(8);
  p.timestamp_10us = c.u32(12);
  p.lastIgFrame = c.u32(16);
  return p;
}

EntityControl readEntity(const Cursor& c) {
  EntityControl p;
  p.entityId = c.u16(2);
  const uint8_t b4 = c.u8(4);
  p.entityState = b4 & 0x03;
  p.attached = (b4 & 0x04) != 0;
  p.flags4 = b4 & 0xf8;
  p.animationFlags = c.u8(5);
  p.alpha = c.u8(6);
  p.entityType = c.u16(8);
  p.parentId = c.u16(10);
  p.roll_deg = c.f32(12);
  p.pitch_deg = c.f32(16);
  p.yaw_deg = c.f32(20);
  p.lat_deg = c.f64(24);
  p.lon_deg = c.f64(32);
  p.alt_m = c.f64(40);
  return p;
}

CelestialSphereControl readCelestial(const Cursor& c) {
  CelestialSphereControl p;
  p.hour = c.u8(2);
  p.minute = c.u8(3);
  const uint8_t b4 = c.u8(4);
  p.ephemerisEnable = (b4 & 0x01) != 0;
  p.sunEnable = (b4 & 0x02) != 0;
  p.moonEnable = (b4 & 0x04) != 0;
  p.starFieldEnable = (b4 & 0x08) != 0;
  p.dateTimeValid = (b4 & 0x10) != 0;
  p.date_mmddyyyy = c.u32(8);
  p.starIntensity_pct = c.f32(12);
  return p;
}

ViewControl readViewControl(const Cursor& c) {
  ViewControl p;
  p.viewId = c.u16(2);
  p.groupId = c.u8(4);
  p.enable = c.u8(5) & ViewControl::kAll;
  p.entityId = c.u16(6);
  p.x_m = c.f32(8);
  p.y_m = c.f32(12);
  p.z_m = c.f32(16);
  p.roll_deg = c.f32(20);
  p.pitch_deg = c.f32(24);
  p.yaw_deg = c.f32(28);
  return p;
}

ViewDefinition readViewDefinition(const Cursor& c) {
  ViewDefinition p;
  p.viewId = c.u16(2);
  p.groupId = c.u8(4);
  const uint8_t b5 = c.u8(5), b6 = c.u8(6);
  p.enable = b5 & ViewDefinition::kAll;
  p.mirrorMode = static_cast<uint8_t>(b5 >> 6);
  p.pixelReplication = b6 & 0x07;
  p.orthographic = (b6 & 0x08) != 0;
  p.reorder = (b6 & 0x10) != 0;
  p.viewType = static_cast<uint8_t>(b6 >> 5);
  p.near_m = c.f32(8);
  p.far_m = c.f32(12);
  p.left_deg = c.f32(16);
  p.right_deg = c.f32(20);
  p.top_deg = c.f32(24);
  p.bottom_deg = c.f32(28);
  return p;
}

HatHotRequest readHatHotRequest(const Cursor& c) {
  HatHotRequest p;
  p.hatHotId = c.u16(2);
  const uint8_t b4 = c.u8(4);
  p.requestType = b4 & 0x03;
  p.entityCoordinates = (b4 & 0x04) != 0;
  p.updatePeriod = c.u8(5);
  p.entityId = c.u16(6);
  p.lat_deg = c.f64(8);
  p.lon_deg = c.f64(16);
  p.alt_m = c.f64(24);
  return p;
}

LosRequest readLosSegmentRequest(const Cursor& c) {
  LosRequest p;
  p.kind = LosRequest::kSegment;
  p.losId = c.u16(2);
  const uint8_t b4 = c.u8(4);
  p.extended = (b4 & 0x01) != 0;
  p.sourceEntity = (b4 & 0x02) != 0;
  p.destinationEntity = (b4 & 0x04) != 0;
  p.responseEntity = (b4 & 0x08) != 0;
  p.destinationEntityIdValid = (b4 & 0x10) != 0;
  p.alphaThreshold = c.u8(5);
  p.entityId = c.u16(6);
  p.srcLat_deg = c.f64(8);
  p.srcLon_deg = c.f64(16);
  p.srcAlt_m = c.f64(24);
  p.dstLat_deg = c.f64(32);
  p.dstLon_deg = c.f64(40);
  p.dstAlt_m = c.f64(48);
  p.materialMask = c.u32(56);
  p.updatePeriod = c.u8(60);
  p.destinationEntityId = c.u16(62);
  return p;
}

LosRequest readLosVectorRequest(const Cursor& c) {
  LosRequest p;
  p.kind = LosRequest::kVector;
  p.losId = c.u16(2);
  const uint8_t b4 = c.u8(4);
  p.extended = (b4 & 0x01) != 0;
  p.sourceEntity = (b4 & 0x02) != 0;
  p.responseEntity = (b4 & 0x04) != 0;
  p.alphaThreshold = c.u8(5);
  p.entityId = c.u16(6);
  p.azimuth_deg = c.f32(8);
  p.elevation_deg = c.f32(12);
  p.minRange_m = c.f32(16);
  p.maxRange_m = c.f32(20);
  p.srcLat_deg = c.f64(24);
  p.srcLon_deg = c.f64(32);
  p.srcAlt_m = c.f64(40);
  p.materialMask = c.u32(48);
  p.updatePeriod = c.u8(52);
  return p;
}

bool packetIs(std::span<const std::byte> packet, PacketId id, size_t size) {
  return packet.size() >= size && std::to_integer<uint8_t>(packet[0]) == static_cast<uint8_t>(id) &&
         std::to_integer<uint8_t>(packet[1]) == size;
}

template <class T>
bool inRange(T value, double lo, double hi) {
  const double v = static_cast<double>(value);
  return std::isfinite(v) && v >= lo && v <= hi;
}

}  // namespace

ByteOrder nativeByteOrder() { return kNativeLittle ? ByteOrder::little : ByteOrder::big; }

const char* toString(CigiStatus s) {
  switch (s) {
    case CigiStatus::ok: return "ok";
    case CigiStatus::empty: return "empty datagram";
    case CigiStatus::firstNotControl: return "first packet is not IG Control / Start of Frame";
    case CigiStatus::badVersion: return "CIGI major version is not 3";
    case CigiStatus::badMagic: return "bad byte swap magic";
    case CigiStatus::badPacketSize: return "bad packet size";
    case CigiStatus::packetOverrun: return "packet runs past the end of the datagram";
    case CigiStatus::secondControl: return "second IG Control / Start of Frame in one message";
  }
  return "?";
}

AtmosphereControl readAtmosphere(const Cursor& c) {
  AtmosphereControl p;
  p.atmosphericModelEnable = (c.u8(2) & 0x01) != 0;
  p.humidity_pct = c.u8(3);
  p.airTemperature_c = c.f32(4);
  p.visibility_m = c.f32(8);
  p.horizontalWind_mps = c.f32(12);
  p.verticalWind_mps = c.f32(16);
  p.windDirection_deg = c.f32(20);
  p.pressure_hpa = c.f32(24);
  return p;
}

CigiStatus decodeHostMessage(std::span<const std::byte> bytes, HostMessage& out, const HostMessageFilter& filter) {
  bool swap = false;
  if (const CigiStatus s = checkFraming(bytes, PacketId::igControl, swap); s != CigiStatus::ok) return s;
  out.byteOrder = (swap != kNativeLittle) ? ByteOrder::little : ByteOrder::big;
  out.igControl = readIgControl(Cursor{bytes.data(), swap});
  out.entityCount = out.viewControlCount = out.viewDefinitionCount = 0;
  out.hasCelestial = false;
  out.hasAtmosphere = false;
  out.hatHotCount = 0;
  out.hatHotOmitted = out.unknownPackets = out.omittedPackets = 0;
  out.losCount = 0;
  out.losOmitted = 0;
  for (size_t at = kIgControlSize; at < bytes.size();) {
    const Cursor c{bytes.data() + at, swap};
    const uint8_t id = c.u8(0);
    at += c.u8(1);
    switch (static_cast<PacketId>(id)) {
      case PacketId::entityControl: {
        const uint16_t entityId = c.u16(2);
        if ((filter.entityId >= 0 && entityId != filter.entityId) || out.entityCount == HostMessage::kMaxEntities) {
          ++out.omittedPackets;
          break;
        }
        out.entities[out.entityCount++] = readEntity(c);
        break;
      }
      case PacketId::viewControl: {
        if ((filter.viewId >= 0 && c.u16(2) != filter.viewId) || out.viewControlCount == HostMessage::kMaxViews) {
          ++out.omittedPackets;
          break;
        }
        out.viewControls[out.viewControlCount++] = readViewControl(c);
        break;
      }
      case PacketId::viewDefinition: {
        if ((filter.viewId >= 0 && c.u16(2) != filter.viewId) || out.viewDefinitionCount == HostMessage::kMaxViews) {
          ++out.omittedPackets;
          break;
        }
        out.viewDefinitions[out.viewDefinitionCount++] = readViewDefinition(c);
        break;
      }
      case PacketId::celestialSphereControl:
        out.celestial = readCelestial(c);
        out.hasCelestial = true;
        break;
      case PacketId::atmosphereControl:
        out.atmosphere = readAtmosphere(c);
        out.hasAtmosphere = true;
        break;
      case PacketId::hatHotRequest:
        if (out.hatHotCount == HostMessage::kMaxHatHotRequests) {
          ++out.omittedPackets;
          ++out.hatHotOmitted;
          break;
        }
        out.hatHotRequests[out.hatHotCount++] = readHatHotRequest(c);
        break;
      case PacketId::losSegmentRequest:
      case PacketId::losVectorRequest:
        if (out.losCount == HostMessage::kMaxLosRequests) {
          ++out.omittedPackets;
          ++out.losOmitted;
          break;
        }
        out.losRequests[out.losCount++] =
            id == static_cast<uint8_t>(PacketId::losSegmentRequest) ? readLosSegmentRequest(c) : readLosVectorRequest(c);
        break;
      default:
        ++out.unknownPackets;
        break;
    }
  }
  return CigiStatus::ok;
}

CigiStatus decodeStartOfFrame(std::span<const std::byte> bytes, StartOfFrame& out, ByteOrder* order) {
  bool swap = false;
  if (const CigiStatus s = checkFraming(bytes, PacketId::startOfFrame, swap); s != CigiStatus::ok) return s;
  const Cursor c{bytes.data(), swap};
  out.majorVersion = c.u8(2);
  out.databaseNumber = static_cast<int8_t>(c.u8(3));
  out.igStatus = c.u8(4);
  const uint8_t b5 = c.u8(5);
  out.igMode = static_cast<IgMode>(b5 & 0x03);
  out.timestampValid = (b5 & 0x04) != 0;
  out.hostDefinedEarthModel = (b5 & 0x08) != 0;
  out.minorVersion = static_cast<uint8_t>(b5 >> 4);
  out.igFrame = c.u32(8);
  out.timestamp_10us = c.u32(12);
  out.lastHostFrame = c.u32(16);
  if (order) *order = (swap != kNativeLittle) ? ByteOrder::little : ByteOrder::big;
  return CigiStatus::ok;
}

size_t encode(const IgControl& p, ByteOrder order, std::span<std::byte> out) {
  const Writer w = begin(out, PacketId::igControl, kIgControlSize, order);
  w.u8(2, p.majorVersion);
  w.u8(3, static_cast<uint8_t>(p.databaseNumber));
  w.u8(4, static_cast<uint8_t>((static_cast<uint8_t>(p.igMode) & 0x03) | (p.timestampValid ? 0x04 : 0) |
                               (p.extrapolationEnable ? 0x08 : 0) | ((p.minorVersion & 0x0f) << 4)));
  w.u16(6, kByteSwapMagic);
  w.u32(8, p.hostFrame);
  w.u32(12, p.timestamp_10us);
  w.u32(16, p.lastIgFrame);
  return kIgControlSize;
}

size_t encode(const EntityControl& p, ByteOrder order, std::span<std::byte> out) {
  const Writer w = begin(out, PacketId::entityControl, kEntityControlSize, order);
  w.u16(2, p.entityId);
  w.u8(4, static_cast<uint8_t>((p.entityState & 0x03) | (p.attached ? 0x04 : 0) | (p.flags4 & 0xf8)));
  w.u8(5, p.animationFlags);
  w.u8(6, p.alpha);
  w.u16(8, p.entityType);
  w.u16(10, p.parentId);
  w.f32(12, p.roll_deg);
  w.f32(16, p.pitch_deg);
  w.f32(20, p.yaw_deg);
  w.f64(24, p.lat_deg);
  w.f64(32, p.lon_deg);
  w.f64(40, p.alt_m);
  return kEntityControlSize;
}

size_t encode(const CelestialSphereControl& p, ByteOrder order, std::span<std::byte> out) {
  const Writer w = begin(out, PacketId::celestialSphereControl, kCelestialSphereControlSize, order);
  w.u8(2, p.hour);
  w.u8(3, p.minute);
  w.u8(4, static_cast<uint8_t>((p.ephemerisEnable ? 0x01 : 0) | (p.sunEnable ? 0x02 : 0) | (p.moonEnable ? 0x04 : 0) |
                               (p.starFieldEnable ? 0x08 : 0) | (p.dateTimeValid ? 0x10 : 0)));
  w.u32(8, p.date_mmddyyyy);
  w.f32(12, p.starIntensity_pct);
  return kCelestialSphereControlSize;
}

size_t encode(const AtmosphereControl& p, ByteOrder order, std::span<std::byte> out) {
  const Writer w = begin(out, PacketId::atmosphereControl, kAtmosphereControlSize, order);
  w.u8(2, p.atmosphericModelEnable ? 0x01 : 0x00);
  w.u8(3, p.humidity_pct);
  w.f32(4, p.airTemperature_c);
  w.f32(8, p.visibility_m);
  w.f32(12, p.horizontalWind_mps);
  w.f32(16, p.verticalWind_mps);
  w.f32(20, p.windDirection_deg);
  w.f32(24, p.pressure_hpa);
  return kAtmosphereControlSize;
}

size_t encode(const ViewControl& p, ByteOrder order, std::span<std::byte> out) {
  const Writer w = begin(out, PacketId::viewControl, kViewControlSize, order);
  w.u16(2, p.viewId);
  w.u8(4, p.groupId);
  w.u8(5, p.enable & ViewControl::kAll);
  w.u16(6, p.entityId);
  w.f32(8, p.x_m);
  w.f32(12, p.y_m);
  w.f32(16, p.z_m);
  w.f32(20, p.roll_deg);
  w.f32(24, p.pitch_deg);
  w.f32(28, p.yaw_deg);
  return kViewControlSize;
}

size_t encode(const ViewDefinition& p, ByteOrder order, std::span<std::byte> out) {
  const Writer w = begin(out, PacketId::viewDefinition, kViewDefinitionSize, order);
  w.u16(2, p.viewId);
  w.u8(4, p.groupId);
  w.u8(5, static_cast<uint8_t>((p.enable & ViewDefinition::kAll) | ((p.mirrorMode & 0x03) << 6)));
  w.u8(6, static_cast<uint8_t>((p.pixelReplication & 0x07) | (p.orthographic ? 0x08 : 0) | (p.reorder ? 0x10 : 0) |
                               ((p.viewType & 0x07) << 5)));
  w.f32(8, p.near_m);
  w.f32(12, p.far_m);
  w.f32(16, p.left_deg);
  w.f32(20, p.right_deg);
  w.f32(24, p.top_deg);
  w.f32(28, p.bottom_deg);
  return kViewDefinitionSize;
}

size_t encode(const StartOfFrame& p, ByteOrder order, std::span<std::byte> out) {
  const Writer w = begin(out, PacketId::startOfFrame, kStartOfFrameSize, order);
  w.u8(2, p.majorVersion);
  w.u8(3, static_cast<uint8_t>(p.databaseNumber));
  w.u8(4, p.igStatus);
  w.u8(5, static_cast<uint8_t>((static_cast<uint8_t>(p.igMode) & 0x03) | (p.timestampValid ? 0x04 : 0) |
                               (p.hostDefinedEarthModel ? 0x08 : 0) | ((p.minorVersion & 0x0f) << 4)));
  w.u16(6, kByteSwapMagic);
  w.u32(8, p.igFrame);
  w.u32(12, p.timestamp_10us);
  w.u32(16, p.lastHostFrame);
  return kStartOfFrameSize;
}

size_t encode(const HatHotRequest& p, ByteOrder order, std::span<std::byte> out) {
  const Writer w = begin(out, PacketId::hatHotRequest, kHatHotRequestSize, order);
  w.u16(2, p.hatHotId);
  w.u8(4, static_cast<uint8_t>((p.requestType & 0x03) | (p.entityCoordinates ? 0x04 : 0)));
  w.u8(5, p.updatePeriod);
  w.u16(6, p.entityId);
  w.f64(8, p.lat_deg);
  w.f64(16, p.lon_deg);
  w.f64(24, p.alt_m);
  return kHatHotRequestSize;
}

size_t encode(const HatHotResponse& p, ByteOrder order, std::span<std::byte> out) {
  const Writer w = begin(out, PacketId::hatHotResponse, kHatHotResponseSize, order);
  w.u16(2, p.hatHotId);
  w.u8(4, static_cast<uint8_t>((p.valid ? 0x01 : 0) | (p.hot ? 0x02 : 0) | ((p.hostFrameLsn & 0x0f) << 4)));
  w.f64(8, p.height_m);
  return kHatHotResponseSize;
}

size_t encode(const HatHotExtendedResponse& p, ByteOrder order, std::span<std::byte> out) {
  const Writer w = begin(out, PacketId::hatHotExtendedResponse, kHatHotExtendedResponseSize, order);
  w.u16(2, p.hatHotId);
  w.u8(4, static_cast<uint8_t>((p.valid ? 0x01 : 0) | ((p.hostFrameLsn & 0x0f) << 4)));
  w.f64(8, p.hat_m);
  w.f64(16, p.hot_m);
  w.u32(24, p.materialCode);
  w.f32(28, p.normalAzimuth_deg);
  w.f32(32, p.normalElevation_deg);
  return kHatHotExtendedResponseSize;
}

bool decodePacket(std::span<const std::byte> packet, ByteOrder order, HatHotResponse& out) {
  if (packet.size() < kHatHotResponseSize || std::to_integer<uint8_t>(packet[0]) != static_cast<uint8_t>(PacketId::hatHotResponse) ||
      std::to_integer<uint8_t>(packet[1]) != kHatHotResponseSize)
    return false;
  const Cursor c{packet.data(), swapFor(order)};
  out.hatHotId = c.u16(2);
  const uint8_t b4 = c.u8(4);
  out.valid = (b4 & 0x01) != 0;
  out.hot = (b4 & 0x02) != 0;
  out.hostFrameLsn = static_cast<uint8_t>(b4 >> 4);
  out.height_m = c.f64(8);
  return true;
}

bool decodePacket(std::span<const std::byte> packet, ByteOrder order, HatHotExtendedResponse& out) {
  if (packet.size() < kHatHotExtendedResponseSize ||
      std::to_integer<uint8_t>(packet[0]) != static_cast<uint8_t>(PacketId::hatHotExtendedResponse) ||
      std::to_integer<uint8_t>(packet[1]) != kHatHotExtendedResponseSize)
    return false;
  const Cursor c{packet.data(), swapFor(order)};
  out.hatHotId = c.u16(2);
  const uint8_t b4 = c.u8(4);
  out.valid = (b4 & 0x01) != 0;
  out.hostFrameLsn = static_cast<uint8_t>(b4 >> 4);
  out.hat_m = c.f64(8);
  out.hot_m = c.f64(16);
  out.materialCode = c.u32(24);
  out.normalAzimuth_deg = c.f32(28);
  out.normalElevation_deg = c.f32(32);
  return true;
}

size_t encode(const LosRequest& p, ByteOrder order, std::span<std::byte> out) {
  if (p.kind == LosRequest::kVector) {
    const Writer w = begin(out, PacketId::losVectorRequest, kLosVectorRequestSize, order);
    w.u16(2, p.losId);
    w.u8(4, static_cast<uint8_t>((p.extended ? 0x01 : 0) | (p.sourceEntity ? 0x02 : 0) | (p.responseEntity ? 0x04 : 0)));
    w.u8(5, p.alphaThreshold);
    w.u16(6, p.entityId);
    w.f32(8, p.azimuth_deg);
    w.f32(12, p.elevation_deg);
    w.f32(16, p.minRange_m);
    w.f32(20, p.maxRange_m);
    w.f64(24, p.srcLat_deg);
    w.f64(32, p.srcLon_deg);
    w.f64(40, p.srcAlt_m);
    w.u32(48, p.materialMask);
    w.u8(52, p.updatePeriod);
    return kLosVectorRequestSize;
  }
  const Writer w = begin(out, PacketId::losSegmentRequest, kLosSegmentRequestSize, order);
  w.u16(2, p.losId);
  w.u8(4, static_cast<uint8_t>((p.extended ? 0x01 : 0) | (p.sourceEntity ? 0x02 : 0) | (p.destinationEntity ? 0x04 : 0) |
                               (p.responseEntity ? 0x08 : 0) | (p.destinationEntityIdValid ? 0x10 : 0)));
  w.u8(5, p.alphaThreshold);
  w.u16(6, p.entityId);
  w.f64(8, p.srcLat_deg);
  w.f64(16, p.srcLon_deg);
  w.f64(24, p.srcAlt_m);
  w.f64(32, p.dstLat_deg);
  w.f64(40, p.dstLon_deg);
  w.f64(48, p.dstAlt_m);
  w.u32(56, p.materialMask);
  w.u8(60, p.updatePeriod);
  w.u16(62, p.destinationEntityId);
  return kLosSegmentRequestSize;
}

size_t encode(const LosResponse& p, ByteOrder order, std::span<std::byte> out) {
  const Writer w = begin(out, PacketId::losResponse, kLosResponseSize, order);
  w.u16(2, p.losId);
  w.u8(4, static_cast<uint8_t>((p.valid ? 0x01 : 0) | (p.entityIdValid ? 0x02 : 0) | (p.visible ? 0x04 : 0) |
                               ((p.hostFrameLsn & 0x0f) << 4)));
  w.u8(5, p.responseCount);
  w.u16(6, p.entityId);
  w.f64(8, p.range_m);
  return kLosResponseSize;
}

size_t encode(const LosExtendedResponse& p, ByteOrder order, std::span<std::byte> out) {
  const Writer w = begin(out, PacketId::losExtendedResponse, kLosExtendedResponseSize, order);
  w.u16(2, p.losId);
  w.u8(4, static_cast<uint8_t>((p.valid ? 0x01 : 0) | (p.entityIdValid ? 0x02 : 0) | (p.rangeValid ? 0x04 : 0) |
                               (p.visible ? 0x08 : 0) | ((p.hostFrameLsn & 0x0f) << 4)));
  w.u8(5, p.responseCount);
  w.u16(6, p.entityId);
  w.f64(8, p.range_m);
  w.f64(16, p.lat_deg);
  w.f64(24, p.lon_deg);
  w.f64(32, p.alt_m);
  w.u8(40, p.red);
  w.u8(41, p.green);
  w.u8(42, p.blue);
  w.u8(43, p.alpha);
  w.u32(44, p.materialCode);
  w.f32(48, p.normalAzimuth_deg);
  w.f32(52, p.normalElevation_deg);
  return kLosExtendedResponseSize;
}

bool decodePacket(std::span<const std::byte> packet, ByteOrder order, LosResponse& out) {
  if (!packetIs(packet, PacketId::losResponse, kLosResponseSize)) return false;
  const Cursor c{packet.data(), swapFor(order)};
  out.losId = c.u16(2);
  const uint8_t b4 = c.u8(4);
  out.valid = (b4 & 0x01) != 0;
  out.entityIdValid = (b4 & 0x02) != 0;
  out.visible = (b4 & 0x04) != 0;
  out.hostFrameLsn = static_cast<uint8_t>(b4 >> 4);
  out.responseCount = c.u8(5);
  out.entityId = c.u16(6);
  out.range_m = c.f64(8);
  return true;
}

bool decodePacket(std::span<const std::byte> packet, ByteOrder order, LosExtendedResponse& out) {
  if (!packetIs(packet, PacketId::losExtendedResponse, kLosExtendedResponseSize)) return false;
  const Cursor c{packet.data(), swapFor(order)};
  out.losId = c.u16(2);
  const uint8_t b4 = c.u8(4);
  out.valid = (b4 & 0x01) != 0;
  out.entityIdValid = (b4 & 0x02) != 0;
  out.rangeValid = (b4 & 0x04) != 0;
  out.visible = (b4 & 0x08) != 0;
  out.hostFrameLsn = static_cast<uint8_t>(b4 >> 4);
  out.responseCount = c.u8(5);
  out.entityId = c.u16(6);
  out.range_m = c.f64(8);
  out.lat_deg = c.f64(16);
  out.lon_deg = c.f64(24);
  out.alt_m = c.f64(32);
  out.red = c.u8(40);
  out.green = c.u8(41);
  out.blue = c.u8(42);
  out.alpha = c.u8(43);
  out.materialCode = c.u32(44);
  out.normalAzimuth_deg = c.f32(48);
  out.normalElevation_deg = c.f32(52);
  return true;
}

uint32_t validateLosRequest(const LosRequest& p) {
  constexpr double kMaxOffset_m = 1.0e5, kMaxRange_m = 1.0e6;
  auto point = [](bool entity, double a, double b, double c, uint32_t fa, uint32_t fb, uint32_t fc) {
    uint32_t bad = 0;
    if (entity) {
      if (!inRange(a, -kMaxOffset_m, kMaxOffset_m)) bad |= fa;
      if (!inRange(b, -kMaxOffset_m, kMaxOffset_m)) bad |= fb;
      if (!inRange(c, -kMaxOffset_m, kMaxOffset_m)) bad |= fc;
    } else {
      if (!inRange(a, -90.0, 90.0)) bad |= fa;
      if (!inRange(b, -180.0, 180.0)) bad |= fb;
      if (!inRange(c, -1.0e4, 1.0e6)) bad |= fc;
    }
    return bad;
  };
  uint32_t bad = point(p.sourceEntity, p.srcLat_deg, p.srcLon_deg, p.srcAlt_m, kLosSrcLatX, kLosSrcLonY, kLosSrcAltZ);
  if (p.kind == LosRequest::kSegment) {
    bad |= point(p.destinationEntity, p.dstLat_deg, p.dstLon_deg, p.dstAlt_m, kLosDstLatX, kLosDstLonY, kLosDstAltZ);
  } else {
    if (!inRange(p.azimuth_deg, -360.0, 360.0)) bad |= kLosAzimuth;
    if (!inRange(p.elevation_deg, -90.0, 90.0)) bad |= kLosElevation;
    if (!inRange(p.minRange_m, 0.0, kMaxRange_m)) bad |= kLosMinRange;
    const double lo = (bad & kLosMinRange) ? 0.0 : static_cast<double>(p.minRange_m);
    if (!inRange(p.maxRange_m, lo, kMaxRange_m)) bad |= kLosMaxRange;
  }
  return bad;
}

uint32_t validateHatHotRequest(const HatHotRequest& p) {
  uint32_t bad = 0;
  if (p.requestType > HatHotRequest::kExtended) bad |= kHatHotType;
  if (p.entityCoordinates) {
    constexpr double kMaxOffset_m = 1.0e5;
    if (!inRange(p.lat_deg, -kMaxOffset_m, kMaxOffset_m)) bad |= kHatHotLatX;
    if (!inRange(p.lon_deg, -kMaxOffset_m, kMaxOffset_m)) bad |= kHatHotLonY;
    if (!inRange(p.alt_m, -kMaxOffset_m, kMaxOffset_m)) bad |= kHatHotAltZ;
  } else {
    if (!inRange(p.lat_deg, -90.0, 90.0)) bad |= kHatHotLatX;
    if (!inRange(p.lon_deg, -180.0, 180.0)) bad |= kHatHotLonY;
    if (p.requestType != HatHotRequest::kHot && !inRange(p.alt_m, -1.0e4, 1.0e6)) bad |= kHatHotAltZ;
  }
  return bad;
}

uint32_t validateEntity(const EntityControl& p) {
  uint32_t bad = 0;
  if (!inRange(p.roll_deg, -180.0, 180.0)) bad |= kEntityRoll;
  if (!inRange(p.pitch_deg, -90.0, 90.0)) bad |= kEntityPitch;
  if (!inRange(p.yaw_deg, 0.0, 360.0) || p.yaw_deg == 360.0f) bad |= kEntityYaw;
  if (!inRange(p.lat_deg, -90.0, 90.0)) bad |= kEntityLat;
  if (!inRange(p.lon_deg, -180.0, 180.0)) bad |= kEntityLon;
  if (!inRange(p.alt_m, -1.0e4, 1.0e6)) bad |= kEntityAlt;
  return bad;
}

uint32_t validateViewControl(const ViewControl& p) {
  constexpr double kMaxOffset_m = 1.0e5;
  uint32_t bad = 0;
  if ((p.enable & ViewControl::kX) && !inRange(p.x_m, -kMaxOffset_m, kMaxOffset_m)) bad |= kViewX;
  if ((p.enable & ViewControl::kY) && !inRange(p.y_m, -kMaxOffset_m, kMaxOffset_m)) bad |= kViewY;
  if ((p.enable & ViewControl::kZ) && !inRange(p.z_m, -kMaxOffset_m, kMaxOffset_m)) bad |= kViewZ;
  if ((p.enable & ViewControl::kRoll) && !inRange(p.roll_deg, -180.0, 180.0)) bad |= kViewRoll;
  if ((p.enable & ViewControl::kPitch) && !inRange(p.pitch_deg, -90.0, 90.0)) bad |= kViewPitch;
  if ((p.enable & ViewControl::kYaw) && !inRange(p.yaw_deg, -360.0, 360.0)) bad |= kViewYaw;
  return bad;
}

uint32_t validateViewDefinition(const ViewDefinition& p) {
  uint32_t bad = 0;
  auto distance = [](float v) { return std::isfinite(v) && v > 0.0f && v <= 1.0e8f; };
  if ((p.enable & ViewDefinition::kNear) && !distance(p.near_m)) bad |= kViewNear;
  if ((p.enable & ViewDefinition::kFar) && !distance(p.far_m)) bad |= kViewFar;
  if ((p.enable & ViewDefinition::kLeft) && !inRange(p.left_deg, -90.0, 90.0)) bad |= kViewLeft;
  if ((p.enable & ViewDefinition::kRight) && !inRange(p.right_deg, -90.0, 90.0)) bad |= kViewRight;
  if ((p.enable & ViewDefinition::kTop) && !inRange(p.top_deg, -90.0, 90.0)) bad |= kViewTop;
  if ((p.enable & ViewDefinition::kBottom) && !inRange(p.bottom_deg, -90.0, 90.0)) bad |= kViewBottom;
  return bad;
}

uint32_t validateCelestial(const CelestialSphereControl& p) {
  uint32_t bad = 0;
  if (p.hour >= 24 || p.minute >= 60) bad |= kCelestialTime;
  const uint32_t month = p.date_mmddyyyy / 1000000u, day = (p.date_mmddyyyy / 10000u) % 100u,
                 year = p.date_mmddyyyy % 10000u;
  static constexpr uint8_t kDays[] = {31, 29, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  const bool leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
  if (month < 1 || month > 12 || day < 1 || year < 1 || day > kDays[month < 1 || month > 12 ? 0 : month - 1] ||
      (month == 2 && day == 29 && !leap))
    bad |= kCelestialDate;
  if (!inRange(p.starIntensity_pct, 0.0, 100.0)) bad |= kCelestialStars;
  return bad;
}

uint32_t validateAtmosphere(const AtmosphereControl& p) {
  return p.visibility_m >= 0.0f ? 0u : kAtmosphereVisibility;  // NaN fails too
}

}  // namespace ig::io::cigi
