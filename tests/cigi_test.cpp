// CIGI 3.3 codec, assembler and pcap converter: round trips in both byte orders, hand-checked
// byte layouts, every truncation, bad sizes / magic / order, unknown packets, field-by-field
// rejection, the eyepoint and attitude conventions, late / restart handling, and captures in
// every supported link type.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "io/cigi.h"
#include "io/cigi_link.h"
#include "io/pcap.h"

using namespace ig::io;
using namespace ig::io::cigi;

namespace {

using Bytes = std::vector<std::byte>;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

template <class P>
void append(Bytes& b, const P& p, ByteOrder order) {
  std::byte tmp[256];
  const size_t n = encode(p, order, tmp);
  b.insert(b.end(), tmp, tmp + n);
}

void appendUnknown(Bytes& b, uint8_t id, uint8_t size) {
  b.push_back(std::byte{id});
  b.push_back(std::byte{size});
  for (int i = 2; i < size; ++i) b.push_back(std::byte{static_cast<uint8_t>(0xA0 + i)});
}

struct Sample {
  IgControl ig;
  EntityControl entity;
  ViewControl view;
  ViewDefinition def;
  CelestialSphereControl sky;
  Sample() {
    ig.databaseNumber = 7;
    ig.igMode = IgMode::operate;
    ig.timestampValid = true;
    ig.hostFrame = 0x01020304;
    ig.timestamp_10us = 123456789;
    ig.lastIgFrame = 4242;
    entity.entityId = 0;
    entity.entityType = 1001;
    entity.alpha = 200;
    entity.roll_deg = -12.5f;
    entity.pitch_deg = 3.25f;
    entity.yaw_deg = 271.75f;
    entity.lat_deg = 57.70887345;
    entity.lon_deg = 11.97456123;
    entity.alt_m = 1523.375;
    view.viewId = 0;
    view.entityId = 0;
    view.x_m = 2.5f;
    view.y_m = -0.5f;
    view.z_m = -1.25f;
    view.roll_deg = 1.0f;
    view.pitch_deg = -2.0f;
    view.yaw_deg = 3.0f;
    def.viewId = 0;
    def.near_m = 0.5f;
    def.far_m = 40000.0f;
    def.left_deg = -40.0f;
    def.right_deg = 40.0f;
    def.top_deg = 25.0f;
    def.bottom_deg = -20.0f;
    sky.hour = 14;
    sky.minute = 30;
    sky.dateTimeValid = true;
    sky.sunEnable = true;
    sky.date_mmddyyyy = 6212026;
    sky.starIntensity_pct = 40.0f;
  }
  Bytes bytes(ByteOrder order, bool unknown = false) const {
    Bytes b;
    append(b, ig, order);
    append(b, entity, order);
    if (unknown) appendUnknown(b, 200, 12);
    append(b, view, order);
    append(b, def, order);
    append(b, sky, order);
    return b;
  }
};

HostMessage& scratch() {
  static auto m = std::make_unique<HostMessage>();
  return *m;
}

CigiStatus decode(const Bytes& b) { return decodeHostMessage(b, scratch()); }

uint8_t at(const Bytes& b, size_t i) { return std::to_integer<uint8_t>(b[i]); }

}  // namespace

TEST(CigiCodec, RoundTripBothByteOrders) {
  const Sample s;
  for (ByteOrder order : {ByteOrder::big, ByteOrder::little}) {
    SCOPED_TRACE(order == ByteOrder::big ? "big" : "little");
    const Bytes b = s.bytes(order);
    ASSERT_EQ(b.size(), 24u + 48u + 32u + 32u + 16u);
    HostMessage& m = scratch();
    ASSERT_EQ(decodeHostMessage(b, m), CigiStatus::ok);
    EXPECT_EQ(m.byteOrder, order);
    EXPECT_EQ(m.igControl.majorVersion, 3);
    EXPECT_EQ(m.igControl.minorVersion, 3);
    EXPECT_EQ(m.igControl.databaseNumber, 7);
    EXPECT_EQ(m.igControl.igMode, IgMode::operate);
    EXPECT_TRUE(m.igControl.timestampValid);
    EXPECT_EQ(m.igControl.hostFrame, 0x01020304u);
    EXPECT_EQ(m.igControl.timestamp_10us, 123456789u);
    EXPECT_EQ(m.igControl.lastIgFrame, 4242u);
    ASSERT_EQ(m.entityCount, 1u);
    const EntityControl& e = m.entities[0];
    EXPECT_EQ(e.entityType, 1001);
    EXPECT_EQ(e.alpha, 200);
    EXPECT_EQ(e.roll_deg, -12.5f);
    EXPECT_EQ(e.pitch_deg, 3.25f);
    EXPECT_EQ(e.yaw_deg, 271.75f);
    EXPECT_EQ(e.lat_deg, 57.70887345);
    EXPECT_EQ(e.lon_deg, 11.97456123);
    EXPECT_EQ(e.alt_m, 1523.375);
    ASSERT_EQ(m.viewControlCount, 1u);
    EXPECT_EQ(m.viewControls[0].x_m, 2.5f);
    EXPECT_EQ(m.viewControls[0].z_m, -1.25f);
    EXPECT_EQ(m.viewControls[0].yaw_deg, 3.0f);
    EXPECT_EQ(m.viewControls[0].enable, ViewControl::kAll);
    ASSERT_EQ(m.viewDefinitionCount, 1u);
    EXPECT_EQ(m.viewDefinitions[0].near_m, 0.5f);
    EXPECT_EQ(m.viewDefinitions[0].far_m, 40000.0f);
    EXPECT_EQ(m.viewDefinitions[0].top_deg, 25.0f);
    EXPECT_EQ(m.viewDefinitions[0].bottom_deg, -20.0f);
    ASSERT_TRUE(m.hasCelestial);
    EXPECT_EQ(m.celestial.hour, 14);
    EXPECT_EQ(m.celestial.minute, 30);
    EXPECT_TRUE(m.celestial.dateTimeValid);
    EXPECT_EQ(m.celestial.date_mmddyyyy, 6212026u);
    EXPECT_EQ(m.celestial.starIntensity_pct, 40.0f);
    EXPECT_EQ(m.unknownPackets, 0u);
  }
}

