"""One source for every speed (issue 17): [slicing] gives each path role its feed rate, a robot's
``max_print_speed`` / ``max_travel_speed`` cap them, and the G-code, the plan's estimates and the
simulator all time a move at that speed (``program.gcode.Feeds``)."""

from __future__ import annotations

import dataclasses
import io
import json
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cooprint.config import RobotProfile, SlicingSettings, load_settings
from cooprint.program.commands import parse_coop, read_coop
from cooprint.program.gcode import Feeds, write_gcode
from cooprint.simulation import SimInput, load_inputs, simulate, summary
from cooprint.simulation.timeline import SimRobot
from cooprint.slicing.paths import (BRIDGE, GAP_FILL, INFILL, OVERHANG, PERIMETER_INNER, PERIMETER_OUTER, SKIN,
                                    TOP_SKIN, TRAVEL)

from solids import COARSE, box, to_trimesh
from speeds import expected_times

#: PrusaSlicer 2.5's speeds, role by role (the defaults): what each [slicing] field means.
PRUSA = {PERIMETER_OUTER: 30.0, PERIMETER_INNER: 60.0, SKIN: 20.0, INFILL: 80.0, TOP_SKIN: 15.0, BRIDGE: 60.0,
         GAP_FILL: 20.0, OVERHANG: 60.0}


def test_each_role_prints_at_its_slicing_speed_and_the_first_layer_at_its_own():
    f = Feeds.of_slicer(SlicingSettings())
    assert {r: f.extrude(r, 3) for r in PRUSA} == PRUSA
    assert {r: f.extrude(r, 0) for r in PRUSA} == dict.fromkeys(PRUSA, 30.0)  # PrusaSlicer: every first-layer move
    assert f.travel == 130.0 and f.extrude(TRAVEL, 3) == 80.0  # an extrusion with no role: the infill speed
    s = SlicingSettings(perimeter_speed=45.0, bridge_speed=25.0, first_layer_speed=50.0, travel_speed=200.0)
    f = Feeds.of_slicer(s)
    assert (f.extrude(PERIMETER_INNER, 1), f.extrude(BRIDGE, 1), f.extrude(OVERHANG, 1)) == (45.0, 25.0, 25.0)
    assert (f.extrude(INFILL, 0), f.extrude(SKIN, 0), f.travel) == (50.0, 50.0, 200.0)


def test_a_robots_caps_slow_only_what_is_faster_than_them():
    s = SlicingSettings()
    assert Feeds.of_robot(RobotProfile(), s) == Feeds.of_slicer(s)  # no caps: the slicer's speeds
    f = Feeds.of_robot(RobotProfile(max_print_speed=25.0, max_travel_speed=100.0), s)
    assert {r: f.extrude(r, 3) for r in PRUSA} == {r: min(v, 25.0) for r, v in PRUSA.items()}
    assert {r: f.extrude(r, 0) for r in PRUSA} == dict.fromkeys(PRUSA, 25.0)  # the first layer's 30, capped
    assert f.travel == 100.0
    assert Feeds.of_robot(RobotProfile(max_travel_speed=500.0), s).travel == 130.0


@settings(max_examples=60, deadline=None)
@given(roles=st.lists(st.integers(0, 8), min_size=1, max_size=40), layers=st.lists(st.integers(-1, 3), min_size=40,
       max_size=40), on=st.lists(st.booleans(), min_size=40, max_size=40),
       cap=st.one_of(st.none(), st.floats(1.0, 200.0)))
def test_per_move_speeds_are_extrude_and_travel(roles, layers, on, cap):
    """:meth:`Feeds.move_speeds` (every estimate and simulation) is :meth:`Feeds.extrude` (the
    G-code's F) with the tool on and the travel speed with it off, move by move."""
    f = Feeds.of_robot(RobotProfile(max_print_speed=cap), SlicingSettings())
    n = len(roles)
    got = f.move_speeds(np.array(roles, np.uint8), np.array(layers[:n], np.int32), np.array(on[:n]))
    want = [f.extrude(r, la) if o else f.travel for r, la, o in zip(roles, layers, on)]
    assert got.tolist() == want


