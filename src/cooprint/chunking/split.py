"""Exact plane splits of closed triangle meshes, in numpy.

``split_mesh`` cuts a closed, consistently wound mesh by one plane into two closed meshes: the
triangles on each side, the crossing triangles split at the plane, and a cap on each side made of
the section polygons (with their holes and islands) triangulated by manifold3d. A vertex exactly
on the plane counts as being on the negative side (a symbolic perturbation), so every crossing
edge has one end strictly on each side and each section point lies on exactly one mesh edge,
shared by the two triangles of that edge: the two halves are closed by construction.

The one way this can fail is a section polygon that is not a valid polygon (a self-intersecting
mesh cut through its overlap): the cap triangulation then does not match the section's edges.
``split_mesh`` checks that and raises :class:`CapError`, and the caller falls back to
manifold3d, whose kernel handles such input.

Measured on a 1.6M-triangle mesh it is several times faster than building a manifold3d object
and splitting it (see docs/benchmarks.md).
"""

from __future__ import annotations

import manifold3d
import numpy as np

from cooprint.geometry import distinct_corners, drop_cancelling, edge_loops


class CapError(RuntimeError):
    """The section of the mesh by the plane is not a set of valid polygons."""


class Mesh:
    """A growing vertex pool shared by the pieces of one cutting job.

    Attributes
    ----------
    vertices : (n, 3) float64
        Every vertex made so far (original ones first, section points appended by each split).
    """

    def __init__(self, vertices: np.ndarray):
        self._blocks = [np.asarray(vertices, dtype=np.float64)]
        self._count = len(vertices)
        self._cache: np.ndarray | None = self._blocks[0]

    @property
    def vertices(self) -> np.ndarray:
        if self._cache is None:
            self._cache = np.concatenate(self._blocks)
            self._blocks = [self._cache]
        return self._cache

    def add(self, points: np.ndarray) -> np.ndarray:
        """Append (k, 3) points; return their indices."""
        idx = np.arange(self._count, self._count + len(points), dtype=np.int64)
        self._blocks.append(np.asarray(points, dtype=np.float64))
        self._count += len(points)
        self._cache = None
        return idx


def _plane_basis(normal: np.ndarray) -> np.ndarray:
    """Rows u, v with (u, v, normal) right-handed and orthonormal."""
    n = normal / np.linalg.norm(normal)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(helper, n)
    u /= np.linalg.norm(u)
    return np.vstack([u, np.cross(n, u)])


def _loops(src: np.ndarray, dst: np.ndarray) -> list[np.ndarray]:
    """Closed loops of directed edges ``src[i] -> dst[i]`` (every point in and out once)."""
    if len(np.unique(src)) != len(src):
        raise CapError("a section point has two outgoing edges")
    loops = edge_loops(src, dst)
    if loops is None:
        raise CapError("a section loop does not close")
    return loops


