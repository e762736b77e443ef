#!/usr/bin/python3
"""End to end: igd renders from a Modbus host link driven by mbpoll, the real master.

For each transport (modbus-tcp on loopback, modbus-rtu on a socat pty pair) this runs
build/igd with a tiny headless output for a few seconds at 30 Hz while mbpoll writes complete
sets (14 floats, COMMIT and then visibility_m, one FC16 request each) with a host frame counter,
a moving eyepoint and a changing visibility, and reads the IG status input registers. Then it checks:
  - igd exits 0 and prints "igd: link <name>: received N accepted M malformed 0 ...", with M
    at least the number of writes mbpoll reported as done;
  - the status registers read while igd ran show IG frames counting and the sets accepted;
  - every stats row that rendered one of the sets shows that set's eyepoint, heading and fog
    visibility, and the host frame never goes back.

Usage: modbus_igd_test.py <igd> <source dir>
"""
import csv
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from igd_link_config import write_link_config  # noqa: E402

IGD, SRC = sys.argv[1], sys.argv[2]
RATE_HZ, FRAMES = 30, 90
FIRST_FRAME = 1000


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def set_values(k):
    """Set k: eyepoint, attitude and host frame that identify it in the stats."""
    return {"east": 100.0 + 10.0 * k, "north": -50.0, "up": 300.0, "heading": 90.0 + k,
            "frame": FIRST_FRAME + k, "visibility": 2000.0 + 10.0 * k}


def set_args(k):
    v = set_values(k)
    return [str(v["east"]), str(v["north"]), str(v["up"]), str(v["heading"]), "-2", "0",
            "50", "0.5", "30000", str(k / RATE_HZ), str(v["frame"]), "12", str(k), str(v["visibility"])]


def run_case(name, table, mbpoll_base, tmp):
    os.makedirs(tmp)
    config = write_link_config(tmp, name, "modbus", table, SRC, RATE_HZ, FRAMES, 0.5)
    err_path = os.path.join(tmp, "igd.err")
    with open(err_path, "w") as err:
        igd = subprocess.Popen([IGD, "--config", config], stdout=subprocess.DEVNULL, stderr=err)
    written, statuses, k = 0, [], 0
    deadline = time.monotonic() + 120
    try:
        while igd.poll() is None and time.monotonic() < deadline:
            k += 1
            w = subprocess.run(mbpoll_base + ["-r", "1", "-t", "4:float", "-B", "--"] + set_args(k),
                               capture_output=True, text=True, timeout=30)
            if w.returncode == 0:
                written += 1
            if written and k % 5 == 0:
                r = subprocess.run(mbpoll_base + ["-r", "1", "-t", "3:int", "-B", "-c", "12", "-1"],
                                   capture_output=True, text=True, timeout=30)
                values = [int(m) for m in re.findall(r"^\[\d+\]:\s+(-?\d+)", r.stdout, re.M)]
                if r.returncode == 0 and len(values) == 12:
                    statuses.append(values)
            time.sleep(0.03 if written else 0.1)
        rc = igd.wait(timeout=120)
    finally:
        if igd.poll() is None:
            igd.kill()
            igd.wait()
    err = open(err_path).read()
    assert rc == 0, f"{name}: igd exited {rc}:\n{err}"
    assert written >= 5, f"{name}: only {written} sets written while igd ran:\n{err}"

    m = re.search(rf"igd: link {name}: received (\d+) accepted (\d+) malformed (\d+) out_of_range (\d+)"
                  r" late (\d+) dropped (\d+)", err)
    assert m, f"{name}: no link counters line in igd's stderr:\n{err}"
    received, accepted, malformed, out_of_range = (int(g) for g in m.groups()[:4])
    assert written <= accepted <= k, f"{name}: accepted {accepted}, mbpoll wrote {written} of {k}"
    assert malformed == 0 and out_of_range == 0, m.group(0)
    assert received >= accepted + len(statuses), m.group(0)

    assert statuses, f"{name}: mbpoll never read the status registers"
    last = statuses[-1]
    assert last[0] > 0, f"{name}: ig_frame not counting: {last}"
    assert last[6] >= 1 and last[11] == 2, f"{name}: status {last}"  # accepted, map_version
    assert all(b[0] >= a[0] for a, b in zip(statuses, statuses[1:])), f"{name}: ig_frame went back: {statuses}"

    with open(os.path.join(tmp, "stats.csv")) as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == FRAMES, f"{name}: {len(rows)} stats rows"
    seen, prev = set(), 0
    for row in rows:
        frame = int(row["host_frame"])
        if frame < FIRST_FRAME + 1:
            continue
        assert frame >= prev, f"{name}: host_frame went back at IG frame {row['frame']}"
        prev = frame
        v = set_values(frame - FIRST_FRAME)
        for column, key in (("eye_east_m", "east"), ("eye_north_m", "north"), ("eye_up_m", "up"),
                            ("heading_deg", "heading"), ("fog_visibility_m", "visibility")):
            assert abs(float(row[column]) - v[key]) < 0.01, f"{name}: frame {row['frame']} {column} {row[column]} != {v[key]}"
        seen.add(frame)
    assert len(seen) >= 5, f"{name}: only {len(seen)} host sets rendered: {sorted(seen)}"
    print(f"{name}: {written} sets written, {len(seen)} rendered, {len(statuses)} status reads; {m.group(0)}")


def main():
    tmp = tempfile.mkdtemp(prefix="igd-modbus-e2e-")
    socat = None
    try:
        port = free_port()
        run_case("modbus-tcp", f'tcp_address = "127.0.0.1"\ntcp_port = {port}\nword_order = "high_first"',
                 ["mbpoll", "-m", "tcp", "-p", str(port), "-a", "1", "-o", "2", "127.0.0.1"], os.path.join(tmp, "tcp"))

        a, b = os.path.join(tmp, "a"), os.path.join(tmp, "b")
        socat = subprocess.Popen(["socat", "-d", "-d", f"pty,raw,echo=0,link={a}", f"pty,raw,echo=0,link={b}"],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        end = time.monotonic() + 30
        while not (os.path.exists(a) and os.path.exists(b)) and time.monotonic() < end:
            time.sleep(0.02)
        assert os.path.exists(a) and os.path.exists(b), "socat made no pty pair"
        run_case("modbus-rtu",
                 f'serial_device = "{a}"\nunit_id = 3\nbaud = 115200\nparity = "N"\nword_order = "high_first"',
                 ["mbpoll", "-m", "rtu", "-b", "115200", "-P", "none", "-a", "3", "-o", "2", b],
                 os.path.join(tmp, "rtu"))
    finally:
        if socat is not None:
            socat.terminate()
            socat.wait()
        shutil.rmtree(tmp, ignore_errors=True)
    print("modbus_igd_test: ok")


if __name__ == "__main__":
    main()
