// libFuzzer target for the Modbus register map (io/modbus_map.h): arbitrary request PDUs go
// through checkRequest, are applied to a holding block the way libmodbus applies them, and the
// commit rule decodes the block. Invariants: a request without an exception writes inside the
// map; every applied HostState field is finite and inside its documented range; the status
// block round-trips.
//
// Input: byte 0 bit 0 = word order; bytes 1..56 = the initial holding block (28 registers,
// big-endian); the rest is a
// sequence of PDUs, each preceded by its length byte.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>

#include "io/modbus_map.h"

using namespace ig::io;
using namespace ig::io::modbus;

namespace {

void check(bool ok) {
  if (!ok) std::abort();
}

void checkState(const HostState& s) {
  check(std::isfinite(s.eyeEnu_m.x) && std::fabs(s.eyeEnu_m.x) <= 1e6);
  check(std::isfinite(s.eyeEnu_m.y) && std::fabs(s.eyeEnu_m.y) <= 1e6);
  check(std::isfinite(s.eyeEnu_m.z) && std::fabs(s.eyeEnu_m.z) <= 1e6);
  check(s.heading_deg >= -360.0 && s.heading_deg <= 360.0);
  check(s.pitch_deg >= -90.0 && s.pitch_deg <= 90.0);
  check(s.roll_deg >= -180.0 && s.roll_deg <= 180.0);
  check(s.fovY_deg > 0.0 && s.fovY_deg < 180.0);
  check(s.near_m > 0.0 && s.near_m < s.far_m && s.far_m <= 1e7);
  check(s.simTime_s >= 0.0 && s.simTime_s <= 1e9);
  check(s.hostFrame <= kHostFrameMax);
  check(s.timeOfDay_h == -1.0 || (s.timeOfDay_h >= 0.0 && s.timeOfDay_h < 24.0));
  check(s.visibility_m == -1.0 || (s.visibility_m >= kMinVisibility_m && s.visibility_m <= kMaxVisibility_m));
}

uint16_t be16(std::span<const uint8_t> p, size_t at) { return static_cast<uint16_t>((p[at] << 8) | p[at + 1]); }

// What libmodbus's modbus_reply does to the holding registers for an accepted write.
void applyWrite(std::span<const uint8_t> pdu, const RequestCheck& c, HoldingBlock& regs) {
  switch (c.function) {
    case 0x06: regs[c.writeStart] = be16(pdu, 3); break;
    case 0x10:
      for (uint16_t i = 0; i < c.writeCount; ++i) regs[c.writeStart + i] = be16(pdu, 6 + 2u * i);
      break;
    case 0x16: {
      const uint16_t andMask = be16(pdu, 3), orMask = be16(pdu, 5);
      regs[c.writeStart] = static_cast<uint16_t>((regs[c.writeStart] & andMask) | (orMask & ~andMask));
      break;
    }
    case 0x17:
      for (uint16_t i = 0; i < c.writeCount; ++i) regs[c.writeStart + i] = be16(pdu, 10 + 2u * i);
      break;
    default: check(false);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1 + 2 * kHoldingCount) return 0;
  const WordOrder order = (data[0] & 1) != 0 ? WordOrder::HighFirst : WordOrder::LowFirst;
  HoldingBlock regs{};
  for (size_t i = 0; i < kHoldingCount; ++i) {
    regs[i] = static_cast<uint16_t>((data[1 + 2 * i] << 8) | data[2 + 2 * i]);
  }
  // The block decoded as it stands: whatever is rejected, the defaults stay valid.
  HostState direct;
  const FieldRejects r = decodeHostRegisters(regs, order, direct);
  check(r.count <= kSlotCount && r.count == static_cast<uint32_t>(__builtin_popcount(r.mask)));
  checkState(direct);

  HostRegisterMap map(order);
  std::span<const uint8_t> rest(data + 1 + 2 * kHoldingCount, size - 1 - 2 * kHoldingCount);
  while (!rest.empty()) {
    const size_t n = rest[0] < rest.size() - 1 ? rest[0] : rest.size() - 1;
    const std::span<const uint8_t> pdu = rest.subspan(1, n);
    rest = rest.subspan(1 + n);
    const RequestCheck c = checkRequest(pdu);
    if (c.exception != Exception::None) {
      check(c.writeCount == 0 && !c.readsStatus);
      continue;
    }
    check(!c.truncated);
    if (c.writeCount == 0) continue;
    check(c.writeStart + c.writeCount <= kHoldingCount);
    applyWrite(pdu, c, regs);
    const uint32_t before = map.appliedCommit();
    const WriteOutcome w = map.afterWrite(regs, c.writeStart, c.writeCount);
    check(!(w.committed && w.repeated));
    check(w.committed == (map.appliedCommit() != before));
    checkState(map.state());
  }

  IgStatus st;
  st.igFrame = regs[0];
  st.appliedCommit = map.appliedCommit();
  st.rejectedFields = map.lastRejectedMask();
  st.counters.received = size;
  InputBlock in{};
  encodeStatusRegisters(st, order, in);
  const IgStatus back = decodeStatusRegisters(in, order);
  check(back.igFrame == st.igFrame && back.appliedCommit == st.appliedCommit &&
        back.counters.received == static_cast<uint32_t>(size));
  return 0;
}
