#!/usr/bin/python3
"""End to end: the real igd (headless, 64x64, 30 Hz, paced) with [host] source = "cigi", driven
by the independent Python CIGI host (tests/cigi_sender.py) over loopback UDP.

Checks: every frame's stats row renders the eyepoint of the host frame it names (ENU computed
by Python from the lat/lon/alt it sent), sim_time_s is the host's timestamp, host_lost is 0
while the host sends; igd's Start of Frame packets count up, echo host frames and report
Operate; the exit line counts the datagrams (one deliberately malformed); the record_file holds
the accepted samples.

HAT/HOT on the scene's terrain (a 65 x 65 post 16-bit PNG DEM written here, so Python knows every
height): a HOT and an extended request inside it answer the HOT Python computes (bilinear on the
posts, through the same WGS-84 <-> ENU geodesy), a point outside and a NaN latitude answer
Valid = false (the NaN counted in out_of_range), a HAT/HOT packet with a bad size makes its
message malformed (counted) and igd keeps running and answering; a periodic request is answered
every 2nd frame until cancelled. A 500 m tower (an [hdlod] schedule object) stands on the DEM: an
extended request over it answers its roof (material code 1), and an extended LOS segment towards
it stops at its west wall (range, material 1, normal facing west). Eight LOS rays straight down
into a patch of [forest] stop at a tree above the ground (material 2) or at the ground.
VIS_AFTER host frames after igd's first Start of Frame the host starts sending a visibility
(Atmosphere Control): the stats show it as the fog's and the far plane at 1.77 x it (the frames
before at View Definition's far plane); the recording keeps it.

usage: cigi_igd_test.py <igd> <source dir>
"""
import csv
import json
import math
import os
import re
import socket
import subprocess
import sys
import tempfile

import struct
import time
import zlib

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from igd_link_config import write_link_config  # noqa: E402
import cigi_sender as cs  # noqa: E402

FAILURES = []
ORIGIN = (46.5, 7.9, 0.0)  # config/scenes/default.toml [origin]
RATE_HZ = 30
FRAMES = 75
# From this host frame on the host sends Atmosphere Control with this visibility (m).
VIS_AFTER = 20  # host frames after igd's first Start of Frame (igd renders frames before it too)
VISIBILITY_M = 900.0
# The DEM: 65 x 65 posts 30 m apart, its south-west post at ENU (-960, -960); height =
# 100 m + 0.1 m x value (png_offset_m, png_scale_m).
DEM_N, DEM_SPACING, DEM_SW = 65, 30.0, -960.0


def dem_value(x, y):
    """The 16-bit value of post (x east, y north)."""
    return (7 * x * x + 13 * y + 3 * x * y) % 3001


def write_dem_scene(tmp):
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    rows = b"".join(b"\0" + b"".join(struct.pack(">H", dem_value(x, DEM_N - 1 - r)) for x in range(DEM_N))
                    for r in range(DEM_N))  # the first PNG row is the northernmost
    with open(os.path.join(tmp, "dem.png"), "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", DEM_N, DEM_N, 16, 0, 0, 0, 0)) +
                chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))
    path = os.path.join(tmp, "scene.toml")
    with open(path, "w") as f:
        f.write(f"""name = "hat-hot"
[origin]
lat_deg = {ORIGIN[0]}
lon_deg = {ORIGIN[1]}
height_m = {ORIGIN[2]}
[terrain]
source = "dem"
file = "dem.png"
spacing_m = {DEM_SPACING}
png_scale_m = 0.1
png_offset_m = 100.0
lod = "block"
offset_m = [{DEM_SW}, {DEM_SW}, 0]
[hdlod]
schedule = "tower.sched"
[forest]
area_m = [{FOREST[0]}, {FOREST[1]}, {FOREST[2]}, {FOREST[3]}]
glade_fraction = 0
layers = 2
fins = false
""")
    # A 500 m tower (an [hdlod] object) standing on the DEM: HOT over it is its roof, a LOS
    # segment towards it stops at its wall (material code 1, "object").
    with open(os.path.join(tmp, "tower.sched"), "w") as f:
        f.write(f"""hdlod-schedule 1
duration_s 100
model tower box {2 * TOWER_HALF[0]} {2 * TOWER_HALF[1]} {TOWER_HEIGHT}
object tower tower
at tower 0 {TOWER_AT[0]} {TOWER_AT[1]} {tower_base()!r} 0
""")
    return path


