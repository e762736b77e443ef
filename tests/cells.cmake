# Hierarchical cells (lod/cells*): tree validation, voxelizer and dimension, selection.
ig_add_test(cells_tree_test cells_tree_test.cpp LIBS ig_lod)
ig_add_test(cells_voxel_test cells_voxel_test.cpp LIBS ig_lod)
ig_add_test(cells_select_test cells_select_test.cpp LIBS ig_lod)
add_test(NAME cells_bench_test COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cells_bench_test.sh $<TARGET_FILE:igbench>)
set_tests_properties(cells_bench_test PROPERTIES TIMEOUT 300)
