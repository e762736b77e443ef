#include "io/replay.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

#include "lod/view.h"

namespace ig::io {
namespace {

constexpr std::string_view kMagic = "igd-recording";
// Version 1 has the first 12 fields; version 2 adds the date and time of day; version 3 adds the
// off-axis window (HostState windowShiftX, windowShiftY, windowWidth_tan); version 4 (written now)
// the host's visibility (HostState visibility_m).
constexpr int kVersion = 4;
constexpr const char* kFieldNames[] = {"t_s",         "host_frame", "sim_time_s", "east_m",
                                       "north_m",     "up_m",       "heading_deg", "pitch_deg",
                                       "roll_deg",    "fovy_deg",   "near_m",     "far_m",
                                       "tod_h",       "date_ymd",   "shift_x",    "shift_y",
                                       "width_tan",   "vis_m"};
constexpr size_t kFieldCount = std::size(kFieldNames);
constexpr size_t kFieldCountV1 = 12;
constexpr size_t kFieldCountV2 = 14;
constexpr size_t kFieldCountV3 = 17;
// The window's limits, as the frame loop checks a host sample (ig/service.cpp).
constexpr double kMaxShift = lod::kMaxWindowShift;
// Timestamps are written to 0.1 ms: a sample within that of the replay time is due.
constexpr double kTimeTolerance_s = 1e-4;
// host_frame is read as a double: integers are exact up to 2^53.
constexpr double kMaxExactFrame = 9007199254740992.0;

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

bool parseDouble(std::string_view tok, double& v) {
  const char* end = tok.data() + tok.size();
  auto r = std::from_chars(tok.data(), end, v);
  return r.ec == std::errc() && r.ptr == end;
}

}  // namespace

bool parseRecording(std::string_view text, const std::string& name, Recording& out, std::string& error) {
  Recording rec;
  int lineNo = 0;
  bool sawHeader = false;
  size_t fields = kFieldCount;
  auto fail = [&](const std::string& msg) {
    error = name + ":" + std::to_string(lineNo) + ": " + msg;
    return false;
  };
  while (!text.empty()) {
    const size_t eol = text.find('\n');
    std::string_view line = text.substr(0, eol);
    text.remove_prefix(eol == std::string_view::npos ? text.size() : eol + 1);
    ++lineNo;
    if (const size_t hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
    line = trim(line);
    if (line.empty()) continue;
    const std::string_view raw = line;

    std::string_view tokens[kFieldCount + 1];
    size_t count = 0;
    while (!line.empty() && count <= kFieldCount) {
      const size_t sp = line.find_first_of(" \t");
      tokens[count++] = line.substr(0, sp);
      line = trim(sp == std::string_view::npos ? std::string_view{} : line.substr(sp));
    }
    if (!sawHeader) {
      double version = 0;
      if (count != 2 || tokens[0] != kMagic || !parseDouble(tokens[1], version) ||
          (version != 1 && version != 2 && version != 3 && version != 4))
        return fail("expected header 'igd-recording 4' (or 3, 2, 1), got '" + std::string(raw) + "'");
      fields = version == 1 ? kFieldCountV1 : version == 2 ? kFieldCountV2 : version == 3 ? kFieldCountV3 : kFieldCount;
      sawHeader = true;
      continue;
    }
    if (count != fields || !line.empty())
      return fail("expected " + std::to_string(fields) + " fields, got " +
                  (line.empty() ? std::to_string(count) : std::string("more")));
    double v[kFieldCount] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, -1.0, 0, 0, 0, 0, -1.0};
    for (size_t i = 0; i < fields; ++i) {
      if (!parseDouble(tokens[i], v[i]) || !std::isfinite(v[i]))
        return fail(std::string(kFieldNames[i]) + " = '" + std::string(tokens[i]) + "': not a finite number");
    }
    HostSample s;
    s.t_s = v[0];
    if (v[1] < 0 || v[1] != std::floor(v[1]))
      return fail("host_frame = '" + std::string(tokens[1]) + "': not a non-negative integer");
    if (v[1] > kMaxExactFrame)  // read as a double: exact (and convertible) only up to 2^53
      return fail("host_frame = '" + std::string(tokens[1]) + "': not a non-negative integer up to 2^53");
    s.state.hostFrame = static_cast<uint64_t>(v[1]);
    s.state.simTime_s = v[2];
    s.state.eyeEnu_m = {v[3], v[4], v[5]};
    s.state.heading_deg = v[6];
    s.state.pitch_deg = v[7];
    s.state.roll_deg = v[8];
    s.state.fovY_deg = v[9];
    s.state.near_m = v[10];
    s.state.far_m = v[11];
    s.state.timeOfDay_h = v[12];
    if (v[13] < 0 || v[13] > 99991231 || v[13] != std::floor(v[13]))
      return fail("date_ymd = '" + std::string(tokens[13]) + "': not a date YYYYMMDD (0 = none)");
    s.state.dateYmd = static_cast<int32_t>(v[13]);
    if (s.state.timeOfDay_h >= 24.0)
      return fail("tod_h = '" + std::string(tokens[12]) + "': must be < 24 (negative = none)");
    if (s.t_s < 0 || (!rec.samples.empty() && s.t_s < rec.samples.back().t_s))
      return fail("t_s = '" + std::string(tokens[0]) + "': must be >= 0 and non-decreasing");
    if (!(s.state.fovY_deg > 0 && s.state.fovY_deg < 180))
      return fail("fovy_deg = '" + std::string(tokens[9]) + "': must be in (0, 180)");
    if (!(s.state.near_m > 0 && s.state.far_m > s.state.near_m))
      return fail("near_m/far_m = '" + std::string(tokens[10]) + " " + std::string(tokens[11]) +
                  "': need 0 < near_m < far_m");
    if (fields >= kFieldCountV3) {
      s.state.windowShiftX = v[14];
      s.state.windowShiftY = v[15];
      s.state.windowWidth_tan = v[16];
      for (size_t i : {size_t{14}, size_t{15}})
        if (!(std::abs(v[i]) <= kMaxShift))
          return fail(std::string(kFieldNames[i]) + " = '" + std::string(tokens[i]) + "': must be in [-500, 500]");
      if (!(v[16] >= 0.0 && v[16] <= 2.0 * kMaxShift))
        return fail("width_tan = '" + std::string(tokens[16]) + "': must be in [0, 1000] (0 = the output's aspect ratio)");
    }
    s.state.visibility_m = v[17];
    if (!(v[17] <= kMaxVisibility_m))
      return fail("vis_m = '" + std::string(tokens[17]) + "': must be <= 1e7 (metres; <= 0 = the scene's fog)");
    rec.samples.push_back(s);
  }
  if (!sawHeader) return fail("empty recording: expected header 'igd-recording 4'");
  if (rec.samples.empty()) return fail("recording has no samples");
  out = std::move(rec);
  return true;
}

bool loadRecording(const std::string& file, Recording& out, std::string& error) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    error = file + ": cannot open: " + std::strerror(errno);
    return false;
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  return parseRecording(ss.str(), file, out, error);
}

