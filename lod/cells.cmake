# Hierarchical cells (paper 003): the cell tree, the voxelizer and the budgeted selection.
target_sources(ig_lod PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/cells.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/cells_voxel.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/cells_select.cpp
)
