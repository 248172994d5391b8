"""pymavlink as a MAVLink client of Harrier's router (run by tests/tests/it/mavlink_gcs.rs).

    python3 gcs_router_client.py --api http://127.0.0.1:8080 --token T --vehicles 1,42 --silent 42
    python3 gcs_router_client.py --connect udpout:127.0.0.1:14551 --vehicles 1,42 --command 1
    python3 gcs_router_client.py --connect udpout:127.0.0.1:14551 --vehicles 7 --command 7 --signing-key HEX
    python3 gcs_router_client.py --tlog FILE.tlog --db FILE.sqlite --vehicles 1
    python3 gcs_router_client.py --connect udpout:127.0.0.1:14551 --tracks 1
    python3 gcs_router_client.py --connect udpout:127.0.0.1:14551 --vehicles 1,2 --count 10

With --api: the vehicle routes with httpx (401, 404, 422, a refused command's ACK result, an
accepted arm, a timeout from the --silent vehicle, assignment errors, the counters in /metrics).
With --connect: connects through the router as QGroundControl or MAVProxy would, waits for every
listed vehicle's HEARTBEAT (and checks that the ground station's own, system 255, is not among
those it sees, nor is its first one: `wait_heartbeat()` must find a vehicle), then sends
COMMAND_LONG MAV_CMD_COMPONENT_ARM_DISARM (disarm) to vehicle --command and waits for its
COMMAND_ACK, which comes back through the router (with --blocked: sends it three times and fails
if any COMMAND_ACK comes within a second of each, as a router filter keeps it from the vehicle). With --tlog: reads a session's .tlog and checks
it holds HEARTBEATs of the ground station and of every listed vehicle. With --db: reads the
session file's vehicle log (telemetry, link events, command outcomes) and actions. With
--signing-key (64 hex characters) the --connect client signs everything it sends (MAVLink 2
signing, link id 1) and accepts only correctly signed messages: the router forwards the vehicles'
signed frames unchanged. With --tracks N the --connect client also waits for N of Harrier's
tracks as ADSB_VEHICLE messages from the ground station and prints each as a line
`TRACK {json}`. With --count S the --connect client, once it has the listed vehicles' HEARTBEATs,
counts every message it receives for S seconds, by source system and type, and prints a line
`COUNTS {json}`: for each `SYSTEM/TYPE` the number received and the rate, (n - 1) over the time
from the first to the last (the router's filters, tests/tests/it/mavlink_gcs.rs); with
--gcs-heartbeat the ground station's HEARTBEAT (mavlink.router_heartbeat) is no failure. Prints what it
saw; exits non-zero on any failure.
"""

import argparse
import json
import os
import sys
import time

import httpx
from pymavlink import mavutil


def fail(msg):
    print(f"gcs_router_client: FAILED: {msg}", file=sys.stderr)
    sys.exit(1)


