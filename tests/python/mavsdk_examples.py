#!/usr/bin/env python3
"""What MAVSDK-Python's example programs do (mavlink/MAVSDK-Python, examples/), with the same
plugins, calls and arguments, against one harrier-sim vehicle — this repository's own code, not
copies — each checking that the vehicle did what the example intends.

Usage: mavsdk_examples.py EXAMPLE --url udpout://127.0.0.1:PORT [--plan FILE] [--autopilot px4|ardupilot]

EXAMPLE:
  takeoff_and_land  arm, takeoff, land: climbed to the takeoff altitude, landed, disarmed.
  goto              arm, takeoff, goto_location 20 m north and 30 m east, 10 m higher (AMSL):
                    reached within 2 m, then land.
  mission           a MissionPlan of waypoints (speed, fly-through, one with a loiter time),
                    return to launch after the mission: upload, arm, start_mission, mission
                    progress up to N/N, is_mission_finished, home reached, landed and disarmed
                    (ArduPilot: taken off in GUIDED first, as ArduCopter does not arm in AUTO).
  mission_import    mission_raw.import_qgroundcontrol_mission of a QGC .plan (--plan), upload
                    of its mission, geofence and rally points, download of each (the same items
                    back), arm, start_mission, progress N/N.
  geofence          an inclusion polygon and an exclusion circle around home through the
                    geofence plugin: uploaded, downloaded back.
  do_orbit          arm, takeoff, do_orbit (radius 10 m, 2 m/s, centre and AMSL height as the
                    example gives them: home + 10 m): orbits at that height within 2 m and that
                    radius within 2 m; then return_to_launch: home reached, landed, disarmed.

Every wait is on a telemetry stream with a deadline; the last line is a JSON summary. Exit code 0
on success; any failure raises. Run by tests/tests/it/sim_missions.rs.
"""

import argparse
import asyncio
import json
import math
import warnings

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)
    from mavsdk import System
    from mavsdk.action import OrbitYawBehavior
    from mavsdk.geofence import Circle, FenceType, GeofenceData, Point, Polygon
    from mavsdk.mission import MissionItem, MissionPlan

# The helpers mavsdk_flight.py already has (as mavsdk_ardupilot.py takes them).
from mavsdk_flight import EARTH_RADIUS, first, free_tcp_port


def log(*args):
    print("mavsdk_examples:", *args, flush=True)


def offset(lat, lon, north, east):
    """The point `north`, `east` m from (lat, lon)."""
    dlat = math.degrees(north / EARTH_RADIUS)
    dlon = math.degrees(east / (EARTH_RADIUS * math.cos(math.radians(lat))))
    return lat + dlat, lon + dlon


def distance(a_lat, a_lon, b_lat, b_lon):
    """Horizontal distance (m), equirectangular (short range)."""
    north = math.radians(b_lat - a_lat) * EARTH_RADIUS
    east = math.radians(b_lon - a_lon) * EARTH_RADIUS * math.cos(math.radians(a_lat))
    return math.hypot(north, east)


async def connect(url):
    drone = System(port=free_tcp_port())
    await drone.connect(system_address=url)
    await first(drone.core.connection_state(), lambda s: s.is_connected, "connection", 20)
    await first(drone.telemetry.health_all_ok(), lambda ok: ok, "health all ok", 20)
    home = await first(drone.telemetry.home(), lambda h: True, "home", 10)
    log(f"connected, home {home.latitude_deg:.6f} {home.longitude_deg:.6f} {home.absolute_altitude_m:.1f}")
    return drone, home


async def takeoff(drone, alt):
    await drone.action.set_takeoff_altitude(alt)
    await drone.action.arm()
    await drone.action.takeoff()
    p = await first(
        drone.telemetry.position(), lambda p: p.relative_altitude_m > alt - 0.3, f"climb to {alt} m", 30
    )
    return p


async def land_and_disarm(drone, timeout=90):
    await first(drone.telemetry.in_air(), lambda a: not a, "landed", timeout)
    await first(drone.telemetry.armed(), lambda a: not a, "disarm after landing", 20)


async def ex_takeoff_and_land(drone, home, args):
    p = await takeoff(drone, 5.0)
    await drone.action.land()
    await land_and_disarm(drone)
    return {"climbed_m": p.relative_altitude_m}


