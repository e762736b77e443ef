#include "ig/systemd.h"

#include <systemd/sd-daemon.h>

#include <cstdio>
#include <cstdlib>

namespace ig {

SystemdNotifier::SystemdNotifier(double interval_s) {
  underSystemd_ = std::getenv("NOTIFY_SOCKET") != nullptr;
  uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) {
    watchdogInterval_ns_ = static_cast<int64_t>(usec) * 1000 / 2;
    if (interval_s > 0 && interval_s * 1e6 < static_cast<double>(usec)) {
      watchdogInterval_ns_ = static_cast<int64_t>(interval_s * 1e9);
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
