"""Small whole-array helpers on triangle meshes: (n, 3) float vertices, (m, 3) int faces."""

from __future__ import annotations

import numpy as np


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


def _directed_keys(faces: np.ndarray, n: np.int64, reverse: bool = False) -> np.ndarray:
    """(3m,) int64 sorted keys ``a * n + b`` of the directed edges a -> b (b -> a if ``reverse``),
    built in place: one array of 3m plus one temporary."""
    nxt = faces[:, [1, 2, 0]].ravel()
    if reverse:
        nxt *= n
        nxt += faces.ravel()
    else:
        nxt += faces.ravel() * n
    nxt.sort()
    return nxt


def winding_consistent(faces: np.ndarray) -> bool:
    """No directed edge used twice (neighbouring triangles run their shared edge oppositely)."""
    directed = _directed_keys(np.asarray(faces, dtype=np.int64), np.int64(int(faces.max()) + 1))
    return not bool((directed[1:] == directed[:-1]).any())


def open_edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Directed edges (src, dst) of the faces whose twin (dst -> src) no face has: the open
    boundary. ``None`` when a directed edge repeats (the winding is inconsistent, or more than
    two faces share an edge)."""
    f = np.asarray(faces, dtype=np.int64)
    n = np.int64(int(f.max()) + 1)
    d = _directed_keys(f, n)
    if (d[1:] == d[:-1]).any():
        return None
    twin = (d % n) * n + d // n
    pos = np.minimum(np.searchsorted(d, twin), len(d) - 1)
    lone = d[pos] != twin
    del twin, pos
    d = d[lone]
    return d // n, d % n


def edge_loops(src: np.ndarray, dst: np.ndarray) -> list[np.ndarray] | None:
    """Closed loops of the directed edges ``src[i] -> dst[i]``, each an (k,) vertex array.

    At a pinch vertex (two edges out) any choice closes a loop. Returns ``None`` when an edge
    leads to a vertex with no edge out (the edges do not form closed loops).
    """
    nxt: dict[int, list[int]] = {}
    for a, b in zip(src.tolist(), dst.tolist()):
        nxt.setdefault(a, []).append(b)
    loops = []
    while nxt:
        start = next(iter(nxt))
        loop, cur = [], start
        while True:
            loop.append(cur)
            outs = nxt.get(cur)
            if not outs:
                return None
            nb = outs.pop()
            if not outs:
                del nxt[cur]
            cur = nb
            if cur == start:
                break
        loops.append(np.asarray(loop, dtype=np.int64))
    return loops


def distinct_corners(faces: np.ndarray) -> np.ndarray:
    """(m,) bool: triangles whose three corners are three different vertices."""
    f = faces
    return (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])


def is_closed(faces: np.ndarray) -> bool:
    """Every edge shared by exactly two triangles, in opposite directions.

    Equivalently: no directed edge repeats, and the directed edges reversed are the same set.
    Two plain sorts, no argsort: about 5x faster than :func:`edge_table`.
    """
    if len(faces) == 0:
        return False
    f = np.asarray(faces, dtype=np.int64)
    n = np.int64(int(f.max()) + 1)
    fwd = _directed_keys(f, n)
    if (fwd[1:] == fwd[:-1]).any():
        return False
    return bool(np.array_equal(fwd, _directed_keys(f, n, reverse=True)))


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Volume enclosed by a closed, outward-wound mesh, mm^3 (divergence theorem)."""
    if len(faces) == 0:
        return 0.0
    v = np.asarray(vertices, dtype=np.float64)
    total = 0.0
    for lo in range(0, len(faces), 1 << 16):  # in slices: a few MB of temporaries at most
        f = faces[lo:lo + (1 << 16)]
        p, q, r = v[f[:, 0]].T, v[f[:, 1]].T, v[f[:, 2]].T
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
    """Only the vertices ``faces`` use, re-indexed."""
    used = np.zeros(len(vertices), dtype=bool)
    used[faces] = True
    if used.all():
        return vertices, faces
    remap = np.cumsum(used) - 1
    return vertices[used], remap[faces]
