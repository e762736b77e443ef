#include "io/can_map.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

namespace ig::io {
namespace {

constexpr int32_t kNa32 = std::numeric_limits<int32_t>::min();
constexpr int16_t kNa16 = std::numeric_limits<int16_t>::min();
constexpr uint16_t kNaHeading = 0xFFFF;
constexpr uint32_t kNaTime = 0xFFFFFFFFu;
constexpr uint8_t kFullMask = (1u << kCanFrameCount) - 1;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Divisors of the raw values (exact in double, so raw / divisor is correctly rounded).
constexpr double kLatLonDiv = 1e7, kHeightDiv = 1e3, kAngleDiv = 100.0, kTimeDiv = 1e3;

void putU16(uint8_t* p, uint16_t v) {
  p[0] = static_cast<uint8_t>(v);
  p[1] = static_cast<uint8_t>(v >> 8);
}
void putU32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}
uint16_t getU16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }
uint32_t getU32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8) | (static_cast<uint32_t>(p[2]) << 16) |
         (static_cast<uint32_t>(p[3]) << 24);
}

// Rounds v / scale to an integer in [lo, hi]; NaN/inf -> na.
int64_t toRaw(double v, double div, int64_t lo, int64_t hi, int64_t na) {
  if (!std::isfinite(v)) return na;
  const double r = std::round(v * div);
  if (r <= static_cast<double>(lo)) return lo;
  if (r >= static_cast<double>(hi)) return hi;
  return static_cast<int64_t>(r);
}

bool isNewer(uint8_t a, uint8_t b) { return static_cast<int8_t>(static_cast<uint8_t>(a - b)) > 0; }

}  // namespace

bool validateCanLinkConfig(const CanLinkConfig& config, LinkConfigError& error) {
  if (config.interface.empty() || config.interface.size() > 15 ||
      config.interface.find_first_of(" /\t\n") != std::string::npos) {
    error = {"host.can.interface", "\"" + config.interface + "\"",
             "must be a network interface name of 1..15 characters"};
    return false;
  }
  if (config.baseId > 0x7FF - (kCanFrameCount - 1)) {
    error = {"host.can.base_id", std::to_string(config.baseId),
             "must be 0..2043 (0x7FB) so that base_id+4 is an 11-bit id"};
    return false;
  }
  if (config.stale_ms < 1 || config.stale_ms > 60000) {
    error = {"host.can.stale_ms", std::to_string(config.stale_ms), "must be 1..60000"};
    return false;
  }
  return true;
}

bool validateCanLinkConfig(const CanLinkConfig& config, std::string& error) {
  LinkConfigError e;
  if (validateCanLinkConfig(config, e)) return true;
  error = e.message();
  return false;
}

const char* toString(CanDecodeStatus status) {
  switch (status) {
    case CanDecodeStatus::Ok: return "ok";
    case CanDecodeStatus::NotInMap: return "not in the frame map";
    case CanDecodeStatus::BadLength: return "length is not 8";
    case CanDecodeStatus::Remote: return "remote frame";
    case CanDecodeStatus::Fd: return "CAN FD frame";
  }
  return "?";
}

