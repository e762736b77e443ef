# Hierarchical cells (paper 003): igtool cells-build (mesh / copies / spheres -> packed cell database).
target_sources(ig_core PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/cells_tool.cpp)
