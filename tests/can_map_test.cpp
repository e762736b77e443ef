// SocketCAN frame map: codec round trip and exact bytes, field-by-field rejection, set assembly
// (complete, reordered, incomplete, newer counter drops the old set, late, duplicate, stale with
// a fake clock, counter wrap and resync), candump line parsing (good and bad lines), candump
// logs to recordings (including a log written by the real candump inside user-mode Linux), the
// DBC file against the C++ map, config validation and the transport's start-up errors.
#include <gtest/gtest.h>

#include <algorithm>
#include <glm/geometric.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>

#include "io/can_link.h"
#include "io/can_map.h"
#include "scene_attitude.h"
#ifdef IG_TEST_WITH_CIGI
#include "io/cigi.h"
#include "io/cigi_link.h"
#endif

using namespace ig::io;

namespace {

const ig::lod::Geodetic kOrigin{47.25, 11.35, 600.0};
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

CanEyeSet sampleSet() {
  CanEyeSet s;
  s.lat_deg = 47.2612345;
  s.lon_deg = 11.3598765;
  s.height_m = 1523.456;
  s.heading_deg = 271.25;
  s.pitch_deg = -3.5;
  s.roll_deg = 12.75;
  s.simTime_s = 36000.125;
  s.hostFrame = 0x123456;
  s.visibility_m = 4321.0;
  s.timeOfDay_h = 13.5;
  return s;
}

// The attitude HostState must carry for an attitude sent at (lat, lon), in kOrigin's axes
// (computed independently of igd's conversion).
ig::test::SceneAttitude expectedAttitude(double lat, double lon, double heading, double pitch, double roll) {
  return ig::test::sceneAttitude(kOrigin.lat_deg, kOrigin.lon_deg, lat, lon, heading, pitch, roll);
}

std::array<CanFrame, kCanFrameCount> encode(const CanEyeSet& s, uint8_t seq, uint32_t base = 0x100) {
  std::array<CanFrame, kCanFrameCount> f;
  encodeCanSet(s, seq, base, f);
  return f;
}

// A candump -l line for a frame (classic data frames only).
std::string candumpLine(const CanFrame& f, int64_t t_us, const char* ifname = "vcan0") {
  char buf[128];
  int n = std::snprintf(buf, sizeof buf, "(%lld.%06lld) %s %03X#", static_cast<long long>(t_us / 1000000),
                        static_cast<long long>(t_us % 1000000), ifname, f.id);
  for (int i = 0; i < f.len; ++i) n += std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), "%02X", f.data[static_cast<size_t>(i)]);
  return std::string(buf) + "\n";
}

struct Assembly {
  CanLinkConfig config;
  LinkCounters counters;
  CanSetAssembler assembler{config, kOrigin, counters};
  HostState out;
  int commits = 0;
  CanSetAssembler::Result push(const CanFrame& f, int64_t t_us) {
    const auto r = assembler.push(f, t_us, out);
    if (r == CanSetAssembler::Result::Committed) ++commits;
    return r;
  }
  void pushAll(const std::array<CanFrame, kCanFrameCount>& frames, int64_t t_us) {
    for (const CanFrame& f : frames) push(f, t_us);
  }
  LinkCountersSnapshot c() const { return snapshot(counters); }
  // Commits sampleSet() edited by `edit` with counter `seq` (at 1 ms x seq) and returns the state.
  template <class Edit>
  const HostState& commitEdited(uint8_t seq, Edit edit) {
    CanEyeSet s = sampleSet();
    edit(s);
    pushAll(encode(s, seq), 1000 * int64_t{seq});
    return out;
  }
};

// Decodes every frame of a set (base id 0x100) into `out`; returns the fields rejected.
int decodeAll(const std::array<CanFrame, kCanFrameCount>& frames, CanEyeSet& out) {
  int rejected = 0;
  for (const CanFrame& fr : frames) {
    CanDecodedFrame d;
    EXPECT_EQ(decodeCanFrame(fr, 0x100, d, out), CanDecodeStatus::Ok);
    rejected += d.rejectedFields;
  }
  return rejected;
}

// The uint24 in bytes 5-7 of a frame (the time of day, the visibility), little-endian.
uint32_t u24(const CanFrame& f) { return f.data[5] | uint32_t{f.data[6]} << 8 | uint32_t{f.data[7]} << 16; }
void putU24(CanFrame& f, uint32_t v) {
  f.data[5] = static_cast<uint8_t>(v);
  f.data[6] = static_cast<uint8_t>(v >> 8);
  f.data[7] = static_cast<uint8_t>(v >> 16);
}

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Codec

TEST(CanMap, RoundTripWithinHalfAStep) {
  const CanEyeSet in = sampleSet();
  const auto frames = encode(in, 42);
  CanEyeSet out;
  for (int i = 0; i < kCanFrameCount; ++i) {
    CanDecodedFrame d;
    ASSERT_EQ(decodeCanFrame(frames[static_cast<size_t>(i)], 0x100, d, out), CanDecodeStatus::Ok);
    EXPECT_EQ(d.seq, 42);
    EXPECT_EQ(static_cast<int>(d.index), i);
    EXPECT_EQ(d.rejectedFields, 0);
  }
  EXPECT_NEAR(out.lat_deg, in.lat_deg, 0.5e-7);
  EXPECT_NEAR(out.lon_deg, in.lon_deg, 0.5e-7);
  EXPECT_NEAR(out.height_m, in.height_m, 0.5e-3);
  EXPECT_NEAR(out.heading_deg, in.heading_deg, 0.005);
  EXPECT_NEAR(out.pitch_deg, in.pitch_deg, 0.005);
  EXPECT_NEAR(out.roll_deg, in.roll_deg, 0.005);
  EXPECT_NEAR(out.simTime_s, in.simTime_s, 0.5e-3);
  EXPECT_EQ(out.hostFrame, 0x123456u);
}

TEST(CanMap, RoundTripAtTheLimits) {
  for (double lat : {-90.0, 90.0, 0.0, -0.0000001}) {
    for (double lon : {-180.0, 180.0, 179.9999999, -179.9999999}) {
      CanEyeSet in = sampleSet();
      in.lat_deg = lat;
      in.lon_deg = lon;
      in.height_m = -1000.0;
      in.pitch_deg = 90.0;
      in.roll_deg = -180.0;
      in.heading_deg = 359.99;
      const auto frames = encode(in, 0);
      CanEyeSet out;
      CanDecodedFrame d;
      for (const CanFrame& f : frames) ASSERT_EQ(decodeCanFrame(f, 0x100, d, out), CanDecodeStatus::Ok);
      EXPECT_NEAR(out.lat_deg, lat, 0.5e-7);
      EXPECT_NEAR(out.lon_deg, lon, 0.5e-7);
      EXPECT_DOUBLE_EQ(out.height_m, -1000.0);
      EXPECT_DOUBLE_EQ(out.pitch_deg, 90.0);
      EXPECT_DOUBLE_EQ(out.roll_deg, -180.0);
      EXPECT_DOUBLE_EQ(out.heading_deg, 359.99);
    }
  }
}

TEST(CanMap, ExactBytesLittleEndian) {
  CanEyeSet s;
  s.lat_deg = 47.0;          // 470000000 = 0x1C03_A180
  s.lon_deg = -1.0;          // -10000000 = 0xFF67_6980
  s.height_m = 1.5;          // 1500 = 0x5DC
  s.heading_deg = -90.0;     // wraps to 270.00 -> 27000 = 0x6978
  s.pitch_deg = -0.01;       // -1 = 0xFFFF
  s.roll_deg = 1.0;          // 100 = 0x64
  s.simTime_s = 65.536;      // 65536 = 0x10000
  s.hostFrame = 0x1ABCDEF;   // only 0xABCDEF travels
  const auto f = encode(s, 0xA5, 0x300);
  const std::array<std::array<uint8_t, 8>, 5> want{{
      {0xA5, 0x80, 0xA1, 0x03, 0x1C, 0, 0, 0},
      {0xA5, 0x80, 0x69, 0x67, 0xFF, 0, 0, 0},
      {0xA5, 0xDC, 0x05, 0x00, 0x00, 0, 0, 0},
      {0xA5, 0x78, 0x69, 0xFF, 0xFF, 0x64, 0x00, 0},
      {0xA5, 0x00, 0x00, 0x01, 0x00, 0xEF, 0xCD, 0xAB},
  }};
  for (size_t i = 0; i < 5; ++i) {
    EXPECT_EQ(f[i].id, 0x300 + i);
    EXPECT_EQ(f[i].len, 8);
    EXPECT_FALSE(f[i].extended || f[i].remote || f[i].fd || f[i].error);
    for (size_t b = 0; b < 8; ++b) EXPECT_EQ(f[i].data[b], want[i][b]) << "frame " << i << " byte " << b;
  }
}

