"""The least-area triangulation of a closed 3-D polygon (a hole's boundary loop), by dynamic
programming over its diagonals (Barequet-Sharir; the first step of Liepa's hole filling).

Of all triangulations that use only the loop's vertices, the one of least total area: on a
planar loop it is a triangulation inside the polygon (any triangle outside adds area), on a loop
that climbs and comes back down (a car body's open bottom running up round its wheel arches) it
spans the arches with near-vertical "curtains" and closes the bottom flat, as the loop suggests,
where a fan from the centre would make a tent. O(k^3) time and O(k^2) memory for k vertices:
used up to :data:`MAX_LOOP` vertices (0.1 s at 500, 3 s at 1500).
"""

from __future__ import annotations

import numba
import numpy as np

from cooprint import jit

jit.setup()  # Ctrl-C held while numba compiles; LLVM calls untimed (cooprint.jit)

#: Largest loop triangulated by :func:`least_area_triangulation`, vertices.
MAX_LOOP = 1500


@numba.njit(cache=True)
def _tri_area(p: np.ndarray, i: int, m: int, j: int) -> float:
    ax, ay, az = p[m, 0] - p[i, 0], p[m, 1] - p[i, 1], p[m, 2] - p[i, 2]
    bx, by, bz = p[j, 0] - p[i, 0], p[j, 1] - p[i, 1], p[j, 2] - p[i, 2]
    cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    return 0.5 * np.sqrt(cx * cx + cy * cy + cz * cz)


@numba.njit(cache=True)
def _least_area(p: np.ndarray, banned: np.ndarray) -> np.ndarray:
    k = len(p)
    w = np.zeros((k, k))
    best = np.full((k, k), -1, dtype=np.int32)
    for gap in range(2, k):
        for i in range(k - gap):
            j = i + gap
            if banned[i, j] and gap < k - 1:
                w[i, j] = np.inf
                continue
            lo, arg = np.inf, -1
            for m in range(i + 1, j):
                c = w[i, m] + w[m, j] + _tri_area(p, i, m, j)
                if c < lo:
                    lo, arg = c, m
            w[i, j] = lo
            best[i, j] = arg
    if not w[0, k - 1] < np.inf:
        return np.empty((0, 3), dtype=np.int64)
    tris = np.empty((k - 2, 3), dtype=np.int64)
    stack = np.empty((k, 2), dtype=np.int64)
    stack[0, 0], stack[0, 1] = 0, k - 1
    top, n = 1, 0
    while top:
        top -= 1
        i, j = stack[top, 0], stack[top, 1]
        if j - i < 2:
            continue
        m = best[i, j]
        tris[n, 0], tris[n, 1], tris[n, 2] = i, m, j
        n += 1
        stack[top, 0], stack[top, 1] = i, m
        stack[top + 1, 0], stack[top + 1, 1] = m, j
        top += 2
    return tris


def least_area_triangulation(points: np.ndarray, banned: np.ndarray) -> np.ndarray | None:
    """(k - 2, 3) int64: triangles over the (k, 3) loop ``points`` (indices into them, wound
    as the loop runs), of least total area, using no diagonal (i, j), i < j, where
    ``banned[i, j]`` ((k, k) bool: the vertices already have an edge, which a second time
    would be non-manifold); ``None`` when every triangulation needs one."""
    tris = _least_area(np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(banned))
    return tris if len(tris) else None


@numba.njit(cache=True)
def _union_find(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    parent = np.arange(n)
    for k in range(len(a)):
        x, y = a[k], b[k]
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        while parent[y] != y:
            parent[y] = parent[parent[y]]
            y = parent[y]
        if x != y:
            if x < y:
                parent[y] = x
            else:
                parent[x] = y
    for i in range(n):  # parents are smaller: one pass in order settles every label
        parent[i] = parent[parent[i]]
    return parent


def components(n: int, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(n,) int64: for items 0 .. n - 1 joined by the links ``a[k] - b[k]``, the smallest item
    of each one's group (union-find, linear time; the repairs' fans and pieces)."""
    return _union_find(n, np.ascontiguousarray(a, dtype=np.int64), np.ascontiguousarray(b, dtype=np.int64))
