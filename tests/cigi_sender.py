#!/usr/bin/python3
"""An independent CIGI 3.3 host encoder (and Start of Frame decoder), written from the layouts
of SISO-STD-013-2014 (CIGI ICD 3.3), not from igd's C++: each packet is one struct.pack format
string with the byte offsets spelled out.

Used by tests/cigi_interop_test.py (against igd's decoder and Debian's tshark) and as a small
CIGI host for end-to-end runs:

    tests/cigi_sender.py --port 8004 --rate 30 --seconds 5 [--little-endian] [--lat .. --lon ..]

sends IG Control + Entity Control + Celestial Sphere Control (+ Atmosphere Control with
--visibility M: igd's fog) at `rate` messages per second, flying north-east from the given
point, and prints the Start of Frame packets it receives back (when --listen-port is given).
"""
import argparse
import math
import socket
import struct
import sys
import time

MAGIC = 0x8000

# Packet ids and sizes (ICD 3.3, section 4.1).
IG_CONTROL, ENTITY_CONTROL, CELESTIAL, VIEW_CONTROL, VIEW_DEFINITION, START_OF_FRAME = 1, 2, 9, 16, 21, 101
ATMOSPHERE = 10
HAT_HOT_REQUEST, HAT_HOT_RESPONSE, HAT_HOT_EXT_RESPONSE = 24, 102, 103
LOS_SEGMENT_REQUEST, LOS_VECTOR_REQUEST, LOS_RESPONSE, LOS_EXT_RESPONSE = 25, 26, 104, 105


def ig_control(order, host_frame, timestamp_ticks=0, timestamp_valid=True, database=0, ig_mode=1,
               last_ig_frame=0, minor_version=3):
    """IG Control, 24 bytes:
    0 id | 1 size | 2 major version | 3 database number (int8)
    4 ig mode (bits 0-1), timestamp valid (bit 2), extrapolation (bit 3), minor version (bits 4-7)
    5 reserved | 6-7 byte swap magic | 8-11 host frame | 12-15 timestamp | 16-19 last IG frame | 20-23 reserved"""
    flags = (ig_mode & 3) | (4 if timestamp_valid else 0) | ((minor_version & 15) << 4)
    return struct.pack(order + "BBBbBBHIIII", IG_CONTROL, 24, 3, database, flags, 0, MAGIC,
                       host_frame & 0xffffffff, timestamp_ticks & 0xffffffff, last_ig_frame, 0)


def entity_control(order, entity_id, roll, pitch, yaw, lat, lon, alt, entity_type=0, state=1):
    """Entity Control, 48 bytes:
    0 id | 1 size | 2-3 entity id | 4 state (0-1), attach (2), collision (3), inherit alpha (4), clamp (5-6)
    5 animation flags | 6 alpha | 7 reserved | 8-9 entity type | 10-11 parent id
    12-15 roll f32 | 16-19 pitch f32 | 20-23 yaw f32 | 24-31 lat f64 | 32-39 lon f64 | 40-47 alt f64"""
    return struct.pack(order + "BBHBBBBHHfffddd", ENTITY_CONTROL, 48, entity_id, state & 3, 0, 255, 0,
                       entity_type, 0, roll, pitch, yaw, lat, lon, alt)


def view_control(order, view_id, entity_id, x, y, z, roll, pitch, yaw, enable=0x3f, group=0):
    """View Control, 32 bytes:
    0 id | 1 size | 2-3 view id | 4 group id | 5 enables x,y,z,roll,pitch,yaw (bits 0-5)
    6-7 entity id | 8-11 x | 12-15 y | 16-19 z (m, f32) | 20-23 roll | 24-27 pitch | 28-31 yaw (deg, f32)"""
    return struct.pack(order + "BBHBBHffffff", VIEW_CONTROL, 32, view_id, group, enable & 0x3f, entity_id,
                       x, y, z, roll, pitch, yaw)


def view_definition(order, view_id, near, far, left, right, top, bottom, enable=0x3f, group=0):
    """View Definition, 32 bytes:
    0 id | 1 size | 2-3 view id | 4 group id | 5 enables near,far,left,right,top,bottom (bits 0-5), mirror (6-7)
    6 pixel replication (0-2), projection (3), reorder (4), view type (5-7) | 7 reserved
    8-11 near | 12-15 far (m) | 16-19 left | 20-23 right | 24-27 top | 28-31 bottom (deg)"""
    return struct.pack(order + "BBHBBBBffffff", VIEW_DEFINITION, 32, view_id, group, enable & 0x3f, 0, 0,
                       near, far, left, right, top, bottom)


