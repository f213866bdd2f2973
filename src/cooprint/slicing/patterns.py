"""Curved infill patterns and polyline clipping (issue 17).

``clip_polylines(polylines, rings)`` -> list of (k, 2) arrays: the parts of open polylines
  inside the region of closed ``rings`` (even-odd, as :func:`cooprint.slicing.infill.hatch`),
  each part a polyline with its ends on the boundary; whole-array work (numba or numpy), no
  Python loop per point.
``gyroid(rings, spacing, z, angle_deg)`` -> list of (k, 2) arrays: PrusaSlicer's gyroid pattern
  (FillGyroid) at height ``z``, line distance ``spacing`` (= line spacing / density), rotated by
  ``angle_deg``, clipped to ``rings``, on a global grid so that layers and chunks line up, in an
  order that keeps travel short (nearest next, each polyline possibly reversed).

How (written from PrusaSlicer 2.5's FillGyroid.cpp, not copied): the gyroid surface
sin x cos y + sin y cos z + sin z cos x = 0 cut at height z is a family of waves, each the graph
of a closed-form function of the running coordinate, one wave every pi pattern units; the
pattern unit is ``spacing / 2.44`` mm (PrusaSlicer's DensityAdjust: a wave's arc is about
pi / 2.44 times its straight length, so the total length is about area / spacing). When
|sin z| <= |cos z| the waves run along y instead of x. The pattern's origin is a multiple of
one period (2 pi units) in the rotated frame, so every region, layer and chunk cuts the same
waves. PrusaSlicer turns its gyroid by fill_angle + ``CORRECTION_DEG`` (-45): its default
orientation (fill_angle 45) is ``angle_deg=0``; a caller holding PrusaSlicer's infill angle
passes ``infill_angle_deg + CORRECTION_DEG``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from cooprint.slicing.anchor import chain_order
from cooprint.slicing.rings import RingSet, crossings

#: PrusaSlicer's FillGyroid::DensityAdjust: pattern unit = line distance / this.
DENSITY_ADJUST = 2.44
#: PrusaSlicer's FillGyroid::CorrectionAngle, degrees: its gyroid is turned by the infill angle plus this.
CORRECTION_DEG = -45.0
#: Pieces of a clipped gyroid shorter than this are dropped, mm (PrusaSlicer: 0.8 x the 0.45 mm
#: infill line spacing, so that tiny bits between a wave and the boundary are not printed).
MIN_PIECE = 0.36


def clip_polylines(polylines: list[np.ndarray], rings: list[np.ndarray]) -> list[np.ndarray]:
    """The parts of ``polylines`` inside ``rings`` (module docstring).

    Parameters
    ----------
    polylines : list of (k, 2) float, or (m, k, 2) float
        Open polylines (k >= 2); an array: m polylines of k points each (a batch of hatch
        segments: no Python work per polyline on the way in).
    rings : list of (m, 2) float
        The region's closed rings (outlines and holes, any orientation; even-odd rule).

    Returns
    -------
    list of (j, 2) float64
        Every maximal inside part, in the order of the input (polyline by polyline, along each);
        a part's ends are the input's ends or crossings with the boundary.
    """
    if isinstance(polylines, np.ndarray):
        polylines = np.asarray(polylines, dtype=np.float64)[:, :, :2] if polylines.shape[1] >= 2 else []
    else:
        polylines = [np.asarray(p, dtype=np.float64)[:, :2] for p in polylines if len(p) >= 2]
    rs = RingSet(rings)
    if not len(polylines) or not len(rs):
        return []
    pts, off = _clip(polylines, rs)
    bounds = off.tolist()  # views of the flat result (np.split's per-part overhead is 3x this)
    return [pts[a:b] for a, b in zip(bounds[:-1], bounds[1:])]


def _clip(polylines: list[np.ndarray] | np.ndarray, rs: RingSet) -> tuple[np.ndarray, np.ndarray]:
    """Flat clipping: (points (n, 2), offsets (p + 1,)) of the inside parts."""
    # one NaN row between polylines: the crossing search skips the segments touching it
    if isinstance(polylines, np.ndarray):  # m polylines of k points
        m, k = polylines.shape[:2]
        sizes = np.full(m, k, dtype=np.int64)
        flat = np.full((m, k + 1, 2), np.nan)
        flat[:, :k] = polylines
        flat = flat.reshape(-1, 2)
        first = np.arange(m, dtype=np.int64) * (k + 1)
    else:
        sizes = np.array([len(p) for p in polylines], dtype=np.int64)
        flat = np.full((int(sizes.sum()) + len(sizes), 2), np.nan)
        first = np.concatenate([[0], np.cumsum(sizes + 1)[:-1]]).astype(np.int64)
        idx = np.repeat(first, sizes) + (np.arange(sizes.sum()) - np.repeat(first - np.arange(len(sizes)), sizes))
        flat[idx] = np.concatenate(polylines)
    x0, y0, cell, nx, ny, start, ids = rs.grid
    seg, t = crossings(flat, rs.a, rs.b, x0, y0, cell, nx, ny, start, ids)
    cuts = np.sort(seg + t)
    pa, pb = _pieces(first, first + sizes - 1, cuts)
    mid = _at(flat, 0.5 * (pa + pb))
    keep = rs.contains(mid)
    pa, pb = pa[keep], pb[keep]
    if not len(pa):
        return np.zeros((0, 2)), np.zeros(1, np.int64)
    # two kept pieces that meet (a touching, not crossing, boundary point) are one part
    new = np.concatenate(([True], pa[1:] != pb[:-1]))
    heads = np.flatnonzero(new)
    ra, rb = pa[heads], pb[np.concatenate((heads[1:] - 1, [len(pb) - 1]))]
    return _emit(flat, ra, rb)


@numba.njit(cache=True)
def _at(flat, g):
    """Points at global parameters g (vertex index + fraction along the next segment)."""
    out = np.empty((g.shape[0], 2))
    for k in range(g.shape[0]):
        i = int(math.floor(g[k]))
        t = g[k] - i
        if t <= 0.0:
            out[k, 0], out[k, 1] = flat[i, 0], flat[i, 1]
        else:
            out[k, 0] = flat[i, 0] + t * (flat[i + 1, 0] - flat[i, 0])
            out[k, 1] = flat[i, 1] + t * (flat[i + 1, 1] - flat[i, 1])
    return out


@numba.njit(cache=True)
def _pieces(first, last, cuts):
    """Split every polyline [first[p], last[p]] (global parameters) at the sorted ``cuts``."""
    n = first.shape[0]
    cap = 2 * n + 2 * cuts.shape[0] + 2
    pa = np.empty(cap)
    pb = np.empty(cap)
    m = 0
    j = 0
    for p in range(n):
        lo, hi = float(first[p]), float(last[p])
        while j < cuts.shape[0] and cuts[j] <= lo:
            j += 1
        prev = lo
        while j < cuts.shape[0] and cuts[j] < hi:
            c = cuts[j]
            if c - prev > 1e-9:
                pa[m] = prev
                pb[m] = c
                m += 1
                prev = c
            j += 1
        if hi - prev > 1e-9:
            pa[m] = prev
            pb[m] = hi
            m += 1
        elif m > 0 and pb[m - 1] == prev and prev > lo:
            pb[m - 1] = hi  # a cut a hair before the end: the last piece runs to the end
    return pa[:m], pb[:m]


@numba.njit(cache=True)
def _emit(flat, ra, rb):
    """Points of the parts [ra, rb] of ``flat`` (ends interpolated, vertices between copied)."""
    n = ra.shape[0]
    off = np.zeros(n + 1, np.int64)
    for k in range(n):
        inner = max(int(math.ceil(rb[k])) - int(math.floor(ra[k])) - 1, 0)
        off[k + 1] = off[k] + 2 + inner
    out = np.empty((off[n], 2))
    ends = np.empty(2)
    for k in range(n):
        o = off[k]
        ends[0], ends[1] = ra[k], rb[k]
        e = _at(flat, ends)
        out[o] = e[0]
        o += 1
        for i in range(int(math.floor(ra[k])) + 1, int(math.ceil(rb[k]))):
            out[o] = flat[i]
            o += 1
        out[o] = e[1]
    return out, off


def _wave(x: np.ndarray, zs: float, zc: float, vertical: bool, flip: bool) -> np.ndarray:
    """One gyroid wave's offset from its base line, pattern units, at running coordinate ``x``.

    The closed form solves sin x cos y + sin y cos z + sin z cos x = 0 for the wave's cross
    coordinate (a cos + b sin = c, written with asin so that it is continuous along the wave)."""
    if vertical:
        ph = (math.pi if zc < 0 else 0.0) + math.pi
        a = np.sin(x + ph)
        b = -zc
        res = zs * np.cos(x + ph + (math.pi if flip else 0.0))
        r = np.sqrt(a * a + b * b)
        return np.arcsin(np.clip(a / r, -1, 1)) + np.arcsin(np.clip(res / r, -1, 1)) + math.pi
    ph = math.pi if zs < 0 else 0.0
    a = np.cos(x + ph)
    b = -zs
    res = zc * np.sin(x + ph + (0.0 if flip else math.pi))
    r = np.sqrt(a * a + b * b)
    return np.arcsin(np.clip(a / r, -1, 1)) + np.arcsin(np.clip(res / r, -1, 1)) + 0.5 * math.pi


def gyroid_waves(lo: np.ndarray, hi: np.ndarray, spacing: float, z: float) -> list[np.ndarray]:
    """The gyroid's unclipped waves covering the box [lo, hi] (pattern frame, mm), one (k, 2)
    array per wave, on the global grid."""
    d = spacing / DENSITY_ADJUST
    zp = z / d
    zs, zc = math.sin(zp), math.cos(zp)
    vertical = abs(zs) <= abs(zc)
    period = 2 * math.pi * d
    origin = np.floor(np.asarray(lo) / period) * period - period
    size = (np.asarray(hi) - origin) / d + 2 * math.pi  # pattern units, with a period of margin
    run, cross = (1, 0) if vertical else (0, 1)
    # samples along the waves: the lobes' exact points (multiples of pi / 2), split to ~0.25 mm
    m = int(min(4, max(1, math.ceil(0.5 * math.pi * d / 0.25))))
    step = 0.5 * math.pi / m
    u = np.arange(int(math.ceil(size[run] / step)) + 1) * step
    base_flip = not vertical
    shapes = (_wave(u, zs, zc, vertical, base_flip), _wave(u, zs, zc, vertical, not base_flip))
    first = -math.pi if vertical else 0.0
    n_waves = int(math.ceil((size[cross] - first) / math.pi)) + 1
    waves = []
    for j in range(n_waves):
        v = shapes[j % 2] + first + j * math.pi
        pts = np.empty((len(u), 2))
        pts[:, run] = u * d + origin[run]
        pts[:, cross] = v * d + origin[cross]
        waves.append(pts)
    return waves


def gyroid(rings: list[np.ndarray], spacing: float, z: float, angle_deg: float = 0.0) -> list[np.ndarray]:
    """PrusaSlicer's gyroid infill of the region ``rings`` at height ``z`` (module docstring).

    Parameters
    ----------
    rings : list of (m, 2) float
        The region's closed rings (even-odd).
    spacing : float
        Line distance, mm (the line spacing / the density): the total length is about
        area / ``spacing``.
    z : float
        Height of the layer, mm (the pattern changes with it, with a period of
        2 pi ``spacing`` / 2.44).
    angle_deg : float
        Rotation of the pattern, degrees.

    Returns
    -------
    list of (k, 2) float64
        Polylines inside the region, ends on its boundary, pieces shorter than ``MIN_PIECE``
        dropped, in nearest-next order (each possibly reversed).
    """
    rings = [np.asarray(r, dtype=np.float64)[:, :2] for r in rings if len(r) >= 3]
    if not rings or not spacing > 0:
        return []
    a = math.radians(angle_deg)
    rot = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])  # world -> pattern frame
    local = [r @ rot.T for r in rings]
    allp = np.concatenate(local)
    rs = RingSet(local)
    waves = gyroid_waves(allp.min(axis=0), allp.max(axis=0), spacing, z)
    pts, off = _clip(waves, rs)
    if len(off) < 2:
        return []
    seg = np.hypot(*np.diff(pts, axis=0).T)
    cum = np.concatenate(([0.0], np.cumsum(seg)))
    lengths = cum[off[1:] - 1] - cum[off[:-1]]
    keep = np.flatnonzero(lengths >= MIN_PIECE)
    if not len(keep):
        return []
    heads, tails = pts[off[keep]], pts[off[keep + 1] - 1]
    order, rev = chain_order(heads, tails, heads[0])
    world = pts @ rot
    out = []
    for k, r in zip(keep[order], rev):
        p = world[off[k]:off[k + 1]]
        out.append(p[::-1].copy() if r else p.copy())
    return out
