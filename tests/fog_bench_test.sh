#!/usr/bin/env bash
# igbench fog --json (docs: README "Fog"): one JSON object with every field it documents; at each
# visibility the fog-culled picture is the one drawn with the host's far plane to within one
# colour level, and thick fog draws fewer triangles (none when the eye is above the opaque
# distance); scripts/plot_fog.py plots it. Times are reported, not asserted (benchmarks hold the goals).
set -euo pipefail
igbench=$1
cd "$2"
out=$("$igbench" fog --json --frames 2 --width 320 --height 180 --visibility 300 --visibility 800 --visibility 20000)
/usr/bin/python3 - "$out" <<'PY'
import json, sys
d = json.loads(sys.argv[1])
for k in ("suite", "scene", "renderer", "width_px", "height_px", "frames", "points", "speedup_min", "speedup_max",
          "max_diff_levels"):
    assert k in d, k
assert d["suite"] == "fog" and d["frames"] == 2 and (d["width_px"], d["height_px"]) == (320, 180), d
p = {round(x["visibility_m"]): x for x in d["points"]}
assert sorted(p) == [300, 800, 20000], p
for v, x in p.items():
    for k in ("cull_distance_m", "triangles_cull", "triangles_full", "triangle_ratio", "frame_ms_cull", "frame_ms_full",
              "speedup", "max_diff_levels", "differ_pct", "psnr_db_min"):
        assert k in x, (v, k)
    assert abs(x["cull_distance_m"] - 1.7719 * v) < 0.001 * v, x
    assert x["max_diff_levels"] <= 1 and x["psnr_db_min"] > 60, x
    assert x["frame_ms_cull"] > 0 and x["frame_ms_full"] > 0, x
    assert x["triangles_full"] > 10000, x
# The built-in flight is 900 m up: at 300 m visibility nothing is within the opaque distance (532 m).
assert p[300]["triangles_cull"] == 0, p[300]
assert 0 < p[800]["triangles_cull"] < 0.5 * p[800]["triangles_full"], p[800]
assert p[20000]["triangle_ratio"] > 0.95, p[20000]
assert d["max_diff_levels"] <= 1, d
PY
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
printf '%s\n' "$out" > "$tmp/fog.json"
/usr/bin/python3 scripts/plot_fog.py "$tmp/fog.json" "$tmp/fog.png"
[ "$(head -c 8 "$tmp/fog.png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] || { echo "plot_fog.py wrote no PNG" >&2; exit 1; }
echo "fog_bench_test: 1 passed, 0 failed"
