#!/usr/bin/env python3
"""Time pymavlink's MAVLink 2 decoding (`MAVLink.parse_buffer`) on a recorded telemetry stream.

The anchor of harrier-link's `decode` benchmark (link/benches/decode.rs): both decode the same
file, fed in the same 4096-byte pieces (one socket read each), and both decode every frame into a
message with its fields.

The stream is written once by this script (`--write`, the default path is
target/mavlink-stream.bin, where the Rust bench reads it): `--frames` MAVLink 2 frames (100 000 by
default) of three vehicles at PX4-like rates (per vehicle and 0.1 s: ATTITUDE x5,
LOCAL_POSITION_NED x3, GLOBAL_POSITION_INT x1; SYS_STATUS at 2 Hz; HEARTBEAT at 1 Hz) with a
ground station's HEARTBEAT at 1 Hz and a COMMAND_LONG every 2 s, field values drifting as a flight
would (seeded: the same bytes every time), sequence numbers per sender.

pymavlink's MAVLink 2 parser is Python (its C extension `mavnative` only ever handled MAVLink 1
and is not in the wheel); only the CRC runs in native code, through `fastcrc` when installed.
Each repeat decodes the whole file once; the figure is the median over repeats (the fastest is
printed too), in microseconds per frame and frames per second.

    python3 scripts/pymavlink_decode_bench.py                  # write the stream if missing, time
    python3 scripts/pymavlink_decode_bench.py --write-only     # write the stream, time nothing
    python3 scripts/pymavlink_decode_bench.py --json           # one JSON object on stdout
"""
import argparse
import json
import math
import random
import statistics
import sys
import time
from pathlib import Path

try:
    import pymavlink
    from pymavlink.dialects.v20 import common as mavlink2
except ImportError:
    sys.exit("pymavlink is not installed: pip install pymavlink==2.4.50")

try:
    import fastcrc  # noqa: F401  (pymavlink uses it for the CRC when it is there)
    CRC = "fastcrc"
except ImportError:
    CRC = "python"

CHUNK = 4096
DEFAULT_PATH = Path(__file__).resolve().parent.parent / "target" / "mavlink-stream.bin"


class Vehicle:
    """One simulated PX4 vehicle: its own sequence numbers and a slowly drifting flight state."""

    def __init__(self, system_id, rng):
        self.mav = mavlink2.MAVLink(None, srcSystem=system_id, srcComponent=1)
        self.rng = rng
        self.x, self.y, self.z = rng.uniform(-500, 500), rng.uniform(-500, 500), -rng.uniform(30, 120)
        self.yaw = rng.uniform(-math.pi, math.pi)
        self.speed = rng.uniform(5, 15)

    def tick(self, t_ms, k):
        """Frames of one 0.1 s tick (k counts ticks)."""
        r, mav = self.rng, self.mav
        self.yaw += r.gauss(0, 0.02)
        vx, vy = self.speed * math.cos(self.yaw), self.speed * math.sin(self.yaw)
        self.x += 0.1 * vx
        self.y += 0.1 * vy
        out = []
        if k % 10 == 0:
            out.append(mavlink2.MAVLink_heartbeat_message(
                mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_PX4, 157, 0x06040000,
                mavlink2.MAV_STATE_ACTIVE, 3))
        if k % 5 == 0:
            out.append(mavlink2.MAVLink_sys_status_message(
                0x3520FC2F, 0x3520FC2F, 0x3520FC2F, r.randint(200, 400), r.randint(15000, 16800),
                r.randint(500, 2500), r.randint(40, 100), 0, 0, 0, 0, 0, 0))
        for i in range(5):
            out.append(mavlink2.MAVLink_attitude_message(
                t_ms + 20 * i, r.gauss(0, 0.05), r.gauss(0, 0.05), self.yaw,
                r.gauss(0, 0.01), r.gauss(0, 0.01), r.gauss(0, 0.02)))
        for i in range(3):
            out.append(mavlink2.MAVLink_local_position_ned_message(
                t_ms + 33 * i, self.x, self.y, self.z, vx, vy, r.gauss(0, 0.1)))
        lat = int((47.397742 + self.x / 111_320.0) * 1e7)
        lon = int((8.545594 + self.y / 75_000.0) * 1e7)
        out.append(mavlink2.MAVLink_global_position_int_message(
            t_ms, lat, lon, int((488.0 - self.z) * 1000), int(-self.z * 1000), int(vx * 100),
            int(vy * 100), 0, int(math.degrees(self.yaw) % 360 * 100)))
        return [m.pack(mav) for m in out]


