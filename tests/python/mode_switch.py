"""A router client switches a vehicle's flight mode as QGroundControl's and MAVProxy's flight-mode
menus do (run by tests/tests/it/authority.rs).

    python3 mode_switch.py --connect udpout:127.0.0.1:14551 --vehicle 2 --mode LOITER

Connects through Harrier's MAVLink router, waits for the vehicle's HEARTBEAT, then asks for the
mode with pymavlink's own `set_mode` (MAVProxy's `mode` command calls the same: for PX4,
COMMAND_LONG MAV_CMD_DO_SET_MODE with the custom main and sub mode, as QGroundControl sends;
for ArduPilot, the mode number), and waits until a HEARTBEAT of the vehicle shows the mode (or
the COMMAND_ACK refuses it). Mode names are pymavlink's (`mode_mapping()` of the vehicle: PX4
`LOITER` is AUTO.LOITER, Hold). Prints `MODE {json}` with the ACK's result and the seconds it
took; exits non-zero on any failure.
"""

import argparse
import json
import sys
import time

from pymavlink import mavutil


def fail(msg):
    print(f"mode_switch: FAILED: {msg}", file=sys.stderr)
    sys.exit(1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--connect", required=True, help="pymavlink connection string of the router")
    ap.add_argument("--vehicle", type=int, required=True, help="system id")
    ap.add_argument("--mode", required=True, help="pymavlink mode name (LOITER, RTL, ...)")
    ap.add_argument("--timeout", type=float, default=20.0)
    args = ap.parse_args()

    m = mavutil.mavlink_connection(args.connect, source_system=246, source_component=190)
    deadline = time.monotonic() + args.timeout
    # A router endpoint hears a client once it sent something.
    hb = None
    while hb is None:
        if time.monotonic() > deadline:
            fail(f"no HEARTBEAT of vehicle {args.vehicle}")
        m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        msg = m.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
        if msg is not None and msg.get_srcSystem() == args.vehicle and msg.type != mavutil.mavlink.MAV_TYPE_GCS:
            hb = msg
    m.target_system, m.target_component = args.vehicle, 1
    # The vehicle's own mode table, from its HEARTBEAT (pymavlink's `mode_mapping()` reads the
    # last HEARTBEAT of any system, and a router carries several).
    px4 = hb.autopilot == mavutil.mavlink.MAV_AUTOPILOT_PX4
    mapping = mavutil.px4_map if px4 else mavutil.mode_mapping_byname(hb.type)
    if not mapping or args.mode not in mapping:
        fail(f"mode {args.mode} not in the vehicle's table {sorted(mapping or {})}")
    started = time.monotonic()
    if px4:
        # What QGroundControl and pymavlink's set_mode_px4 send: base mode, main, sub.
        base, main, sub = mapping[args.mode]
        m.mav.command_long_send(args.vehicle, 1, mavutil.mavlink.MAV_CMD_DO_SET_MODE, 0, base, main, sub, 0, 0, 0, 0)
    else:
        m.set_mode_apm(mapping[args.mode])
    result = None
    while time.monotonic() < deadline:
        msg = m.recv_match(type=["COMMAND_ACK", "HEARTBEAT"], blocking=True, timeout=0.5)
        if msg is None or msg.get_srcSystem() != args.vehicle:
            continue
        if msg.get_type() == "COMMAND_ACK" and msg.command == mavutil.mavlink.MAV_CMD_DO_SET_MODE:
            result = msg.result
            if result != mavutil.mavlink.MAV_RESULT_ACCEPTED:
                fail(f"DO_SET_MODE refused: result {result}")
        elif msg.get_type() == "HEARTBEAT" and mavutil.mode_string_v10(msg) == args.mode:
            out = {"vehicle": args.vehicle, "mode": args.mode, "ack": result, "seconds": time.monotonic() - started}
            print("MODE " + json.dumps(out), flush=True)
            return
    fail(f"vehicle {args.vehicle} not seen in {args.mode} within {args.timeout} s (ACK result {result})")


if __name__ == "__main__":
    main()
