"""The viewer page (``cooprint view DIR`` -> DIR/sim/viewer.html) driven in Debian's headless chromium.

Issue 16's "Tested in a real browser": a small two-robot plan made here (a bar with a ledge: the
seed's three chunks, robot B waiting for A's centre chunk, overhang warnings under the ledge) and a
one-printer G-code file are simulated and viewed; each page is opened from file:// with the network
blocked, and must draw the robots' colours, play, seek from the slider, the findings and the Gantt
chart, switch colour modes, travel and the layer range, all without a console error. The page also
shows the floor grid from its first frame (a G-code preview's part far from the origin too), a layer
range as high as the material, each robot's state and progress, and disables what the plan has no
data for (a G-code file's chunks, its missing events).
"""

from __future__ import annotations

import colorsys
import io
import json

import numpy as np
import pytest
from browser import open_viewer
from PIL import Image
from solids import COARSE, box, ledge, to_trimesh

from cooprint.cli import main
from cooprint.render.palette import robot_colour
from cooprint.render.viewer import write_viewer
from cooprint.simulation import load_inputs, simulate, summary

SETTINGS = [f"--set={k}={v}" for k, v in COARSE.items()]
#: Hue tolerance (degrees) and least saturation of a pixel counted as a robot's colour under shading.
HUE_TOL, MIN_SAT = 12.0, 0.25
#: Least number of pixels (of the 1280 x 900 page's 3D view) of a robot's outline, and of its
#: material (the small test plan's: thousands of pixels each).
OUTLINE_PIXELS, MATERIAL_PIXELS = 500, 1000


def _cli(*args) -> None:
    code = main([str(a) for a in args])
    assert code == 0, f"cooprint {' '.join(map(str, args))} exited {code}"


@pytest.fixture(scope="module")
def plan(tmp_path_factory, viewer_bundle):
    """A simulated two-robot plan of a 40 x 420 x 12 mm bar with a ledge (a cantilever: overhang
    findings) and its viewer page."""
    root = tmp_path_factory.mktemp("viewer")
    to_trimesh(ledge(40, 420, 12, 16)).export(root / "bar.stl")
    out = root / "job"
    _cli("run", root / "bar.stl", "--out", out, "--robots", 2, "--simulate", "-q", "--no-picture", *SETTINGS)
    _cli("view", out)
    summary = json.loads((out / "sim" / "summary.json").read_text())
    return out, summary


@pytest.fixture(scope="module")
def gcode_view(tmp_path_factory, viewer_bundle):
    """A 30 x 30 x 4 mm box sliced for one printer, simulated alone and viewed."""
    root = tmp_path_factory.mktemp("gcode")
    to_trimesh(box(30, 30, 4)).export(root / "box.stl")
    _cli("slice", root / "box.stl", "--out", root / "part.gcode", "-q", *SETTINGS)
    _cli("simulate", root / "part.gcode", "--out", root / "part", "-q")
    _cli("view", root / "part")
    return root / "part"


@pytest.fixture(scope="module")
def view(plan, chromium):
    """The two-robot plan's page, open for the whole module (each test sets the state it needs)."""
    page = open_viewer(chromium, plan[0] / "sim" / "viewer.html")
    yield page
    page.close()


def shot(view) -> np.ndarray:
    """The 3D view (#view) as an RGB array, after the page settled."""
    view.settle()
    png = view.page.locator("#view").screenshot()
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


def reset_camera(view) -> None:
    """The camera as the page opened (a finding's click moves it): #view-reset, then the mouse off
    the button (its hover shade would differ between pictures)."""
    view.page.click("#view-reset")
    view.page.mouse.move(1, 1)


def colour_pixels(img: np.ndarray, rgb) -> int:
    """Pixels of ``img`` with the hue of ``rgb`` (within HUE_TOL) and some saturation: the colour
    as the shading leaves it (lit, shaded, antialiased)."""
    flat = img.reshape(-1, 3).astype(float) / 255.0
    mx, mn = flat.max(axis=1), flat.min(axis=1)
    sat = np.where(mx > 0, (mx - mn) / np.maximum(mx, 1e-9), 0.0)
    r, g, b = flat.T
    hue = np.degrees(np.arctan2(np.sqrt(3) * (g - b), 2 * r - g - b)) % 360  # the hexagonal hue
    ref = colorsys.rgb_to_hsv(*(c / 255.0 for c in rgb))[0] * 360
    near = np.abs((hue - ref + 180) % 360 - 180) <= HUE_TOL
    return int(np.count_nonzero(near & (sat >= MIN_SAT) & (mx > 0.15)))


