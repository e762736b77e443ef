// Segment queries against the forest's near trees (paper 004's 3D trees, lod/forest_kdtree.h):
// the first intersection of a segment with the triangles of the tree models, each tree where
// and as the near pass draws it: at its decoded base, turned and scaled by its pose
// (treePose: the hash of its index that render/forest_pass.cpp's vertex shader uses). For the
// host's line-of-sight queries (CIGI LOS, io/): a sensor's view into a forest stops at the
// first trunk or crown. Every tree of the forest counts, however far: the far representation
// (shell layers, fins) is how the trees look from afar, not other trees.
//
// Index: a uniform grid over the ground (cells of at least twice the widest crown, 8 m or more,
// at most ~4 M cells), each cell listing the trees whose crown box reaches into it (most trees
// are in 1 ... 4 cells). A query clips the segment to the forest's box (ground to the tallest
// tree top), walks the cells its ground track crosses in order (2D DDA) and tests each cell's
// trees by their box (the model's, turned and scaled: conservative), then the model's triangles
// in the tree's own space (lod/mesh_rays.h); it stops at the first cell that ends beyond the
// nearest hit. So a ray costs the cells it crosses and their trees, not the forest: in a dense
// forest it stops within a few cells. Alpha-tested leaf cards of real models count as their
// whole quads. Memory: 4 bytes a tree (its kd leaf) + 4 per (tree, cell) + 4 per cell.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/forest_kdtree.h"
#include "lod/forest_model.h"
#include "lod/mesh_rays.h"

namespace ig::lod {

// The pose the near pass draws tree `tree` (an index into ForestKdTree::trees()) with: yaw about
// the trunk (radians, [0, 2 pi) x jitter) and uniform scale (1 +- 0.1 x jitter). jitter:
// render::ForestPassDesc::yawJitter (0: none).
struct TreePose {
  double yaw_rad = 0.0;
  double scale = 1.0;
};
TreePose treePose(uint32_t tree, float jitter);

struct TreeHit {
  double t = 0.0;                    // along the segment, [0, 1]
  glm::dvec3 point_m{0.0};           // world (local ENU)
  glm::dvec3 normal{0.0, 0.0, 1.0};  // unit, facing the segment's start
  uint32_t tree = 0;                 // index into ForestKdTree::trees()
};

class ForestRays {
 public:
  ForestRays() = default;
  // `kd` must outlive this index and not change; models: one mesh per model index of the kd
  // tree's trees (a tree whose model has no mesh is never hit). The kd tree's node boxes must
  // hold the scaled models: ForestKdParams treeHeight_m / crownRadius_m at least 1.1 x the
  // tallest / widest model, as ig/forest_layer.cpp builds it.
  ForestRays(const ForestKdTree& kd, std::span<const TreeMesh> models, float yawJitter);

  // The first intersection of the segment from -> to (world metres) with a tree. False when
  // nothing is hit, for a non-finite segment and for an empty index; `work` (may be null) adds
  // what the query examined (grid cells and trees' boxes as nodes, the models' nodes, triangles).
  bool intersect(const glm::dvec3& from_m, const glm::dvec3& to_m, TreeHit& hit, RayWork* work = nullptr) const;

  bool empty() const { return kd_ == nullptr; }
  // The highest point a tree reaches; meaningless when empty.
  double top_m() const { return boxMax_.z; }
  // The grid: cell edge (m), cells east and north, (tree, cell) entries.
  double cell_m() const { return cell_m_; }
  uint32_t cellsX() const { return nx_; }
  uint32_t cellsY() const { return ny_; }
  size_t entries() const { return entries_.size(); }

 private:
  struct Model {
    MeshRays mesh;
    double radius_m = 0.0, zMin_m = 0.0, zMax_m = 0.0;  // the mesh's extent about the trunk axis
  };
  // Tree i of the kd tree against the segment (nearer than `best`).
  bool testTree(uint32_t i, const glm::dvec3& from, const glm::dvec3& d, double& best, TreeHit& hit, RayWork& w) const;

  const ForestKdTree* kd_ = nullptr;
  std::vector<Model> models_;
  float jitter_ = 1.0f;
  std::vector<uint32_t> leafOf_;                  // per tree: its kd leaf (the base decodes from it)
  std::vector<uint32_t> cellStart_, entries_;     // per cell: [cellStart_[c], cellStart_[c + 1]) in entries_
  glm::dvec3 boxMin_{0.0}, boxMax_{0.0};          // every tree (the grid's ground rectangle, ground to top)
  double cell_m_ = 8.0;
  uint32_t nx_ = 0, ny_ = 0;
};

}  // namespace ig::lod
