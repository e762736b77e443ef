// A second thread for the per-frame passes of an LOD selection (lod::ChunkRunner; used by the
// cells selection, lod/cells_select.h).
//
// forEach(n, fn, ctx): the calling thread takes chunks 0, 1, 2, ... and the helper thread
// n-1, n-2, ... through one atomic claim word, until all n are taken; it returns when every chunk
// is done. A helper that wakes late just takes fewer chunks (none, for a short pass), so a pass
// never waits for the helper to wake, only for a chunk it is running.
//
// A caller waiting for a chunk the helper is running spins, yields, then sleeps 20 us at a time,
// so that a real-time caller on the helper's CPU lets it finish.
//
// Between passes the helper spins for `spin_us` (the passes of one frame follow each other within
// microseconds), then sleeps in the kernel (futex, std::atomic::wait) until the next pass: an idle
// selector costs no CPU. The thread exists only while the WorkerPair does: a scene without cells
// has none.
#pragma once

#include <atomic>
#include <cstdint>
#include <thread>

#include "lod/cells_select.h"

namespace ig {

class WorkerPair final : public lod::ChunkRunner {
 public:
  explicit WorkerPair(uint32_t spin_us = 200);
  ~WorkerPair() override;
  WorkerPair(const WorkerPair&) = delete;
  WorkerPair& operator=(const WorkerPair&) = delete;

  void forEach(uint32_t chunks, ChunkFn fn, void* ctx) override;
  // Chunks the helper ran since construction (for tests and stats).
  uint64_t helperChunks() const { return helperTotal_.load(std::memory_order_relaxed); }

 private:
  // The claim word: generation (24 bits) | chunks (20) | taken (20).
  static constexpr uint64_t kCountMask = (1u << 20) - 1;
  // Takes the next chunk of generation `gen`: its ordinal among all taken (0, 1, ...) and the
  // pass's chunk count, or false when the pass is fully taken or over.
  bool take(uint32_t gen, uint32_t& ordinal, uint32_t& chunks);
  void loop();

  std::atomic<uint64_t> claim_{0};
  std::atomic<uint32_t> go_{0};          // the generation of the last pass published
  std::atomic<uint32_t> helperDone_{0};  // chunks the helper finished in this pass
  std::atomic<uint64_t> helperTotal_{0};
  std::atomic<ChunkFn> fn_{nullptr};
  std::atomic<void*> ctx_{nullptr};
  std::atomic<bool> stop_{false};
  uint32_t gen_ = 0;  // the caller's
  uint32_t spin_us_;
  std::thread thread_;
};

}  // namespace ig
