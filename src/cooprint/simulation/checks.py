"""Physical checks of a simulated plan (seed §2-3 made executable).

* ``body-on-material``: a robot's body footprint (``body_width`` x ``body_length``, its front
  ``build_depth`` behind the nozzle along the robot's facing) over material deposited before.
* ``robots-collide``: two robots' footprints overlapping at the same instant.
* ``printhead-hits-material``: material deposited before within the printhead's reach (a square
  of half-side ``nozzle_depth`` around the nozzle, in the robot's frame) that rises above the
  printhead's underside (``nozzle_height`` above the nozzle tip), seed Fig. 3b: a chunk whose
  slope is steeper than theta_max = atan(nh / nd) reaches it.
* ``overhang`` (a warning): material laid down with nothing below it: no material whose top is
  at most one layer of air lower (between 2.5 and 0.5 layer heights below) within ``radius``, and
  not on the floor.

The nozzle is looked at every ``step`` mm of its path (and at every move's ends); material is the
deposited paths sampled every ``step`` mm (more on prints of more than ``MAX_SAMPLES`` points). The
body and printhead checks work on rasters in the robot's frame (u along its facing, v to its
left) with cells of half the ``tolerance`` (more on very large prints): the body check
keeps, per cell, the earliest time material was laid down there, takes the minimum over the
footprint with a sliding-window filter once, and then needs one look-up per nozzle sample; the
printhead check keeps, per cell, the highest material laid down so far and sweeps the nozzle
samples in time order in batches, adding the material laid down before each batch and filtering
only the batch's region (the material laid down during a batch is compared point by point). A
footprint that only touches material (within ``tolerance``, which covers half a line width) is
not a finding; a plan the chunker made keeps the body just clear of its chunk's outer edge.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cooprint.config import RobotProfile, SlicingSettings
from cooprint.simulation.timeline import Finding, SimRobot, Timeline

#: Spacing of nozzle and material samples, mm.
STEP = 2.0
#: Overlap below this is touching, not standing on, mm (half a line width, and the cells of
#: the rasters, which are half of it).
TOLERANCE = 2.0
#: At most this many material samples (the spacing grows on very long prints); nozzle moves
#: sampled at once; cells of one raster (the cells grow on very large prints).
MAX_SAMPLES = 8_000_000
MOVES_AT_ONCE = 100_000
MAX_CELLS = 8_000_000
#: Nozzle samples the printhead check looks at together.
BATCH = 2048
#: The overhang check looks this far around a point for material below it (at least half the
#: sparse infill's line spacing plus a sample step, so that skins over sparse infill are not
#: overhangs), mm.
OVERHANG_RADIUS = 5.0


def path_samples(tl: Timeline, step: float, deposits_only: bool, moves: slice = slice(None)
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (k, 3) float32 along the moves (of the range ``moves``) every ``step`` mm and at
    their ends, their times (k,) and the move each lies on (k,)."""
    sel = np.arange(len(tl.t0))[moves]
    if deposits_only:
        sel = sel[tl.on[sel]]
    if len(sel) == 0:
        return np.zeros((0, 3), np.float32), np.zeros(0), np.zeros(0, np.int64)
    p0 = tl.p0[sel].astype(np.float32)
    d = tl.p1[sel].astype(np.float32) - p0
    n = np.maximum(np.ceil(tl.length[sel] / step).astype(np.int64), 1)
    frac = np.arange(1, int(n.sum()) + 1, dtype=np.float64)  # the j-th of n points: j / n
    frac -= np.repeat((np.cumsum(n) - n).astype(np.float64), n)
    frac *= np.repeat(1.0 / n, n)
    pts = np.repeat(p0, n, axis=0)
    pts += frac.astype(np.float32)[:, None] * np.repeat(d, n, axis=0)
    times = np.repeat(tl.t0[sel], n)
    times += frac * np.repeat(tl.t1[sel] - tl.t0[sel], n)
    move = np.repeat(sel, n)
    if not deposits_only and sel[0] == 0:  # the very first position too
        pts = np.vstack([p0[:1], pts])
        times = np.r_[tl.t0[:1], times]
        move = np.r_[0, move]
    return pts, times, move


