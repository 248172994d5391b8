#!/usr/bin/env python3
"""Flies a harrier-sim vehicle with the real pymavlink client, as a user would fly PX4 SITL.

Usage: pymavlink_flight.py --port PORT [--sysid 1] [--signing-key HEX [--expect-ignored S]]

Connects to the vehicle's API link (udpout:127.0.0.1:PORT), then: heartbeat with PX4 mode
decoding, telemetry (position, status, GPS, battery, home, autopilot version), parameters, message
intervals, an unsupported command, arm, takeoff to MIS_TAKEOFF_ALT, OFFBOARD with velocity
setpoints (the vehicle must move north), fallback to Hold when setpoints stop, land and disarm.
No sleeps: every wait is on a message, with a deadline. Exit code 0 on success; any failure raises.
Run by tests/tests/it/pymavlink_client.rs.

With --signing-key (64 hex characters) the client signs every message (MAVLink 2 signing,
`setup_signing`, link id 1) and accepts only correctly signed ones: every message from the vehicle
must carry a valid signature. With --expect-ignored S as well, it sends HEARTBEATs and arm
commands for S seconds and succeeds only if nothing at all comes back (a vehicle with another
key must ignore it).
"""

import argparse
import math
import os
import sys
import time

os.environ["MAVLINK20"] = "1"  # before importing mavutil: MAVLink 2 framing

from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink


def log(*args):
    print("pymavlink_flight:", *args, flush=True)


class Client:
    def __init__(self, port, sysid, signing_key=None):
        self.conn = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{port}", dialect="common", source_system=255, source_component=190
        )
        self.signed = signing_key is not None
        if self.signed:
            # No allow_unsigned_callback: unsigned and wrongly signed messages are dropped.
            self.conn.setup_signing(bytes.fromhex(signing_key), sign_outgoing=True, link_id=1)
        self.sysid = sysid
        self.last_hb = None

    def recv(self, mtype, cond=lambda m: True, timeout=5.0, on_msg=None):
        """The first message of type `mtype` from the vehicle satisfying `cond`, within `timeout` s."""
        deadline = time.monotonic() + timeout
        types = [mtype] if isinstance(mtype, str) else list(mtype)
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no {mtype} satisfying the condition within {timeout} s")
            m = self.conn.recv_match(blocking=True, timeout=min(left, 0.5))
            if m is None or m.get_srcSystem() != self.sysid:
                continue
            assert m.get_signed() == self.signed, f"signed {m.get_signed()}: {m}"
            if m.get_type() == "HEARTBEAT":
                self.last_hb = m
            if on_msg is not None:
                on_msg(m)
            if m.get_type() in types and cond(m):
                return m

    def command(self, cmd, *params, expect=mavlink.MAV_RESULT_ACCEPTED):
        p = list(params) + [0.0] * (7 - len(params))
        self.conn.mav.command_long_send(self.sysid, 1, cmd, 0, *p)
        ack = self.recv("COMMAND_ACK", lambda m: m.command == cmd)
        assert ack.result == expect, f"command {cmd}: result {ack.result}, expected {expect}"
        return ack

    def mode(self):
        return mavutil.mode_string_v10(self.last_hb)

    def wait_mode(self, name, timeout=5.0):
        self.recv("HEARTBEAT", lambda m: mavutil.mode_string_v10(m) == name, timeout)

    def param(self, name, value=None, timeout=3.0):
        if value is None:
            self.conn.mav.param_request_read_send(self.sysid, 1, name.encode(), -1)
        else:
            self.conn.mav.param_set_send(
                self.sysid, 1, name.encode(), value, mavlink.MAV_PARAM_TYPE_REAL32
            )
        m = self.recv("PARAM_VALUE", lambda m: m.param_id == name, timeout)
        return m.param_value


