// Modbus register map codec: hand-made register arrays in both word orders, field-by-field
// rejection (NaN, infinities, ranges, near < far), the commit rule (nothing applies until
// COMMIT changes; a half-written set is never published; a repeated COMMIT is late), the
// status block, and request checks at every truncation.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

#include "io/modbus_map.h"

using namespace ig::io;
using namespace ig::io::modbus;

namespace {

constexpr uint16_t kNaNHigh = 0x7FC0, kNaNLow = 0x0000;  // quiet NaN 0x7FC00000

// Puts a float at `address` by hand: the 32-bit pattern split into words, in the given order.
void putFloat(HoldingBlock& b, uint16_t address, float v, WordOrder order) {
  const uint32_t bits = std::bit_cast<uint32_t>(v);
  const auto high = static_cast<uint16_t>(bits >> 16), low = static_cast<uint16_t>(bits & 0xFFFF);
  b[address] = order == WordOrder::LowFirst ? low : high;
  b[address + 1] = order == WordOrder::LowFirst ? high : low;
}

// A full set written by hand, as a host would.
HoldingBlock makeSet(WordOrder order, uint32_t commit) {
  HoldingBlock b{};
  const float values[] = {1250.5f, -830.25f, 455.0f, 135.0f, -9.5f, 12.0f, 60.0f, 0.5f, 20000.0f,
                          3600.25f, 4242.0f, 13.5f};
  for (int i = 0; i < 12; ++i) putFloat(b, static_cast<uint16_t>(2 * i), values[i], order);
  const auto high = static_cast<uint16_t>(commit >> 16), low = static_cast<uint16_t>(commit & 0xFFFF);
  b[24] = order == WordOrder::LowFirst ? low : high;
  b[25] = order == WordOrder::LowFirst ? high : low;
  putFloat(b, 26, 2500.0f, order);  // visibility_m, after COMMIT
  return b;
}

void expectSet(const HostState& s) {
  EXPECT_DOUBLE_EQ(s.eyeEnu_m.x, 1250.5);
  EXPECT_DOUBLE_EQ(s.eyeEnu_m.y, -830.25);
  EXPECT_DOUBLE_EQ(s.eyeEnu_m.z, 455.0);
  EXPECT_DOUBLE_EQ(s.heading_deg, 135.0);
  EXPECT_DOUBLE_EQ(s.pitch_deg, -9.5);
  EXPECT_DOUBLE_EQ(s.roll_deg, 12.0);
  EXPECT_DOUBLE_EQ(s.fovY_deg, 60.0);
  EXPECT_DOUBLE_EQ(s.near_m, 0.5);
  EXPECT_DOUBLE_EQ(s.far_m, 20000.0);
  EXPECT_DOUBLE_EQ(s.simTime_s, 3600.25);
  EXPECT_EQ(s.hostFrame, 4242u);
  EXPECT_DOUBLE_EQ(s.timeOfDay_h, 13.5);
  EXPECT_DOUBLE_EQ(s.visibility_m, 2500.0);
}

class ModbusMapOrders : public ::testing::TestWithParam<WordOrder> {};

}  // namespace

TEST(ModbusMap, WordOrderByHand) {
  // 1.0f = 0x3F800000; 0x12345678 as uint32.
  std::array<uint16_t, 4> r{};
  writeF32(r, 0, 1.0f, WordOrder::LowFirst);
  writeU32(r, 2, 0x12345678u, WordOrder::LowFirst);
  EXPECT_EQ(r, (std::array<uint16_t, 4>{0x0000, 0x3F80, 0x5678, 0x1234}));
  writeF32(r, 0, 1.0f, WordOrder::HighFirst);
  writeU32(r, 2, 0x12345678u, WordOrder::HighFirst);
  EXPECT_EQ(r, (std::array<uint16_t, 4>{0x3F80, 0x0000, 0x1234, 0x5678}));
  EXPECT_EQ(readF32(r, 0, WordOrder::HighFirst), 1.0f);
  EXPECT_EQ(readU32(r, 2, WordOrder::HighFirst), 0x12345678u);
  EXPECT_EQ(readU32(r, 2, WordOrder::LowFirst), 0x56781234u);

  WordOrder o{};
  EXPECT_TRUE(parseWordOrder("low_first", o));
  EXPECT_EQ(o, WordOrder::LowFirst);
  EXPECT_TRUE(parseWordOrder("high_first", o));
  EXPECT_EQ(o, WordOrder::HighFirst);
  EXPECT_FALSE(parseWordOrder("big", o));
  EXPECT_FALSE(parseWordOrder("", o));
}

TEST(ModbusMap, AddressesAreFixed) {
  // The documented map (docs/modbus.md): integrators hard-code these.
  EXPECT_EQ(slotAddress(Slot::East), 0);
  EXPECT_EQ(slotAddress(Slot::Heading), 6);
  EXPECT_EQ(slotAddress(Slot::FovY), 12);
  EXPECT_EQ(slotAddress(Slot::SimTime), 18);
  EXPECT_EQ(slotAddress(Slot::HostFrame), 20);
  EXPECT_EQ(slotAddress(Slot::TimeOfDay), 22);
  EXPECT_EQ(kCommitAddress, 24);
  EXPECT_EQ(slotAddress(Slot::Visibility), 26);  // after COMMIT: map version 1 hosts write 26 registers
  EXPECT_EQ(kHoldingCount, 28);
  EXPECT_EQ(kMapVersion, 2u);
  EXPECT_EQ(slotName(Slot::Visibility), "visibility_m");
  EXPECT_EQ(kInputCount, 24);
  EXPECT_EQ(slotName(Slot::TimeOfDay), "time_of_day_h");
}

