#!/usr/bin/env python3
"""Poses as three PX4 multirotors to a ground station's GCS link and records the hand-off
messages it sends them (pymavlink).

Usage: handoff_vehicles.py --gcs 127.0.0.1:PORT --seconds S [--sysids 11,12,13]

Each vehicle (its own UDP socket, its own system id) sends a HEARTBEAT (PX4, armed, Hold, or
the mode it was last switched to) at 1 Hz and a GLOBAL_POSITION_INT 30 m above home at 10 Hz,
acknowledges every COMMAND_LONG / COMMAND_INT with MAV_RESULT_ACCEPTED, answers a
REQUEST_MESSAGE for GIMBAL_MANAGER_INFORMATION (280) as its own gimbal manager (device 154),
and records what it is sent: FOLLOW_TARGET, MAV_CMD_DO_ORBIT, MAV_CMD_DO_SET_ROI_LOCATION (with
the UNIX time of arrival). After S seconds it prints one JSON line per received message and a
summary line, then exits 0. Run by tests/tests/it/handoff.rs.
"""

import argparse
import json
import os
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

m = mavutil.mavlink
HOME = (47.397742, 8.545594, 488.0)
GIMBAL = 154


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--gcs", required=True)
    ap.add_argument("--seconds", type=float, required=True)
    ap.add_argument("--sysids", default="11,12,13")
    args = ap.parse_args()
    ids = [int(x) for x in args.sysids.split(",")]
    links = {
        i: mavutil.mavlink_connection(f"udpout:{args.gcs}", source_system=i, source_component=1)
        for i in ids
    }
    # PX4 Hold: main 4, sub 3.
    modes = {i: (4 << 16) | (3 << 24) for i in ids}
    records = []
    start = time.time()
    next_hb = next_pos = start
    while time.time() - start < args.seconds:
        now = time.time()
        if now >= next_hb:
            next_hb += 1.0
            for i, c in links.items():
                c.mav.heartbeat_send(
                    m.MAV_TYPE_QUADROTOR,
                    m.MAV_AUTOPILOT_PX4,
                    m.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | m.MAV_MODE_FLAG_SAFETY_ARMED,
                    modes[i],
                    m.MAV_STATE_ACTIVE,
                )
        if now >= next_pos:
            next_pos += 0.1
            boot = int((now - start) * 1000)
            for c in links.values():
                c.mav.global_position_int_send(
                    boot, int(HOME[0] * 1e7), int(HOME[1] * 1e7), int((HOME[2] + 30) * 1000), 30000,
                    0, 0, 0, 0,
                )
        for i, c in links.items():
            while True:
                msg = c.recv_match(blocking=False)
                if msg is None:
                    break
                t = msg.get_type()
                arrived = time.time()
                if t == "FOLLOW_TARGET":
                    records.append({
                        "vehicle": i, "kind": "follow", "time_unix": arrived,
                        "lat": msg.lat * 1e-7, "lon": msg.lon * 1e-7, "alt": msg.alt,
                        "vel": list(msg.vel), "cov": list(msg.position_cov),
                        "caps": msg.est_capabilities,
                    })
                elif t in ("COMMAND_LONG", "COMMAND_INT"):
                    if msg.target_system not in (0, i):
                        continue
                    c.mav.command_ack_send(msg.command, m.MAV_RESULT_ACCEPTED)
                    if msg.command == m.MAV_CMD_DO_SET_MODE:
                        modes[i] = (int(msg.param2) << 16) | (int(msg.param3) << 24)
                        records.append({"vehicle": i, "kind": "mode", "main": int(msg.param2),
                                        "sub": int(msg.param3)})
                    elif msg.command == m.MAV_CMD_REQUEST_MESSAGE and int(msg.param1) == 280:
                        c.mav.gimbal_manager_information_send(
                            int((arrived - start) * 1000), 0, GIMBAL, 0, 0, -1.57, 0, -3.14, 3.14)
                        records.append({"vehicle": i, "kind": "gimbal_request"})
                    elif t == "COMMAND_INT" and msg.command in (
                        m.MAV_CMD_DO_ORBIT, m.MAV_CMD_DO_SET_ROI_LOCATION
                    ):
                        records.append({
                            "vehicle": i,
                            "kind": "orbit" if msg.command == m.MAV_CMD_DO_ORBIT else "roi",
                            "time_unix": arrived, "lat": msg.x * 1e-7, "lon": msg.y * 1e-7,
                            "alt": msg.z, "param1": msg.param1, "param2": msg.param2,
                            "component": msg.target_component,
                        })
        time.sleep(0.002)
    for r in records:
        print(json.dumps(r))
    print(json.dumps({"kind": "done", "records": len(records)}), flush=True)


if __name__ == "__main__":
    main()
