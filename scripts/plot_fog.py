#!/usr/bin/python3
"""What fog culling buys: plot `igbench fog --json` to a PNG.

    build/igbench fog --json > out/fog.json
    scripts/plot_fog.py out/fog.json out/fog.png

Left: triangles drawn per frame against the visibility, with the far plane at the fog's opaque
distance (culled) and at the host's (full). Right: frame time (select + submit + glFinish, p50)
of both, with the speedup and the largest picture difference (8-bit levels) at each point.
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_fog.py FOG.json OUT.png")
    try:
        with open(sys.argv[1], encoding="utf-8") as f:
            d = json.load(f)
        points = sorted(d["points"], key=lambda p: p["visibility_m"])
        vis = [p["visibility_m"] for p in points]
        tri_cull = [p["triangles_cull"] for p in points]
        tri_full = [p["triangles_full"] for p in points]
        ms_cull = [p["frame_ms_cull"] for p in points]
        ms_full = [p["frame_ms_full"] for p in points]
    except (OSError, ValueError, KeyError, TypeError) as e:
        sys.exit(f"plot_fog.py: {sys.argv[1]}: not an igbench fog JSON file ({e})")
    fig, (a, b) = plt.subplots(1, 2, figsize=(12, 4.5))
    a.plot(vis, tri_full, "o-", color="tab:red", label="far plane at the host's")
    a.plot(vis, tri_cull, "o-", color="tab:blue", label="far plane where the fog is opaque ([fog] cull)")
    a.set_xscale("log")
    a.set_xlabel("visibility (m)")
    a.set_ylabel("triangles per frame (p50)")
    a.set_ylim(bottom=0)
    a.legend(loc="lower right", fontsize=8)
    b.plot(vis, ms_full, "o-", color="tab:red", label="far plane at the host's")
    b.plot(vis, ms_cull, "o-", color="tab:blue", label="[fog] cull")
    for p in points:
        b.annotate(f"{p['speedup']:.2f}x, diff {p['max_diff_levels']}",
                   (p["visibility_m"], p["frame_ms_cull"]), textcoords="offset points", xytext=(4, -12), fontsize=7)
    b.set_xscale("log")
    b.set_xlabel("visibility (m)")
    b.set_ylabel("frame ms (p50: select + submit + glFinish)")
    b.set_ylim(bottom=0)
    b.legend(loc="lower right", fontsize=8)
    fig.suptitle(f"igbench fog: scene '{d['scene']}', {d['width_px']}x{d['height_px']}, {d['frames']} frames per "
                 f"visibility; largest picture difference {d['max_diff_levels']} level(s)", fontsize=10)
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
