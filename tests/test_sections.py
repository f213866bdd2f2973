"""Mesh sectioning (slicing/sections.py) against manifold3d's own slice, and the loop invariants."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cooprint.io.mesh import solid_from_trimesh
from cooprint.slicing import sections
from cooprint.slicing.section_kernels import link, walk
from cooprint.slicing.sections import LayerSlicer

from solids import box, car, to_trimesh, tube


def ring_area(r):
    return 0.5 * float(np.sum(r[:, 0] * np.roll(r[:, 1], -1) - np.roll(r[:, 0], -1) * r[:, 1]))


@pytest.mark.parametrize("shape", [lambda: box(20, 10, 5), lambda: tube(25, 10, 20), car])
def test_sections_match_manifold3d(shape):
    sol = solid_from_trimesh(to_trimesh(shape()))
    lo, hi = sol.bounds[0, 2], sol.bounds[1, 2]
    zs = np.linspace(lo + 0.013, hi - 0.013, 37)
    ours = LayerSlicer(sol.vertices, sol.faces).sections(zs)
    for z, cs in zip(zs, ours):
        ref = sol.manifold.slice(float(z))
        assert cs.area() == pytest.approx(ref.area(), rel=1e-9, abs=1e-9)
        assert (cs ^ ref).area() == pytest.approx(ref.area(), rel=1e-7, abs=1e-9)


def test_outlines_run_counter_clockwise_and_holes_clockwise():
    sol = solid_from_trimesh(to_trimesh(tube(25, 10, 20)))
    (rings,) = LayerSlicer(sol.vertices, sol.faces).rings(np.array([10.0]))
    areas = sorted(ring_area(r) for r in rings)
    assert len(areas) == 2 and areas[0] < 0 < areas[1]
    assert areas[1] + areas[0] == pytest.approx(np.pi * (25**2 - 10**2), rel=0.01)


def test_a_plane_through_vertices_counts_them_below():
    sol = solid_from_trimesh(to_trimesh(box(20, 10, 5)))  # corners at z = 0 and z = 5
    a, b, c = LayerSlicer(sol.vertices, sol.faces).sections(np.array([0.0, 2.5, 5.0]))
    assert a.area() == pytest.approx(200.0) and b.area() == pytest.approx(200.0) and c.is_empty()


def test_an_open_mesh_is_refused():
    sol = solid_from_trimesh(to_trimesh(box(20, 10, 5)))
    z = sol.vertices[sol.faces, 2]
    side = int(np.flatnonzero((z.min(axis=1) < 2.5) & (z.max(axis=1) > 2.5))[0])  # a wall triangle
    faces = np.delete(sol.faces, side, axis=0)
    with pytest.raises(ValueError, match="not closed"):
        LayerSlicer(sol.vertices, faces).rings(np.array([2.5]))


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(1, 40), min_size=1, max_size=12), st.randoms(use_true_random=False))
def test_walk_gives_each_cycle_from_its_smallest_member(lengths, rnd):
    # build a permutation out of cycles of the given lengths over shuffled elements
    n = sum(lengths)
    perm = list(range(n))
    rnd.shuffle(perm)
    nxt = np.empty(n, dtype=np.int64)
    cycles, at = [], 0
    for L in lengths:
        members = perm[at:at + L]
        at += L
        for i, m in enumerate(members):
            nxt[m] = members[(i + 1) % L]
        cycles.append(members)
    # each element's point is (its number, 2 x its number), its layer 3 x its number
    start = np.stack([np.arange(n), 2 * np.arange(n)], axis=1).astype(np.float64)
    pts, ring_at, ring_layer = walk(nxt, start, 3 * np.arange(n, dtype=np.int64), 0.0, 0)
    assert np.array_equal(pts[:, 1], 2 * pts[:, 0])
    order = pts[:, 0].astype(np.int64)
    walked = [order[a:b].tolist() for a, b in zip(ring_at[:-1], ring_at[1:])]
    assert ring_layer.tolist() == [3 * w[0] for w in walked]
    expected = []
    for members in sorted(cycles, key=min):  # cycles by their smallest member, each walked from it
        cur, seen = min(members), []
        for _ in range(len(members)):
            seen.append(cur)
            cur = int(nxt[cur])
        expected.append(seen)
    assert walked == expected


def test_walk_drops_collinear_points_and_keeps_the_outline():
    """A square whose sides carry 1,000 vertices each (a finely tessellated flat face's section,
    with float noise) keeps its 4 corners; a fine circle (sagitta far below the tolerance) keeps
    its area within the promised drift; a triangle, and a ring after a compacted one, stay as
    they were; without ``eps`` nothing is dropped."""
    t = np.linspace(0.0, 1.0, 1000, endpoint=False)
    side = [np.c_[t, 0 * t], np.c_[1 + 0 * t, t], np.c_[1 - t, 1 + 0 * t], np.c_[0 * t, 1 - t]]
    square = 50.0 * np.concatenate(side) + np.random.default_rng(1).normal(0, 1e-9, (4000, 2))
    a = np.linspace(0.0, 2 * np.pi, 20000, endpoint=False)
    circle = np.c_[np.cos(a), np.sin(a)] * 10.0
    tri = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    rings = [square, circle, tri]
    start = np.concatenate(rings)
    at = np.cumsum([0] + [len(r) for r in rings])
    nxt = np.arange(1, len(start) + 1, dtype=np.int64)
    nxt[at[1:] - 1] = at[:-1]  # each ring a cycle from its first point
    layer = np.zeros(len(start), np.int64)
    pts, ring_at, _ = walk(nxt, start, layer, 1e-6, sections.COLLINEAR_RUN)
    sq, c, tr = (pts[a:b] for a, b in zip(ring_at[:-1], ring_at[1:]))
    assert len(sq) == 4 and np.allclose(sq, [[0, 0], [50, 0], [50, 50], [0, 50]], atol=1e-6)
    assert len(c) < len(circle) and abs(abs(ring_area(c)) - np.pi * 100) < 2 * np.pi * 10 * 1024 * 1e-6
    assert np.array_equal(tr, tri)
    pts, ring_at, _ = walk(nxt, start, layer, 0.0, sections.COLLINEAR_RUN)
    assert np.array_equal(pts, start) and ring_at.tolist() == at.tolist()


def test_link_finds_the_next_segment_and_refuses_open_chains():
    s_key = np.array([30, 10, 20], np.int64)
    e_key = np.array([10, 20, 30], np.int64)
    assert link(s_key, e_key).tolist() == [1, 2, 0]
    with pytest.raises(ValueError, match="not closed"):
        link(s_key, np.array([10, 20, 40], np.int64))  # 40 starts no segment
    with pytest.raises(ValueError, match="not closed"):
        link(np.array([10, 10], np.int64), np.array([10, 10], np.int64))  # two segments start on one edge
    with pytest.raises(ValueError, match="not closed"):
        walk(np.array([1, 1], np.int64), np.zeros((2, 2)), np.zeros(2, np.int64), 0.0, 0)  # not a permutation


def test_segment_groups_change_nothing(monkeypatch):
    sol = solid_from_trimesh(to_trimesh(car()))
    zs = np.linspace(sol.bounds[0, 2] + 0.01, sol.bounds[1, 2] - 0.01, 23)
    whole = LayerSlicer(sol.vertices, sol.faces).rings(zs)
    monkeypatch.setattr(sections, "SEGMENTS", 50)  # many groups, a layer alone over the budget
    grouped = LayerSlicer(sol.vertices, sol.faces).rings(zs)
    assert [len(r) for r in grouped] == [len(r) for r in whole]
    for a, b in zip(grouped, whole):
        for ra, rb in zip(a, b):
            np.testing.assert_array_equal(ra, rb)
