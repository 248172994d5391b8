"""A headless API client of the live ground station, as a user's script would be: httpx for REST,
websockets for the stream. Run by tests/tests/it/api_clients.rs against a live server fed by
harrier-sim over real Zenoh (HARRIER_URL, HARRIER_TOKEN in the environment).

    HARRIER_URL=http://127.0.0.1:8080 HARRIER_TOKEN=... python3 -m pytest tests/python/test_api_client.py
"""

import asyncio
import json
import os
import time

import httpx
import pytest
import websockets

URL = os.environ["HARRIER_URL"]
TOKEN = os.environ["HARRIER_TOKEN"]
AUTH = {"Authorization": f"Bearer {TOKEN}"}
# A second, named token of `[[api.tokens]]`, and one whose `expires` is in the past.
SECOND_TOKEN = os.environ["HARRIER_SECOND_TOKEN"]
EXPIRED_TOKEN = os.environ["HARRIER_EXPIRED_TOKEN"]


@pytest.fixture(scope="module")
def api():
    with httpx.Client(base_url=URL, timeout=10.0) as c:
        yield c


def confirmed_tracks(api, within_s=60.0):
    """Polls until the tracker reports a confirmed track."""
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        r = api.get("/api/v1/tracks")
        assert r.status_code == 200, r.text
        body = r.json()
        if body["tracks"]:
            return body
        time.sleep(0.2)
    pytest.fail(f"no confirmed track within {within_s} s")


def test_health_and_estimators(api):
    h = api.get("/api/v1/health").json()
    assert h["status"] == "ok"
    names = [e["name"] for e in api.get("/api/v1/estimators").json()["estimators"]]
    assert {"ekf", "cdkf", "imm", "cimm"} <= set(names)


def test_list_tracks_and_one_track(api):
    body = confirmed_tracks(api)
    k = body["tracks"][0]
    assert k["status"] == "confirmed" and len(k["state"]) == 6
    d = api.get(f"/api/v1/tracks/{k['id']}")
    assert d.status_code == 200, d.text
    d = d.json()
    major, minor = d["ellipse_95"]["semi_axes"]
    assert major >= minor > 0
    assert d["history"] and len(d["history"][-1]) == 4
    bound = d["bound"]  # the set-membership bound runs beside the tracks in this deployment
    assert bound and len(bound["center"]) == 4 and len(bound["shape"]) == 4
    assert bound["semi_axes"][0] >= bound["semi_axes"][1] > 0
    assert api.get("/api/v1/tracks/123456789").status_code == 404
    assert api.get("/api/v1/tracks/abc").json()["error"]
    vehicles = api.get("/api/v1/vehicles").json()["vehicles"]
    assert vehicles and all(v["detections"]["scans"] > 0 for v in vehicles)
    one = api.get(f"/api/v1/vehicles/{vehicles[0]['id']}")
    assert one.status_code == 200 and one.json()["id"] == vehicles[0]["id"], one.text
    assert api.get("/api/v1/vehicles/200").status_code == 404
    assert api.get("/api/v1/vehicles/300").status_code == 400
    scans = api.get("/api/v1/detections").json()["scans"]
    assert scans and scans[-1]["seq"] >= scans[0]["seq"]


def test_changing_the_estimator_needs_the_token_and_keeps_the_tracks(api):
    before = {k["id"] for k in confirmed_tracks(api)["tracks"]}
    change = {"name": "imm", "params": {}}
    assert api.put("/api/v1/estimator", json=change).status_code == 401
    wrong = {"Authorization": "Bearer not-the-token"}
    assert api.put("/api/v1/estimator", json=change, headers=wrong).status_code == 401
    r = api.put("/api/v1/estimator", content=b"{not json", headers={**AUTH, "Content-Type": "application/json"})
    assert r.status_code == 400 and r.json()["error"]
    r = api.put("/api/v1/estimator", json={"params": {}}, headers=AUTH)
    assert r.status_code == 422 and "name" in r.json()["error"]
    r = api.put("/api/v1/estimator", json={"name": "nonesuch"}, headers=AUTH)
    assert r.status_code == 422 and "nonesuch" in r.json()["error"]
    assert api.get("/api/v1/estimator").json()["name"] != "nonesuch"

    original = api.get("/api/v1/estimator").json()
    r = api.put("/api/v1/estimator", json=change, headers=AUTH)
    assert r.status_code == 200, r.text
    assert api.get("/api/v1/estimator").json()["name"] == "imm"
    assert api.get("/api/v1/health").json()["estimator"] == "imm"
    after = {k["id"] for k in api.get("/api/v1/tracks").json()["tracks"]}
    assert before & after, f"the tracks {before} were not handed over: {after}"
    r = api.put("/api/v1/estimator", json=original, headers=AUTH)
    assert r.status_code == 200 and r.json()["name"] == original["name"]


