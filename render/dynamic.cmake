# Paper 002: dynamic objects with per-object commands, octree command ranges and occlusion
# queries, the adaptive choice, and the start-up calibration of the performance model.
target_sources(ig_render PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/dynamic_pass.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/perf_calibration.cpp
)
