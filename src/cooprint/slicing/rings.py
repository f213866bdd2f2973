"""Whole-array queries on a region's closed rings (issue 17): inside tests, nearest boundary
points, and crossings of polylines with the boundary, for the fill patterns, the infill anchors
and the bridge detector.

A region is a list of closed rings ((k, 2) float64, outlines and holes, any orientation, the
even-odd rule as :func:`cooprint.slicing.infill.hatch`). :class:`RingSet` flattens them once into
edges and builds two acceleration structures in numba: horizontal bands of edges (inside tests by
ray casting) and a uniform grid of edges (nearest edge, polyline crossings), so that a query costs
the edges near it instead of every edge of the region.
"""

from __future__ import annotations

import math

import numba
import numpy as np


class EdgeSet:
    """Straight edges ``a[i] -> b[i]`` ((E, 2) float64 each) with their search structures,
    built on first use."""

    def __init__(self, a: np.ndarray, b: np.ndarray):
        self.a = np.ascontiguousarray(a, dtype=np.float64).reshape(-1, 2)
        self.b = np.ascontiguousarray(b, dtype=np.float64).reshape(-1, 2)
        self._bands = None
        self._grid = None

    def __len__(self) -> int:
        return len(self.a)

    @property
    def bands(self):
        """Edges bucketed by horizontal band: (y0, band height, band start (B + 1,), edge ids)."""
        if self._bands is None:
            n = max(len(self.a), 1)
            lo = min(self.a[:, 1].min(), self.b[:, 1].min()) if len(self.a) else 0.0
            hi = max(self.a[:, 1].max(), self.b[:, 1].max()) if len(self.a) else 1.0
            nb = int(min(max(1, math.sqrt(n) * 2), 4096))
            h = max((hi - lo) / nb, 1e-9)
            self._bands = (lo, h) + _build_bands(self.a, self.b, lo, h, nb)
        return self._bands

    @property
    def grid(self):
        """Uniform grid of edges: (x0, y0, cell, nx, ny, cell start (nx*ny + 1,), edge ids).

        Every edge is registered in the 3 x 3 cells around each of its samples (one every half
        cell), so a point within 3/4 of a cell of an edge finds it in its own cell."""
        if self._grid is None:
            lo = np.minimum(self.a.min(axis=0), self.b.min(axis=0)) if len(self.a) else np.zeros(2)
            hi = np.maximum(self.a.max(axis=0), self.b.max(axis=0)) if len(self.a) else np.ones(2)
            ext = np.maximum(hi - lo, 1e-6)
            cell = max(math.sqrt(ext[0] * ext[1] / (4.0 * max(len(self.a), 1))), float(ext.max()) / 1024.0, 1e-3)
            nx, ny = int(ext[0] / cell) + 3, int(ext[1] / cell) + 3
            x0, y0 = lo[0] - cell, lo[1] - cell
            self._grid = (x0, y0, cell, nx, ny) + _build_grid(self.a, self.b, x0, y0, cell, nx, ny)
        return self._grid

    def contains(self, pts: np.ndarray) -> np.ndarray:
        """(n,) bool: every point inside the region (even-odd; a point on an edge is either)."""
        pts = np.ascontiguousarray(pts, dtype=np.float64).reshape(-1, 2)
        if not len(self.a):
            return np.zeros(len(pts), dtype=bool)
        y0, h, start, ids = self.bands
        return _contains(pts, self.a, self.b, y0, h, start, ids)

    def nearest(self, pts: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For every point, the nearest edge within ``tol`` (else -1), its parameter t in [0, 1]
        along that edge and the distance (inf when none)."""
        pts = np.ascontiguousarray(pts, dtype=np.float64).reshape(-1, 2)
        if not len(self.a):
            return np.full(len(pts), -1, np.int64), np.zeros(len(pts)), np.full(len(pts), np.inf)
        x0, y0, cell, nx, ny, start, ids = self.grid
        return _nearest(pts, self.a, self.b, x0, y0, cell, nx, ny, start, ids, tol)


def successors(sizes: np.ndarray) -> np.ndarray:
    """For rings of ``sizes`` vertices stored one after the other, the index of every vertex's
    successor along its ring (each ring's last vertex: its first); empty rings have none."""
    sizes = np.asarray(sizes, dtype=np.int64)
    ends = np.cumsum(sizes)
    after = np.arange(1, int(ends[-1]) + 1 if len(ends) else 1)
    full = sizes > 0
    after[ends[full] - 1] = (ends - sizes)[full]
    return after


class RingSet(EdgeSet):
    """The edges of a region's closed rings with their search structures.

    Attributes
    ----------
    a, b : (E, 2) float64
        Start and end of every edge (ring ``r``'s edges are ``ring_start[r]:ring_start[r + 1]``,
        edge ``i`` runs from vertex ``i`` of its ring to the next, the last one back to the first).
    ring_of : (E,) int64
        Ring index of every edge.
    ring_start : (R + 1,) int64
        First edge of every ring.
    param : (E,) float64
        Arc length from the ring's first vertex to the start of every edge, mm.
    seg_len : (E,) float64
        Length of every edge, mm.
    ring_len : (R,) float64
        Perimeter of every ring, mm.
    """

    def __init__(self, rings: list[np.ndarray]):
        rings = [np.asarray(r, dtype=np.float64)[:, :2] for r in rings if len(r) >= 2]
        self.rings = rings
        sizes = np.array([len(r) for r in rings], dtype=np.int64)
        self.ring_start = np.concatenate(([0], np.cumsum(sizes)))
        if not rings:
            super().__init__(np.zeros((0, 2)), np.zeros((0, 2)))
            self.ring_of, self.param = np.zeros(0, np.int64), np.zeros(0)
            self.seg_len, self.ring_len = np.zeros(0), np.zeros(0)
            return
        a = np.concatenate(rings)
        b, self.ring_of, self.seg_len, self.param, self.ring_len, *grid = _ring_set(a, self.ring_start)
        super().__init__(a, b)
        self._grid = tuple(grid)  # every user of a RingSet asks its grid: built with the rest


    def points_at(self, ring: np.ndarray, param: np.ndarray) -> np.ndarray:
        """(n, 2) points at arc lengths ``param`` (taken modulo the perimeter) of rings ``ring``."""
        ring = np.asarray(ring, dtype=np.int64)
        p = np.mod(param, self.ring_len[ring])
        # the edge holding each point: the last edge of its ring starting at or before it
        key = self.ring_of.astype(np.float64) * (self.ring_len.max() + 1.0) + self.param
        q = ring.astype(np.float64) * (self.ring_len.max() + 1.0) + p
        e = np.clip(np.searchsorted(key, q, side="right") - 1, 0, len(self.a) - 1)
        t = np.where(self.seg_len[e] > 0, (p - self.param[e]) / np.where(self.seg_len[e] > 0, self.seg_len[e], 1), 0)
        return self.a[e] + t[:, None] * (self.b[e] - self.a[e])


@numba.njit(cache=True)
def _ring_set(a, ring_start):
    """:class:`RingSet`'s arrays for the rings ``a[ring_start[r]:ring_start[r + 1]]`` and its
    grid, in one compiled call (a slicer region's RingSet took ~20 numpy calls): (b, ring_of,
    seg_len, param, ring_len, then :attr:`EdgeSet.grid`'s seven values). The numbers are those
    of the whole-array steps it replaces: lengths by ``hypot``, the arc lengths as one running
    sum over all rings less the sum before the ring, the grid's cell as ``EdgeSet.grid`` sizes it."""
    n, nr = a.shape[0], ring_start.shape[0] - 1
    b = np.empty_like(a)
    ring_of = np.empty(n, np.int64)
    seg = np.empty(n)
    param = np.empty(n)
    ring_len = np.empty(nr)
    cum = 0.0
    for r in range(nr):
        s, e = ring_start[r], ring_start[r + 1]
        before = cum
        for i in range(s, e):
            j = i + 1 if i + 1 < e else s
            b[i, 0], b[i, 1] = a[j, 0], a[j, 1]
            ring_of[i] = r
            seg[i] = math.hypot(a[j, 0] - a[i, 0], a[j, 1] - a[i, 1])
            cum += seg[i]
            param[i] = cum - seg[i] - before
        ring_len[r] = cum - before
    lo_x, lo_y, hi_x, hi_y = np.inf, np.inf, -np.inf, -np.inf  # b holds the same points
    for i in range(n):
        lo_x, hi_x = min(lo_x, a[i, 0]), max(hi_x, a[i, 0])
        lo_y, hi_y = min(lo_y, a[i, 1]), max(hi_y, a[i, 1])
    ex, ey = max(hi_x - lo_x, 1e-6), max(hi_y - lo_y, 1e-6)
    cell = max(math.sqrt(ex * ey / (4.0 * max(n, 1))), max(ex, ey) / 1024.0, 1e-3)
    nx, ny = int(ex / cell) + 3, int(ey / cell) + 3
    x0, y0 = lo_x - cell, lo_y - cell
    start, ids = _build_grid(a, b, x0, y0, cell, nx, ny)
    return b, ring_of, seg, param, ring_len, x0, y0, cell, nx, ny, start, ids


@numba.njit(cache=True)
def _build_bands(a, b, y0, h, nb):
    n = a.shape[0]
    lo = np.empty(n, np.int64)
    hi = np.empty(n, np.int64)
    count = np.zeros(nb + 1, np.int64)
    for i in range(n):
        ya, yb = a[i, 1], b[i, 1]
        l = int((min(ya, yb) - y0) / h)
        u = int((max(ya, yb) - y0) / h)
        lo[i] = min(max(l, 0), nb - 1)
        hi[i] = min(max(u, 0), nb - 1)
        for k in range(lo[i], hi[i] + 1):
            count[k + 1] += 1
    start = np.cumsum(count)
    fill = start[:-1].copy()
    ids = np.empty(start[-1], np.int64)
    for i in range(n):
        for k in range(lo[i], hi[i] + 1):
            ids[fill[k]] = i
            fill[k] += 1
    return start, ids


@numba.njit(cache=True)
def _contains(pts, a, b, y0, h, start, ids):
    nb = start.shape[0] - 1
    out = np.zeros(pts.shape[0], np.bool_)
    for q in range(pts.shape[0]):
        px, py = pts[q, 0], pts[q, 1]
        k = int((py - y0) / h)
        if k < 0 or k >= nb:
            if k == nb and py - y0 <= nb * h * (1 + 1e-12):
                k = nb - 1
            else:
                continue
        inside = False
        for j in range(start[k], start[k + 1]):
            i = ids[j]
            ya, yb = a[i, 1], b[i, 1]
            if (ya > py) != (yb > py):
                x = a[i, 0] + (py - ya) * (b[i, 0] - a[i, 0]) / (yb - ya)
                if x > px:
                    inside = not inside
        out[q] = inside
    return out


@numba.njit(cache=True)
def _build_grid(a, b, x0, y0, cell, nx, ny):
    n = a.shape[0]
    # pass 1: count, pass 2: fill (the same walk twice)
    count = np.zeros(nx * ny + 1, np.int64)
    ids = np.empty(0, np.int64)
    start = count
    fill = count
    for stage in range(2):
        for i in range(n):
            dx, dy = b[i, 0] - a[i, 0], b[i, 1] - a[i, 1]
            steps = int(math.sqrt(dx * dx + dy * dy) / (0.5 * cell)) + 1
            last = -1
            for s in range(steps + 1):
                t = s / steps
                cx = int((a[i, 0] + t * dx - x0) / cell)
                cy = int((a[i, 1] + t * dy - y0) / cell)
                c = cy * nx + cx
                if c == last:
                    continue
                last = c
                for oy in range(max(cy - 1, 0), min(cy + 2, ny)):
                    for ox in range(max(cx - 1, 0), min(cx + 2, nx)):
                        k = oy * nx + ox
                        if stage == 0:
                            count[k + 1] += 1
                        elif fill[k] == start[k] or ids[fill[k] - 1] != i:
                            ids[fill[k]] = i
                            fill[k] += 1
        if stage == 0:
            start = np.cumsum(count)
            ids = np.full(start[-1], -1, np.int64)
            fill = start[:-1].copy()
    # compact: the 3 x 3 registration repeats an edge in a cell (counted, filled once)
    out_start = np.zeros(nx * ny + 1, np.int64)
    for k in range(nx * ny):
        out_start[k + 1] = out_start[k] + (fill[k] - start[k])
    out = np.empty(out_start[-1], np.int64)
    for k in range(nx * ny):
        out[out_start[k]:out_start[k + 1]] = ids[start[k]:fill[k]]
    return out_start, out


@numba.njit(cache=True)
def _nearest(pts, a, b, x0, y0, cell, nx, ny, start, ids, tol):
    n = pts.shape[0]
    edge = np.full(n, -1, np.int64)
    tt = np.zeros(n)
    dist = np.full(n, np.inf)
    # an edge within 3/4 of a cell of a point is in the point's cell (3 x 3 registration);
    # farther tolerances look that many cells further
    reach = max(0, int(math.ceil((tol - 0.75 * cell) / cell)))
    for q in range(n):
        px, py = pts[q, 0], pts[q, 1]
        cx = int((px - x0) / cell)
        cy = int((py - y0) / cell)
        if cx < -reach or cy < -reach or cx >= nx + reach or cy >= ny + reach:
            continue
        for oy in range(max(cy - reach, 0), min(cy + reach + 1, ny)):
            for ox in range(max(cx - reach, 0), min(cx + reach + 1, nx)):
                k = oy * nx + ox
                for j in range(start[k], start[k + 1]):
                    i = ids[j]
                    dx, dy = b[i, 0] - a[i, 0], b[i, 1] - a[i, 1]
                    l2 = dx * dx + dy * dy
                    t = 0.0 if l2 == 0 else ((px - a[i, 0]) * dx + (py - a[i, 1]) * dy) / l2
                    t = min(max(t, 0.0), 1.0)
                    ex, ey = a[i, 0] + t * dx - px, a[i, 1] + t * dy - py
                    d = math.sqrt(ex * ex + ey * ey)
                    if d <= tol and d < dist[q]:
                        dist[q] = d
                        edge[q] = i
                        tt[q] = t
    return edge, tt, dist


@numba.njit(cache=True)
def crossings(pts, a, b, x0, y0, cell, nx, ny, start, ids):
    """Crossings of the segments ``pts[i] -> pts[i + 1]`` with the edges ``a -> b``.

    Returns (segment index (c,), parameter along the segment (c,)), unsorted; a crossing at an
    edge's end may be reported by both edges that meet there."""
    cap = 64
    seg_out = np.empty(cap, np.int64)
    t_out = np.empty(cap)
    nc = 0
    seen = np.full(a.shape[0], -1, np.int64)
    eps = 1e-12
    for s in range(pts.shape[0] - 1):
        px, py = pts[s, 0], pts[s, 1]
        dx, dy = pts[s + 1, 0] - px, pts[s + 1, 1] - py
        if dx != dx or dy != dy:  # NaN: a break between polylines
            continue
        steps = int(math.sqrt(dx * dx + dy * dy) / (0.5 * cell)) + 1
        last = -1
        for k in range(steps + 1):
            f = k / steps
            cx = int((px + f * dx - x0) / cell)
            cy = int((py + f * dy - y0) / cell)
            if cx < 0 or cy < 0 or cx >= nx or cy >= ny:
                continue
            c = cy * nx + cx
            if c == last:
                continue
            last = c
            for j in range(start[c], start[c + 1]):
                i = ids[j]
                if seen[i] == s:
                    continue
                seen[i] = s
                ex, ey = b[i, 0] - a[i, 0], b[i, 1] - a[i, 1]
                den = dx * ey - dy * ex
                if den == 0.0:
                    continue
                qx, qy = a[i, 0] - px, a[i, 1] - py
                t = (qx * ey - qy * ex) / den
                u = (qx * dy - qy * dx) / den
                if t < -eps or t > 1 + eps or u < -eps or u > 1 + eps:
                    continue
                if nc == cap:
                    cap *= 2
                    s2 = np.empty(cap, np.int64)
                    t2 = np.empty(cap)
                    s2[:nc] = seg_out[:nc]
                    t2[:nc] = t_out[:nc]
                    seg_out, t_out = s2, t2
                seg_out[nc] = s
                t_out[nc] = min(max(t, 0.0), 1.0)
                nc += 1
    return seg_out[:nc], t_out[:nc]
