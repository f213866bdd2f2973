"""The viewer's geometry: what the page draws, as compact binary buffers (docs/viewer.md).

Per robot, in its time order:

* ``material``: the segments it lays down, as polylines (a vertex where the nozzle is at a time:
  consecutive segments that meet in space and time share a vertex), each segment with its
  chunk, role and layer height (runs over the segments: they change seldom);
* ``travel``: its moves with the tool off, the same way (no attributes).

The page draws robot r's first ``k`` material segments with a draw range (``k``: those ended by
the time shown) and the one under way up to the nozzle; the nozzle at time t is the
interpolation of the material and travel vertices around t (a robot's *track*: the two streams'
vertices merged in time order), so no separate track is stored.

Level of detail (:func:`simplify`): a vertex is dropped where the nozzle's path in *space and
time* stays within ``tolerance`` of the chord from the last kept vertex to the next: the
position interpolated in time along the merged segment is never farther than the tolerance from
where the nozzle really is, so nearly collinear segments at one speed merge and the nozzle's
timing stays exact at every kept vertex. Vertices where a chunk, role or layer height changes
are kept. Above a budget of segments (``max_segments``) the material is thinned evenly (as the
PNG snapshot thins it) and the result says so (``thinned``); never silently.

Encoding: positions are quantized to uint16 over the bounding box (material, travel, chunk
outlines), times to integer units of ``time_unit`` s (1 ms, coarser only for plans so long that
a delta would not fit 32 bits); both are delta-coded along each stream (positions modulo 2^16)
and their bytes shuffled into planes, so that gzip finds the runs of small numbers; the whole is
one gzip stream, base64 in the page (the browser inflates it with ``DecompressionStream``).
Timelines are read a block of ``BLOCK_MOVES`` moves at a time: a big plan's moves are never
copied whole.
"""

from __future__ import annotations

import base64
import gzip
from dataclasses import dataclass
from typing import Any, Mapping

import numba
import numpy as np

from cooprint.render.paths import ROLE_COLOURS
from cooprint.render.sim import BLOCK_MOVES
from cooprint.simulation import SimResult
from cooprint.slicing.paths import ROLE_NAMES

#: The least level-of-detail tolerance, mm: a tenth of a bead's width, below what a screen shows
#: of a whole part; a larger plan's tolerance grows with its size (:func:`display_tolerance`).
LOD_TOLERANCE_MM = 0.05
#: The most material segments a page holds (after the level of detail); above, thinned evenly.
#: About 80 bytes of the browser's memory each (buffers and times) and a full redraw of 3 M
#: segments takes about 0.2 s in software GL; the playback draws only what is new.
MAX_SEGMENTS = 3_000_000
#: The most travel segments a page holds; above, thinned evenly as the material.
MAX_TRAVEL = 1_000_000
#: The most chunk outline edges (feature edges of the chunk meshes); above, thinned evenly.
MAX_OUTLINE_EDGES = 200_000
#: Angle between two faces' normals above which their common edge is drawn, degrees.
FEATURE_ANGLE_DEG = 30.0
#: A dropped vertex is looked at from at most this many vertices back (bounds the work per vertex).
LOD_WINDOW = 128
#: Quantization steps of a position over the bounding box.
QMAX = 65535
FORMAT = "cooprint-viewer-geometry/1"


def display_tolerance(extent: np.ndarray) -> float:
    """The level-of-detail tolerance for a scene of ``extent`` (3,) mm: ``LOD_TOLERANCE_MM``, or
    1/20,000 of its diagonal when larger (a 10 m part: 0.7 mm)."""
    return max(LOD_TOLERANCE_MM, float(np.linalg.norm(extent)) / 20_000.0)