def client(url, vehicles, command, signing_key=None, tracks=0, count_s=0.0, gcs_heartbeat=False, timeout_s=20.0,
           blocked=False):
    if signing_key:
        # Signing needs MAVLink 2 framing from the first message sent.
        os.environ["MAVLINK20"] = "1"
        mavutil.set_dialect("common")
    m = mavutil.mavlink_connection(url, source_system=200, source_component=191)
    if signing_key:
        # No allow_unsigned_callback: unsigned and wrongly signed messages are dropped.
        m.setup_signing(bytes.fromhex(signing_key), sign_outgoing=True, link_id=1)
    seen = {}
    deadline = time.monotonic() + timeout_s
    want = set(vehicles)
    # A router endpoint hears a client once it sent something: announce, then wait_heartbeat().
    m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    last_hb = time.monotonic()
    if want:
        first = None
        while first is None and time.monotonic() < deadline:
            m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            first = m.wait_heartbeat(timeout=0.5)
        if first is None:
            fail(f"{url}: no HEARTBEAT within {timeout_s} s")
        if first.get_srcSystem() not in want and not (gcs_heartbeat and first.get_srcSystem() == 255):
            fail(f"wait_heartbeat() found system {first.get_srcSystem()}, not a vehicle of {sorted(want)}")
        seen[first.get_srcSystem()] = first.type
    while not want <= set(seen) and time.monotonic() < deadline:
        if time.monotonic() - last_hb > 0.5:
            m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            last_hb = time.monotonic()
        msg = m.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
        if msg is not None:
            if signing_key and not msg.get_signed():
                fail(f"unsigned HEARTBEAT accepted: {msg}")
            seen[msg.get_srcSystem()] = msg.type
    if not want <= set(seen):
        fail(f"{url}: heartbeats seen from {sorted(seen)}, wanted {sorted(want)}")
    if 255 in seen and not gcs_heartbeat:
        fail("the ground station's own HEARTBEAT (system 255) reached a router client")
    print(f"{url}: heartbeats from {sorted(seen)}")
    if command and blocked:
        # The endpoint's incoming filter keeps the command from the vehicle: no ACK ever comes.
        for attempt in range(3):
            m.mav.command_long_send(command, 1, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, attempt, 0, 0, 0, 0, 0, 0, 0)
            ack = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=1.0)
            if ack is not None:
                fail(f"{url}: a blocked command was acknowledged: {ack}")
        print(f"{url}: 3 COMMAND_LONGs to vehicle {command}, no COMMAND_ACK (blocked)")
    elif command:
        for attempt in range(3):
            m.mav.command_long_send(command, 1, mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, attempt, 0, 0, 0, 0, 0, 0, 0)
            ack = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=2.0)
            if ack is not None and ack.command == mavutil.mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
                print(f"{url}: COMMAND_ACK from {ack.get_srcSystem()}: result {ack.result}")
                if ack.get_srcSystem() != command or ack.result != mavutil.mavlink.MAV_RESULT_ACCEPTED:
                    fail(f"unexpected ACK {ack}")
                break
        else:
            fail(f"{url}: no COMMAND_ACK from vehicle {command}")
    if tracks:
        # Harrier's confirmed tracks, as traffic from the ground station (system 255).
        got = {}
        end = time.monotonic() + timeout_s
        while len(got) < tracks and time.monotonic() < end:
            if time.monotonic() - last_hb > 0.5:
                m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
                last_hb = time.monotonic()
            msg = m.recv_match(type="ADSB_VEHICLE", blocking=True, timeout=0.5)
            if msg is None:
                continue
            if msg.get_srcSystem() != 255:
                fail(f"ADSB_VEHICLE from system {msg.get_srcSystem()}, not the ground station")
            callsign = msg.callsign if isinstance(msg.callsign, str) else msg.callsign.decode()
            got[callsign] = msg
            track = {
                "callsign": callsign.rstrip("\x00"),
                "icao": msg.ICAO_address,
                "lat": msg.lat / 1e7,
                "lon": msg.lon / 1e7,
                "alt_m": msg.altitude / 1e3,
                "heading_deg": msg.heading / 100,
                "speed_m_s": msg.hor_velocity / 100,
                "flags": msg.flags,
            }
            print("TRACK " + json.dumps(track), flush=True)
        if len(got) < tracks:
            fail(f"{url}: ADSB_VEHICLE of {sorted(got)}, wanted {tracks} tracks")
    if count_s:
        count(m, url, count_s)
    m.close()


def count(m, url, seconds):
    """Counts the messages received for `seconds`, by source system and type; prints COUNTS."""
    seen = {}
    start = time.monotonic()
    last_hb = 0.0
    while time.monotonic() - start < seconds:
        if time.monotonic() - last_hb > 0.5:
            # Stay the endpoint's peer.
            m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            last_hb = time.monotonic()
        msg = m.recv_match(blocking=True, timeout=0.2)
        if msg is None or msg.get_type() == "BAD_DATA":
            continue
        now = time.monotonic()
        c = seen.setdefault(f"{msg.get_srcSystem()}/{msg.get_type()}", [0, now, now])
        c[0] += 1
        c[2] = now
    messages = {
        k: {"n": n, "hz": (n - 1) / (last - first) if n > 1 and last > first else 0.0}
        for k, (n, first, last) in sorted(seen.items())
    }
    print("COUNTS " + json.dumps({"url": url, "seconds": seconds, "messages": messages}), flush=True)


