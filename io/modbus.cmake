# Modbus host link: the pure register map (modbus_map.cpp) and the libmodbus transports, TCP
# server and RTU slave (modbus_link.cpp). Debian: libmodbus-dev.
pkg_check_modules(MODBUS REQUIRED IMPORTED_TARGET GLOBAL libmodbus)
target_sources(ig_io PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/modbus_map.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/modbus_link.cpp
)
target_link_libraries(ig_io PRIVATE PkgConfig::MODBUS Threads::Threads)