// Finite values outside the valid range are saturated to the raw type, never wrapped into it and
// never sent as "not available": the receiver sees an out-of-range raw value and rejects it.
TEST(CanMap, FiniteValuesSaturateToTheRawType) {
  CanEyeSet s = sampleSet();
  // 2^32 + 470000000 steps: wrapped to 32 bits it would be 47.0 deg, a valid latitude.
  s.lat_deg = 429.4967296 + 47.0;
  s.lon_deg = -500.0;          // below INT32_MIN + 1 steps
  s.pitch_deg = -400.0;        // below INT16_MIN + 1 steps
  s.roll_deg = 400.0;          // above INT16_MAX steps
  s.simTime_s = 1e10;          // above the largest uint32 below "not available"
  const auto f = encode(s, 1);
  auto u32 = [](const CanFrame& fr) {
    return static_cast<uint32_t>(fr.data[1] | fr.data[2] << 8 | fr.data[3] << 16) | static_cast<uint32_t>(fr.data[4]) << 24;
  };
  EXPECT_EQ(u32(f[0]), 0x7FFFFFFFu);
  EXPECT_EQ(u32(f[1]), 0x80000001u);  // INT32_MIN + 1: INT32_MIN is "not available"
  EXPECT_EQ(f[3].data[3] | f[3].data[4] << 8, 0x8001);
  EXPECT_EQ(f[3].data[5] | f[3].data[6] << 8, 0x7FFF);
  EXPECT_EQ(u32(f[4]), 0xFFFFFFFEu);  // 0xFFFFFFFF is "not available"
  CanEyeSet out;
  const int rejected = decodeAll(f, out);
  EXPECT_EQ(rejected, 4);  // lat, lon, pitch, roll; sim time 4294967.294 s is the largest valid
  EXPECT_TRUE(std::isnan(out.lat_deg));
  EXPECT_DOUBLE_EQ(out.simTime_s, 4294967.294);
}

// Heading is wrapped into [0, 360) before rounding, and a value that rounds up to 360.00 is sent
// as 0.00 (the raw 36000 would be rejected).
TEST(CanMap, HeadingThatRoundsTo360IsSentAsZero) {
  for (double h : {359.996, -0.001, 719.999}) {
    CanEyeSet s = sampleSet();
    s.heading_deg = h;
    const auto f = encode(s, 1);
    EXPECT_EQ(f[3].data[1] | f[3].data[2] << 8, 0) << h;
    CanEyeSet out;
    CanDecodedFrame d;
    ASSERT_EQ(decodeCanFrame(f[3], 0x100, d, out), CanDecodeStatus::Ok);
    EXPECT_EQ(d.rejectedFields, 0) << h;
    EXPECT_EQ(out.heading_deg, 0.0) << h;
  }
}

// The decoder sets every member of its CanDecodedFrame: one reused across frames does not carry
// the previous frame's rejections.
TEST(CanMap, DecodedFrameIsResetForEachFrame) {
  CanEyeSet bad = sampleSet();
  bad.pitch_deg = kNaN;
  bad.roll_deg = kNaN;
  const auto fb = encode(bad, 1);
  const auto fg = encode(sampleSet(), 2);
  CanDecodedFrame d;
  CanEyeSet out;
  ASSERT_EQ(decodeCanFrame(fb[3], 0x100, d, out), CanDecodeStatus::Ok);
  EXPECT_EQ(d.rejectedFields, 2);
  ASSERT_EQ(decodeCanFrame(fg[3], 0x100, d, out), CanDecodeStatus::Ok);
  EXPECT_EQ(d.rejectedFields, 0);
  EXPECT_EQ(d.seq, 2);
  EXPECT_EQ(d.index, CanFrameIndex::Attitude);
}

TEST(CanMap, NanEncodesAsNotAvailableAndDecodesAsRejected) {
  CanEyeSet in = sampleSet();
  in.lat_deg = kNaN;
  in.lon_deg = std::numeric_limits<double>::infinity();
  in.height_m = kNaN;
  in.heading_deg = kNaN;
  in.pitch_deg = kNaN;
  in.roll_deg = -std::numeric_limits<double>::infinity();
  in.simTime_s = kNaN;
  const auto f = encode(in, 1);
  EXPECT_EQ(f[0].data[4], 0x80);  // INT32_MIN
  EXPECT_EQ(f[3].data[1], 0xFF);  // heading 0xFFFF
  EXPECT_EQ(f[3].data[2], 0xFF);
  CanEyeSet out;
  const int rejected = decodeAll(f, out);
  EXPECT_EQ(rejected, 7);
  EXPECT_TRUE(std::isnan(out.lat_deg) && std::isnan(out.lon_deg) && std::isnan(out.height_m));
  EXPECT_TRUE(std::isnan(out.heading_deg) && std::isnan(out.pitch_deg) && std::isnan(out.roll_deg));
  EXPECT_TRUE(std::isnan(out.simTime_s));
}

TEST(CanMap, OutOfRangeRawValuesAreRejectedOneByOne) {
  struct Case {
    const char* what;
    CanEyeSet set;
  };
  std::vector<Case> cases;
  auto with = [](auto edit) {
    CanEyeSet s = sampleSet();
    edit(s);
    return s;
  };
  cases.push_back({"lat 90.0000001", with([](CanEyeSet& s) { s.lat_deg = 90.0000001; })});
  cases.push_back({"lat -95", with([](CanEyeSet& s) { s.lat_deg = -95; })});
  cases.push_back({"lon 180.0000001", with([](CanEyeSet& s) { s.lon_deg = 180.0000001; })});
  cases.push_back({"height -1000.001", with([](CanEyeSet& s) { s.height_m = -1000.001; })});
  cases.push_back({"height 1e6+0.001", with([](CanEyeSet& s) { s.height_m = 1e6 + 0.001; })});
  cases.push_back({"pitch 90.01", with([](CanEyeSet& s) { s.pitch_deg = 90.01; })});
  cases.push_back({"roll -180.01", with([](CanEyeSet& s) { s.roll_deg = -180.01; })});
  cases.push_back({"visibility NaN", with([](CanEyeSet& s) { s.visibility_m = kNaN; })});
  for (const Case& c : cases) {
    Assembly a;
    a.pushAll(encode(sampleSet(), 1), 0);
    ASSERT_EQ(a.commits, 1);
    const HostState good = a.out;
    a.pushAll(encode(c.set, 2), 1000);
    ASSERT_EQ(a.commits, 2) << c.what;
    EXPECT_EQ(a.c().outOfRange, 1u) << c.what;
    EXPECT_EQ(a.c().accepted, 2u) << c.what;
    // The rejected field kept its last good value, so the state is the same as before.
    EXPECT_DOUBLE_EQ(a.out.lat_deg, good.lat_deg) << c.what;
    EXPECT_DOUBLE_EQ(a.out.lon_deg, good.lon_deg) << c.what;
    EXPECT_DOUBLE_EQ(a.out.height_m, good.height_m) << c.what;
    EXPECT_DOUBLE_EQ(a.out.pitch_deg, good.pitch_deg) << c.what;
    EXPECT_DOUBLE_EQ(a.out.roll_deg, good.roll_deg) << c.what;
    EXPECT_DOUBLE_EQ(a.out.simTime_s, good.simTime_s) << c.what;
    EXPECT_DOUBLE_EQ(a.out.visibility_m, good.visibility_m) << c.what;
  }
  // Heading cannot be sent out of range by the encoder (it wraps): poke 360.00.
  Assembly a;
  a.pushAll(encode(sampleSet(), 1), 0);
  auto f = encode(sampleSet(), 2);
  f[3].data[1] = 36000 & 0xFF;
  f[3].data[2] = 36000 >> 8;
  f[3].data[3] = 0x10;  // pitch 0x0010 = 0.16 deg: the rest of the frame still applies
  f[3].data[4] = 0x00;
  a.pushAll(f, 1000);
  EXPECT_EQ(a.c().outOfRange, 1u);
  // The kept heading and the new pitch as sent, in the scene's axes at the set's eye.
  const CanEyeSet g = sampleSet();
  const auto want = expectedAttitude(g.lat_deg, g.lon_deg, 271.25, 0.16, g.roll_deg);
  EXPECT_NEAR(a.out.heading_deg, want.heading_deg, 1e-9);
  EXPECT_NEAR(a.out.pitch_deg, want.pitch_deg, 1e-9);
}

