#!/usr/bin/env bash
# igbench terrain on the real DEM (scripts/fetch-data) prints one JSON object with every field
# the terrain issue names; ROAM needs fewer triangles than block LOD at equal error (a count,
# not a time, so it is deterministic). The DEM goes through the memory-mapped cache (written on
# the first run); Deferred runs under a visit budget, converges after the
# teleport, and the raster comparison ran. Times are reported, never asserted.
set -euo pipefail
igbench=$1
src=$2
cd "$src"
cache=$(mktemp -d)
trap 'rm -rf "$cache"' EXIT
run() { "$igbench" terrain --frames 24 --width 320 --height 180 --raster-frames 4 --cache-dir "$cache" --json; }
out=$(run)
/usr/bin/python3 - "$out" <<'PY'
import json, sys
d = json.loads(sys.argv[1])
for k in ("dem", "samples", "methods", "sweep", "block_triangles_at_equal_error", "roam_triangles_at_equal_error",
          "teleport", "raster", "frame_vs_raster_ratio", "bounds_ms", "bounds_bytes", "load_ms", "dem_mapped"):
    assert k in d, k
assert d["samples"] == 1201 * 1201, d["samples"]
assert d["dem_mapped"] and not d["dem_from_cache"], (d["dem_mapped"], d["dem_from_cache"])
for m in ("roam_enhmerge", "roam_merge", "roam_rebuild", "block", "roam_deferred"):
    r = d["methods"][m]
    for f in ("update_ms_p50", "update_ms_p99", "update_cpu_ms_p99", "teleport_update_ms", "triangles_p50",
              "visible_triangles_p50", "max_error_px", "uploads_p50", "emit_visible_ms_p50"):
        assert f in r, (m, f)
    assert r["update_ms_p99"] >= r["update_ms_p50"] >= 0, (m, r)
    assert r["triangles_p50"] > 0, (m, r)
    assert r["max_error_px"] <= 1.0 + 1e-9, (m, r)
# Deferred refines the surroundings too; what it draws matches enhMerge's view-culled mesh.
r = d["methods"]["roam_deferred"]
assert r["triangles_p50"] >= d["methods"]["roam_enhmerge"]["triangles_p50"], d["methods"]
assert "visits_p50" in r and "pending_p99" in r, r
t = d["teleport"]
assert t["jump_km"] > 10, t
assert t["deferred_frames_to_visible"] >= 1 and t["deferred_frames_to_finished"] >= t["deferred_frames_to_visible"], t
assert t["merge_ops"] > t["enhmerge_ops"] > 0, t
assert d["raster"]["ran"] and d["raster"]["triangles"] > 0 and d["raster"]["raster_ms"] > 0, d["raster"]
assert d["frame_vs_raster_ratio"] > 0, d["frame_vs_raster_ratio"]
assert [s["tolerance_px"] for s in d["sweep"]] == [0.5, 1, 2, 4, 8]
tris = [s["triangles"] for s in d["sweep"]]
assert tris == sorted(tris, reverse=True), tris  # coarser tolerance, fewer triangles
for s in d["sweep"]:
    assert s["render_ms"] > 0 and s["rmse"] >= 0 and s["psnr_db"] > 0, s
# The reference view looks at relief (the flight starts over the DEM's most rugged block): the
# sweep shows what accuracy costs. Over the sea where the old fixed start looked, 8 px drew the
# same picture as 0.5 px (RMSE 0.07 against 0.04).
rmse = [s["rmse"] for s in d["sweep"]]
assert rmse[-1] >= 1.0 and rmse[-1] > 1.5 * rmse[0], rmse
assert 0 < d["roam_triangles_at_equal_error"] < d["block_triangles_at_equal_error"], d
print("terrain_bench_test: 1 passed, 0 failed")
PY
# A long cache path (the JSON's dem_cache) still gives one whole JSON object (its header was
# printed into a 512-byte buffer and cut off), and the plot script draws the JSON of
# --no-baselines (no sweep: it raised on the log scale of no data).
long="$cache/$(printf 'd%.0s' $(seq 1 200))/$(printf 'e%.0s' $(seq 1 200))"
mkdir -p "$long"
out=$("$igbench" terrain --synthetic 65 --frames 12 --no-render --no-baselines --raster-frames 0 --cache-dir "$long" --json)
printf '%s' "$out" > "$cache/terrain.json"
/usr/bin/python3 - "$out" "$long" <<'PY'
import json, sys
d = json.loads(sys.argv[1])
assert d["dem_cache"].startswith(sys.argv[2] + "/"), d["dem_cache"]
assert d["sweep"] == [] and "roam_deferred" in d["methods"], d
print("terrain_bench_test (long cache path): 1 passed, 0 failed")
PY
/usr/bin/python3 "$src/scripts/plot_terrain_sweep.py" "$cache/terrain.json" "$cache/terrain.png"
[ "$(head -c 8 "$cache/terrain.png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] || { echo "plot_terrain_sweep.py wrote no PNG" >&2; exit 1; }
# A sweep that is not rendered (--no-render) reports no image error (null), not a perfect-looking
# 0 RMSE at 0 dB, and the plot script draws it.
out=$("$igbench" terrain --synthetic 65 --frames 12 --no-render --raster-frames 0 --cache-dir "$cache" --json)
printf '%s' "$out" > "$cache/terrain_unrendered.json"
/usr/bin/python3 - "$out" <<'PY'
import json, sys
d = json.loads(sys.argv[1])
assert d["sweep_rendered"] is False and d["sweep"], d
for s in d["sweep"]:
    assert s["triangles"] > 0 and s["rmse"] is None and s["psnr_db"] is None and s["render_ms"] is None, s
print("terrain_bench_test (sweep not rendered): 1 passed, 0 failed")
PY
/usr/bin/python3 "$src/scripts/plot_terrain_sweep.py" "$cache/terrain_unrendered.json" "$cache/terrain_unrendered.png"
[ "$(head -c 8 "$cache/terrain_unrendered.png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] || { echo "plot_terrain_sweep.py wrote no PNG" >&2; exit 1; }
