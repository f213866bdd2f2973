"""The Gantt chart, the animations' timing and `cooprint render`'s options (issue 16, "the pictures
that exist, fixed"): a header whose title and legend never overlap, each robot's colour in the
legend, travel visible, days on a long plan's axis, GIF delays that add up to the length asked,
formats from --out's suffix, contradictions and overlong animations refused, --accel."""

from __future__ import annotations

import dataclasses
import itertools
import json

import numpy as np
import pytest
from PIL import Image

from badinput import assert_rejected
from speeds import UNIFORM_TOML
from cooprint.cli import main
from cooprint.errors import UserError
from cooprint.render.palette import robot_colour
from cooprint.render.sim import (DAY, GANTT_LEFT, GANTT_RIGHT, GANTT_TOP, TRAVEL_COLOUR, WAIT_COLOUR, _axis_label,
                                 _hms, _nice_step, _row_pitch, frame_count, gantt_header, gantt_height, gantt_names, gantt_title,
                                 gif_delays, render_gantt)
from cooprint.simulation import simulate
from cooprint.simulation.inputs import load_manifest


def _pixels(path) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB")).astype(int)


def _exact(img: np.ndarray, colour, tol: int = 3) -> np.ndarray:
    return np.abs(img - np.asarray(colour)).sum(axis=-1) < tol


def _program(lines: int) -> str:
    """Robot A: ``lines`` printed lines 4 mm long (0.1 s each), each followed by a travel back to
    the start of the next (4 mm, 1/30 s): a quarter of its time travelling, a few of each in
    each pixel column of the chart; it tells B when it is half-way."""
    text = "MOVE 0 0 0.2\n"
    for k in range(lines):
        text += f"TOOL ON\nMOVE 4 {0.5 * k} 0.2\nTOOL OFF\nMOVE 0 {0.5 * k + 0.5} 0.2\n"
        text += "NOTIFY half\n" if k == lines // 2 else ""
    return text


@pytest.fixture(scope="module")
def plan(tmp_path_factory):
    """A manifest of two robots: A prints lines with travel between (see :func:`_program`), B waits
    for A to be half-way, then prints a zigzag of short moves (where acceleration counts)."""
    d = tmp_path_factory.mktemp("plan")
    (d / "A.coop").write_text(_program(1500))
    zigzag = "".join(f"MOVE {5 * (k % 2)} {2000 + 0.5 * k} 0.2\n" for k in range(1, 400))
    (d / "B.coop").write_text("MOVE 0 2000 0.2\nWAIT half\nTOOL ON\n" + zigzag)
    (d / "m.toml").write_text(UNIFORM_TOML  # every extrusion at 40 mm/s, travel at 120
                              + '[[robots]]\nname = "A"\nprogram = "A.coop"\nstart = [0, 0, 0.2]\nfacing_deg = 90\n'
                              '[[robots]]\nname = "B"\nprogram = "B.coop"\nstart = [0, 2000, 0.2]\nfacing_deg = 90\n')
    return d / "m.toml"


@pytest.fixture(scope="module")
def result(plan):
    return simulate(load_manifest(plan), checks=False)