def celestial(order, hour, minute, month, day, year, valid=True, star_intensity=0.0):
    """Celestial Sphere Control, 16 bytes:
    0 id | 1 size | 2 hour | 3 minute | 4 ephemeris (0), sun (1), moon (2), stars (3), date/time valid (4)
    5-7 reserved | 8-11 date MMDDYYYY (u32) | 12-15 star field intensity (%, f32)"""
    flags = 0x02 | (0x10 if valid else 0)
    date = month * 1000000 + day * 10000 + year
    return struct.pack(order + "BBBBBBBBIf", CELESTIAL, 16, hour, minute, flags, 0, 0, 0, date, star_intensity)


def atmosphere(order, visibility, humidity=40, temperature=12.5, wind=(3.0, -0.5, 270.0), pressure=1009.0):
    """Atmosphere Control, 32 bytes (ICD 3.3, 4.1.10):
    0 id | 1 size | 2 atmospheric model enable (bit 0) | 3 global humidity (%, u8)
    4-7 air temperature (deg C) | 8-11 visibility range (m) | 12-15 horizontal wind (m/s)
    16-19 vertical wind (m/s) | 20-23 wind direction (deg) | 24-27 barometric pressure (hPa) | 28-31 reserved"""
    return struct.pack(order + "BBBBffffffI", ATMOSPHERE, 32, 0, humidity, temperature, visibility,
                       wind[0], wind[1], wind[2], pressure, 0)


def hat_hot_request(order, hat_hot_id, request_type, lat_x, lon_y, alt_z, update_period=0, entity=False,
                    entity_id=0):
    """HAT/HOT Request, 32 bytes (ICD 3.3, 4.1.24):
    0 id | 1 size | 2-3 HAT/HOT ID | 4 request type (0-1: 0 HAT, 1 HOT, 2 extended), coordinate system (2: 1 entity)
    5 update period (frames, 0 = once) | 6-7 entity id
    8-15 latitude / x offset f64 | 16-23 longitude / y offset f64 | 24-31 altitude / z offset f64"""
    flags = (request_type & 3) | (4 if entity else 0)
    return struct.pack(order + "BBHBBHddd", HAT_HOT_REQUEST, 32, hat_hot_id, flags, update_period, entity_id,
                       lat_x, lon_y, alt_z)


def decode_hat_hot_responses(data):
    """The HAT/HOT responses after an IG message's Start of Frame (in its byte order):
    HAT/HOT Response, 16 bytes (ICD 3.3, 4.2.2): 0 id | 1 size | 2-3 HAT/HOT ID
      4 valid (0), response type (1: 0 HAT, 1 HOT), host frame LSN (4-7) | 5-7 reserved | 8-15 height f64
    HAT/HOT Extended Response, 40 bytes (4.2.3): 0 id | 1 size | 2-3 HAT/HOT ID
      4 valid (0), host frame LSN (4-7) | 5-7 reserved | 8-15 HAT f64 | 16-23 HOT f64 | 24-27 material code u32
      28-31 normal azimuth f32 | 32-35 normal elevation f32 | 36-39 reserved"""
    order = decode_start_of_frame(data)["order"]
    out = []
    at = 24
    while at + 2 <= len(data):
        pid, size = data[at], data[at + 1]
        if pid == HAT_HOT_RESPONSE and size == 16:
            _, _, hid, flags, height = struct.unpack(order + "BBHB3xd", data[at:at + 16])
            out.append({"ext": False, "id": hid, "valid": flags & 1, "hot": (flags >> 1) & 1, "lsn": flags >> 4,
                        "height": height})
        elif pid == HAT_HOT_EXT_RESPONSE and size == 40:
            _, _, hid, flags, hat, hot, material, az, el = struct.unpack(order + "BBHB3xddIff4x", data[at:at + 40])
            out.append({"ext": True, "id": hid, "valid": flags & 1, "lsn": flags >> 4, "hat": hat, "hot": hot,
                        "material": material, "azimuth": az, "elevation": el})
        at += max(size, 2)
    return out


