import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

import browser
import pytest
from hypothesis import settings

# Locally, property tests draw new examples each run (that is how they find bugs); in CI they
# replay a fixed set, so that a landing never depends on the luck of the draw.
settings.register_profile("ci", derandomize=True, print_blob=True)
settings.register_profile("dev", print_blob=True)
settings.load_profile("ci" if os.environ.get("CI") else "dev")


@pytest.fixture(scope="module")
def car_stl(tmp_path_factory):
    """The generated car (420 mm) as an STL file (a module may define its own)."""
    from cooprint.io.bundle import write_stl
    from cooprint.models import car

    path = tmp_path_factory.mktemp("mesh") / "car.stl"
    solid = car(420.0)
    write_stl(path, solid.vertices, solid.faces)
    return path


@pytest.fixture(scope="session")
def chromium():
    """Debian's headless chromium through Playwright, one per session (tests/browser.py; skips the
    test with the reason when chromium is missing or cannot start)."""
    with browser.chromium_session() as b:
        yield b


@pytest.fixture(scope="session")
def viewer_bundle():
    """The viewer's JavaScript bundle, built when missing or stale (skips the test when it cannot be)."""
    return browser.require_bundle()
