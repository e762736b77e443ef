# Frame governor (issue 7 item 3): per-phase budgets, an online time model (least squares with
# forgetting) and the control law that steers the layers' LOD knobs. Pure: time is passed in.
target_sources(ig_lod PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/governor.cpp)
