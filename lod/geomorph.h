// Geomorphing against popping: a vertex that a split adds starts at the height the coarser
// mesh had there (the midpoint of its diamond's hypotenuse, lod/roam.h splitEnds) and moves to
// its true height over morph_s seconds of simulation time. Vertices removed by merges pop (no
// morph-out).
//
// Fixed-capacity open-addressing table keyed by grid vertex, allocated at construction; no
// allocation per frame. When it is full a new vertex simply pops.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace ig::lod {

class Geomorph {
 public:
  Geomorph(size_t capacity, double morph_s);

  // Starts morphing vertex (x, y) from startHeight_m at time now_s (ignored if it is already
  // morphing or the table is full).
  void start(int x, int y, float startHeight_m, double now_s);
  // The height to draw vertex (x, y) with at now_s.
  float height(int x, int y, float trueHeight_m, double now_s) const;
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
    float startHeight_m;
  };
  static uint64_t key(int x, int y) {
    return ((static_cast<uint64_t>(static_cast<uint32_t>(x)) << 32) | static_cast<uint32_t>(y)) + 1;
  }
  size_t slot(uint64_t k) const;

  double morph_s_;
  size_t capacity_;
  std::vector<Entry> table_, scratch_;
  size_t live_ = 0;
  double lastEnd_s_ = -1e300;
};

}  // namespace ig::lod