def changed_pixels(a: np.ndarray, b: np.ndarray) -> int:
    """Pixels that differ by more than a little between two pictures of the same size."""
    assert a.shape == b.shape
    return int(np.count_nonzero(np.abs(a.astype(int) - b.astype(int)).max(axis=2) > 24))


def test_the_page_loads_offline_and_draws_every_robot_in_its_colour(view, plan):
    out, summary = plan
    makespan = view.hook("c.makespan")
    assert makespan == pytest.approx(summary["makespan_s"], rel=1e-6)
    assert 0 < view.hook("c.firstFrameMs") < 60_000
    view.hook("(c.pause(), c.seek(0))")
    start = shot(view)
    view.hook(f"c.seek({makespan})")
    end = shot(view)
    assert end.std() > 8, "the 3D view is blank"
    for i, robot in enumerate(summary["robots"]):
        outline, done = colour_pixels(start, robot_colour(i)), colour_pixels(end, robot_colour(i))
        # at t = 0 the robot's outline (body, frame, printhead); at the end its material too
        assert outline >= OUTLINE_PIXELS, f"robot {robot['name']}'s outline is not drawn in {robot_colour(i)}"
        assert done - outline >= MATERIAL_PIXELS, \
            f"robot {robot['name']}'s material is not drawn in its colour {robot_colour(i)} ({outline} -> {done} px)"
    view.assert_clean()


def test_play_advances_the_clock(view):
    view.hook("(c.pause(), c.seek(0), c.setSpeed(1000))")
    view.settle()
    before = view.page.locator("#clock").inner_text()
    assert view.hook("c.time()") == 0 and not view.hook("c.playing()")
    view.page.click("#play")
    view.page.wait_for_function("() => window.cooprint.time() > 5", timeout=20_000)
    assert view.hook("c.playing()")
    view.page.wait_for_function(f"() => document.querySelector('#clock').innerText !== {json.dumps(before)}",
                                timeout=20_000)
    view.page.click("#play")
    assert not view.hook("c.playing()")
    t = view.hook("c.time()")
    view.settle()
    assert view.hook("c.time()") == t, "the clock moved while paused"
    elapsed, total = view.page.locator("#clock").inner_text().split("/")
    assert elapsed.strip() != total.strip()
    view.assert_clean()


def _drag_slider_to(view, t: float) -> None:
    """Drag #time-slider's thumb from the start to the place of time ``t``."""
    view.hook("(c.pause(), c.seek(0))")
    view.settle()
    box_ = view.page.locator("#time-slider").bounding_box()
    makespan = view.hook("c.makespan")
    thumb = 8  # half of chromium's range thumb: its centre runs from left + 8 to right - 8
    y = box_["y"] + box_["height"] / 2
    x0 = box_["x"] + thumb
    x1 = x0 + (box_["width"] - 2 * thumb) * t / makespan
    view.page.mouse.move(x0, y)
    view.page.mouse.down()
    view.page.mouse.move(x1, y, steps=8)
    view.page.mouse.up()


def status_line(view, robot: str) -> str:
    """The text of robot ``robot``'s status line (#status) once the page settled."""
    view.settle()
    return " ".join(view.page.locator(f'#status [data-robot="{robot}"] > span').all_text_contents())


def test_dragging_the_slider_to_a_wait_shows_the_robot_waiting(view, plan):
    _, summary = plan
    wait = max((e for e in summary["events"] if e["kind"] == "wait"), key=lambda e: e["until_s"] - e["time_s"])
    middle = (wait["time_s"] + wait["until_s"]) / 2
    robot = wait["robot"]
    _drag_slider_to(view, middle)
    t = view.hook("c.time()")
    assert wait["time_s"] < t < wait["until_s"], f"the slider went to {t} s, not into the wait {wait}"
    assert view.hook(f"c.robotState({json.dumps(robot)})")["state"] == "waiting"
    # its status line says so, and for which event
    line = status_line(view, robot)
    assert "waiting for" in line and all(e in line for e in wait["events"]), f"robot {robot}'s status line during its wait: {line!r}"
    # and after the wait, the same robot is at work again
    view.hook(f"c.seek({wait['until_s'] + 1})")
    assert view.hook(f"c.robotState({json.dumps(robot)})")["state"] in ("printing", "travelling")
    assert "waiting" not in status_line(view, robot)
    view.assert_clean()


