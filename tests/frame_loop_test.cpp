// Frame pacing with a fake clock: absolute deadlines, phase times, overrun and missed-slot
// accounting, free-run. No real time passes in these tests. Also the summary and the JSON helpers.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include <fcntl.h>
#include <unistd.h>

#include "ig/clock.h"
#include "ig/frame_loop.h"
#include "ig/json.h"
#include "ig/stats.h"

using namespace ig;

namespace {
constexpr int64_t kMs = 1'000'000;
}

TEST(FramePacer, FramesStartOnAbsoluteSlotsWithoutDrift) {
  FakeClock clock;
  FramePacer pacer(clock, 50.0, false);  // 20 ms period
  const int64_t t0 = clock.now_ns();
  for (int i = 0; i < 100; ++i) {
    EXPECT_EQ(pacer.beginFrame(), i);
    EXPECT_EQ(clock.now_ns(), t0 + i * 20 * kMs);  // exactly on the slot, frame after frame
    clock.advance_ns(7 * kMs + 333);              // odd work times must not accumulate drift
    const FrameTiming& t = pacer.endFrame();
    EXPECT_FALSE(t.overrun);
    EXPECT_EQ(t.missedSlots, 0);
  }
  EXPECT_EQ(pacer.frames(), 100);
  EXPECT_EQ(pacer.overruns(), 0);
}

TEST(FramePacer, PhaseTimesAddUpToWork) {
  FakeClock clock;
  FramePacer pacer(clock, 60.0, false);
  pacer.beginFrame();
  clock.advance_ns(1 * kMs);
  pacer.endPhase(Phase::Input);
  clock.advance_ns(2 * kMs);
  pacer.endPhase(Phase::Lod);
  clock.advance_ns(3 * kMs);
  pacer.endPhase(Phase::Submit);
  clock.advance_ns(4 * kMs);
  pacer.endPhase(Phase::GpuFinish);
  clock.advance_ns(5 * kMs);
  pacer.endPhase(Phase::Present);
  const FrameTiming& t = pacer.endFrame();
  EXPECT_DOUBLE_EQ(t.phase_ms[0], 1.0);
  EXPECT_DOUBLE_EQ(t.phase_ms[1], 2.0);
  EXPECT_DOUBLE_EQ(t.phase_ms[2], 3.0);
  EXPECT_DOUBLE_EQ(t.phase_ms[3], 4.0);
  EXPECT_DOUBLE_EQ(t.phase_ms[4], 5.0);
  EXPECT_DOUBLE_EQ(t.work_ms, 15.0);
}

TEST(FramePacer, OverrunSkipsMissedSlotsAndStaysPhaseLocked) {
  FakeClock clock;
  FramePacer pacer(clock, 100.0, false);  // 10 ms
  const int64_t t0 = clock.now_ns();
  EXPECT_EQ(pacer.beginFrame(), 0);
  clock.advance_ns(25 * kMs);  // runs past slots 1 and 2
  const FrameTiming& t = pacer.endFrame();
  EXPECT_TRUE(t.overrun);
  EXPECT_EQ(t.missedSlots, 2);
  EXPECT_EQ(pacer.beginFrame(), 3);
  EXPECT_EQ(clock.now_ns(), t0 + 30 * kMs);  // next frame on the slot grid, not at 25 ms
  clock.advance_ns(2 * kMs);
  EXPECT_FALSE(pacer.endFrame().overrun);
  EXPECT_EQ(pacer.overruns(), 1);
  EXPECT_EQ(pacer.missedSlots(), 2);
  EXPECT_EQ(pacer.frames(), 2);
}

TEST(FramePacer, WorkEndingExactlyOnTheNextSlotIsNotAnOverrun) {
  FakeClock clock;
  FramePacer pacer(clock, 100.0, false);
  pacer.beginFrame();
  clock.advance_ns(10 * kMs);
  EXPECT_FALSE(pacer.endFrame().overrun);
  pacer.beginFrame();
  clock.advance_ns(10 * kMs + 1);
  EXPECT_TRUE(pacer.endFrame().overrun);
}