def ignored(c, seconds):
    """Heartbeats and arm commands for `seconds`: nothing may come back."""
    end = time.monotonic() + seconds
    sent = 0
    while time.monotonic() < end:
        c.conn.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        c.conn.mav.command_long_send(c.sysid, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
        sent += 2
        m = c.conn.recv_match(blocking=True, timeout=0.2)
        assert m is None, f"the vehicle answered a client with the wrong key: {m}"
    log(f"ignored: {sent} messages sent, nothing came back in {seconds} s")
    return 0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", type=int, required=True)
    ap.add_argument("--sysid", type=int, default=1)
    ap.add_argument("--signing-key")
    ap.add_argument("--expect-ignored", type=float)
    args = ap.parse_args()
    c = Client(args.port, args.sysid, args.signing_key)
    if args.expect_ignored is not None:
        return ignored(c, args.expect_ignored)

    # 1. Connect: announce ourselves as a GCS until the vehicle's first HEARTBEAT arrives.
    deadline = time.monotonic() + 10.0
    hb = None
    while hb is None:
        if time.monotonic() > deadline:
            raise TimeoutError("no HEARTBEAT from the vehicle within 10 s")
        c.conn.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        hb = c.conn.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
        if hb is not None and hb.get_srcSystem() != args.sysid:
            hb = None
    c.last_hb = hb
    c.conn.target_system, c.conn.target_component = hb.get_srcSystem(), hb.get_srcComponent()
    assert hb.get_srcComponent() == 1
    assert hb.autopilot == mavlink.MAV_AUTOPILOT_PX4, hb
    assert hb.type == mavlink.MAV_TYPE_QUADROTOR, hb
    assert hb.base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    assert not hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    assert "OFFBOARD" in c.conn.mode_mapping()
    assert c.mode() == "LOITER", c.mode()  # PX4 AUTO.LOITER ("Hold")
    assert hb.get_signed() == c.signed, hb
    log("heartbeat ok, mode", c.mode(), "MAVLink", c.conn.WIRE_PROTOCOL_VERSION, "signed", c.signed)

    # 2. Telemetry.
    gp = c.recv("GLOBAL_POSITION_INT")
    assert abs(gp.lat / 1e7 - 47.397742) < 1e-5 and abs(gp.lon / 1e7 - 8.545594) < 1e-5, gp
    assert abs(gp.relative_alt) < 100 and abs(gp.alt - 488000) < 100, gp
    c.recv("LOCAL_POSITION_NED")
    c.recv("ATTITUDE")
    ss = c.recv("SYS_STATUS", timeout=3)
    for bit in (mavlink.MAV_SYS_STATUS_SENSOR_GPS, mavlink.MAV_SYS_STATUS_PREARM_CHECK):
        assert ss.onboard_control_sensors_present & bit and ss.onboard_control_sensors_health & bit
    es = c.recv("EXTENDED_SYS_STATE", timeout=3)
    assert es.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND
    gps = c.recv("GPS_RAW_INT")
    assert gps.fix_type >= mavlink.GPS_FIX_TYPE_3D_FIX and gps.satellites_visible > 5
    bat = c.recv("BATTERY_STATUS", timeout=3)
    assert 0 < bat.battery_remaining <= 100
    c.recv("HOME_POSITION", timeout=5)  # streamed every 2 s
    c.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_HOME_POSITION)
    home = c.recv("HOME_POSITION")
    assert abs(home.latitude / 1e7 - 47.397742) < 1e-6 and home.altitude == 488000
    c.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    av = c.recv("AUTOPILOT_VERSION")
    assert av.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    log("telemetry ok")

    # 3. Parameters.
    assert c.param("MIS_TAKEOFF_ALT") == 2.5
    assert c.param("MIS_TAKEOFF_ALT", 4.0) == 4.0
    assert c.param("MIS_TAKEOFF_ALT", -3.0) == 4.0  # out of range: refused, value unchanged
    assert c.param("MPC_LAND_SPEED", 1.5) == 1.5
    c.conn.mav.param_request_list_send(args.sysid, 1)
    first = c.recv("PARAM_VALUE")
    seen = {first.param_id}
    while len(seen) < first.param_count:
        seen.add(c.recv("PARAM_VALUE").param_id)
    assert "MIS_TAKEOFF_ALT" in seen, seen
    log("parameters ok:", sorted(seen))

    # 4. Message intervals; an unsupported command.
    c.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 50_000)
    t0 = c.recv("LOCAL_POSITION_NED").time_boot_ms
    n = 0
    while n < 10:
        last = c.recv("LOCAL_POSITION_NED").time_boot_ms
        n += 1
    rate = n / max((last - t0) / 1000.0, 1e-3)
    assert 14 < rate < 27, f"LOCAL_POSITION_NED at {rate:.1f} Hz, expected 20"
    c.command(mavlink.MAV_CMD_DO_FLIGHTTERMINATION, expect=mavlink.MAV_RESULT_UNSUPPORTED)
    log(f"message interval ok ({rate:.1f} Hz), unsupported command ok")

    # 5. Arm and take off to MIS_TAKEOFF_ALT (param7 NaN).
    c.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
    c.recv("HEARTBEAT", lambda m: m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
    nan = float("nan")
    c.command(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, nan)
    c.wait_mode("TAKEOFF", timeout=3)
    c.recv("EXTENDED_SYS_STATE", lambda m: m.landed_state == mavlink.MAV_LANDED_STATE_IN_AIR, 10)
    c.wait_mode("LOITER", timeout=10)
    gp = c.recv("GLOBAL_POSITION_INT")
    assert abs(gp.relative_alt - 4000) < 300, gp
    log("takeoff ok, altitude", gp.relative_alt / 1000)

    # 6. OFFBOARD with velocity setpoints: 3 m/s north, one setpoint per LOCAL_POSITION_NED (20 Hz).
    vel_only = 0b0000_1101_1100_0111  # ignore position, acceleration, yaw, yaw rate

    def send_setpoint(m=None):
        if m is None or m.get_type() == "LOCAL_POSITION_NED":
            c.conn.mav.set_position_target_local_ned_send(
                0, args.sysid, 1, mavlink.MAV_FRAME_LOCAL_NED, vel_only,
                0, 0, 0, 3.0, 0.0, 0.0, 0, 0, 0, 0, 0,
            )

    start = c.recv("LOCAL_POSITION_NED", on_msg=send_setpoint)
    for _ in range(3):
        c.recv("LOCAL_POSITION_NED", on_msg=send_setpoint)
    c.conn.set_mode_px4("OFFBOARD", None, None)
    ack = c.recv("COMMAND_ACK", lambda m: m.command == mavlink.MAV_CMD_DO_SET_MODE, on_msg=send_setpoint)
    assert ack.result == mavlink.MAV_RESULT_ACCEPTED, ack
    c.recv("HEARTBEAT", lambda m: mavutil.mode_string_v10(m) == "OFFBOARD", on_msg=send_setpoint)
    # Bad input in flight: a NaN setpoint and a datagram of garbage are refused and counted (the
    # Rust side checks the counters); the vehicle keeps flying the last good setpoint.
    c.conn.mav.set_position_target_local_ned_send(
        0, args.sysid, 1, mavlink.MAV_FRAME_LOCAL_NED, vel_only,
        0, 0, 0, nan, 0.0, 0.0, 0, 0, 0, 0, 0,
    )
    c.conn.write(b"\xfd\x09 not a MAVLink frame")
    end = c.recv("LOCAL_POSITION_NED", lambda m: m.x - start.x > 8.0, 10, on_msg=send_setpoint)
    assert mavutil.mode_string_v10(c.last_hb) == "OFFBOARD", c.last_hb
    assert abs(end.y - start.y) < 0.5 and abs(end.z - start.z) < 0.5, (start, end)
    assert abs(end.vx - 3.0) < 0.3, end
    log(f"offboard ok: moved {end.x - start.x:.1f} m north at {end.vx:.2f} m/s")

    # 7. Setpoints stop: back to Hold (AUTO.LOITER) after 0.5 s, and the vehicle brakes.
    c.wait_mode("LOITER", timeout=3)
    c.recv("LOCAL_POSITION_NED", lambda m: math.hypot(m.vx, m.vy) < 0.2, 10)
    log("offboard loss -> LOITER ok")

    # 8. Land: descends, touches down, disarms.
    c.command(mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, nan, nan, nan, nan)
    c.wait_mode("LAND", timeout=3)
    c.recv("EXTENDED_SYS_STATE", lambda m: m.landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND, 15)
    c.recv("HEARTBEAT", lambda m: not m.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED, 5)
    gp = c.recv("GLOBAL_POSITION_INT")
    assert abs(gp.relative_alt) < 100, gp
    log("land and disarm ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
