#!/usr/bin/env bash
# igtool cells-build: a procedural scene -> a cell database (JSON consistent with the file, the
# box-counting dimension about 2 at the fine levels); with the real bunny (scripts/fetch-cells)
# when SRC is given: D(l) within 1.95..2.05 at levels 6..8 (paper 003, Table 1: 1.983..1.998);
# bad options exit 2 naming the value.
set -euo pipefail
igtool=$1
src=${2:-}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$igtool" cells-build --scene spheres:40 --cell-levels 5 --depth 3 -o "$tmp/s.ighc" --json > "$tmp/s.json"
/usr/bin/python3 - "$tmp/s.json" "$tmp/s.ighc" <<'PY'
import json, os, sys
j = json.load(open(sys.argv[1]))
assert j["cells"] == sum(j["cells_per_level"]), j
assert j["file_bytes"] == os.path.getsize(sys.argv[2]), j
assert j["payload_bytes"] == sum(j["bytes_per_level"]), j
assert 1.9 < j["dimension"][-1] < 2.1, j["dimension"]
assert len(j["box_counting_dimension"]) == len(j["voxels"]), j
assert j["box_counting_dimension"][0] == 0 and 1.5 < j["box_counting_dimension"][-1] < 3.0, j
PY
if [ -n "$src" ]; then
  "$igtool" cells-build "$src/data/cells/src/bunny.obj" --y-up --size 0.155 --voxel-levels 9 --cell-levels 6 \
    --depth 3 -o "$tmp/b.ighc" --json > "$tmp/b.json"
  /usr/bin/python3 - "$tmp/b.json" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
assert j["triangles"] == 69666, j["triangles"]
for l in (6, 7, 8):
    assert 1.95 < j["dimension"][l] < 2.05, (l, j["dimension"])
PY
fi
if "$igtool" cells-build --scene spheres:0 -o "$tmp/x.ighc" 2> "$tmp/err"; then exit 1; fi
grep -q "spheres:0" "$tmp/err"
if "$igtool" cells-build "$tmp/missing.obj" -o "$tmp/x.ighc" 2> "$tmp/err"; then exit 1; fi
grep -q "missing.obj" "$tmp/err"
echo "cells_tool_test: ok"