TEST_P(ModbusMapOrders, DecodesHandMadeSet) {
  const WordOrder order = GetParam();
  const HoldingBlock b = makeSet(order, 1);
  HostState s;
  const FieldRejects r = decodeHostRegisters(b, order, s);
  EXPECT_EQ(r.count, 0u);
  EXPECT_EQ(r.mask, 0u);
  expectSet(s);
}

TEST_P(ModbusMapOrders, WrongWordOrderIsRejectedNotMisapplied) {
  // A block written low-first read as high-first (or the reverse) gives garbage floats; the ones
  // that land outside their ranges are rejected rather than rendered.
  const WordOrder order = GetParam();
  const WordOrder other = order == WordOrder::LowFirst ? WordOrder::HighFirst : WordOrder::LowFirst;
  const HoldingBlock b = makeSet(order, 1);
  HostState s;
  const FieldRejects r = decodeHostRegisters(b, other, s);
  EXPECT_GT(r.count, 0u);
}

TEST_P(ModbusMapOrders, EncodeDecodeRoundTrip) {
  const WordOrder order = GetParam();
  HostState in;
  in.eyeEnu_m = {-1234.5, 987.25, 1500.0};
  in.heading_deg = 270.0;
  in.pitch_deg = 5.0;
  in.roll_deg = -30.0;
  in.fovY_deg = 40.0;
  in.near_m = 1.0;
  in.far_m = 50000.0;
  in.simTime_s = 12.5;
  in.hostFrame = 77;
  in.timeOfDay_h = -1.0;
  in.visibility_m = 3200.0;
  HoldingBlock b{};
  encodeHostRegisters(in, 0xCAFEBABE, order, b);
  EXPECT_EQ(readU32(b, kCommitAddress, order), 0xCAFEBABEu);
  HostState out;
  out.timeOfDay_h = 12.0;
  EXPECT_EQ(decodeHostRegisters(b, order, out).count, 0u);
  EXPECT_EQ(out.eyeEnu_m, in.eyeEnu_m);
  EXPECT_EQ(out.heading_deg, in.heading_deg);
  EXPECT_EQ(out.roll_deg, in.roll_deg);
  EXPECT_EQ(out.far_m, in.far_m);
  EXPECT_EQ(out.hostFrame, 77u);
  EXPECT_EQ(out.timeOfDay_h, -1.0);
  EXPECT_EQ(out.visibility_m, 3200.0);
  // The defaults encode to a block that decodes cleanly (the registers at start-up).
  encodeHostRegisters(HostState{}, 0, order, b);
  HostState d;
  EXPECT_EQ(decodeHostRegisters(b, order, d).count, 0u);
  EXPECT_FLOAT_EQ(static_cast<float>(d.near_m), 0.1f);
  EXPECT_EQ(d.timeOfDay_h, -1.0);
  EXPECT_EQ(d.visibility_m, -1.0);  // not given: a host of map version 1 never writes it
  EXPECT_FLOAT_EQ(readF32(b, slotAddress(Slot::Visibility), order), -1.0f);
}

TEST_P(ModbusMapOrders, NaNRejectedFieldByField) {
  const WordOrder order = GetParam();
  HostState good;
  decodeHostRegisters(makeSet(order, 1), order, good);
  for (int slot = 0; slot < kSlotCount; ++slot) {
    if (slot == static_cast<int>(Slot::Commit)) continue;
    HoldingBlock b = makeSet(order, 2);
    // A different good value everywhere, then NaN in one slot.
    putFloat(b, 0, 10.0f, order);
    b[2 * slot] = order == WordOrder::LowFirst ? kNaNLow : kNaNHigh;
    b[2 * slot + 1] = order == WordOrder::LowFirst ? kNaNHigh : kNaNLow;
    HostState s = good;
    const FieldRejects r = decodeHostRegisters(b, order, s);
    EXPECT_EQ(r.count, 1u) << slotName(static_cast<Slot>(slot));
    EXPECT_EQ(r.mask, 1u << slot) << slotName(static_cast<Slot>(slot));
    // The rejected field keeps its last good value; the others apply.
    if (slot == 0) {
      EXPECT_EQ(s.eyeEnu_m.x, good.eyeEnu_m.x);
    } else {
      EXPECT_EQ(s.eyeEnu_m.x, 10.0);
    }
    if (slot == static_cast<int>(Slot::Pitch)) {
      EXPECT_EQ(s.pitch_deg, good.pitch_deg);
    }
    if (slot == static_cast<int>(Slot::HostFrame)) {
      EXPECT_EQ(s.hostFrame, good.hostFrame);
    }
  }
}

