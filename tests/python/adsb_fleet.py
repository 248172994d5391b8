"""What the ADS-B replays (sbs_replay.py, beast_replay.py) share: a fleet of aircraft in straight
flight around an origin, the one-client TCP server they replay to, the real-time pacing of the
replay and the report of what was sent.
"""

import argparse
import json
import math
import socket
import time

FT = 0.3048
KT = 1852.0 / 3600.0
EARTH_R = 6_371_000.0


class Aircraft:
    """Aircraft `index`: address 0x400000 + 37·index, callsign HRR<index>, 2 to 100 km from
    `origin` (lat, lon), 300 to 12 000 m up, 50 to 250 m/s on a random course, level or climbing
    or descending at up to 10 m/s. `last` is what the replay last reported of its position."""

    def __init__(self, rng, index, origin, t0):
        self.icao = 0x400000 + index * 37
        self.hex = f"{self.icao:06X}"
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
        self.last = None

    def advance(self, t):
        dt = t - self.t
        self.lat += math.degrees(self.vn * dt / EARTH_R)
        self.lon += math.degrees(self.ve * dt / (EARTH_R * math.cos(math.radians(self.lat))))
        self.alt += self.vu * dt
        self.t = t


def arguments(doc, aircraft, rate, unit):
    """The replays' common options (`--aircraft`, `--rate`, `--duration`, `--origin`, `--seed`,
    `--accept-timeout`); the caller adds its own and parses."""
    p = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--aircraft", type=int, default=aircraft)
    p.add_argument("--rate", type=float, default=rate, help=f"{unit} per second")
    p.add_argument("--duration", type=float, default=15.0, help="seconds of replay")
    p.add_argument("--origin", default="47.397742,8.545594", help="lat,lon the aircraft fly around")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--accept-timeout", type=float, default=30.0)
    return p


def origin(a):
    return tuple(float(v) for v in a.origin.split(","))


def accept_one(timeout):
    """Listens on a loopback port of the OS's choice, prints `{"ready": PORT}`, and returns the
    listening socket and the first client's connection."""
    srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)
    srv.settimeout(timeout)
    print(json.dumps({"ready": srv.getsockname()[1]}), flush=True)
    conn, _ = srv.accept()
    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return srv, conn


def paced(start, rate, total):
    """Yields how many messages to send now, every 10 ms, so that `total` messages go at `rate`
    per second from `start` (UNIX time)."""
    batch = max(1, int(rate / 100))
    sent = 0
    while sent < total:
        pause = start + sent / rate - time.time()
        if pause > 0:
            time.sleep(pause)
        n = min(batch, total - sent)
        yield n
        sent += n


def fleet_report(fleet):
    """Per aircraft (hex address): its last reported position, callsign and velocity."""
    return {
        ac.hex: {**ac.last, "callsign": ac.callsign, "ve": ac.ve, "vn": ac.vn, "vu": ac.vu}
        for ac in fleet
        if ac.last is not None
    }
