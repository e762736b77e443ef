#!/usr/bin/env bash
# igbench hdlod on a small construction site prints one JSON object with the fields the HDLOD
# issue names (selection only for now), and HDLOD never draws more triangles than full detail.
set -euo pipefail
igbench=$1
out=$("$igbench" hdlod --scale 0.05 --repeats 3 --json)
/usr/bin/python3 - "$out" <<'PY'
import json, sys
d = json.loads(sys.argv[1])
for k in ("objects", "triangles", "build_s", "cases", "sweep", "select_ms_max"):
    assert k in d, k
assert d["objects"] == d["static"] + d["pseudo_dynamic"] + d["dynamic"] + d["empty"], d
assert [(c["time"], c["screen"]) for c in d["cases"]] == [
    (t, s) for t in ("start", "1/3", "2/3", "end") for s in ("1/1", "1/4", "1/16")], d["cases"]
for c in d["cases"]:
    for side in ("hdlod", "full"):
        for f in ("triangles", "draws", "select_ms"):
            assert f in c[side], (c, side, f)
    assert 0 < c["hdlod"]["triangles"] <= c["full"]["triangles"], c
tris = [s["triangles"] for s in d["sweep"]]
assert tris == sorted(tris, reverse=True), tris  # a larger r never draws more
print("hdlod_bench_test: 1 passed, 0 failed")
PY
