"""The fleet's scene in the snapshot, the MP4 and the GIF (issue 16, "the pictures that exist,
fixed"): robots drawn whole as boxes and hidden where the print is nearer to the camera, a G-code
printer drawn with its nozzle only, a floor grid with a scale, the view framed on the part, and
every robot's name and progress bar inside the picture at any size."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image, ImageDraw

from cooprint.config import RobotProfile, SlicingSettings
from cooprint.jobs import robot_names
from cooprint.program.commands import parse_coop
from cooprint.render.chunks import BACKGROUND
from cooprint.render.kernels import NO_DEPTH
from cooprint.render.palette import robot_colour
from cooprint.render.sim import GRID_COLOUR, NOZZLE_WIDTH, _deposited, _Scene, overlay_layout, render_animation, render_snapshot
from cooprint.simulation import SimInput, simulate
from cooprint.simulation.inputs import read_gcode
from cooprint.simulation.timeline import SimRobot

#: A small robot (the default's 350 x 300 mm body would dwarf these scenes).
SMALL = RobotProfile(build_depth=60.0, body_length=60.0, body_width=60.0, nozzle_height=30.0, nozzle_depth=10.0)
#: The default view's directions on the floor: towards the camera, and to the picture's right.
TOWARDS = np.array([np.cos(np.radians(-35.0)), np.sin(np.radians(-35.0))])
RIGHT = np.array([-TOWARDS[1], TOWARDS[0]])


def _robot(name: str, text: str, start, facing, profile=SMALL) -> SimRobot:
    return SimRobot(name, parse_coop(text, name), np.array(start, float), np.asarray(facing, float), profile=profile)


def _sim(robots, profile=SMALL):
    return simulate(SimInput(robots, profile, SlicingSettings(), "test"), checks=False)


def _picture(res, t: float, size=(1280, 720), robots: bool = True):
    """What :func:`render_snapshot` draws before its overlay: the picture, the picture before
    the robots, the depth picture and the scene."""
    scene = _Scene(res, size, -35.0, 30.0)
    rgb, depth = scene.canvas()
    scene.material(rgb, depth, *_deposited(res, t), sort=True)
    before = rgb.copy()
    if robots:
        scene.robots(rgb, depth, t)
    return rgb, before, depth, scene


def _silhouette(scene, solids) -> np.ndarray:
    """(h, w) bool: the pixels the boxes ``solids`` cover (their faces seen from the camera)."""
    mask = Image.new("L", scene.size, 0)
    draw = ImageDraw.Draw(mask)
    for s in solids:
        for quad, _, _, _ in s.faces(scene):
            draw.polygon([tuple(q) for q in quad.tolist()], fill=255, outline=255)
    return np.asarray(mask) > 0


@pytest.fixture(scope="module")
def wall_scene():
    """A prints a wall 200 mm wide and 120 mm tall square to the view; B stands behind it (seen
    from the camera), its printhead's top above the wall; C stands in front of it."""
    layers = np.arange(2.0, 121.0, 2.0)
    text = f"MOVE {-100 * RIGHT[0]:.3f} {-100 * RIGHT[1]:.3f} 2\nTOOL ON\n"
    for k, z in enumerate(layers):
        s = 100 if k % 2 == 0 else -100
        text += f"MOVE {s * RIGHT[0]:.3f} {s * RIGHT[1]:.3f} {z:.3f}\nMOVE {s * RIGHT[0]:.3f} {s * RIGHT[1]:.3f} {z + 2:.3f}\n"
    a = _robot("A", text, [-100 * RIGHT[0], -100 * RIGHT[1], 2.0], RIGHT)
    behind = 60 * RIGHT - 50 * TOWARDS
    front = 60 * RIGHT + 80 * TOWARDS
    b = _robot("B", "", [*behind, 5.0], RIGHT)
    c = _robot("C", "", [*front, 5.0], RIGHT)
    return _sim([a, b, c])