def rest(url, token, vehicle, silent):
    """The vehicle routes through the API, with httpx: errors, a refused command, an accepted
    one, and a command to a vehicle that never acknowledges."""
    auth = {"Authorization": f"Bearer {token}"}
    with httpx.Client(base_url=url, timeout=30.0) as c:
        def cmd(v, body, headers=auth):
            return c.post(f"/api/v1/vehicles/{v}/commands", json=body, headers=headers)

        r = cmd(vehicle, {"command": "arm"}, headers={})
        if r.status_code != 401:
            fail(f"no token: {r.status_code} {r.text}")
        r = cmd(9, {"command": "arm"})
        if r.status_code != 404 or "no vehicle 9" not in r.json()["error"]:
            fail(f"unknown vehicle: {r.status_code} {r.text}")
        r = cmd(vehicle, {"command": "fly"})
        if r.status_code != 422:
            fail(f"unknown command: {r.status_code} {r.text}")
        # PX4 refuses OFFBOARD before setpoints arrive: the ACK's result is the answer.
        r = cmd(vehicle, {"command": "set_mode", "mode": "offboard"})
        body = r.json()
        if r.status_code != 200 or body["ok"] or body["result"] != "denied":
            fail(f"refused command: {r.status_code} {r.text}")
        r = cmd(vehicle, {"command": "arm"})
        body = r.json()
        if r.status_code != 200 or not body["ok"] or body["result"] != "accepted":
            fail(f"arm: {r.status_code} {r.text}")
        print(f"arm: {body}")
        r = cmd(silent, {"command": "arm"})
        body = r.json()
        if r.status_code != 504 or body["result"] != "timeout" or body["attempts"] != 3:
            fail(f"silent vehicle: {r.status_code} {r.text}")
        print(f"silent vehicle: {body}")
        v = c.get(f"/api/v1/vehicles/{vehicle}").json()
        if v["link"]["state"] != "connected" or not v["link"]["armed"] or v["link"]["rate_hz"] <= 0:
            fail(f"vehicle view: {v}")
        for body, status in [
            ({"vehicles": [9], "track": 1, "law": "togvf"}, 404),
            ({"vehicles": [], "track": 1, "law": "togvf"}, 422),
            ({"vehicles": [vehicle], "track": 1, "law": "spiral"}, 422),
            ({"vehicles": [vehicle], "track": 987654, "law": "togvf"}, 404),
        ]:
            r = c.post("/api/v1/assignments", json=body, headers=auth)
            if r.status_code != status:
                fail(f"assignment {body}: {r.status_code} {r.text}, wanted {status}")
        metrics = c.get("/api/v1/metrics").text
        for line in ['harrier_mavlink_command_results_total{result="timeout"} 1',
                     'harrier_mavlink_command_results_total{result="denied"} 1',
                     'harrier_vehicle_connected{vehicle="%d"} 1' % vehicle]:
            if line not in metrics.splitlines():
                fail(f"{line!r} not in /metrics")
        malformed = [l for l in metrics.splitlines() if l.startswith('harrier_mavlink_malformed_total{side="gcs"}')]
        if not malformed or float(malformed[0].split()[-1]) < 1:
            fail(f"garbage not counted: {malformed}")
        print("rest: ok")


def tlog(path, vehicles):
    m = mavutil.mavlink_connection(path)
    counts = {}
    while True:
        msg = m.recv_match(blocking=False)
        if msg is None:
            break
        if msg.get_type() == "HEARTBEAT":
            counts[msg.get_srcSystem()] = counts.get(msg.get_srcSystem(), 0) + 1
    print(f"{path}: HEARTBEATs by system {counts}")
    for s in set(vehicles) | {255}:
        if counts.get(s, 0) < 1:
            fail(f"{path}: no HEARTBEAT of system {s}")


def database(path, vehicle):
    """The session file's vehicle log: telemetry of the vehicle, its command outcomes."""
    import sqlite3
    db = sqlite3.connect(path)
    kinds = dict(db.execute("SELECT kind, count(*) FROM vehicle_log WHERE vehicle = ? GROUP BY kind", (vehicle,)))
    results = [r[0] for r in db.execute(
        "SELECT json_extract(json, '$.result') FROM vehicle_log WHERE kind = 'command' ORDER BY id")]
    print(f"{path}: vehicle_log of {vehicle}: {kinds}; command results {results}")
    if kinds.get("telemetry", 0) < 1 or kinds.get("event", 0) < 1:
        fail(f"no telemetry or link event of vehicle {vehicle} recorded: {kinds}")
    if "denied" not in results or "accepted" not in results or "timeout" not in results:
        fail(f"command outcomes not recorded: {results}")
    actions = db.execute("SELECT count(*) FROM actions WHERE path LIKE '%/vehicles/%/commands'").fetchone()[0]
    if actions < 5:
        fail(f"command requests not recorded as actions: {actions}")


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--connect", action="append", default=[])
    p.add_argument("--tlog")
    p.add_argument("--vehicles", default="")
    p.add_argument("--command", type=int, default=0)
    p.add_argument("--api")
    p.add_argument("--token")
    p.add_argument("--silent", type=int, default=0)
    p.add_argument("--db")
    p.add_argument("--signing-key")
    p.add_argument("--tracks", type=int, default=0, help="wait for this many tracks as ADSB_VEHICLE")
    p.add_argument("--gcs-heartbeat", action="store_true", help="the ground station's HEARTBEAT may come (mavlink.router_heartbeat)")
    p.add_argument("--count", type=float, default=0.0, help="count the messages for this many seconds")
    p.add_argument("--blocked", action="store_true", help="--command must NOT be acknowledged (a router filter blocks it)")
    a = p.parse_args()
    vehicles = [int(v) for v in a.vehicles.split(",") if v]
    if a.api:
        rest(a.api, a.token, vehicles[0], a.silent)
    for url in a.connect:
        client(url, vehicles, a.command, a.signing_key, a.tracks, a.count, a.gcs_heartbeat, blocked=a.blocked)
    if a.tlog:
        tlog(a.tlog, vehicles)
    if a.db:
        database(a.db, vehicles[0])
    print("gcs_router_client: ok")


if __name__ == "__main__":
    main()
