# Forest pass (paper 004): shell layers and fins far away, instanced 3D trees near, and the
# offline layer / fin textures rendered from the tree models.
target_sources(ig_render PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/forest_pass.cpp)
