#include "ig/realtime.h"

#include <malloc.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstring>

namespace ig {
namespace {

std::string cpuList(const cpu_set_t& set) {
  std::string out;
  for (int c = 0; c < CPU_SETSIZE; ++c) {
    if (!CPU_ISSET(c, &set)) continue;
    int end = c;
    while (end + 1 < CPU_SETSIZE && CPU_ISSET(end + 1, &set)) ++end;
    if (!out.empty()) out += ",";
    out += std::to_string(c);
    if (end > c) {
      out += '-';
      out += std::to_string(end);
    }
    c = end;
  }
  return out.empty() ? "none" : out;
}

std::string listOf(const std::vector<int64_t>& v) {
  std::string s = "[";
  for (size_t i = 0; i < v.size(); ++i) {
    if (i) s += ", ";
    s += std::to_string(v[i]);
  }
  s += ']';
  return s;
}

// The mask the thread had before applyRealtime narrowed it: what helper threads go back to.
cpu_set_t gOriginalMask;
bool gHaveOriginalMask = false;

}  // namespace

bool applyRealtime(const RealtimeSettings& s, std::string& error) {
  if (!s.cpus.empty()) {
    // The CPUs this process may run on (a container or systemd's CPUAffinity= may narrow it).
    cpu_set_t allowed;
    CPU_ZERO(&allowed);
    if (sched_getaffinity(0, sizeof allowed, &allowed) != 0) {
      error = std::string("service.cpu_affinity: sched_getaffinity: ") + std::strerror(errno);
      return false;
    }
    gOriginalMask = allowed;
    gHaveOriginalMask = true;
    cpu_set_t want;
    CPU_ZERO(&want);
    for (int64_t c : s.cpus) {
      if (c < 0 || c >= CPU_SETSIZE || !CPU_ISSET(static_cast<int>(c), &allowed)) {
        error = "service.cpu_affinity = " + listOf(s.cpus) + ": CPU " + std::to_string(c) +
                " is not available to this process (allowed: " + cpuList(allowed) + ")";
        return false;
      }
      CPU_SET(static_cast<int>(c), &want);
    }
    if (const int rc = pthread_setaffinity_np(pthread_self(), sizeof want, &want); rc != 0) {
      error = "service.cpu_affinity = " + listOf(s.cpus) + ": pthread_setaffinity_np: " + std::strerror(rc);
      return false;
    }
  }
  if (s.priority > 0) {
    sched_param p{};
    p.sched_priority = s.priority;
    if (const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p); rc != 0) {
      error = "service.realtime_priority = " + std::to_string(s.priority) +
              ": pthread_setschedparam(SCHED_FIFO): " + std::strerror(rc) +
              " (needs root, CAP_SYS_NICE, or LimitRTPRIO=" + std::to_string(s.priority) + " in the systemd unit)";
      return false;
    }
  }
  if (s.lockMemory && mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
    error = std::string("service.lock_memory = true: mlockall: ") + std::strerror(errno) +
            " (needs CAP_IPC_LOCK or LimitMEMLOCK=infinity in the systemd unit)";
    return false;
  }
  return true;
}

void normalScheduling() {
  sched_param p{};
  p.sched_priority = 0;
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &p);
  if (gHaveOriginalMask) pthread_setaffinity_np(pthread_self(), sizeof gOriginalMask, &gOriginalMask);
}

std::string describeScheduling() {
  int policy = 0;
  sched_param p{};
  pthread_getschedparam(pthread_self(), &policy, &p);
  cpu_set_t set;
  CPU_ZERO(&set);
  pthread_getaffinity_np(pthread_self(), sizeof set, &set);
  std::string s = policy == SCHED_FIFO ? "SCHED_FIFO " + std::to_string(p.sched_priority)
                  : policy == SCHED_RR ? "SCHED_RR " + std::to_string(p.sched_priority)
                                       : std::string("SCHED_OTHER");
  return s + ", CPUs " + cpuList(set);
}

bool keepFreedMemory() {
  const bool trim = mallopt(M_TRIM_THRESHOLD, 512 << 20) == 1;
  const bool mmap = mallopt(M_MMAP_THRESHOLD, 32 << 20) == 1;
  return trim && mmap;
}

}  // namespace ig
