#!/usr/bin/python3
"""Plot an igd per-frame stats file (CSV or JSON lines) to a PNG a person can read at a glance.

    scripts/plot_frame_stats.py out/frame_stats.csv out/frame_times.png

Top: work per frame stacked by phase (input, lod, submit, gpu_finish, present) with the frame
period as a dashed line; overruns marked in red. Below: triangles drawn per frame, and with the
frame governor the knobs it steered, each relative to its first frame (1 = the scene's detail).
"""
import csv
import json
import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

PHASES = ["input_ms", "lod_ms", "submit_ms", "gpu_finish_ms", "present_ms"]
# The governor's knobs, and whether a larger value is more detail.
KNOBS = [("terrain_tolerance_px", False), ("forest_near_m", True), ("hdlod_tolerance_px", False),
         ("cells_voxel_budget", True), ("forest_layers", True)]


def load(path):
    rows, run = [], {}
    with open(path, encoding="utf-8") as f:
        # By content, not by name: igd writes either format to any file name (stats.format).
        first = f.readline()
        f.seek(0)
        if not first.lstrip().startswith("{"):
            rows = [{k: float(v) for k, v in r.items()} for r in csv.DictReader(f)]
        else:
            for line in f:
                obj = json.loads(line)
                if "run" in obj:
                    run = obj["run"]
                else:
                    rows.append({k: float("nan") if v is None else float(v) for k, v in obj.items()})
    return rows, run


def nearest_rank(sorted_values, p):
    """The nearest-rank percentile of sorted values, as igd's summary (ig/stats.cpp) computes it."""
    k = math.ceil(p / 100.0 * len(sorted_values))
    return sorted_values[min(max(k, 1), len(sorted_values)) - 1]


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_frame_stats.py STATS(.csv|.jsonl) OUT.png")
    rows, run = load(sys.argv[1])
    if not rows:
        sys.exit(f"{sys.argv[1]}: no frames")
    frames = [r["frame"] for r in rows]
    knobs = [(k, up) for k, up in KNOBS if any(r.get(k, float("nan")) == r.get(k, float("nan")) for r in rows)]
    if knobs:
        fig, (ax, ax2, ax3) = plt.subplots(3, 1, figsize=(11, 8), sharex=True, gridspec_kw={"height_ratios": [3, 1, 1]})
    else:
        fig, (ax, ax2) = plt.subplots(2, 1, figsize=(11, 6.5), sharex=True, gridspec_kw={"height_ratios": [3, 1]})
    bottom = [0.0] * len(rows)
    for phase in PHASES:
        values = [r.get(phase, 0.0) for r in rows]
        ax.bar(frames, values, bottom=bottom, width=1.0, label=phase.replace("_ms", ""), linewidth=0)
        bottom = [b + v for b, v in zip(bottom, values)]
    period = rows[0]["period_ms"]
    ax.axhline(period, color="k", linestyle="--", linewidth=1, label=f"period {period:.1f} ms")
    over = [r for r in rows if r["overrun"]]
    if over:
        ax.scatter([r["frame"] for r in over], [r["work_ms"] for r in over], color="red", s=12, zorder=5,
                   label=f"overrun ({len(over)})")
    work = sorted(r["work_ms"] for r in rows)
    p50, p99 = nearest_rank(work, 50), nearest_rank(work, 99)
    ax.set_title(f"igd frame work: {len(rows)} frames, p50 {p50:.1f} ms, p99 {p99:.1f} ms, "
                 f"overruns {len(over)}")
    ax.set_ylabel("ms per frame")
    ax.legend(loc="upper right", fontsize=8, ncol=4)
    ax2.plot(frames, [r["triangles"] for r in rows], color="tab:green")
    ax2.set_ylabel("triangles")
    ax2.set_xlabel("frame")
    if knobs:
        # Detail relative to the first frame: a tolerance's inverse, a distance or budget as is.
        for k, up in knobs:
            first = next(r[k] for r in rows if r[k] == r[k])
            ax3.plot(frames, [(r[k] / first if up else first / r[k]) for r in rows], label=k)
        ax3.set_ylabel("detail (governor)")
        ax3.set_yscale("log")
        ax3.legend(loc="upper right", fontsize=8, ncol=4)
        ax3.set_xlabel("frame")
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=100)
    print(f"plot: {sys.argv[2]}")


if __name__ == "__main__":
    main()
