// Host recordings: parsing with precise errors, truncation at every length, round trip,
// replay by slot time, looping, and the committed built-in recording.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <vector>

#include "io/replay.h"

using namespace ig::io;

namespace {
const char* kGood =
    "igd-recording 1\n"
    "# comment line\n"
    "0.0 0 100.0  10 20 300  90 -5 2  45 0.1 100000\n"
    "0.5 1 100.5  11 21 301  91 -5 2  45 0.1 100000   # trailing comment\n"
    "1.0 2 101.0  12 22 302  92 -5 2  45 0.1 100000\n";

std::string parseError(const std::string& text) {
  Recording r;
  std::string e;
  EXPECT_FALSE(parseRecording(text, "rec.txt", r, e)) << text;
  return e;
}
}  // namespace

TEST(Replay, ParsesFieldsWithUnits) {
  Recording r;
  std::string e;
  ASSERT_TRUE(parseRecording(kGood, "rec.txt", r, e)) << e;
  ASSERT_EQ(r.samples.size(), 3u);
  const HostState& s = r.samples[1].state;
  EXPECT_EQ(s.hostFrame, 1u);
  EXPECT_DOUBLE_EQ(s.simTime_s, 100.5);
  EXPECT_DOUBLE_EQ(s.eyeEnu_m.y, 21.0);
  EXPECT_DOUBLE_EQ(s.heading_deg, 91.0);
  EXPECT_DOUBLE_EQ(r.duration_s(), 1.0);
}

TEST(Replay, ErrorsNameFileLineFieldAndValue) {
  EXPECT_EQ(parseError("bogus 1\n"), "rec.txt:1: expected header 'igd-recording 4' (or 3, 2, 1), got 'bogus 1'");
  EXPECT_EQ(parseError("igd-recording 1\n0 0 0 1 2 3 4 5 6 45 0.1\n"), "rec.txt:2: expected 12 fields, got 11");
  EXPECT_EQ(parseError("igd-recording 1\n0 0 0 1 nan 3 4 5 6 45 0.1 1000\n"),
            "rec.txt:2: north_m = 'nan': not a finite number");
  EXPECT_EQ(parseError("igd-recording 1\n0 0 0 1 2 3 4 5 6 45 0.1 1000\n\n-1 0 0 1 2 3 4 5 6 45 0.1 1000\n"),
            "rec.txt:4: t_s = '-1': must be >= 0 and non-decreasing");
  EXPECT_EQ(parseError("igd-recording 1\n0 0 0 1 2 3 4 5 6 190 0.1 1000\n"),
            "rec.txt:2: fovy_deg = '190': must be in (0, 180)");
  EXPECT_EQ(parseError("igd-recording 1\n0 0 0 1 2 3 4 5 6 45 0 1000\n"),
            "rec.txt:2: near_m/far_m = '0 1000': need 0 < near_m < far_m");
  EXPECT_EQ(parseError("igd-recording 1\n0 1.5 0 1 2 3 4 5 6 45 0.1 1000\n"),
            "rec.txt:2: host_frame = '1.5': not a non-negative integer");
  EXPECT_EQ(parseError("igd-recording 1\n"), "rec.txt:1: recording has no samples");
  EXPECT_EQ(parseError(""), "rec.txt:0: empty recording: expected header 'igd-recording 4'");
}

TEST(Replay, TruncatedAtEveryLengthFailsCleanlyOrParsesAPrefix) {
  const std::string full = kGood;
  for (size_t n = 0; n <= full.size(); ++n) {
    Recording r;
    r.samples.push_back({});  // sentinel: must survive a failed parse
    std::string e;
    if (parseRecording(full.substr(0, n), "cut", r, e)) {
      EXPECT_GE(r.samples.size(), 1u);
      EXPECT_LE(r.samples.size(), 3u);
    } else {
      EXPECT_EQ(r.samples.size(), 1u) << "output touched on failure at length " << n;
      EXPECT_EQ(e.rfind("cut:", 0), 0u);
    }
  }
}