def _step(timelines: dict[str, Timeline], step: float, deposits_only: bool) -> float:
    """``step``, or longer on a print so long that it would make more than ``MAX_SAMPLES``."""
    total = sum(float(tl.length[tl.on].sum() if deposits_only else tl.length.sum()) for tl in timelines.values())
    return max(step, total / MAX_SAMPLES)


@dataclass(frozen=True)
class Material:
    """Every robot's deposited paths as points every ``step`` mm: position (k, 3) float32, time
    (k,), layer height (k,) and move (k,) (its index in its robot's timeline); robot ``i``'s
    points are ``bounds[i]:bounds[i + 1]``, in the order it laid them down."""

    xyz: np.ndarray
    t: np.ndarray
    h: np.ndarray
    move: np.ndarray
    bounds: np.ndarray

    @staticmethod
    def sample(robots: list[SimRobot], timelines: dict[str, Timeline], step: float,
               layer_height: float) -> "Material":
        step = _step(timelines, step, deposits_only=True)
        parts = [path_samples(timelines[r.name], step, deposits_only=True) for r in robots]
        h = [r.bead(timelines[r.name].index, 0.0, layer_height)[1][move] for r, (_, _, move) in zip(robots, parts)]
        return Material(np.vstack([p[0] for p in parts] + [np.zeros((0, 3), np.float32)]),
                        np.concatenate([p[1] for p in parts] + [np.zeros(0)]), np.concatenate(h + [np.zeros(0)]),
                        np.concatenate([p[2] for p in parts] + [np.zeros(0, np.int64)]),
                        np.cumsum([0] + [len(p[1]) for p in parts]))

    def robot(self, i: int) -> slice:
        return slice(int(self.bounds[i]), int(self.bounds[i + 1]))


def _frame(facing: np.ndarray) -> np.ndarray:
    """(2, 2) rows: the facing direction and its left."""
    f = np.asarray(facing, dtype=np.float64) / np.linalg.norm(facing)
    return np.array([f, [-f[1], f[0]]])


def body_box(profile: RobotProfile, tolerance: float = 0.0) -> tuple[float, float, float, float]:
    """(u_lo, u_hi, v_lo, v_hi) of the body relative to the nozzle, in the robot's frame (u along
    the facing, v to its left), shrunk by ``tolerance``."""
    bd, length, w = profile.build_depth, profile.body_length, profile.body_width
    return (-bd - length + tolerance, -bd - tolerance, -w / 2 + tolerance, w / 2 - tolerance)


def body_corners(profile: RobotProfile, facing: np.ndarray, tolerance: float = 0.0) -> np.ndarray:
    """(4, 2) corners of the body relative to the nozzle, in world XY, for a robot facing
    ``facing``."""
    u_lo, u_hi, v_lo, v_hi = body_box(profile, tolerance)
    return np.array([[u_lo, v_lo], [u_hi, v_lo], [u_hi, v_hi], [u_lo, v_hi]]) @ _frame(facing)


def head_box(profile: RobotProfile, tolerance: float = 0.0) -> tuple[float, float, float, float]:
    """(u_lo, u_hi, v_lo, v_hi) of the printhead's reach around the nozzle (a square of half-side
    ``nozzle_depth``), shrunk by ``tolerance``."""
    r = max(profile.nozzle_depth - tolerance, 0.0)
    return (-r, r, -r, r)


def _sliding(a: np.ndarray, w: int, axis: int, op: np.ufunc) -> np.ndarray:
    """``op`` (minimum or maximum) over every window of ``w`` entries along ``axis``: out[i] covers
    a[i:i + w] (``n - w + 1`` entries); log2(w) passes of doubling windows."""
    def part(x, start, length):
        idx = [slice(None)] * x.ndim
        idx[axis] = slice(start, start + length)
        return x[tuple(idx)]

    out, span = a, 1
    while 2 * span <= w:
        m = out.shape[axis] - span
        out = op(part(out, 0, m), part(out, span, m))
        span *= 2
    if w > span:  # overlapping windows: fine for min and max
        m = out.shape[axis] - (w - span)
        out = op(part(out, 0, m), part(out, w - span, m))
    return out