TEST(ModbusMap, RangesPerField) {
  const WordOrder o = WordOrder::LowFirst;
  struct Case {
    Slot slot;
    float value;
    bool ok;
  };
  const float inf = std::numeric_limits<float>::infinity();
  const Case cases[] = {
      {Slot::East, 1e6f, true},        {Slot::East, 1.1e6f, false},   {Slot::North, -inf, false},
      {Slot::Up, -1e6f, true},         {Slot::Heading, 360.0f, true}, {Slot::Heading, -360.5f, false},
      {Slot::Pitch, 90.0f, true},      {Slot::Pitch, 90.5f, false},   {Slot::Roll, -180.0f, true},
      {Slot::Roll, 181.0f, false},     {Slot::FovY, 0.0f, false},     {Slot::FovY, 180.0f, false},
      {Slot::FovY, 179.0f, true},      {Slot::Near, 0.0f, false},     {Slot::Near, -1.0f, false},
      {Slot::Far, 1.1e7f, false},      {Slot::SimTime, -0.5f, false}, {Slot::SimTime, 1e9f, true},
      {Slot::SimTime, inf, false},     {Slot::HostFrame, 12.5f, false}, {Slot::HostFrame, -1.0f, false},
      {Slot::HostFrame, 16777216.0f, true}, {Slot::HostFrame, 16777218.0f, false},
      {Slot::TimeOfDay, 23.99f, true}, {Slot::TimeOfDay, 24.0f, false}, {Slot::TimeOfDay, -inf, false},
      {Slot::Visibility, 1e7f, true},  {Slot::Visibility, 1.1e7f, true}, {Slot::Visibility, inf, true},
      {Slot::Visibility, std::numeric_limits<float>::quiet_NaN(), false}, {Slot::Visibility, -inf, true},
      {Slot::Visibility, 0.0f, true},  {Slot::Visibility, -3.0f, true},
  };
  for (const Case& c : cases) {
    HoldingBlock b = makeSet(o, 1);
    putFloat(b, slotAddress(c.slot), c.value, o);
    HostState s;
    const FieldRejects r = decodeHostRegisters(b, o, s);
    EXPECT_EQ(r.count, c.ok ? 0u : 1u) << slotName(c.slot) << " = " << c.value;
    EXPECT_EQ(r.mask, c.ok ? 0u : 1u << static_cast<int>(c.slot)) << slotName(c.slot) << " = " << c.value;
  }
  // A negative time of day means "not given".
  HoldingBlock b = makeSet(o, 1);
  putFloat(b, slotAddress(Slot::TimeOfDay), -5.0f, o);
  HostState s;
  s.timeOfDay_h = 10.0;
  EXPECT_EQ(decodeHostRegisters(b, o, s).count, 0u);
  EXPECT_EQ(s.timeOfDay_h, -1.0);
  // Visibility: <= 0 is "not given" (the scene's fog; a zero-filled register must not fog the
  // picture out), below 1 m is drawn at 1 m, a rejected one keeps the last good value.
  // Writes the visibility register and decodes the set: the rejected fields' count.
  const auto visibility = [&](float v) {
    putFloat(b, slotAddress(Slot::Visibility), v, o);
    return decodeHostRegisters(b, o, s).count;
  };
  s.visibility_m = 800.0;
  visibility(0.0f);
  EXPECT_EQ(s.visibility_m, -1.0);
  visibility(0.25f);
  EXPECT_EQ(s.visibility_m, 1.0);
  visibility(750.5f);
  EXPECT_EQ(s.visibility_m, 750.5);
  EXPECT_EQ(visibility(std::numeric_limits<float>::quiet_NaN()), 1u);
  EXPECT_EQ(s.visibility_m, 750.5);
  visibility(-1.0f);
  EXPECT_EQ(s.visibility_m, -1.0);
  // A host's "unlimited" (above 1e7, +infinity): 1e7, as CIGI's.
  visibility(3e8f);
  EXPECT_EQ(s.visibility_m, 1e7);
  visibility(750.5f);
  EXPECT_EQ(visibility(std::numeric_limits<float>::infinity()), 0u);
  EXPECT_EQ(s.visibility_m, 1e7);
  // The largest host frame float32 holds exactly.
  putFloat(b, slotAddress(Slot::HostFrame), 16777216.0f, o);
  decodeHostRegisters(b, o, s);
  EXPECT_EQ(s.hostFrame, 16777216u);
}

// Both ends of every documented range, and one step past each (as far as float32 allows):
// the boundary values apply, their neighbours outside are rejected.
TEST(ModbusMap, RangeEdgesBothSides) {
  const WordOrder o = WordOrder::HighFirst;
  struct Case {
    Slot slot;
    float value;
    bool ok;
  };
  const Case cases[] = {
      {Slot::East, -1e6f, true},       {Slot::East, -1.0001e6f, false},  {Slot::East, 1.0001e6f, false},
      {Slot::North, 1e6f, true},       {Slot::North, -1e6f, true},       {Slot::North, 1.0001e6f, false},
      {Slot::North, -1.0001e6f, false}, {Slot::Up, 1e6f, true},          {Slot::Up, 1.0001e6f, false},
      {Slot::Heading, -360.0f, true},  {Slot::Heading, 360.01f, false},
      {Slot::Pitch, -90.0f, true},     {Slot::Pitch, -90.01f, false},
      {Slot::Roll, 180.0f, true},      {Slot::Roll, 180.01f, false},     {Slot::Roll, -180.01f, false},
      {Slot::SimTime, 0.0f, true},     {Slot::SimTime, 1.0001e9f, false},
      {Slot::TimeOfDay, 0.0f, true},
  };
  for (const Case& c : cases) {
    HoldingBlock b = makeSet(o, 1);
    putFloat(b, slotAddress(c.slot), c.value, o);
    HostState s;
    const FieldRejects r = decodeHostRegisters(b, o, s);
    EXPECT_EQ(r.mask, c.ok ? 0u : 1u << static_cast<int>(c.slot)) << slotName(c.slot) << " = " << c.value;
  }
  // Midnight is a time of day (0 h), not "not given".
  HoldingBlock b = makeSet(o, 1);
  putFloat(b, slotAddress(Slot::TimeOfDay), 0.0f, o);
  HostState s;
  EXPECT_EQ(decodeHostRegisters(b, o, s).count, 0u);
  EXPECT_EQ(s.timeOfDay_h, 0.0);
}

