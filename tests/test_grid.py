"""The grid layout (issue 14 item 1): rows as seed2's, each cut into even and odd columns."""

import math
import re
from dataclasses import replace

import manifold3d as m3d
import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings as hsettings, strategies as st

from cooprint.chunking import cut as cut_module
from cooprint.chunking import cut_chunks, plan_chunks
from cooprint.chunking.cut import SNAP
from cooprint.chunking.grid import grid_dependencies, lane_width, plan_grid
from cooprint.chunking.layouts import LAYOUTS, get_layout, layout_feasibility
from cooprint.chunking.split import CapError
from cooprint.config import ChunkingSettings, JobSettings, RobotProfile
from cooprint.errors import ConfigError, InfeasibleError, UserError
from cooprint.io.mesh import solid_from_trimesh
from cooprint.models import car

from solids import box, to_trimesh

ID = re.compile(r"^(C|L(\d+)|R(\d+))-(\d+)$")


def solid_of(man):
    return solid_from_trimesh(to_trimesh(man))


def job(robot=None, **chunking):
    return JobSettings(robot=robot or RobotProfile(), chunking=ChunkingSettings(**chunking))


def grid(man_or_solid, robots=4, settings=None):
    solid = man_or_solid if hasattr(man_or_solid, "vertices") else solid_of(man_or_solid)
    return solid, LAYOUTS["grid"](solid, settings or job(), robots)


def parse(cid):
    m = ID.match(cid)
    assert m, f"{cid} does not say where it is"
    row = 0 if m.group(1) == "C" else (-int(m.group(2)) if m.group(2) else int(m.group(3)))
    return row, int(m.group(4))


def column_planes(cs, ch):
    c = np.asarray(cs.plan.axis)
    return [p for p in ch.planes if abs(float(np.dot(p.normal, c))) < 1e-9]


def row_planes(cs, ch):
    u = np.asarray(cs.plan.columns.direction)
    return [p for p in ch.planes if abs(float(np.dot(p.normal, u))) < 1e-9]


def slope_deg(plane):
    n = np.asarray(plane.normal)
    return math.degrees(math.atan2(math.hypot(n[0], n[1]), abs(n[2])))


def u_span(cs, ch):
    t = ch.vertices @ np.asarray(cs.plan.columns.direction)
    return float(t.min()), float(t.max())


def expected_deps(cs):
    """The rule of issue 14 (a), from the ids and the extents: an odd column after its even
    neighbours in its row; a chunk of row k after the chunks of the row inside it whose extent
    along the centre line overlaps its own; nothing else."""
    tol = 1e-6 * max(cs.plan.columns.extent, 1.0)
    out = {}
    for a in cs.chunks:
        want = set()
        for b in cs.chunks:
            if b.row == a.row and a.col % 2 == 1 and abs(b.col - a.col) == 1:
                want.add(b.id)
            inner = a.row - 1 if a.row > 0 else a.row + 1
            if a.row != 0 and b.row == inner:
                (a0, a1), (b0, b1) = u_span(cs, a), u_span(cs, b)
                if min(a1, b1) - max(a0, b0) > tol:
                    want.add(b.id)
        out[a.id] = want
    return out


