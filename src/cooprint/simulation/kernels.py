"""Compiled loops of the simulator's checks (numba, one core).

The checks are sweeps in time order and look-ups in rasters: sequential by nature, so they are
written as plain loops and compiled, instead of being forced into whole-array passes that would
each make a temporary of every sample. The tests (``tests/test_simulation.py``) hold each to a
plain definition: the rasters and the overhang test to brute force over every pair of points,
the footprint sweep to the per-sample checks.

Arrays: positions float32 (as the samples are kept), times float64. Large work arrays are
allocated by the callers with numpy, not here.
"""

from __future__ import annotations

import numba
import numpy as np

from cooprint import jit
from cooprint.program.commands import MOVE, TOOL_OFF, TOOL_ON

jit.setup()  # Ctrl-C held while numba compiles; LLVM calls untimed (cooprint.jit)

_jit = numba.njit(cache=True, nogil=True)
#: For the small helpers called per sample: inlined into their callers (a call would pass each
#: array with a reference count taken and dropped, which costs more than the helper's work).
_inline = numba.njit(cache=True, nogil=True, inline="always")


@_jit
def move_table(kind, xyz, start, started, index, p0, p1, on, length):
    """The MOVEs of a program (``kind`` (n,) uint8, targets ``xyz`` (n, 3)) written to ``index``
    (their command indices), ``p0`` and ``p1`` (start and end positions; the first starts at
    ``start`` if ``started``, else at its own target), ``on`` (they deposit: the tool on, as the
    TOOL commands before them leave it, and a length above 0) and ``length``."""
    tool = False
    j = 0
    for i in range(len(kind)):
        c = kind[i]
        if c == TOOL_ON:
            tool = True
        elif c == TOOL_OFF:
            tool = False
        elif c == MOVE:
            index[j] = i
            for a in range(3):
                p1[j, a] = xyz[i, a]
                if j > 0:
                    p0[j, a] = p1[j - 1, a]
                else:
                    p0[j, a] = start[a] if started else xyz[i, a]
            d0, d1, d2 = p1[j, 0] - p0[j, 0], p1[j, 1] - p0[j, 1], p1[j, 2] - p0[j, 2]
            length[j] = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            on[j] = tool and length[j] > 0
            j += 1


@_jit
def sample_counts(length, step):
    """(k,) how many samples each move of ``length`` gets: ``ceil(length / step)``, at least 1."""
    n = np.empty(len(length), np.int64)
    for i in range(len(length)):
        c = int(np.ceil(length[i] / step))
        n[i] = c if c > 1 else 1
    return n


@_inline
def _segment(p0, p1, m):
    """Move ``m``'s start and its step to the end, in float32 (as the samples are kept)."""
    a0, a1, a2 = np.float32(p0[m, 0]), np.float32(p0[m, 1]), np.float32(p0[m, 2])
    return a0, a1, a2, np.float32(p1[m, 0]) - a0, np.float32(p1[m, 1]) - a1, np.float32(p1[m, 2]) - a2


@_jit
def sample_moves(p0, p1, t0, t1, sel, n, first, xyz, t, move, value, out, k):
    """Points along moves ``sel`` (``n[j]`` points on move ``sel[j]``: the i-th of n at i / n
    of the way, its end included; with ``first`` the start of the first move before them),
    written to ``xyz`` (float32) and ``t`` from row ``k`` on, with the move of each to ``move``
    and a value of its move (``value[m]``) to ``out``, unless those are empty. Returns the next
    row."""
    if first:
        m = sel[0]
        for a in range(3):
            xyz[k, a] = np.float32(p0[m, a])
        t[k] = t0[m]
        if len(move):
            move[k] = m
        if len(out):
            out[k] = value[m]
        k += 1
    for j in range(len(sel)):
        m = sel[j]
        c = n[j]
        a0, a1, a2, d0, d1, d2 = _segment(p0, p1, m)
        dt = t1[m] - t0[m]
        inv = 1.0 / c
        for i in range(1, c + 1):
            f = i * inv
            f32 = np.float32(f)
            xyz[k, 0] = a0 + f32 * d0
            xyz[k, 1] = a1 + f32 * d1
            xyz[k, 2] = a2 + f32 * d2
            t[k] = t0[m] + f * dt
            if len(move):
                move[k] = m
            if len(out):
                out[k] = value[m]
            k += 1
    return k


@_inline
def _in_frame(x, y, frame):
    """``x, y`` (float32) in a robot's frame (rows of ``frame``: its facing and its left)."""
    return x * frame[0, 0] + y * frame[0, 1], x * frame[1, 0] + y * frame[1, 1]


@_jit
def bounds_in_frame(xyz, frame):
    """(2,), (2,) float32: the lowest and highest (u, v) of points ``xyz`` (k, 3) float32 in a
    robot's frame (zeros if there are none)."""
    lo = np.zeros(2, np.float32)
    hi = np.zeros(2, np.float32)
    for i in range(len(xyz)):
        u, v = _in_frame(xyz[i, 0], xyz[i, 1], frame)
        if i == 0 or u < lo[0]:
            lo[0] = u
        if i == 0 or v < lo[1]:
            lo[1] = v
        if i == 0 or u > hi[0]:
            hi[0] = u
        if i == 0 or v > hi[1]:
            hi[1] = v
    return lo, hi


@_inline
def _cell(x, y, frame, g, gi):
    """Row and column of the cell of a point at ``x, y`` on a raster in a robot's frame
    (``g, gi`` as :func:`_window` takes them): ``floor(((u, v) - lo) / cell)`` plus the padding."""
    u, v = _in_frame(x, y, frame)
    return int(np.floor((u - g[0]) / g[2])) + gi[0], int(np.floor((v - g[1]) / g[2])) + gi[1]


@_inline
def _window(u, v, g, gi):
    """Row and column of the low corner cell of the footprint of a nozzle at ``u, v`` on a raster
    ``g = (lo_u, lo_v, cell, off_u, off_v)`` (``off``: the footprint's corner relative to the
    nozzle), ``gi = (pad_u, pad_v, last_row, last_col, ...)``: clipped so the window lies in it."""
    a = int(np.floor((u + g[3] - g[0]) / g[2])) + gi[0]
    b = int(np.floor((v + g[4] - g[1]) / g[2])) + gi[1]
    return min(max(a, 0), gi[2]), min(max(b, 0), gi[3])


@_jit
def earliest(grid, xyz, t, frame, g, gi):
    """``grid[cell] = min(grid[cell], t)`` for every point ``xyz`` (k, 3) float32 laid down at
    ``t``, in its cell of the raster ``g, gi`` (:func:`_cell`)."""
    for i in range(len(t)):
        a, b = _cell(xyz[i, 0], xyz[i, 1], frame, g, gi)
        if t[i] < grid[a, b]:
            grid[a, b] = t[i]


@_jit
def _window_min_1d(a, out, w, tmp_pre, tmp_suf):
    """out[i] = min(a[i:i + w]) (van Herk / Gil-Werman: prefix and suffix minima in blocks of w)."""
    n = len(a)
    for s in range(0, n, w):
        e = min(s + w, n)
        tmp_pre[s] = a[s]
        for i in range(s + 1, e):
            tmp_pre[i] = min(tmp_pre[i - 1], a[i])
        tmp_suf[e - 1] = a[e - 1]
        for i in range(e - 2, s - 1, -1):
            tmp_suf[i] = min(tmp_suf[i + 1], a[i])
    for i in range(n - w + 1):
        out[i] = min(tmp_suf[i], tmp_pre[i + w - 1])