def _overlap(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


@pytest.mark.parametrize("width", [1200, 800, 520])
@pytest.mark.parametrize("robots", [1, 2, 16, 64])
def test_the_title_and_the_legend_never_overlap(width, robots):
    """Every line of the title and every swatch and label of the legend, measured: none over
    another, all inside the picture, the rows below all of them; a long title (375 days, with the
    lower bound) wraps onto a line of its own in a narrow picture."""
    title = gantt_title(375 * DAY + 12345.0, 370 * DAY)
    header = gantt_header(title, robots, width, critical=True, bound=True)
    assert len(header.legend) == 5 and len(header.boxes) == len(header.title) + 10
    for a, b in itertools.combinations(header.boxes, 2):
        assert not _overlap(a, b), (a, b)
    for x0, y0, x1, y1 in header.boxes:
        assert 0 <= x0 and x1 <= width - GANTT_RIGHT + 1 and y1 < header.bottom
    assert "".join(t for _, _, t, _ in header.title).replace(" ", "") == "".join(title).replace(" ", "")
    if width == 520:
        assert len(header.title) == 2  # the makespan, then the lower bound under it
    if width == 1200:
        assert len(header.title) == 1 and header.bottom <= GANTT_TOP  # today's height: one line each


def test_the_gantt_legend_shows_each_robots_printing_colour(result, tmp_path):
    img = _pixels(render_gantt(result, tmp_path / "g.png"))
    header = img[:GANTT_TOP]
    for k in range(2):
        assert _exact(header, robot_colour(k)).sum() >= 14 * 14, k  # its own swatch in the legend
        assert _exact(img[GANTT_TOP:], robot_colour(k)).sum() > 1000, k  # its printing
    assert _exact(header, WAIT_COLOUR).sum() >= 18 * 14


def test_a_narrow_gantt_grows_to_hold_its_wrapped_header(result, tmp_path):
    bound = 0.8 * result.makespan
    img = _pixels(render_gantt(result, tmp_path / "g.png", size=(480, 0), critical=["x"], lower_bound=bound))
    # no chunks in these programs: no critical path to frame, so none in the legend
    header = gantt_header(gantt_title(result.makespan, bound), 2, 480, critical=False, bound=True)
    assert header.bottom > GANTT_TOP and img.shape[0] == gantt_height(2, header.bottom)
    # A's row starts under the header: its colour in the legend's swatch, then from the row on
    legend_end = int(max(box[3] for box in header.boxes)) + 1
    a = _exact(img, robot_colour(0)).any(axis=1)
    assert a[:legend_end].any() and not a[legend_end:header.bottom].any() and a[header.bottom]


def test_travel_shows_as_a_strip_as_tall_as_its_share(result, tmp_path):
    """A travels a quarter of its printing time: the strip under its bar is grey in most columns
    while it works, about a quarter of the strip tall; the printing above it stays whole."""
    img = _pixels(render_gantt(result, tmp_path / "g.png"))
    pitch = _row_pitch(2)
    bar = max(10, int(pitch * 2 / 3))
    strip = max(3, round(bar / 4))
    tl = result.timelines["A"]
    x0 = GANTT_LEFT
    x1 = int(GANTT_LEFT + tl.t1[-1] / result.makespan * (img.shape[1] - GANTT_LEFT - GANTT_RIGHT)) - 1
    row = img[GANTT_TOP + bar - strip:GANTT_TOP + bar, x0:x1]
    grey = _exact(row, TRAVEL_COLOUR)
    travel = (tl.t1 - tl.t0)[~tl.on].sum() / tl.t1[-1]
    assert 0.2 < travel < 0.3
    assert grey.any(axis=0).mean() > 0.95  # every column of A's work has some travel in it
    assert 0.8 * travel < grey.mean() < 1.5 * travel + 1 / strip  # as tall as the share (rounded up)
    assert _exact(img[GANTT_TOP:GANTT_TOP + bar - strip - 1, x0:x1], robot_colour(0)).mean() > 0.99


def _stretched(result, days: float):
    """The plan with its times scaled so that its makespan is ``days`` days."""
    k = days * DAY / result.makespan
    tls = {n: dataclasses.replace(tl, t0=tl.t0 * k, t1=tl.t1 * k, waits=[(a * k, b * k, e) for a, b, e in tl.waits],
                                  notifies=[(t * k, e) for t, e in tl.notifies])
           for n, tl in result.timelines.items()}
    return dataclasses.replace(result, timelines=tls)


def test_a_long_plans_axis_and_title_are_in_days(result, tmp_path):
    assert _hms(375 * DAY) == "375 d 00:00:00" and _hms(273007) == "3 d 03:50:07"  # was 75:50:07
    assert _hms(59 * 60 + 40) == "0:59:40" and _hms(86399) == "23:59:59"
    assert _nice_step(375 * DAY / 8) == 50 * DAY and _nice_step(3 * DAY / 8) == DAY / 2
    assert _nice_step(1.5 * DAY) == 2 * DAY and _nice_step(1000 * DAY / 8) == 200 * DAY
    assert _axis_label(50 * DAY, 375 * DAY) == "50 d" and _axis_label(1.5 * DAY, 3 * DAY) == "1 d 12:00"
    assert _axis_label(0, 375 * DAY) == "0 d" and _axis_label(7200, 3600 * 20) == "2:00:00"
    long = _stretched(result, 375)
    path = render_gantt(long, tmp_path / "g.png")
    with Image.open(path) as im:
        assert im.text["Title"] == f"makespan 375 d 00:00:00 ({375 * DAY:.0f} s)"
    img = _pixels(path)
    axis = GANTT_TOP + 2 * _row_pitch(2)
    ticks = np.flatnonzero(_exact(img[axis + 3], (60, 60, 60)))
    assert len(ticks) == 8  # 0, 50, ... 350 days
    assert np.diff(ticks).std() < 1.0


def test_gif_delays_add_up_to_the_length():
    d = gif_delays(480, 20.0)
    assert len(d) == 480 and sum(d) == 20_000 and set(d) == {40, 50}
    for frames, length in ((48, 2.0), (7, 1.0), (1000, 41.7), (30, 0.6), (240, 10.0)):
        d = gif_delays(frames, length)
        assert len(d) == frames and abs(sum(d) - 1000 * length) <= 10 and min(d) >= 20
        assert all(x % 10 == 0 for x in d)


def test_a_gif_lasts_the_length_asked_at_the_fps_asked(plan, tmp_path, capsys):
    out = tmp_path / "a.gif"  # the format from the suffix
    assert main(["render", "--manifest", str(plan), "--out", str(out), "--duration", "2", "--fps", "24"]) == 0
    assert "animation: 2.0 s, 48 frames at 24 fps" in capsys.readouterr().out
    with Image.open(out) as im:
        assert im.format == "GIF" and im.n_frames == 48
        total = 0
        for k in range(im.n_frames):
            im.seek(k)
            total += im.info["duration"]
    assert abs(total - 2000) <= 10


def test_an_mp4_from_the_suffix(plan, tmp_path, capsys):
    import imageio_ffmpeg

    out = tmp_path / "a.mp4"
    assert main(["render", "--manifest", str(plan), "--out", str(out), "--duration", "1", "--fps", "6"]) == 0
    assert imageio_ffmpeg.count_frames_and_secs(str(out))[0] == 6


def test_speedup_past_ten_minutes_is_refused_and_duration_asks_for_it():
    with pytest.raises(UserError) as e:
        frame_count(DAY, 24.0, speedup=100)
    assert "--speedup 100 over the 1 d 00:00:00 plan makes an animation of 14 min 24 s (20,736 frames" in str(e.value)
    assert "take --speedup 144 or more, or give the length you want with --duration" in str(e.value)
    assert frame_count(DAY, 24.0, speedup=144) == 14_400
    assert frame_count(DAY, 24.0, duration=800) == 19_200  # asked for by its length
    with pytest.raises(UserError, match="--fps 60: a GIF plays at most 50 frames/s"):
        frame_count(100.0, 60.0, duration=2, gif=True)
    assert frame_count(100.0, 50.0, duration=2, gif=True) == 100


RENDER_REFUSALS = [
    (["--format", "mp4", "--out", "anim.gif"],
     "--format mp4 writes an MP4 but --out anim.gif is named as a GIF: give --out anim.mp4 or --format gif"),
    (["--format", "gif", "--out", "anim.MP4"], "give --out anim.gif or --format mp4"),
    (["--format", "gantt", "--out", "g.jpg"], "--format gantt writes a PNG but --out g.jpg is named as a JPEG"),
    (["--format", "png", "--out", "s.gif"], "give --out s.png or --format gif"),
    (["--out", "g.webm"], "--out g.webm: cooprint draws .png (--format png or gantt), .mp4 or .gif, not a WebM"),
    (["--format", "gif", "--out", "anim"], "--format gif writes a GIF: give --out anim.gif"),
    (["--out", "a.gif", "--at", "5"], "--at is the time of a png snapshot; --format gif (from --out's suffix) does "
                                      "not use it"),
    (["--format", "gantt", "--out", "g.png", "--at", "5"], "--format gantt does not use it"),
    (["--format", "gantt", "--out", "g.png", "--duration", "5"], "--duration shapes an animation"),
    (["--out", "a.mp4", "--speedup", "0.01"], "makes an animation of"),
    (["--out", "a.gif", "--fps", "100"], "a GIF plays at most 50 frames/s"),
]


@pytest.mark.parametrize("opts, needle", RENDER_REFUSALS, ids=[" ".join(o) for o, _ in RENDER_REFUSALS])
def test_render_refuses_contradictions_in_one_line(plan, tmp_path, capsys, opts, needle):
    opts = [str(tmp_path / o) if k and opts[k - 1] == "--out" else o for k, o in enumerate(opts)]
    assert_rejected(["render", "--manifest", plan, *opts], capsys, watch=[tmp_path, plan.parent], contains=needle)


def test_render_accel_draws_the_times_of_simulate_accel(plan, tmp_path, capsys):
    assert main(["simulate", "--manifest", str(plan), "--out", str(tmp_path / "s"), "--accel", "-q"]) in (0, 1)
    accel = json.loads((tmp_path / "s" / "sim" / "summary.json").read_text())["makespan_s"]
    titles = {}
    for extra in ([], ["--accel"]):
        out = tmp_path / f"g{len(extra)}.png"
        assert main(["render", "--manifest", str(plan), "--format", "gantt", "--out", str(out), *extra]) == 0
        with Image.open(out) as im:
            titles[bool(extra)] = im.text["Title"]
    assert titles[True] == f"makespan {_hms(accel)} ({accel:.0f} s)"
    assert titles[False] != titles[True]  # the zigzag takes longer when its moves accelerate


def test_render_of_a_simulated_folder_is_timed_as_its_simulation_unless_told(plan, tmp_path, capsys):
    """`render DIR` of a `simulate --accel --out DIR` folder reads the files its summary names and
    times them with acceleration (the summary's makespan); --no-accel draws constant-speed times."""
    folder = tmp_path / "s"
    assert main(["simulate", "--manifest", str(plan), "--out", str(folder), "--accel", "-q"]) in (0, 1)
    accel = json.loads((folder / "sim" / "summary.json").read_text())["makespan_s"]
    assert main(["render", str(folder), "--format", "gantt"]) == 0
    with Image.open(folder / "sim" / "gantt.png") as im:
        assert im.text["Title"] == f"makespan {_hms(accel)} ({accel:.0f} s)"
    out = tmp_path / "no.png"
    assert main(["render", str(folder), "--format", "gantt", "--no-accel", "--out", str(out)]) == 0
    plain = simulate(load_manifest(plan), checks=False).makespan
    with Image.open(out) as im:
        assert im.text["Title"] == f"makespan {_hms(plain)} ({plain:.0f} s)"
    assert abs(plain - accel) > 1


def test_render_of_a_missing_path_says_so(tmp_path, capsys):
    assert_rejected(["render", tmp_path / "nonexist"], capsys, watch=[tmp_path],
                    contains=f"{tmp_path / 'nonexist'}: no such file or folder")


def _renamed(result, names: dict[str, str]):
    """The plan with its robots renamed (``names``: old -> new)."""
    robots = [dataclasses.replace(r, name=names.get(r.name, r.name)) for r in result.robots]
    tls = {names.get(n, n): tl for n, tl in result.timelines.items()}
    return dataclasses.replace(result, robots=robots, timelines=tls)


@pytest.mark.parametrize("width", [1200, 480])
def test_a_long_robot_name_never_runs_under_the_bars(result, tmp_path, width):
    """A 30-character name: the bars start right of it (the whole name in a 1200 px chart), or,
    where that would take more than a third of the picture, the name is cut short with "…"."""
    long = "my_really_long_part_name_v2_fi"
    assert len(long) == 30
    renamed = _renamed(result, {"A": long})
    img = _pixels(render_gantt(renamed, tmp_path / "g.png", size=(width, 0)))
    bar = max(10, int(_row_pitch(2) * 2 / 3))
    font = min(16, max(10, bar - 2))
    names, left = gantt_names([long, "B"], font, width)
    assert left > GANTT_LEFT and left <= max(GANTT_LEFT, width // 3)
    assert names[0] == f"robot {long}" if width == 1200 else names[0].endswith("…")
    top = next(y for y in range(img.shape[0]) if _exact(img[y, left:left + 3], robot_colour(0)).all())
    row = _exact(img[top:top + bar, :left], robot_colour(0))  # A's label, left of A's bars
    label_cols = np.flatnonzero(row.any(axis=0))
    assert label_cols.max() < left - 5  # the label ends before the bars
    assert label_cols.max() - label_cols.min() > 0.8 * _text_width(names[0], font)  # drawn whole
    # A's bar is in its row right of `left` from its first column on
    assert _exact(img[top:top + bar, left:left + 10], robot_colour(0)).mean() > 0.5


def _text_width(text: str, font: int) -> float:
    from cooprint.render.sim import _cached_font
    return _cached_font(font).getlength(text)


def _chunk_lines(cid: str, y: float, n: int) -> str:
    return f";@chunk {cid}\nMOVE 0 {y} 0.2\nTOOL ON\n" + "".join(
        f"MOVE {4 * ((k + 1) % 2)} {y + 0.5 * k} 0.2\n" for k in range(n)) + "TOOL OFF\n"


def test_the_critical_path_drawn_is_the_chain_that_sets_the_makespan(tmp_path):
    """One robot printing C, L1, R1 (the schedule's precedence chain is C -> L1): its work alone
    sets the makespan, so all three are framed. Two robots, B waiting for A's C before R1: the
    chain is R1 (B, ends last) <- C (A, told B), not A's L1."""
    from cooprint.render.sim import CRITICAL_COLOUR, simulated_critical_path

    (tmp_path / "A.coop").write_text(_chunk_lines("C", 0, 40) + _chunk_lines("L1", 50, 40) + _chunk_lines("R1", 100, 40))
    (tmp_path / "m.toml").write_text('[[robots]]\nname = "A"\nprogram = "A.coop"\nstart = [0, 0, 0.2]\n')
    one = simulate(load_manifest(tmp_path / "m.toml"), checks=False)
    assert sorted(simulated_critical_path(one)) == ["C", "L1", "R1"]
    img = _pixels(render_gantt(one, tmp_path / "g.png", critical=["C", "L1"]))
    red = _exact(img[GANTT_TOP:], CRITICAL_COLOUR).any(axis=0)
    cols = img.shape[1] - GANTT_LEFT - GANTT_RIGHT
    last = GANTT_LEFT + int(0.95 * cols)  # R1 ends the plan: its frame reaches the right end
    assert red[last:].any() and red[GANTT_LEFT:GANTT_LEFT + cols // 10].any()

    (tmp_path / "A2.coop").write_text(_chunk_lines("C", 0, 40) + "NOTIFY C\n" + _chunk_lines("L1", 50, 20))
    (tmp_path / "B2.coop").write_text("MOVE 0 500 0.2\nWAIT C\n" + _chunk_lines("R1", 500, 60))
    (tmp_path / "m2.toml").write_text('[[robots]]\nname = "A"\nprogram = "A2.coop"\nstart = [0, 0, 0.2]\n'
                                      '[[robots]]\nname = "B"\nprogram = "B2.coop"\nstart = [0, 500, 0.2]\n')
    two = simulate(load_manifest(tmp_path / "m2.toml"), checks=False)
    assert simulated_critical_path(two) == ["R1", "C"]
