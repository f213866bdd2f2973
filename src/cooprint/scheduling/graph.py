"""From a :class:`~cooprint.chunking.ChunkSet` to the scheduler's :class:`ChunkDAG` (issue 14,
item 2): the work of each chunk, where its robot stands, and the three kinds of constraint.

* (a) **precedence**: the layout's ``deps`` (a chunk leans on the faces of those).
* (b) **body rule**: while a robot prints chunk X its nozzle goes over X's footprint (the convex
  hull of X's vertices in XY) in X's facing, so its body (``u in [-bd - bl, -bd]``,
  ``|v| <= bw / 2`` in the robot's frame) sweeps the Minkowski sum of that hull and the turned
  body rectangle. A robot must never stand on material, so every other chunk whose hull reaches
  into that sweep (by more than :data:`TOUCH`: chunks that only touch it do not count) is printed
  after X. If such a chunk must come before X anyway, no order can print the layout: that is a
  :class:`~cooprint.errors.UserError`.
* (c) **exclusion**: two chunks whose robots' whole outlines (body, frame, printhead:
  :meth:`RobotProfile.outline`), each swept over its own chunk's hull in its own facing, come
  closer than ``clearance`` may never be printed at the same time. Pairs the constraints (a) and
  (b) already order (one is an ancestor of the other) are left out: they never overlap in time.

Every shape is a convex polygon (a hull, or a hull swept by a rectangle: again a hull), points
in numpy arrays; pairs are found by vectorised box tests and decided by the separating-axis
test, a batch of pairs at a time, so a thousand chunks take a fraction of a second.

Work estimates: :func:`work_from_layers` times a chunk's sliced layers exactly as the simulator
times them (:func:`cooprint.simulation.timeline.move_durations` on a ``.coop`` plan: the
profile's ``print_speed`` on every depositing move, ``travel_speed`` on the others), and
:func:`work_from_volume` estimates it before slicing (``cooprint chunk``).
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from cooprint.chunking import Chunk, ChunkSet
from cooprint.config import RobotProfile, SlicingSettings
from cooprint.errors import UserError
from cooprint.geometry import unit_xy
from cooprint.scheduling.dag import ChunkDAG
from cooprint.slicing.paths import LayerPaths

#: Work of a chunk with nothing to print, s: positive, so that every chunk is a real job.
MIN_WORK = 1e-3
#: How far (mm) a chunk must reach into a robot's body sweep before the body rule orders it:
#: chunks that merely touch (a shared cut face, a rounding error) do not count.
TOUCH = 0.5
#: Rounding slack of the exclusion test, mm: outlines that touch are not closer than 0.
EXACT = 1e-6
#: Pairs of polygons tested per numpy batch (keeps the (pairs, k, k) temporaries a few MB).
BATCH = 4096

# -- convex polygons --------------------------------------------------------------------------

#: Eight directions for the Akl-Toussaint prefilter of :func:`convex_hull`, counter-clockwise.
_DIRS = np.array([[math.cos(a), math.sin(a)] for a in np.arange(8) * math.pi / 4])


def convex_hull(points: np.ndarray) -> np.ndarray:
    """(k, 2) the convex hull of (n, 2) points, counter-clockwise, no repeated or collinear
    vertex (Andrew's monotone chain). The points strictly inside the octagon of the extreme
    points in eight directions are dropped first (vectorised), so the chain walks only the few
    near the boundary."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    p = p[np.lexsort((p[:, 1], p[:, 0]))]
    if len(p) > 1:
        p = p[np.r_[True, (np.diff(p, axis=0) != 0).any(axis=1)]]
    if len(p) <= 2:
        return p
    ext = p[np.argmax(p @ _DIRS.T, axis=0)]
    ext = ext[(ext != np.roll(ext, 1, axis=0)).any(axis=1)]
    if len(ext) >= 3:
        e = np.roll(ext, -1, axis=0) - ext
        cross = e[:, 0] * (p[:, None, 1] - ext[:, 1]) - e[:, 1] * (p[:, None, 0] - ext[:, 0])
        scale = float(np.abs(p).max()) + 1.0
        p = p[~(cross > 1e-9 * scale * scale).all(axis=1)]
    xs, ys = p[:, 0].tolist(), p[:, 1].tolist()

    def chain(order: range) -> list[int]:
        out: list[int] = []
        for i in order:
            while len(out) >= 2:
                a, b = out[-2], out[-1]
                if (xs[b] - xs[a]) * (ys[i] - ys[a]) - (ys[b] - ys[a]) * (xs[i] - xs[a]) > 0:
                    break
                out.pop()
            out.append(i)
        return out

    lower = chain(range(len(p)))
    upper = chain(range(len(p) - 1, -1, -1))
    return p[lower[:-1] + upper[:-1]]


def _rect_corners(rect: Sequence[float], facing: np.ndarray) -> np.ndarray:
    """(4, 2) world XY corners, relative to the nozzle, of ``rect = (u_lo, u_hi, v_lo, v_hi)``
    in the frame of a robot facing ``facing`` (u along it, v to its left)."""
    u0, u1, v0, v1 = rect
    left = np.array([-facing[1], facing[0]])
    u = np.array([u0, u1, u1, u0])
    v = np.array([v0, v0, v1, v1])
    return u[:, None] * facing + v[:, None] * left


def _from_lowest(poly: np.ndarray) -> np.ndarray:
    """A counter-clockwise convex polygon started at its lowest vertex (the leftmost of the
    lowest): from there its edges turn through angles that rise from [0, pi) to below 2 pi."""
    k = int(np.lexsort((poly[:, 0], poly[:, 1]))[0])
    return np.roll(poly, -k, axis=0)


def swept(hull: np.ndarray, rect: Sequence[float], facing: np.ndarray) -> np.ndarray:
    """The convex polygon a robot part ``rect`` covers while the nozzle goes over ``hull`` (a
    counter-clockwise convex polygon): their Minkowski sum, walked from the sum of their lowest
    vertices along the edges of both in the order of their angles (no hull needed)."""
    p = _from_lowest(hull)
    r = _from_lowest(_rect_corners(rect, facing))
    edges = np.vstack([np.roll(p, -1, axis=0) - p, np.roll(r, -1, axis=0) - r])
    edges = edges[(edges != 0).any(axis=1)]
    angle = np.arctan2(edges[:, 1], edges[:, 0])
    angle = np.where(angle < 0, angle + 2 * math.pi, angle)
    steps = np.cumsum(edges[np.argsort(angle, kind="stable")][:-1], axis=0)
    return p[0] + r[0] + np.vstack([np.zeros((1, 2)), steps])


class _Polygons:
    """Convex polygons padded to one array: vertices (N, K, 2) (the last one repeated),
    unit edge normals (N, K, 2) (the last one repeated over the padding), vertex counts and
    boxes."""

    def __init__(self, polys: Sequence[np.ndarray]):
        counts = np.array([len(q) for q in polys], dtype=np.int64)
        k = int(counts.max(initial=1))
        flat = np.concatenate(polys) if polys else np.zeros((0, 2))
        first = np.r_[0, np.cumsum(counts)[:-1]]
        j = np.arange(k)[None, :]
        idx = first[:, None] + np.minimum(j, counts[:, None] - 1)
        nxt = first[:, None] + (np.minimum(j, counts[:, None] - 1) + 1) % counts[:, None]
        self.count = counts
        self.verts = flat[idx]
        e = flat[nxt] - self.verts
        nrm = np.stack([e[..., 1], -e[..., 0]], axis=-1)
        length = np.linalg.norm(nrm, axis=-1, keepdims=True)
        self.normals = np.where(length > 0, nrm / np.where(length > 0, length, 1.0), [1.0, 0.0])
        self.box = np.column_stack([self.verts.min(axis=1), self.verts.max(axis=1)]).reshape(len(polys), 4)


def _separation(pa: _Polygons, ia: np.ndarray, pb: _Polygons, ib: np.ndarray) -> np.ndarray:
    """(p,) for each pair of convex polygons ``pa[ia[j]]``, ``pb[ib[j]]``: the largest gap
    between their projections over the edge normals of both (separating-axis test). Above 0
    they are apart (by at least that much); at or below 0 they overlap, by ``-gap`` (the
    smallest overlap of all axes: how far one reaches into the other)."""
    out = np.empty(len(ia))
    order = np.argsort(np.maximum(pa.count[ia], pb.count[ib]), kind="stable")
    for lo in range(0, len(order), BATCH):
        sel = order[lo:lo + BATCH]
        a, b = ia[sel], ib[sel]
        ka, kb = int(pa.count[a].max()), int(pb.count[b].max())
        va, na = pa.verts[a, :ka], pa.normals[a, :ka]
        vb, nb = pb.verts[b, :kb], pb.normals[b, :kb]
        gap = np.full(len(sel), -np.inf)
        for axes in (na, nb):
            sa = np.einsum("pkd,pjd->pkj", va, axes)
            sb = np.einsum("pkd,pjd->pkj", vb, axes)
            g = np.maximum(sa.min(axis=1) - sb.max(axis=1), sb.min(axis=1) - sa.max(axis=1))
            gap = np.maximum(gap, g.max(axis=1))
        out[sel] = gap
    return out


def _distance(pa: _Polygons, ia: np.ndarray, pb: _Polygons, ib: np.ndarray) -> np.ndarray:
    """(p,) the distance between disjoint convex polygons: the shortest from a vertex of one to
    an edge of the other (exact for disjoint convex polygons)."""
    out = np.empty(len(ia))
    for lo in range(0, len(ia), BATCH // 8):
        a, b = ia[lo:lo + BATCH // 8], ib[lo:lo + BATCH // 8]
        ka, kb = int(pa.count[a].max()), int(pb.count[b].max())
        va, vb = pa.verts[a, :ka], pb.verts[b, :kb]
        best = np.full(len(a), np.inf)
        for v, w, kw, cw in ((va, vb, kb, pb.count[b]), (vb, va, ka, pa.count[a])):
            # edges of w: vertex j to vertex j + 1, the last real vertex back to the first
            nxt = np.minimum(np.arange(kw) + 1, kw - 1)[None, :].repeat(len(a), 0)
            nxt[np.arange(kw)[None, :] >= (cw - 1)[:, None]] = 0
            e0 = w
            d = np.take_along_axis(w, nxt[:, :, None], axis=1) - e0
            rel = v[:, :, None, :] - e0[:, None, :, :]
            dd = (d * d).sum(axis=-1)[:, None, :]
            t = np.clip((rel * d[:, None]).sum(axis=-1) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
            dist = np.linalg.norm(rel - t[..., None] * d[:, None], axis=-1)
            best = np.minimum(best, dist.reshape(len(a), -1).min(axis=1))
        out[lo:lo + len(a)] = best
    return out


def _box_pairs(box_a: np.ndarray, box_b: np.ndarray, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Index pairs ``(i, j)`` whose XY boxes (``xmin, ymin, xmax, ymax``) overlap by more than
    ``-margin`` on both axes (``margin`` > 0: boxes that far apart still count; < 0: they must
    overlap by that much). Rows in blocks, so that n x n booleans are never held at once."""
    ii, jj = [], []
    step = max(1, (1 << 22) // max(len(box_b), 1))
    for lo in range(0, len(box_a), step):
        a = box_a[lo:lo + step, None, :]
        b = box_b[None, :, :]
        near = ((np.minimum(a[..., 2], b[..., 2]) - np.maximum(a[..., 0], b[..., 0]) > -margin)
                & (np.minimum(a[..., 3], b[..., 3]) - np.maximum(a[..., 1], b[..., 1]) > -margin))
        i, j = np.nonzero(near)
        ii.append(i + lo)
        jj.append(j)
    if not ii:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(ii), np.concatenate(jj)


# -- the DAG ---------------------------------------------------------------------------------


def _ancestors(n: int, preds: list[list[int]], order: list[int]) -> np.ndarray:
    """(n, n) bool: ``anc[i, j]`` when chunk j must be finished before chunk i (transitively),
    from each chunk's direct predecessors and a topological order."""
    anc = np.zeros((n, n), dtype=bool)
    for i in order:
        for p in preds[i]:
            anc[i] |= anc[p]
            anc[i, p] = True
    return anc


def _topological(n: int, preds: list[list[int]]) -> list[int] | None:
    """Indices with every chunk after its predecessors, or ``None`` on a cycle."""
    indeg = [len(p) for p in preds]
    succ: list[list[int]] = [[] for _ in range(n)]
    for i, ps in enumerate(preds):
        for p in ps:
            succ[p].append(i)
    ready = [i for i in range(n) if indeg[i] == 0]
    order = []
    while ready:
        i = ready.pop()
        order.append(i)
        for s in succ[i]:
            indeg[s] -= 1
            if indeg[s] == 0:
                ready.append(s)
    return order if len(order) == n else None


def _chain(preds: list[list[int]], src: int, dst: int) -> list[int] | None:
    """A chain of predecessor links from ``src`` (first) to ``dst`` (last): ``src`` must be
    finished before ``dst``; ``None`` when it need not."""
    back = {dst: -1}
    todo = [dst]
    while todo:
        i = todo.pop()
        for p in preds[i]:
            if p not in back:
                back[p] = i
                todo.append(p)
    if src not in back:
        return None
    out = [src]
    while back[out[-1]] != -1:
        out.append(back[out[-1]])
    return out


def _outer_base_middle(box: np.ndarray, facing: np.ndarray, z: float) -> np.ndarray:
    """(3,) the middle of the footprint's edge on the body's side: from the box's centre
    against ``facing`` to the box's boundary, at the chunk's base."""
    centre = (box[:2] + box[2:]) / 2
    half = (box[2:] - box[:2]) / 2
    f = np.abs(facing)
    t = min((half[k] / f[k] for k in range(2) if f[k] > 1e-12), default=0.0)
    return np.r_[centre - t * facing, z]


def build_dag(chunks: ChunkSet, robot: RobotProfile, clearance: float, work: Mapping[str, float],
              travel_speed: float, ends: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None) -> ChunkDAG:
    """The :class:`ChunkDAG` of ``chunks`` for robots of profile ``robot``.

    Parameters
    ----------
    chunks
        A layout's chunks; the DAG keeps their order.
    robot
        The robots' profile (the outline: body, frame, printhead).
    clearance
        Outlines closer than this (mm, XY) make two chunks exclusive (``[program] clearance``).
    work
        ``{chunk id: s}`` (:func:`work_from_layers` or :func:`work_from_volume`); a chunk with
        nothing to print (0) gets :data:`MIN_WORK`.
    travel_speed
        mm/s, for :meth:`ChunkDAG.travel`.
    ends
        ``{chunk id: (first xyz, last xyz)}`` printed (:func:`ends_from_layers`); a chunk not in
        it starts and ends at the middle of its footprint's edge on the body's side, at its base.

    Raises
    ------
    UserError
        A robot's body would stand on a chunk that must be printed before the one it prints.
    """
    ids = tuple(c.id for c in chunks.chunks)
    n = len(ids)
    index = {c: i for i, c in enumerate(ids)}
    missing = [c for c in ids if c not in work]
    if missing:
        raise ValueError(f"build_dag: no work given for chunk {missing[0]}")
    w = np.array([float(work[c]) for c in ids])
    if not np.isfinite(w).all():
        raise ValueError(f"build_dag: work of chunk {ids[int(np.flatnonzero(~np.isfinite(w))[0])]} is not finite")
    w = np.maximum(w, MIN_WORK)
    axis = unit_xy(chunks.plan.axis)
    facing = np.array([axis if c.facing is None else unit_xy(c.facing) for c in chunks.chunks]).reshape(n, 2)
    hulls = [convex_hull(c.vertices[:, :2]) for c in chunks.chunks]
    footprint = np.array([np.r_[c.vertices[:, :2].min(axis=0), c.vertices[:, :2].max(axis=0)]
                          for c in chunks.chunks]).reshape(n, 4)
    start, end = np.empty((n, 3)), np.empty((n, 3))
    for i, c in enumerate(chunks.chunks):
        if ends is not None and c.id in ends:
            start[i], end[i] = (np.asarray(p, dtype=np.float64)[:3] for p in ends[c.id])
        else:
            start[i] = end[i] = _outer_base_middle(footprint[i], facing[i], float(c.vertices[:, 2].min()))

    deps = {c: tuple(chunks.deps.get(c, ())) for c in ids}
    preds = [[index[d] for d in deps[c]] for c in ids]
    outline = robot.outline()
    parts = [[swept(hulls[i], outline[p], facing[i]) for p in ("body", "frame", "printhead")] for i in range(n)]

    # (b) the body rule: chunks reaching into X's body sweep come after X
    bodies, footprints = _Polygons([pp[0] for pp in parts]), _Polygons(hulls)
    bx, by = _box_pairs(bodies.box, footprints.box, -TOUCH)
    keep = bx != by
    bx, by = bx[keep], by[keep]
    depth = -_separation(bodies, bx, footprints, by)
    hit = depth > TOUCH
    body_pred: list[list[int]] = [[] for _ in range(n)]
    for x, y in sorted(zip(bx[hit].tolist(), by[hit].tolist())):
        body_pred[y].append(x)
    both = [list(dict.fromkeys(preds[i] + body_pred[i])) for i in range(n)]
    order = _topological(n, both)
    if order is None:
        _unprintable(ids, preds, body_pred, both, depth[hit], bx[hit], by[hit], robot, facing)
    assert order is not None
    anc = _ancestors(n, both, order)

    # (c) exclusions: outlines swept over their chunks within clearance, unless already ordered
    boxes = np.array([np.r_[np.min([q.min(axis=0) for q in pp], axis=0), np.max([q.max(axis=0) for q in pp], axis=0)]
                      for pp in parts]).reshape(n, 4)
    ca, cb = _box_pairs(boxes, boxes, clearance)
    keep = (ca < cb) & ~anc[ca, cb] & ~anc[cb, ca]
    ca, cb = ca[keep], cb[keep]
    pieces = _Polygons([q for pp in parts for q in pp])
    part = np.arange(3)
    pa = (3 * ca[:, None, None] + part[None, :, None] + 0 * part[None, None, :]).ravel()  # 3 x 3 parts a pair
    pb = (3 * cb[:, None, None] + 0 * part[None, :, None] + part[None, None, :]).ravel()
    pair = np.arange(len(ca)).repeat(9)
    gap_a = np.minimum(pieces.box[pb, 2:], pieces.box[pa, 2:]) - np.maximum(pieces.box[pb, :2], pieces.box[pa, :2])
    near = (gap_a > -clearance).all(axis=1)
    pa, pb, pair = pa[near], pb[near], pair[near]
    gap = _separation(pieces, pa, pieces, pb)
    limit = clearance - EXACT  # touching outlines are not closer than a clearance of 0
    close = gap < limit
    between = close & (gap > 0)
    if between.any():
        close[between] = _distance(pieces, pa[between], pieces, pb[between]) < limit
    excl = np.zeros(len(ca), dtype=bool)
    excl[pair[close]] = True
    exclusive = tuple((ids[a], ids[b]) for a, b in sorted(zip(ca[excl].tolist(), cb[excl].tolist())))
    return ChunkDAG(ids=ids, work=w, facing=facing, start=start, end=end, footprint=footprint, deps=deps,
                    body_deps={c: tuple(ids[x] for x in sorted(body_pred[i])) for i, c in enumerate(ids)},
                    exclusive=exclusive, travel_speed=float(travel_speed))


def _unprintable(ids: tuple[str, ...], preds: list[list[int]], body_pred: list[list[int]], both: list[list[int]],
                 depth: np.ndarray, bx: np.ndarray, by: np.ndarray, robot: RobotProfile, facing: np.ndarray) -> None:
    """Raise the one-line error for a body rule that contradicts the order: X's body sweeps
    over Y, and Y must be printed before X."""
    if _topological(len(ids), preds) is None:
        raise ValueError("the layout's chunk dependencies form a cycle")
    for x, y, d in zip(bx.tolist(), by.tolist(), depth.tolist()):
        chain = _chain(both, y, x)
        if chain is None:
            continue
        deg = math.degrees(math.atan2(facing[x][1], facing[x][0]))
        raise UserError(
            f"chunk {ids[x]}: its robot's body would stand on chunk {ids[y]}, which must be printed before it "
            f"({' -> '.join(ids[k] for k in chain)}; facing {deg:.0f} deg the body, {robot.build_depth:g} to "
            f"{robot.build_depth + robot.body_length:g} mm behind the nozzle, reaches {d:.0f} mm into "
            f"{ids[y]}'s footprint): face the robot the other way or choose another layout")
    raise ValueError("the chunk constraints form a cycle")  # pragma: no cover (a body edge closes every cycle)


# -- work estimates --------------------------------------------------------------------------


def _layer_moves(layers: Sequence[tuple[int, LayerPaths]]):
    """Yield each non-empty layer's program piece (:func:`layer_program`) of one chunk, the
    nozzle starting at the chunk's first point, and where each piece starts."""
    from cooprint.program.build import layer_program
    from cooprint.program.commands import quantize

    here = None
    for li, layer in layers:
        if not len(layer):
            continue
        if here is None:
            here = quantize(np.r_[layer.points[0], layer.z])
        piece, nxt = layer_program(layer, here, index=li)
        yield piece, here
        here = nxt


def work_from_layers(layers: Mapping[str, Sequence[tuple[int, LayerPaths]]], robot: RobotProfile,
                     slicing: SlicingSettings, *, gcode: bool = False) -> dict[str, float]:
    """``{chunk id: s}``: the constant-speed time of each chunk's layer moves, from its first
    printed point to its last, as the robot programs make them
    (:func:`cooprint.program.build.layer_program`).

    The times are the simulator's for a ``cooprint run`` plan
    (:func:`cooprint.simulation.timeline.move_durations` on a ``.coop`` robot): length over the
    profile's ``print_speed`` for a move that deposits (tool on, length > 0), over its
    ``travel_speed`` for any other. With ``gcode`` they are the written G-code's instead
    (:meth:`Feeds.of_robot`: the first layer at ``min(slicing.first_layer_speed,
    print_speed)``). The way into the chunk and out of it are travel between chunks
    (:meth:`ChunkDAG.travel`), not work.
    """
    from cooprint.program.commands import MOVE
    from cooprint.program.gcode import Feeds

    feeds = Feeds.of_robot(robot, slicing)
    out = {}
    for cid, chunk_layers in layers.items():
        total = 0.0
        for piece, here in _layer_moves(chunk_layers):
            mv = piece.kind == MOVE
            xyz = piece.xyz[mv]
            p0 = np.vstack([here[None], xyz[:-1]])
            length = np.linalg.norm(xyz - p0, axis=1)
            if gcode:
                speed = feeds.speeds(piece)[mv]
            else:
                speed = np.where(piece.tool_on()[mv] & (length > 0), robot.print_speed, robot.travel_speed)
            total += float((length / speed).sum())
        out[cid] = total
    return out


def ends_from_layers(layers: Mapping[str, Sequence[tuple[int, LayerPaths]]]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``{chunk id: (first xyz, last xyz)}``: where the nozzle starts printing each chunk (its
    first layer's first point) and where it ends (its last layer's last point), on the 1 µm
    grid of the programs; chunks with nothing to print are left out."""
    from cooprint.program.commands import quantize

    out = {}
    for cid, chunk_layers in layers.items():
        full = [layer for _, layer in chunk_layers if len(layer)]
        if full:
            first, last = full[0], full[-1]
            out[cid] = (quantize(np.r_[first.points[0], first.z]), quantize(np.r_[last.points[-1], last.z]))
    return out


#: :func:`work_from_volume`'s factor: the time of the sliced layers (:func:`work_from_layers`)
#: over the printed-volume model, measured on 17 chunks of 7 generated parts (car 420 mm, box
#: 300 x 900 x 60, cylinder r 60 h 120, hollow box, lying tube, plate 900 x 400 x 10, slender
#: post; seed2 layout, default robot and slicing): median 1.104, range 1.005 (lying tube) to
#: 1.260 (the hollow box's 10 mm walls), coefficient of variation 5%. The rest is travel
#: between paths and perimeter overlap. (Volume alone, without the shells, spread 0.256 to 0.397,
#: 17%, and its factor holds only for one infill density.)
VOLUME_FACTOR = 1.10


def printed_volume(chunk: Chunk, slicing: SlicingSettings) -> float:
    """mm^3 the slicer will deposit in ``chunk``, estimated from its mesh: a shell of
    ``perimeters`` extrusion widths horizontally behind every face (its area times the XY part
    of its unit normal), of ``top_layers`` / ``bottom_layers`` layers vertically under faces
    looking up / over faces looking down (area times the Z part), at most the volume; the rest
    filled at ``infill_density``. Cut faces are faces: each chunk is sliced on its own, so they
    get perimeters too."""
    tri = chunk.vertices[chunk.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) / 2  # area times unit normal
    side = float(np.linalg.norm(n[:, :2], axis=1).sum())
    up, down = float(n[:, 2].clip(min=0).sum()), float((-n[:, 2]).clip(min=0).sum())
    shell = (side * slicing.perimeters * slicing.extrusion_width
             + (up * slicing.top_layers + down * slicing.bottom_layers) * slicing.layer_height)
    shell = min(shell, chunk.volume)
    return shell + slicing.infill_density * (chunk.volume - shell)


def work_from_volume(chunks: ChunkSet, robot: RobotProfile, slicing: SlicingSettings) -> dict[str, float]:
    """``{chunk id: s}`` before slicing (``cooprint chunk``): the :func:`printed_volume` over the
    deposition rate ``extrusion_width * layer_height * print_speed``, times
    :data:`VOLUME_FACTOR` (the travel between paths and the overlaps the model leaves out)."""
    rate = slicing.extrusion_width * slicing.layer_height * robot.print_speed
    return {c.id: VOLUME_FACTOR * printed_volume(c, slicing) / rate for c in chunks.chunks}


__all__ = ["MIN_WORK", "TOUCH", "VOLUME_FACTOR", "build_dag", "convex_hull", "ends_from_layers", "printed_volume",
           "swept", "work_from_layers", "work_from_volume"]
