// Regular decimation ("block LOD", geomipmapping-like): the baseline of paper 001, section 3
// (shared/seeds/001). The DEM is cut into square blocks of B x B quads (B a power of two);
// block level k keeps every 2^k-th row and column. Per block and level, the exact maximum
// vertical error of that level's triangulation (as drawn: border ring zipped, clamped onto the
// DEM, neighbours at the same level) against every sample of the block is precomputed (made
// monotone in k). The fans to a coarser neighbour's edge are not in it (paper 001's crack fix).
//
// Selection rule (per frame, per block): a block outside the frustum is not drawn; otherwise
// it takes the coarsest level k with
//     error_m(block, k) * viewportHeight_px / (2 tan(fovY / 2)) / distance(eye, box) <= tolerance_px
// (distance 0, eye inside the box: finest level). Cracks are fixed as in the paper: an edge
// shared with a coarser neighbour uses only the neighbour's vertices, and the finer block's
// border ring is re-connected to them with fans (a zip of the edge and the first inner row),
// so both sides of every block edge have the same vertices.
//
// Vertices use the same sample-grid coordinates and clamping rule as lod/roam.h (the grid is
// padded to whole blocks; coordinates east / north of the DEM clamp to its edge and triangles
// that become zero-area are not emitted), so ROAM and block LOD are compared on one path.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/roam.h"
#include "lod/view.h"

namespace ig::lod {

struct BlockLodConfig {
  int blockQuads = 64;  // B: quads per block side, a power of two >= 2
};

struct BlockLodStats {
  uint32_t blocksVisible = 0;
  uint64_t triangles = 0;  // emitted by emitTriangles() for this view (after clamping)
  double maxErrorPx = 0.0; // largest projected level error among visible blocks
};

class BlockLod {
 public:
  // Same inputs and lifetime rule as Roam: the heights must outlive the object.
  BlockLod(std::span<const float> heights_m, int width, int height, double spacing_m, const glm::dvec3& origin_m,
           const BlockLodConfig& config = {});

  // Chooses each block's level for the view (RoamView's tolerance and camera; maxTriangles and
  // maxOperations are ignored: block LOD has no such control). No allocation.
  BlockLodStats update(const RoamView& view);
  // Upper bound on the triangles emitTriangles() writes.
  size_t triangleBound() const;
  size_t emitTriangles(std::span<RoamTriangle> out) const;

  int blocksX() const { return blocksX_; }
  int blocksY() const { return blocksY_; }
  int levels() const { return levels_; }
  int level(int bx, int by) const { return level_[static_cast<size_t>(by) * blocksX_ + bx]; }  // -1 = culled
  double levelError_m(int bx, int by, int k) const {
    return static_cast<double>(error_m_[(static_cast<size_t>(by) * blocksX_ + bx) * levels_ + k]);
  }
  glm::dvec3 vertexPosition(int x, int y) const;

 private:
  float heightAt(int x, int y) const;
  Aabb blockBox(int bx, int by) const;  // relative to origin
  int edgeStep(int bx, int by, int nbx, int nby) const;
  size_t emitBlock(int bx, int by, std::span<RoamTriangle> out) const;
  // emitBlock with the block's own step `s` and the edge steps (south, east, north, west) given.
  size_t emitBlockSteps(int bx, int by, int s, const int (&edgeSteps)[4], std::span<RoamTriangle> out) const;

  const float* heights_m_;
  int width_, height_;
  double spacing_m_;
  glm::dvec3 origin_m_;
  int B_, blocksX_, blocksY_, levels_;
  std::vector<float> error_m_;          // per block, per level
  std::vector<float> zMin_m_, zMax_m_;  // per block
  std::vector<int8_t> level_;           // per block, this frame
};

}  // namespace ig::lod
