// Geomorphing against popping: a vertex that a split adds starts at the height the coarser
// mesh had there (the midpoint of its diamond's hypotenuse, lod/roam.h splitEnds) and moves to
// its true height over morph_s seconds of simulation time (Geomorph). Merges morph out
// (MorphOut, below): the fine triangles stay drawn while each removed vertex moves onto the
// coarse surface, then the coarse triangles replace them.
//
// Fixed-capacity open-addressing table keyed by grid vertex, allocated at construction; no
// allocation per frame. When it is full a new vertex simply pops.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "lod/roam.h"

namespace ig::lod {

class Geomorph {
 public:
  // splits = false: startSplits is never called (MorphOut), which spares its scratch set.
  Geomorph(size_t capacity, double morph_s, bool splits = true);

  // Starts morphing vertex (x, y) from startHeight_m at time now_s (ignored if it is already
  // morphing, the table is full or now_s is not finite: every start* ignores such a time).
  void start(int x, int y, float startHeight_m, double now_s);
  // Starts the morphs of the vertices the last update of `roam` created (Roam::createdVertices,
  // coarse before fine), each from the height the surface drawn so far had there: the midpoint
  // of its split ends (Roam::splitEnds) as they are drawn at now_s. An end created earlier in
  // the same update, or still on its way from an earlier one, is not at its true height yet,
  // so the midpoint of the true heights would make the new vertex pop (a refinement of several
  // levels in one update: the first frame, a teleport, a tolerance change). A vertex created
  // again while the morph of an earlier life still runs starts afresh. heights_m: the
  // samplesX x samplesY true heights the roam was built on (clamped at the edges).
  // On a DEM that is not 2^k + 1 samples a side, vertices beyond it are drawn clamped onto its
  // east / north edge (lod/roam.h): the start height is the drawn surface at that clamped
  // point (not always the midpoint of the ends), and from the first call on, every vertex
  // is keyed by the DEM sample it is drawn at, so the padded-grid vertices drawn at one point
  // share one morph (one height: no crack). A call naming another DEM drops every morph.
  void startSplits(const Roam& roam, std::span<const float> heights_m, int samplesX, int samplesY, double now_s);
  // Morph-out: vertex (x, y) moves from its true height to targetHeight_m over morph_s
  // (replaces a running morph of the vertex).
  void startOut(int x, int y, float targetHeight_m, double now_s);
  // The height to draw vertex (x, y) with at now_s (a NaN now_s: the morph's end height).
  float height(int x, int y, float trueHeight_m, double now_s) const;
  // How far the morph of (x, y) has gone at now_s, in [0, 1] (1 for a NaN now_s); -1 if it has no entry.
  double progress(int x, int y, double now_s) const;
  // True if (x, y) has a morph entry (running, or finished but not yet expired).
  bool contains(int x, int y) const { return live_ > 0 && table_[slot(key(x, y))].key != 0; }
  // True while any vertex is still morphing (callers can skip the per-triangle pass).
  bool active(double now_s) const { return live_ > 0 && now_s < lastEnd_s_; }
  // Drops finished morphs; call once a frame (cheap when nothing expired).
  void expire(double now_s);
  double morph_s() const { return morph_s_; }
  size_t size() const { return live_; }

 private:
  struct Entry {
    uint64_t key;       // 0 = empty
    double start_s;
    float startHeight_m;  // in: the height it starts from; out: the height it ends at
    bool out;
  };
  // Vertices drawn at one DEM sample (padded-grid vertices beyond the DEM, clamped onto its
  // edge) share one entry once startSplits has named the DEM (demX_ > 0).
  uint64_t key(int x, int y) const {
    if (demX_ > 0) {
      x = std::clamp(x, 0, demX_ - 1);
      y = std::clamp(y, 0, demY_ - 1);
    }
    return rawKey(x, y);
  }
  static uint64_t rawKey(int x, int y) {
    return ((static_cast<uint64_t>(static_cast<uint32_t>(x)) << 32) | static_cast<uint32_t>(y)) + 1;
  }
  size_t slot(uint64_t k) const;
  // In [0, 1]; a time that is not a number draws the morph as finished (std::clamp would pass
  // the NaN on into the height).
  double morphFraction(double now_s, double start_s) const {
    const double t = (now_s - start_s) / morph_s_;
    return !(t < 1.0) ? 1.0 : t > 0.0 ? t : 0.0;
  }

