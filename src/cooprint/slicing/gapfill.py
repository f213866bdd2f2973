"""Lines along the middle of thin regions (issue 17): gap fill between perimeters and thin walls.

CONTRACT (lead, issue 17; the helper that owns this module replaces the body):

``medial_lines(region, min_width, max_width)`` -> list of ``(points (k, 2), width)``.
  ``region``: a CrossSection (mm) of thin parts (what is left between perimeters, or a wall too
  thin for a loop); the result follows its medial axis (the centres of its largest inscribed
  circles) where the local width (twice the distance to the boundary) is from ``min_width`` to
  ``max_width``; each piece is a polyline laid at one width, the local width averaged over the
  piece (a new piece where it changes by more than 10%), so that ``width x length`` covers the
  region's area (PrusaSlicer's gap fill: ThickPolylines of variable width). Pieces shorter than
  ``min_width`` are dropped. Whole-array work; no Python loop per point.

How (a sampled medial axis, no Voronoi library): the boundary is sampled every ``h`` (a quarter
of ``min_width``, 0.01-0.05 mm), each sample with its inward normal; at a reflex corner the
sample is repeated with normals fanned from one edge's normal to the next (the corner is a point
site, its medial branch a parabola). For each sample ``p`` with normal ``n`` the largest disc
tangent at ``p`` and empty of samples has radius ``min_q |q - p|^2 / (2 n.(q - p))`` (discs
tangent at ``p`` are nested, so one pass over the samples near the largest allowed disc finds
it); its centre is a medial point, its radius half the local width, and ``q`` the sample it
touches on the other side. A medial point is kept when the two touching samples face each other
(PrusaSlicer's MedialAxis keeps Voronoi edges between boundary segments within 22.5 degrees of
antiparallel, and every edge of a point site, here a reflex corner), when its width is in range,
and once per pair of sides (the sample whose index is the smaller of the two). Kept points
follow the boundary order, so consecutive ones are chained into polylines (a new chain where
the medial point jumps, i.e. at a branch); chains whose ends meet are joined, free ends that
stop short of the boundary by about half a width (the square end of a strip) are extended to
it, as PrusaSlicer does, so that ``width x length`` matches the area.
"""

from __future__ import annotations

import manifold3d
import numba
import numpy as np

#: Cosine of the largest angle (at the medial point, between the two touching samples) at which
#: two boundary segments still count as opposite sides: 180 - 22.5 degrees, PrusaSlicer's.
_COS_OPPOSITE = float(np.cos(np.radians(180.0 - 22.5)))
#: The same for a reflex corner (a point site): any branch wider than a right angle, so that
#: the axis follows a strip round its corners.
_COS_POINT = float(np.cos(np.radians(95.0)))
#: A reflex corner turning by more than this is a point site (smaller turns are a sampled curve).
_POINT_TURN = np.radians(20.0)
#: A new piece where the local width leaves the piece's running mean by more than this ratio.
_WIDTH_STEP = 0.10


