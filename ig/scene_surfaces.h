// The scene's surfaces above the terrain for the host's terrain queries (CIGI HAT/HOT and line
// of sight, io/cigi_link.h): the [hdlod] objects and the [forest] trees together, whichever a
// segment meets first. Holds pointers to the layers' own (io::SceneSurfaces), which must
// outlive it. Frame thread only.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>

#include "io/link.h"

namespace ig {

class SurfaceSet final : public io::SceneSurfaces {
 public:
  void add(const io::SceneSurfaces* surfaces) {
    if (surfaces != nullptr && count_ < parts_.size()) parts_[count_++] = surfaces;
  }
  bool empty() const { return count_ == 0; }

  bool intersect(const glm::dvec3& from_m, const glm::dvec3& to_m, io::SurfaceQuery query, io::SurfaceHit& hit,
                 uint32_t* work) const override {
    // Each part searches only up to the nearest hit so far: the segment shrinks to it.
    bool found = false;
    glm::dvec3 end = to_m;
    double scale = 1.0;  // the shrunk segment's end as a fraction of the whole
    for (size_t i = 0; i < count_; ++i) {
      io::SurfaceHit h;
      if (!parts_[i]->intersect(from_m, end, query, h, work)) continue;
      found = true;
      hit = h;
      hit.t = h.t * scale;
      scale = hit.t;
      end = h.point_m;
    }
    return found;
  }
  double top_m() const override {
    double top = -1e300;
    for (size_t i = 0; i < count_; ++i) top = std::max(top, parts_[i]->top_m());
    return top;
  }

 private:
  std::array<const io::SceneSurfaces*, 4> parts_{};
  size_t count_ = 0;
};

}  // namespace ig
