"""The page's "Sensor biases" panel in a real browser: headless Chromium (Debian's
/usr/bin/chromium, or HARRIER_CHROMIUM) driven by Playwright, against a running server with
`[registration]`. Waits until the panel shows a row for every sensor GET /api/v1/biases lists,
then prints one JSON line: the panel's rows (`[kind, label, text]`), whether the panel is visible,
the API's list just before and just after reading the rows, and the page's console errors.
Run by tests/tests/it/live_server.rs (`registered_radars_…`).

    python3 tests/python/biases_panel.py http://127.0.0.1:8080
"""

import json
import os
import sys

import httpx
from playwright.sync_api import sync_playwright

URL = sys.argv[1].rstrip("/")
CHROMIUM = os.environ.get("HARRIER_CHROMIUM", "/usr/bin/chromium")
ARGS = ["--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]


def biases():
    r = httpx.get(f"{URL}/api/v1/biases", timeout=5)
    r.raise_for_status()
    return r.json()


def main():
    errors = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS, headless=True)
        page = browser.new_page(viewport={"width": 1600, "height": 1000})
        page.on("console", lambda m: errors.append(f"console.error: {m.text}") if m.type == "error" else None)
        page.on("pageerror", lambda e: errors.append(f"pageerror: {e}"))
        page.goto(f"{URL}/")
        sensors = len(biases())
        page.wait_for_function(
            "n => !document.getElementById('biases-panel').hidden"
            " && document.querySelectorAll('#biases tr[data-kind=sensor]').length >= n",
            arg=sensors,
            timeout=30_000,
        )
        before = biases()
        rows = page.eval_on_selector_all(
            "#biases tr", "trs => trs.map(t => [t.dataset.kind, t.cells[0].textContent, t.cells[1].textContent])"
        )
        after = biases()
        visible = page.is_visible("#biases-panel")
        browser.close()
    print(json.dumps({"rows": rows, "visible": visible, "before": before, "after": after, "errors": errors}))


if __name__ == "__main__":
    main()