async def ex_goto(drone, home, args):
    await takeoff(drone, 10.0)
    lat, lon = offset(home.latitude_deg, home.longitude_deg, 20.0, 30.0)
    alt = home.absolute_altitude_m + 20.0
    await drone.action.goto_location(lat, lon, alt, 0.0)
    await first(
        drone.telemetry.position(),
        lambda p: distance(lat, lon, p.latitude_deg, p.longitude_deg) < 2.0
        and abs(p.absolute_altitude_m - alt) < 2.0,
        "the goto point within 2 m",
        60,
    )
    # It holds there: settled within 0.5 m before it is landed.
    there = await first(
        drone.telemetry.position(),
        lambda p: distance(lat, lon, p.latitude_deg, p.longitude_deg) < 0.5
        and abs(p.absolute_altitude_m - alt) < 0.5,
        "a stop at the goto point",
        30,
    )
    miss = distance(lat, lon, there.latitude_deg, there.longitude_deg)
    log(f"goto: {miss:.2f} m from the point, {there.absolute_altitude_m - alt:+.2f} m in altitude")
    await drone.action.land()
    await land_and_disarm(drone)
    return {"goto_miss_m": miss}


async def progress_to_end(stream, total, timeout):
    """Mission progress up to total/total: the progress values seen."""
    seen = []

    async def scan():
        async for p in stream:
            if not seen or seen[-1] != (p.current, p.total):
                seen.append((p.current, p.total))
                log(f"mission progress: {p.current}/{p.total}")
            if p.total == total and p.current == total:
                return

    try:
        await asyncio.wait_for(scan(), timeout)
    except asyncio.TimeoutError:
        raise TimeoutError(f"mission progress {seen} never reached {total}/{total}") from None
    return seen


async def ex_mission(drone, home, args):
    items = []
    for k, (north, east, loiter) in enumerate([(30.0, 0.0, float("nan")), (30.0, 30.0, 2.0), (0.0, 30.0, float("nan"))]):
        lat, lon = offset(home.latitude_deg, home.longitude_deg, north, east)
        items.append(
            MissionItem(
                lat, lon, 15.0, 8.0, loiter != loiter, float("nan"), float("nan"),
                MissionItem.CameraAction.NONE, loiter, float("nan"), float("nan"), float("nan"),
                float("nan"), MissionItem.VehicleAction.NONE,
            )
        )
    plan = MissionPlan(items)
    await drone.mission.set_return_to_launch_after_mission(True)
    await drone.mission.upload_mission(plan)
    log("mission uploaded")
    # MAVSDK's Mission plugin answers UNSUPPORTED to downloading an ArduPilot mission (its home
    # item 0 is AMSL); the PX4 one comes back.
    back = await drone.mission.download_mission() if args.autopilot == "px4" else plan
    assert len(back.mission_items) == len(items), back
    for a, b in zip(items, back.mission_items):
        assert distance(a.latitude_deg, a.longitude_deg, b.latitude_deg, b.longitude_deg) < 0.01, (a, b)
        assert abs(a.relative_altitude_m - b.relative_altitude_m) < 0.01, (a, b)
    progress = asyncio.ensure_future(progress_to_end(drone.mission.mission_progress(), len(items), 150))
    if args.autopilot == "ardupilot":
        # ArduCopter neither arms in AUTO nor leaves the ground in it without a takeoff item:
        # up in GUIDED first (MAVSDK's takeoff), then the mission.
        await takeoff(drone, 10.0)
    else:
        await drone.action.arm()
    await drone.mission.start_mission()
    seen = await progress
    assert await drone.mission.is_mission_finished()
    await land_and_disarm(drone, 120)
    p = await first(drone.telemetry.position(), lambda p: True, "position", 5)
    off = distance(home.latitude_deg, home.longitude_deg, p.latitude_deg, p.longitude_deg)
    log(f"back home: {off:.2f} m from it")
    assert off < 2.0, off
    return {"progress": seen, "home_miss_m": off}


async def ex_mission_import(drone, home, args):
    data = await drone.mission_raw.import_qgroundcontrol_mission(args.plan)
    log(f"imported {len(data.mission_items)} mission, {len(data.geofence_items)} fence, {len(data.rally_items)} rally items")
    await drone.mission_raw.upload_mission(data.mission_items)
    await drone.mission_raw.upload_geofence(data.geofence_items)
    await drone.mission_raw.upload_rally_points(data.rally_items)

    def same(a, b):
        key = lambda i: (i.seq, i.frame, i.command, i.x, i.y, round(i.z, 3), i.mission_type)
        return [key(i) for i in a] == [key(i) for i in b]

    back = await drone.mission_raw.download_mission()
    assert same(data.mission_items, back), (data.mission_items, back)
    assert same(data.geofence_items, await drone.mission_raw.download_geofence())
    assert same(data.rally_items, await drone.mission_raw.download_rallypoints())
    log("mission, fence and rally points downloaded back unchanged")
    total = len(data.mission_items)
    progress = asyncio.ensure_future(progress_to_end(drone.mission_raw.mission_progress(), total, 150))
    await drone.action.arm()
    await drone.mission_raw.start_mission()
    seen = await progress
    return {"progress": seen}


