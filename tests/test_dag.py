"""Issue 14 item 2: the chunk DAG (precedence, body rule, exclusions) and the work estimates."""

from __future__ import annotations

import dataclasses
import graphlib
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cooprint.chunking import Chunk, ChunkSet, cut_chunks, plan_chunks
from cooprint.chunking.planes import ChunkPlan, SlopeLimits
from cooprint.config import ChunkingSettings, RobotProfile, SlicingSettings
from cooprint.errors import UserError
from cooprint.io.mesh import solid_from_trimesh
from cooprint.scheduling import ChunkDAG
from cooprint.scheduling.graph import (MIN_WORK, TOUCH, _Polygons, build_dag, convex_hull, ends_from_layers,
                                       signed_distance, swept, work_from_layers, work_from_volume)

from solids import box, car, to_trimesh

ROBOT = RobotProfile()  # bd 300, bl 350, bw 300, fw 300, nd 25
TRAVEL = SlicingSettings().travel_speed  # mm/s, between chunks
CLEAR = 5.0
UP, DOWN = (0.0, 1.0), (0.0, -1.0)

_BOX_FACES = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4],
                       [1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])


def box_chunk(cid: str, x0: float, x1: float, y0: float, y1: float, h: float = 50.0, facing=UP,
              row: int = 0, col: int = 0) -> Chunk:
    """An axis-aligned box chunk standing on the floor (8 vertices, outward triangles)."""
    v = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0],
                  [x0, y0, h], [x1, y0, h], [x1, y1, h], [x0, y1, h]], dtype=np.float64)
    return Chunk(cid, "centre", 0, v, _BOX_FACES.copy(), (x1 - x0) * (y1 - y0) * h, (), row, col, facing)


def chunk_set(chunks, deps=None, axis=(0.0, 1.0, 0.0)) -> ChunkSet:
    plan = ChunkPlan(60.0, 300.0, 0.0, 50.0, SlopeLimits(9.5, 76.0), (0.0, 0.0, 0.0), axis, 150.0, 0, 0, 300.0)
    deps = deps or {}
    return ChunkSet(plan, tuple(chunks), {c.id: tuple(deps.get(c.id, ())) for c in chunks},
                    float(sum(c.volume for c in chunks)), "grid")


def dag_of(cs: ChunkSet, clearance: float = CLEAR, robot: RobotProfile = ROBOT) -> ChunkDAG:
    return build_dag(cs, robot, clearance, {c.id: 10.0 for c in cs.chunks}, TRAVEL)


def rows(width=400.0, gap=0.0, depth=250.0, behind=True, n=4, gap_rows=10.0):
    """A front row F0..F3 along X at y in [0, depth] facing +Y and (``behind``) a second row
    B0..B3 just behind it (towards -Y), also facing +Y: the front row's robots stand on it."""
    out = []
    for j in range(n):
        x0 = j * (width + gap)
        out.append(box_chunk(f"F{j}", x0, x0 + width, 0.0, depth, row=0, col=j))
    if behind:
        for j in range(n):
            x0 = j * (width + gap)
            out.append(box_chunk(f"B{j}", x0, x0 + width, -gap_rows - depth, -gap_rows, row=-1, col=j))
    return out


# --- an independent oracle for box chunks facing +-Y: every swept part is an axis-aligned box ---

def _swept_box(c: Chunk, rect, facing):
    """The box a part ``rect`` = (u0, u1, v0, v1) covers over chunk ``c`` (facing +-Y)."""
    (x0, y0, _), (x1, y1, _) = c.bounds
    u0, u1, v0, v1 = rect
    if facing[1] > 0:  # u = +y, v = -x
        return (x0 - v1, y0 + u0, x1 - v0, y1 + u1)
    return (x0 + v0, y0 - u1, x1 + v1, y1 - u0)  # u = -y, v = +x


def _box_gap(a, b):
    gx = max(a[0] - b[2], b[0] - a[2])
    gy = max(a[1] - b[3], b[1] - a[3])
    return gx, gy


def _box_distance(a, b):
    gx, gy = _box_gap(a, b)
    return math.hypot(max(gx, 0.0), max(gy, 0.0)) if max(gx, gy) > 0 else max(gx, gy)


