#!/bin/sh
# Run inside user-mode Linux by tests/uml/make_candump_sample.sh: the real candump logs what
# cansend sends: three sets of the frame map (counters 10, 11, 12; the third in reverse order),
# then a lone frame of set 13. The frames were encoded by hand (Python struct, not igd's
# encoder): lat 47.2612345 + 0.001 k deg, lon 11.3598765 deg, height 1523.456 m, heading 271.25,
# pitch -3.5, roll 12.75 deg, sim time 36000.125 + k s, host frame 1000 + k.
candump -L vcan0 >"$IG_WORK/candump.log" &
pid=$!
i=0
until grep -q 'vcan0.*raw' /proc/net/can/rcvlist_all; do
  i=$((i + 1)); [ $i -lt 500 ] || break; sleep 0.01
done
for f in 100#0AF97D2B1C000000 101#0A2D61C506000000 102#0A003F1700000000 103#0AF569A2FEFB0400 104#0A7D512502E80300 \
         100#0B09A52B1C000000 101#0B2D61C506000000 102#0B003F1700000000 103#0BF569A2FEFB0400 104#0B65552502E90300 \
         104#0C4D592502EA0300 103#0CF569A2FEFB0400 102#0C003F1700000000 101#0C2D61C506000000 100#0C19CC2B1C000000 \
         100#0D19CC2B1C000000; do
  cansend vcan0 "$f" || { printf 'FAIL\ncansend %s\n' "$f" >"$IG_WORK/result"; exit 1; }
done
kill -INT $pid
wait $pid
echo PASS >"$IG_WORK/result"
