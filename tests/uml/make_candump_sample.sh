#!/usr/bin/env bash
# Regenerates tests/uml/candump_sample.log: a log written by the real candump inside user-mode
# Linux (see sample_run.sh), read by can_map_test's RealCandumpLogFromUserModeLinux.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d /tmp/can_sample.XXXXXX)
trap 'rm -rf "$work"' EXIT
"$here/boot.sh" "$work" "$here/sample_run.sh" || true
if [ "$(head -n1 "$work/result" 2>/dev/null)" != PASS ]; then
  cat "$work/console.log" "$work/result" 2>/dev/null
  echo "make_candump_sample.sh: FAILED" >&2
  exit 1
fi
cp "$work/candump.log" "$here/candump_sample.log"
cat "$here/candump_sample.log"
