#!/bin/sh
# Run by tests/uml/init.sh inside user-mode Linux once vcan0 is up: the SocketCAN probe
# (tests/can_uml_probe.cpp) against the real kernel stack. IG_PROBE and IG_SRC come from the
# kernel command line (tests/can_uml_test.sh).
echo "can_run: $IG_PROBE $IG_SRC $IG_WORK"
exec timeout 60 "$IG_PROBE" "$IG_SRC" "$IG_WORK"
