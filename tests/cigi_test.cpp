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
#include <numbers>
#include <string>
#include <vector>

#include "io/cigi.h"
#include "io/cigi_link.h"
#include "io/pcap.h"
#include "lod/hdlod_rays.h"
#include "lod/hdlod_scene.h"
#include "lod/terrain_grid.h"
#include "lod/view.h"

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

TEST(CigiCodec, HatHotRequestAndResponsesRoundTripAndLayout) {
  HatHotRequest q;
  q.hatHotId = 0x1234;
  q.requestType = HatHotRequest::kExtended;
  q.entityCoordinates = true;
  q.updatePeriod = 9;
  q.entityId = 0x0506;
  q.lat_deg = 57.5;
  q.lon_deg = -11.25;
  q.alt_m = 1234.5;
  HatHotResponse r;
  r.hatHotId = 0x0708;
  r.valid = true;
  r.hot = true;
  r.hostFrameLsn = 0xa;
  r.height_m = 123.25;
  HatHotExtendedResponse x;
  x.hatHotId = 0x4321;
  x.valid = true;
  x.hostFrameLsn = 5;
  x.hat_m = 11.5;
  x.hot_m = 22.75;
  x.materialCode = 9;
  x.normalAzimuth_deg = 45.5f;
  x.normalElevation_deg = 80.25f;
  for (ByteOrder order : {ByteOrder::big, ByteOrder::little}) {
    const bool be = order == ByteOrder::big;
    Bytes b;
    append(b, Sample().ig, order);
    append(b, q, order);
    ASSERT_EQ(b.size(), 24u + 32u);
    // Request at 24: id 24, size 32, ID, type 2 | entity (bit 2), period 9, entity id, lat at +8.
    EXPECT_EQ(at(b, 24), 24);
    EXPECT_EQ(at(b, 25), 32);
    EXPECT_EQ(at(b, 26), be ? 0x12 : 0x34);
    EXPECT_EQ(at(b, 28), 0x02 | 0x04);
    EXPECT_EQ(at(b, 29), 9);
    EXPECT_EQ(at(b, 30), be ? 0x05 : 0x06);
    EXPECT_EQ(at(b, be ? 32 : 39), 0x40);  // 57.5 = 0x404CC00000000000
    EXPECT_EQ(at(b, be ? 33 : 38), 0x4c);
    ASSERT_EQ(decode(b), CigiStatus::ok);
    ASSERT_EQ(scratch().hatHotCount, 1u);
    const HatHotRequest& d = scratch().hatHotRequests[0];
    EXPECT_EQ(d.hatHotId, 0x1234);
    EXPECT_EQ(d.requestType, HatHotRequest::kExtended);
    EXPECT_TRUE(d.entityCoordinates);
    EXPECT_EQ(d.updatePeriod, 9);
    EXPECT_EQ(d.entityId, 0x0506);
    EXPECT_EQ(d.lat_deg, 57.5);
    EXPECT_EQ(d.lon_deg, -11.25);
    EXPECT_EQ(d.alt_m, 1234.5);

    Bytes rb;
    append(rb, r, order);
    ASSERT_EQ(rb.size(), 16u);
    EXPECT_EQ(at(rb, 0), 102);
    EXPECT_EQ(at(rb, 1), 16);
    EXPECT_EQ(at(rb, 2), be ? 0x07 : 0x08);
    EXPECT_EQ(at(rb, 4), 0x01 | 0x02 | 0xa0);
    EXPECT_EQ(at(rb, be ? 8 : 15), 0x40);  // 123.25 = 0x405ED00000000000
    EXPECT_EQ(at(rb, be ? 9 : 14), 0x5e);
    HatHotResponse rd;
    ASSERT_TRUE(decodePacket(rb, order, rd));
    EXPECT_EQ(rd.hatHotId, r.hatHotId);
    EXPECT_TRUE(rd.valid && rd.hot);
    EXPECT_EQ(rd.hostFrameLsn, 0xa);
    EXPECT_EQ(rd.height_m, 123.25);

    Bytes xb;
    append(xb, x, order);
    ASSERT_EQ(xb.size(), 40u);
    EXPECT_EQ(at(xb, 0), 103);
    EXPECT_EQ(at(xb, 1), 40);
    EXPECT_EQ(at(xb, 4), 0x01 | 0x50);
    EXPECT_EQ(at(xb, be ? 8 : 15), 0x40);   // HAT 11.5 = 0x4027000000000000
    EXPECT_EQ(at(xb, be ? 9 : 14), 0x27);
    EXPECT_EQ(at(xb, be ? 16 : 23), 0x40);  // HOT 22.75 = 0x4036C00000000000
    EXPECT_EQ(at(xb, be ? 17 : 22), 0x36);
    EXPECT_EQ(at(xb, be ? 27 : 24), 9);     // material code
    EXPECT_EQ(at(xb, be ? 28 : 31), 0x42);  // azimuth 45.5f = 0x42360000
    EXPECT_EQ(at(xb, be ? 29 : 30), 0x36);
    EXPECT_EQ(at(xb, be ? 32 : 35), 0x42);  // elevation 80.25f = 0x42A08000
    EXPECT_EQ(at(xb, be ? 33 : 34), 0xa0);
    HatHotExtendedResponse xd;
    ASSERT_TRUE(decodePacket(xb, order, xd));
    EXPECT_EQ(xd.hatHotId, x.hatHotId);
    EXPECT_TRUE(xd.valid);
    EXPECT_EQ(xd.hostFrameLsn, 5);
    EXPECT_EQ(xd.hat_m, 11.5);
    EXPECT_EQ(xd.hot_m, 22.75);
    EXPECT_EQ(xd.materialCode, 9u);
    EXPECT_EQ(xd.normalAzimuth_deg, 45.5f);
    EXPECT_EQ(xd.normalElevation_deg, 80.25f);
    EXPECT_FALSE(decodePacket(rb, order, xd));  // wrong id
    EXPECT_FALSE(decodePacket(std::span(xb.data(), 39), order, xd));
  }
  // A wrong size for the known id is malformed; more than capacity are counted, not kept.
  Bytes bad;
  append(bad, Sample().ig, ByteOrder::big);
  appendUnknown(bad, 24, 30);
  EXPECT_EQ(decode(bad), CigiStatus::badPacketSize);
  Bytes many;
  append(many, Sample().ig, ByteOrder::big);
  for (size_t i = 0; i <= HostMessage::kMaxHatHotRequests; ++i) append(many, q, ByteOrder::big);
  ASSERT_EQ(decode(many), CigiStatus::ok);
  EXPECT_EQ(scratch().hatHotCount, HostMessage::kMaxHatHotRequests);
  EXPECT_EQ(scratch().hatHotOmitted, 1u);
  // Validation: type 3, NaN / out-of-range latitude and longitude; HOT ignores the altitude.
  HatHotRequest g;
  g.lat_deg = 46.5;
  g.lon_deg = 7.9;
  g.alt_m = kNaN;
  EXPECT_EQ(validateHatHotRequest(g), 0u);  // HOT
  g.requestType = HatHotRequest::kHat;
  EXPECT_EQ(validateHatHotRequest(g), uint32_t{kHatHotAltZ});
  g.alt_m = 100.0;
  g.requestType = 3;
  g.lat_deg = 90.5;
  g.lon_deg = kNaN;
  EXPECT_EQ(validateHatHotRequest(g), uint32_t{kHatHotType | kHatHotLatX | kHatHotLonY});
  g.requestType = HatHotRequest::kHot;
  g.entityCoordinates = true;
  g.lat_deg = 2.0e5;
  g.lon_deg = 0.0;
  EXPECT_EQ(validateHatHotRequest(g), uint32_t{kHatHotLatX});
}

