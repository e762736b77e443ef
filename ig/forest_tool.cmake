# Forest (paper 004): igtool forest-textures (tree models, meshoptimizer LODs, textures T and S)
# and the service's forest layer.
find_package(meshoptimizer REQUIRED CONFIG)
target_sources(ig_core PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/forest_tool.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/forest_layer.cpp
)
target_link_libraries(ig_core PRIVATE meshoptimizer::meshoptimizer)
