#!/usr/bin/env python3
"""An ADS-B receiver's Beast binary output (port 30005), as dump1090 and readsb write it, for
harrier's ADS-B feed with `adsb.format = "beast"`: N aircraft in straight flight around an
origin, each sending DF17 extended squitters — identification (TC 4), airborne position (TC 11,
barometric altitude, CPR even and odd in turn) and airborne velocity (TC 19 subtype 1) — with
their 24-bit parity, in Beast frames (every 0x1a doubled), replayed at real time and a fixed frame
rate over TCP to the one client that connects. Some frames are corrupted (1 to 3 bits flipped
after the DF: the parity fails).

Every frame is checked with pyModeS, an independent decoder, as it is sent: the parity (valid, or
failed for a corrupted one), the callsign, the velocity, and the positions its streaming decoder
(PipeDecoder: global from an even/odd pair, then local) makes, against the true position.
Encoding: ICAO Doc 9871 appendix C; Junzi Sun, "The 1090 Megahertz Riddle" (CPR: chapter 5).

Prints one JSON line `{"ready": PORT}` once it listens (port 0: the OS picks), and, after the
replay, one JSON line with what it sent: the frame counts, pyModeS's checks and, per aircraft
(hex address), its callsign, its true position when its last position frame was sent (lat, lon,
altitude in m, UNIX time) and its velocity (east, north, up in m/s in its own ENU axes). Then
closes the connection and exits; exits with an error if pyModeS disagrees with a frame.

    python3 beast_replay.py --aircraft 150 --rate 1000 --duration 15 --origin 47.397742,8.545594
"""

import json
import math
import random
import sys
import time

import pyModeS

import adsb_fleet
from adsb_fleet import EARTH_R, FT, KT
CHARSET = "#ABCDEFGHIJKLMNOPQRSTUVWXYZ##### ###############0123456789######"
GENERATOR = 0xFFF409


def crc(data):
    """The Mode S 24-bit parity remainder of `data` (bytes)."""
    c = 0
    for b in data:
        c ^= b << 16
        for _ in range(8):
            c = (c << 1) ^ GENERATOR if c & 0x800000 else c << 1
        c &= 0xFFFFFF
    return c


def df17(icao, me):
    """A DF17 (CA 5) message with its parity, from the address and the 56-bit ME field."""
    body = bytes([0x8D]) + icao.to_bytes(3, "big") + me.to_bytes(7, "big")
    return body + crc(body).to_bytes(3, "big")


def nl(lat):
    """The number of longitude zones at a latitude (NZ = 15)."""
    lat = abs(lat)
    if lat < 1e-9:
        return 59
    if lat >= 87.0:
        return 2 if lat == 87.0 else 1
    a = 1.0 - math.cos(math.pi / 30.0)
    return math.floor(2.0 * math.pi / math.acos(1.0 - a / math.cos(math.radians(lat)) ** 2))


def cpr_encode(lat, lon, odd):
    """Airborne CPR: 17-bit latitude and longitude in the even (0) or odd (1) zone grid."""
    i = 1 if odd else 0
    dlat = 360.0 / (60 - i)
    yz = math.floor(2**17 * (lat % dlat) / dlat + 0.5)
    rlat = dlat * (yz / 2**17 + math.floor(lat / dlat))
    dlon = 360.0 / max(nl(rlat) - i, 1)
    xz = math.floor(2**17 * (lon % dlon) / dlon + 0.5)
    return yz % 2**17, xz % 2**17


def identification(icao, callsign):
    me = 4 << 51  # TC 4, category 0
    for k, ch in enumerate(callsign.ljust(8)[:8]):
        me |= CHARSET.index(ch) << (42 - 6 * k)
    return df17(icao, me)


def position(icao, lat, lon, alt_ft, odd):
    n = (alt_ft + 1000) // 25  # Q = 1: 25 ft steps
    alt12 = ((n & 0x7F0) << 1) | 0x10 | (n & 0xF)
    ylat, xlon = cpr_encode(lat, lon, odd)
    me = (11 << 51) | (alt12 << 36) | (int(odd) << 34) | (ylat << 17) | xlon
    return df17(icao, me)


def velocity(icao, ve, vn, vu):
    e_kt, n_kt, fpm = ve / KT, vn / KT, vu / FT * 60.0
    vew, vns = min(round(abs(e_kt)) + 1, 1023), min(round(abs(n_kt)) + 1, 1023)
    vr = min(round(abs(fpm) / 64.0) + 1, 511)
    me = (19 << 51) | (1 << 48)  # TC 19, subtype 1
    me |= (int(e_kt < 0) << 42) | (vew << 32) | (int(n_kt < 0) << 31) | (vns << 21)
    me |= (int(fpm < 0) << 19) | (vr << 10)
    return df17(icao, me)


def beast(timestamp, signal, msg):
    """A Beast Mode S long frame: 0x1a '3', the 6-byte 12 MHz time stamp, the signal level and the
    message, every 0x1a of them doubled."""
    body = (timestamp % 2**48).to_bytes(6, "big") + bytes([signal]) + msg
    return b"\x1a3" + body.replace(b"\x1a", b"\x1a\x1a")


def metres(lat1, lon1, lat2, lon2):
    dn = math.radians(lat2 - lat1) * EARTH_R
    de = math.radians(lon2 - lon1) * EARTH_R * math.cos(math.radians(lat1))
    return math.hypot(dn, de)


