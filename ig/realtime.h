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

// Keeps freed memory in the process for reuse. glibc's malloc gives memory back to the kernel
// whenever a free() leaves more than M_TRIM_THRESHOLD (128 KiB until the process first frees a
// large block) at the top of the heap, and serves large blocks with fresh mmaps that it unmaps
// on free; Mesa's llvmpipe allocates and frees megabytes in every frame, so every frame paid the
// page faults again (the default scene on llvmpipe: work p50 24-28 ms before, 13-15 ms after,
// overruns 1-16 of 300 frames before, 0 after). Fixes both thresholds (trim 512 MiB, mmap
// 32 MiB: larger blocks still get their own mapping). igd calls it at start-up, before the GL
// context exists. False if glibc refused a setting (or the allocator is not glibc's, e.g. under
// a sanitizer, where it has no effect).
bool keepFreedMemory();

}  // namespace ig
