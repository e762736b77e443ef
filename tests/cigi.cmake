# CIGI 3.3 host link: codec / assembler / pcap unit tests, the link over loopback UDP, and the
# interoperability test against an independent Python encoder and Debian's tshark dissector.
ig_add_test(cigi_test cigi_test.cpp LIBS ig_io)
ig_add_test(cigi_link_test cigi_link_test.cpp LIBS ig_io)

# cigi_probe: the CIGI link (or the pcap converter) alone, printing what it decoded, for the
# script tests below.
add_executable(cigi_probe cigi_probe.cpp)
target_link_libraries(cigi_probe PRIVATE ig_io ig_warnings)

# Interoperability with an independent encoder (tests/cigi_sender.py, struct.pack from the
# ICD's layouts) and with Debian's tshark CIGI dissector, on a real capture of loopback traffic
# (dumpcap on lo: needs root or CAP_NET_RAW), which is then also converted by the pcap reader.
add_test(NAME cigi_interop_test COMMAND /usr/bin/python3 ${CMAKE_CURRENT_SOURCE_DIR}/cigi_interop_test.py
  $<TARGET_FILE:cigi_probe>)
set_tests_properties(cigi_interop_test PROPERTIES TIMEOUT 120)
if(IG_SANITIZE)
  set_tests_properties(cigi_interop_test PROPERTIES ENVIRONMENT "ASAN_OPTIONS=abort_on_error=1")
endif()

# End to end through the real igd (headless, 64x64, paced at 30 Hz) driven by the Python host.
if(TARGET igd)
  add_test(NAME cigi_igd_test COMMAND /usr/bin/python3 ${CMAKE_CURRENT_SOURCE_DIR}/cigi_igd_test.py
    $<TARGET_FILE:igd> ${PROJECT_SOURCE_DIR})
  set_tests_properties(cigi_igd_test PROPERTIES TIMEOUT 180)
  if(IG_SANITIZE)
    # igd runs the Mesa driver: keep ASAN and UBSAN, not LeakSanitizer (see ig_add_test).
    set_tests_properties(cigi_igd_test PROPERTIES ENVIRONMENT "ASAN_OPTIONS=detect_leaks=0:abort_on_error=1")
  endif()
endif()

# igbench queries: the cost of HAT/HOT and LOS per kind of surface (terrain, objects, trees).
# Release only, like every benchmark test.
if(NOT IG_SANITIZE)
  add_test(NAME queries_bench_test COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/queries_bench_test.sh $<TARGET_FILE:igbench>)
  set_tests_properties(queries_bench_test PROPERTIES TIMEOUT 120)
endif()
