// SocketCAN host link, pure part: the frame map (encoder and decoder of the 8-byte frames), the
// set assembler that applies a set of frames atomically, and the candump log reader. No
// sockets, no clock, no threads: time is passed in, so tests step a fake clock.
//
// The frame map (docs/can.md and config/igd_host.dbc say the same; tests check they agree).
// Classic CAN, 11-bit ids, DLC 8, every multi-byte signal little-endian (Intel, DBC "@1").
// Byte 0 of every frame is the set's sequence counter (uint8, wraps 255 -> 0).
//
//   id          frame              bytes 1..7
//   base_id+0   IG_EYE_LAT         1-4 lat       int32  x 1e-7 deg  [-90, 90]        (1.1 cm)
//                                  5-7 time_of_day uint24 x 0.01 s - 0.01 s [-0.01, 86399.99] UTC, drives the sun;
//                                                                     raw 0 (-0.01 s) = not given
//   base_id+1   IG_EYE_LON         1-4 lon       int32  x 1e-7 deg  [-180, 180]      (1.1 cm at the equator)
//   base_id+2   IG_EYE_HEIGHT      1-4 height    int32  x 1e-3 m    [-1000, 1000000] WGS-84 ellipsoid height
//                                  5-7 visibility uint24 x 1 m      [0, 16777214]    the fog's visibility; 0 = not given,
//                                                                                     above 1e7 = 1e7 (unlimited)
//   base_id+3   IG_EYE_ATTITUDE    1-2 heading   uint16 x 0.01 deg  [0, 360)         clockwise from true north at the eye
//                                  3-4 pitch     int16  x 0.01 deg  [-90, 90]        nose up positive
//                                  5-6 roll      int16  x 0.01 deg  [-180, 180]      right wing down positive
//   base_id+4   IG_SIM_TIME        1-4 sim_time  uint32 x 1e-3 s    [0, 4294967.294] since scenario start
//                                  5-7 host_frame uint24            host frame number modulo 2^24
// Unused bytes (5-7 of the longitude frame, 7 of the attitude frame) are sent as 0 and
// ignored. The raw value INT32_MIN (lat, lon, height), 0xFFFF (heading), INT16_MIN (pitch,
// roll), 0xFFFFFFFF (sim_time) or 0xFFFFFF (visibility, time of day) means "not available" (the
// encoder writes it for NaN or infinite values; for the visibility and the time of day NaN
// only) and is rejected like an out-of-range value.
// time_of_day (added in map version 2, in bytes version 1 sent as 0): raw 0 = not given, the
// scene's sun applies (so a host that sends zeros keeps it); raw r in 1 .. 8,640,000 = (r - 1) /
// 100 seconds after midnight UTC (io::HostState::timeOfDay_h, in hours); larger raw values are
// rejected. The date is not carried (the scene's [sun] date applies), as with Modbus.
// visibility (added in map version 2, in bytes version 1 sent as 0): 0 = not given, the scene's
// [fog] applies (so a host that sends zeros there keeps the scene's fog); 1 .. 10,000,000 m =
// the fog's meteorological visibility (io::HostState::visibility_m); 10,000,001 .. 16,777,214 =
// 10,000,000 (a host's "unlimited", as CIGI's is clamped). The encoder sends <= 0 as 0, +infinity
// and anything above the raw range as 16,777,214.
//
// Set assembly (CanSetAssembler): the five frames with the same counter form a set. The frame
// that completes the set commits it (in any order); the set's fields are then validated one by
// one (a rejected field keeps its last good value, ++outOfRange) and one HostState is produced.
// Its heading/pitch/roll are converted from the local level frame at the eye (heading from true
// north there) to the scene's ENU axes (grid north of the origin), as the CIGI link does
// (lod::EnuFrame::attitudeFromGeodetic): they differ by the meridian convergence away from the
// origin. A rejected attitude field keeps its last good value as sent, converted at the new eye.
//   - a frame with a newer counter while a set is incomplete: the old set is dropped (++dropped)
//     and the new one started;
//   - a frame with an older counter than the incomplete set, or not newer than the last
//     committed set while that commit is at most stale_ms old: ++late, ignored;
//   - a second frame of the same id in one set: ++malformed, ignored;
//   - a set still incomplete stale_ms after its first frame: dropped (++dropped);
//   - a frame of the map with the wrong length, a remote, CAN FD or 29-bit frame: ++malformed.
// "Newer" is modulo 256: counter a is newer than b when (int8_t)(a - b) > 0. After stale_ms
// with no commit any counter starts a new set, so a host that restarts its counter resyncs.
// Link loss (no complete set for [host] link_timeout_s) is the service's business.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>

