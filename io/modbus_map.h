// Modbus host link, pure part: the register map (docs/modbus.md says the same, with mbpoll
// examples), the commit rule that applies a written set atomically, the IG status block, and a
// check of a request PDU against the map. No sockets, no clock, no threads, no libmodbus.
//
// Addresses are PDU addresses (0-based). mbpoll numbers references from 1 by default
// (reference = address + 1); `mbpoll -0` uses the addresses below as they are.
//
// Holding registers (the host master writes them: FC6, FC16, FC23, FC22; reads back with FC3).
// Every value is 32 bits in two registers; the word order is configured ([host.modbus]
// word_order): "low_first" = the register at the lower address holds the low 16 bits (mbpoll's
// default), "high_first" = it holds the high 16 bits (mbpoll -B). Each register is big-endian
// on the wire, as Modbus says.
//
//   addr  name           type     unit  accepted range                 default
//    0    east_m         float32  m     [-1e6, 1e6]                    0      eyepoint, scene ENU
//    2    north_m        float32  m     [-1e6, 1e6]                    0        frame (x east, y north,
//    4    up_m           float32  m     [-1e6, 1e6]                    0        z up from the origin)
//    6    heading_deg    float32  deg   [-360, 360]                    0      clockwise from grid north (y)
//    8    pitch_deg      float32  deg   [-90, 90]                      0      nose up positive
//   10    roll_deg       float32  deg   [-180, 180]                    0      right wing down positive
//   12    fovy_deg       float32  deg   (0, 180)                       45     vertical field of view
//   14    near_m         float32  m     (0, 1e6], < far_m              0.1    near clip plane
//   16    far_m          float32  m     (0, 1e7], > near_m             1e5    far clip plane
//   18    sim_time_s     float32  s     [0, 1e9]                       0      since scenario start
//   20    host_frame     float32  -     integer 0 .. 16777216 (2^24)   0      host frame counter
//   22    time_of_day_h  float32  h     [0, 24), or < 0 = not given    -1     UTC, drives the sun
//   24    commit         32 bits  -     any value                      0      see below
//   26    visibility_m   float32  m     any but NaN; <= 0 = not given;  -1     the fog's visibility
//                                       else clamped to [1, 1e7]               (as CIGI's)
//
// visibility_m comes after COMMIT (map version 2 added it; version 1 hosts that write 26
// registers leave it at -1: the scene's [fog] applies). 0 is "not given" too, so that a host
// that zero-fills the register does not fog the picture out. Like every field it applies with
// the next commit: write 14 floats from address 0 in one FC16 request, or write it before COMMIT.
// Position is ENU metres in float32 (not lat/lon doubles) so that every register is one float
// an mbpoll -t 4:float command or a PLC REAL can write; float32 keeps 1 mm up to 8 km from the
// origin and 6 cm at 1000 km. The link fills the geodetic lat/lon/height from the ENU eyepoint.
//
// Commit rule (HostRegisterMap): writes land in the registers but apply nothing until a write
// request covers a COMMIT register (24 or 25) and leaves the 32-bit COMMIT value different
// from the last applied one. Then the whole block is decoded and applied at once, so a
// half-written set is never rendered. Write the set and COMMIT in one FC16 request (mbpoll
// writes all 13 or 14 floats in one), or write the set first and COMMIT last. COMMIT is compared as
// raw bits: write an incrementing integer as float32 or int32, only the change matters; it
// starts at 0, so the first set needs a non-zero commit. A commit write that leaves the value
// unchanged is a repeat: nothing applies, ++late.
// On commit each field is validated on its own: NaN, infinite or outside its range -> the field
// keeps its last applied value, its bit is set in rejected_fields and ++outOfRange; near_m and
// far_m must also satisfy near < far (otherwise both are rejected). The rest applies.
//
// Input registers (read-only status, FC4): unsigned 32-bit values in two registers each, in the
// same word order (mbpoll -t 3:int reads them):
//
//   addr  name             what
//    0    ig_frame         IG frame number (counts up from 0)
//    2    last_host_frame  host frame of the sample the IG rendered in its last frame
//    4    host_lost        1 while no valid host input for longer than [host] link_timeout_s
//    6    applied_commit   the COMMIT value of the last applied set, raw bits as written
//    8    rejected_fields  bit k set: the field at address 2k was rejected in the last applied set
//   10    received         requests received (low 32 bits of the link counters)
//   12    accepted         sets applied
//   14    malformed        bad frames (CRC, framing) and requests answered with an exception
//   16    out_of_range     fields rejected
//   18    late             repeated commits
//   20    dropped          always 0 (a set is never dropped: the newest write wins)
//   22    map_version      2 (1: no visibility_m register)
//
// Anything else (coils, discrete inputs, holding registers >= 28, input registers >= 24) is
// answered with exception 2 (illegal data address); unsupported function codes with exception 1.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <string_view>

#include "io/host_state.h"
#include "io/link.h"