def los_segment_request(order, los_id, src, dst, extended=False, update_period=0, src_entity=False,
                        dst_entity=False, response_entity=False, entity_id=0, alpha=0, material_mask=0,
                        dst_entity_id=None):
    """LOS Segment Request, 64 bytes (ICD 3.3, 4.1.25):
    0 id | 1 size | 2-3 LOS ID | 4 request type (0: 1 extended), source coordinate system (1: 1 entity),
      destination coordinate system (2), response coordinate system (3), destination entity ID valid (4)
    5 alpha threshold | 6-7 entity id | 8-15, 16-23, 24-31 source lat / lon / alt (or x / y / z) f64
    32-39, 40-47, 48-55 destination lat / lon / alt (or x / y / z) f64 | 56-59 material mask u32
    60 update period | 61 reserved | 62-63 destination entity id"""
    flags = ((1 if extended else 0) | (2 if src_entity else 0) | (4 if dst_entity else 0) |
             (8 if response_entity else 0) | (16 if dst_entity_id is not None else 0))
    return struct.pack(order + "BBHBBHddddddIBxH", LOS_SEGMENT_REQUEST, 64, los_id, flags, alpha, entity_id,
                       src[0], src[1], src[2], dst[0], dst[1], dst[2], material_mask, update_period,
                       dst_entity_id or 0)


def los_vector_request(order, los_id, src, azimuth, elevation, min_range, max_range, extended=False,
                       update_period=0, src_entity=False, response_entity=False, entity_id=0, alpha=0,
                       material_mask=0):
    """LOS Vector Request, 56 bytes (ICD 3.3, 4.1.26):
    0 id | 1 size | 2-3 LOS ID | 4 request type (0: 1 extended), source coordinate system (1: 1 entity),
      response coordinate system (2) | 5 alpha threshold | 6-7 entity id
    8-11 azimuth f32 | 12-15 elevation f32 | 16-19 minimum range f32 | 20-23 maximum range f32
    24-31, 32-39, 40-47 source lat / lon / alt (or x / y / z) f64 | 48-51 material mask u32
    52 update period | 53-55 reserved"""
    flags = (1 if extended else 0) | (2 if src_entity else 0) | (4 if response_entity else 0)
    return struct.pack(order + "BBHBBHffffdddIB3x", LOS_VECTOR_REQUEST, 56, los_id, flags, alpha, entity_id,
                       azimuth, elevation, min_range, max_range, src[0], src[1], src[2], material_mask,
                       update_period)


def decode_los_responses(data):
    """The LOS responses after an IG message's Start of Frame (in its byte order):
    LOS Response, 16 bytes (ICD 3.3, 4.2.4): 0 id | 1 size | 2-3 LOS ID
      4 valid (0), entity ID valid (1), visible (2), host frame LSN (4-7) | 5 response count | 6-7 entity id
      8-15 range f64
    LOS Extended Response, 56 bytes (4.2.5): 0 id | 1 size | 2-3 LOS ID
      4 valid (0), entity ID valid (1), range valid (2), visible (3), host frame LSN (4-7)
      5 response count | 6-7 entity id | 8-15 range f64 | 16-23, 24-31, 32-39 lat / lon / alt (or x / y / z) f64
      40-43 red, green, blue, alpha | 44-47 material code u32 | 48-51 normal azimuth f32
      52-55 normal elevation f32"""
    order = decode_start_of_frame(data)["order"]
    out = []
    at = 24
    while at + 2 <= len(data):
        pid, size = data[at], data[at + 1]
        if pid == LOS_RESPONSE and size == 16:
            _, _, lid, flags, count, entity, rng = struct.unpack(order + "BBHBBHd", data[at:at + 16])
            out.append({"ext": False, "id": lid, "valid": flags & 1, "entity_valid": (flags >> 1) & 1,
                        "visible": (flags >> 2) & 1, "lsn": flags >> 4, "count": count, "entity": entity,
                        "range": rng})
        elif pid == LOS_EXT_RESPONSE and size == 56:
            (_, _, lid, flags, count, entity, rng, lat, lon, alt, red, green, blue, alpha, material, az,
             el) = struct.unpack(order + "BBHBBHddddBBBBIff", data[at:at + 56])
            out.append({"ext": True, "id": lid, "valid": flags & 1, "entity_valid": (flags >> 1) & 1,
                        "range_valid": (flags >> 2) & 1, "visible": (flags >> 3) & 1, "lsn": flags >> 4,
                        "count": count, "entity": entity, "range": rng, "lat": lat, "lon": lon, "alt": alt,
                        "rgba": (red, green, blue, alpha), "material": material, "azimuth": az, "elevation": el})
        at += max(size, 2)
    return out