TEST(Replay, FormatParseRoundTrip) {
  const Recording a = makeDefaultRecording(30.0, 2.0);
  Recording b;
  std::string e;
  ASSERT_TRUE(parseRecording(formatRecording(a), "rt", b, e)) << e;
  ASSERT_EQ(a.samples.size(), b.samples.size());
  for (size_t i = 0; i < a.samples.size(); ++i) {
    EXPECT_NEAR(a.samples[i].t_s, b.samples[i].t_s, 1e-4);
    EXPECT_NEAR(a.samples[i].state.eyeEnu_m.x, b.samples[i].state.eyeEnu_m.x, 1e-3);
    EXPECT_EQ(a.samples[i].state.hostFrame, b.samples[i].state.hostFrame);
  }
}

TEST(Replay, CommittedDefaultRecordingIsTheBuiltInOne) {
  std::ifstream in(std::string(IG_SOURCE_DIR) + "/config/recordings/default.rec");
  ASSERT_TRUE(in);
  std::stringstream ss;
  ss << in.rdbuf();
  EXPECT_EQ(ss.str(), formatRecording(makeDefaultRecording(60.0, 20.0)))
      << "regenerate with: build/igtool make-recording";
}

// igtool make-recording --duration D: the recording is D long (its last sample at D), samples
// every 1 / rate from 0 s. floor(D x rate) + 1 samples ended at 0.28 s for 0.29 s at 100 Hz
// (0.29 x 100 = 28.999999999999996) and at 0.29 s for 0.295 s.
TEST(Replay, DefaultRecordingEndsAtItsDuration) {
  struct Case {
    double rate_hz, duration_s;
    size_t samples;
  };
  for (const Case c : {Case{100.0, 0.29, 30}, Case{100.0, 0.295, 31}, Case{60.0, 20.0, 1201}, Case{10.0, 1.0, 11},
                       Case{100.0, 0.0, 1}, Case{7.0, 1.0, 8}}) {
    const Recording r = makeDefaultRecording(c.rate_hz, c.duration_s);
    ASSERT_EQ(r.samples.size(), c.samples) << c.rate_hz << " Hz, " << c.duration_s << " s";
    EXPECT_EQ(r.duration_s(), c.duration_s) << c.rate_hz << " Hz";
    EXPECT_EQ(r.samples.front().t_s, 0.0);
    for (size_t i = 1; i < r.samples.size(); ++i) {
      const double step = r.samples[i].t_s - r.samples[i - 1].t_s;
      EXPECT_GT(step, 0.0) << i;
      EXPECT_LE(step, 1.0 / c.rate_hz + 1e-12) << i;
    }
  }
}

TEST(Replay, SourcePublishesNewestSampleBySlotTime) {
  Recording r;
  std::string e;
  ASSERT_TRUE(parseRecording(kGood, "rec.txt", r, e));
  LatestValueMailbox<HostState> box;
  ReplaySource src(r, false);
  HostState out;
  uint64_t seq = 0;
  EXPECT_TRUE(src.advanceTo(0.0, box));
  ASSERT_TRUE(box.readIfNewer(out, seq));
  EXPECT_EQ(out.hostFrame, 0u);
  EXPECT_TRUE(src.advanceTo(0.2, box));
  EXPECT_FALSE(box.readIfNewer(out, seq));  // nothing new between samples
  EXPECT_TRUE(src.advanceTo(1.0, box));     // jumps over sample 1 to the newest
  ASSERT_TRUE(box.readIfNewer(out, seq));
  EXPECT_EQ(out.hostFrame, 2u);
  EXPECT_FALSE(src.advanceTo(1.5, box));  // past the end, not looping
  EXPECT_EQ(sampleAt(r, 0.7).state.hostFrame, 1u);
  EXPECT_EQ(sampleAt(r, -5).state.hostFrame, 0u);
}

TEST(Replay, LoopingRestartsAtTheBeginning) {
  Recording r;
  std::string e;
  ASSERT_TRUE(parseRecording(kGood, "rec.txt", r, e));
  LatestValueMailbox<HostState> box;
  ReplaySource src(r, true);
  HostState out;
  uint64_t seq = 0;
  src.advanceTo(1.0, box);
  box.readIfNewer(out, seq);
  EXPECT_EQ(out.hostFrame, 2u);
  EXPECT_TRUE(src.advanceTo(1.6, box));  // 0.6 into the second loop
  ASSERT_TRUE(box.readIfNewer(out, seq));
  EXPECT_EQ(out.hostFrame, 1u);
}

