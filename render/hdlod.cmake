# HDLOD render pass (paper 000, section 4): glMultiDrawElementsIndirect per octant of a
# single-reference octree, arrays updated incrementally.
target_sources(ig_render PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_pass.cpp)