TEST(CigiCodec, ByteLayoutMatchesTheStandard) {
  const Sample s;
  const Bytes be = s.bytes(ByteOrder::big), le = s.bytes(ByteOrder::little);
  // IG Control: id 1, size 24, version 3, database 7, mode operate | timestamp valid | minor 3.
  EXPECT_EQ(at(be, 0), 1);
  EXPECT_EQ(at(be, 1), 24);
  EXPECT_EQ(at(be, 2), 3);
  EXPECT_EQ(at(be, 3), 7);
  EXPECT_EQ(at(be, 4), 0x01 | 0x04 | 0x30);
  // Magic 0x8000 in the sender's order.
  EXPECT_EQ(at(be, 6), 0x80);
  EXPECT_EQ(at(be, 7), 0x00);
  EXPECT_EQ(at(le, 6), 0x00);
  EXPECT_EQ(at(le, 7), 0x80);
  // Host frame 0x01020304 at 8..11.
  EXPECT_EQ(at(be, 8), 1);
  EXPECT_EQ(at(be, 11), 4);
  EXPECT_EQ(at(le, 8), 4);
  EXPECT_EQ(at(le, 11), 1);
  // Entity Control at 24: id 2, size 48; yaw float at +20; lat double at +24.
  EXPECT_EQ(at(be, 24), 2);
  EXPECT_EQ(at(be, 25), 48);
  float yaw;
  uint32_t yawBits = (uint32_t{at(be, 44)} << 24) | (uint32_t{at(be, 45)} << 16) | (uint32_t{at(be, 46)} << 8) | at(be, 47);
  std::memcpy(&yaw, &yawBits, 4);
  EXPECT_EQ(yaw, 271.75f);
  uint64_t latBits = 0;
  for (int i = 0; i < 8; ++i) latBits = (latBits << 8) | at(be, 48 + i);
  double lat;
  std::memcpy(&lat, &latBits, 8);
  EXPECT_EQ(lat, 57.70887345);
  // View Control at 72 (id 16, 32 bytes), View Definition at 104 (id 21), Celestial at 136 (id 9).
  EXPECT_EQ(at(be, 72), 16);
  EXPECT_EQ(at(be, 73), 32);
  EXPECT_EQ(at(be, 77), 0x3f);
  EXPECT_EQ(at(be, 104), 21);
  EXPECT_EQ(at(be, 105), 32);
  EXPECT_EQ(at(be, 136), 9);
  EXPECT_EQ(at(be, 137), 16);
  EXPECT_EQ(at(be, 138), 14);
  EXPECT_EQ(at(be, 139), 30);
  EXPECT_EQ(at(be, 140), 0x02 | 0x10);
  // Date 6212026 = 0x005ec9ba big-endian at +8.
  EXPECT_EQ(at(be, 144), 0x00);
  EXPECT_EQ(at(be, 145), 0x5e);
  EXPECT_EQ(at(be, 146), 0xc9);
  EXPECT_EQ(at(be, 147), 0xba);
}

TEST(CigiCodec, StartOfFrameRoundTripAndLayout) {
  StartOfFrame sof;
  sof.databaseNumber = -3;
  sof.igStatus = 1;
  sof.igMode = IgMode::standby;
  sof.igFrame = 0x0a0b0c0d;
  sof.timestamp_10us = 99;
  sof.lastHostFrame = 77;
  for (ByteOrder order : {ByteOrder::big, ByteOrder::little}) {
    Bytes b;
    append(b, sof, order);
    ASSERT_EQ(b.size(), 24u);
    EXPECT_EQ(at(b, 0), 101);
    EXPECT_EQ(at(b, 1), 24);
    EXPECT_EQ(at(b, 2), 3);
    EXPECT_EQ(at(b, 3), 0xfd);
    EXPECT_EQ(at(b, 4), 1);
    EXPECT_EQ(at(b, 5), 0x00 | 0x04 | 0x30);
    EXPECT_EQ(at(b, 8), order == ByteOrder::big ? 0x0a : 0x0d);
    StartOfFrame d;
    ByteOrder got;
    ASSERT_EQ(decodeStartOfFrame(b, d, &got), CigiStatus::ok);
    EXPECT_EQ(got, order);
    EXPECT_EQ(d.databaseNumber, -3);
    EXPECT_EQ(d.igStatus, 1);
    EXPECT_EQ(d.igMode, IgMode::standby);
    EXPECT_TRUE(d.timestampValid);
    EXPECT_EQ(d.minorVersion, 3);
    EXPECT_EQ(d.igFrame, 0x0a0b0c0du);
    EXPECT_EQ(d.timestamp_10us, 99u);
    EXPECT_EQ(d.lastHostFrame, 77u);
    for (size_t n = 0; n < b.size(); ++n)
      EXPECT_NE(decodeStartOfFrame(std::span(b.data(), n), d), CigiStatus::ok) << n;
  }
}

