// Frame pacing with a fake clock: absolute deadlines, phase times, overrun and missed-slot
// accounting, free-run. No real time passes in these tests. Also the summary and the JSON helpers.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <fcntl.h>
#include <unistd.h>

#include "ig/clock.h"
#include "ig/bench_terrain.h"
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

// Slots are k / rate, not k times a period rounded to the nanosecond: at 600 Hz that period
// (1666667 ns) put the slots 0.33 ns a frame late, 17 ms after a day, while the replay and the
// geomorphing clock (slotTime_s) and the live recording's stamps count k / rate.
TEST(FramePacer, SlotTimesDoNotAccumulateThePeriodsRounding) {
  for (const double rate : {60.0, 600.0, 90.0}) {
    SCOPED_TRACE(rate);
    FakeClock clock;
    FramePacer pacer(clock, rate, false);
    const int64_t t0 = clock.now_ns();
    const int64_t day = std::llround(86400.0 * rate);  // 5,184,000 frames at 60 Hz
    EXPECT_NEAR(static_cast<double>(pacer.slotTime_ns(day)), 86400e9, 1.0);
    ASSERT_EQ(pacer.beginFrame(), 0);
    // A frame that ends just before the slot a day later: the loop skips to that slot and
    // starts it at its time.
    clock.advance_ns(86'400'000'000'000 - 1);
    const FrameTiming& t = pacer.endFrame();
    EXPECT_EQ(t.missedSlots, day - 1);
    ASSERT_EQ(pacer.beginFrame(), day);
    EXPECT_EQ(clock.now_ns() - t0, 86'400'000'000'000)
        << "the slot a day later starts " << (clock.now_ns() - t0 - 86'400'000'000'000) << " ns late";
    // And frame by frame from there.
    clock.advance_ns(1000);
    pacer.endFrame();
    ASSERT_EQ(pacer.beginFrame(), day + 1);
    EXPECT_NEAR(static_cast<double>(clock.now_ns() - t0), 86400e9 + 1e9 / rate, 1.0);
  }
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

// Host pacing (CIGI synchronous mode): the loop runs free and waits for the host's next message
// before each frame. That wait is no work of the frame: a frame that waited most of a period
// for the host and then worked 3 ms is no overrun, and the wait is not the frame thread's own
// time between frames either.
TEST(FramePacer, HostWaitBeforeAFrameIsNeitherWorkNorTimeBetweenFrames) {
  FakeClock clock;
  FramePacer pacer(clock, 100.0, true);  // 10 ms period, host-paced: free-run
  int waits = 0;
  pacer.setWait([&](int64_t) {
    ++waits;
    clock.advance_ns(9 * kMs);  // the host answers 9 ms later
    return true;
  });
  const int64_t t0 = clock.now_ns();
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(pacer.beginFrame(), i);
    clock.advance_ns(3 * kMs);
    const FrameTiming& t = pacer.endFrame();
    EXPECT_DOUBLE_EQ(t.work_ms, 3.0) << "frame " << i;
    EXPECT_FALSE(t.overrun) << "frame " << i;
    EXPECT_EQ(t.start_ns, (i + 1) * 9 * kMs + i * 3 * kMs) << "frame " << i;
    EXPECT_DOUBLE_EQ(t.between_ms, 0.0) << "frame " << i;
  }
  EXPECT_EQ(waits, 3);
  EXPECT_EQ(clock.now_ns(), t0 + 36 * kMs);
  EXPECT_EQ(clock.sleeps(), 0);
  EXPECT_EQ(pacer.overruns(), 0);
}

