// Ray queries against a 4D scene (paper 000's objects, lod/hdlod_scene.h) at one schedule time:
// the first intersection of a segment with the triangles of every object present at t, where
// that object is at t. For the host's terrain queries (CIGI HAT/HOT and line of sight, io/): a
// vehicle on a slab, a laser range finder aimed at a crane, a helicopter's height above a roof.
//
// Index (built once, immutable, safe to read from any thread): per model a bounding volume
// hierarchy over its triangles in model space (lod/mesh_rays.h); over the objects one hierarchy of their swept
// boxes (lod::hdlod::sweptBox: every place the object can be in [0, T]), so moving objects need
// no rebuild. A query walks the objects' hierarchy with the segment, tests each candidate's
// presence at t and its box at t, takes the segment into that object's model space (the
// position is rigid: a translation and a turn about z) and walks the model's hierarchy there.
// The triangle test runs in double precision in model space: coordinates near the model's
// origin, however far the object stands from the scene's origin.
//
// Polygon soups: triangles are hit from either side; zero-area and non-finite triangles are left
// out of the index (counted). The normal returned faces the segment's start.
//
// Cost: O(log objects + log triangles) for a segment that misses most of the scene; the stats
// count the nodes and triangles examined (the work cap of the caller).
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/hdlod_scene.h"
#include "lod/mesh_rays.h"

namespace ig::lod::hdlod {

struct RayHit {
  double t = 0.0;                  // along the segment: point = from + t (to - from), in [0, 1]
  glm::dvec3 point_m{0.0};         // world (local ENU)
  glm::dvec3 normal{0.0, 0.0, 1.0};  // unit, the hit triangle's, facing the segment's start
  uint32_t object = 0;             // index in Scene::objects
};

using lod::RayWork;  // hierarchy nodes visited (objects' and models') and triangles tested

class SceneRays {
 public:
  SceneRays() = default;
  // The scene must outlive this index and must not change while it is used (objects and models
  // are read at query time). A scene that fails validateScene() gives an empty index.
  explicit SceneRays(const Scene& scene);

  // The first intersection of the segment from -> to (world metres) with an object present at
  // schedule time t_s (clamped to [0, T] like every function of the scene; NaN reads as 0).
  // False when nothing is hit, for a non-finite segment and for an empty index. `work` (may be
  // null) adds what the query examined.
  bool intersect(const glm::dvec3& from_m, const glm::dvec3& to_m, double t_s, RayHit& hit,
                 RayWork* work = nullptr) const;

  bool empty() const { return objectNodes_.empty(); }
  // The highest point any object reaches at any time (from the swept boxes); meaningless when empty.
  double top_m() const { return top_m_; }
  size_t triangles() const { return triangles_; }            // indexed
  size_t degenerateTriangles() const { return degenerate_; }  // left out

 private:
  const Scene* scene_ = nullptr;
  std::vector<MeshRays> models_;
  std::vector<BoxNode> objectNodes_;  // over the objects' swept boxes (lod/mesh_rays.h)
  std::vector<uint32_t> objects_;  // object numbers in leaf order
  double top_m_ = 0.0;
  size_t triangles_ = 0, degenerate_ = 0;
};

}  // namespace ig::lod::hdlod
