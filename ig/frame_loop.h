// Fixed-rate frame pacing with absolute deadlines, per-phase timing and overrun accounting.
//
// Frame slots are t0 + k / rate, rounded to the nanosecond (not t0 + k times a period rounded to
// the nanosecond, which drifts from k / rate: 17 ms a day at 600 Hz). A frame starts at its
// slot. A frame whose work ends after the start of the next slot is an overrun (or, with a work
// budget, whose work exceeds the budget); the slots it ran past are skipped (counted as missed)
// so the loop stays phase-locked to real time instead of drifting. In free-run mode (tests,
// benchmarks, offline replay) nothing sleeps and every slot is used, so the simulation time of
// frame k is still k / rate.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>

#include "ig/clock.h"

namespace ig {

enum class Phase : int { Input, Lod, Submit, GpuFinish, Present, Count };
constexpr int kPhaseCount = static_cast<int>(Phase::Count);
const char* phaseName(Phase p);

struct FrameTiming {
  int64_t frame = 0;          // slot number: 0, 1, 2, ... (gaps after overruns when paced)
  int64_t start_ns = 0;       // actual start, relative to the loop start
  int64_t lateness_ns = 0;    // start - slot time (how late the wake-up was)
  double interval_ms = 0.0;   // since the previous frame's start
  std::array<double, kPhaseCount> phase_ms{};
  double work_ms = 0.0;       // start to end of the last phase
  // The frame thread's own time after the previous frame closed (stats, status report, reload
  // hand-off) until it began waiting for this slot. Lateness beyond it is the OS waking us late.
  double between_ms = 0.0;
  bool overrun = false;       // work exceeded the budget (default: ran past the next slot)
  int64_t missedSlots = 0;    // slots skipped after this frame
};

class FramePacer {
 public:
  // budget_ms > 0: a frame whose work exceeds it is an overrun; 0: the frame period.
  FramePacer(Clock& clock, double rate_hz, bool freeRun, double budget_ms = 0.0);

  // Fixes the loop start (slot 0) at `t0_ns` instead of the first beginFrame's time, so other
  // clocks of the frame loop (host sample stamps) share its time base. Before the first frame.
  void startAt(int64_t t0_ns) {
    started_ = true;
    t0_ns_ = t0_ns;
    prevStart_ns_ = t0_ns;
  }
  // What else a frame waits for before it starts: `wait(slotTime_ns)` is called in beginFrame
  // with the slot's time on the clock, before a paced loop's sleep to it. Host pacing (CIGI
  // synchronous mode) waits there for the host's next message; a paced loop with a long period
  // sleeps towards the slot in pieces there (watchdog pings, a stop request). Its time is neither
  // the frame's work (nor an overrun) nor the frame thread's own time between frames
  // (between_ms). Returning false starts no frame: beginFrame returns -1. Set before the first
  // frame.
  void setWait(std::function<bool(int64_t slotTime_ns)> wait) { wait_ = std::move(wait); }
  // Waits (above), sleeps until the next slot and starts the frame; returns its slot number, or
  // -1 when the wait said not to start it.
  int64_t beginFrame();
  // Ends the phase that began at the previous mark (frame start or previous endPhase).
  void endPhase(Phase phase);
  // Closes the frame: work time, overrun, missed slots. Valid until the next beginFrame.
  const FrameTiming& endFrame();

  // Reload: a new work budget (0 = the period) from the next frame on.
  void setBudget_ms(double budget_ms) { budget_ns_ = static_cast<int64_t>(budget_ms * 1e6 + 0.5); }
  double budget_ms() const { return static_cast<double>(budget_ns_ > 0 ? budget_ns_ : period_ns_) * 1e-6; }
  double period_s() const { return static_cast<double>(period_ns_) * 1e-9; }
  int64_t period_ns() const { return period_ns_; }
  // Scheduled time of a slot since the loop start: the replay/simulation clock of a frame.
  // Exact (slot / rate), not rounded to the nanosecond period.
  double slotTime_s(int64_t slot) const { return static_cast<double>(slot) / rate_hz_; }
  // The same in nanoseconds on the clock since the loop start (the time the loop sleeps until):
  // slot * 1e9 / rate rounded, without accumulating the rounding of the period.
  int64_t slotTime_ns(int64_t slot) const {
    return static_cast<int64_t>(std::llround(static_cast<long double>(slot) * 1e9L / static_cast<long double>(rate_hz_)));
  }
  int64_t frames() const { return frames_; }
  int64_t overruns() const { return overruns_; }
  int64_t missedSlots() const { return missed_; }

 private:
  Clock& clock_;
  double rate_hz_;
  int64_t period_ns_;
  int64_t budget_ns_;         // 0 = the period
  bool freeRun_;
  bool started_ = false;
  int64_t t0_ns_ = 0;
  int64_t nextSlot_ = 0;
  int64_t frameStart_ns_ = 0, prevStart_ns_ = 0, mark_ns_ = 0;
  int64_t prevEnd_ns_ = -1;   // the previous endFrame's time; -1 before the first frame
  FrameTiming timing_;
  std::function<bool(int64_t)> wait_;  // setWait
  int64_t frames_ = 0, overruns_ = 0, missed_ = 0;
};

}  // namespace ig