// The replay is driven by the time it is given: a time before the previous one (Service::run
// called again restarts its slots, and so the replay time, at 0) publishes the sample current
// then, looping or not. It published nothing until the time caught up with the previous one:
// the frames rendered the last sample of the earlier run.
TEST(Replay, TimeThatGoesBackPublishesTheSampleCurrentThen) {
  Recording r;
  std::string e;
  ASSERT_TRUE(parseRecording(kGood, "rec.txt", r, e));
  for (const bool loop : {false, true}) {
    SCOPED_TRACE(loop ? "looping" : "not looping");
    LatestValueMailbox<HostState> box;
    ReplaySource src(r, loop);
    HostState out;
    uint64_t seq = 0;
    src.advanceTo(loop ? 2.6 : 1.0, box);  // looping: 0.6 into the third loop
    ASSERT_TRUE(box.readIfNewer(out, seq));
    EXPECT_EQ(out.hostFrame, loop ? 1u : 2u);
    EXPECT_TRUE(src.advanceTo(0.0, box));
    ASSERT_TRUE(box.readIfNewer(out, seq)) << "nothing published for replay time 0";
    EXPECT_EQ(out.hostFrame, 0u);
    EXPECT_TRUE(src.advanceTo(0.5, box));
    ASSERT_TRUE(box.readIfNewer(out, seq));
    EXPECT_EQ(out.hostFrame, 1u);
  }
}

// A looping replay's sample for a replay time is a function of that time alone, not of the
// frames before it: a paced run that skipped slots after an overrun renders the same frame for a
// slot as a free run that rendered every slot (README). Replay time 2.0 of a 1.0 s recording is
// the end of its second pass (the sample at 1.0), reached step by step; jumped to over skipped
// slots it showed the start of the third pass (the sample at 0.0).
TEST(Replay, LoopingSampleDependsOnTheTimeNotOnTheFramesBefore) {
  Recording r;
  std::string e;
  ASSERT_TRUE(parseRecording(kGood, "rec.txt", r, e));
  auto current = [&](const std::vector<double>& times) {
    LatestValueMailbox<HostState> box;
    ReplaySource src(r, true);
    HostState out;
    uint64_t seq = 0;
    for (double t : times) {
      src.advanceTo(t, box);
      box.readIfNewer(out, seq);
    }
    return out.hostFrame;
  };
  for (const double t : {1.0, 1.25, 2.0, 2.5, 3.0, 4.75}) {
    SCOPED_TRACE(t);
    std::vector<double> steps;
    for (double s = 0.0; s < t; s += 0.25) steps.push_back(s);
    steps.push_back(t);
    const uint64_t stepped = current(steps);
    EXPECT_EQ(current({0.0, t}), stepped);
    EXPECT_EQ(current({t}), stepped);
    EXPECT_EQ(current({0.0, t - 0.75, t}), stepped);
  }
}

TEST(Replay, Version2CarriesTimeOfDayAndDate) {
  Recording r;
  std::string e;
  ASSERT_TRUE(parseRecording("igd-recording 2\n0 7 1.5 1 2 3 4 5 6 45 0.1 1000 13.25 20260621\n"
                             "0.1 8 1.6 1 2 3 4 5 6 45 0.1 1000 -1 0\n",
                             "rec.txt", r, e))
      << e;
  ASSERT_EQ(r.samples.size(), 2u);
  EXPECT_DOUBLE_EQ(r.samples[0].state.timeOfDay_h, 13.25);
  EXPECT_EQ(r.samples[0].state.dateYmd, 20260621);
  EXPECT_LT(r.samples[1].state.timeOfDay_h, 0.0);
  // Version 1 files leave the sun to the scene.
  ASSERT_TRUE(parseRecording(kGood, "rec.txt", r, e)) << e;
  EXPECT_LT(r.samples[0].state.timeOfDay_h, 0.0);
  EXPECT_EQ(r.samples[0].state.dateYmd, 0);
  EXPECT_EQ(parseError("igd-recording 2\n0 0 0 1 2 3 4 5 6 45 0.1 1000\n"), "rec.txt:2: expected 14 fields, got 12");
  EXPECT_EQ(parseError("igd-recording 2\n0 0 0 1 2 3 4 5 6 45 0.1 1000 24 0\n"),
            "rec.txt:2: tod_h = '24': must be < 24 (negative = none)");
  EXPECT_EQ(parseError("igd-recording 2\n0 0 0 1 2 3 4 5 6 45 0.1 1000 1 2026.5\n"),
            "rec.txt:2: date_ymd = '2026.5': not a date YYYYMMDD (0 = none)");
}

