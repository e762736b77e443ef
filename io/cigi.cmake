# CIGI 3.3 over UDP: the pure codec (cigi.cpp), the assembler and UDP transport (cigi_link.cpp)
# and the pcap capture -> recording converter (pcap.cpp).
target_sources(ig_io PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/cigi.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/cigi_link.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/pcap.cpp
)
find_package(Threads REQUIRED)
target_link_libraries(ig_io PUBLIC Threads::Threads)