def write_stream(path, frames, seed=2026):
    """Writes `frames` MAVLink 2 frames to `path`; returns the number written."""
    rng = random.Random(seed)
    vehicles = [Vehicle(s, rng) for s in (1, 2, 3)]
    gcs = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    chunks, n, k = [], 0, 0
    while n < frames:
        t_ms = 100 * k
        tick = []
        for v in vehicles:
            tick += v.tick(t_ms, k)
        if k % 10 == 0:
            tick.append(mavlink2.MAVLink_heartbeat_message(
                mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0,
                mavlink2.MAV_STATE_ACTIVE, 3).pack(gcs))
        if k % 20 == 0:
            tick.append(mavlink2.MAVLink_command_long_message(
                1 + k // 20 % 3, 1, mavlink2.MAV_CMD_DO_REPOSITION, 0, -1.0, 1.0, 0.0,
                float("nan"), 47.4 + rng.uniform(-0.01, 0.01), 8.55 + rng.uniform(-0.01, 0.01),
                520.0).pack(gcs))
        tick = tick[:frames - n]
        chunks += tick
        n += len(tick)
        k += 1
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(b"".join(chunks))
    return n


def decode(data):
    """Decodes `data` in CHUNK-byte pieces with a fresh parser; returns the frame count."""
    mav = mavlink2.MAVLink(None)
    n = 0
    for i in range(0, len(data), CHUNK):
        msgs = mav.parse_buffer(data[i:i + CHUNK])
        if msgs:
            n += len(msgs)
    bad = mav.total_receive_errors
    if bad:
        sys.exit(f"pymavlink reported {bad} receive errors on the stream")
    return n


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--stream", type=Path, default=DEFAULT_PATH, help="the stream file")
    ap.add_argument("--frames", type=int, default=100_000, help="frames to write")
    ap.add_argument("--write", action="store_true", help="write the stream even if it exists")
    ap.add_argument("--write-only", action="store_true", help="write the stream and exit")
    ap.add_argument("--repeat", type=int, default=3, help="repeats (each decodes the whole file)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()

    if args.write or args.write_only or not args.stream.exists():
        n = write_stream(args.stream, args.frames)
        print(f"wrote {n} frames ({args.stream.stat().st_size} bytes) to {args.stream}",
              file=sys.stderr)
        if args.write_only:
            return
    data = args.stream.read_bytes()

    frames = decode(data)  # warm-up, and the count
    wall, cpu = [], []
    for _ in range(args.repeat):
        w0, c0 = time.perf_counter(), time.process_time()
        if decode(data) != frames:
            sys.exit("pymavlink decoded a different number of frames on a repeat")
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    us = [t / frames * 1e6 for t in wall]
    cpu_us = [t / frames * 1e6 for t in cpu]
    result = {
        "decoder": "pymavlink.dialects.v20.common.MAVLink.parse_buffer",
        "pymavlink": getattr(pymavlink, "__version__", None) or _dist_version("pymavlink"),
        "crc": CRC,
        "python": sys.version.split()[0],
        "stream": str(args.stream),
        "bytes": len(data),
        "frames": frames,
        "chunk": CHUNK,
        "repeat": args.repeat,
        "median_us_per_frame": statistics.median(us),
        "min_us_per_frame": min(us),
        "median_cpu_us_per_frame": statistics.median(cpu_us),
        "median_frames_per_s": frames / statistics.median(wall),
    }
    if args.json:
        print(json.dumps(result))
    else:
        print(f"pymavlink {result['pymavlink']} MAVLink 2 parse_buffer (Python, CRC: {CRC}), "
              f"Python {result['python']}: {frames} frames, {len(data)} bytes, "
              f"{CHUNK}-byte pieces")
        print(f"  median {result['median_us_per_frame']:.2f} us/frame "
              f"({result['median_frames_per_s']:.0f} frames/s), fastest "
              f"{result['min_us_per_frame']:.2f} us/frame, median CPU "
              f"{result['median_cpu_us_per_frame']:.2f} us/frame ({args.repeat} repeats)")


def _dist_version(name):
    from importlib.metadata import version
    return version(name)


if __name__ == "__main__":
    main()