TEST(CigiCodec, LosRequestsAndResponsesRoundTripAndLayout) {
  LosRequest seg;
  seg.kind = LosRequest::kSegment;
  seg.losId = 0x1234;
  seg.extended = true;
  seg.destinationEntity = true;
  seg.destinationEntityIdValid = true;
  seg.alphaThreshold = 7;
  seg.entityId = 0x0506;
  seg.srcLat_deg = 57.5;
  seg.srcLon_deg = -11.25;
  seg.srcAlt_m = 1234.5;
  seg.dstLat_deg = 10.0;
  seg.dstLon_deg = 20.0;
  seg.dstAlt_m = -30.0;
  seg.materialMask = 0x01020304;
  seg.updatePeriod = 9;
  seg.destinationEntityId = 0x0a0b;
  LosRequest vec;
  vec.kind = LosRequest::kVector;
  vec.losId = 0x2345;
  vec.sourceEntity = true;
  vec.responseEntity = true;
  vec.alphaThreshold = 3;
  vec.entityId = 0x0708;
  vec.azimuth_deg = 45.5f;
  vec.elevation_deg = -5.0f;
  vec.minRange_m = 1.0f;
  vec.maxRange_m = 2000.0f;
  vec.srcLat_deg = 1.25;
  vec.srcLon_deg = 2.25;
  vec.srcAlt_m = 3.25;
  vec.materialMask = 88;
  vec.updatePeriod = 6;
  LosResponse r;
  r.losId = 0x0708;
  r.valid = true;
  r.visible = true;
  r.hostFrameLsn = 0xa;
  r.entityId = 0x0c0d;
  r.range_m = 123.25;
  LosExtendedResponse x;
  x.losId = 0x4321;
  x.valid = true;
  x.rangeValid = true;
  x.entityIdValid = true;
  x.hostFrameLsn = 5;
  x.responseCount = 1;
  x.entityId = 0x0e0f;
  x.range_m = 11.5;
  x.lat_deg = 57.5;
  x.lon_deg = -11.25;
  x.alt_m = 22.75;
  x.red = 1, x.green = 2, x.blue = 3, x.alpha = 4;
  x.materialCode = 9;
  x.normalAzimuth_deg = 45.5f;
  x.normalElevation_deg = 80.25f;
  for (ByteOrder order : {ByteOrder::big, ByteOrder::little}) {
    const bool be = order == ByteOrder::big;
    Bytes b;
    append(b, Sample().ig, order);
    append(b, seg, order);
    append(b, vec, order);
    ASSERT_EQ(b.size(), 24u + 64u + 56u);
    // Segment at 24: flags extended | destination entity | destination entity id valid.
    EXPECT_EQ(at(b, 24), 25);
    EXPECT_EQ(at(b, 25), 64);
    EXPECT_EQ(at(b, 26), be ? 0x12 : 0x34);
    EXPECT_EQ(at(b, 28), 0x01 | 0x04 | 0x10);
    EXPECT_EQ(at(b, 29), 7);
    EXPECT_EQ(at(b, 30), be ? 0x05 : 0x06);
    EXPECT_EQ(at(b, be ? 32 : 39), 0x40);  // source latitude 57.5 = 0x404CC00000000000 at +8
    EXPECT_EQ(at(b, be ? 33 : 38), 0x4c);
    EXPECT_EQ(at(b, be ? 56 : 63), 0x40);  // destination latitude 10 = 0x4024000000000000 at +32
    EXPECT_EQ(at(b, be ? 57 : 62), 0x24);
    EXPECT_EQ(at(b, be ? 80 : 83), 0x01);  // material mask at +56
    EXPECT_EQ(at(b, 84), 9);               // update period at +60
    EXPECT_EQ(at(b, be ? 86 : 87), 0x0a);  // destination entity id at +62
    // Vector at 88: flags source entity | response entity.
    EXPECT_EQ(at(b, 88), 26);
    EXPECT_EQ(at(b, 89), 56);
    EXPECT_EQ(at(b, 92), 0x02 | 0x04);
    EXPECT_EQ(at(b, 93), 3);
    EXPECT_EQ(at(b, be ? 96 : 99), 0x42);   // azimuth 45.5f = 0x42360000 at +8
    EXPECT_EQ(at(b, be ? 108 : 111), 0x44); // max range 2000f = 0x44FA0000 at +20
    EXPECT_EQ(at(b, be ? 109 : 110), 0xfa);
    EXPECT_EQ(at(b, be ? 112 : 119), 0x3f); // source x 1.25 = 0x3FF4000000000000 at +24
    EXPECT_EQ(at(b, be ? 113 : 118), 0xf4);
    EXPECT_EQ(at(b, be ? 139 : 136), 88);   // material mask at +48
    EXPECT_EQ(at(b, 140), 6);               // update period at +52
    ASSERT_EQ(decode(b), CigiStatus::ok);
    ASSERT_EQ(scratch().losCount, 2u);
    const LosRequest& s = scratch().losRequests[0];
    EXPECT_EQ(s.kind, LosRequest::kSegment);
    EXPECT_EQ(s.losId, 0x1234);
    EXPECT_TRUE(s.extended && s.destinationEntity && s.destinationEntityIdValid);
    EXPECT_FALSE(s.sourceEntity || s.responseEntity);
    EXPECT_EQ(s.alphaThreshold, 7);
    EXPECT_EQ(s.entityId, 0x0506);
    EXPECT_EQ(s.srcLat_deg, 57.5);
    EXPECT_EQ(s.srcLon_deg, -11.25);
    EXPECT_EQ(s.srcAlt_m, 1234.5);
    EXPECT_EQ(s.dstLat_deg, 10.0);
    EXPECT_EQ(s.dstLon_deg, 20.0);
    EXPECT_EQ(s.dstAlt_m, -30.0);
    EXPECT_EQ(s.materialMask, 0x01020304u);
    EXPECT_EQ(s.updatePeriod, 9);
    EXPECT_EQ(s.destinationEntityId, 0x0a0b);
    const LosRequest& v = scratch().losRequests[1];
    EXPECT_EQ(v.kind, LosRequest::kVector);
    EXPECT_EQ(v.losId, 0x2345);
    EXPECT_TRUE(!v.extended && v.sourceEntity && v.responseEntity);
    EXPECT_EQ(v.entityId, 0x0708);
    EXPECT_EQ(v.azimuth_deg, 45.5f);
    EXPECT_EQ(v.elevation_deg, -5.0f);
    EXPECT_EQ(v.minRange_m, 1.0f);
    EXPECT_EQ(v.maxRange_m, 2000.0f);
    EXPECT_EQ(v.srcLat_deg, 1.25);
    EXPECT_EQ(v.srcLon_deg, 2.25);
    EXPECT_EQ(v.srcAlt_m, 3.25);
    EXPECT_EQ(v.materialMask, 88u);
    EXPECT_EQ(v.updatePeriod, 6);

    Bytes rb;
    append(rb, r, order);
    ASSERT_EQ(rb.size(), 16u);
    EXPECT_EQ(at(rb, 0), 104);
    EXPECT_EQ(at(rb, 1), 16);
    EXPECT_EQ(at(rb, 2), be ? 0x07 : 0x08);
    EXPECT_EQ(at(rb, 4), 0x01 | 0x04 | 0xa0);
    EXPECT_EQ(at(rb, 5), 1);  // response count
    EXPECT_EQ(at(rb, be ? 6 : 7), 0x0c);
    EXPECT_EQ(at(rb, be ? 8 : 15), 0x40);  // 123.25 = 0x405ED00000000000
    EXPECT_EQ(at(rb, be ? 9 : 14), 0x5e);
    LosResponse rd;
    ASSERT_TRUE(decodePacket(rb, order, rd));
    EXPECT_EQ(rd.losId, r.losId);
    EXPECT_TRUE(rd.valid && rd.visible && !rd.entityIdValid);
    EXPECT_EQ(rd.hostFrameLsn, 0xa);
    EXPECT_EQ(rd.responseCount, 1);
    EXPECT_EQ(rd.entityId, 0x0c0d);
    EXPECT_EQ(rd.range_m, 123.25);

    Bytes xb;
    append(xb, x, order);
    ASSERT_EQ(xb.size(), 56u);
    EXPECT_EQ(at(xb, 0), 105);
    EXPECT_EQ(at(xb, 1), 56);
    EXPECT_EQ(at(xb, 4), 0x01 | 0x02 | 0x04 | 0x50);
    EXPECT_EQ(at(xb, 5), 1);
    EXPECT_EQ(at(xb, be ? 8 : 15), 0x40);   // range 11.5 = 0x4027000000000000
    EXPECT_EQ(at(xb, be ? 9 : 14), 0x27);
    EXPECT_EQ(at(xb, be ? 16 : 23), 0x40);  // latitude 57.5
    EXPECT_EQ(at(xb, be ? 17 : 22), 0x4c);
    EXPECT_EQ(at(xb, be ? 32 : 39), 0x40);  // altitude 22.75 = 0x4036C00000000000
    EXPECT_EQ(at(xb, be ? 33 : 38), 0x36);
    EXPECT_EQ(at(xb, 40), 1);
    EXPECT_EQ(at(xb, 43), 4);
    EXPECT_EQ(at(xb, be ? 47 : 44), 9);     // material code
    EXPECT_EQ(at(xb, be ? 48 : 51), 0x42);  // azimuth 45.5f = 0x42360000
    EXPECT_EQ(at(xb, be ? 52 : 55), 0x42);  // elevation 80.25f = 0x42A08000
    EXPECT_EQ(at(xb, be ? 53 : 54), 0xa0);
    LosExtendedResponse xd;
    ASSERT_TRUE(decodePacket(xb, order, xd));
    EXPECT_EQ(xd.losId, x.losId);
    EXPECT_TRUE(xd.valid && xd.rangeValid && xd.entityIdValid && !xd.visible);
    EXPECT_EQ(xd.hostFrameLsn, 5);
    EXPECT_EQ(xd.entityId, 0x0e0f);
    EXPECT_EQ(xd.range_m, 11.5);
    EXPECT_EQ(xd.lat_deg, 57.5);
    EXPECT_EQ(xd.lon_deg, -11.25);
    EXPECT_EQ(xd.alt_m, 22.75);
    EXPECT_EQ(xd.red + xd.green + xd.blue + xd.alpha, 10);
    EXPECT_EQ(xd.materialCode, 9u);
    EXPECT_EQ(xd.normalAzimuth_deg, 45.5f);
    EXPECT_EQ(xd.normalElevation_deg, 80.25f);
    EXPECT_FALSE(decodePacket(rb, order, xd));  // wrong id
    EXPECT_FALSE(decodePacket(std::span(xb.data(), 55), order, xd));
  }
  // Wrong sizes are malformed; more than capacity are counted, not kept.
  for (const uint8_t id : {uint8_t{25}, uint8_t{26}}) {
    Bytes bad;
    append(bad, Sample().ig, ByteOrder::big);
    appendUnknown(bad, id, 60);
    EXPECT_EQ(decode(bad), CigiStatus::badPacketSize) << int(id);
  }
  Bytes many;
  append(many, Sample().ig, ByteOrder::big);
  for (size_t i = 0; i <= HostMessage::kMaxLosRequests; ++i) append(many, i % 2 ? vec : seg, ByteOrder::big);
  ASSERT_EQ(decode(many), CigiStatus::ok);
  EXPECT_EQ(scratch().losCount, HostMessage::kMaxLosRequests);
  EXPECT_EQ(scratch().losOmitted, 1u);
  EXPECT_EQ(scratch().omittedPackets, 1u);
  // Validation: points as HAT/HOT's, vector angles and ranges.
  LosRequest g;
  g.srcLat_deg = 46.5;
  g.srcLon_deg = 7.9;
  g.srcAlt_m = 500.0;
  g.dstLat_deg = 46.6;
  g.dstLon_deg = 7.9;
  g.dstAlt_m = 500.0;
  EXPECT_EQ(validateLosRequest(g), 0u);
  g.srcAlt_m = kNaN;
  g.dstLat_deg = 90.5;
  g.dstLon_deg = -180.5;
  g.dstAlt_m = 1.1e6;
  EXPECT_EQ(validateLosRequest(g), uint32_t{kLosSrcAltZ | kLosDstLatX | kLosDstLonY | kLosDstAltZ});
  g.destinationEntity = true;
  g.dstLat_deg = 2.0e5;
  g.dstLon_deg = -1.0e5;
  g.dstAlt_m = 0.0;
  EXPECT_EQ(validateLosRequest(g), uint32_t{kLosSrcAltZ | kLosDstLatX});
  LosRequest w;
  w.kind = LosRequest::kVector;
  w.srcAlt_m = 100.0;
  w.azimuth_deg = 359.0f;
  w.elevation_deg = -90.0f;
  w.maxRange_m = 1000.0f;
  w.dstLat_deg = kNaN;  // not a vector's field
  EXPECT_EQ(validateLosRequest(w), 0u);
  w.azimuth_deg = 361.0f;
  w.elevation_deg = std::numeric_limits<float>::quiet_NaN();
  w.minRange_m = 10.0f;
  w.maxRange_m = 5.0f;  // below the minimum
  EXPECT_EQ(validateLosRequest(w), uint32_t{kLosAzimuth | kLosElevation | kLosMaxRange});
  w.azimuth_deg = 0.0f;
  w.elevation_deg = 0.0f;
  w.minRange_m = -1.0f;
  w.maxRange_m = 2.0e6f;
  EXPECT_EQ(validateLosRequest(w), uint32_t{kLosMinRange | kLosMaxRange});
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

// Atmosphere Control: every field through both byte orders (offsets as Wireshark's dissector
// reads them: tests/cigi_interop_test.py), kept as the message's last one, and its visibility
// validated (> 0, <= 1e7 m, finite).
TEST(Cigi, AtmosphereControlRoundTripsAndItsVisibilityIsChecked) {
  AtmosphereControl p;
  p.atmosphericModelEnable = true;
  p.humidity_pct = 87;
  p.airTemperature_c = -12.25f;
  p.visibility_m = 1234.5f;
  p.horizontalWind_mps = 17.5f;
  p.verticalWind_mps = -2.0f;
  p.windDirection_deg = 275.0f;
  p.pressure_hpa = 987.5f;
  for (ByteOrder order : {ByteOrder::big, ByteOrder::little}) {
    Bytes b;
    IgControl ig;
    append(b, ig, order);
    AtmosphereControl first = p;
    first.visibility_m = 50.0f;
    append(b, first, order);
    append(b, p, order);  // the last one counts
    ASSERT_EQ(b.size(), kIgControlSize + 2 * kAtmosphereControlSize);
    EXPECT_EQ(static_cast<uint8_t>(b[kIgControlSize]), 10u);
    EXPECT_EQ(static_cast<uint8_t>(b[kIgControlSize + 1]), 32u);
    HostMessage m;
    ASSERT_EQ(decodeHostMessage(b, m), CigiStatus::ok);
    ASSERT_TRUE(m.hasAtmosphere);
    EXPECT_TRUE(m.atmosphere.atmosphericModelEnable);
    EXPECT_EQ(m.atmosphere.humidity_pct, 87);
    EXPECT_EQ(m.atmosphere.airTemperature_c, -12.25f);
    EXPECT_EQ(m.atmosphere.visibility_m, 1234.5f);
    EXPECT_EQ(m.atmosphere.horizontalWind_mps, 17.5f);
    EXPECT_EQ(m.atmosphere.verticalWind_mps, -2.0f);
    EXPECT_EQ(m.atmosphere.windDirection_deg, 275.0f);
    EXPECT_EQ(m.atmosphere.pressure_hpa, 987.5f);
    EXPECT_EQ(m.unknownPackets, 0u);
    // A wrong size is malformed, as for every packet igd decodes.
    b[kIgControlSize + 1] = std::byte{28};
    EXPECT_EQ(decodeHostMessage(b, m), CigiStatus::badPacketSize);
  }
  HostMessage none;
  Bytes b;
  append(b, IgControl{}, ByteOrder::big);
  ASSERT_EQ(decodeHostMessage(b, none), CigiStatus::ok);
  EXPECT_FALSE(none.hasAtmosphere);
  EXPECT_EQ(validateAtmosphere(p), 0u);
  for (float v : {-1.0f, -1e-30f, -std::numeric_limits<float>::infinity(), std::numeric_limits<float>::quiet_NaN()}) {
    p.visibility_m = v;
    EXPECT_EQ(validateAtmosphere(p), kAtmosphereVisibility) << v;
  }
  for (float v : {0.0f, 0.001f, 1e7f, 1.5e7f, std::numeric_limits<float>::max(), std::numeric_limits<float>::infinity()}) {
    p.visibility_m = v;
    EXPECT_EQ(validateAtmosphere(p), 0u) << v;
  }
}

// The host's visibility reaches HostState, 0 and "unlimited" clamped to 1 m and 10,000 km; a
// NaN or negative one is counted and the last good one kept; a message without Atmosphere
// Control changes nothing.
TEST(CigiAssembler, AtmosphereVisibilityAppliesAndABadOneIsRejected) {
  CigiAssembler a({}, kOrigin);
  LinkCounters c;
  Host h;
  ASSERT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  EXPECT_LE(a.state().visibility_m, 0.0);  // not given: the scene's fog
  auto withAtmosphere = [&](float visibility, ByteOrder order) {
    Bytes b = h.message(order);
    AtmosphereControl p;
    p.visibility_m = visibility;
    append(b, p, order);
    return b;
  };
  ASSERT_EQ(a.apply(withAtmosphere(800.0f, ByteOrder::little), c), CigiAssembler::Result::published);
  EXPECT_EQ(a.state().visibility_m, 800.0);
  EXPECT_EQ(c.outOfRange.load(), 0u);
  uint64_t rejected = 0;
  for (float bad : {-10.0f, -std::numeric_limits<float>::infinity(), std::numeric_limits<float>::quiet_NaN()}) {
    ASSERT_EQ(a.apply(withAtmosphere(bad, ByteOrder::big), c), CigiAssembler::Result::published);
    EXPECT_EQ(a.state().visibility_m, 800.0) << bad;
    EXPECT_EQ(c.outOfRange.load(), ++rejected) << bad;
  }
  ASSERT_EQ(a.apply(h.message(), c), CigiAssembler::Result::published);
  EXPECT_EQ(a.state().visibility_m, 800.0);
  struct Clamp {
    float sent;
    double kept;
  };
  for (const Clamp k : {Clamp{0.0f, 1.0}, Clamp{0.25f, 1.0}, Clamp{2e7f, 1e7}, Clamp{std::numeric_limits<float>::max(), 1e7},
                        Clamp{std::numeric_limits<float>::infinity(), 1e7}}) {
    ASSERT_EQ(a.apply(withAtmosphere(k.sent, ByteOrder::little), c), CigiAssembler::Result::published);
    EXPECT_EQ(a.state().visibility_m, k.kept) << k.sent;
  }
  EXPECT_EQ(c.outOfRange.load(), rejected);
  ASSERT_EQ(a.apply(withAtmosphere(25000.0f, ByteOrder::big), c), CigiAssembler::Result::published);
  EXPECT_EQ(a.state().visibility_m, 25000.0);
}

TEST(CigiAssembler, ViewDefinitionAndCelestialSphere) {
  CigiAssembler a({}, kOrigin);
  LinkCounters c;
  Host h;
  ASSERT_EQ(a.apply(h.message(ByteOrder::big, false, true, true), c), CigiAssembler::Result::published);
  // top 25, bottom -20, left -40, right 40: an asymmetric window, in lod::Camera's tangent units.
  constexpr double kRad = M_PI / 180.0;
  const double t = std::tan(25.0 * kRad), b = std::tan(-20.0 * kRad);
  EXPECT_NEAR(2.0 * std::tan(0.5 * a.state().fovY_deg * kRad), t - b, 1e-12);
  EXPECT_NEAR(a.state().windowShiftY, 0.5 * (t + b), 1e-12);
  EXPECT_DOUBLE_EQ(a.state().windowShiftX, 0.0);
  EXPECT_NEAR(a.state().windowWidth_tan, 2.0 * std::tan(40.0 * kRad), 1e-12);
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

// View Definition's left/right make the window off-axis (a side channel of a cabin); the camera
// built from it projects the left and right edges to NDC -1 and +1. A reversed pair is rejected
// and the last good window kept.
TEST(CigiAssembler, ViewDefinitionLeftRightMakeAnOffAxisWindow) {
  CigiAssembler a({}, kOrigin);
  LinkCounters c;
  Host h;
  h.s.def.left_deg = -10.0f;
  h.s.def.right_deg = 50.0f;
  h.s.def.top_deg = 20.0f;
  h.s.def.bottom_deg = -20.0f;
  ASSERT_EQ(a.apply(h.message(ByteOrder::big, false, true), c), CigiAssembler::Result::published);
  const HostState st = a.state();
  EXPECT_DOUBLE_EQ(st.fovY_deg, 40.0);  // symmetric vertically: exactly top - bottom
  EXPECT_DOUBLE_EQ(st.windowShiftY, 0.0);
  EXPECT_GT(st.windowShiftX, 0.3);      // centred right of the view axis
  ig::lod::Camera cam;
  cam.fovY_deg = st.fovY_deg;
  cam.aspect = st.windowWidth_tan / (2.0 * std::tan(20.0 * M_PI / 180.0));
  cam.shiftX = st.windowShiftX;
  cam.shiftY = st.windowShiftY;
  const glm::dmat4 p = ig::lod::projection(cam);
  for (double edge : {-10.0, 50.0}) {
    const glm::dvec4 clip = p * glm::dvec4(std::tan(edge * M_PI / 180.0), 0.0, -1.0, 1.0);
    EXPECT_NEAR(clip.x / clip.w, edge < 0.0 ? -1.0 : 1.0, 1e-6) << edge;
  }
  EXPECT_EQ(c.outOfRange.load(), 0u);
  h.s.def.left_deg = 30.0f;  // right of the right edge
  h.s.def.right_deg = 20.0f;
  ASSERT_EQ(a.apply(h.message(ByteOrder::big, false, true), c), CigiAssembler::Result::published);
  EXPECT_EQ(a.state().windowShiftX, st.windowShiftX);
  EXPECT_EQ(a.state().windowWidth_tan, st.windowWidth_tan);
  EXPECT_EQ(c.outOfRange.load(), 1u);
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

// ---------------------------------------------------------------------------------------------
// HAT/HOT answers from a terrain (the frame loop's side).

namespace {

// A 21 x 21 post plane around the origin, 100 m apart: z = 50 + 0.02 east + 0.01 north (ENU
// metres). Bilinear interpolation reproduces a plane exactly, so the expected HOT is known.
struct Plane {
  std::vector<float> heights;
  ig::lod::HeightGrid grid;
  Plane() {
    for (int y = 0; y < 21; ++y)
      for (int x = 0; x < 21; ++x) heights.push_back(static_cast<float>(z(-1000.0 + 100.0 * x, -1000.0 + 100.0 * y)));
    grid = {heights, 21, 21, 100.0, {-1000.0, -1000.0, 0.0}};
  }
  static double z(double e, double n) { return 50.0 + 0.02 * e + 0.01 * n; }
};

HatHotRequest geodeticRequest(uint16_t id, uint8_t type, double east_m, double north_m, double alt_m, uint8_t period = 0) {
  const ig::lod::Geodetic g = ig::lod::EnuFrame(kOrigin).toGeodetic({east_m, north_m, 0.0});
  HatHotRequest r;
  r.hatHotId = id;
  r.requestType = type;
  r.updatePeriod = period;
  r.lat_deg = g.lat_deg;
  r.lon_deg = g.lon_deg;
  r.alt_m = alt_m;
  return r;
}

// The responses of one frame, decoded.
struct Answers {
  std::vector<HatHotResponse> basic;
  std::vector<HatHotExtendedResponse> extended;
};
Answers answerFrame(CigiHatHotResponder& r, uint32_t igFrame, const ig::lod::HeightGrid* terrain,
                    const HostState* host = nullptr) {
  Bytes buf(CigiHatHotResponder::kMaxBytesPerFrame);
  const size_t n = r.answer(igFrame, 0x1237, terrain, host, ByteOrder::little, buf);
  Answers a;
  for (size_t at = 0; at < n; at += std::to_integer<uint8_t>(buf[at + 1])) {
    const std::span<const std::byte> p(buf.data() + at, n - at);
    if (std::to_integer<uint8_t>(buf[at]) == 102) {
      EXPECT_TRUE(decodePacket(p, ByteOrder::little, a.basic.emplace_back()));
      EXPECT_EQ(a.basic.back().hostFrameLsn, 7);
    } else {
      EXPECT_TRUE(decodePacket(p, ByteOrder::little, a.extended.emplace_back()));
    }
  }
  return a;
}

}  // namespace

TEST(CigiHatHot, AnswersFromTheFullResolutionTerrain) {
  const Plane plane;
  CigiHatHotResponder r(kOrigin);
  // HOT and HAT 224 m from the origin: the ENU plane's drop below the ellipsoid there is 4 mm.
  r.add({geodeticRequest(1, HatHotRequest::kHot, 100.0, 200.0, 0.0), 0}, 5);
  r.add({geodeticRequest(2, HatHotRequest::kHat, 100.0, 200.0, 900.0), 0}, 5);
  r.add({geodeticRequest(3, HatHotRequest::kExtended, -350.0, 420.0, 700.0), 0}, 5);
  r.add({geodeticRequest(4, HatHotRequest::kHot, 1500.0, 0.0, 0.0), 0}, 5);  // outside the terrain
  r.add({geodeticRequest(5, HatHotRequest::kHot, 0.0, 0.0, 0.0), kHatHotLatX}, 5);  // rejected field
  Answers a = answerFrame(r, 5, &plane.grid);
  ASSERT_EQ(a.basic.size(), 4u);
  ASSERT_EQ(a.extended.size(), 1u);
  const double hot1 = kOrigin.height_m + Plane::z(100.0, 200.0);
  EXPECT_TRUE(a.basic[0].valid && a.basic[0].hot);
  EXPECT_NEAR(a.basic[0].height_m, hot1, 0.01);
  EXPECT_TRUE(a.basic[1].valid && !a.basic[1].hot);
  EXPECT_NEAR(a.basic[1].height_m, 900.0 - hot1, 0.01);
  const HatHotExtendedResponse& x = a.extended[0];
  const double hot3 = kOrigin.height_m + Plane::z(-350.0, 420.0);
  EXPECT_TRUE(x.valid);
  EXPECT_NEAR(x.hot_m, hot3, 0.05);  // 547 m out: the ENU plane lies 23 mm above the ellipsoid
  EXPECT_NEAR(x.hat_m, 700.0 - x.hot_m, 1e-9);
  // The normal leans down-slope, towards -east and -north, against the LOCAL vertical there,
  // which leans from the ENU up axis by (east, north) / earth radius: 0.22 deg of azimuth on
  // this gentle slope (without it the azimuth would be -116.565 deg).
  constexpr double kR = 6371000.0, kDeg = 180.0 / std::numbers::pi;
  const double nEast = -0.02 - (-350.0 / kR), nNorth = -0.01 - 420.0 / kR;
  EXPECT_NEAR(x.normalAzimuth_deg, std::atan2(nEast, nNorth) * kDeg, 0.01);
  EXPECT_NEAR(x.normalElevation_deg, 90.0 - std::atan(std::hypot(nEast, nNorth)) * kDeg, 0.001);
  EXPECT_EQ(a.basic[2].hatHotId, 4);
  EXPECT_FALSE(a.basic[2].valid);
  EXPECT_EQ(a.basic[3].hatHotId, 5);
  EXPECT_FALSE(a.basic[3].valid);
  // No terrain: Valid = false.
  r.add({geodeticRequest(6, HatHotRequest::kHot, 0.0, 0.0, 0.0), 0}, 6);
  a = answerFrame(r, 6, nullptr);
  ASSERT_EQ(a.basic.size(), 1u);
  EXPECT_FALSE(a.basic[0].valid);
  // Entity coordinates: 300 m ahead and 100 m right of an ownship at the origin heading east.
  HostState host;
  HatHotRequest e;
  e.hatHotId = 7;
  e.requestType = HatHotRequest::kHat;
  e.entityCoordinates = true;
  e.lat_deg = 300.0;
  e.lon_deg = 100.0;
  e.alt_m = 0.0;
  r.add({e, 0}, 7);
  a = answerFrame(r, 7, &plane.grid, &host);  // no ownship known: invalid
  ASSERT_EQ(a.basic.size(), 1u);
  EXPECT_FALSE(a.basic[0].valid);
  host.hasOwnship = true;
  host.ownshipLat_deg = kOrigin.lat_deg;
  host.ownshipLon_deg = kOrigin.lon_deg;
  host.ownshipAlt_m = kOrigin.height_m + 500.0;
  host.ownshipYaw_deg = 90.0;
  r.add({e, 0}, 8);
  a = answerFrame(r, 8, &plane.grid, &host);
  ASSERT_EQ(a.basic.size(), 1u);
  EXPECT_TRUE(a.basic[0].valid);
  EXPECT_NEAR(a.basic[0].height_m, 500.0 - Plane::z(300.0, -100.0), 0.03);
  EXPECT_EQ(r.answered(), 8u);
  EXPECT_TRUE(r.idle());
}

TEST(CigiHatHot, GroundSamplesTheGridLayersPostsLikeItsHeightAt) {
  // The service hands the "grid" layer's posts to the link as a HeightGrid: the same heights
  // as TerrainGrid::heightAt inside, nothing outside.
  ig::lod::TerrainGridDesc d;
  d.heights.postsX = d.heights.postsY = 33;
  d.heights.postSpacing_m = 25.0;
  d.offset_m = {-400.0, -300.0, 12.0};
  d.chunkQuads = 16;
  const ig::lod::TerrainGrid grid(d);
  const ig::lod::HeightGrid g{grid.heights(), 33, 33, 25.0, d.offset_m};
  ig::lod::GroundSample s;
  for (const auto& [e, n] : {std::pair{-400.0, -300.0}, {-123.4, 56.7}, {399.0, 499.0}, {400.0, 500.0}}) {
    ASSERT_TRUE(ig::lod::sampleGround(g, e, n, s)) << e << " " << n;
    EXPECT_NEAR(s.height_m, grid.heightAt(e, n), 1e-9) << e << " " << n;
  }
  EXPECT_FALSE(ig::lod::sampleGround(g, 400.1, 0.0, s));
  EXPECT_FALSE(ig::lod::sampleGround(g, 0.0, -300.1, s));
  EXPECT_FALSE(ig::lod::sampleGround(g, kNaN, 0.0, s));
}

TEST(CigiHatHot, PeriodicRequestsCancelAndBoundedWorkPerFrame) {
  const Plane plane;
  CigiHatHotResponder r(kOrigin);
  r.add({geodeticRequest(9, HatHotRequest::kHot, 0.0, 0.0, 0.0, 3), 0}, 10);  // every 3rd frame
  std::vector<uint32_t> answeredAt;
  for (uint32_t f = 10; f < 20; ++f) {
    if (f == 15) r.add({geodeticRequest(9, HatHotRequest::kHot, 0.0, 0.0, 0.0, 0), 0}, f);  // cancel (answered once)
    if (!answerFrame(r, f, &plane.grid).basic.empty()) answeredAt.push_back(f);
  }
  EXPECT_EQ(answeredAt, (std::vector<uint32_t>{10, 13, 15}));
  EXPECT_TRUE(r.idle());
  // 40 one-shot requests: 32 answered this frame, 8 the next (counted as deferred).
  for (uint16_t i = 0; i < 40; ++i) r.add({geodeticRequest(i, HatHotRequest::kHot, 0.0, 0.0, 0.0), 0}, 20);
  EXPECT_EQ(answerFrame(r, 20, &plane.grid).basic.size(), CigiHatHotResponder::kMaxAnswersPerFrame);
  EXPECT_EQ(r.deferred(), 8u);
  EXPECT_EQ(answerFrame(r, 21, &plane.grid).basic.size(), 8u);
  // More periodic requests than the table holds: the extra one is refused (answered once).
  for (uint16_t i = 0; i <= CigiHatHotResponder::kMaxPeriodic; ++i)
    r.add({geodeticRequest(static_cast<uint16_t>(100 + i), HatHotRequest::kHot, 0.0, 0.0, 0.0, 200), 0}, 22);
  EXPECT_EQ(r.periodicCount(), CigiHatHotResponder::kMaxPeriodic);
  EXPECT_EQ(r.refused(), 1u);
}


// ---------------------------------------------------------------------------------------------
// Line of sight: LOS Segment / Vector Requests answered from the terrain.

namespace {

ig::lod::Geodetic geodeticOf(glm::dvec3 enu) { return ig::lod::EnuFrame(kOrigin).toGeodetic(enu); }

LosRequest losSegment(uint16_t id, glm::dvec3 from, glm::dvec3 to, bool extended, uint8_t period = 0) {
  const ig::lod::Geodetic a = geodeticOf(from), b = geodeticOf(to);
  LosRequest r;
  r.kind = LosRequest::kSegment;
  r.losId = id;
  r.extended = extended;
  r.updatePeriod = period;
  r.srcLat_deg = a.lat_deg;
  r.srcLon_deg = a.lon_deg;
  r.srcAlt_m = a.height_m;
  r.dstLat_deg = b.lat_deg;
  r.dstLon_deg = b.lon_deg;
  r.dstAlt_m = b.height_m;
  return r;
}

struct LosAnswers {
  std::vector<LosResponse> basic;
  std::vector<LosExtendedResponse> extended;
  size_t bytes = 0;
};
LosAnswers answerLosFrame(CigiHatHotResponder& r, uint32_t igFrame, const ig::lod::HeightGrid* terrain,
                          const HostState* host = nullptr, ByteOrder order = ByteOrder::little) {
  Bytes buf(CigiHatHotResponder::kMaxBytesPerFrame);
  const size_t n = r.answer(igFrame, 0x1233, terrain, host, order, buf);
  LosAnswers a;
  a.bytes = n;
  for (size_t at = 0; at < n; at += std::to_integer<uint8_t>(buf[at + 1])) {
    const std::span<const std::byte> p(buf.data() + at, n - at);
    if (std::to_integer<uint8_t>(buf[at]) == 104) {
      EXPECT_TRUE(decodePacket(p, order, a.basic.emplace_back()));
      EXPECT_EQ(a.basic.back().hostFrameLsn, 3);
    } else if (std::to_integer<uint8_t>(buf[at]) == 105) {
      EXPECT_TRUE(decodePacket(p, order, a.extended.emplace_back()));
      EXPECT_EQ(a.extended.back().hostFrameLsn, 3);
    }
  }
  return a;
}

}  // namespace

TEST(CigiLos, SegmentAnswersTheFirstTerrainIntersection) {
  const Plane plane;
  CigiHatHotResponder r(kOrigin);
  // From 200 m above the ENU origin down through the plane: 200 - 300 t = 50 + 0.02 (400 t) + 0.01 (300 t).
  const glm::dvec3 a{0.0, 0.0, 200.0}, b{400.0, 300.0, -100.0};
  const double t = 150.0 / 311.0;
  r.add(LosJob{losSegment(1, a, b, false), 0}, 5);
  r.add(LosJob{losSegment(2, a, b, true), 0}, 5);
  r.add(LosJob{losSegment(3, a, {500.0, 0.0, 200.0}, true), 0}, 5);           // above the ground all the way
  r.add(LosJob{losSegment(4, a, {100.0, 0.0, Plane::z(100.0, 0.0)}, false), 0}, 5);  // ends on the ground
  r.add(LosJob{losSegment(5, a, b, true), kLosSrcLatX}, 5);                     // a rejected field
  LosAnswers got = answerLosFrame(r, 5, &plane.grid);
  ASSERT_EQ(got.basic.size(), 2u);
  ASSERT_EQ(got.extended.size(), 3u);
  const double range = t * glm::length(b - a);
  EXPECT_EQ(got.basic[0].losId, 1);
  EXPECT_TRUE(got.basic[0].valid);
  EXPECT_FALSE(got.basic[0].visible);
  EXPECT_FALSE(got.basic[0].entityIdValid);
  EXPECT_EQ(got.basic[0].responseCount, 1);
  EXPECT_NEAR(got.basic[0].range_m, range, 1e-3);
  const LosExtendedResponse& x = got.extended[0];
  EXPECT_TRUE(x.valid && x.rangeValid && !x.visible && !x.entityIdValid);
  EXPECT_NEAR(x.range_m, range, 1e-3);
  const ig::lod::Geodetic hit = geodeticOf(a + (b - a) * t);
  EXPECT_NEAR(x.lat_deg, hit.lat_deg, 1e-9);
  EXPECT_NEAR(x.lon_deg, hit.lon_deg, 1e-9);
  EXPECT_NEAR(x.alt_m, hit.height_m, 1e-3);
  EXPECT_EQ(x.materialCode, 0u);
  EXPECT_EQ(x.red + x.green + x.blue + x.alpha, 0);
  // LOS and HOT agree at the hit point, normal included.
  HatHotRequest hot;
  hot.requestType = HatHotRequest::kExtended;
  hot.lat_deg = x.lat_deg;
  hot.lon_deg = x.lon_deg;
  hot.alt_m = x.alt_m;
  const HatHotAnswer h = computeHatHot(hot, ig::lod::EnuFrame(kOrigin), kOrigin.height_m, &plane.grid, nullptr);
  ASSERT_TRUE(h.valid);
  EXPECT_NEAR(h.hot_m, x.alt_m, 1e-3);
  EXPECT_NEAR(h.normalAzimuth_deg, x.normalAzimuth_deg, 1e-3);
  EXPECT_NEAR(h.normalElevation_deg, x.normalElevation_deg, 1e-3);
  // Clear of the ground: not valid, visible. Ending on the ground (to rounding): visible, and
  // where rounding puts the destination a hair below the surface, valid at the destination.
  EXPECT_FALSE(got.extended[1].valid);
  EXPECT_TRUE(got.extended[1].visible);
  EXPECT_EQ(got.basic[1].losId, 4);
  EXPECT_TRUE(got.basic[1].visible);
  if (got.basic[1].valid) {
    EXPECT_NEAR(got.basic[1].range_m, glm::length(glm::dvec3{100.0, 0.0, Plane::z(100.0, 0.0)} - a), 1e-3);
  }
  EXPECT_EQ(got.extended[2].losId, 5);
  EXPECT_FALSE(got.extended[2].valid || got.extended[2].visible);
  // No terrain: not valid.
  r.add(LosJob{losSegment(6, a, b, false), 0}, 6);
  got = answerLosFrame(r, 6, nullptr);
  ASSERT_EQ(got.basic.size(), 1u);
  EXPECT_FALSE(got.basic[0].valid);
  EXPECT_EQ(r.losAnswered(), 6u);
  EXPECT_EQ(r.answered(), 0u);  // HAT/HOT's counter
  EXPECT_TRUE(r.idle());
}

TEST(CigiLos, VectorAndEntityCoordinates) {
  const Plane plane;
  CigiHatHotResponder r(kOrigin);
  // 300 m above the origin, due east, 45 deg down: 300 - s sin45 = 50 + 0.02 s cos45.
  const ig::lod::Geodetic src = geodeticOf({0.0, 0.0, 300.0});
  LosRequest v;
  v.kind = LosRequest::kVector;
  v.losId = 7;
  v.extended = true;
  v.srcLat_deg = src.lat_deg;
  v.srcLon_deg = src.lon_deg;
  v.srcAlt_m = src.height_m;
  v.azimuth_deg = 90.0f;
  v.elevation_deg = -45.0f;
  v.minRange_m = 10.0f;
  v.maxRange_m = 1000.0f;
  r.add(LosJob{v, 0}, 1);
  LosRequest shortVector = v;
  shortVector.losId = 8;
  shortVector.maxRange_m = 300.0f;  // stops short of the ground
  r.add(LosJob{shortVector, 0}, 1);
  LosAnswers got = answerLosFrame(r, 1, &plane.grid, nullptr, ByteOrder::big);
  ASSERT_EQ(got.extended.size(), 2u);
  const double s = 250.0 / (std::sqrt(0.5) * 1.02);
  EXPECT_TRUE(got.extended[0].valid);
  EXPECT_FALSE(got.extended[0].visible);
  EXPECT_NEAR(got.extended[0].range_m, s, 1e-3);
  const ig::lod::Geodetic hit = geodeticOf({s * std::sqrt(0.5), 0.0, 300.0 - s * std::sqrt(0.5)});
  EXPECT_NEAR(got.extended[0].lat_deg, hit.lat_deg, 1e-8);
  EXPECT_NEAR(got.extended[0].lon_deg, hit.lon_deg, 1e-8);
  EXPECT_NEAR(got.extended[0].alt_m, hit.height_m, 1e-3);
  EXPECT_FALSE(got.extended[1].valid);
  // Entity coordinates: an ownship 500 m above the origin heading east; from the ownship to 1 km
  // ahead and 1 km down: 500 - d = 50 + 0.02 d. Response point as offsets in body axes.
  HostState host;
  LosRequest e;
  e.kind = LosRequest::kSegment;
  e.losId = 9;
  e.extended = true;
  e.sourceEntity = e.destinationEntity = e.responseEntity = true;
  e.dstLat_deg = 1000.0;
  e.dstAlt_m = 1000.0;
  r.add(LosJob{e, 0}, 2);
  got = answerLosFrame(r, 2, &plane.grid, &host);  // no ownship yet: not valid
  ASSERT_EQ(got.extended.size(), 1u);
  EXPECT_FALSE(got.extended[0].valid);
  host.hasOwnship = true;
  host.ownshipLat_deg = kOrigin.lat_deg;
  host.ownshipLon_deg = kOrigin.lon_deg;
  host.ownshipAlt_m = kOrigin.height_m + 500.0;
  host.ownshipYaw_deg = 90.0;
  r.add(LosJob{e, 0}, 3);
  got = answerLosFrame(r, 3, &plane.grid, &host);
  ASSERT_EQ(got.extended.size(), 1u);
  const double d = 450.0 / 1.02;
  EXPECT_TRUE(got.extended[0].valid);
  EXPECT_NEAR(got.extended[0].range_m, d * std::sqrt(2.0), 1e-3);
  EXPECT_NEAR(got.extended[0].lat_deg, d, 1e-3);  // x forward
  EXPECT_NEAR(got.extended[0].lon_deg, 0.0, 1e-3);
  EXPECT_NEAR(got.extended[0].alt_m, d, 1e-3);    // z down
}

TEST(CigiLos, PeriodicCancelAndAByteCapPerDatagram) {
  const Plane plane;
  CigiHatHotResponder r(kOrigin);
  const glm::dvec3 a{0.0, 0.0, 200.0}, b{400.0, 300.0, -100.0};
  r.add(LosJob{losSegment(9, a, b, false, 3), 0}, 10);  // every 3rd frame
  r.add(HatHotJob{geodeticRequest(9, HatHotRequest::kHot, 0.0, 0.0, 0.0, 0), 0}, 10);  // not the same ID space
  std::vector<uint32_t> answeredAt;
  for (uint32_t f = 10; f < 20; ++f) {
    if (f == 15) r.add(LosJob{losSegment(9, a, b, false, 0), 0}, f);  // cancel (answered once)
    if (!answerLosFrame(r, f, &plane.grid).basic.empty()) answeredAt.push_back(f);
  }
  EXPECT_EQ(answeredAt, (std::vector<uint32_t>{10, 13, 15}));
  EXPECT_TRUE(r.idle());
  EXPECT_EQ(r.answered(), 1u);
  // 40 extended requests: 25 x 56 bytes fit one datagram with its Start of Frame (1,472 bytes).
  for (uint16_t i = 0; i < 40; ++i) r.add(LosJob{losSegment(i, a, b, true), 0}, 20);
  LosAnswers got = answerLosFrame(r, 20, &plane.grid);
  EXPECT_EQ(got.extended.size(), 25u);
  EXPECT_LE(kStartOfFrameSize + got.bytes, 1472u);
  EXPECT_EQ(r.losDeferred(), 15u);
  EXPECT_EQ(answerLosFrame(r, 21, &plane.grid).extended.size(), 15u);
  // A full table of periodic requests refuses the next one (answered once).
  for (uint16_t i = 0; i <= CigiHatHotResponder::kMaxPeriodic; ++i) r.add(LosJob{losSegment(100 + i, a, b, false, 200), 0}, 22);
  EXPECT_EQ(r.periodicCount(), CigiHatHotResponder::kMaxPeriodic);
  EXPECT_EQ(r.losRefused(), 1u);
  EXPECT_EQ(r.refused(), 0u);
}

// A LOS answer costs the grid cells its ray crosses: a frame answers rays until it has examined
// kMaxQueryWorkPerFrame cells (always one), the rest wait for the next frames, and nothing is lost.
TEST(CigiLos, AFrameStopsAnsweringRaysOnceItsCellBudgetIsSpent) {
  const int n = 1025;  // 1 m posts, flat at 0: each ray below passes 2,000 cells above the ground
  const std::vector<float> heights(static_cast<size_t>(n) * n, 0.0f);
  const ig::lod::HeightGrid grid{heights, n, n, 1.0, {-512.0, -512.0, 0.0}};
  const glm::dvec3 a{-500.0, -500.0, 100.0}, b{500.0, 500.0, 50.0};
  ig::lod::GroundHit hit;
  uint32_t cellsPerRay = 0;
  ASSERT_FALSE(ig::lod::intersectGround(grid, a, b, hit, &cellsPerRay));
  ASSERT_GE(cellsPerRay, 1999u);
  ASSERT_LE(cellsPerRay, 2001u);
  CigiHatHotResponder r(kOrigin);
  for (uint16_t i = 0; i < 20; ++i) r.add(LosJob{losSegment(i, a, b, false), 0}, 1);
  // Rays while fewer than the budget's cells are spent: k with (k - 1) x cells < budget.
  const size_t perFrame = (CigiHatHotResponder::kMaxQueryWorkPerFrame + cellsPerRay - 1) / cellsPerRay;
  ASSERT_LT(perFrame, 20u);
  std::vector<size_t> answered;
  std::vector<uint16_t> ids;
  for (uint32_t f = 1; f <= 5 && !r.idle(); ++f) {
    const LosAnswers got = answerLosFrame(r, f, &grid);
    answered.push_back(got.basic.size());
    for (const LosResponse& x : got.basic) {
      ids.push_back(x.losId);
      EXPECT_FALSE(x.valid);  // above the flat ground all the way
      EXPECT_TRUE(x.visible);
    }
  }
  EXPECT_EQ(answered, (std::vector<size_t>{perFrame, perFrame, 20 - 2 * perFrame}));
  std::vector<uint16_t> all(20);
  for (uint16_t i = 0; i < 20; ++i) all[i] = i;
  EXPECT_EQ(ids, all) << "in queue order, each once";
  EXPECT_EQ(r.losAnswered(), 20u);
  EXPECT_EQ(r.losDeferred(), (20 - perFrame) + (20 - 2 * perFrame));
}

TEST(CigiAssembler, LosRequestsAreValidatedLikeHatHot) {
  CigiAssembler a({}, kOrigin);
  LinkCounters c;
  Host h;
  Bytes b = h.message();
  LosRequest good = losSegment(1, {0.0, 0.0, 200.0}, {100.0, 0.0, 0.0}, false);
  LosRequest nan = good;
  nan.losId = 2;
  nan.dstAlt_m = kNaN;
  LosRequest other = good;  // entity coordinates of an entity igd does not know
  other.losId = 3;
  other.sourceEntity = true;
  other.srcLat_deg = other.srcLon_deg = other.srcAlt_m = 0.0;
  other.entityId = 9;
  LosRequest vec;
  vec.kind = LosRequest::kVector;
  vec.losId = 4;
  vec.elevation_deg = 91.0f;
  vec.maxRange_m = 100.0f;
  for (const LosRequest& r : {good, nan, other, vec}) append(b, r, ByteOrder::big);
  ASSERT_EQ(a.apply(b, c), CigiAssembler::Result::published);
  const CigiAssembler::LosJobs jobs = a.losJobs();
  ASSERT_EQ(jobs.requests.size(), 4u);
  EXPECT_EQ(jobs.bad[0], 0u);
  EXPECT_EQ(jobs.bad[1], uint32_t{kLosDstAltZ});
  EXPECT_EQ(jobs.bad[2], CigiAssembler::kLosUnknownEntity);
  EXPECT_EQ(jobs.bad[3], uint32_t{kLosElevation});
  EXPECT_EQ(c.outOfRange.load(), 3u);
}

// ---------------------------------------------------------------------------------------------
// HAT/HOT and LOS against the scene's objects (io::SceneSurfaces; igd: the [hdlod] objects).

namespace {

// On the Plane: a slab 16 m above the ground at (100, 200) (a bridge deck, z 70 ... 71) and a
// tower 10 x 10 x 40 m standing on the ground at (-300, 0) (z 44 ... 84).
struct Objects final : ig::io::SceneSurfaces {
  ig::lod::hdlod::Scene scene;
  ig::lod::hdlod::SceneRays rays;
  Objects() {
    namespace hd = ig::lod::hdlod;
    scene.duration_s = 1.0;
    scene.models = {hd::makeBoxModel("deck", {20.0, 20.0, 1.0}), hd::makeBoxModel("tower", {10.0, 10.0, 40.0})};
    hd::Object deck, tower;
    deck.name = "deck";
    deck.visible = {{0.0, 1.0}};
    deck.path = {{0.0, {100.0, 200.0, 70.0}, 0.0}};
    tower.name = "tower";
    tower.model = 1;
    tower.visible = {{0.0, 1.0}};
    tower.path = {{0.0, {-300.0, 0.0, Plane::z(-300.0, 0.0)}, 0.0}};
    scene.objects = {deck, tower};
    rays = hd::SceneRays(scene);
  }
  Objects(const Objects&) = delete;
  bool intersect(const glm::dvec3& from, const glm::dvec3& to, SurfaceMask mask, SurfaceHit& hit, uint32_t* work) const override {
    if (!(mask & surfaceBit(kSurfaceObject))) return false;
    ig::lod::hdlod::RayHit h;
    ig::lod::hdlod::RayWork w;
    const bool found = rays.intersect(from, to, 0.5, h, &w);
    if (work) *work += w.nodes + w.triangles;
    if (found) hit = {h.t, h.point_m, h.normal, kSurfaceObject};
    return found;
  }
  double top_m() const override { return rays.top_m(); }
};

}  // namespace

TEST(CigiObjects, HatHotFindsRoofsAndTheGroundUnderABridge) {
  const Plane plane;
  const Objects objects;
  const ig::lod::EnuFrame enu(kOrigin);
  const QueryScene scene(&plane.grid, &objects);
  const double h0 = kOrigin.height_m;
  // HOT over the deck: its top. From 200 m (extended): the same, material "object", normal up.
  HatHotAnswer a = computeHatHot(geodeticRequest(1, HatHotRequest::kHot, 100.0, 200.0, 0.0), enu, h0, scene, nullptr);
  ASSERT_TRUE(a.valid);
  EXPECT_NEAR(a.hot_m, h0 + 71.0, 0.02);
  EXPECT_EQ(a.materialCode, kMaterialObject);
  a = computeHatHot(geodeticRequest(2, HatHotRequest::kExtended, 100.0, 200.0, h0 + 200.0), enu, h0, scene, nullptr);
  EXPECT_NEAR(a.hot_m, h0 + 71.0, 0.02);
  EXPECT_NEAR(a.hat_m, 200.0 - 71.0, 0.02);
  EXPECT_NEAR(a.normalElevation_deg, 90.0, 0.1);
  // Under the deck (at 60 m): the ground, 54 m; material "terrain".
  a = computeHatHot(geodeticRequest(3, HatHotRequest::kHat, 100.0, 200.0, h0 + 60.0), enu, h0, scene, nullptr);
  ASSERT_TRUE(a.valid);
  EXPECT_NEAR(a.hat_m, 60.0 - Plane::z(100.0, 200.0), 0.02);
  EXPECT_EQ(a.materialCode, kMaterialTerrain);
  // The tower's roof; beside it the ground; without the objects the ground everywhere.
  a = computeHatHot(geodeticRequest(4, HatHotRequest::kHot, -300.0, 0.0, 0.0), enu, h0, scene, nullptr);
  EXPECT_NEAR(a.hot_m, h0 + Plane::z(-300.0, 0.0) + 40.0, 0.02);
  a = computeHatHot(geodeticRequest(5, HatHotRequest::kHot, -310.0, 0.0, 0.0), enu, h0, scene, nullptr);
  EXPECT_NEAR(a.hot_m, h0 + Plane::z(-310.0, 0.0), 0.02);
  a = computeHatHot(geodeticRequest(6, HatHotRequest::kHot, -300.0, 0.0, 0.0), enu, h0, &plane.grid, nullptr);
  EXPECT_NEAR(a.hot_m, h0 + Plane::z(-300.0, 0.0), 0.02);
  EXPECT_EQ(a.materialCode, kMaterialTerrain);
}

TEST(CigiObjects, LineOfSightStopsAtTheNearerOfObjectAndTerrain) {
  const Plane plane;
  const Objects objects;
  CigiHatHotResponder r(kOrigin);
  // Level at 60 m from the west towards the tower: its west wall at x = -305, facing west.
  const glm::dvec3 a{-400.0, 0.0, 60.0}, b{-200.0, 0.0, 60.0};
  r.add(LosJob{losSegment(1, a, b, true), 0}, 5);
  r.add(LosJob{losSegment(2, a, b, false), 0}, 5);
  // Down through the deck (it shadows the ground below it) and past it (the ground).
  r.add(LosJob{losSegment(3, {100.0, 200.0, 200.0}, {100.0, 200.0, 0.0}, true), 0}, 5);
  r.add(LosJob{losSegment(4, {130.0, 200.0, 200.0}, {130.0, 200.0, 0.0}, true), 0}, 5);
  // Over the tower: clear.
  r.add(LosJob{losSegment(5, {-400.0, 0.0, 120.0}, {-200.0, 0.0, 120.0}, false), 0}, 5);
  // The host's material mask: terrain only (bit 0) sees through the tower (and stays above the
  // ground); objects only (bit 1) sees through the ground beside the deck, and meets the tower.
  LosRequest terrainOnly = losSegment(6, a, b, false), objectsOnly = losSegment(7, {130.0, 200.0, 200.0}, {130.0, 200.0, 0.0}, false);
  terrainOnly.materialMask = 1u << kMaterialTerrain;
  objectsOnly.materialMask = 1u << kMaterialObject;
  LosRequest towerOnly = losSegment(8, a, b, false);
  towerOnly.materialMask = 1u << kMaterialObject;
  r.add(LosJob{terrainOnly, 0}, 5);
  r.add(LosJob{objectsOnly, 0}, 5);
  r.add(LosJob{towerOnly, 0}, 5);
  Bytes buf(CigiHatHotResponder::kMaxBytesPerFrame);
  const size_t n = r.answer(5, 0x1233, QueryScene(&plane.grid, &objects), nullptr, ByteOrder::little, buf);
  std::vector<LosExtendedResponse> x;
  std::vector<LosResponse> basic;
  for (size_t at = 0; at < n; at += std::to_integer<uint8_t>(buf[at + 1])) {
    const std::span<const std::byte> p(buf.data() + at, n - at);
    if (std::to_integer<uint8_t>(buf[at]) == 105) EXPECT_TRUE(decodePacket(p, ByteOrder::little, x.emplace_back()));
    else EXPECT_TRUE(decodePacket(p, ByteOrder::little, basic.emplace_back()));
  }
  ASSERT_EQ(x.size(), 3u);
  ASSERT_EQ(basic.size(), 5u);
  EXPECT_TRUE(basic[2].visible && !basic[2].valid);  // terrain only: through the tower, above the ground
  EXPECT_TRUE(basic[3].visible && !basic[3].valid);  // objects only: through the ground
  EXPECT_TRUE(basic[4].valid && !basic[4].visible);  // objects only: the tower
  EXPECT_NEAR(basic[4].range_m, 95.0, 1e-3);
  EXPECT_TRUE(x[0].valid && !x[0].visible);
  EXPECT_NEAR(x[0].range_m, 95.0, 1e-3);
  EXPECT_EQ(x[0].materialCode, kMaterialObject);
  EXPECT_NEAR(x[0].normalAzimuth_deg, -90.0, 0.1);  // west
  EXPECT_NEAR(x[0].normalElevation_deg, 0.0, 0.1);
  EXPECT_NEAR(x[0].lon_deg, geodeticOf({-305.0, 0.0, 60.0}).lon_deg, 1e-9);
  EXPECT_TRUE(basic[0].valid && !basic[0].visible);
  EXPECT_NEAR(basic[0].range_m, 95.0, 1e-3);
  EXPECT_NEAR(x[1].range_m, 129.0, 1e-3);  // the deck's top at 71 m
  EXPECT_EQ(x[1].materialCode, kMaterialObject);
  EXPECT_NEAR(x[2].range_m, 200.0 - Plane::z(130.0, 200.0), 1e-3);
  EXPECT_EQ(x[2].materialCode, kMaterialTerrain);
  EXPECT_TRUE(basic[1].visible);
  EXPECT_FALSE(basic[1].valid);
}

// HAT/HOT answers share the frame's work budget: with objects that cost 5,000 units a query, a
// frame answers requests until kMaxQueryWorkPerFrame is spent (always one), the rest wait for the
// next frames in queue order, and nothing is lost. Without objects a HOT costs 2 (two samples).
TEST(CigiObjects, HatHotAnswersShareTheFramesWorkBudget) {
  struct Costly final : SceneSurfaces {
    bool intersect(const glm::dvec3&, const glm::dvec3&, SurfaceMask, SurfaceHit&, uint32_t* work) const override {
      if (work) *work += 5000;
      return false;
    }
    double top_m() const override { return 500.0; }
  } costly;
  const Plane plane;
  const HatHotAnswer cheap = computeHatHot(geodeticRequest(1, HatHotRequest::kHot, 100.0, 200.0, 0.0),
                                           ig::lod::EnuFrame(kOrigin), kOrigin.height_m, &plane.grid, nullptr);
  EXPECT_EQ(cheap.work, 2u);
  CigiHatHotResponder r(kOrigin);
  for (uint16_t i = 0; i < 20; ++i) r.add({geodeticRequest(i, HatHotRequest::kHot, 100.0, 200.0, 0.0), 0}, 1);
  const size_t perFrame = (CigiHatHotResponder::kMaxQueryWorkPerFrame + 5001) / 5002;  // (k - 1) x 5002 < budget
  ASSERT_EQ(perFrame, 4u);
  std::vector<size_t> answered;
  std::vector<uint16_t> ids;
  for (uint32_t f = 1; f <= 10 && !r.idle(); ++f) {
    Bytes buf(CigiHatHotResponder::kMaxBytesPerFrame);
    const size_t n = r.answer(f, 0x1237, QueryScene(&plane.grid, &costly), nullptr, ByteOrder::little, buf);
    size_t count = 0;
    for (size_t at = 0; at < n; at += std::to_integer<uint8_t>(buf[at + 1])) {
      HatHotResponse x;
      ASSERT_TRUE(decodePacket(std::span<const std::byte>(buf.data() + at, n - at), ByteOrder::little, x));
      EXPECT_TRUE(x.valid);  // the objects were missed: the ground
      ids.push_back(x.hatHotId);
      ++count;
    }
    answered.push_back(count);
  }
  EXPECT_EQ(answered, (std::vector<size_t>{4, 4, 4, 4, 4}));
  std::vector<uint16_t> all(20);
  for (uint16_t i = 0; i < 20; ++i) all[i] = i;
  EXPECT_EQ(ids, all) << "in queue order, each once";
  EXPECT_EQ(r.answered(), 20u);
  EXPECT_EQ(r.deferred(), 16u + 12u + 8u + 4u);
}
