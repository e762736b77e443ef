// ig::WorkerPair (ig/worker_pair.h): the chunk contract of lod::ChunkRunner on two real threads,
// and the cells selection run on it choosing exactly as on one thread.
#include "ig/worker_pair.h"

#include <gtest/gtest.h>

#include <pthread.h>
#include <sched.h>

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "lod/cells.h"
#include "lod/cells_select.h"
#include "cells_random_tree.h"

namespace {

using namespace ig;

struct Record {
  std::vector<std::atomic<int>> runs;
  std::vector<uint32_t> order[2];  // chunks in the order each worker ran them
  int sleepUs = 0;
  explicit Record(size_t n) : runs(n) {}
};

void recordChunk(void* ctx, uint32_t chunk, uint32_t worker) {
  Record& r = *static_cast<Record*>(ctx);
  r.runs[chunk].fetch_add(1, std::memory_order_relaxed);
  r.order[worker].push_back(chunk);
  if (r.sleepUs > 0) std::this_thread::sleep_for(std::chrono::microseconds(r.sleepUs));
}

TEST(WorkerPair, EveryChunkOnceCallerFromTheFrontHelperFromTheBack) {
  WorkerPair pair;
  std::mt19937 rng(3);
  for (int pass = 0; pass < 3000; ++pass) {
    const uint32_t n = pass < 300 ? static_cast<uint32_t>(pass % 40) : static_cast<uint32_t>(rng() % 200);
    Record r(n);
    pair.forEach(n, &recordChunk, &r);
    for (uint32_t c = 0; c < n; ++c) ASSERT_EQ(r.runs[c].load(), 1) << "pass " << pass << " chunk " << c;
    // Worker 0: 0, 1, ..., k-1; worker 1: n-1, n-2, ..., k.
    for (size_t i = 0; i < r.order[0].size(); ++i) ASSERT_EQ(r.order[0][i], i) << "pass " << pass;
    for (size_t i = 0; i < r.order[1].size(); ++i) ASSERT_EQ(r.order[1][i], n - 1 - i) << "pass " << pass;
    ASSERT_EQ(r.order[0].size() + r.order[1].size(), n);
  }
}

TEST(WorkerPair, TheHelperTakesChunksOfLongPassesAndSleepsBetween) {
  WorkerPair pair(50);
  uint64_t helper = 0;
  for (int pass = 0; pass < 10; ++pass) {
    Record r(8);
    r.sleepUs = 2000;
    pair.forEach(8, &recordChunk, &r);
    helper += r.order[1].size();
    std::this_thread::sleep_for(std::chrono::milliseconds(5));  // longer than the spin: the helper sleeps
  }
  EXPECT_GT(helper, 0u);
  EXPECT_EQ(pair.helperChunks(), helper);
}

// Runs every pass on a WorkerPair, but the caller's first chunk of a pass waits (up to 5 s) until
// the helper has run one chunk of it, so the helper's share of the work is certain to be exercised
// even when the test machine is too loaded to wake the helper within a short pass.
class HelperTakesPartRunner final : public lod::ChunkRunner {
 public:
  explicit HelperTakesPartRunner(WorkerPair& pair) : pair_(pair) {}
  void forEach(uint32_t chunks, ChunkFn fn, void* ctx) override {
    Pass p{fn, ctx, chunks};
    if (chunks >= 2) ++forcedPasses;
    pair_.forEach(chunks, &HelperTakesPartRunner::run, &p);
    if (chunks >= 2 && p.helperRan.load() == 0) ++passesWithoutHelper;
  }
  uint64_t forcedPasses = 0, passesWithoutHelper = 0;

