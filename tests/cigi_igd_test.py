#!/usr/bin/python3
"""End to end: the real igd (headless, 64x64, 30 Hz, paced) with [host] source = "cigi", driven
by the independent Python CIGI host (tests/cigi_sender.py) over loopback UDP.

Checks: every frame's stats row renders the eyepoint of the host frame it names (ENU computed
by Python from the lat/lon/alt it sent), sim_time_s is the host's timestamp, host_lost is 0
while the host sends; igd's Start of Frame packets count up, echo host frames and report
Operate; the exit line counts the datagrams (one deliberately malformed); the record_file holds
the accepted samples.

usage: cigi_igd_test.py <igd> <source dir>
"""
import csv
import math
import os
import re
import socket
import subprocess
import sys
import tempfile

import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from igd_link_config import write_link_config  # noqa: E402
import cigi_sender as cs  # noqa: E402

FAILURES = []
ORIGIN = (46.5, 7.9, 0.0)  # config/scenes/default.toml [origin]
RATE_HZ = 30
FRAMES = 75


def check(cond, what):
    if not cond:
        FAILURES.append(what)
        print("FAIL:", what, flush=True)


def free_udp_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def entity_for(frame):
    """The ownship for host frame `frame`: flying north at 60 m/s, 700 m above the ellipsoid."""
    lat = ORIGIN[0] + frame * 2.0 / 111132.0
    return (0.0, -4.0, 45.0, lat, ORIGIN[1], 700.0)


def main():
    igd, src = sys.argv[1], sys.argv[2]
    tmp = tempfile.mkdtemp(prefix="cigi_igd_")
    port = free_udp_port()
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.setblocking(False)
    host_port = rx.getsockname()[1]
    stats = os.path.join(tmp, "stats.csv")
    rec = os.path.join(tmp, "host.rec")
    cfg = write_link_config(tmp, "cigi", "cigi", f"""bind_address = "127.0.0.1"
port = {port}
host_address = "127.0.0.1"
host_port = {host_port}
entity_id = 0
view_id = 0""", src, RATE_HZ, FRAMES, 3.0, rec)
    proc = subprocess.Popen([igd, "--config", cfg], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sofs = []
    frame = 1
    t0 = time.monotonic()
    sent_malformed = False
    while proc.poll() is None and time.monotonic() - t0 < 120:
        roll, pitch, yaw, lat, lon, alt = entity_for(frame)
        msg = (cs.ig_control(">" if frame % 2 else "<", frame, int(round(frame * 1e5 / RATE_HZ))) +
               cs.entity_control(">" if frame % 2 else "<", 0, roll, pitch, yaw, lat, lon, alt) +
               cs.celestial(">" if frame % 2 else "<", 10, 30, 6, 21, 2026))
        try:
            tx.sendto(msg, ("127.0.0.1", port))
            if sofs and not sent_malformed:  # igd is listening: its Start of Frame arrived
                tx.sendto(msg[:30], ("127.0.0.1", port))  # truncated inside Entity Control
                sent_malformed = True
        except OSError:
            pass  # igd not bound yet (ECONNREFUSED is not reported for unconnected UDP anyway)
        frame += 1
        while True:
            try:
                sofs.append(cs.decode_start_of_frame(rx.recv(65536)))
            except BlockingIOError:
                break
        time.sleep(1.0 / RATE_HZ)
    out, err = proc.communicate(timeout=60)
    while True:
        try:
            sofs.append(cs.decode_start_of_frame(rx.recv(65536)))
        except BlockingIOError:
            break
    check(proc.returncode == 0, "igd exit status %s: %s" % (proc.returncode, err[-2000:]))

    # Stats: the rendered eyepoint is the one Python sent for that host frame.
    with open(stats) as f:
        rows = list(csv.DictReader(f))
    check(len(rows) == FRAMES, "%d stats rows, expected %d" % (len(rows), FRAMES))
    rendered = [r for r in rows if int(r["host_frame"]) > 0]
    check(len(rendered) >= FRAMES // 2, "only %d of %d frames rendered a host sample" % (len(rendered), len(rows)))
    for r in rendered:
        hf = int(r["host_frame"])
        roll, pitch, yaw, lat, lon, alt = entity_for(hf)
        enu, heading, _, _ = cs.expected_eye(ORIGIN, lat, lon, alt, cs_f32(yaw), cs_f32(pitch), cs_f32(roll))
        got = (float(r["eye_east_m"]), float(r["eye_north_m"]), float(r["eye_up_m"]))
        check(all(abs(g - e) <= 0.006 for g, e in zip(got, enu)),
              "frame %s host frame %d: eye %r, expected %r" % (r["frame"], hf, got, enu))
        check(abs(float(r["heading_deg"]) - heading) <= 0.0006, "frame %s: heading %s, expected %.4f" % (r["frame"], r["heading_deg"], heading))
        check(abs(float(r["sim_time_s"]) - round(hf * 1e5 / RATE_HZ) * 1e-5) <= 6e-5,
              "frame %s: sim_time_s %s for host frame %d" % (r["frame"], r["sim_time_s"], hf))
    tail = rows[-20:]
    check(all(r["host_lost"] == "0" for r in tail), "host_lost in the last 20 frames: %r" % [r["host_lost"] for r in tail])
    frames_seen = [int(r["host_frame"]) for r in rendered]
    check(frames_seen == sorted(frames_seen), "host frames rendered in order")

    # Start of Frame: counts up, echoes host frames, Operate once the host is there.
    check(len(sofs) >= FRAMES // 2, "received %d Start of Frame packets" % len(sofs))
    check(all(b["ig_frame"] > a["ig_frame"] for a, b in zip(sofs, sofs[1:])), "IG frame numbers increase")
    check(all(s["major"] == 3 and s["minor"] == 3 for s in sofs), "Start of Frame version 3.3")
    late = sofs[-10:]
    # Status 0 (normal) or 2 (the previous frame overran: possible on a loaded machine), never 1.
    check(all(s["mode"] == 1 and s["status"] in (0, 2) for s in late), "last Start of Frames Operate: %r" % late[-1:])
    check(any(0 < s["last_host_frame"] < frame for s in sofs), "Start of Frame echoes host frames")

    # The exit line.
    m = re.search(r"igd: link cigi: received (\d+) accepted (\d+) malformed (\d+) out_of_range (\d+) late (\d+) dropped (\d+)", err)
    check(m is not None, "no 'igd: link cigi:' line in stderr: %s" % err[-2000:])
    if m:
        received, accepted, malformed, out_of_range, late_n, _ = map(int, m.groups())
        check(malformed == 1 and out_of_range == 0 and late_n == 0, "link counters: %s" % m.group(0))
        check(received == accepted + malformed and accepted >= FRAMES // 2, "link counters: %s" % m.group(0))

    # The recording of accepted samples.
    with open(rec) as f:
        lines = [l for l in f.read().splitlines() if l.strip() and not l.startswith("#")]
    check(lines and lines[0].startswith("igd-recording"), "record_file header: %r" % lines[:1])
    check(len(lines) - 1 >= FRAMES // 2, "record_file has %d samples" % (len(lines) - 1))

    print("cigi_igd_test: %d frames, %d rendered host samples, %d Start of Frame packets; %d failures" %
          (len(rows), len(rendered), len(sofs), len(FAILURES)))
    if not FAILURES:
        import shutil
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        print("files kept in", tmp)
    return 1 if FAILURES else 0


def cs_f32(x):
    import struct
    return struct.unpack("f", struct.pack("f", x))[0]


if __name__ == "__main__":
    sys.exit(main())
