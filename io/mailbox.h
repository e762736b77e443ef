// Latest-value mailbox: a producer (host link thread or the replay) publishes, the frame loop
// reads the newest value at the start of each frame. Older values are overwritten, never
// queued: the IG always renders the newest eyepoint. Lock held only for a struct copy.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>

namespace ig::io {

template <class T>
class LatestValueMailbox {
 public:
  void publish(const T& value) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      value_ = value;
      ++sequence_;
    }
    changed_.notify_all();
  }
  // Waits until a value newer than `lastSequence` is published or `timeout` passes. Returns
  // true if one is there (read it with readIfNewer). Used by the host-paced (synchronous) mode.
  bool waitNewer(uint64_t lastSequence, std::chrono::nanoseconds timeout) const {
    std::unique_lock<std::mutex> lock(mutex_);
    return changed_.wait_for(lock, timeout, [&] { return sequence_ != lastSequence; });
  }
  // Copies the newest value into `out` if one was published since `lastSequence`; updates
  // lastSequence. Returns true if `out` changed.
  bool readIfNewer(T& out, uint64_t& lastSequence) const {
    std::lock_guard<std::mutex> lock(mutex_);
    if (sequence_ == lastSequence) return false;
    out = value_;
    lastSequence = sequence_;
    return true;
  }
  uint64_t sequence() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return sequence_;
  }

 private:
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  T value_{};
  uint64_t sequence_ = 0;
};

}  // namespace ig::io
