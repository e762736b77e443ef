#!/usr/bin/env bash
# igbench perfmodel --quick (two sweeps) and igbench adaptive --quick print one JSON object each with the
# fields issue 7 names; predictions are positive and finite, the calibration's T_tri table and t_c
# pair are consistent, every mode of the adaptive run drew
# every frame, and the ratios are consistent with the per-mode means; the adaptive pass ends the
# occluded phase in occlusion culling; boxes under a pixel count as partly rasterized
# (raster_share). (Timing goals are benchmark results, not asserted here.)
set -euo pipefail
igbench=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
perf=$("$igbench" perfmodel --quick --sweeps 2 --calibration-runs 2 --json --cache "$dir/calibration.txt" \
      --calibration-trace "$dir/calibration.csv")
# --calibration-trace: every frame of the calibration's interleaved loads. Each timed frame
# follows an untimed frame of the same load in the same repeat (llvmpipe leaves part of a frame's
# work to the next one: a load timed after another load's frame paid for that one); the warm-up
# repeat is not timed; every load has as many timed frames. A trace that cannot be written fails
# at once, naming the file.
/usr/bin/python3 - "$dir/calibration.csv" <<'PY'
import csv, collections, sys
rows = list(csv.DictReader(open(sys.argv[1])))
assert rows and list(rows[0].keys()) == ["run", "repeat", "load", "timed", "frame_ms", "submit_ms", "thread_ms"], rows[:1]
timed = collections.Counter()
for i, r in enumerate(rows):
    assert float(r["frame_ms"]) > 0 and 0 <= float(r["submit_ms"]) <= float(r["frame_ms"]) + 1e-3, r
    if r["timed"] == "1":
        prev = rows[i - 1]
        assert i > 0 and prev["timed"] == "0" and (prev["load"], prev["repeat"], prev["run"]) == (r["load"], r["repeat"], r["run"]), (prev, r)
        assert r["repeat"] != "0", r
        timed[r["load"]] += 1
    elif r["repeat"] != "0":
        assert i + 1 < len(rows) and rows[i + 1]["load"] == r["load"] and rows[i + 1]["timed"] == "1", (r, rows[i + 1:i + 2])
assert len(timed) == 19 and len(set(timed.values())) == 1 and min(timed.values()) >= 5, timed
assert {"full_1", "full_4", "layer", "layer_small", "layer_mid", "state_2000", "nodes_64_boxes"} <= set(timed), timed
PY
if "$igbench" perfmodel --quick --sizes 10 --calibration-trace "$dir/no-such-dir/c.csv" 2> "$dir/err.txt"; then
  echo "an unwritable --calibration-trace was accepted"; exit 1
fi
grep -q "$dir/no-such-dir/c.csv" "$dir/err.txt" || { cat "$dir/err.txt"; exit 1; }
# 10 boxes of ~1,000 px and 20,000 of ~0.6 px (0.05 screens): most of the small ones cover no
# pixel centre, so only a share of their triangles reaches the rasterizer. (Before the adaptive
# run: its viewport has a calibration of its own, which replaces this one in the cache file.)
tiny=$("$igbench" perfmodel --sizes 10,20000 --coverage 0.05 --repeats 3 --sweeps 1 --json --cache "$dir/calibration.txt")
adaptive=$("$igbench" adaptive --quick --json --cache "$dir/calibration.txt" --trace "$dir/trace.json")
# Fewer boxes than the few-moving phase's 300 (--objects takes 100 ... 1000000): the growing phase
# must not run away (the box count wrapped around below zero and it added boxes without end).
small=$(timeout 60 "$igbench" adaptive --objects 200 --frames-per-phase 10 --window 5 --repeats 1 --json \
        --cache "$dir/calibration.txt")
# The device string (the calibration key: GL vendor, renderer, version, CPU model) goes into both
# JSON objects escaped and whole: Mesa's force_gl_renderer (driconf, read from the environment)
# names the renderer with a quote, a backslash and, as a long CPU model name and Mesa version
# string can, enough characters to fill the adaptive benchmark's 512-byte header buffer (printed
# raw, the quote broke the JSON; cut off at the buffer, the JSON was unterminated). The
# perfmodel run calibrates at the adaptive run's viewport and material work, so the adaptive run
# takes the constants from the cache.
renderer="llvm\"pipe\\x$(printf 'y%.0s' $(seq 1 150))"
named_perf=$(force_gl_renderer="$renderer" "$igbench" perfmodel --quick --sizes 10 --repeats 1 --width 480 --height 270 \
             --fragment-work 0 --calibrate-first --json --cache "$dir/named.txt")
named_adaptive=$(force_gl_renderer="$renderer" timeout 60 "$igbench" adaptive --objects 100 --frames-per-phase 10 \
                 --window 10 --repeats 1 --json --cache "$dir/named.txt")
/usr/bin/python3 - "$named_perf" "$named_adaptive" "$renderer" <<'PY'
import json, sys
for text in sys.argv[1:3]:
    d = json.loads(text)
    assert ("|" + sys.argv[3] + "|") in d["device"], d["device"]