TEST(CanMap, VisibilityZeroIsNotGivenAndPositiveIsAtLeastOneMetre) {
  auto vis = [](double v, uint8_t seq, Assembly& a) {
    return a.commitEdited(seq, [v](CanEyeSet& s) { s.visibility_m = v; }).visibility_m;
  };
  Assembly a;
  EXPECT_EQ(vis(4321.0, 1, a), 4321.0);
  // 0 (what map version 1 hosts send in these bytes) and negative: not given, the scene's fog.
  EXPECT_EQ(vis(0.0, 2, a), -1.0);
  EXPECT_EQ(vis(-5.0, 3, a), -1.0);
  // A positive visibility below 1 m is sent as 1 m, never as "not given".
  EXPECT_EQ(vis(0.3, 4, a), 1.0);
  EXPECT_EQ(vis(1e7, 5, a), 1e7);
  // Not available (NaN): rejected, the last good value stays.
  EXPECT_EQ(vis(2500.0, 6, a), 2500.0);
  EXPECT_EQ(vis(kNaN, 7, a), 2500.0);
  EXPECT_EQ(a.c().outOfRange, 1u);
  // A host's "unlimited": raw values above 1e7 and +infinity (sent as the largest raw) are 1e7.
  EXPECT_EQ(vis(2e7, 8, a), 1e7);
  EXPECT_EQ(vis(std::numeric_limits<double>::infinity(), 9, a), 1e7);
  EXPECT_EQ(a.c().outOfRange, 1u);
  auto f = encode(sampleSet(), 10);
  EXPECT_EQ(u24(f[2]), 4321u);
  CanEyeSet inf = sampleSet();
  inf.visibility_m = std::numeric_limits<double>::infinity();
  f = encode(inf, 11);
  EXPECT_EQ(u24(f[2]), 0xFFFFFEu);
  // Just below the raw range's end: never rounded into "not available" (0xFFFFFF).
  for (double big : {16777214.5, 16777214.9}) {
    inf.visibility_m = big;
    f = encode(inf, 11);
    EXPECT_EQ(u24(f[2]), 0xFFFFFEu) << big;
  }
  // The raw "not available" 0xFFFFFF is rejected.
  f = encode(sampleSet(), 12);
  putU24(f[2], 0xFFFFFF);
  a.pushAll(f, 12000);
  EXPECT_EQ(a.c().outOfRange, 2u);
  EXPECT_EQ(a.out.visibility_m, 1e7);
}

TEST(CanMap, TimeOfDayZeroIsNotGivenAndTheDayWraps) {
  auto tod = [](double h, uint8_t seq, Assembly& a) {
    return a.commitEdited(seq, [h](CanEyeSet& s) { s.timeOfDay_h = h; }).timeOfDay_h;
  };
  Assembly a;
  EXPECT_NEAR(tod(13.5, 1, a), 13.5, 1e-12);
  // Midnight is raw 1, not "not given"; 23:59:59.99 is the largest.
  EXPECT_EQ(tod(0.0, 2, a), 0.0);
  EXPECT_NEAR(tod(86399.99 / 3600.0, 3, a), 86399.99 / 3600.0, 1e-12);
  // Not given (negative, what map version 1 hosts' zeros mean): -1, the scene's sun.
  EXPECT_EQ(tod(-1.0, 4, a), -1.0);
  auto f = encode(sampleSet(), 5);
  putU24(f[0], 0);
  a.pushAll(f, 5000);
  EXPECT_EQ(a.out.timeOfDay_h, -1.0);
  // +infinity: not given too (raw 0).
  CanEyeSet inf = sampleSet();
  inf.timeOfDay_h = std::numeric_limits<double>::infinity();
  f = encode(inf, 1);
  EXPECT_EQ(u24(f[0]), 0u);
  // Less than half a centisecond before midnight: 23:59:59.99 (raw 8,640,000), not rounded up
  // past the day.
  inf.timeOfDay_h = 86399.996 / 3600.0;
  f = encode(inf, 1);
  EXPECT_EQ(u24(f[0]), kCanTimeOfDayMaxRaw);
  Assembly late;
  EXPECT_NEAR(tod(86399.996 / 3600.0, 1, late), 86399.99 / 3600.0, 1e-12);
  EXPECT_EQ(late.c().outOfRange, 0u);
  // 25 h wraps to 1 h; the encoder's centiseconds are exact.
  EXPECT_NEAR(tod(25.0, 6, a), 1.0, 1e-12);
  f = encode(sampleSet(), 7);
  EXPECT_EQ(u24(f[0]), 1u + 4'860'000u);
  // Not available (NaN) and raw beyond 23:59:59.99: rejected, the last good value stays.
  EXPECT_NEAR(tod(6.0, 8, a), 6.0, 1e-12);
  EXPECT_NEAR(tod(std::numeric_limits<double>::quiet_NaN(), 9, a), 6.0, 1e-12);
  f = encode(sampleSet(), 10);
  const uint32_t past = kCanTimeOfDayMaxRaw + 1;
  putU24(f[0], past);
  a.pushAll(f, 10000);
  EXPECT_NEAR(a.out.timeOfDay_h, 6.0, 1e-12);
  EXPECT_EQ(a.c().outOfRange, 2u);
}

TEST(CanMap, OtherFieldsOfASetApplyWhenOneIsRejected) {
  Assembly a;
  a.pushAll(encode(sampleSet(), 1), 0);
  CanEyeSet s = sampleSet();
  s.lat_deg = kNaN;
  s.lon_deg = 12.0;
  s.heading_deg = 10.0;
  s.simTime_s = 36001.0;
  s.hostFrame = 77;
  a.pushAll(encode(s, 2), 1000);
  EXPECT_EQ(a.c().outOfRange, 1u);
  EXPECT_NEAR(a.out.lat_deg, 47.2612345, 1e-9);  // kept
  EXPECT_DOUBLE_EQ(a.out.lon_deg, 12.0);
  // Heading 10 from true north at 12 E, in the axes of the origin at 11.35 E.
  EXPECT_NEAR(a.out.heading_deg, expectedAttitude(47.2612345, 12.0, 10.0, s.pitch_deg, s.roll_deg).heading_deg, 1e-9);
  EXPECT_DOUBLE_EQ(a.out.simTime_s, 36001.0);
  EXPECT_EQ(a.out.hostFrame, 77u);
}

