// Per-frame statistics: one line per frame, CSV or JSON lines, plus the run summary
// (percentiles) that igd prints at exit and igbench reports. Storage for the summary is
// reserved at start-up; recording a frame does not allocate.
#pragma once

#include <cstdint>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

#include "ig/config.h"
#include "ig/frame_loop.h"

namespace ig {

inline constexpr double kStatsNaN = std::numeric_limits<double>::quiet_NaN();

struct FrameRecord {
  FrameTiming timing;
  double period_ms = 0.0;       // the frame period (1000 / rate_hz)
  uint64_t triangles = 0;
  uint32_t drawCalls = 0;
  uint32_t passes = 0;          // render passes this frame (one per layer the scene has)
  uint64_t uploads = 0;         // triangles written to GPU buffers this frame (changed geometry)
  uint64_t hostFrame = 0;
  double simTime_s = 0.0;
  double eyeEast_m = 0.0;       // eyepoint in the scene's local ENU frame
  double eyeNorth_m = 0.0;
  double eyeHeight_m = 0.0;     // height above the ENU origin
  double heading_deg = 0.0;
  bool hostLost = false;        // no valid host input for longer than [host] link_timeout_s
  // The frame governor's choices this frame was drawn with; NaN where a layer is absent or not
  // steered (no governor).
  double predicted_ms = kStatsNaN;        // the governor's prediction of this frame's work
  double terrainTolerance_px = kStatsNaN;
  double forestNear_m = kStatsNaN;        // 3D trees drawn up to here
  double forestLayers = kStatsNaN;        // shell layers drawn
  double hdlodTolerance_px = kStatsNaN;
  double cellsVoxelBudget = kStatsNaN;    // this frame's voxel budget (the knob, capped by the load cap)
};

class StatsWriter {
 public:
  StatsWriter() = default;
  ~StatsWriter();
  StatsWriter(const StatsWriter&) = delete;
  StatsWriter& operator=(const StatsWriter&) = delete;
  // Opens (truncates) the file and writes the header (CSV) or a first "run" object (JSONL)
  // with `runInfo` (a JSON object's members, e.g. "\"layers\":[\"terrain\"]"). False with an
  // error naming the file if it cannot be created or the header cannot be written (a full disk).
  bool open(const std::string& file, StatsFormat format, const std::string& runInfo, std::string& error);
  void write(const FrameRecord& r);
  // Flushes and closes the file; false if that or any earlier write failed (see error()).
  bool close();
  // The first write error ("" if none): a full disk or an I/O error loses lines; the stdio
  // buffer reports it when it is flushed, so it may show a few frames late, or only at close().
  const std::string& error() const { return error_; }

 private:
  void noteError();
  static constexpr int64_t kFlushEvery_ns = 250'000'000;  // of frame time (FrameTiming::start_ns)
  FILE* file_ = nullptr;
  int64_t lastFlush_ns_ = INT64_MIN / 2;  // the first frame is flushed
  std::string path_;
  StatsFormat format_ = StatsFormat::Csv;
  std::string error_;
};

struct RunSummary {
  int64_t frames = 0;           // every frame of the run (percentiles: the last kMaxCapacity;
                                // workMs_max and workMs_mean: every frame)
  int64_t overruns = 0;
  int64_t missedSlots = 0;
  double workMs_p50 = 0, workMs_p99 = 0, workMs_max = 0, workMs_mean = 0;
  std::array<double, kPhaseCount> phaseMs_p50{};
  uint64_t triangles_p50 = 0;
  uint32_t drawCalls_p50 = 0;
};

// Collects frames for percentiles; capacity fixed at construction (older frames beyond it
// are dropped from the percentiles, never reallocated; RunSummary::frames still counts every
// frame added).
class SummaryCollector {
 public:
  // The most frames kept for the percentiles (10 minutes at 60 Hz, about 8 MB).
  static constexpr size_t kMaxCapacity = 36000;
  explicit SummaryCollector(size_t capacity);
  void add(const FrameRecord& r);
  RunSummary summarize(int64_t overruns, int64_t missedSlots) const;

 private:
  std::vector<FrameRecord> records_;
  size_t capacity_;
  size_t next_ = 0;
  int64_t added_ = 0;
  double workMax_ms_ = 0.0, workSum_ms_ = 0.0;  // of every frame added (not only those kept)
};

double percentile(std::vector<double> values, double p);

}  // namespace ig
