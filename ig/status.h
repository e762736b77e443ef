// The service's health report, once per [service] status_interval_s:
//   - one line for `systemctl status igd` (sd_notify STATUS=), e.g.
//     "frame 5400, 30.00 Hz: work p99 21.3 of 33.3 ms, overruns 0 (0 in last 1.0 s); host cigi ok; config #2"
//   - optionally a JSON file ([service] status_file, e.g. /run/igd/status.json), replaced
//     atomically (write to a temporary file, then rename), so a reader never sees half a report.
// Collecting a frame does not allocate; a report formats into a buffer reserved at start-up.
// Memory is bounded whatever the rate and interval (about 0.7 MB): the work percentiles of an
// interval are exact over its first kExactFrames frames; an interval with more (1000 Hz for
// 65 s, a free-running loop) takes them from a histogram of every frame of the interval, within
// 0.1 % (1 us below 2 ms).
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "ig/frame_loop.h"
#include "io/link.h"

namespace ig {

// What the frame loop knows besides the frames themselves.
struct StatusContext {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  const char* state = "running";    // "running" | "stopping"
  double rate_hz = 0.0;
  double budgetFrame_ms = 0.0;      // the work budget of a frame
  int64_t budgetTriangles = 0;
  std::string hostSource;           // "replay", "cigi", ... ("none")
  bool hostLost = false;
  bool haveLink = false;
  io::LinkCountersSnapshot link;
  bool haveHatHot = false;          // the link answers HAT/HOT and LOS Requests (CIGI)
  io::HatHotCounters hatHot;
  uint64_t hostRejected = 0;        // samples the frame loop rejected (NaN, out of range)
  int configGeneration = 1;         // 1 at start, +1 per successful reload
  std::string lastReloadError;      // "" = the last reload (if any) succeeded
  std::string layers;               // e.g. "terrain forest"
  std::string scheduling;           // e.g. "SCHED_FIFO 40, CPUs 2"
  // The frame governor ([governor] enabled): the detail it gives each layer now (NaN: the scene
  // has no such layer) and its decisions so far.
  bool haveGovernor = false;
  double terrainTolerance_px = kNaN, forestNear_m = kNaN, hdlodTolerance_px = kNaN, cellsVoxelBudget = kNaN;
  double forestLayers = kNaN;  // shell layers drawn
  int64_t governorDecreases = 0, governorIncreases = 0, governorEmergencies = 0;
};

class StatusReporter {
 public:
  // `file` "" = no file, only the one-line text. `interval_s` > 0.
  StatusReporter(std::string file, double interval_s, double rate_hz);

  // The first interval starts here (the frame loop's start).
  void start(int64_t now_ns) { lastReport_ns_ = now_ns; }
  // Reload: a new file and interval from the next report on (a file no longer used is removed).
  // The totals (frames, overruns, missed slots) and the frames of the current interval are kept.
  // May allocate (between frames).
  void reconfigure(std::string file, double interval_s, double rate_hz);
  // A reporter created after frames have run (a reload that switched the report on): the
  // totals so far, e.g. from the frame pacer, so that they do not restart at 0.
  void setTotals(int64_t frames, int64_t overruns, int64_t missedSlots) {
    totalFrames_ = frames;
    totalOverruns_ = overruns;
    totalMissed_ = missedSlots;
  }
  // Per frame: adds the frame's timing to the current interval.
  void addFrame(const FrameTiming& t, uint64_t triangles);
  // True when `now_ns` (the frame loop's clock) is at least one interval after the last report.
  bool due(int64_t now_ns) const { return now_ns - lastReport_ns_ >= interval_ns_; }
  // Builds the report of the interval since the last one, writes the file (if any) and
  // returns the one-line status. Starts a new interval.
  const std::string& report(int64_t now_ns, const StatusContext& ctx);
  // Bytes reserved for the frames of an interval (bounded: see above).
  size_t reservedBytes() const {
    return work_ms_.capacity() * sizeof(double) + histogram_.capacity() * sizeof(uint32_t);
  }
  // The most frames of an interval whose work times are kept exactly.
  static constexpr size_t kExactFrames = size_t{1} << 16;
  // The JSON of the last report (tests).
  const std::string& json() const { return json_; }
  // The error of the last failed file write, "" if none (logged once by the caller).
  const std::string& fileError() const { return fileError_; }

 private:
  std::string file_, tmpFile_;
  int64_t interval_ns_ = 0;
  int64_t lastReport_ns_ = 0;
  // Current interval.
  // Work times of the interval's first kExactFrames frames (exact percentiles), and of every
  // frame in a log-linear histogram of microseconds (kSubBuckets per power of two).
  static constexpr int kSubBits = 10;
  static constexpr uint64_t kSubBuckets = uint64_t{1} << kSubBits;
  static constexpr int kMaxShift = 30;  // values up to 2^41 us (25 days) and beyond clamp there
  static constexpr size_t kHistogramBins = static_cast<size_t>((kMaxShift + 2) * kSubBuckets);
  static size_t histogramBin(double work_ms);
  static double histogramValue_ms(size_t bin);
  double histogramPercentile(double p) const;
  std::vector<double> work_ms_;
  std::vector<uint32_t> histogram_;
  double workMax_ms_ = 0.0;         // of every frame of the interval (work_ms_ may have dropped some)
  std::array<double, kPhaseCount> phaseMax_ms_{};
  int64_t overruns_ = 0, missed_ = 0, frames_ = 0;
  uint64_t triangles_ = 0;
  // Totals.
  int64_t totalFrames_ = 0, totalOverruns_ = 0, totalMissed_ = 0, lastFrame_ = -1;
  std::string json_, line_, fileError_;
};

}  // namespace ig
