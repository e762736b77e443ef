# Hierarchical cells (lod/cells*): tree validation, voxelizer and dimension, selection.
ig_add_test(cells_tree_test cells_tree_test.cpp LIBS ig_lod)
ig_add_test(cells_voxel_test cells_voxel_test.cpp LIBS ig_lod)
ig_add_test(cells_select_test cells_select_test.cpp LIBS ig_lod)
# The selection's passes on two real threads (ig/worker_pair.h): the chunk contract, same choices.
ig_add_test(worker_pair_test worker_pair_test.cpp LIBS ig_core)
# The same under ThreadSanitizer (its own build; Release configuration only, like the benchmarks).
if(NOT IG_SANITIZE)
  add_test(NAME worker_pair_tsan_test COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/worker_pair_tsan_test.sh ${PROJECT_SOURCE_DIR})
  set_tests_properties(worker_pair_tsan_test PROPERTIES TIMEOUT 300)
endif()
# The packed cell database (lod/cells_db): round trip, corruption, zlib crc.
ig_add_test(cells_db_test cells_db_test.cpp LIBS ig_lod ZLIB::ZLIB)
# The splat pass (render/cells_pass) on a headless context: no holes, coverage per level, arena.
ig_add_test(cells_pass_gltest cells_pass_gltest.cpp LIBS ig_render GL)
# igtool cells-build on procedural spheres, then on the real Stanford bunny (scripts/fetch-cells).
add_test(NAME cells_tool_test COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cells_tool_test.sh $<TARGET_FILE:igtool>)
add_test(NAME fetch_cells COMMAND ${PROJECT_SOURCE_DIR}/scripts/fetch-cells)
set_tests_properties(fetch_cells PROPERTIES FIXTURES_SETUP cells_data TIMEOUT 300)
add_test(NAME cells_bunny_test COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cells_tool_test.sh $<TARGET_FILE:igtool> ${PROJECT_SOURCE_DIR})
set_tests_properties(cells_bunny_test PROPERTIES FIXTURES_REQUIRED cells_data)
# igbench cells --quick: selection, the bunny's PSNR sweep, streaming through nginx (benchmark
# smoke test: Release only, like the other benchmarks).
if(NOT IG_SANITIZE)
  add_test(NAME cells_bench_test COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cells_bench_test.sh $<TARGET_FILE:igbench>
           ${PROJECT_SOURCE_DIR})
  set_tests_properties(cells_bench_test PROPERTIES FIXTURES_REQUIRED cells_data TIMEOUT 300)
  # scripts/cells-ab (the selection of two revisions side by side) builds and runs on a small tree.
  add_test(NAME cells_ab_test COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/cells_ab_test.sh $<TARGET_FILE:igbench>
           ${PROJECT_SOURCE_DIR})
  set_tests_properties(cells_ab_test PROPERTIES TIMEOUT 300)
endif()
