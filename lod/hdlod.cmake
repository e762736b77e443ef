# HDLOD (paper 000): 4D scene model, cluster-tree generation, per-frame selection, and the
# synthetic construction-site generator. Pure: no GL, no clock, no threads.
target_sources(ig_lod PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_scene.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_build.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_select.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_site.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_cache.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_models.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_rays.cpp
)
# glTF models (lod/hdlod_models.cpp): Debian libtinygltf-dev (CMake package TinyGLTF, a shared
# library with its header).
find_package(TinyGLTF REQUIRED CONFIG)
target_link_libraries(ig_lod PRIVATE TinyGLTF::TinyGLTF)
# IFC models (lod/hdlod_models.cpp): Debian libassimp-dev (pkg-config assimp; its IFC importer is
# enabled in Debian's build).
pkg_check_modules(ASSIMP REQUIRED IMPORTED_TARGET assimp)
target_link_libraries(ig_lod PRIVATE PkgConfig::ASSIMP)

# Parent-cluster simplifiers (lod/hdlod_simplify.h): Debian libmeshoptimizer-dev (CMake package
# meshoptimizer, target meshoptimizer::meshoptimizer) and libopenmesh-dev (CMake package OpenMesh,
# targets OpenMeshCore and OpenMeshTools).
find_package(meshoptimizer REQUIRED CONFIG)
find_package(OpenMesh REQUIRED CONFIG)
target_sources(ig_lod PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/hdlod_simplify.cpp)
target_link_libraries(ig_lod PRIVATE meshoptimizer::meshoptimizer OpenMeshTools OpenMeshCore)
