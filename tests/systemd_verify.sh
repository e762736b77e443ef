#!/usr/bin/env bash
# Verifies systemd/igd.service with `systemd-analyze verify`, the way systemd itself would load it.
#
# Usage: systemd_verify.sh <path to the built igd>
#
# The unit is copied into a temporary folder and its ExecStart binary (/usr/local/bin/igd, where
# scripts/install-service puts it) is pointed at the built igd, so that verify can check that the
# command exists and is executable. The test FAILS on a non-zero exit status or on ANY output
# (stdout or stderr): systemd prints a warning and carries on for unknown keys, bad values and
# the like, so "exit 0" alone proves little. To show that this check can fail at all, deliberately
# broken copies must make verify complain. Also checks the settings the service relies on
# (Type=notify, WatchdogSec=, Restart=on-failure).
set -u

fail() {
  echo "systemd_verify: FAIL: $*" >&2
  exit 1
}

[ $# -eq 1 ] || fail "usage: $0 <path to igd>"
igd=$1
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
unit_src="$here/../systemd/igd.service"
installed_bin=/usr/local/bin/igd

[ -f "$unit_src" ] || fail "unit file not found: $unit_src"
[ -x "$igd" ] || fail "igd binary not found or not executable: $igd"
command -v systemd-analyze >/dev/null 2>&1 || fail "systemd-analyze not found (install the systemd package)"
case "$igd" in
  /*) ;;
  *) igd="$(pwd)/$igd" ;;
esac
case "$igd" in
  *[[:space:]\#\&\\]*) fail "igd path contains characters this script does not handle: $igd" ;;
esac

tmp=$(mktemp -d "${TMPDIR:-/tmp}/igd-systemd-verify.XXXXXX") || fail "mktemp failed"
trap 'rm -rf "$tmp"' EXIT

# --- the settings igd's systemd integration relies on -------------------------------------------
grep -Eq '^Type=notify[[:space:]]*$' "$unit_src" || fail "$unit_src: expected Type=notify (igd sends READY=1)"
grep -Eq '^WatchdogSec=[0-9]+[a-z]*[[:space:]]*$' "$unit_src" \
  || fail "$unit_src: expected WatchdogSec=<time> (igd pings WATCHDOG=1 from its frame loop)"
grep -Eq '^Restart=on-failure[[:space:]]*$' "$unit_src" || fail "$unit_src: expected Restart=on-failure"
grep -Eq '^RestartPreventExitStatus=2[[:space:]]*$' "$unit_src" \
  || fail "$unit_src: expected RestartPreventExitStatus=2 (exit code 2 = bad config: a restart cannot fix it)"
n=$(grep -c "^ExecStart=$installed_bin " "$unit_src")
[ "$n" -eq 1 ] || fail "$unit_src: expected exactly one ExecStart=$installed_bin ..., found $n"

# --- the real unit, pointed at the built binary ---------------------------------------------------
unit="$tmp/igd.service"
sed "s#^ExecStart=$installed_bin #ExecStart=$igd #" "$unit_src" >"$unit" || fail "sed failed"
grep -q "^ExecStart=$igd " "$unit" || fail "rewriting ExecStart to $igd failed"
! grep -q "$installed_bin" "$unit" || fail "copy still names $installed_bin"

# verify_unit FILE: runs systemd-analyze verify; sets $out (stdout+stderr) and $rc.
verify_unit() {
  out=$(SYSTEMD_PAGER=cat SYSTEMD_COLORS=0 systemd-analyze verify "$1" 2>&1)
  rc=$?
}

verify_unit "$unit"
if [ "$rc" -ne 0 ] || [ -n "$out" ]; then
  echo "systemd-analyze verify igd.service (exit status $rc) said:" >&2
  printf '%s\n' "$out" >&2
  fail "systemd/igd.service does not verify cleanly (any output counts as a failure)"
fi
echo "systemd_verify: igd.service verifies cleanly (ExecStart=$igd)"

# --- the template unit of a cabin's display channels (scripts/channel-unit), as instance "left" ----
template=$(bash "$here/../scripts/channel-unit") || fail "scripts/channel-unit failed"
channel="$tmp/igd@left.service"
printf '%s\n' "$template" | sed "s#^ExecStart=$installed_bin #ExecStart=$igd #" >"$channel" || fail "sed failed"
# Each channel has its own config, stats, snapshots, status file and state/log/runtime folders.
for want in "--config /etc/igd/%i.toml " "--stats /var/log/igd/%i/frame_stats.csv " \
            "--snapshot-dir /var/lib/igd/%i/snapshots " "--status-file /run/igd/%i/status.json" \
            "WorkingDirectory=/var/lib/igd/%i" "StateDirectory=igd/%i" "LogsDirectory=igd/%i" "RuntimeDirectory=igd/%i"; do
  grep -qF -- "$want" "$channel" || fail "scripts/channel-unit: the template lacks '$want'"
done
verify_unit "$channel"
if [ "$rc" -ne 0 ] || [ -n "$out" ]; then
  echo "systemd-analyze verify igd@left.service (exit status $rc) said:" >&2
  printf '%s\n' "$out" >&2
  fail "the channel template from scripts/channel-unit does not verify cleanly"
fi
echo "systemd_verify: igd@left.service (scripts/channel-unit) verifies cleanly"

# --- the check must be able to fail ----------------------------------------------------------------
# broken_copy NAME WHAT EXPECT SED-SCRIPT: a copy of the verified unit edited by SED-SCRIPT must make
# verify complain (output or non-zero exit), and the complaint must mention EXPECT.
broken_copy() {
  local name=$1 what=$2 expect=$3 script=$4
  local f="$tmp/$name.service"
  sed "$script" "$unit" >"$f" || fail "sed failed for $name"
  cmp -s "$unit" "$f" && fail "self-test '$what': the edit did not change the unit"
  verify_unit "$f"
  if [ "$rc" -eq 0 ] && [ -z "$out" ]; then
    fail "self-test '$what': systemd-analyze verify accepted a broken unit silently, so this test cannot detect problems"
  fi
  printf '%s\n' "$out" | grep -qi -- "$expect" \
    || fail "self-test '$what': verify complained (exit $rc) but not about '$expect': $out"
  echo "systemd_verify: self-test '$what' rejected as expected: $(printf '%s' "$out" | head -n 1)"
}

broken_copy igd-unknown-key "unknown key Bogus=1 in [Service]" "Bogus" 's/^\[Service\]$/[Service]\nBogus=1/'
broken_copy igd-bad-type "Type=bogus" "service type" 's/^Type=notify$/Type=bogus/'

echo "systemd_verify: PASS"
exit 0
