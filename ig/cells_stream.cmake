# Hierarchical cells (paper 003): the streaming client (ig/cells_stream) and the parts of
# igbench cells with the bunny, nginx and pictures (ig/bench_cells_stream), and the [cells] scene
# layer of the service (ig/cells_layer).
target_sources(ig_core PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/cells_stream.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/bench_cells_stream.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/cells_layer.cpp
)