// The clip planes' own ranges: near (0, 1e6], far (0, 1e7], each at its edges (with the other
// plane in the same set far enough to keep near < far).
TEST(ModbusMap, ClipPlaneRangeEdges) {
  const WordOrder o = WordOrder::LowFirst;
  struct Case {
    float near_m, far_m;
    uint32_t mask;
  };
  const uint32_t nearBit = 1u << static_cast<int>(Slot::Near), farBit = 1u << static_cast<int>(Slot::Far);
  const Case cases[] = {
      {1e6f, 1e7f, 0u},           // both at their upper edges
      {1.0001e6f, 1e7f, nearBit}, // near just past 1e6
      {0.5f, 1.0001e7f, farBit},  // far just past 1e7
      {0.5f, 0.0f, farBit},       // far 0: rejected on its own, near still applies against the last far
      {0.5f, -2.0f, farBit},
  };
  for (const Case& c : cases) {
    HoldingBlock b = makeSet(o, 1);
    putFloat(b, slotAddress(Slot::Near), c.near_m, o);
    putFloat(b, slotAddress(Slot::Far), c.far_m, o);
    HostState s;  // near 0.1, far 1e5
    const FieldRejects r = decodeHostRegisters(b, o, s);
    EXPECT_EQ(r.mask, c.mask) << c.near_m << " .. " << c.far_m;
    if (!(c.mask & nearBit)) {
      EXPECT_EQ(s.near_m, static_cast<double>(c.near_m));
    }
    if (!(c.mask & farBit)) {
      EXPECT_EQ(s.far_m, static_cast<double>(c.far_m));
    }
  }
}

TEST(ModbusMap, ClipPlanesMustStayOrdered) {
  const WordOrder o = WordOrder::HighFirst;
  HostState last;
  last.near_m = 1.0;
  last.far_m = 1000.0;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const uint32_t nearBit = 1u << static_cast<int>(Slot::Near), farBit = 1u << static_cast<int>(Slot::Far);
  HoldingBlock b = makeSet(o, 1);
  HostState s;
  FieldRejects r;
  // A set with these clip planes decoded over the last good values.
  auto decode = [&](float nearV, float farV) {
    putFloat(b, slotAddress(Slot::Near), nearV, o);
    putFloat(b, slotAddress(Slot::Far), farV, o);
    s = last;
    r = decodeHostRegisters(b, o, s);
  };
  // near >= far in the same set: both rejected, both keep their last good values.
  decode(500.0f, 400.0f);
  EXPECT_EQ(r.count, 2u);
  EXPECT_EQ(r.mask, nearBit | farBit);
  EXPECT_EQ(s.near_m, 1.0);
  EXPECT_EQ(s.far_m, 1000.0);
  // far rejected (NaN) and the new near beyond the last good far: near rejected too.
  decode(2000.0f, nan);
  EXPECT_EQ(r.count, 2u);
  // far rejected and near still below the last good far: near applies.
  decode(5.0f, nan);
  EXPECT_EQ(r.count, 1u);
  EXPECT_EQ(s.near_m, 5.0);
  EXPECT_EQ(s.far_m, 1000.0);
  // near == far in the same set is not near < far: both rejected.
  decode(300.0f, 300.0f);
  EXPECT_EQ(r.mask, nearBit | farBit);
  EXPECT_EQ(s.near_m, 1.0);
  EXPECT_EQ(s.far_m, 1000.0);
  // far rejected and the new near equal to the last good far: near rejected too.
  decode(1000.0f, nan);
  EXPECT_EQ(r.count, 2u);
  EXPECT_EQ(s.near_m, 1.0);
  // near rejected (NaN) and the new far below or equal to the last good near: far rejected too.
  for (const float badFar : {0.5f, 1.0f}) {
    decode(nan, badFar);
    EXPECT_EQ(r.count, 2u) << badFar;
    EXPECT_EQ(s.far_m, 1000.0) << badFar;
  }
  // near rejected and the new far above the last good near: far applies.
  decode(nan, 2.0f);
  EXPECT_EQ(r.mask, nearBit);
  EXPECT_EQ(s.near_m, 1.0);
  EXPECT_EQ(s.far_m, 2.0);
}