def assert_valid_grid(solid, cs, settings, robots):
    """Every promise of the grid layout on one chunk set."""
    robot = settings.robot
    theta_max = math.degrees(math.atan2(robot.nozzle_height, robot.nozzle_depth))
    snap = SNAP * float(np.linalg.norm(np.ptp(solid.vertices, axis=0)))
    assert cs.layout == "grid"
    assert cs.volume == pytest.approx(solid.volume, rel=1e-6)
    ids = cs.ids
    assert len(set(ids)) == len(ids)
    axis = np.asarray(cs.plan.axis)
    cols = cs.plan.columns
    lane = lane_width(robot, settings.program.clearance)
    for ch in cs.chunks:
        assert ch.volume > 1e-9 * solid.volume, ch.id
        tm = trimesh.Trimesh(ch.vertices, ch.faces, process=False)
        assert tm.is_watertight and tm.is_winding_consistent, ch.id
        assert tm.volume == pytest.approx(ch.volume, rel=1e-9, abs=1e-9 * solid.volume)
        row, col = parse(ch.id)
        assert (ch.row, ch.col) == (row, col)
        assert ch.role == ("centre" if row == 0 else "left" if row < 0 else "right") and ch.index == abs(row)
        for p in ch.planes:  # between its planes, every face at most theta_max steep
            assert p.signed_distance(ch.vertices).max() <= snap + 1e-9, ch.id
            assert slope_deg(p) <= theta_max + 1e-9 and slope_deg(p) == pytest.approx(cs.plan.theta_deg)
        for p in column_planes(cs, ch):  # even: both faces recede as they rise; odd: leans on them
            assert (p.normal[2] > 0) == (col % 2 == 0), (ch.id, p)
        for p in row_planes(cs, ch):  # the outer face recedes, the inner one leans
            outward = float(np.dot(p.normal, axis)) * (1 if row >= 0 else -1) > 0
            assert (p.normal[2] > 0) == (outward or row == 0), (ch.id, p)
        sign = 1.0 if row < 0 or (row == 0 and (col // 2) % 2 == 0) else -1.0
        assert ch.facing == pytest.approx((sign * axis[0], sign * axis[1]))
    # precedence (a): the rule, acyclic, and the chunk order respects it
    want = expected_deps(cs)
    seen = set()
    for ch in cs.chunks:
        assert set(cs.deps[ch.id]) == want[ch.id], ch.id
        assert set(cs.deps[ch.id]) <= seen, f"{ch.id} comes before one of {cs.deps[ch.id]}"
        seen.add(ch.id)
        if ch.row == 0 and ch.col % 2 == 0:
            assert cs.deps[ch.id] == ()
    # the lane rule: an even column's top and an odd column's base are at least a lane wide
    if cols.count > 1:
        assert cols.odd_base >= lane - 1e-9 and cols.period >= 2 * (lane + cols.run) - 1e-9
        assert cols.even_base == pytest.approx(cols.period / 2 + cols.run)


def test_slab_rows_and_columns():
    solid, cs = grid(box(2000, 600, 150), robots=4)
    assert_valid_grid(solid, cs, job(), 4)
    plan = cs.plan
    assert plan.rows == 5 and plan.columns.count == 4  # 2000 mm: two pairs of 2 x (305 + 37.5) mm at least
    assert plan.columns.run == pytest.approx(150 / 4)  # h / tan(atan(100/25))
    assert plan.columns.even_base == pytest.approx(537.5) and plan.columns.odd_base == pytest.approx(462.5)
    assert sorted(cs.ids) == sorted(f"{r}-{c}" for r in ("C", "L1", "L2", "R1", "R2") for c in range(4))
    assert cs.deps["C-1"] == ("C-0", "C-2") and cs.deps["C-3"] == ("C-2",)
    assert set(cs.deps["L1-2"]) == {"C-1", "C-2", "C-3"}
    assert set(cs.deps["R2-1"]) == {"R1-0", "R1-1", "R1-2", "R2-0", "R2-2"}


def test_measured_column_widths_follow_the_lane_rule():
    solid, cs = grid(box(3000, 600, 150), robots=4)
    cols, z_top = cs.plan.columns, 150.0
    lane = lane_width(RobotProfile(), 5.0)
    inner = [ch for ch in cs.chunks if 0 < ch.col < cols.count - 1 and ch.row == 0]  # rows 0 spans the height
    assert inner
    for ch in inner:  # an even column is narrowest at the top, an odd one at the floor
        z = ch.vertices[:, 2]
        at = np.isclose(z, z_top) if ch.col % 2 == 0 else np.isclose(z, 0.0)
        width = np.ptp(ch.vertices[at] @ np.asarray(cols.direction))
        assert width == pytest.approx(cols.odd_base) and width >= lane


def test_wall_within_the_build_depth_is_one_row():
    solid, cs = grid(box(4000, 300, 200), robots=4)
    assert_valid_grid(solid, cs, job(), 4)
    assert cs.plan.mode == "whole" and cs.plan.rows == 1
    assert cs.ids == ["C-0", "C-2", "C-4", "C-6", "C-1", "C-3", "C-5", "C-7"]  # four pairs, evens first
    assert [ch.facing[1] for ch in sorted(cs.chunks, key=lambda c: c.col)] == [1, 1, -1, -1, 1, 1, -1, -1]


def test_three_rows():
    solid, cs = grid(box(1500, 500, 100), robots=2)
    assert_valid_grid(solid, cs, job(), 2)
    assert sorted({ch.row for ch in cs.chunks}) == [-1, 0, 1]


def test_part_shorter_than_a_period_is_one_column_per_row():
    solid, cs = grid(box(500, 600, 100), robots=4)
    assert_valid_grid(solid, cs, job(), 4)
    assert cs.plan.columns.count == 1 and {ch.col for ch in cs.chunks} == {0}
    seed = cut_chunks(solid, plan_chunks(solid.vertices, RobotProfile(), ChunkingSettings(), 4))
    assert sorted(c.id.split("-")[0] for c in cs.chunks) == sorted(seed.ids)  # the seed's rows


def test_robots_set_the_number_of_pairs():
    for robots, count in ((1, 2), (2, 4), (3, 6), (8, 8)):  # 3000 mm holds 4 pairs of 2 x (305 + 5) mm
        _, cs = grid(box(3000, 300, 20), robots=robots)
        assert cs.plan.columns.count == count, robots


def test_column_width_sets_half_the_period_and_the_last_column_is_partial():
    settings = job(column_width=400.0)
    solid, cs = grid(box(2000, 300, 40), robots=4, settings=settings)
    assert_valid_grid(solid, cs, settings, 4)
    cols = cs.plan.columns
    assert cols.period == 800 and cols.given and cols.count == 5  # 400 + 10, 390, 410, 390, the rest
    last = max(cs.chunks, key=lambda c: c.col)
    assert last.col == 4 and last.volume < min(c.volume for c in cs.chunks if c.col < 4)


def test_column_width_too_narrow_for_the_robot_is_one_line():
    settings = job(column_width=300.0)
    with pytest.raises(InfeasibleError) as err:
        grid(box(2000, 600, 150), robots=4, settings=settings)
    text = str(err.value)
    assert "\n" not in text and len(text) < 250
    # the width asked for, the lane (robot width + clearance) and the smallest width allowed
    assert "chunking.column_width = 300 mm" in text and "lane 305.0" in text and "width 300 + clearance 5" in text
    assert "smallest 342.5 mm" in text and "chunking.column_width >= 342.5" in text
    f = layout_feasibility("grid", solid_of(box(2000, 600, 150)).vertices, settings, 4)
    assert not f.feasible and f.chunks == 0
    assert f.max_height == 0.0  # no height fits a column narrower than the lane


def test_a_wider_frame_or_clearance_widens_the_lane():
    robot = RobotProfile(frame_width=500.0)
    settings = replace(job(robot), program=replace(JobSettings().program, clearance=20.0))
    assert lane_width(robot, 20.0) == 520.0
    with pytest.raises(UserError, match=r"lane 520.0 \(body/frame/printhead width 500 \+ clearance 20\)"):
        narrow = replace(settings, chunking=ChunkingSettings(column_width=500.0))
        plan_grid(solid_of(box(3000, 300, 40)).vertices, narrow, 2)
    solid, cs = grid(box(3000, 300, 40), robots=8, settings=settings)
    assert_valid_grid(solid, cs, settings, 8)
    assert cs.plan.columns.odd_base >= 520.0


def test_islands_and_a_ring_drop_empty_chunks_and_keep_ids():
    two = box(800, 500, 60).translate((-800, 0, 0)) + box(800, 500, 60).translate((800, 0, 0))
    solid, cs = grid(two, robots=4)
    assert_valid_grid(solid, cs, job(), 4)
    ring_man = m3d.Manifold.cylinder(60, 900, 900, 128) - m3d.Manifold.cylinder(62, 600, 600, 128).translate((0, 0, -1))
    ring, rs = grid(ring_man, robots=6)
    assert_valid_grid(ring, rs, job(), 6)
    cols = rs.plan.columns.count
    centre_cols = {c.col for c in rs.chunks if c.row == 0}
    assert 0 in centre_cols and cols - 1 in centre_cols and len(centre_cols) < cols  # the hole: no chunk there
    assert len(rs.chunks) < rs.plan.rows * cols


def test_car_of_two_metres_along_and_across_the_centre_line():
    solid = car(2000.0)
    for angle in (0.0, 90.0):  # rows along the car, then columns along it
        settings = job(centre_angle_deg=angle)
        _, cs = grid(solid, robots=4, settings=settings)
        assert_valid_grid(solid, cs, settings, 4)
    assert cs.plan.columns.count > 1


def test_rotated_centre_line_cuts_columns_along_it():
    settings = job(centre_angle_deg=90.0)  # centre line along +Y, rows along -X
    solid, cs = grid(box(600, 2000, 150), robots=4, settings=settings)
    assert_valid_grid(solid, cs, settings, 4)
    assert cs.plan.columns.direction == pytest.approx((0, 1, 0)) and cs.plan.rows == 5
    c0 = [c for c in cs.chunks if c.col == 0]
    assert all(c.bounds[0][1] == pytest.approx(-1000) for c in c0)


def test_manifold_fallback_gives_the_same_chunks(monkeypatch):
    solid, expected = grid(box(2000, 600, 150), robots=4)

    def failing(*args, **kwargs):
        raise CapError("section is not a valid polygon")

    monkeypatch.setattr(cut_module, "split_mesh", failing)
    _, cs = grid(solid, robots=4)
    assert {c.id: c.volume for c in cs.chunks} == pytest.approx({c.id: c.volume for c in expected.chunks}, rel=1e-9)
    assert cs.deps == expected.deps
    assert_valid_grid(solid, cs, job(), 4)


def test_dependencies_come_from_the_geometry_not_the_ids():
    solid, cs = grid(box(2000, 600, 150), robots=4)
    renamed = tuple(replace(c, id=f"x{i}") for i, c in enumerate(cs.chunks))
    deps = grid_dependencies(renamed, np.asarray(cs.plan.columns.direction))
    back = {f"x{i}": c.id for i, c in enumerate(cs.chunks)}
    assert {back[k]: tuple(back[d] for d in v) for k, v in deps.items()} == cs.deps


def test_registry_and_seed2():
    solid = solid_of(box(400, 900, 60))
    settings = job()
    seed = LAYOUTS["seed2"](solid, settings, 2)
    ref = cut_chunks(solid, plan_chunks(solid.vertices, settings.robot, settings.chunking, 2))
    assert seed.layout == "seed2" and seed.ids == ref.ids and seed.deps == ref.deps
    assert get_layout("grid") is LAYOUTS["grid"] and set(LAYOUTS) == {"seed2", "grid"}
    with pytest.raises(ConfigError, match="chunking.layout = 'auto'"):
        get_layout("auto")
    with pytest.raises(InfeasibleError, match=r"^the seed2 layout takes 1 or 2 robots, not 3; use --layout grid$"):
        LAYOUTS["seed2"](solid, settings, 3)
    f = layout_feasibility("seed2", solid.vertices, settings, 3)
    assert not f.feasible and f.hints == ("--layout grid",)
    assert layout_feasibility("seed2", solid.vertices, settings, 2).chunks == len(ref.chunks)


def test_grid_feasibility_states_rows_columns_and_chunks():
    solid, cs = grid(box(2000, 600, 150), robots=4)
    f = layout_feasibility("grid", solid.vertices, job(), 4)
    assert f.feasible and f.chunks == len(cs.chunks) == 20
    assert "5 rows" in f.reason and "4 columns 500.0 mm wide" in f.reason and "lane 305.0" in f.reason
    tall = layout_feasibility("grid", solid_of(box(2000, 600, 700)).vertices, job(), 4)
    assert not tall.feasible and "centre chunk base" in tall.reason  # seed2's row limit, same words
    assert cs.plan.to_dict()["columns"]["columns"] == 4 and cs.plan.to_dict()["layout"] == "grid"


@hsettings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(x=st.floats(300, 4000), y=st.floats(100, 1400), z=st.floats(10, 200), robots=st.integers(1, 16),
       body=st.floats(150, 700), frame=st.none() | st.floats(100, 900), clearance=st.floats(1, 50),
       angle=st.sampled_from([0.0, 30.0, 90.0]), hole=st.booleans(), width=st.none() | st.floats(200, 1500))
def test_grid_properties(x, y, z, robots, body, frame, clearance, angle, hole, width):
    robot = RobotProfile(body_width=body, frame_width=frame)
    settings = job(robot, centre_angle_deg=angle, column_width=width)
    settings = replace(settings, program=replace(settings.program, clearance=clearance))
    man = box(x, y, z)
    if hole:  # a hole through the middle: rows and columns with two islands, or none
        man = man - box(x / 2, y / 2, z + 2).translate((0, 0, -1))
    solid = solid_of(man)
    run = z * robot.nozzle_depth / robot.nozzle_height  # h / tan(theta_max)
    if width is not None and width - run < lane_width(robot, clearance):
        with pytest.raises(InfeasibleError, match=r"^chunking.column_width = .* is too narrow: smallest"):
            LAYOUTS["grid"](solid, settings, robots)
        return
    cs = LAYOUTS["grid"](solid, settings, robots)
    assert_valid_grid(solid, cs, settings, robots)
    bound = layout_feasibility("grid", solid.vertices, settings, robots).chunks
    assert len(cs.chunks) == bound or (angle == 30.0 or hole or width) and len(cs.chunks) < bound


def test_too_many_chunks_is_refused_with_a_column_width():
    v = solid_of(box(30000, 3000, 10)).vertices
    f = layout_feasibility("grid", v, job(column_width=310.0), 64)
    assert not f.feasible and "more than 1,000" in f.reason and f.hints[0].startswith("chunking.column_width >= ")
    need = float(f.hints[0].split(">= ")[1])
    assert layout_feasibility("grid", v, job(column_width=need), 64).feasible


def closure(cs, cid):
    out, todo = set(), list(cs.deps[cid])
    while todo:
        d = todo.pop()
        if d not in out:
            out.add(d)
            todo.extend(cs.deps[d])
    return out


def sample(ch, n=1200, seed=0):
    tm = trimesh.Trimesh(ch.vertices, ch.faces, process=False)
    return np.vstack([ch.vertices, trimesh.sample.sample_surface(tm, n, seed=seed)[0]])


def worst_rise(cs, robot):
    """Seed Fig. 3b on the grid: the most that material of a chunk printed before (a dependency,
    transitively) rises above the printhead (``nozzle_height`` over the tip) within its square
    (half-side ``nozzle_depth`` around the nozzle), over sampled nozzle positions; <= 0 is clear."""
    c, u = np.asarray(cs.plan.axis), np.asarray(cs.plan.columns.direction)
    worst = -np.inf
    for ch in cs.chunks:
        before = closure(cs, ch.id)
        if not before:
            continue
        prior = np.vstack([sample(cs[d], 500) for d in before])
        noz = sample(ch, 500, seed=1)
        pc, pu = prior @ c, prior @ u
        for i in range(0, len(noz), 256):
            q = noz[i:i + 256]
            near = ((np.abs((q @ c)[:, None] - pc[None, :]) <= robot.nozzle_depth)
                    & (np.abs((q @ u)[:, None] - pu[None, :]) <= robot.nozzle_depth))
            if near.any():
                rise = prior[None, :, 2] - q[:, None, 2] - robot.nozzle_height
                worst = max(worst, float(rise[near].max()))
    return worst


@pytest.mark.parametrize("shape,robots", [(lambda: box(2000, 600, 150), 4), (lambda: box(4000, 300, 200), 4),
                                          (lambda: m3d.Manifold.cylinder(60, 900, 900, 96)
                                           - m3d.Manifold.cylinder(62, 600, 600, 96).translate((0, 0, -1)), 6)])
def test_printhead_clears_every_face_and_reach_holds(shape, robots):
    """Wherever the nozzle goes in a chunk, the printhead clears every chunk printed before it
    (:func:`worst_rise`), and each chunk lies within the build depth along the chunking axis."""
    robot = RobotProfile()
    solid, cs = grid(shape(), robots=robots)
    for ch in cs.chunks:
        assert np.ptp(ch.vertices @ np.asarray(cs.plan.axis)) <= robot.build_depth + 1e-6, ch.id
    assert worst_rise(cs, robot) <= 1e-6


def test_printhead_check_catches_a_face_steeper_than_theta_max():
    # the wall's column faces at 76 deg, checked with a robot whose theta_max is 45 deg
    _, cs = grid(box(4000, 300, 200), robots=4)
    assert worst_rise(cs, RobotProfile(nozzle_height=25, nozzle_depth=25)) > 1.0


def test_progress_counts_every_piece():
    calls = []
    solid = solid_of(box(2000, 600, 150))
    cs = LAYOUTS["grid"](solid, job(), 4, lambda done, total: calls.append((done, total)))
    assert calls[-1] == (len(cs.chunks), len(cs.chunks)) and [d for d, _ in calls] == list(range(1, len(calls) + 1))


def test_centre_row_top_is_a_clearance_wider_where_the_part_allows_it():
    """Two or more robots: the centre row's top is 2 nozzle_depth + clearance wide (rows L1 and
    R1 keep their printheads a clearance apart); a part too tall for that keeps seed2's
    2 nozzle_depth (nefertiti, 494.6 mm, was refused by the grid before)."""
    settings = JobSettings()
    low = solid_from_trimesh(to_trimesh(box(800.0, 600.0, 200.0)), path="<low>")
    tall = solid_from_trimesh(to_trimesh(box(800.0, 600.0, 495.0)), path="<tall>")
    nd, clearance = settings.robot.nozzle_depth, settings.program.clearance
    assert plan_grid(low.vertices, settings, 4).top_width == pytest.approx(2 * nd + clearance)
    assert plan_grid(tall.vertices, settings, 4).top_width == pytest.approx(2 * nd)
    assert plan_grid(low.vertices, settings, 1).top_width == 0.0
