// CIGI 3.3 codec (SISO-STD-013-2014, Common Image Generator Interface, version 3.3): bytes <->
// packet structs. Pure: no sockets, no clock, no allocation. Untrusted bytes never assert: a
// bad message returns a CigiStatus, a decoded value outside its range is reported by the
// validate*() functions field by field so the caller can reject only that field.
//
// A message is one UDP datagram: a sequence of packets, each [packet id u8][packet size u8]
// [size - 2 bytes of body]. The first packet of a host -> IG message must be IG Control (id 1)
// and the first packet of an IG -> host message Start of Frame (id 101); both carry the Byte
// Swap Magic 0x8000 at byte 6, written in the sender's byte order, so a receiver reading 0x0080
// knows every multi-byte field of the message is byte-swapped. Both orders are decoded and
// encoded. Layouts (byte offsets within a packet) are written next to each struct; they match
// the ICD and Wireshark's CIGI dissector (tests/cigi_tshark_test.py checks that).
//
// Decoded packets: IG Control (1), Entity Control (2), Celestial Sphere Control (9), Atmosphere
// Control (10), View Control (16), View Definition (21), HAT/HOT Request (24), LOS Segment Request (25), LOS Vector
// Request (26). Encoded besides: Start of Frame (101), HAT/HOT Response (102), HAT/HOT Extended
// Response (103), LOS Response (104), LOS Extended Response (105). Every other packet id is skipped by its size byte. A
// known id with a size other than its fixed size, a size below 2, or a packet running past the
// end of the datagram makes the whole message malformed.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

