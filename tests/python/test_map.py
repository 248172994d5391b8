"""The dashboard's geographic map in a real browser: headless Chromium (Debian's /usr/bin/chromium)
driven by Playwright for Python against a running `harrier demo` with no network (HARRIER_URL),
run by tests/tests/it/dashboard.rs before test_dashboard.py, in its own page:

- the offline tiles the demo rendered of its world (GET /api/v1/map names them; the server serves
  them at /tiles/{z}/{x}/{y}) are under the tracks in a screenshot (the live picture's canvas
  hidden: tile pixels, not the page's background), with their attribution and no console error;
- every track and UAV is drawn at its WGS-84 place: the pixel the page drew it at, turned back
  into latitude and longitude by Leaflet, then into the server's ENU frame by PROJ (pyproj), is
  within 2 m of where GET /api/v1/tracks (or the track's history) and GET /api/v1/vehicles put it;
- the local grid is still a choice, and the choice is kept;
- with 20 tracks and 10 UAVs moving, the geographic map alone runs at ≥ 30 fps;
- with a tile URL configured (`[map] tile_url`), the page uses it: a tile server this script runs
  (Python's http.server on port 0, logging every request) gets the tile requests and its tiles are
  drawn. tests/tests/it/dashboard.rs starts that second Harrier server when asked with a line
  `HARRIER-TILE-SERVER URL` and answers `tile-server http://HOST:PORT`.
"""

import http.server
import io
import math
import os
import pathlib
import re
import threading
import time
import zlib
import struct

import httpx
import pytest
from PIL import Image
from pyproj import Transformer

# The browser and its one page per module, the console's errors, the stress load and the way to ask
# tests/tests/it/dashboard.rs: test_dashboard.py's.
from test_dashboard import MAX_FRAME_MS, MIN_FPS, Console, ask, browser, session, stress  # noqa: F401 (fixtures)

URL = os.environ["HARRIER_URL"].rstrip("/")
SHOTS = pathlib.Path(os.environ.get("HARRIER_SCREENSHOTS", "target/screenshots"))
CONTROLLED = os.environ.get("HARRIER_RESTART_CONTROL") == "stdio"
BACKGROUND = (12, 18, 25)  # the page's #0c1219
# WGS-84 geodetic (lat, lon, h) → ECEF, by PROJ: independent of the page's and the server's code.
TO_ECEF = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=False)


def enu(origin, lat, lon, h):
    """ENU (m) of a WGS-84 position in the frame at `origin` (the API's `{lat_deg, lon_deg, alt_m}`)."""
    x0, y0, z0 = TO_ECEF.transform(origin["lat_deg"], origin["lon_deg"], origin["alt_m"])
    x, y, z = TO_ECEF.transform(lat, lon, h)
    d = (x - x0, y - y0, z - z0)
    la, lo = math.radians(origin["lat_deg"]), math.radians(origin["lon_deg"])
    e = (-math.sin(lo), math.cos(lo), 0.0)
    n = (-math.sin(la) * math.cos(lo), -math.sin(la) * math.sin(lo), math.cos(la))
    dot = lambda a: a[0] * d[0] + a[1] * d[1] + a[2] * d[2]  # noqa: E731
    return dot(e), dot(n)


def state(page):
    return page.evaluate("() => ({ready: window.harrier?.ready, map: window.harrier?.map})")


def wait_map(page, predicate, within_s, what):
    deadline = time.monotonic() + within_s
    s = None
    while time.monotonic() < deadline:
        s = state(page)
        if s.get("ready") and s.get("map") and predicate(s["map"]):
            return s["map"]
        time.sleep(0.2)
    pytest.fail(f"{what} not within {within_s} s; last map state: {s and {k: v for k, v in (s.get('map') or {}).items() if k != 'drawn'}}")


def drawn_with_latlng(page):
    """The drawn tracks and UAVs, each with the latitude and longitude under its pixel."""
    return page.evaluate(
        """() => {
      const m = window.harrier.map, v = window.harrier.mapView;
      const at = (d) => ({...d, ll: v.toLatLng(d.px[0], d.px[1])});
      return {tracks: m.drawn.tracks.map(at), uavs: m.drawn.uavs.map(at), zoom: m.zoom};
    }"""
    )


