#!/usr/bin/env python3
"""Flies an ArduCopter-personality harrier-sim vehicle with MAVSDK-Python (and its bundled
mavsdk_server) through MAVSDK's ArduPilot path.

Usage: mavsdk_ardupilot.py --url udpout://127.0.0.1:PORT [--takeoff-alt 10.0]

Connects to the vehicle's API link, then: connection, the autopilot's version (ArduPilot's
encoding), health all ok, home and position, arm, takeoff (for ArduPilot MAVSDK switches to
GUIDED, its "Offboard", then sends NAV_TAKEOFF with the height above home), the climb, a goto
(MAVSDK: GUIDED, then DO_REPOSITION as a COMMAND_INT), hold (LOITER), land, landed and the
disarm after landing that ArduCopter does. Every wait is on a telemetry stream, with a deadline.
Exit code 0 on success; any failure raises. Run by tests/tests/it/mavsdk_client.rs.
"""

import argparse
import asyncio
import math
import os
import traceback
import warnings

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)
    from mavsdk import System
    from mavsdk.telemetry import FlightMode

from mavsdk_flight import east_north_m, first, free_tcp_port

EARTH_RADIUS = 6_371_000.0


def log(*args):
    print("mavsdk_ardupilot:", *args, flush=True)


def offset(origin, east, north):
    """The latitude and longitude `east`, `north` metres from `origin` (short range)."""
    lat0 = math.radians(origin.latitude_deg)
    lat = origin.latitude_deg + math.degrees(north / EARTH_RADIUS)
    lon = origin.longitude_deg + math.degrees(east / (EARTH_RADIUS * math.cos(lat0)))
    return lat, lon


async def fly(url, takeoff_alt):
    drone = System(port=free_tcp_port())
    log(f"connecting to {url}")
    await drone.connect(system_address=url)
    await first(drone.core.connection_state(), lambda s: s.is_connected, "connection", 20)
    info = await drone.info.get_version()
    log(f"autopilot version {info.flight_sw_major}.{info.flight_sw_minor}.{info.flight_sw_patch}")
    assert (info.flight_sw_major, info.flight_sw_minor, info.flight_sw_patch) == (4, 5, 7), info

    await first(drone.telemetry.health_all_ok(), lambda ok: ok, "health all ok", 20)
    home = await first(drone.telemetry.home(), lambda h: True, "home", 10)
    log(f"home {home}")
    assert abs(home.absolute_altitude_m - 488.0) < 0.1, home

    # ArduPilot keeps MAVSDK's takeoff altitude on the MAVSDK side (no MIS_TAKEOFF_ALT).
    await drone.action.set_takeoff_altitude(takeoff_alt)
    await drone.action.arm()
    await first(drone.telemetry.armed(), lambda a: a, "armed", 5)
    log("armed")
    await drone.action.takeoff()
    mode = await first(
        drone.telemetry.flight_mode(), lambda m: m == FlightMode.OFFBOARD, "GUIDED", 10
    )
    log(f"flight mode {mode} (ArduCopter GUIDED)")
    await first(drone.telemetry.in_air(), lambda a: a, "in air", 10)
    above = await first(
        drone.telemetry.position(),
        lambda p: p.relative_altitude_m > takeoff_alt - 0.3,
        f"climb to {takeoff_alt} m",
        30,
    )
    log(f"took off: {above.relative_altitude_m:.2f} m")

    # Goto 30 m east, 20 m north, 5 m higher (AMSL): DO_REPOSITION in GUIDED.
    lat, lon = offset(home, 30.0, 20.0)
    await drone.action.goto_location(lat, lon, home.absolute_altitude_m + takeoff_alt + 5.0, 0.0)
    there = await first(
        drone.telemetry.position(),
        lambda p: math.hypot(*(a - b for a, b in zip(east_north_m(home, p), (30.0, 20.0)))) < 1.0
        and abs(p.relative_altitude_m - takeoff_alt - 5.0) < 0.5,
        "the goto point",
        40,
    )
    east, north = east_north_m(home, there)
    log(f"goto: at {east:.1f} m east, {north:.1f} m north, {there.relative_altitude_m:.1f} m up")
    # Stopped there, so that LOITER holds that point (it brakes to a stop where it is).
    await first(
        drone.telemetry.velocity_ned(),
        lambda v: math.hypot(v.north_m_s, v.east_m_s, v.down_m_s) < 0.2,
        "a stop at the goto point",
        20,
    )

    await drone.action.hold()
    mode = await first(
        drone.telemetry.flight_mode(),
        lambda m: m in (FlightMode.HOLD, FlightMode.POSCTL),
        "hold",
        5,
    )
    log(f"hold: {mode}")

    await drone.action.land()
    await first(drone.telemetry.flight_mode(), lambda m: m == FlightMode.LAND, "LAND", 5)
    await first(drone.telemetry.in_air(), lambda a: not a, "landed", 60)
    await first(drone.telemetry.armed(), lambda a: not a, "disarm after landing", 15)
    landed = await first(drone.telemetry.position(), lambda p: True, "position", 5)
    east, north = east_north_m(home, landed)
    log(f"landed and disarmed {east:.1f} m east, {north:.1f} m north of home")
    assert abs(east - 30.0) < 2.0 and abs(north - 20.0) < 2.0, (east, north)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--url", required=True, help="MAVSDK connection URL of the vehicle")
    ap.add_argument("--takeoff-alt", type=float, default=10.0)
    args = ap.parse_args()
    try:
        asyncio.run(fly(args.url, args.takeoff_alt))
    except Exception:  # noqa: BLE001 - report, then exit without waiting for mavsdk_server
        traceback.print_exc()
        os._exit(1)
    log("ok")


if __name__ == "__main__":
    main()