// Version 3 adds the host's off-axis window (CIGI View Definition's asymmetric left/right/bottom/
// top): a recorded side channel replays with the window it was rendered with, exactly.
TEST(Replay, Version3CarriesTheOffAxisWindowExactly) {
  Recording a;
  HostSample h;
  h.state.windowShiftX = -0.57735026918962573;  // left -60 deg, right 0 deg: tan(-60) / 2
  h.state.windowShiftY = 0.1;
  h.state.windowWidth_tan = 1.7320508075688772;
  a.samples.push_back(h);
  h.t_s = 0.5;
  h.state.windowShiftX = h.state.windowShiftY = h.state.windowWidth_tan = 0.0;
  a.samples.push_back(h);
  const std::string text = formatRecording(a);
  EXPECT_EQ(text.rfind("igd-recording 4\n", 0), 0u) << text;
  EXPECT_NE(text.find(" 0 0 0 -1\n"), std::string::npos) << "a symmetric window, no visibility: " << text;
  Recording b;
  std::string e;
  ASSERT_TRUE(parseRecording(text, "rt", b, e)) << e;
  ASSERT_EQ(b.samples.size(), 2u);
  EXPECT_EQ(b.samples[0].state.windowShiftX, a.samples[0].state.windowShiftX);
  EXPECT_EQ(b.samples[0].state.windowShiftY, a.samples[0].state.windowShiftY);
  EXPECT_EQ(b.samples[0].state.windowWidth_tan, a.samples[0].state.windowWidth_tan);
  EXPECT_EQ(b.samples[1].state.windowWidth_tan, 0.0);
  // Version 2 files still read, with a symmetric window.
  ASSERT_TRUE(parseRecording("igd-recording 2\n0 7 1.5 1 2 3 4 5 6 45 0.1 1000 -1 0\n", "rec.txt", b, e)) << e;
  EXPECT_EQ(b.samples[0].state.windowShiftX, 0.0);
  EXPECT_EQ(b.samples[0].state.windowWidth_tan, 0.0);
  // Bad windows name the field and the value.
  EXPECT_EQ(parseError("igd-recording 3\n0 0 0 1 2 3 4 5 6 45 0.1 1000 -1 0 0 0\n"), "rec.txt:2: expected 17 fields, got 16");
  EXPECT_EQ(parseError("igd-recording 3\n0 0 0 1 2 3 4 5 6 45 0.1 1000 -1 0 600 0 1\n"),
            "rec.txt:2: shift_x = '600': must be in [-500, 500]");
  EXPECT_EQ(parseError("igd-recording 3\n0 0 0 1 2 3 4 5 6 45 0.1 1000 -1 0 0 nan 1\n"),
            "rec.txt:2: shift_y = 'nan': not a finite number");
  EXPECT_EQ(parseError("igd-recording 3\n0 0 0 1 2 3 4 5 6 45 0.1 1000 -1 0 0 0 -1\n"),
            "rec.txt:2: width_tan = '-1': must be in [0, 1000] (0 = the output's aspect ratio)");
  EXPECT_EQ(parseError("igd-recording 5\n"), "rec.txt:1: expected header 'igd-recording 4' (or 3, 2, 1), got 'igd-recording 5'");
}

