"""Debian's chromium, driven by Playwright, for the viewer's browser tests (and the viewer benchmark).

The browser is the system's (``/usr/bin/chromium``, installed by ``make test``'s ``browser`` target),
started once per test session; Playwright's own browser download is never used. When chromium, its
driver or the viewer's JavaScript bundle is missing, the tests that need them are skipped and say
why. Pages are opened from ``file://`` with every other request aborted and recorded, and every
console error and uncaught exception collected, so a test can assert the page needed no network and
raised nothing.
"""

from __future__ import annotations

import fcntl
import shutil
import subprocess
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CHROMIUM = Path("/usr/bin/chromium")
#: Software WebGL2 (SwiftShader) works headless; no network, no updates, no sandbox (containers).
CHROMIUM_ARGS = ["--no-sandbox", "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
VIEWER_JS = REPO / "src" / "cooprint" / "render" / "viewer" / "assets" / "viewer.js"
VIEWER_SRC = REPO / "viewer"
#: How long a page may take to draw its first frame (software GL on a shared 2-core machine).
READY_TIMEOUT_MS = 60_000
#: Resolves when a paused viewer page has finished drawing: the page's own ``cooprint.idle()``
#: (nothing left to draw, the picture on the screen); on a page without it (an older one), until two
#: animation frames pass without a frame drawn (it draws only on the frame after a change, and a
#: large picture over several frames).
SETTLE_JS = """async () => {
  const c = window.cooprint, raf = () => new Promise((r) => requestAnimationFrame(r));
  if (typeof c.idle === 'function') return c.idle();
  for (let n = -1; c.frames() !== n;) { n = c.frames(); await raf(); await raf(); }
}"""


def launch_chromium(playwright):
    """Debian's chromium, headless, through Playwright; raises when it cannot start."""
    return playwright.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS, headless=True)


def _bundle_stale() -> bool:
    """Whether viewer.js is missing or older than a source of the viewer's npm project."""
    if not VIEWER_JS.exists():
        return True
    sources = [*VIEWER_SRC.glob("src/*.js"), VIEWER_SRC / "package.json", VIEWER_SRC / "package-lock.json"]
    built = VIEWER_JS.stat().st_mtime
    return any(p.exists() and p.stat().st_mtime > built for p in sources)


def ensure_bundle() -> str | None:
    """Build the viewer's JavaScript bundle when it is missing or stale (as ``make`` does: ``npm ci``
    then ``npm run build`` in viewer/, under a lock so that parallel test workers build it once);
    None when it is there, else why it could not be built."""
    if not _bundle_stale():
        return None
    if shutil.which("npm") is None:
        return (f"the viewer's bundle {VIEWER_JS.relative_to(REPO)} is missing or stale and npm is not "
                "installed: `make test` builds it (needs Node.js and npm)")
    with open(Path(tempfile.gettempdir()) / "cooprint-viewer-build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not _bundle_stale():  # another worker built it meanwhile
            return None
        steps = [["npm", "ci", "--no-audit", "--no-fund", "--loglevel=error"]] * (
            not (VIEWER_SRC / "node_modules" / "three").is_dir()) + [["npm", "run", "--silent", "build"]]
        for cmd in steps:
            proc = subprocess.run(cmd, cwd=VIEWER_SRC, capture_output=True, text=True)
            if proc.returncode != 0:
                last = (proc.stderr.strip() or proc.stdout.strip()).splitlines()[-1:] or [""]
                return f"building the viewer's bundle failed (`{' '.join(cmd)}` in viewer/: {last[0]})"
    return None


@contextmanager
def chromium_session():
    """A headless Debian chromium, closed on exit; skips the test when there is none or it cannot start."""
    sync_api = pytest.importorskip("playwright.sync_api",
                                   reason="playwright not installed: pip install -e '.[test]'")
    if not CHROMIUM.exists():
        pytest.skip(f"chromium not installed: `make test` installs Debian's chromium ({CHROMIUM} is missing; "
                    "or `apt-get install chromium`)")
    with sync_api.sync_playwright() as p:
        try:
            browser = launch_chromium(p)
        except Exception as exc:  # Playwright's own error type varies between its versions
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            pytest.skip(f"chromium could not start: {first}")
        try:
            yield browser
        finally:
            browser.close()


def require_bundle() -> Path:
    """The viewer's JavaScript bundle, built if missing or stale; skips the test when it cannot be."""
    why = ensure_bundle()
    if why:
        pytest.skip(why)
    return VIEWER_JS


@dataclass
class ViewerPage:
    """A viewer page opened from disk: the Playwright page, the requests it tried to make that were
    not ``file://`` (all aborted), and the console errors and uncaught exceptions it produced."""

    page: object
    blocked: list[str] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)

    def settle(self) -> None:
        """Wait until the (paused) page has drawn whatever was changed (SETTLE_JS)."""
        self.page.evaluate(SETTLE_JS)

    def close(self) -> None:
        """Close the page's browser context."""
        self.page.context.close()

    def hook(self, expr: str):
        """Evaluate ``expr`` with ``c`` bound to ``window.cooprint`` (awaits a Promise)."""
        return self.page.evaluate(f"async () => {{ const c = window.cooprint; return {expr}; }}")

    def assert_clean(self) -> None:
        """No network request tried, no console error or page error, none caught by the page."""
        caught = self.page.evaluate("() => (window.cooprint && window.cooprint.errors) || []")
        assert self.blocked == [], f"the page tried to reach the network: {self.blocked}"
        assert self.errors == [] and caught == [], f"errors on the page: {self.errors + list(caught)}"


def open_viewer(browser, html: Path, width: int = 1280, height: int = 900) -> ViewerPage:
    """Open ``html`` (a viewer page) in a new context of ``browser`` with the network blocked, and
    wait for its first frame (``window.cooprint.ready``)."""
    context = browser.new_context(viewport={"width": width, "height": height})
    page = context.new_page()
    view = ViewerPage(page)

    def route(r):
        if r.request.url.startswith(("file:", "data:", "blob:", "about:")):
            r.continue_()
        else:
            view.blocked.append(r.request.url)
            r.abort()

    page.route("**/*", route)
    page.on("console", lambda m: view.errors.append(f"console.{m.type}: {m.text}") if m.type == "error" else None)
    page.on("pageerror", lambda e: view.errors.append(f"pageerror: {e}"))
    page.goto(Path(html).resolve().as_uri())
    page.wait_for_function("() => window.cooprint && window.cooprint.ready", timeout=READY_TIMEOUT_MS)
    page.evaluate("""() => { window.cooprint.ready.then(() => { window.__firstFrame = 'drawn'; },
                                                       (e) => { window.__firstFrame = 'failed: ' + e; }); }""")
    page.wait_for_function("() => window.__firstFrame", timeout=READY_TIMEOUT_MS)
    state = page.evaluate("() => window.__firstFrame")
    assert state == "drawn", f"the viewer did not draw its first frame ({state}); errors: {view.errors}"
    return view