void encodeCanSet(const CanEyeSet& set, uint8_t seq, uint32_t baseId, std::array<CanFrame, kCanFrameCount>& out) {
  for (int i = 0; i < kCanFrameCount; ++i) {
    CanFrame& f = out[static_cast<size_t>(i)];
    f = CanFrame{};
    f.id = baseId + static_cast<uint32_t>(i);
    f.len = kCanFrameLen;
    f.data[0] = seq;
  }
  constexpr int64_t i32lo = std::numeric_limits<int32_t>::min() + 1, i32hi = std::numeric_limits<int32_t>::max();
  constexpr int64_t i16lo = std::numeric_limits<int16_t>::min() + 1, i16hi = std::numeric_limits<int16_t>::max();
  putU32(&out[0].data[1], static_cast<uint32_t>(toRaw(set.lat_deg, kLatLonDiv, i32lo, i32hi, kNa32)));
  // Time of day: raw 0 = not given, else 1 + centiseconds after midnight (the day wraps).
  uint32_t tod = 0;
  if (std::isnan(set.timeOfDay_h)) {
    tod = kCanVisibilityNa;
  } else if (set.timeOfDay_h >= 0.0 && std::isfinite(set.timeOfDay_h)) {
    const double s = std::fmod(set.timeOfDay_h, 24.0) * 3600.0;
    tod = 1u + static_cast<uint32_t>(std::min(std::round(s * 100.0), static_cast<double>(kCanTimeOfDayMaxRaw - 1)));
  }
  out[0].data[5] = static_cast<uint8_t>(tod);
  out[0].data[6] = static_cast<uint8_t>(tod >> 8);
  out[0].data[7] = static_cast<uint8_t>(tod >> 16);
  putU32(&out[1].data[1], static_cast<uint32_t>(toRaw(set.lon_deg, kLatLonDiv, i32lo, i32hi, kNa32)));
  putU32(&out[2].data[1], static_cast<uint32_t>(toRaw(set.height_m, kHeightDiv, i32lo, i32hi, kNa32)));
  // NaN: not available; not given (<= 0): 0; a positive visibility at least 1 m (never "not
  // given" by rounding), "unlimited" (+infinity, anything above the raw range) the largest raw.
  const double v = set.visibility_m;
  const uint32_t vis = std::isnan(v)                                   ? kCanVisibilityNa
                       : v <= 0.0                                      ? 0u
                       : v >= static_cast<double>(kCanVisibilityNa - 1) ? kCanVisibilityNa - 1
                                                                       : static_cast<uint32_t>(std::max(1.0, std::round(v)));
  out[2].data[5] = static_cast<uint8_t>(vis);
  out[2].data[6] = static_cast<uint8_t>(vis >> 8);
  out[2].data[7] = static_cast<uint8_t>(vis >> 16);
  uint16_t heading = kNaHeading;
  if (std::isfinite(set.heading_deg)) {
    double h = std::fmod(set.heading_deg, 360.0);
    if (h < 0.0) h += 360.0;
    const auto raw = static_cast<int64_t>(std::round(h * kAngleDiv));
    heading = static_cast<uint16_t>(raw >= 36000 ? 0 : raw);
  }
  putU16(&out[3].data[1], heading);
  putU16(&out[3].data[3], static_cast<uint16_t>(toRaw(set.pitch_deg, kAngleDiv, i16lo, i16hi, kNa16)));
  putU16(&out[3].data[5], static_cast<uint16_t>(toRaw(set.roll_deg, kAngleDiv, i16lo, i16hi, kNa16)));
  putU32(&out[4].data[1], static_cast<uint32_t>(toRaw(set.simTime_s, kTimeDiv, 0, kNaTime - 1, kNaTime)));
  out[4].data[5] = static_cast<uint8_t>(set.hostFrame);
  out[4].data[6] = static_cast<uint8_t>(set.hostFrame >> 8);
  out[4].data[7] = static_cast<uint8_t>(set.hostFrame >> 16);
}

CanDecodeStatus decodeCanFrame(const CanFrame& frame, uint32_t baseId, CanDecodedFrame& out, CanEyeSet& fields) {
  if (frame.error || frame.extended || frame.id < baseId || frame.id - baseId >= kCanFrameCount)
    return CanDecodeStatus::NotInMap;
  if (frame.remote) return CanDecodeStatus::Remote;
  if (frame.fd) return CanDecodeStatus::Fd;
  if (frame.len != kCanFrameLen) return CanDecodeStatus::BadLength;
  const uint8_t* d = frame.data.data();
  out.index = static_cast<CanFrameIndex>(frame.id - baseId);
  out.seq = d[0];
  out.rejectedFields = 0;
  // A field outside [lo, hi] or equal to its "not available" value becomes NaN.
  auto checked = [&out](int64_t raw, int64_t lo, int64_t hi, double div) {
    if (raw < lo || raw > hi) {
      ++out.rejectedFields;
      return kNaN;
    }
    return static_cast<double>(raw) / div;
  };
  switch (out.index) {
    case CanFrameIndex::Lat:
      fields.lat_deg = checked(static_cast<int32_t>(getU32(d + 1)), -900'000'000, 900'000'000, kLatLonDiv);
      if (const int64_t tod = static_cast<int64_t>(d[5]) | (static_cast<int64_t>(d[6]) << 8) | (static_cast<int64_t>(d[7]) << 16);
          tod == 0) {
        fields.timeOfDay_h = -1.0;  // not given
      } else {
        fields.timeOfDay_h = checked(tod - 1, 0, kCanTimeOfDayMaxRaw - 1, 100.0 * 3600.0);
      }
      break;
    case CanFrameIndex::Lon:
      fields.lon_deg = checked(static_cast<int32_t>(getU32(d + 1)), -1'800'000'000, 1'800'000'000, kLatLonDiv);
      break;
    case CanFrameIndex::Height:
      fields.height_m = checked(static_cast<int32_t>(getU32(d + 1)), static_cast<int64_t>(kCanHeightMin_m * kHeightDiv),
                                static_cast<int64_t>(kCanHeightMax_m * kHeightDiv), kHeightDiv);
      // Above 1e7 m (a host's "unlimited"): 1e7, as CIGI's; 0xFFFFFF: not available.
      fields.visibility_m = std::min(checked(static_cast<int64_t>(d[5]) | (static_cast<int64_t>(d[6]) << 8) |
                                                 (static_cast<int64_t>(d[7]) << 16),
                                             0, kCanVisibilityNa - 1, 1.0),
                                     static_cast<double>(kCanVisibilityMax_m));
      break;
    case CanFrameIndex::Attitude:
      fields.heading_deg = checked(getU16(d + 1), 0, 35999, kAngleDiv);
      fields.pitch_deg = checked(static_cast<int16_t>(getU16(d + 3)), -9000, 9000, kAngleDiv);
      fields.roll_deg = checked(static_cast<int16_t>(getU16(d + 5)), -18000, 18000, kAngleDiv);
      break;
    case CanFrameIndex::SimTime:
      fields.simTime_s = checked(getU32(d + 1), 0, kNaTime - 1, kTimeDiv);
      fields.hostFrame = static_cast<uint32_t>(d[5]) | (static_cast<uint32_t>(d[6]) << 8) |
                         (static_cast<uint32_t>(d[7]) << 16);
      break;
  }
  return CanDecodeStatus::Ok;
}

