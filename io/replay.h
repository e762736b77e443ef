// Host recordings: a timestamped text file of HostState samples, written by the recorder (or
// `igtool make-recording`) and replayed into the frame loop for tests and hardware-in-the-loop
// runs. Text so a person can read and edit it; '#' starts a comment.
//
//   igd-recording 4
//   # t_s host_frame sim_time_s east_m north_m up_m heading_deg pitch_deg roll_deg fovy_deg near_m far_m tod_h date_ymd shift_x shift_y width_tan vis_m
//   0.000 0 0.000 -1200.0 -1800.0 450.0 35.0 -4.0 0.0 45.0 0.1 100000 -1 0 0 0 0 -1
//
// t_s is the replay clock (seconds from the start of the replay, non-decreasing); the sample
// with the largest t_s <= now is the current one. tod_h (UTC hours, negative = not given) and
// date_ymd (YYYYMMDD, 0 = not given) drive the sun when the host sent them. shift_x, shift_y
// and width_tan are the host's off-axis window (CIGI View Definition's left/right/bottom/top:
// HostState windowShiftX, windowShiftY, windowWidth_tan; 0 0 0 = symmetric, as wide as the
// output). vis_m is the host's visibility for the fog (CIGI Atmosphere Control, the Modbus
// register visibility_m, the CAN signal Visibility; HostState
// visibility_m, metres, at most 1e7; <= 0 = not given: the scene's [fog]). Version 3 files (the
// first 17 fields), version 2 (14) and version 1 (12) are still read, with a symmetric window
// and no visibility.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "io/host_state.h"
#include "io/mailbox.h"

namespace ig::io {

struct HostSample {
  double t_s = 0.0;
  HostState state;
};

struct Recording {
  std::vector<HostSample> samples;
  double duration_s() const { return samples.empty() ? 0.0 : samples.back().t_s; }
};

// Parses a recording. On error returns false and sets `error` to "name:line: message" naming
// the bad field and value; `out` is untouched.
bool parseRecording(std::string_view text, const std::string& name, Recording& out, std::string& error);
bool loadRecording(const std::string& file, Recording& out, std::string& error);
std::string formatRecording(const Recording& recording);
// The header lines and one sample line of the current version (the live recorder appends).
std::string recordingHeader();
std::string formatSample(const HostSample& sample);
bool saveRecording(const std::string& file, const Recording& recording, std::string& error);

// The sample current at replay time t_s: the last one with t <= t_s (the first one before it).
// Requires a non-empty recording.
const HostSample& sampleAt(const Recording& recording, double t_s);

// Feeds a recording into a mailbox as replay time advances. Deterministic: driven by the
// time it is given, not by a clock.
class ReplaySource {
 public:
  ReplaySource(Recording recording, bool loop) : recording_(std::move(recording)), loop_(loop) {}
  // Publishes the current sample for replay time t_s (if it changed). Returns false once a
  // non-looping replay has passed its last sample. A time before the previous call's (a frame
  // loop run again from slot 0) replays from the beginning: the sample current at t_s.
  bool advanceTo(double t_s, LatestValueMailbox<HostState>& mailbox);
  bool finished(double t_s) const { return !loop_ && t_s > recording_.duration_s(); }
  const Recording& recording() const { return recording_; }

 private:
  Recording recording_;
  bool loop_;
  size_t next_ = 0;        // first sample not yet published
  double loopBase_s_ = 0;  // replay time at which the current pass of a loop started
  double lastT_s_ = 0;     // the previous call's t_s
};

// The built-in host recording used by the default scene: a circuit over the default terrain
// (climb-out, a banked turn, a low pass and a descent) with simulation time. Samples every
// 1 / rate_hz s from 0 s; the last one is at duration_s (duration_s() == duration_s), after a
// shorter step when the duration is not a whole number of periods.
Recording makeDefaultRecording(double rate_hz, double duration_s);

}  // namespace ig::io
