// Calibration of the performance model of paper 002 (lod/perfmodel.h), run when a program starts
// (igbench perfmodel and adaptive; igd draws no dynamic objects and does not call it), on the GL
// implementation actually in use, with the material and box mesh of render/dynamic_pass.h:
//   frag_ns      1 vs 4 full-screen boxes drawn back to front (every fragment shaded): T_frag
//   frame_ns     the intercept of the same line (a frame that draws: clear, tiles, finish)
//   depthFrag_ns the same boxes depth-only, as occlusion boxes are drawn
//   tri_ns_12 ... tri_ns_768 (triByDraw_ns)  900 octree leaves holding 1, 2, 4 ... 64 tiny
//                boxes each (one instanced call per node) against a frame without boxes, less
//                the nodes' t_c, t_s and frustum tests: T_tri by the triangles of a call, from
//                the application thread's CPU time (llvmpipe's vertex stage runs on it)
//   tri_ns       the last of them (long calls; where the size of the calls is not known)
//   raster_tri_ns, edge_ns  6000 boxes of ~6 px and of ~30 px in front of a full-screen layer
//                against the layer alone, the rasterizer's side (after the GL calls returned),
//                fragments counted by GL_SAMPLES_PASSED: per triangle and per edge pixel
//   draw_raster_ns  the ~6 px boxes as per-object commands against their ~113 node ranges, the
//                rasterizer's side: per draw (taken out of raster_tri_ns)
//   command_ns   20000 tiny boxes as per-object commands vs the same in their 112 node ranges: t_c
//   submit_ns    900 tiny boxes, one per octree leaf, as node ranges vs per-object commands: t_s
//   state_ns     one tiny box per draw with a uniform change between draws, minus the box: T_state
//   cull_ns      per-object frustum tests of boxes behind the camera
//   rerecord_ns  every object moved each frame in octree mode (node ranges rewritten): t_r
//   occlusionTest_ns  q queries on tiny nodes minus the same frame without: one test
//   overlap, overlap_triangles  45,000 and 135,000 boxes of a few pixels: how much (2) without
//                overlap over-predicts each, as a share of the smaller stage; the line
//                w (1 - T0 / N_tri) through the two (a software rasterizer overlaps its stages
//                only once a frame overflows its scene buffer)
// Each constant is a difference between loads (lower quartile of repeated frames, glFinish + a
// monotonic clock), so fixed costs cancel. The loads of T_frag, T_tri, t_c, t_s, T_state,
// T_rtri and T_edge are measured interleaved, one timed frame of each per repeat (11 repeats,
// 25 with a budget of 8 s or more), so a slow phase of the machine weighs on all of them alike;
// each timed frame follows an untimed one of the same load (llvmpipe leaves part of a frame's
// work to the next frame, and the scenes modelled repeat from frame to frame);
// the others are the median of three slopes. With `runs` > 1 the whole measurement is repeated
// and each constant is the median of the runs. Results are
// cached in a small text file keyed by GL_VENDOR / GL_RENDERER / GL_VERSION, the CPU (model,
// the number this process may use, LP_NUM_THREADS when set), the material and the viewport; a
// cache for another key, or one that does not parse, is ignored and rewritten.
// The measurements run with a settled C heap (a large block freed first): glibc trims the heap
// top eagerly until a process frees its first large block, and llvmpipe allocates in every
// draw, so a fresh process would measure brk and page faults instead of the draws.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "lod/perfmodel.h"

namespace ig::render {

class DynamicPass;

// One frame of the interleaved loads (CalibrationOptions::trace), for looking at the noise
// behind a constant: each timed frame follows an untimed frame of the same load.
struct CalibrationFrame {
  int run = 0;             // 0 ... runs - 1
  int repeat = 0;          // 0 is the warm-up repeat (shaders compiled, node ranges built; not used)
  const char* load = "";   // calibrationLoadName(): full_1, layer_small, state_2000 ...
  bool timed = false;      // one of the frames the constants come from
  double frame_ms = 0.0;   // glFinish to glFinish
  double submit_ms = 0.0;  // until the GL calls returned (the rest is the rasterizer's)
  double thread_ms = 0.0;  // CPU time of the application thread until the GL calls returned
};

struct CalibrationOptions {
  int width_px = 640;          // viewport of the measurements (the fragment costs scale with it)
  int height_px = 360;
  uint32_t fragmentWork = 0;   // material: DynamicPassConfig::fragmentWork of the pass to model
  double budget_s = 3.0;       // repeats are cut when the measurements run longer than this
  bool ignoreCache = false;    // measure even if the cache matches (the cache is rewritten)
  int runs = 1;                // the measurements run this often (1 ... 9; budget_s each) and each
                               // constant is the median of the runs: a shared machine slows down
                               // in phases of seconds, and one run can fall into one
  std::vector<CalibrationFrame>* trace = nullptr;  // when set, every frame of the interleaved loads
  // Called after each run's measurements (run 0 ... runs - 1; not when the constants come from the
  // cache). igbench perfmodel draws a sweep of its scenes there, so that the calibration and the
  // frames it predicts share the minutes of a shared machine. False stops the calibration with
  // the error it sets.
  std::function<bool(int run, std::string& error)> afterRun;
};

struct CalibrationResult {
  lod::PerfConstants constants;
  bool fromCache = false;
  std::string key;             // what the cache is keyed by
  double seconds = 0.0;        // time spent measuring (0 from the cache)
};

// Needs a current GL context (render/context.h). `cachePath` may be empty (no cache). Returns
// false with a message when the measurements fail (GL errors, a constant not positive); a cache
// that cannot be written is not an error (the message goes to `warning`).
bool calibrate(const std::string& cachePath, const CalibrationOptions& options, CalibrationResult& out,
               std::string& error, std::string* warning = nullptr);

// The loads of T_tri by the size of a call (also for tests): `perNode` (1 ... 64) tiny boxes in
// each of the first `nodes` (<= 1344) 2 m leaves of an octree over +-64 m of depth 6 (the
// calibration's), 0.4 m apart on a 4 x 4 x 4 lattice inside the leaf: one instanced call of
// `perNode` boxes per leaf.
void addCalibrationGrid(DynamicPass& pass, uint32_t nodes, int perNode);

// The median of the runs' values of one constant (calibrate() with runs > 1): the nearest-rank
// p50, the lower middle of an even count, as ig::percentile (ig/stats.h). Preemption only adds
// time, so of two runs the faster is the undisturbed one. 0 for none.
double medianOfRuns(std::vector<double> values);

// The cache key of the current context for these options.
std::string calibrationKey(const CalibrationOptions& options);
// Cache file I/O (also for tests). read returns false with the reason when the file is absent,
// has another key or version, or a field is missing, repeated, not a number, negative or NaN.
bool readCalibrationCache(const std::string& path, const std::string& key, lod::PerfConstants& out,
                          std::string& why);
bool writeCalibrationCache(const std::string& path, const std::string& key, const lod::PerfConstants& c,
                           std::string& error);

}  // namespace ig::render
