// HDLOD, part 3: per-frame selection, paper 000 appendix 1 (DISPLAY_CLUSTER), no GL.
//
// From the root, for camera v, time t (clamped to [0, T]) and tolerance r (radians):
//
//   f_c(t) == 0                          -> skip the subtree (nothing of it is present)
//   box outside the view frustum         -> skip the subtree (dynamic leaves: the model box
//                                           moved to p_s(t); others: b_c)
//   leaf (an object)                     -> draw it (its error is 0: nothing finer exists), with
//                                           the coarsest version of its model whose measured
//                                           eps < r * distance(eye, box) (hdlod_build.h)
//   group (virtual root, dynamic group)  -> recurse
//   delta_c(t) < r * distance(eye, b_c)  -> good enough: draw g_c if f_c(t) >= 0.5, else skip
//                                           the whole subtree (most of it is absent)
//   otherwise                            -> recurse into the children
//
// delta_c(t) / distance is the angle the error subtends, so r is in radians;
// toleranceFromPixels() converts a screen-space tolerance in pixels. The test is written as
// delta < r * distance, so a camera inside (or on) a box, distance 0, is never "good enough":
// the traversal refines down to the objects. r = 0 selects exactly the present objects in the
// frustum (the same set as selectAll()).
//
// Output: (cluster, model matrix) draws into the caller's span, in traversal order; the count is
// returned. A draw of an Object or Dynamic cluster draws the scene model `cluster.mesh` with the
// matrix; a Merged cluster draws HdlodTree::meshes[cluster.mesh] with translate(origin). Dynamic
// objects' matrices (computed for time t) go into the caller's `moving` span. When a span is
// full, further draws are counted in stats but not written (size them with drawBound() and
// movingBound()). No allocation, no clock; recursion depth = tree depth. A box found inside a
// frustum plane is not tested against it again below (plane masking: same outcome, fewer tests).
//
// Bad input: a non-finite camera or time, a NaN tolerance, a field of view outside (0, 180)
// degrees, a non-positive aspect, or not 0 < near < far selects nothing and sets stats.rejected.
// A negative r is treated as 0; r = +inf accepts any error (the coarsest clusters present).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/mat4x4.hpp>

#include "lod/hdlod_build.h"
#include "lod/hdlod_scene.h"
#include "lod/view.h"

namespace ig::lod::hdlod {

struct Draw {
  uint32_t cluster = 0;
  // Object / Dynamic leaves: 0 = the scene model itself, k > 0 = its k-th coarser version
  // (HdlodTree::lodsOf(cluster.mesh)[k - 1]); always 0 for merged clusters.
  uint32_t lod = 0;
  // World matrix (double; the renderer makes it camera-relative): the tree's leafMatrix for
  // objects and merged clusters, an entry of the selection's `moving` span for dynamic objects.
  // Valid while the tree and that span are (until the next selection into the same span). A
  // pointer, not a copy: copying 128 bytes per draw into the list was 40 % of a cold selection
  // (docs/hdlod.md), and the renderer reads the matrix only for draws new to its lists.
  const glm::dmat4* model = nullptr;
};

struct SelectView {
  Camera camera;
  double time_s = 0.0;
  double tolerance_rad = 0.0;  // r
};

struct SelectStats {
  uint32_t visited = 0;   // clusters whose f_c(t) was evaluated
  uint32_t absent = 0;    // skipped: f_c(t) == 0
  uint32_t culled = 0;    // skipped: outside the frustum
  uint32_t halfSkipped = 0;  // good enough but f_c(t) < 0.5
  uint32_t draws = 0;     // selected (also those that did not fit into the span)
  uint64_t triangles = 0; // of the selected draws
  bool overflow = false;  // more draws than the span holds
  bool rejected = false;  // bad input, nothing selected
};

// Screen-space tolerance -> angle: r_px pixels of a viewport `viewportHeight_px` high with a
// vertical field of view fovY_deg (small-angle, at the centre of the screen).
double toleranceFromPixels(double r_px, double fovY_deg, double viewportHeight_px);

// The most draws any selection can produce (leaves + merged clusters).
size_t drawBound(const HdlodTree& tree);
// The most dynamic-object draws (matrices in `moving`) any selection can produce.
size_t movingBound(const HdlodTree& tree);

size_t selectHdlod(const HdlodTree& tree, const Scene& scene, const SelectView& view, std::span<Draw> out,
                   std::span<glm::dmat4> moving, SelectStats* stats = nullptr);

// The baseline without HDLOD: every present object whose box is in the frustum (r is ignored).
size_t selectAll(const HdlodTree& tree, const Scene& scene, const SelectView& view, std::span<Draw> out,
                 std::span<glm::dmat4> moving, SelectStats* stats = nullptr);

// A selection's output for one tree, sized once (no allocation per frame): the overloads below
// select into it and set `count`.
struct DrawList {
  explicit DrawList(const HdlodTree& tree) : draws(drawBound(tree)), moving(movingBound(tree)) {}
  std::vector<Draw> draws;
  std::vector<glm::dmat4> moving;
  size_t count = 0;
  std::span<const Draw> selected() const { return {draws.data(), count}; }
};

size_t selectHdlod(const HdlodTree& tree, const Scene& scene, const SelectView& view, DrawList& out, SelectStats* stats = nullptr);
size_t selectAll(const HdlodTree& tree, const Scene& scene, const SelectView& view, DrawList& out, SelectStats* stats = nullptr);

}  // namespace ig::lod::hdlod