assert json.loads(sys.argv[2])["calibration_from_cache"] is True
# --calibrate-first: the whole calibration before the sweep.
cal = json.loads(sys.argv[1])["calibration"]
assert cal["from_cache"] is False and cal["between_sweeps"] is False, cal
PY
/usr/bin/python3 - "$small" <<'PY'
import json, sys
s = json.loads(sys.argv[1])
rows = s["trace"]
assert max(r["objects"] for r in rows) <= 200 + 4, rows  # 200 boxes and the 4 walls
assert [r["objects"] for r in rows if r["phase"] == "growing"][-1] == 200, rows
PY
/usr/bin/python3 - "$perf" "$adaptive" "$dir/trace.json" "$tiny" <<'PY'
import json, math, sys
t = json.loads(sys.argv[4])
assert t["calibration"]["from_cache"] is True and t["calibration"]["between_sweeps"] is False, t["calibration"]
for pt in t["points"]:
    if pt["objects"] == 10:
        assert pt["raster_share"] >= 0.99, pt
    else:
        assert 0.05 < pt["raster_share"] < 0.9, pt
p = json.loads(sys.argv[1])
for pt in p["points"]:
    assert 0 <= pt["raster_share"] <= 1, pt
for k in ("points", "error_pct_median", "error_pct_max", "calibration"):
    assert k in p, k
assert len(p["points"]) >= 4, p["points"]
for pt in p["points"]:
    for f in ("objects", "measured_ms", "predicted_ms", "error_pct"):
        assert f in pt, (pt, f)
    assert pt["measured_ms"] > 0 and math.isfinite(pt["predicted_ms"]) and pt["predicted_ms"] > 0, pt
    assert abs(pt["error_pct"] - 100 * abs(pt["predicted_ms"] - pt["measured_ms"]) / pt["measured_ms"]) < 0.5, pt
# Two sweeps: each point keeps its faster median (the error above is recomputed from it), and the
# spread between the sweeps is reported.
assert p["sweeps"] == 2, p["sweeps"]
for pt in p["points"]:
    assert len(pt["sweep_ms"]) == 2 and abs(min(pt["sweep_ms"]) - pt["measured_ms"]) < 1e-3, pt
assert 0 <= p["sweep_spread_pct_median"] <= p["sweep_spread_pct_max"], p
# The calibration: T_tri by the triangles of a call (12 ... 768), non-increasing, its last entry
# the long-call T_tri; t_c at 20,000 commands and at the large count (never below it); one run
# with --quick.
c = p["calibration"]
# Two calibration runs and two sweeps take turns: run, sweep, run, sweep.
assert c["from_cache"] is False and c["runs"] == 2 and c["between_sweeps"] is True, c
by = c["tri_ns_by_draw"]
assert list(by.keys()) == [str(12 << i) for i in range(7)], by
vals = list(by.values())
assert all(v > 0 for v in vals) and all(a >= b for a, b in zip(vals, vals[1:])), by
assert abs(c["tri_ns"] - vals[-1]) < 0.01, (c["tri_ns"], vals)
assert c["command_count"] == 20000, c
assert c["command_large_ns"] >= c["command_ns"] - 0.05, c
assert c["command_large_count"] in (0, 135000), c
# The application thread's CPU time until the GL calls return: within that wall time.
for pt in p["points"]:
    assert 0 <= pt["app_cpu_ms"] <= pt["submit_ms"] + 0.05, pt
errs = sorted(pt["error_pct"] for pt in p["points"])
assert abs(p["error_pct_max"] - errs[-1]) < 0.01, (p["error_pct_max"], errs)
a = json.loads(sys.argv[2])
for mode in ("percommand", "octree", "occlusion", "adaptive"):
    m = a["modes"][mode]
    assert m["mean_ms"] > 0 and m["p99_ms"] >= m["mean_ms"] * 0.5, (mode, m)
assert a["adaptive_worst_ratio"] > 0 and a["adaptive_mean_ratio"] > 0, a
for mode, m in a["modes"].items():
    assert 0 < m["app_cpu_mean_ms"] <= 2 * m["mean_ms"], (mode, m)
# The walls of the last phase hide most boxes: whichever mode the growing phase ended in, the
# adaptive pass's estimate sees them and it ends in occlusion culling (condition (6), or its
# per-object form).
last = a["trace"][-1]
assert last["phase"] == "occluded" and last["adaptive_mode"] == "occlusion" and last["hidden"] > 0, last
assert last["cond6_visible_ms"] < last["cond6_all_ms"], last
for row in a["trace"]:
    assert all(row[k] >= 0 for k in ("cond5_percommand_ms", "cond5_octree_ms", "cond6_all_ms", "cond6_visible_ms")), row
assert json.load(open(sys.argv[3]))["modes"].keys() == a["modes"].keys()
print(f"perfmodel: error median {p['error_pct_median']:.1f} % max {p['error_pct_max']:.1f} %; "
      f"adaptive worst {a['adaptive_worst_ratio']:.2f} mean {a['adaptive_mean_ratio']:.2f}")
PY
# scripts/plot_perfmodel.py draws the run as a PNG; a JSON without points is refused by name.
plot="$(dirname "$0")/../scripts/plot_perfmodel.py"
printf '%s\n' "$perf" > "$dir/perf.json"
/usr/bin/python3 "$plot" "$dir/perf.json" "$dir/perf.png"
[ "$(head -c 8 "$dir/perf.png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] || { echo "plot_perfmodel.py wrote no PNG" >&2; exit 1; }
echo '{"points":[]}' > "$dir/empty.json"
if /usr/bin/python3 "$plot" "$dir/empty.json" "$dir/empty.png" 2> "$dir/plot_err.txt"; then
  echo "plot_perfmodel.py accepted a run without points"; exit 1
fi
grep -q "empty.json: no points" "$dir/plot_err.txt" || { cat "$dir/plot_err.txt"; exit 1; }