// CAN sends heading from TRUE north at the eye, pitch and roll against its local horizontal;
// HostState's attitude is in the scene's ENU axes (grid north of the origin). One degree of
// longitude east of an origin at 57.7 N, local north is turned by the meridian convergence:
// exactly atan2(-sin(lat) sin(dlon), sin^2(lat) cos(dlon) + cos^2(lat)), about dlon * sin(lat)
// = 0.845 deg, and tilted nose up by asin(sin(lat) cos(lat) (1 - cos(dlon))).
TEST(CanSet, AttitudeIsConvertedToTheScenesAxes) {
  const ig::lod::Geodetic origin{57.7, 11.97, 100.0};
  CanLinkConfig config;
  LinkCounters counters;
  CanSetAssembler assembler(config, origin, counters);
  CanEyeSet s = sampleSet();
  s.lat_deg = 57.7;
  s.lon_deg = 12.97;
  s.height_m = 1000.0;
  s.heading_deg = 0.0;
  s.pitch_deg = 0.0;
  s.roll_deg = 0.0;
  HostState out;
  int commits = 0;
  for (const CanFrame& f : encode(s, 1))
    commits += assembler.push(f, 0, out) == CanSetAssembler::Result::Committed ? 1 : 0;
  ASSERT_EQ(commits, 1);
  const double d = 3.14159265358979323846 / 180.0, sf = std::sin(57.7 * d), cf = std::cos(57.7 * d);
  const double heading = 360.0 + std::atan2(-sf * std::sin(d), sf * sf * std::cos(d) + cf * cf) / d;
  EXPECT_NEAR(out.heading_deg, heading, 1e-9);
  EXPECT_NEAR(out.heading_deg, 360.0 - 1.0 * sf, 0.01);  // dlon * sin(lat)
  EXPECT_NEAR(out.pitch_deg, std::asin(sf * cf * (1.0 - std::cos(d))) / d, 1e-9);
  // A general attitude, and one looking straight up, against the independent conversion.
  struct Case {
    double heading, pitch, roll;
  };
  uint8_t seq = 2;
  for (const Case c : {Case{30.0, 10.0, 20.0}, Case{271.25, -3.5, 12.75}, Case{45.0, 90.0, 0.0}}) {
    s.heading_deg = c.heading;
    s.pitch_deg = c.pitch;
    s.roll_deg = c.roll;
    for (const CanFrame& f : encode(s, seq)) assembler.push(f, 1000 * seq, out);
    ++seq;
    const auto want = ig::test::sceneAttitude(origin.lat_deg, origin.lon_deg, 57.7, 12.97, c.heading, c.pitch, c.roll);
    EXPECT_NEAR(ig::test::headingDiff_deg(out.heading_deg, want.heading_deg), 0.0, 1e-9) << c.heading;
    EXPECT_NEAR(out.pitch_deg, want.pitch_deg, 1e-9) << c.heading;
    EXPECT_NEAR(out.roll_deg, want.roll_deg, 1e-9) << c.heading;
  }
  EXPECT_EQ(snapshot(counters).accepted, 4u);
}

// A rejected attitude field keeps its last good value AS SENT (true north at the eye) and is
// converted again at the new eye: not the previous eye's scene-axes value carried along.
TEST(CanSet, RejectedAttitudeKeepsTheSentValueConvertedAtTheNewEye) {
  Assembly a;
  CanEyeSet s = sampleSet();
  s.heading_deg = 30.0;
  s.pitch_deg = 5.0;
  s.roll_deg = -10.0;
  a.pushAll(encode(s, 1), 0);
  auto want = expectedAttitude(s.lat_deg, s.lon_deg, 30.0, 5.0, -10.0);
  EXPECT_NEAR(a.out.heading_deg, want.heading_deg, 1e-9);
  EXPECT_NEAR(a.out.pitch_deg, want.pitch_deg, 1e-9);
  EXPECT_NEAR(a.out.roll_deg, want.roll_deg, 1e-9);
  s.lon_deg = kOrigin.lon_deg + 1.0;  // one degree east: about 0.73 deg of convergence at 47 N
  s.heading_deg = kNaN;
  s.pitch_deg = kNaN;
  s.roll_deg = kNaN;
  a.pushAll(encode(s, 2), 1000);
  EXPECT_EQ(a.c().outOfRange, 3u);
  want = expectedAttitude(s.lat_deg, s.lon_deg, 30.0, 5.0, -10.0);
  EXPECT_NEAR(a.out.heading_deg, want.heading_deg, 1e-9);
  EXPECT_NEAR(a.out.pitch_deg, want.pitch_deg, 1e-9);
  EXPECT_NEAR(a.out.roll_deg, want.roll_deg, 1e-9);
  EXPECT_LT(a.out.heading_deg, 29.5);
}

#ifdef IG_TEST_WITH_CIGI
// The same geodetic pose sent over CAN and over CIGI renders the same view: both links convert
// the attitude to the scene's axes with one function.
TEST(CanSet, AttitudeMatchesTheCigiLinkForTheSamePose) {
  const ig::lod::Geodetic origin{57.7, 11.97, 100.0};
  CanLinkConfig config;
  LinkCounters counters;
  CanSetAssembler can(config, origin, counters);
  CigiAssembler cigiAsm({}, origin);
  struct Case {
    double lat, lon, heading, pitch, roll;
  };
  uint8_t seq = 0;
  uint32_t frame = 100;
  for (const Case c : {Case{57.7, 12.97, 30.0, 10.0, 20.0}, Case{57.7, 12.97, 0.0, 0.0, 0.0},
                       Case{58.2, 10.5, 271.25, -3.5, 12.75}, Case{57.7, 12.97, 45.0, 90.0, 0.0},
                       Case{57.7, 12.97, 45.0, -90.0, 0.0}}) {
    CanEyeSet s = sampleSet();
    s.lat_deg = c.lat;
    s.lon_deg = c.lon;
    s.height_m = 1000.0;
    s.heading_deg = c.heading;
    s.pitch_deg = c.pitch;
    s.roll_deg = c.roll;
    HostState out;
    for (const CanFrame& f : encode(s, seq)) can.push(f, 1000 * seq, out);
    ++seq;
    cigi::IgControl ig;
    ig.hostFrame = frame++;
    cigi::EntityControl e;
    e.lat_deg = c.lat;
    e.lon_deg = c.lon;
    e.alt_m = 1000.0;
    e.yaw_deg = static_cast<float>(c.heading);  // all exact in float32
    e.pitch_deg = static_cast<float>(c.pitch);
    e.roll_deg = static_cast<float>(c.roll);
    std::vector<std::byte> msg(cigi::kIgControlSize + cigi::kEntityControlSize);
    const size_t n = cigi::encode(ig, cigi::ByteOrder::big, msg);
    cigi::encode(e, cigi::ByteOrder::big, std::span<std::byte>(msg).subspan(n));
    LinkCounters cc;
    ASSERT_EQ(cigiAsm.apply(msg, cc), CigiAssembler::Result::published);
    const HostState& w = cigiAsm.state();
    EXPECT_NEAR(ig::test::headingDiff_deg(out.heading_deg, w.heading_deg), 0.0, 1e-9) << c.heading << " " << c.pitch;
    EXPECT_NEAR(out.pitch_deg, w.pitch_deg, 1e-9) << c.heading << " " << c.pitch;
    EXPECT_NEAR(out.roll_deg, w.roll_deg, 1e-9) << c.heading << " " << c.pitch;
    EXPECT_NEAR(glm::distance(out.eyeEnu_m, w.eyeEnu_m), 0.0, 1e-6);
  }
}
#endif

TEST(CanMap, FramesOutsideTheMapOrMalformed) {
  const auto frames = encode(sampleSet(), 3);
  CanEyeSet out;
  CanDecodedFrame d;
  CanFrame f = frames[0];
  EXPECT_EQ(decodeCanFrame(f, 0x101, d, out), CanDecodeStatus::NotInMap);  // below base
  f.id = 0x105;
  EXPECT_EQ(decodeCanFrame(f, 0x100, d, out), CanDecodeStatus::NotInMap);  // above base+4
  f = frames[1];
  f.extended = true;
  EXPECT_EQ(decodeCanFrame(f, 0x100, d, out), CanDecodeStatus::NotInMap);  // 29-bit 0x101
  f = frames[1];
  f.error = true;
  EXPECT_EQ(decodeCanFrame(f, 0x100, d, out), CanDecodeStatus::NotInMap);
  f = frames[1];
  f.remote = true;
  EXPECT_EQ(decodeCanFrame(f, 0x100, d, out), CanDecodeStatus::Remote);
  f = frames[1];
  f.fd = true;
  EXPECT_EQ(decodeCanFrame(f, 0x100, d, out), CanDecodeStatus::Fd);
  for (int len : {0, 1, 7, 12, 64}) {
    f = frames[1];
    f.len = static_cast<uint8_t>(len);
    EXPECT_EQ(decodeCanFrame(f, 0x100, d, out), CanDecodeStatus::BadLength) << len;
  }
  Assembly a;
  f = frames[2];
  f.len = 7;
  EXPECT_EQ(a.push(f, 0), CanSetAssembler::Result::Rejected);
  f.id = 0x7FF;
  EXPECT_EQ(a.push(f, 0), CanSetAssembler::Result::Ignored);
  EXPECT_EQ(a.c().received, 1u);
  EXPECT_EQ(a.c().malformed, 1u);
}

