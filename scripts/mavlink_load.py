#!/usr/bin/env python3
"""Load of the ground station's MAVLink GCS link and router (BENCHMARKS.md, issue 9).

    cargo build --release --bin harrier
    scripts/mavlink_load.py --bin target/release/harrier --vehicles 20 --hz 50 --seconds 60

Starts `harrier serve` with its GCS link and a UDP router endpoint on loopback, then plays N
PX4-like vehicles (one UDP socket each, system ids 1..N): ATTITUDE and GLOBAL_POSITION_INT at
--hz, HEARTBEAT and SYS_STATUS at 1 Hz, MAVLink 2 with per-vehicle sequence numbers. A router
client (pymavlink's parser on its own thread) registers on the router endpoint and receives the
forwarded frames. Reports:

- frames sent by the vehicles, received by the server (its /metrics) and forwarded to the client;
- router added latency: vehicle send → client receive of each ATTITUDE (its time_boot_ms carries
  a per-vehicle counter), p50/p99/p99.9/max: an upper bound (it includes both Python sides;
  `--baseline` sends straight to the client, without Harrier, to measure those);
- the server's CPU share (utime + stime from /proc over the measured window);
- the guidance loop's tick lateness histogram at 20 Hz from /metrics.

Needs pymavlink (in the venv scripts/setup makes: eval "$(scripts/setup --env)"). Prints one JSON object at the end.
"""

import argparse
import json
import os
import re
import socket
import subprocess
import sys
import threading
import time
import urllib.request

from pymavlink.dialects.v20 import common as mavlink2