CanSetAssembler::CanSetAssembler(const CanLinkConfig& config, const lod::Geodetic& origin, LinkCounters& counters)
    : baseId_(config.baseId), stale_us_(config.stale_ms * 1000), enu_(origin), counters_(counters) {
  state_.lat_deg = origin.lat_deg;
  state_.lon_deg = origin.lon_deg;
  state_.height_m = origin.height_m;
  state_.eyeEnu_m = glm::dvec3(0.0);
}

bool CanSetAssembler::expire(int64_t now_us) {
  if (!inProgress_ || now_us - start_us_ <= stale_us_) return false;
  inProgress_ = false;
  counters_.dropped.fetch_add(1, std::memory_order_relaxed);
  return true;
}

CanSetAssembler::Result CanSetAssembler::push(const CanFrame& frame, int64_t now_us, HostState& out) {
  CanDecodedFrame d;
  CanEyeSet fields;
  const CanDecodeStatus status = decodeCanFrame(frame, baseId_, d, fields);
  if (status == CanDecodeStatus::NotInMap) return Result::Ignored;
  counters_.received.fetch_add(1, std::memory_order_relaxed);
  if (status != CanDecodeStatus::Ok) {
    counters_.malformed.fetch_add(1, std::memory_order_relaxed);
    return Result::Rejected;
  }
  expire(now_us);
  if (inProgress_) {
    if (d.seq == seq_) {
      if (mask_ & (1u << static_cast<unsigned>(d.index))) {
        counters_.malformed.fetch_add(1, std::memory_order_relaxed);  // the same frame twice in one set
        return Result::Rejected;
      }
    } else if (isNewer(d.seq, seq_)) {
      counters_.dropped.fetch_add(1, std::memory_order_relaxed);  // the incomplete set is abandoned
      inProgress_ = false;
    } else {
      counters_.late.fetch_add(1, std::memory_order_relaxed);
      return Result::Rejected;
    }
  }
  if (!inProgress_) {
    if (committed_ && now_us - lastCommit_us_ <= stale_us_ && !isNewer(d.seq, lastSeq_)) {
      counters_.late.fetch_add(1, std::memory_order_relaxed);  // a set already committed, or older
      return Result::Rejected;
    }
    inProgress_ = true;
    seq_ = d.seq;
    mask_ = 0;
    start_us_ = now_us;
    partial_ = CanEyeSet{};
  }
  mask_ = static_cast<uint8_t>(mask_ | (1u << static_cast<unsigned>(d.index)));
  switch (d.index) {
    case CanFrameIndex::Lat:
      partial_.lat_deg = fields.lat_deg;
      partial_.timeOfDay_h = fields.timeOfDay_h;
      break;
    case CanFrameIndex::Lon: partial_.lon_deg = fields.lon_deg; break;
    case CanFrameIndex::Height:
      partial_.height_m = fields.height_m;
      partial_.visibility_m = fields.visibility_m;
      break;
    case CanFrameIndex::Attitude:
      partial_.heading_deg = fields.heading_deg;
      partial_.pitch_deg = fields.pitch_deg;
      partial_.roll_deg = fields.roll_deg;
      break;
    case CanFrameIndex::SimTime:
      partial_.simTime_s = fields.simTime_s;
      partial_.hostFrame = fields.hostFrame;
      break;
  }
  if (mask_ != kFullMask) return Result::Pending;
  inProgress_ = false;
  committed_ = true;
  lastSeq_ = seq_;
  lastCommit_us_ = now_us;
  commit(out);
  return Result::Committed;
}

