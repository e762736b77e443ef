# Hierarchical cells streaming (paper 003), the pure part: the LRU cache of resident cells with a
# byte budget (the HTTP range fetcher is io/range_fetch, see io/cells.cmake).
target_sources(ig_lod PRIVATE
  ${CMAKE_CURRENT_SOURCE_DIR}/cells_cache.cpp
)
