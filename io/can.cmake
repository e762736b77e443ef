# SocketCAN host link (io/can_map: frame map, set assembler, candump logs; io/can_link: raw
# CAN socket transport). Linux headers only, no library.
target_sources(ig_io PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/can_map.cpp
  ${CMAKE_CURRENT_SOURCE_DIR}/can_link.cpp
)
target_link_libraries(ig_io PRIVATE Threads::Threads)
