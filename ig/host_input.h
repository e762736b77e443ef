// Host input of the frame loop: a live host link (CIGI, CAN, Modbus) or nothing, the optional
// recorder of accepted host samples, and link-loss detection.
//
//   link thread --publish()--> HostInput --> mailbox (newest sample, read by the frame loop)
//                                      \--> recorder queue --> recorder thread --> file
//
// The recorder thread exists only when [host] record_file is set; without a link no thread
// runs at all. Recorded sample times are seconds since the frame loop's start (setTimeBase) --
// the same clock as the frame slots of the run; samples from before it are stamped 0 -- so
// replaying the recording feeds each frame the sample it had live.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "ig/clock.h"
#include "io/link.h"
#include "io/mailbox.h"
#include "io/replay.h"

namespace ig {

class HostRecorder {
 public:
  HostRecorder() = default;
  ~HostRecorder() { close(); }
  HostRecorder(const HostRecorder&) = delete;
  HostRecorder& operator=(const HostRecorder&) = delete;

  // Creates (truncates) the file, writes the header and starts the writer thread; samples
  // appended before are written first. False with an error naming the file when it cannot be
  // created or the header cannot be written (a full disk): a recording that would stay empty
  // fails at start-up.
  bool open(const std::string& file, std::string& error);
  // Queues one sample (any thread; never blocks on the file).
  void append(const io::HostSample& sample);
  // Writes what is queued, stops the thread, closes the file. Idempotent.
  void close();
  // Samples that reached the file, and samples lost to write errors (a full disk, an I/O error:
  // the batch whose write or flush failed). The first error is logged once when it happens.
  uint64_t written() const { return written_.load(); }
  uint64_t failed() const { return failed_.load(); }
  std::string firstError() const;
  const std::string& file() const { return file_; }

 private:
  void run();
  std::string file_;
  FILE* out_ = nullptr;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::vector<io::HostSample> pending_;
  bool stopping_ = false;
  std::thread thread_;
  std::atomic<uint64_t> written_{0};
  std::atomic<uint64_t> failed_{0};
  mutable std::mutex errorMutex_;
  std::string firstError_;  // errorMutex_
};

class HostInput final : public io::HostSink {
 public:
  HostInput(io::LatestValueMailbox<io::HostState>& mailbox, Clock& clock) : mailbox_(mailbox), clock_(&clock) {}
  ~HostInput() override { stop(); }

  // Starts the link (if any), then recording (if `recordFile` is not empty): the file is
  // created (truncated) only after the link started, so a failed start leaves an existing
  // recording untouched; samples published meanwhile are kept. Samples published before
  // setTimeBase are recorded at time 0. Returns false with an error naming the link's address
  // or the file; nothing is left running then.
  bool start(std::unique_ptr<io::HostLink> link, const std::string& recordFile, double linkTimeout_s,
             std::string& error);
  // From now on samples are stamped with `clock` and recorded times count from `t0_ns` (the
  // frame loop's start); earlier samples get 0. Call before the link's next sample matters
  // (the frame loop calls it once, before its first frame).
  void setTimeBase(Clock& clock, int64_t t0_ns) {
    // One lock with publish(): a sample is stamped entirely with the old base (time 0) or
    // entirely with the new one, never the new clock minus the old t0.
    std::lock_guard<std::mutex> lock(timeMutex_);
    clock_.store(&clock);
    t0_ns_.store(t0_ns);
    timeBaseSet_ = true;
    if (lastPublish_ns_.load() >= 0) lastPublish_ns_.store(t0_ns);
  }
  void stop();

  // Link thread: a complete, accepted host sample.
  void publish(const io::HostState& state) override;

  // Frame loop: true while a link is configured and nothing valid arrived for longer than the
  // link timeout (or never). Logs the transitions once each.
  bool updateLost();
  bool lost() const { return lost_; }
  io::HostLink* link() { return link_.get(); }
  // Reload: the new [host] link_timeout_s, from the next frame on (render thread).
  void setLinkTimeout(double linkTimeout_s) { timeout_ns_ = static_cast<int64_t>(linkTimeout_s * 1e9); }
  HostRecorder* recorder() { return recorder_.get(); }
  // Threads this input runs (link receive thread + recorder writer).
  uint32_t threads() const { return (link_ ? 1u : 0u) + (recorder_ ? 1u : 0u); }
  // "igd: link cigi: received N accepted N ..." (empty without a link).
  std::string countersLine() const;

 private:
  io::LatestValueMailbox<io::HostState>& mailbox_;
  std::atomic<Clock*> clock_;
  std::unique_ptr<io::HostLink> link_;
  std::unique_ptr<HostRecorder> recorder_;
  std::atomic<int64_t> t0_ns_{0};
  std::mutex timeMutex_;                     // publish() vs setTimeBase()
  bool timeBaseSet_ = false;                 // before setTimeBase, recorded times are 0 (timeMutex_)
  double lastRecorded_s_ = 0.0;              // recorder times stay non-decreasing (timeMutex_)
  int64_t timeout_ns_ = 0;
  std::atomic<int64_t> lastPublish_ns_{-1};  // -1 = nothing yet
  bool lost_ = false;
  bool everLost_ = false;
};

}  // namespace ig
