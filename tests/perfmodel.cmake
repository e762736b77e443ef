# Paper 002: performance model, switching, q*, fits and the octree (pure), and the dynamic
# pass with its three strategies and the calibration cache (GL).
ig_add_test(perfmodel_test perfmodel_test.cpp LIBS ig_lod)
# What a mutation pass found perfmodel_test leaves open (lod/perfmodel).
ig_add_test(perfmodel_mutation_test perfmodel_mutation_test.cpp LIBS ig_lod)
# Mutation-testing pass over lod/dynamic_octree.cpp: placement, counts, thresholds and traversal
# details the octree tests above leave open.
ig_add_test(dynamic_octree_mutation_test dynamic_octree_mutation_test.cpp LIBS ig_lod)
ig_add_test(dynamic_gltest dynamic_gltest.cpp LIBS ig_render GL)
# The two benchmarks at CI size: schema and consistency (Release only: under ASAN the timings
# mean nothing and the run is slow).
if(NOT IG_SANITIZE)
  add_test(NAME perfmodel_bench_test
           COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/perfmodel_bench_test.sh $<TARGET_FILE:igbench>)
  set_tests_properties(perfmodel_bench_test PROPERTIES TIMEOUT 300)
endif()
