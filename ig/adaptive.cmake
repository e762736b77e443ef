# igbench adaptive (paper 002): the adaptive strategy against the three fixed ones, side by side.
target_sources(ig_core PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/bench_adaptive.cpp)
