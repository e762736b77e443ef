// Segment queries against one triangle mesh in its own space (the shared part of the host's
// terrain queries against scene objects: lod/hdlod_rays.h for the 4D scene's models,
// lod/forest_rays.h for the tree models). A bounding volume hierarchy over the triangles
// (median split on the longest axis of the centroids, up to 4 triangles a leaf), the triangles
// copied in leaf order; the test (Moller-Trumbore) runs in double precision, hits either side
// (polygon soups have no reliable orientation) and includes the edges, so a segment through
// an edge two triangles share never slips through. Zero-area and non-finite triangles are left
// out (counted). Immutable after build: safe to read from any thread.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

namespace ig::lod {

// What a query examined: its cost, for the caller's per-frame cap.
struct RayWork {
  uint32_t nodes = 0;      // hierarchy nodes visited
  uint32_t triangles = 0;  // triangles tested
};

// A bounding volume hierarchy over boxes (median split on the longest axis of the boxes'
// centres, up to `leafItems` a leaf), the one MeshRays and lod::hdlod::SceneRays walk. A node's
// box holds its items; a leaf holds order[first, first + count), an inner node has count 0 and
// its children at `first` and `first + 1`. Node 0 is the root (none for no items).
struct BoxItem {
  glm::dvec3 min{0.0}, max{0.0};
  uint32_t id = 0;
};
struct BoxNode {
  glm::dvec3 min{0.0}, max{0.0};
  uint32_t first = 0, count = 0;
};
void buildBoxHierarchy(std::vector<BoxItem>& items, uint32_t leafItems, std::vector<BoxNode>& nodes,
                       std::vector<uint32_t>& order);

class MeshRays {
 public:
  MeshRays() = default;
  // positions: `count` vertices, each three floats at `stride` bytes from the last (x, y, z
  // first); indices: three per triangle, every one < count (others are left out as degenerate).
  MeshRays(const float* positions, size_t count, size_t stride, std::span<const uint32_t> indices);

  // The segment o + t d, t in [0, tBest): on a hit nearer than tBest sets tBest, `normal` (unit,
  // the triangle's, facing the segment's start) and returns true.
  bool intersect(const glm::dvec3& o, const glm::dvec3& d, double& tBest, glm::dvec3& normal, RayWork& work) const;

  bool empty() const { return nodes_.empty(); }
  size_t triangles() const { return tris_.size(); }
  size_t degenerateTriangles() const { return degenerate_; }

 private:
  struct Tri {
    glm::dvec3 a, e1, e2;  // a vertex and the two edges from it
  };
  std::vector<BoxNode> nodes_;  // leaves index tris_ directly (stored in leaf order)
  std::vector<Tri> tris_;
  size_t degenerate_ = 0;
};

// Whether the segment o + t d, t in [0, tMax], meets the box [lo, hi] (slab test; a zero
// direction component needs o inside that slab); the second form also gives the part inside,
// [t0, t1].
bool segmentMeetsBox(const glm::dvec3& o, const glm::dvec3& d, double tMax, const glm::dvec3& lo, const glm::dvec3& hi);
bool segmentMeetsBox(const glm::dvec3& o, const glm::dvec3& d, double tMax, const glm::dvec3& lo, const glm::dvec3& hi,
                     double& t0, double& t1);

}  // namespace ig::lod
