// Terrain as a plain regular grid cut into square chunks, each with its own origin so vertex
// data stays small (float, relative to the chunk) however far the terrain lies from the world
// origin (camera-relative rendering). This is the foundation terrain; the terrain issue
// replaces the per-frame selection with ROAM + enhMerge.
//
// Selection rule (per frame): a chunk is drawn if its bounding box intersects the view
// frustum; it is drawn whole at full resolution, nearest chunks first, and chunks that would
// take the frame past its triangle budget are dropped, farthest first.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/heightfield.h"
#include "lod/view.h"

namespace ig::lod {

struct TerrainGridDesc {
  HeightfieldDesc heights;           // posts = quads + 1 per side
  glm::dvec3 offset_m{0, 0, 0};      // SW corner of the terrain in local ENU
  int chunkQuads = 64;               // quads per chunk side
};

struct TerrainVertex {
  float position[3];  // metres, relative to the chunk origin
  float normal[3];
};

// Vertex of height-field sample (x, y) (clamped into the field), positioned relative to sample
// (0, 0), with the normal from central differences. The normal depends only on the sample,
// so triangles of different sizes that share a vertex light it the same (no lighting cracks).
TerrainVertex heightFieldVertex(std::span<const float> heights_m, int width, int height, double spacing_m, int x, int y);

struct TerrainChunk {
  glm::dvec3 origin_m;   // ENU position of the chunk's SW corner at height 0
  Aabb bounds;           // ENU, double
  uint32_t firstVertex;  // into TerrainGrid::vertices(); indices are relative to it
  uint32_t firstIndex;   // into TerrainGrid::indices()
  uint32_t indexCount;   // triangles * 3
  int quadsX, quadsY;    // this chunk's size (edge chunks may be smaller)
};

class TerrainGrid {
 public:
  // Builds heights, vertices, normals and chunk bounds. Start-up work only.
  explicit TerrainGrid(const TerrainGridDesc& desc);

  std::span<const TerrainChunk> chunks() const { return chunks_; }
  std::span<const TerrainVertex> vertices() const { return vertices_; }
  // Triangle indices of all chunks, each chunk's relative to its firstVertex.
  std::span<const uint32_t> indices() const { return indices_; }
  uint64_t triangleCount(const TerrainChunk& c) const { return 2ull * c.quadsX * c.quadsY; }
  uint64_t totalTriangles() const;
  // Height at ENU (x, y) by bilinear interpolation; terrain offset z added. Outside: clamps.
  double heightAt(double east_m, double north_m) const;
  const TerrainGridDesc& desc() const { return desc_; }
  // The full-resolution posts, row-major (row = north), postsX * postsY, offset z not added.
  std::span<const float> heights() const { return heights_m_; }

  // Writes the indices (into chunks()) of the chunks to draw for this view, nearest first,
  // within `maxTriangles`. `out` must have room for chunks().size() entries; returns the
  // number written. No allocation.
  size_t select(const Frustum& frustum, const glm::dvec3& eye_m, uint64_t maxTriangles, std::span<uint32_t> out) const;

 private:
  TerrainGridDesc desc_;
  std::vector<float> heights_m_;
  std::vector<TerrainVertex> vertices_;
  std::vector<uint32_t> indices_;
  std::vector<TerrainChunk> chunks_;
};

}  // namespace ig::lod
