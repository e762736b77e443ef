#!/usr/bin/env bash
# The SocketCAN link against the real kernel stack: boots Debian's user-mode Linux (hostfs root,
# tests/uml/init.sh loads vcan + can-raw and creates vcan0) and runs tests/can_uml_probe.cpp
# there, which drives the CanLink with cansend, canplayer, candump and a python3-can sender.
# A boot failure, a missing kernel or modules, or a timeout FAILS with the console log printed.
#
#   can_uml_test.sh <can_uml_probe binary> <source dir>
set -uo pipefail
probe=$1 src=$2
work=$(mktemp -d /tmp/can_uml.XXXXXX)
trap 'rm -rf "$work"' EXIT
fail() {
  echo "can_uml_test: FAIL: $*"
  echo "---- UML console ($work/console.log) ----"
  cat "$work/console.log" 2>/dev/null
  echo "---- result ----"
  cat "$work/result" 2>/dev/null
  exit 1
}
start=$(date +%s%N)
IG_UML_TIMEOUT=100 bash "$src/tests/uml/boot.sh" "$work" "$src/tests/uml/can_run.sh" IG_PROBE="$probe" IG_SRC="$src"
rc=$?
elapsed=$(awk -v a="$start" -v b="$(date +%s%N)" 'BEGIN { printf "%.1f", (b - a) / 1e9 }')
[ $rc -eq 124 ] && fail "user-mode Linux timed out (rc 124)"
[ -s "$work/result" ] || fail "no result file: user-mode Linux did not boot or the probe did not run (kernel rc $rc)"
[ "$(head -n1 "$work/result")" = PASS ] || fail "the probe reported FAIL"
grep -q 'reboot: Power down' "$work/console.log" || fail "the kernel did not power off cleanly (rc $rc)"
value() { sed -n "s/^$1=//p" "$work/result"; }
expect() {
  local got
  got=$(value "$1")
  [ "$got" = "$2" ] || fail "$1 = '$got', expected $2"
}
# 3 cansend sets + set 14 + 60 canplayer sets + 1 python3-can set; set 13 dropped by set 14,
# the lone frame of set 15 dropped as stale; one late frame; a 2-byte, a remote and a CAN FD
# frame malformed; 3 error frames. Frames: 15 + (2 + 5 + 1 + 1) + 3 + 300 + 5.
expect accepted 65
expect received 332
expect dropped 2
expect late 1
expect malformed 3
expect out_of_range 0
expect bus_errors 3
expect candump_sets 65
n=$(grep -c 'igd: can vcan0: bus error frame' "$work/console.log")
[ "$n" = 1 ] || fail "bus error logged $n times, expected once for the burst"
echo "can_uml_test: PASS in ${elapsed}s (kernel rc $rc)"
cat "$work/result"
