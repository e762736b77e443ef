#!/usr/bin/env bash
# worker_pair_test under ThreadSanitizer: the two-thread passes of the cells selection
# (ig/worker_pair.*, lod/cells_select.*) with every memory access checked for data races. Built
# here with the system compiler (~20 s on 2 cores) because the ASAN build cannot also be a TSAN one.
set -euo pipefail
src=$1
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
cd "$src"
c++ -std=c++20 -O1 -g -fsanitize=thread -I. tests/worker_pair_test.cpp ig/worker_pair.cpp lod/cells.cpp \
  lod/cells_select.cpp lod/view.cpp lod/geo.cpp -lgtest -lgtest_main -pthread -o "$out/worker_pair_tsan"
TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1" "$out/worker_pair_tsan"
