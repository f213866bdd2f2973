"""Physical checks of a simulated plan (seed §2-3 made executable).

* ``body-on-material``: a robot's body footprint (``body_width`` x ``body_length``, its front
  ``build_depth`` behind the nozzle along the robot's facing) over material deposited before.
* ``robots-collide``: two robots' outlines (body, frame and printhead of each,
  :func:`outline_boxes`) overlapping at the same instant; the detail says which parts met.
* ``printhead-hits-material``: material deposited before within the printhead's reach (a square
  of half-side ``nozzle_depth`` around the nozzle, in the robot's frame) that rises above the
  printhead's underside (``nozzle_height`` above the nozzle tip), seed Fig. 3b: a chunk whose
  slope is steeper than theta_max = atan(nh / nd) reaches it.
* ``chunk-order``: material of a chunk laid down before every chunk it depends on is finished
  (a bundle's ``chunks[].deps``; :func:`chunk_order`).
* ``nozzle-in-material`` and ``double-deposit``: the nozzle's tip inside material laid down
  before, and material laid where material of the same layer already lies
  (:func:`material_checks`: a height field swept over every robot's moves in time order).
* ``overhang`` (a warning): material laid down with nothing below it: no material whose top is
  at most one layer of air lower (between 2.5 and 0.5 layer heights below) within ``radius``, and
  not on the floor.
* ``outside-part`` (bundles): material outside the part (the union of the chunk meshes) or
  outside every chunk of the robot that lays it, by more than half a line width
  (:func:`outside_part`).

The nozzle is looked at every ``step`` mm of its path (and at every move's ends); material is the
deposited paths sampled every ``step`` mm (more on prints of more than ``MAX_SAMPLES`` points). The
body and printhead checks work on rasters in the robot's frame (u along its facing, v to its
left) with cells of half the ``tolerance`` (more on very large prints), in one sweep along each
robot's path that makes its nozzle samples on the fly: the body check keeps, per cell, the
earliest time material was laid down there, takes the minimum over the footprint with a
sliding-window filter once, and then needs one look-up per nozzle sample; the printhead check
adds, before each nozzle sample, the material laid down before it to a raster of the highest
material so far (and to its maxima over blocks of cells) and looks at the reach block by block.
The overhang check sorts the material into cells. The loops are compiled (:mod:`.kernels`). A
footprint that only touches material (within ``tolerance``, which covers half a line width) is
not a finding; a plan the chunker made keeps the body just clear of its chunk's outer edge.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from cooprint.config import RobotProfile, SlicingSettings
from cooprint.geometry import unit_xy
from cooprint.simulation import kernels
from cooprint.simulation.inputs import ChunkMesh
from cooprint.simulation.timeline import Finding, SimRobot, Timeline, changes, segment_max
from cooprint.slicing.paths import ROUND_ROLES

#: Spacing of nozzle and material samples, mm.
STEP = 2.0
#: Overlap below this is touching, not standing on, mm (half a line width, and the cells of
#: the rasters, which are half of it).
TOLERANCE = 2.0
#: At most this many material samples (the spacing grows on very long prints); cells of one
#: raster (the cells grow on very large prints).
MAX_SAMPLES = 8_000_000
MAX_CELLS = 8_000_000
#: At most this many instants of the collision check (its step grows past 8,000 h of plan).
MAX_INSTANTS = 4_000_000
#: The collision check's instants are looked at this many at a time (the nozzles and facings of
#: a block of instants, not of all of them).
COLLIDE_BLOCK = 1 << 18
#: Between two instants the collision check looks closer wherever the robots could have met,
#: down to windows in which they move this little relative to each other, mm: an overlap that
#: lasts less than such a window is at most this deep beyond the parts' tolerances.
COLLIDE_DEPTH = 0.05
#: The printhead check keeps the highest material over blocks of this many cells square too,
#: and over blocks of this many blocks square.
HEAD_BLOCK = 8
#: The overhang check looks this far around a point for material below it (at least half the
#: sparse infill's line spacing plus a sample step, so that skins over sparse infill are not
#: overhangs), mm.
OVERHANG_RADIUS = 5.0


def _selection(tl: Timeline, step: float, deposits_only: bool) -> tuple[np.ndarray, np.ndarray, bool]:
    """The moves to sample, how many points each gets, and whether the very first position
    comes first (when the nozzle's whole path is asked for)."""
    sel = np.flatnonzero(tl.on) if deposits_only else np.arange(len(tl.t0))
    return sel, kernels.sample_counts(tl.length[sel], step), bool(not deposits_only and len(sel))


def path_samples(tl: Timeline, step: float, deposits_only: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (k, 3) float32 along the moves every ``step`` mm and at their ends (the nozzle's
    whole path, or the material), their times (k,) and the move each lies on (k,): the samples
    the checks see."""
    sel, n, first = _selection(tl, step, deposits_only)
    k = int(n.sum()) + first
    out = np.empty((k, 3), np.float32), np.empty(k), np.empty(k, np.int64)
    if len(sel):
        kernels.sample_moves(tl.p0, tl.p1, tl.t0, tl.t1, sel, n, first, *out, np.zeros(0), np.zeros(0), 0)
    return out


def _step(timelines: dict[str, Timeline], step: float, deposits_only: bool) -> float:
    """``step``, or longer on a print so long that it would make more than ``MAX_SAMPLES``."""
    total = sum(float(block_sum(lambda a, e: tl.length[a:e], len(tl.t0), lambda a, e: tl.on[a:e]) if deposits_only
                      else tl.length.sum()) for tl in timelines.values())
    return max(step, total / MAX_SAMPLES)


@dataclass(frozen=True)
class Material:
    """Every robot's deposited paths as points every ``step`` mm: position (k, 3) float32, time
    (k,) float64 and layer height (k,) float32; robot ``i``'s points are
    ``bounds[i]:bounds[i + 1]``, in the order it laid them down (:meth:`moves` says on which of
    its moves)."""

    xyz: np.ndarray
    t: np.ndarray
    h: np.ndarray
    bounds: np.ndarray

    @staticmethod
    def sample(robots: list[SimRobot], timelines: dict[str, Timeline], step: float,
               layer_height: float) -> "Material":
        step = _step(timelines, step, deposits_only=True)
        blocks = [[(c, min(len(tl.t0), c + BLOCK_MOVES)) for c in range(0, len(tl.t0), BLOCK_MOVES)]
                  for tl in (timelines[r.name] for r in robots)]

        def deposits(tl: Timeline, c: int, d: int) -> tuple[np.ndarray, np.ndarray]:
            """The moves of ``c:d`` that deposit (from ``c``) and how many points each gets."""
            sel = np.flatnonzero(tl.on[c:d])
            return sel, kernels.sample_counts(tl.length[c:d][sel], step)

        sizes = [sum(int(deposits(timelines[r.name], c, d)[1].sum()) for c, d in b) for r, b in zip(robots, blocks)]
        bounds = np.cumsum([0] + sizes)
        xyz, t, h = np.empty((bounds[-1], 3), np.float32), np.empty(bounds[-1]), np.empty(bounds[-1], np.float32)
        for i, (r, b) in enumerate(zip(robots, blocks)):  # each robot's points in order, a block of moves at a time
            tl = timelines[r.name]
            k = int(bounds[i])
            for c, d in b:
                sel, n = deposits(tl, c, d)
                if len(sel):
                    k = kernels.sample_moves(tl.p0[c:d], tl.p1[c:d], tl.t0[c:d], tl.t1[c:d], sel, n, False, xyz, t,
                                             np.zeros(0, np.int64),
                                             r.layer_heights(tl.index[c:d], layer_height).astype(np.float32), h, k)
        return Material(xyz, t, h, bounds)

    def moves(self, points: np.ndarray, timeline: Timeline) -> np.ndarray:
        """The move (index into its robot's ``timeline``) each of ``points`` (indices into the
        material, of one robot) lies on: the first to end at or after the point's time (a
        point's time lies in its move's, and a move that deposits takes some time)."""
        return np.searchsorted(timeline.t1, self.t[points], side="left")

    def robot(self, i: int) -> slice:
        return slice(int(self.bounds[i]), int(self.bounds[i + 1]))

    def before(self, t: float) -> "Material":
        """The material laid down before time ``t`` (each robot's points are in time order: a
        prefix of each; views when one robot laid it all)."""
        ends = [int(self.bounds[i]) + int(np.searchsorted(self.t[self.robot(i)], t, side="left"))
                for i in range(len(self.bounds) - 1)]
        if all(e == int(b) for e, b in zip(ends, self.bounds[1:])):
            return self
        parts = [slice(int(a), e) for a, e in zip(self.bounds[:-1], ends)]
        bounds = np.cumsum([0] + [e - int(a) for a, e in zip(self.bounds[:-1], ends)])
        if len(parts) == 1:
            return Material(self.xyz[parts[0]], self.t[parts[0]], self.h[parts[0]], bounds)
        return Material(*(np.concatenate([getattr(self, f)[sl] for sl in parts]) for f in ("xyz", "t", "h")), bounds)


def _frame(facing: np.ndarray) -> np.ndarray:
    """(2, 2) rows: the facing direction and its left."""
    f = unit_xy(facing)
    return np.array([f, [-f[1], f[0]]])


def body_box(profile: RobotProfile, tolerance: float = 0.0) -> tuple[float, float, float, float]:
    """(u_lo, u_hi, v_lo, v_hi) of the body relative to the nozzle, in the robot's frame (u along
    the facing, v to its left), shrunk by ``tolerance``."""
    u_lo, u_hi, v_lo, v_hi = profile.outline()["body"]
    return (u_lo + tolerance, u_hi - tolerance, v_lo + tolerance, v_hi - tolerance)


def body_corners(profile: RobotProfile, facing: np.ndarray, tolerance: float = 0.0) -> np.ndarray:
    """(4, 2) corners of the body relative to the nozzle, in world XY, for a robot facing
    ``facing``."""
    u_lo, u_hi, v_lo, v_hi = body_box(profile, tolerance)
    return np.array([[u_lo, v_lo], [u_hi, v_lo], [u_hi, v_hi], [u_lo, v_hi]]) @ _frame(facing)


def head_box(profile: RobotProfile, tolerance: float = 0.0) -> tuple[float, float, float, float]:
    """(u_lo, u_hi, v_lo, v_hi) of the printhead's reach around the nozzle (a square of half-side
    ``nozzle_depth``), shrunk by ``tolerance``."""
    r = max(profile.outline()["printhead"][1] - tolerance, 0.0)
    return (-r, r, -r, r)


#: The parts of a robot's outline (seed Fig. 1 and 3), in the order of :func:`outline_boxes`.
PARTS = ("body", "frame", "printhead")
#: How far each part is shrunk before two robots' outlines are compared, mm: two parts meet
#: when they overlap by more than the sum of their shrinks. The body keeps the footprint checks'
#: ``TOLERANCE`` (2 mm; a coarse wheel base, and bodies meeting bodies are judged as before). The
#: frame and the printhead are machined parts placed to the programs' 1 µm grid: a shrink of
#: 0.1 mm each lets two of them touch face to face (rounding in the time sampling and the
#: corners' arithmetic is far below it) and finds any true overlap of more than 0.2 mm. It must
#: stay under 0.5 mm: two printheads facing each other across a gap 1 mm narrower than
#: ``2 * nozzle_depth`` overlap by 1 mm, which must be found.
OUTLINE_TOLERANCE = {"body": TOLERANCE, "frame": 0.1, "printhead": 0.1}


def outline_boxes(profile: RobotProfile, tolerance: dict[str, float] | float | None = None
                  ) -> dict[str, tuple[float, float, float, float]]:
    """The robot's outline: part -> ``(u_lo, u_hi, v_lo, v_hi)`` relative to the nozzle, in the
    robot's frame (u along its facing, from the body to the nozzle; v to its left), each part a
    vertical prism compared in XY:

    * ``body``: ``u`` in ``[-build_depth - body_length, -build_depth]``, ``v`` in ``+-body_width/2``
      (on the floor, on its wheels);
    * ``frame``: ``u`` in ``[-build_depth, -nozzle_depth]``, ``v`` in ``+-frame_width/2`` (from the
      body's front over the print to the printhead; ``frame_width`` defaults to ``body_width``);
    * ``printhead``: ``u``, ``v`` in ``+-nozzle_depth`` (from ``nozzle_height`` above the tip up).

    Each is shrunk on every side by ``tolerance`` (mm, one for all or per part; ``None``:
    :data:`OUTLINE_TOLERANCE`), never past its centre line."""
    tol = OUTLINE_TOLERANCE if tolerance is None else tolerance
    out = {}
    for part, (u0, u1, v0, v1) in profile.outline().items():
        t = tol[part] if isinstance(tol, dict) else float(tol)
        tu, tv = min(t, (u1 - u0) / 2), min(t, (v1 - v0) / 2)
        out[part] = (u0 + tu, u1 - tu, v0 + tv, v1 - tv)
    return out


def outline_corners(profile: RobotProfile, facing: np.ndarray, tolerance: dict[str, float] | float | None = None
                    ) -> dict[str, np.ndarray]:
    """Part -> (4, 2) corners of the robot's outline (:func:`outline_boxes`) relative to the
    nozzle, in world XY, for a robot facing ``facing``."""
    frame = _frame(facing)
    return {part: np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]]) @ frame
            for part, (u0, u1, v0, v1) in outline_boxes(profile, tolerance).items()}


def outline_tables(pa: RobotProfile, fa: np.ndarray, pb: RobotProfile, fb: np.ndarray,
                   tolerance: dict[str, float] | float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What :func:`kernels.outlines_overlap` takes for robot a (profile ``pa``, facing ``fa``)
    against robot b: the four separating axes (4, 2) and, for each pair of parts (a's part
    ``p // 3``, b's part ``p % 3`` of :data:`PARTS`), the open interval (``lo``, ``hi`` (9, 4))
    of ``(nozzle_b - nozzle_a) . axis`` in which the two overlap (their Minkowski difference:
    ``min(a) - max(b)`` to ``max(a) - min(b)`` of the corners' projections)."""
    axes = np.vstack([_frame(fa), _frame(fb)])
    ca, cb = outline_corners(pa, fa, tolerance), outline_corners(pb, fb, tolerance)
    lo, hi = np.empty((len(PARTS) ** 2, 4)), np.empty((len(PARTS) ** 2, 4))
    for i, x in enumerate(PARTS):
        sa = ca[x] @ axes.T  # (4 corners, 4 axes)
        for j, y in enumerate(PARTS):
            sb = cb[y] @ axes.T
            lo[i * len(PARTS) + j] = sa.min(axis=0) - sb.max(axis=0)
            hi[i * len(PARTS) + j] = sa.max(axis=0) - sb.min(axis=0)
    return axes, lo, hi


@dataclass(frozen=True)
class _Raster:
    """Square cells over the material's box in one robot's (u, v) frame, padded on each side by
    a window: a footprint (``box`` relative to the nozzle) covers ``window`` cells from the cell
    of its low corner, which always lies in the padded grid after clipping; a point's cell
    counted from ``lo`` lies ``window`` cells further in the grid."""

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

    @property
    def params(self) -> tuple[np.ndarray, np.ndarray]:
        """The raster as the kernels take it: ``(lo_u, lo_v, cell, box_u_lo, box_v_lo)`` and
        ``(window_u, window_v, last row and column of a window's corner, window_u, window_v)``."""
        return (np.array([self.lo[0], self.lo[1], self.cell, self.box[0], self.box[2]]),
                np.array([*self.window, self.shape[0] - self.window[0], self.shape[1] - self.window[1], *self.window],
                         dtype=np.int64))


#: Moves looked at a block at a time by the checks that sweep a robot's path (their per-move
#: arrays are made for one block, not for the whole program: bounded memory on any plan).
BLOCK_MOVES = 1 << 20


def block_sum(values: Callable[[int, int], np.ndarray], n: int,
              mask: Callable[[int, int], np.ndarray] | None = None) -> float:
    """``np.sum(v)`` (or ``np.sum(v[m])``) of per-move values ``v`` (``values(a, e)``: those of
    moves ``a:e``, float64; ``mask(a, e)``: which of them count), the very same double, made a
    block of ``BLOCK_MOVES`` at a time: numpy sums a float64 array pairwise (halves of a length
    rounded down to a multiple of 8, down to 128 values), so a sum of a range that is one of
    those halves is its own ``np.sum``, and the halves are added as numpy adds them. Summaries
    keep their numbers to the last bit without an array of every move."""
    block, moves = BLOCK_MOVES, n
    if mask is None:
        get = values
    else:  # the selected values, by their rank among the selected: a block's worth at a time
        counts = np.cumsum([0] + [int(np.count_nonzero(mask(a, min(a + block, moves)))) for a in range(0, moves, block)])

        def get(lo: int, hi: int) -> np.ndarray:
            b0 = int(np.searchsorted(counts, lo, side="right")) - 1
            b1 = int(np.searchsorted(counts, hi, side="left"))
            a, e = b0 * block, min(b1 * block, moves)
            return values(a, e)[mask(a, e)][lo - counts[b0]:hi - counts[b0]]

        n = int(counts[-1])

    def pairwise(lo: int, size: int) -> float:
        if size <= max(block, 128):
            return np.add.reduce(get(lo, lo + size), initial=0.0)
        half = size // 2
        half -= half % 8
        return pairwise(lo, half) + pairwise(lo + half, size - half)

    return float(pairwise(0, n)) if n else 0.0


def chunk_slots(r: SimRobot, tl: Timeline, a: int, e: int) -> np.ndarray:
    """(e - a,) int64 the chunk slot of moves ``a:e`` of robot ``r``: the chunk's index in its
    program, or past them (``len(chunks)``) between chunks."""
    chunk = r.program.chunk[tl.index[a:e]].astype(np.int64)
    chunk[chunk < 0] = len(r.program.chunks)
    return chunk


def footprint_checks(robots: list[SimRobot], timelines: dict[str, Timeline], profile: RobotProfile,
                     material: Material, body: bool = True, head: bool = True, step: float = STEP,
                     tolerance: float = TOLERANCE) -> list[Finding]:
    """``body-on-material`` (``body``): a robot's body over material laid down before; and
    ``printhead-hits-material`` (``head``): material laid down before within the printhead's
    reach and higher than ``nozzle_height`` over the nozzle tip. One finding per robot, kind and
    chunk, with the first instant and how many nozzle samples.

    A robot that turns (``;@facing``) is checked span by span (:meth:`SimRobot.facing_spans`),
    each in the facing then in force, on rasters in that facing's frame; a span after a turn
    starts with the turn point itself, so that the body is checked there in the old facing (the
    last sample before) and in the new one (and in a facing it passes through while turning
    there, a span without moves)."""
    n_step = _step(timelines, step, deposits_only=False)
    findings = []
    fleet_profile = profile
    for r in robots:
        profile = r.profile or fleet_profile  # each robot's own body and printhead
        tl = timelines[r.name]
        if len(tl.t0) == 0:
            continue
        slots = len(r.program.chunks) + 1
        count, when, where = np.zeros((2, slots), np.int64), np.full((2, slots), np.inf), np.zeros((2, slots, 3))
        spans = r.facing_spans(tl)
        for j, span in enumerate(spans):
            frame = _frame(span.facing).astype(np.float32)
            a, e = span.start, span.stop
            # the material laid down before the span's last instant, on rasters in its frame
            last = float(tl.t1[e - 1]) if a < e else span.time
            mat = material.before(last) if len(spans) > 1 else material
            checks = robot_checks(mat, frame, profile, body, head, tolerance, tl)
            if not checks:
                break
            b, h = (checks[0] if body else None), (checks[-1] if head else None)
            states = (b is not None, (b or _BodyCheck.idle()).state, h is not None, (h or _HeadCheck.idle()).state)
            if a == e:  # no moves: the turn point alone, as a move that goes nowhere
                p = span.position[None].astype(np.float64)
                kernels.footprint_sweep(p, p, np.array([span.time]), np.array([span.time]), np.ones(1, np.int64),
                                        False, chunk_slots(r, tl, a, a + 1) if a < len(tl.t0) else
                                        np.array([slots - 1], np.int64), frame, *states, count, when, where)
            # its moves, from the turn point on (from the start, for the first span), a block at a
            # time (the sweep carries its state from one block to the next: the same hits)
            for c in range(a, e, BLOCK_MOVES):
                d = min(e, c + BLOCK_MOVES)
                kernels.footprint_sweep(tl.p0[c:d], tl.p1[c:d], tl.t0[c:d], tl.t1[c:d],
                                        kernels.sample_counts(tl.length[c:d], n_step), c == a,
                                        chunk_slots(r, tl, c, d), frame, *states, count, when, where)
        for k, (kind, detail) in enumerate(((_BodyCheck.kind, _BodyCheck.detail), (_HeadCheck.kind, _head_detail(profile)))):
            findings += _slot_findings(kind, r, count[k], when[k], where[k], detail)
    return sorted(findings, key=lambda f: (f.time, f.kind))


def _slot_findings(kind: str, r: SimRobot, count: np.ndarray, when: np.ndarray, where: np.ndarray,
                   detail: str) -> list[Finding]:
    """One finding per chunk slot of robot ``r`` that a sweep counted hits in (``count``, the
    first instant ``when`` and place ``where`` per slot; the last slot, past the program's
    chunks, is its moves between chunks)."""
    return [Finding(kind, r.name, float(when[slot]), tuple(float(x) for x in where[slot]),
                    r.program.chunks[slot] if slot < len(r.program.chunks) else None, detail, int(count[slot]))
            for slot in np.flatnonzero(count)]


def _head_detail(profile: RobotProfile) -> str:
    return (f"material laid down before rises within the printhead's reach ({profile.nozzle_depth:g} mm) "
            f"above its underside ({profile.nozzle_height:g} mm over the nozzle tip)")


def robot_checks(material: Material, frame: np.ndarray, profile: RobotProfile, body: bool = True,
                 head: bool = True, tolerance: float = TOLERANCE, timeline: Timeline | None = None) -> list:
    """The footprint checks of one robot (``frame``: its facing and its left, float32), on rasters
    sharing one cell size (1 mm, or more on very large prints) over the material; each has
    ``hits(uv, z, t)``: the indices of the nozzle samples (in the robot's frame, in time order)
    that meet material. With the robot's ``timeline``, the printhead check leaves out the
    material that is never above the printhead when it passes (:func:`kernels.reachable`): its
    nozzle samples must then come from that timeline."""
    boxes = ([body_box(profile, tolerance)] if body else []) + ([head_box(profile, tolerance)] if head else [])
    if not boxes:
        return []
    lo, hi = kernels.bounds_in_frame(material.xyz, frame)
    size = max((b[1] - b[0]) + (b[3] - b[2]) for b in boxes)
    cell = max(tolerance / 2, float(np.sqrt(np.prod(hi - lo + 2 * size) / MAX_CELLS)))
    return ([_BodyCheck(_Raster.over(lo, hi, cell, boxes[0]), frame, material)] if body else []) + \
        ([_HeadCheck(_Raster.over(lo, hi, cell, boxes[-1]), frame, material, profile, tolerance, timeline)]
         if head else [])


class _BodyCheck:
    """The earliest time material lay in each cell, its minimum over the body's footprint taken
    once (a sliding window); then one look-up per nozzle sample."""

    kind = "body-on-material"
    detail = "the body stands on material laid down before"

    def __init__(self, grid: _Raster, frame: np.ndarray, material: Material):
        first = np.full(grid.shape, np.inf)
        kernels.earliest(first, material.xyz, material.t, frame, *grid.params)
        self.state = (kernels.window_min(first, *grid.window), *grid.params)  # what the kernels take

    @staticmethod
    def idle() -> "_BodyCheck":
        """A check of the same types for a sweep that does not run it."""
        idle = object.__new__(_BodyCheck)
        idle.state = (np.zeros((1, 1)), np.zeros(5), np.zeros(6, np.int64))
        return idle

    def hits(self, uv: np.ndarray, z: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Indices of the nozzle samples (``uv`` (k, 2) in the robot's frame, heights, times)
        whose body stands on material."""
        return kernels.body_hits(*self.state, uv, t)


class _HeadCheck:
    """The highest material laid down so far in each cell (and in blocks of ``HEAD_BLOCK`` x
    ``HEAD_BLOCK`` cells): the nozzle samples are swept in time order, and before each the
    material laid down until its time is added (each robot's points are in time order); a
    sample's window is looked at block by block, cell by cell only in blocks that reach above
    the printhead and straddle the window's edge."""

    kind = "printhead-hits-material"

    def __init__(self, grid: _Raster, frame: np.ndarray, material: Material, profile: RobotProfile,
                 tolerance: float, timeline: Timeline | None = None):
        lift = np.float32(profile.nozzle_height + tolerance)
        xyz, t, bounds = material.xyz, material.t, material.bounds
        if timeline is not None:  # only the material that can reach this robot's printhead
            keep = np.empty(len(t), dtype=bool)
            kernels.reachable(t, xyz[:, 2], bounds, timeline.t1, np.minimum(timeline.p0[:, 2], timeline.p1[:, 2]),
                              float(lift), keep)
        else:
            keep = np.ones(len(t), dtype=bool)
        high = np.full(grid.shape, -np.inf, dtype=np.float32)
        coarse = np.full((2, *(-(-n // HEAD_BLOCK) for n in grid.shape)), -np.inf, dtype=np.float32)  # both levels
        added = bounds[:-1].astype(np.int64)  # per robot: its points added so far
        top = np.full(1, -np.inf, dtype=np.float32)  # the highest material added
        self.state = (high, coarse, HEAD_BLOCK, xyz, t, keep, frame, bounds[1:].astype(np.int64), added, top,
                      *grid.params, lift)  # what the kernels take
        self.detail = _head_detail(profile)

    @staticmethod
    def idle() -> "_HeadCheck":
        """A check of the same types for a sweep that does not run it."""
        idle = object.__new__(_HeadCheck)
        idle.state = (np.zeros((1, 1), np.float32), np.zeros((2, 1, 1), np.float32), HEAD_BLOCK,
                      np.zeros((0, 3), np.float32), np.zeros(0), np.zeros(0, bool), np.eye(2, dtype=np.float32),
                      np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(1, np.float32), np.zeros(5),
                      np.zeros(6, np.int64), np.float32(0))
        return idle

    def hits(self, uv: np.ndarray, z: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Indices of the nozzle samples (in time order, after those of earlier calls) whose
        printhead meets material."""
        return kernels.head_hits(*self.state, uv, z, t)


def overhangs(robots: list[SimRobot], timelines: dict[str, Timeline], material: Material,
              slicing: SlicingSettings, radius: float | None = None) -> list[Finding]:
    """Material laid down with nothing below it: no material laid down before whose top is at most
    one layer of air lower (between 2.5 and 0.5 of the point's layer height below it) within
    ``radius`` mm, and not on the floor (a warning; one finding per robot and chunk); except a
    bridge's thread anchored at both ends (:func:`anchored`).

    Cells of ``radius / 2`` from half a cell before the material's lowest x and y (the same
    material laid elsewhere gets the same findings): each (cell, height) keeps the earliest time
    material was there; a point looks in its band of heights in its own cell, then in the 24 cells
    around. So a point with material within ``radius`` below is never an overhang, and one is
    found when nothing lies within ``radius`` (up to about 2.1 ``radius`` on the diagonals)."""
    if radius is None:
        spacing = slicing.extrusion_width / slicing.infill_density if slicing.infill_density > 0 else 0.0
        radius = max(OVERHANG_RADIUS, spacing / 2 + STEP)
    xyz, t, h = material.xyz, material.t, material.h
    if len(t) == 0:
        return []
    # cells from half a cell before the material's corner: the same material laid anywhere gets the
    # same cells (not the floating point's rounding at cell edges when its sizes are whole cells)
    origin = (float(xyz[:, 0].min()) - radius / 4, float(xyz[:, 1].min()) - radius / 4)
    todo = np.flatnonzero(kernels.overhang_flags(xyz, h, t, radius / 2, origin=origin))
    findings = []
    for i, r in enumerate(robots):
        block = material.robot(i)
        bad = todo[np.searchsorted(todo, block.start):np.searchsorted(todo, block.stop)]
        moves = material.moves(bad, timelines[r.name])
        keep = ~anchored(material, block, bad, moves, r, timelines[r.name], radius)
        bad, moves = bad[keep], moves[keep]
        findings += _group([(t[bad], xyz[bad], moves)], "overhang", r, timelines[r.name],
                           f"material laid down with nothing below it within {radius:g} mm (more than one layer "
                           "of air)")
    return findings


def anchored(material: Material, block: slice, bad: np.ndarray, moves: np.ndarray, r: SimRobot, tl: Timeline,
             reach: float) -> np.ndarray:
    """(k,) bool: which of the points ``bad`` (a robot's material with nothing below it, indices
    into ``material`` in ``block``, laid by its ``moves``) are a bridge's thread held at both ends:
    laid with a round role (``ROUND_ROLES``: bridge infill, overhang perimeter; the slicer lays
    them over air on purpose, as a thread with bridge flow and speed), in a stretch of unsupported
    points along one continuous extrusion (no travel between them) that has a supported point
    (material within ``reach`` below) right before it and right after it on the same extrusion,
    and that runs straight between those two anchors (every point within ``reach`` of the segment
    joining them, in XY). A bridge line from one anchor to the other is held; a bridge that runs
    out into the air (a cantilever: an end with nothing within reach), or that goes out and back
    from one side, is not. Other roles keep the rule (their points are never held)."""
    held = np.zeros(len(bad), dtype=bool)
    if not len(bad):
        return held
    thread = np.isin(r.program.role[tl.index[moves]], ROUND_ROLES)
    if not thread.any():
        return held
    # runs of consecutive unsupported points, the points right before and after each, their moves
    new = np.r_[True, np.diff(bad) != 1]
    before, after = bad[new] - 1, bad[np.r_[new[1:], True]] + 1
    ends = np.clip(np.stack([before, after]), block.start, block.stop - 1)  # (2, runs)
    end_moves = material.moves(ends.ravel(), tl)
    # extrusions: the moves between two travels (moves that go somewhere without depositing),
    # numbered over the moves these points lie on (a timeline's lengths may be computed on demand)
    lo, hi = int(min(moves.min(), end_moves.min())), int(max(moves.max(), end_moves.max())) + 1
    off = lo + np.flatnonzero(~tl.on[lo:hi])
    breaks = off[tl.length[off] > 0]
    extrusion = np.searchsorted(breaks, moves)
    # stretches: the runs cut where the extrusion changes
    new |= np.r_[True, np.diff(extrusion) != 0]
    first = np.flatnonzero(new)
    last = np.r_[first[1:], len(bad)] - 1
    before, after = bad[first] - 1, bad[last] + 1
    inside = (before >= block.start) & (after < block.stop)
    ends = np.clip(np.stack([before, after]), block.start, block.stop - 1)  # (2, stretches)
    ends_extrusion = np.searchsorted(breaks, material.moves(ends.ravel(), tl)).reshape(2, -1)
    held_ends = inside & (ends_extrusion[0] == extrusion[first]) & (ends_extrusion[1] == extrusion[last])
    # every point within reach of the segment between its stretch's anchors
    stretch = np.cumsum(new) - 1
    a = material.xyz[ends[0], :2].astype(np.float64)[stretch]
    b = material.xyz[ends[1], :2].astype(np.float64)[stretch]
    p = material.xyz[bad, :2].astype(np.float64)
    ab = b - a
    u = np.clip(np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0.0, 1.0)
    aside = np.hypot(*(p - a - u[:, None] * ab).T)
    straight = np.ones(len(first), dtype=bool)
    np.logical_and.at(straight, stretch, aside <= reach)
    return thread & (held_ends & straight)[stretch]


def robots_collide(robots: list[SimRobot], timelines: dict[str, Timeline], profile: RobotProfile,
                   dt: float = 0.5, tolerance: dict[str, float] | float | None = None) -> list[Finding]:
    """Pairs of robots whose outlines overlap at the same instant: body, frame and printhead of
    each (:func:`outline_boxes`, each robot's own profile, shrunk by ``tolerance``, by default
    :data:`OUTLINE_TOLERANCE`) against those of the other, each robot in the facing in force at
    that instant, sampled every ``dt`` s (or at ``MAX_INSTANTS`` instants over a longer plan),
    and between the instants wherever the robots could have met (:func:`_between_instants`).

    One finding per pair of robots: the first instant they meet, with the parts that meet then
    in its detail (``the printhead of A meets the printhead of B``) and, when others meet later,
    how many instants each pair of parts met; ``count`` is the instants they overlap at all
    (an instant stands for the ``dt`` around it)."""
    findings = []
    if len(robots) < 2:
        return findings
    end = max((tl.end for tl in timelines.values()), default=0.0)
    dt = max(dt, end / MAX_INSTANTS)  # a plan of years (a program that jumps kilometres) is looked at less often
    times = np.arange(0.0, end + dt, dt)
    robots = [r for r in robots if len(timelines[r.name].t1) or r.start is not None]  # one with neither is nowhere
    facing, turns, speed = {}, {}, {}  # per robot: its facings, when it turns, its top speed
    for r in robots:
        spans = r.facing_spans(timelines[r.name])
        facing[r.name] = ([sp.facing for sp in spans],)
        turns[r.name] = np.array([sp.time for sp in spans[1:]])
        speed[r.name] = _top_speed(timelines[r.name])
    for i, a in enumerate(robots):
        for b in robots[i + 1:]:
            pa, pb = a.profile or profile, b.profile or profile  # each robot's own outline
            pair = _Pair(a, b, pa, pb, facing, tolerance)
            both, turn = speed[a.name] + speed[b.name], np.sort(np.r_[turns[a.name], turns[b.name]])
            h = dt / 2
            refine = both > 0.0 and both * h > COLLIDE_DEPTH  # the windows between instants are looked into
            mask, near = np.zeros(len(times), np.int32), []
            for s in range(0, len(times), COLLIDE_BLOCK):  # the instants a block at a time
                at = times[s:s + COLLIDE_BLOCK]
                state = _pair_state(pair, at, timelines)  # both nozzles and facings there
                mask[s:s + COLLIDE_BLOCK] = got = pair.mask(at, state[2], state[3], state[0], state[1])
                if refine:  # the windows without an overlap at their instant that may hold one
                    free = np.flatnonzero(got == 0)
                    na, nb, ka, kb = state if len(free) == len(at) else (x[free] for x in state)
                    close = pair.mask(at[free], ka, kb, na, nb, margin=both * h / 2) != 0
                    if len(turn):
                        close |= np.searchsorted(turn, at[free] - h) != np.searchsorted(turn, at[free] + h,
                                                                                         side="right")
                    near.append(free[close] + s)
            when = times.copy()
            if refine:
                _between_instants(pair, times, dt, mask, when, both, turn, timelines,
                                  np.concatenate(near) if near else np.zeros(0, np.int64))
            k = np.flatnonzero(mask)
            if len(k):
                k = k[np.argsort(when[k], kind="stable")]
                t = float(when[k[0]])
                tl, tb = timelines[a.name], timelines[b.name]
                pos = tl.position(t) if len(tl.t1) else np.asarray(a.start, dtype=np.float64)
                other = tb.position(t) if len(tb.t1) else np.asarray(b.start, dtype=np.float64)
                chunk_b = _chunk_of(b, tb, t) if len(tb.t1) else None
                where_b = f"{b.name}'s nozzle at ({other[0]:.1f}, {other[1]:.1f}, {other[2]:.1f}) mm" + \
                    (f" in chunk {chunk_b}" if chunk_b else "")
                findings.append(Finding("robots-collide", a.name, t, tuple(float(x) for x in pos),
                                        _chunk_of(a, timelines[a.name], t),
                                        _collide_detail(a.name, b.name, mask[k], where_b), int(len(k))))
    return findings


class _Pair:
    """Two robots' outlines against each other (:func:`robots_collide`): the kernel's tables for
    each pair of facings in force, kept, for the parts shrunk by ``tolerance`` less a margin."""

    def __init__(self, a: SimRobot, b: SimRobot, pa: RobotProfile, pb: RobotProfile, facing: dict,
                 tolerance: dict[str, float] | float | None) -> None:
        self.a, self.b, self.pa, self.pb = a, b, pa, pb
        self.fa, self.fb = facing[a.name][0], facing[b.name][0]
        self.tol = OUTLINE_TOLERANCE if tolerance is None else tolerance
        self.tables: dict = {}

    def mask(self, times: np.ndarray, ka: np.ndarray, kb: np.ndarray, na: np.ndarray, nb: np.ndarray,
             margin: float = 0.0) -> np.ndarray:
        """The kernel's bit masks at ``times`` (robot a's facing ``ka``, b's ``kb``, nozzles ``na``,
        ``nb`` there), every part grown by ``margin`` mm (0: as the check compares them)."""
        tol = ({p: t - margin for p, t in self.tol.items()} if isinstance(self.tol, dict)
               else float(self.tol) - margin)
        mask = np.zeros(len(times), np.int32)
        if len(times) == 0:
            return mask
        # runs of instants with the same pair of facings in force
        cuts = np.r_[0, np.flatnonzero((np.diff(ka) != 0) | (np.diff(kb) != 0)) + 1, len(times)]
        for s, e in zip(cuts[:-1], cuts[1:]):
            key = (int(ka[s]), int(kb[s]), margin)
            if key not in self.tables:
                self.tables[key] = outline_tables(self.pa, self.fa[key[0]], self.pb, self.fb[key[1]], tol)
            mask[s:e] = kernels.outlines_overlap(na[s:e], nb[s:e], *self.tables[key])
        return mask


def _between_instants(pair: _Pair, times: np.ndarray, dt: float, mask: np.ndarray, when: np.ndarray,
                      speed: float, turns: np.ndarray, timelines: dict[str, Timeline], near: np.ndarray) -> None:
    """Overlaps that begin and end between two instants of the collision check, added to
    ``mask`` (and their first time to ``when``) at the instant whose window (``dt`` wide) holds
    them: two printheads crossing head-on at travel speed overlap for less than ``dt``.

    Within half a window ``h`` of an instant the robots move at most ``speed * h`` relative to
    each other (``speed``: the sum of their fastest moves in XY; the timelines interpolate each
    move linearly), so outlines that do not meet there with every part grown by ``speed * h / 2``
    do not meet anywhere in the window (each axis's interval grows by at least ``speed * h``).
    Windows that may hold an overlap are halved and looked at again, down to ``COLLIDE_DEPTH``
    of relative motion (at most ``MAX_INSTANTS`` windows at a time); a window in which a robot
    turns is always halved (its outline changes).
    ``near``: the instants (indices into ``times``, ascending) whose whole windows may hold an
    overlap, as :func:`robots_collide` finds them a block of instants at a time: the first
    look, with ``speed * dt / 2 > COLLIDE_DEPTH``."""
    centre, owner, h = times[near], near, dt / 2
    first = True
    while len(centre) and speed * h > COLLIDE_DEPTH:
        if not first:  # the windows that may still hold an overlap
            close = _in_blocks(centre, lambda c, state: pair.mask(c, state[2], state[3], state[0], state[1],
                                                                   margin=speed * h / 2) != 0, pair, timelines)
            if len(turns):
                close |= np.searchsorted(turns, centre - h) != np.searchsorted(turns, centre + h, side="right")
            centre, owner = centre[close], owner[close]
        first = False
        if 2 * len(centre) > MAX_INSTANTS:  # bounded work: robots that stay within a hair of each other for days
            break
        h /= 2
        # each window halved: its two halves' centres, in time order (windows are at least 2 h apart)
        halves = np.empty(2 * len(centre))
        halves[0::2], halves[1::2] = centre - h, centre + h
        centre, owner = halves, np.repeat(owner, 2)
        hit = _in_blocks(centre, lambda c, state: pair.mask(c, state[2], state[3], state[0], state[1]), pair,
                         timelines)
        got = hit != 0
        if got.any():
            first_hit = np.unique(owner[got], return_index=True)[1]  # each window's earliest (sorted)
            k = np.flatnonzero(got)[first_hit]
            mask[owner[k]] = hit[k]
            when[owner[k]] = centre[k]
            keep = mask[owner] == 0
            centre, owner = centre[keep], owner[keep]


def _in_blocks(t: np.ndarray, look, pair: _Pair, timelines: dict[str, Timeline]) -> np.ndarray:
    """``look(times, state)`` for sorted times ``t``, ``COLLIDE_BLOCK`` at a time (``state``:
    both nozzles and facings there, :func:`_pair_state`), concatenated: the robots' states at a
    block of times at once, not at all of them."""
    out = [look(t[s:s + COLLIDE_BLOCK], _pair_state(pair, t[s:s + COLLIDE_BLOCK], timelines))
           for s in range(0, len(t), COLLIDE_BLOCK)]
    return np.concatenate(out) if out else np.zeros(0, np.int32)


def _pair_state(pair: _Pair, t: np.ndarray, timelines: dict[str, Timeline]):
    """Both robots' nozzles in XY and the facings in force at sorted times ``t``."""
    out = []
    for r in (pair.a, pair.b):
        out.append(_nozzle_xy(r, timelines[r.name], t))
    ks = []
    for r in (pair.a, pair.b):
        spans = r.facing_spans(timelines[r.name])
        starts = np.array([sp.time for sp in spans])
        ks.append(np.searchsorted(starts[1:], t, side="right"))
    return out[0], out[1], ks[0], ks[1]


def _top_speed(tl: Timeline) -> float:
    """At least the fastest the nozzle moves in XY on any move of ``tl``, mm/s (its fastest in
    XYZ; 0: it never moves)."""
    top = 0.0
    for a in range(0, len(tl.t1), BLOCK_MOVES):  # a block of moves at a time (the maximum is the same)
        span = tl.t1[a:a + BLOCK_MOVES] - tl.t0[a:a + BLOCK_MOVES]
        moving = span > 0
        top = max(top, float(np.max(tl.length[a:a + BLOCK_MOVES][moving] / span[moving], initial=0.0)))
    return top


def _collide_detail(a: str, b: str, masks: np.ndarray, where_b: str = "") -> str:
    """Which parts of robots ``a`` and ``b`` meet: at the first instant of ``masks`` (the
    kernel's bit masks of the instants they overlap; ``where_b``: where b is then, the finding's
    position being a's), and how many instants each pair of parts meets when more than one pair
    does."""
    n = len(PARTS)
    pairs = [(PARTS[p // n], PARTS[p % n]) for p in range(n * n)]
    first = [f"the {x} of {a} meets the {y} of {b}" for p, (x, y) in enumerate(pairs) if masks[0] >> p & 1]
    counts = [(x, y, int(np.count_nonzero(masks >> p & 1))) for p, (x, y) in enumerate(pairs)]
    counts = [c for c in counts if c[2]]
    detail = " and ".join(first) + (f" ({where_b})" if where_b else "")
    if len(counts) > 1:
        detail += "; instants met: " + ", ".join(f"{a} {x} / {b} {y} {c}" for x, y, c in counts)
    return detail


def _nozzle_xy(r: SimRobot, tl: Timeline, times: np.ndarray) -> np.ndarray | None:
    """(T, 2) the nozzle's XY at sorted ``times`` (as :meth:`Timeline.position`); a robot without
    moves stands at its start all along (``None``: it has none either, it is nowhere)."""
    if len(tl.t1) == 0:
        if r.start is None:
            return None
        return np.broadcast_to(np.asarray(r.start, dtype=np.float64)[:2], (len(times), 2))
    # the kernel's pointer walks from the move under way at the first time (where a walk from
    # the first move would stop): the same positions, without walking the moves before
    k = min(int(np.searchsorted(tl.t1, times[0], side="left")), len(tl.t1) - 1) if len(times) else 0
    return kernels.positions_at(tl.t0[k:], tl.t1[k:], tl.p0[k:], tl.p1[k:], times)


def _chunk_of(r: SimRobot, tl: Timeline, t: float) -> str | None:
    k = min(int(np.searchsorted(tl.t1, t)), len(tl.index) - 1)
    if k < 0:
        return None
    c = int(r.program.chunk[tl.index[k]])
    return r.program.chunks[c] if c >= 0 else None


#: A chunk's first deposit may start this long before a dependency's last one ends and still be
#: in order, s: the timelines' rounding (a dependent chunk printed right after its dependency, by
#: the same robot or after a WAIT, starts at the very instant it ends).
ORDER_TOLERANCE = 1e-6


def chunk_order(robots: list[SimRobot], timelines: dict[str, Timeline],
                deps: dict[str, tuple[str, ...]]) -> list[Finding]:
    """``chunk-order``: material of a chunk laid down before every chunk it depends on
    (``deps``: job.json ``chunks[].deps``) is finished: the chunk would lean on material that is
    not there yet (seed §3: a chunk is printed on the sloped face of the chunks before it).

    A chunk starts at its first deposit (the start of the first tool-on move of that chunk, by
    any robot) and is finished at the end of its last one; a chunk without material is finished
    at its NOTIFY (the event named by its id), or at once when nothing announces it. One finding
    per chunk that starts before a dependency is finished: the robot and the place of its first
    deposit, then, the dependencies not finished and by how many seconds; the count is how many."""
    start: dict[str, tuple[float, str, np.ndarray]] = {}  # chunk: (time, robot, position) of its first deposit
    end: dict[str, float] = {}  # chunk: when its last deposit ends
    announced: dict[str, float] = {}  # event: when it is first announced
    for r in robots:
        tl = timelines[r.name]
        for t, event in tl.notifies:
            announced[event] = min(announced.get(event, np.inf), float(t))
        first_of, last_of = {}, {}  # per chunk (index in the program): its first and last deposit
        for b in range(0, len(tl.t0), BLOCK_MOVES):
            on = np.flatnonzero(tl.on[b:b + BLOCK_MOVES]) + b
            chunk = r.program.chunk[tl.index[on]]
            for c in np.unique(chunk[chunk >= 0]).tolist():
                moves = on[chunk == c]
                first_of.setdefault(c, int(moves[0]))
                last_of[c] = int(moves[-1])
        for c in sorted(first_of):
            name = r.program.chunks[c]
            first, last = first_of[c], last_of[c]
            if name not in start or tl.t0[first] < start[name][0]:
                start[name] = (float(tl.t0[first]), r.name, tl.p0[first])
            end[name] = max(end.get(name, -np.inf), float(tl.t1[last]))
    findings = []
    for c, needs in deps.items():
        if c not in start:
            continue  # no material: nothing leans on anything
        t, robot, where = start[c]
        early = [(d, end.get(d, announced.get(d, 0.0)) - t) for d in needs]
        early = [(d, dt) for d, dt in early if dt > ORDER_TOLERANCE]
        if early:
            detail = "laid down before the chunks it depends on are finished: " + \
                ", ".join(f"{d} ({dt:.3f} s early)" for d, dt in early)
            findings.append(Finding("chunk-order", robot, t, tuple(float(x) for x in where), c, detail, len(early)))
    return sorted(findings, key=lambda f: (f.time, f.chunk))


#: Cells of the material height field, in line widths: half a line width, so that the bead beside
#: (a line spacing away, at least 0.72 line widths: two points of one cell are at most
#: 0.71 widths apart) never shares a cell with the nozzle's axis.
MATERIAL_CELL = 0.5
#: At most this many cells of the height field at once (28 bytes each): a larger print is swept
#: in bands of columns, each move in every band it passes through.
MATERIAL_CELLS = 2_500_000
#: At most about this many cells in all bands (the cells grow on a print spread wider than
#: 1 m square at half a line width, so that material kilometres apart is a few bands, not
#: millions).
MATERIAL_ALL_CELLS = 4 * MATERIAL_CELLS
#: Material of the layer a move lays is the same bead again when its axis passes within this
#: many line widths of the nozzle's: half the closest two beads of one layer come by design (the fill
#: area's edge is a quarter line spacing from the last perimeter's axis: PrusaSlicer's 25%
#: infill overlap, so an infill line may run along a perimeter 0.1 mm from it).
DOUBLE_NEAR = 0.125
#: At most about this many cell visits in all (the moves' X plus Y extents over the cell size):
#: on a print of more path than that, the cells grow (nefertiti's 2-robot plan, 48 km of moves in
#: X plus Y: 2.4 mm), so the sweep stays at a few tenths of a second; coarser cells miss more (a
#: cell keeps the last bead laid in it: a layer repeated is still found, in fewer cells), never
#: find more (the distances to that bead's segment are exact).
MATERIAL_VISITS = 20_000_000
#: A double deposit is more than this many line widths of doubled path in a row (4.5 mm for a
#: 0.45 mm line): slicers overlap short pieces by design or where a section is thinner than two
#: perimeters (benchy's hull beside its chimney at z 38.6 mm: two perimeters 0.08 mm apart for
#: between one and two line widths; PrusaSlicer's own G-code of the OCCT housing at z 224.8 mm:
#: a 3.6 mm piece run over by an infill line, 8 line widths), a few millimetres of a bead more
#: than a print can take; a layer or a chunk laid twice, or two robots in one region, double
#: whole paths (tens of line widths and more).
DOUBLE_RUN = 10.0
#: Moves merged into time order and swept at a time (divided among the robots of a large fleet).
MATERIAL_BATCH = 1 << 16


def _move_columns(r: SimRobot, tl: Timeline, a: int, e: int, width: float, height: float, offset: int,
                  carry: tuple[float, float, bool]) -> tuple[list[np.ndarray], tuple[float, float, bool]]:
    """What :func:`kernels.material_sweep` takes of a robot's moves ``a:e``: ends, times, tool on,
    then chunk slots (after ``offset``), layer heights, widths, deposits before each (mm) and how
    far back the robot's own material is its fresh bead (the extrusion under way since the tool
    went on, and two line widths before it: a sliver of a section thinner than a line is a loop
    whose two sides meet). ``carry``: deposits so far, where the extrusion under way began, and
    whether the tool was on, at move ``a``; returned for move ``e``."""
    on = tl.on[a:e]
    done, began, was_on = carry
    ch = r.program.chunk[tl.index[a:e]].astype(np.int64)
    wid, hgt = r.bead(tl.index[a:e], width, height)
    laid = np.where(on, tl.length[a:e], 0.0)
    dep = done + np.concatenate([[0.0], np.cumsum(laid)[:-1]])
    begins = on & ~np.r_[was_on, on[:-1]]
    first = np.maximum.accumulate(np.where(begins, np.arange(len(on)), -1))
    since = np.where(first >= 0, dep[np.maximum(first, 0)], began)
    fresh = np.where(on, dep - since, 0.0) + 2 * wid
    cols = [tl.p0[a:e], tl.p1[a:e], tl.t0[a:e], tl.t1[a:e], on,
            np.where(ch < 0, len(r.program.chunks), ch) + offset, hgt, wid, dep, fresh]
    after = (done + float(laid.sum()), float(since[-1]) if len(since) else began,
             bool(on[-1]) if len(on) else was_on)
    return cols, after


def material_checks(robots: list[SimRobot], timelines: dict[str, Timeline], slicing: SlicingSettings,
                    cell: float | None = None, max_cells: int = MATERIAL_CELLS,
                    batch: int = MATERIAL_BATCH) -> list[Finding]:
    """The nozzle against the material laid down before it (errors, one finding per robot and
    chunk: the first instant and place, and how many cells of path):

    * ``nozzle-in-material``: on any move, tool on or off, the tip goes into material: a bead
      within half a line width of the nozzle's axis whose top is more than half a layer height
      (the move's) above the tip. Why half a layer: a bead's top is the tip height of the move
      that laid it, the layers of every chunk share one z grid and coordinates are on a 1 µm
      grid, so material of the layer the nozzle is in has its top at the tip (a travel across the
      layer it is printing) and the next material above is a whole layer higher; half a layer is
      as far from both as can be.
    * ``double-deposit``: with the tool on, a bead within ``DOUBLE_NEAR`` line widths of the axis
      is of the layer the move lays (its top within half a layer height of the tip) where the
      plan expects the layer below (a whole layer lower) or the floor, along more than
      ``DOUBLE_RUN`` line widths of path in a row (an infill line ending on the perimeter, the
      seam where a loop closes, two perimeters of a section thinner than two lines overlap for
      less).

    How: the material is a height field of cells of half a line width (``MATERIAL_CELL`` x the
    slicing settings' ``extrusion_width``; larger on a print of more path than
    ``MATERIAL_VISITS`` cells or wider than ``MATERIAL_ALL_CELLS``), each keeping its top, the
    robot that laid it, how far along that robot's deposits and the bead's segment (distances to
    it are exact). The moves of all robots are merged by start time (``batch`` at a time; a move
    sees every move that started before it whole) and each walks the cells its axis passes
    through, is checked against them and lays its bead there (:func:`kernels.material_sweep`). A
    robot's own material is its fresh bead, not material laid before, within the extrusion under
    way (since the tool went on) and two line widths of deposits before it (the segment before a
    corner). Prints wider than ``max_cells`` cells are swept in bands of columns."""
    w = float(slicing.extrusion_width)
    active = [(i, r, timelines[r.name]) for i, r in enumerate(robots) if len(timelines[r.name].t0)]
    box = np.array([np.inf, np.inf, -np.inf, -np.inf])
    walk = sum(kernels.path_extent(tl.p0, tl.p1, tl.on, box) for _, _, tl in active)
    if not np.isfinite(box).all():
        return []  # nothing is laid down
    if cell is None:
        area = float(np.prod(box[2:] - box[:2] + w))
        cell = max(MATERIAL_CELL * w, walk / MATERIAL_VISITS, float(np.sqrt(area / MATERIAL_ALL_CELLS)))
    lo, hi = box[:2] - cell, box[2:] + cell
    nx, ny = (int(np.ceil((hi[k] - lo[k]) / cell)) + 1 for k in range(2))
    ncol = max(1, min(nx, max_cells // ny))
    offsets = np.cumsum([0] + [len(r.program.chunks) + 1 for _, r, _ in active])  # each robot's chunk slots
    slots = int(offsets[-1])
    count, when, where = np.zeros((2, slots), np.int64), np.full((2, slots), np.inf), np.zeros((2, slots, 3))
    nr = len(active)
    cells = np.empty((ncol, ny, kernels.FIELDS), np.float32)  # per cell: top, robot, path position, bead
    run, run_t, run_xyz = np.zeros(nr), np.zeros(nr), np.zeros((nr, 3))
    run_cells, run_slot = np.zeros(nr, np.int64), np.zeros(nr, np.int64)
    batch = max(min(batch, 1024), batch // nr)  # moves at a time, of all robots (a row of each column per robot)
    out_r, out_k = np.empty(batch, np.int64), np.empty(batch, np.int64)
    heads = np.full((nr, batch), np.inf)
    cols = [np.empty((nr, batch, 3)), np.empty((nr, batch, 3)), np.empty((nr, batch)), np.empty((nr, batch)),
            np.empty((nr, batch), bool), np.empty((nr, batch), np.int64)] + [np.empty((nr, batch)) for _ in range(4)]
    for col0 in range(0, nx, ncol):
        cells[:, :, kernels.TOP] = -np.inf
        cells[:, :, kernels.WHO] = -1
        run.fill(0.0)
        highest = np.full(1, -np.inf)
        cursor = np.zeros(nr, np.int64)
        carry = [(0.0, 0.0, False)] * nr  # per robot: deposits so far, where its extrusion began, tool on
        while True:
            n = np.zeros(nr, np.int64)
            for j, (_, _, tl) in enumerate(active):
                part = tl.t0[cursor[j]:cursor[j] + batch]
                n[j] = len(part)
                heads[j, :len(part)] = part
            k = kernels.merge_by_time(heads, n, batch, out_r, out_k)
            if k == 0:
                break
            taken = np.bincount(out_r[:k], minlength=nr)
            for j, (_, r, tl) in enumerate(active):  # each robot's moves of the batch, a row each
                a = int(cursor[j])
                e = a + int(taken[j])
                if e == a:
                    continue
                cursor[j] = e
                part, carry[j] = _move_columns(r, tl, a, e, w, slicing.layer_height, int(offsets[j]), carry[j])
                for c, src in zip(cols, part):
                    c[j, :e - a] = src
            kernels.material_sweep(out_r[:k], out_k[:k], *cols, float(lo[0]), float(lo[1]), cell, col0, cells,
                                   DOUBLE_NEAR, DOUBLE_RUN, highest, run, run_cells, run_t, run_xyz, run_slot, count,
                                   when, where)
    findings = []
    details = (f"the nozzle tip goes into material laid down before (a bead within half a line width of its axis, "
               f"its top more than half a layer above the tip; count: cells of {cell:.3g} mm along the path)",
               f"material laid where material of the same layer already lies (a bead within {DOUBLE_NEAR:g} line "
               f"width of the axis, more than {DOUBLE_RUN:g} line widths of path in a row; count: cells of "
               f"{cell:.3g} mm)")
    for j, (_, r, _) in enumerate(active):
        own = slice(int(offsets[j]), int(offsets[j + 1]))  # the robot's chunk slots
        for check, kind in enumerate(("nozzle-in-material", "double-deposit")):
            findings += _slot_findings(kind, r, count[check, own], when[check, own], where[check, own], details[check])
    return sorted(findings, key=lambda f: (f.time, f.kind))


#: How far below the floor (z = 0) a nozzle may go before it is a finding, mm: the programs'
#: 1 µm grid.
FLOOR_TOLERANCE = 1e-3


def below_floor(robots: list[SimRobot], timelines: dict[str, Timeline]) -> list[Finding]:
    """Moves that take the nozzle below the floor (z < 0): it would print into the floor, or
    drive its printhead into it. One finding per robot and chunk: the first instant the nozzle
    passes z = 0 (where a move crosses it), and how many moves go below."""
    findings = []
    for r in robots:
        tl = timelines[r.name]
        z0, z1 = tl.p0[:, 2], tl.p1[:, 2]
        low = np.concatenate([np.flatnonzero(np.minimum(z0[c:c + BLOCK_MOVES], z1[c:c + BLOCK_MOVES]) < -FLOOR_TOLERANCE)
                              + c for c in range(0, len(z0), BLOCK_MOVES)] or [np.zeros(0, np.int64)])
        if not len(low):
            continue
        a, b = z0[low], z1[low]
        # the fraction of the move done when it crosses z = 0 (0 when it starts below)
        f = np.where(a < 0, 0.0, a / np.where(a - b > 0, a - b, 1.0))
        t = tl.t0[low] + f * (tl.t1[low] - tl.t0[low])
        xyz = tl.p0[low] + f[:, None] * (tl.p1[low] - tl.p0[low])
        findings += _group([(t, xyz, low)], "below-floor", r, tl,
                           "the nozzle goes below the floor (z < 0): it would print into the floor")
    return findings


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


#: ``outside-part``: how much further than half its line width a material point may lie outside
#: the section of its chunk, mm (the slicer simplifies each section by 0.0125 mm; the programs
#: round to 1 µm; the samples are float32).
OUTSIDE_SLACK = 0.02
#: Segments of chunk sections made at once (32 bytes each): bounds the check's memory.
SECTION_SEGMENTS = 1 << 19
#: Test heights are kept as integers in units of 1 / HEIGHT_KEY mm (0.1 µm).
HEIGHT_KEY = 1e4
#: A point outside its own chunk's section at its layer's middle is looked at again this many
#: key units (1 µm, the programs' grid) lower and higher: a horizontal face of the chunk that
#: lies exactly at a layer's middle belongs to the layer below or above depending on the last bit.
_NUDGE = 10


def _in_chunk(solid: ChunkMesh, xyz: np.ndarray, lo: np.ndarray, hi: np.ndarray, key: np.ndarray, tol: np.ndarray,
              ok: np.ndarray) -> None:
    """``ok[lo[r]:hi[r]]``: the points of run ``r`` lie inside ``solid``'s section at height
    ``key[r] / HEIGHT_KEY``, or within ``tol[r]`` of its outline. The sections are made a block of
    heights at a time (at most ``SECTION_SEGMENTS`` segments)."""
    if not len(lo):
        return
    keys, sec = np.unique(key, return_inverse=True)
    heights = keys / HEIGHT_KEY
    counts = kernels.section_counts(solid.vertices, solid.faces, heights)
    order = np.argsort(sec, kind="stable")
    sec_sorted = sec[order]
    a = 0
    while a < len(heights):
        e = a + max(1, int(np.searchsorted(np.cumsum(counts[a:]), SECTION_SEGMENTS, side="right")))
        offsets = np.concatenate([[0], np.cumsum(counts[a:e])]).astype(np.int64)
        segs = np.empty((int(offsets[-1]), 4))
        kernels.section_segments(solid.vertices, solid.faces, heights[a:e], offsets, segs)
        runs = order[np.searchsorted(sec_sorted, a):np.searchsorted(sec_sorted, e)]
        kernels.inside_sections(xyz, lo[runs], hi[runs], (sec[runs] - a).astype(np.int64), tol[runs], offsets,
                                segs, ok)
        a = e


def _in_chunk_points(solid: ChunkMesh, xyz: np.ndarray, key: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """(k,) bool: points ``xyz`` (each with its height key and tolerance) inside ``solid``'s
    section at their height, or at one ``_NUDGE`` below or above it."""
    order = np.argsort(key, kind="stable")
    pts, k = xyz[order], key[order]
    start = np.flatnonzero(np.r_[True, k[1:] != k[:-1]])
    lo, hi = start, np.r_[start[1:], len(k)]
    run_tol = np.maximum.reduceat(tol[order], start) if len(k) else np.zeros(0)
    ok = np.zeros(len(k), dtype=bool)
    for nudge in (0, -_NUDGE, _NUDGE):
        got = np.zeros(len(k), dtype=bool)
        _in_chunk(solid, pts, lo, hi, k[start] + nudge, run_tol, got)
        ok |= got
    out = np.empty(len(k), dtype=bool)
    out[order] = ok
    return out


def _runs(r: SimRobot, tl: Timeline, xyz: np.ndarray, t: np.ndarray, h: np.ndarray,
          width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One robot's material points (``xyz``, times ``t``, layer heights ``h``) in runs of one
    chunk and one test height: each run's first point, chunk (index into the program's
    ``chunks``, -1 between chunks), height key and half the widest line of its commands (of the
    commands from its first move to the next run's, ``width`` where the program gives none). A
    point lies on the first move to end at or after its time."""
    prog = r.program
    first = changes(prog.chunk, tl.index)  # the moves that begin a chunk's span
    cuts = np.searchsorted(t, tl.t1[first - 1], side="right")  # their first points
    start, key = kernels.height_runs(xyz[:, 2], h, cuts, 1024)
    move = np.searchsorted(tl.t1, t[start], side="left")
    run_chunk = prog.chunk[tl.index[move]].astype(np.int64)
    widest = segment_max(prog.width, tl.index[move]) if len(move) else np.zeros(0)
    return start, run_chunk, key, np.where(widest > 0, widest, width) / 2


def outside_part(robots: list[SimRobot], timelines: dict[str, Timeline], material: Material,
                 chunks: dict[str, ChunkMesh], owners: dict[str, tuple[str, ...]], width: float) -> list[Finding]:
    """``outside-part``: material outside the part (outside every chunk of ``chunks``, meshes by
    id) or outside every chunk of the robot that lays it (``owners``: each robot's chunk ids),
    with a tolerance of half the line width (``width`` where a program gives none) plus
    ``OUTSIDE_SLACK``: a bead's centre line may lie on the outline, not further out.

    Each material point is tested at its layer's middle (its height less half its layer's
    height), where the slicer cut the chunk: the tip of the top layer of a chunk lies on the
    chunk's top face, its middle inside. A point is first tested against the chunk its move is
    annotated with (when that is one of the robot's); the few that fail, against all the robot's
    chunks, then the other robots' (each a step of 1 µm lower and higher too). Two findings per
    robot and chunk, as the case may be: material inside another robot's chunk, and material
    outside the part, with the first instant and how many points."""
    findings = []
    holders: dict[str, list[str]] = {}
    for name, ids in owners.items():
        for cid in ids:
            holders.setdefault(cid, []).append(name)
    for i, r in enumerate(robots):
        block = material.robot(i)
        xyz, t, h = material.xyz[block], material.t[block], material.h[block]
        tl = timelines[r.name]
        if len(t) == 0:
            continue
        prog = r.program
        start, run_chunk, key, half = _runs(r, tl, xyz, t, h, width)
        hi = np.r_[start[1:], len(t)]
        tol = half + OUTSIDE_SLACK
        own = [c for c in owners.get(r.name, ()) if c in chunks]
        ok = np.zeros(len(t), dtype=bool)
        for c, cid in enumerate(prog.chunks):  # the points of each of its own chunks, against that chunk
            if cid in own:
                sel = np.flatnonzero(run_chunk == c)
                _in_chunk(chunks[cid], xyz, start[sel], hi[sel], key[sel], tol[sel], ok)
        bad = np.flatnonzero(~ok)
        if not len(bad):
            continue
        run = np.searchsorted(start, bad, side="right") - 1
        bad_xyz, bad_key, bad_tol = xyz[bad], key[run], tol[run]
        found = np.full(len(bad), -1, np.int64)  # -1: outside the part; else the chunk (by order) that holds it
        ids = list(chunks)
        for c in own + [c for c in ids if c not in own]:  # its own chunks first
            todo = np.flatnonzero(found < 0)
            if not len(todo):
                break
            inside = _in_chunk_points(chunks[c], bad_xyz[todo], bad_key[todo], bad_tol[todo])
            found[todo[inside]] = ids.index(c)
        at = bad + block.start  # indices into the material
        mine = ", ".join(own) if own else "none"
        where = found < 0
        findings += _group([(material.t[at[where]], material.xyz[at[where]], material.moves(at[where], tl))],
                           "outside-part", r, tl,
                           "material outside the part: outside every chunk by more than half a line width")
        for k in sorted(set(found[found >= 0].tolist())):
            cid = ids[k]
            if cid in own:
                continue
            sel = found == k
            by = ", ".join(holders.get(cid, [])) or "no robot"
            findings += _group([(material.t[at[sel]], material.xyz[at[sel]], material.moves(at[sel], tl))],
                               "outside-part", r, tl,
                               f"material of robot {r.name} in another robot's chunk: inside chunk {cid} (printed "
                               f"by {by}), outside every chunk of {r.name} ({mine})")
    return sorted(findings, key=lambda f: (f.time, f.detail))


__all__ = ["FLOOR_TOLERANCE", "ORDER_TOLERANCE", "OUTLINE_TOLERANCE", "OUTSIDE_SLACK", "PARTS", "Material", "below_floor",
           "body_box", "body_corners", "chunk_order", "footprint_checks", "head_box", "outline_boxes", "outline_corners",
           "material_checks", "outline_tables", "outside_part", "overhangs", "path_samples", "robots_collide"]
