# SocketCAN host link: the frame map, set assembly, candump logs and the DBC file (unit tests),
# and the real kernel stack inside user-mode Linux (vcan + can-raw, driven by can-utils).
ig_add_test(can_map_test can_map_test.cpp LIBS ig_io)
# With the CIGI link built too, the CAN attitude is checked against the CIGI assembler's.
if("cigi" IN_LIST IG_HOST_LINKS)
  target_compile_definitions(can_map_test PRIVATE IG_TEST_WITH_CIGI=1)
endif()

# The real kernel stack inside user-mode Linux (tests/uml/). ASAN cannot run there (UML's
# address space ends at 0x7fc0000000, below ASAN's fixed shadow range), so in a sanitizer build
# the probe is compiled from the sources without sanitizers.
if(IG_SANITIZE)
  add_executable(can_uml_probe can_uml_probe.cpp ${PROJECT_SOURCE_DIR}/io/can_map.cpp
    ${PROJECT_SOURCE_DIR}/io/can_link.cpp ${PROJECT_SOURCE_DIR}/lod/geo.cpp)
  target_compile_options(can_uml_probe PRIVATE -fno-sanitize=all)
  target_link_options(can_uml_probe PRIVATE -fno-sanitize=all)
  target_include_directories(can_uml_probe PRIVATE ${PROJECT_SOURCE_DIR})
  target_link_libraries(can_uml_probe PRIVATE glm::glm Threads::Threads ig_warnings)
else()
  add_executable(can_uml_probe can_uml_probe.cpp)
  target_link_libraries(can_uml_probe PRIVATE ig_io Threads::Threads ig_warnings)
endif()
# UML on hosts with a larger XSAVE area than its own (AVX-512, AMX): tests/uml/xstate_shim.cpp,
# preloaded by tests/uml/boot.sh. Never sanitized: it runs inside the UML kernel process.
add_library(uml_xstate_shim SHARED uml/xstate_shim.cpp)
target_compile_options(uml_xstate_shim PRIVATE -fno-sanitize=all)
target_link_options(uml_xstate_shim PRIVATE -fno-sanitize=all)
target_link_libraries(uml_xstate_shim PRIVATE ${CMAKE_DL_LIBS} ig_warnings)
add_test(NAME can_uml_test COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/can_uml_test.sh $<TARGET_FILE:can_uml_probe>
  ${PROJECT_SOURCE_DIR})
set_tests_properties(can_uml_test PROPERTIES TIMEOUT 150 ENVIRONMENT "IG_UML_SHIM=$<TARGET_FILE:uml_xstate_shim>")

# igd end to end inside user-mode Linux: [host] source = "can" on vcan0, canplayer sends, the
# stats CSV, the counters line and the recording are checked. Not in a sanitizer build: igd
# itself would need ASAN, which cannot run inside UML (see above).
if(NOT IG_SANITIZE)
  add_test(NAME can_igd_test COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/can_igd_test.sh $<TARGET_FILE:igd>
    ${PROJECT_SOURCE_DIR})
  set_tests_properties(can_igd_test PROPERTIES TIMEOUT 200 ENVIRONMENT "IG_UML_SHIM=$<TARGET_FILE:uml_xstate_shim>")
endif()
