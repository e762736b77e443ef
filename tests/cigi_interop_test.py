#!/usr/bin/python3
"""CIGI interoperability on real loopback traffic, captured with dumpcap:

1. An independent Python encoder (tests/cigi_sender.py) sends host messages in both byte orders
   (with an unknown packet, another entity, a NaN field, a bad magic, IG Control not first and
   a late frame) to igd's CIGI link (tests/cigi_probe.cpp runs the link alone); every sample
   the link publishes must match what Python computes independently (WGS-84, attitude).
2. Python decodes every Start of Frame the link sends: Standby / status 1 before the host
   appears, Operate / status 0 after, IG frame counting up, the last host frame echoed.
3. Debian's tshark CIGI dissector decodes the capture: every host message Python sent and every
   Start of Frame igd sent, with the field values matching.
4. The capture goes through igd's pcap converter: the same samples as the live link.
5. HAT/HOT: a HOT and an extended request (sent with the last message) are answered after a
   Start of Frame from the probe's synthetic terrain (a known plane): the HOT Python computes
   independently, both in Python's decoding and in tshark's.

usage: cigi_interop_test.py <cigi_probe>
"""
import math
import os
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cigi_sender as cs  # noqa: E402

ORIGIN = (57.7, 11.97, 100.0)
FAILURES = []
CHILDREN = []  # dumpcap and cigi_probe: killed on the way out, even when main() raises


def check(cond, what):
    if not cond:
        FAILURES.append(what)
        print("FAIL:", what, flush=True)


def f32(x):
    return struct.unpack("f", struct.pack("f", x))[0]


def close(a, b, tol):
    return abs(a - b) <= tol * max(1.0, abs(a), abs(b))


def readline(proc, timeout=20.0):
    """A line from the probe's stdout, failing the test (not hanging) past the timeout."""
    import select
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        r, _, _ = select.select([proc.stdout], [], [], max(0.0, end - time.monotonic()))
        if r:
            return proc.stdout.readline()
    raise RuntimeError("timed out waiting for cigi_probe output")


def parse_sample(line):
    v = line.split()
    assert v[0] == "SAMPLE", line
    keys = ["t_s", "host_frame", "sim_time_s", "east_m", "north_m", "up_m", "lat_deg", "lon_deg", "height_m",
            "heading_deg", "pitch_deg", "roll_deg", "fovy_deg", "near_m", "far_m", "time_of_day_h", "date_ymd",
            "visibility_m"]
    return {k: float(x) for k, x in zip(keys, v[1:])}


def parse_counters(line):
    v = line.split()
    assert v[0] == "COUNTERS", line
    return {k: int(x) for k, x in (kv.split("=") for kv in v[1:])}