async def ex_geofence(drone, home, args):
    lat, lon = home.latitude_deg, home.longitude_deg
    d = 0.0001
    polygon = Polygon(
        [Point(lat - d, lon - d), Point(lat + d, lon - d), Point(lat + d, lon + d), Point(lat - d, lon + d)],
        FenceType.INCLUSION,
    )
    circle = Circle(Point(lat + d / 2, lon + d / 2), 3.0, FenceType.EXCLUSION)
    await drone.geofence.upload_geofence(GeofenceData([polygon], [circle]))
    log("geofence uploaded")
    back = await drone.geofence.download_geofence()
    assert len(back.polygons) == 1 and len(back.circles) == 1, back
    got = [(round(p.latitude_deg, 7), round(p.longitude_deg, 7)) for p in back.polygons[0].points]
    want = [(round(p.latitude_deg, 7), round(p.longitude_deg, 7)) for p in polygon.points]
    assert got == want, (got, want)
    assert abs(back.circles[0].radius - 3.0) < 1e-3, back
    return {"vertices": len(got)}


async def ex_do_orbit(drone, home, args):
    await takeoff(drone, 5.0)
    position = await first(drone.telemetry.position(), lambda p: True, "position", 5)
    orbit_height = position.absolute_altitude_m + 10
    # The example's centre, from home.
    lat, lon = offset(home.latitude_deg, home.longitude_deg, 30.0, -40.0)
    await drone.action.do_orbit(
        radius_m=10,
        velocity_ms=2,
        yaw_behavior=OrbitYawBehavior.HOLD_FRONT_TO_CIRCLE_CENTER,
        latitude_deg=lat,
        longitude_deg=lon,
        absolute_altitude_m=orbit_height,
    )
    on_circle = await first(
        drone.telemetry.position(),
        lambda p: abs(distance(lat, lon, p.latitude_deg, p.longitude_deg) - 10.0) < 1.0
        and abs(p.absolute_altitude_m - orbit_height) < 1.0,
        "the orbit: radius 10 m at the asked height within 1 m",
        90,
    )
    samples = []

    async def watch():
        async for p in drone.telemetry.position():
            samples.append(p)
            if len(samples) >= 30:
                return

    await asyncio.wait_for(watch(), 30)
    worst_h = max(abs(p.absolute_altitude_m - orbit_height) for p in samples)
    worst_r = max(abs(distance(lat, lon, p.latitude_deg, p.longitude_deg) - 10.0) for p in samples)
    log(f"orbit: height within {worst_h:.2f} m, radius within {worst_r:.2f} m")
    assert worst_h < 2.0 and worst_r < 2.0, (worst_h, worst_r)
    await drone.action.return_to_launch()
    await land_and_disarm(drone, 150)
    p = await first(drone.telemetry.position(), lambda p: True, "position", 5)
    off = distance(home.latitude_deg, home.longitude_deg, p.latitude_deg, p.longitude_deg)
    log(f"returned: {off:.2f} m from home")
    assert off < 2.0, off
    return {"orbit_height_err_m": worst_h, "orbit_radius_err_m": worst_r, "home_miss_m": off,
            "first_on_circle_alt": on_circle.absolute_altitude_m}


EXAMPLES = {
    "takeoff_and_land": ex_takeoff_and_land,
    "goto": ex_goto,
    "mission": ex_mission,
    "mission_import": ex_mission_import,
    "geofence": ex_geofence,
    "do_orbit": ex_do_orbit,
}


async def main(args):
    drone, home = await connect(args.url)
    summary = await EXAMPLES[args.example](drone, home, args)
    summary["example"] = args.example
    print(json.dumps(summary), flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("example", choices=sorted(EXAMPLES))
    ap.add_argument("--url", required=True)
    ap.add_argument("--plan")
    ap.add_argument("--autopilot", choices=["px4", "ardupilot"], default="px4")
    asyncio.run(main(ap.parse_args()))