def test_robots_are_hidden_where_the_print_is_nearer_and_cover_it_where_they_are(wall_scene, tmp_path):
    res = wall_scene
    t = res.makespan
    rgb, before, depth, scene = _picture(res, t)
    material = depth > NO_DEPTH / 2
    masks = [_silhouette(scene, scene._solids(i, r, t)) for i, r in enumerate(res.robots)]
    _, mb, mc = masks
    changed = (rgb != before).any(axis=2)
    # B, behind the wall: not one pixel of the wall over it is drawn over ...
    hidden = mb & material & ~masks[0] & ~mc
    assert hidden.sum() > 500
    assert not changed[hidden].any()
    # ... and B is there: its printhead's top above the wall
    assert (mb & ~material & changed).sum() > 200
    # C, in front of the wall, covers it (the wall shows through it)
    covering = mc & material & ~masks[0] & ~mb
    assert covering.sum() > 500
    assert changed[covering].mean() > 0.97
    # the picture written is the same drawing
    snap = np.asarray(Image.open(render_snapshot(res, t, tmp_path / "s.png")).convert("RGB"))
    bottom = scene.layout.bottom
    assert np.array_equal(snap[bottom:-60], rgb[bottom:-60])


def test_each_face_is_drawn_at_its_depth(wall_scene):
    """A face's depth plane, at each of its corners' pixels, is the corner's depth."""
    res = wall_scene
    scene = _Scene(res, (1280, 720), -35.0, 30.0)
    for i, r in enumerate(res.robots):
        for s in scene._solids(i, r, res.makespan / 3):
            for (quad, plane, _, _), face in zip(s.faces(scene), s.sides(scene)):
                corners = s.corners[list(s.FACES[face])]
                assert np.allclose(quad, scene.px(corners))
                assert np.allclose(np.column_stack([quad, np.ones(4)]) @ plane, corners @ scene.basis[2])


def test_a_gcode_printer_is_drawn_with_its_nozzle_only(tmp_path):
    """Where a G-code printer's body stands is not known: the picture shows the material and
    the nozzle (a rod from the tip up nozzle_height and a dot), no body, frame or printhead."""
    g = tmp_path / "p.gcode"
    g.write_text("G21\nG90\nM83\nG1 Z0.2 F600\nG1 X40 Y0 E2 F1200\nG1 X40 Y40 E2\nG1 X0 Y40 E2\n")
    res = simulate(SimInput([read_gcode(g)], RobotProfile(), SlicingSettings(), str(g), placed=False), checks=False)
    assert not res.placed
    t = res.makespan * 0.7
    rgb, before, _, scene = _picture(res, t)
    (rod,) = scene._solids(0, res.robots[0], t)
    tip = scene.nozzle(res.robots[0], t)
    ends = scene.px(np.array([tip, tip + [0, 0, RobotProfile().nozzle_height]]))
    ys, xs = np.nonzero((rgb != before).any(axis=2))
    assert len(xs) > 30  # the nozzle is drawn
    # every pixel drawn lies within a few pixels of the rod's axis (or the tip's dot)
    d = ends[1] - ends[0]
    f = np.clip(((np.column_stack([xs, ys]) - ends[0]) @ d) / (d @ d), 0, 1)
    off = np.linalg.norm(np.column_stack([xs, ys]) - (ends[0] + f[:, None] * d), axis=1)
    assert off.max() <= max(6.0 * scene.k, NOZZLE_WIDTH / 2 ** 0.5 * scene.scale) + 2.0
    # a placed robot's body is drawn: thousands of pixels far from its nozzle
    placed = _sim([_robot("A", "MOVE 0 0 0.2\nTOOL ON\nMOVE 40 0 0.2\nMOVE 40 40 0.2\n", [0, 0, 0.2], [0, 1],
                          RobotProfile())], RobotProfile())
    rgb, before, _, scene = _picture(placed, placed.makespan * 0.7)
    assert (rgb != before).any(axis=2).sum() > 50_000


def test_a_floor_grid_with_labels_and_a_scale_bar(wall_scene, tmp_path):
    res = wall_scene
    img = np.asarray(Image.open(render_snapshot(res, res.makespan / 2, tmp_path / "s.png")).convert("RGB")).astype(int)
    scene = _Scene(res, (1280, 720), -35.0, 30.0)
    assert scene.grid_step in (10.0, 20.0, 50.0) and scene.bar_length in (20.0, 50.0, 100.0)
    assert (np.abs(img - GRID_COLOUR).sum(axis=2) == 0).sum() > 2000  # the grid's lines
    # the scale bar: a dark line bar_length mm long (at the picture's scale) in the bottom left
    dark = (np.abs(img - (50, 50, 50)).sum(axis=2) < 30)[-40:, :400]
    longest = max(int(row.sum()) for row in dark)
    assert abs(longest - scene.bar_length * scene.scale) <= 3


