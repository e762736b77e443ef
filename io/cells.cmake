# Hierarchical cells streaming (paper 003): the asynchronous HTTP byte-range fetcher (one worker
# thread, POSIX sockets, zlib crc32 of each range). Debian: zlib1g-dev.
find_package(ZLIB REQUIRED)
find_package(Threads REQUIRED)
target_sources(ig_io PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/range_fetch.cpp
)
target_link_libraries(ig_io PRIVATE ZLIB::ZLIB PUBLIC Threads::Threads)