@numba.njit(cache=True, nogil=True)
def simplify(p, t, fixed, tol, window, keep):  # pragma: no cover (compiled)
    """Mark in ``keep`` (n,) the vertices of polylines ``p`` (n, 3) with times ``t`` (n,) that
    the level of detail keeps: a vertex is dropped when every vertex between the last kept one
    and the next candidate lies within ``tol`` of the point interpolated in time on the chord
    between those two (so the nozzle shown at any time is within ``tol`` of the true one); the
    ``fixed`` vertices (ends of polylines, changes of attributes) are kept, and no chord spans
    more than ``window`` vertices."""
    n = len(t)
    tol2 = tol * tol
    for i in range(n):
        keep[i] = False
    if n == 0:
        return
    keep[0] = True
    a = 0
    c = 1
    while c < n:
        if c == n - 1 or fixed[c] or c + 1 - a > window:
            keep[c] = True
            a = c
            c += 1
            continue
        b = c + 1
        dt = t[b] - t[a]
        ok = True
        for j in range(a + 1, b):
            f = (t[j] - t[a]) / dt if dt > 0 else 0.0
            if f < 0.0:
                f = 0.0
            elif f > 1.0:
                f = 1.0
            d2 = 0.0
            for k in range(3):
                d = p[a, k] + f * (p[b, k] - p[a, k]) - p[j, k]
                d2 += d * d
            if d2 > tol2:
                ok = False
                break
        if ok:
            c += 1
        else:
            keep[c] = True
            a = c
            c += 1


@dataclass
class _Paths:
    """Polylines of one kind (material or travel) of one robot: vertices ``pos`` (m, 3) mm and
    ``time`` (m,) s, polyline vertex counts ``lengths`` (k,), and per segment (``m - k`` of them,
    in order) the attributes ``attrs`` (segments, a) int (material: chunk, role, height index)."""

    pos: np.ndarray
    time: np.ndarray
    lengths: np.ndarray
    attrs: np.ndarray

    @property
    def segments(self) -> int:
        return len(self.time) - len(self.lengths)

    @staticmethod
    def empty(n_attrs: int) -> "_Paths":
        return _Paths(np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64), np.zeros((0, n_attrs), np.int64))

    @staticmethod
    def concat(parts: list["_Paths"], n_attrs: int) -> "_Paths":
        if not parts:
            return _Paths.empty(n_attrs)
        return _Paths(np.concatenate([q.pos for q in parts]), np.concatenate([q.time for q in parts]),
                      np.concatenate([q.lengths for q in parts]), np.concatenate([q.attrs for q in parts]))

    def segment_starts(self) -> np.ndarray:
        """Each segment's first vertex (segments,): every vertex but the last of each polyline."""
        starts = np.ones(len(self.time), bool)
        starts[np.cumsum(self.lengths) - 1] = False
        return np.flatnonzero(starts)


def _polylines(p0: np.ndarray, p1: np.ndarray, t0: np.ndarray, t1: np.ndarray, attrs: np.ndarray,
               tol: float | None) -> _Paths:
    """Segments (in time order) joined into polylines where one ends where and when the next
    starts, simplified within ``tol`` (``None``: as they are)."""
    n = len(t0)
    if n == 0:
        return _Paths.empty(attrs.shape[1])
    brk = np.ones(n, bool)  # segment j starts a polyline
    brk[1:] = np.any(p1[:-1] != p0[1:], axis=1) | (t1[:-1] != t0[1:])
    cb = np.cumsum(brk)
    end = np.arange(n) + cb  # the vertex each segment ends at
    nv = n + int(cb[-1])
    pos, time = np.empty((nv, 3)), np.empty(nv)
    pos[end], time[end] = p1, t1
    first = np.flatnonzero(brk)
    pos[end[first] - 1], time[end[first] - 1] = p0[first], t0[first]
    lengths = np.diff(np.append(end[first] - 1, nv))
    if tol is None:
        return _Paths(pos, time, lengths, attrs)
    fixed = np.zeros(nv, bool)
    fixed[end[first] - 1] = True  # polylines' ends
    fixed[np.cumsum(lengths) - 1] = True
    if attrs.shape[1]:  # a vertex between segments of other attributes
        change = np.flatnonzero(np.any(attrs[1:] != attrs[:-1], axis=1)) + 1
        fixed[end[change] - 1] = True
    keep = np.empty(nv, bool)
    simplify(pos, time, fixed, tol, LOD_WINDOW, keep)
    poly = np.repeat(np.arange(len(lengths)), lengths)
    seg_of = np.full(nv, -1, np.int64)  # the segment each vertex starts
    seg_of[end - 1] = np.arange(n)
    kept = np.flatnonzero(keep)
    new_lengths = np.bincount(poly[kept], minlength=len(lengths))
    kept_starts = kept[np.append(poly[kept][1:] == poly[kept][:-1], False)]  # those the next kept one follows
    return _Paths(pos[kept], time[kept], new_lengths, attrs[seg_of[kept_starts]])


