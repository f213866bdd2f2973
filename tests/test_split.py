"""The numpy plane splitter: closed halves, exact volumes, degenerate planes, fallback."""

import numpy as np
import pytest

from cooprint.chunking import cut_chunks, plan_chunks
from cooprint.chunking import cut as cut_module
from cooprint.chunking.split import CapError, Mesh, _check_cap, split_mesh
from cooprint.config import ChunkingSettings, RobotProfile
from cooprint.geometry import compact, drop_cancelling, is_closed, signed_volume
from cooprint.io.mesh import solid_from_arrays

from solids import box, lying_tube, to_trimesh, tube


def arrays(man):
    tm = to_trimesh(man)
    return np.asarray(tm.vertices, dtype=np.float64), np.asarray(tm.faces, dtype=np.int64)


def split(man, normal, offset, snap=0.0):
    v, f = arrays(man)
    pool = Mesh(v)
    pos, neg = split_mesh(pool, f, normal, offset, snap)
    return pool.vertices, pos, neg, signed_volume(v, f)


@pytest.mark.parametrize("normal, offset", [
    ((0, 0, 1), 5.0),            # through the middle of a 20 x 30 x 10 box
    ((0, 0, 1), 10.0),           # exactly through the top face's vertices
    ((0, 0, 1), 0.0),            # exactly through the bottom face
    ((1, 0, 0), 0.0),            # through the middle, along edges of the box's triangulation
    ((0.3, 0.5, 0.8), 4.0),      # oblique
])
def test_box_halves_are_closed_and_add_up(normal, offset):
    n = np.asarray(normal, dtype=float) / np.linalg.norm(normal)
    v, pos, neg, total = split(box(20, 30, 10), n, offset)
    vp, vn = signed_volume(v, pos), signed_volume(v, neg)
    assert vp + vn == pytest.approx(total, rel=1e-12)
    for piece, sign in ((pos, 1.0), (neg, -1.0)):
        # a plane through a face leaves a zero-volume sliver on one side (dropped as dust by
        # cut_chunks); every piece with volume is closed
        if abs(signed_volume(v, piece)) > 1e-9:
            assert is_closed(piece)
            d = sign * (compact(v, piece)[0] @ n - offset)
            assert d.min() >= -1e-9  # every vertex on its own side of the plane
    # manifold3d's split of the same solid gives the same volumes
    ref_pos, ref_neg = box(20, 30, 10).split_by_plane(tuple(n), offset)
    assert vp == pytest.approx(ref_pos.volume(), abs=1e-9)
    assert vn == pytest.approx(ref_neg.volume(), abs=1e-9)


def test_section_with_holes_and_islands():
    # a lying pipe cut across: every section is an annulus; two pipes side by side: two islands
    pipes = lying_tube(30, 18, 200) + lying_tube(30, 18, 200).translate((80, 0, 0))
    v, pos, neg, total = split(pipes, (0, 1, 0), 13.0)
    assert is_closed(pos) and is_closed(neg)
    assert signed_volume(v, pos) == pytest.approx(total / 2 - 13.0 * 2 * np.pi * (30**2 - 18**2) * 0.9935,
                                                  rel=1e-2)
    assert signed_volume(v, pos) + signed_volume(v, neg) == pytest.approx(total, rel=1e-12)


def test_snap_merges_points_next_to_vertices():
    v, f = arrays(box(20, 30, 10))
    pool = Mesh(v)
    pos, neg = split_mesh(pool, f, (0, 0, 1), 10.0 - 1e-9, snap=1e-6)
    assert len(pool.vertices) == len(v)  # every section point snapped onto a top corner
    assert abs(signed_volume(pool.vertices, pos)) < 1e-6  # only a flat sliver above the plane
    assert is_closed(neg)
    assert signed_volume(pool.vertices, neg) == pytest.approx(20 * 30 * 10, rel=1e-9)


def test_cap_check_rejects_a_cap_that_does_not_close_the_section():
    src, dst = np.array([0, 1, 2, 3]), np.array([1, 2, 3, 0])  # a square loop 0-1-2-3
    good = np.array([[1, 0, 3], [1, 3, 2]])  # against the loop: closes it
    _check_cap(good, src, dst)
    for bad in (good[:1],                    # a triangle missing
                good[:, ::-1],               # along the loop instead of against it
                np.array([[1, 0, 3], [1, 3, 2], [1, 3, 2]])):  # an edge repeated
        with pytest.raises(CapError):
            _check_cap(bad, src, dst)


def test_cut_chunks_falls_back_to_manifold_when_a_cap_fails(monkeypatch):
    solid = solid_from_arrays(*arrays(tube(25, 10, 60)))
    plan = plan_chunks(solid.vertices, RobotProfile(), ChunkingSettings(theta_deg=70, shift=12), robots=1)
    expected = {c.id: c.volume for c in cut_chunks(solid, plan).chunks}

    def failing(*args, **kwargs):
        raise CapError("section is not a valid polygon")

    monkeypatch.setattr(cut_module, "split_mesh", failing)
    cs = cut_chunks(solid, plan)
    assert {c.id: c.volume for c in cs.chunks} == pytest.approx(expected, rel=1e-9)
    for ch in cs.chunks:
        assert is_closed(ch.faces)


def test_numpy_and_manifold_kernels_agree_on_a_tube():
    solid = solid_from_arrays(*arrays(tube(25, 10, 60)))
    plan = plan_chunks(solid.vertices, RobotProfile(), ChunkingSettings(theta_deg=70, shift=12), robots=1)
    ours = {c.id: c.volume for c in cut_chunks(solid, plan).chunks}
    kernel = cut_module._ManifoldKernel(solid)
    ref = {sp.id: kernel.extract(sp.piece)[2] for sp in cut_module.row_pieces(kernel, plan)}
    assert set(ours) <= set(ref) and len(ours) >= 5
    for cid, vol in ours.items():
        assert vol == pytest.approx(ref[cid], rel=1e-9), cid


def test_drop_cancelling_removes_triangles_wound_both_ways():
    faces = np.array([[0, 1, 2], [3, 4, 5], [2, 1, 0], [1, 2, 0], [4, 5, 3], [6, 7, 8]])
    out = drop_cancelling(faces)
    # (0,1,2) and (1,2,0) are one winding, (2,1,0) the other: one pair cancels, one (0,1,2) stays;
    # (3,4,5) and (4,5,3) are the same winding: both stay
    assert sorted(map(tuple, out.tolist())) == [(0, 1, 2), (3, 4, 5), (4, 5, 3), (6, 7, 8)]
    assert np.array_equal(drop_cancelling(faces[[1, 5]]), faces[[1, 5]])