TEST(CigiCodec, EveryTruncationInsideAPacketIsRejected) {
  const Sample s;
  for (ByteOrder order : {ByteOrder::big, ByteOrder::little}) {
    const Bytes full = s.bytes(order, /*unknown=*/true);
    const size_t boundaries[] = {24, 72, 84, 116, 148, 164};
    ASSERT_EQ(full.size(), 164u);
    size_t rejected = 0;
    for (size_t n = 0; n < full.size(); ++n) {
      const Bytes cut(full.begin(), full.begin() + static_cast<long>(n));
      const bool boundary = std::find(std::begin(boundaries), std::end(boundaries), n) != std::end(boundaries);
      const CigiStatus st = decode(cut);
      if (boundary) {
        // A cut between packets is a shorter but well-formed message.
        EXPECT_EQ(st, CigiStatus::ok) << n;
      } else {
        EXPECT_NE(st, CigiStatus::ok) << "length " << n;
        ++rejected;
      }
    }
    EXPECT_EQ(rejected, full.size() - 5);  // all but the 5 boundaries below the full length
    EXPECT_EQ(decode(full), CigiStatus::ok);
  }
}

TEST(CigiCodec, WrongSizesBadMagicBadVersionAndOrder) {
  const Sample s;
  const Bytes good = s.bytes(ByteOrder::big, true);
  ASSERT_EQ(decode(good), CigiStatus::ok);
  // The size byte of every packet (IG Control 0, Entity 24, unknown 72, View 84, ViewDef 116, Sky 148).
  for (size_t off : {0, 24, 84, 116, 148}) {
    for (int delta : {-1, 1, -8, 8}) {
      Bytes b = good;
      b[off + 1] = std::byte{static_cast<uint8_t>(at(b, off + 1) + delta)};
      EXPECT_NE(decode(b), CigiStatus::ok) << off << " " << delta;
    }
    for (int size : {0, 1}) {
      Bytes b = good;
      b[off + 1] = std::byte{static_cast<uint8_t>(size)};
      EXPECT_NE(decode(b), CigiStatus::ok) << off << " size " << int(size);
    }
  }
  {
    Bytes b = good;  // unknown packet claiming more than is left
    b[73] = std::byte{250};
    EXPECT_EQ(decode(b), CigiStatus::packetOverrun);
    b[73] = std::byte{0};
    EXPECT_EQ(decode(b), CigiStatus::badPacketSize);
  }
  {
    Bytes b = good;
    b[6] = std::byte{0x12};
    b[7] = std::byte{0x34};
    EXPECT_EQ(decode(b), CigiStatus::badMagic);
    b[6] = std::byte{0x00};
    b[7] = std::byte{0x00};
    EXPECT_EQ(decode(b), CigiStatus::badMagic);
  }
  {
    Bytes b = good;
    b[2] = std::byte{2};
    EXPECT_EQ(decode(b), CigiStatus::badVersion);
  }
  {
    Bytes b;  // Entity Control first
    append(b, s.entity, ByteOrder::big);
    append(b, s.ig, ByteOrder::big);
    EXPECT_EQ(decode(b), CigiStatus::firstNotControl);
    Bytes two;  // two IG Controls
    append(two, s.ig, ByteOrder::big);
    append(two, s.ig, ByteOrder::big);
    EXPECT_EQ(decode(two), CigiStatus::secondControl);
    Bytes sof;  // a Start of Frame is not a host message
    append(sof, StartOfFrame{}, ByteOrder::big);
    EXPECT_EQ(decode(sof), CigiStatus::firstNotControl);
  }
  EXPECT_EQ(decode({}), CigiStatus::empty);
  Bytes lone = good;  // one stray byte after the last packet
  lone.push_back(std::byte{2});
  EXPECT_EQ(decode(lone), CigiStatus::packetOverrun);
  // A little-endian magic in a big-endian message: every field is then read swapped, sizes
  // are single bytes and still valid, so the message decodes with swapped values.
  Bytes swapped = good;
  std::swap(swapped[6], swapped[7]);
  ASSERT_EQ(decode(swapped), CigiStatus::ok);
  EXPECT_EQ(scratch().igControl.hostFrame, 0x04030201u);
}

TEST(CigiCodec, UnknownPacketsAreSkippedBySize) {
  const Sample s;
  Bytes b;
  append(b, s.ig, ByteOrder::little);
  appendUnknown(b, 200, 12);
  appendUnknown(b, 3, 32);    // Component Control: not decoded by igd
  appendUnknown(b, 77, 2);    // header only
  append(b, s.entity, ByteOrder::little);
  appendUnknown(b, 255, 255);
  HostMessage& m = scratch();
  ASSERT_EQ(decodeHostMessage(b, m), CigiStatus::ok);
  EXPECT_EQ(m.unknownPackets, 4u);
  ASSERT_EQ(m.entityCount, 1u);
  EXPECT_EQ(m.entities[0].lat_deg, s.entity.lat_deg);
  EXPECT_EQ(m.entities[0].yaw_deg, s.entity.yaw_deg);
}

