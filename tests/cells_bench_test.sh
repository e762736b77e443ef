#!/usr/bin/env bash
# igbench cells on a small scene prints one JSON object with the fields the cells issue names
# (selection only for now); budgets are never exceeded (exit 1 otherwise).
set -euo pipefail
igbench=$1
out=$("$igbench" cells --spheres 100 --levels 7 --frames 60 --json)
/usr/bin/python3 - "$out" <<'PY'
import json, sys
d = json.loads(sys.argv[1])
for k in ("cells", "levels", "dimension", "select_ms_p99", "voxels_drawn_p50", "voxel_budget",
          "budget_exceeded_frames", "bytes_per_frame_max", "w_bytes", "sweep"):
    assert k in d, k
assert d["budget_exceeded_frames"] == 0, d
assert d["bytes_per_frame_max"] <= d["w_bytes"], d
assert d["voxels_drawn_p50"] <= d["voxel_budget"], d
assert 1.8 < d["dimension"][-1] < 2.2, d["dimension"]  # sphere surfaces: about 2
for s in d["sweep"]:
    assert s["voxels_drawn_p50"] <= s["voxel_budget"], s
print("cells_bench_test: 1 passed, 0 failed")
PY
