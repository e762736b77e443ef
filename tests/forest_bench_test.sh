#!/usr/bin/env bash
# igbench forest --quick (the CI mode, ~10 s) prints one JSON object with every field the forest
# issue names, with sane values; no tree is dropped (exit 1 otherwise). Runs in the source
# folder: the real DEM and tree models are used when scripts/fetch-data / fetch-forest fetched
# them, the procedural fallbacks otherwise (the JSON's "ground" and "models" say which).
set -euo pipefail
igbench=$1
out=$("$igbench" forest --quick --json)
/usr/bin/python3 - "$out" <<'PY'
import json, sys
d = json.loads(sys.argv[1])
for k in ("trees", "area_km2", "cull_ms_p50", "cull_ms_p99", "trees_drawn_p50", "layers", "fins_drawn_p50",
          "frame_ms_p50", "popping_max", "popping_max_no_forest", "sweep", "cull_sweep", "ground", "models"):
    assert k in d, k
assert d["trees"] > 10000, d["trees"]
assert 0 < d["trees_drawn_p50"] <= d["trees"], d
assert d["cull_ms_p99"] >= d["cull_ms_p50"] >= 0, d
assert d["frame_ms_p50"] > 0 and d["layers"] == 8, d
assert d["popping_max"] >= d["popping_p50"] >= 0 and d["popping_max_no_forest"] > 0, d
near = [s["near_m"] for s in d["cull_sweep"]]
drawn = [s["trees_drawn_p50"] for s in d["cull_sweep"]]
assert near == sorted(near) and drawn == sorted(drawn), d["cull_sweep"]  # a longer near range draws more
assert len(d["sweep"]) >= 4, d["sweep"]
for s in d["sweep"]:
    assert s["frame_ms"] > 0 and 10 < s["psnr_db"] < 99, s  # rendered, close to but not equal to the reference
# Fewer layers drawn of the 8 (composited): 4, 2, 1, each rendered and close to the reference.
assert [s["layers_drawn"] for s in d["drawn_sweep"]] == [4, 2, 1], d["drawn_sweep"]
for s in d["drawn_sweep"]:
    assert s["layers"] == 8 and s["frame_ms"] > 0 and 10 < s["psnr_db"] < 99, s
    assert 0 < s["switch_change"] < 255 and 0 <= s["switch_popped"] <= 1, s
print("forest_bench_test: 1 passed, 0 failed")
PY
