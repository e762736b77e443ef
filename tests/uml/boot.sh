#!/usr/bin/env bash
# Boots Debian's user-mode Linux kernel with the host's / as a hostfs root and tests/uml/init.sh
# as PID 1, which sets up vcan0 and runs <run script>. Extra KEY=VALUE arguments reach the run
# script's environment through the kernel command line (no spaces in values).
#
#   tests/uml/boot.sh <work dir> <run script> [KEY=VALUE ...]
#
# The console (kernel log and everything the scripts print) goes to <work dir>/console.log.
# Exit status: the kernel's (0 after a clean power-off), 124 on timeout (IG_UML_TIMEOUT
# seconds, default 90), 127 without the kernel. The caller judges <work dir>/result.
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
work=$1 run=$2
shift 2
kernel=$(command -v linux.uml || command -v linux || true)
if [ -z "$kernel" ]; then
  echo "boot.sh: no user-mode Linux kernel (linux.uml): install Debian's user-mode-linux" >"$work/console.log"
  exit 127
fi
mkdir -p "$work/uml"
# On CPUs with AVX-512 or AMX the host's XSAVE area is larger than this UML kernel's, and its
# first FPU restore through ptrace fails: IG_UML_SHIM (tests/uml/xstate_shim.cpp, built with the
# tests) fixes the buffer sizes, and the guest's glibc leaves AVX-512 alone (init.sh).
preload=()
if grep -qwE 'avx512f|amx_tile' /proc/cpuinfo; then
  IG_UML_SHIM=${IG_UML_SHIM:-$here/../../build/tests/libuml_xstate_shim.so}  # scripts run by hand
  [ -f "$IG_UML_SHIM" ] || {
    echo "boot.sh: this CPU has AVX-512 or AMX: user-mode Linux needs IG_UML_SHIM (the uml_xstate_shim library)" >"$work/console.log"
    exit 127
  }
  preload=(env LD_PRELOAD="$IG_UML_SHIM")
  set -- "$@" IG_NO_AVX512=1
fi
# mem: the probe, can-utils and python3 fit easily. uml_dir: the mconsole socket folder, not
# ~/.uml. con0 on our stdin/stdout, every other console off.
TMPDIR=$work timeout -k 5 "${IG_UML_TIMEOUT:-90}" "${preload[@]}" "$kernel" mem=384M rootfstype=hostfs rootflags=/ rw \
  init="$here/init.sh" uml_dir="$work/uml" con=null con0=fd:0,fd:1 \
  IG_WORK="$work" IG_RUN="$run" "$@" </dev/null >"$work/console.log" 2>&1
