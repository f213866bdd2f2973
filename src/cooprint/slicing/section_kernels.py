"""Compiled kernels of the mesh sectioning (:mod:`.sections`; numba, imported on first use)."""

from __future__ import annotations

import numba
import numpy as np

from cooprint import jit

jit.setup()  # Ctrl-C held while numba compiles; LLVM calls untimed (cooprint.jit)


@numba.njit(cache=True, nogil=True)
def segments(v, number, faces, heights, cand, first, last):
    """The segment of every triangle ``cand[t]`` at every height ``first[t] .. last[t] - 1``
    (triangle by triangle, each one's layers upwards): its start point (k, 2), the keys of the
    edges (and layer) where it starts and ends, and its layer. Each segment runs between the
    cuts of the two edges at the triangle's lone corner (the one corner above the plane, or the
    one at or below it), so that the solid is on its left; each cut is made from the edge's
    ends in the order of their numbers in the mesh (``number``), so both triangles of an edge
    get the same point."""
    n = 0
    for t in range(len(cand)):
        n += last[t] - first[t]
    start = np.empty((n, 2))
    s_key = np.empty(n, np.int64)
    e_key = np.empty(n, np.int64)
    layer = np.empty(n, np.int64)
    nv = np.int64(len(v))
    nh = np.int64(len(heights))
    i = 0
    for t in range(len(cand)):
        f0, f1, f2 = np.int64(faces[cand[t], 0]), np.int64(faces[cand[t], 1]), np.int64(faces[cand[t], 2])
        z0, z1, z2 = v[f0, 2], v[f1, 2], v[f2, 2]
        for k in range(first[t], last[t]):
            h = heights[k]
            u0, u1, u2 = z0 > h, z1 > h, z2 > h
            lone_above = np.int64(u0) + np.int64(u1) + np.int64(u2) == 1
            if u0 == lone_above:
                a, b, c = f0, f1, f2
            elif u1 == lone_above:
                a, b, c = f1, f2, f0
            else:
                a, b, c = f2, f0, f1
            if not lone_above:  # ac -> ab, else ab -> ac
                b, c = c, b
            # start on edge a-b, end on edge a-c
            lo, hi = (a, b) if number[a] < number[b] else (b, a)
            t_ = (h - v[lo, 2]) / (v[hi, 2] - v[lo, 2])
            start[i, 0] = v[lo, 0] + t_ * (v[hi, 0] - v[lo, 0])
            start[i, 1] = v[lo, 1] + t_ * (v[hi, 1] - v[lo, 1])
            s_key[i] = (min(a, b) * nv + max(a, b)) * nh + k
            e_key[i] = (min(a, c) * nv + max(a, c)) * nh + k
            layer[i] = k
            i += 1
    return start, s_key, e_key, layer


@numba.njit(cache=True, nogil=True)
def renumber(faces, n_vertices):
    """``faces`` with the vertices numbered in the order the faces first use them (row by row),
    and each used vertex's old number by its new one."""
    new = np.full(n_vertices, -1, faces.dtype)
    number = np.empty(n_vertices, faces.dtype)
    out = np.empty_like(faces)
    k = 0
    for i in range(faces.shape[0]):
        for c in range(3):
            old = faces[i, c]
            if new[old] < 0:
                new[old] = k
                number[k] = old
                k += 1
            out[i, c] = new[old]
    return out, number[:k]


@numba.njit(cache=True, nogil=True)
def link(s_key, e_key):
    """The segment that starts where each segment ends (``s_key`` of the next is ``e_key`` of
    this one), found with an open-addressing hash table of the start keys. A key that starts
    two segments or ends one that none starts: the mesh is not closed (ValueError)."""
    n = len(s_key)
    bits = 1
    while (1 << bits) < 2 * n:
        bits += 1
    mask = (1 << bits) - 1
    shift = np.uint64(64 - bits)
    mix = np.uint64(0x9E3779B97F4A7C15)
    table = np.full(1 << bits, -1, np.int64)
    for i in range(n):
        s = np.int64((np.uint64(s_key[i]) * mix) >> shift)
        while table[s] >= 0:
            if s_key[table[s]] == s_key[i]:
                raise ValueError("the mesh is not closed: a section does not form loops")
            s = (s + 1) & mask
        table[s] = i
    nxt = np.empty(n, np.int64)
    for i in range(n):
        s = np.int64((np.uint64(e_key[i]) * mix) >> shift)
        while True:
            j = table[s]
            if j < 0:
                raise ValueError("the mesh is not closed: a section does not form loops")
            if s_key[j] == e_key[i]:
                nxt[i] = j
                break
            s = (s + 1) & mask
    return nxt


@numba.njit(cache=True, nogil=True)
def walk(nxt, start, layer, eps, run):
    """The cycles of the permutation ``nxt`` (the segments' links) as rings: ``pts`` lists the
    segments' start points cycle by cycle, cycles in the order of their smallest member, each
    from that member along ``nxt``; cycle ``r`` is ``pts[ring_at[r]:ring_at[r + 1]]``, on layer
    ``ring_layer[r]`` (its segments'). (Walking up from element 0, every element not yet seen
    starts a cycle whose other members are all larger.) The points are gathered here, as the
    cycles are walked: a separate ``start[order]`` costs as much as the walk.

    With ``eps > 0``, a ring of 4 points or more is walked without the points that lie on the
    segment between the last point kept and the next one (within ``eps``; at most ``run`` in a
    row; its first point kept): a tessellated flat face's vertices, dropped as the ring is
    gathered rather than in a pass over copies of the rings."""
    n = len(nxt)
    seen = np.zeros(n, np.bool_)
    pts = np.empty((n, 2))
    ring_at = np.empty(n + 1, np.int64)
    ring_layer = np.empty(n, np.int64)
    w = 0
    r = 0
    for i in range(n):
        if seen[i]:
            continue
        ring_at[r] = w
        ring_layer[r] = layer[i]
        r += 1
        s = w
        j = i
        while not seen[j]:
            seen[j] = True
            pts[w, 0] = start[j, 0]
            pts[w, 1] = start[j, 1]
            w += 1
            j = nxt[j]
        if j != i:
            raise ValueError("the mesh is not closed: a section does not form loops")
        if eps > 0.0 and w - s >= 4:  # compacted in place: a point kept moves to k <= its index
            ax, ay = pts[s, 0], pts[s, 1]  # the last point kept
            k = s + 1
            dropped = 0
            for j in range(s + 1, w):
                nx, ny = (pts[j + 1, 0], pts[j + 1, 1]) if j + 1 < w else (pts[s, 0], pts[s, 1])
                dx, dy = nx - ax, ny - ay
                l2 = dx * dx + dy * dy
                px, py = pts[j, 0] - ax, pts[j, 1] - ay
                if dropped < run and l2 > 0.0:
                    t = (px * dx + py * dy) / l2
                    cross = px * dy - py * dx
                    if 0.0 <= t <= 1.0 and cross * cross <= eps * eps * l2:
                        dropped += 1
                        continue
                ax, ay = pts[j, 0], pts[j, 1]
                pts[k, 0] = ax
                pts[k, 1] = ay
                k += 1
                dropped = 0
            w = k
    ring_at[r] = w
    return pts[:w], ring_at[:r + 1], ring_layer[:r]