def unknown_packet(packet_id, size):
    return struct.pack("BB", packet_id, size) + bytes(range(size - 2))


def decode_start_of_frame(data):
    """Start of Frame, 24 bytes (ICD 3.3, 4.2.1):
    0 id | 1 size | 2 major version | 3 database number (int8) | 4 IG status
    5 IG mode (0-1), timestamp valid (2), earth reference model (3), minor version (4-7)
    6-7 magic | 8-11 IG frame | 12-15 timestamp | 16-19 last host frame | 20-23 reserved
    The magic, read big-endian, is 0x8000 for a big-endian sender and 0x0080 for a little-endian one."""
    if len(data) < 24 or data[0] != START_OF_FRAME or data[1] != 24:
        raise ValueError("not a Start of Frame: %r" % data[:4])
    magic_be = struct.unpack(">H", data[6:8])[0]
    order = ">" if magic_be == 0x8000 else "<" if magic_be == 0x0080 else None
    if order is None:
        raise ValueError("bad magic 0x%04x" % magic_be)
    _, _, major, database, status, flags, _, ig_frame, ts, last_host, _ = struct.unpack(order + "BBBbBBHIIII", data[:24])
    return {"order": order, "major": major, "minor": flags >> 4, "database": database, "status": status,
            "mode": flags & 3, "timestamp_valid": bool(flags & 4), "earth_model": (flags >> 3) & 1,
            "ig_frame": ig_frame, "timestamp": ts, "last_host_frame": last_host}


# ---- WGS-84 and the CIGI attitude convention, written independently of igd's C++ -------------
A = 6378137.0
F = 1 / 298.257223563
E2 = F * (2 - F)


def geodetic_to_ecef(lat, lon, h):
    la, lo = math.radians(lat), math.radians(lon)
    n = A / math.sqrt(1 - E2 * math.sin(la) ** 2)
    return ((n + h) * math.cos(la) * math.cos(lo), (n + h) * math.cos(la) * math.sin(lo),
            (n * (1 - E2) + h) * math.sin(la))


def ned_axes(lat, lon):
    la, lo = math.radians(lat), math.radians(lon)
    north = (-math.sin(la) * math.cos(lo), -math.sin(la) * math.sin(lo), math.cos(la))
    east = (-math.sin(lo), math.cos(lo), 0.0)
    down = (-math.cos(la) * math.cos(lo), -math.cos(la) * math.sin(lo), -math.sin(la))
    return north, east, down


def body_axes_ned(yaw, pitch, roll):
    """Forward, right, down body axes in NED for heading yaw (clockwise from north), then pitch
    (nose up), then roll (right side down)."""
    y, p, r = math.radians(yaw), math.radians(pitch), math.radians(roll)
    cy, sy, cp, sp, cr, sr = math.cos(y), math.sin(y), math.cos(p), math.sin(p), math.cos(r), math.sin(r)
    fwd = (cy * cp, sy * cp, -sp)
    right = (cy * sp * sr - sy * cr, sy * sp * sr + cy * cr, cp * sr)
    down = (cy * sp * cr + sy * sr, sy * sp * cr - cy * sr, cp * cr)
    return fwd, right, down


def combine(basis, v):
    return tuple(sum(basis[i][k] * v[i] for i in range(3)) for k in range(3))


def enu_of_geodetic(origin, lat, lon, h):
    """(east, north, up) of a geodetic point in the ENU frame at `origin` (lat, lon, h)."""
    p, o = geodetic_to_ecef(lat, lon, h), geodetic_to_ecef(*origin)
    n, e, d = ned_axes(origin[0], origin[1])
    r = [p[k] - o[k] for k in range(3)]
    return (sum(r[k] * e[k] for k in range(3)), sum(r[k] * n[k] for k in range(3)), -sum(r[k] * d[k] for k in range(3)))


def geodetic_of_enu(origin, east, north, up):
    """(lat, lon, h) of an ENU point of the frame at `origin` (iterative latitude, < 1e-12 deg)."""
    o = geodetic_to_ecef(*origin)
    n, e, d = ned_axes(origin[0], origin[1])
    x, y, z = (o[k] + east * e[k] + north * n[k] - up * d[k] for k in range(3))
    lon = math.atan2(y, x)
    p = math.hypot(x, y)
    lat = math.atan2(z, p * (1 - E2))
    for _ in range(10):
        nn = A / math.sqrt(1 - E2 * math.sin(lat) ** 2)
        h = p / math.cos(lat) - nn
        lat = math.atan2(z, p * (1 - E2 * nn / (nn + h)))
    nn = A / math.sqrt(1 - E2 * math.sin(lat) ** 2)
    return math.degrees(lat), math.degrees(lon), p / math.cos(lat) - nn