// Version 4: the host's visibility (CIGI Atmosphere Control) replays exactly, "-1" (none) reads
// back as not given, version 3 files read without one, and a bad value names the field.
TEST(Replay, VisibilityRoundTripsAndOlderFilesHaveNone) {
  Recording a;
  HostSample h;
  h.state.visibility_m = static_cast<double>(1234.567f);  // a host's float
  a.samples.push_back(h);
  h.t_s = 1.0;
  h.state.visibility_m = -1.0;
  a.samples.push_back(h);
  h.t_s = 2.0;
  h.state.visibility_m = 1e7;
  a.samples.push_back(h);
  const std::string text = formatRecording(a);
  Recording b;
  std::string e;
  ASSERT_TRUE(parseRecording(text, "rt", b, e)) << e;
  ASSERT_EQ(b.samples.size(), 3u);
  EXPECT_EQ(b.samples[0].state.visibility_m, a.samples[0].state.visibility_m);
  EXPECT_LE(b.samples[1].state.visibility_m, 0.0);
  EXPECT_EQ(b.samples[2].state.visibility_m, 1e7);
  ASSERT_TRUE(parseRecording("igd-recording 3\n0 0 0 1 2 3 4 5 6 45 0.1 1000 -1 0 0 0 0\n", "rec.txt", b, e)) << e;
  EXPECT_LE(b.samples[0].state.visibility_m, 0.0);
  ASSERT_TRUE(parseRecording("igd-recording 4\n0 0 0 1 2 3 4 5 6 45 0.1 1000 -1 0 0 0 0 800\n", "rec.txt", b, e)) << e;
  EXPECT_EQ(b.samples[0].state.visibility_m, 800.0);
  EXPECT_EQ(parseError("igd-recording 4\n0 0 0 1 2 3 4 5 6 45 0.1 1000 -1 0 0 0 0\n"), "rec.txt:2: expected 18 fields, got 17");
  EXPECT_EQ(parseError("igd-recording 4\n0 0 0 1 2 3 4 5 6 45 0.1 1000 -1 0 0 0 0 2e7\n"),
            "rec.txt:2: vis_m = '2e7': must be <= 1e7 (metres; <= 0 = the scene's fog)");
  EXPECT_EQ(parseError("igd-recording 4\n0 0 0 1 2 3 4 5 6 45 0.1 1000 -1 0 0 0 0 inf\n"),
            "rec.txt:2: vis_m = 'inf': not a finite number");
}

TEST(Replay, SampleLinesRoundTripToAMicrometre) {
  HostSample h;
  h.t_s = 12.3456789;
  h.state.hostFrame = 42;
  h.state.eyeEnu_m = {1234567.1234567, -7654321.7654321, 10000.000001};
  h.state.heading_deg = 359.999999;
  h.state.timeOfDay_h = 6.5;
  h.state.dateYmd = 20261123;
  Recording r;
  std::string e;
  ASSERT_TRUE(parseRecording(recordingHeader() + formatSample(h), "rec.txt", r, e)) << e;
  const HostState& s = r.samples.at(0).state;
  EXPECT_NEAR(s.eyeEnu_m.x, h.state.eyeEnu_m.x, 1e-6);
  EXPECT_NEAR(s.eyeEnu_m.y, h.state.eyeEnu_m.y, 1e-6);
  EXPECT_NEAR(s.eyeEnu_m.z, h.state.eyeEnu_m.z, 1e-6);
  EXPECT_NEAR(s.heading_deg, h.state.heading_deg, 1e-6);
  EXPECT_EQ(s.dateYmd, 20261123);
  EXPECT_EQ(s.hostFrame, 42u);
}

