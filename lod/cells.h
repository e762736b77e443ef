// Hierarchical cells (HC), paper 003 (shared/seeds/003, "Adaptive rendering of three dimension
// scenes using hierarchical cells structure"). An HC is an octree over the scene: the root cell
// is a cube, each cell splits into (up to) 8 octant children, and layer q (all cells at level q)
// is one version of the scene at one level of detail, P = 2 between levels.
//
// Each cell holds an octree image of its part of the scene: a binary voxel octree of a fixed
// depth d below the cell (`cellVoxelDepth`), so a cell at level q draws voxels of edge
//     rootEdge_m / 2^(q + d),
// V = the number of occupied voxels at that resolution inside the cell, S = its byte size.
// Octree images are monotone: every occupied voxel has an occupied parent voxel, so
//     sum V(children) >= V(cell)   and   V(child) > 0  =>  V(cell) > 0.
// build() checks both; the selection (lod/cells_select.h) relies on them.
//
// Storage: one flat array per field (struct of arrays), cells in breadth-first order, so each
// level is one index range and the children of a cell are one contiguous range. About 26 bytes
// per cell: 1 M cells take ~26 MB.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/view.h"

namespace ig::lod {

inline constexpr uint32_t kNoCell = 0xFFFFFFFFu;
inline constexpr int kMaxCellLevels = 16;  // cell coordinates are 16-bit

// Cell flags.
inline constexpr uint8_t kCellEmpty = 1;  // V = 0: nothing to draw (set by build())

// One cell as given to build(). Order: breadth-first (a cell after its parent, all cells of level
// q before those of level q + 1), the children of one parent contiguous and in increasing octant.
struct CellDesc {
  uint32_t parent = kNoCell;  // index in the same array; kNoCell for the root (index 0 only)
  uint8_t octant = 0;         // 0..7 in the parent: bit 0 = +x half, bit 1 = +y, bit 2 = +z
  uint32_t voxels = 0;        // V
  uint32_t bytes = 0;         // S: size of the cell's octree image in the database
};

struct CellTreeInfo {
  glm::dvec3 rootMin_m{0.0};  // the root cube's lowest corner (world / local ENU)
  double rootEdge_m = 1.0;    // the root cube's edge, > 0
  int cellVoxelDepth = 0;     // d: depth of each cell's voxel octree, 0..20
};

class CellTree {
 public:
  // Validates and stores the cells. On failure returns false, leaves the tree empty and names
  // the first bad cell and value in `error`.
  bool build(const CellTreeInfo& info, std::span<const CellDesc> cells, std::string& error);

  uint32_t size() const { return static_cast<uint32_t>(parent_.size()); }
  bool empty() const { return parent_.empty(); }
  int levels() const { return static_cast<int>(levelBegin_.size()) - 1; }
  // Cells of level q are [levelBegin(q), levelBegin(q + 1)).
  uint32_t levelBegin(int q) const { return levelBegin_[static_cast<size_t>(q)]; }
  const CellTreeInfo& info() const { return info_; }

  uint32_t parent(uint32_t c) const { return parent_[c]; }
  uint32_t firstChild(uint32_t c) const { return firstChild_[c]; }
  uint32_t childCount(uint32_t c) const { return childCount_[c]; }
  int level(uint32_t c) const { return level_[c]; }
  uint32_t voxels(uint32_t c) const { return voxels_[c]; }
  uint32_t bytes(uint32_t c) const { return bytes_[c]; }
  uint8_t flags(uint32_t c) const { return flags_[c]; }
  bool isEmpty(uint32_t c) const { return (flags_[c] & kCellEmpty) != 0; }
  // Integer position of the cell in its level's grid (0 .. 2^level - 1 per axis).
  glm::uvec3 coord(uint32_t c) const { return {x_[c], y_[c], z_[c]}; }

  double cellEdge_m(int level) const { return cellEdge_m_[static_cast<size_t>(level)]; }
  double voxelEdge_m(int level) const { return voxelEdge_m_[static_cast<size_t>(level)]; }
  Aabb box(uint32_t c) const;

  uint64_t totalVoxels(int level) const;  // sum of V over layer `level`
  uint64_t totalBytes() const;            // sum of S over all cells

 private:
  void clear();

  CellTreeInfo info_;
  std::vector<uint32_t> parent_, firstChild_, voxels_, bytes_;
  std::vector<uint8_t> childCount_, level_, flags_;
  std::vector<uint16_t> x_, y_, z_;
  std::vector<uint32_t> levelBegin_;  // levels() + 1 entries
  std::vector<double> cellEdge_m_, voxelEdge_m_;
};

}  // namespace ig::lod
