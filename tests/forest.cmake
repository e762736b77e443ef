# Forest (lod/forest*): placement and fades, the kd-tree and its selection, fins and cones.
ig_add_test(forest_placement_test forest_placement_test.cpp LIBS ig_lod)
ig_add_test(forest_kdtree_test forest_kdtree_test.cpp LIBS ig_lod)
ig_add_test(forest_fins_test forest_fins_test.cpp LIBS ig_lod)
add_test(NAME forest_bench_test COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/forest_bench_test.sh $<TARGET_FILE:igbench>)
set_tests_properties(forest_bench_test PROPERTIES TIMEOUT 300)
