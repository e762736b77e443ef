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
# A scan in absolute coordinates (ECEF ~6.4e6 m, where a float's step is 0.5 m) voxelizes as the
# same mesh at the origin: the loader stored float coordinates, so the 10 m sphere below became
# a lattice of 0.5 m steps before voxelizing (finest voxel 4 cm).
/usr/bin/python3 - "$tmp" <<'PY'
import math, sys
for name, off in (("near", (0.0, 0.0, 0.0)), ("far", (6378137.0, 6378137.0, 6378137.0))):
    with open(f"{sys.argv[1]}/{name}.obj", "w") as f:
        rings, segs, r = 12, 24, 5.0
        f.write("v %.6f %.6f %.6f\n" % (off[0], off[1], off[2] + r))
        for i in range(1, rings):
            th = math.pi * i / rings
            for j in range(segs):
                ph = 2 * math.pi * j / segs
                f.write("v %.6f %.6f %.6f\n" % (off[0] + r * math.sin(th) * math.cos(ph),
                                                 off[1] + r * math.sin(th) * math.sin(ph), off[2] + r * math.cos(th)))
        f.write("v %.6f %.6f %.6f\n" % (off[0], off[1], off[2] - r))
        ring = lambda i, j: 2 + (i - 1) * segs + j % segs
        for j in range(segs):
            f.write("f 1 %d %d\n" % (ring(1, j), ring(1, j + 1)))
            last = 2 + (rings - 1) * segs
            f.write("f %d %d %d\n" % (last, ring(rings - 1, j + 1), ring(rings - 1, j)))
        for i in range(1, rings - 1):
            for j in range(segs):
                f.write("f %d %d %d %d\n" % (ring(i, j), ring(i + 1, j), ring(i + 1, j + 1), ring(i, j + 1)))
PY
for name in near far; do
  "$igtool" cells-build "$tmp/$name.obj" --voxel-levels 8 --cell-levels 4 --depth 3 -o "$tmp/$name.ighc" --json \
    > "$tmp/$name.json"
done
/usr/bin/python3 - "$tmp/near.json" "$tmp/far.json" <<'PY'
import json, sys
a, b = (json.load(open(f)) for f in sys.argv[1:3])
voxel = a["finest_voxel_m"]
assert abs(a["root_edge_m"] - b["root_edge_m"]) <= voxel, (a["root_edge_m"], b["root_edge_m"])
for k in range(3):
    assert abs(a["root_min_m"][k] - b["root_min_m"][k]) <= voxel, (a["root_min_m"], b["root_min_m"])
for l, (na, nb) in enumerate(zip(a["voxels"], b["voxels"])):
    assert abs(na - nb) <= 0.01 * na, ("voxels per level at the origin / at 6.4e6 m", a["voxels"], b["voxels"])
PY
if "$igtool" cells-build --scene spheres:0 -o "$tmp/x.ighc" 2> "$tmp/err"; then exit 1; fi
grep -q "spheres:0" "$tmp/err"
if "$igtool" cells-build "$tmp/missing.obj" -o "$tmp/x.ighc" 2> "$tmp/err"; then exit 1; fi
grep -q "missing.obj" "$tmp/err"
echo "cells_tool_test: ok"