#include "io/host_state.h"
#include "io/link.h"
#include "io/replay.h"
#include "lod/geo.h"

namespace ig::io {

// [host.can] in the service config. Field names follow the TOML keys (base_id -> baseId).
struct CanLinkConfig {
  std::string interface = "vcan0";  // SocketCAN network interface, 1..15 characters
  uint32_t baseId = 0x100;          // id of the first frame; the map uses baseId..baseId+4, so 0..0x7FB
  int64_t stale_ms = 100;           // an incomplete set older than this is dropped, 1..60000 ms
  bool operator==(const CanLinkConfig&) const = default;
};

// Checks the ranges above; on failure sets `error` (its message() is like "host.can.base_id =
// 2047: must be 0..2043 (0x7FB) so that base_id+4 is an 11-bit id"). The string form sets that
// message.
bool validateCanLinkConfig(const CanLinkConfig& config, LinkConfigError& error);
bool validateCanLinkConfig(const CanLinkConfig& config, std::string& error);

// One CAN frame as read from a socket or a candump log. `id` is without flag bits.
struct CanFrame {
  uint32_t id = 0;
  uint8_t len = 0;         // data bytes: 0..8 classic, 0..64 CAN FD
  bool extended = false;   // 29-bit id
  bool remote = false;     // remote transmission request
  bool fd = false;         // CAN FD frame
  bool error = false;      // error frame (CAN_ERR_FLAG); id holds the error class bits
  std::array<uint8_t, 64> data{};
};

inline constexpr int kCanFrameCount = 5;   // frames in one set: base_id + 0..4
inline constexpr uint8_t kCanFrameLen = 8; // every frame of the map is DLC 8
enum class CanFrameIndex : uint8_t { Lat = 0, Lon = 1, Height = 2, Attitude = 3, SimTime = 4 };

// Scaling and ranges of the map (the DBC file carries the same numbers).
inline constexpr double kCanLatLonScale_deg = 1e-7;
inline constexpr double kCanHeightScale_m = 1e-3;
inline constexpr double kCanAngleScale_deg = 0.01;
inline constexpr double kCanSimTimeScale_s = 1e-3;
inline constexpr double kCanHeightMin_m = -1000.0, kCanHeightMax_m = 1'000'000.0;
inline constexpr uint32_t kCanVisibilityMax_m = 10'000'000;  // larger raw values mean this much
static_assert(kCanVisibilityMax_m == kMaxVisibility_m);
inline constexpr uint32_t kCanVisibilityNa = 0xFFFFFF;       // "not available" (uint24 all ones)
inline constexpr uint32_t kCanTimeOfDayMaxRaw = 8'640'000;    // 23:59:59.99 UTC (raw r: (r - 1) / 100 s)

// The values one set carries. NaN = not available (the encoder sends the "not available" raw
// value; the decoder reports a rejected field as NaN).
struct CanEyeSet {
  double lat_deg = 0.0;
  double lon_deg = 0.0;
  double height_m = 0.0;
  double heading_deg = 0.0;
  double pitch_deg = 0.0;
  double roll_deg = 0.0;
  double simTime_s = 0.0;
  uint32_t hostFrame = 0;  // only the low 24 bits travel
  double visibility_m = 0.0;  // <= 0: not given (raw 0); positive values are sent as at least 1 m; NaN: not available
  double timeOfDay_h = -1.0;  // UTC hours; < 0 or +infinity: not given (raw 0); NaN: not available;
                              //   24 and above wrap to the day (25 h = 1 h)
};

// Encodes a set into its five frames (ids baseId+0..4, counter `seq` in byte 0). NaN or
// infinite values become "not available"; finite values are rounded and saturated to the raw
// type (not to the valid range, so an out-of-range value reaches the receiver and is rejected
// there); heading is wrapped into [0, 360) first.
void encodeCanSet(const CanEyeSet& set, uint8_t seq, uint32_t baseId, std::array<CanFrame, kCanFrameCount>& out);

enum class CanDecodeStatus : uint8_t {
  Ok,
  NotInMap,     // id outside baseId..baseId+4, 29-bit id or an error frame: not ours, ignore
  BadLength,    // a frame of the map whose length is not 8
  Remote,       // a remote frame with a map id
  Fd,           // a CAN FD frame with a map id
};
const char* toString(CanDecodeStatus status);

// One decoded frame: its place in the set, the counter, and the fields it carries written into
// `fields` (the other fields of `fields` are untouched). A field that is "not available" or
// outside its range is written as NaN and counted in `rejectedFields`.
struct CanDecodedFrame {
  CanFrameIndex index = CanFrameIndex::Lat;
  uint8_t seq = 0;
  int rejectedFields = 0;
};
CanDecodeStatus decodeCanFrame(const CanFrame& frame, uint32_t baseId, CanDecodedFrame& out, CanEyeSet& fields);

// Assembles sets into HostStates (rules at the top of this file). Not thread-safe: one per
// receive thread. The counters it updates are the link's.
class CanSetAssembler {
 public:
  CanSetAssembler(const CanLinkConfig& config, const lod::Geodetic& origin, LinkCounters& counters);

