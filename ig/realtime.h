// Real-time scheduling of the render thread: SCHED_FIFO priority, CPU affinity and locked
// memory, from [service] realtime_priority / cpu_affinity / lock_memory. Only the calling
// thread is changed (the render thread); host-link, recorder and snapshot threads keep normal
// scheduling. A thread started after this must call normalScheduling() itself, because new
// threads inherit the policy and affinity of their creator.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ig {

struct RealtimeSettings {
  int priority = 0;              // 0 = leave the scheduling alone; 1..99 = SCHED_FIFO priority
  std::vector<int64_t> cpus;     // empty = any CPU
  bool lockMemory = false;       // mlockall(MCL_CURRENT | MCL_FUTURE)
};

// Applies `s` to the calling thread. On failure returns false with an error naming the config
// key, the value and the reason (e.g. "service.realtime_priority = 40: sched_setscheduler:
// Operation not permitted (needs CAP_SYS_NICE or LimitRTPRIO=40 in the unit)").
bool applyRealtime(const RealtimeSettings& s, std::string& error);

// Puts the calling thread back to SCHED_OTHER on every CPU the process may use (for helper
// threads started by a real-time thread). Best effort.
void normalScheduling();

// "SCHED_FIFO 40, CPUs 2-3" / "SCHED_OTHER, CPUs 0-1": the calling thread's scheduling.
std::string describeScheduling();

}  // namespace ig