def mutating_routes(api):
    """Every (method, path) of the OpenAPI document that is not a read, path parameters set."""
    doc = api.get("/api/openapi.json").json()
    routes = []
    for path, item in doc["paths"].items():
        for method in item:
            if method in ("post", "put", "patch", "delete"):
                routes.append((method.upper(), path.replace("{id}", "1")))
    return routes


def test_every_mutating_route_refuses_missing_wrong_and_expired_tokens(api):
    routes = mutating_routes(api)
    # The estimator, assignments, vehicle commands and sessions routes at least.
    assert len(routes) >= 4, routes
    for method, path in routes:
        cases = {
            "missing": {},
            "wrong": {"Authorization": "Bearer not-the-token-at-all"},
            "expired": {"Authorization": f"Bearer {EXPIRED_TOKEN}"},
            "malformed": {"Authorization": f"Bearer{TOKEN}"},
        }
        for case, headers in cases.items():
            r = api.request(method, path, json={}, headers=headers)
            assert r.status_code == 401, f"{method} {path} with a {case} token: {r.status_code} {r.text}"
            assert r.headers["www-authenticate"].startswith("Bearer"), (method, path, case)
            if case == "expired":
                assert "expired" in r.json()["error"] and '"ci"' in r.json()["error"], r.text
                assert 'error="invalid_token"' in r.headers["www-authenticate"]
        # Both valid tokens pass the guard (the body `{}` is then refused or served by the route).
        for token in (TOKEN, SECOND_TOKEN):
            r = api.request(method, path, json={}, headers={"Authorization": f"Bearer {token}"})
            assert r.status_code != 401, f"{method} {path} with a valid token: {r.text}"
    # Reads need no token by default; the WebSocket takes no commands (client messages are
    # ignored), so the mutating routes are all there is to guard.
    assert api.get("/api/v1/tracks").status_code == 200
    metrics = api.get("/api/v1/metrics").text
    for reason in ("auth_missing", "auth_wrong", "auth_expired"):
        assert f'reason="{reason}"' in metrics, reason


def test_cors_is_locked_to_the_served_origin(api):
    """No `Access-Control-Allow-Origin` for another site's page: its browser refuses to read the
    response and to send a mutating request after the preflight."""
    evil = "http://evil.example:8000"
    r = api.get("/api/v1/tracks", headers={"Origin": evil})
    assert r.status_code == 200 and "access-control-allow-origin" not in r.headers
    preflight = api.options(
        "/api/v1/estimator",
        headers={
            "Origin": evil,
            "Access-Control-Request-Method": "PUT",
            "Access-Control-Request-Headers": "authorization,content-type",
        },
    )
    assert "access-control-allow-origin" not in preflight.headers, preflight.headers
    assert "access-control-allow-methods" not in preflight.headers, preflight.headers


def test_the_websocket_streams_a_snapshot_then_every_scan():
    async def watch():
        ws_url = URL.replace("http://", "ws://") + "/api/v1/ws"
        async with websockets.connect(ws_url, open_timeout=10) as ws:
            first = json.loads(await asyncio.wait_for(ws.recv(), 10))
            assert first["type"] == "snapshot" and first["dropped"] == 0
            assert "tracks" in first and "estimator" in first
            seqs, started = [], time.monotonic()
            while len(seqs) < 20:
                m = json.loads(await asyncio.wait_for(ws.recv(), 10))
                assert m["type"] in ("scan", "vehicles", "vehicle_event", "assignment"), m["type"]
                if m["type"] != "scan":
                    continue
                assert {"t", "vehicle", "sensor", "kind", "detections", "events", "tracks"} <= m.keys()
                seqs.append(m["seq"])
            elapsed = time.monotonic() - started
            assert seqs == list(range(seqs[0], seqs[0] + 20)), seqs
            assert seqs[0] > first["seq"]
            print(f"20 scan messages in {elapsed:.2f} s ({20 / elapsed:.1f} Hz), seq {seqs[0]}..{seqs[-1]}")

    asyncio.run(watch())


def zenoh_session():
    """A peer session to the server's Zenoh endpoint (HARRIER_ZENOH), as a second consumer would open."""
    import zenoh

    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("connect/endpoints", json.dumps([os.environ["HARRIER_ZENOH"]]))
    conf.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
    return zenoh.open(conf)


