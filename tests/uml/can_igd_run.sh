#!/bin/sh
# Run by tests/uml/init.sh inside user-mode Linux for tests/can_igd_test.sh: igd with
# [host] source = "can" on vcan0, fed by canplayer replaying $IG_WORK/host.log. igd's own
# outputs (stats CSV, recording, stderr) land in $IG_WORK for the host side to check.
echo "can_igd_run: $IG_IGD --config $IG_WORK/igd.toml"
"$IG_IGD" --config "$IG_WORK/igd.toml" >"$IG_WORK/igd.out" 2>"$IG_WORK/igd.err" &
pid=$!
# igd's CAN socket is bound once its id filters show up in the kernel's filter list; its frame
# loop starts right after it prints "igd: <w>x<h> at <rate> Hz" (the terrain build before that
# takes seconds inside UML). Send only then, so that the frames see the sets.
i=0
until grep -q 'vcan0.*raw' /proc/net/can/rcvlist_fil 2>/dev/null && grep -q '^igd: .* at .* Hz' "$IG_WORK/igd.err"; do
  if ! kill -0 $pid 2>/dev/null; then echo "can_igd_run: igd exited before its frame loop started"; break; fi
  i=$((i + 1))
  if [ $i -ge 6000 ]; then echo "can_igd_run: igd did not start its frame loop on vcan0 within 60 s"; break; fi
  sleep 0.01
done
grep -q 'vcan0.*raw' /proc/net/can/rcvlist_fil && echo "can_igd_run: igd's CAN filters:" && grep 'vcan0' /proc/net/can/rcvlist_fil /proc/net/can/rcvlist_err
t0=$(date +%s.%N)
canplayer -I "$IG_WORK/host.log"
echo "can_igd_run: canplayer exited with $? ($(date +%s.%N) - $t0 s)"
wait $pid
rc=$?
echo "can_igd_run: igd exited with $rc"
cat "$IG_WORK/igd.err"
printf 'DONE\nigd_rc=%d\n' $rc >"$IG_WORK/result"
