"""Hatching: parallel lines clipped to polygons, as one whole-array scanline pass.

The scanlines of a direction sit on a global grid (multiples of the spacing in the rotated
frame), so lines of the same direction line up from layer to layer and from chunk to chunk.
"""

from __future__ import annotations

import math

import numpy as np


def hatch(polygons: list[np.ndarray], spacing: float, angle_deg: float) -> np.ndarray:
    """Lines at ``angle_deg`` every ``spacing`` mm, clipped to ``polygons`` (even-odd rule).

    Parameters
    ----------
    polygons : list of (k, 2) float
        Closed rings (outlines and holes; orientation does not matter).

    Returns
    -------
    (n, 2, 2) float64
        Segments in boustrophedon order: scanline by scanline, alternating direction, so that
        consecutive segments are close.
    """
    if not polygons or spacing <= 0:
        return np.zeros((0, 2, 2))
    pts = np.concatenate([np.asarray(p, dtype=np.float64) for p in polygons])
    return hatch_flat(pts, np.array([len(p) for p in polygons], dtype=np.int64), spacing, angle_deg)


def hatch_flat(pts: np.ndarray, sizes: np.ndarray, spacing: float, angle_deg: float) -> np.ndarray:
    """:func:`hatch` of the rings ``pts[0:sizes[0]]``, the next ``sizes[1]`` points, ... (all
    rings' points in one array: no list of arrays to make)."""
    if not len(pts) or spacing <= 0:
        return np.zeros((0, 2, 2))
    a = math.radians(angle_deg)
    rot = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])  # world -> hatch frame
    # each point's successor along its ring (the last one's: the ring's first)
    nxt = np.arange(1, len(pts) + 1)
    ends = np.cumsum(sizes)
    nxt[ends[sizes > 0] - 1] = (ends - sizes)[sizes > 0]
    p0 = pts @ rot.T
    p1 = pts[nxt] @ rot.T
    y0, y1 = p0[:, 1], p1[:, 1]
    lo, hi = np.minimum(y0, y1), np.maximum(y0, y1)
    first = np.ceil(lo / spacing).astype(np.int64)  # scanline k sits at y = k * spacing
    last = np.ceil(hi / spacing).astype(np.int64)    # half-open [lo, hi): each vertex counted once
    count = np.maximum(last - first, 0)
    if count.sum() == 0:
        return np.zeros((0, 2, 2))
    edge = np.repeat(np.arange(len(p0)), count)
    line = np.repeat(first, count) + (np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count))
    y = line * spacing
    t = (y - y0[edge]) / (y1[edge] - y0[edge])
    x = p0[edge, 0] + t * (p1[edge, 0] - p0[edge, 0])
    order = np.lexsort((x, line))
    line, x = line[order], x[order]
    # pair crossings per scanline: 1st-2nd, 3rd-4th, ...
    new = np.ones(len(line), dtype=bool)
    new[1:] = line[1:] != line[:-1]
    starts = np.flatnonzero(new)
    rank = np.arange(len(line)) - np.repeat(starts, np.diff(np.append(starts, len(line))))
    is_start = rank % 2 == 0
    valid = is_start[:-1] & (line[1:] == line[:-1])
    i = np.flatnonzero(valid)
    seg_line = line[i]
    xa, xb = x[i], x[i + 1]
    keep = xb - xa > 1e-9
    seg_line, xa, xb = seg_line[keep], xa[keep], xb[keep]
    flip = (seg_line - seg_line.min(initial=0)) % 2 == 1 if len(seg_line) else np.zeros(0, dtype=bool)
    # boustrophedon: odd scanlines run backwards, and their segments in reverse order
    key = np.where(flip, -xa, xa)
    order = np.lexsort((key, seg_line))
    seg_line, xa, xb, flip = seg_line[order], xa[order], xb[order], flip[order]
    ys = seg_line * spacing
    start = np.stack([np.where(flip, xb, xa), ys], axis=1)
    end = np.stack([np.where(flip, xa, xb), ys], axis=1)
    seg = np.stack([start, end], axis=1)
    return seg @ rot  # back to world (rot is orthonormal: inverse = transpose)