def _thin(paths: _Paths, pick: np.ndarray) -> _Paths:
    """The segments ``pick`` (sorted indices) of ``paths`` only, joined again where they meet."""
    s = paths.segment_starts()[pick]
    return _polylines(paths.pos[s], paths.pos[s + 1], paths.time[s], paths.time[s + 1], paths.attrs[pick], None)


@dataclass
class ViewerGeometry:
    """The page's geometry: ``header`` (JSON-able: tables, counts, the arrays' directory) and
    ``payload`` (the arrays' bytes, one after the other, 8-byte aligned, before gzip)."""

    header: dict[str, Any]
    payload: bytes

    def encoded(self) -> str:
        """The payload gzip-compressed and base64-encoded, as the page holds it."""
        return base64.b64encode(gzip.compress(self.payload, compresslevel=6, mtime=0)).decode("ascii")

    @property
    def thinned(self) -> dict[str, int] | None:
        return self.header["thinned"]


def _shuffled(a: np.ndarray) -> bytes:
    """The bytes of ``a`` (n, ...) in planes: the first byte of every element, then the second...
    (``a`` C-contiguous, little-endian; columns of a 2-d array one after the other)."""
    a = np.ascontiguousarray(a.T if a.ndim == 2 else a)
    b = a.view(np.uint8).reshape(a.shape + (a.itemsize,))
    return np.ascontiguousarray(np.moveaxis(b, -1, -2 if a.ndim == 2 else 0)).tobytes()


def _unshuffled(raw: bytes, dtype: str, shape: tuple[int, ...]) -> np.ndarray:
    """:func:`_shuffled` undone."""
    dt = np.dtype(dtype)
    if len(shape) == 2:
        b = np.frombuffer(raw, np.uint8).reshape(shape[1], dt.itemsize, shape[0])
        return np.ascontiguousarray(np.moveaxis(b, -2, -1)).view(dt).reshape(shape[1], shape[0]).T
    b = np.frombuffer(raw, np.uint8).reshape(dt.itemsize, shape[0])
    return np.ascontiguousarray(b.T).view(dt).reshape(shape)


class _Writer:
    """The payload and its directory: each array's name, dtype, shape, byte offset, codec."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.size = 0
        self.directory: dict[str, dict[str, Any]] = {}

    def add(self, name: str, a: np.ndarray, codec: str = "raw") -> None:
        a = np.ascontiguousarray(a)
        raw = _shuffled(a) if codec == "shuffle" else a.tobytes()
        self.directory[name] = {"dtype": a.dtype.str.lstrip("<|="), "shape": list(a.shape), "offset": self.size,
                                "bytes": len(raw), "codec": codec}
        pad = -len(raw) % 8
        self.parts += [raw, b"\0" * pad]
        self.size += len(raw) + pad


def _runs(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``values`` (n,) as runs: the index where each starts and its value."""
    if not len(values):
        return np.zeros(0, np.uint32), values[:0]
    at = np.flatnonzero(np.r_[True, values[1:] != values[:-1]])
    return at.astype(np.uint32), values[at]


