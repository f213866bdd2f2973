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

Every shape is a convex polygon (a hull, or a hull swept by a rectangle: their Minkowski sum),
points in numpy arrays; pairs are found by vectorised box tests and decided, a batch of pairs
at a time, by the signed distance of two convex polygons from their Minkowski difference (the
separating-axis gap when they overlap, the exact distance when apart): a thousand chunks take a
fraction of a second (:func:`signed_distance`).

Work estimates: :func:`work_from_layers` times a chunk's sliced layers exactly as the simulator
and the G-code time them (:func:`cooprint.simulation.timeline.move_durations` on a ``.coop``
plan: every move at the robot's :class:`~cooprint.program.gcode.Feeds`, the slicer's speed of its
path role under the robot's caps), and :func:`work_from_volume` estimates it before slicing
(``cooprint chunk``).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING, Mapping, Sequence

import numpy as np

from cooprint.chunking import Chunk, ChunkSet
from cooprint.config import RobotProfile, SlicingSettings
from cooprint.errors import UserError
from cooprint.geometry import unit_xy
from cooprint.scheduling.dag import ChunkDAG
from cooprint.slicing.paths import LayerPaths

if TYPE_CHECKING:
    from cooprint.program.commands import Program

#: Work of a chunk with nothing to print, s: positive, so that every chunk is a real job.
MIN_WORK = 1e-3
#: How far (mm) a chunk must reach into a robot's body sweep before the body rule orders it:
#: chunks that merely touch (a shared cut face, a rounding error) do not count.
TOUCH = 0.5
#: A vertex whose edges turn by less than this (sine of the angle) is on a straight edge and
#: dropped, so that rounding never makes a polygon's edge angles run backwards.
STRAIGHT = 1e-9
#: Rounding slack of the exclusion test, mm: outlines that touch are not closer than 0.
EXACT = 1e-6

# -- convex polygons --------------------------------------------------------------------------

#: Sixteen directions for the prefilter of :func:`convex_hull`, counter-clockwise.
_DIRS = np.array([[math.cos(a), math.sin(a)] for a in np.arange(16) * math.pi / 8])


def convex_hull(points: np.ndarray) -> np.ndarray:
    """(k, 2) the convex hull of (n, 2) points, counter-clockwise from its lowest vertex (the
    leftmost of the lowest), without repeated vertices or vertices on straight edges.

    Whole-array: the points strictly inside the polygon of the extreme points in sixteen
    directions are dropped (Akl-Toussaint); the rest, in angular order around a point inside
    that polygon, form a star-shaped polygon whose every vertex that does not turn left is
    dropped at once, pass after pass, until all turn left (a Graham scan done in parallel: an
    extreme point always turns left, so only inner points go)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if len(p) > 16:
        pt = np.ascontiguousarray(p.T)
        ext = p[np.argmax(_DIRS @ pt, axis=1)]
        ext = ext[(ext != np.roll(ext, 1, axis=0)).any(axis=1)]
        if len(ext) >= 3:
            e = np.roll(ext, -1, axis=0) - ext
            normal = np.column_stack([e[:, 1], -e[:, 0]])  # outward
            tol = STRAIGHT * float(np.abs(ext).max() + 1.0) * np.hypot(e[:, 0], e[:, 1])
            inside = ((normal @ pt) < ((normal * ext).sum(axis=1) - tol)[:, None]).all(axis=0)
            p = np.vstack([ext, p[~inside]])
    p = p[np.lexsort((p[:, 1], p[:, 0]))]
    if len(p) > 1:
        p = p[np.r_[True, (np.diff(p, axis=0) != 0).any(axis=1)]]
    if len(p) <= 2:
        return p
    centre = p.mean(axis=0)
    d = p - centre
    q = p[np.lexsort((np.hypot(d[:, 0], d[:, 1]), np.arctan2(d[:, 1], d[:, 0])))]
    while len(q) >= 3:
        e_in = q - q[np.r_[len(q) - 1, 0:len(q) - 1]]
        e_out = q[np.r_[1:len(q), 0]] - q
        turn = e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0]
        left = turn > STRAIGHT * np.hypot(e_in[:, 0], e_in[:, 1]) * np.hypot(e_out[:, 0], e_out[:, 1])
        if left.all():
            break
        q = q[left]
    if len(q) < 3:  # all on one line: its two ends
        return p[[0, -1]]
    return np.roll(q, -int(np.lexsort((q[:, 0], q[:, 1]))[0]), axis=0)


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
    """Convex counter-clockwise polygons normalised for whole-array work: vertices on straight
    edges and repeated ones dropped, each started at its lowest vertex (the leftmost of the
    lowest), so that its edges' angles rise from [0, pi) to below 2 pi; padded to one array.

    ``verts``, ``edges`` (N, K, 2) (padding: the last vertex, zero edges), ``angle`` (N, K)
    (padding: inf), ``count`` (N,), ``box`` (N, 4); ``neg`` the same for the polygons turned
    through 180 degrees (``-P``, for Minkowski differences)."""

    def __init__(self, polys: Sequence[np.ndarray], negate: bool = True):
        flat = np.concatenate(polys) if len(polys) else np.zeros((0, 2))
        gid = np.repeat(np.arange(len(polys)), [len(q) for q in polys])
        nxt, _ = _cyclic(gid)
        flat, gid = self._keep(flat, gid, (flat[nxt] != flat).any(axis=1), len(polys))  # repeated points
        nxt, prv = _cyclic(gid)
        e_out, e_in = flat[nxt] - flat, flat - flat[prv]
        cross = e_in[:, 0] * e_out[:, 1] - e_in[:, 1] * e_out[:, 0]
        turns = cross > STRAIGHT * np.linalg.norm(e_in, axis=1) * np.linalg.norm(e_out, axis=1)
        flat, gid = self._keep(flat, gid, turns, len(polys))  # points on straight edges
        self._pad(flat, gid, len(polys))
        self.box = np.column_stack([self.verts.min(axis=1), self.verts.max(axis=1)]).reshape(len(polys), 4)
        self.neg = _Polygons.__new__(_Polygons)
        if negate:
            self.neg._pad(-flat, gid, len(polys))

    @staticmethod
    def _keep(flat: np.ndarray, gid: np.ndarray, keep: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
        """The points ``keep`` selects, all points of a polygon it would leave below three."""
        keep = keep | (np.bincount(gid, keep, n)[gid] < 3)
        return flat[keep], gid[keep]

    def _pad(self, flat: np.ndarray, gid: np.ndarray, n: int) -> None:
        count = np.bincount(gid, minlength=n)
        first = np.r_[0, np.cumsum(count)[:-1]]
        order = np.lexsort((flat[:, 0], flat[:, 1], gid))  # per polygon, lowest then leftmost first
        lowest = np.where(count > 0, order[np.minimum(first, max(len(order) - 1, 0))] - first, 0) if len(order) \
            else np.zeros(n, dtype=np.int64)
        k = int(count.max(initial=1))
        j = np.arange(k)[None, :]
        real = j < count[:, None]
        m = np.maximum(count, 1)[:, None]
        idx = first[:, None] + (lowest[:, None] + np.minimum(j, m - 1)) % m
        nxt = first[:, None] + (lowest[:, None] + np.minimum(j, m - 1) + 1) % m
        self.count = count
        self.verts = flat[idx]
        self.edges = np.where(real[..., None], flat[nxt] - self.verts, 0.0)
        angle = np.arctan2(self.edges[..., 1], self.edges[..., 0])
        angle = np.where(angle < 0, angle + 2 * math.pi, angle)
        self.angle = np.where(real, np.maximum.accumulate(np.where(real, angle, 0.0), axis=1), np.inf)


def _cyclic(gid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Next and previous index of each point of polygons stored one after another (``gid``:
    each point's polygon, ascending), cyclic within its polygon."""
    if not len(gid):
        return gid, gid
    start = np.flatnonzero(np.r_[True, gid[1:] != gid[:-1]])
    end = np.r_[start[1:], len(gid)] - 1
    i = np.arange(len(gid))
    nxt, prv = i + 1, i - 1
    nxt[end] = start
    prv[start] = end
    return nxt, prv


def signed_distance(pa: _Polygons, ia: np.ndarray, pb: _Polygons, ib: np.ndarray) -> np.ndarray:
    """(p,) for each pair of convex polygons ``A = pa[ia[j]]``, ``B = pb[ib[j]]``: their
    distance (mm) when apart, minus how far they overlap when not (the least shift that parts
    them, along one of their edge normals: the separating-axis test's depth).

    Both come from their Minkowski difference ``D = A + (-B)``, walked from the sum of the
    lowest vertices along the edges of both in angle order (O(k log k) a pair, not O(k^2)):
    A and B meet where D holds the origin; the largest distance of the origin outside D's edge
    lines is the separating-axis gap, and when it is positive the distance to D's boundary is
    the distance between A and B."""
    out = np.empty(len(ia))
    size = pa.count[ia] + pb.count[ib]
    order = np.argsort(-size, kind="stable")
    lo = 0
    while lo < len(order):
        step = max(1, (1 << 19) // int(size[order[lo]]))
        sel = order[lo:lo + step]
        lo += step
        a, b = ia[sel], ib[sel]
        ka, kb = int(pa.count[a].max()), int(pb.neg.count[b].max())
        edges = np.concatenate([pa.edges[a, :ka], pb.neg.edges[b, :kb]], axis=1)
        angle = np.concatenate([pa.angle[a, :ka], pb.neg.angle[b, :kb]], axis=1)
        edges = np.take_along_axis(edges, np.argsort(angle, axis=1, kind="stable")[..., None], axis=1)
        start = pa.verts[a, 0] + pb.neg.verts[b, 0]
        verts = start[:, None, :] + np.cumsum(edges, axis=1) - edges  # D's vertex where each edge starts
        length2 = (edges * edges).sum(axis=-1)
        real = length2 > 0
        length = np.sqrt(np.where(real, length2, 1.0))
        # origin's distance outside each edge line: -(n . v), n = (e_y, -e_x) / |e| outward
        outside = -(edges[..., 1] * verts[..., 0] - edges[..., 0] * verts[..., 1]) / length
        gap = np.where(real, outside, -np.inf).max(axis=1)
        t = np.clip(-(verts * edges).sum(axis=-1) / np.where(real, length2, 1.0), 0.0, 1.0)
        near = np.linalg.norm(verts + t[..., None] * edges, axis=-1).min(axis=1)
        out[sel] = np.where(gap > 0, near, gap)
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


def _work_array(ids: tuple[str, ...], work: Mapping[str, float]) -> np.ndarray:
    """(n,) each chunk's work, s, checked (given and finite), at least :data:`MIN_WORK`."""
    missing = [c for c in ids if c not in work]
    if missing:
        raise ValueError(f"build_dag: no work given for chunk {missing[0]}")
    w = np.array([float(work[c]) for c in ids])
    if not np.isfinite(w).all():
        raise ValueError(f"build_dag: work of chunk {ids[int(np.flatnonzero(~np.isfinite(w))[0])]} is not finite")
    return np.maximum(w, MIN_WORK)


def _put_ends(ids: tuple[str, ...], start: np.ndarray, end: np.ndarray,
              ends: Mapping[str, tuple[np.ndarray, np.ndarray]] | None) -> None:
    """Write the printed first and last points of ``ends`` into ``start``/``end`` (rows of
    ``ids``); chunks not in it keep theirs."""
    for i, c in enumerate(ids):
        if ends is not None and c in ends:
            start[i], end[i] = (np.asarray(p, dtype=np.float64)[:3] for p in ends[c])


def retimed(dag: ChunkDAG, work: Mapping[str, float],
            ends: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None) -> ChunkDAG:
    """``dag`` with new work (and printed ends), its constraints kept: (a), (b) and (c) are
    geometry and do not depend on the work, so the chunks' sweeps are not made again (what
    :func:`build_dag` would give for the same chunks with this work and these ends)."""
    start, end = dag.start.copy(), dag.end.copy()
    _put_ends(dag.ids, start, end, ends)
    return replace(dag, work=_work_array(dag.ids, work), start=start, end=end)


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
        mm/s, for :meth:`ChunkDAG.travel`: the robots' travel speed (:meth:`Feeds.of_robot`'s).
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
    w = _work_array(ids, work)
    axis = unit_xy(chunks.plan.axis)
    facing = np.array([axis if c.facing is None else unit_xy(c.facing) for c in chunks.chunks]).reshape(n, 2)
    hulls = [convex_hull(c.vertices[:, :2]) for c in chunks.chunks]
    footprint = np.array([np.r_[c.vertices[:, :2].min(axis=0), c.vertices[:, :2].max(axis=0)]
                          for c in chunks.chunks]).reshape(n, 4)
    start, end = np.empty((n, 3)), np.empty((n, 3))
    for i, c in enumerate(chunks.chunks):
        start[i] = end[i] = _outer_base_middle(footprint[i], facing[i], float(c.vertices[:, 2].min()))
    _put_ends(ids, start, end, ends)

    deps = {c: tuple(chunks.deps.get(c, ())) for c in ids}
    preds = [[index[d] for d in deps[c]] for c in ids]
    outline = robot.outline()
    parts = [[swept(hulls[i], outline[p], facing[i]) for p in ("body", "frame", "printhead")] for i in range(n)]

    # (b) the body rule: chunks reaching into X's body sweep come after X
    bodies, footprints = _Polygons([pp[0] for pp in parts], negate=False), _Polygons(hulls)
    bx, by = _box_pairs(bodies.box, footprints.box, -TOUCH)
    keep = bx != by
    bx, by = bx[keep], by[keep]
    depth = -signed_distance(bodies, bx, footprints, by)
    hit = depth > TOUCH
    body_pred: list[list[int]] = [[] for _ in range(n)]
    for x, y in sorted(zip(bx[hit].tolist(), by[hit].tolist())):
        body_pred[y].append(x)
    both = [list(dict.fromkeys(preds[i] + body_pred[i])) for i in range(n)]
    order = _topological(n, both)
    if order is None:
        _unprintable(ids, preds, both, depth[hit], bx[hit], by[hit], robot, facing)
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
    overlap = np.minimum(pieces.box[pb, 2:], pieces.box[pa, 2:]) - np.maximum(pieces.box[pb, :2], pieces.box[pa, :2])
    near = (overlap > -clearance).all(axis=1)
    pa, pb, pair = pa[near], pb[near], pair[near]
    close = signed_distance(pieces, pa, pieces, pb) < clearance - EXACT  # touching is not closer than 0
    excl = np.zeros(len(ca), dtype=bool)
    excl[pair[close]] = True
    exclusive = tuple((ids[a], ids[b]) for a, b in sorted(zip(ca[excl].tolist(), cb[excl].tolist())))
    return ChunkDAG(ids=ids, work=w, facing=facing, start=start, end=end, footprint=footprint, deps=deps,
                    body_deps={c: tuple(ids[x] for x in sorted(body_pred[i])) for i, c in enumerate(ids)},
                    exclusive=exclusive, travel_speed=float(travel_speed), detour=_detour(robot, clearance))


def _detour(robot: RobotProfile, clearance: float) -> float:
    """How far outside the part a robot drives round it to change sides, mm: two radii of its
    whole outline (the farthest corner from the nozzle) and the clearance, the ring where the
    programs turn it clear of the part and of every robot over it (:mod:`cooprint.program.fleet`)."""
    return 2 * robot.outline_radius() + clearance


def _unprintable(ids: tuple[str, ...], preds: list[list[int]], both: list[list[int]], depth: np.ndarray,
                 bx: np.ndarray, by: np.ndarray, robot: RobotProfile, facing: np.ndarray) -> None:
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
            f"({' -> '.join(ids[k] for k in chain)}; facing {deg:.0f} deg its body, {robot.build_depth:g} to "
            f"{robot.build_depth + robot.body_length:g} mm behind the nozzle, reaches {d:.0f} mm into "
            f"{ids[y]}'s footprint; face the robot the other way or choose another layout)")
    raise ValueError("the chunk constraints form a cycle")  # pragma: no cover (a body edge closes every cycle)