def test_offline_tiles_under_the_tracks_and_everything_at_its_wgs84_place(session):
    page, console = session
    page.goto(URL + "/", wait_until="load")
    m = wait_map(
        page,
        lambda m: m.get("mode") == "geo" and m["tracks"] >= 1 and m["uavs"] >= 3 and (m.get("tiles") or {}).get("loaded", 0) >= 4,
        45.0,
        "the geographic map with tiles, ≥ 1 track and 3 UAVs",
    )
    body = httpx.get(f"{URL}/api/v1/map", timeout=5).json()
    src = body["sources"][0]
    print(f"map: {len(body['sources'])} source(s), first {src['name']!r} {src['kind']} {src['url']} zoom {src['min_zoom']}–{src['max_zoom']}; page zoom {m['zoom']}, tiles {m['tiles']}", flush=True)
    assert src["kind"] == "mbtiles" and src["url"] == "/tiles/{z}/{x}/{y}" and src["format"] == "png"
    assert m["tiles"]["errors"] == 0 and m["tiles"]["source"] == src["name"]
    attribution = page.inner_text("#geomap .leaflet-control-attribution")
    assert src["attribution"] and src["attribution"] in attribution, attribution
    # A tile straight from the server: the PNG the page shows.
    lat, lon = body["origin"]["lat_deg"], body["origin"]["lon_deg"]
    z = 15
    x = int((lon + 180) / 360 * 2**z)
    y = int((1 - math.asinh(math.tan(math.radians(lat))) / math.pi) / 2 * 2**z)
    r = httpx.get(f"{URL}/tiles/{z}/{x}/{y}", timeout=5)
    assert r.status_code == 200 and r.headers["content-type"] == "image/png", r
    assert Image.open(io.BytesIO(r.content)).size == (256, 256)

    # Every drawn track and UAV at its place: the page's pixel → Leaflet's latitude and longitude
    # → PROJ's ENU, against REST. A track is compared with REST's estimate of the same time (its
    # state, or its history); UAVs stand on the ground.
    origin = body["origin"]
    h = origin["alt_m"] + body["plane_z"]
    worst = {"tracks": 0.0, "uavs": 0.0}
    matched = set()
    deadline = time.monotonic() + 20
    while time.monotonic() < deadline:
        d = drawn_with_latlng(page)
        rest = {k["id"]: k for k in httpx.get(f"{URL}/api/v1/tracks", timeout=5).json()["tracks"]}
        for k in d["tracks"]:
            r = rest.get(k["id"])
            if r is None:
                continue
            # REST's estimates of that time: the state, or the history (several scans may share a
            # time: every update of it is a candidate).
            want = [r["state"][:2]] if r["t"] == k["t"] else []
            if not want:
                hist = httpx.get(f"{URL}/api/v1/tracks/{k['id']}", timeout=5).json()["history"]
                want = [e[1:3] for e in hist if e[0] == k["t"]]
            if not want:
                continue
            got = enu(origin, k["ll"][0], k["ll"][1], h)
            err = min(math.hypot(got[0] - w[0], got[1] - w[1]) for w in want)
            assert err <= 2.0, f"track {k['id']} drawn {err:.2f} m from REST's estimates of its time ({got} vs {want})"
            # And where the page meant to draw it (its own store's estimate).
            assert math.hypot(got[0] - k["x"], got[1] - k["y"]) <= 2.0
            worst["tracks"] = max(worst["tracks"], err)
            matched.add(k["id"])
        if matched >= {k["id"] for k in d["tracks"]}:
            break
        time.sleep(0.1)
    drawn_ids = {k["id"] for k in drawn_with_latlng(page)["tracks"]}
    assert matched and matched >= drawn_ids - {max(drawn_ids)}, f"tracks compared {matched}, drawn {drawn_ids}"
    vehicles = {str(v["id"]): v for v in httpx.get(f"{URL}/api/v1/vehicles", timeout=5).json()["vehicles"]}
    d = drawn_with_latlng(page)
    for u in d["uavs"]:
        v = vehicles[u["label"]]
        want = v["link"]["position"]
        speed = math.hypot(*v["link"]["velocity"][:2])
        assert speed < 0.5, f"UAV {u['label']} moves at {speed:.1f} m/s: not on the ground"
        got = enu(origin, u["ll"][0], u["ll"][1], h)
        err = math.hypot(got[0] - want[0], got[1] - want[1])
        assert err <= 2.0, f"UAV {u['label']} drawn {err:.2f} m from REST's position ({got} vs {want})"
        worst["uavs"] = max(worst["uavs"], err)
    mpp = 2 * math.pi * 6378137 * math.cos(math.radians(lat)) / (256 * 2 ** d["zoom"])
    print(f"positions: {len(matched)} track(s), {len(d['uavs'])} UAVs; worst {worst['tracks']:.2f} m (tracks), {worst['uavs']:.2f} m (UAVs) at {mpp:.2f} m per pixel", flush=True)
    assert len(d["uavs"]) >= 3

    # Tiles under the tracks: the live picture's canvas hidden, the pixels around each drawn track
    # are the tiles' ground (dark greens and browns, several of them), not the page's background.
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.locator("#map-pane").screenshot(path=str(SHOTS / "geomap.png"))
    page.evaluate("() => document.querySelector('.harrier-overlay').style.visibility = 'hidden'")
    time.sleep(0.1)
    shot = Image.open(io.BytesIO(page.locator("#map").screenshot())).convert("RGB")
    page.evaluate("() => document.querySelector('.harrier-overlay').style.visibility = ''")
    shot.save(SHOTS / "geomap-tiles.png")
    tracks = drawn_with_latlng(page)["tracks"]
    for k in tracks:
        cx, cy = (int(round(v)) for v in k["px"])
        box = [shot.getpixel((i, j)) for i in range(cx - 20, cx + 21, 4) for j in range(cy - 20, cy + 21, 4) if 0 <= i < shot.width and 0 <= j < shot.height]
        background = sum(1 for p in box if max(abs(a - b) for a, b in zip(p, BACKGROUND)) <= 6)
        colours = len(set(box))
        print(f"under T{k['id']} at ({cx}, {cy}): {len(box)} pixels, {background} background, {colours} colours", flush=True)
        assert len(box) >= 60 and background == 0, f"no tiles under track {k['id']}"
        assert colours >= 2, f"one flat colour under track {k['id']}"
    assert console.errors == [], "console errors:\n" + "\n".join(console.errors)