def expected_eye(origin, lat, lon, alt, yaw, pitch, roll, offset=(0, 0, 0), view_ypr=(0, 0, 0)):
    """Eye in the origin's ENU frame and heading/pitch/roll relative to the ENU axes."""
    ned = ned_axes(lat, lon)
    body = [combine(ned, a) for a in body_axes_ned(yaw, pitch, roll)]  # body axes in ECEF
    view_in_body = body_axes_ned(*view_ypr)
    view = [combine(body, a) for a in view_in_body]
    p = geodetic_to_ecef(lat, lon, alt)
    off = combine(body, offset)
    eye = tuple(p[k] + off[k] for k in range(3))
    o = geodetic_to_ecef(*origin)
    on, oe, od = ned_axes(origin[0], origin[1])
    ou = tuple(-x for x in od)
    d = tuple(eye[k] - o[k] for k in range(3))
    dot = lambda a, b: sum(a[k] * b[k] for k in range(3))
    enu = (dot(d, oe), dot(d, on), dot(d, ou))
    f = (dot(view[0], oe), dot(view[0], on), dot(view[0], ou))
    r = (dot(view[1], oe), dot(view[1], on), dot(view[1], ou))
    heading = math.degrees(math.atan2(f[0], f[1])) % 360.0
    pitch_out = math.degrees(math.asin(max(-1.0, min(1.0, f[2]))))
    # Roll: the angle of the right axis below the horizontal, about the forward axis.
    h = math.radians(heading)
    right0 = (math.cos(h), -math.sin(h), 0.0)
    up0 = (right0[1] * f[2] - right0[2] * f[1], right0[2] * f[0] - right0[0] * f[2], right0[0] * f[1] - right0[1] * f[0])
    roll_out = math.degrees(math.atan2(-dot(r, up0), dot(r, right0)))
    return enu, heading, pitch_out, roll_out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--address", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=8004)
    ap.add_argument("--listen-port", type=int, default=0, help="receive Start of Frame on this port (0: none)")
    ap.add_argument("--rate", type=float, default=30.0)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--little-endian", action="store_true")
    ap.add_argument("--lat", type=float, default=57.7)
    ap.add_argument("--lon", type=float, default=11.97)
    ap.add_argument("--alt", type=float, default=600.0)
    ap.add_argument("--heading", type=float, default=45.0)
    ap.add_argument("--speed", type=float, default=50.0, help="m/s along the heading")
    ap.add_argument("--entity", type=int, default=0)
    ap.add_argument("--visibility", type=float, default=None,
                    help="send Atmosphere Control with this visibility range (m): igd's fog (default: none sent)")
    args = ap.parse_args()
    order = "<" if args.little_endian else ">"
    tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    if args.listen_port:
        tx.bind(("0.0.0.0", args.listen_port))
    tx.setblocking(False)
    n = int(args.seconds * args.rate)
    t0 = time.monotonic()
    for frame in range(n):
        t = frame / args.rate
        d = args.speed * t
        lat = args.lat + d * math.cos(math.radians(args.heading)) / 111320.0
        lon = args.lon + d * math.sin(math.radians(args.heading)) / (111320.0 * math.cos(math.radians(args.lat)))
        msg = (ig_control(order, frame, int(round(t * 1e5))) +
               entity_control(order, args.entity, 0.0, 0.0, args.heading % 360.0, lat, lon, args.alt) +
               celestial(order, 12, 0, 6, 21, 2026))
        if args.visibility is not None:
            msg += atmosphere(order, args.visibility)
        tx.sendto(msg, (args.address, args.port))
        while True:
            try:
                data = tx.recv(65536)
            except BlockingIOError:
                break
            sof = decode_start_of_frame(data)
            print("SOF ig_frame=%d last_host_frame=%d mode=%d status=%d" %
                  (sof["ig_frame"], sof["last_host_frame"], sof["mode"], sof["status"]), flush=True)
        delay = t0 + (frame + 1) / args.rate - time.monotonic()
        if delay > 0:
            time.sleep(delay)
    return 0


if __name__ == "__main__":
    sys.exit(main())
