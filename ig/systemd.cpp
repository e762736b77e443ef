#include "ig/systemd.h"

#include <systemd/sd-daemon.h>

#include <cstdlib>

namespace ig {

SystemdNotifier::SystemdNotifier(double interval_s) {
  underSystemd_ = std::getenv("NOTIFY_SOCKET") != nullptr;
  uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) watchdogInterval_ns_ = static_cast<int64_t>(usec) * 1000 / 2;
  if (interval_s > 0 && watchdogInterval_ns_ > 0) watchdogInterval_ns_ = static_cast<int64_t>(interval_s * 1e9);
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
