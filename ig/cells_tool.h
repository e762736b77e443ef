// igtool cells-build (hierarchical cells, paper 003): a mesh (OBJ / PLY / glTF: the Stanford
// bunny from scripts/fetch-cells), N scattered copies of it, or a procedural scene of spheres ->
// voxel pyramid -> cell tree -> the packed cell database file (lod/cells_db.h). Prints the
// box-counting dimension per voxel level (the paper's Table 1: about 2 for surfaces, 3 for
// solids), the cells and bytes per level, and the build times; --json prints one JSON object.
// The written file is reopened and every cell's crc and structure checked.
#pragma once

#include <cstdint>
#include <string>

#include "lod/cells_voxel.h"

namespace ig {

struct CellsBuildOptions {
  std::string input;              // mesh file (.obj, .ply, .gltf, .glb); "" with `scene`
  std::string scene;              // "spheres:N": N procedural spheres in a 1,024 m cube (as igbench cells)
  int copies = 0;                 // > 0: scatter this many copies of `input` (random place, turn, scale); <= 50 M triangles in all
  double size_m = 0.0;            // scale `input` so that its largest extent is this (0: as it is)
  bool yUp = false;               // `input` is y up: turn it to z up ((x, y, z) -> (x, -z, y))
  bool shading = true;            // bake sun shading into the vertex colours (splats are drawn unlit)
  int voxelLevels = 0;            // finest voxel level; 0: cellLevels - 1 + voxelDepth
  int cellLevels = 6;             // L
  int voxelDepth = 3;             // d: voxel octree depth per cell
  bool solid = false;             // fill the inside of closed meshes
  std::string out = "cells.ighc"; // database file to write
  uint32_t seed = 1;              // for spheres and copies
  bool json = false;              // one JSON object on stdout instead of text
};

// The procedural scene of igbench cells and `--scene spheres:N`: `count` spheres of radius 8 - 60 m
// scattered through the cube [0, kCellsSceneEdge_m]^3, each with its own colour.
inline constexpr double kCellsSceneEdge_m = 1024.0;
lod::VoxelMesh cellsSphereScene(int count, uint32_t seed);

// The mesh cells-build voxelizes: the input (scaled, turned z up, copied) or the procedural scene,
// with sun shading baked into its colours when `shading`. `source` names it. False with `error`
// naming the bad option or input. (The options' ranges are checked by runCellsBuild.)
bool cellsBuildMesh(const CellsBuildOptions& options, lod::VoxelMesh& mesh, std::string& source, std::string& error);

// Returns the exit code: 0 written, 2 bad option or input (message names it), 1 write failure.
int runCellsBuild(const CellsBuildOptions& options);

}  // namespace ig
