"""A headless API client of the live ground station, as a user's script would be: httpx for REST,
websockets for the stream. Run by tests/tests/api_clients.rs against a live server fed by
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
    assert api.get("/api/v1/tracks/123456789").status_code == 404
    assert api.get("/api/v1/tracks/abc").json()["error"]
    vehicles = api.get("/api/v1/vehicles").json()["vehicles"]
    assert vehicles and all(v["scans"] > 0 for v in vehicles)
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
                assert m["type"] == "scan", m["type"]
                assert {"t", "vehicle", "sensor", "kind", "detections", "events", "tracks"} <= m.keys()
                seqs.append(m["seq"])
            elapsed = time.monotonic() - started
            assert seqs == list(range(seqs[0], seqs[0] + 20)), seqs
            assert seqs[0] > first["seq"]
            print(f"20 scan messages in {elapsed:.2f} s ({20 / elapsed:.1f} Hz), seq {seqs[0]}..{seqs[-1]}")

    asyncio.run(watch())
