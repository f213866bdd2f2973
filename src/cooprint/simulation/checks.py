"""Physical checks of a simulated plan (seed §2-3 made executable).

* ``body-on-material``: a robot's body footprint (``body_width`` x ``body_length``, its front
  ``build_depth`` behind the nozzle along the robot's facing) over material deposited before.
* ``robots-collide``: two robots' footprints overlapping at the same instant.

Both look at the nozzle every ``step`` mm of its path (and at every move's ends). Material is the
deposited paths, sampled every ``step`` mm, each point with the time it was laid down. To keep the
work proportional to the print, the nozzle samples are taken in windows: a window's footprints
all lie in the box of its nozzle positions grown by the body, and only the material points in
that box that existed before the window ended are looked at one sample at a time. A footprint
that only touches material (within ``tolerance``, which covers half a line width) is not a
finding; a plan the chunker made keeps the body just clear of its chunk's outer edge.
"""

from __future__ import annotations

import numpy as np

from cooprint.config import RobotProfile
from cooprint.simulation.timeline import Finding, SimRobot, Timeline

#: Spacing of nozzle and material samples, mm.
STEP = 2.0
#: Overlap below this is touching, not standing on, mm.
TOLERANCE = 1.0
#: Nozzle samples per window.
WINDOW = 512
#: At most this many material samples (the spacing grows on very long prints), and nozzle moves
#: sampled at once.
MAX_SAMPLES = 8_000_000
MOVES_AT_ONCE = 100_000
#: A robot whose body is found on material this many times is not looked at any further (the
#: finding's count then says "at least").
MAX_HITS = 20_000


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


def _frame(facing: np.ndarray) -> np.ndarray:
    """(2, 2) rows: the facing direction and its left."""
    f = np.asarray(facing, dtype=np.float64) / np.linalg.norm(facing)
    return np.array([f, [-f[1], f[0]]])


def body_box(profile: RobotProfile, tolerance: float = 0.0) -> tuple[float, float, float, float]:
    """(u_lo, u_hi, v_lo, v_hi) of the body relative to the nozzle, in the robot's frame (u along
    the facing, v to its left), shrunk by ``tolerance``."""
    bd, length, w = profile.build_depth, profile.body_length, profile.body_width
    return (-bd - length + tolerance, -bd - tolerance, -w / 2 + tolerance, w / 2 - tolerance)


def body_on_material(robots: list[SimRobot], timelines: dict[str, Timeline], profile: RobotProfile,
                     step: float = STEP, tolerance: float = TOLERANCE) -> list[Finding]:
    """Every robot whose body stands on material laid down before (one finding per robot and
    chunk, with the first instant and how many samples)."""
    m_step = _step(timelines, step, deposits_only=True)
    n_step = _step(timelines, step, deposits_only=False)
    parts = [path_samples(tl, m_step, deposits_only=True) for tl in timelines.values()]
    m_xy = np.vstack([p[0][:, :2] for p in parts]).astype(np.float32) if parts else np.zeros((0, 2), np.float32)
    m_t = np.concatenate([p[1] for p in parts]) if parts else np.zeros(0)
    del parts
    findings = []
    u_lo, u_hi, v_lo, v_hi = body_box(profile, tolerance)
    for r in robots:
        tl = timelines[r.name]
        frame = _frame(r.facing).astype(np.float32)
        m_uv = m_xy @ frame.T
        order = np.argsort(m_uv[:, 0])
        mu, mv_, mt = m_uv[order, 0], m_uv[order, 1], m_t[order]
        del m_uv, order
        hits: list[tuple[float, tuple, int]] = []
        for first in range(0, len(tl.t0), MOVES_AT_ONCE):
            if len(hits) >= MAX_HITS:
                break
            n_xyz, n_t, n_move = path_samples(tl, n_step, False, slice(first, first + MOVES_AT_ONCE))
            n_uv = n_xyz[:, :2] @ frame.T.astype(np.float64)
            for a in range(0, len(n_t), WINDOW):
                if len(hits) >= MAX_HITS:
                    break
                u, v, t = n_uv[a:a + WINDOW, 0], n_uv[a:a + WINDOW, 1], n_t[a:a + WINDOW]
                # (queries in the array's own float32: another type would convert the whole array)
                lo, hi = np.searchsorted(mu, np.array([u.min() + u_lo, u.max() + u_hi], dtype=mu.dtype))
                near = np.flatnonzero((mv_[lo:hi] >= v.min() + v_lo) & (mv_[lo:hi] <= v.max() + v_hi)
                                      & (mt[lo:hi] < t.max())) + lo
                if len(near) == 0:
                    continue
                rows_per_pass = max(1, (1 << 22) // len(near))  # bound the (samples x points) tests
                for b in range(0, len(t), rows_per_pass):
                    du = mu[near][None, :] - u[b:b + rows_per_pass, None]
                    dv = mv_[near][None, :] - v[b:b + rows_per_pass, None]
                    inside = ((du >= u_lo) & (du <= u_hi) & (dv >= v_lo) & (dv <= v_hi)
                              & (mt[near][None, :] < t[b:b + rows_per_pass, None]))
                    for k in np.flatnonzero(inside.any(axis=1)) + a + b:
                        hits.append((float(n_t[k]), tuple(float(x) for x in n_xyz[k]), int(n_move[k])))
        findings += _group(hits, "body-on-material", r, tl, "the body stands on material laid down before")
    return findings


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


def _group(hits: list[tuple[float, tuple, int]], kind: str, r: SimRobot, tl: Timeline,
           detail: str) -> list[Finding]:
    """One finding per chunk from ``(time, position, move)`` hits: the first instant, and how
    many samples."""
    out: dict[str | None, Finding] = {}
    counts: dict[str | None, int] = {}
    for t, pos, move in sorted(hits):
        c = int(r.program.chunk[tl.index[move]])
        chunk = r.program.chunks[c] if c >= 0 else None
        counts[chunk] = counts.get(chunk, 0) + 1
        if chunk not in out:
            out[chunk] = Finding(kind, r.name, t, pos, chunk, detail)
    return [Finding(f.kind, f.robot, f.time, f.position, f.chunk, f.detail, counts[c]) for c, f in out.items()]


__all__ = ["body_box", "body_on_material", "path_samples", "robots_collide"]