TEST_P(ModbusMapOrders, CommitAppliesTheWholeSetAtOnce) {
  const WordOrder order = GetParam();
  HostRegisterMap map(order);
  HoldingBlock regs{};
  encodeHostRegisters(HostState{}, 0, order, regs);
  const HoldingBlock set = makeSet(order, 1);

  // The host writes the first half of the set: nothing applies.
  std::copy(set.begin(), set.begin() + 12, regs.begin());
  WriteOutcome w = map.afterWrite(regs, 0, 12);
  EXPECT_FALSE(w.committed);
  EXPECT_EQ(map.state().eyeEnu_m.x, 0.0);
  // The second half, still without COMMIT: nothing applies.
  std::copy(set.begin() + 12, set.begin() + 24, regs.begin() + 12);
  w = map.afterWrite(regs, 12, 12);
  EXPECT_FALSE(w.committed);
  EXPECT_EQ(map.state().hostFrame, 0u);
  // visibility_m, after COMMIT's address, written before it: still nothing applies.
  std::copy(set.begin() + 26, set.begin() + 28, regs.begin() + 26);
  w = map.afterWrite(regs, 26, 2);
  EXPECT_FALSE(w.committed);
  EXPECT_EQ(map.state().visibility_m, -1.0);
  // COMMIT (one register of it, as FC6 would): the whole set applies.
  regs[24] = set[24];
  regs[25] = set[25];
  w = map.afterWrite(regs, order == WordOrder::LowFirst ? 24 : 25, 1);
  EXPECT_TRUE(w.committed);
  EXPECT_EQ(w.rejects.count, 0u);
  expectSet(map.state());
  EXPECT_EQ(map.appliedCommit(), 1u);

  // A new half set and the same COMMIT value again: a repeat, nothing applies (late).
  putFloat(regs, 0, -1.0f, order);
  w = map.afterWrite(regs, 0, 26);
  EXPECT_FALSE(w.committed);
  EXPECT_TRUE(w.repeated);
  EXPECT_EQ(map.state().eyeEnu_m.x, 1250.5);
  // A new COMMIT value applies what the registers hold now.
  writeU32(regs, kCommitAddress, 2, order);
  w = map.afterWrite(regs, 24, 2);
  EXPECT_TRUE(w.committed);
  EXPECT_EQ(map.state().eyeEnu_m.x, -1.0);
  // Any change counts, even backwards (a host restarting its counter).
  writeU32(regs, kCommitAddress, 1, order);
  EXPECT_TRUE(map.afterWrite(regs, 20, 6).committed);
  // 14 floats in one request (a map version 2 host): the visibility after COMMIT applies with it.
  putFloat(regs, slotAddress(Slot::Visibility), 600.0f, order);
  writeU32(regs, kCommitAddress, 3, order);
  EXPECT_TRUE(map.afterWrite(regs, 0, 28).committed);
  EXPECT_EQ(map.state().visibility_m, 600.0);
  // The visibility alone, after the commit: it waits for the next one.
  putFloat(regs, slotAddress(Slot::Visibility), 900.0f, order);
  EXPECT_FALSE(map.afterWrite(regs, 26, 2).committed);
  EXPECT_EQ(map.state().visibility_m, 600.0);
  // A write that ends just before COMMIT never commits, whatever COMMIT holds.
  writeU32(regs, kCommitAddress, 99, order);
  EXPECT_FALSE(map.afterWrite(regs, 0, 24).committed);
  EXPECT_FALSE(map.afterWrite(regs, 23, 1).committed);
  EXPECT_FALSE(map.afterWrite(regs, 0, 0).committed);
}

TEST_P(ModbusMapOrders, EncodesTheLargestHostFrame) {
  // 2^24 is in range (float32 holds it exactly) and is sent as it is; a larger counter is
  // wrapped into the range rather than sent as a value the IG rejects.
  const WordOrder order = GetParam();
  HostState in;
  in.hostFrame = kHostFrameMax;
  HoldingBlock b{};
  encodeHostRegisters(in, 1, order, b);
  HostState out;
  EXPECT_EQ(decodeHostRegisters(b, order, out).count, 0u);
  EXPECT_EQ(out.hostFrame, uint64_t{kHostFrameMax});
  in.hostFrame = uint64_t{kHostFrameMax} + 3;
  encodeHostRegisters(in, 1, order, b);
  EXPECT_EQ(decodeHostRegisters(b, order, out).count, 0u);
  EXPECT_LE(out.hostFrame, uint64_t{kHostFrameMax});
}

TEST_P(ModbusMapOrders, OnlyAWriteCoveringCommitCommitsOrRepeats) {
  // The COMMIT registers hold a value different from the applied one (0): a write that does
  // not cover them is neither a commit nor a repeat, even right next to them.
  const WordOrder order = GetParam();
  HostRegisterMap map(order);
  const HoldingBlock regs = makeSet(order, 7);
  for (const auto& [start, count] : {std::pair{26, 2}, std::pair{27, 1}, std::pair{0, 24}, std::pair{23, 1},
                                     std::pair{25, 0}, std::pair{24, 0}}) {
    const WriteOutcome w = map.afterWrite(regs, static_cast<uint16_t>(start), static_cast<uint16_t>(count));
    EXPECT_FALSE(w.committed) << start << " + " << count;
    EXPECT_FALSE(w.repeated) << start << " + " << count;
  }
  EXPECT_EQ(map.appliedCommit(), 0u);
  // Either COMMIT register alone covers it.
  EXPECT_TRUE(map.afterWrite(regs, 25, 1).committed);
  EXPECT_EQ(map.appliedCommit(), 7u);
}

