"""Pictures for N robots (issue 14, item 6): the chunk picture coloured by robot with each chunk's
order, the Gantt chart with N rows, the critical path and the lower bound."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from PIL import Image

import fleet_layouts
from badinput import assert_rejected
from cooprint.cli import main
from cooprint.config import RobotProfile, SlicingSettings
from cooprint.jobs import chunk_job, robot_names
from cooprint.models import car
from cooprint.program.commands import parse_coop
from cooprint.render.chunks import CENTRE_COLOUR, UNASSIGNED_COLOUR, order_label, render_chunks
from cooprint.render.palette import robot_colour, robot_palette
from cooprint.render.sim import BOUND_COLOUR, CRITICAL_COLOUR, WAIT_COLOUR, gantt_height, render_gantt
from cooprint.scheduling import Assignment
from cooprint.simulation import SimInput, load_inputs, simulate
from cooprint.simulation.timeline import SimRobot


def _pixels(path) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB")).astype(float)


def _shaded(img: np.ndarray, colour, tol: float = 6.0) -> int:
    """Pixels that are ``colour`` times a shade in [0.3, 1] (the renderer's lighting)."""
    c = np.asarray(colour, float)
    k = img @ c / (c @ c)
    off = np.linalg.norm(img - k[..., None] * c, axis=-1)
    return int(((off < tol) & (k > 0.3) & (k < 1.02)).sum())


def _exact(img: np.ndarray, colour, tol: float = 3.0) -> int:
    return int((np.abs(img - np.asarray(colour, float)).sum(axis=-1) < tol).sum())


def test_the_palette_gives_64_distinct_colours_apart_from_the_waiting_yellow():
    pal = robot_palette(64)
    assert len(set(pal)) == 64
    assert pal[:2] == [(214, 96, 77), (67, 147, 195)]  # the colours of the earlier pictures
    assert min(np.abs(np.subtract(c, WAIT_COLOUR)).sum() for c in pal) > 60
    assert CRITICAL_COLOUR not in pal


@pytest.fixture(scope="module")
def car_chunks():
    return chunk_job(car(420.0), robots=2).chunks


def test_chunk_picture_coloured_by_robot_with_a_legend(car_chunks, tmp_path):
    ids = [c.id for c in car_chunks.chunks]
    # three robots, chunks dealt round: every robot's colour on the chunks, the side colours gone
    sched = Assignment({r: tuple(ids[k::3]) for k, r in enumerate(robot_names(3))}, "test")
    img = _pixels(render_chunks(car_chunks, tmp_path / "s.png", schedule=sched))
    plain = _pixels(render_chunks(car_chunks, tmp_path / "p.png"))
    for k in range(3):
        assert _shaded(img[100:], robot_colour(k)) > 2000, k  # the chunks, below the legend
        assert _exact(img[:100], robot_colour(k)) >= 200, k  # its legend swatch (16 x 16)
    assert _shaded(plain, CENTRE_COLOUR) > 2000 and _shaded(img, CENTRE_COLOUR) < 50
    assert _exact(plain[:100], robot_colour(2)) == 0  # no legend without a schedule




def test_chunk_picture_of_200_chunks_and_16_robots(tmp_path):
    chunks = fleet_layouts.box_grid(20, 10)
    ids = [c.id for c in chunks.chunks]
    names = robot_names(16)
    sched = Assignment({r: tuple(ids[k::16]) for k, r in enumerate(names)}, "test")
    img = _pixels(render_chunks(chunks, tmp_path / "g.png", schedule=sched))
    for k in range(16):
        assert _shaded(img[100:], robot_colour(k), tol=4.0) > 200, k
    # labels: each a white box, fewer than the chunks where they would overlap, and some drawn
    white = (np.abs(img - 255).sum(axis=-1) < 3)[100:]
    assert 200 * 30 < white.sum()


def test_labels_say_robot_and_order_and_a_chunk_of_no_robot_is_grey(car_chunks, tmp_path):
    assert order_label("B", 2) == "B3" and order_label("R27", 0) == "R27#1"  # not "R271"
    ids = [c.id for c in car_chunks.chunks]
    img = _pixels(render_chunks(car_chunks, tmp_path / "u.png", schedule=Assignment({"A": tuple(ids[1:])}, "test")))
    assert _shaded(img[100:], UNASSIGNED_COLOUR) > 500 and _shaded(img[100:], robot_colour(0)) > 2000


def _gantt_result(n: int):
    """``n`` robots in a chain: robot k waits for robot k-1's second chunk, then prints three."""
    robots = []
    for i in range(n):
        name, y = f"R{i}", 1000.0 * i
        text = f"MOVE 0 {y} 0\n" + (f"WAIT R{i - 1}:c1\n" if i else "")
        for k in range(3):
            text += f";@chunk {name}c{k}\nTOOL ON\nMOVE {400 * (k + 1)} {y} 0\nTOOL OFF\nMOVE {400 * (k + 1)} {y + 10} 0\n"
            text += f"NOTIFY {name}:c1\n" if k == 1 else ""
        robots.append(SimRobot(name, parse_coop(text + ";@chunk -\n", name), np.array([0, y, 0.0]), np.array([0.0, 1.0])))
    return simulate(SimInput(robots, RobotProfile(), SlicingSettings(), "test"), checks=False)


def test_gantt_has_a_row_per_robot_and_marks_the_critical_path(tmp_path):
    four, sixteen = _gantt_result(4), _gantt_result(16)
    small = _pixels(render_gantt(four, tmp_path / "4.png"))
    critical = [f"R{i}c1" for i in range(16)] + ["R15c2"]
    bound = 0.9 * sixteen.makespan
    big = _pixels(render_gantt(sixteen, tmp_path / "16.png", critical=critical, lower_bound=bound))
    assert big.shape[0] == gantt_height(16) > small.shape[0] == gantt_height(4)
    assert gantt_height(64) > gantt_height(16) and gantt_height(64) < 64 * 25  # rows thin out
    for k in range(16):
        assert _exact(big, robot_colour(k)) > 300, k  # every robot's printing
    assert _exact(small, CRITICAL_COLOUR) == 0 and _exact(big, CRITICAL_COLOUR) > 17 * 100
    # the lower bound: a dashed vertical line at its time, over the rows
    left, right = 110, big.shape[1] - 30
    x = int(round(left + bound / sixteen.makespan * (right - left)))
    column = (np.abs(big[:, x - 1:x + 2] - BOUND_COLOUR).sum(axis=-1) < 3).any(axis=1)
    assert column[100:gantt_height(16) - 70].mean() > 0.3


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    from cooprint.jobs import run

    out = tmp_path_factory.mktemp("pics") / "job"
    run(car(420.0), out, overrides={"slicing.layer_height": 1.0, "slicing.first_layer_height": 1.0,
                                    "slicing.extrusion_width": 1.6, "slicing.nozzle_diameter": 1.2})
    return out


def test_cooprint_run_draws_the_chunks_by_robot(bundle):
    img = _pixels(bundle / "chunks.png")
    record = json.loads((bundle / "job.json").read_text())
    for k, robot in enumerate(record["schedule"]["sequences"]):
        assert _shaded(img[100:], robot_colour(k)) > 2000, robot
        assert _exact(img[:100], robot_colour(k)) >= 200, robot  # the legend
    assert _shaded(img, CENTRE_COLOUR) < 50  # not by side


def test_render_gantt_reads_the_critical_path_and_bound_of_job_json(bundle, tmp_path, capsys):
    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    record = json.loads((job / "job.json").read_text())
    assert load_inputs([str(job)]).critical_path == tuple(record["schedule"]["critical_path"])
    del record["schedule"]["critical_path"]  # a bundle without one: today's picture
    (job / "job.json").write_text(json.dumps(record))
    assert load_inputs([str(job)]).critical_path is None
    record["schedule"] |= {"critical_path": ["C", "R1"], "lower_bound_s": 1000.0}
    (job / "job.json").write_text(json.dumps(record))
    inp = load_inputs([str(job)])
    assert inp.critical_path == ("C", "R1") and inp.lower_bound == 1000.0
    assert main(["render", str(job), "--format", "gantt"]) == 0
    assert _exact(_pixels(job / "sim" / "gantt.png"), CRITICAL_COLOUR) > 100
    record["schedule"]["critical_path"] = ["C", "Q7"]
    (job / "job.json").write_text(json.dumps(record))
    line = assert_rejected(["render", str(job), "--format", "gantt", "--force"], capsys, watch=[job])
    assert "schedule.critical_path[1]" in line and "Q7" in line