def free_port(kind=socket.SOCK_DGRAM):
    s = socket.socket(socket.AF_INET, kind)
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def cpu_seconds(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def metrics(api):
    return urllib.request.urlopen(f"http://{api}/api/v1/metrics", timeout=5).read().decode()


def metric(text, series):
    for line in text.splitlines():
        if line.startswith(series + " "):
            return float(line.split()[-1])
    return 0.0


def percentile(xs, q):
    if not xs:
        return float("nan")
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="target/release/harrier")
    ap.add_argument("--vehicles", type=int, default=20)
    ap.add_argument("--hz", type=float, default=50.0)
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--warmup", type=float, default=3.0)
    ap.add_argument("--baseline", action="store_true",
                    help="send straight to the client socket (no Harrier): the Python sides' own latency")
    ap.add_argument("--client-id", type=int, default=200,
                    help="the router client's MAVLink system id (not a vehicle's: with --vehicles 254 use 255, "
                         "the id QGroundControl uses beside the server's own)")
    a = ap.parse_args()
    if not 1 <= a.vehicles <= 254:
        sys.exit("mavlink_load: --vehicles must be 1..254 (255 is the ground station's own system id)")
    if 1 <= a.client_id <= a.vehicles:
        sys.exit(f"mavlink_load: --client-id {a.client_id} is a vehicle's id (1..{a.vehicles})")

    gcs, router, zport = free_port(), free_port(), free_port(socket.SOCK_STREAM)
    server = subprocess.Popen(
        [a.bin, "serve", "--listen", "127.0.0.1:0", "--gcs", f"udpin:127.0.0.1:{gcs}",
         "--router", f"udpin:127.0.0.1:{router}", "--zenoh-listen", f"tcp/127.0.0.1:{zport}"],
        stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
        env={**os.environ, "RUST_LOG": "warn", "HARRIER_TOKEN": "load"})
    api = None
    deadline = time.monotonic() + 30
    while api is None and time.monotonic() < deadline:
        line = server.stderr.readline()
        if not line:
            break
        m = re.search(r"ready: http://([0-9.:]+)/api/v1", line)
        if m:
            api = m.group(1)
    if api is None:
        server.kill()
        sys.exit("mavlink_load: the server did not start")
    threading.Thread(target=lambda: [None for _ in server.stderr], daemon=True).start()

    # The router client: register, then receive on its own thread.
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.bind(("127.0.0.1", 0))
    client.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 8 << 20)
    cmav = mavlink2.MAVLink(None, srcSystem=a.client_id, srcComponent=191)
    client.sendto(cmav.heartbeat_encode(6, 8, 0, 0, 0).pack(cmav), ("127.0.0.1", router))
    sent_at = {}
    latencies = []
    received = {"frames": 0, "attitude": 0}
    measuring = threading.Event()
    stop = threading.Event()

    def receive():
        parser = mavlink2.MAVLink(None)
        parser.robust_parsing = True
        client.settimeout(0.2)
        while not stop.is_set():
            try:
                data = client.recv(65536)
            except socket.timeout:
                continue
            now = time.perf_counter()
            for msg in parser.parse_buffer(data) or []:
                received["frames"] += 1
                if msg.get_type() == "ATTITUDE":
                    sent = sent_at.pop((msg.get_srcSystem(), msg.time_boot_ms), None)
                    if sent is not None and sent[1]:
                        received["attitude"] += 1
                        latencies.append(now - sent[0])

    rx = threading.Thread(target=receive, daemon=True)
    rx.start()

    socks, mavs = [], []
    for i in range(a.vehicles):
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.bind(("127.0.0.1", 0))
        socks.append(s)
        mavs.append(mavlink2.MAVLink(None, srcSystem=i + 1, srcComponent=1))
    dest = client.getsockname() if a.baseline else ("127.0.0.1", gcs)
    period = 1.0 / a.hz
    sent = {"frames": 0, "attitude": 0}
    start = time.perf_counter()
    next_tick = start
    k = 0
    cpu0 = t_cpu0 = None
    m0 = None
    while True:
        now = time.perf_counter()
        if now < next_tick:
            time.sleep(next_tick - now)
        elapsed = time.perf_counter() - start
        if cpu0 is None and elapsed >= a.warmup:
            cpu0, t_cpu0, m0 = cpu_seconds(server.pid), time.perf_counter(), metrics(api)
            sent_meas = dict(sent)
            measuring.set()
        if elapsed >= a.warmup + a.seconds:
            break
        for i, (s, mav) in enumerate(zip(socks, mavs)):
            frames = []
            if k % int(a.hz) == 0:
                frames.append(mav.heartbeat_encode(2, 12, 129, 6 << 16, 4).pack(mav))
                frames.append(mav.sys_status_encode(0, 0, 0, 500, 16000, -1, 90, 0, 0, 0, 0, 0, 0).pack(mav))
            boot = k & 0xFFFFFFFF
            frames.append(mav.attitude_encode(boot, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0).pack(mav))
            frames.append(mav.global_position_int_encode(boot, 473977420 + i, 85455940, 600000, 100000,
                                                         100, 0, 0, 9000).pack(mav))
            sent_at[(i + 1, boot)] = (time.perf_counter(), measuring.is_set())
            for f in frames:
                s.sendto(f, dest)
            sent["frames"] += len(frames)
            sent["attitude"] += measuring.is_set()
        k += 1
        next_tick += period
    measuring.clear()
    cpu1, t_cpu1, m1 = cpu_seconds(server.pid), time.perf_counter(), metrics(api)
    time.sleep(0.5)  # the last frames' way through
    stop.set()
    rx.join()
    server.terminate()
    server.wait(timeout=10)

    window = t_cpu1 - t_cpu0
    attitude_sent = sent["attitude"]
    late_max = metric(m1, "harrier_guidance_tick_late_max_seconds")
    buckets = {}
    for line in m1.splitlines():
        m = re.match(r'harrier_guidance_tick_late_seconds_bucket\{le="([^"]+)"\} (\S+)', line)
        if m:
            buckets[m.group(1)] = float(m.group(2))
    out = {
        "vehicles": a.vehicles,
        "hz": a.hz,
        "seconds": round(window, 1),
        "frames_sent_per_s": round((sent["frames"] - sent_meas["frames"]) / window),
        "server_frames_received": int(metric(m1, "harrier_mavlink_frames_received_total")
                                      - metric(m0, "harrier_mavlink_frames_received_total")),
        "frames_sent": sent["frames"] - sent_meas["frames"],
        "server_sequence_gaps": int(sum(float(l.split()[-1]) for l in m1.splitlines()
                                        if l.startswith("harrier_vehicle_frames_lost_total{"))),
        "attitude_sent": attitude_sent,
        "attitude_forwarded": received["attitude"],
        "baseline_without_harrier": a.baseline,
        "router_lost": attitude_sent - received["attitude"],
        "router_latency_ms": {q: round(percentile(latencies, p) * 1e3, 3)
                              for q, p in [("p50", 0.5), ("p99", 0.99), ("p99.9", 0.999), ("max", 1.0)]},
        "server_cpu_share": round((cpu1 - cpu0) / window, 3),
        "guidance_tick_late": {"buckets": buckets, "max_s": late_max},
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