TEST(ModbusMap, CommitWithBadFieldsAppliesTheRest) {
  const WordOrder o = WordOrder::LowFirst;
  HostRegisterMap map(o);
  HoldingBlock regs = makeSet(o, 1);
  ASSERT_TRUE(map.afterWrite(regs, 0, 26).committed);
  putFloat(regs, slotAddress(Slot::Pitch), std::numeric_limits<float>::quiet_NaN(), o);
  putFloat(regs, slotAddress(Slot::FovY), 200.0f, o);
  putFloat(regs, slotAddress(Slot::Heading), 10.0f, o);
  writeU32(regs, kCommitAddress, 2, o);
  const WriteOutcome w = map.afterWrite(regs, 0, 26);
  EXPECT_TRUE(w.committed);
  EXPECT_EQ(w.rejects.count, 2u);
  EXPECT_EQ(map.lastRejectedMask(), (1u << static_cast<int>(Slot::Pitch)) | (1u << static_cast<int>(Slot::FovY)));
  EXPECT_EQ(map.state().pitch_deg, -9.5);  // last good
  EXPECT_EQ(map.state().fovY_deg, 60.0);   // last good
  EXPECT_EQ(map.state().heading_deg, 10.0);
}

TEST_P(ModbusMapOrders, StatusBlockLayout) {
  const WordOrder order = GetParam();
  IgStatus st;
  st.igFrame = 0x00010002;
  st.lastHostFrame = 4242;
  st.hostLost = true;
  st.appliedCommit = 0x40A00000;  // 5.0f as written by mbpoll -t 4:float
  st.rejectedFields = 0x110;
  st.counters.received = 10;
  st.counters.accepted = 4;
  st.counters.malformed = 3;
  st.counters.outOfRange = 2;
  st.counters.late = 1;
  st.counters.dropped = 0;
  InputBlock in{};
  encodeStatusRegisters(st, order, in);
  const bool lowFirst = order == WordOrder::LowFirst;
  EXPECT_EQ(in[0], lowFirst ? 0x0002 : 0x0001);
  EXPECT_EQ(in[1], lowFirst ? 0x0001 : 0x0002);
  EXPECT_EQ(in[lowFirst ? 2 : 3], 4242);
  EXPECT_EQ(in[lowFirst ? 4 : 5], 1);  // host_lost
  EXPECT_EQ(in[lowFirst ? 10 : 11], 10);  // received
  EXPECT_EQ(in[lowFirst ? 22 : 23], kMapVersion);
  const IgStatus back = decodeStatusRegisters(in, order);
  EXPECT_EQ(back.igFrame, st.igFrame);
  EXPECT_EQ(back.appliedCommit, st.appliedCommit);
  EXPECT_EQ(back.rejectedFields, st.rejectedFields);
  EXPECT_TRUE(back.hostLost);
  EXPECT_EQ(back.counters.malformed, 3u);
  EXPECT_EQ(back.counters.late, 1u);
  EXPECT_EQ(back.mapVersion, kMapVersion);
}

TEST_P(ModbusMapOrders, StatusBlockEveryFieldAtItsAddress) {
  // A distinct value in every field: each lands at its documented address and decodes back.
  const WordOrder order = GetParam();
  IgStatus st;
  st.igFrame = 0x01010101;
  st.lastHostFrame = 0x02020202;
  st.hostLost = true;
  st.appliedCommit = 0x04040404;
  st.rejectedFields = 0x05050505;
  st.counters.received = 0x06060606;
  st.counters.accepted = 0x07070707;
  st.counters.malformed = 0x08080808;
  st.counters.outOfRange = 0x09090909;
  st.counters.late = 0x0A0A0A0A;
  st.counters.dropped = 0x0B0B0B0B;
  st.mapVersion = 0x0C0C0C0C;
  InputBlock in{};
  in.fill(0xEEEE);
  encodeStatusRegisters(st, order, in);
  const uint32_t want[kStatusSlotCount] = {0x01010101, 0x02020202, 1,          0x04040404, 0x05050505, 0x06060606,
                                           0x07070707, 0x08080808, 0x09090909, 0x0A0A0A0A, 0x0B0B0B0B, 0x0C0C0C0C};
  for (int k = 0; k < kStatusSlotCount; ++k)
    EXPECT_EQ(readU32(in, static_cast<uint16_t>(2 * k), order), want[k]) << "input register " << 2 * k;
  const IgStatus back = decodeStatusRegisters(in, order);
  EXPECT_EQ(back.igFrame, st.igFrame);
  EXPECT_EQ(back.lastHostFrame, st.lastHostFrame);
  EXPECT_TRUE(back.hostLost);
  EXPECT_EQ(back.appliedCommit, st.appliedCommit);
  EXPECT_EQ(back.rejectedFields, st.rejectedFields);
  EXPECT_EQ(back.counters.received, st.counters.received);
  EXPECT_EQ(back.counters.accepted, st.counters.accepted);
  EXPECT_EQ(back.counters.malformed, st.counters.malformed);
  EXPECT_EQ(back.counters.outOfRange, st.counters.outOfRange);
  EXPECT_EQ(back.counters.late, st.counters.late);
  EXPECT_EQ(back.counters.dropped, st.counters.dropped);
  EXPECT_EQ(back.mapVersion, st.mapVersion);
  st.hostLost = false;
  encodeStatusRegisters(st, order, in);
  EXPECT_EQ(readU32(in, 4, order), 0u);
  EXPECT_FALSE(decodeStatusRegisters(in, order).hostLost);
}

