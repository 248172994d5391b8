#!/usr/bin/env python3
"""A TAK client of a TAK server's plain TCP CoT input (FreeTAKServer's 8087), as ATAK connects:
it sends its own position report (an `a-f-G-U-C` event with a callsign, which the server takes for
the client's identity) and then decodes, with takproto (cot_listen.py's decoder), every event the
server sends it.

Prints `{"connected": {"uid": UID}}` once its position report is sent, then one JSON line per
decoded event (the fields of cot_listen.py, `via` "server") and `{"error": ...}` for a frame it
cannot decode; `{"closed": true}` when the server closes the connection. Re-sends its position
report every --sa-interval seconds, as TAK clients do. Exits after --timeout seconds.

    python3 tak_client.py --port 8087 --timeout 60
"""

import argparse
import datetime
import json
import select
import socket
import sys
import time

from cot_listen import emit, frames, report

UID = "harrier-test-client"


def iso(t):
    utc = datetime.datetime.fromtimestamp(t, datetime.timezone.utc)
    return utc.strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def position_report(uid, callsign):
    now = time.time()
    return (
        '<?xml version="1.0" encoding="UTF-8" standalone="yes"?>'
        f'<event version="2.0" uid="{uid}" type="a-f-G-U-C" how="h-e" time="{iso(now)}" '
        f'start="{iso(now)}" stale="{iso(now + 120)}">'
        '<point lat="47.4" lon="8.55" hae="500" ce="10" le="10"/>'
        f'<detail><contact callsign="{callsign}" endpoint="*:-1:stcp"/>'
        '<__group name="Cyan" role="Team Member"/>'
        '<takv device="test" platform="harrier tests" os="linux" version="1"/></detail></event>'
    ).encode()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--uid", default=UID)
    ap.add_argument("--timeout", type=float, default=60.0)
    ap.add_argument("--sa-interval", type=float, default=5.0)
    args = ap.parse_args()

    s = socket.create_connection((args.host, args.port), timeout=10)
    s.sendall(position_report(args.uid, "harrier test client"))
    emit({"connected": {"uid": args.uid}})
    sent = time.monotonic()
    buf = bytearray()
    deadline = time.monotonic() + args.timeout
    while time.monotonic() < deadline:
        if time.monotonic() - sent > args.sa_interval:
            s.sendall(position_report(args.uid, "harrier test client"))
            sent = time.monotonic()
        ready, _, _ = select.select([s], [], [], 0.2)
        if not ready:
            continue
        data = s.recv(65536)
        if not data:
            emit({"closed": True})
            return
        buf += data
        try:
            done, rest = frames(bytes(buf).lstrip())
        except ValueError as e:
            emit({"error": f"server: {e}"})
            buf = bytearray()
            continue
        buf = bytearray(rest)
        for f in done:
            report(f, "server")
    sys.exit(0)


if __name__ == "__main__":
    main()
