#!/usr/bin/python3
"""What HDLOD's tolerance costs and buys: plot the r sweep of `igbench hdlod --json` to a PNG.

    build/igbench hdlod --json > out/hdlod.json
    scripts/plot_hdlod.py out/hdlod.json out/hdlod_sweep.png

Left: triangles and draws against r (pixels), with the full-detail count. Middle: selection
and frame time against r. Right: PSNR of the HDLOD image against the full-detail one, with the
35 dB goal at r = 1 px. The sweep is at 1/3 of the schedule with the site filling the screen.
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_hdlod.py HDLOD.json OUT.png")
    with open(sys.argv[1], encoding="utf-8") as f:
        d = json.load(f)
    sweep = [s for s in d["sweep"] if s["r_px"] > 0]
    if not sweep:
        sys.exit(f"{sys.argv[1]}: no sweep rows with r > 0")
    r = [s["r_px"] for s in sweep]
    full = next((s for s in d["sweep"] if s["r_px"] == 0), None)
    fig, (a, b, c) = plt.subplots(1, 3, figsize=(15, 4.5))

    a.plot(r, [s["triangles"] for s in sweep], "o-", color="tab:green", label="triangles")
    a.plot(r, [s["draws"] for s in sweep], "s-", color="tab:olive", label="draws")
    if full:
        a.axhline(full["triangles"], color="tab:green", ls=":", label="triangles at r = 0 (full detail)")
    a.set_xscale("log", base=2)
    a.set_yscale("log")
    a.set_xlabel("tolerance r (px)")
    a.set_title("what is drawn")
    a.legend()
    a.grid(True, which="both", alpha=0.3)

    b.plot(r, [s["select_ms"] for s in sweep], "o-", color="tab:blue", label="selection")
    if "frame_ms" in sweep[0]:
        b.plot(r, [s["frame_ms"] for s in sweep], "s-", color="tab:red", label="frame (select + submit + glFinish)")
        if full and "frame_ms" in full:
            b.axhline(full["frame_ms"], color="tab:red", ls=":", label="frame at r = 0")
    b.axhline(0.5, color="tab:blue", ls="--", lw=0.8, label="selection goal 0.5 ms")
    b.set_xscale("log", base=2)
    b.set_yscale("log")
    b.set_xlabel("tolerance r (px)")
    b.set_ylabel("ms")
    b.set_title("time per frame")
    b.legend()
    b.grid(True, which="both", alpha=0.3)

    if "psnr_db" in sweep[0]:
        c.plot(r, [s["psnr_db"] for s in sweep], "o-", color="tab:purple", label="PSNR vs full detail")
        c.axhline(35.0, color="gray", ls="--", lw=0.8, label="goal at r = 1 px")
        c.axvline(1.0, color="gray", ls=":", lw=0.8)
        c.set_xscale("log", base=2)
        c.set_xlabel("tolerance r (px)")
        c.set_ylabel("dB")
        c.legend()
    else:
        c.text(0.5, 0.5, "no rendering in this run", ha="center", va="center", transform=c.transAxes)
    c.set_title("image error")
    c.grid(True, which="both", alpha=0.3)

    fig.suptitle(
        f"igbench hdlod: scale {d['scale']}, {d['objects']} objects, {d['triangles']} triangles, "
        f"{d['width']}x{d['height']}, sweep at {d.get('sweep_time', '1/3')} of the schedule"
    )
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
