#!/usr/bin/python3
"""What accuracy costs in time: plot the sweep of `igbench terrain --json` to a PNG.

    build/igbench terrain --json > out/terrain.json
    scripts/plot_terrain_sweep.py out/terrain.json out/terrain_sweep.png

Left: triangles and update time against the screen-space tolerance. Right: image error
(PSNR against the full-resolution render) against render time (when the sweep was rendered).
A note under the plots gives Deferred's update, teleport and frame-vs-raster figures.
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_terrain_sweep.py TERRAIN.json OUT.png")
    with open(sys.argv[1], encoding="utf-8") as f:
        d = json.load(f)
    sweep = d["sweep"]
    tol = [s["tolerance_px"] for s in sweep]
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.5))
    # --no-baselines (large DEMs) runs no sweep: the panels say so, the notes below still come.
    a.plot(tol, [s["triangles"] for s in sweep], "o-", color="tab:green", label="triangles")
    if sweep:
        a.set_xscale("log", base=2)
        a.set_yscale("log")
    else:
        a.text(0.5, 0.5, "no sweep in this run (--no-baselines)", ha="center", va="center", transform=a.transAxes)
    a.set_xlabel("tolerance (px)")
    a.set_ylabel("triangles")
    a2 = a.twinx()
    a2.plot(tol, [s["update_ms"] for s in sweep], "s--", color="tab:blue", label="update ms (p50)")
    a2.set_ylabel("ROAM update ms (p50)")
    a.set_title(f"{d['dem']}: triangles and update time")
    rendered = [s for s in sweep if s.get("psnr_db") is not None]  # null: the sweep was not rendered
    b.plot([s["render_ms"] for s in rendered], [s["psnr_db"] for s in rendered], "o-", color="tab:red")
    for s in rendered:
        b.annotate(f"{s['tolerance_px']:g} px", (s["render_ms"], s["psnr_db"]), textcoords="offset points", xytext=(4, 4))
    b.set_xlabel("render ms (glFinish)")
    b.set_ylabel("PSNR vs full resolution (dB)")
    b.set_title("image error against render time" if d.get("sweep_rendered", True) else "(sweep not rendered at this size)")
    notes = []
    m = d.get("methods", {}).get("roam_deferred")
    if m:
        notes.append(f"Deferred update p50/p99 {m['update_ms_p50']:.2f}/{m['update_ms_p99']:.2f} ms "
                     f"({d.get('deferred_visits', '?')} visits), {m['triangles_p50']} triangles")
    t = d.get("teleport")
    if t:
        notes.append(f"teleport {t['jump_km']:.0f} km: merges alone {t['merge_ms']:.1f} ms, Deferred first frame "
                     f"{t['deferred_first_frame_ms']:.2f} ms, visible in {t['deferred_frames_to_visible']} frames")
    if d.get("raster", {}).get("ran"):
        notes.append(f"frame vs raster limit: {d['frame_vs_raster_ratio']:.2f}x")
    if notes:
        fig.text(0.01, 0.01, "; ".join(notes), fontsize=8)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.savefig(sys.argv[2], dpi=100)
    print(f"plot: {sys.argv[2]}")


if __name__ == "__main__":
    main()