// A live sample the links accept (CIGI near/far (0, 1e8], Modbus near (0, 1e6]) must load back
// from the recording: a near plane of 1e-7 m was written as "0.000000" and the whole file was
// then refused ("need 0 < near_m < far_m").
TEST(Replay, TinyClipPlanesAndFieldOfViewSurviveTheRecording) {
  HostSample h;
  h.state.near_m = 1e-7;
  h.state.far_m = 2e-4;
  h.state.fovY_deg = 1e-7;
  Recording r;
  std::string e;
  ASSERT_TRUE(parseRecording(recordingHeader() + formatSample(h), "rec.txt", r, e)) << e;
  const HostState& s = r.samples.at(0).state;
  EXPECT_DOUBLE_EQ(s.near_m, 1e-7);
  EXPECT_DOUBLE_EQ(s.far_m, 2e-4);
  EXPECT_DOUBLE_EQ(s.fovY_deg, 1e-7);
  // A live CIGI value is a float: it round-trips exactly too.
  h.state.near_m = static_cast<double>(0.1f);
  h.state.far_m = static_cast<double>(50000.3f);
  ASSERT_TRUE(parseRecording(recordingHeader() + formatSample(h), "rec.txt", r, e)) << e;
  EXPECT_EQ(r.samples.at(0).state.near_m, static_cast<double>(0.1f));
  EXPECT_EQ(r.samples.at(0).state.far_m, static_cast<double>(50000.3f));
}

// host_frame is a uint64: a value that does not fit (or that a double cannot hold exactly) is
// an error naming the value, not an undefined float -> integer conversion.
TEST(Replay, HostFrameTooLargeIsAnError) {
  EXPECT_EQ(parseError("igd-recording 1\n0 1e20 0 1 2 3 4 5 6 45 0.1 1000\n"),
            "rec.txt:2: host_frame = '1e20': not a non-negative integer up to 2^53");
  EXPECT_EQ(parseError("igd-recording 1\n0 18446744073709551616 0 1 2 3 4 5 6 45 0.1 1000\n"),
            "rec.txt:2: host_frame = '18446744073709551616': not a non-negative integer up to 2^53");
  Recording r;
  std::string e;
  ASSERT_TRUE(parseRecording("igd-recording 1\n0 9007199254740992 0 1 2 3 4 5 6 45 0.1 1000\n", "rec.txt", r, e)) << e;
  EXPECT_EQ(r.samples.at(0).state.hostFrame, 9007199254740992ull);
}

// tod_h must stay below 24: a time of day that the fixed format would round up to 24 (any value
// within 5e-7 h of midnight, which the parser accepts) must be written so that it reads back.
TEST(Replay, TimeOfDayJustBeforeMidnightSurvivesTheRecording) {
  Recording r;
  std::string e;
  ASSERT_TRUE(parseRecording("igd-recording 2\n0 0 0 1 2 3 4 5 6 45 0.1 1000 23.9999999 20261231\n", "rec.txt", r, e))
      << e;
  Recording back;
  ASSERT_TRUE(parseRecording(formatRecording(r), "rec.txt", back, e)) << e;
  EXPECT_DOUBLE_EQ(back.samples.at(0).state.timeOfDay_h, 23.9999999);
  HostSample h;
  h.state.timeOfDay_h = std::nextafter(24.0, 0.0);
  ASSERT_TRUE(parseRecording(recordingHeader() + formatSample(h), "rec.txt", back, e)) << e;
  EXPECT_LT(back.samples.at(0).state.timeOfDay_h, 24.0);
  EXPECT_EQ(back.samples.at(0).state.timeOfDay_h, h.state.timeOfDay_h);
}

// A sample line is written whole whatever its length: the parser accepts any finite position,
// and a line cut at a fixed buffer size lost its end and its newline (the next sample was glued
// to it, and the file no longer parsed).
TEST(Replay, HugeFiniteValuesAreWrittenWhole) {
  Recording r;
  HostSample h;
  h.state.eyeEnu_m = {1e300, -1e300, 1e300};
  h.state.simTime_s = 1e300;
  r.samples.push_back(h);
  h.t_s = 1.0;
  h.state.hostFrame = 1;
  r.samples.push_back(h);
  Recording back;
  std::string e;
  ASSERT_TRUE(parseRecording(formatRecording(r), "rec.txt", back, e)) << e;
  ASSERT_EQ(back.samples.size(), 2u);
  EXPECT_EQ(back.samples[1].state.eyeEnu_m.x, 1e300);
  EXPECT_EQ(back.samples[1].state.eyeEnu_m.y, -1e300);
  EXPECT_EQ(back.samples[1].state.simTime_s, 1e300);
  EXPECT_EQ(back.samples[1].state.hostFrame, 1u);
}
