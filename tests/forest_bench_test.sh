#!/usr/bin/env bash
# igbench forest on a small forest prints one JSON object with the fields the forest issue
# names (culling only for now), and no tree is dropped (exit 1 otherwise).
set -euo pipefail
igbench=$1
out=$("$igbench" forest --posts 65 --frames 60 --json)
/usr/bin/python3 - "$out" <<'PY'
import json, sys
d = json.loads(sys.argv[1])
for k in ("trees", "area_km2", "cull_ms_p50", "cull_ms_p99", "trees_drawn_p50", "fins_drawn_p50", "sweep"):
    assert k in d, k
assert d["trees"] > 10000, d["trees"]
assert 0 < d["trees_drawn_p50"] <= d["trees"], d
assert d["cull_ms_p99"] >= d["cull_ms_p50"] >= 0, d
near = [s["near_m"] for s in d["sweep"]]
drawn = [s["trees_drawn_p50"] for s in d["sweep"]]
assert near == sorted(near) and drawn == sorted(drawn), d["sweep"]  # a longer near range draws more
print("forest_bench_test: 1 passed, 0 failed")
PY
