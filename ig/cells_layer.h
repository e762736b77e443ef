// The [cells] scene layer (paper 003, docs/cells.md): a hierarchical-cells database streamed
// from a local file or an http:// server (ig/cells_stream.h), selected each frame under a voxel
// budget and a byte budget (lod/cells_select.h) and drawn as point splats (render/cells_pass.h).
//
// Placement: the database's root corner (its rootMin) goes to `origin_m` in scene ENU. The layer
// keeps a copy of the database's cell tree moved there, so the selector sees the frame camera as
// it is and the pass draws camera-relative from the moved corner (a database 1e6 m from the
// scene origin keeps float precision inside its root cube).
//
// Use: create() at start-up (opens the stream: reads the header and the index, blocking up to
// open_timeout_s for an http source; starts the fetcher's worker thread, and with select_threads = 2
// the selection's helper thread), initRender() once the
// renderer exists (the GPU arena), then per frame
//   select(camera, viewport, clock, budget_ms)
//                              the lod phase: receive arrived cells (uploads into the arena),
//                              select for the camera within the budgets (the refinement stops
//                              so that the call ends near budget_ms on `clock`), request missing
//                              cells
//   draw(renderer)             the submit phase (between Renderer::beginFrame and endFrame):
//                              draw the selection, then pin the drawn cells and evict over the
//                              memory budget.
// Nothing blocks after create(); the arrays select() writes into are sized at create().
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "ig/cells_deadline.h"
#include "ig/clock.h"
#include "ig/config.h"
#include "ig/worker_pair.h"
#include "lod/cells.h"
#include "lod/cells_select.h"
#include "lod/view.h"

namespace ig {

namespace render {
class Renderer;
class CellsPass;
}  // namespace render

class CellStream;
class CellsPassSink;
class CellSink;

// CellsLayerConfig ([cells] scene keys) is in ig/config.h.

struct CellsLayerStats {
  lod::CellSelectStats select;   // the last frame's selection
  uint32_t drawnCells = 0;       // cells the pass drew in the last frame (resident in the arena)
  uint64_t drawnPoints = 0;      // their points (= voxels)
  uint64_t residentBytes = 0;    // decoded points held by the stream's LRU
  uint32_t residentCells = 0;
  uint64_t fetchedBytes = 0;     // payload bytes of the cells that arrived since start
  uint64_t arrivedCells = 0;
  uint32_t inFlight = 0;         // cells requested and not yet arrived (broken ones excluded)
  uint64_t broken = 0;           // cells refused, corrupt after retries or undecodable
  uint64_t uploadFailures = 0;   // arrivals the arena had no room for
  uint64_t frames = 0;           // select() calls
  uint64_t stoppedFrames = 0;    // select() calls whose refinement stopped at its time budget
  float maxVoxel_px = 0.0f;      // the largest on-screen voxel over all frames with cells drawn
  uint64_t maxDrawnVoxels = 0;   // the most voxels drawn in one frame
  double select_ms_sum = 0.0, select_ms_max = 0.0;  // per-frame timings the service records
  double draw_ms_sum = 0.0, draw_ms_max = 0.0;
  uint64_t timedFrames = 0;
};

// Threads for the selection's passes that a config asks for: select_threads, or with 0 (the
// default) 2 on a machine with at least 4 hardware threads, else 1.
int selectThreadsFor(const CellsLayerConfig& config);

class CellsLayer {
 public:
  // Opens the source and checks the database. nullptr + error (naming [cells] source and the
  // file or URL) on failure.
  static std::unique_ptr<CellsLayer> create(const CellsLayerConfig& config, std::string& error);
  ~CellsLayer();

  // The render pass and its GPU arena (a GL context must be current). Fails naming gpu_mb when
  // the arena's largest block cannot hold the database's largest cell (it could never be drawn).
  bool initRender(std::string& error);
  // Per frame (lod phase). With a clock and budget_ms > 0 the refinement stops so that this call
  // ends near budget_ms after it began: at budget_ms less what the calls stopped before spent
  // after their stop (the draw list). CellView::stop: the cut stays valid and the next frames go
  // on from it; the passes over the cut are not stopped. Without, it runs to the best cut.
  void select(const lod::Camera& camera, int viewportHeight_px, const Clock* clock = nullptr, double budget_ms = 0.0);
  // Per frame, after select() (submit phase).
  void draw(render::Renderer& renderer);
  // Reload: the budgets that apply between frames.
  void setBudgets(uint64_t voxelBudget, uint64_t wBytes, double minVoxel_px);
  // W must hold the database's largest cell, or that cell could never be fetched: false with an
  // error naming w_bytes and the cell's size otherwise (create() and igd's reload refuse it).
  bool checkByteBudget(uint64_t wBytes, std::string& error) const;
  // This frame's voxel budget (the frame governor's), >= 1.
  void setVoxelBudget(uint64_t voxelBudget) { view_.voxelBudget = voxelBudget; }
  uint64_t voxelBudget() const { return view_.voxelBudget; }
  // The service's measurement of this frame's select() and draw() (its clock).
  void recordTiming(double select_ms, double draw_ms);

  const CellsLayerStats& stats() const { return stats_; }  // refreshed by select() and draw()
  const lod::CellTree& tree() const { return tree_; }  // moved to origin_m
  uint64_t gpuBytes() const;
  // The fetcher's worker, and the selection's helper with select_threads = 2.
  uint32_t threads() const { return workers_ ? 2 : 1; }
  // One line for the start-up log, one for the exit.
  std::string describe() const;
  std::string summaryLine() const;

 private:
  CellsLayer();
  CellsLayerConfig config_;
  std::unique_ptr<CellStream> stream_;
  lod::CellTree tree_;
  std::unique_ptr<WorkerPair> workers_;  // before selector_: outlives it
  std::unique_ptr<lod::CellSelector> selector_;
  std::unique_ptr<render::CellsPass> pass_;
  std::unique_ptr<CellsPassSink> sink_;
  lod::CellView view_;
  std::vector<lod::CellDraw> draws_;
  std::vector<uint32_t> requests_;
  uint32_t drawCount_ = 0;
  uint32_t largestCell_bytes_ = 0;
  CellSelectDeadline deadline_;  // the refinement's time budget
  CellsLayerStats stats_;
};

}  // namespace ig
