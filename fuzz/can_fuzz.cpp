// libFuzzer target for the SocketCAN frame map: the frame decoder and the set assembler (the
// input read as a stream of frames with time steps), and the candump line parser and log
// converter (the same input read as text).
// Properties checked beyond "no crash, no UB, no leak": every committed state has its fields in
// the map's ranges and finite; a frame that decodes re-encodes to the same bytes when its
// fields were in range; a parsed candump line re-formats and re-parses to the same frame.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <string_view>

#include "io/can_map.h"

using namespace ig::io;

namespace {

const ig::lod::Geodetic kOrigin{45.0, 7.0, 300.0};

void checkState(const HostState& s) {
  if (!(s.lat_deg >= -90 && s.lat_deg <= 90 && s.lon_deg >= -180 && s.lon_deg <= 180 &&
        s.height_m >= kCanHeightMin_m && s.height_m <= kCanHeightMax_m && s.heading_deg >= 0 && s.heading_deg < 360 &&
        s.pitch_deg >= -90 && s.pitch_deg <= 90 && s.roll_deg >= -180 && s.roll_deg <= 180 && s.simTime_s >= 0 &&
        std::isfinite(s.simTime_s) && std::isfinite(s.eyeEnu_m.x) && std::isfinite(s.eyeEnu_m.y) &&
        std::isfinite(s.eyeEnu_m.z) && s.hostFrame < (1u << 24) &&
        (s.visibility_m == -1.0 || (s.visibility_m >= kMinVisibility_m && s.visibility_m <= kMaxVisibility_m)) &&
        (s.timeOfDay_h == -1.0 || (s.timeOfDay_h >= 0.0 && s.timeOfDay_h < 24.0))))
    std::abort();
}

// Frames: [id low byte][flags: bits 0-2 id high bits, 3 extended, 4 remote, 5 fd, 6 error,
// 7 big time step][len][dt][data bytes (len, at most 8 here)].
void fuzzFrames(const uint8_t* data, size_t size) {
  static LinkCounters counters;
  static auto assembler = std::make_unique<CanSetAssembler>(CanLinkConfig{}, kOrigin, counters);
  static int64_t now_us = 0;
  size_t i = 0;
  while (i + 4 <= size) {
    CanFrame f;
    const uint8_t flags = data[i + 1];
    f.id = static_cast<uint32_t>(data[i]) | (static_cast<uint32_t>(flags & 7) << 8);
    f.extended = flags & 8;
    f.remote = flags & 16;
    f.fd = flags & 32;
    f.error = flags & 64;
    f.len = data[i + 2] % 65;
    now_us += (flags & 128) ? static_cast<int64_t>(data[i + 3]) * 10'000 : data[i + 3];
    i += 4;
    const size_t n = std::min<size_t>(std::min<size_t>(f.len, 8), size - i);
    for (size_t b = 0; b < n; ++b) f.data[b] = data[i + b];
    i += n;

    CanDecodedFrame d;
    CanEyeSet fields;
    if (decodeCanFrame(f, 0x100, d, fields) == CanDecodeStatus::Ok && d.rejectedFields == 0 &&
        d.index == CanFrameIndex::Attitude) {
      // Re-encode the attitude and compare the bytes that carry it.
      CanEyeSet s;
      s.heading_deg = fields.heading_deg;
      s.pitch_deg = fields.pitch_deg;
      s.roll_deg = fields.roll_deg;
      std::array<CanFrame, kCanFrameCount> again;
      encodeCanSet(s, d.seq, 0x100, again);
      for (size_t b = 0; b < 7; ++b)
        if (again[3].data[b] != f.data[b]) std::abort();
    }
    HostState out;
    if (assembler->push(f, now_us, out) == CanSetAssembler::Result::Committed) checkState(out);
    assembler->expire(now_us);
  }
}

void fuzzText(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  size_t pos = 0;
  while (pos <= text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    CandumpLine line;
    std::string reason;
    if (parseCandumpLine(text.substr(pos, end - pos), line, reason)) {
      if (line.frame.len > (line.frame.fd ? 64 : 8)) std::abort();
      if (!line.frame.extended && line.frame.id > 0x7FF) std::abort();
      if (!line.frame.fd && !line.frame.remote && !line.frame.error) {
        // Re-format as candump does and parse again.
        char buf[64];
        int n = std::snprintf(buf, sizeof buf, "(%lld.%06lld) x ", static_cast<long long>(line.time_us / 1000000),
                              static_cast<long long>(line.time_us % 1000000));
        n += line.frame.extended ? std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), "%08X#", line.frame.id)
                                 : std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), "%03X#", line.frame.id);
        for (int b = 0; b < line.frame.len; ++b)
          n += std::snprintf(buf + n, sizeof buf - static_cast<size_t>(n), "%02X", line.frame.data[static_cast<size_t>(b)]);
        CandumpLine again;
        if (!parseCandumpLine(buf, again, reason) || again.time_us != line.time_us || again.frame.id != line.frame.id ||
            again.frame.len != line.frame.len || again.frame.extended != line.frame.extended)
          std::abort();
        for (size_t b = 0; b < line.frame.len; ++b)
          if (again.frame.data[b] != line.frame.data[b]) std::abort();
      }
    } else if (reason.empty()) {
      std::abort();
    }
    pos = end + 1;
  }
  Recording rec;
  std::string error;
  if (candumpTextToRecording(text, "fuzz.log", CanLinkConfig{}, kOrigin, rec, error)) {
    double last = 0.0;
    for (const HostSample& s : rec.samples) {
      checkState(s.state);
      if (s.t_s < last) std::abort();
      last = s.t_s;
    }
  } else if (error.empty()) {
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  fuzzFrames(data, size);
  fuzzText(data, size);
  return 0;
}