@_jit
def window_min(a, w0, w1):
    """(n0 - w0 + 1, n1 - w1 + 1): the minimum of ``a`` over every w0 x w1 window (out[i, j] covers
    a[i:i + w0, j:j + w1])."""
    n0, n1 = a.shape
    m0, m1 = n0 - w0 + 1, n1 - w1 + 1
    rows = np.empty((n0, m1), a.dtype)
    pre = np.empty(max(n0, n1), a.dtype)
    suf = np.empty(max(n0, n1), a.dtype)
    for i in range(n0):
        _window_min_1d(a[i], rows[i], w1, pre, suf)
    out = np.empty((m0, m1), a.dtype)
    col = np.empty(n0, a.dtype)
    res = np.empty(m0, a.dtype)
    for j in range(m1):
        for i in range(n0):
            col[i] = rows[i, j]
        _window_min_1d(col, res, w0, pre, suf)
        for i in range(m0):
            out[i, j] = res[i]
    return out


@_inline
def _reaches(high, coarse, block, r0, c0, win0, win1, level):
    """Whether a cell of the ``win0`` x ``win1`` window from ``r0, c0`` holds material higher
    than ``level`` (``high``, ``coarse`` as :func:`head_hits` keeps them): big block by big block,
    block by block only in big blocks that reach above ``level``, cell by cell only in blocks
    that reach above it and straddle the window's edge."""
    r1, c1 = r0 + win0 - 1, c0 + win1 - 1
    big = block * block
    for gr in range(r0 // big, r1 // big + 1):
        for gc in range(c0 // big, c1 // big + 1):
            if coarse[1, gr, gc] <= level:
                continue
            for br in range(max(r0, gr * big) // block, min(r1, gr * big + big - 1) // block + 1):
                a0, a1 = max(br * block, r0), min(br * block + block - 1, r1)
                for bc in range(max(c0, gc * big) // block, min(c1, gc * big + big - 1) // block + 1):
                    if coarse[0, br, bc] <= level:
                        continue
                    b0, b1 = max(bc * block, c0), min(bc * block + block - 1, c1)
                    if a1 - a0 == block - 1 and b1 - b0 == block - 1:
                        return True  # the whole block lies in the window
                    for rr in range(a0, a1 + 1):
                        for cc in range(b0, b1 + 1):
                            if high[rr, cc] > level:
                                return True
    return False


@_jit
def reachable(m_t, m_z, bounds, t1, z_low, lift, out):
    """Which material points can ever reach a robot's printhead: higher by more than ``lift``
    than the lowest the robot's nozzle goes after the point is laid down (its moves end at
    ``t1`` and go no lower than ``z_low``). Robot ``j``'s points ``bounds[j]:bounds[j + 1]`` are
    in time order. The others can never be above the printhead when it passes. Writes ``out``
    (k,) bool."""
    k = len(t1)
    low = np.empty(k + 1)
    low[k] = np.inf
    for i in range(k - 1, -1, -1):  # the lowest from each move on
        low[i] = min(low[i + 1], z_low[i])
    for j in range(len(bounds) - 1):
        i = 0
        for p in range(bounds[j], bounds[j + 1]):
            while i < k and t1[i] <= m_t[p]:  # the moves that end before: none of their samples comes after
                i += 1
            out[p] = m_z[p] > low[i] + lift


@_jit
def body_hits(first, g, gi, uv, t):
    """Indices of the nozzle samples (``uv`` (k, 2) in the robot's frame, times ``t``) whose body
    window (raster ``g, gi`` of :func:`_window`) holds material laid down before: ``first``
    is the earliest time over each window."""
    hit = np.empty(len(t), np.int64)
    k = 0
    for i in range(len(t)):
        r, c = _window(uv[i, 0], uv[i, 1], g, gi)
        if first[r, c] < t[i]:
            hit[k] = i
            k += 1
    return hit[:k]


@_jit
def head_hits(high, coarse, block, m_xyz, m_t, keep, frame, stops, added, top, g, gi, lift, uv, z, t):
    """Indices of the nozzle samples (``uv`` (k, 2) in the robot's frame, heights ``z``, times
    ``t``; in time order, and after those of earlier calls) whose printhead window (raster
    ``g, gi``; ``gi[4:6]`` its size in cells) holds material laid down before that is higher than
    the nozzle by more than ``lift``.

    Before each sample, the material laid down before its time is added to ``high`` (the highest
    in each cell), ``coarse[0]`` (over blocks of ``block`` x ``block`` cells), ``coarse[1]`` (over
    blocks of those) and ``top`` (the highest of all): robot ``j``'s points ``added[j]:stops[j]``
    of ``m_xyz`` (in time order; those with ``keep``), in their cells in the robot's ``frame``;
    ``added`` says how far each robot's points are in. All of these are updated in place.
    """
    hit = np.empty(len(t), np.int64)
    k = 0
    big = block * block
    for i in range(len(t)):
        for j in range(len(added)):  # the material laid down before this sample
            p = added[j]
            e = stops[j]
            while p < e and m_t[p] < t[i]:
                if keep[p]:
                    zm = m_xyz[p, 2]
                    r, c = _cell(m_xyz[p, 0], m_xyz[p, 1], frame, g, gi)
                    if zm > high[r, c]:
                        high[r, c] = zm
                        if zm > coarse[0, r // block, c // block]:
                            coarse[0, r // block, c // block] = zm
                            if zm > coarse[1, r // big, c // big]:
                                coarse[1, r // big, c // big] = zm
                                if zm > top[0]:
                                    top[0] = zm
                p += 1
            added[j] = p
        level = z[i] + lift
        if top[0] <= level:
            continue
        r, c = _window(uv[i, 0], uv[i, 1], g, gi)
        if _reaches(high, coarse, block, r, c, gi[4], gi[5], level):
            hit[k] = i
            k += 1
    return hit[:k]


@_jit
def footprint_sweep(p0, p1, t0, t1, n, first, chunk, frame, body, body_state, head, head_state, count, when, where):
    """Both footprint checks along a robot's whole path, sampled by :func:`sample_moves`
    (``n[m]`` points on move ``m``; ``first``: the start too) a few thousand samples at a time,
    without keeping them. ``body_state`` is what :func:`body_hits` takes before the samples,
    ``head_state`` what :func:`head_hits` takes. A hit of check ``k`` (0: body, 1: printhead)
    on a move of chunk ``chunk[m]`` adds one to ``count[k, chunk]``; the first one of each chunk
    leaves its time in ``when`` and its position in ``where``."""
    size = max(4096, int(n.max()) + 1) if len(n) else 1  # samples at a time; a move's all fit
    xyz = np.empty((size, 3), np.float32)
    uv = np.empty((size, 2), np.float32)
    t = np.empty(size)
    move = np.empty(size, np.int64)
    no_values = np.zeros(0)
    m0 = 0
    while m0 < len(t0):  # the moves whose samples fit in the buffer, then the checks on them
        start = first and m0 == 0
        m1, k = m0, int(start)
        while m1 < len(t0) and k + n[m1] <= size:
            k += n[m1]
            m1 += 1
        k = sample_moves(p0, p1, t0, t1, np.arange(m0, m1), n[m0:m1], start, xyz, t, move, no_values, no_values, 0)
        for j in range(k):
            uv[j, 0], uv[j, 1] = _in_frame(xyz[j, 0], xyz[j, 1], frame)
        for check in range(2):
            if check == 0 and body:
                hits = body_hits(body_state[0], body_state[1], body_state[2], uv[:k], t[:k])
            elif check == 1 and head:
                hits = head_hits(*head_state, uv[:k], xyz[:k, 2], t[:k])
            else:
                continue
            for h in hits:
                ch = chunk[move[h]]
                count[check, ch] += 1
                if count[check, ch] == 1:
                    when[check, ch] = t[h]
                    for a in range(3):
                        where[check, ch, a] = xyz[h, a]
        m0 = m1


@_inline
def _band(z, h):
    """The heights (micrometres) in which a point at ``z`` (micrometres) of layer height ``h``
    (mm) looks for material below it: from 2.5 to 0.5 layer heights lower."""
    return int(max(np.rint(z - 2500.0 * h), 0.0)), int(max(np.rint(z - 500.0 * h), -1.0))


@_inline
def _band_has_support(heights, a, e, lo, hi, t):
    """Whether a height ``z`` of ``heights[a:e]`` (sorted, distinct) lies in ``[lo, hi]`` with an
    earliest time ``t`` before ``t``."""
    end = e
    while a < e:  # the first height >= lo
        m = (a + e) >> 1
        if heights[m].z < lo:
            a = m + 1
        else:
            e = m
    while a < end and heights[a].z <= hi:
        if heights[a].t < t:
            return True
        a += 1
    return False


#: Work records of :func:`overhang_band`: a point (height in micrometres above the lowest point,
#: layer height, time, index) and a distinct height of a cell (and its earliest time).
OVERHANG_POINT = np.dtype([("z", "<i4"), ("h", "<f4"), ("t", "<f8"), ("p", "<i4")])
OVERHANG_HEIGHT = np.dtype([("z", "<i4"), ("t", "<f8")])


@_inline
def _column(x, cell, ox, x0):
    return int(np.floor((x - x0) / cell)) - ox


@_jit
def overhang_grid(xyz, cell, x0, y0):
    """The cells of the overhang test (squares of ``cell`` from ``x0, y0``): ``ox, oy`` (the
    first cell, 2 below the lowest so that the 24 around each point exist), ``nx, ny`` (how
    many), ``zmin`` (the lowest height) and how many points lie in each column of cells (nx,)."""
    mx, my, zmin, top_x, top_y = np.inf, np.inf, np.inf, -np.inf, -np.inf
    for i in range(len(xyz)):
        fx, fy = np.floor((xyz[i, 0] - x0) / cell), np.floor((xyz[i, 1] - y0) / cell)
        mx, my, top_x, top_y = min(mx, fx), min(my, fy), max(top_x, fx), max(top_y, fy)
        zmin = min(zmin, float(xyz[i, 2]))
    ox, oy = int(mx) - 2, int(my) - 2
    nx, ny = int(top_x) - ox + 3, int(top_y) - oy + 3
    columns = np.zeros(nx, np.int64)
    for i in range(len(xyz)):
        columns[_column(xyz[i, 0], cell, ox, x0)] += 1
    return ox, oy, nx, ny, zmin, columns


@_jit
def overhang_cells(xyz, cell, ox, oy, ny, x0, y0):
    """(k,) int32: the cell of each point (``column * ny + row`` of :func:`overhang_grid`'s
    cells), computed once so that each band of :func:`overhang_band` finds its points by one
    comparison instead of two divisions per point and band."""
    out = np.empty(len(xyz), np.int32)
    for i in range(len(xyz)):
        out[i] = _column(xyz[i, 0], cell, ox, x0) * ny + int(np.floor((xyz[i, 1] - y0) / cell)) - oy
    return out


@_inline
def _by_height(rec, a, b, order, spare, runs):
    """Indices ``a:b`` of ``rec`` in order of height (``rec.z``; equal heights in any order), in
    ``order`` or ``spare`` (work space of at least ``b - a``; ``runs`` one more), returned. A
    cell's points come as a few runs already in order (a robot's layers, one chunk after the
    other, then the next robot's), so the runs are found and merged pairwise (a natural merge
    sort): linear when the points are in order, ``n log(runs)`` otherwise."""
    n = b - a
    nr = 0
    runs[0] = 0
    for i in range(n):
        order[i] = a + i
        if i > 0 and rec[a + i].z < rec[a + i - 1].z:
            nr += 1
            runs[nr] = i
    nr += 1
    runs[nr] = n
    src, dst = order, spare
    while nr > 1:
        m = 0
        for q in range(0, nr, 2):  # runs q and q + 1 into one
            lo, mid = runs[q], runs[q + 1]
            hi = runs[q + 2] if q + 2 <= nr else mid
            i, j, out = lo, mid, lo
            while i < mid and j < hi:
                if rec[src[j]].z < rec[src[i]].z:
                    dst[out] = src[j]
                    j += 1
                else:
                    dst[out] = src[i]
                    i += 1
                out += 1
            while i < mid:
                dst[out] = src[i]
                i += 1
                out += 1
            while j < hi:
                dst[out] = src[j]
                j += 1
                out += 1
            runs[m] = lo
            m += 1
        runs[m] = n
        nr = m
        src, dst = dst, src
    return src[:n]


@_jit
def overhang_band(xyz, h, t, cellid, ny, zmin, x0, x1, rec, heights, out):
    """The overhang test of the points in the columns of cells ``x0:x1`` (of
    :func:`overhang_grid`'s cells): ``out[i]`` is set when point ``i`` (``xyz`` (k, 3) float32 mm,
    its layer height ``h``, its time ``t``) has nothing below it: no point laid down before it
    whose height lies between 2.5 and 0.5 of its layer height below it (heights in whole
    micrometres above the lowest point ``zmin``), in its own square cell of ``cell`` mm or the 24
    cells around; and it is not on the floor (at most 2.5 layer heights above the lowest point).

    The points of the columns ``x0 - 2:x1 + 2`` are put in order cell by cell (a counting sort)
    in ``rec`` (:data:`OVERHANG_POINT`, at least as many); in each cell the distinct heights,
    lowest first, keep the earliest time material was at them (``heights``,
    :data:`OVERHANG_HEIGHT`). A point looks in its own cell first, while that cell is at hand
    (its points lowest first, the band's start found by a pointer that follows them), then in
    the 24 around (by bisection). Each point's cell comes from :func:`overhang_cells` (``cellid``:
    ``column * ny + row``), so a band picks its points with one comparison each.
    """
    lo_x, hi_x = x0 - 2, x1 + 2  # with the columns around
    cells = (hi_x - lo_x) * ny
    base = lo_x * ny  # the band's cells are cellid base:base + cells
    start = np.zeros(cells + 1, np.int64)  # counting sort by cell
    for i in range(len(cellid)):
        c = cellid[i] - base
        if 0 <= c < cells:
            start[c + 1] += 1
    for c in range(cells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    for i in range(len(cellid)):  # each point to its place, in one record (one stream of writes per cell)
        c = cellid[i] - base
        if 0 <= c < cells:
            j = fill[c]
            fill[c] += 1
            rec[j].z, rec[j].t, rec[j].h, rec[j].p = int(np.rint((xyz[i, 2] - zmin) * 1000.0)), t[i], h[i], i
    zmin_um = np.rint(zmin * 1000.0)
    first = np.zeros(cells + 1, np.int64)  # each cell's distinct heights: heights[first[c]:first[c + 1]]
    todo = np.zeros(start[cells], np.bool_)
    most = 0
    for c in range(cells):
        most = max(most, start[c + 1] - start[c])
    order, spare, runs = np.empty(most, np.int64), np.empty(most, np.int64), np.empty(most + 1, np.int64)
    k = 0
    for c in range(cells):
        first[c] = k
        a, b = start[c], start[c + 1]
        if a == b:
            continue
        o = _by_height(rec, a, b, order, spare, runs)
        for j in o:
            if k > first[c] and heights[k - 1].z == rec[j].z:
                heights[k - 1].t = min(heights[k - 1].t, rec[j].t)
            else:
                heights[k].z, heights[k].t = rec[j].z, rec[j].t
                k += 1
        if not (2 <= c // ny < hi_x - lo_x - 2):
            continue  # a column around: its points are tested in their own band
        p = first[c]  # the own cell, lowest first: a pointer to the lowest height in the band
        for j in o:
            z, tj, hj = rec[j].z, rec[j].t, rec[j].h
            if z + zmin_um <= np.rint(2500.0 * hj) + 1:
                continue  # on the floor, or one layer of air above it
            lo, hi = _band(z, hj)
            while p > first[c] and heights[p - 1].z >= lo:
                p -= 1
            while p < k and heights[p].z < lo:
                p += 1
            q = p
            found = False
            while q < k and heights[q].z <= hi:
                if heights[q].t < tj:
                    found = True
                    break
                q += 1
            todo[j] = not found
    first[cells] = k
    for c in range(cells):  # the 24 cells around
        for j in range(start[c], start[c + 1]):
            if not todo[j]:
                continue
            lo, hi = _band(rec[j].z, rec[j].h)
            found = False
            for q in range(25):
                if q == 12:
                    continue  # the own cell
                d = c + (q // 5 - 2) * ny + q % 5 - 2
                if _band_has_support(heights, first[d], first[d + 1], lo, hi, rec[j].t):
                    found = True
                    break
            out[rec[j].p] = not found


#: The most cells one band of :func:`overhang_flags` may have (two int64 per cell: 128 MB).
OVERHANG_MAX_CELLS = 1 << 23


def overhang_flags(xyz: np.ndarray, h: np.ndarray, t: np.ndarray, cell: float, budget: int = 1 << 21,
                   max_cells: int = OVERHANG_MAX_CELLS, origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """(k,) bool: :func:`overhang_band`'s test of every point, band by band of columns of cells
    with at most about ``budget`` points each (and the two columns on each side), so that the
    work space stays small whatever the print's size.

    A plan spread over a very large area (a program that jumps a kilometre) would need bands of
    more than ``max_cells`` cells: then each band holds only its own points, with its own rows
    (from its lowest to its highest point), and a band still too large is split in two, so that
    the cells and the work stay proportional to the points, not to the area.

    The cells are squares of ``cell`` from ``origin`` (x, y, mm): the simulator puts it at the
    material's lowest corner, so that the same material laid anywhere gets the same cells and
    the same flags (a model sliced for a printer's bed and planned for a robot on the floor)."""
    out = np.zeros(len(t), dtype=bool)
    if len(t) == 0:
        return out
    x0, y0 = origin
    ox, oy, nx, ny, zmin, columns = overhang_grid(xyz, cell, x0, y0)
    if (nx + 4) * ny > max_cells:
        _overhang_sparse(xyz, h, t, cell, ox, zmin, budget, max_cells, out, x0, y0)
        return out
    counts = np.cumsum(columns)
    cuts = [0]
    while cuts[-1] < nx:  # at least one column a band
        cuts.append(max(cuts[-1] + 1, int(np.searchsorted(counts, counts[cuts[-1]] - columns[cuts[-1]] + budget,
                                                          side="right"))))
    cuts[-1] = nx
    most = max(int(columns[max(a - 2, 0):b + 2].sum()) for a, b in zip(cuts[:-1], cuts[1:]))
    rec, heights = np.empty(most, OVERHANG_POINT), np.empty(most, OVERHANG_HEIGHT)
    cellid = overhang_cells(xyz, cell, ox, oy, ny, x0, y0)
    for a, b in zip(cuts[:-1], cuts[1:]):
        overhang_band(xyz, h, t, cellid, ny, zmin, a, b, rec, heights, out)
    return out


def _overhang_sparse(xyz, h, t, cell, ox, zmin, budget, max_cells, out, x0, y0) -> None:
    """:func:`overhang_flags` over a very large area: bands of columns, each given only the
    points of its columns and the two on each side (in their order, so times keep their order).

    The kernel only asks which cell a point is in, and which cells lie within two of each other;
    so a band's rows are renumbered with every gap of more than two empty rows closed to three
    (neighbours within two rows stay so, points farther apart stay farther), and its points are
    handed over at the centres of their renumbered cells, with cells of 1: the cells a band needs
    go with its points, not with the area. A band of too many cells or points is split in two."""
    col = (np.floor((xyz[:, 0].astype(np.float64) - x0) / cell) - ox).astype(np.int64)  # as _column computes it
    row = np.floor((xyz[:, 1].astype(np.float64) - y0) / cell)
    order = np.argsort(col, kind="stable")
    sorted_col = col[order]
    todo = [(int(sorted_col[0]), int(sorted_col[-1]) + 1)]
    while todo:
        a, b = todo.pop()
        lo, hi = np.searchsorted(sorted_col, [a, b])
        if lo == hi:
            continue  # no point of its own
        first, last = np.searchsorted(sorted_col, [a - 2, b + 2])
        idx = order[first:last]
        rows, inverse = np.unique(row[idx], return_inverse=True)
        renumbered = np.concatenate([[0.0], np.cumsum(np.minimum(np.diff(rows), 3.0))])
        ny = int(renumbered[-1]) + 5  # two empty rows on each side
        if b - a > 1 and ((b - a + 4) * ny > min(max_cells, 64 * len(idx) + 4096) or len(idx) > budget):
            m = (a + b) // 2
            todo += [(a, m), (m, b)]
            continue
        in_order = np.argsort(idx)  # the points in their order (times in order), once the band is kept
        idx = idx[in_order]
        local = np.empty((len(idx), 3), np.float32)
        local[:, 0] = col[idx] - (a - 2) + 0.5  # columns from 0 (two before the band's first)
        local[:, 1] = renumbered[inverse.ravel()[in_order]] + 0.5
        local[:, 2] = xyz[idx, 2]
        sub = np.zeros(len(idx), dtype=bool)
        overhang_band(local, h[idx], t[idx], overhang_cells(local, 1.0, 0, -2, ny, 0.0, 0.0), ny, zmin, 2, b - a + 2,
                      np.empty(len(idx), OVERHANG_POINT), np.empty(len(idx), OVERHANG_HEIGHT), sub)
        out[idx] |= sub


@_jit
def outlines_overlap(pa, pb, axes, lo, hi):
    """(T,) int32: which parts of two robots' outlines overlap at each instant, a bit per pair of
    parts (bit ``p`` for the pair of row ``p`` of ``lo``, ``hi``, at most 31 pairs); 0: the
    outlines are apart.

    Every part of a robot is a rectangle in its frame, so all the parts of robot a share two edge
    directions, and all of b's two others: ``axes`` (4, 2) are the four unit normals (a's facing,
    its left, b's facing, its left), the only axes that can separate two of these rectangles
    (separating axis theorem). Two parts overlap iff on every axis ``k`` the nozzles' offset
    ``d = pb[i] - pa[i]`` projects strictly inside ``(lo[p, k], hi[p, k])`` (their Minkowski
    difference, precomputed by the caller): per instant four dot products, and a first test
    against the union of the pairs' intervals rejects robots far apart at once."""
    n_pairs = lo.shape[0]
    out = np.zeros(len(pa), np.int32)
    ulo = np.full(4, np.inf)
    uhi = np.full(4, -np.inf)
    for p in range(n_pairs):
        for k in range(4):
            ulo[k] = min(ulo[k], lo[p, k])
            uhi[k] = max(uhi[k], hi[p, k])
    a0, a1, a2, a3 = axes[0], axes[1], axes[2], axes[3]
    for i in range(len(pa)):
        dx, dy = pb[i, 0] - pa[i, 0], pb[i, 1] - pa[i, 1]
        s0 = dx * a0[0] + dy * a0[1]
        if not ulo[0] < s0 < uhi[0]:
            continue
        s1 = dx * a1[0] + dy * a1[1]
        if not ulo[1] < s1 < uhi[1]:
            continue
        s2 = dx * a2[0] + dy * a2[1]
        if not ulo[2] < s2 < uhi[2]:
            continue
        s3 = dx * a3[0] + dy * a3[1]
        if not ulo[3] < s3 < uhi[3]:
            continue
        mask = 0
        for p in range(n_pairs):
            if (lo[p, 0] < s0 < hi[p, 0] and lo[p, 1] < s1 < hi[p, 1] and lo[p, 2] < s2 < hi[p, 2]
                    and lo[p, 3] < s3 < hi[p, 3]):
                mask |= 1 << p
        out[i] = mask
    return out


@_jit
def positions_at(t0, t1, p0, p1, times):
    """(T, 2) XY of the nozzle at sorted ``times`` (a pointer walks the moves)."""
    out = np.empty((len(times), 2))
    n = len(t1)
    k = 0
    for i in range(len(times)):
        tt = times[i]
        while k < n - 1 and t1[k] < tt:
            k += 1
        span = t1[k] - t0[k]
        f = 1.0
        if span > 0:
            f = (tt - t0[k]) / span
            f = min(max(f, 0.0), 1.0)
        out[i, 0] = p0[k, 0] + f * (p1[k, 0] - p0[k, 0])
        out[i, 1] = p0[k, 1] + f * (p1[k, 1] - p0[k, 1])
    return out


# ----------------------------------------------------------------------------------------------
# outside-part: material points against the sections of the chunks


@_inline
def _grow(a, n):
    """``a``, or a copy twice as long when it holds fewer than ``n`` items."""
    if len(a) >= n:
        return a
    b = np.empty(max(n, 2 * len(a)), a.dtype)
    b[:len(a)] = a
    return b


@_jit
def height_runs(z, h, cuts, capacity):
    """Cut one robot's material points (heights ``z``, layer heights ``h``, in the order laid
    down) into runs of one test height, the layer's middle ``z - h / 2`` as a key in 0.1 µm, and
    also before each of the sorted point indices ``cuts`` (where a chunk begins). Returns each
    run's first point and key (arrays of ``capacity`` to start with, grown when more runs come)."""
    start = np.empty(capacity, np.int64)
    key = np.empty(capacity, np.int64)
    r = -1
    c = 0
    last_z, last_h = np.float32(np.nan), np.float32(np.nan)
    k = np.int64(0)
    for i in range(len(z)):
        new = False
        if z[i] != last_z or h[i] != last_h:
            last_z, last_h = z[i], h[i]
            kk = np.int64(np.round((np.float64(z[i]) - 0.5 * np.float64(h[i])) * 1e4))
            new = kk != k or r < 0
            k = kk
        while c < len(cuts) and cuts[c] <= i:
            new = new or cuts[c] == i
            c += 1
        if new:
            r += 1
            if r == len(start):
                start, key = _grow(start, r + 1), _grow(key, r + 1)
            start[r] = i
            key[r] = k
    return start[:r + 1], key[:r + 1]


@_inline
def _cut_edge(vertices, i, j, h):
    """XY where the edge between vertices ``i`` and ``j`` (one above height ``h``, the other not)
    meets it, computed from the lower end: both triangles of the edge get the same point, also
    when each has its own copy of the corners (an STL's triangle soup)."""
    zi, zj = vertices[i, 2], vertices[j, 2]
    if zi > zj:
        i, j, zi, zj = j, i, zj, zi
    f = (h - zi) / (zj - zi)
    return (vertices[i, 0] + f * (vertices[j, 0] - vertices[i, 0]),
            vertices[i, 1] + f * (vertices[j, 1] - vertices[i, 1]))


@_jit
def section_counts(vertices, faces, heights):
    """(H,) how many triangles of a closed mesh each of the sorted ``heights`` crosses (a
    triangle crosses ``h`` when its lowest corner is at or below it and its highest above: a
    corner at ``h`` counts as below, as in :mod:`cooprint.slicing.sections`)."""
    diff = np.zeros(len(heights) + 1, np.int64)
    for f in range(len(faces)):
        z0, z1, z2 = vertices[faces[f, 0], 2], vertices[faces[f, 1], 2], vertices[faces[f, 2], 2]
        a = np.searchsorted(heights, min(z0, min(z1, z2)), side="left")
        b = np.searchsorted(heights, max(z0, max(z1, z2)), side="left")
        if b > a:
            diff[a] += 1
            diff[b] -= 1
    return np.cumsum(diff)[:-1]


@_jit
def section_segments(vertices, faces, heights, offsets, segs):
    """The sections of a closed mesh at sorted ``heights`` as segments ``segs[offsets[k]:
    offsets[k + 1]]`` (x0, y0, x1, y1) for height ``k`` (``offsets`` from :func:`section_counts`):
    each triangle that crosses a height gives the segment between the two edges that cross it.
    The segments of a section form its closed loops; their order and direction do not matter to
    the point test (:func:`inside_sections`)."""
    pos = offsets[:-1].copy()
    for f in range(len(faces)):
        v = faces[f]
        z0, z1, z2 = vertices[v[0], 2], vertices[v[1], 2], vertices[v[2], 2]
        a = np.searchsorted(heights, min(z0, min(z1, z2)), side="left")
        b = np.searchsorted(heights, max(z0, max(z1, z2)), side="left")
        for k in range(a, b):
            h = heights[k]
            above0, above1, above2 = z0 > h, z1 > h, z2 > h
            # the lone corner: the one above when one is, else the one at or below
            lone = 0
            if int(above0) + int(above1) + int(above2) == 1:
                lone = 0 if above0 else (1 if above1 else 2)
            else:
                lone = 0 if not above0 else (1 if not above1 else 2)
            p, q, r = v[lone], v[(lone + 1) % 3], v[(lone + 2) % 3]
            x0, y0 = _cut_edge(vertices, p, q, h)
            x1, y1 = _cut_edge(vertices, p, r, h)
            s = pos[k]
            segs[s, 0], segs[s, 1], segs[s, 2], segs[s, 3] = x0, y0, x1, y1
            pos[k] = s + 1


@_inline
def _across(ax, ay, bx, by, segs, e):
    """Whether the way from (ax, ay) to (bx, by) crosses segment ``e``: its ends on either side of
    the way's line (one strictly left, the other not: an end on the line counts once between the
    two segments that share it) and the way's ends strictly on either side of the segment's."""
    x0, y0, x1, y1 = segs[e, 0], segs[e, 1], segs[e, 2], segs[e, 3]
    dx, dy = bx - ax, by - ay
    s0 = dx * (y0 - ay) - dy * (x0 - ax)
    s1 = dx * (y1 - ay) - dy * (x1 - ax)
    if (s0 > 0) == (s1 > 0):
        return False
    ex, ey = x1 - x0, y1 - y0
    q0 = ex * (ay - y0) - ey * (ax - x0)
    q1 = ex * (by - y0) - ey * (bx - x0)
    return (q0 > 0 and q1 < 0) or (q0 < 0 and q1 > 0)


@_inline
def _near(px, py, segs, e, tol2):
    """Whether point (px, py) lies within ``sqrt(tol2)`` of segment ``e``."""
    x0, y0, x1, y1 = segs[e, 0], segs[e, 1], segs[e, 2], segs[e, 3]
    dx, dy = x1 - x0, y1 - y0
    ll = dx * dx + dy * dy
    f = 0.0
    if ll > 0:
        f = ((px - x0) * dx + (py - y0) * dy) / ll
        f = min(max(f, 0.0), 1.0)
    qx, qy = x0 + f * dx - px, y0 + f * dy - py
    return qx * qx + qy * qy <= tol2


#: Cells of a section's grid per segment (and at least this many more), and at most this many
#: in all.
_CELLS_PER_SEGMENT = 2
_MIN_CELLS = 16
_MAX_CELLS = 1 << 22


@_jit
def inside_sections(xyz, run_lo, run_hi, run_sec, run_tol, offsets, segs, ok):
    """``ok[i]``: point ``xyz[i]`` (XY) lies inside its section, or within the run's tolerance of
    its outline (a point on the outline is inside). Runs ``r`` are points ``run_lo[r]:run_hi[r]``
    tested against section ``run_sec[r]`` (segments ``segs[offsets[s]:offsets[s + 1]]``, closed
    loops: inside by the parity of the crossings of a ray), sorted by section; each section is
    prepared once for its runs, with the largest of their tolerances.

    The section gets a grid of about two cells per segment: each cell lists the segments that
    may come within the tolerance of it (each segment cut into pieces no longer than a cell, each
    piece's box grown by the tolerance), and knows whether its centre is inside (the crossings of
    the row's centre line, in order along it). A point in a cell that lists no segment is as
    inside as the cell's centre (nothing of the outline passes through the cell); in a cell that
    lists some, it is inside when one of them is within the tolerance, or else when the way from
    the centre to the point crosses the listed segments an odd number of times from a centre
    inside (even from one outside). So a point costs a look-up, and near the outline a few
    segments; a section costs a few passes over its segments and cells."""
    n_runs = len(run_lo)
    # work space reused from section to section (grown when a section needs more)
    last = np.empty(0, np.int64)
    cell_start = np.empty(0, np.int64)
    status = np.empty(0, np.bool_)
    pair_cell = np.empty(1024, np.int64)
    pair_seg = np.empty(1024, np.int64)
    items = np.empty(1024, np.int64)
    rows = np.empty(0, np.int64)
    row_items = np.empty(1024, np.int64)
    xs = np.empty(1024)
    i = 0
    while i < n_runs:
        s = run_sec[i]
        j = i
        tol = 0.0
        while j < n_runs and run_sec[j] == s:
            tol = max(tol, run_tol[j])
            j += 1
        a, b = offsets[s], offsets[s + 1]
        m = b - a
        if m == 0:  # nothing of the chunk at this height
            for r in range(i, j):
                for p in range(run_lo[r], run_hi[r]):
                    ok[p] = False
            i = j
            continue
        sg = segs[a:b]
        xmin, xmax, ymin, ymax = np.inf, -np.inf, np.inf, -np.inf
        for e in range(m):
            xmin = min(xmin, min(sg[e, 0], sg[e, 2]))
            xmax = max(xmax, max(sg[e, 0], sg[e, 2]))
            ymin = min(ymin, min(sg[e, 1], sg[e, 3]))
            ymax = max(ymax, max(sg[e, 1], sg[e, 3]))
        ox, oy = xmin - tol, ymin - tol
        wx, wy = xmax + tol - ox, ymax + tol - oy
        cells = min(_CELLS_PER_SEGMENT * m + _MIN_CELLS, _MAX_CELLS)
        cell = max(np.sqrt(wx * wy / cells), tol, 1e-3)
        nx, ny = int(wx / cell) + 1, int(wy / cell) + 1
        while nx * ny > _MAX_CELLS:
            cell *= 1.5
            nx, ny = int(wx / cell) + 1, int(wy / cell) + 1
        inv = 1.0 / cell
        nc = nx * ny
        last = _grow(last, nc)
        cell_start = _grow(cell_start, nc + 1)
        status = _grow(status, nc)
        rows = _grow(rows, ny + 1)
        last[:nc] = -1
        # (cell, segment) pairs: the cells each piece of a segment may reach within the tolerance
        n_pairs = 0
        for e in range(m):
            x0, y0, x1, y1 = sg[e, 0], sg[e, 1], sg[e, 2], sg[e, 3]
            reach = max(abs(x1 - x0), abs(y1 - y0))
            pieces = 1 if reach <= cell else int(reach * inv) + 1
            for k in range(pieces):
                fa, fb = k / pieces, (k + 1) / pieces
                ax, ay = x0 + fa * (x1 - x0), y0 + fa * (y1 - y0)
                bx, by = x0 + fb * (x1 - x0), y0 + fb * (y1 - y0)
                c0 = int((min(ax, bx) - tol - ox) * inv)
                c1 = min(nx - 1, int((max(ax, bx) + tol - ox) * inv))
                r0 = int((min(ay, by) - tol - oy) * inv)
                r1 = min(ny - 1, int((max(ay, by) + tol - oy) * inv))
                for row in range(max(r0, 0), r1 + 1):
                    for col in range(max(c0, 0), c1 + 1):
                        c = row * nx + col
                        if last[c] == e:  # listed by the segment's previous piece
                            continue
                        last[c] = e
                        if n_pairs == len(pair_cell):
                            pair_cell = _grow(pair_cell, n_pairs + 1)
                            pair_seg = _grow(pair_seg, n_pairs + 1)
                        pair_cell[n_pairs] = c
                        pair_seg[n_pairs] = e
                        n_pairs += 1
        # the pairs by cell (a counting sort): cell c lists items[cell_start[c]:cell_start[c + 1]]
        cell_start[:nc + 1] = 0
        for k in range(n_pairs):
            cell_start[pair_cell[k] + 1] += 1
        for c in range(nc):
            cell_start[c + 1] += cell_start[c]
        items = _grow(items, n_pairs)
        for k in range(n_pairs):
            c = pair_cell[k]
            items[cell_start[c]] = pair_seg[k]
            cell_start[c] += 1
        for c in range(nc, 0, -1):  # back to the starts
            cell_start[c] = cell_start[c - 1]
        cell_start[0] = 0
        # the segments that span some of each row's heights, then each cell's centre inside or not
        rows[:ny + 1] = 0
        for e in range(m):
            r0 = int((min(sg[e, 1], sg[e, 3]) - oy) * inv)
            r1 = min(int((max(sg[e, 1], sg[e, 3]) - oy) * inv), ny - 1)
            for row in range(r0, r1 + 1):
                rows[row + 1] += 1
        for row in range(ny):
            rows[row + 1] += rows[row]
        row_items = _grow(row_items, rows[ny])
        for e in range(m):
            r0 = int((min(sg[e, 1], sg[e, 3]) - oy) * inv)
            r1 = min(int((max(sg[e, 1], sg[e, 3]) - oy) * inv), ny - 1)
            for row in range(r0, r1 + 1):
                row_items[rows[row]] = e
                rows[row] += 1
        for row in range(ny, 0, -1):
            rows[row] = rows[row - 1]
        rows[0] = 0
        xs = _grow(xs, m)
        for row in range(ny):
            cy = oy + (row + 0.5) * cell
            k = 0
            for q in range(rows[row], rows[row + 1]):
                e = row_items[q]
                sy0, sy1 = sg[e, 1], sg[e, 3]
                if (sy0 > cy) != (sy1 > cy):
                    xs[k] = sg[e, 0] + (cy - sy0) * (sg[e, 2] - sg[e, 0]) / (sy1 - sy0)
                    k += 1
            xs[:k].sort()
            q = 0
            for col in range(nx):
                cx = ox + (col + 0.5) * cell
                while q < k and xs[q] < cx:
                    q += 1
                status[row * nx + col] = q % 2 == 1
        # the points
        tol2 = tol * tol
        for r in range(i, j):
            for p in range(run_lo[r], run_hi[r]):
                px, py = np.float64(xyz[p, 0]), np.float64(xyz[p, 1])
                fx, fy = (px - ox) * inv, (py - oy) * inv
                if fx < 0 or fy < 0 or fx >= nx or fy >= ny:
                    ok[p] = False  # beyond the section's box grown by the tolerance
                    continue
                col, row = int(fx), int(fy)
                c = row * nx + col
                inside = status[c]
                ca, cb = cell_start[c], cell_start[c + 1]
                if ca < cb:  # the outline passes near: within the tolerance, or across the way from the centre
                    cx, cy = ox + (col + 0.5) * cell, oy + (row + 0.5) * cell
                    for k in range(ca, cb):
                        e = items[k]
                        if _near(px, py, sg, e, tol2):
                            inside = True
                            break
                        if _across(cx, cy, px, py, sg, e):
                            inside = not inside
                ok[p] = inside
        i = j


@_jit
def path_extent(p0, p1, on, out):
    """The XY box of the moves with the tool on (``out[0:4]``: least x, y, greatest x, y; kept
    from earlier calls) and the sum of every move's X and Y extents (returned)."""
    walk = 0.0
    for m in range(len(p0)):
        walk += abs(p1[m, 0] - p0[m, 0]) + abs(p1[m, 1] - p0[m, 1])
        if on[m]:
            for a in range(2):
                lo, hi = min(p0[m, a], p1[m, a]), max(p0[m, a], p1[m, a])
                out[a] = min(out[a], lo)
                out[2 + a] = max(out[2 + a], hi)
    return walk


@_jit
def merge_by_time(t0, n, size, out_robot, out_k):
    """The next moves of several robots in time order: ``t0`` (R, size) holds each robot's next
    start times (its first ``n[r]`` are real, in order); the first ``size`` of all in order of
    start time (ties: the lower robot first) go to ``out_robot`` and ``out_k`` (the position in
    the robot's row). Returns how many were taken."""
    robots = len(n)
    cur = np.zeros(robots, np.int64)
    j = 0
    while j < size:
        best = -1
        for r in range(robots):
            if cur[r] < n[r] and (best < 0 or t0[r, cur[r]] < t0[best, cur[best]]):
                best = r
        if best < 0:
            break
        out_robot[j], out_k[j] = best, cur[best]
        cur[best] += 1
        j += 1
    return j


@_inline
def _clip(a, b, lo, hi, ta, tb):
    """The part [ta, tb] of the parameter range in which ``a + t * (b - a)`` lies in [lo, hi]."""
    d = b - a
    if d == 0.0:
        if a < lo or a > hi:
            return 1.0, 0.0
        return ta, tb
    s0, s1 = (lo - a) / d, (hi - a) / d
    if s0 > s1:
        s0, s1 = s1, s0
    return max(ta, s0), min(tb, s1)


#: Fields of a cell of the material height field (:func:`material_sweep`), float32 each: the top,
#: the robot, its path position, the bead's segment (ends relative to the field's origin).
TOP, WHO, POS, AX, AY, BX, BY = range(7)
FIELDS = 7
#: Path positions are kept modulo this many mm (float32 keeps them to 4 µm; a robot's own bead
#: laid a whole multiple of it earlier, to within two line widths, passes for its fresh one).
POS_PERIOD = 65536.0


@_inline
def _point_segment(px, py, ax, ay, bx, by):
    """Distance from the point ``p`` to the segment ``a b`` (XY)."""
    dx, dy = bx - ax, by - ay
    d2 = dx * dx + dy * dy
    f = ((px - ax) * dx + (py - ay) * dy) / d2 if d2 > 0 else 0.0
    f = min(max(f, 0.0), 1.0)
    ex, ey = ax + f * dx - px, ay + f * dy - py
    return np.sqrt(ex * ex + ey * ey)


@_inline
def _segments_apart(ax, ay, bx, by, cx, cy, dx, dy):
    """Distance between the segments ``a b`` and ``c d`` (XY): 0 when they cross, else the
    least from an end of one to the other."""
    d1 = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
    d2 = (bx - ax) * (dy - ay) - (by - ay) * (dx - ax)
    d3 = (dx - cx) * (ay - cy) - (dy - cy) * (ax - cx)
    d4 = (dx - cx) * (by - cy) - (dy - cy) * (bx - cx)
    if ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and d1 != 0 and d2 != 0 and d3 != 0 and d4 != 0:
        return 0.0
    return min(min(_point_segment(ax, ay, cx, cy, dx, dy), _point_segment(bx, by, cx, cy, dx, dy)),
               min(_point_segment(cx, cy, ax, ay, bx, by), _point_segment(dx, dy, ax, ay, bx, by)))


@_jit
def material_sweep(order_r, order_k, p0, p1, t0, t1, on, slot, h, w, dep, fresh, ox, oy, cell, col0, cells, near,
                   least, highest, run, run_cells, run_t, run_xyz, run_slot, count, when, where):
    """The nozzle of each move against the material laid down before, and its bead added, in
    time order: move ``order_k[i]`` of robot ``order_r[i]`` (the columns are (robots, moves,
    ...)). A sweep over a height field of cells ``cell`` mm square (origin ``ox, oy``; this band,
    ``cells`` (columns, rows, ``FIELDS``), holds columns ``col0`` on), each keeping the top of
    the material in it (``TOP``, -inf: none), the robot that laid it (``WHO``), how far along
    that robot's deposits (``POS``, mm modulo ``POS_PERIOD``) and that bead's segment (``AX, AY``
    to ``BX, BY``, relative to ``ox, oy``), so that distances to it are exact. One record per
    cell, so that a step to the next cell costs one memory line.

    A move walks the cells its axis passes through (a grid traversal: every cell the segment
    touches, in order, so two paths that cross share a cell); in each, the material there is
    checked, then a move with the tool on lays its bead there (its height, robot, path position
    and segment, unless higher material is there). Material of another robot, or of this one laid
    more than ``fresh[r, k]`` mm of its deposits before the move's start, counts: ``nozzle-in-material`` (check 0)
    when its top is more than half the move's layer height above the lowest the tip is in the
    cell and its segment is within half the move's width ``w`` of the nozzle's way through the
    cell; ``double-deposit`` (check 1) on a move with the tool on when its top is within half a
    layer height of the tip (the same layer) and its segment within ``near`` line widths of the
    middle of the nozzle's way through the cell, once such cells follow one another along the
    robot's path for more than ``least`` line widths (``run``: per robot, the doubled length so far, ``run_cells``
    its cells, ``run_t``, ``run_xyz``, ``run_slot`` where it began; a travel ends it). A hit adds
    to ``count[check, slot]``; the earliest of each slot leaves its time and place in ``when``
    and ``where``. ``highest[0]``: the top of all the material so far (a travel above it by more
    than the tolerance meets nothing and is not walked)."""
    ncol, ny = cells.shape[0], cells.shape[1]
    x_lo, x_hi = ox + col0 * cell, ox + (col0 + ncol) * cell
    y_lo, y_hi = oy, oy + ny * cell
    for i in range(len(order_r)):
        r, k = order_r[i], order_k[i]
        lay = on[r, k]
        if not lay:
            run[r] = 0.0
        ax, ay, az = p0[r, k, 0], p0[r, k, 1], p0[r, k, 2]
        bx, by, bz = p1[r, k, 0], p1[r, k, 1], p1[r, k, 2]
        ta, tb = _clip(ax, bx, x_lo, x_hi, 0.0, 1.0)
        ta, tb = _clip(ay, by, y_lo, y_hi, ta, tb)
        if ta > tb:
            continue
        tol = 0.5 * h[r, k]
        if not lay and min(az, bz) + tol >= highest[0]:
            continue
        length = np.sqrt((bx - ax) ** 2 + (by - ay) ** 2 + (bz - az) ** 2)
        ax_, ay_, bx_, by_ = ax - ox, ay - oy, bx - ox, by - oy  # the move's segment, from the origin
        fr = np.float32(r)
        dm = dep[r, k] % POS_PERIOD  # the path position at the move's start, modulo the period
        gx, gy = (ax - ox) / cell, (ay - oy) / cell
        dx, dy = (bx - ax) / cell, (by - ay) / cell
        ix = min(max(int(np.floor(gx + ta * dx)), col0), col0 + ncol - 1)
        iy = min(max(int(np.floor(gy + ta * dy)), 0), ny - 1)
        sx = 1 if dx > 0 else -1
        sy = 1 if dy > 0 else -1
        nx_t = ((ix + (1 if dx > 0 else 0)) - gx) / dx if dx != 0 else np.inf
        ny_t = ((iy + (1 if dy > 0 else 0)) - gy) / dy if dy != 0 else np.inf
        step_x = abs(1.0 / dx) if dx != 0 else np.inf
        step_y = abs(1.0 / dy) if dy != 0 else np.inf
        tc = ta
        while True:
            te = min(nx_t, ny_t, tb)
            ci = ix - col0
            high = cells[ci, iy, TOP]
            za, ze = az + tc * (bz - az), az + te * (bz - az)
            deep = high > min(za, ze) + tol  # above the tip, or (with the tool on) of its layer
            same = lay and not deep and high > 0.5 * (za + ze) - tol
            if deep or same:
                back = dm + tc * length - cells[ci, iy, POS]
                if back < 0:
                    back += POS_PERIOD
                elif back >= POS_PERIOD:
                    back -= POS_PERIOD
                if not (cells[ci, iy, WHO] == fr and back < fresh[r, k] + tc * length):
                    # the nozzle's way through this cell (its ends, its middle) against the bead's segment
                    qx, qy = cells[ci, iy, AX], cells[ci, iy, AY]
                    rx, ry = cells[ci, iy, BX], cells[ci, iy, BY]
                    ux, uy = ax_ + tc * (bx_ - ax_), ay_ + tc * (by_ - ay_)
                    vx, vy = ax_ + te * (bx_ - ax_), ay_ + te * (by_ - ay_)
                    apart = _segments_apart(ux, uy, vx, vy, qx, qy, rx, ry) if deep else np.inf
                    middle = _point_segment(0.5 * (ux + vx), 0.5 * (uy + vy), qx, qy, rx, ry) if same else np.inf
                    if deep and apart <= 0.5 * w[r, k]:
                        s = slot[r, k]
                        count[0, s] += 1
                        # where the tip goes in: a move that comes down in this cell (a plunge,
                        # a dive) enters the material where its height passes the top less the
                        # tolerance, not where it came into the cell, above the material
                        ti = tc
                        if za > high - tol:
                            ti = min(max((high - tol - az) / (bz - az), tc), te)
                        tt = t0[r, k] + ti * (t1[r, k] - t0[r, k])
                        if tt < when[0, s]:
                            when[0, s] = tt
                            for a in range(3):
                                where[0, s, a] = p0[r, k, a] + ti * (p1[r, k, a] - p0[r, k, a])
                    elif same and middle <= near * w[r, k]:
                        if run[r] == 0.0:  # a doubled stretch begins
                            run_cells[r] = 0
                            run_t[r] = t0[r, k] + tc * (t1[r, k] - t0[r, k])
                            for a in range(3):
                                run_xyz[r, a] = p0[r, k, a] + tc * (p1[r, k, a] - p0[r, k, a])
                            run_slot[r] = slot[r, k]
                        before = run[r]
                        run[r] += max((te - tc) * length, 1e-9)
                        run_cells[r] += 1
                        if run[r] > least * w[r, k]:
                            s = run_slot[r]
                            # the cells of the stretch before it grew past one line width count too
                            count[1, s] += run_cells[r] if before <= least * w[r, k] else 1
                            if run_t[r] < when[1, s]:
                                when[1, s] = run_t[r]
                                for a in range(3):
                                    where[1, s, a] = run_xyz[r, a]
                    elif lay:
                        run[r] = 0.0
            elif lay:
                run[r] = 0.0
            if lay:
                z = az + 0.5 * (tc + te) * (bz - az)
                if z >= high:
                    if z > highest[0]:
                        highest[0] = z
                    cells[ci, iy, TOP] = z
                    cells[ci, iy, WHO] = fr
                    here = dm + tc * length
                    cells[ci, iy, POS] = here - POS_PERIOD if here >= POS_PERIOD else here
                    cells[ci, iy, AX], cells[ci, iy, AY] = ax_, ay_
                    cells[ci, iy, BX], cells[ci, iy, BY] = bx_, by_
            if te >= tb:
                break
            if nx_t <= ny_t:
                ix += sx
                tc = nx_t
                nx_t += step_x
            else:
                iy += sy
                tc = ny_t
                ny_t += step_y
            if ix < col0 or ix >= col0 + ncol or iy < 0 or iy >= ny:
                break
