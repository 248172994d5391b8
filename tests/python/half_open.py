#!/usr/bin/env python3
"""Holds TCP connections that each send half an HTTP request and then wait (a "slow loris").

Usage: half_open.py --port PORT --count N [--host 127.0.0.1] [--timeout S]

Opens N connections to HOST:PORT one after the other, each sending `GET / HTTP/1.1`, `Host: x`
and no blank line (the request head never ends), and notes when the server closes each one (EOF,
or a reset) while it opens the rest. Then prints `{"opened": N, "failed": F, "open_s": S}` on
stdout and waits until the server has closed every connection, at most --timeout s, and prints one
more JSON line: `closed`, for each connection that was closed, the seconds from its connect to
the close and how (`eof`, `reset`, or `data` when bytes came first); `still_open`, how many were
not closed by the deadline. Standard library only. Run by tests/tests/it/http_limits.rs, which
starts several of these so that each stays under the common limit of 1 024 open files.
"""

import argparse
import json
import selectors
import socket
import sys
import time

HALF_REQUEST = b"GET / HTTP/1.1\r\nHost: x\r\n"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--count", type=int, required=True)
    ap.add_argument("--timeout", type=float, default=60.0)
    a = ap.parse_args()

    sel = selectors.DefaultSelector()
    closed = []  # [seconds from connect to close, how]
    seen_data = set()

    def read(key):
        s, t0 = key.fileobj, key.data
        try:
            data = s.recv(4096)
        except (ConnectionResetError, ConnectionAbortedError):
            how = "reset"
        except BlockingIOError:
            return
        else:
            if data:
                seen_data.add(s.fileno())
                return
            how = "data" if s.fileno() in seen_data else "eof"
        closed.append([time.monotonic() - t0, how])
        sel.unregister(s)
        s.close()

    def poll(timeout):
        for key, _ in sel.select(timeout):
            read(key)

    start = time.monotonic()
    failed = 0
    for _ in range(a.count):
        try:
            s = socket.create_connection((a.host, a.port), timeout=10)
        except OSError:
            failed += 1
            continue
        t0 = time.monotonic()
        try:
            s.sendall(HALF_REQUEST)
        except OSError:
            closed.append([time.monotonic() - t0, "reset"])
            s.close()
            continue
        s.setblocking(False)
        sel.register(s, selectors.EVENT_READ, t0)
        poll(0)
    print(
        json.dumps(
            {"opened": a.count - failed, "failed": failed, "open_s": time.monotonic() - start}
        ),
        flush=True,
    )

    deadline = time.monotonic() + a.timeout
    while sel.get_map() and time.monotonic() < deadline:
        poll(max(0.0, deadline - time.monotonic()))
    still_open = len(sel.get_map())
    print(json.dumps({"closed": closed, "still_open": still_open}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
