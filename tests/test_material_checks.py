"""The nozzle against the material laid down before (issue 13 items 2-3): ``nozzle-in-material``
(the tip inside earlier material, tool on or off) and ``double-deposit`` (material laid where
material of the same layer already lies). Each plan is built here: hand-written programs of
walls and skins, and real plans of cooprint's own slicer."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import solids
from cooprint.config import RobotProfile, SlicingSettings
from cooprint.jobs import run
from cooprint.program.commands import parse_coop
from cooprint.simulation import KINDS, SimInput, load_inputs, simulate
from cooprint.simulation.checks import DOUBLE_NEAR, DOUBLE_RUN, material_checks
from cooprint.simulation.timeline import SimRobot, schedule
from speeds import UNIFORM

H, W = 0.2, 0.45  # the slicing settings' layer height and line width
NEW = ("nozzle-in-material", "double-deposit")


def _robot(name: str, text: str, start=(0.0, -400.0, 5.0), facing_deg: float = 90.0) -> SimRobot:
    a = np.radians(facing_deg)
    return SimRobot(name, parse_coop(text, name), np.asarray(start, float), np.array([np.cos(a), np.sin(a)]))


def _found(*robots: SimRobot, **kw) -> list:
    """The two checks' findings on the robots' programs (the other checks left out)."""
    tls, _ = schedule(list(robots), UNIFORM)
    return material_checks(list(robots), tls, SlicingSettings(), **kw)


def _kinds(findings) -> dict[str, int]:
    return {k: sum(f.count for f in findings if f.kind == k) for k in NEW}


def _lines(segments, z: float, chunk: str = "C", layer: int = 0, role: str = "skin") -> str:
    """A layer of separate lines (travel to each, then lay it) at height ``z``."""
    out = [f";@chunk {chunk}", f";@layer {layer} {H}", f";@path {role} {W}"]
    for (x0, y0), (x1, y1) in segments:
        out += [f"MOVE {x0:.3f}, {y0:.3f}, {z:.3f}", "TOOL ON", f"MOVE {x1:.3f}, {y1:.3f}, {z:.3f}", "TOOL OFF"]
    return "\n".join(out) + "\n"


def _wall(layers: int = 10, length: float = 20.0) -> str:
    """A wall one line wide along x from 0 to ``length`` at y = 0, ``layers`` layers (alternating
    directions, one extrusion per layer)."""
    out = [";@chunk C", f";@path outer-perimeter {W}"]
    for i in range(layers):
        z = (i + 1) * H
        a, b = (0.0, length) if i % 2 == 0 else (length, 0.0)
        out += [f";@layer {i} {H}", f"MOVE {a:.3f}, 0, {z:.3f}", "TOOL ON", f"MOVE {b:.3f}, 0, {z:.3f}", "TOOL OFF"]
    return "\n".join(out) + "\n"


def _travel_across(z: float) -> str:
    """Lift, go to one side of the wall, down to ``z`` there (off the wall), and across it."""
    return (f";@chunk -\nMOVE 0, -10, 5\nMOVE 10, -10, 5\nMOVE 10, -10, {z:.3f}\nMOVE 10, 10, {z:.3f}\n"
            "MOVE 10, 10, 5\n")


def _skin(n: int = 10, x0: float = 0.0, y0: float = 0.0, length: float = 10.0, spacing: float = 0.4) -> list:
    """``n`` parallel lines ``spacing`` apart, ``length`` long, alternating (a skin's zigzag)."""
    segs = []
    for i in range(n):
        y = y0 + i * spacing
        a, b = (x0, x0 + length) if i % 2 == 0 else (x0 + length, x0)
        segs.append(((a, y), (b, y)))
    return segs


# --- nozzle-in-material -------------------------------------------------------------------------

def test_a_travel_through_a_finished_wall_is_nozzle_in_material():
    found = _found(_robot("A", _wall(10) + _travel_across(1.0)))
    (f,) = [f for f in found if f.kind == "nozzle-in-material"]
    # the wall's top is 2.0 mm; the tip crosses it at (10, 0, 1.0), chunk "-" (between chunks)
    assert f.robot == "A" and f.chunk is None
    assert abs(f.position[0] - 10) < 1e-6 and abs(f.position[1]) <= W and f.position[2] == pytest.approx(1.0)
    assert f.count >= 1 and f.severity == "error"
    assert _kinds(found)["double-deposit"] == 0


@pytest.mark.parametrize("start, end", [((10, 0, 5), (10, 0, 1)), ((10, -0.5, 5), (10, 0.5, 0.5))])
def test_a_move_down_into_the_wall_is_found_where_the_tip_goes_in(start, end):
    # from 5 mm straight down into the wall (top 2.0 mm), or diving across it: the tip enters the
    # material at the top less the tolerance (half a layer), not at 5 mm where the move starts
    go = "".join(f"MOVE {x}, {y}, {z}\n" for x, y, z in (start, end, start))
    found = _found(_robot("A", _wall(10) + ";@chunk -\n" + go))
    (f,) = [f for f in found if f.kind == "nozzle-in-material"]
    assert f.position[2] == pytest.approx(2.0 - H / 2, abs=1e-6)
    assert abs(f.position[1]) <= W / 2


@pytest.mark.parametrize("below_top, caught", [(0.0, False), (0.09, False), (0.11, True), (1.8, True)])
def test_the_tip_may_go_down_to_half_a_layer_below_the_material_top(below_top, caught):
    # a travel in the plane of the wall's top layer (2.0 mm) is what every layer's travel does;
    # half a layer (0.1 mm) under the top is the clearance: the next material up is a whole layer
    found = _found(_robot("A", _wall(10) + _travel_across(2.0 - below_top)))
    assert (_kinds(found)["nozzle-in-material"] > 0) is caught


def test_a_travel_lifted_above_the_wall_plus_the_clearance_is_clean():
    found = _found(_robot("A", _wall(10) + _travel_across(2.0 + H)))
    assert found == []


def test_a_dive_onto_finished_layers_and_another_robots_print_into_them_are_caught():
    # robot A prints a skin of 5 layers; B then prints its first layer at z 0.2 right through it
    a = _robot("A", "".join(_lines(_skin(10), (i + 1) * H, layer=i) for i in range(5)) + "NOTIFY done\n")
    b = _robot("B", "WAIT done\n" + _lines(_skin(10, y0=0.2), H, chunk="R1"), start=(0, 400, 5), facing_deg=-90)
    found = _found(a, b)
    assert [(f.kind, f.robot, f.chunk) for f in found if f.kind == "nozzle-in-material"] == [
        ("nozzle-in-material", "B", "R1")]
    assert all(f.robot == "B" for f in found)


def test_the_robots_own_fresh_bead_at_corners_and_seams_is_not_material_laid_before():
    # a closed square loop of 4 layers: each corner starts on the segment just laid, each layer
    # ends on its own start (the seam), and the next layer starts on the layer below
    out = [";@chunk C", f";@path perimeter {W}"]
    square = [(0, 0), (10, 0), (10, 10), (0, 10), (0, 0)]
    for i in range(4):
        z = (i + 1) * H
        out += [f";@layer {i} {H}", f"MOVE 0, 0, {z:.3f}", "TOOL ON"]
        out += [f"MOVE {x}, {y}, {z:.3f}" for x, y in square[1:]]
        out += ["TOOL OFF"]
    assert _found(_robot("A", "\n".join(out) + "\n")) == []


# --- double-deposit -----------------------------------------------------------------------------

def test_a_layer_printed_twice_by_one_robot_is_a_double_deposit():
    layers = [_lines(_skin(10), (i + 1) * H, layer=i) for i in range(3)]
    found = _found(_robot("A", layers[0] + layers[1] + layers[1] + layers[2]))
    (f,) = [f for f in found if f.kind == "double-deposit"]
    # the repeated layer's first line, at its start, when the copy begins
    assert f.robot == "A" and f.chunk == "C"
    np.testing.assert_allclose(f.position, (0, 0, 2 * H), atol=0.3)
    assert f.count > 10 * 10 / 0.45  # most of the layer's cells
    # and the next layer goes on where it should: on the layer below, not into material
    assert _kinds(found)["nozzle-in-material"] == 0


def test_two_robots_running_the_same_program_double_deposit():
    text = "".join(_lines(_skin(10), (i + 1) * H, layer=i) for i in range(3))
    res = simulate(SimInput([_robot("A", text), _robot("B", text)], RobotProfile(), SlicingSettings(), "test"))
    # .coop programs without a bundle: no chunk deps, no part and no scheduler's bound to check against
    assert res.checked == tuple(k for k in KINDS if k not in ("chunk-order", "outside-part", "below-lower-bound"))
    dd = [f for f in res.findings if f.kind == "double-deposit"]
    assert {f.robot for f in dd} == {"B"} or {f.robot for f in dd} == {"A", "B"}
    assert sum(f.count for f in dd) > 3 * 10 * 10 / 0.45
    collide = [f for f in res.findings if f.kind == "robots-collide"]  # and the robots are one in the other
    assert collide and "printhead of A meets the printhead of B" in collide[0].detail


def test_beads_side_by_side_and_infill_along_a_perimeter_are_not_double():
    # a line spacing apart (0.4 mm), and 0.1 mm apart (a quarter spacing: the fill area's edge
    # next to the last perimeter) for 10 mm: both are how a slicer lays a layer
    for gap in (0.4, 0.1):
        segs = [((0, 0), (10, 0)), ((10, gap), (0, gap))]
        assert _found(_robot("A", _lines(segs, H))) == [], gap


def test_a_line_laid_again_within_the_nearness_is_double_and_a_short_overlap_is_not():
    near = DOUBLE_NEAR * W * 0.5
    assert _kinds(_found(_robot("A", _lines([((0, 0), (10, 0)), ((10, near), (0, near))], H))))["double-deposit"]
    # an infill line ending on the perimeter, a seam: overlaps shorter than DOUBLE_RUN line widths
    short = DOUBLE_RUN * W * 0.8
    assert _found(_robot("A", _lines([((0, 0), (10, 0)), ((10 - short, 0), (10 - short, 5))], H))) == []
    assert _found(_robot("A", _lines([((0, 0), (10, 0)), ((10, 5), (10, 0)), ((10, 0), (10 - short, 0))], H))) == []


def test_a_layer_printed_twice_is_caught_in_bands_and_on_coarse_cells_the_same():
    text = "".join(_lines(_skin(10, length=30.0), (i + 1) * H, layer=i) for i in (0, 1, 1))
    one = _found(_robot("A", text))
    bands = _found(_robot("A", text), max_cells=20 * 50)  # 20 columns a band
    assert [(f.kind, f.chunk) for f in one] == [(f.kind, f.chunk) for f in bands] == [("double-deposit", "C")]
    assert bands[0].time == one[0].time and bands[0].count == pytest.approx(one[0].count, rel=0.05)
    # coarse cells (a very long print) still find a repeat of the whole layer
    assert [f.kind for f in _found(_robot("A", text), cell=1.0)] == ["double-deposit"]
    # and the moves merged a few at a time (carrying each robot's deposits and extrusion over)
    assert _found(_robot("A", text), batch=3) == one


def test_two_robots_merged_a_few_moves_at_a_time_find_what_they_find_at_once():
    text = "".join(_lines(_skin(6), (i + 1) * H, layer=i) for i in range(2))
    other = _lines(_skin(6, y0=0.2), H, chunk="R1") + _wall(3)
    robots = (_robot("A", text), _robot("B", "MOVE 5, 5, 5\n" + other, start=(0, 400, 5), facing_deg=-90))
    at_once = _found(*robots)
    assert {f.kind for f in at_once} == set(NEW)
    for batch in (2, 5, 7):
        assert _found(*robots, batch=batch) == at_once


# --- real plans ---------------------------------------------------------------------------------

def test_a_sliced_part_of_several_layers_with_perimeters_and_infill_has_neither(tmp_path):
    # a tube (outer and hole perimeters, skins and sparse infill) at the default line and layer
    solids.to_trimesh(solids.tube(12.0, 5.0, 3.0)).export(tmp_path / "tube.stl")
    run(tmp_path / "tube.stl", tmp_path / "job", robots=1, picture=False)
    res = simulate(load_inputs([str(tmp_path / "job")]))
    assert set(NEW) <= set(res.checked)
    program = res.robots[0].program
    roles = set(program.role[program.width > 0].tolist())
    assert len(roles) >= 3 and len(set(program.layer.tolist())) >= 10  # perimeters, skins, infill; 15 layers
    assert [f for f in res.findings if f.kind in NEW] == []


def test_the_bar_bundle_of_two_robots_has_neither_and_a_copied_program_doubles(tmp_path):
    job = solids.bar_bundle(tmp_path, 12.0)
    res = simulate(load_inputs([str(job)]))
    assert [f for f in res.findings if f.kind in NEW] == []
    # robot B's program replaced by A's: B lays A's chunks again (the first report); job.json
    # edited to match (a program that job.json does not describe is refused: test_bad_sim_inputs.py)
    (job / "robots" / "B.coop").write_text((job / "robots" / "A.coop").read_text())
    record = json.loads((job / "job.json").read_text())
    record["robots"][1]["stats"] = record["robots"][0]["stats"]
    (job / "job.json").write_text(json.dumps(record))
    res = simulate(load_inputs([str(job)]))
    assert {f.robot for f in res.findings if f.kind == "double-deposit"} >= {"B"}


# --- property -----------------------------------------------------------------------------------

@settings(max_examples=15, deadline=None)
@given(x0=st.floats(-200, 200), y0=st.floats(-200, 200), n=st.integers(3, 12),
       length=st.floats(1.2 * DOUBLE_RUN * W, 30),  # each line is one extrusion: longer than a double run
       layers=st.integers(1, 5), angle=st.floats(0, 180), repeat=st.integers(0, 4))
def test_a_stack_of_layers_printed_once_is_clean_and_repeated_is_caught(x0, y0, n, length, layers, angle, repeat):
    a = np.radians(angle)
    rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])

    def layer(i: int) -> str:
        segs = [(tuple(rot @ p + (x0, y0)) for p in map(np.asarray, seg)) for seg in _skin(n, length=length)]
        return _lines([tuple(s) for s in segs], (i + 1) * H, layer=i)

    once = "".join(layer(i) for i in range(layers))
    assert _found(_robot("A", once)) == []
    k = repeat % layers
    twice = "".join(layer(i) + (layer(i) if i == k else "") for i in range(layers))
    found = _found(_robot("A", twice))
    assert [f.kind for f in found] == ["double-deposit"]
    assert found[0].position[2] == pytest.approx((k + 1) * H)


