# Large continuous forests (paper 004): distribution map and placement, the near-tree kd-tree
# with its per-frame cull / gather / sort, the fins rule with tangent-cone groups, and the tree
# model meshes (procedural fallback).
target_sources(ig_lod PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/forest.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/forest_kdtree.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/forest_fins.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/forest_model.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/forest_rays.cpp
)