def _collect(result: SimResult, tol: float, chunk_ids: list[str]) -> tuple[list[_Paths], list[_Paths]]:
    """Every robot's material (attributes: chunk index in ``chunk_ids``, role, layer height in
    µm) and travel polylines, a block of moves at a time, simplified within ``tol``."""
    material, travel = [], []
    for r in result.robots:
        tl = result.timelines[r.name]
        prog = r.program
        glob = np.array([chunk_ids.index(c) for c in prog.chunks] + [-1], np.int64)  # -1: between chunks
        mats, travs = [], []
        for a in range(0, len(tl.t0), BLOCK_MOVES):
            e = min(a + BLOCK_MOVES, len(tl.t0))
            on = np.asarray(tl.on[a:e])
            t0, t1, p0, p1 = tl.t0[a:e], tl.t1[a:e], tl.p0[a:e], tl.p1[a:e]
            idx = tl.index[a:e][on]
            attrs = np.column_stack([glob[np.asarray(prog.chunk[idx], np.int64)], np.asarray(prog.role[idx], np.int64),
                                     np.rint(np.asarray(prog.height[idx]) * 1000).astype(np.int64)])
            mats.append(_polylines(p0[on], p1[on], t0[on], t1[on], attrs, tol))
            off = ~on & np.any(p0 != p1, axis=1)  # moves without travel (filament only) draw nothing
            travs.append(_polylines(p0[off], p1[off], t0[off], t1[off], np.zeros((int(off.sum()), 0), np.int64), tol))
        material.append(_Paths.concat(mats, 3))
        travel.append(_Paths.concat(travs, 0))
    return material, travel


def _thin_evenly(paths: list[_Paths], most: int) -> tuple[list[_Paths], dict[str, int] | None]:
    """At most ``most`` segments of all robots' ``paths``, spread evenly over them in order."""
    total = sum(p.segments for p in paths)
    if total <= most:
        return paths, None
    pick = np.linspace(0, total - 1, most).astype(np.int64)
    out, first = [], 0
    for p in paths:
        mine = pick[np.searchsorted(pick, first):np.searchsorted(pick, first + p.segments)] - first
        out.append(_thin(p, np.unique(mine)))
        first += p.segments
    return out, {"shown": int(sum(p.segments for p in out)), "total": int(total)}


def feature_edges(vertices: np.ndarray, faces: np.ndarray, angle_deg: float = FEATURE_ANGLE_DEG) -> np.ndarray:
    """(k, 2, 3) the edges of a triangle mesh (a soup is welded at 1 µm) where its faces meet at
    more than ``angle_deg``, or that do not join exactly two faces: a chunk's outline."""
    if not len(faces):
        return np.zeros((0, 2, 3))
    q = np.rint(np.asarray(vertices, np.float64) * 1000).astype(np.int64)
    uniq, inv = np.unique(q, axis=0, return_inverse=True)
    f = inv.reshape(-1)[np.asarray(faces)]
    pts = uniq / 1000.0
    tri = pts[f]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    edges = np.sort(np.stack([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]], axis=1).reshape(-1, 2), axis=1)
    face = np.repeat(np.arange(len(f)), 3)
    key = edges[:, 0] * (len(pts) + 1) + edges[:, 1]
    order = np.argsort(key, kind="stable")
    key, edges, face = key[order], edges[order], face[order]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    count = np.diff(np.append(start, len(key)))
    pair = start[count == 2]
    sharp = np.einsum("ij,ij->i", normal[face[pair]], normal[face[pair + 1]]) < np.cos(np.radians(angle_deg))
    chosen = np.concatenate([start[count != 2], pair[sharp]])
    return pts[edges[np.sort(chosen)]]