// ---------------------------------------------------------------------------------------------
// Set assembly

TEST(CanSet, CommitsOnlyWhenAllFiveArrived) {
  Assembly a;
  const auto f = encode(sampleSet(), 7);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(a.push(f[static_cast<size_t>(i)], i * 100), CanSetAssembler::Result::Pending);
  EXPECT_TRUE(a.assembler.setInProgress());
  EXPECT_EQ(a.commits, 0);
  EXPECT_EQ(a.push(f[4], 500), CanSetAssembler::Result::Committed);
  EXPECT_FALSE(a.assembler.setInProgress());
  const auto c = a.c();
  EXPECT_EQ(c.received, 5u);
  EXPECT_EQ(c.accepted, 1u);
  EXPECT_EQ(c.malformed + c.late + c.dropped + c.outOfRange, 0u);
  EXPECT_NEAR(a.out.lat_deg, 47.2612345, 1e-9);
  EXPECT_NEAR(a.out.height_m, 1523.456, 1e-9);
  EXPECT_EQ(a.out.hostFrame, 0x123456u);
  EXPECT_NEAR(a.out.simTime_s, 36000.125, 1e-9);
  // Both the geodetic and the local ENU eyepoint.
  const ig::lod::EnuFrame enu(kOrigin);
  const glm::dvec3 want = enu.fromGeodetic({a.out.lat_deg, a.out.lon_deg, a.out.height_m});
  EXPECT_NEAR(a.out.eyeEnu_m.x, want.x, 1e-6);
  EXPECT_NEAR(a.out.eyeEnu_m.y, want.y, 1e-6);
  EXPECT_NEAR(a.out.eyeEnu_m.z, want.z, 1e-6);
  EXPECT_GT(a.out.eyeEnu_m.x, 600.0);   // 0.0098765 deg east of the origin ~ 746 m
  EXPECT_GT(a.out.eyeEnu_m.y, 1200.0);  // 0.0112345 deg north ~ 1249 m
}

TEST(CanSet, ReorderedFramesCommitOnTheLast) {
  Assembly a;
  const auto f = encode(sampleSet(), 9);
  for (size_t i : {4u, 2u, 0u, 3u}) EXPECT_EQ(a.push(f[i], 0), CanSetAssembler::Result::Pending);
  EXPECT_EQ(a.push(f[1], 0), CanSetAssembler::Result::Committed);
  EXPECT_EQ(a.c().accepted, 1u);
}

TEST(CanSet, NewerCounterDropsTheIncompleteSet) {
  Assembly a;
  CanEyeSet s1 = sampleSet();
  s1.lat_deg = 10.0;
  const auto f1 = encode(s1, 1);
  const auto f2 = encode(sampleSet(), 2);
  a.push(f1[0], 0);
  a.push(f1[1], 10);  // set 1 incomplete
  a.push(f2[0], 20);  // set 2 starts: set 1 dropped
  EXPECT_EQ(a.c().dropped, 1u);
  a.push(f1[2], 30);  // the rest of set 1 is late now
  EXPECT_EQ(a.c().late, 1u);
  for (size_t i = 1; i < 5; ++i) a.push(f2[i], 40);
  EXPECT_EQ(a.commits, 1);
  EXPECT_NEAR(a.out.lat_deg, 47.2612345, 1e-9);  // nothing of set 1 leaked in
}

TEST(CanSet, OlderAndRepeatedCountersAreLateDuplicatesMalformed) {
  Assembly a;
  a.pushAll(encode(sampleSet(), 50), 0);
  ASSERT_EQ(a.commits, 1);
  a.pushAll(encode(sampleSet(), 50), 1000);  // the same set again
  EXPECT_EQ(a.c().late, 5u);
  a.push(encode(sampleSet(), 49)[0], 2000);  // older
  EXPECT_EQ(a.c().late, 6u);
  const auto f = encode(sampleSet(), 51);
  a.push(f[0], 3000);
  a.push(f[0], 3000);  // the same frame twice in one set
  EXPECT_EQ(a.c().malformed, 1u);
  for (size_t i = 1; i < 5; ++i) a.push(f[i], 3000);
  EXPECT_EQ(a.commits, 2);
  EXPECT_EQ(a.c().dropped, 0u);
}

TEST(CanSet, StaleIncompleteSetIsDroppedByTheFakeClock) {
  Assembly a;  // stale_ms = 100
  const auto f = encode(sampleSet(), 5);
  a.push(f[0], 1'000'000);
  a.push(f[1], 1'050'000);
  EXPECT_FALSE(a.assembler.expire(1'100'000));  // exactly 100 ms: still fresh
  EXPECT_TRUE(a.assembler.setInProgress());
  EXPECT_TRUE(a.assembler.expire(1'100'001));
  EXPECT_FALSE(a.assembler.setInProgress());
  EXPECT_EQ(a.c().dropped, 1u);
  EXPECT_FALSE(a.assembler.expire(2'000'000));  // only once
  // A frame arriving after the limit expires the old set itself and starts anew.
  a.push(f[0], 3'000'000);
  a.push(f[1], 3'200'000);
  EXPECT_EQ(a.c().dropped, 2u);
  for (size_t i = 2; i < 5; ++i) a.push(f[i], 3'250'000);
  EXPECT_EQ(a.commits, 0);  // frames 2..4 belong to the set restarted at 3.2 s, which lacks frame 0
  a.push(f[0], 3'260'000);
  EXPECT_EQ(a.commits, 1);
}

