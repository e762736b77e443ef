#!/usr/bin/python3
"""Frame time of the three fixed strategies and the adaptive one (paper 002): plot the trace of
`igbench adaptive --json` to a PNG.

    build/igbench adaptive --json > out/adaptive.json
    scripts/plot_adaptive.py out/adaptive.json out/adaptive.png

Top: mean frame ms per window for each mode (log scale), phases shaded. Bottom: the mode the
adaptive strategy used in each window, the number of occlusion tests q and the boxes in the scene.
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

MODES = ["percommand", "octree", "occlusion", "adaptive"]
COLORS = {"percommand": "tab:orange", "octree": "tab:blue", "occlusion": "tab:green", "adaptive": "black"}


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_adaptive.py ADAPTIVE.json OUT.png")
    with open(sys.argv[1], encoding="utf-8") as f:
        d = json.load(f)
    trace = d["trace"]
    if not trace:
        sys.exit(f"{sys.argv[1]}: empty trace")
    x = [r["frame"] for r in trace]
    fig, (a, b) = plt.subplots(2, 1, figsize=(11, 7), sharex=True, gridspec_kw={"height_ratios": [3, 1.4]})
    for m in MODES:
        a.plot(x, [r[m + "_ms"] for r in trace], "-", color=COLORS[m], lw=2.2 if m == "adaptive" else 1.3,
               label=f"{m}: mean {d['modes'][m]['mean_ms']:.2f} ms, p99 {d['modes'][m]['p99_ms']:.2f} ms")
    a.set_yscale("log")
    a.set_ylabel("frame ms (window mean, fastest of the repetitions)")
    start = 0
    for i, r in enumerate(trace + [None]):
        if r is None or r["phase"] != trace[start]["phase"]:
            lo, hi = (trace[start - 1]["frame"] if start else 0), trace[i - 1]["frame"]
            a.axvspan(lo, hi, color="0.9" if (start // 1) % 2 == 0 and trace[start]["phase"] != "growing" else "0.97")
            a.text((lo + hi) / 2, a.get_ylim()[1], trace[start]["phase"], ha="center", va="bottom", fontsize=9)
            start = i
    a.legend(loc="upper left", fontsize=8)
    a.set_title(f"adaptive / best fixed: worst window {d['adaptive_worst_ratio']:.2f}, "
                f"mean {d['adaptive_mean_ratio']:.2f}", fontsize=10, pad=18)
    modes = ["percommand", "octree", "occlusion"]
    b.step(x, [modes.index(r["adaptive_mode"]) for r in trace], where="post", color="black", label="adaptive mode")
    b.set_yticks([0, 1, 2], modes)
    b.set_xlabel("frame")
    c = b.twinx()
    c.plot(x, [r["q"] for r in trace], ":", color="tab:green", label="q (tests)")
    c.plot(x, [r["objects"] for r in trace], "--", color="tab:gray", label="boxes")
    c.set_yscale("symlog")
    c.legend(loc="center right", fontsize=8)
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
