"""Mesh repairs the loader makes on a mesh that is not a closed 2-manifold as read: splitting
non-manifold edges, removing facets left without a neighbour, closing holes.

These follow admesh (PrusaSlicer's repair) in what they fix, not in how: admesh matches every
edge with one neighbour and drops the rest; here the faces around an edge shared by more than two
triangles are paired by the wedges of solid between them (so two solids touching along an edge
stay two solids, and a stray fin is cut loose and dropped), and the vertices are split so that
each pair of faces has an edge of its own. The surface is unchanged (split vertices keep their
position), so sections and volume are those of the mesh as read.
"""

from __future__ import annotations

import manifold3d
import numpy as np

from cooprint.geometry import _edge_keys, _vertex_count, index_dtype
from cooprint.io.holefill import MAX_LOOP, components, least_area_triangulation


def _edge_groups(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The directed edges of ``faces`` (half-edge ``3 f + j`` runs from corner ``j`` to corner
    ``j + 1``) sorted by their undirected edge: the order, the start of each edge's run in it and
    the run lengths (how many faces share each edge)."""
    a = faces.reshape(-1).astype(np.int64)
    b = faces[:, [1, 2, 0]].reshape(-1).astype(np.int64)
    n = np.int64(len(faces) and int(faces.max()) + 1)
    key = np.minimum(a, b) * n + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    sk = key[order]
    starts = np.flatnonzero(np.r_[True, sk[1:] != sk[:-1]])
    return order, starts, np.diff(np.r_[starts, len(sk)])


def _pair_nonmanifold(vertices: np.ndarray, faces: np.ndarray, halfedges: np.ndarray) -> list[tuple[int, int]]:
    """Pairs of half-edges around one edge shared by more than two faces, each pair bounding a
    wedge of solid.

    Seen along the edge a -> b, a face a -> b -> c faces towards increasing angle (its solid is
    just below its own angle) and a face b -> a -> c the other way: so a face run b -> a pairs
    with the next face round the edge when that one runs a -> b. Faces left over (a fin, a third
    sheet) get no partner; their edge becomes open.
    """
    f, j = halfedges // 3, halfedges % 3
    a0 = faces[f[0], j[0]]
    b0 = faces[f[0], (j[0] + 1) % 3]
    src = faces[f, j]
    third = faces[f, (j + 2) % 3]
    p, q = vertices[a0], vertices[b0]
    d = (q - p) / max(float(np.linalg.norm(q - p)), 1e-300)
    r = vertices[third] - p
    r -= np.outer(r @ d, d)
    e1 = r[0] / max(float(np.linalg.norm(r[0])), 1e-300)
    e2 = np.cross(d, e1)
    order = np.argsort(np.arctan2(r @ e2, r @ e1), kind="stable")
    forward = (src == a0)[order]
    h = halfedges[order]
    pairs, used = [], np.zeros(len(h), dtype=bool)
    for i in range(len(h)):
        k = (i + 1) % len(h)
        if not forward[i] and forward[k] and not used[i] and not used[k]:
            pairs.append((int(h[i]), int(h[k])))
            used[i] = used[k] = True
    return pairs


def separate(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, int]:
    """Split every edge shared by more than two faces so that each edge has at most two: the
    faces around such an edge are paired by :func:`_pair_nonmanifold`, and each end of it gets
    one copy per fan of faces joined through paired edges (other vertices, a hole's pinch
    corner included, stay one); the open pieces this cuts loose are dropped (:func:`_cut_loose`), and so are
    faces that share no edge with another (a stray triangle). Returns the vertices (a copy per
    fan, at the vertex's position), the faces, the number of non-manifold edges split and the
    number of faces dropped."""
    lone = _lone_unless_split(faces)
    if lone is not None:  # no edge to split (the common case): only faces sharing no edge go
        return vertices, faces[~lone], 0, int(lone.sum())
    order, starts, runs = _edge_groups(faces)
    multi = np.flatnonzero(runs > 2)
    n_he = 3 * len(faces)
    pa, pb = [], []
    two = runs == 2
    pa.append(order[starts[two]])
    pb.append(order[starts[two] + 1])
    for g in multi.tolist():
        he = order[starts[g]:starts[g] + runs[g]]
        for x, y in _pair_nonmanifold(vertices, faces, he):
            pa.append(np.array([x]))
            pb.append(np.array([y]))
    ha, hb = np.concatenate(pa), np.concatenate(pb)
    # corners (3 f + j) joined across each paired edge: the same vertex in both faces
    fa, ja, fb, jb = ha // 3, ha % 3, hb // 3, hb % 3
    va, vb = faces[fa, ja], faces[fb, jb]
    same = va == vb  # pair runs the same way (winding not yet consistent)
    jb_next = (jb + 1) % 3
    c1 = np.c_[3 * fa + ja, np.where(same, 3 * fb + jb, 3 * fb + jb_next)]
    c2 = np.c_[3 * fa + (ja + 1) % 3, np.where(same, 3 * fb + jb_next, 3 * fb + jb)]
    links = np.vstack([c1, c2])
    label = components(n_he, links[:, 0], links[:, 1])  # a vertex's corners, by fan
    corner_vertex = faces.reshape(-1).astype(np.int64)
    touched = np.zeros(len(vertices), dtype=bool)  # only the ends of split edges are split
    for g in multi.tolist():
        he = order[starts[g]]
        touched[faces[he // 3, [he % 3, (he % 3 + 1) % 3]]] = True
    key = np.where(touched[corner_vertex], len(vertices) + label, corner_vertex)
    uniq, first, inv = np.unique(key, return_index=True, return_inverse=True)
    new_faces = inv.reshape(-1, 3).astype(index_dtype(len(uniq)))
    loose = _cut_loose(new_faces, touched[corner_vertex].reshape(-1, 3).any(axis=1))
    return vertices[corner_vertex[first]], new_faces[~loose], int(len(multi)), int(loose.sum())


def _cut_loose(faces: np.ndarray, near: np.ndarray) -> np.ndarray:
    """(m,) bool: the faces of the open pieces that the split cut loose (a fin, a sheet inside
    the solid): edge-connected components with an open edge and a face ``near`` a split edge,
    except the largest component (an open part's own body, whose holes are closed later); and
    faces sharing no edge at all."""
    order, starts, runs = _edge_groups(faces)
    two = runs == 2
    fa, fb = order[starts[two]] // 3, order[starts[two] + 1] // 3
    label = components(len(faces), fa, fb)
    size = np.bincount(label, minlength=len(faces))
    is_open = np.zeros(len(faces), dtype=bool)
    is_open[label[order[starts[runs == 1]] // 3]] = True
    touched = np.zeros(len(faces), dtype=bool)
    touched[label[near]] = True
    loose = is_open & touched
    loose[int(np.argmax(size))] = False
    return loose[label] | _lone(order, runs)


def _lone_unless_split(faces: np.ndarray) -> np.ndarray | None:
    """(m,) bool: the faces sharing no edge with another face, as :func:`_lone` finds them, or
    ``None`` when some edge is shared by more than two faces (:func:`separate` splits it). One
    plain sort of the edge keys (:func:`~cooprint.geometry._edge_keys`), not the stable argsort
    of :func:`_edge_groups`: the edges used once are few, and each face looks its up."""
    n = _vertex_count(faces)
    edge = _edge_keys(faces, n) >> 1  # sorted undirected keys min n + max
    starts = np.flatnonzero(np.r_[True, edge[1:] != edge[:-1]])
    runs = np.diff(np.r_[starts, len(edge)])
    if len(runs) and runs.max() > 2:
        return None
    single = edge[starts[runs == 1]]
    del edge, starts, runs
    if len(single) == 0:
        return np.zeros(len(faces), dtype=bool)
    a = faces.astype(np.int64)
    b = a[:, [1, 2, 0]]
    key = np.minimum(a, b) * n + np.maximum(a, b)
    return (single[np.minimum(np.searchsorted(single, key), len(single) - 1)] == key).all(axis=1)


def _lone(order: np.ndarray, runs: np.ndarray) -> np.ndarray:
    """(m,) bool: faces sharing no edge with another face (admesh's unconnected facets), from
    :func:`_edge_groups`' order and runs."""
    shared = np.empty(len(order), dtype=bool)
    shared[order] = np.repeat(runs > 1, runs)
    return ~shared.reshape(-1, 3).any(axis=1)


def _against_loop(loop: np.ndarray, cap: np.ndarray) -> np.ndarray:
    """``cap`` (triangles over the loop's vertices) wound so that it holds each loop edge
    a -> b as b -> a (the loop runs along existing faces)."""
    nxt = np.full(int(loop.max()) + 1, -1, dtype=np.int64)
    nxt[loop] = np.roll(loop, -1)
    if (nxt[cap] == np.roll(cap, -1, axis=1)).any():
        return cap[:, ::-1]
    return cap


def _projected(loop: np.ndarray, pts: np.ndarray) -> np.ndarray | None:
    """The loop triangulated in its best-fit plane, ``None`` unless that projection is a simple
    polygon (every triangle turning the same way)."""
    centred = pts - pts.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    uv = centred @ vt[:2].T
    try:
        tris = np.asarray(manifold3d.triangulate([uv]), dtype=np.int64).reshape(-1, 3)
    except Exception:
        return None
    if len(tris) != len(loop) - 2:
        return None
    p0, p1, p2 = uv[tris[:, 0]], uv[tris[:, 1]], uv[tris[:, 2]]
    area = (p1[:, 0] - p0[:, 0]) * (p2[:, 1] - p0[:, 1]) - (p1[:, 1] - p0[:, 1]) * (p2[:, 0] - p0[:, 0])
    return tris if np.all(area > 0) or np.all(area < 0) else None


def _least_area(pts: np.ndarray, ea: np.ndarray, eb: np.ndarray) -> np.ndarray | None:
    """:func:`~cooprint.io.holefill.least_area_triangulation` of a loop whose vertices at
    positions ``ea[i]``, ``eb[i]`` already share an edge; ``None`` beyond
    :data:`~cooprint.io.holefill.MAX_LOOP` vertices."""
    if len(pts) > MAX_LOOP:
        return None
    banned = np.zeros((len(pts), len(pts)), dtype=np.bool_)
    banned[np.minimum(ea, eb), np.maximum(ea, eb)] = True
    return least_area_triangulation(pts, banned)


def fill_loop(vertices: np.ndarray, loop: np.ndarray, edge_keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles closing one boundary loop (its edges a -> b run along existing faces, so the
    cap holds b -> a), adding no edge the mesh already has (``edge_keys``: sorted
    ``min * len(vertices) + max``, at least those between the loop's vertices; a repeated edge
    would be non-manifold). The
    first that fits of: the least-area triangulation (:mod:`cooprint.io.holefill`, loops up
    to :data:`~cooprint.io.holefill.MAX_LOOP` vertices), the triangulation of the loop
    projected on its best-fit plane, and a fan from a new vertex at the loop's centroid (which
    never repeats an edge). Returns the new vertices ((0, 3) or (1, 3)) and the cap's faces,
    in which the new vertex is numbered -1."""
    pts = vertices[loop].astype(np.float64)
    n = np.int64(len(vertices))
    ring = np.sort(np.minimum(loop, np.roll(loop, -1)) * n + np.maximum(loop, np.roll(loop, -1)))
    by_id = np.argsort(loop)
    ids = loop[by_id]

    def at(v: np.ndarray) -> np.ndarray:  # the position of vertex v on the loop, -1 if off it
        i = np.minimum(np.searchsorted(ids, v), len(ids) - 1)
        return np.where(ids[i] == v, by_id[i], -1)

    ea, eb = at(edge_keys // n), at(edge_keys % n)
    inner = (ea >= 0) & (eb >= 0) & ~np.isin(edge_keys, ring)
    for make in (lambda: _least_area(pts, ea[inner], eb[inner]), lambda: _projected(loop, pts)):
        tris = make()
        if tris is None:
            continue
        cap = _against_loop(loop, loop[tris])
        e = np.sort(cap[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        keys = e[:, 0] * n + e[:, 1]
        pos = np.minimum(np.searchsorted(edge_keys, keys), len(edge_keys) - 1)
        if not ((edge_keys[pos] == keys) & ~np.isin(keys, ring)).any():
            return np.zeros((0, 3)), cap
    fan = np.c_[np.roll(loop, -1), loop, np.full(len(loop), -1)]
    return pts.mean(axis=0)[None, :], fan
