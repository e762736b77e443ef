# Hierarchical cells (paper 003): the cell tree, the voxelizer and the budgeted selection.
target_sources(ig_lod PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/cells.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/cells_voxel.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/cells_select.cpp
)
# The packed cell database (lod/cells_db.*): zlib's crc32, the same the HTTP fetcher checks.
find_package(ZLIB REQUIRED)
target_sources(ig_lod PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/cells_db.cpp)
target_link_libraries(ig_lod PRIVATE ZLIB::ZLIB)