def test_the_status_lines_follow_each_robots_printing(view, plan):
    _, summary = plan
    view.hook("(c.pause(), c.seek(0))")
    names = [r["name"] for r in summary["robots"]]
    assert all(status_line(view, n).endswith(" 0% printed") for n in names)
    view.hook(f"c.seek({summary['makespan_s'] / 2})")
    half = {n: view.hook(f"c.robotState({json.dumps(n)})")["printed"] for n in names}
    assert all(0 < p < 1 for p in half.values()), f"halfway, each robot has printed part of its share: {half}"
    for n in names:
        assert f"{int(100 * half[n] + 1e-9)}% printed" in status_line(view, n)
    view.hook(f"c.seek({summary['makespan_s']})")
    assert [status_line(view, n) for n in names] == [f"{n} done 100% printed" for n in names]
    view.assert_clean()


def test_clicking_a_finding_jumps_to_its_time(view, plan):
    _, summary = plan
    findings = summary["findings"]
    assert findings, "the test plan should have findings (overhangs under the ledge)"
    assert view.page.locator("#findings [data-index]").count() == len(findings)
    for i in sorted(range(len(findings)), key=lambda i: -findings[i]["time_s"])[:2]:
        view.hook("c.seek(0)")
        view.page.click(f'#findings [data-index="{i}"]')
        assert view.hook("c.time()") == pytest.approx(findings[i]["time_s"], abs=1e-3 * summary["makespan_s"])
        assert view.hook("c.selectedFinding()") == i
    view.assert_clean()


def test_colour_modes_change_the_picture(view, plan):
    view.hook(f"(c.pause(), c.seek({plan[1]['makespan_s']}))")
    reset_camera(view)
    pictures = {}
    for mode in ("robot", "chunk", "role", "height"):
        view.page.select_option("#colour-mode", mode)
        assert view.hook("c.colourMode()") == mode
        pictures[mode] = (shot(view), view.page.locator("#legend").inner_text())
    modes = list(pictures)
    for i, a in enumerate(modes):
        for b in modes[i + 1:]:
            assert changed_pixels(pictures[a][0], pictures[b][0]) > 200, f"colour modes {a} and {b} look the same"
            assert pictures[a][1] != pictures[b][1], f"the legend of {a} and {b} is the same"
    view.hook("c.setColourMode('robot')")
    view.assert_clean()


def test_travel_and_the_layer_range_change_the_picture(view, plan):
    view.hook(f"(c.pause(), c.seek({plan[1]['makespan_s'] / 2}), c.setColourMode('robot'))")
    reset_camera(view)
    before = shot(view)
    view.page.click("#travel")
    toggled = shot(view)
    assert changed_pixels(before, toggled) > 20, "travel on/off did not change the picture"
    view.page.click("#travel")
    assert changed_pixels(before, shot(view)) <= 20, "travel back to how it was should give the same picture"

    view.hook(f"c.seek({plan[1]['makespan_s']})")
    full = shot(view)
    hi = view.page.locator("#layer-hi")
    lo_value, hi_value = float(hi.get_attribute("min") or 0), float(hi.get_attribute("max") or 1)
    hi.fill(str(lo_value + 0.3 * (hi_value - lo_value)))
    cut = shot(view)
    assert changed_pixels(full, cut) > 200, "lowering the top of the layer range did not change the picture"
    hi.fill(str(hi_value))
    view.assert_clean()