void CanSetAssembler::commit(HostState& out) {
  uint64_t rejected = 0;
  auto apply = [&rejected](double v, double& into) {
    if (std::isnan(v)) {
      ++rejected;
    } else {
      into = v;
    }
  };
  apply(partial_.lat_deg, state_.lat_deg);
  apply(partial_.lon_deg, state_.lon_deg);
  apply(partial_.height_m, state_.height_m);
  // The attitude fields keep their last good values as sent (in the local level frame at the
  // eye); the conversion to the scene's axes is redone on every commit from those.
  apply(partial_.heading_deg, attitude_.heading_deg);
  apply(partial_.pitch_deg, attitude_.pitch_deg);
  apply(partial_.roll_deg, attitude_.roll_deg);
  apply(partial_.simTime_s, state_.simTime_s);
  apply(partial_.timeOfDay_h, state_.timeOfDay_h);  // -1: not given (the scene's sun)
  // Visibility: 0 = not given (the scene's fog), else metres; a rejected one keeps the last good.
  double visibility = state_.visibility_m;
  apply(partial_.visibility_m, visibility);
  state_.visibility_m = visibility > 0.0 ? std::max(visibility, kMinVisibility_m) : -1.0;
  state_.hostFrame = partial_.hostFrame;
  state_.eyeEnu_m = enu_.fromGeodetic(lod::Geodetic{state_.lat_deg, state_.lon_deg, state_.height_m});
  // Heading from true north at the eye, pitch and roll against its local horizontal -> the
  // scene's ENU axes, the same conversion as CIGI's.
  const lod::Attitude scene = enu_.attitudeFromGeodetic(state_.lat_deg, state_.lon_deg, attitude_);
  state_.heading_deg = scene.heading_deg;
  state_.pitch_deg = scene.pitch_deg;
  state_.roll_deg = scene.roll_deg;
  if (rejected) counters_.outOfRange.fetch_add(rejected, std::memory_order_relaxed);
  counters_.accepted.fetch_add(1, std::memory_order_relaxed);
  out = state_;
}

// ---------------------------------------------------------------------------------------------
// candump logs