  double morph_s_;
  size_t capacity_;
  std::vector<Entry> table_, scratch_;
  // startSplits: set of the vertices created so far in this call (rawKey; an entry with another
  // call's stamp is empty, so it is never cleared).
  struct NewVertex {
    uint64_t key;
    uint32_t stamp;
  };
  std::vector<NewVertex> created_;
  uint32_t stamp_ = 0;
  size_t live_ = 0;
  double lastEnd_s_ = -1e300;
  int demX_ = 0, demY_ = 0;  // the DEM of startSplits (0: keys are the given vertices)
};

// Morph-out on merges. A merge replaces fine triangles by coarse ones and removes vertices;
// drawn at once, each removed vertex would jump from its true height onto the coarse surface
// (a pop). MorphOut keeps the removed fine triangles (ghosts) drawn for morph_s seconds while
// every removed vertex moves linearly from its true height to the coarse surface's height at
// that point, and hides the coarse triangles that replace them until then. At the end the
// ghosts lie exactly on the coarse triangles, so the swap does not show.
//
// Use, once a frame after the LOD update, with the triangles that left the mesh (e.g. from
// lod/triangle_slots.h), the triangle of the new mesh over each (Roam::leafAt) and the
// merge-removed vertices with their target heights (Roam::removedVertices, Roam::meshHeight):
//   morph.update(left, coverOf, removedVertices, targets, now);
//   draw morph.ghosts() (vertex heights from morph.height) and the mesh without the
//   triangles for which morph.hidden(t) is true; call morph.expire(now) at the end of a frame.
// A ghost whose cover leaves the mesh before the morph ends (the eye came back) is dropped
// (it pops, rarely). A cover is hidden only if the ghosts given for it tile it: `left` may
// hold only the triangles that were drawn (view-culled); a cover reaching beyond them is drawn
// under its ghosts rather than open a hole (hidden(t) false, coverHidden(i) false). Fixed capacity, allocated at construction; when full, new merges pop.
// Cover look-ups are linear in the live covers; above kMaxPairTests tests a frame's merges pop.
class MorphOut {
 public:
  static constexpr size_t kMaxPairTests = 1u << 20;
  MorphOut(size_t capacityTriangles, double morph_s);

  struct Stats {
    size_t ghostsAdded = 0, ghostsDropped = 0, popped = 0;
    size_t untiled = 0;  // new covers drawn under their ghosts (not tiled by them)
  };
  // left: triangles that left the mesh; coverOf[i]: the new mesh's triangle holding left[i]'s
  // centroid (Roam::leafAt(sum of its x, sum of its y)); removedVertices / targetHeights_m:
  // Roam::removedVertices() and Roam::meshHeight() there. A now_s that is not finite adds no
  // ghosts (the merges pop).
  Stats update(std::span<const RoamTriangle> left, std::span<const RoamTriangle> coverOf,
               std::span<const RoamVertex> removedVertices, std::span<const float> targetHeights_m, double now_s);
  // Ghost triangles to draw now (counter-clockwise seen from above, as Roam emits them).
  std::span<const RoamTriangle> ghosts() const { return {ghosts_.data(), ghostCount_}; }
  // True for a mesh triangle that ghosts still stand in for (draw it degenerate).
  bool hidden(const RoamTriangle& t) const;
  // Height to draw a ghost vertex with at now_s (true height for vertices that stay).
  float height(int x, int y, float trueHeight_m, double now_s) const;
  // How far removed vertex (x, y) has moved towards the coarse surface, in [0, 1]; -1 for a
  // vertex that stays. A renderer blends whatever else it draws per vertex (normals) with it.
  double progress(int x, int y, double now_s) const { return vertices_.progress(x, y, now_s); }
  // Ends finished morphs: their ghosts go, their covers show. Returns the covers released
  // (a renderer writes them into their slots again); valid until the next call.
  std::span<const RoamTriangle> expire(double now_s);
  bool active() const { return ghostCount_ > 0; }
  size_t coverCount() const { return coverCount_; }
  // Cover i (< coverCount()): a mesh triangle that ghosts stand in for, and whether it is to
  // be hidden now (a renderer finds its slot and draws it degenerate).
  const RoamTriangle& cover(size_t i) const { return covers_[i].tri; }
  bool coverHidden(size_t i) const { return covers_[i].hide; }
  size_t capacity() const { return capacity_; }

 private:
  struct Cover {
    RoamTriangle tri;
    double end_s;
    bool hide;  // false: not tiled by its ghosts, drawn under them
  };
  size_t findCover(const RoamTriangle& t) const;  // index or coverCount_
  double morph_s_;
  size_t capacity_;
  std::vector<RoamTriangle> ghosts_;
  std::vector<uint32_t> ghostCover_;  // per ghost: index into covers_
  std::vector<Cover> covers_;
  std::vector<RoamTriangle> released_;
  std::vector<uint32_t> remap_;
  std::vector<int64_t> area_;  // per new cover: twice the area of its ghosts
  size_t ghostCount_ = 0, coverCount_ = 0;
  Geomorph vertices_;  // removed vertices: start height and the target, as an out-morph
};

}  // namespace ig::lod
