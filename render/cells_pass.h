// Hierarchical-cells render pass (paper 003): each resident cell's voxels (lod::CellPoint,
// decoded from the cell database, lod/cells_db.h) drawn as point splats.
//
// Memory: one GPU buffer of fixed capacity (CellsPassConfig::arenaBytes, the memory budget),
// persistently mapped, 16 bytes a point (float position relative to the tree's rootMin, RGB8 and
// the voxel level in the fourth byte). Cells get blocks from a buddy allocator over the arena
// (blocks of 2^k x 16 points, split and merged again on eviction), so an upload costs no GL call
// and no allocation, and a cell uses at most twice its size. upload() returns false when no block
// is free: the caller evicts (LRU or whatever it keeps) and tries again.
//
// Drawing: one glMultiDrawArrays(GL_POINTS) over the drawn cells' ranges. A point is a square of
// side  max(minPoint_px, pointScale * voxelEdge * pixelsPerMetre * sqrt(1 + t^2) / viewDepth)
// (the voxel's screen footprint face-on, widened off the view axis; voxelEdge from the level
// stored with the point, pixelsPerMetre = viewport height / (2 tan(fovY / 2)), t = the larger of
// the centre's |x| / depth and |y| / depth in view space: there neighbouring voxels of a surface
// seen obliquely project up to sqrt(1 + t^2) footprints apart), capped at the driver's largest
// point size (GL_POINT_SIZE_RANGE). GL discards a point whose centre is outside the view even where its
// square reaches into it; the vertex shader moves centres less than half a point outside a side
// onto the edge, so a surface close to the camera is covered to the frame's border.
// Lit by the time of day only: the colour is the voxel's (igtool cells-build bakes daylight sun
// shading into it, 0.3 ambient + 0.7 sun; no normals are stored), its ambient part dimmed as the
// frame's ambient light and its sun part as the sun (Lighting::daylight: unchanged by day), with
// the renderer's fog; depth-tested and written with the renderer's reverse-Z. Camera-relative:
// rootMin - eye is computed in double each frame and sent as a float and its remainder
// (render/split_offset.h), so a tree 1e7 m from the origin renders as at the origin and a root
// cube of many km places its splats as finely near its far side (positions inside the root cube
// keep float precision relative to its edge: 1e-7 of it).
//
// Nothing is created before init(): a scene without cells costs nothing. The pass binds its own
// program and VAO, enables GL_PROGRAM_POINT_SIZE only while drawing, and leaves the FBO,
// viewport and depth state as Renderer::beginFrame set them.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "lod/cells.h"
#include "lod/cells_db.h"
#include "lod/cells_select.h"

namespace ig::render {

class Renderer;

struct CellsPassConfig {
  uint64_t arenaBytes = uint64_t{64} << 20;  // GPU point memory (16 B a point); 4 KiB .. 32 GiB (2^31 points); rounded down to 256 B
  float pointScale = 1.0f;                   // point side / voxel footprint, > 0 (1: face-on size)
  float minPoint_px = 1.0f;                  // smallest point side, >= 1
};

struct CellsPassStats {
  uint32_t drawnCells = 0;    // cells drawn this frame
  uint64_t drawnPoints = 0;   // their points
  uint32_t notResident = 0;   // cells in the draw list that were not resident (skipped)
  uint32_t drawCalls = 0;     // 0 or 1 (one glMultiDrawArrays)
};

class CellsPass {
 public:
  static constexpr uint32_t kPointBytes = 16;
  static constexpr uint32_t kUnitPoints = 16;  // allocation granule (256 B)

  CellsPass();
  ~CellsPass();
  CellsPass(const CellsPass&) = delete;
  CellsPass& operator=(const CellsPass&) = delete;

  // Creates the program, VAO and arena. A GL context must be current; the tree must outlive the
  // pass. Fails (naming the value) on a bad config or when the buffer cannot be created.
  bool init(const lod::CellTree& tree, const CellsPassConfig& config, std::string& error);
  bool initialized() const { return impl_ != nullptr; }

  // Copies the cell's points into the arena (replacing what the cell had). False when the pass
  // is not initialized, the cell is out of range, or no block of that size is free (evict and
  // retry; a cell larger than the whole arena never fits). Between frames (no GL call).
  bool upload(uint32_t cell, std::span<const lod::CellPoint> points);
  void evict(uint32_t cell);
  void evictAll();
  bool resident(uint32_t cell) const;
  uint64_t bytesUsed() const;       // arena bytes held by resident cells (whole blocks)
  uint64_t capacityBytes() const;   // the arena (0 before init)
  // The most points one cell can have and still be uploaded (into an empty arena: its largest
  // buddy block, the arena rounded down to a power of two granules); 0 before init.
  uint64_t largestCellPoints() const;
  uint64_t bufferBytes() const;     // GPU buffer bytes (0 before init)

  // Between Renderer::beginFrame and endFrame: draws the listed cells that are resident (others
  // are counted in notResident; CellDraw::voxel_px is not used: the size is per point). Adds one
  // draw call to the renderer's stats (points are not triangles: see lastStats()). No
  // allocation.
  void draw(Renderer& renderer, std::span<const lod::CellDraw> cells);
  const CellsPassStats& lastStats() const { return stats_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  CellsPassStats stats_;
};

}  // namespace ig::render