TEST(CigiCodec, FilterKeepsTheOwnshipAmongManyEntities) {
  const Sample s;
  Bytes b;
  append(b, s.ig, ByteOrder::big);
  for (uint16_t id = 1; id <= 60; ++id) {
    EntityControl e = s.entity;
    e.entityId = id;
    e.lat_deg = id;
    append(b, e, ByteOrder::big);
  }
  HostMessage& m = scratch();
  ASSERT_EQ(decodeHostMessage(b, m), CigiStatus::ok);
  EXPECT_EQ(m.entityCount, HostMessage::kMaxEntities);
  EXPECT_EQ(m.omittedPackets, 60u - HostMessage::kMaxEntities);
  HostMessageFilter f;
  f.entityId = 47;
  ASSERT_EQ(decodeHostMessage(b, m, f), CigiStatus::ok);
  ASSERT_EQ(m.entityCount, 1u);
  EXPECT_EQ(m.entities[0].lat_deg, 47.0);
  EXPECT_EQ(m.omittedPackets, 59u);
}

TEST(CigiCodec, FieldValidation) {
  EntityControl e;
  e.yaw_deg = 359.99f;
  e.roll_deg = 180.0f;
  e.pitch_deg = -90.0f;
  e.lat_deg = 90.0;
  e.lon_deg = -180.0;
  e.alt_m = -1.0e4;
  EXPECT_EQ(validateEntity(e), 0u);
  e.yaw_deg = 360.0f;
  EXPECT_EQ(validateEntity(e), kEntityYaw);
  e.yaw_deg = -0.5f;
  EXPECT_EQ(validateEntity(e), kEntityYaw);
  e.yaw_deg = 0.0f;
  e.roll_deg = 180.5f;
  e.pitch_deg = std::numeric_limits<float>::infinity();
  e.lat_deg = kNaN;
  e.lon_deg = 180.001;
  e.alt_m = 1.1e6;
  EXPECT_EQ(validateEntity(e), kEntityRoll | kEntityPitch | kEntityLat | kEntityLon | kEntityAlt);

  ViewDefinition d;
  EXPECT_EQ(validateViewDefinition(d), 0u);
  d.near_m = 0.0f;
  d.far_m = std::numeric_limits<float>::quiet_NaN();
  d.top_deg = 91.0f;
  EXPECT_EQ(validateViewDefinition(d), kViewNear | kViewFar | kViewTop);
  d.enable = ViewDefinition::kLeft;  // disabled fields are not checked
  EXPECT_EQ(validateViewDefinition(d), 0u);

  CelestialSphereControl c;
  c.date_mmddyyyy = 2292024;  // 29 Feb 2024
  EXPECT_EQ(validateCelestial(c), 0u);
  c.date_mmddyyyy = 2292023;
  EXPECT_EQ(validateCelestial(c), kCelestialDate);
  c.date_mmddyyyy = 13012024;
  c.hour = 24;
  EXPECT_EQ(validateCelestial(c), kCelestialDate | kCelestialTime);
  EXPECT_EQ(dateToYmd(6212026), 20260621);
}

// ---------------------------------------------------------------------------------------------
// Assembler

namespace {
const ig::lod::Geodetic kOrigin{57.7, 11.97, 100.0};

struct Host {
  Sample s;
  uint32_t frame = 100;
  Bytes message(ByteOrder order = ByteOrder::big, bool view = false, bool def = false, bool sky = false) {
    s.ig.hostFrame = frame++;
    Bytes b;
    append(b, s.ig, order);
    append(b, s.entity, order);
    if (view) append(b, s.view, order);
    if (def) append(b, s.def, order);
    if (sky) append(b, s.sky, order);
    return b;
  }
};
}  // namespace

TEST(CigiAssembler, PublishesTheOwnshipEyepointAndAttitude) {
  CigiAssembler a({}, kOrigin);
  LinkCounters c;
  Host h;
  h.s.entity.lat_deg = kOrigin.lat_deg;
  h.s.entity.lon_deg = kOrigin.lon_deg;
  h.s.entity.alt_m = 1100.0;
  h.s.entity.yaw_deg = 30.0f;
  h.s.entity.pitch_deg = 10.0f;
  h.s.entity.roll_deg = 20.0f;
  ASSERT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  const HostState& st = a.state();
  EXPECT_NEAR(st.eyeEnu_m.x, 0.0, 1e-6);
  EXPECT_NEAR(st.eyeEnu_m.y, 0.0, 1e-6);
  EXPECT_NEAR(st.eyeEnu_m.z, 1000.0, 1e-6);
  EXPECT_NEAR(st.lat_deg, kOrigin.lat_deg, 1e-9);
  EXPECT_NEAR(st.height_m, 1100.0, 1e-6);
  EXPECT_NEAR(st.heading_deg, 30.0, 1e-6);
  EXPECT_NEAR(st.pitch_deg, 10.0, 1e-6);
  EXPECT_NEAR(st.roll_deg, 20.0, 1e-6);
  EXPECT_EQ(st.hostFrame, 100u);
  EXPECT_NEAR(st.simTime_s, 1234.56789, 1e-9);
  EXPECT_EQ(c.accepted.load(), 1u);
  EXPECT_EQ(c.outOfRange.load(), 0u);
}

