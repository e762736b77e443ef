# Forest (paper 004): placement and fades, the kd-tree and its selection, fins and cones (lod/);
# the GL pass (trees where the map has density, nothing in glades, textures T and S); a scene
# without a forest runs no forest work; the benchmark's JSON in --quick mode.
ig_add_test(forest_placement_test forest_placement_test.cpp LIBS ig_lod)
ig_add_test(forest_kdtree_test forest_kdtree_test.cpp LIBS ig_lod)
ig_add_test(forest_rays_test forest_rays_test.cpp LIBS ig_lod)
# The host queries' surfaces of the layers together (ig/scene_surfaces.h: trees and [hdlod] objects).
ig_add_test(scene_surfaces_test scene_surfaces_test.cpp LIBS ig_core)
ig_add_test(forest_fins_test forest_fins_test.cpp LIBS ig_lod)
# What a mutation pass found forest_kdtree_test and forest_fins_test leave open (lod/forest_kdtree,
# lod/forest_fins).
ig_add_test(forest_mutation_test forest_mutation_test.cpp LIBS ig_lod)
ig_add_test(forest_gltest forest_gltest.cpp LIBS ig_core ig_render PkgConfig::EGL GL)
ig_add_test(forest_service_gltest forest_service_gltest.cpp LIBS ig_core PkgConfig::EGL GL)
# The real tree models (Scopia pine and cypress, Debian's sweethome3d-furniture), fetched at test
# time like the DEM (tests/CMakeLists.txt's fetch_data); the benchmark falls back to procedural
# models without them and says so in its JSON.
add_test(NAME fetch_forest COMMAND ${PROJECT_SOURCE_DIR}/scripts/fetch-forest)
set_tests_properties(fetch_forest PROPERTIES FIXTURES_SETUP forest_models TIMEOUT 300)
# Release only, like every benchmark test: under ASAN it took 9 s of the 2-core CI run, and
# forest_gltest and forest_service_gltest run the same pass, bake and selection code with every
# sanitizer.
if(NOT IG_SANITIZE)
  add_test(NAME forest_bench_test COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/forest_bench_test.sh $<TARGET_FILE:igbench>
           WORKING_DIRECTORY ${PROJECT_SOURCE_DIR})
  set_tests_properties(forest_bench_test PROPERTIES TIMEOUT 300 FIXTURES_REQUIRED "real_data;forest_models")
endif()
