#!/usr/bin/python3
"""Paper 002's performance model against measured frame times: plot `igbench perfmodel --json`
to a PNG.

    build/igbench perfmodel --json > out/perfmodel.json
    scripts/plot_perfmodel.py out/perfmodel.json out/perfmodel.png

Top: frame ms by the number of boxes (log-log), for each strategy: the measured time (the
fastest sweep's median; the bar spans the sweeps' medians, which shows the machine's noise) and
the model's prediction. Bottom: the prediction's error in % of the measured time (positive: the
model predicts too slow), with the goal's bands (median <= 5 %, every point <= 10 %).
"""
import json
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLORS = {"percommand": "tab:orange", "octree": "tab:blue"}


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_perfmodel.py PERFMODEL.json OUT.png")
    with open(sys.argv[1], encoding="utf-8") as f:
        d = json.load(f)
    points = d.get("points") or []
    if not points:
        sys.exit(f"{sys.argv[1]}: no points")
    for p in points:
        for key in ("objects", "strategy", "measured_ms", "predicted_ms"):
            if key not in p:
                sys.exit(f"{sys.argv[1]}: a point without {key}: {p}")
        if not (p["measured_ms"] > 0 and math.isfinite(p["predicted_ms"]) and p["predicted_ms"] > 0):
            sys.exit(f"{sys.argv[1]}: point {p['objects']} {p['strategy']}: measured_ms {p['measured_ms']}, "
                     f"predicted_ms {p['predicted_ms']}")
    strategies = sorted({p["strategy"] for p in points}, key=lambda s: list(COLORS).index(s) if s in COLORS else 99)

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(9, 8), sharex=True, gridspec_kw={"height_ratios": [3, 2]})
    for i, s in enumerate(strategies):
        pts = sorted((p for p in points if p["strategy"] == s), key=lambda p: p["objects"])
        color = COLORS.get(s, f"C{i + 2}")
        # A small shift along x keeps the two strategies' bars apart.
        shift = 1.0 + 0.04 * (i - (len(strategies) - 1) / 2)
        x = [p["objects"] * shift for p in pts]
        measured = [p["measured_ms"] for p in pts]
        # measured_ms is the fastest sweep's median: the bar reaches up to the slowest sweep's.
        high = [max(p.get("sweep_ms") or [p["measured_ms"]]) - p["measured_ms"] for p in pts]
        top.errorbar(x, measured, yerr=[[0.0] * len(pts), high], fmt="o", color=color, capsize=3,
                     label=f"{s}: measured (bar: the sweeps' medians)")
        top.plot(x, [p["predicted_ms"] for p in pts], "--", marker="x", color=color, label=f"{s}: predicted")
        err = [100.0 * (p["predicted_ms"] - p["measured_ms"]) / p["measured_ms"] for p in pts]
        bottom.plot(x, err, "-o", color=color, label=s)
    top.set_xscale("log")
    top.set_yscale("log")
    top.set_ylabel("frame ms")
    cal = d.get("calibration", {})
    where = "from the cache" if cal.get("from_cache") else f"{cal.get('runs', '?')} calibration runs"
    if cal.get("between_sweeps"):
        where += " between them"
    top.set_title(f"igbench perfmodel: {d.get('sweeps', '?')} sweeps, {where}; error median "
                  f"{d.get('error_pct_median', float('nan')):.2f} %, max {d.get('error_pct_max', float('nan')):.2f} % "
                  "(goal 5 / 10)", fontsize=10)
    top.grid(True, which="both", alpha=0.3)
    top.legend(fontsize=8)
    for band, alpha in ((10, 0.08), (5, 0.12)):
        bottom.axhspan(-band, band, color="tab:green", alpha=alpha, lw=0)
    bottom.axhline(0, color="black", lw=0.8)
    bottom.set_xlabel("boxes")
    bottom.set_ylabel("predicted - measured, % of measured")
    bottom.grid(True, which="both", alpha=0.3)
    bottom.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=100)


if __name__ == "__main__":
    main()
