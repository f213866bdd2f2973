"""Small whole-array helpers on triangle meshes: (n, 3) float vertices, (m, 3) int faces; and the
unit XY direction every stage takes a robot's facing as."""

from __future__ import annotations

import math

import numpy as np

#: Largest coordinate any input may hold, mm (1 km): every reader refuses a point farther from
#: the origin along an axis (a mesh, a ``.coop`` MOVE, a G-code move, a manifest start), so that
#: no stage meets a size its arrays cannot hold (a plan 1e308 mm wide, rasters of terabytes).
#: Nothing cooprint prints is near it; anything past it is a unit or file error.
MAX_COORD_MM = 1e6


def unit_xy(v) -> np.ndarray:
    """(2,) float64: the XY part of ``v`` scaled to length 1 (a robot's facing, a direction)."""
    a = np.asarray(v, dtype=np.float64)[:2]
    return a / np.linalg.norm(a)


def unit_deg(deg: float) -> np.ndarray:
    """(2,) float64: the unit XY vector at ``deg`` degrees from +X (a facing given in degrees)."""
    return np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])


def edge_table(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """Directed edges (3m, 2), how many triangles use each edge's undirected twin (3m,), and
    whether no directed edge repeats (the winding is consistent where edges are shared)."""
    edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    n = np.int64(max(int(faces.max()) + 1, 1))
    lo, hi = np.minimum(edges[:, 0], edges[:, 1]), np.maximum(edges[:, 0], edges[:, 1])
    key = lo * n + hi
    order = np.argsort(key)
    sk = key[order]
    starts = np.flatnonzero(np.r_[True, sk[1:] != sk[:-1]])
    uses = np.empty(len(key), dtype=np.int64)
    uses[order] = np.repeat(np.diff(np.r_[starts, len(sk)]), np.diff(np.r_[starts, len(sk)]))
    return edges, uses, winding_consistent(faces)


#: Faces handled per step by the whole-mesh checks below: their temporaries stay a few MB.
STEP = 1 << 16


def index_dtype(n_vertices: int) -> type:
    """The integer type for face indices into ``n_vertices`` vertices: int32 while it fits
    (half the memory of int64), int64 beyond."""
    return np.int32 if n_vertices < 2**31 else np.int64


def _edge_keys(faces: np.ndarray, n: np.int64) -> np.ndarray:
    """(3m,) int64 sorted keys of the directed edges a -> b: ``2 (min n + max) + (a < b)``, so an
    edge and its twin sort next to each other (twin first when a < b). Built a slice of faces at
    a time: the keys are the only whole-mesh array."""
    keys = np.empty(3 * len(faces), dtype=np.int64)
    for lo in range(0, len(faces), STEP):
        a = faces[lo:lo + STEP].astype(np.int64)
        b = a[:, [1, 2, 0]]
        k = np.minimum(a, b) * n + np.maximum(a, b)
        k *= 2
        k += a < b
        keys[3 * lo:3 * lo + k.size] = k.ravel()
    keys.sort()
    return keys


def _repeats(keys: np.ndarray) -> bool:
    """Whether a sorted array holds some value twice (here: a directed edge used twice)."""
    return bool((keys[1:] == keys[:-1]).any())


def _vertex_count(faces: np.ndarray) -> np.int64:
    return np.int64(int(faces.max()) + 1)


def winding_consistent(faces: np.ndarray) -> bool:
    """No directed edge used twice (neighbouring triangles run their shared edge oppositely)."""
    return not _repeats(_edge_keys(faces, _vertex_count(faces)))


def open_edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Directed edges (src, dst) of the faces whose twin (dst -> src) no face has: the open
    boundary. ``None`` when a directed edge repeats (the winding is inconsistent, or more than
    two faces share an edge)."""
    n = _vertex_count(faces)
    keys = _edge_keys(faces, n)
    if _repeats(keys):
        return None
    edge = keys >> 1  # without repeats, an edge is there once (open) or twice (with its twin)
    lone = np.ones(len(keys), dtype=bool)
    same = edge[1:] == edge[:-1]
    del edge
    lone[1:] &= ~same
    lone[:-1] &= ~same
    keys = keys[lone]
    lo, hi = (keys >> 1) // n, (keys >> 1) % n
    forward = (keys & 1).astype(bool)
    src, dst = np.where(forward, lo, hi), np.where(forward, hi, lo)
    order = np.argsort(src * n + dst)  # by source vertex: edge_loops' choices at pinch vertices
    return src[order], dst[order]


def edge_loops(src: np.ndarray, dst: np.ndarray) -> list[np.ndarray] | None:
    """Simple closed loops of the directed edges ``src[i] -> dst[i]``, each an (k,) vertex array.

    A walk that comes back to a vertex already on it closes the loop since then, so a pinch
    vertex (two edges out) splits its boundary into simple loops, whichever edge is taken.
    Returns ``None`` when an edge leads to a vertex with no edge out (the edges do not form
    closed loops).
    """
    nxt: dict[int, list[int]] = {}
    for a, b in zip(src.tolist(), dst.tolist()):
        nxt.setdefault(a, []).append(b)
    loops = []
    while nxt:
        cur = next(iter(nxt))
        path: list[int] = []
        where: dict[int, int] = {}
        while True:
            if cur in where:  # back on the walk: the part since then is a simple loop
                i = where[cur]
                for v in path[i:]:
                    del where[v]
                loops.append(np.asarray(path[i:], dtype=np.int64))
                del path[i:]
                if not path and cur not in nxt:
                    break
            outs = nxt.get(cur)
            if not outs:
                return None
            where[cur] = len(path)
            path.append(cur)
            nb = outs.pop()
            if not outs:
                del nxt[cur]
            cur = nb
    return loops


def distinct_corners(faces: np.ndarray) -> np.ndarray:
    """(m,) bool: triangles whose three corners are three different vertices."""
    f = faces
    return (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])


def is_closed(faces: np.ndarray) -> bool:
    """Every edge shared by exactly two triangles, in opposite directions.

    One sort of the directed edges (:func:`_edge_keys`): closed means the sorted keys come in
    pairs, an edge's two directions side by side. About 5x faster than :func:`edge_table`, and
    the keys are its only whole-mesh array.
    """
    if len(faces) == 0:
        return False
    keys = _edge_keys(faces, _vertex_count(faces))
    back, fwd = keys[0::2], keys[1::2]
    return bool(len(keys) % 2 == 0 and not (back & 1).any() and np.array_equal(fwd - back, np.ones_like(back)))


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Volume enclosed by a closed, outward-wound mesh, mm^3 (divergence theorem)."""
    if len(faces) == 0:
        return 0.0
    x, y, z = np.asarray(vertices, dtype=np.float64).T.copy()  # contiguous coordinates: fast gathers
    total = 0.0
    for lo in range(0, len(faces), STEP):  # in slices: a few MB of temporaries at most
        f = faces[lo:lo + STEP]
        p, q, r = ((x[f[:, k]], y[f[:, k]], z[f[:, k]]) for k in range(3))
        det = p[0] * (q[1] * r[2] - q[2] * r[1]) + p[1] * (q[2] * r[0] - q[0] * r[2]) \
            + p[2] * (q[0] * r[1] - q[1] * r[0])
        total += float(det.sum())
    return total / 6.0


def drop_cancelling(faces: np.ndarray) -> np.ndarray:
    """``faces`` without pairs of the same triangle wound both ways.

    Such a pair encloses no volume (a zero-thickness sliver, e.g. where a cutting plane grazes a
    face) but puts four faces on each of its edges. Of the triangles with one vertex set, the
    surplus of the more frequent winding is kept.
    """
    if len(faces) < 2:
        return faces
    order = np.argsort(faces, axis=1)
    key = np.take_along_axis(faces, order, axis=1)
    # winding parity: even for the cyclic orders (0,1,2), (1,2,0), (2,0,1) of the sort
    even = ((order[:, 1] - order[:, 0]) % 3) == 1
    _, group, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    group = group.ravel()
    if count.max() < 2:
        return faces
    n_even = np.bincount(group, weights=even, minlength=len(count)).astype(np.int64)
    surplus = 2 * n_even - count  # > 0: that many even ones kept, < 0: odd ones
    # rank of each face among the faces of its group with its parity
    idx = np.lexsort((np.arange(len(faces)), even, group))
    g, e = group[idx], even[idx]
    new = np.r_[True, (g[1:] != g[:-1]) | (e[1:] != e[:-1])]
    starts = np.flatnonzero(new)
    rank = np.arange(len(idx)) - np.repeat(starts, np.diff(np.r_[starts, len(idx)]))
    keep_n = np.where(e, np.maximum(surplus[g], 0), np.maximum(-surplus[g], 0))
    keep = np.zeros(len(faces), dtype=bool)
    keep[idx] = rank < keep_n
    return faces[keep]


def compact(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Only the vertices ``faces`` use, re-indexed (faces keep their integer type)."""
    used = np.zeros(len(vertices), dtype=bool)
    used[faces] = True
    if used.all():
        return vertices, faces
    remap = np.cumsum(used, dtype=faces.dtype)
    remap -= 1
    return vertices[used], remap[faces]
