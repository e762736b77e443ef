// Counts heap allocations while armed, for "no allocation per frame" tests: replaces the global
// operator new / delete of the test executable that includes it (include it from one file only).
//   gAllocs = 0; gCountAllocs = true;  ...code under test...  gCountAllocs = false;
#pragma once

#include <atomic>
#include <cstdlib>
#include <new>

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif

inline std::atomic<bool> gCountAllocs{false};
inline std::atomic<long> gAllocs{0};

void* operator new(std::size_t n) {
  if (gCountAllocs.load()) ++gAllocs;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  if (gCountAllocs.load()) ++gAllocs;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