std::string recordingHeader() {
  std::string s = std::string(kMagic) + " " + std::to_string(kVersion) + "\n#";
  for (const char* n : kFieldNames) s += std::string(" ") + n;
  return s + "\n";
}

namespace {
// `v` with `decimals` fixed decimals when that text reads back as exactly `v` (the usual case,
// and what the committed recordings hold), else with 17 significant digits: a field that must
// stay positive (fovy, near, far) never rounds to 0 and a live float value replays exactly.
std::string exactFixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  double back = 0;
  if (parseDouble(buf, back) && back == v) return buf;
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}
}  // namespace

std::string formatSample(const HostSample& h) {
  // Micrometres and micro-degrees: a recorded live run replays within float precision of what
  // was rendered live. The frustum fields are written exactly (a tiny near plane or field of
  // view would otherwise round to 0, which the parser refuses).
  const HostState& st = h.state;
  const std::string fovy = exactFixed(st.fovY_deg, 6), nearM = exactFixed(st.near_m, 6),
                    farM = exactFixed(st.far_m, 3);
  // tod_h must read back below 24 (the parser refuses 24): a time within 5e-7 h (1.8 ms) of midnight
  // would round up to "24.000000" in the fixed format.
  std::string tod = "-1.000000";
  if (st.timeOfDay_h >= 0) {
    char t[64];
    std::snprintf(t, sizeof t, "%.6f", st.timeOfDay_h);
    double back = 0;
    if (!parseDouble(t, back) || back >= 24.0) std::snprintf(t, sizeof t, "%.17g", st.timeOfDay_h);
    tod = t;
  }
  // Any finite value the parser accepts is written whole (%f of a huge value is hundreds of
  // digits): a line cut at a fixed buffer lost its end and its newline.
  // The window in tangent units, exactly (a symmetric window is "0 0 0").
  auto window = [](double v) { return v == 0.0 ? std::string("0") : exactFixed(v, 9); };
  const std::string shiftX = window(st.windowShiftX), shiftY = window(st.windowShiftY),
                    width = window(st.windowWidth_tan);
  // The visibility exactly (a host's float survives); none is "-1".
  const std::string vis = st.visibility_m > 0.0 ? exactFixed(st.visibility_m, 3) : std::string("-1");
  auto print = [&](char* out, size_t size) {
    return std::snprintf(out, size, "%.6f %llu %.6f %.6f %.6f %.6f %.6f %.6f %.6f %s %s %s %s %d %s %s %s %s\n", h.t_s,
                         static_cast<unsigned long long>(st.hostFrame), st.simTime_s, st.eyeEnu_m.x, st.eyeEnu_m.y,
                         st.eyeEnu_m.z, st.heading_deg, st.pitch_deg, st.roll_deg, fovy.c_str(), nearM.c_str(),
                         farM.c_str(), tod.c_str(), static_cast<int>(st.dateYmd), shiftX.c_str(), shiftY.c_str(),
                         width.c_str(), vis.c_str());
  };
  char buf[512];
  const int n = print(buf, sizeof buf);
  if (n >= 0 && static_cast<size_t>(n) < sizeof buf) return buf;
  std::string line(static_cast<size_t>(n > 0 ? n : 0) + 1, '\0');
  print(line.data(), line.size());
  line.resize(line.size() - 1);
  return line;
}

