#!/usr/bin/env bash
# igbench queries --json (the host's terrain queries per kind of surface, docs/cigi.md) prints one
# JSON object with every field it documents and sane values: each kind timed, hits where a kind
# must hit (a HOT inside the grid, a ray into the site or the forest), work within what one
# query may cost (the per-frame query work budget's units), the indices built.
set -euo pipefail
igbench=$1
out=$("$igbench" queries --json --queries 300)
/usr/bin/python3 - "$out" <<'PY'
import json, sys
d = json.loads(sys.argv[1])
for k in ("suite", "queries", "terrain_posts", "objects", "object_triangles", "objects_index_ms", "trees",
          "forest_index_ms", "forest_index_mb"):
    assert k in d, k
assert d["suite"] == "queries" and d["queries"] == 300, d
assert d["objects"] > 1000 and d["object_triangles"] > 100000 and d["trees"] > 100000, d
assert d["objects_index_ms"] > 0 and d["forest_index_ms"] > 0 and 1 < d["forest_index_mb"] < 200, d
for kind in ("terrain_hot", "terrain_los", "objects_hot", "objects_los", "forest_los"):
    k = d[kind]
    for f in ("us_p50", "us_p99", "us_mean", "work_mean", "work_max", "hit_pct", "ns_per_work"):
        assert f in k, (kind, f)
    assert 0 < k["us_p50"] <= k["us_p99"], (kind, k)
    assert 1 <= k["work_mean"] <= k["work_max"] <= 40000, (kind, k)
assert d["terrain_hot"]["hit_pct"] == 100.0 and d["objects_hot"]["hit_pct"] == 100.0, d
assert d["objects_los"]["hit_pct"] > 90 and d["forest_los"]["hit_pct"] > 90 and d["terrain_los"]["hit_pct"] > 50, d
print("queries_bench_test: 1 passed, 0 failed")
PY
