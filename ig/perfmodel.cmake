# igbench perfmodel (paper 002, Table 1): predicted vs measured frame time over scene sizes.
target_sources(ig_core PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/bench_perfmodel.cpp)