@pytest.mark.parametrize("far", [0.0, 2000.0])
def test_the_view_is_framed_on_the_part(far):
    """A 30 mm square printed by a full-size robot (its body 300 mm behind the nozzle), a second
    robot ``far`` mm away: the part's pixels span at least 40 % of the picture's width or height."""
    text = "MOVE 0 0 0.4\nTOOL ON\n" + "".join(f"MOVE {x} {y} {0.4 * (k + 1)}\n" for k in range(5)
                                               for x, y in ((30, 0), (30, 30), (0, 30), (0, 0)))
    robots = [_robot("A", text, [0, 0, 0.4], [0, 1], RobotProfile())]
    if far:
        robots.append(_robot("B", "MOVE 0 0 5\n", [far, far, 5.0], [-1, 0], RobotProfile()))
    res = _sim(robots, RobotProfile())
    _, _, depth, scene = _picture(res, res.makespan)
    ys, xs = np.nonzero(depth > NO_DEPTH / 2)
    w, h = scene.size
    assert (xs.max() - xs.min()) / w >= 0.4 or (ys.max() - ys.min()) / h >= 0.4
    assert ys.min() >= scene.layout.bottom  # under the overlay


@pytest.mark.parametrize("size", [(640, 360), (1280, 720)])
@pytest.mark.parametrize("n", [2, 4, 12, 64])
def test_every_robots_name_and_bar_are_inside_the_picture(size, n):
    w, h = size
    lay = overlay_layout(robot_names(n), size, "t = 123:45:06 / 123:45:06")
    assert len(lay.cells) == n
    boxes = [lay.clock_box] + [b for c in lay.cells for b in (c.box, c.bar)]
    for x0, y0, x1, y1 in boxes:
        assert 0 <= x0 < x1 <= w and 0 <= y0 < y1 <= lay.bottom <= 0.4 * h
    for i, a in enumerate(boxes):  # nothing drawn over anything else
        for b in boxes[i + 1:]:
            assert a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1], (a, b)
    if n <= 3:
        assert all(c.state_at is not None for c in lay.cells)  # few robots: "robot A", the bar and the state
    if n <= 4 or size[0] >= 1280 and n <= 12:  # the state word where there is room (a 640 px GIF of 4 robots)
        assert all(c.state_at is not None for c in lay.cells)
    from cooprint.render.sim import STATES, _text_box
    for c in lay.cells:  # the state word inside the picture, right of the bar, clear of the next cell
        if c.state_at is not None:
            x0, _, x1, _ = _text_box(max(STATES, key=len), (c.state_at[0], 0), c.state_font)
            assert c.bar[2] < x0 and x1 <= w
            assert all(x1 <= o.at[0] or o.at[0] < c.at[0] or o.at[1] != c.at[1] for o in lay.cells if o is not c)


@pytest.mark.parametrize("size", [(640, 360), (1280, 720)])
def test_a_waiting_robots_bar_keeps_its_colour_and_shows_yellow_and_waiting(size, tmp_path):
    """Four robots, D waiting half-way for A's long line: its bar is filled in its colour and
    framed in the Gantt chart's yellow, in the GIF's size as in the PNG's."""
    from cooprint.render.sim import WAIT_COLOUR
    texts = {"A": "MOVE 0 0 0.4\nTOOL ON\nMOVE 0 400 0.4\nNOTIFY go\n",
             "D": "MOVE 300 0 0.4\nTOOL ON\nMOVE 340 0 0.4\nTOOL OFF\nWAIT go\nTOOL ON\nMOVE 380 0 0.4\n"}
    robots = [_robot(name, texts.get(name, f"MOVE {100 * k} 0 0.4\nTOOL ON\nMOVE {100 * k + 40} 0 0.4\n"),
                     [100 * k, 0, 0.4], [0, 1]) for k, name in enumerate(robot_names(4))]
    res = _sim(robots)
    (a, b, _), = res.timelines["D"].waits
    t = (a + b) / 2
    img = np.asarray(Image.open(render_snapshot(res, t, tmp_path / "s.png", size=size)).convert("RGB")).astype(int)
    lay = _Scene(res, size, -35.0, 30.0).layout
    cell = lay.cells[3]
    assert cell.state_at is not None
    x0, y0, x1, y1 = cell.bar
    bar = img[y0:y1 + 1, x0:x1 + 1]
    near = lambda c: (np.abs(bar - np.asarray(c)).sum(axis=2) < 12).mean()
    assert near(robot_colour(3)) > 0.1  # its progress (half) in its colour, not grey
    assert near(WAIT_COLOUR) > 0.15  # the yellow frame
    assert near((150, 150, 150)) == 0