def medial_lines(region: manifold3d.CrossSection, min_width: float, max_width: float
                 ) -> list[tuple[np.ndarray, float]]:
    """Centre lines of ``region`` with their widths (module docstring).

    Parameters
    ----------
    region : CrossSection, mm.
    min_width, max_width : float, mm, ``0 < min_width < max_width``: the range of local widths
        that get a line.

    Returns
    -------
    list of (points (k, 2) float64, width float): polylines (k >= 2) inside ``region``; a
    closed loop repeats its first point at its end.
    """
    if not (0.0 < min_width < max_width):
        raise ValueError(f"medial_lines: need 0 < min_width < max_width, got {min_width}, {max_width}")
    polys = [np.asarray(p, dtype=np.float64) for p in region.to_polygons() if len(p) >= 3]
    if not polys:
        return []
    h = float(np.clip(min_width / 4.0, 0.01, 0.05))
    r_max = 0.5 * max_width * 1.05
    pts, nrm, edge, point_like, cstart = _sample_boundary(polys, h, r_max)
    radius, partner = _inscribed_discs(pts, nrm, r_max, h)
    centres = pts + radius[:, None] * nrm
    widths = 2.0 * radius
    keep = _keep_mask(pts, centres, radius, partner, point_like, min_width, max_width, r_max)
    chains = _chain(centres, widths, keep, cstart, h)
    chains = _join_chains(chains, centres, widths, h)
    seg_a, seg_b = _edges(polys)
    out: list[tuple[np.ndarray, float]] = []
    for idx, closed in chains:
        m = centres[idx]
        w = widths[idx]
        if not closed:
            m, w = _extend_ends(m, w, pts, edge, seg_a, seg_b, h)
        if closed:
            m = np.vstack([m, m[:1]])
            w = np.append(w, w[0])
        lo, hi = _pieces(m, w, _WIDTH_STEP)
        for a, b in zip(lo, hi):
            seg = m[a:b + 1]
            ww = w[a:b + 1]
            lens = np.hypot(*np.diff(seg, axis=0).T)
            length = lens.sum()
            if length < min_width:
                continue
            width = float(np.dot(0.5 * (ww[1:] + ww[:-1]), lens) / length)
            keep_pt = _simplify(seg, 0.25 * h)
            out.append((seg[keep_pt], width))
    return out


