"""The robot's whole outline in the simulator (issue 13 items 1 and 7): body, frame and
printhead of every pair of robots compared at every instant, the parts that met named; the
``frame_width`` field; ``--fail-on``; the new kinds in summary.json."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cooprint.cli import main
from cooprint.config import RobotProfile, load_settings
from cooprint.program.commands import parse_coop
from cooprint.simulation import KINDS, SimInput, simulate, summary
from cooprint.simulation import kernels
from cooprint.simulation.checks import OUTLINE_TOLERANCE, PARTS, outline_boxes, outline_corners, outline_tables
from cooprint.simulation.inputs import _facing
from cooprint.simulation.timeline import SimRobot

from badinput import assert_rejected
from speeds import UNIFORM_SLICING

PROFILE = load_settings().robot  # bd 300, body 300 x 350, nd 25, nh 100, frame as wide as the body


def two_robots(a_text: str, a_start, a_deg: float, b_text: str, b_start, b_deg: float,
               a_profile: RobotProfile | None = None, b_profile: RobotProfile | None = None):
    """Simulate robots A and B (their .coop text, start, facing in degrees, own profile)."""
    s = load_settings()
    a = SimRobot("A", parse_coop(a_text, "A"), np.asarray(a_start, float), _facing(a_deg), profile=a_profile)
    b = SimRobot("B", parse_coop(b_text, "B"), np.asarray(b_start, float), _facing(b_deg), profile=b_profile)
    return simulate(SimInput([a, b], s.robot, UNIFORM_SLICING, "<test>"))  # 40 mm/s, travel 120


def collisions(res):
    return [f for f in res.findings if f.kind == "robots-collide"]


def test_the_outline_is_the_profiles_boxes():
    """The model of docs/simulator.md, every length from the profile (u along the facing)."""
    p = dataclasses.replace(PROFILE, frame_width=120.0)
    assert outline_boxes(p, 0.0) == {"body": (-650.0, -300.0, -150.0, 150.0), "frame": (-300.0, -25.0, -60.0, 60.0),
                                     "printhead": (-25.0, 25.0, -25.0, 25.0)}
    assert outline_boxes(PROFILE, 0.0)["frame"] == (-300.0, -25.0, -150.0, 150.0)  # default: the body's width
    shrunk = outline_boxes(PROFILE)  # each part by its own tolerance
    assert shrunk["body"] == (-648.0, -302.0, -148.0, 148.0) and shrunk["printhead"] == (-24.9, 24.9, -24.9, 24.9)
    # facing +y: the body lies behind the nozzle along -y, the left is -x
    c = outline_corners(PROFILE, np.array([0.0, 1.0]), 0.0)
    assert np.allclose(c["body"].min(axis=0), [-150, -650]) and np.allclose(c["body"].max(axis=0), [150, -300])
    assert np.allclose(c["frame"].min(axis=0), [-150, -300]) and np.allclose(c["frame"].max(axis=0), [150, -25])


LINE_PROGRAM = "MOVE -100 0 0.2\nTOOL ON\nMOVE 100 0 0.2\nTOOL OFF\nMOVE 100 0 30\n"


def test_two_robots_running_the_same_program_collide_printhead_on_printhead():
    """B's program is A's, from the same start: every instant, every part on its twin."""
    res = two_robots(LINE_PROGRAM, [-100, 0, 5], 90.0, LINE_PROGRAM, [-100, 0, 5], 90.0)
    (f,) = collisions(res)
    assert f.robot == "A" and f.time == 0.0 and f.count == len(np.arange(0.0, res.makespan + 0.5, 0.5))
    assert "the printhead of A meets the printhead of B" in f.detail
    assert "the body of A meets the body of B" in f.detail and "the frame of A meets the frame of B" in f.detail
    assert summary(res)["finding_counts"]["robots-collide"] == f.count


def facing_across(gap: float):
    """A faces +x with its nozzle on x = 0, B faces -x with its nozzle on x = ``gap``; both
    print a line along y, side by side: their bodies are more than 600 mm apart."""
    a = "MOVE 0 -50 0.2\nTOOL ON\nMOVE 0 50 0.2\nTOOL OFF\n"
    b = f"MOVE {gap} -50 0.2\nTOOL ON\nMOVE {gap} 50 0.2\nTOOL OFF\n"
    return two_robots(a, [0, -50, 5], 0.0, b, [gap, -50, 5], 180.0)


@pytest.mark.parametrize("gap", [2 * 25.0 - 1.0, 30.0, 1.0])
def test_printheads_crossing_while_the_bodies_stay_apart_are_caught(gap):
    (f,) = collisions(facing_across(gap))
    assert f.detail.split(" (B\'s nozzle at ")[0] == "the printhead of A meets the printhead of B"
    assert f.time == 0.0 and f.count > 1


def test_the_same_robots_1_mm_further_apart_than_the_outlines_need_are_clean():
    """The printheads need 2 * nozzle_depth = 50 mm between the nozzles (less the 2 x 0.1 mm
    that is touching): at 51 mm nothing meets."""
    assert facing_across(2 * PROFILE.nozzle_depth + 1.0).findings == []
    # and exactly face to face (0.2 mm of contact allowed) is touching, not a collision
    assert collisions(facing_across(2 * PROFILE.nozzle_depth)) == []
    assert collisions(facing_across(2 * PROFILE.nozzle_depth - 0.15)) == []
    assert collisions(facing_across(2 * PROFILE.nozzle_depth - 0.3)) != []


@pytest.mark.parametrize("a_x, apart", [(-90.0, 0.0), (-110.0, 0.0), (-90.0, 50.2), (-90.0, 49.6)])
def test_printheads_that_cross_head_on_between_two_instants_are_caught(a_x, apart):
    """A (facing +y) and B (facing -y) travel towards each other along x at 120 mm/s each, their
    printheads ``apart`` in y: they overlap (|dx| < 49.8 mm) for 0.42 s. From 180 mm apart that
    is 0.54-0.96 s, between the check's instants 0.5 and 1.0 s; from 200 mm, 0.63-1.04 s. One
    printhead passing 0.4 mm into the other is found; 50.2 mm apart, touching, is not."""
    a = f"MOVE {a_x} 0 5\nMOVE 300 0 5\n"
    b = f"MOVE 90 {apart} 5\nMOVE -300 {apart} 5\n"
    found = collisions(two_robots(a, [a_x, 0, 5], 90.0, b, [90, apart, 5], -90.0))
    if apart > 50:
        assert found == []
        return
    (f,) = found
    assert f.detail.split(" (B\'s nozzle at ")[0] == "the printhead of A meets the printhead of B"
    enter = (90 - a_x - 49.8) / 240  # when |dx| first drops under 49.8 mm
    assert enter <= f.time <= enter + 0.25


def test_a_frame_over_another_robots_printhead_is_caught_and_frame_width_counts():
    """A faces +y at the origin: its frame spans y -300 .. -25 over x -150 .. 150. B faces -x
    with its nozzle at (140, -150): its printhead (x 115 .. 165) lies under A's frame, its own
    frame and body stretch away along +x. With A's frame 200 mm wide (x -100 .. 100) it is clear."""
    still = "MOVE {x} {y} 50\nMOVE {x} {y} 60\n"
    a, b = still.format(x=0, y=0), still.format(x=140, y=-150)
    (f,) = collisions(two_robots(a, [0, 0, 50], 90.0, b, [140, -150, 50], 180.0))
    assert f.detail.split(" (B\'s nozzle at ")[0] == "the frame of A meets the printhead of B"
    narrow = dataclasses.replace(PROFILE, frame_width=200.0)
    assert collisions(two_robots(a, [0, 0, 50], 90.0, b, [140, -150, 50], 180.0, a_profile=narrow)) == []
    # and the other way round: B's own profile is B's (the printhead's half-side 10 mm: x 130 .. 150)
    small_head = dataclasses.replace(PROFILE, nozzle_depth=10.0)
    (f,) = collisions(two_robots(b, [140, -150, 50], 180.0, a, [0, 0, 50], 90.0, a_profile=small_head))
    assert f.detail.split(" (B\'s nozzle at ")[0] == "the printhead of A meets the frame of B"
    assert collisions(two_robots(b, [140, -150, 50], 180.0, a, [0, 0, 50], 90.0, a_profile=small_head,
                                 b_profile=narrow)) == []


