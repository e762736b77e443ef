// Time is passed in, never read inside logic: the frame loop takes a Clock, production uses
// the monotonic clock, tests use FakeClock and step it.
#pragma once

#include <atomic>
#include <cstdint>

namespace ig {

class Clock {
 public:
  virtual ~Clock() = default;
  virtual int64_t now_ns() const = 0;
  // Sleeps until the absolute time `deadline_ns` (returns at once if it has passed).
  virtual void sleepUntil_ns(int64_t deadline_ns) = 0;
};

// CLOCK_MONOTONIC; sleeps with clock_nanosleep(TIMER_ABSTIME), so deadlines do not drift.
class MonotonicClock final : public Clock {
 public:
  int64_t now_ns() const override;
  void sleepUntil_ns(int64_t deadline_ns) override;
};

// CPU time of the calling thread in ms (CLOCK_THREAD_CPUTIME_ID): what the work itself cost,
// without the time other processes on a shared machine took the core away. For benchmarks.
double threadCpuMs();

// A deadline on a Clock for lod/'s stop callbacks (lod/ reads no clock): past(this) is true once
// `clock` reads end_ns or later. Roam (ig/roam_deadline.h) and the cells layer use it.
struct ClockDeadline {
  const Clock* clock = nullptr;
  int64_t end_ns = 0;
  static bool past(void* self) {
    const auto* d = static_cast<const ClockDeadline*>(self);
    return d->clock->now_ns() >= d->end_ns;
  }
};

// Test clock: time moves only when told to. Sleeping jumps to the deadline. Safe to read from
// other threads (a host link stamping samples) while the test advances it.
class FakeClock final : public Clock {
 public:
  explicit FakeClock(int64_t start_ns = 1'000'000'000) : now_(start_ns) {}
  int64_t now_ns() const override { return now_.load(); }
  void sleepUntil_ns(int64_t deadline_ns) override {
    ++sleeps_;
    if (deadline_ns > now_.load()) now_.store(deadline_ns);
  }
  void advance_ns(int64_t d) { now_ += d; }
  int64_t sleeps() const { return sleeps_; }

 private:
  std::atomic<int64_t> now_;
  int64_t sleeps_ = 0;
};

}  // namespace ig
