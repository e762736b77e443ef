# Hierarchical cells streaming (paper 003): the HTTP byte-range fetcher against real nginx
# (scripts/cells-server) and a fault-injecting python server, and the LRU cell cache.
find_package(ZLIB REQUIRED)
ig_add_test(range_fetch_test range_fetch_test.cpp LIBS ig_io ZLIB::ZLIB)
ig_add_test(cells_cache_test cells_cache_test.cpp LIBS ig_lod)
# The streaming client (ig/cells_stream): local file and nginx, budgets, corrupt cells, server down.
ig_add_test(cells_stream_client_test cells_stream_client_test.cpp LIBS ig_core)
# The [cells] scene layer (ig/cells_layer) on a headless context: draws the object after some
# frames within the budgets, origin_m placement (1e6 m), bad sources named.
ig_add_test(cells_layer_gltest cells_layer_gltest.cpp LIBS ig_core GL)