def test_the_local_grid_is_a_choice_and_stays_chosen(session):
    page, console = session
    assert page.is_visible("#map-mode")
    page.click("button[data-map-mode=grid]")
    m = wait_map(page, lambda m: m["mode"] == "grid" and m["tracks"] >= 1 and m["uavs"] >= 3, 5.0, "the local grid")
    assert page.is_visible("#gridmap") and page.is_hidden("#geomap")
    assert page.get_attribute("#map", "data-mode") == "grid"
    assert page.evaluate("() => localStorage.getItem('harrier.map')") == "grid"
    page.locator("#map-pane").screenshot(path=str(SHOTS / "grid.png"))
    page.reload(wait_until="load")
    wait_map(page, lambda m: m["mode"] == "grid" and m["uavs"] >= 3, 20.0, "the grid again after a reload")
    page.click("button[data-map-mode=geo]")
    m = wait_map(page, lambda m: m["mode"] == "geo" and m["tracks"] >= 1 and m["uavs"] >= 3, 10.0, "back on the geographic map")
    assert page.is_visible("#geomap") and page.is_hidden("#gridmap")
    assert console.errors == [], "console errors:\n" + "\n".join(console.errors)


def test_the_geographic_map_runs_at_30_fps_with_20_tracks_and_10_uavs(session):
    """The map view alone (no 3-D view), 20 synthetic tracks and 7 more UAVs moving at 10 Hz: the
    page's own work per frame (median of 1-s p90s over 5 s) leaves room for ≥ 30 fps
    (MAX_FRAME_MS), and the median of 1-s frame rates stays above MIN_FPS, as in
    test_dashboard.py's stress test: the frame rate also depends on what else the shared CPU runs
    (up to three windows). The ≥ 30 fps figure itself is measured on an idle machine
    (BENCHMARKS.md, "Map tiles and the geographic map")."""
    page, _ = session
    page.click("button[data-view=map]")
    page.uncheck("[data-layer=bound]")
    page.evaluate(stress(20, 10))
    wait_map(page, lambda m: m["mode"] == "geo" and m["tracks"] >= 20 and m["uavs"] >= 10, 10.0, "the load drawn")
    time.sleep(2.0)
    windows = []
    for _ in range(3):
        samples = []
        for _ in range(5):
            time.sleep(1.0)
            samples.append(page.evaluate("() => [window.harrier.fps, window.harrier.frameMs]"))
        windows.append((sorted(s[0] for s in samples)[2], sorted(s[1] for s in samples)[2]))
        if windows[-1][0] >= 30 and windows[-1][1] <= MAX_FRAME_MS:
            break
    m = state(page)["map"]
    print(f"geographic map stress: {m['tracks']} tracks, {m['uavs']} UAVs; windows {', '.join(f'{a:.0f} fps {b:.1f} ms' for a, b in windows)}", flush=True)
    page.locator("#map-pane").screenshot(path=str(SHOTS / "geomap-stress.png"))
    page.evaluate("() => clearInterval(window.__stress)")
    assert max(w[0] for w in windows) >= MIN_FPS, f"the geographic map draws at {windows} (fps, ms) with 20 tracks and 10 UAVs"
    assert min(w[1] for w in windows) <= MAX_FRAME_MS, f"the page works {windows} per frame"


