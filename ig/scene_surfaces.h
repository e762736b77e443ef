// The scene's surfaces above the terrain for the host's terrain queries (CIGI HAT/HOT and line
// of sight, io/cigi_link.h): the [hdlod] objects and the [forest] trees together, whichever a
// segment meets first. Holds pointers to the layers' own (io::SceneSurfaces), which must
// outlive it. Frame thread only.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>

#include "io/link.h"
#include "lod/mesh_rays.h"

namespace ig {

// A layer's answer (a lod hit with t, point_m and normal) as an io::SurfaceHit of `material`:
// the layers' io::SceneSurfaces adapters. Adds the work (nodes + triangles) to `work` when set.
template <typename LodHit>
bool toSurfaceHit(bool found, const LodHit& h, const lod::RayWork& w, uint32_t material, io::SurfaceHit& hit,
                  uint32_t* work) {
  if (work != nullptr) *work += w.nodes + w.triangles;
  if (!found) return false;
  hit.t = h.t;
  hit.point_m = h.point_m;
  hit.normal = h.normal;
  hit.material = material;
  return true;
}

class SurfaceSet final : public io::SceneSurfaces {
 public:
  void add(const io::SceneSurfaces* surfaces) {
    if (surfaces != nullptr && count_ < parts_.size()) parts_[count_++] = surfaces;
  }
  bool empty() const { return count_ == 0; }

  bool intersect(const glm::dvec3& from_m, const glm::dvec3& to_m, io::SurfaceMask mask, io::SurfaceHit& hit,
                 uint32_t* work) const override {
    // Each part searches only up to the nearest hit so far: the segment shrinks to it.
    bool found = false;
    glm::dvec3 end = to_m;
    double scale = 1.0;  // the shrunk segment's end as a fraction of the whole
    for (size_t i = 0; i < count_; ++i) {
      io::SurfaceHit h;
      if (!parts_[i]->intersect(from_m, end, mask, h, work)) continue;
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
