# HDLOD (paper 000): scene model and schedule files; cluster tree, selection, site generator.
ig_add_test(hdlod_scene_test ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_scene_test.cpp LIBS ig_lod)
ig_add_test(hdlod_tree_test ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_tree_test.cpp LIBS ig_lod)
# What a mutation pass found the selection tests above leave open (lod/hdlod_select).
ig_add_test(hdlod_select_mutation_test ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_select_mutation_test.cpp LIBS ig_lod)
ig_add_test(hdlod_rays_test ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_rays_test.cpp LIBS ig_lod)
# Release only, like every benchmark test: under ASAN it took 6 s of the 2-core CI run, and the
# hdlod_*_test and hdlod_pass_gltest files run the same build, selection and pass code with every
# sanitizer.
if(NOT IG_SANITIZE)
  add_test(NAME hdlod_bench_test COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_bench_test.sh $<TARGET_FILE:igbench>)
  set_tests_properties(hdlod_bench_test PROPERTIES TIMEOUT 300)
endif()
ig_add_test(hdlod_simplify_test ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_simplify_test.cpp LIBS ig_lod)
ig_add_test(hdlod_cache_test ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_cache_test.cpp LIBS ig_lod)
ig_add_test(hdlod_pass_gltest ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_pass_gltest.cpp LIBS ig_render GL)
ig_add_test(hdlod_models_test ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_models_test.cpp LIBS ig_lod)
# A real building (the FZK-Haus IFC from Debian's assimp-testmodels), fetched at test time like
# the forest's models (scripts/fetch-ifc: data/ifc/, never committed).
add_test(NAME fetch_ifc COMMAND ${PROJECT_SOURCE_DIR}/scripts/fetch-ifc)
set_tests_properties(fetch_ifc PROPERTIES FIXTURES_SETUP ifc_models TIMEOUT 300)
add_executable(hdlod_ifc_test ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_ifc_test.cpp)
target_link_libraries(hdlod_ifc_test PRIVATE ig_lod GTest::gtest GTest::gtest_main ig_warnings)
target_compile_definitions(hdlod_ifc_test PRIVATE IG_SOURCE_DIR="${PROJECT_SOURCE_DIR}" IG_BINARY_DIR="${PROJECT_BINARY_DIR}")
add_test(NAME hdlod_ifc_test COMMAND hdlod_ifc_test WORKING_DIRECTORY ${PROJECT_SOURCE_DIR})
set_tests_properties(hdlod_ifc_test PROPERTIES FIXTURES_REQUIRED ifc_models TIMEOUT 120)