def oracle(cs: ChunkSet, clearance: float):
    """Body deps and exclusions of box chunks facing +-Y, from box arithmetic alone."""
    out = ROBOT.outline()
    body_pred = {c.id: set() for c in cs.chunks}
    for x in cs.chunks:
        b = _swept_box(x, out["body"], x.facing)
        for y in cs.chunks:
            if y.id != x.id:
                (x0, y0, _), (x1, y1, _) = y.bounds
                gx, gy = _box_gap(b, (x0, y0, x1, y1))
                if max(gx, gy) < -TOUCH:
                    body_pred[y.id].add(x.id)
    return body_pred, {(a.id, b.id) for i, a in enumerate(cs.chunks) for b in cs.chunks[i + 1:]
                       if min(_box_distance(_swept_box(a, out[p], a.facing), _swept_box(b, out[q], b.facing))
                              for p in out for q in out) < clearance - 1e-6}


def _ancestors(dag: ChunkDAG) -> dict[str, set[str]]:
    anc: dict[str, set[str]] = {}
    for c in dag.topological_order():
        anc[c] = set()
        for p in dag.preds(c):
            anc[c] |= anc[p] | {p}
    return anc


# --- geometry helpers ----------------------------------------------------------------------------

def test_convex_hull_drops_inner_and_collinear_points_and_runs_counter_clockwise():
    rng = np.random.default_rng(1)
    inner = rng.uniform(-1, 1, (500, 2))
    square = np.array([[-2, -2], [2, -2], [2, 2], [-2, 2], [0, -2], [2, 0]], dtype=float)
    h = convex_hull(np.vstack([inner, square, square]))
    assert sorted(map(tuple, h.tolist())) == sorted(map(tuple, square[:4].tolist()))
    x, y = h[:, 0], h[:, 1]
    assert 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)) == pytest.approx(16.0)  # CCW: area > 0


def _monotone_chain(points):
    """Reference hull (Andrew), counter-clockwise, strict turns only."""
    pts = sorted(set(map(tuple, np.asarray(points).tolist())))
    if len(pts) <= 2:
        return pts

    def half(seq):
        out = []
        for p in seq:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out

    return half(pts)[:-1] + half(pts[::-1])[:-1]


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 400), kind=st.sampled_from(["normal", "grid", "line", "ring"]))
def test_convex_hull_matches_the_monotone_chain(seed, n, kind):
    rng = np.random.default_rng(seed)
    if kind == "normal":
        pts = rng.normal(0, 100, (n, 2)) * rng.uniform(0.01, 1, 2)
    elif kind == "grid":  # many collinear and repeated points
        pts = rng.integers(-5, 6, (n, 2)).astype(float) * 10
    elif kind == "line":
        pts = np.outer(rng.integers(-50, 51, n), [3.0, -1.0]) + [7.0, 2.0]  # exactly on one line
    else:  # points on a circle and inside it, as a curved chunk's
        a = rng.uniform(0, 2 * np.pi, n)
        r = np.where(rng.random(n) < 0.5, 200.0, rng.uniform(0, 200, n))
        pts = np.column_stack([r * np.cos(a), r * np.sin(a)])
    got = convex_hull(pts)
    ref = np.array(_monotone_chain(pts))
    assert sorted(map(tuple, got.tolist())) == sorted(map(tuple, ref.tolist()))
    if len(got) >= 3:
        k = int(np.lexsort((got[:, 0], got[:, 1]))[0])
        assert k == 0 and _area(got) > 0  # from the lowest vertex, counter-clockwise


def test_swept_body_is_the_hull_moved_by_the_turned_rectangle():
    hull = convex_hull(np.array([[0, 0], [100, 0], [100, 50], [0, 50]], dtype=float))
    body = swept(hull, ROBOT.outline()["body"], np.array(UP))
    lo, hi = body.min(axis=0), body.max(axis=0)
    assert lo.tolist() == pytest.approx([-150.0, -650.0])
    assert hi.tolist() == pytest.approx([250.0, 50.0 - 300.0])


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), deg=st.floats(0.0, 360.0), part=st.sampled_from(["body", "frame", "printhead"]))
def test_swept_is_the_hull_of_every_vertex_plus_every_corner(seed, deg, part):
    rng = np.random.default_rng(seed)
    hull = convex_hull(rng.uniform(-300, 300, (int(rng.integers(3, 40)), 2)))
    f = np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])
    rect = ROBOT.outline()[part]
    u0, u1, v0, v1 = rect
    corners = np.array([[u, v] for u in (u0, u1) for v in (v0, v1)]) @ np.array([f, [-f[1], f[0]]])
    expect = convex_hull((hull[:, None] + corners[None]).reshape(-1, 2))
    got = swept(hull, rect, f)
    assert _area(got) == pytest.approx(_area(expect), rel=1e-9)
    for a, b in ((got, expect), (expect, got)):  # each polygon's vertices on or inside the other
        e = np.roll(b, -1, axis=0) - b
        rel = a[:, None, :] - b[None]
        assert (e[None, :, 0] * rel[..., 1] - e[None, :, 1] * rel[..., 0] >= -1e-6).all()