TEST(CanSet, CounterWrapsAndResyncsAfterStale) {
  Assembly a;
  a.pushAll(encode(sampleSet(), 254), 0);
  a.pushAll(encode(sampleSet(), 255), 10'000);
  a.pushAll(encode(sampleSet(), 0), 20'000);  // 0 is newer than 255
  a.pushAll(encode(sampleSet(), 1), 30'000);
  EXPECT_EQ(a.commits, 4);
  a.pushAll(encode(sampleSet(), 200), 40'000);  // 199 steps ahead = 57 behind: late while fresh
  EXPECT_EQ(a.commits, 4);
  EXPECT_EQ(a.c().late, 5u);
  a.pushAll(encode(sampleSet(), 200), 130'001);  // stale_ms after the last commit: a restarted host resyncs
  EXPECT_EQ(a.commits, 5);
}

// "Late" is measured from the last commit's own time (not from the first one, nor the clock's
// zero); exactly stale_ms after it is still fresh, as for an incomplete set.
TEST(CanSet, LateIsMeasuredFromTheLastCommit) {
  Assembly a;  // stale_ms = 100
  a.pushAll(encode(sampleSet(), 10), 1'000'000);
  a.pushAll(encode(sampleSet(), 11), 5'000'000);
  ASSERT_EQ(a.commits, 2);
  a.pushAll(encode(sampleSet(), 11), 5'050'000);  // the same set again, 50 ms later: late
  EXPECT_EQ(a.commits, 2);
  EXPECT_EQ(a.c().late, 5u);
  a.push(encode(sampleSet(), 3)[0], 5'100'000);  // an older counter exactly stale_ms later: late
  EXPECT_EQ(a.c().late, 6u);
  EXPECT_FALSE(a.assembler.setInProgress());
  a.pushAll(encode(sampleSet(), 3), 5'100'001);  // past it: a restarted host resyncs
  EXPECT_EQ(a.commits, 3);
  EXPECT_EQ(a.c().late, 6u);
}

TEST(CanSet, ConfigurableBaseIdAndStale) {
  Assembly a;
  a.config.baseId = 0x7FB;
  a.config.stale_ms = 5;
  CanSetAssembler asm2(a.config, kOrigin, a.counters);
  HostState out;
  const auto f = encode(sampleSet(), 1, 0x7FB);
  EXPECT_EQ(f[4].id, 0x7FFu);
  for (size_t i = 0; i < 4; ++i) asm2.push(f[i], 0, out);
  EXPECT_TRUE(asm2.expire(5001));
  EXPECT_EQ(asm2.push(encode(sampleSet(), 1, 0x100)[0], 0, out), CanSetAssembler::Result::Ignored);
}

TEST(CanSet, StartsFromTheOriginBeforeTheFirstSet) {
  Assembly a;
  EXPECT_DOUBLE_EQ(a.assembler.lastState().lat_deg, kOrigin.lat_deg);
  CanEyeSet s = sampleSet();
  s.lat_deg = kNaN;
  s.lon_deg = kNaN;
  s.height_m = kNaN;
  a.pushAll(encode(s, 1), 0);
  EXPECT_DOUBLE_EQ(a.out.lat_deg, kOrigin.lat_deg);
  EXPECT_NEAR(glm::length(a.out.eyeEnu_m), 0.0, 1e-6);
  EXPECT_EQ(a.c().outOfRange, 3u);
}

// ---------------------------------------------------------------------------------------------
// candump lines

TEST(Candump, ParsesEveryFrameKind) {
  CandumpLine l;
  std::string r;
  ASSERT_TRUE(parseCandumpLine("(1699999999.123456) vcan0 101#0011223344556677", l, r)) << r;
  EXPECT_EQ(l.time_us, 1699999999123456);
  EXPECT_EQ(l.interface, "vcan0");
  EXPECT_EQ(l.frame.id, 0x101u);
  EXPECT_EQ(l.frame.len, 8);
  EXPECT_EQ(l.frame.data[7], 0x77);
  EXPECT_FALSE(l.frame.extended || l.frame.remote || l.frame.fd || l.frame.error);

  ASSERT_TRUE(parseCandumpLine("(0.5) can0 1234ABCD#", l, r)) << r;
  EXPECT_EQ(l.time_us, 500000);
  EXPECT_TRUE(l.frame.extended);
  EXPECT_EQ(l.frame.id, 0x1234ABCDu);
  EXPECT_EQ(l.frame.len, 0);

  ASSERT_TRUE(parseCandumpLine("(1.000001) vcan0 20000004#0004000000000000", l, r)) << r;
  EXPECT_TRUE(l.frame.error);
  EXPECT_EQ(l.frame.id, 0x4u);

  ASSERT_TRUE(parseCandumpLine("(1.000001) vcan0 103#R", l, r)) << r;
  EXPECT_TRUE(l.frame.remote);
  EXPECT_EQ(l.frame.len, 0);
  ASSERT_TRUE(parseCandumpLine("(1.000001) vcan0 103#R8", l, r)) << r;
  EXPECT_EQ(l.frame.len, 8);

  ASSERT_TRUE(parseCandumpLine("(1.000001) vcan0 102##1001122", l, r)) << r;
  EXPECT_TRUE(l.frame.fd);
  EXPECT_EQ(l.frame.len, 3);
  EXPECT_EQ(l.frame.data[2], 0x22);
  ASSERT_TRUE(parseCandumpLine("(1.000001) vcan0 102##0" + std::string(128, 'A'), l, r)) << r;
  EXPECT_EQ(l.frame.len, 64);

  ASSERT_TRUE(parseCandumpLine("(1.000001) vcan0 101#00.11.22\r", l, r)) << r;
  EXPECT_EQ(l.frame.len, 3);
  ASSERT_TRUE(parseCandumpLine("(1.000001)  vcan0  101#0011223344556677_C  R", l, r)) << r;
  EXPECT_EQ(l.frame.len, 8);
  ASSERT_TRUE(parseCandumpLine("(1.1) vcan0 101#", l, r)) << r;
  EXPECT_EQ(l.time_us, 1100000);
}

TEST(Candump, RejectsBadLinesWithAReason) {
  auto bad = [](std::string_view line) {
    CandumpLine l;
    std::string r;
    EXPECT_FALSE(parseCandumpLine(line, l, r)) << line;
    return r;
  };
  EXPECT_EQ(bad("1699999999.123456 vcan0 101#00"), "timestamp \"1699999999.123456\": expected (seconds.micros)");
  EXPECT_EQ(bad("(1699999999) vcan0 101#00"), "timestamp \"(1699999999)\": expected (seconds.micros)");
  EXPECT_EQ(bad("(-1.5) vcan0 101#00"), "timestamp \"(-1.5)\": expected (seconds.micros)");
  EXPECT_EQ(bad("(1.x) vcan0 101#00"), "timestamp \"(1.x)\": expected (seconds.micros)");
  EXPECT_EQ(bad("(1.5) vcan0"), "expected \"(seconds.micros) interface id#data\", got \"(1.5) vcan0\"");
  EXPECT_EQ(bad("(1.5) vcan0 101#00 extra words"),
            "expected \"(seconds.micros) interface id#data\", got \"(1.5) vcan0 101#00 extra words\"");
  EXPECT_EQ(bad("(1.5) vcan0 101#00 X"), "unexpected \"X\" after the frame (only a direction R or T may follow)");
  EXPECT_EQ(bad("(1.5) vcan0 10100"), "frame \"10100\": no '#' between id and data");
  EXPECT_EQ(bad("(1.5) vcan0 1010#00"), "id \"1010\": expected 3 hex digits (11-bit) or 8 (29-bit)");
  EXPECT_EQ(bad("(1.5) vcan0 10G#00"), "id \"10G\": not hexadecimal");
  EXPECT_EQ(bad("(1.5) vcan0 800#00"), "id \"800\": an 11-bit id is at most 7FF");
  EXPECT_EQ(bad("(1.5) vcan0 40000000#00"), "id \"40000000\": above 3FFFFFFF (only the error flag may be set above 29 bits)");
  EXPECT_EQ(bad("(1.5) vcan0 101#001"), "data \"001\": expected pairs of hex digits");
  EXPECT_EQ(bad("(1.5) vcan0 101#0G"), "data \"0G\": expected pairs of hex digits");
  EXPECT_EQ(bad("(1.5) vcan0 101#001122334455667788"), "data \"001122334455667788\": more than 8 bytes");
  EXPECT_EQ(bad("(1.5) vcan0 101#R9"), "frame \"101#R9\": a remote frame takes only a length digit 0..8 after 'R'");
  EXPECT_EQ(bad("(1.5) vcan0 101##"), "frame \"101##\": CAN FD needs a flags hex digit after '##'");
  EXPECT_EQ(bad("(1.5) vcan0 101##0" + std::string(18, '0')), "frame \"101##0000000000000000000\": 9 bytes is not a CAN FD length");
  EXPECT_EQ(bad("(1.5) vcan0 20000004##000"), "frame \"20000004##000\": an error frame cannot be CAN FD");
  EXPECT_EQ(bad("(1.5) vcan0 101#00_C"), "frame \"101#00_C\": a DLC above 8 needs 8 data bytes");
  EXPECT_EQ(bad("(1.5) vcan0 101#0011223344556677_3"), "frame \"101#0011223344556677_3\": '_' must be followed by one DLC digit 9..F");
  EXPECT_EQ(bad("(1.5) averyveryverylongname 101#00"), "interface \"averyveryverylongname\": longer than 15 characters");
  EXPECT_EQ(bad(""), "expected \"(seconds.micros) interface id#data\", got \"\"");
}

TEST(Candump, TruncatedAtEveryLengthNeverCrashes) {
  const std::string line = "(1699999999.123456) vcan0 101##3001122334455667788";
  for (size_t n = 0; n <= line.size(); ++n) {
    CandumpLine l;
    std::string r;
    const bool ok = parseCandumpLine(std::string_view(line).substr(0, n), l, r);
    EXPECT_EQ(ok, r.empty()) << n;
  }
}

// ---------------------------------------------------------------------------------------------
// candump logs to recordings

TEST(Candump, LogToRecordingRelativeToTheFirstSet) {
  std::string log;
  log += "(1700000000.000000) vcan0 7DF#0102030405060708\n";  // another node's traffic
  log += "(1700000000.000500) vcan0 20000004#0004000000000000\n";  // a bus error frame
  for (int k = 0; k < 10; ++k) {
    CanEyeSet s = sampleSet();
    s.hostFrame = static_cast<uint32_t>(100 + k);
    s.simTime_s = 10.0 + k / 60.0;
    s.heading_deg = 10.0 * k;
    const auto f = encode(s, static_cast<uint8_t>(k));
    const int64_t t = 1700000000'010000 + k * 16667;
    for (size_t i = 0; i < 5; ++i) log += candumpLine(f[i], t + static_cast<int64_t>(i) * 100);
    if (k == 3) log += "\n";  // blank lines are fine
  }
  Recording rec;
  std::string error;
  CandumpStats stats;
  ASSERT_TRUE(candumpTextToRecording(log, "x.log", CanLinkConfig{}, kOrigin, rec, error, &stats)) << error;
  ASSERT_EQ(rec.samples.size(), 10u);
  EXPECT_DOUBLE_EQ(rec.samples[0].t_s, 0.0);
  EXPECT_NEAR(rec.samples[9].t_s, 9 * 0.016667, 1e-9);
  EXPECT_EQ(rec.samples[9].state.hostFrame, 109u);
  const CanEyeSet g = sampleSet();
  EXPECT_NEAR(rec.samples[9].state.heading_deg,
              expectedAttitude(g.lat_deg, g.lon_deg, 90.0, g.pitch_deg, g.roll_deg).heading_deg, 1e-9);
  EXPECT_NEAR(rec.samples[9].state.simTime_s, 10.15, 0.5e-3);
  EXPECT_EQ(stats.lines, 52u);
  EXPECT_EQ(stats.otherFrames, 1u);
  EXPECT_EQ(stats.errorFrames, 1u);
  EXPECT_EQ(stats.counters.received, 50u);
  EXPECT_EQ(stats.counters.accepted, 10u);
}

TEST(Candump, LogErrorsNameFileAndLine) {
  const auto f = encode(sampleSet(), 1);
  std::string good;
  for (size_t i = 0; i < 5; ++i) good += candumpLine(f[i], 1'000'000 + static_cast<int64_t>(i));
  Recording rec;
  rec.samples.push_back({});
  std::string error;
  EXPECT_FALSE(candumpTextToRecording(good + "(2.0) vcan0 101#00112\n", "my.log", CanLinkConfig{}, kOrigin, rec, error));
  EXPECT_EQ(error, "my.log:6: data \"00112\": expected pairs of hex digits");
  EXPECT_EQ(rec.samples.size(), 1u);  // untouched
  EXPECT_FALSE(candumpTextToRecording(good + "(0.5) vcan0 101#00\n", "my.log", CanLinkConfig{}, kOrigin, rec, error));
  EXPECT_EQ(error, "my.log:6: timestamp 0.500000 is before the previous line's 1.000004");
  EXPECT_FALSE(candumpTextToRecording("(1.0) vcan0 100#0000000000000000\n", "my.log", CanLinkConfig{}, kOrigin, rec, error));
  EXPECT_EQ(error, "my.log: no complete frame set with ids 0x100..0x104 (1 frames, 1 of them in the map, 0 malformed, 1 incomplete sets)");
  CanLinkConfig other;
  other.baseId = 0x200;
  EXPECT_FALSE(candumpTextToRecording(good, "my.log", other, kOrigin, rec, error));
  EXPECT_EQ(error, "my.log: no complete frame set with ids 0x200..0x204 (5 frames, 0 of them in the map, 0 malformed, 0 incomplete sets)");
  EXPECT_FALSE(candumpToRecording("/nonexistent/x.log", CanLinkConfig{}, kOrigin, rec, error));
  EXPECT_EQ(error, "/nonexistent/x.log: cannot open: No such file or directory");
  ASSERT_TRUE(candumpTextToRecording(good, "my.log", CanLinkConfig{}, kOrigin, rec, error)) << error;
  EXPECT_EQ(rec.samples.size(), 1u);
}

// A log written by the real `candump -L vcan0` inside user-mode Linux while `cansend` sent
// three sets, the third with its frames in reverse order, then a lone frame of a fourth set
// (tests/uml/make_candump_sample.sh regenerates it).
TEST(Candump, RealCandumpLogFromUserModeLinux) {
  const std::string path = std::string(IG_SOURCE_DIR) + "/tests/uml/candump_sample.log";
  Recording rec;
  std::string error;
  CandumpStats stats;
  CanLinkConfig config;
  config.stale_ms = 1000;  // each cansend took 50-200 ms inside UML: a set spans up to 0.62 s
  ASSERT_TRUE(candumpToRecording(path, config, kOrigin, rec, error, &stats)) << error;
  ASSERT_EQ(rec.samples.size(), 3u);
  EXPECT_DOUBLE_EQ(rec.samples[0].t_s, 0.0);
  EXPECT_GT(rec.samples[2].t_s, rec.samples[1].t_s);
  for (size_t k = 0; k < 3; ++k) {
    const HostState& s = rec.samples[k].state;
    EXPECT_EQ(s.hostFrame, 1000 + k);
    EXPECT_NEAR(s.lat_deg, 47.2612345 + 0.001 * static_cast<double>(k), 1e-9);
    EXPECT_NEAR(s.lon_deg, 11.3598765, 1e-9);
    EXPECT_NEAR(s.height_m, 1523.456, 1e-9);
    // Sent as heading 271.25, pitch -3.5, roll 12.75 from true north at the eye.
    const auto want = expectedAttitude(s.lat_deg, s.lon_deg, 271.25, -3.5, 12.75);
    EXPECT_NEAR(s.heading_deg, want.heading_deg, 1e-9);
    EXPECT_NEAR(s.pitch_deg, want.pitch_deg, 1e-9);
    EXPECT_NEAR(s.roll_deg, want.roll_deg, 1e-9);
    EXPECT_NEAR(s.simTime_s, 36000.125 + static_cast<double>(k), 1e-9);
  }
  EXPECT_EQ(stats.counters.received, 16u);
  EXPECT_EQ(stats.counters.accepted, 3u);
  EXPECT_EQ(stats.counters.dropped, 1u);  // the lone frame at the end
}

// ---------------------------------------------------------------------------------------------
// The DBC file against the C++ map: same ids, lengths, signal layout and scaling, and every
// signal decoded from the C++ encoder's frames with the DBC's own definition gives the value.

namespace {
struct DbcSignal {
  std::string name;
  int start = 0, length = 0;
  bool intel = true, isSigned = false;
  double factor = 1, offset = 0, min = 0, max = 0;
  std::string unit;
};
struct DbcMessage {
  uint32_t id = 0;
  std::string name;
  int dlc = 0;
  std::vector<DbcSignal> signals;
};

std::vector<DbcMessage> parseDbc(const std::string& text) {
  std::vector<DbcMessage> out;
  const std::regex bo(R"(^BO_ (\d+) (\w+): (\d+) (\w+)\s*$)");
  const std::regex sg(
      R"re(^ SG_ (\w+) : (\d+)\|(\d+)@([01])([+-]) \(([^,]+),([^)]+)\) \[([^|]+)\|([^\]]+)\] "([^"]*)" (\w+)\s*$)re");
  std::istringstream in(text);
  std::string line;
  std::smatch m;
  while (std::getline(in, line)) {
    if (std::regex_match(line, m, bo)) {
      out.push_back({static_cast<uint32_t>(std::stoul(m[1])), m[2], std::stoi(m[3]), {}});
    } else if (std::regex_match(line, m, sg)) {
      EXPECT_FALSE(out.empty()) << line;
      if (out.empty()) continue;
      out.back().signals.push_back({m[1], std::stoi(m[2]), std::stoi(m[3]), m[4] == "1", m[5] == "-",
                                    std::stod(m[6]), std::stod(m[7]), std::stod(m[8]), std::stod(m[9]), m[10]});
    } else {
      EXPECT_EQ(line.rfind("SG_", 0), std::string::npos) << "unparsed signal line: " << line;
      EXPECT_EQ(line.rfind(" SG_", 0), std::string::npos) << "unparsed signal line: " << line;
      EXPECT_EQ(line.rfind("BO_ ", 0), std::string::npos) << "unparsed message line: " << line;
    }
  }
  return out;
}

// Little-endian (Intel) signal extraction as DBC defines it.
int64_t dbcRaw(const CanFrame& f, const DbcSignal& s) {
  uint64_t v = 0;
  for (int b = 0; b < s.length; ++b) {
    const int bit = s.start + b;
    v |= static_cast<uint64_t>((f.data[static_cast<size_t>(bit / 8)] >> (bit % 8)) & 1) << b;
  }
  if (s.isSigned && (v >> (s.length - 1)) & 1) v |= ~uint64_t{0} << s.length;
  return static_cast<int64_t>(v);
}
}  // namespace

TEST(CanDbc, MatchesTheCppMap) {
  const std::string text = readFile(std::string(IG_SOURCE_DIR) + "/config/igd_host.dbc");
  ASSERT_FALSE(text.empty());
  EXPECT_EQ(text.rfind("VERSION \"", 0), 0u);
  EXPECT_NE(text.find("\nBU_: HOST IG\n"), std::string::npos);
  const auto msgs = parseDbc(text);
  ASSERT_EQ(msgs.size(), static_cast<size_t>(kCanFrameCount));
  const char* names[] = {"IG_EYE_LAT", "IG_EYE_LON", "IG_EYE_HEIGHT", "IG_EYE_ATTITUDE", "IG_SIM_TIME"};
  const CanLinkConfig defaults;
  for (size_t i = 0; i < msgs.size(); ++i) {
    EXPECT_EQ(msgs[i].id, defaults.baseId + i);
    EXPECT_EQ(msgs[i].name, names[i]);
    EXPECT_EQ(msgs[i].dlc, kCanFrameLen);
    ASSERT_FALSE(msgs[i].signals.empty());
    const DbcSignal& seq = msgs[i].signals[0];
    EXPECT_EQ(seq.name, "SeqCounter");
    EXPECT_EQ(seq.start, 0);
    EXPECT_EQ(seq.length, 8);
    int bits = 0;
    for (const DbcSignal& s : msgs[i].signals) {
      EXPECT_TRUE(s.intel) << s.name;
      EXPECT_EQ(s.offset, s.name == "TimeOfDay" ? -0.01 : 0.0) << s.name;  // raw 0 = -0.01 s: not given
      EXPECT_LE(s.start + s.length, 64) << s.name;
      bits += s.length;
    }
    EXPECT_LE(bits, 64);
  }
  // Decode the C++ encoder's frames with the DBC and compare physical values.
  const CanEyeSet in = sampleSet();
  const auto frames = encode(in, 0xC3);
  const std::map<std::string, double> want{{"EyeLatitude", in.lat_deg}, {"EyeLongitude", in.lon_deg},
                                           {"EyeHeight", in.height_m},  {"Heading", in.heading_deg},
                                           {"Pitch", in.pitch_deg},     {"Roll", in.roll_deg},
                                           {"SimTime", in.simTime_s},   {"HostFrame", in.hostFrame},
                                           {"Visibility", in.visibility_m}, {"TimeOfDay", in.timeOfDay_h * 3600.0},
                                           {"SeqCounter", 0xC3}};
  int checked = 0;
  for (size_t i = 0; i < msgs.size(); ++i) {
    for (const DbcSignal& s : msgs[i].signals) {
      ASSERT_TRUE(want.count(s.name)) << s.name;
      const double phys = static_cast<double>(dbcRaw(frames[i], s)) * s.factor + s.offset;
      EXPECT_NEAR(phys, want.at(s.name), s.factor / 2 + 1e-12) << s.name;
      ++checked;
    }
  }
  EXPECT_EQ(checked, 15);
  // The DBC's ranges are the C++ valid ranges: min and max decode, one step outside does not.
  struct Edge {
    size_t msg;
    const char* signal;
  };
  for (const Edge& e : {Edge{0, "EyeLatitude"}, Edge{0, "TimeOfDay"}, Edge{1, "EyeLongitude"}, Edge{2, "EyeHeight"},
                        Edge{2, "Visibility"}, Edge{3, "Heading"}, Edge{3, "Pitch"}, Edge{3, "Roll"}}) {
    const auto& sigs = msgs[e.msg].signals;
    const auto it = std::find_if(sigs.begin(), sigs.end(), [&](const DbcSignal& s) { return s.name == e.signal; });
    ASSERT_NE(it, sigs.end());
    for (double v : {it->min, it->max, it->min - it->factor, it->max + it->factor}) {
      CanFrame f = frames[e.msg];
      const auto raw = static_cast<int64_t>(std::llround((v - it->offset) / it->factor));
      for (int b = 0; b < it->length; ++b) {
        const int bit = it->start + b;
        auto& byte = f.data[static_cast<size_t>(bit / 8)];
        byte = static_cast<uint8_t>((byte & ~(1 << (bit % 8))) | (((raw >> b) & 1) << (bit % 8)));
      }
      CanEyeSet out;
      CanDecodedFrame d;
      ASSERT_EQ(decodeCanFrame(f, 0x100, d, out), CanDecodeStatus::Ok);
      const bool inside = v >= it->min && v <= it->max;
      EXPECT_EQ(d.rejectedFields == 0, inside) << e.signal << " = " << v;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Config and transport start-up (this machine's kernel may have no AF_CAN at all; the real
// socket is exercised inside user-mode Linux by can_uml_test).

TEST(CanLinkConfig, ValidationNamesKeyAndValue) {
  std::string e;
  CanLinkConfig c;
  EXPECT_TRUE(validateCanLinkConfig(c, e));
  c.baseId = 0x7FB;
  EXPECT_TRUE(validateCanLinkConfig(c, e));
  c.baseId = 2047;
  EXPECT_FALSE(validateCanLinkConfig(c, e));
  EXPECT_EQ(e, "host.can.base_id = 2047: must be 0..2043 (0x7FB) so that base_id+4 is an 11-bit id");
  c = {};
  c.stale_ms = 0;
  EXPECT_FALSE(validateCanLinkConfig(c, e));
  EXPECT_EQ(e, "host.can.stale_ms = 0: must be 1..60000");
  c = {};
  c.interface = "";
  EXPECT_FALSE(validateCanLinkConfig(c, e));
  EXPECT_EQ(e, "host.can.interface = \"\": must be a network interface name of 1..15 characters");
  c.interface = "a-much-too-long-name";
  EXPECT_FALSE(validateCanLinkConfig(c, e));
}

TEST(CanLink, StartFailsCleanlyNamingTheInterface) {
  CanLinkConfig c;
  c.interface = "can9";
  auto link = makeCanLink(c, kOrigin);
  EXPECT_EQ(link->name(), "can");
  struct NullSink : HostSink {
    void publish(const HostState&) override {}
  } sink;
  std::string e;
  EXPECT_FALSE(link->start(sink, e));
  // Without AF_CAN in the kernel the socket itself fails; with it, the interface is missing.
  const bool noAfCan = e == "cannot open a CAN socket for host.can.interface = can9: Address family not supported by protocol";
  const bool noIf = e == "host.can.interface = can9: no such CAN interface";
  EXPECT_TRUE(noAfCan || noIf) << e;
  link->stop();
  link->stop();
  c.baseId = 4000;
  CanLink bad(c, kOrigin);
  EXPECT_FALSE(bad.start(sink, e));
  EXPECT_EQ(e, "host.can.base_id = 4000: must be 0..2043 (0x7FB) so that base_id+4 is an 11-bit id");
  EXPECT_EQ(bad.busErrors(), 0u);
}