# A patch of forest (ENU east0, north0, east1, north1), away from every other query: LOS rays
# straight down into it stop at a tree (material 2) above the ground, or at the ground.
FOREST = (600.0, -900.0, 900.0, -600.0)
FOREST_RAYS = [(610.0 + 35.0 * k, -610.0 - 37.0 * k) for k in range(8)]

# The tower: centred on TOWER_AT (ENU), its base 1 m below the DEM there.
TOWER_AT, TOWER_HALF, TOWER_HEIGHT = (300.0, 300.0), (20.0, 15.0), 500.0


def tower_base():
    return dem_height(*TOWER_AT) - 1.0


def dem_height(e, n):
    """Bilinear ENU height of the DEM at (east, north); None outside."""
    fx, fy = (e - DEM_SW) / DEM_SPACING, (n - DEM_SW) / DEM_SPACING
    if not (0 <= fx <= DEM_N - 1 and 0 <= fy <= DEM_N - 1):
        return None
    x0, y0 = min(int(fx), DEM_N - 2), min(int(fy), DEM_N - 2)
    tx, ty = fx - x0, fy - y0
    h = lambda x, y: cs_f32(100.0 + 0.1 * dem_value(x, y))  # noqa: E731 (igd keeps float heights)
    a = h(x0, y0) + (h(x0 + 1, y0) - h(x0, y0)) * tx
    b = h(x0, y0 + 1) + (h(x0 + 1, y0 + 1) - h(x0, y0 + 1)) * tx
    return a + (b - a) * ty


def expected_hot(lat, lon):
    """Height above the ellipsoid of the DEM surface under (lat, lon), iterated on its height."""
    h = ORIGIN[2]
    for _ in range(6):
        e, n, _ = cs.enu_of_geodetic(ORIGIN, lat, lon, h)
        h = cs.geodetic_of_enu(ORIGIN, e, n, dem_height(e, n))[2]
    return h


# The LOS segment (ENU metres): from 800 m up in the north-west down to 200 m below the DEM.
LOS_A, LOS_B = (-300.0, 200.0, 800.0), (400.0, -300.0, -200.0)


