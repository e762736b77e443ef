// The cells phase's time budget for lod::CellSelector::select() (lod/ reads no clock): arm()
// before the call hands the view a stop for the refinement at start + budget, less what the
// calls before still spent after their stop or their last poll (the draw list, a pass over the
// cut: learned, so that the whole call ends near the budget); done() after the call disarms the
// view and learns from it. The passes over the cut before the refinement are not stopped, so a
// call can still run past the budget when they alone take longer. Used by the [cells] layer in
// igd and by igbench cells' deadline replays. Not movable while armed (the view points at it).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "ig/clock.h"
#include "lod/cells_select.h"

namespace ig {

class CellSelectDeadline {
 public:
  // budget_ms <= 0 or not finite: no stop.
  void arm(lod::CellView& view, const Clock& clock, int64_t start_ns, double budget_ms) {
    lastPoll_ns_ = -1;
    if (!(budget_ms > 0.0) || !std::isfinite(budget_ms)) return;
    const double room_ms = std::max(0.0, budget_ms - afterStop_ms_);
    deadline_ = {&clock, start_ns + static_cast<int64_t>(room_ms * 1e6)};
    view.stop = &CellSelectDeadline::past;
    view.stopContext = this;
  }
  // Learns from every call that polled the stop: the time from its last poll to the end of the
  // call. In a stopped call that poll is the stop; in one that was not stopped it lies at most
  // kCellStopPoll candidates before the refinement's end (a slight overestimate). Calls that are
  // not stopped teach it too, so the first stopped call does not overrun by the whole draw list.
  void done(lod::CellView& view) {
    view.stop = nullptr;
    view.stopContext = nullptr;
    if (deadline_.clock == nullptr || lastPoll_ns_ < 0) return;
    const double after_ms = static_cast<double>(deadline_.clock->now_ns() - lastPoll_ns_) * 1e-6;
    afterStop_ms_ = learned_ ? 0.8 * afterStop_ms_ + 0.2 * after_ms : after_ms;
    learned_ = true;
  }
  double afterStop_ms() const { return afterStop_ms_; }

 private:
  static bool past(void* self) {
    auto* d = static_cast<CellSelectDeadline*>(self);
    const int64_t now = d->deadline_.clock->now_ns();
    d->lastPoll_ns_ = now;
    return now >= d->deadline_.end_ns;
  }
  ClockDeadline deadline_;
  int64_t lastPoll_ns_ = -1;
  double afterStop_ms_ = 0.0;
  bool learned_ = false;
};

}  // namespace ig
