// Voxelizer for hierarchical cells (paper 003, section 2 and 3): triangles -> binary voxel octree
// with a colour per voxel per level (an "octree image", P = 2 between levels), its box-counting
// dimension per level (the paper's Table 1), and the HC built from it.
//
// Voxels are kept sparse: per level, the sorted Morton codes of the occupied voxels (bit 0 of
// each 3-bit group = x, bit 1 = y, bit 2 = z, the same as a cell's octant) and one RGBA8 colour
// each. A voxel of the finest level is occupied when a triangle touches its cube (exact
// triangle-box separating-axis test; a triangle lying exactly on a voxel face counts for the
// voxel above it only, voxels being half-open [i, i + 1)), a coarser voxel when any of its 8
// children is. With `solid`, voxels whose centre is inside a closed mesh are occupied too.
//
// Dimension between levels l and l + 1 (voxel edge halves), the paper's HC dimension D (each
// layer holds 2^D times the voxels of the one above):
//     D(l) = log2(N(l + 1) / N(l)),
// about 2 for surfaces, 3 for solids. The paper's Table 1 lists a different quantity, the
// Kolmogorov-Hausdorff (box-counting) estimate at one level, log M(eps) / log(1 / eps) with eps the
// voxel edge relative to the root cube:
//     H(l) = log2(N(l)) / l
// (the bunny: 15100 voxels at 1/128 -> 1.983, 61010 at 1/256 -> 1.987, ... 1.998 at level 10).
// H tends to the same limit, more slowly (from below for an object smaller than the cube).
//
// Cells from the pyramid (buildCellTree): cell level q holds the occupied voxels of level q as
// cells; a cell's octree image has depth d = cellVoxelDepth, so
//     V(cell) = occupied voxels of level q + d inside it,
//     S(cell) = 16 (header) + one child-mask byte per occupied node of levels q .. q + d - 1
//               inside it + 3 colour bytes per voxel of level q + d
// (a plain BVO encoding; the database file will use the same counts).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "lod/cells.h"

namespace ig::lod {

inline constexpr int kMaxVoxelLevels = 16;

struct VoxelMesh {
  std::vector<glm::dvec3> positions_m;
  std::vector<uint32_t> indices;  // three per triangle
  std::vector<uint32_t> colors;   // RGBA8 per vertex (0xAABBGGRR), or empty: white
};

// Procedural meshes (append to `mesh`; `color` is RGBA8 0xAABBGGRR).
// A UV sphere: `segments` around (>= 3), segments / 2 rings.
void appendSphere(VoxelMesh& mesh, const glm::dvec3& center_m, double radius_m, int segments, uint32_t color);
// A quad a-b-c-d (two triangles a-b-c, a-c-d).
void appendQuad(VoxelMesh& mesh, const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c, const glm::dvec3& d,
                uint32_t color);
// A closed axis-aligned box (12 triangles, outward winding).
void appendBox(VoxelMesh& mesh, const glm::dvec3& min_m, const glm::dvec3& max_m, uint32_t color);

struct VoxelizeConfig {
  int levels = 8;                 // finest voxel level: 2^levels voxels along the root edge, 1..16
  glm::dvec3 boxMin_m{0.0};       // root cube, used when boxEdge_m > 0
  double boxEdge_m = 0.0;         // <= 0: the smallest cube around the mesh (padded by 1e-6 of its size)
  bool solid = false;             // also fill the inside of a closed mesh (ray parity along +z)
};

struct VoxelPyramid {
  glm::dvec3 boxMin_m{0.0};
  double boxEdge_m = 1.0;
  std::vector<std::vector<uint64_t>> codes;   // per level 0..levels(): sorted Morton codes
  std::vector<std::vector<uint32_t>> colors;  // per level: RGBA8 per voxel (mean of what it covers)

  int levels() const { return static_cast<int>(codes.size()) - 1; }
  size_t count(int level) const { return codes[static_cast<size_t>(level)].size(); }
  // D(l) = log2(N(l + 1) / N(l)) for l in 0 .. levels() - 1 (0 if N(l) = 0).
  double dimension(int level) const;
  // H(l) = log2(N(l)) / l for l in 1 .. levels() (the paper's Table 1; 0 for l = 0 or N(l) = 0).
  double boxCountingDimension(int level) const;
};

// Morton code of voxel (x, y, z) (each < 2^21) and back.
uint64_t mortonEncode(uint32_t x, uint32_t y, uint32_t z);
glm::uvec3 mortonDecode(uint64_t code);

// Voxelizes the mesh. Fails (false, `error` names the bad value) on NaN / infinite vertices,
// indices out of range, a count of indices not a multiple of 3, colours not one per vertex,
// levels out of range, or an explicit box that does not contain the mesh. An empty mesh gives
// an empty pyramid (no voxel at any level).
bool voxelize(const VoxelMesh& mesh, const VoxelizeConfig& config, VoxelPyramid& out, std::string& error);

struct CellBuildConfig {
  int cellLevels = 6;      // L: cell levels 0 .. L - 1, 1..kMaxCellLevels
  int cellVoxelDepth = 2;  // d: L - 1 + d must be <= the pyramid's levels()
};

// Builds the HC (one cell per occupied voxel of levels 0 .. L - 1) with V and S as above.
// Fails on an empty pyramid or a bad config (error names the value).
bool buildCellTree(const VoxelPyramid& pyramid, const CellBuildConfig& config, CellTree& out, std::string& error);

}  // namespace ig::lod
