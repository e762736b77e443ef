// The client side of hierarchical-cell streaming (paper 003, section 3; docs/cells.md): a cell
// database (lod/cells_db.h) read from a local file or an http:// URL (nginx, scripts/cells-server)
// through the asynchronous byte-range fetcher (io/range_fetch.h), the per-cell residency the
// selector reads (lod/cells_select.h), and a memory budget with LRU eviction (lod/cells_cache.h).
//
// Per frame, in this order:
//   receive(sink)   cells that arrived since the last frame: the fetcher has checked their crc;
//                   decodeCell checks their structure; the sink uploads the points (the GPU
//                   arena of render/cells_pass.h, or nothing); the cell becomes Resident.
//   select          the caller runs CellSelector::select(view, residency(), draw, requests)
//                   with W = the channel's bytes per frame.
//   request(reqs)   the selector's requests become range fetches; the cells are InFlight.
//   drawn(draw)     the drawn cells and their ancestors are pinned; the least recently drawn
//                   cells are evicted while the resident points are over the memory budget.
// Nothing here blocks except open(), which reads the header and the index (with a timeout).
//
// Failures: a cell whose bytes fail the crc is fetched again by the fetcher; one that still fails,
// fails to decode, or that the server refuses (416, 404) is marked broken: it stays InFlight for
// the selector, which then keeps drawing a resident ancestor instead, and is never requested
// again (counted in stats().broken, the first error kept in lastError()). While the server is
// down the fetcher retries with a backoff and the selector keeps drawing what is resident.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "io/range_fetch.h"
#include "lod/cells.h"
#include "lod/cells_cache.h"
#include "lod/cells_db.h"
#include "lod/cells_select.h"

namespace ig::render {
class CellsPass;
}

namespace ig {

struct CellStreamOptions {
  std::string source;                          // database file path, or http://HOST:PORT/path
  uint64_t memoryBudget_bytes = uint64_t{256} << 20;  // decoded points held (16 B a voxel)
  double openTimeout_s = 10.0;                 // for the header and the index
  io::RangeFetcherOptions fetch;
};

// Where arrived cells go (the GPU arena, or nothing for selection-only runs).
class CellSink {
 public:
  virtual ~CellSink() = default;
  // False: no room (the stream evicts least recently drawn cells and tries once more).
  virtual bool upload(uint32_t cell, std::span<const lod::CellPoint> points) = 0;
  virtual void evict(uint32_t cell) = 0;
};

// The GPU arena of render/cells_pass.h as the sink (uploads cost no GL call: the arena is
// persistently mapped).
class CellsPassSink final : public CellSink {
 public:
  explicit CellsPassSink(render::CellsPass& pass) : pass_(pass) {}
  bool upload(uint32_t cell, std::span<const lod::CellPoint> points) override;
  void evict(uint32_t cell) override;

 private:
  render::CellsPass& pass_;
};

struct CellStreamStats {
  uint64_t requested = 0;       // cells handed to the fetcher
  uint64_t arrived = 0;         // cells made resident
  uint64_t arrivedBytes = 0;    // their payload bytes (S)
  uint64_t broken = 0;          // cells refused, corrupt after retries or undecodable
  uint64_t evicted = 0;         // cells dropped by the memory budget
  uint64_t uploadFailures = 0;  // arrivals the sink had no room for even after evicting (dropped, requested again later)
  uint64_t residentBytes = 0;   // decoded point bytes resident now
  uint32_t residentCells = 0;
  uint32_t inFlight = 0;        // cells requested and not yet arrived (broken ones excluded)
};

class CellStream {
 public:
  CellStream();
  ~CellStream();
  CellStream(const CellStream&) = delete;
  CellStream& operator=(const CellStream&) = delete;

  // Opens the source (starting the fetcher's worker thread), reads and checks the header and the
  // index. Errors name the source and the bad value.
  bool open(const CellStreamOptions& options, std::string& error);
  bool isOpen() const { return fetcher_ != nullptr; }

  const lod::CellDbHeader& header() const { return header_; }
  const lod::CellTree& tree() const { return tree_; }
  std::span<const lod::Residency> residency() const { return residency_; }
  const std::vector<lod::CellDbEntry>& entries() const { return entries_; }

  // Takes the cells that arrived; returns how many became resident this call. Non-blocking.
  uint32_t receive(CellSink& sink);
  // Submits the selector's requests. Cells out of the database are refused here (the client),
  // counted as broken, and named in lastError(). Non-blocking.
  void request(std::span<const uint32_t> cells);
  // After drawing frame `frame`: pins the drawn cells (and ancestors) and evicts over budget.
  void drawn(std::span<const lod::CellDraw> cells, uint64_t frame, CellSink& sink);

  CellStreamStats stats() const;
  io::RangeFetcherStats fetchStats() const;
  const std::string& lastError() const { return lastError_; }
  bool isBroken(uint32_t cell) const { return cell < broken_.size() && broken_[cell] != 0; }

 private:
  void markBroken(uint32_t cell, const std::string& why);
  void evictOver(uint64_t frame, CellSink& sink);

  std::unique_ptr<io::RangeFetcher> fetcher_;
  lod::CellDbHeader header_;
  lod::CellTree tree_;
  std::vector<lod::CellDbEntry> entries_;
  std::vector<lod::Residency> residency_;
  std::vector<uint8_t> broken_;
  std::unique_ptr<lod::CellCache> cache_;
  std::vector<io::RangeResult> results_;
  std::vector<io::RangeRequest> batch_;
  std::vector<lod::CellPoint> points_;
  std::vector<uint32_t> evicted_;
  CellStreamStats stats_;
  uint64_t lastFrame_ = 0;
  std::string lastError_;
};

}  // namespace ig
