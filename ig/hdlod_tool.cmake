# HDLOD (paper 000): igtool site (schedule + models + cache of the synthetic construction site),
# the build progress bar, and the [hdlod] scene layer.
target_sources(ig_core PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_tool.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_layer.cpp
)