INSTANTIATE_TEST_SUITE_P(Both, ModbusMapOrders, ::testing::Values(WordOrder::LowFirst, WordOrder::HighFirst),
                         [](const auto& p) { return std::string(toString(p.param)); });

TEST(ModbusRequest, ChecksAgainstTheMap) {
  using V = std::vector<uint8_t>;
  auto check = [](const V& pdu) { return checkRequest(pdu); };
  // FC16: 13 floats + COMMIT from 0.
  V fc16 = {0x10, 0x00, 0x00, 0x00, 26, 52};
  fc16.resize(fc16.size() + 52, 0);
  RequestCheck c = check(fc16);
  EXPECT_EQ(c.exception, Exception::None);
  EXPECT_EQ(c.writeStart, 0);
  EXPECT_EQ(c.writeCount, 26);
  // 14 floats from 0 (map version 2: visibility_m after COMMIT).
  V fc16v2 = {0x10, 0x00, 0x00, 0x00, 28, 56};
  fc16v2.resize(fc16v2.size() + 56, 0);
  c = check(fc16v2);
  EXPECT_EQ(c.exception, Exception::None);
  EXPECT_EQ(c.writeCount, 28);
  // FC16 one register past the map: illegal data address, no write.
  V past = {0x10, 0x00, 0x01, 0x00, 28, 56};
  past.resize(past.size() + 56, 0);
  c = check(past);
  EXPECT_EQ(c.exception, Exception::IllegalDataAddress);
  EXPECT_EQ(c.writeCount, 0);
  EXPECT_FALSE(c.flush);
  // FC16 byte count disagreeing with the count: illegal data value, flush.
  V bad = {0x10, 0x00, 0x00, 0x00, 2, 2, 0, 0};
  c = check(bad);
  EXPECT_EQ(c.exception, Exception::IllegalDataValue);
  EXPECT_TRUE(c.flush);
  // FC6 to the commit's high register and past the end.
  EXPECT_EQ(check({0x06, 0x00, 25, 0x00, 0x01}).writeStart, 25);
  EXPECT_EQ(check({0x06, 0x00, 27, 0x00, 0x01}).writeStart, 27);
  EXPECT_EQ(check({0x06, 0x00, 28, 0x00, 0x01}).exception, Exception::IllegalDataAddress);
  // FC3 / FC4 limits.
  EXPECT_EQ(check({0x03, 0x00, 0x00, 0x00, 28}).exception, Exception::None);
  EXPECT_EQ(check({0x03, 0x00, 0x00, 0x00, 29}).exception, Exception::IllegalDataAddress);
  EXPECT_EQ(check({0x03, 0x00, 0x00, 0x00, 0}).exception, Exception::IllegalDataValue);
  EXPECT_TRUE(check({0x04, 0x00, 0x00, 0x00, 24}).readsStatus);
  EXPECT_EQ(check({0x04, 0x00, 0x16, 0x00, 3}).exception, Exception::IllegalDataAddress);
  EXPECT_EQ(check({0x04, 0xFF, 0xFF, 0x00, 1}).exception, Exception::IllegalDataAddress);
  // No coils or discrete inputs.
  EXPECT_EQ(check({0x01, 0x00, 0x00, 0x00, 1}).exception, Exception::IllegalDataAddress);
  EXPECT_EQ(check({0x02, 0x00, 0x00, 0x00, 1}).exception, Exception::IllegalDataAddress);
  EXPECT_EQ(check({0x05, 0x00, 0x00, 0xFF, 0x00}).exception, Exception::IllegalDataAddress);
  EXPECT_EQ(check({0x0F, 0x00, 0x00, 0x00, 8, 1, 0xFF}).exception, Exception::IllegalDataAddress);
  // FC22 mask write and FC23 write-and-read.
  EXPECT_EQ(check({0x16, 0x00, 24, 0xFF, 0xFF, 0x00, 0x01}).writeStart, 24);
  c = check({0x17, 0x00, 0x00, 0x00, 2, 0x00, 24, 0x00, 2, 4, 0, 0, 0, 7});
  EXPECT_EQ(c.exception, Exception::None);
  EXPECT_EQ(c.writeStart, 24);
  EXPECT_EQ(c.writeCount, 2);
  EXPECT_EQ(check({0x17, 0x00, 0x00, 0x00, 2, 0x00, 27, 0x00, 2, 4, 0, 0, 0, 7}).exception,
            Exception::IllegalDataAddress);
  // Report slave id passes; unknown functions are illegal and flush.
  EXPECT_EQ(check({0x11}).exception, Exception::None);
  c = check({0x07});
  EXPECT_EQ(c.exception, Exception::IllegalFunction);
  EXPECT_TRUE(c.flush);
  EXPECT_EQ(check({0x2B, 0x0E, 0x01, 0x00}).exception, Exception::IllegalFunction);
}

