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

import json
import math
import random
import sys
import time

import adsb_fleet
from adsb_fleet import FT, KT

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


class Aircraft(adsb_fleet.Aircraft):
    def __init__(self, rng, index, origin, t0):
        super().__init__(rng, index, origin, t0)
        self.sent_id = False
        self.next_kind = 3

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
    p = adsb_fleet.arguments(__doc__, aircraft=300, rate=500.0, unit="lines")
    p.add_argument("--malformed-every", type=int, default=97, help="one broken line every N lines")
    a = p.parse_args()
    rng = random.Random(a.seed)
    srv, conn = adsb_fleet.accept_one(a.accept_timeout)
    start = time.time()
    fleet = [Aircraft(rng, i, adsb_fleet.origin(a), start) for i in range(a.aircraft)]
    sent = malformed = k = 0
    for n in adsb_fleet.paced(start, a.rate, int(a.rate * a.duration)):
        out = []
        for _ in range(n):
            if a.malformed_every and (sent + 1) % a.malformed_every == 0:
                out.append(MALFORMED[malformed % len(MALFORMED)])
                malformed += 1
            else:
                out.append(fleet[k % len(fleet)].line(time.time()))
                k += 1
            sent += 1
        conn.sendall(("\r\n".join(out) + "\r\n").encode("latin-1"))
    report = {
        "sent": sent,
        "malformed": malformed,
        "elapsed_s": time.time() - start,
        "aircraft": adsb_fleet.fleet_report(fleet),
    }
    print(json.dumps(report), flush=True)
    conn.close()
    srv.close()


if __name__ == "__main__":
    sys.exit(main())