  enum class Result : uint8_t { Ignored, Pending, Committed, Rejected };
  // Feeds one frame received at `now_us` (any monotonic microsecond clock). Frames outside the
  // map are Ignored (not counted); map frames count as received. On Committed `out` holds the
  // new HostState. Rejected: malformed, late or duplicate.
  Result push(const CanFrame& frame, int64_t now_us, HostState& out);
  // Drops an incomplete set older than stale_ms (++dropped). Returns true if one was dropped.
  bool expire(int64_t now_us);

  bool setInProgress() const { return inProgress_; }
  // The state of the last committed set (starts at the scene origin, level, time 0).
  const HostState& lastState() const { return state_; }

 private:
  void commit(HostState& out);

  uint32_t baseId_;
  int64_t stale_us_;
  lod::EnuFrame enu_;
  LinkCounters& counters_;
  HostState state_;            // last good value of every field (attitude: in the scene's axes)
  lod::Attitude attitude_;     // last good heading/pitch/roll as sent (local level frame at the eye)
  CanEyeSet partial_;          // fields of the set in progress
  uint8_t seq_ = 0;            // counter of the set in progress
  uint8_t mask_ = 0;           // frames of it received (bit = CanFrameIndex)
  bool inProgress_ = false;
  int64_t start_us_ = 0;       // arrival of its first frame
  bool committed_ = false;     // a set was committed
  uint8_t lastSeq_ = 0;        // its counter
  int64_t lastCommit_us_ = 0;  // and when
};

// candump log files (`candump -l`, or `candump -L` on stdout), one frame a line:
//   (1699999999.123456) vcan0 101#0011223344556677      classic data frame, 3 hex digits = 11-bit id
//   (1699999999.123456) vcan0 12345678#00               8 hex digits = 29-bit id (error frame if 0x20000000 is set)
//   (1699999999.123456) vcan0 101#R                     remote frame (optionally #R<len>)
//   (1699999999.123456) vcan0 101##3001122              CAN FD: flags nibble, then the data
// An optional trailing direction token ("R" or "T") and "." separators between data bytes are accepted.
struct CandumpLine {
  int64_t time_us = 0;          // the timestamp, microseconds
  std::string_view interface;   // points into the line
  CanFrame frame;
};
// Parses one line (without its newline). On failure returns false and sets `reason`.
bool parseCandumpLine(std::string_view line, CandumpLine& out, std::string& reason);

// What a candump conversion saw, for igtool's summary and the tests.
struct CandumpStats {
  uint64_t lines = 0;         // frame lines parsed
  uint64_t otherFrames = 0;   // frames outside the map (other ids, 29-bit), ignored
  uint64_t errorFrames = 0;   // bus error frames (CAN_ERR_FLAG), ignored
  LinkCountersSnapshot counters;  // the assembler's counters (received = frames of the map)
};

// Reads a candump log, feeds the frames of the map (any interface) through a CanSetAssembler
// with the log's timestamps and returns one sample per committed set; t_s is relative to the
// first committed set. Blank lines are skipped; a bad line or a timestamp that goes back stops
// with "file:line: reason"; a log without a complete set is an error too. `out` is untouched
// on error.
bool candumpToRecording(const std::string& logFile, const CanLinkConfig& config, const lod::Geodetic& origin,
                        Recording& out, std::string& error, CandumpStats* stats = nullptr);
// The same on text in memory; `name` is used in messages.
bool candumpTextToRecording(std::string_view text, const std::string& name, const CanLinkConfig& config,
                            const lod::Geodetic& origin, Recording& out, std::string& error,
                            CandumpStats* stats = nullptr);

}  // namespace ig::io
