#include "io/modbus_map.h"

#include <algorithm>
#include <bit>
#include <cmath>

namespace ig::io::modbus {
namespace {

constexpr std::string_view kSlotNames[kSlotCount] = {
    "east_m",   "north_m", "up_m",  "heading_deg", "pitch_deg",  "roll_deg",      "fovy_deg",
    "near_m",   "far_m",   "sim_time_s", "host_frame", "time_of_day_h", "commit", "visibility_m"};

constexpr double kMaxEnu_m = 1e6;
constexpr double kMaxNear_m = 1e6;
constexpr double kMaxFar_m = 1e7;
constexpr double kMaxSimTime_s = 1e9;

// libmodbus 3.1 limits (modbus.h), repeated so this file does not need libmodbus.
constexpr int kMaxReadBits = 2000;
constexpr int kMaxWriteBits = 1968;
constexpr int kMaxReadRegisters = 125;
constexpr int kMaxWriteRegisters = 123;
constexpr int kMaxWrWriteRegisters = 121;
constexpr int kMaxWrReadRegisters = 125;

// Function codes.
constexpr uint8_t kReadCoils = 0x01, kReadDiscreteInputs = 0x02, kReadHolding = 0x03, kReadInput = 0x04,
                  kWriteCoil = 0x05, kWriteRegister = 0x06, kWriteCoils = 0x0F, kWriteRegisters = 0x10,
                  kReportSlaveId = 0x11, kMaskWriteRegister = 0x16, kWriteAndReadRegisters = 0x17;

bool inRange(double v, double lo, double hi) { return std::isfinite(v) && v >= lo && v <= hi; }

uint16_t be16(std::span<const uint8_t> pdu, size_t at) {
  return static_cast<uint16_t>((pdu[at] << 8) | pdu[at + 1]);
}

}  // namespace

bool parseWordOrder(std::string_view text, WordOrder& out) {
  if (text == "low_first") {
    out = WordOrder::LowFirst;
    return true;
  }
  if (text == "high_first") {
    out = WordOrder::HighFirst;
    return true;
  }
  return false;
}

std::string_view toString(WordOrder order) { return order == WordOrder::LowFirst ? "low_first" : "high_first"; }

std::string_view slotName(Slot s) { return kSlotNames[static_cast<int>(s)]; }

uint32_t readU32(std::span<const uint16_t> regs, uint16_t address, WordOrder order) {
  const uint32_t first = regs[address], second = regs[address + 1u];
  return order == WordOrder::LowFirst ? (second << 16) | first : (first << 16) | second;
}

void writeU32(std::span<uint16_t> regs, uint16_t address, uint32_t value, WordOrder order) {
  const auto low = static_cast<uint16_t>(value & 0xFFFFu), high = static_cast<uint16_t>(value >> 16);
  regs[address] = order == WordOrder::LowFirst ? low : high;
  regs[address + 1u] = order == WordOrder::LowFirst ? high : low;
}

float readF32(std::span<const uint16_t> regs, uint16_t address, WordOrder order) {
  return std::bit_cast<float>(readU32(regs, address, order));
}

void writeF32(std::span<uint16_t> regs, uint16_t address, float value, WordOrder order) {
  writeU32(regs, address, std::bit_cast<uint32_t>(value), order);
}

FieldRejects decodeHostRegisters(std::span<const uint16_t, kHoldingCount> holding, WordOrder order,
                                 HostState& state) {
  FieldRejects r;
  auto value = [&](Slot s) { return static_cast<double>(readF32(holding, slotAddress(s), order)); };
  auto reject = [&](Slot s) {
    r.mask |= 1u << static_cast<int>(s);
    ++r.count;
  };
  // Applies slot s to `field` when lo <= v <= hi (finite).
  auto apply = [&](Slot s, double& field, double lo, double hi) {
    const double v = value(s);
    if (inRange(v, lo, hi)) {
      field = v;
    } else {
      reject(s);
    }
  };
  apply(Slot::East, state.eyeEnu_m.x, -kMaxEnu_m, kMaxEnu_m);
  apply(Slot::North, state.eyeEnu_m.y, -kMaxEnu_m, kMaxEnu_m);
  apply(Slot::Up, state.eyeEnu_m.z, -kMaxEnu_m, kMaxEnu_m);
  apply(Slot::Heading, state.heading_deg, -360.0, 360.0);
  apply(Slot::Pitch, state.pitch_deg, -90.0, 90.0);
  apply(Slot::Roll, state.roll_deg, -180.0, 180.0);
  if (const double fov = value(Slot::FovY); std::isfinite(fov) && fov > 0.0 && fov < 180.0) {
    state.fovY_deg = fov;
  } else {
    reject(Slot::FovY);
  }
  // Clip planes: each in its range, then near < far with whatever values stand.
  double nearCandidate = state.near_m, farCandidate = state.far_m;
  bool nearOk = false, farOk = false;
  if (const double v = value(Slot::Near); std::isfinite(v) && v > 0.0 && v <= kMaxNear_m) {
    nearCandidate = v;
    nearOk = true;
  }
  if (const double v = value(Slot::Far); std::isfinite(v) && v > 0.0 && v <= kMaxFar_m) {
    farCandidate = v;
    farOk = true;
  }
  if (nearOk && farOk && !(nearCandidate < farCandidate)) nearOk = farOk = false;
  if (nearOk && !farOk && !(nearCandidate < state.far_m)) nearOk = false;
  if (farOk && !nearOk && !(state.near_m < farCandidate)) farOk = false;
  if (nearOk) state.near_m = nearCandidate; else reject(Slot::Near);
  if (farOk) state.far_m = farCandidate; else reject(Slot::Far);

  apply(Slot::SimTime, state.simTime_s, 0.0, kMaxSimTime_s);
  if (const double f = value(Slot::HostFrame);
      inRange(f, 0.0, static_cast<double>(kHostFrameMax)) && f == std::floor(f)) {
    state.hostFrame = static_cast<uint64_t>(f);
  } else {
    reject(Slot::HostFrame);
  }
  if (const double tod = value(Slot::TimeOfDay); std::isfinite(tod) && tod < 24.0) {
    state.timeOfDay_h = tod < 0.0 ? -1.0 : tod;
  } else {
    reject(Slot::TimeOfDay);
  }
  // Visibility: 0 or negative = not given; above 1e7 (a host's "unlimited", +infinity too) =
  // 1e7, as CIGI's; NaN is rejected.
  if (const double vis = value(Slot::Visibility); !std::isnan(vis)) {
    state.visibility_m = vis <= 0.0 ? -1.0 : std::clamp(vis, kMinVisibility_m, kMaxVisibility_m);
  } else {
    reject(Slot::Visibility);
  }
  return r;
}

void encodeHostRegisters(const HostState& state, uint32_t commit, WordOrder order,
                         std::span<uint16_t, kHoldingCount> holding) {
  auto put = [&](Slot s, double v) { writeF32(holding, slotAddress(s), static_cast<float>(v), order); };
  put(Slot::East, state.eyeEnu_m.x);
  put(Slot::North, state.eyeEnu_m.y);
  put(Slot::Up, state.eyeEnu_m.z);
  put(Slot::Heading, state.heading_deg);
  put(Slot::Pitch, state.pitch_deg);
  put(Slot::Roll, state.roll_deg);
  put(Slot::FovY, state.fovY_deg);
  put(Slot::Near, state.near_m);
  put(Slot::Far, state.far_m);
  put(Slot::SimTime, state.simTime_s);
  put(Slot::HostFrame, static_cast<double>(state.hostFrame % (uint64_t{kHostFrameMax} + 1)));
  put(Slot::TimeOfDay, state.timeOfDay_h < 0.0 ? -1.0 : state.timeOfDay_h);
  writeU32(holding, kCommitAddress, commit, order);
  put(Slot::Visibility, state.visibility_m > 0.0 ? state.visibility_m : -1.0);
}

void encodeStatusRegisters(const IgStatus& status, WordOrder order, std::span<uint16_t, kInputCount> input) {
  auto put = [&](StatusSlot s, uint64_t v) {
    writeU32(input, static_cast<uint16_t>(2 * static_cast<int>(s)), static_cast<uint32_t>(v), order);
  };
  put(StatusSlot::IgFrame, status.igFrame);
  put(StatusSlot::LastHostFrame, status.lastHostFrame);
  put(StatusSlot::HostLost, status.hostLost ? 1 : 0);
  put(StatusSlot::AppliedCommit, status.appliedCommit);
  put(StatusSlot::RejectedFields, status.rejectedFields);
  put(StatusSlot::Received, status.counters.received);
  put(StatusSlot::Accepted, status.counters.accepted);
  put(StatusSlot::Malformed, status.counters.malformed);
  put(StatusSlot::OutOfRange, status.counters.outOfRange);
  put(StatusSlot::Late, status.counters.late);
  put(StatusSlot::Dropped, status.counters.dropped);
  put(StatusSlot::MapVersion, status.mapVersion);
}

IgStatus decodeStatusRegisters(std::span<const uint16_t, kInputCount> input, WordOrder order) {
  auto get = [&](StatusSlot s) { return readU32(input, static_cast<uint16_t>(2 * static_cast<int>(s)), order); };
  IgStatus st;
  st.igFrame = get(StatusSlot::IgFrame);
  st.lastHostFrame = get(StatusSlot::LastHostFrame);
  st.hostLost = get(StatusSlot::HostLost) != 0;
  st.appliedCommit = get(StatusSlot::AppliedCommit);
  st.rejectedFields = get(StatusSlot::RejectedFields);
  st.counters.received = get(StatusSlot::Received);
  st.counters.accepted = get(StatusSlot::Accepted);
  st.counters.malformed = get(StatusSlot::Malformed);
  st.counters.outOfRange = get(StatusSlot::OutOfRange);
  st.counters.late = get(StatusSlot::Late);
  st.counters.dropped = get(StatusSlot::Dropped);
  st.mapVersion = get(StatusSlot::MapVersion);
  return st;
}

RequestCheck checkRequest(std::span<const uint8_t> pdu) {
  RequestCheck c;
  auto fail = [&](Exception e, bool flush) {
    c.exception = e;
    c.flush = flush;
    return c;
  };
  auto truncated = [&] {
    c.truncated = true;
    return fail(Exception::IllegalDataValue, true);
  };
  if (pdu.empty()) return truncated();
  c.function = pdu[0];
  switch (c.function) {
    case kReadCoils:
    case kReadDiscreteInputs: {
      if (pdu.size() < 5) return truncated();
      const int nb = be16(pdu, 3);
      if (nb < 1 || nb > kMaxReadBits) return fail(Exception::IllegalDataValue, true);
      return fail(Exception::IllegalDataAddress, false);  // no coils or discrete inputs in the map
    }
    case kReadHolding:
    case kReadInput: {
      if (pdu.size() < 5) return truncated();
      const int address = be16(pdu, 1), nb = be16(pdu, 3);
      const int size = c.function == kReadInput ? kInputCount : kHoldingCount;
      if (nb < 1 || nb > kMaxReadRegisters) return fail(Exception::IllegalDataValue, true);
      if (address + nb > size) return fail(Exception::IllegalDataAddress, false);
      c.readsStatus = c.function == kReadInput;
      return c;
    }
    case kWriteCoil:
      if (pdu.size() < 5) return truncated();
      return fail(Exception::IllegalDataAddress, false);
    case kWriteRegister: {
      if (pdu.size() < 5) return truncated();
      const uint16_t address = be16(pdu, 1);
      if (address >= kHoldingCount) return fail(Exception::IllegalDataAddress, false);
      c.writeStart = address;
      c.writeCount = 1;
      return c;
    }
    case kWriteCoils: {
      if (pdu.size() < 6 || pdu.size() < 6u + pdu[5]) return truncated();
      const int nb = be16(pdu, 3), bytes = pdu[5];
      if (nb < 1 || nb > kMaxWriteBits || bytes * 8 < nb) return fail(Exception::IllegalDataValue, true);
      return fail(Exception::IllegalDataAddress, false);
    }
    case kWriteRegisters: {
      if (pdu.size() < 6 || pdu.size() < 6u + pdu[5]) return truncated();
      const int address = be16(pdu, 1), nb = be16(pdu, 3), bytes = pdu[5];
      if (nb < 1 || nb > kMaxWriteRegisters || bytes != 2 * nb) return fail(Exception::IllegalDataValue, true);
      if (address + nb > kHoldingCount) return fail(Exception::IllegalDataAddress, false);
      c.writeStart = static_cast<uint16_t>(address);
      c.writeCount = static_cast<uint16_t>(nb);
      return c;
    }
    case kReportSlaveId:
      return c;
    case kMaskWriteRegister: {
      if (pdu.size() < 7) return truncated();
      const uint16_t address = be16(pdu, 1);
      if (address >= kHoldingCount) return fail(Exception::IllegalDataAddress, false);
      c.writeStart = address;
      c.writeCount = 1;
      return c;
    }
    case kWriteAndReadRegisters: {
      if (pdu.size() < 10 || pdu.size() < 10u + pdu[9]) return truncated();
      const int readAddress = be16(pdu, 1), nbRead = be16(pdu, 3);
      const int writeAddress = be16(pdu, 5), nbWrite = be16(pdu, 7), bytes = pdu[9];
      if (nbWrite < 1 || nbWrite > kMaxWrWriteRegisters || nbRead < 1 || nbRead > kMaxWrReadRegisters ||
          bytes != 2 * nbWrite) {
        return fail(Exception::IllegalDataValue, true);
      }
      if (readAddress + nbRead > kHoldingCount || writeAddress + nbWrite > kHoldingCount) {
        return fail(Exception::IllegalDataAddress, false);
      }
      c.writeStart = static_cast<uint16_t>(writeAddress);
      c.writeCount = static_cast<uint16_t>(nbWrite);
      return c;
    }
    default:
      // Unknown to the map (and to libmodbus, whose framing then guesses the length): flush.
      return fail(Exception::IllegalFunction, true);
  }
}

HostRegisterMap::HostRegisterMap(WordOrder order, const HostState& initial) : order_(order), state_(initial) {}

WriteOutcome HostRegisterMap::afterWrite(std::span<const uint16_t, kHoldingCount> holding, uint16_t start,
                                         uint16_t count) {
  WriteOutcome out;
  const int end = start + count;  // one past the last register written
  const bool coversCommit = count > 0 && start < kCommitAddress + 2 && end > kCommitAddress;
  if (!coversCommit) return out;
  const uint32_t commit = readU32(holding, kCommitAddress, order_);
  if (commit == appliedCommit_) {
    out.repeated = true;
    return out;
  }
  out.rejects = decodeHostRegisters(holding, order_, state_);
  out.committed = true;
  appliedCommit_ = commit;
  lastRejectedMask_ = out.rejects.mask;
  return out;
}

}  // namespace ig::io::modbus