def test_a_robot_without_moves_stands_at_its_start():
    """An idle robot (an empty program) is where it was placed, not at the origin."""
    far = two_robots("", [0, 2000, 5], 90.0, LINE_PROGRAM, [-100, 0, 5], 90.0)
    assert collisions(far) == []  # (it was taken to stand at the origin, on B's line)
    (f,) = collisions(two_robots("", [40, 10, 5], 90.0, LINE_PROGRAM, [-100, 0, 5], 90.0))
    assert "A printhead / B printhead" in f.detail and f.position == (40.0, 10.0, 5.0)
    assert "B's nozzle at (" in f.detail  # the finding's position is A's; the detail says where B was


def test_the_parts_met_later_are_counted():
    """A stands facing +y at the origin; B, facing +y too, drives along y = 40 from x = 400 to
    -400: its frame (y -260 .. 15) and body come over A's frame and body first, its printhead
    (y 15 .. 65) meets A's (y -25 .. 25) only while the nozzles are within 50 mm in x. One
    finding for the pair; the detail names what met first and counts each pair of parts."""
    a = "MOVE 0 0 50\nMOVE 0 0 60\n"
    b = "MOVE 400 40 50\nMOVE -400 40 50\n"
    res = two_robots(a, [0, 0, 50], 90.0, b, [400, 40, 50], 90.0)
    (f,) = collisions(res)
    first, _, counts = f.detail.partition("; instants met: ")
    assert "the frame of A meets the frame of B" in first and "printhead of B" not in first
    met = dict((k, int(n)) for k, n in (c.rsplit(" ", 1) for c in counts.split(", ")))
    assert met["A printhead / B printhead"] < met["A frame / B frame"] <= f.count
    assert met["A printhead / B printhead"] == pytest.approx(100 / 120 / 0.5, abs=1)  # 100 mm at 120 mm/s