def main():
    probe = sys.argv[1]
    tmp = tempfile.mkdtemp(prefix="cigi_interop_")
    cap = os.path.join(tmp, "cigi.pcap")

    # Capture UDP on loopback from before the link starts until after it stops.
    # -a duration: a backstop should this process be killed before it stops dumpcap itself.
    dumpcap = subprocess.Popen(["dumpcap", "-q", "-i", "lo", "-P", "-f", "udp", "-a", "duration:300", "-w", cap],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    CHILDREN.append(dumpcap)
    started = ""
    end = time.monotonic() + 30
    while time.monotonic() < end:
        line = dumpcap.stderr.readline()
        if not line:
            break
        started += line
        if "Capturing on" in line:
            break
    if "Capturing on" not in started:
        dumpcap.kill()
        print("dumpcap did not start capturing on lo:", started, dumpcap.stderr.read())
        return 1
    # "Capturing on" can come before the capture filter is live (seen on Linux 6.18): send
    # markers to a socket of our own until dumpcap has written one, so that the link's first
    # Start of Frame is not lost. tshark's filters below select the CIGI ports only.
    def written():
        return os.path.getsize(cap) if os.path.exists(cap) else 0

    marker = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    marker.bind(("127.0.0.1", 0))
    end = time.monotonic() + 30
    while written() <= 24 and time.monotonic() < end:  # 24: the pcap file header
        marker.sendto(b"capture marker", marker.getsockname())
        time.sleep(0.02)
    marker.close()
    if written() <= 24:
        dumpcap.kill()
        print("dumpcap wrote no packet within 30 s:", dumpcap.stderr.read())
        return 1

    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", 0))
    rx.settimeout(10.0)
    host_port = rx.getsockname()[1]
    link = subprocess.Popen([probe, "link", str(host_port), "%r,%r,%r" % ORIGIN], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    CHILDREN.append(link)
    port = int(readline(link).split()[1])
    sofs = []

    # Before any host message the link reports Standby with IG status 1 (host lost).
    for _ in range(2):
        data = rx.recv(65536)
        sofs.append((data, cs.decode_start_of_frame(data)))
    check(sofs[0][1]["mode"] == 0 and sofs[0][1]["status"] == 1, "Start of Frame before the host: %r" % sofs[0][1])

    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sent = []      # every datagram, with what tshark should show for it
    expected = []  # the samples the link should publish

    def send(msg, fields=None, expect=None):
        tx.sendto(msg, ("127.0.0.1", port))
        sent.append((msg, fields))
        if expect is not None:
            expected.append(expect)
            got = parse_sample(readline(link))
            compare_sample(got, expect, "message %d" % len(sent))
            samples.append(got)

    samples = []

    def compare_sample(got, exp, what):
        for k in ("east_m", "north_m", "up_m", "height_m"):
            check(abs(got[k] - exp[k]) < 1e-4, "%s: %s = %.9f, expected %.9f" % (what, k, got[k], exp[k]))
        for k in ("lat_deg", "lon_deg"):
            check(abs(got[k] - exp[k]) < 1e-9, "%s: %s = %.12f, expected %.12f" % (what, k, got[k], exp[k]))
        for k in ("heading_deg", "pitch_deg", "roll_deg"):
            d = (got[k] - exp[k] + 180.0) % 360.0 - 180.0
            check(abs(d) < 1e-6, "%s: %s = %.9f, expected %.9f" % (what, k, got[k], exp[k]))
        for k in ("host_frame", "sim_time_s", "fovy_deg", "near_m", "far_m", "time_of_day_h", "date_ymd", "visibility_m"):
            check(close(got[k], exp[k], 1e-9), "%s: %s = %r, expected %r" % (what, k, got[k], exp[k]))

    def expect(frame, ticks, ent, view, vdef, sky, vis):
        roll, pitch, yaw, lat, lon, alt = ent
        enu, h, p, r = cs.expected_eye(ORIGIN, lat, lon, alt, f32(yaw), f32(pitch), f32(roll),
                                       tuple(f32(x) for x in view[:3]), tuple(f32(x) for x in (view[5], view[4], view[3])))
        g = ecef_to_lat_lon_h(*ecef_of_enu(enu))
        near, far, top, bottom = vdef
        # igd keeps the window's height in tangents (docs/cigi.md): fovy = top - bottom only when symmetric.
        t, b = f32(top), f32(bottom)
        fovy = t - b if t == -b else 2.0 * math.degrees(math.atan(0.5 * (math.tan(math.radians(t)) - math.tan(math.radians(b)))))
        return {"host_frame": frame, "sim_time_s": ticks * 1e-5, "east_m": enu[0], "north_m": enu[1], "up_m": enu[2],
                "lat_deg": g[0], "lon_deg": g[1], "height_m": g[2], "heading_deg": h, "pitch_deg": p, "roll_deg": r,
                "fovy_deg": fovy, "near_m": f32(near), "far_m": f32(far),
                "time_of_day_h": sky[0] + sky[1] / 60.0, "date_ymd": sky[4] * 10000 + sky[2] * 100 + sky[3],
                "visibility_m": f32(vis)}

    def ig_fields(order, frame, ticks, db, ent_list, view=None, vdef=None, sky=None, vis=None):
        f = {"cigi.byte_swap": "0x8000" if order == ">" else "0x0080", "cigi.ig_control.host_frame_number": frame,
             "cigi.ig_control.timestamp": ticks, "cigi.ig_control.db_number": db, "cigi.ig_control.ig_mode": 1,
             "cigi.ig_control.timestamp_valid": 1, "cigi.ig_control.minor_version": 3,
             "cigi.entity_control.entity_id": [e[0] for e in ent_list],
             "cigi.entity_control.roll": [f32(e[1][0]) for e in ent_list],
             "cigi.entity_control.pitch": [f32(e[1][1]) for e in ent_list],
             "cigi.entity_control.yaw": [f32(e[1][2]) for e in ent_list],
             "cigi.entity_control.lat_xoff": [e[1][3] for e in ent_list],
             "cigi.entity_control.lon_yoff": [e[1][4] for e in ent_list],
             "cigi.entity_control.alt_zoff": [e[1][5] for e in ent_list]}
        if view:
            for k, v in zip(("xoff", "yoff", "zoff", "roll", "pitch", "yaw"), view):
                f["cigi.view_control." + k] = f32(v)
        if vdef:
            for k, v in zip(("near", "far", "top", "bottom"), vdef):
                f["cigi.view_def." + k] = f32(v)
        if sky:
            f["cigi.celestial_sphere_control.hour"] = sky[0]
            f["cigi.celestial_sphere_control.minute"] = sky[1]
            f["cigi.celestial_sphere_control.date"] = sky[2] * 1000000 + sky[3] * 10000 + sky[4]
            f["cigi.celestial_sphere_control.date_time_valid"] = 1
        if vis is not None:
            f["cigi.atmosphere_control.visibility_range"] = f32(vis)
            f["cigi.atmosphere_control.humidity"] = 40
            f["cigi.atmosphere_control.air_temp"] = 12.5
            f["cigi.atmosphere_control.barometric_pressure"] = 1009.0
        return f

    # 1: big-endian, every packet igd decodes.
    ent1 = (5.0, -3.0, 30.0, ORIGIN[0] + 0.01, ORIGIN[1] + 0.02, 800.0)
    view1 = (2.0, 0.5, -1.5, 1.0, -5.0, 10.0)
    vdef1 = (0.25, 50000.0, 24.0, -18.0)
    sky1 = (9, 45, 3, 20, 2026)
    o = ">"
    msg = (cs.ig_control(o, 100, 100000, database=6) + cs.entity_control(o, 0, *ent1) +
           cs.view_control(o, 0, 0, *view1) + cs.view_definition(o, 0, vdef1[0], vdef1[1], -35.0, 35.0, vdef1[2], vdef1[3]) +
           cs.celestial(o, *sky1) + cs.atmosphere(o, 3500.0))
    send(msg, ig_fields(o, 100, 100000, 6, [(0, ent1)], view1, vdef1, sky1, 3500.0),
         expect(100, 100000, ent1, view1, vdef1, sky1, 3500.0))

    # 2: little-endian, an unknown packet and another entity before the ownship.
    o = "<"
    ent2 = (-20.0, 12.5, 350.0, ORIGIN[0] - 0.05, ORIGIN[1] - 0.1, 2500.0)
    other = (0.0, 0.0, 90.0, 10.0, 10.0, 10.0)
    view2 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    vdef2 = (1.0, 80000.0, 30.0, -30.0)
    sky2 = (23, 59, 12, 31, 2025)
    msg = (cs.ig_control(o, 101, 103333) + cs.unknown_packet(250, 20) + cs.entity_control(o, 5, *other) +
           cs.entity_control(o, 0, *ent2) + cs.view_control(o, 0, 0, *view2) +
           cs.view_definition(o, 0, vdef2[0], vdef2[1], -40.0, 40.0, vdef2[2], vdef2[3]) + cs.celestial(o, *sky2) +
           cs.atmosphere(o, 750.3))
    send(msg, ig_fields(o, 101, 103333, 0, [(5, other), (0, ent2)], view2, vdef2, sky2, 750.3),
         expect(101, 103333, ent2, view2, vdef2, sky2, 750.3))

    # 3: NaN latitude and a negative visibility: each rejected alone (the last good ones held), the rest applies.
    o = ">"
    ent3 = (0.0, 0.0, 180.0, float("nan"), ORIGIN[1] + 0.03, 1500.0)
    msg = cs.ig_control(o, 102, 106666) + cs.entity_control(o, 0, *ent3) + cs.atmosphere(o, -5.0)
    held = (ent3[0], ent3[1], ent3[2], ent2[3], ent3[4], ent3[5])
    send(msg, ig_fields(o, 102, 106666, 0, [(0, ent3)], vis=-5.0), expect(102, 106666, held, view2, vdef2, sky2, 750.3))

    # 4: bad magic; 5: IG Control not first; 6: a late frame. None publishes.
    bad = bytearray(cs.ig_control(o, 103, 110000) + cs.entity_control(o, 0, *ent1))
    bad[6:8] = b"\x12\x34"
    send(bytes(bad))
    send(cs.entity_control("<", 0, *ent1) + cs.ig_control("<", 103, 110000))
    late = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    send(cs.ig_control(o, 99, 99000) + cs.entity_control(o, 0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0),
         ig_fields(o, 99, 99000, 0, [(0, (1.0, 1.0, 1.0, 1.0, 1.0, 1.0))]))
    del late

    # 7: back to normal (little-endian), with two HAT/HOT requests: a HOT and an extended one.
    o = "<"
    ent7 = (1.0, 2.0, 3.0, ORIGIN[0] + 0.002, ORIGIN[1] - 0.004, 333.0)
    hot_point = (ORIGIN[0] + 0.004, ORIGIN[1] - 0.009)  # about 445 m north, 540 m west
    ext_point = (ORIGIN[0] - 0.006, ORIGIN[1] + 0.012, 950.0)
    # ... and two LOS requests: a basic segment and an extended vector (points from ENU).
    seg_src = cs.geodetic_of_enu(ORIGIN, *LOS_A)
    seg_dst = cs.geodetic_of_enu(ORIGIN, *LOS_B)
    vec_src = cs.geodetic_of_enu(ORIGIN, *LOS_V)
    msg = (cs.ig_control(o, 104, 113333) + cs.entity_control(o, 0, *ent7) +
           cs.hat_hot_request(o, 21, 1, hot_point[0], hot_point[1], 0.0) +
           cs.hat_hot_request(o, 22, 2, *ext_point) +
           cs.los_segment_request(o, 31, seg_src, seg_dst) +
           cs.los_vector_request(o, 32, vec_src, LOS_AZ, LOS_EL, 5.0, 2000.0, extended=True))
    fields7 = ig_fields(o, 104, 113333, 0, [(0, ent7)])
    fields7.update({"cigi.hat_hot_request.hat_hot_id": [21, 22], "cigi.hat_hot_request.type": [1, 2],
                    "cigi.hat_hot_request.coordinate_system": [0, 0], "cigi.hat_hot_request.update_period": [0, 0],
                    "cigi.hat_hot_request.lat_xoff": [hot_point[0], ext_point[0]],
                    "cigi.hat_hot_request.lon_yoff": [hot_point[1], ext_point[1]],
                    "cigi.hat_hot_request.alt_zoff": [0.0, ext_point[2]],
                    "cigi.los_segment_request.los_id": 31, "cigi.los_segment_request.type": 0,
                    "cigi.los_segment_request.source_coord": 0, "cigi.los_segment_request.destination_coord": 0,
                    "cigi.los_segment_request.response_coord": 0,
                    "cigi.los_segment_request.source_lat_xoff": seg_src[0],
                    "cigi.los_segment_request.source_lon_yoff": seg_src[1],
                    "cigi.los_segment_request.source_alt_zoff": seg_src[2],
                    "cigi.los_segment_request.destination_lat_xoff": seg_dst[0],
                    "cigi.los_segment_request.destination_lon_yoff": seg_dst[1],
                    "cigi.los_segment_request.destination_alt_zoff": seg_dst[2],
                    "cigi.los_segment_request.update_period": 0,
                    "cigi.los_vector_request.los_id": 32, "cigi.los_vector_request.type": 1,
                    "cigi.los_vector_request.source_coord": 0, "cigi.los_vector_request.response_coord": 0,
                    "cigi.los_vector_request.azimuth": LOS_AZ, "cigi.los_vector_request.elevation": LOS_EL,
                    "cigi.los_vector_request.min_range": 5.0, "cigi.los_vector_request.max_range": 2000.0,
                    "cigi.los_vector_request.source_lat_xoff": vec_src[0],
                    "cigi.los_vector_request.source_lon_yoff": vec_src[1],
                    "cigi.los_vector_request.source_alt_zoff": vec_src[2],
                    "cigi.los_vector_request.update_period": 0})
    send(msg, fields7, expect(104, 113333, ent7, view2, vdef2, sky2, 750.3))

    # Start of Frame after the host appeared: Operate, status 0, echoes host frame 104, database 6.
    deadline = time.monotonic() + 20
    last = None
    while time.monotonic() < deadline:
        data = rx.recv(65536)
        last = cs.decode_start_of_frame(data)
        sofs.append((data, last))
        if last["last_host_frame"] == 104:
            break
    check(last is not None and last["last_host_frame"] == 104, "Start of Frame echoing host frame 104: %r" % last)
    check(last["mode"] == 1 and last["status"] == 0, "Operate / status 0 after the host appeared: %r" % last)
    check(last["database"] == 6, "Start of Frame database = the host's request (6): %r" % last)
    # The answers follow a Start of Frame in the same datagram, within a few frames.
    answers = [(d, a) for d, _ in sofs for a in cs.decode_hat_hot_responses(d)]
    los_answers = [(d, a) for d, _ in sofs for a in cs.decode_los_responses(d)]
    while (len(answers) < 2 or len(los_answers) < 2) and time.monotonic() < deadline:
        data = rx.recv(65536)
        sofs.append((data, cs.decode_start_of_frame(data)))
        answers += [(data, a) for a in cs.decode_hat_hot_responses(data)]
        los_answers += [(data, a) for a in cs.decode_los_responses(data)]

    link.stdin.close()
    rest = link.stdout.read().splitlines()
    link.wait(timeout=30)
    counters = parse_counters([l for l in rest if l.startswith("COUNTERS")][0])
    check(counters["received"] == 7 and counters["accepted"] == 4 and counters["malformed"] == 2 and
          counters["late"] == 1 and counters["out_of_range"] == 2 and counters["send_errors"] == 0,
          "link counters: %r" % counters)
    rx.setblocking(False)
    while True:
        try:
            data = rx.recv(65536)
        except BlockingIOError:
            break
        sofs.append((data, cs.decode_start_of_frame(data)))
    for a, b in zip(sofs, sofs[1:]):
        check(b[1]["ig_frame"] == a[1]["ig_frame"] + 1, "IG frame numbers count up: %d then %d" % (a[1]["ig_frame"], b[1]["ig_frame"]))
    for _, s in sofs:
        check(s["major"] == 3 and s["minor"] == 3 and s["order"] == "<" and s["timestamp_valid"] and s["earth_model"] == 0,
              "Start of Frame header: %r" % s)

    # dumpcap writes what the kernel hands it, in capture order, and may not yet have the last
    # packets (its read timeout, a loaded machine): a fixed sleep lost them now and then. Send
    # markers until one is in the file; every packet before it is then written too.
    marker = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    marker.bind(("127.0.0.1", 0))
    end_marker = b"capture end marker %d" % os.getpid()
    end = time.monotonic() + 30
    found = False
    while not found and time.monotonic() < end:
        marker.sendto(end_marker, marker.getsockname())
        with open(cap, "rb") as f:
            found = end_marker in f.read()
        if not found:
            time.sleep(0.02)
    marker.close()
    check(found, "dumpcap did not write the capture end marker within 30 s")
    dumpcap.send_signal(signal.SIGTERM)
    dumpcap.wait(timeout=30)

    # tshark: the host messages Python sent ...
    host_fields = list(sent[0][1].keys()) + [k for k in sent[1][1].keys() if k not in sent[0][1]]
    host_fields += [k for k in fields7 if k.startswith(("cigi.hat_hot_request", "cigi.los_"))]
    host_fields = list(dict.fromkeys(host_fields))
    rows = tshark(cap, port, host_port, "udp.dstport == %d && cigi.ig_control" % port, host_fields)
    want = [f for _, f in sent if f is not None]
    check(len(rows) == len(want), "tshark decoded %d host messages, expected %d" % (len(rows), len(want)))
    for i, (row, w) in enumerate(zip(rows, want)):
        for k, v in w.items():
            check(field_matches(row[k], v), "tshark host message %d: %s = %r, sent %r" % (i + 1, k, row[k], v))
    # ... and the Start of Frame packets igd sent.
    sof_fields = ["cigi.packet_id", "cigi.packet_size", "cigi.version", "cigi.byte_swap", "cigi.sof.db_number",
                  "cigi.sof.ig_status", "cigi.sof.ig_mode", "cigi.sof.timestamp_valid", "cigi.sof.earth_reference_model",
                  "cigi.sof.minor_version", "cigi.sof.ig_frame_number", "cigi.sof.timestamp",
                  "cigi.sof.last_host_frame_number"]
    rows = tshark(cap, port, host_port, "udp.dstport == %d && cigi.sof" % host_port, sof_fields)
    check(len(rows) == len(sofs), "tshark decoded %d Start of Frame packets, Python received %d" % (len(rows), len(sofs)))
    for row, (data, s) in zip(rows, sofs):
        packets = packet_list(data)  # Start of Frame and the responses after it, if any
        w = {"cigi.packet_id": [p[0] for p in packets],
             "cigi.packet_size": [p[1] for p in packets], "cigi.version": 3, "cigi.byte_swap": "0x0080",
             "cigi.sof.db_number": s["database"], "cigi.sof.ig_status": s["status"], "cigi.sof.ig_mode": s["mode"],
             "cigi.sof.timestamp_valid": 1, "cigi.sof.earth_reference_model": 0, "cigi.sof.minor_version": 3,
             "cigi.sof.ig_frame_number": s["ig_frame"], "cigi.sof.timestamp": s["timestamp"],
             "cigi.sof.last_host_frame_number": s["last_host_frame"]}
        for k, v in w.items():
            check(field_matches(row[k], v), "tshark Start of Frame %d: %s = %r, expected %r" % (s["ig_frame"], k, row[k], v))
    check(any(s["mode"] == 0 and s["status"] == 1 for _, s in sofs) and any(s["mode"] == 1 and s["status"] == 0 for _, s in sofs),
          "both Standby/host-lost and Operate/normal Start of Frame packets were captured")

    # HAT/HOT: exactly the two answers, with the HOT of the probe's plane at the points.
    check([a["id"] for _, a in answers] == [21, 22], "HAT/HOT answers: %r" % answers)
    want_hot = {21: hot_of_plane(*hot_point), 22: hot_of_plane(ext_point[0], ext_point[1])}
    for data, a in answers:
        lsn = cs.decode_start_of_frame(data)["last_host_frame"] & 15
        hot = a["hot"] if a["ext"] else a["height"]
        check(a["valid"] == 1 and a["lsn"] == lsn and abs(hot - want_hot[a["id"]]) < 1e-4,
              "HAT/HOT answer %d: %r, expected HOT %.6f" % (a["id"], a, want_hot[a["id"]]))
        if a["ext"]:
            check(abs(a["hat"] - (ext_point[2] - a["hot"])) < 1e-9 and a["material"] == 0, "extended answer: %r" % a)
            # The plane's normal (ENU slope 0.03 east, -0.02 north) in the local north-east-down
            # frame at the point (whose vertical leans from the ENU up axis by distance / radius).
            az, el = normal_az_el(ext_point[0], ext_point[1], (-0.03, 0.02, 1.0))
            check(abs(a["azimuth"] - az) < 0.001 and abs(a["elevation"] - el) < 0.001,
                  "extended answer normal: %r, expected azimuth %.4f elevation %.4f" % (a, az, el))
        else:
            check(a["hot"] == 1, "HOT answer has Response Type HOT: %r" % a)
    rows = tshark(cap, port, host_port, "udp.dstport == %d && cigi.hat_hot_response" % host_port,
                  ["cigi.hat_hot_response.hat_hot_id", "cigi.hat_hot_response.valid", "cigi.hat_hot_response.type",
                   "cigi.hat_hot_response.height", "cigi.hat_hot_response.host_frame_number_lsn"])
    got = [a for _, a in answers if not a["ext"]]
    check(len(rows) == len(got) == 1, "tshark decoded %d HAT/HOT Responses, Python %d" % (len(rows), len(got)))
    for row, a in zip(rows, got):
        w = {"cigi.hat_hot_response.hat_hot_id": a["id"], "cigi.hat_hot_response.valid": 1,
             "cigi.hat_hot_response.type": 1, "cigi.hat_hot_response.height": want_hot[21],
             "cigi.hat_hot_response.host_frame_number_lsn": a["lsn"]}
        for k, v in w.items():
            check(field_matches(row[k], v), "tshark HAT/HOT Response: %s = %r, expected %r" % (k, row[k], v))
    ext_fields = ["cigi.hat_hot_ext_response.hat_hot_id", "cigi.hat_hot_ext_response.valid", "cigi.hat_hot_ext_response.hat",
                  "cigi.hat_hot_ext_response.hot", "cigi.hat_hot_ext_response.material_code",
                  "cigi.hat_hot_ext_response.normal_vector_azimuth", "cigi.hat_hot_ext_response.normal_vector_elevation",
                  "cigi.hat_hot_ext_response.host_frame_number_lsn"]
    rows = tshark(cap, port, host_port, "udp.dstport == %d && cigi.hat_hot_ext_response" % host_port, ext_fields)
    got = [a for _, a in answers if a["ext"]]
    check(len(rows) == len(got) == 1, "tshark decoded %d HAT/HOT Extended Responses, Python %d" % (len(rows), len(got)))
    for row, a in zip(rows, got):
        w = dict(zip(ext_fields, [a["id"], 1, ext_point[2] - want_hot[22], want_hot[22], 0, a["azimuth"], a["elevation"],
                                  a["lsn"]]))
        for k, v in w.items():
            check(field_matches(row[k], v), "tshark HAT/HOT Extended Response: %s = %r, expected %r" % (k, row[k], v))

    # LOS: the segment's and the vector's first intersection with the probe's plane.
    check(sorted(a["id"] for _, a in los_answers) == [31, 32], "LOS answers: %r" % los_answers)
    seg_range, _ = los_segment_hit(seg_src, seg_dst)
    vec_range, vec_hit = los_vector_hit(vec_src, LOS_AZ, LOS_EL)
    for data, a in los_answers:
        lsn = cs.decode_start_of_frame(data)["last_host_frame"] & 15
        check(a["valid"] == 1 and a["lsn"] == lsn and a["count"] == 1 and a["entity_valid"] == 0 and not a["visible"],
              "LOS answer flags: %r" % a)
        if a["id"] == 31:
            check(not a["ext"] and abs(a["range"] - seg_range) < 1e-3,
                  "LOS segment answer: %r, expected range %.4f" % (a, seg_range))
        else:
            check(a["ext"] and a["range_valid"] == 1 and abs(a["range"] - vec_range) < 1e-3 and
                  abs(a["lat"] - vec_hit[0]) < 1e-8 and abs(a["lon"] - vec_hit[1]) < 1e-8 and
                  abs(a["alt"] - vec_hit[2]) < 1e-3 and a["material"] == 0 and a["rgba"] == (0, 0, 0, 0),
                  "LOS vector answer: %r, expected range %.4f at %r" % (a, vec_range, vec_hit))
            az, el = normal_az_el(vec_hit[0], vec_hit[1], (-0.03, 0.02, 1.0))
            check(abs(a["azimuth"] - az) < 0.001 and abs(a["elevation"] - el) < 0.001,
                  "LOS vector answer normal: %r, expected azimuth %.4f elevation %.4f" % (a, az, el))
    los_fields = ["cigi.los_response.los_id", "cigi.los_response.valid", "cigi.los_response.visible",
                  "cigi.los_response.count", "cigi.los_response.range", "cigi.los_response.host_frame_number_lsn"]
    rows = tshark(cap, port, host_port, "udp.dstport == %d && cigi.los_response" % host_port, los_fields)
    got = [a for _, a in los_answers if not a["ext"]]
    check(len(rows) == len(got) == 1, "tshark decoded %d LOS Responses, Python %d" % (len(rows), len(got)))
    for row, a in zip(rows, got):
        for k, v in zip(los_fields, [31, 1, 0, 1, a["range"], a["lsn"]]):
            check(field_matches(row[k], v), "tshark LOS Response: %s = %r, expected %r" % (k, row[k], v))
    # CIGI 3.2 and 3.3 share the extended layout (Host Frame Number LSN in byte 4's high nibble);
    # tshark names its fields cigi.3_2_los_ext_response.* (cigi.los_ext_response.* is 3.0/3.1's).
    los_ext_fields = ["cigi.3_2_los_ext_response." + f for f in
                      ("los_id", "valid", "range_valid", "visible", "entity_id_valid", "response_count", "range",
                       "lat_xoff", "lon_yoff", "alt_zoff", "material_code", "normal_vector_azimuth",
                       "normal_vector_elevation", "host_frame_number_lsn")]
    rows = tshark(cap, port, host_port, "udp.dstport == %d && cigi.3_2_los_ext_response" % host_port, los_ext_fields)
    got = [a for _, a in los_answers if a["ext"]]
    check(len(rows) == len(got) == 1, "tshark decoded %d LOS Extended Responses, Python %d" % (len(rows), len(got)))
    for row, a in zip(rows, got):
        for k, v in zip(los_ext_fields, [32, 1, 1, 0, 0, 1, a["range"], a["lat"], a["lon"], a["alt"], 0, a["azimuth"],
                                         a["elevation"], a["lsn"]]):
            check(field_matches(row[k], v), "tshark LOS Extended Response: %s = %r, expected %r" % (k, row[k], v))

    # The capture through igd's pcap converter: the same samples as the live link.
    out = subprocess.run([probe, "pcap", cap, str(port), "%r,%r,%r" % ORIGIN], capture_output=True, text=True, timeout=60)
    check(out.returncode == 0, "pcap conversion: %s" % out.stderr)
    lines = out.stdout.splitlines()
    conv = [parse_sample(l) for l in lines if l.startswith("SAMPLE")]
    check(len(conv) == len(samples), "pcap gave %d samples, the live link %d" % (len(conv), len(samples)))
    for i, (a, b) in enumerate(zip(conv, samples)):
        for k in b:
            if k != "t_s":
                check(a[k] == b[k], "pcap sample %d: %s = %r, live %r" % (i, k, a[k], b[k]))
    check(conv and conv[0]["t_s"] == 0.0 and all(b["t_s"] >= a["t_s"] for a, b in zip(conv, conv[1:])),
          "pcap sample times start at 0 and do not decrease: %r" % [c["t_s"] for c in conv])
    pc = parse_counters([l for l in lines if l.startswith("COUNTERS")][0])
    check(pc["received"] == 7 and pc["malformed"] == 2 and pc["late"] == 1 and pc["out_of_range"] == 2,
          "pcap counters: %r" % pc)

    print("cigi_interop_test: %d host messages, %d Start of Frame packets, %d samples; %d failures" %
          (len(sent), len(sofs), len(samples), len(FAILURES)))
    if not FAILURES:
        import shutil
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        print("capture kept in", cap)
    return 1 if FAILURES else 0


# LOS requests of message 7 (ENU metres around ORIGIN; azimuth / elevation in degrees).
LOS_A, LOS_B = (100.0, -50.0, 300.0), (700.0, 250.0, -200.0)
LOS_V, LOS_AZ, LOS_EL = (-200.0, 100.0, 400.0), 120.0, -30.0


def packet_list(data):
    """(id, size) of every packet of a datagram."""
    out, at = [], 0
    while at + 2 <= len(data):
        out.append((data[at], data[at + 1]))
        at += max(data[at + 1], 2)
    return out


def plane_hit(p, d):
    """Parameter s where p + s d (ENU) meets the probe's plane z = 30 + 0.03 east - 0.02 north."""
    return (30.0 + 0.03 * p[0] - 0.02 * p[1] - p[2]) / (d[2] - 0.03 * d[0] + 0.02 * d[1])


def los_segment_hit(src, dst):
    a, b = enu_of_geodetic(*src), enu_of_geodetic(*dst)
    d = [b[k] - a[k] for k in range(3)]
    t = plane_hit(a, d)
    return t * math.sqrt(sum(x * x for x in d)), tuple(a[k] + t * d[k] for k in range(3))


def los_vector_hit(src, az, el):
    """Range and geodetic hit of a vector: azimuth from true north and elevation above the
    local horizontal at the source (its NED axes), converted to the origin's ENU axes."""
    n, e, dn = cs.ned_axes(src[0], src[1])
    az, el = math.radians(az), math.radians(el)
    ned = (math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el))
    ecef = [ned[0] * n[k] + ned[1] * e[k] + ned[2] * dn[k] for k in range(3)]
    on, oe, od = cs.ned_axes(ORIGIN[0], ORIGIN[1])
    dot = lambda a, b: sum(x * y for x, y in zip(a, b))  # noqa: E731
    d = (dot(ecef, oe), dot(ecef, on), -dot(ecef, od))
    p = enu_of_geodetic(*src)
    s = plane_hit(p, d)
    hit = [p[k] + s * d[k] for k in range(3)]
    return s, ecef_to_lat_lon_h(*ecef_of_enu(hit))


def ecef_of_enu(enu):
    o = cs.geodetic_to_ecef(*ORIGIN)
    n, e, d = cs.ned_axes(ORIGIN[0], ORIGIN[1])
    return tuple(o[k] + enu[0] * e[k] + enu[1] * n[k] - enu[2] * d[k] for k in range(3))


def enu_of_geodetic(lat, lon, h):
    p, o = cs.geodetic_to_ecef(lat, lon, h), cs.geodetic_to_ecef(*ORIGIN)
    n, e, d = cs.ned_axes(ORIGIN[0], ORIGIN[1])
    r = [p[k] - o[k] for k in range(3)]
    dot = lambda a, b: sum(x * y for x, y in zip(a, b))  # noqa: E731
    return dot(r, e), dot(r, n), -dot(r, d)


def normal_az_el(lat, lon, n_enu):
    """Azimuth (from true north, clockwise) and elevation of an ENU direction at (lat, lon)."""
    on, oe, od = cs.ned_axes(ORIGIN[0], ORIGIN[1])
    ecef = [n_enu[0] * oe[k] + n_enu[1] * on[k] - n_enu[2] * od[k] for k in range(3)]
    pn, pe, pd = cs.ned_axes(lat, lon)
    dot = lambda a, b: sum(x * y for x, y in zip(a, b))  # noqa: E731
    north, east, down = dot(ecef, pn), dot(ecef, pe), dot(ecef, pd)
    return math.degrees(math.atan2(east, north)), math.degrees(math.asin(-down / math.sqrt(dot(ecef, ecef))))


def hot_of_plane(lat, lon):
    """The height above the ellipsoid of tests/cigi_probe.cpp's terrain (the ENU plane
    z = 30 + 0.03 east - 0.02 north) under (lat, lon): the surface point straight under the
    geodetic point, found by iterating on its height."""
    h = ORIGIN[2]
    for _ in range(6):
        e, n, _ = enu_of_geodetic(lat, lon, h)
        h = ecef_to_lat_lon_h(*ecef_of_enu((e, n, 30.0 + 0.03 * e - 0.02 * n)))[2]
    return h


def ecef_to_lat_lon_h(x, y, z):
    """Iterative geodetic latitude (converges to < 1e-12 deg in a few steps)."""
    lon = math.atan2(y, x)
    p = math.hypot(x, y)
    lat = math.atan2(z, p * (1 - cs.E2))
    for _ in range(10):
        n = cs.A / math.sqrt(1 - cs.E2 * math.sin(lat) ** 2)
        h = p / math.cos(lat) - n
        lat = math.atan2(z, p * (1 - cs.E2 * n / (n + h)))
    n = cs.A / math.sqrt(1 - cs.E2 * math.sin(lat) ** 2)
    return math.degrees(lat), math.degrees(lon), p / math.cos(lat) - n


def tshark(cap, port, host_port, display_filter, fields):
    cmd = ["tshark", "-r", cap, "-d", "udp.port==%d,cigi" % port, "-d", "udp.port==%d,cigi" % host_port,
           "-Y", display_filter, "-T", "fields", "-E", "separator=|", "-E", "occurrence=a", "-E", "aggregator=,"]
    for f in fields:
        cmd += ["-e", f]
    out = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    if out.returncode != 0:
        FAILURES.append("tshark failed: " + out.stderr)
        return []
    return [dict(zip(fields, line.split("|"))) for line in out.stdout.splitlines()]


def field_matches(text, want):
    if isinstance(want, list):
        parts = text.split(",")
        return len(parts) == len(want) and all(field_matches(p, w) for p, w in zip(parts, want))
    if isinstance(want, str):
        return text.lower() == want.lower()
    if isinstance(want, float) and math.isnan(want):
        return text.lower() in ("nan", "-nan")
    try:
        v = float(text)
    except ValueError:
        return False
    if isinstance(want, int):
        return v == want
    return close(v, want, 1e-6)


if __name__ == "__main__":
    try:
        rc = main()
    finally:
        for child in CHILDREN:
            if child.poll() is None:
                child.kill()
                child.wait()
    sys.exit(rc)
