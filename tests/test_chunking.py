import math
from dataclasses import replace

import numpy as np
import pytest
import trimesh

from cooprint.chunking import cut_chunks, plan_chunks, slope_limits
from cooprint.chunking.cut import SNAP
from cooprint.config import ChunkingSettings, RobotProfile
from cooprint.errors import InfeasibleError
from cooprint.io.mesh import solid_from_trimesh
from cooprint.scheduling import seed_two_robots

from solids import box, car, lying_tube, thin_walls, to_trimesh, tube

ROBOT = RobotProfile()  # bd 300, nh 100, nd 25


def chunked(man, robot=ROBOT, robots=1, **kw):
    """The seed's geometry: by default for one robot (a wedge-topped centre chunk unless
    ``top_width`` is given; two robots get 2 x nozzle_depth, tested on its own)."""
    solid = solid_from_trimesh(to_trimesh(man))
    plan = plan_chunks(solid.vertices, robot, ChunkingSettings(**kw), robots)
    return solid, cut_chunks(solid, plan)


def t_coord(plan, pts):
    return (np.asarray(pts) - plan.centre) @ np.asarray(plan.axis)


# --- seed eq. (1)-(2) -------------------------------------------------------------------------

def test_slope_limits_are_seed_equations_1_and_2():
    lim = slope_limits(RobotProfile(build_depth=200, nozzle_height=30, nozzle_depth=30), 100)
    assert lim.theta_max_deg == pytest.approx(45.0)
    assert lim.theta_min_deg == pytest.approx(math.degrees(math.atan(0.5)))
    assert lim.feasible


def test_default_theta_is_theta_max():
    _, cs = chunked(box())
    assert cs.plan.theta_deg == pytest.approx(math.degrees(math.atan(100 / 25)))


def test_infeasible_robot_prints_the_numbers():
    robot = RobotProfile(build_depth=20, nozzle_height=10, nozzle_depth=20)
    with pytest.raises(InfeasibleError, match=r"theta_min 56.3 > theta_max atan\(10/20\) = 26.6 deg"):
        chunked(box(), robot)


@pytest.mark.parametrize("theta", [3.0, 80.0])
def test_theta_outside_range_is_refused_with_range(theta):
    with pytest.raises(InfeasibleError, match=r"theta_deg = .* outside the printable range \(5.71, 75.96\]"):
        chunked(box(), theta_deg=theta)


def test_centre_chunk_wider_than_build_depth_is_refused():
    with pytest.raises(InfeasibleError, match=r"centre chunk base 305.0 mm > build depth 300 mm.*chunking.top_width <= 285.0"):
        chunked(box(y=400, z=30), top_width=290.0)  # 400 mm deep: it does not fit the build depth whole


def test_shift_beyond_reach_is_refused():
    with pytest.raises(InfeasibleError, match=r"reach s \+ h/tan\(theta\) = 307.5 mm > build depth 300"):
        chunked(box(), shift=300.0)


# --- exact geometry on a box ------------------------------------------------------------------

def test_box_chunks_have_exact_volumes():
    # 40 x 300 x 30 box, theta 60, s 50: centre wedge, two full slabs and a remainder per side
    solid, cs = chunked(box(40, 300, 30), theta_deg=60.0, shift=50.0)
    run = 30 / math.tan(math.radians(60))
    centre = 40 * (2 * run) * 30 / 2
    slab = 40 * 50 * 30
    rest = (40 * 300 * 30 - centre) / 2 - 2 * slab
    assert cs.ids == ["C", "L1", "L2", "L3", "R1", "R2", "R3"]
    expect = {"C": centre, "L1": slab, "L2": slab, "L3": rest, "R1": slab, "R2": slab, "R3": rest}
    for c in cs.chunks:
        assert c.volume == pytest.approx(expect[c.id], rel=1e-9), c.id
    assert cs.volume == pytest.approx(solid.volume, rel=1e-12)


def test_centre_chunk_is_narrower_at_its_top_and_faces_recede():
    _, cs = chunked(box(40, 300, 30), theta_deg=60.0, shift=50.0, top_width=10.0)
    c = cs["C"]
    t = t_coord(cs.plan, c.vertices)
    z = c.vertices[:, 2]
    base, top = np.ptp(t[z < 1e-9]), np.ptp(t[z > 30 - 1e-9])
    assert base == pytest.approx(10 + 2 * 30 / math.tan(math.radians(60)))
    assert top == pytest.approx(10.0)
    # every side chunk is a parallelogram leaning towards the centre: its top is nearer the centre
    for ch in cs.chunks[1:-1]:
        tt, zz = np.abs(t_coord(cs.plan, ch.vertices)), ch.vertices[:, 2]
        assert tt[zz > 30 - 1e-9].min() < tt[zz < 1e-9].min() - 1.0, ch.id


def test_dependencies_and_seed_assignment():
    _, cs = chunked(box(40, 300, 30), theta_deg=60.0, shift=50.0)
    assert cs.deps == {"C": (), "L1": ("C",), "L2": ("L1",), "L3": ("L2",),
                       "R1": ("C",), "R2": ("R1",), "R3": ("R2",)}
    a = seed_two_robots(cs, ["A", "B"])
    assert a.sequences == {"A": ("C", "L1", "L2", "L3"), "B": ("R1", "R2", "R3")}  # seed eq. (6)-(7)
    assert a.cross_robot_deps(cs.deps) == [("C", "R1")]  # the seed's single NOTIFY
    one = seed_two_robots(cs, ["A"])
    assert one.sequences["A"][0] == "C" and len(one.sequences["A"]) == 7