def _cap(points: np.ndarray, src: np.ndarray, dst: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Triangles closing the boundary ``src -> dst`` (indices into ``points``), wound so that
    every boundary edge appears reversed in them."""
    if len(src) == 0:
        return np.zeros((0, 3), dtype=np.int64)
    loops = _loops(src, dst)
    basis = _plane_basis(normal).T
    polys = [points[lp] @ basis for lp in loops]
    area = sum(float(np.dot(p[:, 0], np.roll(p[:, 1], -1)) - np.dot(np.roll(p[:, 0], -1), p[:, 1]))
               for p in polys)
    flip = area < 0  # triangulate fills counter-clockwise outlines
    if flip:
        polys = [p[::-1] for p in polys]
        loops = [lp[::-1] for lp in loops]
    tris = np.asarray(manifold3d.triangulate(polys), dtype=np.int64).reshape(-1, 3)
    tris = np.concatenate(loops)[tris]
    if not flip:  # loops ran along the boundary: the cap must run against it
        tris = tris[:, ::-1]
    _check_cap(tris, src, dst)
    return tris


def _check_cap(tris: np.ndarray, src: np.ndarray, dst: np.ndarray) -> None:
    """Every boundary edge reversed exactly once in the cap, every other cap edge paired."""
    e = tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    n = np.int64(max(int(e.max(initial=0)), int(src.max(initial=0)), int(dst.max(initial=0))) + 1)
    cap_keys = np.sort(e[:, 0] * n + e[:, 1])
    want = np.sort(dst * n + src)  # reversed boundary
    twins = np.sort(e[:, 1] * n + e[:, 0])
    if len(np.unique(cap_keys)) != len(cap_keys):
        raise CapError("cap repeats an edge")
    inner = np.setdiff1d(cap_keys, want, assume_unique=True)
    on_loop = np.intersect1d(cap_keys, want, assume_unique=True)
    forward = np.sort(src * n + dst)  # the mesh side already uses these
    if (len(on_loop) != len(want) or len(np.setdiff1d(inner, twins, assume_unique=True))
            or len(np.intersect1d(cap_keys, forward, assume_unique=True))):
        raise CapError("cap does not match the section")


def split_mesh(mesh: Mesh, faces: np.ndarray, normal, offset: float,
               snap: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Split the closed mesh ``faces`` (indices into ``mesh``) by the plane
    ``x . normal = offset``.

    A section point closer than ``snap`` (mm) to an end of its edge is that end: no sliver
    triangles, no points that single-precision STL would fuse with their neighbours.

    Returns
    -------
    pos, neg : (k, 3) int64
        Faces of the closed pieces on the side the normal points to and on the other side
        (either may be empty). Section points are appended to ``mesh``.

    Raises
    ------
    CapError
        When the section is not a valid set of polygons (see the module docstring).
    """
    normal = np.asarray(normal, dtype=np.float64)
    verts = mesh.vertices
    if len(faces) == 0:
        return faces, faces
    d = verts @ normal - offset
    side = d[faces] > 0  # (m, 3): True = positive; exactly on the plane counts as negative
    count = side.sum(axis=1)
    pos_whole, neg_whole = faces[count == 3], faces[count == 0]
    cross = (count == 1) | (count == 2)
    if not cross.any():
        return pos_whole, neg_whole
    cf, cs, cc = faces[cross], side[cross], count[cross]
    # rotate each crossing triangle (orientation kept) so that its lone vertex comes first
    lone_is_pos = cc == 1
    lone = np.where(lone_is_pos[:, None], cs, ~cs).argmax(axis=1)
    rot = (np.arange(3)[None, :] + lone[:, None]) % 3
    tri = np.take_along_axis(cf, rot, axis=1)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]

    # one section point per crossing edge, computed from the edge's endpoints in a fixed order
    lo_ab, hi_ab = np.minimum(a, b), np.maximum(a, b)
    lo_ac, hi_ac = np.minimum(a, c), np.maximum(a, c)
    n_v = np.int64(len(verts))
    keys = np.concatenate([lo_ab * n_v + hi_ab, lo_ac * n_v + hi_ac])
    uniq, inv = np.unique(keys, return_inverse=True)
    e0, e1 = uniq // n_v, uniq % n_v
    t = d[e0] / (d[e0] - d[e1])
    span = verts[e1] - verts[e0]
    pts = verts[e0] + t[:, None] * span
    length = np.linalg.norm(span, axis=1)
    to0 = t * length <= snap
    to1 = ((1 - t) * length <= snap) & ~to0
    fresh = ~(to0 | to1)
    new_idx = np.where(to0, e0, e1)
    new_idx[fresh] = mesh.add(pts[fresh])
    p_ab, p_ac = new_idx[inv[: len(a)]], new_idx[inv[len(a):]]

    # split: the lone vertex's side gets a triangle, the other side a quad (two triangles)
    tip = np.stack([a, p_ab, p_ac], axis=1)
    quad = np.concatenate([np.stack([p_ab, b, c], axis=1), np.stack([p_ab, c, p_ac], axis=1)])
    quad_pos = np.concatenate([~lone_is_pos, ~lone_is_pos])
    pos_parts = [pos_whole, _proper(tip[lone_is_pos]), _proper(quad[quad_pos])]
    neg_parts = [neg_whole, _proper(tip[~lone_is_pos]), _proper(quad[~quad_pos])]

    # the positive piece's open boundary: p_ab -> p_ac where the tip is positive, else reversed
    src = np.where(lone_is_pos, p_ab, p_ac)
    dst = np.where(lone_is_pos, p_ac, p_ab)
    keep = src != dst  # both ends snapped to one vertex: no edge left
    cap_pos = _cap(mesh.vertices, src[keep], dst[keep], normal)
    pos, neg = np.concatenate(pos_parts + [cap_pos]), np.concatenate(neg_parts + [cap_pos[:, ::-1]])
    if len(cap_pos):
        # a plane grazing a face can leave a cap triangle on that face, wound the other way:
        # drop both (only triangles lying in the plane can be such a pair)
        off = np.abs(mesh.vertices @ normal - offset) <= snap + 1e-9
        pos, neg = _without_cancelling(pos, off), _without_cancelling(neg, off)
    return pos, neg


def _without_cancelling(faces: np.ndarray, in_plane: np.ndarray) -> np.ndarray:
    flat = in_plane[faces].all(axis=1)
    if flat.sum() < 2:
        return faces
    return np.concatenate([faces[~flat], drop_cancelling(faces[flat])])


def _proper(tris: np.ndarray) -> np.ndarray:
    """Drop triangles that snapping collapsed (two corners the same vertex)."""
    return tris[distinct_corners(tris)]