namespace {

int hexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

bool isFdLength(size_t n) { return n <= 8 || n == 12 || n == 16 || n == 20 || n == 24 || n == 32 || n == 48 || n == 64; }

std::string quoted(std::string_view s) {
  std::string q = "\"";
  for (char c : s.substr(0, 64)) q += (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) ? '?' : c;
  if (s.size() > 64) q += "...";
  return q + "\"";
}

// Parses hex data bytes (optionally separated by '.') into frame.data; up to `maxLen` bytes.
bool parseData(std::string_view s, size_t maxLen, CanFrame& frame, std::string& reason) {
  size_t n = 0;
  size_t i = 0;
  while (i < s.size()) {
    if (s[i] == '.') {
      ++i;
      continue;
    }
    if (i + 1 >= s.size() || hexValue(s[i]) < 0 || hexValue(s[i + 1]) < 0) {
      reason = "data " + quoted(s) + ": expected pairs of hex digits";
      return false;
    }
    if (n == maxLen) {
      reason = "data " + quoted(s) + ": more than " + std::to_string(maxLen) + " bytes";
      return false;
    }
    frame.data[n++] = static_cast<uint8_t>(hexValue(s[i]) * 16 + hexValue(s[i + 1]));
    i += 2;
  }
  frame.len = static_cast<uint8_t>(n);
  return true;
}

bool parseFrameToken(std::string_view tok, CanFrame& frame, std::string& reason) {
  const size_t hash = tok.find('#');
  if (hash == std::string_view::npos) {
    reason = "frame " + quoted(tok) + ": no '#' between id and data";
    return false;
  }
  const std::string_view idText = tok.substr(0, hash);
  if (idText.size() != 3 && idText.size() != 8) {
    reason = "id " + quoted(idText) + ": expected 3 hex digits (11-bit) or 8 (29-bit)";
    return false;
  }
  uint32_t id = 0;
  for (char c : idText) {
    const int v = hexValue(c);
    if (v < 0) {
      reason = "id " + quoted(idText) + ": not hexadecimal";
      return false;
    }
    id = id * 16 + static_cast<uint32_t>(v);
  }
  frame = CanFrame{};
  if (idText.size() == 3) {
    if (id > 0x7FF) {
      reason = "id " + quoted(idText) + ": an 11-bit id is at most 7FF";
      return false;
    }
    frame.id = id;
  } else {
    if (id > 0x3FFFFFFF) {
      reason = "id " + quoted(idText) + ": above 3FFFFFFF (only the error flag may be set above 29 bits)";
      return false;
    }
    frame.extended = true;
    frame.error = (id & 0x20000000u) != 0;
    frame.id = id & 0x1FFFFFFFu;
  }
  std::string_view rest = tok.substr(hash + 1);
  if (!rest.empty() && rest[0] == '#') {  // CAN FD: flags nibble, then data
    if (frame.error) {
      reason = "frame " + quoted(tok) + ": an error frame cannot be CAN FD";
      return false;
    }
    if (rest.size() < 2 || hexValue(rest[1]) < 0) {
      reason = "frame " + quoted(tok) + ": CAN FD needs a flags hex digit after '##'";
      return false;
    }
    frame.fd = true;
    if (!parseData(rest.substr(2), 64, frame, reason)) return false;
    if (!isFdLength(frame.len)) {
      reason = "frame " + quoted(tok) + ": " + std::to_string(frame.len) + " bytes is not a CAN FD length";
      return false;
    }
    return true;
  }
  if (!rest.empty() && (rest[0] == 'R' || rest[0] == 'r')) {
    frame.remote = true;
    if (rest.size() == 1) return true;
    if (rest.size() == 2 && rest[1] >= '0' && rest[1] <= '8') {
      frame.len = static_cast<uint8_t>(rest[1] - '0');
      return true;
    }
    reason = "frame " + quoted(tok) + ": a remote frame takes only a length digit 0..8 after 'R'";
    return false;
  }
  // Classic data, optionally "_<len8_dlc>" (DLC 9..F) after 8 bytes.
  const size_t underscore = rest.find('_');
  if (underscore != std::string_view::npos) {
    const std::string_view dlc = rest.substr(underscore + 1);
    const int v = dlc.size() == 1 ? hexValue(dlc[0]) : -1;
    if (v < 9) {
      reason = "frame " + quoted(tok) + ": '_' must be followed by one DLC digit 9..F";
      return false;
    }
    rest = rest.substr(0, underscore);
    if (!parseData(rest, 8, frame, reason)) return false;
    if (frame.len != 8) {
      reason = "frame " + quoted(tok) + ": a DLC above 8 needs 8 data bytes";
      return false;
    }
    return true;
  }
  return parseData(rest, 8, frame, reason);
}

void splitSpaces(std::string_view s, std::string_view* tokens, size_t maxTokens, size_t& count) {
  count = 0;
  size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
    if (i >= s.size()) break;
    size_t j = i;
    while (j < s.size() && s[j] != ' ' && s[j] != '\t') ++j;
    if (count < maxTokens) tokens[count] = s.substr(i, j - i);
    ++count;
    i = j;
  }
}

std::string formatTime(int64_t us) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%lld.%06lld", static_cast<long long>(us / 1'000'000),
                static_cast<long long>(us % 1'000'000));
  return buf;
}

}  // namespace

