// systemd integration: sd_notify READY / WATCHDOG / STOPPING / STATUS. Every call is a no-op
// when the process was not started by systemd (no NOTIFY_SOCKET).
#pragma once

#include <cstdint>
#include <string>

namespace ig {

class SystemdNotifier {
 public:
  // `interval_s` > 0 overrides the watchdog ping interval; 0 = half of WatchdogSec. One that is
  // not below WatchdogSec (systemd would kill the service between two pings) is replaced by
  // half of WatchdogSec and warning() says so.
  explicit SystemdNotifier(double interval_s = 0.0);
  // "" or a line for the log about service.watchdog_interval_s.
  const std::string& warning() const { return warning_; }
  bool underSystemd() const { return underSystemd_; }
  bool watchdogEnabled() const { return watchdogInterval_ns_ > 0; }
  int64_t watchdogInterval_ns() const { return watchdogInterval_ns_; }
  void ready(const std::string& status);
  // Pings the watchdog if the interval has passed since the last ping (rate-limited, so it
  // can be called every frame). Returns true if it pinged.
  bool watchdog(int64_t now_ns);
  void status(const std::string& text);
  void stopping();

 private:
  bool underSystemd_ = false;
  int64_t watchdogInterval_ns_ = 0;
  int64_t lastPing_ns_ = INT64_MIN;
  std::string warning_;
};

}  // namespace ig
