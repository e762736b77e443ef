#include "ig/snapshot_writer.h"

#include <cstring>

namespace ig {

SnapshotWriter::SnapshotWriter(size_t slots, int width_px, int height_px) : slots_(slots) {
  for (auto& s : slots_) {
    s.image.width = width_px;
    s.image.height = height_px;
    s.image.rgba.resize(static_cast<size_t>(width_px) * static_cast<size_t>(height_px) * 4);
  }
  thread_ = std::thread([this] { run(); });
}

SnapshotWriter::~SnapshotWriter() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

render::Image* SnapshotWriter::acquire() {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto& s : slots_) {
    if (s.state == Slot::State::Free) {
      s.state = Slot::State::Filling;
      return &s.image;
    }
  }
  ++dropped_;
  return nullptr;
}

void SnapshotWriter::submit(render::Image* image, const char* path) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& s : slots_) {
      if (&s.image == image) {
        std::strncpy(s.path.data(), path, s.path.size() - 1);
        s.path.back() = '\0';
        s.state = Slot::State::Queued;
      }
    }
  }
  wake_.notify_one();
}

void SnapshotWriter::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    Slot* job = nullptr;
    for (auto& s : slots_)
      if (s.state == Slot::State::Queued) job = &s;
    if (!job) {
      if (stopping_) return;
      wake_.wait(lock);
      continue;
    }
    lock.unlock();
    std::string error;
    const bool ok = render::writePng(job->path.data(), job->image, error);
    lock.lock();
    if (ok) {
      ++written_;
    } else {
      if (failed_++ == 0) firstError_ = error;
    }
    job->state = Slot::State::Free;
    idle_.notify_all();
  }
}

void SnapshotWriter::flush() {
  std::unique_lock<std::mutex> lock(mutex_);
  idle_.wait(lock, [&] {
    for (const auto& s : slots_)
      if (s.state == Slot::State::Queued) return false;
    return true;
  });
}

uint64_t SnapshotWriter::written() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return written_;
}
uint64_t SnapshotWriter::failed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return failed_;
}
uint64_t SnapshotWriter::dropped() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return dropped_;
}
std::string SnapshotWriter::firstError() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return firstError_;
}

}  // namespace ig
