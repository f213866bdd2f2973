"""Bridge direction (issue 17): the angle at which a bridge's lines are best anchored, as
PrusaSlicer's BridgeDetector chooses it.

``bridge_angle(area, anchors, spacing)`` -> degrees or ``None``.
  ``area``: the bridge region (a CrossSection, mm); ``anchors``: where its lines may rest (the
  lower layer's material under and around it, a CrossSection); ``spacing``: line spacing, mm.
  Candidate directions every 5 degrees plus the directions of the bridge outline's edges; for
  each, lines across ``area`` at ``spacing``; a line counts when both of its ends lie on
  ``anchors``; the best direction has the most anchored length (ties: the shortest longest
  line). ``None`` when no line is anchored at both ends (a cantilever: the caller uses its
  default angle).

How (written from PrusaSlicer 2.5's BridgeDetector.cpp, not copied): the anchors are the
lower material within one spacing of the bridge; the test lines are cut by the bridge grown by
half a spacing (so that a supported end lies inside an anchor, not on its edge). Candidates are
every 5 degrees, the bridge outline's edge directions and the chords of the supported stretches
of the grown outline (which find the best direction for C-shaped supports), merged within
1 degree. Directions within one spacing of the best anchored length prefer the shorter longest
line. Differences: a line counts only if it also passes over unsupported area, so that lines
lying wholly on a support do not make a cantilever look anchored; outline edges shorter than two
spacings give no candidate (a curve's many short edges add nothing to the 5 degree step); a
direction's anchored length is measured with probe lines ``PROBES`` times denser than the
spacing (at most ``SCAN_LINES`` across the bridge), scaled back: counted at the spacing itself, one
line more or less (where the spacing grid falls) outweighs the difference between two directions
a degree apart.

All candidates are evaluated in one whole-array pass: the scanlines of every direction are cut
by the grown bridge's and the anchors' edges together, and the anchor crossings on a scanline
tell, by parity, whether a line's ends rest on anchors and whether it crosses air between.
"""

from __future__ import annotations

import math

import manifold3d
import numpy as np

from cooprint.slicing.patterns import clip_polylines

#: Candidate directions every this many degrees (PrusaSlicer: 5).
STEP_DEG = 5.0
#: Candidates closer than this are merged, degrees (PrusaSlicer: 1).
MERGE_DEG = 1.0
#: Most probe lines per direction across a bridge (a bigger bridge is probed more sparsely).
SCAN_LINES = 400
#: Probe lines per line spacing (a bridge narrower than SCAN_LINES / PROBES spacings).
PROBES = 4


def _rings(cs: manifold3d.CrossSection) -> list[np.ndarray]:
    return [np.asarray(p, dtype=np.float64) for p in cs.to_polygons() if len(p) >= 3]


def bridge_angle(area: manifold3d.CrossSection, anchors: manifold3d.CrossSection, spacing: float) -> float | None:
    """Direction of ``area``'s bridge lines, degrees in [0, 180), or ``None`` (module docstring)."""
    if spacing <= 0 or area.is_empty() or anchors.is_empty():
        return None
    miter = manifold3d.JoinType.Miter
    grown = area.offset(spacing, miter)
    support = grown ^ anchors
    if support.is_empty():
        return None
    clip = _rings(area.offset(0.5 * spacing, miter))
    support_rings = _rings(support)
    if not clip or not support_rings:
        return None
    angles = _candidates(_rings(area), _rings(grown), _rings(anchors), 2.0 * spacing)
    # probes denser than the lines (up to SCAN_LINES across the bridge), their
    # anchored length scaled back to the line spacing
    lo, hi = np.asarray(area.bounds()[:2]), np.asarray(area.bounds()[2:])
    scan = max(spacing / PROBES, float(np.hypot(*(hi - lo))) / SCAN_LINES)
    cover, longest = _coverage(clip, support_rings, angles, scan)
    cover *= scan / spacing
    if not (cover > 0).any():
        return None
    order = np.argsort(-cover, kind="stable")
    best = order[0]
    for i in order[1:]:
        if cover[best] - cover[i] >= spacing:
            break
        if longest[i] < longest[best]:
            best = i
    return float(np.degrees(angles[best]) % 180.0)


def _candidates(area: list[np.ndarray], grown: list[np.ndarray], anchors: list[np.ndarray], min_edge: float
                ) -> np.ndarray:
    """Candidate directions, radians in [0, pi): the fixed step, the outline's edges at least
    ``min_edge`` long (the many short edges of a curve say nothing the fixed step does not) and
    the chords of the supported stretches of the grown outline, merged within ``MERGE_DEG``."""
    fixed = np.radians(np.arange(0.0, 180.0, STEP_DEG))
    d = np.concatenate([np.roll(r, -1, axis=0) - r for r in area])
    d = d[np.hypot(d[:, 0], d[:, 1]) >= min_edge]
    edges = np.arctan2(d[:, 1], d[:, 0])
    supported = clip_polylines([np.vstack([r, r[:1]]) for r in grown], anchors)
    chords = np.array([p[-1] - p[0] for p in supported if np.hypot(*(p[-1] - p[0])) > 1e-6]).reshape(-1, 2)
    tol = math.radians(MERGE_DEG)
    exact = _merge(np.concatenate([edges, np.arctan2(chords[:, 1], chords[:, 0])]) % math.pi, tol)
    # a fixed step within the merge tolerance of an edge's own direction gives way to it
    gap = np.abs((fixed[:, None] - exact[None, :] + 0.5 * math.pi) % math.pi - 0.5 * math.pi)
    fixed = fixed[(gap > tol).all(axis=1)] if len(exact) else fixed
    return np.sort(np.concatenate([exact, fixed]))