# -- work estimates --------------------------------------------------------------------------


def work_from_layers(layers: Mapping[str, Sequence[tuple[int, LayerPaths]]], robot: RobotProfile,
                     slicing: SlicingSettings) -> dict[str, float]:
    """``{chunk id: s}``: :func:`work_from_program` of each chunk's commands (its layers through
    :func:`cooprint.program.build.layer_program`)."""
    from cooprint.program.stream import canonical_program

    return {cid: work_from_program(canonical_program(cid, chunk_layers), robot, slicing)
            for cid, chunk_layers in layers.items()}


def work_from_program(canon: "Program", robot: RobotProfile, slicing: SlicingSettings) -> float:
    """The constant-speed time of a chunk's layer moves, s, from its first printed point to its
    last, as the robot programs make them: ``canon`` is the chunk's canonical program
    (:func:`cooprint.program.stream.canonical_program`), timed layer by layer from its first
    point on (the way to that point is travel between chunks, :meth:`ChunkDAG.travel`, not work).

    The times are the simulator's for a ``cooprint run`` plan
    (:func:`cooprint.simulation.timeline.move_durations` on a ``.coop`` robot) and the written
    G-code's: length over the speed of :meth:`Feeds.of_robot` (the slicer's speed of the move's
    path role with the tool on, at most ``first_layer_speed`` on the first layer, its travel
    speed with the tool off, each under the robot's caps).
    """
    from cooprint.program.commands import COLUMNS, MOVE, Program
    from cooprint.program.gcode import Feeds

    if len(canon) == 0:
        return 0.0
    feeds = Feeds.of_robot(robot, slicing)
    # each layer's commands; the first one's first move (to the chunk's first point, from
    # nowhere) is the way in
    cuts = np.r_[1, np.flatnonzero(np.diff(canon.layer) != 0) + 1, len(canon)]
    here = canon.xyz[0]
    total = 0.0
    for a, b in zip(cuts[:-1].tolist(), cuts[1:].tolist()):
        piece = Program("", *(getattr(canon, f)[a:b] for f in COLUMNS))
        mv = piece.kind == MOVE
        xyz = piece.xyz[mv]
        p0 = np.vstack([here[None], xyz[:-1]])
        length = np.linalg.norm(xyz - p0, axis=1)
        total += float((length / feeds.speeds(piece)[mv]).sum())
        if len(xyz):
            here = xyz[-1]
    return total


