# The service side of the host links: an in-process link drives the frame loop (recording,
# link loss, synchronous mode, Start of Frame calls), then the recording is replayed.
ig_add_test(host_input_gltest host_input_gltest.cpp LIBS ig_core GL)