TEST(CigiAssembler, ViewOffsetIsInEntityBodyAxes) {
  CigiAssembler a({}, kOrigin);
  LinkCounters c;
  Host h;
  h.s.entity.lat_deg = kOrigin.lat_deg;
  h.s.entity.lon_deg = kOrigin.lon_deg;
  h.s.entity.alt_m = kOrigin.height_m + 500.0;
  h.s.entity.yaw_deg = 90.0f;  // facing east
  h.s.entity.pitch_deg = 0.0f;
  h.s.entity.roll_deg = 0.0f;
  h.s.view = ViewControl{};
  h.s.view.x_m = 10.0f;   // forward -> east
  h.s.view.y_m = 4.0f;    // right -> south
  h.s.view.z_m = -2.0f;   // up
  h.s.view.yaw_deg = 15.0f;
  ASSERT_EQ(a.apply(h.message(ByteOrder::little, true), c), CigiAssembler::Result::published);
  EXPECT_NEAR(a.state().eyeEnu_m.x, 10.0, 1e-6);
  EXPECT_NEAR(a.state().eyeEnu_m.y, -4.0, 1e-6);
  EXPECT_NEAR(a.state().eyeEnu_m.z, 502.0, 1e-4);  // plus the curvature over 10 m (< 0.1 mm)
  EXPECT_NEAR(a.state().heading_deg, 105.0, 1e-6);
  EXPECT_NEAR(a.state().pitch_deg, 0.0, 1e-6);

  // Rolled 90 deg right: the body's right axis points down, so a right offset lowers the eye.
  h.s.entity.roll_deg = 90.0f;
  h.s.view = ViewControl{};
  h.s.view.y_m = 5.0f;
  ASSERT_EQ(a.apply(h.message(ByteOrder::big, true), c), CigiAssembler::Result::published);
  EXPECT_NEAR(a.state().eyeEnu_m.z, 495.0, 1e-4);
  EXPECT_NEAR(a.state().eyeEnu_m.x, 0.0, 1e-6);
  EXPECT_NEAR(a.state().roll_deg, 90.0, 1e-6);
  EXPECT_NEAR(a.state().heading_deg, 90.0, 1e-6);

  // Disabled offsets keep their previous values.
  h.s.view.enable = ViewControl::kX;
  h.s.view.x_m = 1.0f;
  h.s.view.y_m = 99.0f;
  ASSERT_EQ(a.apply(h.message(ByteOrder::big, true), c), CigiAssembler::Result::published);
  EXPECT_NEAR(a.state().eyeEnu_m.x, 1.0, 1e-6);
  EXPECT_NEAR(a.state().eyeEnu_m.z, 495.0, 1e-4);
  EXPECT_EQ(c.outOfRange.load(), 0u);
}

TEST(CigiAssembler, AttitudeFarFromTheOriginIsInSceneAxes) {
  // 1 degree of longitude east at 57.7 N: local north there is rotated by the meridian
  // convergence (about sin(lat) * 1 deg) relative to the scene's grid north.
  CigiAssembler a({}, kOrigin);
  LinkCounters c;
  Host h;
  h.s.entity.lat_deg = kOrigin.lat_deg;
  h.s.entity.lon_deg = kOrigin.lon_deg + 1.0;
  h.s.entity.alt_m = 1000.0;
  h.s.entity.yaw_deg = 0.0f;
  h.s.entity.pitch_deg = 0.0f;
  h.s.entity.roll_deg = 0.0f;
  ASSERT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  const double convergence = std::sin(kOrigin.lat_deg * 3.14159265358979 / 180.0);
  EXPECT_NEAR(a.state().heading_deg, 360.0 - convergence, 0.01);
  EXPECT_NEAR(a.state().lon_deg, kOrigin.lon_deg + 1.0, 1e-9);
}

TEST(CigiAssembler, BadFieldIsRejectedAloneAndKeepsItsLastGoodValue) {
  CigiAssembler a({}, kOrigin);
  LinkCounters c;
  Host h;
  ASSERT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  const HostState before = a.state();
  h.s.entity.lat_deg = kNaN;
  h.s.entity.lon_deg += 0.01;  // still applies
  ASSERT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  EXPECT_EQ(c.outOfRange.load(), 1u);
  EXPECT_NEAR(a.state().lat_deg, before.lat_deg, 1e-5);   // kept
  EXPECT_NEAR(a.state().lon_deg, before.lon_deg + 0.01, 1e-6);
  EXPECT_EQ(a.state().hostFrame, before.hostFrame + 1);

  // Each field alone.
  auto fresh = [] { return Host(); };
  struct Case { const char* name; void (*mutate)(Sample&); };
  const Case cases[] = {
      {"roll", [](Sample& s) { s.entity.roll_deg = 181.0f; }},
      {"pitch", [](Sample& s) { s.entity.pitch_deg = std::numeric_limits<float>::quiet_NaN(); }},
      {"yaw", [](Sample& s) { s.entity.yaw_deg = 360.0f; }},
      {"lat", [](Sample& s) { s.entity.lat_deg = 91.0; }},
      {"lon", [](Sample& s) { s.entity.lon_deg = -std::numeric_limits<double>::infinity(); }},
      {"alt", [](Sample& s) { s.entity.alt_m = 2e6; }},
      {"near", [](Sample& s) { s.def.near_m = -1.0f; }},
      {"far<near", [](Sample& s) { s.def.far_m = 0.25f; }},
      {"top", [](Sample& s) { s.def.top_deg = std::numeric_limits<float>::infinity(); }},
      {"view x", [](Sample& s) { s.view.x_m = std::numeric_limits<float>::quiet_NaN(); }},
      {"view pitch", [](Sample& s) { s.view.pitch_deg = 95.0f; }},
      {"hour", [](Sample& s) { s.sky.hour = 25; }},
      {"date", [](Sample& s) { s.sky.date_mmddyyyy = 2302026; }},
  };
  for (const Case& k : cases) {
    SCOPED_TRACE(k.name);
    CigiAssembler b({}, kOrigin);
    LinkCounters cc;
    Host hh = fresh();
    ASSERT_EQ(b.apply(hh.message(ByteOrder::big, true, true, true), cc), CigiAssembler::Result::published);
    const HostState good = b.state();
    k.mutate(hh.s);
    ASSERT_EQ(b.apply(hh.message(ByteOrder::big, true, true, true), cc), CigiAssembler::Result::published);
    EXPECT_EQ(cc.outOfRange.load(), 1u);
    EXPECT_EQ(cc.accepted.load(), 2u);
    const HostState& now = b.state();
    // Nothing changed except the frame counter (the same values were resent).
    EXPECT_EQ(now.hostFrame, good.hostFrame + 1);
    EXPECT_EQ(now.eyeEnu_m, good.eyeEnu_m);
    EXPECT_EQ(now.heading_deg, good.heading_deg);
    EXPECT_EQ(now.pitch_deg, good.pitch_deg);
    EXPECT_EQ(now.roll_deg, good.roll_deg);
    EXPECT_EQ(now.fovY_deg, good.fovY_deg);
    EXPECT_EQ(now.near_m, good.near_m);
    EXPECT_EQ(now.far_m, good.far_m);
    EXPECT_EQ(now.timeOfDay_h, good.timeOfDay_h);
    EXPECT_EQ(now.dateYmd, good.dateYmd);
  }
}

