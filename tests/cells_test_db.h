// A small hierarchical-cells database for tests: a mesh in the 100 m cube [0, 100]^3 voxelized
// to 7 levels (0.78 m voxels), 5 cell levels of 4^3-voxel cells, written to `path`.
#pragma once

#include <string>

#include "lod/cells.h"
#include "lod/cells_db.h"
#include "lod/cells_voxel.h"

namespace ig::test {

inline bool writeTestCellDb(const lod::VoxelMesh& mesh, const std::string& path, lod::CellTree* tree,
                            std::string& error) {
  lod::VoxelizeConfig vc;
  vc.levels = 7;
  vc.boxMin_m = glm::dvec3(0.0);
  vc.boxEdge_m = 100.0;
  lod::VoxelPyramid pyramid;
  if (!lod::voxelize(mesh, vc, pyramid, error)) return false;
  lod::CellBuildConfig bc;
  bc.cellLevels = 5;
  bc.cellVoxelDepth = 2;
  return lod::writeCellDb(path, pyramid, bc, tree, error);
}

}  // namespace ig::test
