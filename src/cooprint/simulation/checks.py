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

The nozzle is looked at every ``step`` mm of its path (and at every move's ends); material is its
deposited paths sampled every cell. The body and printhead checks work on rasters in the robot's
frame (u along its facing, v to its left) with cells of half the ``tolerance``: the body check
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
    """Points (k, 3) along the moves (of the range ``moves``) every ``step`` mm and at their ends,
    their times (k,) and the move each lies on (k,)."""
    sel = np.arange(len(tl.t0))[moves]
    if deposits_only:
        sel = sel[tl.on[sel]]
    if len(sel) == 0:
        return np.zeros((0, 3)), np.zeros(0), np.zeros(0, np.int64)
    p0, p1, t0, t1 = tl.p0[sel], tl.p1[sel], tl.t0[sel], tl.t1[sel]
    n = np.maximum(np.ceil(np.linalg.norm(p1 - p0, axis=1) / step).astype(np.int64), 1)
    move = np.repeat(np.arange(len(sel)), n)
    frac = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n) + 1) / np.repeat(n, n)
    pts = p0[move] + frac[:, None] * (p1[move] - p0[move])
    times = t0[move] + frac * (t1[move] - t0[move])
    if not deposits_only and sel[0] == 0:  # the very first position too
        pts = np.vstack([p0[:1], pts])
        times = np.r_[t0[:1], times]
        move = np.r_[0, move]
    return pts, times, sel[move]


def _step(timelines: dict[str, Timeline], step: float, deposits_only: bool) -> float:
    """``step``, or longer on a print so long that it would make more than ``MAX_SAMPLES``."""
    total = sum(float(np.linalg.norm(tl.p1 - tl.p0, axis=1)[tl.on if deposits_only else slice(None)].sum())
                for tl in timelines.values())
    return max(step, total / MAX_SAMPLES)


@dataclass(frozen=True)
class Material:
    """Every robot's deposited paths as points every ``step`` mm, in the order they were laid
    down: position (k, 3), time (k,), layer height (k,), robot (k,) (its index in the list) and
    move (k,) (its index in that robot's timeline)."""

    xyz: np.ndarray
    t: np.ndarray
    h: np.ndarray
    robot: np.ndarray
    move: np.ndarray

    @staticmethod
    def sample(robots: list[SimRobot], timelines: dict[str, Timeline], step: float,
               layer_height: float) -> "Material":
        step = _step(timelines, step, deposits_only=True)
        parts = [path_samples(timelines[r.name], step, deposits_only=True) for r in robots]
        if not parts:
            return Material(np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros(0, np.int16), np.zeros(0, np.int64))
        t = np.concatenate([p[1] for p in parts])
        order = np.argsort(t, kind="stable")  # each robot's part is in time order already: a merge
        move = np.concatenate([p[2] for p in parts])
        robot = np.repeat(np.arange(len(parts), dtype=np.int16), [len(p[1]) for p in parts])
        h = np.concatenate([r.program.height[timelines[r.name].index[p[2]]] for r, p in zip(robots, parts)])
        h = np.where(h > 0, h, layer_height)
        return Material(np.vstack([p[0] for p in parts])[order], t[order], h[order], robot[order], move[order])


def _frame(facing: np.ndarray) -> np.ndarray:
    """(2, 2) rows: the facing direction and its left."""
    f = np.asarray(facing, dtype=np.float64) / np.linalg.norm(facing)
    return np.array([f, [-f[1], f[0]]])


