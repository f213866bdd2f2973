"""Cross-sections of a closed triangle mesh at many heights, in whole-array numpy passes.

Every triangle that a plane ``z = h`` crosses gives one segment; segments meet on the mesh edges
they cut, so each layer's segments form closed loops. A vertex exactly at ``h`` counts as below
(as in :mod:`cooprint.chunking.split`), so a plane never passes "through" a vertex and the loops
stay closed. Segments run so that the solid is on their left: outlines come out counter-clockwise
and holes clockwise, and ``CrossSection(..., FillRule.Positive)`` nests them (and unites
overlapping shells).

The loops are found by compiled passes (numba) over the segments: the segments of a group of
layers are made, each is linked to the one that starts on the edge where it ends (a hash table of
the start edges), and the cycles of that permutation are walked from their smallest member
(:mod:`.section_kernels`, imported on first use: importing the slicer does not load numba). The memory is that of the segments of the
layers asked for, not of a mesh data structure.
"""

from __future__ import annotations

import manifold3d
import numpy as np

from cooprint.geometry import STEP, index_dtype

#: Segments made in one pass (about 100 bytes each: points made and walked, keys, links, hash table): bounds
#: the memory of a block of layers without changing its sections.
SEGMENTS = 1 << 15
#: At most this many points in a row are dropped as collinear (:meth:`LayerSlicer.rings`), so that
#: the dropped ones stay within ``COLLINEAR_RUN x eps`` of the ring.
COLLINEAR_RUN = 1024


class LayerSlicer:
    """A closed mesh prepared for slicing: triangles sorted by their lowest corner, vertices
    renumbered in the order these triangles first use them (a layer's triangles then read
    vertices stored near each other), each keeping its number in the mesh (``number``), which
    decides the direction in which an edge is cut."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray):
        from cooprint.slicing.section_kernels import renumber  # numba: on first use

        vertices = np.asarray(vertices, dtype=np.float64)
        z = vertices[:, 2]
        lo, hi = np.empty(len(faces)), np.empty(len(faces))
        for a in range(0, len(faces), STEP):  # a slice at a time: no (m, 3) temporaries
            f = faces[a:a + STEP]  # (corner by corner: min(axis=1) over rows of 3 is 6x slower)
            z0, z1, z2, b = z[f[:, 0]], z[f[:, 1]], z[f[:, 2]], a + len(f)
            np.minimum(np.minimum(z0, z1, out=lo[a:b]), z2, out=lo[a:b])
            np.maximum(np.maximum(z0, z1, out=hi[a:b]), z2, out=hi[a:b])
        order = np.argsort(lo, kind="stable")
        self.lo, self.hi = lo[order], hi[order]
        del lo, hi
        faces = np.asarray(faces)[order].astype(index_dtype(len(vertices)), copy=False)
        del order
        self.faces, self.number = renumber(faces, len(vertices))
        del faces
        self.vertices = np.take(vertices, self.number, axis=0)  # (2-4x faster than indexing rows)

    def rings(self, heights: np.ndarray, eps: float = 0.0) -> list[list[np.ndarray]]:
        """For every height (ascending), the closed rings (k, 2) of the section there; with
        ``eps > 0``, without the points that lie on the segment between the last point kept and
        the next one (within ``eps``, at most ``COLLINEAR_RUN`` in a row: a tessellated flat
        face's vertices), and without the rings this leaves under 3 points.

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
            self._group_rings(heights, cand[sel], np.maximum(first[sel], lo), np.minimum(last[sel], hi), eps, out)
            lo = hi
        return out

    def _group_rings(self, heights: np.ndarray, cand: np.ndarray, first: np.ndarray, last: np.ndarray,
                     eps: float, out: list[list[np.ndarray]]) -> None:
        """Append to ``out`` the rings of triangles ``cand``, each crossing layers ``first`` to
        ``last - 1`` (collinear points within ``eps`` dropped, :meth:`rings`)."""
        from cooprint.slicing.section_kernels import link, segments, walk

        if len(cand) == 0:
            return
        start, s_key, e_key, layer = segments(self.vertices, self.number, self.faces, heights,
                                               cand.astype(np.int64), first.astype(np.int64), last.astype(np.int64))
        nxt = link(s_key, e_key)
        del s_key, e_key
        pts, ring_at, ring_layer = walk(nxt, start, layer, float(eps), COLLINEAR_RUN)
        del start, nxt
        ring_layer = ring_layer.tolist()
        for k, (s, e) in enumerate(zip(ring_at[:-1].tolist(), ring_at[1:].tolist())):
            if e - s >= 3:
                out[ring_layer[k]].append(pts[s:e])

    def sections(self, heights: np.ndarray) -> list[manifold3d.CrossSection]:
        """:meth:`rings` as cross-sections (outlines and holes nested, overlaps united)."""
        return [manifold3d.CrossSection(r, manifold3d.FillRule.Positive) if r else manifold3d.CrossSection()
                for r in self.rings(heights)]
