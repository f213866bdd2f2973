"""Cross-sections of a closed triangle mesh at many heights, in whole-array numpy passes.

Every triangle that a plane ``z = h`` crosses gives one segment; segments meet on the mesh edges
they cut, so each layer's segments form closed loops. A vertex exactly at ``h`` counts as below
(as in :mod:`cooprint.chunking.split`), so a plane never passes "through" a vertex and the loops
stay closed. Segments run so that the solid is on their left: outlines come out counter-clockwise
and holes clockwise, and ``CrossSection(..., FillRule.Positive)`` nests them (and unites
overlapping shells).

The loops are found without a Python loop over segments: each segment points to the one that
starts on the edge where it ends (a sort and a search), the cycles of that permutation are
labelled by pointer doubling (min label over 2, 4, 8 ... successors) and ordered by list ranking.
The memory is that of the segments of the layers asked for, not of a mesh data structure.
"""

from __future__ import annotations

import manifold3d
import numpy as np

from cooprint.geometry import STEP, index_dtype

#: Segments made in one numpy pass (about 200 bytes of temporaries each): bounds the memory of a
#: block of layers without changing its sections.
SEGMENTS = 1 << 15


class LayerSlicer:
    """A closed mesh prepared for slicing (triangles sorted by their lowest corner)."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        self.vertices = np.asarray(vertices, dtype=np.float64)
        z = self.vertices[:, 2]
        lo, hi = np.empty(len(faces)), np.empty(len(faces))
        for a in range(0, len(faces), STEP):  # a slice at a time: no (m, 3) temporaries
            tz = z[faces[a:a + STEP]]
            lo[a:a + len(tz)], hi[a:a + len(tz)] = tz.min(axis=1), tz.max(axis=1)
        order = np.argsort(lo, kind="stable")
        self.lo, self.hi = lo[order], hi[order]
        del lo, hi
        self.faces = np.asarray(faces)[order].astype(index_dtype(len(self.vertices)), copy=False)

    def rings(self, heights: np.ndarray) -> list[list[np.ndarray]]:
        """For every height (ascending), the closed rings (k, 2) of the section there.

        The segments are made in groups of consecutive layers of at most ``SEGMENTS`` segments
        (a layer is never split): each layer's loops depend on that layer alone, so the groups
        change nothing but the size of the temporaries.
        """
        heights = np.asarray(heights, dtype=np.float64)
        n = len(heights)
        out: list[list[np.ndarray]] = [[] for _ in heights]
        if n == 0:
            return out
        # triangles crossing some height: lo <= h < hi (corners at h count as below)
        end = int(np.searchsorted(self.lo, heights[-1], side="right"))
        cand = np.flatnonzero(self.hi[:end] > heights[0])
        first = np.searchsorted(heights, self.lo[cand], side="left")
        last = np.searchsorted(heights, self.hi[cand], side="left")
        cross = last > first
        cand, first, last = cand[cross], first[cross], last[cross]
        per_layer = np.cumsum(np.bincount(first, minlength=n + 1) - np.bincount(last, minlength=n + 1))[:n]
        lo = 0
        while lo < n:
            hi = lo + max(1, int(np.searchsorted(np.cumsum(per_layer[lo:]), SEGMENTS, side="right")))
            sel = (first < hi) & (last > lo)
            self._group_rings(heights, cand[sel], np.maximum(first[sel], lo), np.minimum(last[sel], hi), out)
            lo = hi
        return out

    def _group_rings(self, heights: np.ndarray, cand: np.ndarray, first: np.ndarray, last: np.ndarray,
                     out: list[list[np.ndarray]]) -> None:
        """Append to ``out`` the rings of triangles ``cand``, each crossing layers ``first`` to
        ``last - 1``."""
        count = last - first
        if len(cand) == 0:
            return
        tri = np.repeat(cand, count)
        layer = np.repeat(first, count) + (np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count))
        del cand, first, count
        f = self.faces[tri].astype(np.int64)
        del tri
        h = heights[layer]
        z = self.vertices[f, 2]
        above = z > h[:, None]
        n_above = above.sum(axis=1)
        lone_above = n_above == 1
        lone = np.where(lone_above[:, None], above, ~above).argmax(axis=1)
        rot = (np.arange(3)[None, :] + lone[:, None]) % 3
        f = np.take_along_axis(f, rot, axis=1)
        z = np.take_along_axis(z, rot, axis=1)
        a, b, c = f[:, 0], f[:, 1], f[:, 2]
        p_ab = _cut(self.vertices, a, b, z[:, 0], z[:, 1], h)
        p_ac = _cut(self.vertices, a, c, z[:, 0], z[:, 2], h)
        n_v = np.int64(len(self.vertices))
        k_ab = (np.minimum(a, b) * n_v + np.maximum(a, b)) * len(heights) + layer
        k_ac = (np.minimum(a, c) * n_v + np.maximum(a, c)) * len(heights) + layer
        # the solid on the left: ab -> ac when the lone corner is above, ac -> ab when below
        start = np.where(lone_above[:, None], p_ab, p_ac)
        s_key = np.where(lone_above, k_ab, k_ac)
        e_key = np.where(lone_above, k_ac, k_ab)
        del p_ab, p_ac, k_ab, k_ac, f, z, above, rot, a, b, c, h
        order = np.argsort(s_key)
        pos = np.searchsorted(s_key[order], e_key)
        pos = np.minimum(pos, len(order) - 1)
        if not np.array_equal(s_key[order][pos], e_key):
            raise ValueError("the mesh is not closed: a section does not form loops")
        nxt = order[pos]
        del order, pos, s_key, e_key
        label, rank = _cycles(nxt)
        seq = np.lexsort((rank, label))
        pts, lab, lay = start[seq], label[seq], layer[seq]
        cuts = np.flatnonzero(np.r_[True, lab[1:] != lab[:-1], True])
        for s, e in zip(cuts[:-1].tolist(), cuts[1:].tolist()):
            if e - s >= 3:
                out[int(lay[s])].append(pts[s:e])

    def sections(self, heights: np.ndarray) -> list[manifold3d.CrossSection]:
        """:meth:`rings` as cross-sections (outlines and holes nested, overlaps united)."""
        return [manifold3d.CrossSection(r, manifold3d.FillRule.Positive) if r else manifold3d.CrossSection()
                for r in self.rings(heights)]


def _cut(v: np.ndarray, i: np.ndarray, j: np.ndarray, zi: np.ndarray, zj: np.ndarray, h: np.ndarray) -> np.ndarray:
    """XY where the edge i-j meets z = h, computed from the edge's ends in index order (so both
    triangles of the edge get the same point)."""
    swap = i > j
    i, j = np.where(swap, j, i), np.where(swap, i, j)
    zi, zj = np.where(swap, zj, zi), np.where(swap, zi, zj)
    t = (h - zi) / (zj - zi)
    return v[i, :2] + t[:, None] * (v[j, :2] - v[i, :2])


def _cycles(nxt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For a permutation ``nxt``: each element's cycle label (its smallest member) and its rank
    along the cycle from that member (0, 1, 2 ...)."""
    n = len(nxt)
    idx = np.arange(n)
    label, ptr = idx.copy(), nxt.copy()
    while True:  # min over 1, 2, 4 ... successors; stops when a doubling changes nothing
        new = np.minimum(label, label[ptr])
        ptr = ptr[ptr]
        if np.array_equal(new, label):
            break
        label = new
    # list ranking: cut each cycle before its label, count the steps to the end
    succ = nxt.copy()
    tail = nxt == label  # the element whose successor is the cycle's first
    succ[tail] = idx[tail]
    dist = (~tail).astype(np.int64)
    while True:
        nd = dist + dist[succ]
        ns = succ[succ]
        if np.array_equal(ns, succ):
            break
        dist, succ = nd, ns
    length = np.bincount(label, minlength=n)[label]
    return label, length - 1 - dist
