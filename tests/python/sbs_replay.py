#!/usr/bin/env python3
"""An ADS-B receiver's BaseStation (SBS-1, port 30003) output, as dump1090 writes it, for
harrier's ADS-B feed: N aircraft in straight flight around an origin, replayed at real time and
a fixed line rate over TCP to the one client that connects, with malformed lines mixed in.

Prints one JSON line `{"ready": PORT}` once it listens (port 0: the OS picks), and, after the
replay, one JSON line with what it sent: the line counts and, per aircraft (hex address), its
callsign, its last position report (lat, lon, altitude in m, UNIX time sent) and its velocity
(east, north, up in m/s in its own ENU axes). Then closes the connection and exits.

    python3 sbs_replay.py --aircraft 300 --rate 500 --duration 15 --origin 47.397742,8.545594
"""

import argparse
import json
import math
import random
import socket
import sys
import time

FT = 0.3048
KT = 1852.0 / 3600.0
EARTH_R = 6_371_000.0

# Broken lines of the kinds a real feed shows (cut short, garbage, a bad address, a NaN).
MALFORMED = [
    "MSG,3,1,1,4CA2",
    "\x00\x01garbage",
    "MSG,3,1,1,ZZZZZZ,1,,,,,,37000,,,51.0,-1.0,,,0,0,0,0",
    "MSG,3,1,1,4CA2D6,1,,,,,,NaN,,,51.0,-1.0,,,0,0,0,0",
    "MSG,4,1,1,4CA2D6,1,,,,,,,abc,90,,,0,,,,,0",
]


def sbs(kind, hexid, callsign="", alt="", gs="", track="", lat="", lon="", vr="", squawk="", gnd="0"):
    now = time.gmtime()
    stamp_d = time.strftime("%Y/%m/%d", now)
    stamp_t = time.strftime("%H:%M:%S.000", now)
    return ",".join(
        str(f)
        for f in [
            "MSG", kind, 1, 1, hexid, 1, stamp_d, stamp_t, stamp_d, stamp_t, callsign, alt, gs,
            track, lat, lon, vr, squawk, 0, 0, 0, gnd,
        ]
    )


class Aircraft:
    def __init__(self, rng, index, origin, t0):
        self.hex = f"{0x400000 + index * 37:06X}"
        self.callsign = f"HRR{index:04d}"
        lat0, lon0 = origin
        r = rng.uniform(2_000.0, 100_000.0)
        b = rng.uniform(0.0, 2 * math.pi)
        self.lat = lat0 + math.degrees(r * math.cos(b) / EARTH_R)
        self.lon = lon0 + math.degrees(r * math.sin(b) / (EARTH_R * math.cos(math.radians(lat0))))
        self.alt = rng.uniform(300.0, 12_000.0)
        speed = rng.uniform(50.0, 250.0)
        self.course = rng.uniform(0.0, 360.0)
        self.ve = speed * math.sin(math.radians(self.course))
        self.vn = speed * math.cos(math.radians(self.course))
        self.vu = rng.choice([0.0, 0.0, rng.uniform(-10.0, 10.0)])
        self.t = t0
        self.sent_id = False
        self.next_kind = 3
        self.last = None

    def advance(self, t):
        dt = t - self.t
        self.lat += math.degrees(self.vn * dt / EARTH_R)
        self.lon += math.degrees(self.ve * dt / (EARTH_R * math.cos(math.radians(self.lat))))
        self.alt += self.vu * dt
        self.t = t

    def line(self, t):
        self.advance(t)
        if not self.sent_id:
            self.sent_id = True
            return sbs(1, self.hex, callsign=self.callsign)
        kind, self.next_kind = self.next_kind, 7 - self.next_kind  # 3, 4, 3, 4 ...
        if kind == 3:
            alt_ft = round(self.alt / FT / 25.0) * 25
            lat, lon = round(self.lat, 5), round(self.lon, 5)
            self.last = {"lat": lat, "lon": lon, "alt_m": alt_ft * FT, "t": t}
            return sbs(3, self.hex, alt=alt_ft, lat=f"{lat:.5f}", lon=f"{lon:.5f}")
        gs = math.hypot(self.ve, self.vn) / KT
        return sbs(
            4, self.hex, gs=f"{gs:.0f}", track=f"{self.course:.0f}", vr=f"{self.vu / FT * 60.0:.0f}"
        )


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--aircraft", type=int, default=300)
    p.add_argument("--rate", type=float, default=500.0, help="lines per second")
    p.add_argument("--duration", type=float, default=15.0, help="seconds of replay")
    p.add_argument("--malformed-every", type=int, default=97, help="one broken line every N lines")
    p.add_argument("--origin", default="47.397742,8.545594", help="lat,lon the aircraft fly around")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--accept-timeout", type=float, default=30.0)
    a = p.parse_args()
    rng = random.Random(a.seed)
    origin = tuple(float(v) for v in a.origin.split(","))

    srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)
    srv.settimeout(a.accept_timeout)
    print(json.dumps({"ready": srv.getsockname()[1]}), flush=True)
    conn, _ = srv.accept()
    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    start = time.time()
    fleet = [Aircraft(rng, i, origin, start) for i in range(a.aircraft)]
    total = int(a.rate * a.duration)
    sent = malformed = 0
    batch = max(1, int(a.rate / 100))  # every 10 ms
    k = 0
    while sent < total:
        due = start + sent / a.rate
        pause = due - time.time()
        if pause > 0:
            time.sleep(pause)
        out = []
        for _ in range(min(batch, total - sent)):
            if a.malformed_every and (sent + 1) % a.malformed_every == 0:
                out.append(MALFORMED[malformed % len(MALFORMED)])
                malformed += 1
            else:
                out.append(fleet[k % len(fleet)].line(time.time()))
                k += 1
            sent += 1
        conn.sendall(("\r\n".join(out) + "\r\n").encode("latin-1"))
    elapsed = time.time() - start
    report = {
        "sent": sent,
        "malformed": malformed,
        "elapsed_s": elapsed,
        "aircraft": {
            ac.hex: {**ac.last, "callsign": ac.callsign, "ve": ac.ve, "vn": ac.vn, "vu": ac.vu}
            for ac in fleet
            if ac.last is not None
        },
    }
    print(json.dumps(report), flush=True)
    conn.close()
    srv.close()


if __name__ == "__main__":
    sys.exit(main())