@pytest.mark.parametrize("size", [(640, 360), (1280, 720)])
@pytest.mark.parametrize("n", [2, 4, 12])
def test_every_robots_name_is_drawn_in_its_colour(size, n, tmp_path):
    robots = [_robot(name, f"MOVE {100 * k} 0 0.4\nTOOL ON\nMOVE {100 * k + 40} 0 0.4\n", [100 * k, 0, 0.4], [0, 1])
              for k, name in enumerate(robot_names(n))]
    res = _sim(robots)
    img = np.asarray(Image.open(render_snapshot(res, res.makespan / 2, tmp_path / "s.png", size=size)).convert("RGB"))
    lay = _Scene(res, size, -35.0, 30.0).layout
    for i, cell in enumerate(lay.cells):  # ink at least half the robot's colour (the text is smoothed)
        x0, y0, x1, y1 = cell.box
        off = np.abs(img[y0:y1, x0:x1].astype(int) - robot_colour(i)).sum(axis=2)
        assert off.min() < 0.5 * np.abs(np.subtract(robot_colour(i), BACKGROUND)).sum(), cell.text


def test_the_animation_draws_the_robots_as_the_snapshot_does(wall_scene, tmp_path):
    """The last frame of a GIF and the snapshot at the end, both 640 x 360: the same robots at
    the same places (the GIF's 128 colours aside)."""
    res = wall_scene
    gif = render_animation(res, tmp_path / "a.gif", fps=2, duration=1)
    with Image.open(gif) as im:
        im.seek(im.n_frames - 1)
        last = np.asarray(im.convert("RGB")).astype(int)
    snap = np.asarray(Image.open(render_snapshot(res, res.makespan, tmp_path / "s.png", size=(640, 360)))
                      .convert("RGB")).astype(int)
    assert last.shape == snap.shape
    assert np.median(np.abs(last - snap).sum(axis=2)) < 12


def test_the_nozzles_rod_shows_over_its_frame_and_a_small_part_under_the_frame_shows():
    """A 5 mm square printed by a robot whose frame hangs between the camera and the print: the
    rod from the tip up to the printhead is drawn over the see-through frame (the printhead reads
    as attached), and the print and the floor under the frame stay visible (the frame takes
    :data:`ROBOT_ALPHA` of a material pixel, :data:`OVER_PART_ALPHA` of a floor pixel there)."""
    from cooprint.render.sim import NOZZLE_COLOUR
    text = "MOVE 0 0 0.4\nTOOL ON\n" + "".join(
        f"MOVE {5 * ((k + 1) // 2 % 2)} {5 * (k // 2 % 2)} {0.4 + 0.4 * (k // 4)}\n" for k in range(1, 49))
    res = _sim([_robot("A", text, [0, 0, 0.4], -TOWARDS)])  # its frame towards the camera
    t = res.makespan / 2
    rgb, before, depth, scene = _picture(res, t)
    solids = scene._solids(0, res.robots[0], t)
    rod = _silhouette(scene, [s for s in solids if s.on_top])
    frame = _silhouette(scene, [s for s in solids if not s.on_top])
    material = depth > NO_DEPTH / 2
    seen = rod & frame & ~material  # the rod behind the frame (seen from the camera)
    assert seen.sum() > 500
    assert (np.abs(rgb[seen].astype(int) - np.asarray(NOZZLE_COLOUR)).sum(axis=1) < 150).mean() > 0.9
    diff = np.abs(rgb.astype(int) - before.astype(int)).sum(axis=2)
    under = frame & ~rod
    assert (under & material).sum() > 100  # the print lies under the frame ...
    assert np.median(diff[under & material]) <= 0.2 * 3 * 255  # ... and shows through it
    ys, xs = np.nonzero(material)
    near = np.zeros_like(material)  # the floor round the print, under the frame
    near[ys.min() - 40:ys.max() + 40, xs.min() - 40:xs.max() + 40] = True
    floor = under & near & ~material
    solid = under & ~near & (diff > 0)  # faces elsewhere, over no material: drawn whole
    assert floor.sum() > 1000 and 0 < np.median(diff[floor]) <= 0.5 * diff[solid].max()