namespace ig::io::modbus {

enum class WordOrder : uint8_t {
  LowFirst,   // "low_first": lower address = low 16 bits (mbpoll default)
  HighFirst,  // "high_first": lower address = high 16 bits (mbpoll -B)
};
// "low_first" or "high_first"; false for anything else.
bool parseWordOrder(std::string_view text, WordOrder& out);
std::string_view toString(WordOrder order);

// Holding register slots, each two registers at address 2 * slot.
enum class Slot : uint8_t {
  East, North, Up, Heading, Pitch, Roll, FovY, Near, Far, SimTime, HostFrame, TimeOfDay, Commit, Visibility,
};
inline constexpr int kSlotCount = 14;
inline constexpr uint16_t kHoldingCount = 2 * kSlotCount;  // 28 holding registers
inline constexpr uint16_t slotAddress(Slot s) { return static_cast<uint16_t>(2 * static_cast<int>(s)); }
inline constexpr uint16_t kCommitAddress = slotAddress(Slot::Commit);  // 24
inline constexpr uint32_t kHostFrameMax = 16777216;                    // 2^24: float32 integers are exact up to here
// Names as in the map above ("east_m", ...), for logs and docs.
std::string_view slotName(Slot s);

// Input register slots, each two registers at address 2 * slot.
enum class StatusSlot : uint8_t {
  IgFrame, LastHostFrame, HostLost, AppliedCommit, RejectedFields,
  Received, Accepted, Malformed, OutOfRange, Late, Dropped, MapVersion,
};
inline constexpr int kStatusSlotCount = 12;
inline constexpr uint16_t kInputCount = 2 * kStatusSlotCount;  // 24 input registers
inline constexpr uint32_t kMapVersion = 2;

using HoldingBlock = std::array<uint16_t, kHoldingCount>;
using InputBlock = std::array<uint16_t, kInputCount>;

// 32-bit value <-> the two registers at `address`, `address + 1`. Requires address + 1 < size.
uint32_t readU32(std::span<const uint16_t> regs, uint16_t address, WordOrder order);
void writeU32(std::span<uint16_t> regs, uint16_t address, uint32_t value, WordOrder order);
float readF32(std::span<const uint16_t> regs, uint16_t address, WordOrder order);
void writeF32(std::span<uint16_t> regs, uint16_t address, float value, WordOrder order);

struct FieldRejects {
  uint32_t mask = 0;   // bit k: slot k rejected
  uint32_t count = 0;  // number of rejected fields
};

// Decodes a holding block into `state`, field by field: a valid field replaces the value in
// `state`, a rejected one leaves it (its last good value). Fills hostFrame, simTime_s,
// eyeEnu_m, heading/pitch/roll, fovY_deg, near_m/far_m, timeOfDay_h (-1 when not given) and
// visibility_m (-1 when not given, else clamped to kMinVisibility_m ... kMaxVisibility_m);
// lat/lon/height and dateYmd are left alone (the link fills the geodetic eyepoint).
FieldRejects decodeHostRegisters(std::span<const uint16_t, kHoldingCount> holding, WordOrder order,
                                 HostState& state);
// The block that decodes back to `state` (float32 rounding aside) with the given COMMIT value:
// the holding registers' contents at start-up, and what a host encoder writes.
void encodeHostRegisters(const HostState& state, uint32_t commit, WordOrder order,
                         std::span<uint16_t, kHoldingCount> holding);

struct IgStatus {
  uint32_t igFrame = 0;
  uint32_t lastHostFrame = 0;
  bool hostLost = false;
  uint32_t appliedCommit = 0;
  uint32_t rejectedFields = 0;
  LinkCountersSnapshot counters;  // written modulo 2^32
  uint32_t mapVersion = kMapVersion;
};
void encodeStatusRegisters(const IgStatus& status, WordOrder order, std::span<uint16_t, kInputCount> input);
IgStatus decodeStatusRegisters(std::span<const uint16_t, kInputCount> input, WordOrder order);

// What a request PDU (function code + data: no unit id, MBAP header or CRC) does to the map,
// checked the way libmodbus 3.1 checks it, so the link knows before replying what will be
// written and which exception the master gets.
enum class Exception : uint8_t { None = 0, IllegalFunction = 1, IllegalDataAddress = 2, IllegalDataValue = 3 };
struct RequestCheck {
  uint8_t function = 0;                  // function code (0 for an empty PDU)
  Exception exception = Exception::None; // what to answer instead of the normal reply
  bool truncated = false;                // PDU shorter than its function code needs (answered
                                         //   as IllegalDataValue)
  bool flush = false;                    // framing cannot be trusted: discard pending input after replying
  bool readsStatus = false;              // reads input registers (refresh the status block first)
  uint16_t writeStart = 0;               // holding registers written: [writeStart, writeStart + writeCount)
  uint16_t writeCount = 0;               //   (0: the request writes nothing)
};
RequestCheck checkRequest(std::span<const uint8_t> pdu);

// The commit rule over the holding block. The caller applies a write to the block (libmodbus
// does it in its mapping), then calls afterWrite with the range written.
struct WriteOutcome {
  bool committed = false;  // the set was applied: state() is the new sample
  bool repeated = false;   // COMMIT written with the value already applied: nothing applied (++late)
  FieldRejects rejects;    // fields rejected by this commit (++outOfRange each)
};

class HostRegisterMap {
 public:
  // `initial` is the state before any commit (the last good value of every field).
  explicit HostRegisterMap(WordOrder order, const HostState& initial = {});
  WriteOutcome afterWrite(std::span<const uint16_t, kHoldingCount> holding, uint16_t start, uint16_t count);
  const HostState& state() const { return state_; }  // the last applied set
  uint32_t appliedCommit() const { return appliedCommit_; }
  uint32_t lastRejectedMask() const { return lastRejectedMask_; }
  WordOrder wordOrder() const { return order_; }

 private:
  WordOrder order_;
  HostState state_;
  uint32_t appliedCommit_ = 0;
  uint32_t lastRejectedMask_ = 0;
};

}  // namespace ig::io::modbus
