#include "ig/bench_cells.h"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "ig/bench_cells_path.h"
#include "ig/cells_deadline.h"
#include "ig/clock.h"
#include "ig/json.h"
#include "ig/cells_tool.h"
#include "ig/stats.h"
#include "ig/worker_pair.h"
#include "lod/cells.h"
#include "lod/cells_select.h"
#include "lod/cells_voxel.h"

namespace ig {
namespace {

using BenchClock = std::chrono::steady_clock;
double msSince(BenchClock::time_point t0) { return std::chrono::duration<double, std::milli>(BenchClock::now() - t0).count(); }

constexpr double kSceneEdge_m = kCellsSceneEdge_m;

// What a frame chose: its stats, its draw list (cells and voxel sizes, in order) and its requests,
// hashed; equal in every replay of the same views and arrivals, with one thread or two.
uint64_t choiceSignature(const lod::CellSelectStats& s, const std::vector<lod::CellDraw>& draw,
                         const std::vector<uint32_t>& requests) {
  uint64_t h = s.drawnVoxels * 0x9E3779B97F4A7C15ull ^ (uint64_t{s.drawnCells} << 40) ^ (uint64_t{s.requestedCells} << 20) ^
               s.requestedBytes ^ (uint64_t{s.splits} << 52) ^ (uint64_t{s.merges} << 30);
  auto mix = [&h](uint64_t v) { h = (h ^ v) * 0x100000001B3ull; };
  for (uint32_t k = 0; k < s.drawnCells && k < draw.size(); ++k) {
    uint32_t bits = 0;
    std::memcpy(&bits, &draw[k].voxel_px, 4);
    mix(uint64_t{draw[k].cell} << 32 | bits);
  }
  for (uint32_t k = 0; k < s.requestedCells && k < requests.size(); ++k) mix(requests[k]);
  return h;
}

struct SweepPoint {
  uint64_t budget = 0;
  double minQualityP50_px = 0.0, minQualityMax_px = 0.0, selectP50_ms = 0.0, selectP99_ms = 0.0;
  double oneThreadP50_ms = 0.0, oneThreadP99_ms = 0.0;  // the same frames on one thread
  uint64_t voxelsP50 = 0, cutCellsP50 = 0;
};

// The tree as scripts/cells-ab reads it: header, count, one CellDesc per cell.
int dumpTree(const lod::CellTree& tree, const std::string& path) {
  std::vector<lod::CellDesc> cells(tree.size());
  for (uint32_t c = 0; c < tree.size(); ++c) {
    const glm::uvec3 k = tree.coord(c);
    cells[c] = {tree.parent(c), static_cast<uint8_t>((k.x & 1) | ((k.y & 1) << 1) | ((k.z & 1) << 2)), tree.voxels(c),
                tree.bytes(c)};
  }
  const lod::CellTreeInfo& info = tree.info();
  const double header[5] = {info.rootMin_m.x, info.rootMin_m.y, info.rootMin_m.z, info.rootEdge_m,
                            static_cast<double>(info.cellVoxelDepth)};
  const uint64_t n = cells.size();
  FILE* f = std::fopen(path.c_str(), "wb");
  bool ok = f != nullptr && std::fwrite(header, sizeof header, 1, f) == 1 && std::fwrite(&n, sizeof n, 1, f) == 1 &&
            std::fwrite(cells.data(), sizeof(lod::CellDesc), cells.size(), f) == cells.size();
  if (f != nullptr && std::fclose(f) != 0) ok = false;
  if (!ok) {
    std::fprintf(stderr, "igbench cells: cannot write the tree to %s\n", path.c_str());
    return 1;
  }
  std::fprintf(stderr, "igbench cells: %u cells, %d levels written to %s\n", tree.size(), tree.levels(), path.c_str());
  return 0;
}

}  // namespace

int runCellsBench(const CellsBenchOptions& o) {
  if (o.spheres < 1 || o.cellLevels < 1 || o.cellLevels > lod::kMaxCellLevels || o.cellVoxelDepth < 0 ||
      o.cellLevels - 1 + o.cellVoxelDepth > lod::kMaxVoxelLevels || o.frames < 8 || o.height_px < 1 ||
      o.latencyFrames < 0) {
    std::fprintf(stderr,
                 "igbench cells: bad options (spheres = %d, levels = %d, voxel depth = %d, frames = %d, height = %d, "
                 "latency = %d): levels - 1 + voxel depth must be <= %d\n",
                 o.spheres, o.cellLevels, o.cellVoxelDepth, o.frames, o.height_px, o.latencyFrames,
                 lod::kMaxVoxelLevels);
    return 2;
  }
  // Build the HC.
  const auto tBuild = BenchClock::now();
  const lod::VoxelMesh mesh = cellsSphereScene(o.spheres, o.seed);
  lod::VoxelizeConfig vc;
  vc.levels = o.cellLevels - 1 + o.cellVoxelDepth;
  vc.boxMin_m = glm::dvec3(0.0);
  vc.boxEdge_m = kSceneEdge_m;
  lod::VoxelPyramid pyramid;
  std::string error;
  if (!lod::voxelize(mesh, vc, pyramid, error)) {
    std::fprintf(stderr, "igbench cells: %s\n", error.c_str());
    return 1;
  }
  lod::CellTree tree;
  lod::CellBuildConfig bc;
  bc.cellLevels = o.cellLevels;
  bc.cellVoxelDepth = o.cellVoxelDepth;
  if (!lod::buildCellTree(pyramid, bc, tree, error)) {
    std::fprintf(stderr, "igbench cells: %s\n", error.c_str());
    return 1;
  }
  const double buildMs = msSince(tBuild);
  if (!o.dumpTree.empty()) return dumpTree(tree, o.dumpTree);
  std::vector<double> dimension;
  for (int l = 0; l < pyramid.levels(); ++l) dimension.push_back(pyramid.dimension(l));
  std::vector<double> boxCounting;  // the paper's Table 1: log2 N(l) / l, levels 1 .. L
  for (int l = 1; l <= pyramid.levels(); ++l) boxCounting.push_back(pyramid.boxCountingDimension(l));
  std::vector<size_t> voxelsPerLevel;
  for (int l = 0; l <= pyramid.levels(); ++l) voxelsPerLevel.push_back(pyramid.count(l));
  uint32_t largestCell = 0;
  for (uint32_t c = 0; c < tree.size(); ++c) largestCell = std::max(largestCell, tree.bytes(c));
  pyramid = {};

  std::vector<lod::CellDraw> draw(tree.size());
  std::vector<uint32_t> requests(tree.size());

  // The path, streaming: nothing resident at the start, requests arrive latencyFrames later.
  // Replayed `repeats` times with a fresh selector and nothing resident: the selection depends on
  // the views and the arrivals only (never on the clock), so every replay makes the same choices
  // (checked: `replays_differ_frames`), and a frame's time is the fastest of its replays (what
  // other processes on the machine add is not the selection's cost). With two select threads each
  // replay runs twice, on two threads and on one, alternating, so that the two are compared in the
  // same minutes; both must choose the same (`threads_differ_frames`).
  const int repeats = std::max(1, o.repeats);
  const bool twoThreads = o.selectThreads >= 2;
  std::unique_ptr<WorkerPair> workers;
  if (twoThreads) workers = std::make_unique<WorkerPair>();
  std::vector<lod::Residency> residency(tree.size());
  std::vector<int> arrival(tree.size(), 0);
  std::vector<uint32_t> inFlight;
  inFlight.reserve(tree.size());
  // The simulated fetcher: nothing resident at the start of a replay; a frame's requests arrive
  // latencyFrames later.
  const auto startReplay = [&] {
    std::fill(residency.begin(), residency.end(), lod::Residency::Absent);
    inFlight.clear();
  };
  const auto deliver = [&](int frame) {
    size_t keep = 0;
    for (uint32_t c : inFlight) {
      if (arrival[c] <= frame) residency[c] = lod::Residency::Resident;
      else inFlight[keep++] = c;
    }
    inFlight.resize(keep);
  };
  const auto fetch = [&](const lod::CellSelectStats& s, int frame) {
    for (uint32_t k = 0; k < s.requestedCells; ++k) {
      residency[requests[k]] = lod::Residency::InFlight;
      arrival[requests[k]] = frame + o.latencyFrames;
      inFlight.push_back(requests[k]);
    }
  };
  lod::CellSelectorConfig selectorConfig;
  if (o.maxOps > 0) selectorConfig.maxOperations = o.maxOps;
  lod::CellSelectorConfig oneThreadConfig = selectorConfig;
  selectorConfig.runner = workers.get();
  lod::CellView view;
  view.viewportHeight_px = o.height_px;
  view.minVoxel_px = 1.0;
  view.voxelBudget = o.voxelBudget;
  view.byteBudget = o.wBytes;
  std::vector<double> selectMs(static_cast<size_t>(o.frames), 1e300), oneThreadMs(selectMs), firstMs, voxelsDrawn,
      quality, cutCells;
  std::vector<uint64_t> signature(static_cast<size_t>(o.frames), 0);
  std::vector<lod::CellSelectStats> firstStats;  // the first replay's, per frame (--trace)
  uint64_t bytesMax = 0, bytesTotal = 0;
  // Frames over a budget (drawn voxels > voxel budget or requested bytes > W, path and sweep):
  // the exit status is 1 if there is any.
  int exceeded = 0, teleportFrame = 2 * o.frames / 3, fullQualityFrame = -1, replaysDiffer = 0, threadsDiffer = 0;
  uint32_t unfetchable = 0;
  for (int run = 0; run < repeats * (twoThreads ? 2 : 1); ++run) {
    const bool oneThread = twoThreads && run % 2 == 1;
    lod::CellSelector selector(tree, oneThread ? oneThreadConfig : selectorConfig);
    startReplay();
    for (int i = 0; i < o.frames; ++i) {
      deliver(i);
      view.camera = cellsPathCamera(i, o.frames);
      view.camera.aspect = 16.0 / 9.0;
      const auto t0 = BenchClock::now();
      const lod::CellSelectStats s = selector.select(view, residency, draw, requests);
      const double ms = msSince(t0);
      const size_t fi = static_cast<size_t>(i);
      std::vector<double>& times = oneThread ? oneThreadMs : selectMs;
      times[fi] = std::min(times[fi], ms);
      const uint64_t sig = choiceSignature(s, draw, requests);
      if (run == 0) {
        signature[fi] = sig;
        firstMs.push_back(ms);
        voxelsDrawn.push_back(static_cast<double>(s.drawnVoxels));
        quality.push_back(static_cast<double>(s.maxVoxel_px));
        cutCells.push_back(s.cutCells);
        firstStats.push_back(s);
        if (s.drawnVoxels > o.voxelBudget || s.requestedBytes > o.wBytes || !s.valid) ++exceeded;
        bytesMax = std::max(bytesMax, s.requestedBytes);
        bytesTotal += s.requestedBytes;
        unfetchable = std::max(unfetchable, s.unfetchable);
      } else if (sig != signature[fi]) {
        ++(oneThread ? threadsDiffer : replaysDiffer);
      }
      fetch(s, i);
      if (run == 0 && i >= teleportFrame && fullQualityFrame < 0 && s.requestedCells == 0 && s.blockedSplits == 0 &&
          inFlight.empty())
        fullQualityFrame = i;
    }
  }
  const double teleportMs = selectMs[static_cast<size_t>(teleportFrame)];

  // The path under a deadline (igd's cells phase budget, ig/cells_deadline.h): each select() held
  // to deadline_ms. Its choices depend on the clock, so the replays are not compared; their frames
  // are pooled. Against the path above: how many frames the voxels drawn take to fill, from the
  // start and after the teleport, to 95 % of the most the path above drew in that part (the
  // budget, unless the view holds fewer).
  const auto framesToFill = [&](const std::vector<double>& drawn, bool afterTeleport) {
    const int from = afterTeleport ? teleportFrame : 0, to = afterTeleport ? o.frames : teleportFrame;
    const double full = *std::max_element(voxelsDrawn.begin() + from, voxelsDrawn.begin() + to);
    for (int i = from; i < to && i < static_cast<int>(drawn.size()); ++i)
      if (drawn[static_cast<size_t>(i)] >= 0.95 * full) return i - from;
    return -1;
  };
  std::vector<double> deadlineMs, deadlineQuality, deadlineDrawn;  // deadlineDrawn: the first replay's, per frame
  std::vector<char> deadlineStopped;                                  // the first replay's, per frame
  int stoppedFrames = 0, deadlineFill = -1, deadlineFillTeleport = -1;
  if (o.deadline_ms > 0.0) {
    int fillSum = 0, fillTeleportSum = 0, fills = 0, fillsTeleport = 0;
    for (int run = 0; run < repeats; ++run) {
      lod::CellSelector selector(tree, selectorConfig);
      startReplay();
      std::vector<double> drawn;
      const MonotonicClock clock;
      CellSelectDeadline deadline;
      lod::CellView dv = view;
      for (int i = 0; i < o.frames; ++i) {
        deliver(i);
        dv.camera = cellsPathCamera(i, o.frames);
        dv.camera.aspect = 16.0 / 9.0;
        const auto t0 = BenchClock::now();
        deadline.arm(dv, clock, clock.now_ns(), o.deadline_ms);
        const lod::CellSelectStats s = selector.select(dv, residency, draw, requests);
        deadline.done(dv);
        deadlineMs.push_back(msSince(t0));
        stoppedFrames += s.stopped ? 1 : 0;
        if (run == 0) deadlineStopped.push_back(s.stopped ? 1 : 0);
        deadlineQuality.push_back(static_cast<double>(s.maxVoxel_px));
        drawn.push_back(static_cast<double>(s.drawnVoxels));
        if (s.drawnVoxels > o.voxelBudget || s.requestedBytes > o.wBytes || !s.valid) ++exceeded;
        fetch(s, i);
      }
      if (run == 0) deadlineDrawn = drawn;
      if (const int f = framesToFill(drawn, false); f >= 0) fillSum += f, ++fills;
      if (const int f = framesToFill(drawn, true); f >= 0) fillTeleportSum += f, ++fillsTeleport;
    }
    // The mean over the replays (-1: some replay never filled).
    deadlineFill = fills == repeats ? (fillSum + repeats / 2) / repeats : -1;
    deadlineFillTeleport = fillsTeleport == repeats ? (fillTeleportSum + repeats / 2) / repeats : -1;
  }
  const int fill = framesToFill(voxelsDrawn, false), fillTeleport = framesToFill(voxelsDrawn, true);
  // Each path frame's fastest deadline replay (the replays' choices may differ, since the stop
  // reads the clock; each replay holds every frame to the same deadline).
  std::vector<double> deadlineFastestMs;
  if (!deadlineMs.empty()) {
    deadlineFastestMs.assign(static_cast<size_t>(o.frames), 1e300);
    for (size_t k = 0; k < deadlineMs.size(); ++k)
      deadlineFastestMs[k % deadlineFastestMs.size()] = std::min(deadlineFastestMs[k % deadlineFastestMs.size()], deadlineMs[k]);
  }
  if (!o.trace.empty()) {
    std::FILE* f = std::fopen(o.trace.c_str(), "w");
    if (f == nullptr) {
      std::fprintf(stderr, "igbench cells: cannot write the trace %s: %s\n", o.trace.c_str(), std::strerror(errno));
      return 1;
    }
    std::fprintf(f, "frame,select_ms,select_ms_one_thread,cut_cells,drawn_voxels,max_voxel_px,splits,merges,"
                    "blocked_splits,requested_cells,requested_bytes,deadline_ms_fastest,deadline_ms_first,deadline_stopped_first\n");
    for (size_t i = 0; i < firstStats.size(); ++i) {
      const lod::CellSelectStats& s = firstStats[i];
      const bool dl = i < deadlineStopped.size();
      std::fprintf(f, "%zu,%.4f,%.4f,%u,%llu,%.3f,%u,%u,%u,%u,%llu,%.4f,%.4f,%d\n", i, selectMs[i],
                   twoThreads ? oneThreadMs[i] : selectMs[i], s.cutCells, static_cast<unsigned long long>(s.drawnVoxels),
                   static_cast<double>(s.maxVoxel_px), s.splits, s.merges, s.blockedSplits, s.requestedCells,
                   static_cast<unsigned long long>(s.requestedBytes), dl ? deadlineFastestMs[i] : -1.0, dl ? deadlineMs[i] : -1.0,
                   dl ? int{deadlineStopped[i]} : -1);
    }
    if (std::fclose(f) != 0) {
      std::fprintf(stderr, "igbench cells: cannot write the trace %s\n", o.trace.c_str());
      return 1;
    }
  }

  // Sweep over voxel budgets, everything resident, over every 4th frame of the path (replayed
  // as the path is, each frame's fastest time).
  std::vector<SweepPoint> sweep;
  for (double f : {0.0625, 0.125, 0.25, 0.5, 1.0, 2.0, 4.0}) {
    SweepPoint p;
    p.budget = static_cast<uint64_t>(f * static_cast<double>(o.voxelBudget));
    lod::CellView v = view;
    v.voxelBudget = p.budget;
    v.byteBudget = o.wBytes;
    std::vector<double> q, ms, ms1, vox, cut;
    std::vector<uint64_t> sigs;
    for (int run = 0; run < repeats * (twoThreads ? 2 : 1); ++run) {
      const bool oneThread = twoThreads && run % 2 == 1;
      lod::CellSelectorConfig sweepConfig;
      sweepConfig.runner = oneThread ? nullptr : workers.get();
      lod::CellSelector sel(tree, sweepConfig);
      size_t k = 0;
      for (int i = 0; i < o.frames; i += 4) {
        v.camera = cellsPathCamera(i, o.frames);
        const auto t0 = BenchClock::now();
        const lod::CellSelectStats s = sel.select(v, {}, draw, requests);
        const double dt = msSince(t0);
        if (run == 0 && (!s.valid || s.drawnVoxels > p.budget || s.requestedBytes > v.byteBudget)) ++exceeded;
        if (i == 0 || i == ((teleportFrame + 3) / 4) * 4) continue;  // from the root / the teleport: not steady
        if (run > 0) {
          std::vector<double>& times = oneThread ? ms1 : ms;
          if (times.size() <= k) times.push_back(dt);
          else times[k] = std::min(times[k], dt);
          if (choiceSignature(s, draw, requests) != sigs[k]) ++(oneThread ? threadsDiffer : replaysDiffer);
          ++k;
          continue;
        }
        ms.push_back(dt);
        sigs.push_back(choiceSignature(s, draw, requests));
        q.push_back(static_cast<double>(s.maxVoxel_px));
        vox.push_back(static_cast<double>(s.drawnVoxels));
        cut.push_back(s.cutCells);
      }
    }
    if (twoThreads) {
      p.oneThreadP50_ms = percentile(ms1, 50);
      p.oneThreadP99_ms = percentile(ms1, 99);
    }
    p.cutCellsP50 = static_cast<uint64_t>(percentile(cut, 50));
    p.minQualityP50_px = percentile(q, 50);
    p.minQualityMax_px = *std::max_element(q.begin(), q.end());
    p.selectP50_ms = percentile(ms, 50);
    p.selectP99_ms = percentile(ms, 99);
    p.voxelsP50 = static_cast<uint64_t>(percentile(vox, 50));
    sweep.push_back(p);
  }

  // The bunny: PSNR sweep and streaming through nginx.
  CellsStreamBenchResult bunny;
  if (o.withMesh) {
    std::string err;
    if (!runCellsStreamBench(o.mesh, bunny, err)) {
      std::fprintf(stderr, "igbench cells: %s\n", err.c_str());
      return 3;
    }
    for (const CellsStreamRun& r : bunny.runs) exceeded += r.budgetExceededFrames;
  }

  // Settled: the first frame after the teleport with nothing requested, no split blocked and
  // nothing in flight. The viewer keeps moving after the teleport, so on a large scene (the
  // default path) every frame requests the cells coming into view and it never settles: null in
  // the JSON ("never" in the summary), not -1 (docs/cells.md, Benchmark).
  const double secondsToFull = fullQualityFrame < 0 ? -1.0 : (fullQualityFrame - teleportFrame) / 60.0;
  const std::string settleFrames = fullQualityFrame < 0 ? "null" : std::to_string(fullQualityFrame - teleportFrame);
  char settleSecondsBuf[32];
  std::snprintf(settleSecondsBuf, sizeof settleSecondsBuf, "%.3f", secondsToFull);
  const std::string settleSeconds = fullQualityFrame < 0 ? "null" : settleSecondsBuf;
  if (o.json) {
    std::printf("{\"suite\":\"cells\",\"spheres\":%d,\"cells\":%u,\"levels\":%d,\"cell_voxel_depth\":%d,"
                "\"build_ms\":%.0f,\"total_bytes\":%llu,\"largest_cell_bytes\":%u,\"voxels_per_level\":[",
                o.spheres, tree.size(), tree.levels(), o.cellVoxelDepth, buildMs,
                static_cast<unsigned long long>(tree.totalBytes()), largestCell);
    for (size_t l = 0; l < voxelsPerLevel.size(); ++l) std::printf("%s%zu", l ? "," : "", voxelsPerLevel[l]);
    std::printf("],\"dimension\":[");
    for (size_t l = 0; l < dimension.size(); ++l) std::printf("%s%.4f", l ? "," : "", dimension[l]);
    std::printf("],\"box_counting_dimension\":[");
    for (size_t l = 0; l < boxCounting.size(); ++l) std::printf("%s%.4f", l ? "," : "", boxCounting[l]);
    std::printf("],\"frames\":%d,\"latency_frames\":%d,\"max_ops\":%u,\"select_ms_p50\":%.4f,\"select_ms_p99\":%.4f,"
                "\"select_ms_max\":%.4f,\"teleport_select_ms\":%.4f,\"voxels_drawn_p50\":%.0f,\"voxel_budget\":%llu,"
                "\"budget_exceeded_frames\":%d,\"bytes_per_frame_max\":%llu,\"w_bytes\":%llu,\"bytes_total\":%llu,"
                "\"unfetchable_cells\":%u,\"frames_to_settle_after_teleport\":%s,\"seconds_to_settle_after_teleport\":%s,"
                "\"max_voxel_px_p50\":%.3f,\"cut_cells_p50\":%.0f,\"repeats\":%d,\"select_ms_p99_first_replay\":%.4f,"
                "\"replays_differ_frames\":%d,\"select_threads\":%d,\"select_ms_p50_one_thread\":%.4f,"
                "\"select_ms_p99_one_thread\":%.4f,\"threads_differ_frames\":%d,\"frames_to_fill\":%d,"
                "\"frames_to_fill_after_teleport\":%d,\"select_sweep\":[",
                o.frames, o.latencyFrames, o.maxOps, percentile(selectMs, 50), percentile(selectMs, 99),
                *std::max_element(selectMs.begin(), selectMs.end()), teleportMs, percentile(voxelsDrawn, 50),
                static_cast<unsigned long long>(o.voxelBudget), exceeded, static_cast<unsigned long long>(bytesMax),
                static_cast<unsigned long long>(o.wBytes), static_cast<unsigned long long>(bytesTotal), unfetchable,
                settleFrames.c_str(), settleSeconds.c_str(), percentile(quality, 50),
                percentile(cutCells, 50), repeats, percentile(firstMs, 99), replaysDiffer, twoThreads ? 2 : 1,
                twoThreads ? percentile(oneThreadMs, 50) : percentile(selectMs, 50),
                twoThreads ? percentile(oneThreadMs, 99) : percentile(selectMs, 99), threadsDiffer, fill, fillTeleport);
    for (size_t k = 0; k < sweep.size(); ++k) {
      const SweepPoint& p = sweep[k];
      std::printf("%s{\"voxel_budget\":%llu,\"voxels_drawn_p50\":%llu,\"min_quality_px\":%.3f,\"min_quality_px_max\":%.3f,"
                  "\"cut_cells_p50\":%llu,\"select_ms\":%.4f,\"select_ms_p99\":%.4f,\"select_ms_one_thread\":%.4f,"
                  "\"select_ms_p99_one_thread\":%.4f}",
                  k ? "," : "", static_cast<unsigned long long>(p.budget), static_cast<unsigned long long>(p.voxelsP50),
                  p.minQualityP50_px, p.minQualityMax_px, static_cast<unsigned long long>(p.cutCellsP50), p.selectP50_ms,
                  p.selectP99_ms, twoThreads ? p.oneThreadP50_ms : p.selectP50_ms,
                  twoThreads ? p.oneThreadP99_ms : p.selectP99_ms);
    }
    std::printf("]");
    if (o.deadline_ms > 0.0)
      std::printf(",\"deadline\":{\"deadline_ms\":%.3f,\"replays\":%d,\"select_ms_p50\":%.4f,\"select_ms_p99\":%.4f,"
                  "\"select_ms_max\":%.4f,\"stopped_frames\":%d,\"frames\":%zu,\"frames_to_fill\":%d,"
                  "\"frames_to_fill_after_teleport\":%d,\"max_voxel_px_p50\":%.3f,\"select_ms_p50_fastest\":%.4f,"
                  "\"select_ms_p99_fastest\":%.4f}",
                  o.deadline_ms, repeats, percentile(deadlineMs, 50), percentile(deadlineMs, 99),
                  *std::max_element(deadlineMs.begin(), deadlineMs.end()), stoppedFrames, deadlineMs.size(), deadlineFill,
                  deadlineFillTeleport, percentile(deadlineQuality, 50), percentile(deadlineFastestMs, 50),
                  percentile(deadlineFastestMs, 99));
    // Per path frame (scripts/plot_cells.py): voxels drawn in the first replay, without and with
    // the deadline, and the select time (the fastest replay's) without it.
    const auto printArray = [](const char* name, const std::vector<double>& v, int decimals) {
      std::printf(",\"%s\":[", name);
      for (size_t k = 0; k < v.size(); ++k) std::printf("%s%.*f", k ? "," : "", decimals, v[k]);
      std::printf("]");
    };
    printArray("path_voxels_drawn", voxelsDrawn, 0);
    printArray("path_select_ms", selectMs, 4);
    if (o.deadline_ms > 0.0) printArray("path_voxels_drawn_deadline", deadlineDrawn, 0);
    std::printf(",\"teleport_frame\":%d", teleportFrame);
    if (o.withMesh) {
      std::printf(",%s,\"seconds_to_full_quality\":{", cellsStreamJson(bunny).c_str());
      for (size_t k = 0; k < bunny.runs.size(); ++k)
        std::printf("%s\"%g\":%.3f", k ? "," : "", bunny.runs[k].rate_mbit, bunny.runs[k].secondsToFullQuality);
      std::printf("},\"gl\":%s", jsonString(bunny.context).c_str());
    }
    std::printf("}\n");
  } else {
    std::printf("cells suite: %d spheres -> %u cells, %d levels (voxels of %.2f m), built in %.0f ms, %.1f MB\n",
                o.spheres, tree.size(), tree.levels(), tree.voxelEdge_m(tree.levels() - 1), buildMs,
                static_cast<double>(tree.totalBytes()) / 1e6);
    std::printf("  dimension per level:");
    for (double d : dimension) std::printf(" %.3f", d);
    std::printf("\n  box-counting dimension log2 N(l) / l (the paper's Table 1), levels 1 ..:");
    for (double d : boxCounting) std::printf(" %.3f", d);
    std::printf("\n  path (%d frames, teleport at %d, streaming W = %llu B/frame, latency %d frames):\n", o.frames,
                teleportFrame, static_cast<unsigned long long>(o.wBytes), o.latencyFrames);
    std::printf("    select p50 %.3f ms, p99 %.3f ms (fastest of %d replays per frame; one replay: p99 %.3f ms, replays "
                "that chose differently: %d frames), teleport %.3f ms; voxels drawn p50 %.0f of %llu; over budget: %d "
                "frames; bytes/frame max %llu; %s after the teleport\n",
                percentile(selectMs, 50), percentile(selectMs, 99), repeats, percentile(firstMs, 99), replaysDiffer,
                teleportMs, percentile(voxelsDrawn, 50), static_cast<unsigned long long>(o.voxelBudget), exceeded,
                static_cast<unsigned long long>(bytesMax),
                fullQualityFrame < 0 ? "never settled (nothing requested, blocked or in flight)"
                                     : ("settled " + settleSeconds + " s").c_str());
    if (twoThreads)
      std::printf("    on %d select threads; the same frames on one thread: p50 %.3f ms, p99 %.3f ms (frames that chose "
                  "differently: %d)\n",
                  2, percentile(oneThreadMs, 50), percentile(oneThreadMs, 99), threadsDiffer);
    std::printf("    the voxels drawn reached 95 %% of their most %d frames after the start, %d after the teleport\n", fill, fillTeleport);
    if (o.deadline_ms > 0.0)
      std::printf("  path with each select() held to %.2f ms (the refinement stopped early enough; %d replays pooled): select "
                  "p50 %.3f ms, p99 %.3f ms, max %.3f ms; stopped in %d of %zu frames; the voxels drawn reached 95 %% of "
                  "the most above %d frames after the start, %d after the teleport; largest voxel p50 %.2f px (without: %.2f); "
                  "each frame's fastest replay: p50 %.3f ms, p99 %.3f ms\n",
                  o.deadline_ms, repeats, percentile(deadlineMs, 50), percentile(deadlineMs, 99),
                  *std::max_element(deadlineMs.begin(), deadlineMs.end()), stoppedFrames, deadlineMs.size(), deadlineFill,
                  deadlineFillTeleport, percentile(deadlineQuality, 50), percentile(quality, 50),
                  percentile(deadlineFastestMs, 50), percentile(deadlineFastestMs, 99));
    std::printf("  sweep (all resident): budget, voxels p50, largest voxel px p50 / max, cut cells p50, select ms p50 / p99"
                "%s\n", twoThreads ? ", one thread p50 / p99" : "");
    for (const SweepPoint& p : sweep) {
      std::printf("    %9llu %9llu %8.2f %8.2f %8llu %8.3f %8.3f", static_cast<unsigned long long>(p.budget),
                  static_cast<unsigned long long>(p.voxelsP50), p.minQualityP50_px, p.minQualityMax_px,
                  static_cast<unsigned long long>(p.cutCellsP50), p.selectP50_ms, p.selectP99_ms);
      if (twoThreads) std::printf(" %8.3f %8.3f", p.oneThreadP50_ms, p.oneThreadP99_ms);
      std::printf("\n");
    }
    if (o.withMesh) {
      std::printf("  mesh %s: %u cells, %d levels, %.1f MB; full detail %llu voxels drawn in %.1f ms\n",
                  o.mesh.mesh.c_str(), bunny.cells, bunny.levels, static_cast<double>(bunny.fileBytes) / 1e6,
                  static_cast<unsigned long long>(bunny.fullVoxels), bunny.fullRenderMs);
      std::printf("  sweep (all resident): budget, voxels, largest voxel px, select ms, render ms, PSNR dB vs full detail\n");
      for (const CellsSweepRow& r : bunny.sweep)
        std::printf("    %9llu %9llu %8.2f %8.3f %8.1f %7.2f\n", static_cast<unsigned long long>(r.budget),
                    static_cast<unsigned long long>(r.voxels), r.maxVoxel_px, r.selectMs, r.renderMs, r.psnr_db);
      for (const CellsStreamRun& r : bunny.runs)
        std::printf("  nginx at %g Mbit/s (W = %llu B/frame): full quality %.2f s after the teleport (warm-up %.2f s), "
                    "quality monotonic %s, %llu bytes, %.2f Mbit/s effective\n",
                    r.rate_mbit, static_cast<unsigned long long>(r.wBytes), r.secondsToFullQuality, r.warmupSeconds,
                    r.qualityMonotonic ? "yes" : "NO", static_cast<unsigned long long>(r.arrivedBytes), r.effectiveMbit);
    }
  }
  return exceeded == 0 && threadsDiffer == 0 ? 0 : 1;
}

}  // namespace ig