def test_object_off_centre_without_left_part():
    # the centre line at the left end: the L plane meets the top corner, so nothing lies left of it
    _, cs = chunked(box(40, 300, 30), theta_deg=60.0, shift=100.0, centre_offset=-150.0)
    assert [c.id for c in cs.chunks if c.role == "left"] == []
    assert cs.ids[0] == "C" and cs.ids[1] == "R1"


def test_rotated_centre_line_chunks_along_x():
    _, cs = chunked(box(300, 40, 30), theta_deg=60.0, shift=50.0, centre_angle_deg=90.0)
    np.testing.assert_allclose(cs.plan.axis, [-1, 0, 0], atol=1e-12)
    assert len(cs.chunks) == 7


# --- physical conditions ----------------------------------------------------------------------

def printhead_overlap(prior: np.ndarray, nozzle: np.ndarray, t_prior, t_nozzle, robot) -> float:
    """Largest height by which printed material pokes into the printhead body (positive = hit).

    The printhead body is everything at least ``nozzle_height`` above the nozzle tip and at most
    ``nozzle_depth`` ahead of it (towards the printed material), as in the seed's Fig. 3b.
    """
    worst = -np.inf
    for i in range(0, len(nozzle), 256):
        d = t_nozzle[i:i + 256, None] - t_prior[None, :]  # distance ahead, >= 0 towards the prior
        dz = prior[None, :, 2] - nozzle[i:i + 256, None, 2]
        ahead = (d >= 0) & (d <= robot.nozzle_depth)
        if ahead.any():
            worst = max(worst, float((dz - robot.nozzle_height)[ahead].max()))
    return worst


def sample(chunk, n=1500, seed=0):
    tm = trimesh.Trimesh(chunk.vertices, chunk.faces, process=False)
    pts, _ = trimesh.sample.sample_surface(tm, n, seed=seed)
    return np.vstack([chunk.vertices, pts])


def check_physics(cs, robot, tol=1e-6):
    """Reach and printhead clearance for every chunk, printed in dependency order."""
    plan = cs.plan
    for ch in cs.chunks:
        t = t_coord(plan, ch.vertices)
        assert np.ptp(t) <= robot.build_depth + tol, f"{ch.id} needs reach {np.ptp(t):.2f}"
        deps = _all_deps(cs, ch.id)
        if not deps:  # the first chunk printed (C, or a side chunk when C is empty)
            continue
        sgn = 1.0 if ch.role == "right" else -1.0  # robot stands outside, faces the centre
        prior = np.vstack([sample(cs[d]) for d in deps])
        noz = sample(ch, seed=1)
        hit = printhead_overlap(prior, noz, sgn * t_coord(plan, prior), sgn * t_coord(plan, noz), robot)
        assert hit <= tol, f"{ch.id}: printed material {hit:.3f} mm into the printhead"


def _all_deps(cs, cid):
    out, todo = [], list(cs.deps[cid])
    while todo:
        d = todo.pop()
        out.append(d)
        todo.extend(cs.deps[d])
    return out


@pytest.mark.parametrize("shape", [lambda: box(40, 300, 30), car, lambda: tube(25, 10, 60), lying_tube])
def test_reach_and_printhead_clearance_hold_for_every_chunk(shape):
    _, cs = chunked(shape(), theta_deg=None)  # theta_max: the steepest printable slope
    check_physics(cs, ROBOT)


def test_clearance_check_catches_a_slope_above_theta_max():
    # cut at 70 deg with a permissive robot, then check with a robot whose theta_max is 45 deg
    permissive = RobotProfile(nozzle_height=100, nozzle_depth=10)
    _, cs = chunked(box(40, 300, 60), permissive, theta_deg=70.0, shift=40.0)
    strict = RobotProfile(nozzle_height=20, nozzle_depth=20)
    with pytest.raises(AssertionError, match="into the printhead"):
        check_physics(cs, strict)


def test_reach_check_catches_a_too_wide_chunk():
    _, cs = chunked(box(40, 300, 30), theta_deg=60.0, shift=50.0)
    with pytest.raises(AssertionError, match="needs reach"):
        check_physics(cs, replace(ROBOT, build_depth=40.0))


# --- invariants on many shapes ----------------------------------------------------------------

def assert_valid_chunkset(solid, cs):
    # the cutter snaps a section point onto a mesh vertex closer than SNAP x diagonal (docs/chunker.md)
    snap = SNAP * float(np.linalg.norm(np.ptp(solid.vertices, axis=0)))
    assert cs.volume == pytest.approx(solid.volume, rel=1e-6)
    ids = cs.ids
    assert len(set(ids)) == len(ids) and ids[0] in ("C", "L1", "R1")
    for ch in cs.chunks:
        assert ch.volume > 0
        tm = trimesh.Trimesh(ch.vertices, ch.faces, process=False)
        assert tm.is_watertight and tm.is_winding_consistent, ch.id
        # two float formulas for the same volume: cancellation far from the origin is ~1e-12 of the solid
        assert tm.volume == pytest.approx(ch.volume, rel=1e-9, abs=1e-9 * solid.volume)
        for p in ch.planes:  # between its planes
            assert p.signed_distance(ch.vertices).max() <= snap + 1e-9, ch.id
        for d in cs.deps[ch.id]:
            assert d in ids


@pytest.mark.parametrize("shape", [box, car, tube, lying_tube, thin_walls])
def test_invariants_on_generated_shapes(shape):
    solid, cs = chunked(shape(), robot=RobotProfile(build_depth=400), shift=60.0)
    assert_valid_chunkset(solid, cs)
    assert len(cs.chunks) >= 3