def body_box(profile: RobotProfile, tolerance: float = 0.0) -> tuple[float, float, float, float]:
    """(u_lo, u_hi, v_lo, v_hi) of the body relative to the nozzle, in the robot's frame (u along
    the facing, v to its left), shrunk by ``tolerance``."""
    bd, length, w = profile.build_depth, profile.body_length, profile.body_width
    return (-bd - length + tolerance, -bd - tolerance, -w / 2 + tolerance, w / 2 - tolerance)


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

    origin: np.ndarray  # (2,) of cell (0, 0), padding included
    cell: float
    shape: tuple[int, int]
    window: tuple[int, int]
    box: tuple[float, float, float, float]

    @staticmethod
    def over(uv: np.ndarray, box: tuple[float, float, float, float], tolerance: float) -> "_Raster":
        lo = uv.min(axis=0) if len(uv) else np.zeros(2)
        hi = uv.max(axis=0) if len(uv) else np.zeros(2)
        size = np.array([box[1] - box[0], box[3] - box[2]])
        area = float(np.prod(hi - lo + 2 * size + 2 * tolerance))
        cell = max(tolerance / 2, np.sqrt(area / MAX_CELLS))
        window = tuple(int(np.ceil(s / cell)) + 1 for s in size)
        origin = lo - np.array(window) * cell
        shape = tuple(int(np.floor((h - l) / cell)) + 1 + 2 * w for l, h, w in zip(lo, hi, window))
        return _Raster(origin, cell, shape, window, box)

    def cells(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cell indices (row, column) of points (material: always inside the grid)."""
        c = np.floor((uv - self.origin) / self.cell).astype(np.int64)
        return c[:, 0], c[:, 1]

    def windows(self, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Index, into the window-filtered grid, of each nozzle position's footprint."""
        c = np.floor((uv + np.array([self.box[0], self.box[2]]) - self.origin) / self.cell).astype(np.int64)
        return (np.clip(c[:, 0], 0, self.shape[0] - self.window[0]),
                np.clip(c[:, 1], 0, self.shape[1] - self.window[1]))


def _nozzle_batches(tl: Timeline, step: float):
    """The nozzle's samples in time order, ``MOVES_AT_ONCE`` moves at a time: (xyz, t, move)."""
    for first in range(0, len(tl.t0), MOVES_AT_ONCE):
        yield path_samples(tl, step, False, slice(first, first + MOVES_AT_ONCE))


def body_on_material(robots: list[SimRobot], timelines: dict[str, Timeline], profile: RobotProfile,
                     material: Material, step: float = STEP, tolerance: float = TOLERANCE) -> list[Finding]:
    """Every robot whose body stands on material laid down before (one finding per robot and
    chunk, with the first instant and how many nozzle samples)."""
    n_step = _step(timelines, step, deposits_only=False)
    box = body_box(profile, tolerance)
    findings = []
    for r in robots:
        tl = timelines[r.name]
        frame = _frame(r.facing)
        m_uv = material.xyz[:, :2] @ frame.T
        grid = _Raster.over(m_uv, box, tolerance)
        first = np.full(grid.shape, np.inf)  # earliest time material lay in each cell
        row, col = grid.cells(m_uv)
        np.minimum.at(first, (row, col), material.t)
        del m_uv, row, col
        first = _sliding(_sliding(first, grid.window[0], 0, np.minimum), grid.window[1], 1, np.minimum)
        hits = []
        for xyz, t, move in _nozzle_batches(tl, n_step):
            wr, wc = grid.windows(xyz[:, :2] @ frame.T)
            k = np.flatnonzero(first[wr, wc] < t)
            hits.append((t[k], xyz[k], move[k]))
        findings += _group(hits, "body-on-material", r, tl, "the body stands on material laid down before")
    return findings


def printhead_hits_material(robots: list[SimRobot], timelines: dict[str, Timeline], profile: RobotProfile,
                            material: Material, step: float = STEP, tolerance: float = TOLERANCE) -> list[Finding]:
    """Every robot whose printhead meets material laid down before: within its reach around the
    nozzle and higher than ``nozzle_height`` above the nozzle tip (one finding per robot and
    chunk)."""
    n_step = _step(timelines, step, deposits_only=False)
    box = head_box(profile, tolerance)
    lift = profile.nozzle_height + tolerance
    m_z, m_t = material.xyz[:, 2], material.t
    top = np.maximum.accumulate(m_z) if len(m_z) else m_z  # the highest material laid down so far
    findings = []
    for r in robots:
        tl = timelines[r.name]
        frame = _frame(r.facing)
        m_uv = material.xyz[:, :2] @ frame.T
        grid = _Raster.over(m_uv, box, tolerance)
        high = np.full(grid.shape, -np.inf, dtype=np.float32)  # highest material in each cell so far
        row, col = grid.cells(m_uv)
        added = 0
        hits = []
        for xyz, t, move in _nozzle_batches(tl, n_step):
            uv_all = xyz[:, :2] @ frame.T
            for a in range(0, len(t), BATCH):
                uv, bt, under = uv_all[a:a + BATCH], t[a:a + BATCH], xyz[a:a + BATCH, 2] + lift
                ka, kb = np.searchsorted(m_t, [bt.min(), bt.max()])
                if kb == 0 or top[kb - 1] <= under.min():
                    continue  # nothing laid down yet reaches that high
                if ka > added:
                    np.maximum.at(high, (row[added:ka], col[added:ka]), m_z[added:ka].astype(np.float32))
                    added = ka
                hit = np.zeros(len(bt), dtype=bool)
                if ka > 0:
                    wr, wc = grid.windows(uv)
                    r0, c0 = wr.min(), wc.min()
                    part = high[r0:wr.max() + grid.window[0], c0:wc.max() + grid.window[1]]
                    part = _sliding(_sliding(part, grid.window[0], 0, np.maximum), grid.window[1], 1, np.maximum)
                    hit = part[wr - r0, wc - c0] > under
                # material laid down during the batch: point by point
                near = np.arange(ka, kb)
                near = near[m_z[near] > under.min()]
                if len(near):
                    lo, hi = uv.min(axis=0), uv.max(axis=0)
                    near = near[(m_uv[near, 0] >= lo[0] + box[0]) & (m_uv[near, 0] <= hi[0] + box[1])
                                & (m_uv[near, 1] >= lo[1] + box[2]) & (m_uv[near, 1] <= hi[1] + box[3])]
                if len(near):
                    du = m_uv[near, 0][None, :] - uv[:, 0, None]
                    dv = m_uv[near, 1][None, :] - uv[:, 1, None]
                    hit |= ((du >= box[0]) & (du <= box[1]) & (dv >= box[2]) & (dv <= box[3])
                            & (m_z[near][None, :] > under[:, None]) & (m_t[near][None, :] < bt[:, None])).any(axis=1)
                k = np.flatnonzero(hit) + a
                hits.append((t[k], xyz[k], move[k]))
        findings += _group(hits, "printhead-hits-material", r, tl,
                           f"material laid down before rises within the printhead's reach ({profile.nozzle_depth:g} mm) "
                           f"above its underside ({profile.nozzle_height:g} mm over the nozzle tip)")
    return findings


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
    zq = np.round((xyz[:, 2] - xyz[:, 2].min()) * 1000).astype(np.int64)  # micrometres
    nz = int(zq.max()) + 1
    # the earliest time of each (cell, height)
    own = (cxy[:, 0] * ny + cxy[:, 1]) * nz
    key, first = _min_by_key(own + zq, t)
    band = (np.clip(np.round(zq - 2500 * h), 0, None).astype(np.int64),
            np.clip(np.round(zq - 500 * h), -1, None).astype(np.int64))
    # on the floor, or one layer of air above it; else look in the point's own cell (most points
    # have material right below), then in the 24 cells around
    todo = np.flatnonzero(xyz[:, 2] > 2.5 * h + 1e-6)
    todo = todo[np.argsort(own[todo], kind="stable")]  # look-ups in key order
    for dx, dy in [(0, 0)] + [(dx, dy) for dx in range(-2, 3) for dy in range(-2, 3) if dx or dy]:
        base = own[todo] + (dx * ny + dy) * nz
        lo = np.searchsorted(key, base + band[0][todo], side="left")
        hi = np.searchsorted(key, base + band[1][todo], side="right")
        found = np.zeros(len(todo), dtype=bool)
        live = np.flatnonzero(lo < hi)
        while len(live):  # each height in the band, lowest first
            ok = first[lo[live]] < t[todo[live]]
            found[live[ok]] = True
            lo[live] += 1
            live = live[~ok & (lo[live] < hi[live])]
        todo = todo[~found]
        if len(todo) == 0:
            break
    findings = []
    for i, r in enumerate(robots):
        bad = todo[material.robot[todo] == i]
        findings += _group([(t[bad], xyz[bad], material.move[bad])], "overhang", r, timelines[r.name],
                           f"material laid down with nothing below it within {radius:g} mm (more than one layer "
                           "of air)")
    return findings


def _min_by_key(key: np.ndarray, value: np.ndarray, presorted: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The distinct keys, sorted, and the smallest value of each."""
    if not presorted:
        order = np.argsort(key, kind="stable")
        key, value = key[order], value[order]
    start = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    return key[start], np.minimum.reduceat(value, start)


def robots_collide(robots: list[SimRobot], timelines: dict[str, Timeline], profile: RobotProfile,
                   dt: float = 0.5, tolerance: float = TOLERANCE) -> list[Finding]:
    """Pairs of robots whose footprints overlap at the same instant (sampled every ``dt`` s)."""
    findings = []
    end = max((tl.end for tl in timelines.values()), default=0.0)
    times = np.arange(0.0, end + dt, dt)
    corners = {}
    u_lo, u_hi, v_lo, v_hi = body_box(profile, tolerance)
    box = np.array([[u_lo, v_lo], [u_hi, v_lo], [u_hi, v_hi], [u_lo, v_hi]])
    for r in robots:
        frame = _frame(r.facing)
        nozzle = timelines[r.name].position(times)[:, :2]
        corners[r.name] = nozzle[:, None, :] + (box @ frame)[None]  # (T, 4, 2) world corners
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


__all__ = ["Material", "body_box", "body_on_material", "head_box", "overhangs", "path_samples",
           "printhead_hits_material", "robots_collide"]
