// The hard end of a budgeted Deferred ROAM update (lod::RoamView::stop) on the caller's clock:
// lod/ reads no clock, so igd and igbench terrain hand it this deadline.
#pragma once

#include <cstdint>

#include "ig/clock.h"
#include "lod/roam.h"

namespace ig {

struct RoamDeadline {
  ClockDeadline deadline;
  // The update of `v` stops once `clock` reads start_ns + budget_ms or later (polled every
  // lod::kStopPollVisits visits). This object must outlive the update.
  void arm(lod::RoamView& v, const Clock& c, int64_t start_ns, double budget_ms) {
    deadline = {&c, start_ns + static_cast<int64_t>(budget_ms * 1e6)};
    v.stop = &ClockDeadline::past;
    v.stopContext = &deadline;
  }
};

}  // namespace ig