def test_clicking_the_gantt_chart_seeks(view, plan):
    makespan = plan[1]["makespan_s"]
    meta = view.page.evaluate("() => JSON.parse(document.getElementById('cooprint-meta').textContent)")
    view.hook("(c.pause(), c.seek(0))")
    plot = view.page.locator("#gantt .cp-gantt-plot")
    plot.scroll_into_view_if_needed()
    box_ = plot.bounding_box()
    # the time axis (its lowest 24 px): a click goes to the time under it
    axis = []
    for fraction in (0.4, 0.8):
        view.page.mouse.click(box_["x"] + fraction * box_["width"], box_["y"] + box_["height"] - 8)
        axis.append(view.hook("c.time()"))
    assert 0.2 * makespan < axis[0] < axis[1] < makespan, f"clicks on the Gantt chart's axis went to {axis}"
    # a robot's bar (row i of n, over the axis): the start of the chunk it prints there
    rows = len(meta["gantt"])
    for i, row in enumerate(meta["gantt"]):
        y = box_["y"] + 4 + (box_["height"] - 4 - 24) * (i + 0.5) / rows
        view.page.mouse.click(box_["x"] + 0.8 * box_["width"], y)
        t = view.hook("c.time()")
        starts = [c[1] for c in row["chunks"]]
        assert any(t == pytest.approx(s, abs=1e-6 * makespan) for s in starts), \
            f"a click on robot {row['name']}'s bar went to {t} s, not to one of its chunks' starts {starts}"
    view.assert_clean()


@pytest.fixture(scope="module")
def gcode_page(gcode_view, chromium):
    """The G-code preview's page, open for the module; ``first``: its 3D view as first drawn."""
    page = open_viewer(chromium, gcode_view / "sim" / "viewer.html")
    page.first = shot(page)
    yield page
    page.close()


def test_a_gcode_file_is_viewed_with_one_robot_and_no_outline(gcode_view, gcode_page):
    page = gcode_page
    summary = json.loads((gcode_view / "sim" / "summary.json").read_text())
    assert len(summary["robots"]) == 1
    name = summary["robots"][0]["name"]
    page.hook("c.seek(0)")
    start = shot(page)
    page.hook(f"c.seek({page.hook('c.makespan')})")
    end = shot(page)
    assert page.hook(f"c.robotState({json.dumps(name)})")["state"] == "done"
    assert colour_pixels(end, robot_colour(0)) >= MATERIAL_PIXELS, "the printed part is not in the robot's colour"
    # no body, frame or printhead drawn (a placed robot's take thousands of pixels): at t = 0,
    # before any material, hardly anything in the robot's colour
    assert colour_pixels(start, robot_colour(0)) < OUTLINE_PIXELS / 5
    page.assert_clean()


#: The floor grid's colours (scene.js: its lines and its centre lines).
GRID_GREYS = (0xdc, 0xb0)
#: Least grid pixels in each quarter of the first frame (a grid around the part: tens of thousands).
GRID_PIXELS = 300


def grid_pixels(img: np.ndarray) -> np.ndarray:
    """Which pixels of ``img`` are the floor grid's greys."""
    grey = (np.ptp(img.astype(int), axis=2) <= 2)
    return grey & np.isin(img[..., 0], [g + d for g in GRID_GREYS for d in (-1, 0, 1)])