@pytest.mark.parametrize("dive_early, caught", [(True, True), (False, False)])
def test_a_transition_that_dives_while_over_the_finished_chunk_is_caught(dive_early, caught):
    # chunk C: 10 layers of skin over x 0..10, y 0..3.6; then the robot goes to chunk L1 beside it
    # (x 12..22): diving straight for L1's first point passes through C's upper layers
    c = "".join(_lines(_skin(10), (i + 1) * H, layer=i) for i in range(10))
    go = ("MOVE 5, 2, 2.2\nMOVE 12, 2, 0.2\n" if dive_early else
          "MOVE 5, 2, 2.2\nMOVE 12, 2, 2.2\nMOVE 12, 2, 0.2\n")
    l1 = _lines(_skin(10, x0=12.0), H, chunk="L1")
    found = _found(_robot("A", c + ";@chunk -\n" + go + l1))
    assert _kinds(found) == {"nozzle-in-material": _kinds(found)["nozzle-in-material"], "double-deposit": 0}
    assert (_kinds(found)["nozzle-in-material"] > 0) is caught


def test_material_kilometres_apart_is_swept_on_a_bounded_field():
    # two walls 1.8 km apart, the second with a travel through it: a few bands of coarse cells
    far = _wall(5).replace("MOVE 0,", "MOVE 900000,").replace("MOVE 20.000,", "MOVE 900020.000,")
    far = far.replace("MOVE 0.000,", "MOVE 900000.000,")
    text = _wall(5).replace("MOVE 0.000,", "MOVE -900000.000,").replace("MOVE 20.000,", "MOVE -899980.000,") + far
    text += ";@chunk -\nMOVE 900010, -10, 5\nMOVE 900010, -10, 0.4\nMOVE 900010, 10, 0.4\n"
    found = _found(_robot("A", text, start=(900010, -10, 5)))
    assert [f.kind for f in found] == ["nozzle-in-material"]
    assert found[0].position[0] == pytest.approx(900010)
