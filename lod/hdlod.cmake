# HDLOD (paper 000): 4D scene model, cluster-tree generation, per-frame selection, and the
# synthetic construction-site generator. Pure: no GL, no clock, no threads.
target_sources(ig_lod PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_scene.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_build.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_select.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_site.cpp
)