# A small plan by hand: the first layer (an outer perimeter and infill, both at the first layer's 30 mm/s),
# then a layer of every role, travel between them.
PLAN = """\
;@layer 0 0.2
;@path outer-perimeter 0.45
MOVE 0, 0, 0.2
TOOL ON
MOVE 30, 0, 0.2
;@path infill 0.45
MOVE 30, 60, 0.2
TOOL OFF
;@layer 1 0.2
;@path travel 0
MOVE 30, 60, 0.4
MOVE 0, 60, 0.4
;@path perimeter 0.45
TOOL ON
MOVE 0, 0, 0.4
;@path outer-perimeter 0.45
MOVE 30, 0, 0.4
;@path skin 0.45
MOVE 30, 20, 0.4
;@path top-skin 0.4
MOVE 30, 35, 0.4
;@path bridge 0.4
MOVE 30, 95, 0.4
;@path gap-fill 0.3
MOVE 30, 105, 0.4
;@path overhang-perimeter 0.45
MOVE 0, 105, 0.4
;@path infill 0.45
MOVE 0, 265, 0.4
TOOL OFF
;@path travel 0
MOVE 0, 0, 0.4
"""
#: (length mm, speed mm/s) of PLAN's moves at the default speeds (PrusaSlicer 2.5's), by hand.
PLAN_PRINTS = [(30, 30), (60, 30), (60, 60), (30, 30), (20, 20), (15, 15), (60, 60), (10, 20), (30, 60), (160, 80)]
PLAN_TRAVELS = [0.2, 30, 265]


def _plan_result(slicing: SlicingSettings, profile: RobotProfile = RobotProfile()):
    robot = SimRobot("A", parse_coop(PLAN, "A"), np.array([0.0, 0.0, 0.2]), np.array([0.0, 1.0]))
    return simulate(SimInput([robot], profile, slicing, "plan"), checks=False)


def test_the_simulators_time_of_a_plan_is_its_lengths_over_its_roles_speeds():
    res = _plan_result(SlicingSettings())
    (rob,) = summary(res)["robots"]
    assert rob["printing_s"] == pytest.approx(sum(length / v for length, v in PLAN_PRINTS), rel=1e-12)
    assert rob["travelling_s"] == pytest.approx(sum(PLAN_TRAVELS) / 130.0, rel=1e-12)
    assert res.makespan == pytest.approx(rob["printing_s"] + rob["travelling_s"], rel=1e-12)
    # (the helper other tests use agrees with the hand-made numbers)
    assert expected_times(parse_coop(PLAN, "A"), SlicingSettings(), [0.0, 0.0, 0.2]) == \
        pytest.approx((rob["printing_s"], rob["travelling_s"]), rel=1e-12)


def test_a_max_print_speed_cap_slows_only_the_roles_faster_than_it():
    capped = summary(_plan_result(SlicingSettings(), RobotProfile(max_print_speed=25.0, max_travel_speed=65.0)))
    (rob,) = capped["robots"]
    assert rob["printing_s"] == pytest.approx(sum(length / min(v, 25.0) for length, v in PLAN_PRINTS), rel=1e-12)
    assert rob["travelling_s"] == pytest.approx(sum(PLAN_TRAVELS) / 65.0, rel=1e-12)
    # the roles at 15 and 20 mm/s take as long as without the cap: only the others add time
    (free,) = summary(_plan_result(SlicingSettings()))["robots"]
    assert rob["printing_s"] - free["printing_s"] == pytest.approx(
        sum(length / 25.0 - length / v for length, v in PLAN_PRINTS if v > 25.0), rel=1e-12)


def _gcode(program, s: SlicingSettings, profile: RobotProfile = RobotProfile()) -> str:
    buf = io.StringIO()
    write_gcode(buf, [program], s, Feeds.of_robot(profile, s), "t", home=False)
    return buf.getvalue()


def _feeds_by_type(text: str) -> dict[str, set[float]]:
    """``{;TYPE name: {F mm/s of its extrusion runs}}`` of a G-code, read here line by line."""
    out: dict[str, set[float]] = {}
    kind = None
    for line in text.splitlines():
        if line.startswith(";TYPE:"):
            kind = line[6:]
        elif line.startswith("G1 F") and kind is not None:
            out.setdefault(kind, set()).add(float(line[4:]) / 60)
        elif line.startswith("G0"):
            m = re.search(r"F(\d+)", line)
            out.setdefault("travel", set()).add(float(m.group(1)) / 60)
    return out