def _edges(polys: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Start and end points (m, 2) of every boundary edge, in the order of :func:`_sample_boundary`."""
    a = np.concatenate(polys)
    b = np.concatenate([np.roll(p, -1, axis=0) for p in polys])
    return a, b


def _sample_boundary(polys: list[np.ndarray], h: float, r_max: float):
    """Boundary samples every <= ``h`` with inward normals, fanned at reflex corners.

    Returns ``pts`` (n, 2), ``nrm`` (n, 2) unit inward normals, ``edge`` (n,) the boundary edge
    of each sample (index into :func:`_edges`), ``point_like`` (n,) bool (at or within 1.5 h of a
    reflex corner that is a point site), ``cstart`` (c + 1,) the first sample of each contour.
    The region lies left of each contour (manifold3d: outer contours counter-clockwise).
    """
    sizes = np.array([len(p) for p in polys])
    v = np.concatenate(polys)
    first = np.repeat(np.cumsum(sizes) - sizes, sizes)
    local = np.arange(len(v)) - first
    nxt = first + (local + 1) % np.repeat(sizes, sizes)
    prv = first + (local - 1) % np.repeat(sizes, sizes)
    e_out = v[nxt] - v
    length = np.hypot(e_out[:, 0], e_out[:, 1])
    length = np.maximum(length, 1e-12)
    d_out = e_out / length[:, None]
    d_in = d_out[prv]
    n_out = np.stack([-d_out[:, 1], d_out[:, 0]], axis=1)
    n_in = n_out[prv]
    turn = np.arctan2(d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0],
                      (d_in * d_out).sum(axis=1))
    reflex = turn < -1e-9
    # samples per vertex: the vertex itself (fanned at a reflex corner), then the edge's interior
    step = h / r_max
    n_fan = np.where(reflex, np.minimum(np.ceil(-turn / step).astype(np.int64) + 1, 64), 1)
    n_edge = np.maximum(np.ceil(length / h).astype(np.int64), 1) - 1
    per = n_fan + n_edge
    total = int(per.sum())
    start = np.cumsum(per) - per
    owner = np.repeat(np.arange(len(v)), per)
    j = np.arange(total) - start[owner]
    is_vertex = j < n_fan[owner]
    # vertex samples: normal angle from n_in turning by `turn` (fan) or the bisector (convex)
    frac = np.where(n_fan[owner] > 1, j / np.maximum(n_fan[owner] - 1, 1), 0.5)
    ang_in = np.arctan2(n_in[owner, 1], n_in[owner, 0])
    ang = ang_in + frac * turn[owner]
    nv = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    t = (j - n_fan[owner] + 1) / (n_edge[owner] + 1)
    t = np.where(is_vertex, 0.0, t)
    pts = v[owner] + t[:, None] * e_out[owner]
    nrm = np.where(is_vertex[:, None], nv, n_out[owner])
    edge = owner
    point_site = reflex & (-turn > _POINT_TURN)
    dist_start = t * length[owner]
    dist_end = (1.0 - t) * length[owner]
    point_like = ((point_site[owner] & (dist_start <= 1.5 * h))
                  | (point_site[nxt[owner]] & (dist_end <= 1.5 * h)))
    cstart = np.concatenate([[0], np.cumsum(np.add.reduceat(per, np.cumsum(sizes) - sizes))])
    return pts, nrm, edge, point_like, cstart


@numba.njit(cache=True)
def _grid(pts, cell):
    """Samples bucketed by square cells of side ``cell``: (order, sorted keys, x0, y0, ny)."""
    x0 = pts[:, 0].min() - cell
    y0 = pts[:, 1].min() - cell
    ny = np.int64((pts[:, 1].max() - y0) / cell) + 3
    n = pts.shape[0]
    keys = np.empty(n, np.int64)
    for i in range(n):
        keys[i] = np.int64((pts[i, 0] - x0) / cell) * ny + np.int64((pts[i, 1] - y0) / cell)
    order = np.argsort(keys, kind="mergesort")
    return order, keys[order], x0, y0, ny


@numba.njit(cache=True)
def _inscribed_discs(pts, nrm, r_max, h):
    """Radius (n,) of the largest sample-free disc tangent at each sample (<= ``r_max``) and the
    sample it touches (``partner``, -1 when none within ``r_max``)."""
    cell = max(r_max * 0.5, 2.0 * h)
    order, skeys, x0, y0, ny = _grid(pts, cell)
    n = pts.shape[0]
    radius = np.full(n, r_max)
    partner = np.full(n, -1, np.int64)
    for i in range(n):
        px, py = pts[i, 0], pts[i, 1]
        nx, ny_ = nrm[i, 0], nrm[i, 1]
        best = r_max
        bj = -1
        cx, cy = px + r_max * nx, py + r_max * ny_
        ix0 = np.int64((cx - r_max - x0) / cell)
        ix1 = np.int64((cx + r_max - x0) / cell)
        iy0 = np.int64((cy - r_max - y0) / cell)
        iy1 = np.int64((cy + r_max - y0) / cell)
        for ix in range(ix0, ix1 + 1):
            lo = np.searchsorted(skeys, ix * ny + iy0)
            hi = np.searchsorted(skeys, ix * ny + iy1 + 1)
            for k in range(lo, hi):
                q = order[k]
                dx = pts[q, 0] - px
                dy = pts[q, 1] - py
                d2 = dx * dx + dy * dy
                if d2 < 1e-18:
                    continue
                proj = dx * nx + dy * ny_
                if proj <= 0.0:
                    continue
                r = d2 / (2.0 * proj)
                if r < best:
                    best = r
                    bj = q
        radius[i] = best
        partner[i] = bj
    return radius, partner


def _keep_mask(pts, centres, radius, partner, point_like, min_width, max_width, r_max):
    """Medial points to lay: opposite sides, width in range, one of each pair of sides."""
    has = partner >= 0
    q = pts[np.where(has, partner, 0)]
    a = pts - centres
    b = q - centres
    cos = (a * b).sum(axis=1) / np.maximum(radius * np.hypot(b[:, 0], b[:, 1]), 1e-18)
    pl = point_like | point_like[np.where(has, partner, 0)]
    opposite = cos <= np.where(pl, _COS_POINT, _COS_OPPOSITE)
    w = 2.0 * radius
    return has & opposite & (w >= min_width) & (w <= max_width) & (np.arange(len(pts)) < partner)


@numba.njit(cache=True)
def _chain_nb(centres, widths, keep, cstart, h):
    """Chains of kept samples in boundary order: (sample indices, chain offsets, contour of each
    chain, whether it starts at its contour's first kept sample, ends at its last)."""
    n = centres.shape[0]
    idx = np.empty(n, np.int64)
    offs = np.empty(n + 1, np.int64)
    nc = 0
    m = 0
    for c in range(cstart.shape[0] - 1):
        prev = -1
        for i in range(cstart[c], cstart[c + 1]):
            if not keep[i]:
                continue
            if prev >= 0:
                dx = centres[i, 0] - centres[prev, 0]
                dy = centres[i, 1] - centres[prev, 1]
                tol = max(4.0 * h, 0.35 * min(widths[i], widths[prev]))
                if dx * dx + dy * dy > tol * tol:
                    offs[nc + 1] = m
                    nc += 1
                    offs[nc] = m
            else:
                offs[nc] = m
            idx[m] = i
            m += 1
            prev = i
        if prev >= 0:
            offs[nc + 1] = m
            nc += 1
    return idx[:m], offs[:nc + 1]


def _chain(centres, widths, keep, cstart, h):
    """Chains of kept samples as a list of index arrays (each >= 2 points)."""
    idx, offs = _chain_nb(centres, widths, keep, cstart, h)
    return [idx[a:b] for a, b in zip(offs[:-1], offs[1:]) if b - a >= 2]


def _join_chains(chains, centres, widths, h):
    """Chains joined where their ends meet (the seam of a contour, a switch of the side that
    carries a branch); a chain whose ends meet is closed. Returns [(indices, closed)]."""
    if not chains:
        return []
    ends = np.array([[c[0], c[-1]] for c in chains])          # (m, 2) sample indices
    p = centres[ends.ravel()]                                    # end points, 2 per chain
    w = widths[ends.ravel()]
    tol = np.maximum(4.0 * h, 0.35 * np.minimum(w[:, None], w[None, :]))
    d = np.hypot(p[:, None, 0] - p[None, :, 0], p[:, None, 1] - p[None, :, 1])
    ii, jj = np.nonzero((d <= tol) & (np.arange(len(p))[:, None] < np.arange(len(p))[None, :]))
    order = np.argsort(d[ii, jj], kind="stable")
    link = np.full(len(p), -1)                                    # end -> end it joins
    for a, b in zip(ii[order], jj[order]):
        if link[a] < 0 and link[b] < 0 and a // 2 != b // 2:
            link[a] = b
            link[b] = a
    out = []
    seen = np.zeros(len(chains), bool)
    # walk from chain ends that are free (or anything left: cycles)
    starts = [e for e in range(len(p)) if link[e] < 0] + list(range(len(p)))
    for e in starts:
        c = e // 2
        if seen[c]:
            continue
        parts = []
        closed = False
        cur = e
        while True:
            c = cur // 2
            seen[c] = True
            parts.append(chains[c] if cur % 2 == 0 else chains[c][::-1])
            other = link[cur ^ 1]
            if other < 0:
                break
            if seen[other // 2]:
                closed = True
                break
            cur = other
        idx = np.concatenate(parts)
        if not closed:
            gap = np.hypot(*(centres[idx[0]] - centres[idx[-1]]))
            seg = np.hypot(*np.diff(centres[idx], axis=0).T).sum()
            wmin = min(widths[idx[0]], widths[idx[-1]])
            closed = gap <= max(4.0 * h, 0.35 * wmin) and seg > 4.0 * wmin
        out.append((idx, closed))
    return out


def _extend_ends(m, w, pts, edge, seg_a, seg_b, h):
    """(m, w) with free ends carried along their direction to the boundary when it is within 0.75 of the
    end's width ahead (the square end of a strip, where the axis stops half a width short)."""
    m = m.copy()
    for end in (0, -1):
        tip = m[end]
        wend = w[end]
        back = m[::-1] if end == -1 else m
        dist = np.hypot(*(back - tip).T)
        k = int(np.searchsorted(dist > 0.5 * wend, True)) if (dist > 0.5 * wend).any() else len(m) - 1
        k = max(k, 1)
        d = tip - back[min(k, len(m) - 1)]
        nd = np.hypot(*d)
        if nd < 1e-9:
            continue
        d = d / nd
        reach = 0.75 * wend
        near = np.hypot(*(pts - tip).T) <= reach + 2.0 * h
        cand = np.unique(edge[near])
        if len(cand) == 0:
            continue
        a = seg_a[cand]
        b = seg_b[cand]
        e = b - a
        den = d[0] * e[:, 1] - d[1] * e[:, 0]
        ok = np.abs(den) > 1e-12
        rel = a - tip
        s = np.where(ok, (rel[:, 0] * e[:, 1] - rel[:, 1] * e[:, 0]) / np.where(ok, den, 1.0), np.inf)
        u = np.where(ok, (rel[:, 0] * d[1] - rel[:, 1] * d[0]) / np.where(ok, den, 1.0), -1.0)
        hit = ok & (s > 0) & (u >= 0) & (u <= 1)
        if not hit.any():
            continue
        s_hit = s[hit].min()
        if s_hit > reach:
            continue
        ext = tip + d * max(s_hit - 0.005, 0.0)
        if end == 0:
            m = np.vstack([ext, m])
            w = np.append(w[0], w)
        else:
            m = np.vstack([m, ext])
            w = np.append(w, w[-1])
    return m, w


@numba.njit(cache=True)
def _pieces_nb(m, w, step):
    """Piece bounds (first, last point) along one chain: a new piece where the width leaves the
    running (length-weighted) mean of the piece by more than ``step``."""
    n = m.shape[0]
    lo = np.empty(n, np.int64)
    hi = np.empty(n, np.int64)
    k = 0
    a = 0
    acc = 0.0
    tot = 0.0
    for i in range(1, n):
        seg = np.hypot(m[i, 0] - m[i - 1, 0], m[i, 1] - m[i - 1, 1])
        wi = 0.5 * (w[i] + w[i - 1])
        if tot > 0.0:
            mean = acc / tot
            if abs(wi - mean) > step * mean:
                lo[k] = a
                hi[k] = i - 1
                k += 1
                a = i - 1
                acc = 0.0
                tot = 0.0
        acc += wi * seg
        tot += seg
    lo[k] = a
    hi[k] = n - 1
    k += 1
    return lo[:k], hi[:k]


def _pieces(m, w, step):
    """Pieces of one chain at near-constant width (see :func:`_pieces_nb`)."""
    return _pieces_nb(np.ascontiguousarray(m), np.ascontiguousarray(w), step)


@numba.njit(cache=True)
def _simplify(pts, tol):
    """Douglas-Peucker: mask (k,) of the points to keep so that the polyline moves < ``tol``."""
    n = pts.shape[0]
    keep = np.zeros(n, np.bool_)
    keep[0] = True
    keep[n - 1] = True
    stack = np.empty((n, 2), np.int64)
    sp = 0
    stack[0, 0] = 0
    stack[0, 1] = n - 1
    sp = 1
    while sp > 0:
        sp -= 1
        a = stack[sp, 0]
        b = stack[sp, 1]
        if b - a < 2:
            continue
        ax, ay = pts[a, 0], pts[a, 1]
        dx, dy = pts[b, 0] - ax, pts[b, 1] - ay
        ll = np.hypot(dx, dy)
        worst = -1.0
        wi = -1
        for i in range(a + 1, b):
            ex, ey = pts[i, 0] - ax, pts[i, 1] - ay
            if ll > 1e-12:
                dist = abs(ex * dy - ey * dx) / ll
            else:
                dist = np.hypot(ex, ey)
            if dist > worst:
                worst = dist
                wi = i
        if worst > tol:
            keep[wi] = True
            stack[sp, 0] = a
            stack[sp, 1] = wi
            sp += 1
            stack[sp, 0] = wi
            stack[sp, 1] = b
            sp += 1
    return keep
