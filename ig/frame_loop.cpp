#include "ig/frame_loop.h"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace ig {

const char* phaseName(Phase p) {
  switch (p) {
    case Phase::Input: return "input";
    case Phase::Lod: return "lod";
    case Phase::Submit: return "submit";
    case Phase::GpuFinish: return "gpu_finish";
    case Phase::Present: return "present";
    case Phase::Count: break;
  }
  return "?";
}

FramePacer::FramePacer(Clock& clock, double rate_hz, bool freeRun, double budget_ms)
    : clock_(clock),
      rate_hz_(rate_hz),
      period_ns_(static_cast<int64_t>(std::llround(1e9 / rate_hz))),
      budget_ns_(static_cast<int64_t>(std::llround(budget_ms * 1e6))),
      freeRun_(freeRun) {
  assert(rate_hz > 0 && "FramePacer: rate_hz must be > 0");
}

int64_t FramePacer::beginFrame() {
  if (!started_) {
    started_ = true;
    t0_ns_ = clock_.now_ns();
    prevStart_ns_ = t0_ns_;
  }
  const int64_t slot = nextSlot_;
  const int64_t slotTime = t0_ns_ + slotTime_ns(slot);
  const int64_t waitStart = prevEnd_ns_ >= 0 ? clock_.now_ns() : 0;
  if (wait_ && !wait_(slotTime)) return -1;
  if (!freeRun_) clock_.sleepUntil_ns(slotTime);
  frameStart_ns_ = clock_.now_ns();
  mark_ns_ = frameStart_ns_;
  timing_ = FrameTiming{};
  if (prevEnd_ns_ >= 0) timing_.between_ms = static_cast<double>(waitStart - prevEnd_ns_) * 1e-6;
  timing_.frame = slot;
  timing_.start_ns = frameStart_ns_ - t0_ns_;
  timing_.lateness_ns = freeRun_ ? 0 : frameStart_ns_ - slotTime;
  timing_.interval_ms = static_cast<double>(frameStart_ns_ - prevStart_ns_) * 1e-6;
  prevStart_ns_ = frameStart_ns_;
  return slot;
}

void FramePacer::endPhase(Phase phase) {
  const int64_t now = clock_.now_ns();
  timing_.phase_ms[static_cast<size_t>(phase)] += static_cast<double>(now - mark_ns_) * 1e-6;
  mark_ns_ = now;
}

const FrameTiming& FramePacer::endFrame() {
  const int64_t end = clock_.now_ns();
  timing_.work_ms = static_cast<double>(end - frameStart_ns_) * 1e-6;
  prevEnd_ns_ = end;
  ++frames_;
  int64_t next = timing_.frame + 1;
  const int64_t nextSlotTime = t0_ns_ + slotTime_ns(next);
  if (budget_ns_ > 0) {
    timing_.overrun = end - frameStart_ns_ > budget_ns_;
  } else {
    timing_.overrun = freeRun_ ? end - frameStart_ns_ > period_ns_ : end > nextSlotTime;
  }
  if (!freeRun_) {
    if (end > nextSlotTime) {
      // First slot that has not started yet (one starting exactly at `end` has not, as for the
      // next slot above): skip the ones we ran past.
      const int64_t since = end - t0_ns_;
      int64_t firstFuture = std::max(  // within a slot or so; exact below
          next, static_cast<int64_t>(std::ceil(static_cast<long double>(since) * static_cast<long double>(rate_hz_) / 1e9L)));
      while (firstFuture > next && slotTime_ns(firstFuture - 1) >= since) --firstFuture;
      while (slotTime_ns(firstFuture) < since) ++firstFuture;
      timing_.missedSlots = firstFuture - next;
      next = firstFuture;
    }
  }
  if (timing_.overrun) ++overruns_;
  missed_ += timing_.missedSlots;
  nextSlot_ = next;
  return timing_;
}

}  // namespace ig
