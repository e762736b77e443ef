// igbench cells: hierarchical cells (paper 003) on a synthetic scene of many voxelized spheres
// (~1 M cells by default). Reports the HC (cells, levels, growth and box-counting dimensions per voxel
// level), the selection along a camera path with a teleport while cells stream in under a byte
// budget per frame (select time p50 / p99, drawn voxels, frames over a budget, bytes per frame),
// and a sweep over voxel budgets with everything resident (the largest on-screen voxel, select
// time), both replayed `repeats` times (each frame's time the fastest of its replays). With a
// mesh (ig/bench_cells_stream.h): the real bunny's PSNR sweep and streaming through nginx.
#pragma once

#include <cstdint>
#include <string>

#include "ig/bench_cells_stream.h"

namespace ig {

struct CellsBenchOptions {
  int spheres = 1100;           // procedural spheres in a 1024 m cube
  int cellLevels = 9;           // L: cell levels (the finest cells are 1024 / 2^(L-1) m)
  // d: voxel octree depth inside a cell (voxels of 1024 / 2^(L-1+d) m). 4 (16^3-voxel cells, 0.25 m
  // voxels): at 3 the path's nearest cells are leaves whose 0.5 m voxels are ~17 px on screen, so
  // the data, not the budget, bounds the picture, and the same 2 M voxels make a cut of 33,000
  // cells instead of 9,400 (the selection's time follows the cut's cells). Building the HC at 4
  // takes ~60 s and ~5.2 GB of memory (3: ~15 s, 1.5 GB). docs/cells.md, "Benchmark".
  int cellVoxelDepth = 4;
  int frames = 600;             // camera path length (60 Hz), a teleport at 2/3
  int height_px = 1080;         // viewport height (fovY 60 deg, 16:9)
  uint64_t voxelBudget = 2000000;  // voxels drawn per frame
  uint64_t wBytes = 1 << 20;       // W: bytes requested per frame
  int latencyFrames = 3;        // a requested cell arrives this many frames later
  // Splits + merges per frame on the path (CellSelectorConfig::maxOperations; 0: no cap). 256 at
  // 16^3-voxel cells: a split there moves ~8 times the voxels of one at 8^3 (where 512 was the
  // default), and the picture fills as fast as at 512 (the fetches, W and the latency, bound it).
  uint32_t maxOps = 256;
  uint32_t seed = 1;
  int repeats = 3;              // the path and the sweep replayed this often; each frame's time is the fastest
  int selectThreads = 2;        // 2: the selection's passes on two threads (ig/worker_pair.h), each replay also
                                // run on one thread for comparison; 1: one thread only
  double deadline_ms = 0.5;     // > 0: the path replayed again with each select() held to this time as igd's cells
                                // phase budget holds it (ig/cells_deadline.h, CellView::stop): its time, stopped
                                // frames and how much later the voxels drawn fill; 0: skip
  bool json = false;
  // The real mesh, the pictures and nginx (ig/bench_cells_stream.h); off: selection only.
  bool withMesh = true;
  CellsStreamBenchOptions mesh;
  // Non-empty: write the cell tree to this file (5 doubles: root corner x, y, z, root edge, voxel
  // depth; uint64 cell count; lod::CellDesc per cell) and exit (scripts/cells-ab).
  std::string dumpTree;
  // Non-empty: write one CSV row per path frame to this file (docs/cells.md, "Benchmark"): the
  // frame's select time (fastest replay, two threads and one), what the first replay did in it,
  // and the first deadline replay's time and whether its refinement was stopped.
  std::string trace;
};

int runCellsBench(const CellsBenchOptions& options);

}  // namespace ig
