"""A robot that waits parks out of the way (issue 13, deliverable 5).

Robot B waited for the centre chunk C parked 5 mm above its first point, which may lie on C's
face, while robot A printed C beneath it: the two printheads overlapped all along the wait. Now a
waiting robot parks where its whole outline (body, frame, printhead) is clear of the outlines of
the robots printing what it waits for, and off the material, then goes to its first point at the
transition height. An idle robot (nothing to print) parks by the same rule, and a robot that
turns round does so where its frame and printhead are clear of the print too.

The outline check here is the test's own (numpy, sharing no code with cooprint's planner or
simulator): each part of a robot is a rectangle in its facing frame, two rectangles overlap
unless an edge normal of one of them separates them (the separating-axis theorem).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import solids
from cooprint.config import load_settings
from cooprint.jobs import coop_job, run, write_coop_bundle
from cooprint.models import car as model_car
from cooprint.models import cylinder as model_cylinder
from cooprint.program import build
from cooprint.program.commands import MOVE, TOOL_ON, WAIT, read_coop
from cooprint.program.gcode import Feeds
from cooprint.simulation import load_inputs, simulate
from cooprint.simulation.timeline import SimRobot, schedule
from cooprint.slicing.paths import PERIMETER_OUTER, LayerPaths

#: How far apart the outlines must stay in the checks below, mm (the planner keeps its
#: clearance, 5 mm; 1 mm is what a plan must keep at the least).
GAP = 1.0


# --- the test's own geometry -----------------------------------------------------------------

def outline_rects(p) -> np.ndarray:
    """(3, 4) u_lo, u_hi, v_lo, v_hi of body, frame and printhead (issue 13's outline), from a
    profile or anything with its fields; the frame as wide as the body when it has no width."""
    bd, bl, bw, nd = p.build_depth, p.body_length, p.body_width, p.nozzle_depth
    fw = getattr(p, "frame_width", None) or bw
    return np.array([[-bd - bl, -bd, -bw / 2, bw / 2], [-bd, -nd, -fw / 2, fw / 2], [-nd, nd, -nd, nd]])


def quads(rects: np.ndarray, nozzles: np.ndarray, facing) -> np.ndarray:
    """(k * 3, 4, 2) the rectangles of a robot facing ``facing`` at every nozzle (k, 2), as
    corner lists in XY."""
    a = np.asarray(facing, float)[:2]
    a = a / np.linalg.norm(a)
    left = np.array([-a[1], a[0]])
    u, v = rects[:, [0, 0, 1, 1]], rects[:, [2, 3, 3, 2]]  # corners in order round each rectangle
    local = u[..., None] * a + v[..., None] * left  # (3, 4, 2)
    return (np.asarray(nozzles, float)[:, None, None, :2] + local[None]).reshape(-1, 4, 2)


def overlapping(p: np.ndarray, q: np.ndarray, gap: float) -> np.ndarray:
    """(n, m) True where quad p[i] and quad q[j] come nearer than ``gap`` along every edge normal
    of both (convex quads: no separating axis)."""
    hit = np.ones((len(p), len(q)), dtype=bool)
    for shapes, mine in ((p, True), (q, False)):
        edge = np.roll(shapes, -1, axis=1) - shapes
        normal = np.stack([-edge[..., 1], edge[..., 0]], axis=-1)
        length = np.linalg.norm(normal, axis=-1, keepdims=True)
        normal = normal / np.where(length > 0, length, 1.0)
        for k in range(4):
            n = normal[:, k]
            if mine:
                a = np.einsum("nij,nj->ni", p, n)[:, None, :]
                b = np.einsum("mij,nj->nmi", q, n)
            else:
                a = np.einsum("nij,mj->nmi", p, n)
                b = np.einsum("mij,mj->mi", q, n)[None]
            apart = (b.min(-1) >= a.max(-1) + gap) | (b.max(-1) <= a.min(-1) - gap)
            hit &= ~apart
    return hit


def path_samples(tl, t0: float, t1: float, step: float = 1.0) -> np.ndarray:
    """(k, 2) the nozzle every ``step`` mm of every move under way between t0 and t1 (both ends
    of each move included)."""
    sel = np.flatnonzero((tl.t1 > t0) & (tl.t0 < t1))
    out = [tl.position(np.array([t0, t1]))[:, :2]]
    for k in sel:
        n = max(1, int(math.ceil(tl.length[k] / step)))
        f = np.linspace(0.0, 1.0, n + 1)[:, None]
        out.append((tl.p0[k] + f * (tl.p1[k] - tl.p0[k]))[:, :2])
    return np.unique(np.round(np.concatenate(out), 3), axis=0)


def distance_to_material(xy: np.ndarray, timelines: dict, t: float) -> float:
    """XY distance from ``xy`` to the nearest bead laid by any robot by time ``t``, mm."""
    segs = [tl.deposited(t)[0] for tl in timelines.values()]
    segs = np.concatenate(segs) if segs else np.zeros((0, 2, 3))
    if not len(segs):
        return math.inf
    a, b = segs[:, 0, :2], segs[:, 1, :2]
    ab = b - a
    l2 = np.einsum("ij,ij->i", ab, ab)
    f = np.clip(np.einsum("ij,ij->i", xy - a, ab) / np.where(l2 > 0, l2, 1.0), 0.0, 1.0)
    return float(np.linalg.norm(a + f[:, None] * ab - xy, axis=1).min())


def waits_in_the_clear(folder) -> list[dict]:
    """Simulate a bundle and, for every robot that waits (and every idle robot, for the whole
    plan), where it stands, how many of the other robots' path samples meanwhile bring their
    outlines within GAP of its own, and how near the nearest material is by the wait's end."""
    inp = load_inputs([str(folder)])
    res = simulate(inp)
    robots = {r.name: r for r in res.robots}
    out = []
    for name, tl in res.timelines.items():
        me = robots[name]
        spans = [(w[0], w[1], w[2]) for w in tl.waits if w[1] > w[0]]
        idle = len(tl.t0) == 0
        if idle:
            spans = [(0.0, res.makespan, ("idle",))]
        for t0, t1, events in spans:
            here = np.asarray(me.start, float) if idle else tl.position(np.array([t0, 0.5 * (t0 + t1), t1]))
            here = here.reshape(-1, 3)
            mine = quads(outline_rects(me.profile), here[:1], me.facing)
            hits = 0
            for other, to in res.timelines.items():
                if other == name:
                    continue
                o = robots[other]
                assert not o.program.turns, "the check takes one facing per robot"
                theirs = quads(outline_rects(o.profile), path_samples(to, t0, t1), o.facing)
                hits += int(overlapping(theirs, mine, GAP).any(axis=1).sum())
            out.append({"robot": name, "events": events, "position": here[0],
                        "still": float(np.ptp(here, axis=0).max()),
                        "hits": hits, "material_mm": distance_to_material(here[0, :2], res.timelines, t1)})
    return out, res


def _errors(res) -> list:
    return [(f.kind, f.robot, f.chunk, f.count) for f in res.findings if f.severity == "error"]


# --- plans ------------------------------------------------------------------------------------

TURNED = {**solids.COARSE, "chunking.centre_angle_deg": 180.0}


@pytest.fixture(scope="module")
def bars(tmp_path_factory):
    """A 420 mm bar (tests/solids.py bar_bundle), and the same bar with the chunking axis
    turned round: then R1's first point (its seam, at the rear of the chunk) lies on C's face,
    where B used to park over A's printhead."""
    root = tmp_path_factory.mktemp("bars")
    plain = solids.bar_bundle(root, 30.0)
    solids.to_trimesh(solids.box(40, 420, 30)).export(root / "bar.stl")
    run(root / "bar.stl", root / "turned", overrides=TURNED, picture=False)
    return {"bar": plain, "turned": root / "turned"}


@pytest.mark.parametrize("name", ["bar", "turned"])
def test_a_waiting_robot_parks_clear_of_the_printing_robot_and_the_material(bars, name):
    folder = bars[name]
    report, res = waits_in_the_clear(folder)
    assert _errors(res) == []
    waits = [r for r in report if r["events"] == ("C",)]
    assert [r["robot"] for r in waits] == ["B"]
    b = waits[0]
    assert b["still"] == 0.0  # it stays where it parked, for the whole wait
    assert b["hits"] == 0
    nd = load_settings().robot.nozzle_depth
    assert b["material_mm"] > nd  # not over material: not even its printhead is
    # where it parks is its start in job.json (the simulator's), its program's first move, the
    # G-code's first G0
    job = json.loads((folder / "job.json").read_text())
    start = next(r["start"] for r in job["robots"] if r["name"] == "B")
    np.testing.assert_allclose(b["position"], start)
    coop = read_coop(folder / "robots" / "B.coop")
    first_move = coop.xyz[np.flatnonzero(coop.kind == MOVE)[0]]
    np.testing.assert_allclose(first_move, start)
    g0 = next(ln for ln in (folder / "robots" / "B.gcode").read_text().splitlines() if ln.startswith("G0 "))
    xyz = [float(w[1:]) for w in g0.split()[1:4]]
    np.testing.assert_allclose(xyz, start)


def test_after_the_wait_it_goes_to_its_first_point_at_the_transition_height(bars):
    """The turned bar: B parks off C, then crosses over C (within its printhead's reach) at a
    clearance above C's top, and goes down to R1's first point only above it."""
    folder = bars["turned"]
    job = json.loads((folder / "job.json").read_text())
    clearance = load_settings().program.clearance
    c_top = next(c["bbox"][1][2] for c in job["chunks"] if c["id"] == "C")
    p = read_coop(folder / "robots" / "B.coop")
    wait = int(np.flatnonzero(p.kind == WAIT)[0])
    on = int(np.flatnonzero(p.kind == TOOL_ON)[0])
    way = p.xyz[[i for i in range(wait + 1, on) if p.kind[i] == MOVE]]
    start = np.asarray(next(r["start"] for r in job["robots"] if r["name"] == "B"))
    assert start[2] >= c_top + clearance
    assert np.linalg.norm(start[:2] - way[-1, :2]) > 2 * load_settings().robot.nozzle_depth  # it did move off
    # across at the start's height, then straight down to the first point
    assert np.all(way[:-1, 2] == start[2]) and np.array_equal(way[-1, :2], way[-2, :2])
    assert way[-1, 2] < start[2]


def test_parking_costs_seconds_of_travel(bars):
    """Parking costs B its way from where it parks to its first point after the wait: less
    than 2 s at its travel speed on the turned bar; the plan no time (A, who prints C and then
    L1, still finishes last)."""
    folder = bars["turned"]
    _, res = waits_in_the_clear(folder)
    ends = {name: tl.end for name, tl in res.timelines.items()}
    assert res.makespan == ends["A"] and ends["B"] <= ends["A"]
    p = read_coop(folder / "robots" / "B.coop")
    on = int(np.flatnonzero(p.kind == TOOL_ON)[0])
    way = p.xyz[[i for i in range(on) if p.kind[i] == MOVE]]
    travel = float(np.linalg.norm(np.diff(way, axis=0), axis=1).sum())
    assert 2 * load_settings().robot.nozzle_depth < travel < 2.0 * load_settings().slicing.travel_speed


def test_the_generated_car_and_cylinder_plan_clear_waits(tmp_path):
    """The generated car (cooprint.models, a 2-robot cut: B waits for C) and a cylinder that
    fits the build depth (one chunk: B has nothing to print and parks for the whole plan)."""
    settings = load_settings(overrides=solids.COARSE)
    for name, solid in (("car", model_car(420.0)), ("cylinder", model_cylinder(60.0, 40.0, 64))):
        job = coop_job(solid, settings, robots=2)
        write_coop_bundle(job, tmp_path / name, picture=False)
        report, res = waits_in_the_clear(tmp_path / name)
        assert _errors(res) == [], name
        assert [r["robot"] for r in report] == ["B"], name
        assert report[0]["hits"] == 0, name
        assert report[0]["material_mm"] > settings.robot.nozzle_depth, name
        if name == "cylinder":
            assert report[0]["events"] == ("idle",)


# --- a WAIT on the way (the general rule) -----------------------------------------------------

def _square(y0: float, y1: float, n: int = 1) -> tuple[list, np.ndarray]:
    """``n`` 1 mm layers of a chunk: each a square perimeter from y0 to y1 (x from -20 to 20),
    its first point at (x=20, y=y1); and its material box."""
    ring = np.array([[20.0, y1], [-20.0, y1], [-20.0, y0], [20.0, y0], [20.0, y1]])
    layers = [(i, LayerPaths.build(i + 1.0, 1.0, [(ring, PERIMETER_OUTER, 1.6)])) for i in range(n)]
    return layers, np.array([[-20.0, y0, 20.0, y1, float(n)]])


def test_a_wait_between_chunks_backs_off_and_lifts():
    """Three robots' worth of rule with two: B prints R1, then waits for A's L1 before R2. At
    that WAIT it is within reach of C and L1, so it lifts, backs off along its facing until its
    outline is clear of A's on C and L1, waits there, and crosses to R2 at the transition height."""
    chunks = {"C": (-10.0, 10.0), "L1": (-40.0, -10.0), "R1": (10.0, 40.0), "R2": (40.0, 70.0)}
    layers, boxes = {}, {}
    for cid, (y0, y1) in chunks.items():  # L1 tall: A is still at it when B is done with R1
        layers[cid], boxes[cid] = _square(y0, y1, 12 if cid == "L1" else 1)
    ring = np.array([[20.0, 40.0], [-20.0, 40.0], [-20.0, 10.0], [20.0, 10.0], [20.0, 12.0]])
    layers["R1"] = [(0, LayerPaths.build(1.0, 1.0, [(ring, PERIMETER_OUTER, 1.6)]))]  # it ends next to C
    material = build.MaterialIndex(boxes, margin=1.0)
    r = load_settings().robot
    body = build.BodySize(r.build_depth, r.body_length, r.body_width)
    seqs = {"A": ("C", "L1"), "B": ("R1", "R2")}
    deps = {"L1": ("C",), "R1": ("C",), "R2": ("R1", "L1")}
    roles = {"C": "centre", "L1": "left", "R1": "right", "R2": "right"}
    programs, placements = build.robot_programs(seqs, layers, deps, material, reach=r.nozzle_depth, clearance=5.0,
                                                axis=(0.0, 1.0), roles=roles, body=body)
    b = programs["B"]
    waits = np.flatnonzero(b.kind == WAIT)
    assert [b.events[b.event[i]] for i in waits] == [("C",), ("L1",)]
    moves = np.flatnonzero(b.kind == MOVE)
    at_wait = b.xyz[moves[moves < waits[1]][-1]]
    # clear along -y (B faces -y) of A's outline on C and L1 (printhead reach 25 each) by 5 mm
    assert at_wait[1] >= 10.0 + 2 * r.nozzle_depth + 5.0 - 1e-3
    assert at_wait[2] >= 1.0 + 1.0 + 5.0  # lifted a clearance above R1 (and its margin)
    on = np.flatnonzero(b.kind == TOOL_ON)
    after = b.xyz[moves[(moves > waits[1]) & (moves < on[on > waits[1]][0])]]
    assert np.all(after[:-1, 2] >= at_wait[2])  # across at a travel height, down only above R2's first point
    np.testing.assert_allclose(after[-1], [20.0, 70.0, 1.0])
    np.testing.assert_allclose(after[-2, :2], [20.0, 70.0])
    # simulated: B's outline where it waits is clear of A's all along
    robots = [SimRobot(n, programs[n], np.asarray(placements[n].start), np.asarray(placements[n].facing), None,
                       profile=r) for n in seqs]
    timelines, findings = schedule(robots, Feeds.of_robot(r, load_settings().slicing))
    assert findings == []
    t0, t1, _ = timelines["B"].waits[1]
    assert t1 > t0  # it did wait: A was still printing
    mine = quads(outline_rects(r), at_wait[None, :2], placements["B"].facing)
    theirs = quads(outline_rects(r), path_samples(timelines["A"], t0, t1), placements["A"].facing)
    assert not overlapping(theirs, mine, GAP).any()


# --- the rule itself, for any outlines and facings ---------------------------------------------

def _rects_of(o: build.Outline) -> np.ndarray:
    return outline_rects(o)


@settings(max_examples=60, deadline=None)
@given(bd=st.floats(60, 400), bl=st.floats(1, 400), bw=st.floats(1, 400), fw=st.floats(1, 400),
       nd=st.floats(1, 60), mine=st.floats(-180, 180), theirs=st.floats(-180, 180),
       pts=st.lists(st.tuples(st.floats(-200, 200), st.floats(-200, 200)), min_size=1, max_size=6),
       here=st.tuples(st.floats(-300, 300), st.floats(-300, 300)))
def test_park_clears_every_outline_whatever_the_facings(bd, bl, bw, fw, nd, mine, theirs, pts, here):
    """``park`` against the test's own rectangles: the robot's outline where it parks is clear,
    by the margin, of the outline of the occupant at each of its points; it stays put where it
    already is clear, and otherwise backs off straight along its facing."""
    o = build.Outline(bd, bl, bw, fw, nd)
    f = np.array([math.cos(math.radians(mine)), math.sin(math.radians(mine))])
    g = np.array([math.cos(math.radians(theirs)), math.sin(math.radians(theirs))])
    pts = np.array(pts)
    here = np.array(here)
    spot = build.park(here, f, [(pts, g, o)], o, 5.0)
    assert not overlapping(quads(_rects_of(o), pts, g), quads(_rects_of(o), spot[None], f), 5.0 - 1e-6).any()
    moved = here - spot
    if np.linalg.norm(moved) > 0:
        assert np.allclose(moved / np.linalg.norm(moved), f)  # straight back, towards its body
    if float(here @ f) <= float((pts @ f).min()) - o.reach(g, -f) - o.reach(f, f) - 5.0 - 1e-6:
        assert np.array_equal(spot, here)  # already clear: it stays


def test_the_idle_robot_parks_its_whole_outline_clear():
    """A cylinder that fits the build depth is one chunk, printed by A; B, with nothing to
    print, parks on its own side with its printhead beyond A's reach (it used to stand 5 mm
    off the part, its printhead 20 mm over it and over A's)."""
    settings = load_settings(overrides=solids.COARSE)
    job = coop_job(model_cylinder(60.0, 40.0, 64), settings, robots=2)
    b = job.placements["B"]
    ax = np.asarray(job.chunked.chunks.plan.axis)[:2]
    printed = np.concatenate([layer.points for _, layer in job.layers["C"] if len(layer)])
    nd = settings.robot.nozzle_depth
    assert np.asarray(b.start[:2]) @ ax >= (printed @ ax).max() + 2 * nd + settings.program.clearance - 1e-3
    a_path = job.programs["A"].xyz[job.programs["A"].kind == MOVE]
    mine = quads(outline_rects(settings.robot), np.asarray(b.start)[None, :2], b.facing)
    theirs = quads(outline_rects(settings.robot), a_path[:, :2], job.placements["A"].facing)
    assert not overlapping(theirs, mine, GAP).any()


@settings(max_examples=40, deadline=None)
@given(angle=st.floats(0, 360), size=st.tuples(st.floats(20, 600), st.floats(20, 600)),
       body=st.tuples(st.floats(100, 400), st.floats(50, 400), st.floats(50, 400)),
       frame=st.floats(1.0, 3.0), nd=st.floats(5, 120))
def test_turn_round_turns_where_the_whole_outline_is_clear(angle, size, body, frame, nd):
    """Where a robot turns round (the last point of ``before``), its whole outline (a frame
    up to 3 times as wide as the body, any printhead) stays clear of the printed box at every
    angle of the turn, from the old facing via the quarter turn to the new one."""
    a = np.array([math.cos(math.radians(angle)), math.sin(math.radians(angle))])
    p = np.array([-a[1], a[0]])
    sx, sy = size
    bd, length, width = body
    corners = np.array([s * a + q * p for s in (-sx / 2, sx / 2) for q in (-sy / 2, sy / 2)])
    lo, hi = corners.min(0), corners.max(0)
    material = build.MaterialIndex({"X": np.array([[lo[0], lo[1], hi[0], hi[1], 10.0]])}, margin=0.0)
    here = np.r_[0.0, 0.0, 10.0]
    p4 = np.r_[(sx / 2 + 5) * a, 0.0]
    b = build.BodySize(bd, length, width, frame * width)
    way = build.turn_round(here, p4, a, material, ["X"], b, nd, 5.0)
    o = b.outline(nd)
    at = way.before[-1, :2]
    via = np.asarray(way.via)
    box = np.array([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]])[None]
    assert abs(via @ a) < 1e-9
    for phi in np.radians(np.linspace(0.0, 180.0, 19)):  # old facing -> via -> new facing (-a)
        f = math.cos(phi) * a + math.sin(phi) * via
        assert not overlapping(quads(_rects_of(o), at[None], f), box, 0.0).any(), math.degrees(phi)