// libmodbus's quantity limits (checked before the address, so a count past the limit is a value
// error that flushes, a count within it but past the map an address error that does not), and
// the address edges of FC22 and FC23.
TEST(ModbusRequest, QuantityLimitsAndAddressEdges) {
  using V = std::vector<uint8_t>;
  auto check = [](const V& pdu) { return checkRequest(pdu); };
  auto fc16 = [](int address, int nb) {
    V p = {0x10, static_cast<uint8_t>(address >> 8), static_cast<uint8_t>(address), static_cast<uint8_t>(nb >> 8),
           static_cast<uint8_t>(nb), static_cast<uint8_t>(2 * nb)};
    p.resize(p.size() + static_cast<size_t>(static_cast<uint8_t>(2 * nb)), 0);
    return p;
  };
  // FC3: 125 registers is the limit (past the map: address error), 126 a value error.
  RequestCheck c = check({0x03, 0x00, 0x00, 0x00, 125});
  EXPECT_EQ(c.exception, Exception::IllegalDataAddress);
  EXPECT_FALSE(c.flush);
  c = check({0x03, 0x00, 0x00, 0x00, 126});
  EXPECT_EQ(c.exception, Exception::IllegalDataValue);
  EXPECT_TRUE(c.flush);
  EXPECT_EQ(check({0x04, 0x00, 0x00, 0x00, 126}).exception, Exception::IllegalDataValue);
  // FC3 reads holding registers: no status refresh.
  c = check({0x03, 0x00, 0x00, 0x00, 28});
  EXPECT_EQ(c.exception, Exception::None);
  EXPECT_FALSE(c.readsStatus);
  EXPECT_EQ(c.writeCount, 0);
  // FC16: 123 registers is the limit, 124 a value error; 0 registers a value error.
  EXPECT_EQ(check(fc16(0, 123)).exception, Exception::IllegalDataAddress);
  c = check(fc16(0, 124));
  EXPECT_EQ(c.exception, Exception::IllegalDataValue);
  EXPECT_TRUE(c.flush);
  c = check(fc16(0, 0));
  EXPECT_EQ(c.exception, Exception::IllegalDataValue);
  EXPECT_TRUE(c.flush);
  EXPECT_EQ(c.writeCount, 0);
  // FC16 ending exactly at the map's end.
  c = check(fc16(26, 2));
  EXPECT_EQ(c.exception, Exception::None);
  EXPECT_EQ(c.writeStart, 26);
  EXPECT_EQ(c.writeCount, 2);
  // FC22 on the last register and just past it.
  EXPECT_EQ(check({0x16, 0x00, 27, 0xFF, 0xFF, 0x00, 0x01}).writeStart, 27);
  c = check({0x16, 0x00, 28, 0xFF, 0xFF, 0x00, 0x01});
  EXPECT_EQ(c.exception, Exception::IllegalDataAddress);
  EXPECT_EQ(c.writeCount, 0);
  // FC23: write ending at the map's end; a read past it or of 0 registers is refused, and then
  // nothing is written.
  c = check({0x17, 0x00, 0x00, 0x00, 28, 0x00, 26, 0x00, 2, 4, 0, 0, 0, 0});
  EXPECT_EQ(c.exception, Exception::None);
  EXPECT_EQ(c.writeStart, 26);
  EXPECT_EQ(c.writeCount, 2);
  c = check({0x17, 0x00, 27, 0x00, 2, 0x00, 24, 0x00, 2, 4, 0, 0, 0, 7});
  EXPECT_EQ(c.exception, Exception::IllegalDataAddress);
  EXPECT_EQ(c.writeCount, 0);
  c = check({0x17, 0x00, 0x00, 0x00, 0, 0x00, 24, 0x00, 2, 4, 0, 0, 0, 7});
  EXPECT_EQ(c.exception, Exception::IllegalDataValue);
  EXPECT_TRUE(c.flush);
  EXPECT_EQ(c.writeCount, 0);
  // FC1: 2000 bits is the limit (then: no coils), 2001 a value error. FC15: a byte count too
  // small for the bits is a value error.
  EXPECT_EQ(check({0x01, 0x00, 0x00, 0x07, 0xD0}).exception, Exception::IllegalDataAddress);
  c = check({0x01, 0x00, 0x00, 0x07, 0xD1});
  EXPECT_EQ(c.exception, Exception::IllegalDataValue);
  EXPECT_TRUE(c.flush);
  c = check({0x0F, 0x00, 0x00, 0x00, 16, 1, 0xFF});
  EXPECT_EQ(c.exception, Exception::IllegalDataValue);
  EXPECT_TRUE(c.flush);
}

TEST(ModbusRequest, EveryTruncationIsRejected) {
  using V = std::vector<uint8_t>;
  std::vector<V> whole = {
      {0x03, 0x00, 0x00, 0x00, 0x02},
      {0x04, 0x00, 0x00, 0x00, 0x02},
      {0x06, 0x00, 0x18, 0x00, 0x01},
      {0x10, 0x00, 0x18, 0x00, 0x02, 0x04, 0x00, 0x01, 0x00, 0x00},
      {0x16, 0x00, 0x18, 0xFF, 0xFF, 0x00, 0x01},
      {0x17, 0x00, 0x00, 0x00, 0x02, 0x00, 0x18, 0x00, 0x02, 0x04, 0x00, 0x01, 0x00, 0x00},
  };
  for (const V& pdu : whole) {
    EXPECT_EQ(checkRequest(pdu).exception, Exception::None) << int(pdu[0]);
    for (size_t n = 0; n < pdu.size(); ++n) {
      const RequestCheck c = checkRequest(std::span<const uint8_t>(pdu.data(), n));
      EXPECT_TRUE(c.truncated) << "function " << int(pdu[0]) << " cut at " << n;
      EXPECT_NE(c.exception, Exception::None);
      EXPECT_EQ(c.writeCount, 0);
    }
  }
}