namespace ig::io::cigi {

constexpr uint8_t kMajorVersion = 3;
constexpr uint8_t kMinorVersion = 3;  // IG Control byte 4 / Start of Frame byte 5, high nibble
constexpr uint16_t kByteSwapMagic = 0x8000;

enum class PacketId : uint8_t {
  igControl = 1,
  entityControl = 2,
  celestialSphereControl = 9,
  atmosphereControl = 10,
  viewControl = 16,
  viewDefinition = 21,
  hatHotRequest = 24,
  losSegmentRequest = 25,
  losVectorRequest = 26,
  startOfFrame = 101,
  hatHotResponse = 102,
  hatHotExtendedResponse = 103,
  losResponse = 104,
  losExtendedResponse = 105,
};

// Fixed sizes (bytes, header included) of the packets igd decodes or encodes.
constexpr size_t kIgControlSize = 24;
constexpr size_t kEntityControlSize = 48;
constexpr size_t kCelestialSphereControlSize = 16;
constexpr size_t kAtmosphereControlSize = 32;
constexpr size_t kViewControlSize = 32;
constexpr size_t kViewDefinitionSize = 32;
constexpr size_t kStartOfFrameSize = 24;
constexpr size_t kHatHotRequestSize = 32;
constexpr size_t kHatHotResponseSize = 16;
constexpr size_t kHatHotExtendedResponseSize = 40;
constexpr size_t kLosSegmentRequestSize = 64;
constexpr size_t kLosVectorRequestSize = 56;
constexpr size_t kLosResponseSize = 16;
constexpr size_t kLosExtendedResponseSize = 56;

enum class ByteOrder : uint8_t { big, little };
// This machine's order: what an encoder writes with ByteOrder native.
ByteOrder nativeByteOrder();

enum class IgMode : uint8_t { standby = 0, operate = 1, debug = 2, offlineMaintenance = 3 };

// IG Control (id 1, 24 bytes), host -> IG, first packet of every host message.
//  0 id  1 size  2 major version (3)  3 database number (int8)
//  4 bits: 0-1 IG mode, 2 timestamp valid, 3 extrapolation/interpolation enable, 4-7 minor version
//  5 reserved  6-7 byte swap magic 0x8000  8-11 host frame number  12-15 timestamp (10 us ticks)
//  16-19 last IG frame number received  20-23 reserved
struct IgControl {
  uint8_t majorVersion = kMajorVersion;
  uint8_t minorVersion = kMinorVersion;
  int8_t databaseNumber = 0;  // 0: no change requested; > 0: database to load
  IgMode igMode = IgMode::operate;
  bool timestampValid = false;
  bool extrapolationEnable = false;
  uint32_t hostFrame = 0;
  uint32_t timestamp_10us = 0;  // host time in 10 us ticks (wraps after 11.9 h)
  uint32_t lastIgFrame = 0;     // the last Start of Frame's IG frame number the host received
};

// Entity Control (id 2, 48 bytes), host -> IG.
//  0 id  1 size  2-3 entity id
//  4 bits: 0-1 entity state, 2 attach state, 3 collision detection, 4 inherit alpha, 5-6 ground clamp
//  5 bits: 0 animation direction, 1 loop mode, 2-3 animation state, 4 extrapolation enable
//  6 alpha  7 reserved  8-9 entity type  10-11 parent id
//  12-15 roll (float32, deg)  16-19 pitch (deg)  20-23 yaw (deg)
//  24-31 latitude (float64, deg) or x offset (m)  32-39 longitude (deg) or y offset (m)
//  40-47 altitude (m; igd reads it as height above the WGS-84 ellipsoid, docs/cigi.md) or z offset (m)
struct EntityControl {
  uint16_t entityId = 0;
  uint8_t entityState = 1;    // 0 inactive/standby, 1 active, 2 destroyed
  bool attached = false;      // true: lat/lon/alt are x/y/z offsets from the parent (metres)
  uint8_t flags4 = 0;         // byte 4 bits 3-7 as received (collision, alpha, clamp)
  uint8_t animationFlags = 0; // byte 5 as received
  uint8_t alpha = 255;
  uint16_t entityType = 0;
  uint16_t parentId = 0;
  float roll_deg = 0;         // right side down positive, [-180, 180]
  float pitch_deg = 0;        // nose up positive, [-90, 90]
  float yaw_deg = 0;          // heading, clockwise from true north, [0, 360)
  double lat_deg = 0;         // [-90, 90]
  double lon_deg = 0;         // [-180, 180]
  double alt_m = 0;           // [-1e4, 1e6]
};

// Celestial Sphere Control (id 9, 16 bytes), host -> IG.
//  0 id  1 size  2 hour (UTC)  3 minute
//  4 bits: 0 ephemeris model enable, 1 sun, 2 moon, 3 star field, 4 date/time valid
//  5-7 reserved  8-11 date as the decimal number MMDDYYYY (u32)  12-15 star field intensity (float32, %)
struct CelestialSphereControl {
  uint8_t hour = 12;
  uint8_t minute = 0;
  bool ephemerisEnable = false;
  bool sunEnable = true;
  bool moonEnable = false;
  bool starFieldEnable = false;
  bool dateTimeValid = false;     // hour, minute and date apply only when set
  uint32_t date_mmddyyyy = 0;     // e.g. 6212026 = 21 June 2026
  float starIntensity_pct = 0;
};

// Atmosphere Control (id 10, 32 bytes), host -> IG: the global atmosphere (where no weather layer
// or region says otherwise). igd uses the visibility range (its fog); the rest is read and kept.
//  0 id  1 size  2 bits: 0 atmospheric model enable  3 global humidity (u8, %)
//  4-7 air temperature (float32, deg C)  8-11 visibility range (m)  12-15 horizontal wind (m/s)
//  16-19 vertical wind (m/s)  20-23 wind direction (deg, from true north)
//  24-27 barometric pressure (hPa)  28-31 reserved
struct AtmosphereControl {
  bool atmosphericModelEnable = false;
  uint8_t humidity_pct = 30;
  float airTemperature_c = 15.0f;
  float visibility_m = 20000.0f;  // >= 0 (igd clamps it to 1 m ... 1e7 m)
  float horizontalWind_mps = 0.0f;
  float verticalWind_mps = 0.0f;
  float windDirection_deg = 0.0f;
  float pressure_hpa = 1013.25f;
};

// View Control (id 16, 32 bytes), host -> IG: the view's eye relative to an entity.
//  0 id  1 size  2-3 view id  4 group id
//  5 bits: 0 x offset enable, 1 y, 2 z, 3 roll, 4 pitch, 5 yaw
//  6-7 entity id  8-11 x offset (float32, m)  12-15 y (m)  16-19 z (m)
//  20-23 roll (deg)  24-27 pitch (deg)  28-31 yaw (deg)
struct ViewControl {
  enum Enable : uint8_t { kX = 1, kY = 2, kZ = 4, kRoll = 8, kPitch = 16, kYaw = 32, kAll = 63 };
  uint16_t viewId = 0;
  uint8_t groupId = 0;
  uint8_t enable = kAll;      // which of the six offsets apply
  uint16_t entityId = 0;
  float x_m = 0;              // entity body axes: x forward, y right, z down
  float y_m = 0;
  float z_m = 0;
  float roll_deg = 0;
  float pitch_deg = 0;
  float yaw_deg = 0;
};

// View Definition (id 21, 32 bytes), host -> IG: the view's frustum.
//  0 id  1 size  2-3 view id  4 group id
//  5 bits: 0 near enable, 1 far, 2 left, 3 right, 4 top, 5 bottom, 6-7 mirror mode
//  6 bits: 0-2 pixel replication, 3 projection type (0 perspective), 4 reorder, 5-7 view type
//  7 reserved  8-11 near (float32, m)  12-15 far (m)  16-19 left (deg)  20-23 right (deg)
//  24-27 top (deg)  28-31 bottom (deg)
struct ViewDefinition {
  enum Enable : uint8_t { kNear = 1, kFar = 2, kLeft = 4, kRight = 8, kTop = 16, kBottom = 32, kAll = 63 };
  uint16_t viewId = 0;
  uint8_t groupId = 0;
  uint8_t enable = kAll;
  uint8_t mirrorMode = 0;
  uint8_t pixelReplication = 0;
  bool orthographic = false;
  bool reorder = false;
  uint8_t viewType = 0;
  float near_m = 0.1f;
  float far_m = 100000.0f;
  float left_deg = -30.0f;    // half-angles from the view direction; left and bottom negative
  float right_deg = 30.0f;
  float top_deg = 22.5f;
  float bottom_deg = -22.5f;
};

// Start of Frame (id 101, 24 bytes, CIGI 3.2/3.3 layout), IG -> host, first packet of every
// IG message.
//  0 id  1 size  2 major version (3)  3 database number (int8)  4 IG status code
//  5 bits: 0-1 IG mode, 2 timestamp valid, 3 earth reference model (0 WGS-84), 4-7 minor version
//  6-7 byte swap magic 0x8000  8-11 IG frame number  12-15 timestamp (10 us ticks)
//  16-19 last host frame number received  20-23 reserved
struct StartOfFrame {
  uint8_t majorVersion = kMajorVersion;
  uint8_t minorVersion = kMinorVersion;
  int8_t databaseNumber = 0;
  uint8_t igStatus = 0;       // 0 normal; igd's codes in docs/cigi.md
  IgMode igMode = IgMode::operate;
  bool timestampValid = true;
  bool hostDefinedEarthModel = false;  // false: WGS-84
  uint32_t igFrame = 0;
  uint32_t timestamp_10us = 0;
  uint32_t lastHostFrame = 0;
};

// HAT/HOT Request (id 24, 32 bytes), host -> IG: the height of terrain (HOT) under a point,
// and the point's height above it (HAT = altitude - HOT).
//  0 id  1 size  2-3 HAT/HOT ID
//  4 bits: 0-1 request type (0 HAT, 1 HOT, 2 extended), 2 coordinate system (0 geodetic,
//    1 entity), 3-7 reserved
//  5 update period (u8, IG frames; 0 = answer once)  6-7 entity id (entity coordinates only)
//  8-15 latitude (float64, deg) or x offset (m)  16-23 longitude (deg) or y offset (m)
//  24-31 altitude (m, ignored for HOT) or z offset (m)
struct HatHotRequest {
  enum Type : uint8_t { kHat = 0, kHot = 1, kExtended = 2 };  // 3 is undefined
  uint16_t hatHotId = 0;
  uint8_t requestType = kHot;     // 2 bits as received: a Type, or 3 (answered Valid = false)
  bool entityCoordinates = false; // true: x/y/z are offsets in the entity's body axes (x forward,
                                  //   y right, z down, metres) from the entity's reference point
  uint8_t updatePeriod = 0;       // 0: answer once; n: answer every n-th IG frame until cancelled
  uint16_t entityId = 0;
  double lat_deg = 0;             // or x offset (m)
  double lon_deg = 0;             // or y offset (m)
  double alt_m = 0;               // or z offset (m)
};

// HAT/HOT Response (id 102, 16 bytes), IG -> host: the answer to a HAT or HOT request.
//  0 id  1 size  2-3 HAT/HOT ID
//  4 bits: 0 valid, 1 response type (0 HAT, 1 HOT), 2-3 reserved, 4-7 host frame number LSN
//  5-7 reserved  8-15 height (float64, m): HAT or HOT
struct HatHotResponse {
  uint16_t hatHotId = 0;
  bool valid = false;
  bool hot = false;               // false: height is the HAT; true: the HOT
  uint8_t hostFrameLsn = 0;       // low 4 bits of the last host frame number received
  double height_m = 0;
};

// HAT/HOT Extended Response (id 103, 40 bytes), IG -> host: the answer to an extended request.
//  0 id  1 size  2-3 HAT/HOT ID
//  4 bits: 0 valid, 1-3 reserved, 4-7 host frame number LSN  5-7 reserved
//  8-15 HAT (float64, m)  16-23 HOT (float64, m)  24-27 material code (u32)
//  28-31 normal vector azimuth (float32, deg from true north, clockwise, [-180, 180])
//  32-35 normal vector elevation (float32, deg above the local horizontal, [-90, 90])  36-39 reserved
struct HatHotExtendedResponse {
  uint16_t hatHotId = 0;
  bool valid = false;
  uint8_t hostFrameLsn = 0;
  double hat_m = 0;
  double hot_m = 0;
  uint32_t materialCode = 0;
  float normalAzimuth_deg = 0;
  float normalElevation_deg = 90;
};

// LOS Segment Request (id 25, 64 bytes) and LOS Vector Request (id 26, 56 bytes), host -> IG:
// the first intersection of a segment (source -> destination) or of a vector (source, azimuth,
// elevation, between a minimum and a maximum range) with the terrain. One struct for both.
// Segment:
//  0 id  1 size  2-3 LOS ID
//  4 bits: 0 request type (0 basic, 1 extended), 1 source point coordinate system (0 geodetic,
//    1 entity), 2 destination point coordinate system, 3 response coordinate system,
//    4 destination entity ID valid, 5-7 reserved
//  5 alpha threshold (u8)  6-7 entity id (entity coordinates)
//  8-15 source latitude (float64, deg) or x offset (m)  16-23 source longitude or y offset
//  24-31 source altitude (m) or z offset  32-39 destination latitude or x offset
//  40-47 destination longitude or y offset  48-55 destination altitude or z offset
//  56-59 material mask (u32)  60 update period (u8)  61 reserved  62-63 destination entity id
// Vector:
//  0 id  1 size  2-3 LOS ID
//  4 bits: 0 request type, 1 source point coordinate system, 2 response coordinate system,
//    3-7 reserved
//  5 alpha threshold  6-7 entity id  8-11 azimuth (float32, deg from true north, clockwise)
//  12-15 elevation (float32, deg above the local horizontal)  16-19 minimum range (float32, m)
//  20-23 maximum range (m)  24-31 source latitude or x offset  32-39 source longitude or y offset
//  40-47 source altitude or z offset  48-51 material mask  52 update period  53-55 reserved
struct LosRequest {
  enum Kind : uint8_t { kSegment = 0, kVector = 1 };
  Kind kind = kSegment;
  uint16_t losId = 0;
  bool extended = false;          // request type: false basic (LOS Response), true extended
  bool sourceEntity = false;      // source x/y/z are offsets in the entity's body axes (x forward,
                                  //   y right, z down, metres) from the entity's reference point
  bool destinationEntity = false; // segment: the same for the destination point
  bool responseEntity = false;    // extended response's point as entity offsets, not lat/lon/alt
  bool destinationEntityIdValid = false;  // segment
  uint8_t alphaThreshold = 0;
  uint16_t entityId = 0;
  uint8_t updatePeriod = 0;       // 0: answer once; n: answer every n-th IG frame until cancelled
  uint32_t materialMask = 0;      // bit n: register hits with material code n (igd: 0 terrain, 1 object, 2 tree); 0: all
  double srcLat_deg = 0;          // or x offset (m)
  double srcLon_deg = 0;          // or y offset (m)
  double srcAlt_m = 0;            // or z offset (m)
  double dstLat_deg = 0;          // segment: destination (or x/y/z offsets)
  double dstLon_deg = 0;
  double dstAlt_m = 0;
  uint16_t destinationEntityId = 0;  // segment
  float azimuth_deg = 0;          // vector
  float elevation_deg = 0;
  float minRange_m = 0;
  float maxRange_m = 0;
};

// LOS Response (id 104, 16 bytes), IG -> host: the answer to a basic LOS request.
//  0 id  1 size  2-3 LOS ID
//  4 bits: 0 valid, 1 entity ID valid, 2 visible, 3 reserved, 4-7 host frame number LSN
//  5 response count  6-7 entity id  8-15 range (float64, m)
struct LosResponse {
  uint16_t losId = 0;
  bool valid = false;             // an intersection was found
  bool entityIdValid = false;     // the intersection is with an entity (igd: never, terrain only)
  bool visible = false;           // segment: nothing between source and destination
  uint8_t hostFrameLsn = 0;
  uint8_t responseCount = 1;      // responses sent for this request (igd: always 1)
  uint16_t entityId = 0;
  double range_m = 0;             // from the source point to the intersection
};

// LOS Extended Response (id 105, 56 bytes), IG -> host: the answer to an extended LOS request.
//  0 id  1 size  2-3 LOS ID
//  4 bits: 0 valid, 1 entity ID valid, 2 range valid, 3 visible, 4-7 host frame number LSN
//  5 response count  6-7 entity id  8-15 range (float64, m)
//  16-23 latitude (float64, deg) or x offset (m)  24-31 longitude or y offset
//  32-39 altitude (m) or z offset  40 red  41 green  42 blue  43 alpha  44-47 material code (u32)
//  48-51 normal vector azimuth (float32, deg)  52-55 normal vector elevation (float32, deg)
struct LosExtendedResponse {
  uint16_t losId = 0;
  bool valid = false;
  bool entityIdValid = false;
  bool rangeValid = false;
  bool visible = false;
  uint8_t hostFrameLsn = 0;
  uint8_t responseCount = 1;
  uint16_t entityId = 0;
  double range_m = 0;
  double lat_deg = 0;             // or x offset (m), as the request's response coordinate system
  double lon_deg = 0;             // or y offset (m)
  double alt_m = 0;               // or z offset (m)
  uint8_t red = 0, green = 0, blue = 0, alpha = 0;
  uint32_t materialCode = 0;
  float normalAzimuth_deg = 0;
  float normalElevation_deg = 90;
};

enum class CigiStatus : uint8_t {
  ok,
  empty,              // zero bytes
  firstNotControl,    // the first packet is not IG Control (host message) / Start of Frame
  badVersion,         // major version byte is not 3
  badMagic,           // byte swap magic is neither 0x8000 nor 0x0080
  badPacketSize,      // size < 2, or the fixed size of a known packet id differs
  packetOverrun,      // a packet runs past the end of the datagram (includes a lone byte)
  secondControl,      // a second IG Control / Start of Frame inside one message
};
const char* toString(CigiStatus s);

// A decoded host -> IG message. Fixed capacity, no allocation: decode into a caller-owned
// instance (it is a few KiB; keep one per receiver, not on a small stack).
struct HostMessage {
  static constexpr size_t kMaxEntities = 32;
  static constexpr size_t kMaxViews = 8;
  ByteOrder byteOrder = ByteOrder::big;
  IgControl igControl;
  std::array<EntityControl, kMaxEntities> entities;
  size_t entityCount = 0;
  std::array<ViewControl, kMaxViews> viewControls;
  size_t viewControlCount = 0;
  std::array<ViewDefinition, kMaxViews> viewDefinitions;
  size_t viewDefinitionCount = 0;
  bool hasCelestial = false;             // the last Celestial Sphere Control of the message
  CelestialSphereControl celestial;
  bool hasAtmosphere = false;            // the last Atmosphere Control of the message
  AtmosphereControl atmosphere;
  // HAT/HOT Requests in message order (all kept, whatever the filter), up to capacity.
  static constexpr size_t kMaxHatHotRequests = 32;
  std::array<HatHotRequest, kMaxHatHotRequests> hatHotRequests;
  size_t hatHotCount = 0;
  uint32_t hatHotOmitted = 0;            // HAT/HOT Requests beyond capacity (also in omittedPackets)
  // LOS Segment and Vector Requests in message order, up to capacity.
  static constexpr size_t kMaxLosRequests = 32;
  std::array<LosRequest, kMaxLosRequests> losRequests;
  size_t losCount = 0;
  uint32_t losOmitted = 0;               // LOS Requests beyond capacity (also in omittedPackets)
  uint32_t unknownPackets = 0;           // packets skipped by their size (other ids)
  uint32_t omittedPackets = 0;           // known packets not kept: filtered out or over capacity
};

// Keeps only the packets a receiver uses, so a message with many entities never loses the
// one that matters to capacity. -1 keeps all (up to capacity).
struct HostMessageFilter {
  int entityId = -1;  // Entity Control with this entity id
  int viewId = -1;    // View Control / View Definition with this view id
};

// Decodes one host -> IG datagram. On any status but ok, `out` holds partial garbage: do not
// use it. Allocation-free; O(bytes).
CigiStatus decodeHostMessage(std::span<const std::byte> bytes, HostMessage& out,
                             const HostMessageFilter& filter = {});
// Decodes one IG -> host datagram's leading Start of Frame (the rest is checked for framing
// only: packet sizes and bounds).
CigiStatus decodeStartOfFrame(std::span<const std::byte> bytes, StartOfFrame& out, ByteOrder* order = nullptr);

// Encoders: each writes one packet of its fixed size into `out` (which must hold at least that
// many bytes; asserts otherwise) in the given byte order and returns the bytes written.
size_t encode(const IgControl& p, ByteOrder order, std::span<std::byte> out);
size_t encode(const EntityControl& p, ByteOrder order, std::span<std::byte> out);
size_t encode(const CelestialSphereControl& p, ByteOrder order, std::span<std::byte> out);
size_t encode(const AtmosphereControl& p, ByteOrder order, std::span<std::byte> out);
size_t encode(const ViewControl& p, ByteOrder order, std::span<std::byte> out);
size_t encode(const ViewDefinition& p, ByteOrder order, std::span<std::byte> out);
size_t encode(const StartOfFrame& p, ByteOrder order, std::span<std::byte> out);
size_t encode(const HatHotRequest& p, ByteOrder order, std::span<std::byte> out);
size_t encode(const HatHotResponse& p, ByteOrder order, std::span<std::byte> out);
size_t encode(const HatHotExtendedResponse& p, ByteOrder order, std::span<std::byte> out);
// A LOS Segment Request (kind kSegment, 64 bytes) or a LOS Vector Request (kVector, 56 bytes).
size_t encode(const LosRequest& p, ByteOrder order, std::span<std::byte> out);
size_t encode(const LosResponse& p, ByteOrder order, std::span<std::byte> out);
size_t encode(const LosExtendedResponse& p, ByteOrder order, std::span<std::byte> out);

// Reads one HAT/HOT response packet (id and size checked; false otherwise) in the given byte
// order (the order of the message's Start of Frame). For hosts and tests.
bool decodePacket(std::span<const std::byte> packet, ByteOrder order, HatHotResponse& out);
bool decodePacket(std::span<const std::byte> packet, ByteOrder order, HatHotExtendedResponse& out);
bool decodePacket(std::span<const std::byte> packet, ByteOrder order, LosResponse& out);
bool decodePacket(std::span<const std::byte> packet, ByteOrder order, LosExtendedResponse& out);

// Field validation, one bit per field that is NaN, infinite or out of range (0 = all good).
// Ranges: docs/cigi.md.
enum EntityField : uint32_t { kEntityRoll = 1, kEntityPitch = 2, kEntityYaw = 4, kEntityLat = 8, kEntityLon = 16, kEntityAlt = 32 };
uint32_t validateEntity(const EntityControl& p);
enum ViewControlField : uint32_t { kViewX = 1, kViewY = 2, kViewZ = 4, kViewRoll = 8, kViewPitch = 16, kViewYaw = 32 };
uint32_t validateViewControl(const ViewControl& p);
// Each enabled field on its own: near and far finite, > 0 and <= 1e8 m; left, right, top, bottom
// finite in [-90, 90] deg. Pairs (0 < near < far, 0 < top - bottom < 180) are the receiver's
// check, since a disabled field keeps the receiver's current value.
enum ViewDefinitionField : uint32_t { kViewNear = 1, kViewFar = 2, kViewLeft = 4, kViewRight = 8, kViewTop = 16, kViewBottom = 32 };
uint32_t validateViewDefinition(const ViewDefinition& p);
// kCelestialTime: hour >= 24 or minute >= 60; kCelestialDate: not a real MMDDYYYY date.
enum CelestialField : uint32_t { kCelestialTime = 1, kCelestialDate = 2, kCelestialStars = 4 };
uint32_t validateCelestial(const CelestialSphereControl& p);
// kAtmosphereVisibility: the visibility range NaN or negative (the others are not checked: igd
// does not use them). 0 and +infinity are valid: the receiver clamps (io/cigi_link.h).
enum AtmosphereField : uint32_t { kAtmosphereVisibility = 1 };
uint32_t validateAtmosphere(const AtmosphereControl& p);
// kHatHotType: request type 3. Geodetic: latitude in [-90, 90], longitude in [-180, 180],
// altitude in [-1e4, 1e6] m (not checked for HOT, which ignores it). Entity: each offset finite
// with abs <= 1e5 m. NaN and infinities always fail.
enum HatHotField : uint32_t { kHatHotType = 1, kHatHotLatX = 2, kHatHotLonY = 4, kHatHotAltZ = 8 };
uint32_t validateHatHotRequest(const HatHotRequest& p);
// LOS: source and (segment) destination points as HAT/HOT's (geodetic: latitude [-90, 90],
// longitude [-180, 180], altitude [-1e4, 1e6] m; entity: offsets finite, abs <= 1e5 m).
// Vector: azimuth in [-360, 360] deg, elevation in [-90, 90] deg, minimum range in [0, 1e6] m,
// maximum range in [minimum, 1e6] m (a bad maximum range sets kLosMaxRange only).
enum LosField : uint32_t {
  kLosSrcLatX = 1, kLosSrcLonY = 2, kLosSrcAltZ = 4, kLosDstLatX = 8, kLosDstLonY = 16, kLosDstAltZ = 32,
  kLosAzimuth = 64, kLosElevation = 128, kLosMinRange = 256, kLosMaxRange = 512
};
uint32_t validateLosRequest(const LosRequest& p);

// MMDDYYYY -> YYYYMMDD (no validation).
inline int32_t dateToYmd(uint32_t mmddyyyy) {
  const uint32_t month = mmddyyyy / 1000000u, day = (mmddyyyy / 10000u) % 100u, year = mmddyyyy % 10000u;
  return static_cast<int32_t>(year * 10000u + month * 100u + day);
}

}  // namespace ig::io::cigi