class Aircraft(adsb_fleet.Aircraft):
    def __init__(self, rng, index, origin, t0):
        super().__init__(rng, index, origin, t0)
        self.sent = 0
        self.odd = False

    def message(self, t):
        """The next message: an identification every 10th, else a position and a velocity in
        turn, the positions even and odd in turn."""
        self.advance(t)
        k, self.sent = self.sent, self.sent + 1
        if k % 10 == 0:
            return "id", identification(self.icao, self.callsign)
        if k % 2 == 1:
            self.odd = not self.odd
            alt_ft = round(self.alt / FT / 25.0) * 25
            self.last = {"lat": self.lat, "lon": self.lon, "alt_m": self.alt, "t": t}
            return "pos", position(self.icao, self.lat, self.lon, alt_ft, self.odd)
        return "vel", velocity(self.icao, self.ve, self.vn, self.vu)


class Checker:
    """Every frame through pyModeS, against what it encodes."""

    def __init__(self):
        self.pipe = pyModeS.PipeDecoder()
        self.checked = self.positions = 0
        self.worst_m = 0.0
        self.errors = []

    def fail(self, what):
        if len(self.errors) < 10:
            self.errors.append(what)

    def check(self, kind, msg, ac, t):
        d = self.pipe.decode(msg.hex().upper(), timestamp=t)
        self.checked += 1
        if kind == "corrupt":
            if d.get("crc_valid") is not False:
                self.fail(f"corrupted {msg.hex()} passes pyModeS's parity check: {dict(d)}")
            return
        if d.get("crc_valid") is not True or d.get("icao") != ac.hex:
            return self.fail(f"{kind} {msg.hex()}: {dict(d)}")
        if kind == "id" and d.get("callsign") != ac.callsign:
            self.fail(f"callsign {d.get('callsign')!r} != {ac.callsign!r}")
        elif kind == "vel":
            gs = math.hypot(ac.ve, ac.vn) / KT
            track = math.degrees(math.atan2(ac.ve, ac.vn)) % 360.0
            dtrack = abs((d.get("track", -1e9) - track + 180.0) % 360.0 - 180.0)
            if abs(d.get("groundspeed", -1e9) - gs) > 1.5 or dtrack > 1.0:
                self.fail(f"velocity {dict(d)} != {gs:.1f} kt {track:.1f} deg")
        elif kind == "pos":
            if abs(d.get("altitude", -1e9) - ac.alt / FT) > 12.5 + 1e-6:
                self.fail(f"altitude {d.get('altitude')} != {ac.alt / FT:.1f} ft")
            if d.get("latitude") is not None:
                self.positions += 1
                err = metres(ac.lat, ac.lon, d["latitude"], d["longitude"])
                self.worst_m = max(self.worst_m, err)
                if err > 10.0:
                    self.fail(f"pyModeS's position of {ac.hex} is {err:.1f} m off")


def main():
    p = adsb_fleet.arguments(__doc__, aircraft=150, rate=1000.0, unit="frames")
    p.add_argument("--corrupt-every", type=int, default=97, help="one corrupted frame every N frames")
    a = p.parse_args()
    rng = random.Random(a.seed)
    srv, conn = adsb_fleet.accept_one(a.accept_timeout)
    start = time.time()
    fleet = [Aircraft(rng, i, adsb_fleet.origin(a), start) for i in range(a.aircraft)]
    checker = Checker()
    sent = corrupted = escaped = k = 0
    for n in adsb_fleet.paced(start, a.rate, int(a.rate * a.duration)):
        out = []
        for _ in range(n):
            now = time.time()
            ac = fleet[k % len(fleet)]
            if a.corrupt_every and (sent + 1) % a.corrupt_every == 0:
                # One of this aircraft's identification or velocity messages with 1 to 3 bits
                # flipped after the DF (the aircraft's own sequence goes on untouched).
                ac.advance(now)
                kind = "corrupt"
                if rng.random() < 0.5:
                    msg = bytearray(identification(ac.icao, ac.callsign))
                else:
                    msg = bytearray(velocity(ac.icao, ac.ve, ac.vn, ac.vu))
                for bit in rng.sample(range(5, 112), rng.randint(1, 3)):
                    msg[bit // 8] ^= 0x80 >> (bit % 8)
                msg = bytes(msg)
                corrupted += 1
            else:
                kind, msg = ac.message(now)
                k += 1
            checker.check(kind, msg, ac, now)
            # A 0x1a signal level now and then, to be doubled.
            signal = 0x1A if sent % 7 == 0 else 0x80 + sent % 100
            frame = beast(round((now - start) * 12e6), signal, msg)
            escaped += frame.count(b"\x1a\x1a")
            out.append(frame)
            sent += 1
        conn.sendall(b"".join(out))
    report = {
        "sent": sent,
        "corrupted": corrupted,
        "escaped": escaped,
        "elapsed_s": time.time() - start,
        "pymodes": {
            "checked": checker.checked,
            "positions": checker.positions,
            "worst_m": checker.worst_m,
            "errors": checker.errors,
        },
        "aircraft": adsb_fleet.fleet_report(fleet),
    }
    print(json.dumps(report), flush=True)
    conn.close()
    srv.close()
    return 1 if checker.errors else 0


if __name__ == "__main__":
    sys.exit(main())
