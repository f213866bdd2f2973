"""Lines along the middle of thin regions (issue 17): gap fill between perimeters and thin walls.

``medial_lines(region, min_width, max_width)`` -> list of ``(points (k, 2), width)``.
  ``region``: a CrossSection (mm) of thin parts (what is left between perimeters, or a wall too
  thin for a loop); the result follows its medial axis (the centres of its largest inscribed
  circles) where the local width (twice the distance to the boundary) is from ``min_width`` to
  ``max_width``; each piece is a polyline laid at one width, the local width averaged over the
  piece (a new piece where it changes by more than 10%), so that ``width x length`` covers the
  region's area (PrusaSlicer's gap fill: ThickPolylines of variable width). Pieces shorter than
  ``min_width`` are dropped. Whole-array work; no Python loop per point.

How (a sampled medial axis, no Voronoi library): the boundary is sampled every ``h`` (a third of
``min_width``, 0.025-0.05 mm: the samples lie on the exact edges, so the widths are exact to
``h^2 / 4 w``), each sample with its inward normal; at a reflex corner the
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
    h = float(np.clip(min_width / 3.0, 0.05, 0.08))
    r_max = 0.5 * max_width * 1.05
    sizes = np.array([len(p) for p in polys], dtype=np.int64)
    out_pts, out_offs, out_w = _medial(np.concatenate(polys), sizes, h, r_max, float(min_width), float(max_width))
    bounds = out_offs.tolist()
    return [(out_pts[bounds[k]:bounds[k + 1]], w) for k, w in enumerate(out_w.tolist())]


@numba.njit(cache=True)
def _medial(v, sizes, h, r_max, min_width, max_width):
    """:func:`medial_lines` of the contours ``v[:sizes[0]]``, the next ``sizes[1]`` points, ...
    with samples every ``h`` and discs up to ``r_max``, in one compiled call (the steps of the
    module docstring): (points (p, 2), offsets (q + 1,), widths (q,)) as :func:`_finish`."""
    pts, nrm, edge, point_like, cstart, seg_a, seg_b = _sample_nb(v, sizes, h, h / r_max)
    spts, order, start, x0, y0, ny, cell = _grid(pts, r_max, h)
    radius, partner = _inscribed_discs(pts, nrm, r_max, h, spts, order, start, x0, y0, ny, cell)
    centres = np.empty_like(pts)
    for i in range(pts.shape[0]):
        centres[i, 0] = pts[i, 0] + radius[i] * nrm[i, 0]
        centres[i, 1] = pts[i, 1] + radius[i] * nrm[i, 1]
    widths = 2.0 * radius
    keep = _keep_mask(pts, centres, radius, partner, point_like, min_width, max_width)
    idx, offs = _chain_nb(centres, widths, keep, cstart, h)
    idx, offs, closed = _join_nb(centres, widths, idx, offs, h)
    return _finish(centres, widths, idx, offs, closed, edge, seg_a, seg_b, min_width, h,
                   spts, order, start, x0, y0, ny, cell)


@numba.njit(cache=True)
def _sample_nb(v, sizes, h, fan_step):
    """Boundary samples of the concatenated contours ``v`` (m, 2) every <= ``h`` with inward
    normals, fanned at reflex corners (``fan_step`` radians apart).

    Returns ``pts`` (n, 2), ``nrm`` (n, 2) unit inward normals, ``edge`` (n,) the boundary edge
    of each sample, ``point_like`` (n,) bool (at or within 1.5 h of a reflex corner that is a
    point site), ``cstart`` (c + 1,) the first sample of each contour, and the edges' start and
    end points ``seg_a``, ``seg_b`` (m, 2).
    The region lies left of each contour (manifold3d: outer contours counter-clockwise).
    """
    m = v.shape[0]
    nxt = np.empty(m, np.int64)
    prv = np.empty(m, np.int64)
    cend = np.cumsum(sizes)
    ncont = sizes.shape[0]
    for c in range(ncont):
        s0 = cend[c] - sizes[c]
        for k in range(sizes[c]):
            nxt[s0 + k] = s0 + (k + 1) % sizes[c]
            prv[s0 + k] = s0 + (k - 1) % sizes[c]
    length = np.empty(m)
    dx = np.empty(m)
    dy = np.empty(m)
    for i in range(m):
        ex = v[nxt[i], 0] - v[i, 0]
        ey = v[nxt[i], 1] - v[i, 1]
        length[i] = max(np.hypot(ex, ey), 1e-12)
        dx[i] = ex / length[i]
        dy[i] = ey / length[i]
    turn = np.empty(m)
    n_fan = np.empty(m, np.int64)
    n_edge = np.empty(m, np.int64)
    for i in range(m):
        j = prv[i]
        turn[i] = np.arctan2(dx[j] * dy[i] - dy[j] * dx[i], dx[j] * dx[i] + dy[j] * dy[i])
        n_fan[i] = min(np.int64(np.ceil(-turn[i] / fan_step)) + 1, 64) if turn[i] < -1e-9 else 1
        n_edge[i] = max(np.int64(np.ceil(length[i] / h)), 1) - 1
    total = 0
    for i in range(m):
        total += n_fan[i] + n_edge[i]
    pts = np.empty((total, 2))
    nrm = np.empty((total, 2))
    edge = np.empty(total, np.int64)
    point_like = np.zeros(total, np.bool_)
    cstart = np.empty(ncont + 1, np.int64)
    k = 0
    c = 0
    for i in range(m):
        if i == cend[c] - sizes[c]:
            cstart[c] = k
            c += 1
        j = prv[i]
        site = turn[i] < -_POINT_TURN
        site_next = turn[nxt[i]] < -_POINT_TURN
        ang_in = np.arctan2(dx[j], -dy[j])            # angle of the incoming edge's normal
        for f in range(n_fan[i]):
            frac = f / (n_fan[i] - 1) if n_fan[i] > 1 else 0.5
            ang = ang_in + frac * turn[i]
            pts[k, 0] = v[i, 0]
            pts[k, 1] = v[i, 1]
            nrm[k, 0] = np.cos(ang)
            nrm[k, 1] = np.sin(ang)
            edge[k] = i
            point_like[k] = site or (site_next and length[i] <= 1.5 * h)
            k += 1
        for e in range(1, n_edge[i] + 1):
            t = e / (n_edge[i] + 1)
            pts[k, 0] = v[i, 0] + t * dx[i] * length[i]
            pts[k, 1] = v[i, 1] + t * dy[i] * length[i]
            nrm[k, 0] = -dy[i]
            nrm[k, 1] = dx[i]
            edge[k] = i
            point_like[k] = ((site and t * length[i] <= 1.5 * h)
                             or (site_next and (1.0 - t) * length[i] <= 1.5 * h))
            k += 1
    cstart[ncont] = k
    return pts, nrm, edge, point_like, cstart, v, v[nxt]


@numba.njit(cache=True)
def _grid(pts, r_max, h):
    """Samples bucketed by square cells (column-major, so that a column of cells is one
    contiguous run): (samples in cell order, order, start (nx * ny + 1,), x0, y0, ny, cell).
    The cell side is 0.15 of the largest disc, coarser when the grid would pass 2 M cells."""
    n = pts.shape[0]
    lo_x, lo_y, hi_x, hi_y = np.inf, np.inf, -np.inf, -np.inf
    for i in range(n):
        lo_x = min(lo_x, pts[i, 0])
        hi_x = max(hi_x, pts[i, 0])
        lo_y = min(lo_y, pts[i, 1])
        hi_y = max(hi_y, pts[i, 1])
    cell = max(0.15 * r_max, 2.0 * h)
    cell = max(cell, np.sqrt((hi_x - lo_x + 4.0 * cell) * (hi_y - lo_y + 4.0 * cell) / 2e6))
    x0 = lo_x - 2.0 * cell
    y0 = lo_y - 2.0 * cell
    nx = np.int64((hi_x - x0) / cell) + 5
    ny = np.int64((hi_y - y0) / cell) + 5
    keys = np.empty(n, np.int64)
    start = np.zeros(nx * ny + 1, np.int64)
    for i in range(n):
        keys[i] = np.int64((pts[i, 0] - x0) / cell) * ny + np.int64((pts[i, 1] - y0) / cell)
        start[keys[i] + 1] += 1
    for c in range(nx * ny):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, np.int64)
    spts = np.empty((n, 2))
    for i in range(n):
        k = fill[keys[i]]
        fill[keys[i]] += 1
        order[k] = i
        spts[k, 0] = pts[i, 0]
        spts[k, 1] = pts[i, 1]
    return spts, order, start, x0, y0, ny, cell


@numba.njit(cache=True)
def _cells(start, ny, ix0, ix1, iy0, iy1):
    """(lo, hi) ranges of the sorted samples in the cell block [ix0..ix1] x [iy0..iy1] (one per
    column; the block is clamped to the grid)."""
    nx = (start.shape[0] - 1) // ny
    ix0 = max(ix0, 0)
    ix1 = min(ix1, nx - 1)
    iy0 = max(iy0, 0)
    iy1 = min(iy1, ny - 1)
    n = max(ix1 - ix0 + 1, 0)
    lo = np.empty(n, np.int64)
    hi = np.empty(n, np.int64)
    for k in range(n):
        col = (ix0 + k) * ny
        lo[k] = start[col + iy0]
        hi[k] = start[col + iy1 + 1]
    return lo, hi


@numba.njit(cache=True)
def _disc(pts, nrm, i, r_try, spts, order, start, x0, y0, ny, cell):
    """Smallest ``|q - p|^2 / (2 n.(q - p))`` over the samples q in the box of the disc of radius
    ``r_try`` tangent at sample i (exact when the result is below ``r_try``), and its q."""
    px, py = pts[i, 0], pts[i, 1]
    nx_, nyy = nrm[i, 0], nrm[i, 1]
    cx, cy = px + r_try * nx_, py + r_try * nyy
    ix0 = np.int64((cx - r_try - x0) / cell)
    ix1 = np.int64((cx + r_try - x0) / cell)
    iy0 = np.int64((cy - r_try - y0) / cell)
    iy1 = np.int64((cy + r_try - y0) / cell)
    nx = (start.shape[0] - 1) // ny
    ix0 = max(ix0, 0)
    ix1 = min(ix1, nx - 1)
    iy0 = max(iy0, 0)
    iy1 = min(iy1, ny - 1)
    best = np.inf
    bj = -1
    for ix in range(ix0, ix1 + 1):
        for k in range(start[ix * ny + iy0], start[ix * ny + iy1 + 1]):
            dx = spts[k, 0] - px
            dy = spts[k, 1] - py
            proj = dx * nx_ + dy * nyy
            if proj <= 1e-12:
                continue
            r = (dx * dx + dy * dy) / (2.0 * proj)
            if r < best:
                best = r
                bj = k
    return best, (order[bj] if bj >= 0 else -1)


@numba.njit(cache=True)
def _inscribed_discs(pts, nrm, r_max, h, spts, order, start, x0, y0, ny, cell):
    """Radius (n,) of the largest sample-free disc tangent at each sample (<= ``r_max``) and the
    sample it touches (``partner``, -1 when none within ``r_max``). Each search first tries a
    disc a little larger than the previous sample's (neighbours have nearly equal discs), and
    doubles it while it is empty, up to ``r_max``."""
    n = pts.shape[0]
    radius = np.full(n, r_max)
    partner = np.full(n, -1, np.int64)
    guess = r_max
    for i in range(n):
        r_try = min(r_max, 1.05 * guess + 0.5 * h)
        best, bj = _disc(pts, nrm, i, r_try, spts, order, start, x0, y0, ny, cell)
        while best > r_try and r_try < r_max:
            r_try = min(r_max, 2.0 * r_try)
            best, bj = _disc(pts, nrm, i, r_try, spts, order, start, x0, y0, ny, cell)
        if best <= r_max:
            radius[i] = best
            partner[i] = bj
        guess = radius[i]
    return radius, partner


@numba.njit(cache=True)
def _keep_mask(pts, centres, radius, partner, point_like, min_width, max_width):
    """Medial points to lay: opposite sides, width in range, one of each pair of sides."""
    n = pts.shape[0]
    keep = np.zeros(n, np.bool_)
    for i in range(n):
        q = partner[i]
        w = 2.0 * radius[i]
        if q <= i or w < min_width or w > max_width:
            continue
        ax, ay = pts[i, 0] - centres[i, 0], pts[i, 1] - centres[i, 1]
        bx, by = pts[q, 0] - centres[i, 0], pts[q, 1] - centres[i, 1]
        cos = (ax * bx + ay * by) / max(radius[i] * np.hypot(bx, by), 1e-18)
        limit = _COS_POINT if (point_like[i] or point_like[q]) else _COS_OPPOSITE
        keep[i] = cos <= limit
    return keep


@numba.njit(cache=True)
def _chain_nb(centres, widths, keep, cstart, h):
    """Chains of kept samples in boundary order, a new chain at each contour and wherever the
    medial point jumps (a branch): (sample indices (m,), chain offsets (c + 1,))."""
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


@numba.njit(cache=True)
def _join_nb(centres, widths, idx, offs, h):
    """Chains joined where their ends meet (the seam of a contour, a switch of the side that
    carries a branch), nearest pairs first; a chain whose own ends meet is closed. Chains of one
    point are dropped. Returns (indices, offsets, closed) of the joined chains."""
    keep = np.empty(offs.shape[0] - 1, np.int64)
    nc = 0
    for c in range(offs.shape[0] - 1):
        if offs[c + 1] - offs[c] >= 2:
            keep[nc] = c
            nc += 1
    ne = 2 * nc
    ends = np.empty(ne, np.int64)                    # end e: chain e // 2, start (even) or end (odd)
    for c in range(nc):
        ends[2 * c] = idx[offs[keep[c]]]
        ends[2 * c + 1] = idx[offs[keep[c] + 1] - 1]
    reach = 4.0 * h
    for e in range(ne):
        reach = max(reach, 0.35 * widths[ends[e]])
    by_x = np.argsort(centres[ends, 0])
    pa = np.empty(0, np.int64)
    pb = np.empty(0, np.int64)
    pd = np.empty(0)
    na = 0
    for u in range(ne):
        a = by_x[u]
        for v in range(u + 1, ne):
            b = by_x[v]
            dx = centres[ends[b], 0] - centres[ends[a], 0]
            if dx > reach:
                break
            if a // 2 == b // 2:
                continue
            d = np.hypot(dx, centres[ends[b], 1] - centres[ends[a], 1])
            if d <= max(4.0 * h, 0.35 * min(widths[ends[a]], widths[ends[b]])):
                if na == pa.shape[0]:
                    grow = max(16, 2 * na)
                    pa = np.concatenate((pa, np.empty(grow, np.int64)))
                    pb = np.concatenate((pb, np.empty(grow, np.int64)))
                    pd = np.concatenate((pd, np.empty(grow)))
                pa[na] = a
                pb[na] = b
                pd[na] = d
                na += 1
    link = np.full(ne, -1, np.int64)
    for k in np.argsort(pd[:na]):
        if link[pa[k]] < 0 and link[pb[k]] < 0:
            link[pa[k]] = pb[k]
            link[pb[k]] = pa[k]
    out = np.empty(idx.shape[0], np.int64)
    out_offs = np.zeros(nc + 1, np.int64)
    closed = np.zeros(nc, np.bool_)
    seen = np.zeros(nc, np.bool_)
    m = 0
    nout = 0
    for sweep in range(2):                           # from free ends first, then what is left: cycles
        for e0 in range(ne):
            if seen[e0 // 2] or (sweep == 0 and link[e0] >= 0):
                continue
            cur = e0
            is_loop = False
            while True:
                c = cur // 2
                seen[c] = True
                lo, hi = offs[keep[c]], offs[keep[c] + 1]
                if cur % 2 == 0:
                    for k in range(lo, hi):
                        out[m] = idx[k]
                        m += 1
                else:
                    for k in range(hi - 1, lo - 1, -1):
                        out[m] = idx[k]
                        m += 1
                other = link[cur ^ 1]
                if other < 0:
                    break
                if seen[other // 2]:
                    is_loop = True
                    break
                cur = other
            first, last = out[out_offs[nout]], out[m - 1]
            if not is_loop:
                gap = np.hypot(centres[first, 0] - centres[last, 0], centres[first, 1] - centres[last, 1])
                wmin = min(widths[first], widths[last])
                run = 0.0
                for k in range(out_offs[nout] + 1, m):
                    run += np.hypot(centres[out[k], 0] - centres[out[k - 1], 0],
                                    centres[out[k], 1] - centres[out[k - 1], 1])
                is_loop = gap <= max(4.0 * h, 0.35 * wmin) and run > 4.0 * wmin
            closed[nout] = is_loop
            nout += 1
            out_offs[nout] = m
    return out[:m], out_offs[:nout + 1], closed[:nout]


@numba.njit(cache=True)
def _ray_to_boundary(tip, d, reach, edge, seg_a, seg_b, spts, order, start, x0, y0, ny, cell):
    """Distance from ``tip`` along unit ``d`` to the first boundary edge, if below ``reach``
    (else inf); the edges are those of the samples within ``reach`` of the tip."""
    box = reach + cell
    lo, hi = _cells(start, ny, np.int64((tip[0] - box - x0) / cell), np.int64((tip[0] + box - x0) / cell),
                    np.int64((tip[1] - box - y0) / cell), np.int64((tip[1] + box - y0) / cell))
    best = np.inf
    for c in range(lo.shape[0]):
        for k in range(lo[c], hi[c]):
            e = edge[order[k]]
            ax, ay = seg_a[e, 0] - tip[0], seg_a[e, 1] - tip[1]
            ex, ey = seg_b[e, 0] - seg_a[e, 0], seg_b[e, 1] - seg_a[e, 1]
            den = d[0] * ey - d[1] * ex
            if abs(den) < 1e-12:
                continue
            s = (ax * ey - ay * ex) / den
            u = (ax * d[1] - ay * d[0]) / den
            if s > 0.0 and 0.0 <= u <= 1.0 and s < best:
                best = s
    return best if best <= reach else np.inf


@numba.njit(cache=True)
def _extend(m, w, edge, seg_a, seg_b, spts, order, start, x0, y0, ny, cell):
    """Free ends of chain ``m`` (k, 2) carried along their direction to the boundary when it is
    within 0.75 of the end's width ahead (the square end of a strip, where the axis stops half a
    width short; PrusaSlicer extends such ends too). Returns (m, w) with up to 2 more points."""
    k = m.shape[0]
    out_m = np.empty((k + 2, 2))
    out_w = np.empty(k + 2)
    out_m[1:k + 1] = m
    out_w[1:k + 1] = w
    first = 1
    last = k
    for end in range(2):
        t = 0 if end == 0 else k - 1
        step = 1 if end == 0 else -1
        tip = m[t]
        j = t
        while 0 <= j + step < k:
            j += step
            if np.hypot(m[j, 0] - tip[0], m[j, 1] - tip[1]) > 0.5 * w[t]:
                break
        d = tip - m[j]
        nd = np.hypot(d[0], d[1])
        if nd < 1e-9:
            continue
        d = d / nd
        s = _ray_to_boundary(tip, d, 0.75 * w[t], edge, seg_a, seg_b, spts, order, start, x0, y0, ny, cell)
        if s == np.inf:
            continue
        slot = 0 if end == 0 else k + 1
        out_m[slot] = tip + d * max(s - 0.005, 0.0)
        out_w[slot] = w[t]
        if end == 0:
            first = 0
        else:
            last = k + 1
    return out_m[first:last + 1], out_w[first:last + 1]


@numba.njit(cache=True)
def _finish(centres, widths, idx, offs, closed, edge, seg_a, seg_b, min_width, h,
            spts, order, start, x0, y0, ny, cell):
    """Chains -> pieces: ends extended, split where the width leaves the piece's running mean by
    more than 10%, pieces shorter than ``min_width`` dropped, each simplified. Returns the
    pieces as a ragged array (points (p, 2), offsets (q + 1,), width (q,))."""
    nch = offs.shape[0] - 1
    cap = 2 * idx.shape[0] + 4 * nch + 4
    out_p = np.empty((cap, 2))
    out_o = np.empty(cap + 1, np.int64)
    out_w = np.empty(cap)
    npts = 0
    npc = 0
    out_o[0] = 0
    for c in range(nch):
        sel = idx[offs[c]:offs[c + 1]]
        k = sel.shape[0]
        extra = 1 if closed[c] else 0
        m = np.empty((k + extra, 2))
        w = np.empty(k + extra)
        for i in range(k):
            m[i] = centres[sel[i]]
            w[i] = widths[sel[i]]
        if closed[c]:
            m[k] = m[0]
            w[k] = w[0]
        else:
            m, w = _extend(m, w, edge, seg_a, seg_b, spts, order, start, x0, y0, ny, cell)
        n = m.shape[0]
        a = 0
        acc = 0.0
        tot = 0.0
        for i in range(1, n + 1):
            split = i == n
            if not split:
                seg = np.hypot(m[i, 0] - m[i - 1, 0], m[i, 1] - m[i - 1, 1])
                wi = 0.5 * (w[i] + w[i - 1])
                split = tot > 0.0 and abs(wi - acc / tot) > _WIDTH_STEP * acc / tot
            if split:
                if tot >= min_width:
                    keep = _simplify(m[a:i], 0.25 * h)
                    for j in range(a, i):
                        if keep[j - a]:
                            out_p[npts] = m[j]
                            npts += 1
                    out_w[npc] = acc / tot
                    npc += 1
                    out_o[npc] = npts
                a = i - 1
                acc = 0.0
                tot = 0.0
            if i < n:
                acc += wi * seg
                tot += seg
    return out_p[:npts].copy(), out_o[:npc + 1].copy(), out_w[:npc].copy()


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


def single_bead(region: manifold3d.CrossSection, min_width: float, max_width: float
                ) -> tuple[np.ndarray, float] | None:
    """One straight bead for a small island that neither a loop nor a medial line prints (a tip
    under a model's top, a spike's end): along the island's longest direction (the principal
    axis of its outline) through the middle of its extent, as wide as the island is on average
    across it (area / extent, held to ``[min_width, max_width]``) and as long as makes width x
    length the island's area, so the bead lays the island's volume as a medial line's does.
    This is what PrusaSlicer 2.5's Arachne walls print for such an island (one bead, where its
    classic walls print nothing): without it the top sliver of a pointed part is lost and the
    part is a layer short. ``None`` for an empty region."""
    polys = [np.asarray(p, dtype=np.float64) for p in region.to_polygons() if len(p) >= 3]
    area = float(region.area())
    if not polys or area <= 0.0:
        return None
    pts = np.concatenate(polys)
    centre = pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts - centre, full_matrices=False)
    axis = vt[0]
    along = (pts - centre) @ axis
    lo, hi = float(along.min()), float(along.max())
    mid = centre + axis * (0.5 * (lo + hi))
    width = float(np.clip(area / max(hi - lo, 1e-9), min_width, max_width))
    half = 0.5 * area / width
    return np.stack([mid - axis * half, mid + axis * half]), width