# --- the kernel against a point-by-point definition --------------------------------------------

sizes = st.floats(10.0, 400.0)


@st.composite
def profiles(draw):
    bd = draw(st.floats(20.0, 500.0))
    nd = draw(st.floats(5.0, bd - 10.0))
    return RobotProfile(build_depth=bd, nozzle_depth=nd, body_width=draw(sizes), body_length=draw(sizes),
                        frame_width=draw(st.one_of(st.none(), sizes)))


def _inside(points, nozzle, facing, box):
    """Which of ``points`` (k, 2) lie strictly inside ``box`` of a robot at ``nozzle`` facing
    ``facing``."""
    f = np.asarray(facing) / np.linalg.norm(facing)
    d = points - nozzle
    u, v = d @ f, d @ np.array([-f[1], f[0]])
    return (box[0] < u) & (u < box[1]) & (box[2] < v) & (v < box[3])


def _cell_centres(nozzle, facing, box, n=48):
    """Centres of an n x n grid of cells over ``box`` (a robot's part), in world XY, and the
    cells' largest half-diagonal."""
    f = np.asarray(facing) / np.linalg.norm(facing)
    left = np.array([-f[1], f[0]])
    hu, hv = (box[1] - box[0]) / n, (box[3] - box[2]) / n
    u = box[0] + (np.arange(n) + 0.5) * hu
    v = box[2] + (np.arange(n) + 0.5) * hv
    uu, vv = np.meshgrid(u, v)
    return nozzle + uu.reshape(-1, 1) * f + vv.reshape(-1, 1) * left, math.hypot(hu, hv) / 2


@settings(max_examples=60, deadline=None)
@given(pa=profiles(), pb=profiles(), deg_a=st.floats(-180, 180), deg_b=st.floats(-180, 180),
       offset=st.tuples(st.floats(-900, 900), st.floats(-900, 900)), tol=st.floats(0.0, 3.0))
