// Writes snapshot PNGs on a worker thread so PNG encoding and disk I/O never block the frame
// loop. Created only when the service config asks for snapshots (no snapshots, no thread).
// Image slots are allocated once at start-up; when all are busy the snapshot is dropped and
// counted rather than making the frame wait.
#pragma once

#include <array>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "render/image.h"

namespace ig {

class SnapshotWriter {
 public:
  SnapshotWriter(size_t slots, int width_px, int height_px);
  ~SnapshotWriter();  // writes what is queued, then joins
  SnapshotWriter(const SnapshotWriter&) = delete;
  SnapshotWriter& operator=(const SnapshotWriter&) = delete;

  // A free image to read the frame into, or nullptr (all slots busy: the caller drops the
  // snapshot). Hand it back with submit().
  render::Image* acquire();
  // Queues the image for writing to `path` (truncated to 4095 characters).
  void submit(render::Image* image, const char* path);

  // Blocks until every queued snapshot is written (end of a run; never in the frame).
  void flush();

  uint64_t written() const;
  uint64_t failed() const;
  uint64_t dropped() const;
  std::string firstError() const;

 private:
  struct Slot {
    render::Image image;
    std::array<char, 4096> path{};
    enum class State { Free, Filling, Queued } state = State::Free;
  };
  void run();

  std::vector<Slot> slots_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable idle_;
  bool stopping_ = false;
  uint64_t written_ = 0, failed_ = 0, dropped_ = 0;
  std::string firstError_;
  std::thread thread_;  // last: starts after everything above exists
};

}  // namespace ig
