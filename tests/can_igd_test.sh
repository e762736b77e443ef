#!/usr/bin/env bash
# igd end to end over SocketCAN: inside user-mode Linux (the host kernel has no AF_CAN), igd runs
# with [host] source = "can" on vcan0 while canplayer replays 60 sets at 30 Hz written from the
# DBC file by tests/can_dbc_send.py; then tests/can_igd_check.py checks igd's counters line, its
# per-frame stats (eyepoint in ENU, heading, host frame, host_lost) and its recording.
#
#   can_igd_test.sh <igd binary> <source dir>
set -uo pipefail
igd=$1 src=$2
work=$(mktemp -d /tmp/can_igd.XXXXXX)
trap '[ -n "${IG_KEEP_WORK:-}" ] || rm -rf "$work"' EXIT
fail() {
  echo "can_igd_test: FAIL: $*"
  for f in console.log igd.err result; do
    echo "---- $f ----"
    cat "$work/$f" 2>/dev/null
  done
  exit 1
}
sets=60
/usr/bin/python3 "$src/tests/can_dbc_send.py" "$src/config/igd_host.dbc" --candump-log "$work/host.log" $sets ||
  fail "cannot write the candump log"
cat >"$work/igd.toml" <<TOML
[frame]
rate_hz = 30
frames = 150
free_run = false
[output]
mode = "headless"
width_px = 64
height_px = 64
snapshot_dir = "$work/snapshots"
snapshot_every = 0
[stats]
file = "$work/stats.csv"
format = "csv"
[host]
source = "can"
link_timeout_s = 1.0
record_file = "$work/record.rec"
[host.can]
# generous: inside UML, canplayer competes with llvmpipe's threads for two cores
interface = "vcan0"
base_id = 256
stale_ms = 1000
[scene]
file = "$src/config/scenes/default.toml"
TOML
IG_UML_TIMEOUT=120 bash "$src/tests/uml/boot.sh" "$work" "$src/tests/uml/can_igd_run.sh" IG_IGD="$igd"
rc=$?
[ $rc -eq 124 ] && fail "user-mode Linux timed out"
[ "$(head -n1 "$work/result" 2>/dev/null)" = DONE ] || fail "no result: user-mode Linux did not boot or igd did not run (kernel rc $rc)"
grep -qx 'igd_rc=0' "$work/result" || fail "igd failed ($(sed -n 's/^igd_rc=//p' "$work/result"))"
/usr/bin/python3 "$src/tests/can_igd_check.py" "$work" $sets || fail "igd's output does not match what was sent"
echo "can_igd_test: PASS"