// A wait that says "do not start" (a stop request while sleeping towards a long period's slot)
// starts no frame: beginFrame returns -1, nothing is counted, and the pacer does not sleep on.
TEST(FramePacer, AWaitThatRefusesStartsNoFrame) {
  FakeClock clock;
  FramePacer pacer(clock, 0.1, false);  // 10 s period
  bool stop = false;
  pacer.setWait([&](int64_t slot_ns) {
    if (slot_ns - clock.now_ns() > 1'000 * kMs) clock.sleepUntil_ns(clock.now_ns() + 1'000 * kMs);
    return !stop;
  });
  const int64_t t0 = clock.now_ns();
  EXPECT_EQ(pacer.beginFrame(), 0);
  pacer.endFrame();
  stop = true;
  EXPECT_EQ(pacer.beginFrame(), -1);
  EXPECT_EQ(clock.now_ns(), t0 + 1'000 * kMs);  // one piece, not the whole period
  EXPECT_EQ(pacer.frames(), 1);
  stop = false;
  EXPECT_EQ(pacer.beginFrame(), 1);  // the slot is still the next one
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

namespace {
// A fresh temporary folder for one stats-rotation test.
std::filesystem::path statsDir(const char* name) {
  const auto d = std::filesystem::temp_directory_path() / (std::string("igd_rot_") + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}
std::vector<std::string> fileLines(const std::filesystem::path& f) {
  std::ifstream in(f);
  std::vector<std::string> lines;
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}
FrameRecord frameAt(int64_t i) {
  FrameRecord r;
  r.timing.frame = i;
  r.timing.start_ns = i * 33'333'333;
  return r;
}
}  // namespace

// [stats] max_mb, keep: the file is rotated at the size limit (after the line that reaches it),
// every file starts with the header, no line is split, and only `keep` old files stay (the
// oldest deleted). A CSV line is ~170 bytes, the header ~370: a 1000-byte limit holds a few lines.
TEST(StatsRotation, RotatesAtTheSizeLimitKeepingKeepFiles) {
  const auto dir = statsDir("size");
  const std::string file = (dir / "s.csv").string();
  StatsWriter w;
  std::string error;
  ASSERT_TRUE(w.open(file, StatsFormat::Csv, "", error, StatsRotation{1000, 2})) << error;
  const int n = 60;
  for (int i = 0; i < n; ++i) w.write(frameAt(i));
  EXPECT_TRUE(w.close()) << w.error();
  EXPECT_EQ(w.rotateError(), "");
  EXPECT_TRUE(std::filesystem::exists(file + ".1"));
  EXPECT_TRUE(std::filesystem::exists(file + ".2"));
  EXPECT_FALSE(std::filesystem::exists(file + ".3"));  // keep = 2: the oldest were deleted
  // Newest first: file, file.1, file.2 hold consecutive frames ending at n - 1; each file starts
  // with the header and holds whole lines (33 fields), at most one line past the limit.
  int64_t expected = n - 1;
  for (const std::string& f : {file, file + ".1", file + ".2"}) {
    const auto lines = fileLines(f);
    ASSERT_GE(lines.size(), f == file ? 1u : 2u) << f;  // the current file may hold only its header
    EXPECT_EQ(lines[0].rfind("frame,t_ms,", 0), 0u) << f;
    EXPECT_LT(std::filesystem::file_size(f), 1000u + 400u) << f;
    for (size_t k = lines.size() - 1; k >= 1; --k, --expected) {
      EXPECT_EQ(std::count(lines[k].begin(), lines[k].end(), ','), 32) << f << ": " << lines[k];
      EXPECT_EQ(std::stoll(lines[k]), expected) << f << ": " << lines[k];
    }
  }
  EXPECT_GT(expected, 0);  // frame 0 was in a file that keep = 2 deleted
  std::filesystem::remove_all(dir);
}

// A restart (open() again) moves the previous run's file to file.1 instead of truncating it;
// JSON-lines files start with their "run" object after a rotation too.
TEST(StatsRotation, StartUpMovesThePreviousRunsFile) {
  const auto dir = statsDir("start");
  const std::string file = (dir / "s.jsonl").string();
  std::string error;
  for (int run = 0; run < 3; ++run) {
    StatsWriter w;
    ASSERT_TRUE(w.open(file, StatsFormat::JsonLines, "\"run_no\":" + std::to_string(run), error, StatsRotation{0, 3}))
        << error;
    for (int i = 0; i < 3; ++i) w.write(frameAt(i));
    EXPECT_TRUE(w.close());
  }
  EXPECT_EQ(fileLines(file).front(), "{\"run\":{\"run_no\":2}}");
  EXPECT_EQ(fileLines(file + ".1").front(), "{\"run\":{\"run_no\":1}}");
  EXPECT_EQ(fileLines(file + ".2").front(), "{\"run\":{\"run_no\":0}}");
  EXPECT_EQ(fileLines(file + ".1").size(), 4u);
  // keep = 0 (and the default): the old behaviour, truncated, no old files.
  StatsWriter w;
  ASSERT_TRUE(w.open(file, StatsFormat::JsonLines, "\"run_no\":9", error));
  EXPECT_TRUE(w.close());
  EXPECT_EQ(fileLines(file).size(), 1u);
  EXPECT_EQ(fileLines(file + ".1").front(), "{\"run\":{\"run_no\":1}}");
  std::filesystem::remove_all(dir);
}

// A rename that is refused (here: file.1 is a non-empty folder, which refuses as root too) is
// reported once, naming the file; the writer goes on writing every line to the file it has, and
// the lines still reach the file within 0.25 s of frame time.
TEST(StatsRotation, ARefusedRenameIsReportedAndWritingGoesOn) {
  const auto dir = statsDir("refused");
  const std::string file = (dir / "s.csv").string();
  std::filesystem::create_directories(file + ".1/x");
  StatsWriter w;
  std::string error;
  ASSERT_TRUE(w.open(file, StatsFormat::Csv, "", error, StatsRotation{1000, 1})) << error;
  for (int i = 0; i < 30; ++i) w.write(frameAt(i));
  EXPECT_NE(w.rotateError().find(file), std::string::npos) << w.rotateError();
  EXPECT_EQ(w.error(), "");
  EXPECT_GE(fileLines(file).size(), 26u) << "the header and frames 0 ... 24 (flushed at 0.8 s)";
  EXPECT_TRUE(w.close());
  EXPECT_EQ(fileLines(file).size(), 31u);
  EXPECT_TRUE(std::filesystem::is_directory(file + ".1"));
  std::filesystem::remove_all(dir);
}

// The benchmarks' median is the nearest-rank p50 of the percentile helper: of an even count the
// lower middle value (igbench hdlod --quick's 2 frames: the faster; its own median took the upper).
TEST(Stats, MedianIsTheNearestRankP50) {
  EXPECT_EQ(median({}), 0.0);
  EXPECT_EQ(median({7.0}), 7.0);
  EXPECT_EQ(median({9.0, 3.0}), 3.0);
  EXPECT_EQ(median({4, 1, 3, 2}), 2.0);
  EXPECT_EQ(median({5, 1, 4, 2, 3}), 3.0);
  const std::vector<double> v{8, 6, 2, 4};
  EXPECT_EQ(median(v), percentile(v, 50));
}

// igbench terrain's per-method percentiles cover the same frames: frame 0 (the start-up build,
// startup_update_ms) is in none of them. triangles_p50 took frame 0 (a mesh built from the base
// triangles, or under Deferred's visit budget a partial one) while update_ms left it out.
TEST(Stats, TerrainFlightPercentilesLeaveOutTheStartUpFrame) {
  TerrainFlightSamples s;
  s.addUpdate(0, 50.0, 50.0, 10.0, 100.0, 7.0);  // the start-up: few triangles, much work left
  s.addEmit(0, 5.0, 8.0);
  s.addUpdate(1, 1.0, 1.0, 1000.0, 20.0, 0.0);  // the one steady frame of the flight
  s.addEmit(1, 0.5, 800.0);
  for (const auto* v : {&s.update_ms, &s.cpu_ms, &s.triangles, &s.visible, &s.emit_ms, &s.visits, &s.pending})
    EXPECT_EQ(v->size(), 1u);
  EXPECT_EQ(percentile(s.triangles, 50), 1000.0);
  EXPECT_EQ(percentile(s.visible, 50), 800.0);
  EXPECT_EQ(percentile(s.visits, 50), 20.0);
  EXPECT_EQ(percentile(s.pending, 99), 0.0);
  EXPECT_EQ(percentile(s.update_ms, 99), 1.0);
}