@dataclass(frozen=True)
class _Raster:
    """Square cells over the material's box in one robot's (u, v) frame, padded on each side by
    a window: a footprint (``box`` relative to the nozzle) covers ``window`` cells from the cell
    of its low corner, which always lies in the padded grid after clipping."""

    lo: np.ndarray  # (2,) float32: corner of the first cell inside the padding
    cell: float
    shape: tuple[int, int]
    window: tuple[int, int]
    box: tuple[float, float, float, float]

    @staticmethod
    def over(lo: np.ndarray, hi: np.ndarray, cell: float, box: tuple[float, float, float, float]) -> "_Raster":
        size = (box[1] - box[0], box[3] - box[2])
        window = tuple(int(np.ceil(s / cell)) + 1 for s in size)
        shape = tuple(int(np.floor((h - l) / cell)) + 1 + 2 * w for l, h, w in zip(lo, hi, window))
        return _Raster(lo, cell, shape, window, box)

    def cells(self, base: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cell indices (row, column) of material from its cells (k, 2) counted from ``lo``."""
        return base[:, 0] + self.window[0], base[:, 1] + self.window[1]

    def windows(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Index, into the window-filtered grid, of each nozzle position's footprint."""
        c = np.floor((uv + np.array([self.box[0], self.box[2]], np.float32) - self.lo) / self.cell).astype(np.int64)
        return (np.clip(c[:, 0] + self.window[0], 0, self.shape[0] - self.window[0]),
                np.clip(c[:, 1] + self.window[1], 0, self.shape[1] - self.window[1]))


def _nozzle_batches(tl: Timeline, step: float):
    """The nozzle's samples in time order, ``MOVES_AT_ONCE`` moves at a time: (xyz, t, move)."""
    for first in range(0, len(tl.t0), MOVES_AT_ONCE):
        yield path_samples(tl, step, False, slice(first, first + MOVES_AT_ONCE))


def footprint_checks(robots: list[SimRobot], timelines: dict[str, Timeline], profile: RobotProfile,
                     material: Material, body: bool = True, head: bool = True, step: float = STEP,
                     tolerance: float = TOLERANCE) -> list[Finding]:
    """``body-on-material`` (``body``): a robot's body over material laid down before; and
    ``printhead-hits-material`` (``head``): material laid down before within the printhead's
    reach and higher than ``nozzle_height`` over the nozzle tip. One finding per robot, kind and
    chunk, with the first instant and how many nozzle samples."""
    n_step = _step(timelines, step, deposits_only=False)
    findings = []
    for r in robots:
        tl = timelines[r.name]
        frame = _frame(r.facing).astype(np.float32)
        checks = robot_checks(material, frame, profile, body, head, tolerance)
        for xyz, t, move in _nozzle_batches(tl, n_step):
            uv = xyz[:, :2] @ frame.T
            for c in checks:
                k = c.hits(uv, xyz[:, 2], t)
                c.found.append((t[k], xyz[k], move[k]))
        for c in checks:
            findings += _group(c.found, c.kind, r, tl, c.detail)
    return findings


def robot_checks(material: Material, frame: np.ndarray, profile: RobotProfile, body: bool = True,
                 head: bool = True, tolerance: float = TOLERANCE) -> list:
    """The footprint checks of one robot (``frame``: its facing and its left, float32), on rasters
    sharing one cell size (1 mm, or more on very large prints) over the material; each has
    ``hits(uv, z, t)``: the indices of the nozzle samples (in the robot's frame, in time order)
    that meet material."""
    boxes = ([body_box(profile, tolerance)] if body else []) + ([head_box(profile, tolerance)] if head else [])
    if not boxes:
        return []
    m_uv = material.xyz[:, :2] @ frame.T
    lo = m_uv.min(axis=0) if len(m_uv) else np.zeros(2, np.float32)
    hi = m_uv.max(axis=0) if len(m_uv) else np.zeros(2, np.float32)
    size = max((b[1] - b[0]) + (b[3] - b[2]) for b in boxes)
    cell = max(tolerance / 2, float(np.sqrt(np.prod(hi - lo + 2 * size) / MAX_CELLS)))
    base = np.floor((m_uv - lo) / np.float32(cell)).astype(np.int32)  # cells of the material
    return ([_BodyCheck(_Raster.over(lo, hi, cell, boxes[0]), base, material)] if body else []) + \
        ([_HeadCheck(_Raster.over(lo, hi, cell, boxes[-1]), base, m_uv, material, profile, tolerance)]
         if head else [])


class _BodyCheck:
    """The earliest time material lay in each cell, its minimum over the body's footprint taken
    once (a sliding window); then one look-up per nozzle sample."""

    kind = "body-on-material"
    detail = "the body stands on material laid down before"

    def __init__(self, grid: _Raster, cells: np.ndarray, material: Material):
        self.grid = grid
        first = np.full(grid.shape, np.inf)
        np.minimum.at(first, grid.cells(cells), material.t)
        self.first = _sliding(_sliding(first, self.grid.window[0], 0, np.minimum), self.grid.window[1], 1,
                              np.minimum)
        self.found: list = []

    def hits(self, uv: np.ndarray, z: np.ndarray, t: np.ndarray) -> np.ndarray:
        return np.flatnonzero(self.first[self.grid.windows(uv)] < t)


class _HeadCheck:
    """The highest material laid down so far in each cell: the nozzle samples are swept in time
    order in batches of ``BATCH``; before each batch the material laid down until its start is
    added (each robot's points are in time order), and the maximum over the printhead's reach is
    taken over the batch's region only; the material laid down during the batch is compared
    point by point."""

    kind = "printhead-hits-material"

    def __init__(self, grid: _Raster, cells: np.ndarray, m_uv: np.ndarray, material: Material,
                 profile: RobotProfile, tolerance: float):
        self.grid, self.box = grid, grid.box
        self.lift = profile.nozzle_height + tolerance
        self.high = np.full(grid.shape, -np.inf, dtype=np.float32)
        self.cells = grid.cells(cells)
        self.m_uv, self.m_z, self.m_t = m_uv, material.xyz[:, 2], material.t
        self.blocks = [material.robot(i) for i in range(len(material.bounds) - 1)]
        self.top = np.concatenate([np.maximum.accumulate(self.m_z[b]) for b in self.blocks if b.stop > b.start]
                                  + [np.zeros(0, np.float32)])  # each robot's highest so far
        self.added = [b.start for b in self.blocks]
        self.detail = (f"material laid down before rises within the printhead's reach ({profile.nozzle_depth:g} mm) "
                       f"above its underside ({profile.nozzle_height:g} mm over the nozzle tip)")
        self.found: list = []

    def hits(self, uv: np.ndarray, z: np.ndarray, t: np.ndarray) -> np.ndarray:
        out = []
        for a in range(0, len(t), BATCH):
            hit = self._batch(uv[a:a + BATCH], z[a:a + BATCH] + self.lift, t[a:a + BATCH])
            if hit is not None:
                out.append(np.flatnonzero(hit) + a)
        return np.concatenate(out) if out else np.zeros(0, np.int64)

    def _batch(self, uv: np.ndarray, under: np.ndarray, t: np.ndarray) -> np.ndarray | None:
        low = under.min()
        spans = []  # per robot: its points laid down before the batch, and during it
        for b in self.blocks:
            ka, kb = np.searchsorted(self.m_t[b], [t[0], t[-1]]) + b.start
            spans.append((b.start, ka, kb))
        if not any(kb > s and self.top[kb - 1] > low for s, _, kb in spans):
            return None  # nothing laid down yet reaches that high
        for i, (s, ka, _) in enumerate(spans):
            if ka > self.added[i]:
                new = slice(self.added[i], ka)
                np.maximum.at(self.high, (self.cells[0][new], self.cells[1][new]), self.m_z[new])
                self.added[i] = ka
        box, window = self.box, self.grid.window
        hit = np.zeros(len(t), dtype=bool)
        if any(ka > s for s, ka, _ in spans):
            wr, wc = self.grid.windows(uv)
            r0, c0 = wr.min(), wc.min()
            part = self.high[r0:wr.max() + window[0], c0:wc.max() + window[1]]
            part = _sliding(_sliding(part, window[0], 0, np.maximum), window[1], 1, np.maximum)
            hit = part[wr - r0, wc - c0] > under
        near = np.concatenate([np.arange(ka, kb) for _, ka, kb in spans])  # during the batch: point by point
        near = near[self.m_z[near] > low]
        if len(near):
            lo, hi = uv.min(axis=0), uv.max(axis=0)
            m = self.m_uv[near]
            near = near[(m[:, 0] >= lo[0] + box[0]) & (m[:, 0] <= hi[0] + box[1])
                        & (m[:, 1] >= lo[1] + box[2]) & (m[:, 1] <= hi[1] + box[3])]
        rows = max(1, (1 << 22) // max(len(near), 1))  # bound the (samples x points) tests
        for a in range(0, len(t) if len(near) else 0, rows):
            b = slice(a, a + rows)
            du = self.m_uv[near, 0][None, :] - uv[b, 0, None]
            dv = self.m_uv[near, 1][None, :] - uv[b, 1, None]
            hit[b] |= ((du >= box[0]) & (du <= box[1]) & (dv >= box[2]) & (dv <= box[3])
                       & (self.m_z[near][None, :] > under[b, None])
                       & (self.m_t[near][None, :] < t[b, None])).any(axis=1)
        return hit


def overhangs(robots: list[SimRobot], timelines: dict[str, Timeline], material: Material,
              slicing: SlicingSettings, radius: float | None = None) -> list[Finding]:
    """Material laid down with nothing below it: no material laid down before whose top is at most
    one layer of air lower (between 2.5 and 0.5 of the point's layer height below it) within
    ``radius`` mm, and not on the floor (a warning; one finding per robot and chunk).

    Cells of ``radius / 2``: each (cell, height) keeps the earliest time material was there; a
    point looks in its band of heights in its own cell, then in the 24 cells around. So a point
    with material within ``radius`` below is never an overhang, and one is found when nothing lies
    within ``radius`` (up to about 2.1 ``radius`` on the diagonals)."""
    if radius is None:
        spacing = slicing.extrusion_width / slicing.infill_density if slicing.infill_density > 0 else 0.0
        radius = max(OVERHANG_RADIUS, spacing / 2 + STEP)
    xyz, t, h = material.xyz, material.t, material.h
    if len(t) == 0:
        return []
    cell = radius / 2
    cxy = np.floor(xyz[:, :2] / cell).astype(np.int64)
    cxy -= cxy.min(axis=0) - 2
    ny = int(cxy[:, 1].max()) + 3
    zmin = float(xyz[:, 2].min())
    zq = np.round((xyz[:, 2] - zmin) * 1000).astype(np.int64)  # micrometres above the lowest point
    nz = int(zq.max()) + 1
    # everything in the order of (cell, height); the earliest time of each (cell, height)
    own = (cxy[:, 0] * ny + cxy[:, 1]) * nz
    key = own + zq
    order = np.argsort(key)
    key, own, zq, t_s, h_s = key[order], own[order], zq[order], t[order], h[order]
    del cxy
    group = np.r_[True, key[1:] != key[:-1]]
    key = key[group]
    first = np.minimum.reduceat(t_s, np.flatnonzero(group))
    gid = np.cumsum(group) - 1
    del group
    band = (np.clip(np.round(zq - 2500 * h_s), 0, None).astype(np.int64),
            np.clip(np.round(zq - 500 * h_s), -1, None).astype(np.int64))
    # on the floor, or one layer of air above it: supported; most other points have material
    # right below in their own cell: one of the three (cell, height)s just before their own
    ok = zq + round(zmin * 1000) <= np.round(2500 * h_s) + 1
    for back in (1, 2, 3):
        g = np.maximum(gid - back, 0)
        below = key[g] - own
        ok |= (gid >= back) & (below >= band[0]) & (below <= band[1]) & (first[g] < t_s)
    todo = np.flatnonzero(~ok)
    del ok, g, below, gid
    # the rest: every height in the band, in the own cell and the 24 cells around
    for dx, dy in [(0, 0)] + [(dx, dy) for dx in range(-2, 3) for dy in range(-2, 3) if dx or dy]:
        if len(todo) == 0:
            break
        base = own[todo] + (dx * ny + dy) * nz
        lo = np.searchsorted(key, base + band[0][todo], side="left")
        hi = np.searchsorted(key, base + band[1][todo], side="right")
        found = np.zeros(len(todo), dtype=bool)
        live = np.flatnonzero(lo < hi)
        while len(live):  # each height in the band, lowest first
            ok = first[lo[live]] < t_s[todo[live]]
            found[live[ok]] = True
            lo[live] += 1
            live = live[~ok & (lo[live] < hi[live])]
        todo = todo[~found]
    todo = order[todo]  # back to the material's order
    findings = []
    todo.sort()
    for i, r in enumerate(robots):
        block = material.robot(i)
        bad = todo[np.searchsorted(todo, block.start):np.searchsorted(todo, block.stop)]
        findings += _group([(t[bad], xyz[bad], material.move[bad])], "overhang", r, timelines[r.name],
                           f"material laid down with nothing below it within {radius:g} mm (more than one layer "
                           "of air)")
    return findings


def robots_collide(robots: list[SimRobot], timelines: dict[str, Timeline], profile: RobotProfile,
                   dt: float = 0.5, tolerance: float = TOLERANCE) -> list[Finding]:
    """Pairs of robots whose footprints overlap at the same instant (sampled every ``dt`` s)."""
    findings = []
    end = max((tl.end for tl in timelines.values()), default=0.0)
    times = np.arange(0.0, end + dt, dt)
    corners = {}
    for r in robots:
        nozzle = timelines[r.name].position(times)[:, :2]
        corners[r.name] = nozzle[:, None, :] + body_corners(profile, r.facing, tolerance)[None]  # (T, 4, 2)
    for i, a in enumerate(robots):
        for b in robots[i + 1:]:
            p, q = corners[a.name], corners[b.name]
            near = np.flatnonzero((p[:, :, 0].min(1) <= q[:, :, 0].max(1)) & (q[:, :, 0].min(1) <= p[:, :, 0].max(1))
                                  & (p[:, :, 1].min(1) <= q[:, :, 1].max(1)) & (q[:, :, 1].min(1) <= p[:, :, 1].max(1)))
            hit = np.zeros(len(times), dtype=bool)  # boxes apart: no overlap; else separating axes
            hit[near] = _rects_overlap(p[near], q[near])
            if hit.any():
                k = np.flatnonzero(hit)
                t = float(times[k[0]])
                pos = timelines[a.name].position(t)
                findings.append(Finding("robots-collide", a.name, t, tuple(float(x) for x in pos),
                                        _chunk_of(a, timelines[a.name], t),
                                        f"the bodies of robots {a.name} and {b.name} overlap", int(len(k))))
    return findings


def _rects_overlap(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(T,) whether convex quadrilaterals p[t] and q[t] (T, 4, 2) overlap (separating axes)."""
    sep = np.zeros(len(p), dtype=bool)
    for poly in (p, q):
        edges = np.roll(poly, -1, axis=1) - poly
        normals = np.stack([-edges[..., 1], edges[..., 0]], axis=-1)  # (T, 4, 2)
        pa = np.einsum("tkd,tjd->tkj", normals, p)
        qa = np.einsum("tkd,tjd->tkj", normals, q)
        sep |= ((pa.max(axis=2) < qa.min(axis=2)) | (qa.max(axis=2) < pa.min(axis=2))).any(axis=1)
    return ~sep


def _chunk_of(r: SimRobot, tl: Timeline, t: float) -> str | None:
    k = min(int(np.searchsorted(tl.t1, t)), len(tl.index) - 1)
    if k < 0:
        return None
    c = int(r.program.chunk[tl.index[k]])
    return r.program.chunks[c] if c >= 0 else None


def _group(hits: list[tuple[np.ndarray, np.ndarray, np.ndarray]], kind: str, r: SimRobot, tl: Timeline,
           detail: str) -> list[Finding]:
    """One finding per chunk from hits ``(times (k,), positions (k, 3), moves (k,))``: the first
    instant, and how many samples."""
    t = np.concatenate([h[0] for h in hits]) if hits else np.zeros(0)
    if len(t) == 0:
        return []
    xyz = np.vstack([h[1] for h in hits])
    chunk = r.program.chunk[tl.index[np.concatenate([h[2] for h in hits])]]
    order = np.lexsort((t, chunk))
    chunk, t, xyz = chunk[order], t[order], xyz[order]
    start = np.flatnonzero(np.r_[True, chunk[1:] != chunk[:-1]])
    counts = np.diff(np.r_[start, len(chunk)])
    out = [Finding(kind, r.name, float(t[s]), tuple(float(x) for x in xyz[s]),
                   r.program.chunks[chunk[s]] if chunk[s] >= 0 else None, detail, int(n))
           for s, n in zip(start, counts)]
    return sorted(out, key=lambda f: f.time)


__all__ = ["Material", "body_box", "body_corners", "footprint_checks", "head_box", "overhangs", "path_samples", "robots_collide"]
