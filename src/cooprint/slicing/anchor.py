"""Infill lines anchored along the perimeters (issue 17, PrusaSlicer's ``infill_anchor`` and
``infill_anchor_max``).

``anchor_infill(lines, rings, anchor, anchor_max)`` -> list of (k, 2) polylines.
  ``lines``: the sparse infill lines of one region in print order (a list of (k, 2) polylines,
  each with both ends on the region's boundary (within ``tol``), as :func:`~cooprint.slicing.infill.hatch` and
  :func:`~cooprint.slicing.patterns.gyroid` give them); ``rings``: the region's boundary (closed
  rings, outlines and holes). Consecutive lines whose ends lie on the same ring at most
  ``anchor_max`` apart along it are joined by that stretch of the ring into one polyline
  (PrusaSlicer's connect_infill); a line end left unjoined gets an anchor: the ring followed from
  it for at most ``anchor`` mm (not into another line's end). ``anchor = 0`` and
  ``anchor_max = 0`` return ``lines`` unchanged. No added stretch leaves the region.

How (written from PrusaSlicer 2.5's Fill::connect_infill, not copied): every line end is placed
on its ring by arc length; "consecutive" ends are neighbours along a ring (no other line end
between them). The stretches between neighbours are taken shortest first: one shorter than
``anchor_max`` joins its two lines unless they already belong to one polyline (no loops); a
longer one gets an anchor from each end into it. Ends still free then join a neighbour within
``anchor_max`` or get an anchor along the side with more free ring. An anchor stops half a line
width short of the neighbouring end and of the neighbour's own anchor, so no stretch of ring is
printed twice (PrusaSlicer lets the second anchor run up to the first). Ends farther than ``END_TOL`` from every ring stay as they
are. As PrusaSlicer, the ring is masked where an infill line runs along it (within
``COLLIDE`` widths, away from the line's ends): no join over it, anchors stop before it.

The slicer passes the fill region shrunk by half a spacing as ``rings`` and ends the lines 0.1
spacing outside it (``tol``), as PrusaSlicer 2.5 does, so joins and anchors lie beside the inner
perimeter instead of on it. ``snake=True`` (solid infill) joins as PrusaSlicer's rectilinear solid
fill does: a walk from line to line in print order, each time to the nearer free neighbouring
end, which makes one polyline of a convex area where shortest-first leaves several.
``join_infill`` (what the slicer calls, packed: ``join_packed``) is that snake pass followed by
``anchor_infill`` on its chains, PrusaSlicer's two passes, on one
:class:`~cooprint.slicing.rings.RingSet`, in one compiled call after the line ends are placed on
the rings (``_join``; its chains' order is :func:`chain_order`'s, which the gyroid uses too).

The mask samples every ring each half width; only the samples near an infill segment are
measured (``_blocked``: each segment asks the rings' grid for the edges within reach), which
costs the segments' crossings with the rings instead of every sample against every line.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from cooprint.slicing.rings import RingSet

#: A line end within this distance of a ring is on it, mm.
END_TOL = 1e-3
#: A stretch of ring within this many line widths of an infill line is not printed (PrusaSlicer: 0.8).
COLLIDE = 0.8
#: ...except near that line's own ends: its last this many widths (PrusaSlicer: 1.7).
END_CLEAR = 1.7
#: Default line width (``anchor_infill``'s ``width``): anchors stop half of it short of the next
#: line's end, mm (PrusaSlicer's sparse infill width for a 0.4 mm nozzle).
LINE_WIDTH = 0.45


def anchor_infill(lines: list[np.ndarray], rings: list[np.ndarray] | RingSet, anchor: float, anchor_max: float,
                  width: float = LINE_WIDTH, tol: float = END_TOL, snake: bool = False) -> list[np.ndarray]:
    """``lines`` joined and anchored along ``rings`` (module docstring).

    Parameters
    ----------
    lines : list of (k, 2) float
        Infill polylines (k >= 2) in print order, ends on the rings.
    rings : list of (m, 2) float, or RingSet
        The region's closed rings (outlines and holes); a :class:`~cooprint.slicing.rings.RingSet`
        of them when several calls share the region (its search structures are built once).
    anchor : float
        Longest anchor, mm (PrusaSlicer's infill_anchor); 0: no anchors.
    anchor_max : float
        Longest stretch of ring that joins two lines, mm (infill_anchor_max); 0: no joins.
    width : float
        Line width, mm: an anchor stops half of it short of a neighbouring line's end.
    tol : float
        A line end within this distance of a ring is on it, mm: the lines may end a little
        outside the rings (PrusaSlicer ends its lines 0.4 spacing inside the fill region and
        connects them along the region shrunk by 0.5 spacing); the join or anchor starts at the
        end's nearest point on the ring.
    snake : bool
        Join as PrusaSlicer's rectilinear solid fill does: from each line's far end to the
        nearer free neighbour along the ring, chain after chain in print order (long snakes over
        a solid area), rather than shortest stretches first; no anchors.

    Returns
    -------
    list of (j, 2) float64
        The joined and anchored polylines, in nearest-next order from the first line's start.
    """
    return unpacked(*_passes(lines, rings, False, anchor, anchor_max, snake, width, tol))


def join_infill(lines: list[np.ndarray] | np.ndarray, rings: list[np.ndarray] | RingSet, anchor: float,
                anchor_max: float, width: float = LINE_WIDTH, tol: float = END_TOL) -> list[np.ndarray]:
    """``lines`` joined as PrusaSlicer joins them: first snake-wise (``anchor_infill`` with
    ``snake``, no anchors), then the chains' ends shortest stretch first, with anchors; the same
    as those two calls (parameters as :func:`anchor_infill`'s), without unpacking the chains in
    between."""
    return unpacked(*join_packed(lines, rings, anchor, anchor_max, width, tol))


def join_packed(lines: list[np.ndarray] | np.ndarray, rings: list[np.ndarray] | RingSet, anchor: float,
                anchor_max: float, width: float = LINE_WIDTH, tol: float = END_TOL) -> tuple[np.ndarray, np.ndarray]:
    """:func:`join_infill`'s polylines packed: (points (N, 2) float64, offsets (n + 1,) int64,
    polyline i is ``points[offsets[i]:offsets[i + 1]]``), for a caller that batches them
    (the slicer: thousands of infill lines per region, most of them left as 2-point segments).
    ``lines`` may also be an (m, k, 2) array: m polylines of k points (a batch of hatch
    segments: no Python work per line)."""
    return _passes(lines, rings, anchor_max > 0, anchor, anchor_max, False, width, tol)


def unpacked(pts: np.ndarray, offsets: np.ndarray) -> list[np.ndarray]:
    """The polylines ``pts[offsets[i]:offsets[i + 1]]`` as a list (views)."""
    bounds = offsets.tolist()  # (np.split's per-part overhead is 3x this)
    return [pts[a:b] for a, b in zip(bounds[:-1], bounds[1:])]


def _passes(lines, rings, snake_first, anchor, anchor_max, snake, width, tol) -> tuple[np.ndarray, np.ndarray]:
    """``lines`` through a snake pass without anchors if ``snake_first``, then the ``(anchor,
    snake)`` pass (neither runs without anchors or joins), on one packed array and one RingSet of
    ``rings``: (points, offsets) as :func:`_packed`. The line ends are placed on the rings here,
    the passes are one compiled call (:func:`_join`)."""
    pts, lo = _packed(lines)
    if (anchor > 0 or anchor_max > 0) and len(lo) > 1:
        rs = rings if isinstance(rings, RingSet) else RingSet(rings)
        if len(rs):
            n = len(lo) - 1
            ends = np.empty((2 * n, 2))
            ends[0::2] = pts[lo[:-1]]
            ends[1::2] = pts[lo[1:] - 1]
            edge, t, _ = rs.nearest(ends, max(tol, END_TOL))
            x0, y0, cell, nx, ny, gstart, gids = rs.grid
            pts, lo = _join(pts, lo, edge, t, rs.a, rs.b, rs.param, rs.seg_len, rs.ring_of, rs.ring_start,
                            rs.ring_len, x0, y0, cell, nx, ny, gstart, gids, bool(snake_first and anchor_max > 0),
                            float(anchor), float(anchor_max), bool(snake), float(width))
    return pts, lo


def _packed(lines: list[np.ndarray] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The polylines of two points or more, (x, y) only, concatenated: (points (N, 2) float64,
    offsets (n + 1,) int64: line i is ``points[offsets[i]:offsets[i + 1]]``); ``lines`` a list,
    or an (m, k, 2) array of m polylines of k points."""
    if isinstance(lines, np.ndarray):
        m, k = lines.shape[:2]
        if not m or k < 2:
            return np.zeros((0, 2)), np.zeros(1, np.int64)
        return (np.ascontiguousarray(lines[:, :, :2].reshape(-1, 2), dtype=np.float64),
                np.arange(0, m * k + 1, k, dtype=np.int64))
    sizes = np.fromiter(map(len, lines), np.int64, len(lines))
    if (sizes < 2).any():
        lines = [p for p, k in zip(lines, sizes) if k >= 2]
        sizes = sizes[sizes >= 2]
    if not len(lines):
        return np.zeros((0, 2)), np.zeros(1, np.int64)
    try:
        pts = np.concatenate(lines)
    except ValueError:  # rows of different widths
        pts = np.concatenate([np.asarray(p)[:, :2] for p in lines])
    return np.ascontiguousarray(pts[:, :2], dtype=np.float64), np.concatenate(([0], np.cumsum(sizes)))


@numba.njit(cache=True)
def _join(pts, lo, edge, t, a, b, rparam, seg_len, ring_of, ring_start, ring_len, x0, y0, cell, nx, ny,
          gstart, gids, snake_first, anchor, anchor_max, snake, width):
    """The passes of :func:`_passes` over the lines ``pts[lo[i]:lo[i + 1]]`` (at least one, each
    of two points or more) whose ends (2 i: line i's first point, 2 i + 1: its last) lie on
    ``edge`` at ``t`` (:meth:`RingSet.nearest <cooprint.slicing.rings.EdgeSet.nearest>`; ``a``
    .. ``ring_len`` and ``x0`` .. ``gids``: the RingSet and its grid): each pass's chains in
    nearest-next order from the first line's chain, (points, offsets). A snake pass adds no
    anchors, so its chains end at line ends: the next pass takes their places on the rings from
    those (the same query, the same answer) instead of asking the rings again."""
    if snake_first:
        pts, lo, head, tail = _pass(pts, lo, edge, t, a, b, rparam, seg_len, ring_of, ring_start, ring_len,
                                    x0, y0, cell, nx, ny, gstart, gids, 0.0, anchor_max, width, True)
        pts, lo, order, rev = _ordered(pts, lo)
        k = order.shape[0]
        e2 = np.empty(2 * k, np.int64)
        t2 = np.empty(2 * k)
        for j in range(k):
            c = order[j]
            first, last = (tail[c], head[c]) if rev[j] else (head[c], tail[c])
            e2[2 * j], t2[2 * j] = edge[first], t[first]
            e2[2 * j + 1], t2[2 * j + 1] = edge[last], t[last]
        edge, t = e2, t2
    pts, lo, _, _ = _pass(pts, lo, edge, t, a, b, rparam, seg_len, ring_of, ring_start, ring_len,
                          x0, y0, cell, nx, ny, gstart, gids, anchor, anchor_max, width, snake)
    pts, lo, _, _ = _ordered(pts, lo)
    return pts, lo


@numba.njit(cache=True)
def _ordered(pts, off):
    """The polylines ``pts[off[k]:off[k + 1]]`` (at least one) in nearest-next order from the
    first one's start (:func:`chain_order`), packed again: (points, offsets, order, reversed)."""
    k = off.shape[0] - 1
    heads = np.empty((k, 2))
    tails = np.empty((k, 2))
    for j in range(k):
        heads[j] = pts[off[j]]
        tails[j] = pts[off[j + 1] - 1]
    order, rev = _chain(heads, tails, pts[0])
    out, lo = _reordered(pts, off, order, rev)
    return out, lo, order, rev


@numba.njit(cache=True)
def _pass(pts, lo, edge, t, a, b, rparam, seg_len, ring_of, ring_start, ring_len, x0, y0, cell, nx, ny,
          gstart, gids, anchor, anchor_max, width, snake):
    """One pass of :func:`_join` (its parameters): each end's neighbours along its ring, the
    free stretches (:func:`_free_along`), the joins and anchors (:func:`_snake` or
    :func:`_connect`), the chains (:func:`_chains`): (points, offsets, first end, last end), the
    chains in order of their first line."""
    m = edge.shape[0]
    ring = np.full(m, -1, np.int64)
    param = np.zeros(m)
    nv = 0
    for e in range(m):
        i = edge[e]
        if i >= 0:
            ring[e] = ring_of[i]
            param[e] = rparam[i] + t[e] * seg_len[i]
            nv += 1
    # neighbours along each ring: the ends on rings sorted by (ring, arc length), stably
    idx = np.empty(nv, np.int64)
    k = 0
    for e in range(m):
        if ring[e] >= 0:
            idx[k] = e
            k += 1
    idx = idx[np.argsort(param[idx], kind="mergesort")]
    idx = idx[np.argsort(ring[idx], kind="mergesort")]
    nxt = np.full(m, -1, np.int64)
    prv = np.full(m, -1, np.int64)
    g = 0
    while g < nv:
        h = g
        while h + 1 < nv and ring[idx[h + 1]] == ring[idx[g]]:
            h += 1
        for k in range(g, h + 1):
            f = idx[k + 1] if k < h else idx[g]
            nxt[idx[k]] = f
            prv[f] = idx[k]
        g = h + 1
    # each end's ring length and the stretch of ring to its next neighbour
    elen = np.zeros(m)
    arc = np.zeros(m)
    for e in range(m):
        if ring[e] < 0:
            continue
        L = ring_len[ring[e]]
        elen[e] = L
        if nxt[e] == e:
            arc[e] = L
        elif L > 0:
            arc[e] = (param[nxt[e]] - param[e]) % L
        else:
            arc[e] = np.nan
    nt_next, nt_prev = _free_along(pts, lo, a, b, rparam, seg_len, ring_of, ring_start, ring_len, x0, y0, cell,
                                   nx, ny, gstart, gids, ring, param, prv, arc, width)
    if snake:
        code, hook = _snake(nxt, prv, arc, nt_next, nt_prev, anchor_max), np.zeros(m)
    else:
        code, hook = _connect(nxt, prv, arc, elen, nt_next, nt_prev, anchor, anchor_max, 0.5 * width)
    return _chains(pts, lo, ring, param, code, hook, a, b, rparam, seg_len, ring_start, ring_len)


@numba.njit(cache=True)
def _free_along(pts, lo, a, b, rparam, seg_len, ring_of, ring_start, ring_len, x0, y0, cell, nx, ny,
                gstart, gids, ring, param, prv, arc, width):
    """How far the ring is free from every line end forward and backward before it runs within
    ``COLLIDE`` widths of an infill line (one's last ``END_CLEAR`` widths aside, which meet the
    ring anyway): (forward (2n,), backward (2n,)), inf when free up to the neighbouring end.
    PrusaSlicer's mark_boundary_segments_touching_infill: a stretch of ring next to an infill line
    that runs along it would print that line twice. ``ring``, ``param``: each end's ring (-1:
    none) and arc length on it; ``prv``, ``arc``: its previous neighbour, the stretch to its next."""
    m = ring.shape[0]
    fwd = np.full(m, np.inf)
    bwd = np.full(m, np.inf)
    sa, sb = _clear_parts(pts, lo, END_CLEAR * width)
    if sa.shape[0] == 0:
        return fwd, bwd
    # samples along the rings every half width: those near an infill line are blocked
    step = 0.5 * width
    nr = ring_len.shape[0]
    counts = np.empty(nr, np.int64)
    offset = np.zeros(nr + 1, np.int64)
    for r in range(nr):
        counts[r] = max(int(math.ceil(ring_len[r] / step)), 1)
        offset[r + 1] = offset[r] + counts[r]
    big = ring_len.max() + 1.0
    key = np.empty(a.shape[0])  # RingSet.points_at's search key
    for i in range(a.shape[0]):
        key[i] = ring_of[i] * big + rparam[i]
    out = _blocked(sa, sb, a, b, rparam, seg_len, ring_of, ring_start, ring_len, key, big, counts, offset,
                   x0, y0, cell, nx, ny, gstart, gids, COLLIDE * width)
    # the blocked samples' rings and arc lengths, keyed as above (sorted: rings in order, arc
    # length within each); every ring's first and last
    nb = 0
    for g in range(out.shape[0]):
        if out[g]:
            nb += 1
    if nb == 0:
        return fwd, bwd
    br = np.empty(nb, np.int64)
    bp = np.empty(nb)
    bkey = np.empty(nb)
    ring_first = np.full(nr, -1, np.int64)
    ring_last = np.full(nr, -1, np.int64)
    j = 0
    for r in range(nr):
        st = ring_len[r] / counts[r]
        for k in range(counts[r]):
            if out[offset[r] + k]:
                br[j] = r
                bp[j] = k * st
                bkey[j] = r * big + bp[j]
                if ring_first[r] < 0:
                    ring_first[r] = j
                ring_last[r] = j
                j += 1
    for e in range(m):
        r = ring[e]
        if r < 0 or ring_first[r] < 0:
            continue
        L = ring_len[r]
        pe = param[e]
        q = r * big + pe
        lo_, hi_ = 0, nb  # the first blocked sample past the end (np.searchsorted, side "right")
        while lo_ < hi_:
            mid = (lo_ + hi_) // 2
            if bkey[mid] <= q:
                lo_ = mid + 1
            else:
                hi_ = mid
        j = lo_
        ahead = bp[j] - pe if j < nb and br[j] == r else bp[ring_first[r]] + L - pe
        lo_, hi_ = 0, nb  # the last one before it (side "left", minus one)
        while lo_ < hi_:
            mid = (lo_ + hi_) // 2
            if bkey[mid] < q:
                lo_ = mid + 1
            else:
                hi_ = mid
        j = lo_ - 1
        behind = pe - bp[j] if j >= 0 and br[j] == r else pe + L - bp[ring_last[r]]
        # only what lies before the neighbouring end matters
        if ahead < arc[e]:
            fwd[e] = ahead
        if behind < arc[prv[e]]:
            bwd[e] = behind
    return fwd, bwd


@numba.njit(cache=True)
def _find(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@numba.njit(cache=True)
def _hook(e, side, nxt, prv, arc, ring_len, anchor, hw, consumed, nt_next, nt_prev, trim_next, trim_prev, hook):
    """Anchor end ``e`` along its ring, forward (side 1) or backward (-1), into the stretch
    towards its neighbour; the neighbour's free stretch on that side shrinks accordingly."""
    eps = 1e-9
    if consumed[e]:
        return
    free = nt_next[e] if side > 0 else nt_prev[e]
    f = nxt[e] if side > 0 else prv[e]
    if f == e:
        stretch = ring_len[e]
    else:
        stretch = arc[e] if side > 0 else arc[prv[e]]
    # stop half a width short of the neighbouring line's end, and of the neighbour's anchor
    length = min(anchor, free - hw, stretch - hw)
    if length <= eps:
        return  # nothing to take on this side: the end stays free for the other side
    consumed[e] = True
    if side > 0:
        nt_next[e] = 0.0
        trim_next[e] = True
    else:
        nt_prev[e] = 0.0
        trim_prev[e] = True
    if f == e:
        nt_next[e] = 0.0
        nt_prev[e] = 0.0
        trim_next[e] = True
        trim_prev[e] = True
    elif side > 0:
        if stretch - length < nt_prev[f]:
            nt_prev[f] = stretch - length
            trim_prev[f] = True
    else:
        if stretch - length < nt_next[f]:
            nt_next[f] = stretch - length
            trim_next[f] = True
    hook[e] = side * length


@numba.njit(cache=True)
def _connect(nxt, prv, arc, ring_len, nt_next, nt_prev, anchor, anchor_max, hw):
    """Which line ends join which, and the anchors of the others (module docstring).

    ``nxt``/``prv``: the neighbouring end along the ring (-1: the end is on no ring); ``arc``:
    the ring's length from each end to ``nxt``; ``nt_next``/``nt_prev``: how far the ring is
    free from each end (inf: up to the neighbour). Returns (code (2n,): -1 not joined,
    2 * other + 1 joined to ``other`` going forward along the ring, 2 * other going backward;
    hook (2n,): the anchor's length, + forward, - backward, 0 none)."""
    m = nxt.shape[0]
    consumed = nxt < 0
    nt_next = nt_next.copy()
    nt_prev = nt_prev.copy()
    trim_next = nt_next < np.inf
    trim_prev = nt_prev < np.inf
    parent = np.arange(m // 2)
    code = np.full(m, -1, np.int64)
    hook = np.zeros(m)
    # stretches between neighbours, shortest first
    cand = np.empty(m, np.int64)
    nc = 0
    for e in range(m):
        if nxt[e] >= 0 and nxt[e] != e:
            cand[nc] = e
            nc += 1
    cand = cand[:nc]
    cand = cand[np.argsort(arc[cand], kind="mergesort")]
    for e in cand:
        f = nxt[e]
        if consumed[e] or consumed[f] or trim_next[e] or trim_prev[f]:
            continue
        g1, g2 = _find(parent, e // 2), _find(parent, f // 2)
        if g1 == g2:
            continue
        if arc[e] < anchor_max:
            code[e] = 2 * f + 1
            code[f] = 2 * e
            consumed[e] = consumed[f] = True
            nt_next[e] = nt_prev[f] = 0.0
            trim_next[e] = trim_prev[f] = True
            parent[max(g1, g2)] = min(g1, g2)
        elif anchor > 0:
            _hook(e, 1, nxt, prv, arc, ring_len, anchor, hw, consumed, nt_next, nt_prev, trim_next, trim_prev, hook)
            _hook(f, -1, nxt, prv, arc, ring_len, anchor, hw, consumed, nt_next, nt_prev, trim_next, trim_prev, hook)
    # the ends still free: join a neighbour within anchor_max, else anchor on the freer side
    for e in range(m):
        if consumed[e]:
            continue
        p, f = prv[e], nxt[e]
        lp = arc[p] if (p != e and not consumed[p] and not trim_prev[e] and not trim_next[p]) else np.inf
        ln = arc[e] if (f != e and not consumed[f] and not trim_next[e] and not trim_prev[f]) else np.inf
        joined = False
        for k in range(2):
            back = (lp <= ln) if k == 0 else (lp > ln)
            length = lp if back else ln
            if length == np.inf or length > anchor_max:
                break
            o = p if back else f
            g1, g2 = _find(parent, e // 2), _find(parent, o // 2)
            if g1 == g2:
                continue
            if back:
                code[e] = 2 * o
                code[o] = 2 * e + 1
                nt_prev[e] = nt_next[o] = 0.0
                trim_prev[e] = trim_next[o] = True
            else:
                code[e] = 2 * o + 1
                code[o] = 2 * e
                nt_next[e] = nt_prev[o] = 0.0
                trim_next[e] = trim_prev[o] = True
            consumed[e] = consumed[o] = True
            parent[max(g1, g2)] = min(g1, g2)
            joined = True
            break
        if not joined and anchor > 0:
            side = -1 if nt_prev[e] > nt_next[e] else 1
            _hook(e, side, nxt, prv, arc, ring_len, anchor, hw, consumed, nt_next, nt_prev, trim_next, trim_prev, hook)
    return code, hook


@numba.njit(cache=True)
def _snake(nxt, prv, arc, nt_next, nt_prev, anchor_max):
    """Joins (``_connect``'s code) made by walking from each unvisited line's ends, in print
    order, to the nearer free neighbouring end along the ring within ``anchor_max`` whose
    stretch no infill line runs along, and on from that line's other end."""
    m = nxt.shape[0]
    parent = np.arange(m // 2)
    code = np.full(m, -1, np.int64)
    used = nxt < 0
    for st in range(m):
        e = st
        while not used[e]:
            best, fwd, length = -1, False, anchor_max
            g1 = _find(parent, e // 2)
            f = nxt[e]
            if (f != e and not used[f] and nt_next[e] == np.inf and arc[e] <= length
                    and _find(parent, f // 2) != g1):
                best, fwd, length = f, True, arc[e]
            b = prv[e]
            if (b != e and not used[b] and nt_prev[e] == np.inf and arc[b] <= length
                    and _find(parent, b // 2) != g1):
                best, fwd, length = b, False, arc[b]
            if best < 0:
                break
            g2 = _find(parent, best // 2)
            code[e] = 2 * best + 1 if fwd else 2 * best
            code[best] = 2 * e if fwd else 2 * e + 1
            used[e] = used[best] = True
            parent[max(g1, g2)] = min(g1, g2)
            e = best ^ 1
    return code


@numba.njit(cache=True)
def _reserve(buf, m, extra):
    """``buf`` with room for ``extra`` more points after the first ``m``."""
    if m + extra <= buf.shape[0]:
        return buf
    grown = np.empty((max(2 * buf.shape[0], m + extra), 2))
    grown[:m] = buf[:m]
    return grown


@numba.njit(cache=True)
def _push(buf, m, x, y):
    buf = _reserve(buf, m, 1)
    buf[m, 0] = x
    buf[m, 1] = y
    return buf, m + 1


@numba.njit(cache=True)
def _walk(buf, m, a, b, rparam, seg_len, s, k, total, p0, p1, forward):
    """Append the point of the ring (edges s .. s + k) at arc length ``p0`` unless the last
    point is there already (a line end off the ring steps onto it), the ring's vertices strictly
    between ``p0`` and ``p1``, going forward (increasing arc length) or backward, then the point
    at ``p1``."""
    eps = 1e-12
    p0m, p1m = p0 % total, p1 % total
    j, x0, y0 = _ring_point(a, b, rparam, seg_len, s, k, p0m)
    if m == 0 or abs(buf[m - 1, 0] - x0) + abs(buf[m - 1, 1] - y0) > 1e-9:
        buf, m = _push(buf, m, x0, y0)
    span = (p1 - p0) % total if forward else (p0 - p1) % total
    if forward:
        i = j + 1
        d = (rparam[s + i] if i < k else total) - p0m
        while d < span - eps:
            if d > eps:
                buf, m = _push(buf, m, a[s + i % k, 0], a[s + i % k, 1])
            d += seg_len[s + i % k]
            i += 1
    else:
        i = j
        d = p0m - rparam[s + j]
        while d < span - eps:
            if d > eps:
                buf, m = _push(buf, m, a[s + i, 0], a[s + i, 1])
            i = (i - 1) % k
            d += seg_len[s + i]
    _, x1, y1 = _ring_point(a, b, rparam, seg_len, s, k, p1m)
    buf, m = _push(buf, m, x1, y1)
    return buf, m


@numba.njit(cache=True)
def _ring_point(a, b, rparam, seg_len, s, k, p):
    """The point of the ring (edges s .. s + k) at arc length ``p`` (in [0, its length)): (the
    edge it lies on, counted from s; x; y)."""
    j = np.searchsorted(rparam[s:s + k], p, side="right") - 1
    sl = seg_len[s + j]
    t = (p - rparam[s + j]) / sl if sl > 0 else 0.0
    return j, a[s + j, 0] + t * (b[s + j, 0] - a[s + j, 0]), a[s + j, 1] + t * (b[s + j, 1] - a[s + j, 1])


@numba.njit(cache=True)
def _chains(pts, lo, ring, param, code, hook, a, b, rparam, seg_len, ring_start, ring_len):
    """The chains of lines joined by ring stretches, with their anchors: (points, offsets, the
    line end each starts from, the line end it finishes at), in order of their first line."""
    n = lo.shape[0] - 1
    seen = np.zeros(n, np.bool_)
    buf = np.empty((2 * pts.shape[0] + 16, 2))
    m = 0
    off = np.zeros(n + 1, np.int64)
    head = np.zeros(n, np.int64)
    tail = np.zeros(n, np.int64)
    nc = 0
    for st in range(2 * n):
        if code[st] >= 0 or seen[st // 2]:
            continue
        off[nc] = m
        head[nc] = st
        if hook[st] != 0.0:
            r = ring[st]
            s = ring_start[r]
            t0 = m
            buf, m = _walk(buf, m, a, b, rparam, seg_len, s, ring_start[r + 1] - s, ring_len[r],
                           param[st], param[st] + hook[st], hook[st] > 0)
            buf[t0:m] = buf[t0:m][::-1].copy()
            li = st // 2
            fp = lo[li] if st % 2 == 0 else lo[li + 1] - 1  # the line's first point
            if abs(buf[m - 1, 0] - pts[fp, 0]) + abs(buf[m - 1, 1] - pts[fp, 1]) <= 1e-9:
                m -= 1
        e = st
        while True:
            li = e // 2
            seen[li] = True
            size = lo[li + 1] - lo[li]
            buf = _reserve(buf, m, size)
            if e % 2 == 0:
                buf[m:m + size] = pts[lo[li]:lo[li + 1]]
            else:
                buf[m:m + size] = pts[lo[li]:lo[li + 1]][::-1]
            m += size
            other = e ^ 1
            c = code[other]
            r = ring[other]
            if c < 0:
                tail[nc] = other
                if hook[other] != 0.0:
                    s = ring_start[r]
                    buf, m = _walk(buf, m, a, b, rparam, seg_len, s, ring_start[r + 1] - s, ring_len[r],
                                   param[other], param[other] + hook[other], hook[other] > 0)
                break
            to = c // 2
            s = ring_start[r]
            buf, m = _walk(buf, m, a, b, rparam, seg_len, s, ring_start[r + 1] - s, ring_len[r],
                           param[other], param[to], c % 2 == 1)
            nl = lo[to // 2] if to % 2 == 0 else lo[to // 2 + 1] - 1  # the next line's first point
            if abs(buf[m - 1, 0] - pts[nl, 0]) + abs(buf[m - 1, 1] - pts[nl, 1]) <= 1e-9:
                m -= 1  # the stretch ends on it
            e = to
        nc += 1
    off[nc] = m
    return buf[:m], off[:nc + 1], head[:nc], tail[:nc]


@numba.njit(cache=True)
def _reordered(pts, off, chosen, rev):
    """The polylines ``pts[off[k]:off[k + 1]]`` for k in ``chosen``, reversed where ``rev``,
    packed again: (points, offsets)."""
    out = np.empty_like(pts)
    lo = np.zeros(chosen.shape[0] + 1, np.int64)
    m = 0
    for j in range(chosen.shape[0]):
        k = chosen[j]
        size = off[k + 1] - off[k]
        for i in range(size):
            src = off[k + 1] - 1 - i if rev[j] else off[k] + i
            out[m + i, 0] = pts[src, 0]
            out[m + i, 1] = pts[src, 1]
        m += size
        lo[j + 1] = m
    return out[:m], lo


@numba.njit(cache=True)
def _span(lo, hi, alpha, beta):
    """The interval of t where lo <= alpha + beta * t <= hi: (t0, t1), empty when t0 > t1."""
    if abs(beta) < 1e-15:
        if lo <= alpha <= hi:
            return -np.inf, np.inf
        return np.inf, -np.inf
    t0, t1 = (lo - alpha) / beta, (hi - alpha) / beta
    return (t0, t1) if t0 <= t1 else (t1, t0)


@numba.njit(cache=True)
def _near_span(ex, ey, ux, uy, length, ax, ay, vx, vy, ls, reach):
    """The stretch (t0, t1) of the edge ``(ex, ey) + t (ux, uy)``, 0 <= t <= ``length``, within
    ``reach`` of the segment from ``(ax, ay)`` along the unit ``(vx, vy)`` for ``ls``: the edge's
    line cut by the segment's capsule (two discs and the rectangle between them); empty when
    t0 > t1."""
    t0, t1 = np.inf, -np.inf
    for k in range(2):
        px, py = (ax, ay) if k == 0 else (ax + ls * vx, ay + ls * vy)
        wx, wy = px - ex, py - ey
        along = wx * ux + wy * uy
        perp = wx * uy - wy * ux
        h = reach * reach - perp * perp
        if h >= 0.0:
            r = math.sqrt(h)
            t0, t1 = min(t0, along - r), max(t1, along + r)
    s0, s1 = _span(0.0, ls, (ex - ax) * vx + (ey - ay) * vy, ux * vx + uy * vy)
    n0, n1 = _span(-reach, reach, (ex - ax) * -vy + (ey - ay) * vx, ux * -vy + uy * vx)
    lo, hi = max(s0, n0), min(s1, n1)
    if lo <= hi:
        t0, t1 = min(t0, lo), max(t1, hi)
    return max(t0, 0.0), min(t1, length)


@numba.njit(cache=True)
def _blocked(sa, sb, ra, rb, rparam, rlen, ring_of, ring_start, ring_len, key, big, counts, offset,
             x0, y0, cell, nx, ny, start, ids, tol):
    """Which ring samples lie within ``tol`` of a segment ``sa -> sb``: (samples,) bool, ring
    ``r``'s ``counts[r]`` samples (evenly spaced by arc length from its first vertex) at
    ``offset[r]:offset[r + 1]``.

    The same points and the same distance test as sampling every ring (``RingSet.points_at``)
    and asking an :class:`~cooprint.slicing.rings.EdgeSet` of the segments for each sample, but
    only the samples near a segment are looked at: every segment walks the rings' grid (``x0``
    .. ``ids``, :attr:`RingSet.grid`) for the edges within reach, and only the samples on the
    stretch of each such edge near the segment are tested (the infill lines cross the rings far
    more often than they run along them)."""
    eps = 1e-6  # the candidate stretches are widened by this much, mm: rounding never drops a sample
    reach = tol + eps
    out = np.zeros(offset[-1], np.bool_)
    seen = np.full(ra.shape[0], -1, np.int64)
    # the segment is walked in samples half a cell apart and every edge is registered in the
    # 3 x 3 cells around its own such samples: an edge within reach of the segment lies in a cell
    # within 1 + more of a sample's when reach + cell / 2 < (1 + more) cell
    more = int(reach / cell + 0.5)
    for s in range(sa.shape[0]):
        ax, ay = sa[s, 0], sa[s, 1]
        dx, dy = sb[s, 0] - ax, sb[s, 1] - ay
        ls = math.sqrt(dx * dx + dy * dy)
        l2 = dx * dx + dy * dy
        vx, vy = dx / ls, dy / ls
        steps = int(ls / (0.5 * cell)) + 1
        lx, ly = -1 << 40, -1 << 40
        for j in range(steps + 1):
            f = j / steps
            cx = int(math.floor((ax + f * dx - x0) / cell))
            cy = int(math.floor((ay + f * dy - y0) / cell))
            if cx == lx and cy == ly:
                continue
            lx, ly = cx, cy
            for oy in range(max(cy - more, 0), min(cy + more + 1, ny)):
                for ox in range(max(cx - more, 0), min(cx + more + 1, nx)):
                    c = oy * nx + ox
                    for jj in range(start[c], start[c + 1]):
                        i = ids[jj]
                        if seen[i] == s:
                            continue
                        seen[i] = s
                        ex, ey = ra[i, 0], ra[i, 1]
                        fx, fy = rb[i, 0], rb[i, 1]
                        # far on one side of the segment's line, or beyond one of its ends
                        c0 = (ex - ax) * vy - (ey - ay) * vx
                        c1 = (fx - ax) * vy - (fy - ay) * vx
                        if (c0 > reach and c1 > reach) or (c0 < -reach and c1 < -reach):
                            continue
                        c0 = (ex - ax) * vx + (ey - ay) * vy
                        c1 = (fx - ax) * vx + (fy - ay) * vy
                        if (c0 > ls + reach and c1 > ls + reach) or (c0 < -reach and c1 < -reach):
                            continue
                        le = rlen[i]
                        if le > 0:
                            t0, t1 = _near_span(ex, ey, (fx - ex) / le, (fy - ey) / le, le,
                                                ax, ay, vx, vy, ls, reach)
                        else:
                            t0, t1 = _near_span(ex, ey, 1.0, 0.0, 0.0, ax, ay, vx, vy, ls, reach)
                        if t0 > t1:
                            continue
                        r = ring_of[i]
                        L = ring_len[r]
                        n = counts[r]
                        st = L / n
                        k0 = max(int(math.ceil((rparam[i] + t0 - eps) / st)), 0)
                        k1 = min(int(math.floor((rparam[i] + t1 + eps) / st)), n - 1)
                        for k in range(k0, k1 + 1):
                            g = offset[r] + k
                            if out[g]:
                                continue
                            # the sample's point as RingSet.points_at puts it
                            p = k * st
                            q = r * big + p
                            hi = ring_start[r + 1]
                            if key[i] <= q and (i + 1 == hi or key[i + 1] > q):
                                e = i  # mostly on the edge at hand: the search's answer, without it
                            else:
                                lo = ring_start[r]
                                while lo < hi:  # the first edge whose key exceeds q
                                    mid = (lo + hi) // 2
                                    if key[mid] <= q:
                                        lo = mid + 1
                                    else:
                                        hi = mid
                                e = lo - 1
                            t = (p - rparam[e]) / rlen[e] if rlen[e] > 0 else 0.0
                            px = ra[e, 0] + t * (rb[e, 0] - ra[e, 0])
                            py = ra[e, 1] + t * (rb[e, 1] - ra[e, 1])
                            # the distance as EdgeSet.nearest measures it
                            u = ((px - ax) * dx + (py - ay) * dy) / l2
                            u = min(max(u, 0.0), 1.0)
                            wx, wy = ax + u * dx - px, ay + u * dy - py
                            if math.sqrt(wx * wx + wy * wy) <= tol:
                                out[g] = True
    return out


@numba.njit(cache=True)
def _clear_parts(pts, lo, clear):
    """The parts of the lines ``pts[lo[i]:lo[i + 1]]`` farther than ``clear`` (along the line)
    from both its ends, segment by segment: (start (s, 2), end (s, 2))."""
    n = pts.shape[0]
    a = np.empty((max(n - 1, 0), 2))
    b = np.empty((max(n - 1, 0), 2))
    cum = np.zeros(n)  # arc length from the first point, over the joints between lines too
    for j in range(n - 1):
        cum[j + 1] = cum[j] + math.hypot(pts[j + 1, 0] - pts[j, 0], pts[j + 1, 1] - pts[j, 1])
    m = 0
    for li in range(lo.shape[0] - 1):
        first, last = lo[li], lo[li + 1] - 1
        total = cum[last] - cum[first]
        for j in range(first, last):
            seg = math.hypot(pts[j + 1, 0] - pts[j, 0], pts[j + 1, 1] - pts[j, 1])
            s0 = cum[j] - cum[first]
            start = max(s0, clear)
            stop = min(s0 + seg, total - clear)
            if not stop > start + 1e-9:
                continue
            for k in range(2):
                d = (pts[j + 1, k] - pts[j, k]) / seg
                a[m, k] = pts[j, k] + d * (start - s0)
                b[m, k] = pts[j, k] + d * (stop - s0)
            m += 1
    return a[:m], b[:m]


def chain_order(heads: np.ndarray, tails: np.ndarray, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Nearest-next order of polylines given their ends: (order (n,), reversed (n,) bool).

    From ``start``, repeatedly the polyline with the end nearest the current position, entered
    at that end (reversed when it is its tail)."""
    return _chain(np.ascontiguousarray(heads, dtype=np.float64), np.ascontiguousarray(tails, dtype=np.float64),
                  np.asarray(start, dtype=np.float64))


@numba.njit(cache=True)
def _chain(heads, tails, start):
    n = heads.shape[0]
    used = np.zeros(n, np.bool_)
    order = np.empty(n, np.int64)
    rev = np.zeros(n, np.bool_)
    px, py = start[0], start[1]
    for k in range(n):
        best, bd, br = -1, np.inf, False
        for i in range(n):
            if used[i]:
                continue
            d = (heads[i, 0] - px) ** 2 + (heads[i, 1] - py) ** 2
            if d < bd:
                best, bd, br = i, d, False
            d = (tails[i, 0] - px) ** 2 + (tails[i, 1] - py) ** 2
            if d < bd:
                best, bd, br = i, d, True
        used[best] = True
        order[k] = best
        rev[k] = br
        if br:
            px, py = heads[best, 0], heads[best, 1]
        else:
            px, py = tails[best, 0], tails[best, 1]
    return order, rev
