// Rendering performance model of paper 002 (adaptive rendering of dynamic scenes; see
// ../shared/SEEDS.md section 002): the memory model (1), the time model (2), the switching
// conditions (5) and (6) between the three strategies for dynamic objects, and the optimal
// number of occlusion tests q* of equation (11) from c(q), s(q), e(q) fitted online.
//
// Pure: no GL, no clock. Times are nanoseconds; the constants come from a calibration on the
// actual GL implementation (render/perf_calibration.h) and the statistics from the renderer.
//
// Input policy: a count or time that is NaN, infinite or negative is clamped to 0 (a count
// cannot be negative; an unknown statistic contributes nothing) and reported by the functions
// that return a bool; one above 1e150 counts as 1e150 (so that the predicted times stay finite).
// Fits reject such samples, and counts above 1e12 (add() returns false).
#pragma once

#include <array>
#include <cstdint>
#include <span>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

namespace ig::lod {

// ---------------------------------------------------------------------------------------------
// Memory model (1): M = N_vert M_vert + N_index M_index + N_tc M_tc + N_norm M_norm
//                       + sum M_tex + sum M_buf + sum M_desc.
struct MemoryModelInput {
  uint64_t vertices = 0, indices = 0, texCoords = 0, normals = 0;
  uint64_t vertexBytes = 12, indexBytes = 4, texCoordBytes = 8, normalBytes = 12;
  std::span<const uint64_t> textureBytes;     // one entry per texture
  std::span<const uint64_t> bufferBytes;      // command buffers, per-object matrix/colour buffers
  std::span<const uint64_t> descriptorBytes;  // API resource descriptions
};
// Bytes the scene needs in GPU memory; saturates at UINT64_MAX instead of wrapping.
uint64_t sceneMemoryBytes(const MemoryModelInput& in);

// ---------------------------------------------------------------------------------------------
// Time model (2), calibrated constants. All in nanoseconds, per unit named.
struct PerfConstants {
  double frame_ns = 0.0;          // fixed cost of a frame (clear, flush, finish, the tiles'
                                  // load and store); not in (2)
  double tri_ns = 0.0;            // T_tri: one triangle through the vertex stage (the material), in
                                  // long draws (and wherever the size of the draws is not known)
  // T_tri by the size of a submission (one multi-draw call). Entry i: one triangle in
  // submissions of 12 * 2^i triangles (1 ... 64 boxes of 12 triangles), each submission's t_c
  // and t_s charged apart. llvmpipe sets its vertex pipeline up per call and runs it per
  // instance: a box costs it more in a call of a few boxes than in one of 32 or more. All 0: not
  // measured, tri_ns for every draw. triangleCost_ns() interpolates in log2 of the triangles per
  // submission.
  static constexpr int kDrawSizes = 7;
  std::array<double, kDrawSizes> triByDraw_ns{};
  double frag_ns = 0.0;           // T_frag: one shaded fragment (the material)
  double rasterTri_ns = 0.0;      // one triangle through the rasterizer's set-up (edge equations,
                                  // binning into tiles), counted with the fragment stage
  double edge_ns = 0.0;           // per pixel of an object's footprint edge, sqrt(area): the
                                  // partly covered shading blocks along its (and its triangles')
                                  // edges, counted with the fragment stage
  double drawRaster_ns = 0.0;     // per draw command that reaches the rasterizer (each command of a
                                  // multi-draw call is a draw of its own there: its state and
                                  // commands binned into every tile it touches), counted with the
                                  // fragment stage
  double depthFrag_ns = 0.0;      // one depth-test-only fragment (occlusion boxes: T_z-buffer)
  double state_ns = 0.0;          // T_state: one pipeline state change (one draw set-up)
  double command_ns = 0.0;        // t_c: record and issue one draw command (in GL this includes
                                  // the driver's set-up of that draw), in a frame of commandCount
  // t_c grows once a frame's per-object commands and their records no longer fit the caches:
  // commandLarge_ns in a frame of commandLargeCount commands; commandCost_ns() interpolates in
  // log(commands) between the two. commandLargeCount <= commandCount: t_c is one constant.
  double commandCount = 0.0;
  double commandLarge_ns = 0.0;
  double commandLargeCount = 0.0;
  double rerecord_ns = 0.0;       // rewrite one object into a node's command range (octree modes)
  double submit_ns = 0.0;         // t_s: submit one command range (one GL multi-draw call),
                                  // beyond the commands in it
  double cull_ns = 0.0;           // one frustum test of a bounding box (T_fc per box)
  double occlusionTest_ns = 0.0;  // fixed cost of one occlusion test (query, box draw, read)
  // How much the pipeline stages inside each max() of (2) overlap: 1 = fully (the paper's max),
  // 0 = not at all (they add up). A software rasterizer (llvmpipe) bins the whole frame on the
  // application thread and rasterizes it at the flush, so the stages of a small frame add up;
  // once a frame's triangles overflow its scene buffer, earlier scenes are rasterized while
  // later ones are binned. So the overlap is w (1 - overlapTriangles / N_tri) for a frame of
  // N_tri triangles (0 below overlapTriangles); overlapTriangles = 0: always w (a GPU's pipeline).
  double overlap = 1.0;
  double overlapTriangles = 0.0;
};
// True if every constant is finite and >= 0, overlap is in [0, 1] and T_tri, T_frag are > 0.
// (The overlap of a frame is stageOverlap().)
bool valid(const PerfConstants& c);
// T_tri for submissions of `trianglesPerSubmission` triangles: triByDraw_ns interpolated
// linearly in log2(trianglesPerSubmission / 12), the end entries beyond the table; tri_ns when
// the table is not measured or the size is not a number > 0 (unknown: long draws).
double triangleCost_ns(const PerfConstants& c, double trianglesPerSubmission);
// t_c in a frame of `commands` draw commands: command_ns up to commandCount, commandLarge_ns
// from commandLargeCount on, linear in log(commands) between (command_ns when the two are not
// measured, or `commands` is not a number).
double commandCost_ns(const PerfConstants& c, double commands);

// Statistics of one set drawn in a frame: the objects S or the hierarchy H (bounding boxes of
// tested nodes). Counts, not times.
struct PassLoad {
  double triangles = 0;        // triangles submitted
  double fragments = 0;        // shaded fragments: samples that pass the depth test (a
                               // GL_SAMPLES_PASSED count of an earlier frame, or the projected
                               // areas where nothing is hidden)
  double edgePx = 0;           // sum over the objects drawn of sqrt(projected area in px), each
                               // weighted by its boxRasterShare() (see rasterShare)
  double rasterShare = 1;      // the share of the triangles and draw commands that reach the
                               // rasterizer: a triangle that covers no pixel centre is dropped
                               // in set-up (on llvmpipe on the application thread, which T_tri
                               // counts). The mean of boxRasterShare() over the objects drawn;
                               // 1 where the sizes are not known. Not finite: 1; clamped to [0, 1]
  double depthFragments = 0;   // depth-only fragments (occlusion boxes)
  double stateChanges = 0;     // draw set-ups / state changes
  double commands = 0;         // draw commands recorded / issued this frame
  double rerecorded = 0;       // objects rewritten into node command ranges this frame
  double submissions = 0;      // command ranges submitted
  double frustumTests = 0;     // boxes tested against the frustum
  double occlusionTests = 0;   // occlusion queries issued
};

struct TimeBreakdown {
  // Terms of (2), ns. *S = objects, *H = hierarchy.
  double bufS = 0, stateS = 0, vertS = 0, fragS = 0, fcS = 0;
  double bufH = 0, stateH = 0, vertH = 0, fragH = 0, zbufH = 0, fcH = 0;
  double gpuS = 0, gpuH = 0;  // the two max() terms
  double total = 0;
  // Which argument won each max(): 0 state, 1 vertex, 2 fragment, 3 z-buffer.
  int boundS = 0, boundH = 0;
};

// T(S,H) = T_frame + T_buf(S) + T_fc(S) + max(T_state(S), T_vert(S), T_frag(S))
//        + T_fc(H) + T_buf(H) + max(T_state(H), T_vert(H), T_frag(H), T_z(H))           (2)
// with T_buf = commands t_c(commands) + rerecorded t_r + submissions t_s + occlusionTests T_vis,
// T_vert = N_tri T_tri (3) with T_tri = triangleCost_ns(triangles / submissions),
// T_frag = f T_frag (4) + depthFragments T_z + rasterShare (N_tri T_rtri + commands T_draw) + edgePx T_edge
// (depthFragments: depth-only fragments drawn in that set; T_z = depthFrag_ns), T_state = stateChanges T_state,
// T_fc = frustumTests T_cull.
// This implementation's additions: T_fc(S) (per-object culling of strategy 1) and T_frame ((2)
// has T_fc only for H, and no fixed per-frame cost); in T_frag the rasterizer's cost per
// triangle, per edge pixel (the paper's "fragments" of a small object are mostly its edges:
// a rasterizer shades whole blocks) and per draw command (set up in each tile it touches); f counts the fragments that pass the depth test. Each max()
// is generalised by the overlap w of the frame, stageOverlap(): max(a, b, ..) + (1 - w)
// (a + b + .. - max(a, b, ..)), which is (2) for w = 1. Returns ns; `out` gets the terms.
// Invalid inputs (NaN, < 0) are clamped to 0; the return value is always finite and >= 0.
double predictFrame_ns(const PerfConstants& c, const PassLoad& objects, const PassLoad& hierarchy,
                       TimeBreakdown* out = nullptr);
// The overlap of the stages in a frame of `triangles` triangles: overlap * (1 - overlapTriangles /
// triangles), at least 0 (overlap when overlapTriangles is 0).
double stageOverlap(const PerfConstants& c, double triangles);

// One frame of the overlap calibration: its load and its measured time.
struct OverlapSample {
  PassLoad load;
  double measured_ns = 0;
};
// Fits k.overlap and k.overlapTriangles to two frames of different sizes (render/perf_calibration:
// 45,000 and 135,000 boxes of a few pixels). Each frame's w is what (2) without overlap, with the
// other constants of k, over-predicts it by, as a share of its smaller stage (state + vertex or
// fragment), clamped to [0, 1]; then the line w (1 - T0 / N_tri) through the two, with w <= 1
// and T0 >= 0; when the overlap does not grow with the size, the larger w and T0 = 0. The
// calibration fits each run, and again with the median of the runs' constants and the median of
// their times for these frames, so that the overlap agrees with the constants it is used with
// (the median of each constant alone may take T_rtri from one run and the overlap from another,
// fitted to that run's T_rtri). Returns k with the two fields set.
PerfConstants fitOverlap(PerfConstants k, const OverlapSample& small, const OverlapSample& large);

// The expected share of a box's triangles that reach the rasterizer, by its projected area A
// (px): a box smaller than a pixel covers a pixel centre with a probability of about its area,
// and one that covers none is dropped in set-up. min(1, A); 0 for A <= 0 or NaN. (Per triangle,
// min(1, A / 6) for the ~6 a box shows, predicted frames of 50,000 ... 100,000 boxes of ~1 ... 2 px
// 15 ... 34 % too fast on llvmpipe.) PassLoad::rasterShare is its mean over the objects drawn.
double boxRasterShare(double area_px);

// ---------------------------------------------------------------------------------------------
// Scene statistics helpers.

// Screen area in pixels covered by the box `corners` (8 points, eye-relative world metres)
// under `viewProjection` (projection * view rotation, camera-relative) on a width x height
// viewport: the area of the convex hull of the projected corners, clipped to the viewport.
// Returns -1 if a corner is at or behind the eye plane (clip w <= 1e-9: the caller decides; e.g.
// full screen); a corner between the eye and the near plane projects beyond the screen as usual.
double projectedBoxArea_px(const glm::dmat4& viewProjection, const std::array<glm::dvec3, 8>& corners,
                           double width_px, double height_px);


// ---------------------------------------------------------------------------------------------
// The three strategies for dynamic objects and the switching conditions (5) and (6).
enum class DynamicMode : uint8_t {
  PerCommand = 0,  // (1) per-object commands rebuilt every frame, per-object frustum culling
  Octree = 1,      // (2) single-reference octree, pre-built command range per node, node culling
  Occlusion = 2,   // (3) as (2) plus occlusion queries on q nodes, read frames later
};
const char* modeName(DynamicMode m);

// Predicted times of the terms of (5) and (6) for the current frame, ns.
struct ModeInputs {
  double bufS_ns = 0, fcS_ns = 0;   // (5) left:  T_buf(S) + T_fc(S), per-object commands
  double bufH_ns = 0, fcH_ns = 0;   // (5) right: T_buf(H) + T_fc(H), node command ranges
  double frameAll_ns = 0;           // (6) left:  T(S), everything in the visible nodes drawn
  double frameVisible_ns = 0;       // (6) right: T(S_vis), estimated hidden objects removed
  double visTests_ns = 0;           //            + T_vis(H), the occlusion tests
};

struct ModeSwitchConfig {
  double hysteresis = 0.15;  // a condition must fail by this fraction before the mode changes
  uint32_t minFrames = 10;   // frames a mode is kept at least after a change
};

// Mode choice with hysteresis:
//   PerCommand -> Octree     when (5) fails:  bufS + fcS > (bufH + fcH) (1 + h)
//   PerCommand -> Occlusion  when (5) holds but (6) fails and the per-object frame exceeds
//                            occlusion culling's: T(S) > T(S_vis) + T_vis(H) and
//                            T(S) - (bufH + fcH) + (bufS + fcS) > (T(S_vis) + T_vis(H)) (1 + h)
//                            (the estimate of hidden objects runs in PerCommand mode too)
//   Octree     -> PerCommand when (5) holds clearly: bufS + fcS < (bufH + fcH) (1 - h)
//   Octree     -> Occlusion  when (6) fails:  T(S) > (T(S_vis) + T_vis(H)) (1 + h)
//   Occlusion  -> Octree     when (6) holds clearly: T(S) < (T(S_vis) + T_vis(H)) (1 - h)
// At most one change per call, none within minFrames of the last one. NaN inputs are
// ignored (the mode is kept); update returns the mode for this frame.
class ModeSwitcher {
 public:
  explicit ModeSwitcher(ModeSwitchConfig config = {}, DynamicMode initial = DynamicMode::PerCommand)
      : config_(config), mode_(initial) {}
  DynamicMode update(const ModeInputs& in);
  DynamicMode mode() const { return mode_; }
  void force(DynamicMode m) { mode_ = m, framesInMode_ = 0; }
  uint32_t switches() const { return switches_; }