def build_geometry(result: SimResult, chunks: Mapping[str, Any] | None = None, max_segments: int = MAX_SEGMENTS,
                   max_travel: int = MAX_TRAVEL, tolerance: float | None = None) -> ViewerGeometry:
    """The page's geometry of a simulated plan (see the module docstring); ``chunks``: chunk id ->
    mesh (``vertices``, ``faces``: a bundle's chunk meshes) for the chunks' outlines."""
    chunk_ids: list[str] = []
    for r in result.robots:
        chunk_ids += [c for c in r.program.chunks if c not in chunk_ids]
    outlines = [(cid, feature_edges(m.vertices, m.faces)) for cid, m in (chunks or {}).items()]
    edges = np.concatenate([e for _, e in outlines]) if outlines else np.zeros((0, 2, 3))
    edge_chunk = np.concatenate([np.full(len(e), i) for i, (_, e) in enumerate(outlines)]) if outlines \
        else np.zeros(0, np.int64)
    if len(edges) > MAX_OUTLINE_EDGES:
        pick = np.linspace(0, len(edges) - 1, MAX_OUTLINE_EDGES).astype(np.int64)
        edges, edge_chunk = edges[pick], edge_chunk[pick]
    # the bounding box of everything drawn: the moves' ends (a block at a time), the outlines, the starts
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for tl in result.timelines.values():
        for a in range(0, len(tl.t0), BLOCK_MOVES):
            for p in (tl.p0[a:a + BLOCK_MOVES], tl.p1[a:a + BLOCK_MOVES]):
                lo, hi = np.minimum(lo, p.min(axis=0)), np.maximum(hi, p.max(axis=0))
    starts = [_start(result, r) for r in result.robots]
    for p in [edges.reshape(-1, 3)] + [np.array([s]) for s in starts]:
        if len(p):
            lo, hi = np.minimum(lo, p.min(axis=0)), np.maximum(hi, p.max(axis=0))
    if not np.all(np.isfinite(lo)):
        lo, hi = np.zeros(3), np.ones(3)
    span = np.maximum(hi - lo, 1e-6)
    tol = display_tolerance(hi - lo) if tolerance is None else float(tolerance)
    material, travel = _collect(result, tol, chunk_ids)
    before_lod = sum(p.segments for p in material)
    material, thinned = _thin_evenly(material, max_segments)
    travel, travel_thinned = _thin_evenly(travel, max_travel)
    unit = max(1e-3, result.makespan / 2.0**31)  # every delta fits 32 bits

    def quant(p: np.ndarray) -> np.ndarray:
        return np.clip(np.rint((p - lo) / span * QMAX), 0, QMAX).astype(np.uint16)

    heights = np.unique(np.concatenate([m.attrs[:, 2] for m in material])) if material else np.zeros(0, np.int64)
    if len(heights) > 255:  # too many to list: 255 steps from the least to the most
        heights = np.unique(np.linspace(heights.min(), heights.max(), 255).round().astype(np.int64))
    w = _Writer()
    robots = []
    for i, (r, mat, trav) in enumerate(zip(result.robots, material, travel)):
        rec: dict[str, Any] = {"name": r.name, "start": [float(x) for x in starts[i]],
                               "end": float(result.timelines[r.name].end)}
        for kind, paths in (("material", mat), ("travel", trav)):
            q = quant(paths.pos)
            w.add(f"{i}/{kind}/pos", np.diff(q, axis=0, prepend=np.zeros((1, 3), np.uint16)), "shuffle")
            tq = np.rint(paths.time / unit).astype(np.int64)
            w.add(f"{i}/{kind}/time", np.diff(tq, prepend=0).astype(np.uint32), "shuffle")
            w.add(f"{i}/{kind}/lengths", paths.lengths.astype(np.uint32), "shuffle")
            rec[kind] = {"vertices": len(paths.time), "polylines": len(paths.lengths), "segments": paths.segments}
        for j, name in enumerate(("chunk", "role", "height")):
            v = mat.attrs[:, j]
            if name == "height":
                v = np.clip(np.searchsorted(heights, v), 0, max(len(heights) - 1, 0))
            at, val = _runs(v)
            w.add(f"{i}/material/{name}_at", at, "shuffle")
            w.add(f"{i}/material/{name}", val.astype(np.int16 if name == "chunk" else np.uint8))
        robots.append(rec)
    w.add("outlines/pos", np.diff(quant(edges.reshape(-1, 3)), axis=0, prepend=np.zeros((1, 3), np.uint16)),
          "shuffle")
    w.add("outlines/chunk", edge_chunk.astype(np.uint16))
    header = {"format": FORMAT, "lo": lo.tolist(), "hi": hi.tolist(), "qmax": QMAX, "time_unit": unit,
              "tolerance": tol, "robots": robots, "chunks": chunk_ids,
              "outline_chunks": [cid for cid, _ in outlines],
              "roles": [{"name": ROLE_NAMES[k], "colour": list(ROLE_COLOURS[k])} for k in range(len(ROLE_NAMES))],
              "heights": [h / 1000.0 for h in heights.tolist()],
              "segments": {"deposits": int(sum(int(np.count_nonzero(tl.on[a:a + BLOCK_MOVES]))
                                            for tl in result.timelines.values()
                                            for a in range(0, len(tl.t0), BLOCK_MOVES))),
                           "merged": before_lod, "shown": int(sum(p.segments for p in material)),
                           "travel": int(sum(p.segments for p in travel))},
              "thinned": thinned, "travel_thinned": travel_thinned, "directory": w.directory}
    return ViewerGeometry(header, b"".join(w.parts))


