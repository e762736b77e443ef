#!/usr/bin/env bash
# igbench perfmodel --quick (two sweeps) and igbench adaptive --quick print one JSON object each with the
# fields issue 7 names; predictions are positive and finite, every mode of the adaptive run drew
# every frame, and the ratios are consistent with the per-mode means. (Timing goals are
# benchmark results, not asserted here.)
set -euo pipefail
igbench=$1
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
perf=$("$igbench" perfmodel --quick --sweeps 2 --json --cache "$dir/calibration.txt")
adaptive=$("$igbench" adaptive --quick --json --cache "$dir/calibration.txt" --trace "$dir/trace.json")
/usr/bin/python3 - "$perf" "$adaptive" "$dir/trace.json" <<'PY'
import json, math, sys
p = json.loads(sys.argv[1])
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
assert 0 <= p["sweep_spread_pct_median"] <= p["sweep_spread_pct_max"], p
errs = sorted(pt["error_pct"] for pt in p["points"])
assert abs(p["error_pct_max"] - errs[-1]) < 0.01, (p["error_pct_max"], errs)
a = json.loads(sys.argv[2])
for mode in ("percommand", "octree", "occlusion", "adaptive"):
    m = a["modes"][mode]
    assert m["mean_ms"] > 0 and m["p99_ms"] >= m["mean_ms"] * 0.5, (mode, m)
assert a["adaptive_worst_ratio"] > 0 and a["adaptive_mean_ratio"] > 0, a
assert json.load(open(sys.argv[3]))["modes"].keys() == a["modes"].keys()
print(f"perfmodel: error median {p['error_pct_median']:.1f} % max {p['error_pct_max']:.1f} %; "
      f"adaptive worst {a['adaptive_worst_ratio']:.2f} mean {a['adaptive_mean_ratio']:.2f}")
PY
