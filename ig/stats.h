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
  // The far plane the frame was drawn with (the host's, or where the fog is opaque: [fog] cull)
  // and the fog's visibility (the host's or the scene's; NaN without fog).
  double far_m = kStatsNaN;
  double fogVisibility_m = kStatsNaN;
};

// Size-based rotation of the stats file ([stats] max_mb, keep). The file is rotated (file ->
// file.1 -> ... -> file.<keep>, the oldest replaced) when it reaches maxBytes (after the line that
// reaches it: a line is never split across files; each new file starts with the CSV header or
// the JSONL "run" object) and at open(), so a restart keeps the previous run's file as file.1.
// keep = 0: no old files (at the limit the file starts again empty; open() truncates).
// maxBytes = 0: no size limit (open() still rotates when keep > 0). Only regular files rotate
// (/dev/null, a FIFO: never). A rotation is renames, a close and an open (and the few path
// strings it allocates, the only allocation of write()): it does not block the frame for long.
struct StatsRotation {
  uint64_t maxBytes = 0;
  int keep = 0;
};

class StatsWriter {
 public:
  StatsWriter() = default;
  ~StatsWriter();
  StatsWriter(const StatsWriter&) = delete;
  StatsWriter& operator=(const StatsWriter&) = delete;
  // Opens the file and writes the header (CSV) or a first "run" object (JSONL) with `runInfo`
  // (a JSON object's members, e.g. "\"layers\":[\"terrain\"]"). An existing file is rotated to
  // file.1 first where rotation.keep > 0, else truncated. False with an error naming the file
  // if it cannot be created or the header cannot be written (a full disk); a rotation that fails
  // is not (see rotateError()).
  bool open(const std::string& file, StatsFormat format, const std::string& runInfo, std::string& error,
            StatsRotation rotation = {});
  void write(const FrameRecord& r);
  // Flushes and closes the file; false if that or any earlier write failed (see error()).
  bool close();
  // The first write error ("" if none): a full disk or an I/O error loses lines; the stdio
  // buffer reports it when it is flushed, so it may show a few frames late, or only at close().
  const std::string& error() const { return error_; }
  // The first rotation failure ("" if none), naming the file: a rename refused (a read-only
  // folder). The writer goes on writing to the file it has (which then grows past the limit;
  // at open(): the old file is truncated as without rotation) and tries again at the next limit.
  const std::string& rotateError() const { return rotateError_; }

 private:
  void noteError();
  bool writeHeader();
  bool renameOld();   // file -> file.1 -> ... -> file.<keep>; false (rotateError_ set) if refused
  void rollOver();    // at the size limit
  StatsRotation rotation_;
  bool regular_ = false;       // a regular file (rotation applies)
  uint64_t bytes_ = 0;         // written to the current file
  uint64_t rotateAt_ = 0;      // the size at which the next rotation is tried
  std::string runInfo_;
  std::string rotateError_;
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
  // The capacity for a run of `frames` frames (0 = until stopped): frames, at most kMaxCapacity.
  static size_t capacityFor(int64_t frames);
  // Grows the capacity (never shrinks it; at most kMaxCapacity), keeping the frames added: a
  // reload that raises frame.frames keeps the percentiles over the last kMaxCapacity frames of
  // the run, not the start-up frames' count. Allocates: call between frames, not per frame.
  void grow(size_t capacity);
  void add(const FrameRecord& r);
  RunSummary summarize(int64_t overruns, int64_t missedSlots) const;

 private:
  std::vector<FrameRecord> records_;
  size_t capacity_;
  size_t next_ = 0;
  int64_t added_ = 0;
  double workMax_ms_ = 0.0, workSum_ms_ = 0.0;  // of every frame added (not only those kept)
};

// Nearest-rank percentile of the values (0 for none): the value of rank ceil(p / 100 * n), at
// least 1; no interpolation.
double percentile(std::vector<double> values, double p);
// The median of the benchmarks' summaries: percentile(values, 50), the lower middle value of an
// even count (of two frames: the faster); 0 for none.
double median(std::vector<double> values);

}  // namespace ig