 private:
  ModeSwitchConfig config_;
  DynamicMode mode_;
  uint32_t framesInMode_ = 0;
  uint32_t switches_ = 0;
};

// ---------------------------------------------------------------------------------------------
// Optimal number of occlusion tests, (7)-(11):
//   T(q) = c(q) t_c + s(q) t_s + e(q) t_e                                                  (7)
//   c(q) = a_n c_n (n0 - s1 ln(1+q)) + q = cA - cB ln(1+q) + q                            (8)
//   s(q) = n0 + 1 - s1 ln(1+q)           = sA - s1 ln(1+q)                                (9)
//   e(q) = e0 + p q - e1 ln(1+q)                                                          (10)
//   q*   = (a_n c_n s1 t_c + s1 t_s + e1 t_e) / (p t_e + t_c) - 1                          (11)
// with cA = a_n c_n n0, cB = a_n c_n s1.
struct OcclusionCoefficients {
  double cA = 0, cB = 0;     // c(q) - q = cA - cB ln(1+q)
  double sA = 1, s1 = 0;     // s(q)
  double e0 = 0, p = 0, e1 = 0;
};
// Paper: one t_c for a re-recorded command and for a test command. Here tq_ns (the cost of a
// test) may differ from tc_ns (a re-recorded command); tq_ns < 0 means "same as tc_ns", which is
// (11) exactly. Then q* = (cB tc + s1 ts + e1 te) / (p te + tq) - 1.
struct OcclusionCosts {
  double tc_ns = 0, ts_ns = 0, te_ns = 0;  // per command, per submission, per limiting primitive
  double tq_ns = -1.0;                     // per occlusion test (< 0: tc_ns)
};
double occlusionFrame_ns(const OcclusionCoefficients& k, const OcclusionCosts& t, double q);  // (7)
// Stationary point (11); NaN when the denominator p t_e + t_c is not > 0.
double stationaryQ(const OcclusionCoefficients& k, const OcclusionCosts& t);
// Integer q in [0, n0] minimising (7): compares T(0), T(n0) and T at floor/ceil of q* clamped
// to [0, n0]. `time_ns` (optional) gets T at the result.
uint32_t optimalQ(const OcclusionCoefficients& k, const OcclusionCosts& t, uint32_t n0, double* time_ns = nullptr);

// Online least squares with exponential forgetting (weight `forget` per new sample, 1 = none)
// of the three regressions (8)-(10) from per-frame observations: q tests issued, c commands
// recorded, s ranges submitted, e primitives on the limiting stage.
class OcclusionFits {
 public:
  explicit OcclusionFits(double forget = 0.98) : forget_(forget) {}
  // False (sample ignored) if any value is NaN, infinite, negative or above 1e12 (a glitch: no
  // frame has that many; its square would swamp or overflow the sums).
  bool add(double q, double c, double s, double e);
  // False until the samples span at least three distinct q (the e fit has three unknowns)
  // and the normal equations are well conditioned.
  bool solve(OcclusionCoefficients& out) const;
  double samples() const { return n_; }
  void reset() { *this = OcclusionFits(forget_); }

 private:
  double forget_;
  double n_ = 0;
  // Weighted sums for regressors x = ln(1+q), q and targets y_c = c - q, y_s, y_e.
  double sx_ = 0, sxx_ = 0, sq_ = 0, sqq_ = 0, sxq_ = 0;
  double syc_ = 0, sxyc_ = 0, sys_ = 0, sxys_ = 0, sye_ = 0, sxye_ = 0, sqye_ = 0;
  uint32_t distinct_ = 0;
  double lastQ_[3] = {-1, -1, -1};
};

}  // namespace ig::lod
