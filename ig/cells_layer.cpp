#include "ig/cells_layer.h"

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <thread>

#include "ig/cells_stream.h"
#include "render/cells_pass.h"
#include "render/renderer.h"

namespace ig {

namespace {

// The same cells with the root corner at `rootMin_m` (points are stored relative to it).
bool movedTree(const lod::CellTree& from, const glm::dvec3& rootMin_m, lod::CellTree& to, std::string& error) {
  std::vector<lod::CellDesc> cells(from.size());
  for (uint32_t c = 0; c < from.size(); ++c) {
    lod::CellDesc& d = cells[c];
    d.parent = from.parent(c);
    const glm::uvec3 k = from.coord(c);
    d.octant = static_cast<uint8_t>((k.x & 1u) | ((k.y & 1u) << 1) | ((k.z & 1u) << 2));
    d.voxels = from.voxels(c);
    d.bytes = from.bytes(c);
  }
  lod::CellTreeInfo info = from.info();
  info.rootMin_m = rootMin_m;
  return to.build(info, cells, error);
}

}  // namespace

int selectThreadsFor(const CellsLayerConfig& config) {
  if (config.selectThreads > 0) return static_cast<int>(config.selectThreads);
  return std::thread::hardware_concurrency() >= 4 ? 2 : 1;  // 0: a helper only with cores to spare
}

CellsLayer::CellsLayer() = default;
CellsLayer::~CellsLayer() = default;

std::unique_ptr<CellsLayer> CellsLayer::create(const CellsLayerConfig& config, std::string& error) {
  for (double v : config.origin_m) {
    if (!std::isfinite(v)) {
      error = "[cells] origin_m: must be finite";
      return nullptr;
    }
  }
  if (!(config.pointScale > 0.0) || !(config.minVoxel_px >= 0.0) || config.voxelBudget == 0 || config.wBytes == 0 ||
      config.gpu_mb <= 0 || config.memory_mb <= 0) {
    error = "[cells] point_scale, min_voxel_px, voxel_budget, w_bytes, gpu_mb, memory_mb: out of range";
    return nullptr;
  }
  std::unique_ptr<CellsLayer> layer(new CellsLayer);
  layer->config_ = config;
  layer->stream_ = std::make_unique<CellStream>();
  CellStreamOptions o;
  o.source = config.source;
  o.memoryBudget_bytes = static_cast<uint64_t>(config.memory_mb) << 20;
  o.openTimeout_s = config.openTimeout_s;
  if (!layer->stream_->open(o, error)) {
    // The stream's errors start with the source; make sure the key and the source are named.
    if (error.find(config.source) == std::string::npos) error = config.source + ": " + error;
    error = "[cells] source: " + error;
    return nullptr;
  }
  const CellStream& s = *layer->stream_;
  for (const lod::CellDbEntry& e : s.entries()) layer->largestCell_bytes_ = std::max(layer->largestCell_bytes_, e.bytes);
  if (!layer->checkByteBudget(config.wBytes, error)) return nullptr;
  const glm::dvec3 origin(config.origin_m[0], config.origin_m[1], config.origin_m[2]);
  std::string why;
  if (!movedTree(s.tree(), origin, layer->tree_, why)) {
    error = "[cells] source: " + config.source + ": " + why;
    return nullptr;
  }
  lod::CellSelectorConfig selectorConfig;
  if (selectThreadsFor(config) >= 2) {
    layer->workers_ = std::make_unique<WorkerPair>();
    selectorConfig.runner = layer->workers_.get();
  }
  layer->selector_ = std::make_unique<lod::CellSelector>(layer->tree_, selectorConfig);
  layer->draws_.resize(layer->selector_->drawBound());  // sized once: select() writes into them
  layer->requests_.resize(layer->tree_.size());
  layer->view_.minVoxel_px = config.minVoxel_px;
  layer->view_.voxelBudget = config.voxelBudget;
  layer->view_.byteBudget = config.wBytes;
  return layer;
}

bool CellsLayer::initRender(std::string& error) {
  pass_ = std::make_unique<render::CellsPass>();
  render::CellsPassConfig pc;
  pc.arenaBytes = static_cast<uint64_t>(config_.gpu_mb) << 20;
  pc.pointScale = static_cast<float>(config_.pointScale);
  if (!pass_->init(tree_, pc, error)) {
    error = "[cells] render pass: " + error;
    pass_.reset();
    return false;
  }
  // A cell larger than the arena's largest block could never be uploaded: every arrival would
  // evict the unpinned cells to make room, fail, and be fetched again next frame.
  uint64_t largest = 0;
  for (uint32_t c = 0; c < tree_.size(); ++c) largest = std::max<uint64_t>(largest, tree_.voxels(c));
  if (largest > pass_->largestCellPoints()) {
    error = "[cells] gpu_mb = " + std::to_string(config_.gpu_mb) + ": the arena's largest block holds " +
            std::to_string(pass_->largestCellPoints()) + " points, less than the largest cell of " + config_.source +
            " (" + std::to_string(largest) + " points), which could never be drawn";
    pass_.reset();
    return false;
  }
  sink_ = std::make_unique<CellsPassSink>(*pass_);
  return true;
}

bool CellsLayer::checkByteBudget(uint64_t wBytes, std::string& error) const {
  if (wBytes >= largestCell_bytes_) return true;
  error = "[cells] w_bytes = " + std::to_string(wBytes) + ": smaller than the largest cell of " + config_.source + " (" +
          std::to_string(largestCell_bytes_) + " bytes), which could never be fetched";
  return false;
}

void CellsLayer::setBudgets(uint64_t voxelBudget, uint64_t wBytes, double minVoxel_px) {
  view_.voxelBudget = voxelBudget;
  // Never below the largest cell (create() refused that; a reload keeps the last good value).
  if (wBytes >= largestCell_bytes_) view_.byteBudget = wBytes;
  view_.minVoxel_px = minVoxel_px;
}

void CellsLayer::select(const lod::Camera& camera, int viewportHeight_px, const Clock* clock, double budget_ms) {
  const int64_t start_ns = clock && budget_ms > 0.0 ? clock->now_ns() : 0;
  ++stats_.frames;
  if (sink_) stream_->receive(*sink_);
  view_.camera = camera;
  view_.viewportHeight_px = std::max(1, viewportHeight_px);
  if (clock) deadline_.arm(view_, *clock, start_ns, budget_ms);
  stats_.select = selector_->select(view_, stream_->residency(), draws_, requests_);
  deadline_.done(view_);
  if (stats_.select.stopped) ++stats_.stoppedFrames;
  drawCount_ = stats_.select.drawnCells;
  // Without an arena nothing could be drawn: do not fetch either.
  if (sink_) stream_->request({requests_.data(), stats_.select.requestedCells});
}

void CellsLayer::draw(render::Renderer& renderer) {
  if (!pass_) return;
  const std::span<const lod::CellDraw> drawn(draws_.data(), drawCount_);
  pass_->draw(renderer, drawn);
  stream_->drawn(drawn, stats_.frames, *sink_);
  const render::CellsPassStats& p = pass_->lastStats();
  stats_.drawnCells = p.drawnCells;
  stats_.drawnPoints = p.drawnPoints;
  if (p.drawnCells > 0) stats_.maxVoxel_px = std::max(stats_.maxVoxel_px, stats_.select.maxVoxel_px);
  stats_.maxDrawnVoxels = std::max(stats_.maxDrawnVoxels, p.drawnPoints);
  const CellStreamStats s = stream_->stats();
  stats_.residentBytes = s.residentBytes;
  stats_.residentCells = s.residentCells;
  stats_.fetchedBytes = s.arrivedBytes;
  stats_.arrivedCells = s.arrived;
  stats_.inFlight = s.inFlight;
  stats_.broken = s.broken;
  stats_.uploadFailures = s.uploadFailures;
}

void CellsLayer::recordTiming(double select_ms, double draw_ms) {
  ++stats_.timedFrames;
  stats_.select_ms_sum += select_ms;
  stats_.draw_ms_sum += draw_ms;
  stats_.select_ms_max = std::max(stats_.select_ms_max, select_ms);
  stats_.draw_ms_max = std::max(stats_.draw_ms_max, draw_ms);
}

uint64_t CellsLayer::gpuBytes() const { return pass_ ? pass_->bufferBytes() : 0; }

std::string CellsLayer::describe() const {
  const lod::CellTreeInfo& info = tree_.info();
  char buf[768];
  std::snprintf(buf, sizeof buf,
                "cells: %s, %u cells in %d levels, root cube %.1f m at [%.1f, %.1f, %.1f], %.1f MB; voxel budget %" PRIu64
                ", W %" PRIu64 " bytes/frame, arena %" PRId64 " MB, memory %" PRId64 " MB, %d select thread%s",
                config_.source.c_str(), tree_.size(), tree_.levels(), info.rootEdge_m, info.rootMin_m.x, info.rootMin_m.y,
                info.rootMin_m.z, static_cast<double>(stream_->header().fileBytes) / 1e6, view_.voxelBudget,
                view_.byteBudget, config_.gpu_mb, config_.memory_mb, workers_ ? 2 : 1, workers_ ? "s" : "");
  return buf;
}

std::string CellsLayer::summaryLine() const {
  const CellsLayerStats& s = stats_;
  const double n = s.timedFrames > 0 ? static_cast<double>(s.timedFrames) : 1.0;
  char buf[896];
  std::snprintf(buf, sizeof buf,
                "cells: last frame %u cells drawn, %" PRIu64 " voxels (most %" PRIu64 ", budget %" PRIu64
                "), largest voxel %.2f px (max %.2f); resident %.2f MB in %u cells; fetched %.2f MB in %" PRIu64
                " cells, broken %" PRIu64 ", upload failures %" PRIu64 "; select mean %.3f ms max %.3f ms (refinement stopped at "
                "its time budget in %" PRIu64 " of %" PRIu64 " frames), draw mean %.3f ms max %.3f ms",
                s.drawnCells, s.drawnPoints, s.maxDrawnVoxels, view_.voxelBudget,
                static_cast<double>(s.drawnCells > 0 ? s.select.maxVoxel_px : 0.0f), static_cast<double>(s.maxVoxel_px),
                static_cast<double>(s.residentBytes) / 1e6, s.residentCells, static_cast<double>(s.fetchedBytes) / 1e6,
                s.arrivedCells, s.broken, s.uploadFailures, s.select_ms_sum / n, s.select_ms_max, s.stoppedFrames, s.frames,
                s.draw_ms_sum / n,
                s.draw_ms_max);
  std::string line = buf;
  if (s.broken > 0 && !stream_->lastError().empty()) line += " (first: " + stream_->lastError() + ")";
  return line;
}

}  // namespace ig