TEST(CigiAssembler, ViewDefinitionAndCelestialSphere) {
  CigiAssembler a({}, kOrigin);
  LinkCounters c;
  Host h;
  ASSERT_EQ(a.apply(h.message(ByteOrder::big, false, true, true), c), CigiAssembler::Result::published);
  EXPECT_DOUBLE_EQ(a.state().fovY_deg, 45.0);
  EXPECT_DOUBLE_EQ(a.state().near_m, 0.5);
  EXPECT_DOUBLE_EQ(a.state().far_m, 40000.0);
  EXPECT_DOUBLE_EQ(a.state().timeOfDay_h, 14.5);
  EXPECT_EQ(a.state().dateYmd, 20260621);
  // Date/time not valid: ignored.
  h.s.sky.dateTimeValid = false;
  h.s.sky.hour = 3;
  ASSERT_EQ(a.apply(h.message(ByteOrder::big, false, false, true), c), CigiAssembler::Result::published);
  EXPECT_DOUBLE_EQ(a.state().timeOfDay_h, 14.5);
  EXPECT_EQ(c.outOfRange.load(), 0u);
}

TEST(CigiAssembler, NothingPublishedBeforeTheOwnshipPosition) {
  CigiAssembler a({7, 0, -1}, kOrigin);
  LinkCounters c;
  Host h;  // entity 0 is not the ownship
  EXPECT_EQ(a.apply(h.message(), c), CigiAssembler::Result::accepted);
  h.s.entity.entityId = 7;
  EXPECT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  EXPECT_EQ(c.accepted.load(), 2u);
}

TEST(CigiAssembler, LateMessagesAndHostRestart) {
  CigiAssembler a({}, kOrigin);
  LinkCounters c;
  Host h;
  h.frame = 5000;
  ASSERT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);  // 5000
  ASSERT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);  // 5001
  h.frame = 4999;
  EXPECT_EQ(a.apply(h.message(), c), CigiAssembler::Result::late);
  EXPECT_EQ(c.late.load(), 1u);
  EXPECT_EQ(a.state().hostFrame, 5001u);
  h.frame = 5001;  // same frame again, same timestamp: applies
  EXPECT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  h.s.ig.timestamp_10us -= 10;  // same frame, earlier timestamp: late
  h.frame = 5001;
  EXPECT_EQ(a.apply(h.message(), c), CigiAssembler::Result::late);
  h.s.ig.timestamp_10us += 10;
  // A restarted host far behind: applies at once.
  h.frame = 0;
  h.s.ig.timestamp_10us = 0;
  EXPECT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  EXPECT_EQ(a.state().hostFrame, 0u);
  EXPECT_EQ(a.state().simTime_s, 0.0);
  // A restart only a few frames back: late until kRestartAfterLate in a row, then resumes.
  h.frame = 600;
  ASSERT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  h.frame = 10;
  const uint64_t lateBefore = c.late.load();
  for (uint32_t i = 0; i + 1 < CigiAssembler::kRestartAfterLate; ++i)
    EXPECT_EQ(a.apply(h.message(), c), CigiAssembler::Result::late) << i;
  EXPECT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  EXPECT_EQ(c.late.load() - lateBefore, CigiAssembler::kRestartAfterLate - 1);
  EXPECT_EQ(a.state().hostFrame, 10u + CigiAssembler::kRestartAfterLate - 1);
}

TEST(CigiAssembler, FrameAndTimestampUnwrapAcross32Bits) {
  CigiAssembler a({}, kOrigin);
  LinkCounters c;
  Host h;
  h.frame = 0xfffffffeu;
  h.s.ig.timestamp_10us = 0xffffff00u;
  ASSERT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  const double t0 = a.state().simTime_s;
  h.s.ig.timestamp_10us = 0x00000100u;  // +512 ticks across the wrap
  ASSERT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  ASSERT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);  // frame wraps to 0
  EXPECT_EQ(a.state().hostFrame, 0x100000000ull);
  EXPECT_NEAR(a.state().simTime_s - t0, 512e-5, 1e-9);
  EXPECT_EQ(c.late.load(), 0u);
  // Timestamp not valid: simulation time holds.
  h.s.ig.timestampValid = false;
  h.s.ig.timestamp_10us = 5;
  const double held = a.state().simTime_s;
  ASSERT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  EXPECT_EQ(a.state().simTime_s, held);
}