// The same rule a few slots on: work that ends exactly on slot 3 ran past slots 1 and 2 only;
// slot 3 starts then, without sleeping a whole period and counting it as missed.
TEST(FramePacer, WorkEndingExactlyOnALaterSlotStartsThatSlot) {
  FakeClock clock;
  FramePacer pacer(clock, 100.0, false);  // 10 ms
  const int64_t t0 = clock.now_ns();
  EXPECT_EQ(pacer.beginFrame(), 0);
  clock.advance_ns(30 * kMs);
  const FrameTiming& t = pacer.endFrame();
  EXPECT_TRUE(t.overrun);
  EXPECT_EQ(t.missedSlots, 2);
  EXPECT_EQ(pacer.beginFrame(), 3);
  EXPECT_EQ(clock.now_ns(), t0 + 30 * kMs);  // no sleep: slot 3 is now
  EXPECT_EQ(pacer.missedSlots(), 2);
}

TEST(FramePacer, LateWakeUpIsReportedAsLateness) {
  FakeClock clock;
  FramePacer pacer(clock, 100.0, false);
  pacer.beginFrame();
  clock.advance_ns(1 * kMs);
  pacer.endFrame();
  // Simulate the scheduler waking us 3 ms late: sleep returns at the slot, then time passes.
  struct LateClock final : Clock {
    FakeClock& inner;
    explicit LateClock(FakeClock& c) : inner(c) {}
    int64_t now_ns() const override { return inner.now_ns(); }
    void sleepUntil_ns(int64_t d) override { inner.sleepUntil_ns(d + 3 * kMs); }
  } late(clock);
  FramePacer p2(late, 100.0, false);
  p2.beginFrame();
  p2.endFrame();
  p2.beginFrame();
  EXPECT_EQ(p2.endFrame().lateness_ns, 3 * kMs);
}

TEST(FramePacer, TimeBetweenFramesIsSeparatedFromALateWakeUp) {
  FakeClock clock;
  FramePacer pacer(clock, 100.0, false);  // 10 ms
  pacer.beginFrame();
  EXPECT_EQ(pacer.endFrame().between_ms, 0.0);  // no frame before the first
  clock.advance_ns(2 * kMs);                    // igd's own work after the frame (stats, reload)
  pacer.beginFrame();
  clock.advance_ns(1 * kMs);
  const FrameTiming& t = pacer.endFrame();
  EXPECT_DOUBLE_EQ(t.between_ms, 2.0);
  EXPECT_EQ(t.lateness_ns, 0);                   // it fit before the slot
  clock.advance_ns(15 * kMs);                    // between-frames work runs past slot 2
  pacer.beginFrame();
  const FrameTiming& u = pacer.endFrame();
  EXPECT_DOUBLE_EQ(u.between_ms, 15.0);
  EXPECT_EQ(u.lateness_ns, 6 * kMs);             // frame 1 ended at 11 ms, +15 = 6 ms after slot 2
}

TEST(FramePacer, FreeRunNeverSleepsButStillCountsSlowFrames) {
  FakeClock clock;
  FramePacer pacer(clock, 60.0, true);
  for (int i = 0; i < 10; ++i) {
    EXPECT_EQ(pacer.beginFrame(), i);
    clock.advance_ns(i == 4 ? 30 * kMs : 1 * kMs);
    pacer.endFrame();
  }
  EXPECT_EQ(clock.sleeps(), 0);
  EXPECT_EQ(pacer.overruns(), 1);
  EXPECT_EQ(pacer.missedSlots(), 0);
  EXPECT_NEAR(pacer.slotTime_s(9), 9.0 / 60.0, 1e-9);
}

TEST(Stats, SummaryPercentilesAndFixedCapacity) {
  SummaryCollector c(100);
  for (int i = 1; i <= 150; ++i) {  // only the last 100 (51..150) are kept
    FrameRecord r;
    r.timing.work_ms = i;
    r.triangles = static_cast<uint64_t>(i) * 10;
    c.add(r);
  }
  const RunSummary s = c.summarize(3, 4);
  EXPECT_EQ(s.frames, 150);  // every frame counts; the percentiles cover the last 100
  EXPECT_EQ(s.overruns, 3);
  EXPECT_EQ(s.missedSlots, 4);
  EXPECT_DOUBLE_EQ(s.workMs_p50, 100.0);
  EXPECT_DOUBLE_EQ(s.workMs_p99, 149.0);
  EXPECT_DOUBLE_EQ(s.workMs_max, 150.0);
  EXPECT_EQ(s.triangles_p50, 1000u);
}

