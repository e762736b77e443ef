#!/usr/bin/python3
"""Hierarchical cells (paper 003): quality over time while streaming, and what the voxel budget
buys, from `igbench cells --json`, to a PNG.

    build/igbench cells --json > out/cells.json
    scripts/plot_cells.py out/cells.json out/cells.png

The bunny (without --no-mesh): the largest on-screen voxel (pixels, the paper's quality; lower
is sharper) after the teleport, one line per channel rate through nginx, with the all-resident
optimum dashed; it must never rise while the viewer stands still. PSNR of the streamed picture
against the final one over the same time. The budget sweep with every cell resident: PSNR
against the full-detail picture and the selection time, against the voxel budget.
The ~1 M-cell path (always): voxels drawn per frame while cells stream in, without and with the
deadline of --deadline-ms (what holding the selection to a time costs in sharpening), and the
selection time per frame without it.
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def plot_path(ax, d):
    """Voxels drawn per path frame without / with the deadline, select ms on a second axis."""
    drawn = d.get("path_voxels_drawn", [])
    if not drawn:
        ax.set_axis_off()
        return
    frames = range(len(drawn))
    ax.plot(frames, drawn, color="tab:blue", lw=1.2, label="voxels drawn")
    limited = d.get("path_voxels_drawn_deadline", [])
    dl = d.get("deadline", {})
    if limited:
        ax.plot(frames, limited, color="tab:red", lw=1.2,
                label=f'voxels drawn, select held to {dl.get("deadline_ms", 0):g} ms')
    ax.axhline(d["voxel_budget"], color="gray", ls=":", lw=0.8, label="voxel budget")
    if "teleport_frame" in d:
        ax.axvline(d["teleport_frame"], color="black", ls="--", lw=0.8, label="teleport")
    ax.set_xlabel("path frame (60 Hz)")
    ax.set_ylabel("voxels drawn")
    ax.set_title(f'{d["cells"]:,} cells: sharpening while streaming')
    ms = d.get("path_select_ms", [])
    if ms:
        ax2 = ax.twinx()
        ax2.plot(frames, ms, color="tab:gray", lw=0.6, alpha=0.7, label="select ms (no deadline)")
        ax2.set_ylabel("selection without a deadline (ms)", color="tab:gray")
        ax2.legend(fontsize=8, loc="lower right")
    ax.legend(fontsize=8, loc="center right")


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_cells.py CELLS.json OUT.png")
    with open(sys.argv[1], encoding="utf-8") as f:
        d = json.load(f)
    runs = d.get("streaming", [])
    sweep = d.get("sweep", [])
    path = d.get("path_voxels_drawn", [])
    if not runs and not sweep and not path:
        sys.exit(f"{sys.argv[1]}: no 'streaming' runs, no 'sweep' rows and no 'path_voxels_drawn'")
    if not runs and not sweep:
        fig, e = plt.subplots(1, 1, figsize=(7, 4.6))
        plot_path(e, d)
        fig.tight_layout()
        fig.savefig(sys.argv[2], dpi=110)
        return
    fig, (a, b, c, e) = plt.subplots(1, 4, figsize=(21, 4.6))
    plot_path(e, d)
    colours = ["tab:red", "tab:orange", "tab:green", "tab:blue", "tab:purple"]
    for i, run in enumerate(runs):
        col = colours[i % len(colours)]
        curve = run["curve"]  # [t_s, max_voxel_px, psnr_db (-1: not measured), voxels]
        label = f'{run["rate_mbit"]:g} Mbit/s'
        if run["seconds_to_full_quality"] >= 0:
            label += f' (full quality {run["seconds_to_full_quality"]:.2f} s)'
        else:
            label += " (not reached)"
        a.step([p[0] for p in curve], [p[1] for p in curve], where="post", color=col, label=label)
        a.axhline(run["target_voxel_px"], color=col, ls=":", lw=0.8)
        pts = [p for p in curve if p[2] >= 0]
        b.plot([p[0] for p in pts], [min(p[2], 60.0) for p in pts], ".-", color=col, label=label)
    a.set_xscale("symlog", linthresh=0.1)
    a.set_xlim(left=0)
    a.set_yscale("log")
    a.set_xlabel("seconds after the teleport")
    a.set_ylabel("largest voxel on screen (px)")
    a.set_title("sharpening while streaming (dotted: all-resident optimum)")
    if runs:
        a.legend(fontsize=8)
    b.set_xscale("symlog", linthresh=0.1)
    b.set_xlim(left=0)
    b.set_xlabel("seconds after the teleport")
    b.set_ylabel("PSNR vs the final picture (dB, capped at 60)")
    b.set_title("picture while streaming")
    if runs:
        b.legend(fontsize=8)
    if sweep:
        x = [s["voxel_budget"] for s in sweep]
        c.plot(x, [min(s["psnr_db"], 60.0) for s in sweep], "o-", color="tab:blue", label="PSNR vs full detail")
        c.set_xscale("log")
        c.set_xlabel("voxel budget")
        c.set_ylabel("PSNR vs full detail (dB, capped at 60 = identical)", color="tab:blue")
        c2 = c.twinx()
        c2.plot(x, [s["select_ms"] for s in sweep], "s--", color="tab:gray", label="select ms")
        c2.set_ylabel("selection (ms)", color="tab:gray")
        c.set_title("what the voxel budget buys (all resident)")
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
