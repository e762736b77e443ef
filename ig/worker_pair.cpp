#include "ig/worker_pair.h"

#include <chrono>
#include <thread>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define IG_PAUSE() _mm_pause()
#else
#define IG_PAUSE() ((void)0)
#endif

namespace ig {

WorkerPair::WorkerPair(uint32_t spin_us) : spin_us_(spin_us), thread_([this] { loop(); }) {}

WorkerPair::~WorkerPair() {
  stop_.store(true, std::memory_order_release);
  go_.fetch_add(1, std::memory_order_release);
  go_.notify_one();
  thread_.join();
}

bool WorkerPair::take(uint32_t gen, uint32_t& ordinal, uint32_t& chunks) {
  uint64_t s = claim_.load(std::memory_order_acquire);
  for (;;) {
    const uint32_t g = static_cast<uint32_t>(s >> 40), n = static_cast<uint32_t>((s >> 20) & kCountMask),
                   t = static_cast<uint32_t>(s & kCountMask);
    if (g != gen || t >= n) return false;
    if (claim_.compare_exchange_weak(s, s + 1, std::memory_order_acq_rel, std::memory_order_acquire)) {
      ordinal = t;
      chunks = n;
      return true;
    }
  }
}

void WorkerPair::forEach(uint32_t chunks, ChunkFn fn, void* ctx) {
  if (chunks == 0) return;
  if (chunks > kCountMask) {  // more than the claim word counts: all here
    for (uint32_t k = 0; k < chunks; ++k) fn(ctx, k, 0);
    return;
  }
  fn_.store(fn, std::memory_order_relaxed);
  ctx_.store(ctx, std::memory_order_relaxed);
  helperDone_.store(0, std::memory_order_relaxed);
  gen_ = (gen_ + 1) & 0xFFFFFF;
  claim_.store(uint64_t{gen_} << 40 | uint64_t{chunks} << 20, std::memory_order_release);
  go_.store(gen_, std::memory_order_release);
  go_.notify_one();
  uint32_t mine = 0, ordinal = 0, n = 0;
  while (take(gen_, ordinal, n)) fn(ctx, mine++, 0);  // the front, in order
  const uint32_t theirs = chunks - mine;
  // The helper is in a chunk: spin, then yield (it was preempted), then sleep. yield() hands the
  // CPU only to threads of this thread's priority: a SCHED_FIFO render thread ([service]
  // realtime_priority) sharing a CPU with the normal helper would get its chunk back only when
  // the kernel throttles real-time threads (~1 s). A sleep lets any thread run.
  for (uint32_t spins = 0; helperDone_.load(std::memory_order_acquire) != theirs; ++spins) {
    IG_PAUSE();
    if (spins < 4096) continue;
    if (spins < 4096 + 256) std::this_thread::yield();
    else std::this_thread::sleep_for(std::chrono::microseconds(20));
  }
}

void WorkerPair::loop() {
  using Clock = std::chrono::steady_clock;
  uint32_t seen = 0;
  for (;;) {
    // Spin a while for the next pass, then sleep until it is published.
    uint32_t g = go_.load(std::memory_order_acquire);
    if (g == seen) {
      const auto until = Clock::now() + std::chrono::microseconds(spin_us_);
      for (uint32_t i = 1; (g = go_.load(std::memory_order_acquire)) == seen; ++i) {
        IG_PAUSE();
        if ((i & 63) == 0 && Clock::now() >= until) break;
      }
      while ((g = go_.load(std::memory_order_acquire)) == seen) go_.wait(seen, std::memory_order_acquire);
    }
    seen = g;
    if (stop_.load(std::memory_order_acquire)) return;
    uint32_t ordinal = 0, n = 0, mine = 0;
    while (take(g, ordinal, n)) {
      // After a successful claim the pass is still open, so fn_ and ctx_ are this pass's.
      fn_.load(std::memory_order_relaxed)(ctx_.load(std::memory_order_relaxed), n - 1 - mine, 1);
      ++mine;
      helperTotal_.fetch_add(1, std::memory_order_relaxed);
      helperDone_.fetch_add(1, std::memory_order_release);
    }
  }
}

}  // namespace ig
