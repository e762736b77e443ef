# The ROAM terrain layer in the service: Deferred updates and geomorphing both ways.
ig_add_test(terrain_service_gltest terrain_service_gltest.cpp LIBS ig_core GL)
