#!/usr/bin/python3
"""Forest (paper 004): plot `igbench forest --json` to a PNG.

    build/igbench forest --json > out/forest.json
    scripts/plot_forest.py out/forest.json out/forest.png

Left: frame time against the near distance (where the 3D trees end), one line per layer count.
Middle: PSNR against the reference that draws every tree as a 3D model, same axes.
Right: the popping measures: the largest and median mean per-pixel change between consecutive
frames of the slow approach, with and without the forest, and of the transitions alone (camera
held still, fade bands moved 1 m a frame), each also with a hard switch for comparison.
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_forest.py FOREST.json OUT.png")
    with open(sys.argv[1], encoding="utf-8") as f:
        d = json.load(f)
    sweep = d.get("sweep", [])
    if not sweep:
        sys.exit(f"plot_forest.py: {sys.argv[1]} has no render sweep")
    layers = sorted({s["layers"] for s in sweep})
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(15, 4.5))
    for n in layers:
        pts = sorted((s for s in sweep if s["layers"] == n), key=lambda s: s["near_m"])
        near = [s["near_m"] for s in pts]
        a.plot(near, [s["frame_ms"] for s in pts], "o-", label=f"{n} layers")
        b.plot(near, [s["psnr_db"] for s in pts], "o-", label=f"{n} layers")
    a.set_xlabel("near distance: 3D trees up to (m)")
    a.set_ylabel("frame time p50 (ms, glFinish)")
    a.set_title(f"{d['trees']:,} trees, {d['area_km2']:.1f} km², {d['width']}x{d['height']}")
    a.legend()
    a.grid(alpha=0.3)
    b.set_xlabel("near distance: 3D trees up to (m)")
    b.set_ylabel("PSNR vs all-3D reference (dB)")
    b.set_title(f"reference: every tree in 3D, {d['reference_ms'] / 1000:.1f} s a frame")
    b.legend()
    b.grid(alpha=0.3)
    names = ["approach\nmax", "approach\np50", "transitions\nalone, max"]
    forest = [d["popping_max"], d["popping_p50"], d.get("transition_max", 0.0)]
    off = [d["popping_max_no_forest"], d["popping_p50_no_forest"], 0.0]
    hard = [d.get("popping_max_hard_switch", -1.0), None, d.get("transition_max_hard_switch", -1.0)]
    x = list(range(len(names)))
    c.bar([i - 0.27 for i in x], forest, 0.27, label="forest (cross-fade)")
    c.bar([i for i in x], off, 0.27, label="no forest")
    hx = [i + 0.27 for i, h in zip(x, hard) if h is not None and h >= 0]
    hv = [h for h in hard if h is not None and h >= 0]
    if hv:
        c.bar(hx, hv, 0.27, label="forest, hard switch (0.1 m bands)")
    for i, v in enumerate(forest):
        c.text(i - 0.27, v, f"{v:.2f}", ha="center", va="bottom", fontsize=8)
    for xx, v in zip(hx, hv):
        c.text(xx, v, f"{v:.2f}", ha="center", va="bottom", fontsize=8)
    c.set_ylim(0, 1.45 * max(forest + off + [h for h in hard if h is not None]))
    if "transition_popped_max" in d:
        hardPopped = d.get("transition_popped_max_hard_switch", -1.0)
        c.text(0.02, 0.98, "pixels changing by > 8 levels in one frame,\ntransitions alone: "
               f"{100 * d['transition_popped_max']:.3f} %" +
               (f" (hard switch {100 * hardPopped:.3f} %)" if hardPopped >= 0 else ""),
               transform=c.transAxes, va="top", ha="left", fontsize=8)
    c.set_xticks(x, names)
    c.set_ylabel("mean |dRGB| between frames (8-bit levels)")
    c.set_title(f"popping: {d['pop_frames']} frames, 1 m per frame")
    c.legend(fontsize=8, loc="upper right")
    fig.suptitle(f"igbench forest: {d['ground']}; models {d['models']}", fontsize=9)
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