def los_expected_range():
    """Distance from LOS_A to the segment's first point on or below the DEM's bilinear surface:
    a 5 cm march, then bisection of the first step that goes below."""
    d = [b - a for a, b in zip(LOS_A, LOS_B)]
    length = math.sqrt(sum(x * x for x in d))
    below = lambda t: LOS_A[2] + t * d[2] <= dem_height(LOS_A[0] + t * d[0], LOS_A[1] + t * d[1])  # noqa: E731
    steps = int(length / 0.05)
    for k in range(1, steps + 1):
        if below(k / steps):
            lo, hi = (k - 1) / steps, k / steps
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                lo, hi = (lo, mid) if below(mid) else (mid, hi)
            return hi * length
    return float("nan")


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
    status = os.path.join(tmp, "status.json")
    cfg = write_link_config(tmp, "cigi", "cigi", f"""bind_address = "127.0.0.1"
port = {port}
host_address = "127.0.0.1"
host_port = {host_port}
entity_id = 0
view_id = 0""", src, RATE_HZ, FRAMES, 3.0, rec, write_dem_scene(tmp),
                            extra=f'[service]\nstatus_file = "{status}"\n')
    proc = subprocess.Popen([igd, "--config", cfg], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sofs = []
    answers = []  # (the datagram's Start of Frame last host frame, HAT/HOT answer)
    frame = 1
    t0 = time.monotonic()
    sent_malformed = False
    # HAT/HOT points: (lat, lon) of ENU points inside the DEM and one outside it.
    p_hot = cs.geodetic_of_enu(ORIGIN, 123.4, -234.5, 0.0)[:2]
    p_ext = cs.geodetic_of_enu(ORIGIN, -456.7, 345.6, 0.0)[:2]
    p_out = cs.geodetic_of_enu(ORIGIN, 1500.0, 0.0, 0.0)[:2]
    # A LOS segment from above the DEM down through it.
    los_src = cs.geodetic_of_enu(ORIGIN, *LOS_A)
    los_dst = cs.geodetic_of_enu(ORIGIN, *LOS_B)
    los_answers = []
    # Over the tower (extended HOT from high above) and level towards its west wall at 450 m
    # (above every post of the DEM, below the tower's roof).
    p_tower = cs.geodetic_of_enu(ORIGIN, TOWER_AT[0], TOWER_AT[1], 0.0)[:2]
    tower_src = cs.geodetic_of_enu(ORIGIN, TOWER_AT[0] - 150.0, TOWER_AT[1], 450.0)
    tower_dst = cs.geodetic_of_enu(ORIGIN, TOWER_AT[0], TOWER_AT[1], 450.0)
    hat_frame = cancel_frame = None
    vis_from = None  # the first host frame with a visibility
    while proc.poll() is None and time.monotonic() - t0 < 120:
        roll, pitch, yaw, lat, lon, alt = entity_for(frame)
        o = ">" if frame % 2 else "<"
        msg = (cs.ig_control(o, frame, int(round(frame * 1e5 / RATE_HZ))) +
               cs.entity_control(o, 0, roll, pitch, yaw, lat, lon, alt) +
               # An off-axis window (a left side channel): recorded and replayed (version 3).
               cs.view_definition(o, 0, 0.5, 20000.0, -50.0, 10.0, 20.0, -20.0) +
               cs.celestial(o, 10, 30, 6, 21, 2026))
        if vis_from is None and sofs:
            vis_from = frame + VIS_AFTER
        if vis_from is not None and frame >= vis_from:  # the host's visibility (Atmosphere Control): igd's fog
            msg += cs.atmosphere(o, VISIBILITY_M)
        if sent_malformed and hat_frame is None:
            hat_frame = frame
            msg += (cs.hat_hot_request(o, 1, 1, p_hot[0], p_hot[1], 0.0) +
                    cs.hat_hot_request(o, 2, 2, p_ext[0], p_ext[1], 900.0) +
                    cs.hat_hot_request(o, 3, 1, p_out[0], p_out[1], 0.0) +
                    cs.hat_hot_request(o, 4, 1, float("nan"), p_hot[1], 0.0) +
                    cs.hat_hot_request(o, 5, 1, p_hot[0], p_hot[1], 0.0, update_period=2) +
                    cs.los_segment_request(o, 41, los_src, los_dst) +
                    cs.hat_hot_request(o, 7, 2, p_tower[0], p_tower[1], 2000.0) +
                    cs.los_segment_request(o, 42, tower_src, tower_dst, extended=True) +
                    b"".join(cs.los_segment_request(o, 51 + k, cs.geodetic_of_enu(ORIGIN, e, n, 1000.0),
                                                    cs.geodetic_of_enu(ORIGIN, e, n, -100.0), extended=True)
                             for k, (e, n) in enumerate(FOREST_RAYS)))
        elif hat_frame is not None and cancel_frame is None and frame == hat_frame + 12:
            cancel_frame = frame
            msg += cs.hat_hot_request(o, 5, 1, p_hot[0], p_hot[1], 0.0)
        try:
            tx.sendto(msg, ("127.0.0.1", port))
            if sofs and not sent_malformed:  # igd is listening: its Start of Frame arrived
                tx.sendto(msg[:30], ("127.0.0.1", port))  # truncated inside Entity Control
                # A HAT/HOT Request with a size byte of 30 (not 32): the whole message is malformed.
                bad = bytearray(cs.ig_control(o, frame, int(round(frame * 1e5 / RATE_HZ))) +
                                cs.hat_hot_request(o, 6, 1, p_hot[0], p_hot[1], 0.0))
                bad[25] = 30
                tx.sendto(bytes(bad[:24 + 30]), ("127.0.0.1", port))
                sent_malformed = True
        except OSError:
            pass  # igd not bound yet (ECONNREFUSED is not reported for unconnected UDP anyway)
        frame += 1
        while True:
            try:
                data = rx.recv(65536)
                sofs.append(cs.decode_start_of_frame(data))
                answers.extend((sofs[-1]["last_host_frame"], a) for a in cs.decode_hat_hot_responses(data))
                los_answers.extend(cs.decode_los_responses(data))
            except BlockingIOError:
                break
        time.sleep(1.0 / RATE_HZ)
    out, err = proc.communicate(timeout=60)
    while True:
        try:
            data = rx.recv(65536)
            sofs.append(cs.decode_start_of_frame(data))
            answers.extend((sofs[-1]["last_host_frame"], a) for a in cs.decode_hat_hot_responses(data))
            los_answers.extend(cs.decode_los_responses(data))
        except BlockingIOError:
            break
    check(proc.returncode == 0, "igd exit status %s: %s" % (proc.returncode, err[-2000:]))
    # The start-up log names what the answers meet: the DEM's posts, the tower, the forest's trees.
    m = re.search(r"igd: host queries \(HAT/HOT, LOS\) meet: the terrain grid \((\d+) x (\d+) posts\), (\d+) \[forest\]"
                  r" trees \(LOS, index \d+ ms\), 1 \[hdlod\] objects \(12 model triangles", err)
    check(m is not None and int(m.group(1)) == DEM_N and int(m.group(2)) == DEM_N and int(m.group(3)) > 100,
          "start-up log line 'host queries': %s" % [l for l in err.splitlines() if "host queries" in l])

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
    # The host's visibility is the fog's from the host frame that brought it, and the far plane
    # moves in to where that fog is opaque (1.77 x; View Definition's far is 20 km).
    vis_from = vis_from if vis_from is not None else frame + 1  # never sent: every check below fails
    fogged = [r for r in rendered if int(r["host_frame"]) >= vis_from]
    check(len(fogged) >= FRAMES // 4, "only %d frames rendered with the host's visibility" % len(fogged))
    opaque = VISIBILITY_M * math.log(1024.0) / 3.912
    bad_fog = [(r["frame"], r["fog_visibility_m"], r["far_m"]) for r in fogged
               if abs(float(r["fog_visibility_m"]) - VISIBILITY_M) > 0.05 or abs(float(r["far_m"]) - opaque) > 0.1]
    check(not bad_fog, "frames with the host's visibility %.0f m: (frame, fog_visibility_m, far_m) %r, expected far %.1f"
          % (VISIBILITY_M, bad_fog[:3], opaque))
    before = [r for r in rendered if int(r["host_frame"]) < vis_from]
    check(before and all(float(r["far_m"]) > opaque + 1.0 for r in before),
          "frames before the host's visibility drawn to the far plane: %r" % [r["far_m"] for r in before[:3]])
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
        check(malformed == 2 and out_of_range == 1 and late_n == 0, "link counters: %s" % m.group(0))
        check(received == accepted + malformed and accepted >= FRAMES // 2, "link counters: %s" % m.group(0))

    # HAT/HOT answers.
    by_id = {}
    for lhf, a in answers:
        by_id.setdefault(a["id"], []).append((lhf, a))
    check(hat_frame is not None and cancel_frame is not None, "HAT/HOT requests were sent")
    check(sorted(by_id) == [1, 2, 3, 4, 5, 7], "HAT/HOT answers for ids %r, expected 1..5 and 7 (6 was malformed)"
          % sorted(by_id))
    for i in (1, 2, 3, 4, 7):
        check(len(by_id.get(i, [])) == 1, "one-shot request %d answered %d times" % (i, len(by_id.get(i, []))))
    if by_id.get(1):
        a = by_id[1][0][1]
        want = expected_hot(*p_hot)
        check(a["valid"] == 1 and a["hot"] == 1 and abs(a["height"] - want) < 1e-3,
              "HOT inside the DEM: %r, expected valid HOT %.4f" % (a, want))
    if by_id.get(2):
        a = by_id[2][0][1]
        want = expected_hot(*p_ext)
        check(a["ext"] and a["valid"] == 1 and abs(a["hot"] - want) < 1e-3 and abs(a["hat"] - (900.0 - a["hot"])) < 1e-6
              and 0.0 < a["elevation"] <= 90.0, "extended inside the DEM: %r, expected HOT %.4f" % (a, want))
    if by_id.get(7):
        # The roof: the ENU vertical through the DEM point under p_tower, at the roof's height.
        a = by_id[7][0][1]
        e, n, _ = cs.enu_of_geodetic(ORIGIN, p_tower[0], p_tower[1], expected_hot(*p_tower))
        want = cs.geodetic_of_enu(ORIGIN, e, n, tower_base() + TOWER_HEIGHT)[2]
        check(a["ext"] and a["valid"] == 1 and abs(a["hot"] - want) < 1e-3 and a["material"] == 1
              and abs(a["elevation"] - 90.0) < 0.1, "extended HOT over the tower: %r, expected HOT %.4f, material 1"
              % (a, want))
    for i in (3, 4):
        if by_id.get(i):
            check(by_id[i][0][1]["valid"] == 0, "request %d (outside / NaN) answered Valid = false: %r" % (i, by_id[i][0][1]))
    periodic = by_id.get(5, [])
    before = [a for lhf, a in periodic if cancel_frame and lhf < cancel_frame]
    after = [a for lhf, a in periodic if cancel_frame and lhf > cancel_frame]
    check(len(before) >= 3 and all(a["valid"] == 1 for _, a in periodic),
          "periodic request: %d answers before the cancel, all valid" % len(before))
    check(len(after) <= 1, "periodic request: %d answers after the cancel (at most its own one-shot)" % len(after))
    m = re.search(r"hat_hot_requests (\d+) hat_hot_answered (\d+) hat_hot_refused (\d+)", err)
    check(m is not None and int(m.group(1)) == 7 and int(m.group(2)) == len(answers) and int(m.group(3)) == 0,
          "exit line HAT/HOT counters: %s (answers received: %d)" % (m.group(0) if m else err[-500:], len(answers)))
    # The status file's last report (written as igd stops) carries the same counters.
    try:
        with open(status) as f:
            hh = json.load(f)["host"].get("hat_hot")
    except (OSError, ValueError, KeyError) as e:
        hh = "unreadable: %s" % e
    check(isinstance(hh, dict) and hh.get("requests") == 7 and hh.get("answered") == len(answers)
          and hh.get("refused") == 0 and "deferred" in hh, "status file host.hat_hot: %r (answers received: %d)"
          % (hh, len(answers)))

    # The LOS segment: one answer, its range within 1 mm of the first intersection with the DEM.
    want = los_expected_range()
    los = {a["id"]: a for a in los_answers}
    check(len(los_answers) == 2 + len(FOREST_RAYS) and 41 in los and los[41]["valid"] == 1 and
          not los[41]["visible"] and abs(los[41]["range"] - want) < 1e-3 and not los[41]["ext"],
          "LOS segment: %r, expected one valid answer with range %.4f" % (los_answers, want))
    # The tower's west wall, 130 m from the source.
    check(42 in los and los[42]["ext"] and los[42]["valid"] == 1 and not los[42]["visible"] and
          abs(los[42]["range"] - (150.0 - TOWER_HALF[0])) < 1e-3 and los[42]["material"] == 1 and
          abs(los[42]["azimuth"] + 90.0) < 0.1, "LOS towards the tower: %r, expected range %.1f, material 1, normal west"
          % (los.get(42), 150.0 - TOWER_HALF[0]))
    # Straight down into the forest: each ray stops at a tree above the ground (material 2) or at
    # the ground itself (material 0, at the DEM's height within 1 mm); some of them at trees.
    trees = 0
    for k, (e, n) in enumerate(FOREST_RAYS):
        a = los.get(51 + k)
        ground = 1000.0 - dem_height(e, n)  # the ENU distance down to the DEM
        ok = a is not None and a["ext"] and a["valid"] == 1 and not a["visible"] and (
            (a["material"] == 0 and abs(a["range"] - ground) < 1e-3) or
            (a["material"] == 2 and a["range"] < ground - 0.5))
        trees += 1 if ok and a["material"] == 2 else 0
        check(ok, "LOS down into the forest at (%.0f, %.0f): %r, expected a tree (material 2) above the ground or the"
              " ground %.4f m down (material 0)" % (e, n, a, ground))
    check(trees >= 2, "LOS down into the forest: %d of %d rays stopped at a tree" % (trees, len(FOREST_RAYS)))
    m = re.search(r"los_requests (\d+) los_answered (\d+) los_refused (\d+)", err)
    nlos = 2 + len(FOREST_RAYS)
    check(m is not None and int(m.group(1)) == nlos and int(m.group(2)) == nlos and int(m.group(3)) == 0,
          "exit line LOS counters: %s" % (m.group(0) if m else err[-500:]))
    try:
        with open(status) as f:
            lc = json.load(f)["host"].get("los")
    except (OSError, ValueError, KeyError) as e:
        lc = "unreadable: %s" % e
    check(isinstance(lc, dict) and lc.get("requests") == nlos and lc.get("answered") == nlos, "status file host.los: %r" % lc)

    # The recording of accepted samples.
    with open(rec) as f:
        lines = [l for l in f.read().splitlines() if l.strip() and not l.startswith("#")]
    check(lines and lines[0].startswith("igd-recording"), "record_file header: %r" % lines[:1])
    check(len(lines) - 1 >= FRAMES // 2, "record_file has %d samples" % (len(lines) - 1))
    # Each sample keeps View Definition's window: shift_x = (tan r + tan l) / 2, shift_y = 0
    # (top = -bottom), width_tan = tan r - tan l, from the float32 angles sent.
    tl, tr = math.tan(math.radians(cs_f32(-50.0))), math.tan(math.radians(cs_f32(10.0)))
    windows = [tuple(float(x) for x in l.split()[14:17]) for l in lines[1:]]
    bad_windows = [w for w in windows
                   if len(w) != 3 or abs(w[0] - 0.5 * (tr + tl)) > 1e-9 or w[1] != 0.0 or abs(w[2] - (tr - tl)) > 1e-9]
    check(windows and not bad_windows, "recorded windows (shift_x shift_y width_tan): %r, expected %.9f 0 %.9f"
          % (bad_windows[:3], 0.5 * (tr + tl), tr - tl))
    # ... and the host's visibility (vis_m, version 4): none before vis_from, then VISIBILITY_M.
    vis = [(int(l.split()[1]), float(l.split()[17])) for l in lines[1:] if len(l.split()) == 18]
    check(len(vis) == len(lines) - 1 and lines[0].split()[1] == "4", "record_file version 4 with vis_m: %r" % lines[:2])
    bad_vis = [(hf, v) for hf, v in vis if hf >= vis_from and v != VISIBILITY_M] + \
              [(hf, v) for hf, v in vis if hf < vis_from and v > 0.0]
    check(any(hf >= vis_from for hf, _ in vis) and not bad_vis, "recorded visibilities (host frame, vis_m): %r" % bad_vis[:3])

    print("cigi_igd_test: %d frames, %d rendered host samples, %d Start of Frame packets, %d of %d rays into the"
          " forest stopped at trees; %d failures" % (len(rows), len(rendered), len(sofs), trees, len(FOREST_RAYS),
                                                      len(FAILURES)))
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