def test_outline_overlap_against_a_point_by_point_definition(pa, pb, deg_a, deg_b, offset, tol):
    """For each pair of parts: a point found inside both (the cells' centres of a grid over
    a's part, each tested against b's) means the kernel says they overlap; and when the parts
    shrunk by a further ``margin`` still overlap, such a point must be found (a disc of radius
    ``margin`` lies in both then, and it holds a cell centre)."""
    fa, fb = _facing(deg_a), _facing(deg_b)
    noz_a, noz_b = np.zeros(2), np.asarray(offset)
    mask = int(kernels.outlines_overlap(noz_a[None], noz_b[None], *outline_tables(pa, fa, pb, fb, tol))[0])
    boxes_a, boxes_b = outline_boxes(pa, tol), outline_boxes(pb, tol)
    for p in range(len(PARTS) ** 2):
        x, y = PARTS[p // 3], PARTS[p % 3]
        points, half_diag = _cell_centres(noz_a, fa, boxes_a[x])
        witness = bool(_inside(points, noz_b, fb, boxes_b[y]).any())
        if witness:
            assert mask >> p & 1, (x, y)
        margin = half_diag + 1e-6
        deeper_a, deeper_b = outline_boxes(pa, tol + margin), outline_boxes(pb, tol + margin)
        uncut = all(min(bx[1] - bx[0], bx[3] - bx[2]) > 2 * (tol + margin) for bx in
                    (outline_boxes(pa, 0.0)[x], outline_boxes(pb, 0.0)[y]))
        deep = int(kernels.outlines_overlap(noz_a[None], noz_b[None],
                                            *outline_tables(pa, fa, pb, fb, tol + margin))[0])
        if uncut and deep >> p & 1:
            assert witness, (x, y)
        assert not (deep >> p & 1) or mask >> p & 1  # shrinking more never makes parts meet
        del deeper_a, deeper_b


def test_the_kernel_takes_each_instant_on_its_own():
    """Many instants at once: the same as one at a time (and the union's early out keeps it)."""
    rng = np.random.default_rng(3)
    pa, pb = rng.uniform(-800, 800, (500, 2)), rng.uniform(-800, 800, (500, 2))
    tables = outline_tables(PROFILE, _facing(30.0), PROFILE, _facing(-120.0))
    all_at_once = kernels.outlines_overlap(pa, pb, *tables)
    assert (all_at_once != 0).any() and (all_at_once == 0).any()
    assert all(all_at_once[i] == kernels.outlines_overlap(pa[i:i + 1], pb[i:i + 1], *tables)[0] for i in range(500))


def test_the_printhead_tolerance_is_below_half_a_millimetre():
    """Printheads 1 mm closer than 2 * nozzle_depth overlap by 1 mm: the two shrinks must
    leave that a collision (docs/simulator.md)."""
    assert OUTLINE_TOLERANCE["printhead"] < 0.5 and OUTLINE_TOLERANCE["frame"] < 0.5


# --- settings ----------------------------------------------------------------------------------

def test_frame_width_round_trips_through_toml_json_and_set(tmp_path):
    f = tmp_path / "r.toml"
    f.write_text("[robot]\nframe_width = 180\n")
    s = load_settings(f)
    assert s.robot.frame_width == 180.0 and s.robot.resolved_frame_width == 180.0
    again = load_settings(tables=[("job.json: settings.", json.loads(json.dumps(s.to_dict())))])
    assert again.robot == s.robot
    default = load_settings()
    assert default.robot.frame_width is None and default.robot.resolved_frame_width == default.robot.body_width
    assert "frame_width" not in default.to_dict()["robot"]  # TOML has no null: absent means the body's width
    assert load_settings(tables=[("x: ", default.to_dict())]).robot == default.robot
    assert load_settings(overrides={"robot.frame_width": 90}).robot.resolved_frame_width == 90.0


@pytest.mark.parametrize("flags, needle", [
    (["--set", "robot.frame_width=0"], "robot.frame_width = 0: expected a number > 0"),
    (["--set", "robot.frame_width=-20"], "robot.frame_width = -20: expected a number > 0"),
    (["--set", "robot.frame_width=wide"], "robot.frame_width = 'wide': expected a number"),
    (["--set", "robot.nozzle_depth=300"], "robot.nozzle_depth = 300 mm, robot.build_depth = 300 mm: the printhead "
                                          "reaches into the body"),
    (["--set", "robot.build_depth=20"], "option: robot.nozzle_depth = 25 mm, robot.build_depth = 20 mm"),
    (["--set", "robot.nozzle_depth=0"], "robot.nozzle_depth = 0: expected a number > 0"),
    (["--set", "robot.body_length=-1"], "robot.body_length = -1: expected a number > 0"),
])
def test_a_degenerate_outline_is_refused_naming_the_field(tmp_path, capsys, flags, needle):
    part = tmp_path / "p.stl"
    part.write_text("solid p\nendsolid p\n")
    assert_rejected(["run", part, "--out", tmp_path / "o", "-q", *flags], capsys, [tmp_path], contains=needle)


def test_a_degenerate_outline_in_a_robot_file_names_the_file(tmp_path, capsys):
    part = tmp_path / "p.stl"
    part.write_text("solid p\nendsolid p\n")
    robot = tmp_path / "r.toml"
    robot.write_text("[robot]\nbuild_depth = 40\nnozzle_depth = 40\n")
    line = assert_rejected(["chunk", part, "--out", tmp_path / "o", "--robot", robot], capsys, [tmp_path])
    assert f"{robot}: robot.nozzle_depth = 40 mm, robot.build_depth = 40 mm" in line


# --- --fail-on, and the kinds of summary.json --------------------------------------------------

@pytest.fixture()
def overhang_only(tmp_path):
    """A .coop robot that lays a line 5 mm above the floor with nothing below: an overhang
    warning, and nothing else."""
    path = tmp_path / "A.coop"
    path.write_text("MOVE 0 0 5\nTOOL ON\nMOVE 50 0 5\nTOOL OFF\n")
    return path


def test_fail_on_errors_lets_warnings_pass_and_warnings_or_strict_fail(overhang_only, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["simulate", str(overhang_only), "--out", str(out), "-q"]) == 0
    s = json.loads((out / "sim" / "summary.json").read_text())
    assert s["finding_counts"]["overhang"] >= 1 and sum(s["finding_counts"].values()) == s["finding_counts"]["overhang"]
    capsys.readouterr()
    assert main(["simulate", str(overhang_only), "--out", str(out), "-q", "--fail-on", "errors"]) == 0
    assert capsys.readouterr().err == ""
    for flags in (["--fail-on", "warnings"], ["--strict"], ["--strict", "--fail-on", "warnings"]):
        assert main(["simulate", str(overhang_only), "--out", str(out), "-q", *flags]) == 1
        err = capsys.readouterr().err.splitlines()
        assert err[-1].startswith("cooprint: the plan fails --strict: the simulation found warnings (overhang")


def test_fail_on_errors_still_fails_on_errors(tmp_path, capsys):
    """A deadlock is an error: every level fails it."""
    (tmp_path / "A.coop").write_text("WAIT X\nMOVE 0 0 0\n")
    for flags in ([], ["--fail-on", "errors"], ["--fail-on", "warnings"], ["--strict"]):
        assert main(["simulate", str(tmp_path / "A.coop"), "--out", str(tmp_path / "o"), "-q", *flags]) == 1
        assert "the plan is INVALID" in capsys.readouterr().err


def test_conflicting_or_idle_fail_on_is_refused(overhang_only, tmp_path, capsys):
    assert_rejected(["simulate", overhang_only, "--out", tmp_path / "o", "-q", "--strict", "--fail-on", "errors"],
                    capsys, [tmp_path], contains="--strict fails on warnings, --fail-on errors only on errors")
    assert_rejected(["simulate", overhang_only, "--out", tmp_path / "o", "--fail-on", "all"], capsys, [tmp_path],
                    contains="'all' is not one of 'errors', 'warnings'")
    part = tmp_path / "p.stl"
    part.write_text("solid p\nendsolid p\n")
    assert_rejected(["run", part, "--out", tmp_path / "job", "-q", "--fail-on", "warnings"], capsys, [tmp_path],
                    contains="--fail-on warnings needs --simulate")


def test_summary_lists_every_kind_and_checked_only_those_that_ran():
    new = ("nozzle-in-material", "double-deposit", "chunk-order", "outside-part")
    assert all(k in KINDS for k in new)
    assert KINDS.index("printhead-hits-material") < KINDS.index("nozzle-in-material") < KINDS.index("deadlock")
    res = two_robots(LINE_PROGRAM, [-100, 0, 5], 90.0, LINE_PROGRAM, [-100, 0, 5], 90.0)
    s = summary(res)
    assert list(s["finding_counts"]) == list(KINDS)
    assert s["checked"] == [k for k in KINDS if k in res.checked] and "robots-collide" in s["checked"]


@pytest.mark.parametrize("robot, needle", [
    ("frame_width = -1", "fleet.toml: robot.frame_width = -1: expected a number > 0"),
    ("build_depth = 30\nnozzle_depth = 30", "fleet.toml: robot.nozzle_depth = 30 mm, robot.build_depth = 30 mm"),
])
def test_a_manifest_with_a_degenerate_outline_is_refused(tmp_path, capsys, robot, needle):
    (tmp_path / "A.coop").write_text("MOVE 0 0 5\n")
    m = tmp_path / "fleet.toml"
    m.write_text(f'[robot]\n{robot}\n[[robots]]\nname = "A"\nprogram = "A.coop"\n')
    assert_rejected(["simulate", "--manifest", m, "--out", tmp_path / "o"], capsys, [tmp_path], contains=needle)


def test_a_manifest_frame_width_is_the_robots(tmp_path):
    """A manifest's [robot] frame_width reaches the outline check: A's frame 100 mm wide leaves
    B's printhead (x 115 .. 165 under where a 300 mm frame would be) clear."""
    from cooprint.simulation import load_inputs

    (tmp_path / "A.coop").write_text("MOVE 0 0 50\nMOVE 0 0 60\n")
    (tmp_path / "B.coop").write_text("MOVE 140 -150 50\nMOVE 140 -150 60\n")
    m = tmp_path / "fleet.toml"
    robots = ('[[robots]]\nname = "A"\nprogram = "A.coop"\nfacing_deg = 90\n'
              '[[robots]]\nname = "B"\nprogram = "B.coop"\nfacing_deg = 180\n')
    m.write_text(robots)
    assert [f.detail.split(" (")[0] for f in collisions(simulate(load_inputs([], str(m))))] == \
        ["the frame of A meets the printhead of B"]
    m.write_text("[robot]\nframe_width = 100\n" + robots)
    assert collisions(simulate(load_inputs([], str(m)))) == []


def test_the_snapshot_draws_each_robots_frame_and_printhead():
    """The body on the floor up to the printhead's underside (nozzle_height above the tip), the
    frame and the printhead from there up, each over the outline the checks use (the drawing:
    tests/test_render_scene.py)."""
    from cooprint.render.sim import FRAME_THICKNESS, HEAD_HEIGHT, _Scene

    res = facing_across(300.0)
    a = res.robots[0]
    nozzle = res.timelines["A"].position(0.0)
    under = nozzle[2] + PROFILE.nozzle_height
    body, frame, head, rod = _Scene(res, (800, 500), -35.0, 30.0)._solids(0, a, 0.0)
    outline = outline_corners(PROFILE, a.facing, 0.0)
    for box, part, z0, z1 in ((body, "body", 0.0, under), (frame, "frame", under, under + FRAME_THICKNESS),
                              (head, "printhead", under, under + HEAD_HEIGHT)):
        assert np.allclose(box.corners[:4, :2], nozzle[:2] + outline[part][[0, 1, 3, 2]]), part
        assert np.allclose(box.corners[:4, 2], z0) and np.allclose(box.corners[4:, 2], z1), part
    assert np.allclose(rod.corners[:, :2].mean(axis=0), nozzle[:2]) and np.allclose(rod.corners[[0, 7], 2], [nozzle[2], under])
