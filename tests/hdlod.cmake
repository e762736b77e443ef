# HDLOD (paper 000): scene model and schedule files; cluster tree, selection, site generator.
ig_add_test(hdlod_scene_test ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_scene_test.cpp LIBS ig_lod)
ig_add_test(hdlod_tree_test ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_tree_test.cpp LIBS ig_lod)
add_test(NAME hdlod_bench_test COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_bench_test.sh $<TARGET_FILE:igbench>)
set_tests_properties(hdlod_bench_test PROPERTIES TIMEOUT 300)
ig_add_test(hdlod_simplify_test ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_simplify_test.cpp LIBS ig_lod)
