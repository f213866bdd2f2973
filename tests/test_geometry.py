"""Whole-array mesh checks (geometry.py) against a plain reading of their definitions."""

from collections import Counter

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from cooprint.geometry import edge_loops, is_closed, open_edges, winding_consistent

from solids import car, to_trimesh


def _directed(faces):
    return Counter((int(a), int(b)) for f in faces for a, b in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0])))


CAR_FACES = np.asarray(to_trimesh(car()).faces, dtype=np.int32)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["drop", "flip", "repeat", "none"]))
def test_closedness_and_open_edges_match_their_definitions(seed, damage):
    rng = np.random.default_rng(seed)
    faces = CAR_FACES.copy()
    k = rng.integers(0, len(faces), size=int(rng.integers(1, 6)))
    if damage == "drop":
        faces = np.delete(faces, k, axis=0)
    elif damage == "flip":
        faces[k] = faces[k, ::-1]
    elif damage == "repeat":
        faces = np.vstack([faces, faces[k]])
    directed = _directed(faces)
    repeats = any(c > 1 for c in directed.values())
    lone = sorted(e for e in directed if (e[1], e[0]) not in directed)
    assert winding_consistent(faces) == (not repeats)
    assert is_closed(faces) == (not repeats and not lone)
    got = open_edges(faces)
    if repeats:
        assert got is None
    else:
        assert sorted(zip(got[0].tolist(), got[1].tolist())) == lone


def test_a_pinch_vertex_splits_a_boundary_into_simple_loops():
    # two triangles' boundaries meeting at vertex 0, and a square: three loops
    src = np.array([0, 1, 2, 0, 3, 4, 5, 6, 7, 8])
    dst = np.array([1, 2, 0, 3, 4, 0, 6, 7, 8, 5])
    loops = edge_loops(src, dst)
    assert sorted(sorted(lp.tolist()) for lp in loops) == [[0, 1, 2], [0, 3, 4], [5, 6, 7, 8]]
    assert all(len(set(lp.tolist())) == len(lp) for lp in loops)


def test_edges_that_do_not_close_give_none():
    assert edge_loops(np.array([0, 1]), np.array([1, 2])) is None
