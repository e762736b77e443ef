#include "ig/host_input.h"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>

namespace ig {

bool HostRecorder::open(const std::string& file, std::string& error) {
  close();
  out_ = std::fopen(file.c_str(), "wb");
  if (out_ == nullptr) {
    error = "host.record_file '" + file + "': cannot write: " + std::strerror(errno);
    return false;
  }
  file_ = file;
  const std::string header = io::recordingHeader();
  if (std::fputs(header.c_str(), out_) < 0 || std::fflush(out_) != 0) {
    error = "host.record_file '" + file + "': cannot write: " + std::strerror(errno);
    std::fclose(out_);
    out_ = nullptr;
    return false;
  }
  stopping_ = false;
  failed_ = 0;
  firstError_.clear();
  thread_ = std::thread([this] { run(); });
  return true;
}

void HostRecorder::append(const io::HostSample& sample) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    pending_.push_back(sample);
  }
  wake_.notify_one();
}

void HostRecorder::run() {
  std::vector<io::HostSample> batch;
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    // Batch writes: at most every 100 ms, at once on stop.
    wake_.wait_for(lock, std::chrono::milliseconds(100), [&] { return stopping_; });
    batch.swap(pending_);
    const bool last = stopping_;
    lock.unlock();
    bool ok = true;
    for (const io::HostSample& s : batch) ok = std::fputs(io::formatSample(s).c_str(), out_) >= 0 && ok;
    if (!batch.empty()) ok = std::fflush(out_) == 0 && ok;
    const int err = errno;
    if (ok) {
      written_ += batch.size();
    } else {
      std::clearerr(out_);  // a later batch may succeed (space freed)
      const std::string why = "host.record_file '" + file_ + "': write failed: " + std::strerror(err);
      if (failed_.fetch_add(batch.size()) == 0)
        std::fprintf(stderr, "igd: %s; host samples are being lost\n", why.c_str());
      std::lock_guard<std::mutex> errorLock(errorMutex_);
      if (firstError_.empty()) firstError_ = why;
    }
    batch.clear();
    lock.lock();
    if (last && pending_.empty()) return;
  }
}

std::string HostRecorder::firstError() const {
  std::lock_guard<std::mutex> lock(errorMutex_);
  return firstError_;
}

void HostRecorder::close() {
  if (thread_.joinable()) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    wake_.notify_one();
    thread_.join();
  }
  if (out_ != nullptr) {
    std::fclose(out_);
    out_ = nullptr;
  }
}

bool HostInput::start(std::unique_ptr<io::HostLink> link, const std::string& recordFile, double linkTimeout_s,
                      std::string& error) {
  t0_ns_.store(clock_.load()->now_ns());
  timeout_ns_ = static_cast<int64_t>(linkTimeout_s * 1e9);
  // The recorder exists before the link starts (publish() may run on the link's thread at
  // once; its samples queue up), but the file is created only once the link runs: a start that
  // fails (a port in use) leaves the previous run's recording as it was.
  if (!recordFile.empty()) recorder_ = std::make_unique<HostRecorder>();
  if (link) {
    if (!link->start(*this, error)) {
      recorder_.reset();
      return false;
    }
    link_ = std::move(link);
  }
  if (recorder_ && !recorder_->open(recordFile, error)) {
    if (link_) link_->stop();
    link_.reset();
    recorder_.reset();
    return false;
  }
  return true;
}

void HostInput::stop() {
  if (link_) link_->stop();
  if (recorder_) recorder_->close();
}

void HostInput::publish(const io::HostState& state) {
  double t_s = 0.0;
  {
    std::lock_guard<std::mutex> lock(timeMutex_);
    const int64_t now = clock_.load()->now_ns();
    lastPublish_ns_.store(now);
    // Before the frame loop's time base is set, a sample is due at the loop's first frame: 0.
    if (timeBaseSet_) t_s = std::max(lastRecorded_s_, std::max(0.0, static_cast<double>(now - t0_ns_.load()) * 1e-9));
    lastRecorded_s_ = t_s;
  }
  mailbox_.publish(state);
  if (recorder_) {
    io::HostSample s;
    s.t_s = t_s;
    s.state = state;
    recorder_->append(s);
  }
}

bool HostInput::updateLost() {
  if (!link_) return false;
  const int64_t last = lastPublish_ns_.load();
  const int64_t now = clock_.load()->now_ns();
  const int64_t since = last < 0 ? now - t0_ns_.load() : now - last;
  const bool lost = since > timeout_ns_;
  if (lost != lost_) {
    if (lost) {
      std::fprintf(stderr, "igd: host link %.*s lost: no valid input for %.1f s; holding the last eyepoint\n",
                   static_cast<int>(link_->name().size()), link_->name().data(), static_cast<double>(since) * 1e-9);
      everLost_ = true;
    } else if (everLost_) {
      std::fprintf(stderr, "igd: host link %.*s back: valid input again\n", static_cast<int>(link_->name().size()),
                   link_->name().data());
    }
    lost_ = lost;
  }
  return lost_;
}

std::string HostInput::countersLine() const {
  if (!link_) return "";
  const io::LinkCountersSnapshot c = io::snapshot(link_->counters());
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "igd: link %.*s: received %llu accepted %llu malformed %llu out_of_range %llu late %llu dropped %llu",
                static_cast<int>(link_->name().size()), link_->name().data(),
                static_cast<unsigned long long>(c.received), static_cast<unsigned long long>(c.accepted),
                static_cast<unsigned long long>(c.malformed), static_cast<unsigned long long>(c.outOfRange),
                static_cast<unsigned long long>(c.late), static_cast<unsigned long long>(c.dropped));
  return buf + link_->extraCounters();
}

}  // namespace ig
