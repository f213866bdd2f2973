"""A polyline cut where it crosses a region's boundary (overhang perimeters, issue 17): compiled
kernels (numba) for the crossings and the inside test, no Python loop per point.

The kernels are loaded in the process that forks the slicing workers (:func:`warm`), so that
every worker has them without loading numba's cache again.
"""

from __future__ import annotations

import numba
import numpy as np

from cooprint import jit

jit.setup()  # Ctrl-C held while numba compiles; LLVM calls untimed (cooprint.jit)


def split_by_region(line: np.ndarray, rings: list[np.ndarray]) -> list[tuple[np.ndarray, bool]]:
    """``line`` (k, 2) cut where it crosses the boundary of the region of ``rings`` (even-odd):
    ``[(piece, inside)]`` in order, consecutive pieces sharing their end points."""
    if not rings:
        return [(line, False)]
    a0 = np.concatenate(rings)
    a1 = np.concatenate([np.roll(r, -1, axis=0) for r in rings])
    params = _crossings(line, a0, a1)
    if len(params) == 0:  # no crossing: all inside or all outside
        return [(line, bool(_inside((line[:1] + line[1:2]) / 2, a0, a1)[0]))]
    params = np.sort(np.concatenate([np.arange(len(line), dtype=np.float64), params]))
    k = np.minimum(np.floor(params).astype(np.int64), len(line) - 2)
    pts = line[k] + (params - k)[:, None] * (line[k + 1] - line[k])
    inside = _inside((pts[1:] + pts[:-1]) / 2, a0, a1)
    cuts = np.flatnonzero(inside[1:] != inside[:-1]) + 1
    bounds = np.concatenate([[0], cuts, [len(inside)]])
    return [(pts[b0:b1 + 1], bool(inside[b0])) for b0, b1 in zip(bounds[:-1].tolist(), bounds[1:].tolist())]


def warm() -> None:
    """Load the kernels in this process (a few tenths of a second, once)."""
    split_by_region(np.array([[0.0, 0.0], [2.0, 0.0]]), [np.array([[1.0, -1.0], [3.0, -1.0], [3.0, 1.0]])])


@numba.njit(cache=True, nogil=True)
def _crossings(line: np.ndarray, a0: np.ndarray, a1: np.ndarray) -> np.ndarray:
    """Where the polyline ``line`` crosses the edges ``a0 -> a1``: ``segment index + t`` of every
    crossing strictly inside a segment (unsorted)."""
    out = np.empty(64)
    n = 0
    for i in range(len(line) - 1):
        px, py, qx, qy = line[i, 0], line[i, 1], line[i + 1, 0], line[i + 1, 1]
        dx, dy = qx - px, qy - py
        sx0, sx1, sy0, sy1 = min(px, qx), max(px, qx), min(py, qy), max(py, qy)
        for e in range(len(a0)):
            ax, ay, bx, by = a0[e, 0], a0[e, 1], a1[e, 0], a1[e, 1]
            if max(ax, bx) < sx0 or min(ax, bx) > sx1 or max(ay, by) < sy0 or min(ay, by) > sy1:
                continue
            ex, ey = bx - ax, by - ay
            den = dx * ey - dy * ex
            if abs(den) < 1e-15:
                continue
            wx, wy = ax - px, ay - py
            t = (wx * ey - wy * ex) / den
            u = (wx * dy - wy * dx) / den
            if 1e-9 < t < 1 - 1e-9 and 0 <= u < 1:
                if n == len(out):
                    grown = np.empty(2 * n)
                    grown[:n] = out
                    out = grown
                out[n] = i + t
                n += 1
    return out[:n].copy()


@numba.njit(cache=True, nogil=True)
def _inside(pts: np.ndarray, a0: np.ndarray, a1: np.ndarray) -> np.ndarray:
    """Whether each point is inside the region whose boundary edges are ``a0 -> a1`` (even-odd)."""
    res = np.zeros(len(pts), dtype=np.bool_)
    for k in range(len(pts)):
        x, y = pts[k, 0], pts[k, 1]
        c = False
        for e in range(len(a0)):
            y0, y1 = a0[e, 1], a1[e, 1]
            if (y0 > y) != (y1 > y):
                xc = a0[e, 0] + (y - y0) * (a1[e, 0] - a0[e, 0]) / (y1 - y0)
                if x < xc:
                    c = not c
        res[k] = c
    return res