// The summary igd prints at exit: frames and overruns count the whole run, and so must the
// work maximum and mean; only the percentiles come from the last frames kept (a service that
// runs for hours keeps the last 10 minutes). A 200 ms stall in the first hour is the run's max.
TEST(Stats, SummaryMaxAndMeanCoverEveryFrame) {
  SummaryCollector c(100);
  for (int i = 0; i < 300; ++i) {
    FrameRecord r;
    r.timing.work_ms = i == 0 ? 200.0 : 10.0;
    c.add(r);
  }
  const RunSummary s = c.summarize(0, 0);
  EXPECT_EQ(s.frames, 300);
  EXPECT_DOUBLE_EQ(s.workMs_max, 200.0);
  EXPECT_DOUBLE_EQ(s.workMs_mean, (200.0 + 299 * 10.0) / 300.0);
  EXPECT_DOUBLE_EQ(s.workMs_p50, 10.0);
}

// igd sizes the collector from frame.frames: a huge count (frames = 1e11 is a valid config)
// must neither reserve terabytes (std::bad_alloc at start-up) nor cap the frame count.
TEST(Stats, SummaryCapacityIsBoundedAndFramesAreCounted) {
  SummaryCollector c(100'000'000'000);
  const size_t n = SummaryCollector::kMaxCapacity + 5;
  for (size_t i = 0; i < n; ++i) {
    FrameRecord r;
    r.timing.work_ms = 1.0;
    c.add(r);
  }
  EXPECT_EQ(c.summarize(0, 0).frames, static_cast<int64_t>(n));
}

TEST(FramePacer, WorkBudgetDefinesOverrunsWithoutChangingPacing) {
  FakeClock clock;
  FramePacer pacer(clock, 50.0, false, 8.0);  // 20 ms period, 8 ms work budget
  pacer.beginFrame();
  clock.advance_ns(9 * kMs);  // over budget, well inside the period
  const FrameTiming& t = pacer.endFrame();
  EXPECT_TRUE(t.overrun);
  EXPECT_EQ(t.missedSlots, 0);
  EXPECT_EQ(pacer.beginFrame(), 1);  // the next slot is still used
  clock.advance_ns(7 * kMs);
  EXPECT_FALSE(pacer.endFrame().overrun);
  EXPECT_EQ(pacer.overruns(), 1);
}

// The JSON that igbench and igtool print by hand: names and paths from outside are escaped, and a
// number that is not finite prints null (JSON has no NaN or Infinity).
TEST(Json, StringsAreEscapedAndNonFiniteNumbersAreNull) {
  EXPECT_EQ(ig::jsonString("scene \"a\\b\"\n\t"), "\"scene \\\"a\\\\b\\\"\\u000a\\u0009\"");
  EXPECT_EQ(ig::jsonEscape("llvmpipe (LLVM 15.0.6, 256 bits)"), "llvmpipe (LLVM 15.0.6, 256 bits)");
  EXPECT_EQ(ig::jsonNumber(std::nan(""), 2), "null");
  EXPECT_EQ(ig::jsonNumber(-std::numeric_limits<double>::infinity(), 2), "null");
  EXPECT_EQ(ig::jsonNumber(1.005, 1), "1.0");
  EXPECT_EQ(ig::jsonNumber(2.5, 2), "2.50");
}

// A stats file the disk refuses (full, I/O error) is not silently empty: opening reports a
// header that cannot be written, and a write error later in the run (stdio reports it when
// its buffer is flushed, at the latest in close()) is kept for igd to log. /dev/full fails
// every write with ENOSPC.
TEST(Stats, WriteErrorsOfTheStatsFileAreReported) {
  ASSERT_TRUE(std::filesystem::exists("/dev/full"));  // Linux always has it
  StatsWriter w;
  std::string error;
  EXPECT_FALSE(w.open("/dev/full", StatsFormat::Csv, "", error));
  EXPECT_NE(error.find("/dev/full"), std::string::npos) << error;

  // A write that fails after a good open: the file's descriptor is pointed at /dev/full.
  const std::string file =
      (std::filesystem::temp_directory_path() / ("igd_stats_full_" + std::to_string(::getpid()) + ".csv")).string();
  StatsWriter late;
  error.clear();
  ASSERT_TRUE(late.open(file, StatsFormat::JsonLines, "\"layers\":[]", error)) << error;
  const int full = ::open("/dev/full", O_WRONLY);
  ASSERT_GE(full, 0);
  // Find the writer's descriptor by its path and put /dev/full in its place.
  bool swapped = false;
  for (int fd = 3; fd < 1024 && !swapped; ++fd) {
    char link[64], target[4096];
    std::snprintf(link, sizeof link, "/proc/self/fd/%d", fd);
    const ssize_t n = ::readlink(link, target, sizeof target - 1);
    if (n <= 0) continue;
    target[n] = '\0';
    if (std::filesystem::path(target) == std::filesystem::canonical(file)) swapped = ::dup2(full, fd) == fd;
  }
  ::close(full);
  ASSERT_TRUE(swapped);
  FrameRecord r;
  late.write(r);  // the first frame is written out at once (below): the disk refuses it
  EXPECT_NE(late.error().find(file), std::string::npos) << late.error();  // known during the run
  EXPECT_FALSE(late.close());
  std::filesystem::remove(file);
}

// The lines reach the file every 0.25 s of frame time, not only when stdio's 4 KiB buffer fills
// (~25 frames) or at close: a process the watchdog kills keeps the frames before its hang.
TEST(Stats, LinesReachTheFileWithinAQuarterSecondOfFrameTime) {
  const std::string file =
      (std::filesystem::temp_directory_path() / ("igd_stats_flush_" + std::to_string(::getpid()) + ".csv")).string();
  StatsWriter w;
  std::string error;
  ASSERT_TRUE(w.open(file, StatsFormat::Csv, "", error)) << error;
  auto lines = [&] {
    std::ifstream in(file);
    std::string line;
    int n = 0;
    while (std::getline(in, line)) ++n;
    return n - 1;  // the header
  };
  FrameRecord r;
  for (int i = 0; i < 10; ++i) {  // 30 Hz: 0 ... 300 ms
    r.timing.frame = i;
    r.timing.start_ns = int64_t{i} * 33'333'333;
    w.write(r);
  }
  EXPECT_EQ(lines(), 9) << "frames 0 ... 8 (flushed at frame 0 and at frame 8, 267 ms)";
  EXPECT_TRUE(w.close());
  EXPECT_EQ(lines(), 10);
  std::filesystem::remove(file);
}

// The percentile helper of the benchmarks' summaries on hand-made numbers: nearest rank (what the
// docs and scripts/plot_frame_stats.py assume), no interpolation.
TEST(Stats, PercentileIsNearestRank) {
  EXPECT_EQ(percentile({}, 50), 0.0);
  EXPECT_EQ(percentile({7.0}, 50), 7.0);
  EXPECT_EQ(percentile({7.0}, 99), 7.0);
  // Unsorted input; rank ceil(p / 100 * n), at least 1.
  const std::vector<double> v{5, 1, 4, 2, 3};
  EXPECT_EQ(percentile(v, 0), 1.0);
  EXPECT_EQ(percentile(v, 20), 1.0);
  EXPECT_EQ(percentile(v, 21), 2.0);
  EXPECT_EQ(percentile(v, 50), 3.0);
  EXPECT_EQ(percentile(v, 99), 5.0);
  EXPECT_EQ(percentile(v, 100), 5.0);
  // Even count: p50 is the lower middle value (no interpolation).
  EXPECT_EQ(percentile({1, 2, 3, 4}, 50), 2.0);
  std::vector<double> hundred;
  for (int i = 100; i >= 1; --i) hundred.push_back(i);
  EXPECT_EQ(percentile(hundred, 50), 50.0);
  EXPECT_EQ(percentile(hundred, 99), 99.0);
  EXPECT_EQ(percentile(hundred, 1), 1.0);
  std::vector<double> thousand;
  for (int i = 1; i <= 1000; ++i) thousand.push_back(i);
  EXPECT_EQ(percentile(thousand, 99), 990.0);
  EXPECT_EQ(percentile(thousand, 50), 500.0);
}
