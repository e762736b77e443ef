#include "ig/stats.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

#include <sys/stat.h>

namespace ig {

StatsWriter::~StatsWriter() { close(); }

namespace {
bool isRegularFile(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}
}  // namespace

bool StatsWriter::writeHeader() {
  int n = 0;
  if (format_ == StatsFormat::Csv) {
    n += std::fprintf(file_, "frame,t_ms,period_ms,interval_ms,lateness_ms");
    for (int p = 0; p < kPhaseCount; ++p) n += std::fprintf(file_, ",%s_ms", phaseName(static_cast<Phase>(p)));
    n += std::fprintf(file_, "%s", ",work_ms,overrun,missed_slots,triangles,draw_calls,passes,uploads,host_frame,sim_time_s,eye_east_m,eye_north_m,eye_up_m,heading_deg,host_lost,between_ms,gov_predicted_ms,terrain_tolerance_px,forest_near_m,hdlod_tolerance_px,cells_voxel_budget,forest_layers,far_m,fog_visibility_m\n");
  } else {
    n += std::fprintf(file_, "{\"run\":{%s}}\n", runInfo_.c_str());
  }
  bytes_ = n > 0 ? static_cast<uint64_t>(n) : 0;
  return std::fflush(file_) == 0;
}

bool StatsWriter::renameOld() {
  for (int i = rotation_.keep; i >= 1; --i) {
    const std::string from = i == 1 ? path_ : path_ + "." + std::to_string(i - 1);
    const std::string to = path_ + "." + std::to_string(i);
    if (std::rename(from.c_str(), to.c_str()) != 0 && errno != ENOENT) {
      if (rotateError_.empty())
        rotateError_ = "stats file '" + path_ + "': cannot rotate ('" + from + "' -> '" + to + "'): " + std::strerror(errno);
      return false;
    }
  }
  return true;
}

bool StatsWriter::open(const std::string& file, StatsFormat format, const std::string& runInfo, std::string& error,
                       StatsRotation rotation) {
  close();
  path_ = file;
  error_.clear();
  rotateError_.clear();
  format_ = format;
  runInfo_ = runInfo;
  rotation_ = rotation;
  // A restart keeps the previous run's file (a post-mortem after a crash needs it).
  if (rotation_.keep > 0 && isRegularFile(path_)) renameOld();
  file_ = std::fopen(file.c_str(), "w");
  if (!file_) {
    error = "stats file '" + file + "': cannot write: " + std::strerror(errno);
    return false;
  }
  regular_ = isRegularFile(path_);
  if (!writeHeader()) {
    error = "stats file '" + file + "': cannot write: " + std::strerror(errno);
    std::fclose(file_);
    file_ = nullptr;
    return false;
  }
  rotateAt_ = rotation_.maxBytes;
  return true;
}

void StatsWriter::rollOver() {
  std::fflush(file_);
  if (std::ferror(file_) && error_.empty()) noteError();
  if (rotation_.keep > 0 && !renameOld()) {
    rotateAt_ = bytes_ + rotation_.maxBytes;  // go on in this file; try again one limit later
    return;
  }
  if (std::fclose(file_) != 0) noteError();
  file_ = std::fopen(path_.c_str(), "w");
  if (!file_) {
    noteError();
    return;
  }
  if (!writeHeader()) noteError();
  rotateAt_ = rotation_.maxBytes;
}

void StatsWriter::noteError() {
  if (error_.empty()) error_ = "stats file '" + path_ + "': write failed: " + std::strerror(errno);
}

void StatsWriter::write(const FrameRecord& r) {
  if (!file_) return;
  const FrameTiming& t = r.timing;
  const auto& ph = t.phase_ms;
  int n = 0;
  if (format_ == StatsFormat::Csv) {
    n = std::fprintf(file_, "%lld,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%d,%lld,%llu,%u,%u,%llu,%llu,%.4f,%.2f,%.2f,%.2f,%.3f,%d,%.3f,%.3f,%.3f,%.1f,%.3f,%.0f,%.0f,%.1f,%.1f\n",
                 static_cast<long long>(t.frame), static_cast<double>(t.start_ns) * 1e-6, r.period_ms, t.interval_ms,
                 static_cast<double>(t.lateness_ns) * 1e-6, ph[0], ph[1], ph[2], ph[3], ph[4], t.work_ms,
                 t.overrun ? 1 : 0, static_cast<long long>(t.missedSlots),
                 static_cast<unsigned long long>(r.triangles), r.drawCalls, r.passes,
                 static_cast<unsigned long long>(r.uploads), static_cast<unsigned long long>(r.hostFrame),
                 r.simTime_s, r.eyeEast_m, r.eyeNorth_m, r.eyeHeight_m, r.heading_deg, r.hostLost ? 1 : 0, t.between_ms,
                 r.predicted_ms, r.terrainTolerance_px, r.forestNear_m, r.hdlodTolerance_px, r.cellsVoxelBudget,
                 r.forestLayers, r.far_m, r.fogVisibility_m);
  } else {
    // JSON has no NaN: a value that is not there is null.
    char gov[8][32];
    const double govValues[8] = {r.predicted_ms, r.terrainTolerance_px, r.forestNear_m, r.hdlodTolerance_px, r.cellsVoxelBudget,
                                 r.forestLayers, r.far_m, r.fogVisibility_m};
    for (int i = 0; i < 8; ++i) {
      if (!std::isfinite(govValues[i])) std::snprintf(gov[i], sizeof gov[i], "null");  // no NaN or inf in JSON
      else std::snprintf(gov[i], sizeof gov[i], "%.3f", govValues[i]);
    }
    n = std::fprintf(file_,
                 "{\"frame\":%lld,\"t_ms\":%.3f,\"period_ms\":%.3f,\"interval_ms\":%.3f,\"lateness_ms\":%.3f,\"input_ms\":%.3f,"
                 "\"lod_ms\":%.3f,\"submit_ms\":%.3f,\"gpu_finish_ms\":%.3f,\"present_ms\":%.3f,\"work_ms\":%.3f,"
                 "\"overrun\":%s,\"missed_slots\":%lld,\"triangles\":%llu,\"draw_calls\":%u,\"passes\":%u,\"uploads\":%llu,"
                 "\"host_frame\":%llu,\"sim_time_s\":%.4f,\"eye_east_m\":%.2f,\"eye_north_m\":%.2f,\"eye_up_m\":%.2f,"
                 "\"heading_deg\":%.3f,\"host_lost\":%s,\"between_ms\":%.3f,\"gov_predicted_ms\":%s,"
                 "\"terrain_tolerance_px\":%s,\"forest_near_m\":%s,\"hdlod_tolerance_px\":%s,\"cells_voxel_budget\":%s,"
                 "\"forest_layers\":%s,\"far_m\":%s,\"fog_visibility_m\":%s}\n",
                 static_cast<long long>(t.frame), static_cast<double>(t.start_ns) * 1e-6, r.period_ms, t.interval_ms,
                 static_cast<double>(t.lateness_ns) * 1e-6, ph[0], ph[1], ph[2], ph[3], ph[4], t.work_ms,
                 t.overrun ? "true" : "false", static_cast<long long>(t.missedSlots),
                 static_cast<unsigned long long>(r.triangles), r.drawCalls, r.passes,
                 static_cast<unsigned long long>(r.uploads), static_cast<unsigned long long>(r.hostFrame),
                 r.simTime_s, r.eyeEast_m, r.eyeNorth_m, r.eyeHeight_m, r.heading_deg, r.hostLost ? "true" : "false", t.between_ms,
                 gov[0], gov[1], gov[2], gov[3], gov[4], gov[5], gov[6], gov[7]);
  }
  // Written out at least every kFlushEvery_ns of frame time (not only when stdio's 4 KiB buffer
  // fills, ~25 frames): a process the watchdog kills (SIGKILL: no close) keeps the lines of the
  // frames before the hang, which are the ones a post-mortem needs.
  if (t.start_ns - lastFlush_ns_ >= kFlushEvery_ns || t.start_ns < lastFlush_ns_) {
    std::fflush(file_);
    lastFlush_ns_ = t.start_ns;
  }
  if (std::ferror(file_) && error_.empty()) noteError();  // stdio keeps the error of a failed buffer write
  if (n > 0) bytes_ += static_cast<uint64_t>(n);
  // Rotated between lines (a line is never split across files).
  if (rotation_.maxBytes > 0 && regular_ && bytes_ >= rotateAt_) rollOver();
}

bool StatsWriter::close() {
  if (file_) {
    if (std::fclose(file_) != 0) noteError();
    file_ = nullptr;
  }
  return error_.empty();
}

SummaryCollector::SummaryCollector(size_t capacity) : capacity_(std::clamp<size_t>(capacity, 1, kMaxCapacity)) {
  records_.reserve(capacity_);
}

size_t SummaryCollector::capacityFor(int64_t frames) {
  return frames > 0 && frames < static_cast<int64_t>(kMaxCapacity) ? static_cast<size_t>(frames) : kMaxCapacity;
}

void SummaryCollector::grow(size_t capacity) {
  capacity = std::clamp<size_t>(capacity, 1, kMaxCapacity);
  if (capacity <= capacity_) return;
  // Oldest first (a full ring's oldest is at next_), then room for the new frames.
  std::rotate(records_.begin(), records_.begin() + static_cast<std::ptrdiff_t>(next_), records_.end());
  next_ = 0;
  records_.reserve(capacity);
  capacity_ = capacity;
}

void SummaryCollector::add(const FrameRecord& r) {
  workMax_ms_ = added_ == 0 ? r.timing.work_ms : std::max(workMax_ms_, r.timing.work_ms);
  workSum_ms_ += r.timing.work_ms;
  ++added_;
  if (records_.size() < capacity_) {
    records_.push_back(r);
  } else {
    records_[next_] = r;
    next_ = (next_ + 1) % capacity_;
  }
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  // Nearest-rank on the sorted values.
  const double rank = std::ceil(p / 100.0 * static_cast<double>(v.size()));
  const size_t i = static_cast<size_t>(std::clamp(rank, 1.0, static_cast<double>(v.size()))) - 1;
  return v[i];
}

double median(std::vector<double> v) { return percentile(std::move(v), 50); }

RunSummary SummaryCollector::summarize(int64_t overruns, int64_t missedSlots) const {
  RunSummary s;
  s.frames = added_;
  s.overruns = overruns;
  s.missedSlots = missedSlots;
  if (records_.empty()) return s;
  std::vector<double> work, tris, calls;
  for (const auto& r : records_) {
    work.push_back(r.timing.work_ms);
    tris.push_back(static_cast<double>(r.triangles));
    calls.push_back(r.drawCalls);
  }
  s.workMs_p50 = percentile(work, 50);
  s.workMs_p99 = percentile(work, 99);
  // The maximum and the mean of the whole run, as frames (the percentiles: the frames kept).
  s.workMs_max = workMax_ms_;
  s.workMs_mean = workSum_ms_ / static_cast<double>(added_);
  for (int p = 0; p < kPhaseCount; ++p) {
    std::vector<double> v;
    for (const auto& r : records_) v.push_back(r.timing.phase_ms[static_cast<size_t>(p)]);
    s.phaseMs_p50[static_cast<size_t>(p)] = percentile(v, 50);
  }
  s.triangles_p50 = static_cast<uint64_t>(percentile(tris, 50));
  s.drawCalls_p50 = static_cast<uint32_t>(percentile(calls, 50));
  return s;
}

}  // namespace ig