def test_the_gcode_runs_each_role_at_its_speed_and_simulates_as_the_coop():
    program = parse_coop(PLAN, "A")
    g = _gcode(program, SlicingSettings())
    assert _feeds_by_type(g) == {"External perimeter": {30.0}, "Internal infill": {30.0, 80.0}, "Perimeter": {60.0},
                                 "Solid infill": {20.0}, "Top solid infill": {15.0}, "Bridge infill": {60.0},
                                 "Gap fill": {20.0}, "Overhang perimeter": {60.0}, "travel": {130.0}}
    capped = _gcode(program, SlicingSettings(), RobotProfile(max_print_speed=25.0, max_travel_speed=65.0))
    assert _feeds_by_type(capped)["Perimeter"] == {25.0} and _feeds_by_type(capped)["travel"] == {65.0}
    assert _feeds_by_type(capped)["Top solid infill"] == {15.0}


def _bar(tmp_path, perimeter_speed: float):
    from cooprint.jobs import run

    mesh = tmp_path / "bar.stl"
    if not mesh.exists():
        to_trimesh(box(40, 120, 6)).export(mesh)
    out = tmp_path / f"p{perimeter_speed:g}"
    run(mesh, out, overrides={**COARSE, "slicing.perimeter_speed": perimeter_speed}, robots=1, picture=False)
    return out


def test_perimeter_speed_changes_a_plans_print_time_its_estimate_and_its_gcode(tmp_path):
    """``[slicing] perimeter_speed`` 45 against 90: the robot's inner perimeters (not on the first
    layer, at 30 mm/s) take exactly their length x (1/45 - 1/90) longer, in the simulator
    and in the plan's estimate (job.json's chunk work) alike, and its G-code says F2700 against
    F5400 for them; every other role keeps its speed."""
    slow, fast = _bar(tmp_path, 45.0), _bar(tmp_path, 90.0)
    prog = read_coop(slow / "robots" / "A.coop", "A")
    assert np.array_equal(prog.xyz, read_coop(fast / "robots" / "A.coop", "A").xyz, equal_nan=True)  # the same moves
    mv = np.flatnonzero(prog.kind == 0)
    xyz = prog.xyz[mv]
    length = np.r_[0.0, np.linalg.norm(np.diff(xyz, axis=0), axis=1)]
    inner = prog.tool_on()[mv] & (prog.role[mv] == PERIMETER_INNER) & (prog.layer[mv] > 0)
    extra = float(length[inner].sum()) * (1 / 45 - 1 / 90)
    assert extra > 1.0
    sims = [summary(simulate(load_inputs([str(f)])))["robots"][0] for f in (slow, fast)]
    assert sims[0]["printing_s"] - sims[1]["printing_s"] == pytest.approx(extra, rel=1e-9)
    assert sims[0]["travelling_s"] == pytest.approx(sims[1]["travelling_s"], rel=1e-12)
    work = [sum(c["work_s"] for c in json.loads((f / "job.json").read_text())["chunks"]) for f in (slow, fast)]
    assert work[0] - work[1] == pytest.approx(extra, rel=1e-6)  # job.json keeps 1e-9 s
    feeds = [_feeds_by_type((f / "robots" / "A.gcode").read_text()) for f in (slow, fast)]
    assert feeds[0]["Perimeter"] == {30.0, 45.0} and feeds[1]["Perimeter"] == {30.0, 90.0}  # layer 0: 30 mm/s
    assert {k: v for k, v in feeds[0].items() if k != "Perimeter"} == \
        {k: v for k, v in feeds[1].items() if k != "Perimeter"}
    # the G-code simulated at its own F takes as long as the .coop (its retractions aside)
    gsim = summary(simulate(load_inputs([str(slow / "robots" / "A.gcode")]), checks=False))["robots"][0]
    assert gsim["printing_s"] == pytest.approx(sims[0]["printing_s"], rel=1e-3)


def test_the_old_robot_speeds_are_refused_naming_what_replaced_them(tmp_path):
    from cooprint.errors import ConfigError

    f = tmp_path / "old.toml"
    f.write_text("[robot]\nprint_speed = 40.0\n")
    with pytest.raises(ConfigError) as err:
        load_settings(f)
    assert str(err.value) == (f"{f}: robot.print_speed was replaced by the per-role speeds of [slicing] "
                              "(perimeter_speed, infill_speed, ...; docs/slicer.md) and the cap robot.max_print_speed")
    with pytest.raises(ConfigError, match=r"^option: robot.travel_speed was replaced by slicing.travel_speed and the "
                                          r"cap robot.max_travel_speed$"):
        load_settings(overrides={"robot.travel_speed": 120.0})
    assert dataclasses.asdict(load_settings().robot)["max_print_speed"] is None  # absent: no cap