def _merge(a: np.ndarray, tol: float) -> np.ndarray:
    """Directions (radians in [0, pi)) with those within ``tol`` of a kept one dropped."""
    a = np.sort(a)
    if not len(a):
        return a
    keep = np.r_[True, np.diff(a) > tol]
    a = a[keep]
    if len(a) > 1 and a[-1] - a[0] >= math.pi - tol:
        a = a[:-1]  # parallel to the first (0 and pi)
    return a


def _crossings(rings: list[np.ndarray], angles: np.ndarray, spacing: float, kmin: int, nk: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """Crossings of every direction's scanlines with the rings' edges: sorted (key, x), where
    key = angle index * nk + scanline index - kmin and x is along the scanline, mm."""
    p0 = np.concatenate(rings)
    p1 = np.concatenate([np.roll(r, -1, axis=0) for r in rings])
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    x0, y0 = p0[:, 0] * c + p0[:, 1] * s, -p0[:, 0] * s + p0[:, 1] * c  # (A, E): the line frame
    x1, y1 = p1[:, 0] * c + p1[:, 1] * s, -p1[:, 0] * s + p1[:, 1] * c
    first = np.ceil(np.minimum(y0, y1) / spacing).astype(np.int64)
    last = np.ceil(np.maximum(y0, y1) / spacing).astype(np.int64)  # half-open: a vertex counts once
    count = np.maximum(last - first, 0).ravel()
    total = int(count.sum())
    if total == 0:
        return np.zeros(0, np.int64), np.zeros(0)
    pair = np.repeat(np.arange(count.size), count)
    k = np.repeat(first.ravel(), count) + (np.arange(total) - np.repeat(np.cumsum(count) - count, count))
    ya, yb, xa, xb = y0.ravel()[pair], y1.ravel()[pair], x0.ravel()[pair], x1.ravel()[pair]
    t = (k * spacing - ya) / (yb - ya)
    x = xa + t * (xb - xa)
    key = (pair // p0.shape[0]) * nk + (k - kmin)
    order = np.lexsort((x, key))
    return key[order], x[order]


def _coverage(clip: list[np.ndarray], support: list[np.ndarray], angles: np.ndarray, spacing: float
              ) -> tuple[np.ndarray, np.ndarray]:
    """(anchored length (A,), longest anchored line (A,)) of every direction."""
    pts = np.concatenate(clip)
    reach = float(np.hypot(pts[:, 0], pts[:, 1]).max()) + spacing
    kmin = int(math.floor(-reach / spacing)) - 1
    nk = int(math.ceil(2 * reach / spacing)) + 3
    key, x = _crossings(clip, angles, spacing, kmin, nk)
    cover = np.zeros(len(angles))
    longest = np.zeros(len(angles))
    if not len(key):
        return cover, longest
    # pair the clip crossings of each scanline: 1st-2nd, 3rd-4th, ...
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    rank = np.arange(len(key)) - np.repeat(starts, np.diff(np.r_[starts, len(key)]))
    i = np.flatnonzero((rank[:-1] % 2 == 0) & (key[1:] == key[:-1]))
    seg_key, xa, xb = key[i], x[i], x[i + 1]
    skey, sx = _crossings(support, angles, spacing, kmin, nk)
    # anchor crossings before each end on the same scanline: odd = the end rests on an anchor
    before_a = np.searchsorted(_merge_key(skey, sx, nk, reach), _merge_key(seg_key, xa, nk, reach))
    before_b = np.searchsorted(_merge_key(skey, sx, nk, reach), _merge_key(seg_key, xb, nk, reach))
    line_start = np.searchsorted(skey, seg_key, side="left")
    na, nb = before_a - line_start, before_b - line_start
    anchored = (na % 2 == 1) & (nb % 2 == 1) & (nb > na)  # both ends on anchors, air between
    length = xb - xa
    ang = seg_key // nk
    cover = np.bincount(ang[anchored], weights=length[anchored], minlength=len(angles)).astype(np.float64)
    np.maximum.at(longest, ang[anchored], length[anchored])
    return cover, longest


def _merge_key(key: np.ndarray, x: np.ndarray, nk: int, reach: float) -> np.ndarray:
    """One sortable float per (key, x): key * (span) + x, with x shifted to be non-negative."""
    span = 4.0 * reach + 1.0
    return key.astype(np.float64) * span + (x + 2.0 * reach)
