#!/usr/bin/env python3
"""Subscribes to harrier-sim's detections with the real Zenoh Python API (eclipse-zenoh).

Usage: zenoh_subscriber.py --connect tcp/127.0.0.1:PORT --vehicles 1,2 --scans 100

Opens a peer session with multicast scouting off and one explicit tcp endpoint, subscribes to
`harrier/v1/vehicle/*/detections` and `harrier/v1/sim/truth`, and collects until every vehicle has
sent `--scans` scans (deadline `--timeout` s). Every payload is decoded field by field against
DETECTIONS.md (types, lengths, finiteness, angle ranges, encoding); seq numbers must be contiguous
per (vehicle, sensor) once received. Prints one JSON summary line (per-vehicle counts, rates in
simulated and wall time, detections seen, truth samples) on stdout; exits non-zero on any failure.
Run by tests/tests/it/zenoh_detections.rs.
"""

import argparse
import json
import math
import queue
import sys
import time

import zenoh

KINDS = {"position": None, "range_bearing": 2, "az_el": 2, "bearing_size": 3}


def fail(msg):
    print(f"zenoh_subscriber: FAIL: {msg}", file=sys.stderr, flush=True)
    sys.exit(1)


def finite(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def geopoint(g, where):
    for k in ("lat_deg", "lon_deg", "alt_m"):
        if not finite(g.get(k)):
            fail(f"{where}.{k} = {g.get(k)!r}")
    if not (-90 <= g["lat_deg"] <= 90 and -180 <= g["lon_deg"] <= 180):
        fail(f"{where} out of range: {g}")


def vec(v, n, where):
    if not (isinstance(v, list) and len(v) == n and all(finite(x) for x in v)):
        fail(f"{where} = {v!r} is not {n} finite numbers")


def check_scan(key, encoding, d):
    """Checks one DetectionScan; returns (vehicle, sensor, seq, t, n_detections)."""
    if encoding != "application/json;harrier-detections/1":
        fail(f"encoding {encoding!r} on {key}")
    if d.get("schema") != "harrier-detections/1":
        fail(f"schema {d.get('schema')!r}")
    vehicle = d.get("vehicle")
    if not (isinstance(vehicle, int) and 1 <= vehicle <= 255):
        fail(f"vehicle {vehicle!r}")
    if key != f"harrier/v1/vehicle/{vehicle}/detections":
        fail(f"vehicle {vehicle} published on {key}")
    if not (isinstance(d.get("seq"), int) and d["seq"] >= 0):
        fail(f"seq {d.get('seq')!r}")
    if not finite(d.get("t")):
        fail(f"t {d.get('t')!r}")
    # harrier-sim stamps the instant as UNIX time too: its start + t (speed-up 1 here).
    unix = d.get("time_unix")
    if not finite(unix) or abs(unix - time.time()) > 30.0:
        fail(f"time_unix {unix!r} is not within 30 s of this host's clock ({time.time():.3f})")
    if not (isinstance(d.get("sensor"), str) and d["sensor"]):
        fail(f"sensor {d.get('sensor')!r}")
    kind = d.get("kind")
    if kind not in KINDS:
        fail(f"kind {kind!r}")
    geopoint(d["origin"], "origin")
    p = d["platform"]
    vec(p["pos"], 3, "platform.pos")
    vec(p["vel"], 3, "platform.vel")
    vec(p["attitude"], 3, "platform.attitude")
    geopoint(p["geodetic"], "platform.geodetic")
    noise = d["noise_std"]
    n = KINDS[kind] or len(noise)
    vec(noise, n, "noise_std")
    if kind == "position" and n not in (2, 3):
        fail(f"position with {n} components")
    if not all(s > 0 for s in noise):
        fail(f"noise_std {noise}")
    dets = d["detections"]
    if not isinstance(dets, list):
        fail("detections is not a list")
    for i, det in enumerate(dets):
        z = det["z"]
        vec(z, n, f"detections[{i}].z")
        if kind == "range_bearing":
            if z[0] < 0 or not -math.pi <= z[1] <= math.pi:
                fail(f"range_bearing z {z}")
        if kind in ("az_el", "bearing_size"):
            if not (-math.pi <= z[0] <= math.pi and -math.pi / 2 <= z[1] <= math.pi / 2):
                fail(f"{kind} z {z}")
        if kind == "bearing_size" and not z[2] > 0:
            fail(f"subtended angle {z[2]}")
    return vehicle, d["sensor"], d["seq"], d["t"], len(dets)


def check_truth(encoding, d):
    if encoding != "application/json;harrier-truth/1":
        fail(f"truth encoding {encoding!r}")
    if d.get("schema") != "harrier-truth/1" or not finite(d.get("t")):
        fail(f"truth header {d.get('schema')!r} {d.get('t')!r}")
    geopoint(d["origin"], "truth.origin")
    if not d["targets"]:
        fail("truth without targets")
    for tg in d["targets"]:
        if not isinstance(tg["id"], str) or not isinstance(tg["mode"], str):
            fail(f"truth target {tg}")
        vec(tg["state"], 6, f"truth {tg['id']} state")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--connect", required=True)
    ap.add_argument("--vehicles", required=True, help="comma-separated vehicle ids")
    ap.add_argument("--scans", type=int, default=100, help="scans to collect per vehicle")
    ap.add_argument("--timeout", type=float, default=30.0)
    args = ap.parse_args()
    vehicles = [int(v) for v in args.vehicles.split(",")]

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([args.connect]))
    # Peers must not listen on every interface for this test.
    conf.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')

    inbox = queue.Queue()

    def on_sample(sample):
        inbox.put((str(sample.key_expr), str(sample.encoding), sample.payload.to_bytes(), time.monotonic()))

    with zenoh.open(conf) as session:
        session.declare_subscriber("harrier/v1/vehicle/*/detections", on_sample)
        session.declare_subscriber("harrier/v1/sim/truth", on_sample)
        print("zenoh_subscriber: subscribed", file=sys.stderr, flush=True)
        deadline = time.monotonic() + args.timeout
        per = {v: [] for v in vehicles}  # (t, wall, n_detections)
        last_seq = {}
        truth = 0
        while any(len(per[v]) < args.scans for v in vehicles):
            left = deadline - time.monotonic()
            if left <= 0:
                fail(f"timeout: scans so far { {v: len(s) for v, s in per.items()} }, truth {truth}")
            try:
                key, enc, payload, wall = inbox.get(timeout=min(left, 0.5))
            except queue.Empty:
                continue
            try:
                d = json.loads(payload)
            except ValueError as e:
                fail(f"payload on {key} is not JSON: {e}")
            if key == "harrier/v1/sim/truth":
                check_truth(enc, d)
                truth += 1
                continue
            v, sensor, seq, t, n = check_scan(key, enc, d)
            if v not in per:
                fail(f"unexpected vehicle {v}")
            prev = last_seq.get((v, sensor))
            if prev is not None and seq != prev + 1:
                fail(f"vehicle {v} sensor {sensor}: seq {seq} after {prev}")
            last_seq[(v, sensor)] = seq
            per[v].append((t, wall, n))

    summary = {"vehicles": {}, "truth": truth}
    for v, scans in per.items():
        scans = scans[: args.scans]
        (t0, w0, _), (t1, w1, _) = scans[0], scans[-1]
        summary["vehicles"][str(v)] = {
            "scans": len(scans),
            "rate_sim_hz": (len(scans) - 1) / (t1 - t0) if t1 > t0 else None,
            "rate_wall_hz": (len(scans) - 1) / (w1 - w0) if w1 > w0 else None,
            "detections": sum(n for _, _, n in scans),
        }
    print(json.dumps(summary), flush=True)


if __name__ == "__main__":
    main()
