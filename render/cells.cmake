# Hierarchical cells (paper 003): point splats of resident cells from a buddy-allocated GPU arena.
target_sources(ig_render PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/cells_pass.cpp)