def _start(result: SimResult, r) -> np.ndarray:
    """Where robot ``r``'s nozzle is before its first move (its start, or its first move's start)."""
    tl = result.timelines[r.name]
    if r.start is not None:
        return np.asarray(r.start, np.float64)
    return np.asarray(tl.p0[0], np.float64) if len(tl.t0) else np.zeros(3)


def decode(header: Mapping[str, Any], encoded: str) -> dict[str, np.ndarray]:
    """The arrays of a page's geometry (``header``, the base64 gzip ``encoded`` payload), as the
    page decodes them: per robot ``i``, ``i/material/pos`` (m, 3) mm, ``i/material/time`` (m,)
    s, ``i/material/lengths``, the attributes per segment (``i/material/chunk``, ``role``,
    ``height`` in mm), the same for ``travel``; ``outlines/pos`` (k, 2, 3) mm."""
    raw = gzip.decompress(base64.b64decode(encoded))
    lo, hi = np.array(header["lo"]), np.array(header["hi"])
    span = np.maximum(hi - lo, 1e-6)
    arrays = {}
    for name, d in header["directory"].items():
        chunk = raw[d["offset"]:d["offset"] + d["bytes"]]
        shape = tuple(d["shape"])
        arrays[name] = (_unshuffled(chunk, d["dtype"], shape) if d["codec"] == "shuffle"
                        else np.frombuffer(chunk, np.dtype(d["dtype"])).reshape(shape))
    out: dict[str, np.ndarray] = {}
    for name, a in arrays.items():
        if name.endswith("/pos"):
            q = np.cumsum(a.astype(np.int64), axis=0) % (QMAX + 1)
            pos = lo + q / header["qmax"] * span
            out[name] = pos.reshape(-1, 2, 3) if name.startswith("outlines/") else pos
        elif name.endswith("/time"):
            out[name] = np.cumsum(a.astype(np.int64)) * header["time_unit"]
        elif not name.endswith("_at"):
            out[name] = a
    for i, rec in enumerate(header["robots"]):
        n = rec["material"]["segments"]
        for attr in ("chunk", "role", "height"):
            at, val = arrays[f"{i}/material/{attr}_at"].astype(np.int64), arrays[f"{i}/material/{attr}"]
            per = np.repeat(val, np.diff(np.append(at, n)))
            out[f"{i}/material/{attr}"] = np.asarray(header["heights"])[per] if attr == "height" and len(per) else per
    return out


__all__ = ["LOD_TOLERANCE_MM", "MAX_SEGMENTS", "ViewerGeometry", "build_geometry", "decode", "display_tolerance",
           "feature_edges", "simplify"]