def ends_from_layers(layers: Mapping[str, Sequence[tuple[int, LayerPaths]]]
                     ) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``{chunk id: (first xyz, last xyz)}``: where the nozzle starts printing each chunk (its
    first layer's first point) and where it ends (its last layer's last point), on the 1 µm
    grid of the programs (:func:`cooprint.program.stream.chunk_ends`); chunks with nothing to
    print are left out."""
    from cooprint.program.stream import chunk_ends

    return {cid: e for cid, chunk_layers in layers.items() if (e := chunk_ends(chunk_layers)) is not None}


#: :func:`work_from_volume`'s factor: the time of the sliced layers (:func:`work_from_layers`)
#: over the printed-volume model, each kind at its roles' speeds (:func:`volume_speeds`),
#: measured by ``benchmarks/calibrate_volume_factor.py`` on 18 chunks of 6 generated parts (car
#: 420 mm, box 300 x 900 x 60, cylinder r 60 h 120, a box 300 x 600 x 60 hollow with 10 mm walls
#: and floor, plate 900 x 400 x 10, post 20 x 20 x 150; seed2 layout, default robot and slicing,
#: 2026-12-02): median 1.071, range 1.021 (the plate's centre chunk) to 1.359 (the hollow box's
#: side chunks, thin walls), coefficient of variation 8.6%. The rest is travel between paths and
#: perimeter overlap. (With one print speed for every role, before issue 17: median 1.104 on 17
#: chunks; volume alone, without the shells, spread 0.256 to 0.397, and its factor holds only for
#: one infill density.)
VOLUME_FACTOR = 1.07


def printed_volumes(chunk: Chunk, slicing: SlicingSettings) -> tuple[float, float, float, float]:
    """mm^3 the slicer will deposit in ``chunk``, estimated from its mesh, by kind: ``(walls,
    top, bottom, sparse)``. The walls are a shell of ``perimeters`` extrusion widths horizontally
    behind every face (its area times the XY part of its unit normal); the top and bottom shells
    ``top_layers`` / ``bottom_layers`` layers vertically under faces looking up / over faces
    looking down (area times the Z part); the shells together at most the volume (scaled down
    alike when they would be more); the rest filled at ``infill_density``. Cut faces are faces:
    each chunk is sliced on its own, so they get perimeters too."""
    tri = chunk.vertices[chunk.faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) / 2  # area times unit normal
    side = float(np.linalg.norm(n[:, :2], axis=1).sum())
    up, down = float(n[:, 2].clip(min=0).sum()), float((-n[:, 2]).clip(min=0).sum())
    walls = side * slicing.perimeters * slicing.extrusion_width
    top, bottom = up * slicing.top_layers * slicing.layer_height, down * slicing.bottom_layers * slicing.layer_height
    shell = walls + top + bottom
    scale = min(1.0, chunk.volume / shell) if shell > 0 else 1.0
    return walls * scale, top * scale, bottom * scale, slicing.infill_density * (chunk.volume - shell * scale)


def printed_volume(chunk: Chunk, slicing: SlicingSettings) -> float:
    """mm^3 the slicer will deposit in ``chunk``: the sum of :func:`printed_volumes`."""
    return sum(printed_volumes(chunk, slicing))


def volume_speeds(robot: RobotProfile, slicing: SlicingSettings) -> tuple[float, float, float, float]:
    """The mean speed, mm/s, at which a robot lays each kind of :func:`printed_volumes` (the
    time of a volume is volume / (width x height x speed)): the walls one external perimeter and
    ``perimeters - 1`` inner ones, the top shell its top surface at the top solid infill speed
    and the layers under it as solid infill, the bottom shell solid infill, the rest sparse
    infill; every speed the robot's (:meth:`~cooprint.program.gcode.Feeds.of_robot`). Each mean
    is harmonic: the time per volume averaged, not the speeds."""
    from cooprint.program.gcode import Feeds
    from cooprint.slicing.paths import INFILL, PERIMETER_INNER, PERIMETER_OUTER, SKIN, TOP_SKIN

    v = Feeds.of_robot(robot, slicing).role
    p, t = max(slicing.perimeters, 1), max(slicing.top_layers, 1)
    walls = p / (1 / v[PERIMETER_OUTER] + (p - 1) / v[PERIMETER_INNER])
    top = t / (1 / v[TOP_SKIN] + (t - 1) / v[SKIN])
    return walls, top, v[SKIN], v[INFILL]


def work_from_volume(chunks: ChunkSet, robot: RobotProfile, slicing: SlicingSettings) -> dict[str, float]:
    """``{chunk id: s}`` before slicing (``cooprint chunk``): each kind of
    :func:`printed_volumes` over its deposition rate ``extrusion_width * layer_height * speed``
    (:func:`volume_speeds`), times :data:`VOLUME_FACTOR` (the travel between paths and the
    overlaps the model leaves out)."""
    rates = [slicing.extrusion_width * slicing.layer_height * v for v in volume_speeds(robot, slicing)]
    return {c.id: VOLUME_FACTOR * sum(vol / rate for vol, rate in zip(printed_volumes(c, slicing), rates))
            for c in chunks.chunks}


__all__ = ["MIN_WORK", "TOUCH", "VOLUME_FACTOR", "build_dag", "convex_hull", "ends_from_layers", "printed_volume",
           "printed_volumes", "swept", "volume_speeds", "work_from_layers", "work_from_volume"]
