# Paper 002: performance model (memory (1), time (2), switching (5)/(6), optimal q (11)) and the
# single-reference octree with the expensive-node estimate of hidden objects.
target_sources(ig_lod PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/perfmodel.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/dynamic_octree.cpp
)
