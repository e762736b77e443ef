#!/usr/bin/python3
"""The frame governor on the swing replay: plot the trace of `igbench governor --json` to a PNG.

    build/igbench governor --json > out/governor.json
    scripts/plot_governor.py out/governor.json out/governor.png
    (or: build/igbench governor --plot out/governor.png, which calls this script)

Top: frame work per frame, governed (with the governor's prediction) and at the fixed
tolerance, against the frame budget. Middle: the pixel tolerance the governor chose. Bottom:
triangles drawn, governed and fixed (log scale): the load swing and how the governor flattens it.
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_governor.py GOVERNOR.json OUT.png")
    try:
        with open(sys.argv[1], encoding="utf-8") as f:
            d = json.load(f)
        trace = d["tolerance_trace"]
    except (OSError, ValueError, KeyError) as e:
        sys.exit(f"plot_governor.py: {sys.argv[1]}: not an igbench governor JSON file ({e})")
    frame = [t["frame"] for t in trace]
    budget = d["budget_ms"]
    fixed = d["fixed"]
    fig, (a, b, c) = plt.subplots(3, 1, figsize=(12, 9), sharex=True,
                                  gridspec_kw={"height_ratios": [3, 1.4, 1.6]})
    a.plot(frame, [t["fixed_ms"] for t in trace], color="tab:red", lw=0.8, alpha=0.7,
           label=f"fixed {fixed['tolerance_px']:g} px: {fixed['overrun_pct']:.1f} % overruns, "
                 f"p99 {fixed['frame_ms_p99']:.1f} ms")
    a.plot(frame, [t["ms"] for t in trace], color="tab:blue", lw=0.9,
           label=f"governed: {d['overrun_pct']:.2f} % overruns, p99 {d['frame_ms_p99']:.1f} ms")
    a.plot(frame, [t["predicted_ms"] for t in trace], color="black", lw=0.6, ls="--",
           label="governor's prediction")
    a.axhline(budget, color="gray", lw=1.0, ls=":", label=f"budget {budget:.1f} ms ({d['rate_hz']:g} Hz)")
    top = max(budget * 2.5, d["frame_ms_p99"] * 1.2)
    a.set_ylim(0, top)
    a.set_ylabel("frame work (ms)")
    a.legend(loc="upper left", fontsize=8)
    a.set_title(f"igbench governor: load swing {d['load_swing']:.1f}x, {d['width']}x{d['height']}, "
                f"{d['frames']} frames, load average {d.get('load_avg_start', float('nan')):.1f}"
                f"..{d.get('load_avg_end', float('nan')):.1f} on {d.get('cpus', '?')} CPUs", fontsize=10)
    b.plot(frame, [t["tolerance_px"] for t in trace], color="tab:green", lw=1.0)
    b.set_ylabel("tolerance (px)")
    b.set_yscale("log", base=2)
    c.plot(frame, [max(1, t["fixed_triangles"]) for t in trace], color="tab:red", lw=0.8, alpha=0.7,
           label="fixed")
    c.plot(frame, [max(1, t["triangles"]) for t in trace], color="tab:blue", lw=0.9, label="governed")
    c.set_yscale("log")
    c.set_ylabel("triangles")
    c.set_xlabel("frame")
    c.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
