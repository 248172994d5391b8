#!/usr/bin/env python3
"""Flies a harrier-sim vehicle with MAVSDK-Python (and its bundled mavsdk_server), as a user would
fly PX4 SITL.

Usage: mavsdk_flight.py --url udpout://127.0.0.1:PORT [--takeoff-alt 4.0]

Connects to the vehicle's API link, then: connection, health all ok (sensors, local and global
position, home, armable), position, MIS_TAKEOFF_ALT set and read back through the param plugin,
arm, takeoff to that altitude, OFFBOARD with NED velocity setpoints (the vehicle must move east),
offboard stop (Hold), land, landed (in_air false) and the automatic disarm after landing that PX4
does. Every wait is on a telemetry stream, with a deadline. Exit code 0 on success; any failure
raises. Run by tests/tests/it/mavsdk_client.rs.
"""

import argparse
import asyncio
import math
import socket
import warnings

# mavsdk 3.17.4 warns on import that the gRPC wrapper moves to `mavsdk-grpc` from MAVSDK v4 on;
# the pinned 3.x API is the one used here.
with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)
    from mavsdk import System
    from mavsdk.offboard import OffboardError, VelocityNedYaw

EARTH_RADIUS = 6_371_000.0


def log(*args):
    print("mavsdk_flight:", *args, flush=True)


def free_tcp_port():
    """A free local TCP port for mavsdk_server's gRPC endpoint (tests may run side by side)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


async def first(stream, cond, what, timeout):
    """The first item of an async telemetry stream satisfying `cond`, within `timeout` s."""

    async def scan():
        async for item in stream:
            if cond(item):
                return item
        raise RuntimeError(f"stream ended before {what}")

    try:
        return await asyncio.wait_for(scan(), timeout)
    except asyncio.TimeoutError:
        raise TimeoutError(f"no {what} within {timeout} s") from None


def east_north_m(origin, p):
    """Local east/north offset (m) of position `p` from `origin` (equirectangular, short range)."""
    lat0 = math.radians(origin.latitude_deg)
    north = math.radians(p.latitude_deg - origin.latitude_deg) * EARTH_RADIUS
    east = math.radians(p.longitude_deg - origin.longitude_deg) * EARTH_RADIUS * math.cos(lat0)
    return east, north


async def fly(url, takeoff_alt):
    drone = System(port=free_tcp_port())
    log(f"connecting to {url}")
    await drone.connect(system_address=url)

    await first(drone.core.connection_state(), lambda s: s.is_connected, "connection", 20)
    log("connected")
    info = await drone.info.get_version()
    log(f"autopilot version {info.flight_sw_major}.{info.flight_sw_minor}.{info.flight_sw_patch}")
    assert (info.flight_sw_major, info.flight_sw_minor) == (1, 15), info

    await first(drone.telemetry.health_all_ok(), lambda ok: ok, "health all ok", 20)
    health = await first(drone.telemetry.health(), lambda h: True, "health", 5)
    log(f"health {health}")

    home = await first(drone.telemetry.home(), lambda h: True, "home", 10)
    pos = await first(drone.telemetry.position(), lambda p: True, "position", 5)
    log(f"position {pos}, home {home}")
    assert abs(pos.latitude_deg - 47.397742) < 1e-4 and abs(pos.longitude_deg - 8.545594) < 1e-4
    assert abs(pos.relative_altitude_m) < 0.2, pos
    assert abs(home.absolute_altitude_m - 488.0) < 0.1, home

    # The param plugin, and the action plugin's view of the same parameter.
    await drone.param.set_param_float("MIS_TAKEOFF_ALT", takeoff_alt)
    got = await drone.param.get_param_float("MIS_TAKEOFF_ALT")
    assert abs(got - takeoff_alt) < 1e-6, got
    got = await drone.action.get_takeoff_altitude()
    assert abs(got - takeoff_alt) < 1e-6, got
    log(f"MIS_TAKEOFF_ALT = {got}")

    await drone.action.arm()
    await first(drone.telemetry.armed(), lambda a: a, "armed", 5)
    log("armed")
    await drone.action.takeoff()
    await first(drone.telemetry.in_air(), lambda a: a, "in air", 10)
    above = await first(
        drone.telemetry.position(),
        lambda p: p.relative_altitude_m > takeoff_alt - 0.3,
        f"climb to {takeoff_alt} m",
        20,
    )
    log(f"took off: {above.relative_altitude_m:.2f} m")
    # AUTO.TAKEOFF ends in Hold (AUTO.LOITER) at the takeoff altitude.
    await first(drone.telemetry.flight_mode(), lambda m: m.name == "HOLD", "Hold after takeoff", 10)

    # OFFBOARD: an initial setpoint first (PX4 refuses OFFBOARD without one), then 2 m/s east.
    start = await first(drone.telemetry.position(), lambda p: True, "position", 5)
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 90.0))
    try:
        await drone.offboard.start()
    except OffboardError as e:
        raise AssertionError(f"offboard start refused: {e}") from None
    await first(drone.telemetry.flight_mode(), lambda m: m.name == "OFFBOARD", "OFFBOARD", 5)
    await drone.offboard.set_velocity_ned(VelocityNedYaw(0.0, 2.0, 0.0, 90.0))
    moved = await first(
        drone.telemetry.position(),
        lambda p: east_north_m(start, p)[0] > 8.0,
        "8 m east in OFFBOARD",
        15,
    )
    east, north = east_north_m(start, moved)
    log(f"offboard: moved {east:.1f} m east, {north:.1f} m north")
    assert abs(north) < 1.0, (east, north)
    assert abs(moved.relative_altitude_m - takeoff_alt) < 0.5, moved
    velocity = await first(drone.telemetry.velocity_ned(), lambda v: True, "velocity", 5)
    assert abs(velocity.east_m_s - 2.0) < 0.3 and abs(velocity.north_m_s) < 0.3, velocity
    await drone.offboard.stop()
    await first(drone.telemetry.flight_mode(), lambda m: m.name == "HOLD", "Hold after offboard", 5)
    log("offboard stopped")

    await drone.action.land()
    await first(drone.telemetry.flight_mode(), lambda m: m.name == "LAND", "LAND", 5)
    await first(drone.telemetry.in_air(), lambda a: not a, "landed", 30)
    landed = await first(drone.telemetry.position(), lambda p: True, "position", 5)
    assert abs(landed.relative_altitude_m) < 0.2, landed
    # PX4 disarms by itself after touching down (COM_DISARM_LAND); so does the simulator.
    await first(drone.telemetry.armed(), lambda a: not a, "automatic disarm after landing", 10)
    east, north = east_north_m(home, landed)
    log(f"landed and disarmed {east:.1f} m east, {north:.1f} m north of home")
    assert east > 8.0, (east, north)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--url", required=True, help="MAVSDK connection URL of the vehicle")
    ap.add_argument("--takeoff-alt", type=float, default=4.0)
    args = ap.parse_args()
    asyncio.run(fly(args.url, args.takeoff_alt))
    log("ok")  # mavsdk_server is stopped at exit


if __name__ == "__main__":
    main()
