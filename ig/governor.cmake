# igbench governor: the frame governor on a rendered replay whose load swings 10x (ROAM terrain,
# headless), governed against a fixed tolerance side by side.
target_sources(ig_core PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/bench_governor.cpp)
