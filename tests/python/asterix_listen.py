#!/usr/bin/env python3
"""A CAT062 receiver for harrier's ASTERIX feed: binds a UDP port, decodes every datagram with
two independent third-party decoders, aviconv-asterix (CAT062 ed. 1.20 UAP: time, WGS-84
position, Cartesian velocity, and every item kept raw) and asterix4py (the XML definition of
CAT062 ed. 1.18: every item, Cartesian position, track number and status included), and checks
that they agree.

Prints one JSON line `{"ready": PORT}` once it listens, then one `{"record": {...}}` per track
record (track number, time of track s since midnight, lat, lon, x, y, vx, vy, tentative,
sac, sic, service id), and after `--datagrams` datagrams (or `--timeout` s) one
`{"done": {...}}` line with the counts: datagrams, blocks, records, decode errors (either
decoder failed, or a datagram is not exactly one CAT062 block) and disagreements between the
decoders.

    python3 asterix_listen.py --datagrams 25 --timeout 60
"""

import argparse
import json
import socket
import sys
import time

import aviconv_asterix
from asterix4py import AsterixParser


def close(a, b, tol):
    return a is not None and b is not None and abs(a - b) <= tol


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--datagrams", type=int, default=25)
    ap.add_argument("--timeout", type=float, default=60.0)
    args = ap.parse_args()

    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    print(json.dumps({"ready": sock.getsockname()[1]}), flush=True)

    counts = {"datagrams": 0, "blocks": 0, "records": 0, "decode_errors": 0, "disagreements": 0}
    errors = []
    deadline = time.monotonic() + args.timeout
    while counts["datagrams"] < args.datagrams:
        left = deadline - time.monotonic()
        if left <= 0:
            break
        sock.settimeout(left)
        try:
            data = sock.recv(65536)
        except socket.timeout:
            break
        counts["datagrams"] += 1
        try:
            if data[0] != 62 or int.from_bytes(data[1:3], "big") != len(data):
                raise ValueError(f"not one CAT062 block: {data[:3].hex()} in {len(data)} bytes")
            avi = list(aviconv_asterix.iter_records(data))
            a4p = list(AsterixParser(data).get_result().values())
        except Exception as e:  # noqa: BLE001 — any failure of a decoder is counted
            counts["decode_errors"] += 1
            errors.append(repr(e))
            continue
        counts["blocks"] += 1
        if len(avi) != len(a4p):
            counts["decode_errors"] += 1
            errors.append(f"record counts differ: {len(avi)} vs {len(a4p)}")
            continue
        for r, p in zip(avi, a4p):
            counts["records"] += 1
            pos = p.get("100", {})
            trk = p.get("040", {}).get("TrkN")
            status = p.get("080", {})
            same = (
                r.category == 62
                and (r.sac, r.sic) == (p["010"]["SAC"], p["010"]["SIC"])
                and close(r.time_of_track_s, p["070"]["ToT"], 1e-9)
                and close(r.lat, p["105"]["Lat"], 1e-9)
                and close(r.lon, p["105"]["Lon"], 1e-9)
                and close(r.vx_ms, p["185"]["Vx"], 1e-9)
                and close(r.vy_ms, p["185"]["Vy"], 1e-9)
                and r.raw_items.get("I062/040") == f"{trk:04x}"
            )
            if not same:
                counts["disagreements"] += 1
                errors.append(f"decoders disagree: {r} vs {p}")
            rec = {
                "track_number": trk,
                "time_of_track_s": r.time_of_track_s,
                "lat": r.lat,
                "lon": r.lon,
                "x": pos.get("X"),
                "y": pos.get("Y"),
                "vx": r.vx_ms,
                "vy": r.vy_ms,
                "tentative": status.get("CNF") == 1,
                "sac": r.sac,
                "sic": r.sic,
                "service_id": r.service_id,
                "accuracy": p.get("500"),
            }
            print(json.dumps({"record": rec}), flush=True)
    counts["errors"] = errors[:10]
    print(json.dumps({"done": counts}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