def _area(poly):
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def _brute_signed_distance(a, b):
    """Separating axes over all edge normals (O(k^2)); apart: the shortest vertex-edge distance."""
    gap = -np.inf
    for poly in (a, b):
        e = np.roll(poly, -1, axis=0) - poly
        n = np.column_stack([e[:, 1], -e[:, 0]]) / np.linalg.norm(e, axis=1)[:, None]
        pa, pb = a @ n.T, b @ n.T
        gap = max(gap, float(np.maximum(pa.min(0) - pb.max(0), pb.min(0) - pa.max(0)).max()))
    if gap <= 0:
        return gap
    best = np.inf
    for v, w in ((a, b), (b, a)):
        d = np.roll(w, -1, axis=0) - w
        rel = v[:, None] - w[None]
        t = np.clip((rel * d[None]).sum(-1) / (d * d).sum(-1)[None], 0, 1)
        best = min(best, float(np.linalg.norm(rel - t[..., None] * d[None], axis=-1).min()))
    return best


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), shift=st.floats(-200.0, 200.0), spin=st.floats(0.0, 360.0))
def test_signed_distance_of_convex_polygons_matches_the_brute_force(seed, shift, spin):
    rng = np.random.default_rng(seed)
    polys = [convex_hull(rng.normal(0, 60, (int(rng.integers(3, 30)), 2)) * rng.uniform(0.2, 2, 2))
             for _ in range(6)]
    c, s_ = math.cos(math.radians(spin)), math.sin(math.radians(spin))
    polys = [q @ np.array([[c, s_], [-s_, c]]) + [shift * (k % 3), 0.5 * shift * (k // 3)] for k, q in enumerate(polys)]
    pg = _Polygons(polys)
    ia, ib = np.repeat(np.arange(6), 6), np.tile(np.arange(6), 6)
    got = signed_distance(pg, ia, pg, ib)
    for k, (i, j) in enumerate(zip(ia, ib)):
        assert got[k] == pytest.approx(_brute_signed_distance(polys[i], polys[j]), abs=1e-6)


def test_a_turned_layout_gives_the_same_dag():
    """Rotation invariance: the rows of the other tests, facings and all, turned 30 degrees."""
    c, s_ = math.cos(math.radians(30)), math.sin(math.radians(30))
    turn = np.array([[c, -s_, 0], [s_, c, 0], [0, 0, 1]])
    for gap in (0.0, 100.0, 250.0):
        cs = chunk_set(rows(gap=gap, gap_rows=100.0))
        turned = chunk_set([Chunk(ch.id, ch.role, ch.index, ch.vertices @ turn.T, ch.faces, ch.volume, (), ch.row,
                                  ch.col, tuple((turn[:2, :2] @ np.array(ch.facing)).tolist()))
                            for ch in cs.chunks], axis=tuple((turn @ [0.0, 1.0, 0.0]).tolist()))
        a, b = dag_of(cs), dag_of(turned)
        assert a.body_deps == b.body_deps and a.exclusive == b.exclusive and a.exclusive
        assert b.facing[0].tolist() == pytest.approx([-s_, c])


# --- (b) the body rule -----------------------------------------------------------------------

def test_body_deps_point_from_the_front_row_to_the_row_its_robots_stand_on():
    # columns touching: each front robot's body (300 wide) reaches 150 mm into both neighbours
    dag = dag_of(chunk_set(rows(gap=0.0)))
    assert dag.body_deps["B0"] == ("F0", "F1")
    assert dag.body_deps["B1"] == ("F0", "F1", "F2")
    assert dag.body_deps["B3"] == ("F2", "F3")
    assert all(dag.body_deps[f"F{j}"] == () for j in range(4))  # nobody stands on the front row
    # columns 200 mm apart: the body (150 mm either side of the column) reaches only its own
    dag = dag_of(chunk_set(rows(gap=200.0)))
    assert [dag.body_deps[f"B{j}"] for j in range(4)] == [(f"F{j}",) for j in range(4)]
    # the body just touches the neighbour (150 mm gap): touching is not standing on it
    dag = dag_of(chunk_set(rows(gap=150.0)))
    assert [dag.body_deps[f"B{j}"] for j in range(4)] == [(f"F{j}",) for j in range(4)]
    # 1 mm into it: it does
    dag = dag_of(chunk_set(rows(gap=149.0)))
    assert dag.body_deps["B1"] == ("F0", "F1", "F2")


def test_no_body_dep_inside_one_row_and_none_beyond_the_body():
    dag = dag_of(chunk_set(rows(gap=0.0, behind=False)))
    assert all(v == () for v in dag.body_deps.values())
    # a row behind, beyond the body's far end (650 mm behind the nozzle): no dependency
    far = rows(gap=0.0, gap_rows=650.0 + 1.0)
    assert all(v == () for v in dag_of(chunk_set(far)).body_deps.values())
    near = rows(gap=0.0, gap_rows=650.0 - 0.4)  # B reaches 0.4 mm into the body's sweep: too little
    assert all(v == () for v in dag_of(chunk_set(near)).body_deps.values())
    nearer = rows(gap=0.0, gap_rows=650.0 - 10.0)
    assert dag_of(chunk_set(nearer)).body_deps["B0"] == ("F0", "F1")


def test_a_body_over_a_chunk_it_depends_on_is_a_one_line_user_error():
    # F1 leans on B1 (precedence a) but F1's robot stands on B1 while printing: no order works
    cs = chunk_set(rows(gap=200.0), deps={"F1": ("B1",)})
    with pytest.raises(UserError) as err:
        dag_of(cs)
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith("chunk F1: its robot's body would stand on chunk B1, which must be printed before it (")
    assert "B1 -> F1" in msg and msg.endswith("choose another layout)")
    # and through a chain: F1 after B0 after B1... (B0 leans on B1, F1 on B0)
    cs = chunk_set(rows(gap=200.0), deps={"F1": ("B0",), "B0": ("B1",)})
    with pytest.raises(UserError, match=r"chunk F1: .* chunk B1, .*\(B1 -> B0 -> F1;"):
        dag_of(cs)


def test_two_robots_standing_on_each_others_chunk_are_unprintable():
    # A faces +Y over a chunk behind it that faces -Y with its robot standing on A's chunk
    a = box_chunk("A", 0, 200, 0, 250, facing=UP)
    b = box_chunk("B", 0, 200, -600, -350, facing=DOWN)
    with pytest.raises(UserError, match="its robot's body would stand on chunk"):
        dag_of(chunk_set([a, b]))


# --- (c) exclusions ----------------------------------------------------------------------------

def test_neighbouring_columns_are_exclusive_until_apart_by_more_than_body_width_and_clearance():
    bw = ROBOT.body_width
    for gap, pairs in ((0.0, {("F0", "F1"), ("F1", "F2"), ("F2", "F3")}),
                       (bw + CLEAR - 1.0, {("F0", "F1"), ("F1", "F2"), ("F2", "F3")}),
                       (bw + CLEAR + 1.0, set())):
        dag = dag_of(chunk_set(rows(gap=gap, behind=False)))
        assert set(dag.exclusive) == pairs, gap
    # columns two apart never reach each other through one between
    dag = dag_of(chunk_set(rows(gap=0.0, behind=False)))
    assert ("F0", "F2") not in dag.exclusive


def test_pairs_ordered_by_the_body_rule_are_not_exclusive():
    dag = dag_of(chunk_set(rows(gap=0.0)))
    anc = _ancestors(dag)
    assert dag.exclusive
    for a, b in dag.exclusive:
        assert a not in anc[b] and b not in anc[a]
    assert ("F0", "B0") not in dag.exclusive and ("B0", "F0") not in dag.exclusive


def test_facing_none_is_the_plan_axis_and_ends_default_to_the_outer_base_edge():
    c = box_chunk("C", 0, 200, 0, 100, facing=None)
    dag = dag_of(chunk_set([c], axis=(1.0, 0.0, 0.0)))
    assert dag.facing[0].tolist() == pytest.approx([1.0, 0.0])
    assert dag.start[0].tolist() == pytest.approx([0.0, 50.0, 0.0])  # the -X edge's middle: the body's side
    assert dag.end[0].tolist() == pytest.approx([0.0, 50.0, 0.0])
    assert dag.footprint[0].tolist() == pytest.approx([0, 0, 200, 100])


def test_work_from_the_mapping_with_a_floor_for_empty_chunks():
    cs = chunk_set(rows(behind=False))
    dag = build_dag(cs, ROBOT, CLEAR, {"F0": 12.5, "F1": 0.0, "F2": 3.0, "F3": 4.0}, 100.0,
                    ends={"F0": (np.array([1.0, 2.0, 0.2]), np.array([3.0, 4.0, 50.0]))})
    assert dag.work.tolist() == [12.5, MIN_WORK, 3.0, 4.0]
    assert dag.start[0].tolist() == [1.0, 2.0, 0.2] and dag.end[0].tolist() == [3.0, 4.0, 50.0]
    assert dag.travel("F0", "F1") == pytest.approx(np.linalg.norm(dag.start[1, :2] - [3.0, 4.0]) / 100.0)
    with pytest.raises(ValueError, match="no work given for chunk F3"):
        build_dag(cs, ROBOT, CLEAR, {"F0": 1.0, "F1": 1.0, "F2": 1.0}, 100.0)


def test_no_chunks_and_one_chunk():
    empty = dag_of(chunk_set([]))
    assert empty.ids == () and empty.exclusive == () and empty.lower_bound(3) == 0.0
    one = dag_of(chunk_set([box_chunk("A", 0, 10, 0, 10)]))
    assert one.ids == ("A",) and one.body_deps == {"A": ()} and one.exclusive == ()
    assert one.start[0].tolist() == [5.0, 0.0, 0.0]  # facing +Y: the -Y edge's middle


@settings(max_examples=25, deadline=None)
@given(widths=st.lists(st.floats(150.0, 600.0), min_size=2, max_size=5),
       gaps=st.lists(st.floats(0.0, 400.0), min_size=4, max_size=4),
       gap_rows=st.floats(0.0, 800.0), depth=st.floats(100.0, 300.0),
       back_faces_down=st.booleans(), clearance=st.floats(0.0, 50.0))
def test_box_rows_match_the_box_oracle_each_pair_once_none_ordered_acyclic(widths, gaps, gap_rows, depth,
                                                                            back_faces_down, clearance):
    chunks, x = [], 0.0
    for j, w in enumerate(widths):
        chunks.append(box_chunk(f"F{j}", x, x + w, 0.0, depth, col=j))
        x += w + gaps[j % len(gaps)]
    x = 37.0
    for j, w in enumerate(widths):
        # facing -Y the back row's robots stand towards the front row: unprintable when close
        chunks.append(box_chunk(f"B{j}", x, x + w, -gap_rows - depth, -gap_rows, row=-1, col=j,
                                facing=DOWN if back_faces_down else UP))
        x += w + gaps[(j + 1) % len(gaps)]
    cs = chunk_set(chunks)
    body_pred, close = oracle(cs, clearance)
    try:
        dag = dag_of(cs, clearance)
    except UserError:  # the oracle must agree: its body rule alone has a cycle
        with pytest.raises(graphlib.CycleError):
            tuple(graphlib.TopologicalSorter(body_pred).static_order())
        return
    assert {c: set(v) for c, v in dag.body_deps.items()} == body_pred
    order = dag.topological_order()  # acyclic
    assert len(order) == len(dag.ids)
    anc = _ancestors(dag)
    pos = dag.index
    assert len(set(dag.exclusive)) == len(dag.exclusive)
    for a, b in dag.exclusive:
        assert pos[a] < pos[b]
        assert a not in anc[b] and b not in anc[a]
    expected = {(a, b) for a, b in close if a not in anc[b] and b not in anc[a]}
    assert set(dag.exclusive) == expected


def test_a_thousand_chunks_in_well_under_two_seconds():
    import time

    chunks = [box_chunk(f"G{r}_{c}", c * 420.0, c * 420.0 + 400.0, r * 700.0, r * 700.0 + 250.0, row=r, col=c,
                        facing=UP) for r in range(25) for c in range(40)]
    cs = chunk_set(chunks)
    t = time.process_time()  # CPU time: the suite shares two cores
    dag = dag_of(cs)
    assert time.process_time() - t < 2.0
    assert len(dag.ids) == 1000 and dag.exclusive


# --- seed2 chunks of a generated part -----------------------------------------------------------

def test_seed2_chunks_body_rule_agrees_with_the_leaning_order():
    solid = solid_from_trimesh(to_trimesh(car(1500.0)))
    plan = plan_chunks(solid.vertices, ROBOT, ChunkingSettings(), 2)
    cs = cut_chunks(solid, plan)
    dag = build_dag(cs, ROBOT, CLEAR, work_from_volume(cs, ROBOT, SlicingSettings()), TRAVEL)
    assert dag.ids == tuple(cs.ids)
    assert {"L1", "L2", "R1", "R2"} <= set(dag.ids)
    assert "L1" in dag.body_deps["L2"] and "R1" in dag.body_deps["R2"]
    assert "C" in dag.body_deps["L1"]  # the centre chunk is printed from the left (+axis)
    anc = _ancestors(dag)
    for c in dag.ids:
        for d in dag.body_deps[c]:
            assert c not in anc[d]
    assert dag.facing[dag.index["L1"]].tolist() == pytest.approx(list(plan.axis[:2]))
    assert dag.facing[dag.index["R1"]].tolist() == pytest.approx([-x for x in plan.axis[:2]])
    assert len(dag.topological_order()) == len(dag.ids)
    # the default top width (2 x nozzle_depth) makes L1's and R1's printhead sweeps just touch at
    # the top: exclusive with any clearance, not when outlines may touch (clearance 0)
    assert ("L1", "R1") in dag.exclusive
    touching = build_dag(cs, ROBOT, 0.0, {c: 1.0 for c in cs.ids}, TRAVEL)
    assert touching.exclusive == ()
    assert touching.body_deps == dag.body_deps


# --- work estimates ------------------------------------------------------------------------------

def _sliced(man, settings: SlicingSettings):
    from cooprint.slicing import iter_layers
    from cooprint.slicing.slicer import layer_range

    solid = solid_from_trimesh(to_trimesh(man))
    plan = plan_chunks(solid.vertices, ROBOT, ChunkingSettings(), 2)
    cs = cut_chunks(solid, plan)
    base = float(solid.vertices[:, 2].min())
    layers = {}
    for ch in cs.chunks:
        sol = ch.as_solid()
        first = layer_range(sol, settings, base)[0]
        layers[ch.id] = list(enumerate(iter_layers(sol, settings, base=base, workers=1), start=first))
    return cs, layers


BIG = SlicingSettings(layer_height=0.6, first_layer_height=0.6, nozzle_diameter=1.0, extrusion_width=1.2,
                      travel_speed=150.0)
FAST = RobotProfile(max_print_speed=35.0)  # the slicer's speeds, none above 35 mm/s


@pytest.fixture(scope="module")
def sliced_box():
    return _sliced(box(500, 900, 8), BIG)


def test_work_from_layers_is_the_simulators_time_of_the_chunks_layer_moves(sliced_box):
    from cooprint.program.build import layer_program
    from cooprint.program.commands import Program, quantize
    from cooprint.program.gcode import Feeds
    from cooprint.simulation.timeline import SimRobot, move_durations

    s, robot = BIG, FAST
    cs, layers = sliced_box
    work = work_from_layers(layers, robot, s)
    ends = ends_from_layers(layers)
    assert set(work) == set(cs.ids)
    for cid, chunk_layers in layers.items():
        first = ends[cid][0]
        here, pieces = first, []
        for li, layer in chunk_layers:
            piece, here = layer_program(layer, here, robot="A", index=li, chunk=cid)
            pieces.append(piece)
        prog = Program.concat("A", pieces)
        assert np.array_equal(ends[cid][1], here)
        _, _, _, on, _, dur = move_durations(SimRobot("A", prog, first, np.array([0.0, 1.0])), Feeds.of_robot(robot, s))
        assert on.any()
        assert work[cid] == pytest.approx(float(dur.sum()), rel=1e-6)
        # the first layer at first_layer_speed: slower there, longer in all
        slow_first = dataclasses.replace(s, first_layer_speed=5.0)
        assert work_from_layers({cid: chunk_layers}, robot, slow_first)[cid] > work[cid]
        assert np.array_equal(first, quantize(np.r_[chunk_layers[0][1].points[0], chunk_layers[0][1].z]))
    # a chunk with nothing to print: no work, no ends
    empty = {"E": []}
    assert work_from_layers(empty, robot, s) == {"E": 0.0} and ends_from_layers(empty) == {}


def test_work_from_volume_is_the_printed_volume_over_the_deposition_rate_times_the_factor():
    from cooprint.scheduling.graph import VOLUME_FACTOR, printed_volume, printed_volumes

    s = SlicingSettings()  # 2 perimeters of 0.45 mm, 4 + 4 layers of 0.2 mm, 20% infill
    cs = chunk_set(rows(behind=False))
    side = 2 * (400 + 250) * 50
    walls, top, bottom = side * 2 * 0.45, 400 * 250 * 4 * 0.2, 400 * 250 * 4 * 0.2
    sparse = 0.2 * (400 * 250 * 50 - walls - top - bottom)
    assert printed_volumes(cs["F0"], s) == pytest.approx((walls, top, bottom, sparse))
    expect = walls + top + bottom + sparse
    assert printed_volume(cs["F0"], s) == pytest.approx(expect)
    # each kind at its roles' speeds (harmonic means): the walls one external perimeter (30 mm/s)
    # and one inner (60), the top its surface (15) over 3 solid layers (20), the bottom solid (20),
    # the sparse infill 80 mm/s
    rate = 0.45 * 0.2
    seconds = (walls / (2 / (1 / 30 + 1 / 60)) + top / (4 / (1 / 15 + 3 / 20)) + bottom / 20 + sparse / 80) / rate
    w = work_from_volume(cs, ROBOT, s)
    assert w["F0"] == pytest.approx(VOLUME_FACTOR * seconds)
    # a robot capped at 25 mm/s lays the walls and the sparse infill slower, the rest as fast
    capped = work_from_volume(cs, RobotProfile(max_print_speed=25.0), s)
    seconds = (walls / (2 / (1 / 25 + 1 / 25)) + top / (4 / (1 / 15 + 3 / 20)) + bottom / 20 + sparse / 25) / rate
    assert capped["F0"] == pytest.approx(VOLUME_FACTOR * seconds)
    solid = chunk_set([box_chunk("S", 0, 10, 0, 10, 1.0)])  # all shell: the volume, solid
    assert printed_volume(solid["S"], s) == pytest.approx(100.0)


def test_work_from_volume_is_within_a_quarter_of_the_sliced_time(sliced_box):
    cs, layers = sliced_box
    sliced = work_from_layers(layers, FAST, BIG)
    estimate = work_from_volume(cs, FAST, BIG)
    for cid in cs.ids:
        assert estimate[cid] == pytest.approx(sliced[cid], rel=0.25), cid


def test_travel_between_sides_goes_round_the_part():
    """A robot that changes sides drives out of the part, round its footprint box at the detour
    distance and in: the schedulers see that cost (a straight line would cross the print)."""
    from cooprint.scheduling.dag import ChunkDAG

    box = np.array([[0.0, 0.0, 100.0, 100.0]] * 3)
    mid = np.array([[50.0, 50.0, 0.0]] * 3)
    facing = np.array([[0.0, 1.0], [0.0, -1.0], [0.0, 1.0]])
    dag = ChunkDAG(("a", "b", "c"), np.ones(3), facing, mid, mid, box, {}, travel_speed=10.0, detour=50.0)
    # a's robot backs out 100 mm to the ring (y = -50), goes half round the 200 x 200 mm ring
    # (400 mm) and comes in 100 mm from y = 150: 600 mm at 10 mm/s
    assert dag.travel("a", "b") == pytest.approx(60.0)
    assert dag.travel("a", "c") == pytest.approx(0.0)  # one facing: straight (here, no way at all)
    assert dag.travel_matrix().shape == (3, 3)
    assert dag.travel_matrix()[1, 0] == pytest.approx(60.0)
