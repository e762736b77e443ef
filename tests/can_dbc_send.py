#!/usr/bin/python3
"""Sends one set of igd's host frames, encoded from the DBC file alone (an encoder independent
of igd's C++ one), with python3-can on a SocketCAN interface. Used inside user-mode Linux by
can_uml_probe.

  can_dbc_send.py <file.dbc> <interface> <sequence counter> Signal=value ...
  can_dbc_send.py <file.dbc> --candump-log <out file> <sets>

The first form sends one set; every signal of every message in the DBC except SeqCounter must
be given a physical value. The second writes a candump log (for canplayer, interface vcan0) of
a straight climbing flight from the default scene's origin (46.5 N, 7.9 E): set k at
t = 1000 + k/30 s has latitude 46.5 + 2e-5 k deg, longitude 7.9 + 3e-5 k deg, height 1200 + k m,
heading 10 + k deg (from true north at the eye), pitch 1, roll -2 deg, sim time 100 + k/30 s, host frame 7000 + k,
fog visibility 3000 + 10 k m, time of day 10:00:00 + k s UTC, counter k mod 256 (tests/can_igd_check.py knows the same trajectory).
"""
import re
import sys

import can

BO = re.compile(r'^BO_ (\d+) (\w+): (\d+) (\w+)\s*$')
SG = re.compile(r'^ SG_ (\w+) : (\d+)\|(\d+)@([01])([+-]) \(([^,]+),([^)]+)\) \[([^|]+)\|([^\]]+)\] "([^"]*)" (\w+)\s*$')


def parse_dbc(path):
    messages = []
    with open(path, encoding='ascii') as f:
        for line in f:
            line = line.rstrip('\n')
            m = BO.match(line)
            if m:
                messages.append({'id': int(m[1]), 'name': m[2], 'dlc': int(m[3]), 'signals': []})
                continue
            m = SG.match(line)
            if m:
                if m[4] != '1':
                    raise SystemExit(f'{path}: {m[1]}: only little-endian (@1) signals are supported')
                messages[-1]['signals'].append({
                    'name': m[1], 'start': int(m[2]), 'length': int(m[3]), 'signed': m[5] == '-',
                    'factor': float(m[6]), 'offset': float(m[7])})
    return messages


def encode(message, values):
    data = 0
    for s in message['signals']:
        raw = round((values[s['name']] - s['offset']) / s['factor'])
        lo = -(1 << (s['length'] - 1)) if s['signed'] else 0
        hi = (1 << (s['length'] - 1)) - 1 if s['signed'] else (1 << s['length']) - 1
        if not lo <= raw <= hi:
            raise SystemExit(f"{message['name']}.{s['name']} = {values[s['name']]}: raw {raw} does not fit")
        data |= (raw & ((1 << s['length']) - 1)) << s['start']
    return data.to_bytes(message['dlc'], 'little')


def trajectory(k):
    return {'SeqCounter': float(k % 256), 'EyeLatitude': 46.5 + 2e-5 * k, 'EyeLongitude': 7.9 + 3e-5 * k,
            'EyeHeight': 1200.0 + k, 'Heading': 10.0 + k, 'Pitch': 1.0, 'Roll': -2.0,
            'SimTime': 100.0 + k / 30.0, 'HostFrame': float(7000 + k), 'Visibility': 3000.0 + 10.0 * k,
            'TimeOfDay': 36000.0 + k}


def write_log(messages, path, sets):
    with open(path, 'w', encoding='ascii') as f:
        for k in range(sets):
            t_us = 1000_000000 + round(k * 1e6 / 30)
            for i, m in enumerate(messages):
                ts = t_us + 100 * i
                f.write(f"({ts // 1000000}.{ts % 1000000:06d}) vcan0 {m['id']:03X}#{encode(m, trajectory(k)).hex().upper()}\n")


def main():
    if len(sys.argv) < 4:
        raise SystemExit(__doc__)
    messages = parse_dbc(sys.argv[1])
    if sys.argv[2] == '--candump-log':
        write_log(messages, sys.argv[3], int(sys.argv[4]))
        return
    values = {'SeqCounter': float(int(sys.argv[3]))}
    for arg in sys.argv[4:]:
        name, _, value = arg.partition('=')
        values[name] = float(value)
    with can.Bus(channel=sys.argv[2], interface='socketcan') as bus:
        for m in messages:
            payload = encode(m, values)
            bus.send(can.Message(arbitration_id=m['id'], is_extended_id=False, data=payload))
            print(f"sent {m['id']:03X}#{payload.hex().upper()}")


if __name__ == '__main__':
    main()