def tile_png():
    """A 256 × 256 PNG no generated map has: magenta, with a white cross."""
    rows = []
    for j in range(256):
        row = bytearray([0])
        for i in range(256):
            row += bytes((255, 255, 255) if i in (127, 128) or j in (127, 128) else (200, 40, 160))
        rows.append(bytes(row))
    chunk = lambda kind, data: struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))  # noqa: E731
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 256, 256, 8, 2, 0, 0, 0)) + chunk(b"IDAT", zlib.compress(b"".join(rows))) + chunk(b"IEND", b"")


class TileServer(http.server.ThreadingHTTPServer):
    """A tile server on port 0: the same PNG for every /Z/X/Y.png, every request logged."""

    def __init__(self):
        self.png = tile_png()
        self.log = []
        png, log = self.png, self.log

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self):  # noqa: N802 (http.server's name)
                log.append(self.path)
                if re.fullmatch(r"/\d+/\d+/\d+\.png", self.path):
                    self.send_response(200)
                    self.send_header("Content-Type", "image/png")
                    self.send_header("Content-Length", str(len(png)))
                    self.end_headers()
                    self.wfile.write(png)
                else:
                    self.send_error(404)

            def log_message(self, *args):
                pass

        super().__init__(("127.0.0.1", 0), Handler)


@pytest.mark.skipif(not CONTROLLED, reason="needs tests/tests/it/dashboard.rs to start a server with a tile URL")
def test_a_configured_tile_url_is_used(browser):
    tiles = TileServer()
    threading.Thread(target=tiles.serve_forever, daemon=True).start()
    template = f"http://127.0.0.1:{tiles.server_address[1]}/{{z}}/{{x}}/{{y}}.png"
    url = ask(f"HARRIER-TILE-SERVER {template}", "tile-server ").split()[1]
    ctx = browser.new_context(viewport={"width": 1200, "height": 800}, device_scale_factor=1)
    page = ctx.new_page()
    console = Console(page)
    try:
        page.goto(url + "/", wait_until="load")
        m = wait_map(page, lambda m: m.get("mode") == "geo" and (m.get("tiles") or {}).get("loaded", 0) >= 4, 20.0, "the URL's tiles loaded")
        body = httpx.get(f"{url}/api/v1/map", timeout=5).json()
        assert [s["kind"] for s in body["sources"]] == ["url"] and body["sources"][0]["url"] == template
        requested = [p for p in tiles.log if re.fullmatch(r"/\d+/\d+/\d+\.png", p)]
        print(f"tile URL: {len(requested)} tile requests (e.g. {requested[:3]}), page {m['tiles']}", flush=True)
        assert len(requested) >= m["tiles"]["loaded"] >= 4 and m["tiles"]["errors"] == 0
        assert "© Harrier test tiles" in page.inner_text("#geomap .leaflet-control-attribution")
        shot = Image.open(io.BytesIO(page.locator("#map").screenshot())).convert("RGB")
        shot.save(SHOTS / "geomap-url.png")
        px = [shot.getpixel((i, j)) for i in range(0, shot.width, 7) for j in range(0, shot.height, 7)]
        magenta = sum(1 for p in px if abs(p[0] - 200) <= 8 and abs(p[1] - 40) <= 8 and abs(p[2] - 160) <= 8)
        print(f"tile URL: {magenta} of {len(px)} sampled pixels are the tile server's", flush=True)
        assert magenta >= 0.5 * len(px), "the URL's tiles are not what the page shows"
        assert console.errors == [], "console errors:\n" + "\n".join(console.errors)
    finally:
        ctx.close()
        tiles.shutdown()
