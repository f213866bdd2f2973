"""Regenerate docs/img/viewer.png, the README's picture of the interactive viewer
(run: .venv/bin/python docs/make_viewer_screenshot.py, after `make`).

The demo's plan (the generated 700 mm car, two robots) is planned, simulated and viewed in a
temporary folder (``cooprint run car.stl --robots 2 --simulate``, ``cooprint view``); the page is
opened in headless Debian chromium (/usr/bin/chromium, through Playwright) and captured at 62% of
the makespan, the 3D view, the controls and the Gantt chart under it on screen.
"""

from __future__ import annotations

import io
import sys
import tempfile
from pathlib import Path

from PIL import Image

from cooprint.cli import main as cooprint
from cooprint.io.bundle import write_stl
from cooprint.models import car

OUT = Path(__file__).parent / "img" / "viewer.png"
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from browser import SETTLE_JS, launch_chromium  # noqa: E402  (the tests' chromium set-up)
VIEWPORT = {"width": 1400, "height": 1000}
AT = 0.62  # of the makespan: both robots at work, robot B past its wait


def main() -> int:
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        solid = car(700.0)
        write_stl(root / "car.stl", solid.vertices, solid.faces, name="demo car")
        for args in (["run", root / "car.stl", "--out", root / "car", "--robots", "2", "--simulate", "-q",
                      "--no-picture"], ["view", root / "car"]):
            if cooprint([str(a) for a in args]) != 0:
                return 1
        with sync_playwright() as p:
            browser = launch_chromium(p)
            page = browser.new_page(viewport=VIEWPORT)
            page.goto((root / "car" / "sim" / "viewer.html").as_uri())
            page.wait_for_function("() => window.cooprint && window.cooprint.ready", timeout=120_000)
            page.evaluate("() => window.cooprint.ready.then(() => true)")
            page.evaluate(f"() => {{ const c = window.cooprint; c.pause(); c.seek(c.makespan * {AT}); }}")
            page.evaluate(SETTLE_JS)  # until the picture at that time is drawn whole
            png = page.screenshot(full_page=True)
            browser.close()
    OUT.parent.mkdir(exist_ok=True)
    Image.open(io.BytesIO(png)).convert("RGB").save(OUT, optimize=True)
    print(f"wrote {OUT} ({OUT.stat().st_size / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
