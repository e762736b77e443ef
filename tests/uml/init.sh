#!/bin/sh
# PID 1 inside user-mode Linux for the SocketCAN tests (tests/uml/boot.sh boots it with the
# host's / as a hostfs root). The kernel command line puts IG_WORK (a host folder, seen at the
# same path through hostfs) and IG_RUN (the script to run once vcan0 is up) into our
# environment. Loads can-dev, vcan, can, can-raw from Debian's UML modules with
# tests/uml/insmod.py (the host has no kmod), creates vcan0, runs IG_RUN, and powers off. Any
# failure writes "FAIL" and the reason to $IG_WORK/result. Everything printed here goes to the
# UML console, which boot.sh keeps as $IG_WORK/console.log.
export PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin
export HOME=/root LC_ALL=C
# boot.sh on a CPU with AVX-512: UML switches only the FPU state it knows (up to AVX) between the
# threads of a process, so glibc must not keep string data in the AVX-512 registers.
[ "${IG_NO_AVX512:-}" = 1 ] && export GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX512F,-AVX512VL,-AVX512BW,-AVX512DQ,-AVX512CD
here=$(dirname "$0")

off() {
  sync
  echo o > /proc/sysrq-trigger  # power off now (asynchronous: PID 1 must not exit before)
  while :; do sleep 1; done
}
fail() {
  echo "uml-init: FAIL: $*"
  printf 'FAIL\ninit: %s\n' "$*" > "$IG_WORK/result"
  off
}

echo "uml-init: kernel $(uname -r), IG_WORK=$IG_WORK IG_RUN=$IG_RUN"
[ -n "$IG_WORK" ] && [ -d "$IG_WORK" ] || { echo "uml-init: no IG_WORK folder"; off; }
mount -t proc proc /proc || fail "mount /proc"
mount -t sysfs sysfs /sys || fail "mount /sys"
mount -t tmpfs tmpfs /run 2>/dev/null

mods=/usr/lib/uml/modules/$(uname -r)/kernel
[ -d "$mods" ] || fail "no UML modules for kernel $(uname -r) in /usr/lib/uml/modules ($(ls /usr/lib/uml/modules 2>&1))"
/usr/bin/python3 "$here/insmod.py" "$mods/drivers/net/can/dev/can-dev.ko" "$mods/drivers/net/can/vcan.ko" \
  "$mods/net/can/can.ko" "$mods/net/can/can-raw.ko" || fail "loading the CAN modules (see above)"
ip link set lo up
ip link add dev vcan0 type vcan || fail "ip link add dev vcan0 type vcan"
ip link set up vcan0 || fail "ip link set up vcan0"
ip -details link show vcan0

cd "$IG_WORK" || fail "cd $IG_WORK"
"$IG_RUN"
rc=$?
echo "uml-init: $IG_RUN exited with $rc"
[ -s "$IG_WORK/result" ] || fail "$IG_RUN exited with $rc and wrote no result"
off
