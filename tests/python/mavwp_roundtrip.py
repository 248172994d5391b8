#!/usr/bin/env python3
"""pymavlink's mission upload and download round trip of a QGroundControl plan's mission.

Usage: mavwp_roundtrip.py --port PORT --plan FILE [--autopilot px4|ardupilot]

Reads the .plan's mission items (QGC's JSON: command, frame, params 1-7), puts them in a
pymavlink `mavwp.MAVWPLoader` as MISSION_ITEM_INT messages (ArduPilot: home first, as MAVProxy
does), uploads them with the mission protocol as MAVProxy's wp module does (MISSION_COUNT, each
MISSION_REQUEST_INT answered with its item, MISSION_ACK), downloads the list back
(MISSION_REQUEST_LIST, MISSION_COUNT, MISSION_REQUEST_INT each), writes it with `mavwp`'s
`save()` (QGC WPL 110) and loads that file again, and checks every field of every item equal to
what was uploaded — on ArduPilot item 0 excepted, which is the vehicle's home. Prints a JSON
summary; exit code 0 on success. Run by tests/tests/it/sim_missions.rs.
"""

import argparse
import json
import os
import tempfile
import time

from pymavlink import mavutil, mavwp


def recv(m, kind, timeout=5.0):
    deadline = time.time() + timeout
    while time.time() < deadline:
        msg = m.recv_match(type=kind, blocking=True, timeout=deadline - time.time())
        if msg is not None:
            return msg
    raise TimeoutError(f"no {kind} within {timeout} s")


def plan_items(path, m, home):
    with open(path) as f:
        plan = json.load(f)
    items = []
    if home is not None:
        lat, lon, alt = home
        items.append((16, 0, [0, 0, 0, 0, lat, lon, alt]))
    for i in plan["mission"]["items"]:
        items.append((i["command"], i["frame"], [0.0 if p is None else p for p in i["params"]]))
    loader = mavwp.MAVWPLoader(target_system=m.target_system, target_component=m.target_component)
    for seq, (cmd, frame, p) in enumerate(items):
        loader.add(
            mavutil.mavlink.MAVLink_mission_item_int_message(
                m.target_system, m.target_component, seq, frame, cmd, 0, 1,
                p[0], p[1], p[2], p[3], int(round(p[4] * 1e7)), int(round(p[5] * 1e7)), p[6],
            )
        )
    return loader


def key(w):
    return (w.seq, w.frame, w.command, w.autocontinue, w.param1, w.param2, w.param3, w.param4, w.x, w.y, w.z)


def main(args):
    m = mavutil.mavlink_connection(f"udpout:127.0.0.1:{args.port}", source_system=245, source_component=190)
    m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    hb = recv(m, "HEARTBEAT", 10)
    m.target_system, m.target_component = hb.get_srcSystem(), hb.get_srcComponent()
    home = None
    if args.autopilot == "ardupilot":
        h = recv(m, "HOME_POSITION", 10)
        home = (h.latitude * 1e-7, h.longitude * 1e-7, h.altitude * 1e-3)
    up = plan_items(args.plan, m, home)
    n = up.count()

    m.waypoint_count_send(n)
    asked = []
    while True:
        msg = recv(m, ["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"])
        if msg.get_type() == "MISSION_ACK":
            assert msg.type == mavutil.mavlink.MAV_MISSION_ACCEPTED, msg
            break
        asked.append(msg.seq)
        m.mav.send(up.wp(msg.seq))
    assert asked == list(range(n)), asked

    m.waypoint_request_list_send()
    count = recv(m, "MISSION_COUNT").count
    assert count == n, (count, n)
    down = mavwp.MAVWPLoader(target_system=m.target_system, target_component=m.target_component)
    for seq in range(count):
        m.mav.mission_request_int_send(m.target_system, m.target_component, seq)
        down.add(recv(m, "MISSION_ITEM_INT"))
    m.mav.mission_ack_send(m.target_system, m.target_component, mavutil.mavlink.MAV_MISSION_ACCEPTED)

    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "mission.txt")
        down.save(path)
        reloaded = mavwp.MAVWPLoader()
        reloaded.load(path)
    skip = 1 if home is not None else 0
    for s in range(skip, n):
        a, b = key(up.wp(s)), key(down.wp(s))
        assert a == b, (s, a, b)
    # WPL 110 keeps degrees as text with six decimals: the file reloads to the same items
    # within 1e-6 degrees.
    assert reloaded.count() == n, reloaded.count()
    for s in range(n):
        a, b = down.wp(s), reloaded.wp(s)
        # mavwp keeps the file's degrees scaled to 1e7 in either message type.
        scale = 1.0 if abs(b.x) > 360 or abs(b.y) > 360 else 1e7
        assert (a.command, a.frame) == (b.command, b.frame), (a, b)
        assert abs(a.x - b.x * scale) <= 10 and abs(a.y - b.y * scale) <= 10, (s, a.x, b.x, a.y, b.y)
        assert abs(a.z - b.z) < 1e-3 and abs(a.param1 - b.param1) < 1e-6, (a, b)
    if home is not None:
        w = down.wp(0)
        assert (w.x, w.y) == (int(round(home[0] * 1e7)), int(round(home[1] * 1e7))), w
    print(json.dumps({"items": n, "requests": asked}), flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--plan", required=True)
    ap.add_argument("--autopilot", choices=["px4", "ardupilot"], default="px4")
    main(ap.parse_args())
