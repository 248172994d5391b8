#!/usr/bin/env python3
"""Does any field-format feed hold tracking up? (BENCHMARKS.md, issue 23)

    cargo build --release -p harrier-cli
    eval "$(scripts/setup --env)"
    scripts/feeds_load.py --bin target/release/harrier --seconds 60

Runs `harrier bench` (10 vehicles × 50 Hz × 4 detections, one WebSocket client) twice against a
`harrier serve` on loopback: once with every feed off, once with every feed on and each output's
consumer stalled —

- CoT at 50 Hz over TCP to a peer that accepts and never reads, and over UDP;
- ASTERIX CAT062 over UDP to a socket that never reads;
- Foxglove: a WebSocket client that subscribes to every channel and then never reads;
- ADS-B in: tests/python/sbs_replay.py feeding 300 aircraft at 500 lines/s —

and prints one JSON object: the detection → WebSocket latency (p50, p99, p99.9, ms) and the lost
messages of both runs, the ratio of the p99s, and the feeds' counters of the second run.
"""

import argparse
import asyncio
import json
import os
import re
import socket
import subprocess
import sys
import threading
import time
import urllib.request

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def free_port(kind=socket.SOCK_STREAM):
    s = socket.socket(socket.AF_INET, kind)
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


class StalledTcpPeer:
    """Accepts connections and never reads from them."""

    def __init__(self):
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.port = self.sock.getsockname()[1]
        self.conns = []
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self):
        while True:
            try:
                c, _ = self.sock.accept()
            except OSError:
                return
            c.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
            self.conns.append(c)


def stalled_foxglove_client(url, stop):
    """Subscribes to every channel, then reads nothing more until `stop`."""
    import websockets

    async def run():
        async with websockets.connect(url, subprotocols=["foxglove.sdk.v1"], max_size=None) as ws:
            subscribed = 0
            deadline = time.monotonic() + 10
            while time.monotonic() < deadline and subscribed < 4:
                msg = await asyncio.wait_for(ws.recv(), 10)
                if isinstance(msg, str) and json.loads(msg).get("op") == "advertise":
                    subs = [
                        {"id": subscribed + i + 1, "channelId": c["id"]}
                        for i, c in enumerate(json.loads(msg)["channels"])
                    ]
                    subscribed += len(subs)
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
            # Stop reading: the socket's buffers fill, then the server's backlog for this client.
            ws.transport.pause_reading()
            while not stop.is_set():
                await asyncio.sleep(0.2)

    asyncio.run(run())


def serve(binary, config_text):
    """`harrier serve` with `config_text`, once it says it is ready (on stderr); its token."""
    path = f"/tmp/harrier-feeds-load-{os.getpid()}.toml"
    with open(path, "w") as f:
        f.write(config_text)
    token = "feeds-load-token-0123456789abcdef"
    proc = subprocess.Popen(
        [binary, "serve", "-c", path],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "HARRIER_TOKEN": token, "RUST_LOG": "warn"},
    )
    ready = False
    for line in proc.stderr:
        if "harrier serve: ready" in line:
            ready = True
            break
    if not ready:
        proc.kill()
        sys.exit("harrier serve ended before it was ready")
    threading.Thread(target=lambda: [None for _ in proc.stderr], daemon=True).start()
    return proc, token


def bench(binary, api, zenoh, token, pid, seconds):
    out = subprocess.run(
        [
            binary, "bench", "--url", f"http://{api}", "--zenoh-connect", zenoh, "--token", token,
            "--server-pid", str(pid), "--vehicles", "10", "--rate-hz", "50", "--detections", "4",
            "--warmup-s", "5", "--duration-s", str(seconds), "--ws-clients", "1", "--json",
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout)


def feed_counters(api):
    text = urllib.request.urlopen(f"http://{api}/api/v1/metrics", timeout=5).read().decode()
    out = {}
    for line in text.splitlines():
        m = re.match(r'harrier_feed_events_total\{feed="(\w+)",event="(\w+)"\} (\S+)', line)
        if m:
            out.setdefault(m.group(1), {})[m.group(2)] = float(m.group(3))
    return out


def run(binary, seconds, feeds_on):
    api = f"127.0.0.1:{free_port()}"
    zenoh = f"tcp/127.0.0.1:{free_port()}"
    config = f'[api]\nlisten = "{api}"\n[zenoh]\nlisten = ["{zenoh}"]\n[mavlink]\ngcs = []\nrouter = []\n'
    helpers = []
    stop = threading.Event()
    if feeds_on:
        tcp = StalledTcpPeer()
        udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        udp.bind(("127.0.0.1", 0))
        replay = subprocess.Popen(
            [sys.executable, os.path.join(ROOT, "tests/python/sbs_replay.py"), "--aircraft", "300",
             "--rate", "500", "--duration", str(seconds + 60)],
            stdout=subprocess.PIPE,
            text=True,
        )
        sbs_port = json.loads(replay.stdout.readline())["ready"]
        fox = free_port()
        config += (
            f'[cot]\nenabled = true\nhz = 50.0\ndestinations = ["tcp://127.0.0.1:{tcp.port}", '
            f'"udp://127.0.0.1:{udp.getsockname()[1]}"]\n'
            f'[asterix]\nenabled = true\nhz = 10.0\ndestination = "127.0.0.1:{udp.getsockname()[1]}"\n'
            f'[foxglove]\nenabled = true\nlisten = "127.0.0.1:{fox}"\n'
            f'[adsb]\nenabled = true\naddress = "127.0.0.1:{sbs_port}"\n'
        )
        helpers = [tcp, udp, replay]
    proc, token = serve(binary, config)
    if feeds_on:
        t = threading.Thread(target=stalled_foxglove_client, args=(f"ws://127.0.0.1:{fox}", stop), daemon=True)
        t.start()
    try:
        report = bench(binary, api, zenoh, token, proc.pid, seconds)
        counters = feed_counters(api)
    finally:
        stop.set()
        proc.terminate()
        proc.wait(timeout=20)
        for h in helpers:
            if isinstance(h, subprocess.Popen):
                h.kill()
    ws = report["websocket"]
    return {
        "feeds": "on, consumers stalled" if feeds_on else "off",
        "latency_ms": {k: ws["latency_ms"][k] for k in ("p50", "p99", "p999", "max", "count")},
        "missing": ws["missing"],
        "lost": report["server"]["lost"],
        "server_cpu": report.get("cpu"),
        "feed_counters": counters,
    }


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--bin", default=os.path.join(ROOT, "target/release/harrier"))
    p.add_argument("--seconds", type=float, default=60.0)
    a = p.parse_args()
    off = run(a.bin, a.seconds, False)
    print(f"feeds off: {off['latency_ms']}", file=sys.stderr, flush=True)
    on = run(a.bin, a.seconds, True)
    print(f"feeds on:  {on['latency_ms']}", file=sys.stderr, flush=True)
    print(
        json.dumps(
            {"off": off, "on": on, "p99_ratio": on["latency_ms"]["p99"] / off["latency_ms"]["p99"]},
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
