#include "ig/cells_stream.h"

#include <algorithm>
#include <chrono>
#include <cinttypes>
#include <cstdio>

#include "render/cells_pass.h"

namespace ig {
namespace {

constexpr size_t kEvictChunk = 4096;

uint64_t pointBytes(const lod::CellTree& tree, uint32_t cell) {
  return uint64_t{tree.voxels(cell)} * sizeof(lod::CellPoint);
}

}  // namespace

bool CellsPassSink::upload(uint32_t cell, std::span<const lod::CellPoint> points) { return pass_.upload(cell, points); }
void CellsPassSink::evict(uint32_t cell) { pass_.evict(cell); }

CellStream::CellStream() = default;
CellStream::~CellStream() = default;

bool CellStream::open(const CellStreamOptions& options, std::string& error) {
  fetcher_.reset();
  if (options.memoryBudget_bytes == 0) {
    error = "cells: memory budget 0 bytes: must be > 0";
    return false;
  }
  if (!(options.openTimeout_s > 0.0)) {
    error = "cells: open timeout " + std::to_string(options.openTimeout_s) + " s: must be > 0";
    return false;
  }
  std::unique_ptr<io::RangeFetcher> fetcher = io::RangeFetcher::open(options.source, options.fetch, error);
  if (!fetcher) return false;
  std::vector<uint8_t> bytes;
  if (!fetcher->fetchSync(0, static_cast<uint32_t>(lod::kCellDbHeaderBytes), bytes, error, options.openTimeout_s)) {
    error = options.source + ": cannot read the cell database header: " + error;
    return false;
  }
  std::string why;
  if (!lod::parseCellDbHeader(bytes, header_, why)) {
    error = options.source + ": " + why;
    return false;
  }
  if (fetcher->resourceBytes() != 0 && fetcher->resourceBytes() != header_.fileBytes) {
    error = options.source + ": " + std::to_string(fetcher->resourceBytes()) + " bytes, the header says " +
            std::to_string(header_.fileBytes) + " (truncated or replaced while serving?)";
    return false;
  }
  if (header_.indexBytes > 0xFFFFFFFFull) {
    error = options.source + ": index of " + std::to_string(header_.indexBytes) + " bytes is too large";
    return false;
  }
  // In pieces of at most maxRange_bytes (the fetcher refuses larger ranges; an index of more than
  // 2 M cells is larger than the default 64 MiB), all within the open timeout.
  {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(options.openTimeout_s);
    std::vector<uint8_t> piece;
    std::vector<uint8_t> index;
    // Not reserved from the header's count: it grows only with bytes that arrived.
    while (index.size() < header_.indexBytes) {
      const uint64_t left = header_.indexBytes - index.size();
      const auto size = static_cast<uint32_t>(std::min<uint64_t>(left, options.fetch.maxRange_bytes));
      const double timeLeft = std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
      if (!fetcher->fetchSync(header_.indexOffset + index.size(), size, piece, error, std::max(timeLeft, 1e-3))) {
        error = options.source + ": cannot read the cell index: " + error;
        return false;
      }
      index.insert(index.end(), piece.begin(), piece.end());
    }
    bytes.swap(index);
  }
  if (!lod::parseCellDbIndex(header_, bytes, tree_, entries_, why)) {
    error = options.source + ": " + why;
    return false;
  }
  const uint32_t n = tree_.size();
  residency_.assign(n, lod::Residency::Absent);
  broken_.assign(n, 0);
  cache_ = std::make_unique<lod::CellCache>(tree_, options.memoryBudget_bytes);
  results_.clear();
  results_.reserve(1024);
  batch_.clear();
  points_.clear();
  evicted_.assign(kEvictChunk, lod::kNoCell);
  stats_ = {};
  lastError_.clear();
  lastFrame_ = 0;
  fetcher_ = std::move(fetcher);
  return true;
}

void CellStream::markBroken(uint32_t cell, const std::string& why) {
  if (cell < broken_.size()) {
    if (broken_[cell] == 0) ++stats_.broken;
    broken_[cell] = 1;
    // InFlight for the selector: never drawn, never requested again; an ancestor stays drawn.
    residency_[cell] = lod::Residency::InFlight;
  } else {
    ++stats_.broken;
  }
  if (lastError_.empty()) lastError_ = why;
}

uint32_t CellStream::receive(CellSink& sink) {
  if (!fetcher_) return 0;
  results_.clear();
  fetcher_->poll(results_);
  uint32_t made = 0;
  std::string why;
  for (io::RangeResult& r : results_) {
    const uint32_t cell = r.key;
    if (cell >= tree_.size() || residency_[cell] != lod::Residency::InFlight || broken_[cell]) continue;
    if (stats_.inFlight > 0) --stats_.inFlight;
    if (!r.ok) {
      markBroken(cell, fetcher_->source() + ": cell " + std::to_string(cell) + ": " + r.error);
      continue;
    }
    points_.clear();
    if (!lod::decodeCell(tree_, cell, r.data, points_, why)) {
      markBroken(cell, fetcher_->source() + ": cell " + std::to_string(cell) + ": " + why);
      continue;
    }
    bool ok = sink.upload(cell, points_);
    if (!ok) {
      // Make room: evict least recently drawn cells worth twice this one (the arena's blocks are
      // powers of two), then try once more.
      const uint64_t need = 2 * pointBytes(tree_, cell);
      const uint64_t budget = cache_->budgetBytes();
      cache_->setBudgetBytes(cache_->usedBytes() > need ? cache_->usedBytes() - need : 0);
      evictOver(lastFrame_, sink);
      cache_->setBudgetBytes(budget);
      ok = sink.upload(cell, points_);
    }
    if (!ok) {
      ++stats_.uploadFailures;
      residency_[cell] = lod::Residency::Absent;  // requested again when there is room
      continue;
    }
    residency_[cell] = lod::Residency::Resident;
    cache_->insert(cell, static_cast<uint32_t>(std::min<uint64_t>(pointBytes(tree_, cell), 0xFFFFFFFFu)), lastFrame_);
    ++stats_.arrived;
    stats_.arrivedBytes += entries_[cell].bytes;
    ++made;
  }
  return made;
}

void CellStream::request(std::span<const uint32_t> cells) {
  if (!fetcher_) return;
  std::string why;
  for (uint32_t cell : cells) {
    if (cell >= tree_.size()) {
      markBroken(cell, fetcher_->source() + ": cell " + std::to_string(cell) + " is outside the database (" +
                           std::to_string(tree_.size()) + " cells): refused by the client");
      continue;
    }
    if (residency_[cell] != lod::Residency::Absent || broken_[cell]) continue;
    const lod::CellDbEntry& e = entries_[cell];
    io::RangeRequest r;
    r.key = cell;
    r.offset = e.offset;
    r.size = e.bytes;
    r.crc32 = e.crc32;
    if (!fetcher_->submit(r, why)) {
      markBroken(cell, fetcher_->source() + ": cell " + std::to_string(cell) + ": " + why);
      continue;
    }
    residency_[cell] = lod::Residency::InFlight;
    ++stats_.requested;
    ++stats_.inFlight;
  }
}

void CellStream::evictOver(uint64_t frame, CellSink& sink) {
  for (;;) {
    const lod::CellEvictStats st = cache_->evict(frame, evicted_);
    for (uint32_t i = 0; i < st.evicted; ++i) {
      const uint32_t cell = evicted_[i];
      sink.evict(cell);
      residency_[cell] = lod::Residency::Absent;
      ++stats_.evicted;
    }
    if (!st.spanFull) break;
  }
}

void CellStream::drawn(std::span<const lod::CellDraw> cells, uint64_t frame, CellSink& sink) {
  if (!fetcher_) return;
  lastFrame_ = frame;
  for (const lod::CellDraw& d : cells)
    if (d.cell < tree_.size()) cache_->touch(d.cell, frame);
  evictOver(frame, sink);
}

CellStreamStats CellStream::stats() const {
  CellStreamStats s = stats_;
  if (cache_) {
    s.residentBytes = cache_->usedBytes();
    s.residentCells = cache_->residentCells();
  }
  return s;
}

io::RangeFetcherStats CellStream::fetchStats() const { return fetcher_ ? fetcher_->stats() : io::RangeFetcherStats{}; }

}  // namespace ig
