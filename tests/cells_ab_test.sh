#!/usr/bin/env bash
# scripts/cells-ab on a small tree: the tree written by `igbench cells --dump-tree` is read back
# by both sides (CellTree::build validates it), and the working tree's selection runs side by
# side with itself (--old-src: one side renamed into its own namespace; no git needed), so both
# must choose the same cells in every frame of both runs (the selection depends on the views and
# arrivals only). Also: --dump-tree to a path that cannot be written names it and fails; a bad
# revision or source folder is refused.
set -euo pipefail
igbench=$1
src=$2
cd "$src"
if out=$("$igbench" cells --dump-tree /nonexistent-dir/tree.bin --spheres 5 --levels 3 2>&1); then
  echo "FAIL: --dump-tree to an unwritable path succeeded" >&2
  exit 1
fi
grep -q "/nonexistent-dir/tree.bin" <<<"$out" || { echo "FAIL: the error does not name the path: $out" >&2; exit 1; }
out=$(IG_IGBENCH=$igbench scripts/cells-ab --old-src . --spheres 40 --levels 6 --voxel-depth 2 --reps 2 --frames 40 \
      --voxel-budget 20000 --w-bytes 20000 2>&1)
echo "$out"
grep -Eq "cells-ab: streaming path \(40 frames, voxel budget 20000\): .* new/old p50 [0-9.]+ p99 [0-9.]+ mean [0-9.]+ \| the same choices in every frame" <<<"$out"
grep -Eq "cells-ab: everything resident \(40 frames, voxel budget 20000, no op cap\): .* \| the same choices in every frame" <<<"$out"
if IG_IGBENCH=$igbench scripts/cells-ab no-such-revision >/dev/null 2>&1; then
  echo "FAIL: cells-ab accepted a bad revision" >&2
  exit 1
fi
if IG_IGBENCH=$igbench scripts/cells-ab --old-src /nonexistent-dir >/dev/null 2>&1; then
  echo "FAIL: cells-ab accepted a source folder without lod/" >&2
  exit 1
fi
echo "cells_ab_test: ok"
