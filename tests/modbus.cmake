# Modbus host link: the register map codec (both word orders, commit rule, field rejection,
# request checks), and the transports: TCP with libmodbus as the in-process master, then real
# peers: mbpoll as the master over TCP on loopback and over RTU on a socat pty pair.
ig_add_test(modbus_map_test modbus_map_test.cpp LIBS ig_io)
ig_add_test(modbus_link_test modbus_link_test.cpp LIBS ig_io PkgConfig::MODBUS)
# igd end to end: mbpoll writes sets over TCP and over RTU (socat pty pair) while igd renders;
# the stats CSV must show each rendered set's eyepoint, the exit line the link counters.
add_test(NAME modbus_igd_test COMMAND /usr/bin/python3 ${CMAKE_CURRENT_SOURCE_DIR}/modbus_igd_test.py
         $<TARGET_FILE:igd> ${PROJECT_SOURCE_DIR})
set_tests_properties(modbus_igd_test PROPERTIES TIMEOUT 240)
if(IG_SANITIZE)
  # igd runs the Mesa driver: keep ASAN and UBSAN, not LeakSanitizer (see ig_add_test).
  set_tests_properties(modbus_igd_test PROPERTIES ENVIRONMENT "ASAN_OPTIONS=detect_leaks=0:abort_on_error=1")
endif()