def test_the_floor_grid_is_under_a_gcode_part_from_the_first_frame(gcode_page):
    # a G-code's part lies far from the origin, which the scene's box holds: the grid spans both,
    # and was once missing from the first frame (lines reaching behind the camera were dropped)
    grid = grid_pixels(gcode_page.first)
    h, w = grid.shape
    quarters = [int(grid[a:a + h // 2, b:b + w // 2].sum()) for a in (0, h // 2) for b in (0, w // 2)]
    assert min(quarters) >= GRID_PIXELS, f"floor grid pixels in the first frame's quarters: {quarters}"
    label = gcode_page.page.locator("#grid-label").inner_text()
    step = gcode_page.hook("c.gridStep()")
    assert label == (f"grid {step:g} mm" if step < 1000 else f"grid {step / 1000:g} m")
    gcode_page.assert_clean()


def test_the_layer_range_spans_the_material_not_the_travel(gcode_page, plan, view):
    layer = COARSE["slicing.layer_height"]
    for page, top in ((gcode_page, 4.0), (view, 12.0)):  # the 30 x 30 x 4 box, the 12 mm bar
        hi = page.page.locator("#layer-hi")
        assert float(hi.get_attribute("min")) == 0
        assert top - 1e-6 <= float(hi.get_attribute("max")) < top + layer, \
            f"the layer range of a {top} mm high part ends at {hi.get_attribute('max')} mm"


def test_a_gcode_preview_disables_what_it_has_no_data_for(gcode_page):
    page = gcode_page.page
    chunk = page.locator('#colour-mode option[value="chunk"]')
    assert chunk.is_disabled() and "no chunks" in chunk.get_attribute("title")
    with pytest.raises(Exception, match="no chunks"):
        gcode_page.hook("c.setColourMode('chunk')")
    assert gcode_page.hook("c.colourMode()") == "robot"
    for button in ("#prev-event", "#next-event"):  # a lone printer has no NOTIFY / WAIT
        assert page.locator(button).is_disabled()
        assert "no NOTIFY / WAIT" in page.locator(button).get_attribute("title")
    gcode_page.assert_clean()


def test_the_thinned_notice_says_so_and_can_be_closed(plan, chromium, tmp_path):
    inp = load_inputs([str(plan[0])], programs=False)
    result = simulate(inp)
    html = write_viewer(result, summary(result), tmp_path / "thin.html", max_segments=200)
    page = open_viewer(chromium, html)
    try:
        notice = page.page.locator("#notice")
        thinned = page.hook("c.thinned()")
        assert thinned and thinned["shown"] <= 200 < thinned["total"]
        assert notice.is_visible() and f"of {thinned['total']:,} material segments" in notice.inner_text()
        page.page.click("#notice-close")
        assert not notice.is_visible()
        assert page.hook("c.thinned()") == thinned  # (closed, not forgotten)
        page.assert_clean()
    finally:
        page.close()


def test_the_role_colours_name_every_role_of_the_plan(chromium, viewer_bundle, tmp_path):
    """Issue 17's roles in the viewer's "role" mode: a G-code with a patch of every extrusion role
    (PrusaSlicer's ;TYPE: names, written by cooprint's writer), simulated and viewed: the legend
    names each role present, with ROLE_COLOURS' colours, and the colourful ones are drawn."""
    import dataclasses

    from cooprint.config import SlicingSettings
    from cooprint.program.gcode import gcode_text
    from cooprint.program.stream import canonical_program
    from cooprint.render.paths import ROLE_COLOURS
    from cooprint.slicing.paths import (BRIDGE, GAP_FILL, INFILL, OVERHANG, PERIMETER_INNER, PERIMETER_OUTER,
                                        ROLE_NAMES, SKIN, TOP_SKIN, TRAVEL, LayerPaths)

    def patch(x0, y0, step, n=12):
        ys = np.arange(y0, y0 + n + 1e-9, step)
        return np.vstack([np.array([[x0, y], [x0 + n, y]])[::1 - 2 * (k % 2)] for k, y in enumerate(ys)])

    roles = (INFILL, SKIN, TOP_SKIN, BRIDGE, GAP_FILL, PERIMETER_OUTER, PERIMETER_INNER, OVERHANG)
    layers = []
    for i in range(3):
        paths = []
        for k, role in enumerate(roles):
            if paths:
                paths.append((np.array([paths[-1][0][-1], [14 * (k % 4), 14 * (k // 4)]]), TRAVEL, 0.0))
            paths.append((patch(14 * (k % 4), 14 * (k // 4), 0.5), role, 0.5))
        layers.append((i, LayerPaths.build(0.2 * (i + 1), 0.2, paths)))
    prog = canonical_program("C", layers)
    gcode = tmp_path / "roles.gcode"
    gcode.write_text(gcode_text([dataclasses.replace(prog, xyz=prog.xyz + [100.0, 100.0, 0.0])], SlicingSettings()))
    _cli("simulate", gcode, "--out", tmp_path / "roles", "-q")
    _cli("view", tmp_path / "roles")
    view = open_viewer(chromium, tmp_path / "roles" / "sim" / "viewer.html")
    try:
        view.hook(f"(c.pause(), c.seek({view.hook('c.makespan')}))")
        view.page.select_option("#colour-mode", "role")
        assert view.hook("c.colourMode()") == "role"
        legend = view.page.locator("#legend").inner_text()
        lines = [line.strip() for line in legend.splitlines() if line.strip()]
        assert sorted(lines) == sorted(ROLE_NAMES[r] for r in roles), legend
        img = shot(view)
        for role in (BRIDGE, OVERHANG, SKIN, PERIMETER_INNER):  # hues of their own (the reds and greys share)
            assert colour_pixels(img, ROLE_COLOURS[role]) > 200, ROLE_NAMES[role]
        view.assert_clean()
    finally:
        view.page.close()