TEST(CigiAssembler, MalformedCountedAndNothingApplied) {
  CigiAssembler a({}, kOrigin);
  LinkCounters c;
  Host h;
  Bytes b = h.message();
  b.pop_back();
  EXPECT_EQ(a.apply(b, c), CigiAssembler::Result::malformed);
  EXPECT_EQ(c.malformed.load(), 1u);
  EXPECT_EQ(c.accepted.load(), 0u);
  EXPECT_FALSE(a.hasPosition());
}

TEST(CigiAssembler, DatabaseRequests) {
  CigiAssembler any({}, kOrigin);
  LinkCounters c;
  Host h;
  h.s.ig.databaseNumber = 5;
  any.apply(h.message(), c);
  EXPECT_EQ(any.database(), 5);
  CigiAssembler fixed({0, 0, 3}, kOrigin);
  fixed.apply(h.message(), c);  // asks for 5, igd has 3
  EXPECT_EQ(c.outOfRange.load(), 1u);
  EXPECT_EQ(fixed.database(), 3);
  EXPECT_EQ(fixed.state().hostFrame, 101u);  // the rest applied
}

TEST(CigiLinkConfig, ValidationNamesKeyAndValue) {
  std::string e;
  CigiLinkConfig cfg;
  EXPECT_TRUE(validateCigiLinkConfig(cfg, e)) << e;
  cfg.port = 70000;
  EXPECT_FALSE(validateCigiLinkConfig(cfg, e));
  EXPECT_EQ(e, "host.cigi.port = 70000: must be 1..65535");
  cfg = {};
  cfg.bind_address = "0.0.0.300";
  EXPECT_FALSE(validateCigiLinkConfig(cfg, e));
  EXPECT_EQ(e, "host.cigi.bind_address = '0.0.0.300': not an IPv4 address (e.g. \"0.0.0.0\")");
  cfg = {};
  cfg.database = 200;
  EXPECT_FALSE(validateCigiLinkConfig(cfg, e));
  EXPECT_EQ(e, "host.cigi.database = 200: must be -1 (any) or 0..127");
  cfg = {};
  cfg.entity_id = -2;
  EXPECT_FALSE(validateCigiLinkConfig(cfg, e));
  EXPECT_EQ(e, "host.cigi.entity_id = -2: must be 0..65535");
}

// ---------------------------------------------------------------------------------------------
// pcap

namespace {

void put32(Bytes& b, uint32_t v, bool little) {
  for (int i = 0; i < 4; ++i) b.push_back(std::byte{static_cast<uint8_t>(little ? v >> (8 * i) : v >> (24 - 8 * i))});
}
void put16be(Bytes& b, uint16_t v) {
  b.push_back(std::byte{static_cast<uint8_t>(v >> 8)});
  b.push_back(std::byte{static_cast<uint8_t>(v)});
}

Bytes ipv4Udp(const Bytes& payload, uint16_t dstPort, uint16_t flagsFrag = 0) {
  Bytes ip;
  ip.push_back(std::byte{0x45});
  ip.push_back(std::byte{0});
  put16be(ip, static_cast<uint16_t>(20 + 8 + payload.size()));
  put16be(ip, 1);
  put16be(ip, flagsFrag);
  ip.push_back(std::byte{64});
  ip.push_back(std::byte{17});
  put16be(ip, 0);
  for (int i = 0; i < 2; ++i) {
    ip.push_back(std::byte{127});
    ip.push_back(std::byte{0});
    ip.push_back(std::byte{0});
    ip.push_back(std::byte{1});
  }
  put16be(ip, 40000);
  put16be(ip, dstPort);
  put16be(ip, static_cast<uint16_t>(8 + payload.size()));
  put16be(ip, 0);
  ip.insert(ip.end(), payload.begin(), payload.end());
  return ip;
}

Bytes frameFor(uint32_t link, const Bytes& ip) {
  Bytes f;
  if (link == 1) {
    for (int i = 0; i < 12; ++i) f.push_back(std::byte{0});
    put16be(f, 0x0800);
  } else if (link == 113) {
    for (int i = 0; i < 14; ++i) f.push_back(std::byte{0});
    put16be(f, 0x0800);
  } else if (link == 0) {
    put32(f, 2, true);  // AF_INET, little-endian capturing machine
  }
  f.insert(f.end(), ip.begin(), ip.end());
  return f;
}

struct PcapWriter {
  bool little;
  bool nanos;
  uint32_t link;
  Bytes file;
  PcapWriter(bool l, bool n, uint32_t lt) : little(l), nanos(n), link(lt) {
    put32(file, nanos ? 0xa1b23c4d : 0xa1b2c3d4, little);
    file.push_back(std::byte{static_cast<uint8_t>(little ? 2 : 0)});
    file.push_back(std::byte{static_cast<uint8_t>(little ? 0 : 2)});
    file.push_back(std::byte{static_cast<uint8_t>(little ? 4 : 0)});
    file.push_back(std::byte{static_cast<uint8_t>(little ? 0 : 4)});
    put32(file, 0, little);
    put32(file, 0, little);
    put32(file, 65535, little);
    put32(file, link, little);
  }
  void add(double t_s, const Bytes& frame) {
    const uint32_t sec = static_cast<uint32_t>(t_s);
    const double frac = t_s - sec;
    put32(file, sec, little);
    put32(file, static_cast<uint32_t>(std::llround(frac * (nanos ? 1e9 : 1e6))), little);
    put32(file, static_cast<uint32_t>(frame.size()), little);
    put32(file, static_cast<uint32_t>(frame.size()), little);
    file.insert(file.end(), frame.begin(), frame.end());
  }
};

std::string writeTemp(const Bytes& b, const std::string& name) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<long>(b.size()));
  return path;
}

}  // namespace