def test_tracks_are_published_on_zenoh():
    got = []
    with zenoh_session() as session:
        sub = session.declare_subscriber("harrier/v1/tracks")
        deadline = time.monotonic() + 30
        while len(got) < 3 and time.monotonic() < deadline:
            sample = sub.try_recv()
            if sample is None:
                time.sleep(0.05)
                continue
            assert str(sample.key_expr) == "harrier/v1/tracks"
            got.append(json.loads(sample.payload.to_bytes()))
    assert len(got) >= 3, f"{len(got)} track messages in 30 s"
    for m in got:
        assert m["schema"] == "harrier-tracks/1"
        assert {"time_unix", "t", "seq", "estimator", "frame", "tracks"} <= m.keys()
        assert all(k["status"] == "confirmed" and len(k["state"]) == 6 for k in m["tracks"])
    assert [m["seq"] for m in got] == sorted(m["seq"] for m in got)
    assert any(m["tracks"] for m in got)


def metric(api, series):
    for line in api.get("/api/v1/metrics").text.splitlines():
        if line.startswith(series + " "):
            return float(line.split()[-1])
    return 0.0


def test_bad_payloads_are_refused_counted_and_tracking_goes_on(api):
    scan = json.loads(json.dumps(api.get("/api/v1/detections").json()["scans"][-1]))
    good = {
        "schema": "harrier-detections/1", "t": 1.0, "vehicle": 7, "seq": 1, "sensor": "cam",
        "kind": "position", "noise_std": [5.0, 5.0],
        "origin": {"lat_deg": 47.397742, "lon_deg": 8.545594, "alt_m": 488.0},
        "platform": {"pos": [0, 0, 0], "vel": [0, 0, 0], "attitude": [0, 0, 0],
                     "geodetic": {"lat_deg": 47.397742, "lon_deg": 8.545594, "alt_m": 488.0}},
        "detections": [{"z": [10.0, 20.0]}],
    }
    nan = dict(good, detections=[{"z": [float("nan"), 20.0]}])  # json.dumps writes NaN
    negative = dict(good, noise_std=[-1.0, 5.0])
    short = dict(good, detections=[{"z": [1.0]}])
    ingested = sum(metric(api, f'harrier_scans_ingested_total{{vehicle="{v}"}}') for v in ("1", "2"))
    series = lambda r: f'harrier_scans_dropped_total{{vehicle="7",reason="{r}"}}'
    with zenoh_session() as session:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            session.put("harrier/v1/vehicle/7/detections", b"\x00\xffnot json")
            session.put("harrier/v1/vehicle/7/detections", json.dumps(nan))
            session.put("harrier/v1/vehicle/7/detections", json.dumps(negative))
            session.put("harrier/v1/vehicle/7/detections", json.dumps(short))
            if metric(api, series("json")) >= 2 and metric(api, series("invalid")) >= 2:
                break
            time.sleep(0.2)
    assert metric(api, series("json")) >= 2, "garbage and NaN payloads not counted as json"
    assert metric(api, series("invalid")) >= 2, "negative noise and short z not counted as invalid"
    assert metric(api, 'harrier_scans_ingested_total{vehicle="7"}') == 0
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        now = sum(metric(api, f'harrier_scans_ingested_total{{vehicle="{v}"}}') for v in ("1", "2"))
        if now > ingested:
            break
        time.sleep(0.2)
    assert now > ingested, "tracking stopped after the bad payloads"
    assert api.get("/api/v1/health").json()["status"] == "ok"
    assert scan["seq"] > 0


def test_the_session_is_recorded_and_exports_as_a_scenario(api):
    body = api.get("/api/v1/sessions").json()
    assert body["file"] and body["current"] is not None
    current = body["current"]
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        info = api.get(f"/api/v1/sessions/{current}").json()
        # The estimator changes of the test above are actions, committed within flush_ms.
        if info["scans"] > 0 and info["track_rows"] > 0 and info["actions"] >= 2:
            break
        time.sleep(0.2)
    assert info["scans"] > 0 and info["detections"] > 0 and info["track_rows"] > 0, info
    assert info["actions"] >= 2, info
    assert info["ended_unix"] is None
    assert api.get("/api/v1/sessions/999999").status_code == 404
    assert api.get("/api/v1/sessions/x").status_code == 400
    e = api.get(f"/api/v1/sessions/{current}/export")
    assert e.status_code == 200, e.text
    e = e.json()
    scenario = json.loads(e["scenario_json"])
    assert scenario["format"] == "gcs-scenario/1"
    lines = [json.loads(line) for line in e["measurements_jsonl"].splitlines()]
    assert len(lines) == e["lines"] > 0
    assert all(l["sensor"] in e["sensors"] for l in lines)
    assert e["truth_csv"], "the sim's truth was recorded"
