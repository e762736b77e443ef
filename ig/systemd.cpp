#include "ig/systemd.h"

#include <systemd/sd-daemon.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>

namespace ig {

SystemdNotifier::SystemdNotifier(double interval_s) {
  underSystemd_ = std::getenv("NOTIFY_SOCKET") != nullptr;
  uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) {
    // Half of WatchdogSec; a WATCHDOG_USEC beyond int64_t nanoseconds (about 292 years) saturates
    // rather than overflowing into a negative interval (which would switch the pings off).
    constexpr uint64_t kMaxUsec = static_cast<uint64_t>(INT64_MAX / 1000);
    watchdogInterval_ns_ = usec > kMaxUsec ? INT64_MAX / 2 : static_cast<int64_t>(usec) * 1000 / 2;
    if (interval_s > 0 && interval_s * 1e6 < static_cast<double>(usec)) {
      // At least 1 ns: a tiny configured interval pings at every call; 0 would mean no watchdog.
      watchdogInterval_ns_ = std::max<int64_t>(1, static_cast<int64_t>(interval_s * 1e9));
    } else if (interval_s > 0) {
      char buf[256];
      std::snprintf(buf, sizeof buf,
                    "service.watchdog_interval_s = %g: not below systemd's WatchdogSec (%g s), which would "
                    "kill igd between two pings; pinging every %g s (half of WatchdogSec) instead",
                    interval_s, static_cast<double>(usec) * 1e-6, static_cast<double>(watchdogInterval_ns_) * 1e-9);
      warning_ = buf;
    }
  }
}

void SystemdNotifier::ready(const std::string& text) {
  if (underSystemd_) sd_notifyf(0, "READY=1\nSTATUS=%s", text.c_str());
}

bool SystemdNotifier::watchdog(int64_t now_ns) {
  if (watchdogInterval_ns_ <= 0) return false;
  if (lastPing_ns_ != INT64_MIN && now_ns - lastPing_ns_ < watchdogInterval_ns_) return false;
  lastPing_ns_ = now_ns;
  sd_notify(0, "WATCHDOG=1");
  return true;
}

void SystemdNotifier::status(const std::string& text) {
  if (underSystemd_) sd_notifyf(0, "STATUS=%s", text.c_str());
}

void SystemdNotifier::stopping() {
  if (underSystemd_) sd_notify(0, "STOPPING=1");
}

}  // namespace ig