TEST(CigiPcap, EveryLinkTypeByteOrderAndTimestampResolution) {
  for (uint32_t link : {0u, 1u, 101u, 113u, 228u}) {
    for (bool little : {true, false}) {
      for (bool nanos : {false, true}) {
        SCOPED_TRACE(testing::Message() << "link " << link << " little " << little << " nanos " << nanos);
        PcapWriter w(little, nanos, link);
        Host h;
        h.s.entity.lat_deg = kOrigin.lat_deg;
        h.s.entity.lon_deg = kOrigin.lon_deg;
        h.s.entity.alt_m = 600.0;
        w.add(1700000000.25, frameFor(link, ipv4Udp(h.message(), 9999)));           // other port: ignored
        w.add(1700000000.5, frameFor(link, ipv4Udp(h.message(), 8004)));            // t = 0
        w.add(1700000000.6, frameFor(link, ipv4Udp(h.message(), 8004, 0x2000)));    // fragment: skipped
        Bytes bad = h.message();
        bad[1] = std::byte{23};
        w.add(1700000000.7, frameFor(link, ipv4Udp(bad, 8004)));                    // malformed
        h.s.entity.alt_m = 700.0;
        w.add(1700000001.0, frameFor(link, ipv4Udp(h.message(ByteOrder::little), 8004)));  // t = 0.5
        const std::string path = writeTemp(w.file, "cigi_link" + std::to_string(link) + ".pcap");
        Recording r;
        std::string e;
        LinkCountersSnapshot counts;
        ASSERT_TRUE(cigiPcapToRecording(path, 8004, kOrigin, r, e, {}, &counts)) << e;
        ASSERT_EQ(r.samples.size(), 2u);
        EXPECT_DOUBLE_EQ(r.samples[0].t_s, 0.0);
        EXPECT_NEAR(r.samples[1].t_s, 0.5, 1e-6);
        EXPECT_NEAR(r.samples[0].state.eyeEnu_m.z, 500.0, 1e-6);
        EXPECT_NEAR(r.samples[1].state.eyeEnu_m.z, 600.0, 1e-6);
        EXPECT_EQ(r.samples[1].state.hostFrame, r.samples[0].state.hostFrame + 3);
        EXPECT_EQ(counts.received, 3u);
        EXPECT_EQ(counts.malformed, 1u);
        std::remove(path.c_str());
      }
    }
  }
}

TEST(CigiPcap, ErrorsNameTheFile) {
  Recording r;
  std::string e;
  EXPECT_FALSE(cigiPcapToRecording("/nonexistent/x.pcap", 8004, kOrigin, r, e));
  EXPECT_NE(e.find("/nonexistent/x.pcap: cannot open"), std::string::npos) << e;
  const std::string ng = writeTemp(Bytes{std::byte{0x0a}, std::byte{0x0d}, std::byte{0x0d}, std::byte{0x0a},
                                         std::byte{0}, std::byte{0}, std::byte{0}, std::byte{0}, std::byte{0},
                                         std::byte{0}, std::byte{0}, std::byte{0}, std::byte{0}, std::byte{0},
                                         std::byte{0}, std::byte{0}, std::byte{0}, std::byte{0}, std::byte{0},
                                         std::byte{0}, std::byte{0}, std::byte{0}, std::byte{0}, std::byte{0}},
                                   "cigi_ng.pcap");
  EXPECT_FALSE(cigiPcapToRecording(ng, 8004, kOrigin, r, e));
  EXPECT_NE(e.find("is pcapng"), std::string::npos) << e;
  PcapWriter w(true, false, 147);
  const std::string odd = writeTemp(w.file, "cigi_odd.pcap");
  EXPECT_FALSE(cigiPcapToRecording(odd, 8004, kOrigin, r, e));
  EXPECT_EQ(e, odd + ": link type 147 not supported (Ethernet 1, Linux cooked 113, raw IPv4 101/228, loopback 0)");
  PcapWriter empty(true, false, 1);
  const std::string none = writeTemp(empty.file, "cigi_none.pcap");
  EXPECT_FALSE(cigiPcapToRecording(none, 8004, kOrigin, r, e));
  EXPECT_NE(e.find("no CIGI host message to UDP port 8004"), std::string::npos) << e;
  // Every truncation of a capture: an error or a clean parse of the whole records, no crash.
  PcapWriter full(true, false, 1);
  Host h;
  full.add(1.0, frameFor(1, ipv4Udp(h.message(), 8004)));
  full.add(2.0, frameFor(1, ipv4Udp(h.message(), 8004)));
  for (size_t n = 0; n < full.file.size(); ++n) {
    std::string err;
    PcapStats st;
    const bool ok = parsePcapUdp(std::span(full.file.data(), n), "cut.pcap", [](const UdpDatagram&) {}, err, &st);
    EXPECT_EQ(ok, n == 24 || n == full.file.size() / 2 + 12) << n << " " << err;
  }
  std::remove(ng.c_str());
  std::remove(odd.c_str());
  std::remove(none.c_str());
}
