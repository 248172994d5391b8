#!/usr/bin/env python3
"""Load tool for harrier-sim: CPU used by one process running N vehicles at R Hz telemetry and
R Hz detections, with real consumers on both sides.

Usage: scripts/sim_load.py [--bin target/release/harrier-sim] [--vehicles 20] [--rate 50]
                           [--seconds 30] [--warmup 5]

Starts `harrier-sim --count N --scenario crossing --detection-hz R` with its GCS link pointed at a
UDP socket held here and Zenoh listening on loopback; a pymavlink client on every vehicle's API
link raises GLOBAL_POSITION_INT, LOCAL_POSITION_NED and ATTITUDE to R Hz with
SET_MESSAGE_INTERVAL (as MAVSDK does); an eclipse-zenoh subscriber counts the scans. After the
warm-up it reads the process's user + system CPU time from /proc over `--seconds` and prints the
share of one core, with the message rates actually delivered. Used for BENCHMARKS.md.
"""

import argparse
import json
import os
import socket
import subprocess
import sys
import threading
import time

os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402
import zenoh  # noqa: E402

mavlink = mavutil.mavlink


def cpu_seconds(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    ticks = os.sysconf("SC_CLK_TCK")
    return (int(fields[11]) + int(fields[12])) / ticks  # utime + stime


def free_port(kind=socket.SOCK_DGRAM):
    s = socket.socket(socket.AF_INET, kind)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default="target/release/harrier-sim")
    ap.add_argument("--vehicles", type=int, default=20)
    ap.add_argument("--rate", type=float, default=50.0)
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--warmup", type=float, default=5.0)
    args = ap.parse_args()

    gcs = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs.bind(("127.0.0.1", 0))
    gcs.settimeout(0.2)
    api0 = free_port()
    zport = free_port(socket.SOCK_STREAM)
    cmd = [
        args.bin, "--count", str(args.vehicles), "--scenario", "crossing",
        "--detection-hz", str(args.rate),
        "--gcs", f"udpout:127.0.0.1:{gcs.getsockname()[1]}",
        "--api", f"udpin:127.0.0.1:{api0}",
        "--zenoh-listen", f"tcp/127.0.0.1:{zport}",
    ]
    print("running:", " ".join(cmd), file=sys.stderr)
    sim = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    try:
        # Ready when every vehicle has reported its links (a line per vehicle on stderr).
        ready = 0
        while ready < args.vehicles:
            line = sim.stderr.readline()
            if not line:
                sys.exit(f"harrier-sim exited: {sim.wait()}")
            if " up, links " in line:
                ready += 1
        threading.Thread(target=lambda: [None for _ in sim.stderr], daemon=True).start()

        frames = {"n": 0}
        stop = threading.Event()

        def drain_gcs():
            while not stop.is_set():
                try:
                    data = gcs.recv(65536)
                except socket.timeout:
                    continue
                frames["n"] += data.count(b"\xfd")  # one MAVLink 2 frame per datagram here

        threading.Thread(target=drain_gcs, daemon=True).start()

        conns = []
        for k in range(args.vehicles):
            c = mavutil.mavlink_connection(f"udpout:127.0.0.1:{api0 + k}", source_system=255,
                                           source_component=190)
            c.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            for msg in (mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
                        mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, mavlink.MAVLINK_MSG_ID_ATTITUDE):
                c.mav.command_long_send(k + 1, 1, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                        msg, 1e6 / args.rate, 0, 0, 0, 0, 0)
            conns.append(c)

        scans = {"n": 0}
        conf = zenoh.Config()
        conf.insert_json5("mode", '"peer"')
        conf.insert_json5("scouting/multicast/enabled", "false")
        conf.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{zport}"]))
        conf.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
        with zenoh.open(conf) as session:
            def on_sample(_s):
                scans["n"] += 1
            session.declare_subscriber("harrier/v1/vehicle/*/detections", on_sample)
            time.sleep(args.warmup)  # warm-up: let streams and the Zenoh route settle
            c0, f0, s0, w0 = cpu_seconds(sim.pid), frames["n"], scans["n"], time.monotonic()
            time.sleep(args.seconds)  # the measurement window itself
            c1, f1, s1, w1 = cpu_seconds(sim.pid), frames["n"], scans["n"], time.monotonic()
        stop.set()
        wall = w1 - w0
        result = {
            "vehicles": args.vehicles,
            "rate_hz": args.rate,
            "window_s": round(wall, 1),
            "cpu_share_of_one_core": round((c1 - c0) / wall, 4),
            "gcs_frames_per_s": round((f1 - f0) / wall, 1),
            "zenoh_scans_per_s": round((s1 - s0) / wall, 1),
            "cores": os.cpu_count(),
        }
        print(json.dumps(result))
    finally:
        sim.terminate()
        sim.wait()


if __name__ == "__main__":
    main()