std::string formatRecording(const Recording& recording) {
  std::string s = recordingHeader();
  for (const auto& h : recording.samples) s += formatSample(h);
  return s;
}

bool saveRecording(const std::string& file, const Recording& recording, std::string& error) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  if (!out) {
    error = file + ": cannot write: " + std::strerror(errno);
    return false;
  }
  out << formatRecording(recording);
  if (!out.flush()) {
    error = file + ": write failed";
    return false;
  }
  return true;
}

const HostSample& sampleAt(const Recording& recording, double t_s) {
  const auto& v = recording.samples;
  auto it = std::upper_bound(v.begin(), v.end(), t_s + kTimeTolerance_s, [](double t, const HostSample& s) { return t < s.t_s; });
  return it == v.begin() ? v.front() : *(it - 1);
}

bool ReplaySource::advanceTo(double t_s, LatestValueMailbox<HostState>& mailbox) {
  const auto& samples = recording_.samples;
  if (samples.empty()) return false;
  // The pass of a looping replay that t_s falls in, from t_s alone (not from the times given
  // before, which skip slots after an overrun): pass n > 0 covers (n D, (n + 1) D], so its end
  // time shows the last sample, as when the replay gets there frame by frame.
  const double d = recording_.duration_s();
  const double base = loop_ && d > 0 && t_s > d ? d * (std::ceil(t_s / d) - 1.0) : 0.0;
  if (base != loopBase_s_ || t_s < lastT_s_) {
    // Another pass, or time that went back: start over (the scan below finds t_s's sample).
    loopBase_s_ = base;
    next_ = 0;
  }
  lastT_s_ = t_s;
  const double local = t_s - loopBase_s_ + kTimeTolerance_s;
  size_t newest = next_;
  while (newest < samples.size() && samples[newest].t_s <= local) ++newest;
  if (newest != next_) {
    mailbox.publish(samples[newest - 1].state);
    next_ = newest;
  }
  return !finished(t_s);
}

Recording makeDefaultRecording(double rate_hz, double duration_s) {
  constexpr double kPi = 3.14159265358979323846;
  Recording rec;
  // Samples every 1 / rate from 0, the last one at the duration (the recording is that long:
  // floor(0.29 x 100) + 1 samples ended at 0.28 s): a whole number of periods (within rounding:
  // 0.29 x 100 = 28.999999999999996) ends on a period, any other duration with a shorter last step.
  const double periods = duration_s > 0.0 && rate_hz > 0.0 ? duration_s * rate_hz : 0.0;
  const double whole = std::round(periods);
  const auto steps = static_cast<size_t>(std::abs(periods - whole) <= 1e-9 * std::max(1.0, whole) ? whole : std::ceil(periods));
  const size_t n = steps + 1;
  rec.samples.reserve(n);
  // A left-hand orbit of radius 1800 m around the terrain centre at 75 m/s, starting south-west,
  // with a gentle climb and a descending low pass near the end.
  constexpr double kRadius_m = 1800.0, kSpeed_mps = 75.0;
  for (size_t i = 0; i < n; ++i) {
    const double t = i == steps && steps > 0 ? duration_s : static_cast<double>(i) / rate_hz;
    const double a = -0.75 * kPi + kSpeed_mps * t / kRadius_m;  // angle from east, CCW
    HostSample s;
    s.t_s = t;
    s.state.hostFrame = i;
    s.state.simTime_s = 3600.0 * 10.0 + t;  // scenario starts at 10:00 simulation time
    const double u = t / std::max(duration_s, 1e-9);
    s.state.eyeEnu_m = {kRadius_m * std::cos(a), kRadius_m * std::sin(a), 900.0 + 120.0 * std::sin(kPi * u) - 150.0 * u};
    // Tangent of a CCW orbit points at angle a + 90 deg from east; heading is from north, CW.
    s.state.heading_deg = std::fmod(360.0 + 90.0 - (a * 180.0 / kPi + 90.0), 360.0);
    s.state.pitch_deg = -9.0 - 4.0 * u;
    s.state.roll_deg = -12.0;  // banked left
    s.state.fovY_deg = 45.0;
    s.state.near_m = 0.1;
    s.state.far_m = 100000.0;
    rec.samples.push_back(s);
  }
  return rec;
}

}  // namespace ig::io