bool parseCandumpLine(std::string_view line, CandumpLine& out, std::string& reason) {
  while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) line.remove_suffix(1);
  std::string_view tokens[4];
  size_t count = 0;
  splitSpaces(line, tokens, 4, count);
  if (count < 3 || count > 4) {
    reason = "expected \"(seconds.micros) interface id#data\", got " + quoted(line);
    return false;
  }
  // Timestamp: "(sec.frac)", frac 1..9 digits.
  const std::string_view ts = tokens[0];
  if (ts.size() < 4 || ts.front() != '(' || ts.back() != ')') {
    reason = "timestamp " + quoted(ts) + ": expected (seconds.micros)";
    return false;
  }
  const std::string_view inner = ts.substr(1, ts.size() - 2);
  const size_t dot = inner.find('.');
  const std::string_view secText = inner.substr(0, dot);
  const std::string_view fracText = dot == std::string_view::npos ? std::string_view{} : inner.substr(dot + 1);
  int64_t sec = 0;
  const auto [p, ec] = std::from_chars(secText.data(), secText.data() + secText.size(), sec);
  bool fracOk = !fracText.empty() && fracText.size() <= 9;
  for (char c : fracText) fracOk = fracOk && c >= '0' && c <= '9';
  if (dot == std::string_view::npos || secText.empty() || secText.size() > 12 || ec != std::errc{} ||
      p != secText.data() + secText.size() || secText[0] == '-' || !fracOk) {
    reason = "timestamp " + quoted(ts) + ": expected (seconds.micros)";
    return false;
  }
  int64_t frac_us = 0;
  for (size_t i = 0; i < 6; ++i) frac_us = frac_us * 10 + (i < fracText.size() ? fracText[i] - '0' : 0);
  out.time_us = sec * 1'000'000 + frac_us;
  if (tokens[1].size() > 15) {
    reason = "interface " + quoted(tokens[1]) + ": longer than 15 characters";
    return false;
  }
  out.interface = tokens[1];
  if (count == 4 && tokens[3] != "R" && tokens[3] != "T") {
    reason = "unexpected " + quoted(tokens[3]) + " after the frame (only a direction R or T may follow)";
    return false;
  }
  return parseFrameToken(tokens[2], out.frame, reason);
}

bool candumpTextToRecording(std::string_view text, const std::string& name, const CanLinkConfig& config,
                            const lod::Geodetic& origin, Recording& out, std::string& error, CandumpStats* stats) {
  if (!validateCanLinkConfig(config, error)) return false;
  LinkCounters counters;
  CanSetAssembler assembler(config, origin, counters);
  CandumpStats local;
  Recording rec;
  int64_t firstCommit_us = 0;
  int64_t previous_us = 0;
  bool havePrevious = false;
  size_t lineNo = 0;
  size_t pos = 0;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++lineNo;
    if (line.find_first_not_of(" \t\r") == std::string_view::npos) continue;
    CandumpLine parsed;
    std::string reason;
    if (!parseCandumpLine(line, parsed, reason)) {
      error = name + ":" + std::to_string(lineNo) + ": " + reason;
      return false;
    }
    if (havePrevious && parsed.time_us < previous_us) {
      error = name + ":" + std::to_string(lineNo) + ": timestamp " + formatTime(parsed.time_us) +
              " is before the previous line's " + formatTime(previous_us);
      return false;
    }
    havePrevious = true;
    previous_us = parsed.time_us;
    ++local.lines;
    if (parsed.frame.error) {
      ++local.errorFrames;
      continue;
    }
    HostState state;
    const auto result = assembler.push(parsed.frame, parsed.time_us, state);
    if (result == CanSetAssembler::Result::Ignored) {
      ++local.otherFrames;
    } else if (result == CanSetAssembler::Result::Committed) {
      if (rec.samples.empty()) firstCommit_us = parsed.time_us;
      rec.samples.push_back(HostSample{static_cast<double>(parsed.time_us - firstCommit_us) * 1e-6, state});
    }
  }
  if (havePrevious) assembler.expire(previous_us + config.stale_ms * 1000 + 1);  // a set left incomplete at the end
  local.counters = snapshot(counters);
  if (stats) *stats = local;
  if (rec.samples.empty()) {
    char ids[64];
    std::snprintf(ids, sizeof ids, "0x%03X..0x%03X", config.baseId, config.baseId + kCanFrameCount - 1);
    error = name + ": no complete frame set with ids " + ids + " (" + std::to_string(local.lines) + " frames, " +
            std::to_string(local.counters.received) + " of them in the map, " +
            std::to_string(local.counters.malformed) + " malformed, " + std::to_string(local.counters.dropped) +
            " incomplete sets)";
    return false;
  }
  out = std::move(rec);
  return true;
}

bool candumpToRecording(const std::string& logFile, const CanLinkConfig& config, const lod::Geodetic& origin,
                        Recording& out, std::string& error, CandumpStats* stats) {
  std::ifstream in(logFile, std::ios::binary);
  if (!in) {
    error = logFile + ": cannot open: " + std::strerror(errno);
    return false;
  }
  std::ostringstream ss;
  ss << in.rdbuf();
  return candumpTextToRecording(ss.str(), logFile, config, origin, out, error, stats);
}

}  // namespace ig::io