 private:
  struct Pass {
    ChunkFn fn;
    void* ctx;
    uint32_t chunks;
    std::atomic<uint32_t> helperRan{0};
    bool callerWaited = false;  // touched by worker 0 only
  };
  static void run(void* ctx, uint32_t chunk, uint32_t worker) {
    Pass& p = *static_cast<Pass*>(ctx);
    if (worker == 0 && !p.callerWaited && p.chunks >= 2) {  // a lone chunk is the caller's
      p.callerWaited = true;
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
      while (p.helperRan.load() == 0 && std::chrono::steady_clock::now() < deadline) std::this_thread::yield();
    }
    p.fn(p.ctx, chunk, worker);
    if (worker == 1) p.helperRan.fetch_add(1);
  }
  WorkerPair& pair_;
};

// igd's render thread may run SCHED_FIFO ([service] realtime_priority) pinned to one CPU
// (cpu_affinity) while the helper, made before that, is a normal thread that can share that CPU.
// When the render thread preempts the helper in the middle of a chunk and then waits for it, the
// wait must let the helper run: std::this_thread::yield() gives the CPU only to threads of the
// caller's own priority, so the helper got none until the kernel's real-time throttling (up to
// 0.95 s a second). Needs SCHED_FIFO (igd's tests run as root).
struct Preempted {
  std::atomic<bool> helperStarted{false};
  std::atomic<bool> helperDone{false};
};

void preemptedChunk(void* ctx, uint32_t, uint32_t worker) {
  Preempted& p = *static_cast<Preempted*>(ctx);
  if (worker == 0) {
    // The caller's chunk: sleep until the helper is inside its chunk, then preempt it.
    for (int i = 0; i < 2000 && !p.helperStarted.load(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return;
  }
  p.helperStarted = true;
  // 30 ms of CPU time: the caller wakes from its sleep in the middle of it.
  timespec t0{}, t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t0);
  do {
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  } while ((t.tv_sec - t0.tv_sec) * 1000000000LL + (t.tv_nsec - t0.tv_nsec) < 30000000LL);
  p.helperDone = true;
}

TEST(WorkerPair, ARealtimeCallerLetsAPreemptedHelperFinish) {
  // A watchdog above the caller's priority: if the wait never lets the helper run (no real-time
  // throttling on this kernel), it puts the caller back to normal scheduling after 3 s.
  const pthread_t caller = pthread_self();
  std::mutex m;
  std::condition_variable cv;
  bool finished = false, fired = false;
  std::thread watchdog([&] {
    sched_param hi{};
    hi.sched_priority = 2;
    pthread_setschedparam(pthread_self(), SCHED_FIFO, &hi);
    std::unique_lock<std::mutex> lock(m);
    if (!cv.wait_for(lock, std::chrono::seconds(3), [&] { return finished; })) {
      fired = true;
      sched_param normal{};
      pthread_setschedparam(caller, SCHED_OTHER, &normal);
    }
  });
  cpu_set_t before;
  ASSERT_EQ(pthread_getaffinity_np(caller, sizeof before, &before), 0);
  cpu_set_t one;
  CPU_ZERO(&one);
  for (int c = 0; c < CPU_SETSIZE; ++c) {
    if (CPU_ISSET(c, &before)) {
      CPU_SET(c, &one);
      break;
    }
  }
  ASSERT_EQ(pthread_setaffinity_np(caller, sizeof one, &one), 0);
  double elapsed_s = 0.0;
  Preempted p;
  {
    WorkerPair pair;  // the helper: a normal thread on the caller's one CPU
    sched_param rt{};
    rt.sched_priority = 1;
    const int rc = pthread_setschedparam(caller, SCHED_FIFO, &rt);
    EXPECT_EQ(rc, 0) << "SCHED_FIFO refused: " << std::strerror(rc);
    const auto t0 = std::chrono::steady_clock::now();
    pair.forEach(2, preemptedChunk, &p);
    elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    sched_param normal{};
    pthread_setschedparam(caller, SCHED_OTHER, &normal);
  }
  pthread_setaffinity_np(caller, sizeof before, &before);
  {
    std::lock_guard<std::mutex> lock(m);
    finished = true;
  }
  cv.notify_one();
  watchdog.join();
  EXPECT_TRUE(p.helperStarted.load());
  EXPECT_TRUE(p.helperDone.load());
  EXPECT_FALSE(fired) << "the caller waited for the helper without ever letting it run";
  // About 30 ms of helper work; the throttled wait took about 1 s.
  EXPECT_LT(elapsed_s, 0.5) << "the helper only ran when the kernel throttled the real-time caller";
}

TEST(WorkerPair, CellSelectionOnTwoThreadsChoosesExactlyAsOnOne) {
  std::mt19937 rng(11);
  lod::testing_trees::TreeSpec spec;
  spec.levels = 8;
  spec.minChildren = 3;
  spec.maxChildren = 7;
  spec.leafEarly = 0.05;
  spec.rootEdge_m = 256.0;
  const lod::CellTree t = lod::testing_trees::randomTree(rng, spec);
  ASSERT_GT(t.size(), 8000u);
  WorkerPair pair;
  HelperTakesPartRunner runner(pair);
  lod::CellSelectorConfig two;
  two.runner = &runner;
  two.chunkCells = 8;
  two.maxOperations = 400;
  lod::CellSelectorConfig one;
  one.maxOperations = 400;
  lod::CellSelector a(t, one), b(t, two);
  std::vector<lod::Residency> res(t.size(), lod::Residency::Absent);
  std::vector<int> arrival(t.size(), 0);
  std::vector<lod::CellDraw> da(t.size()), db(t.size());
  std::vector<uint32_t> ra(t.size()), rb(t.size());
  lod::CellView v;
  v.camera.far_m = 1e5;
  v.voxelBudget = 60000;
  v.byteBudget = 150000;
  for (int frame = 0; frame < 240; ++frame) {
    const double r = frame * 0.015;
    v.camera.eye_m = frame == 150 ? glm::dvec3(200.0, 40.0, 90.0)
                                  : glm::dvec3(128.0 + 180.0 * std::cos(r), 128.0 + 180.0 * std::sin(r), 120.0);
    v.camera.heading_deg = 270.0 - r * 57.29578;
    v.camera.pitch_deg = -25.0;
    for (uint32_t c = 0; c < t.size(); ++c)
      if (res[c] == lod::Residency::InFlight && arrival[c] <= frame) res[c] = lod::Residency::Resident;
    if (frame % 29 == 11)
      for (uint32_t c = 1; c < t.size(); c += 3)
        if (res[c] == lod::Residency::Resident) res[c] = lod::Residency::Absent;
    const lod::CellSelectStats sa = a.select(v, res, da, ra), sb = b.select(v, res, db, rb);
    const std::string what = "frame " + std::to_string(frame);
    ASSERT_EQ(sa.drawnCells, sb.drawnCells) << what;
    ASSERT_EQ(sa.requestedCells, sb.requestedCells) << what;
    EXPECT_EQ(sa.drawnVoxels, sb.drawnVoxels) << what;
    EXPECT_EQ(sa.cutCells, sb.cutCells) << what;
    EXPECT_EQ(sa.splits, sb.splits) << what;
    EXPECT_EQ(sa.merges, sb.merges) << what;
    EXPECT_EQ(sa.blockedSplits, sb.blockedSplits) << what;
    EXPECT_EQ(sa.reservedVoxels, sb.reservedVoxels) << what;
    EXPECT_EQ(std::bit_cast<uint32_t>(sa.maxVoxel_px), std::bit_cast<uint32_t>(sb.maxVoxel_px)) << what;
    for (uint32_t k = 0; k < sa.drawnCells; ++k) {
      ASSERT_EQ(da[k].cell, db[k].cell) << what << " draw " << k;
      ASSERT_EQ(std::bit_cast<uint32_t>(da[k].voxel_px), std::bit_cast<uint32_t>(db[k].voxel_px)) << what;
    }
    for (uint32_t k = 0; k < sa.requestedCells; ++k) {
      ASSERT_EQ(ra[k], rb[k]) << what << " request " << k;
      res[ra[k]] = lod::Residency::InFlight;
      arrival[ra[k]] = frame + 2;
    }
  }
  // Every pass of two or more chunks ran some of them on the helper thread.
  EXPECT_GT(runner.forcedPasses, 240u);
  EXPECT_EQ(runner.passesWithoutHelper, 0u);
  EXPECT_GT(pair.helperChunks(), runner.forcedPasses - 1);
}

}  // namespace
