"""The one record every scheduler reads (issue 14): the chunks as a dependency DAG with the
work each asks for, where its robot stands, and which chunks may not be printed at once.

A layout (:mod:`cooprint.chunking`) makes a :class:`~cooprint.chunking.ChunkSet`; a
:class:`ChunkDAG` adds what scheduling needs (:func:`cooprint.scheduling.graph.build_dag`):

(a) **precedence** ``deps``: a chunk after every chunk whose face it leans on (the layout's);
(b) **body** ``body_deps``: a chunk after every chunk whose robot's body sweeps over its
    footprint while printing (that robot must never stand on material);
(c) **exclusion** ``exclusive``: two chunks whose robots' outlines (body, frame, printhead, in
    their facings, swept over the chunks) come within ``clearance`` of each other are never
    printed at the same time (in either order).

Times are seconds at the robot's nominal speeds: ``work[i]`` is chunk i's print time, and moving
from the end of chunk i to the start of chunk j costs :meth:`ChunkDAG.travel` (setup time).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
import numpy as np


@dataclass(frozen=True)
class ChunkDAG:
    """Chunks, their work, their order constraints and their exclusions.

    Attributes
    ----------
    ids : tuple of str
        Chunk ids; index ``i`` in every array below is ``ids[i]``.
    work : (n,) float64
        Estimated print time of each chunk, s (> 0).
    facing : (n, 2) float64
        Unit XY direction its robot faces while printing it (body to nozzle).
    start, end : (n, 3) float64
        Where the nozzle starts and ends printing it, mm (for travel times).
    footprint : (n, 4) float64
        XY box of the chunk's material ``xmin, ymin, xmax, ymax``, mm.
    deps : dict
        (a) ``{chunk id: chunk ids whose faces it leans on}``.
    body_deps : dict
        (b) ``{chunk id: chunk ids whose robot's body sweeps over it}`` (they come first).
    exclusive : tuple of (str, str)
        (c) Pairs never printed at the same time, each pair once, in ``ids`` order.
    travel_speed : float
        mm/s, for :meth:`travel`: the robot's travel speed (``slicing.travel_speed`` under its
        ``max_travel_speed``, :meth:`~cooprint.program.gcode.Feeds.of_robot`); by default the
        slicer's default.
    detour : float
        How far outside the part's footprint a robot that changes sides drives round it (its
        whole outline clear of the part and of the robots over it), mm: for :meth:`travel`.
    """

    ids: tuple[str, ...]
    work: np.ndarray
    facing: np.ndarray
    start: np.ndarray
    end: np.ndarray
    footprint: np.ndarray
    deps: dict[str, tuple[str, ...]]
    body_deps: dict[str, tuple[str, ...]] = field(default_factory=dict)
    exclusive: tuple[tuple[str, str], ...] = ()
    travel_speed: float = 130.0
    detour: float = 0.0

    def __post_init__(self) -> None:
        n = len(self.ids)
        for name in ("work", "facing", "start", "end", "footprint"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"ChunkDAG.{name} has {len(getattr(self, name))} rows for {n} chunks")

    @cached_property
    def index(self) -> dict[str, int]:
        """``{chunk id: its row in the arrays}`` (made once)."""
        return {c: i for i, c in enumerate(self.ids)}

    def preds(self, cid: str) -> tuple[str, ...]:
        """Every chunk that must be finished before ``cid`` starts: (a) and (b), each once."""
        return tuple(dict.fromkeys(self.deps.get(cid, ()) + self.body_deps.get(cid, ())))

    def exclusive_with(self) -> dict[str, set[str]]:
        """``{chunk id: the chunks it may not be printed at the same time as}``."""
        out: dict[str, set[str]] = {c: set() for c in self.ids}
        for a, b in self.exclusive:
            out[a].add(b)
            out[b].add(a)
        return out

    def travel(self, a: str | None, b: str) -> float:
        """Seconds to drive from the end of chunk ``a`` to the start of chunk ``b``
        (:meth:`travel_matrix`); 0 from nowhere (``a`` None: a robot starts where its first
        chunk begins)."""
        if a is None:
            return 0.0
        i, j = self.index[a], self.index[b]
        return float(self.travel_matrix(np.array([i]), np.array([j]))[0, 0])

    def travel_matrix(self, rows: np.ndarray | None = None, cols: np.ndarray | None = None) -> np.ndarray:
        """``[i, j]``: seconds from the end of chunk ``rows[i]`` to the start of chunk ``cols[j]``
        (all chunks by default) at ``travel_speed``. In one facing the robot drives straight;
        between two facings more than 60 degrees apart it changes sides: out of the part along
        its old facing's back to a ring ``detour`` outside the part's footprint box, round the
        box the shorter way, and in along the new facing (the program's way round, where it
        turns clear of everything)."""
        rows = np.arange(len(self.ids)) if rows is None else rows
        cols = np.arange(len(self.ids)) if cols is None else cols
        a, b = self.end[rows, :2], self.start[cols, :2]
        straight = np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)
        fr, fc = self.facing[rows], self.facing[cols]
        known = (np.linalg.norm(fr, axis=1) > 0.5)[:, None] & (np.linalg.norm(fc, axis=1) > 0.5)[None, :]
        turns = known & ((fr @ fc.T) < 0.5)  # (a facing left unknown, zero: straight)
        if not turns.any():
            return straight / self.travel_speed
        lo = self.footprint[:, :2].min(axis=0) - self.detour
        hi = self.footprint[:, 2:].max(axis=0) + self.detour
        out_a, ring_a = _to_ring(a, -self.facing[rows], lo, hi)
        out_b, ring_b = _to_ring(b, -self.facing[cols], lo, hi)
        perimeter = 2 * float((hi - lo).sum())
        along = np.abs(ring_a[:, None] - ring_b[None, :])
        around = out_a[:, None] + np.minimum(along, perimeter - along) + out_b[None, :]
        return np.where(turns, np.maximum(around, straight), straight) / self.travel_speed
    def topological_order(self) -> list[str]:
        """The ids in an order where every chunk follows its :meth:`preds`.

        Raises ``ValueError`` naming a chunk on a cycle (a layout whose constraints contradict)."""
        indeg = {c: len(self.preds(c)) for c in self.ids}
        succ: dict[str, list[str]] = {c: [] for c in self.ids}
        for c in self.ids:
            for p in self.preds(c):
                succ[p].append(c)
        ready = [c for c in self.ids if indeg[c] == 0]
        order = []
        while ready:
            c = ready.pop(0)
            order.append(c)
            for s in succ[c]:
                indeg[s] -= 1
                if indeg[s] == 0:
                    ready.append(s)
        if len(order) != len(self.ids):
            stuck = next(c for c in self.ids if indeg[c] > 0)
            raise ValueError(f"the chunk constraints form a cycle through {stuck}")
        return order

    def critical_path(self) -> tuple[float, tuple[str, ...]]:
        """The longest chain of :meth:`preds` by work (s) and its chunks, first to last: no
        schedule can finish sooner, however many robots."""
        w = dict(zip(self.ids, self.work.tolist()))
        best: dict[str, float] = {}
        prev: dict[str, str | None] = {}
        for c in self.topological_order():
            ps = self.preds(c)
            p = max(ps, key=lambda x: best[x]) if ps else None
            best[c] = w[c] + (best[p] if p else 0.0)
            prev[c] = p
        if not best:
            return 0.0, ()
        last: str | None = max(best, key=lambda c: best[c])
        length = best[last]  # type: ignore[index]
        chain = []
        while last is not None:
            chain.append(last)
            last = prev[last]
        return float(length), tuple(reversed(chain))

    def lower_bound(self, robots: int) -> float:
        """LB = max(critical path, total work / robots), s: no schedule of ``robots`` robots
        finishes sooner (travel only adds)."""
        return max(self.critical_path()[0], float(self.work.sum()) / max(robots, 1))

    def tails(self) -> dict[str, float]:
        """Each chunk's work plus the longest chain of work after it (s): the list scheduler's
        critical-path priority."""
        w = dict(zip(self.ids, self.work.tolist()))
        succ: dict[str, list[str]] = {c: [] for c in self.ids}
        for c in self.ids:
            for p in self.preds(c):
                succ[p].append(c)
        tail: dict[str, float] = {}
        for c in reversed(self.topological_order()):
            tail[c] = w[c] + max((tail[s] for s in succ[c]), default=0.0)
        return tail

    def to_dict(self) -> dict[str, object]:
        """For job.json: the constraints by chunk id (the work in s)."""
        return {"work_s": dict(zip(self.ids, self.work.round(3).tolist())),
                "deps": {c: list(self.deps.get(c, ())) for c in self.ids},
                "body_deps": {c: list(self.body_deps.get(c, ())) for c in self.ids},
                "exclusive": [list(p) for p in self.exclusive]}


def _to_ring(p: np.ndarray, back: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For points ``p`` (k, 2) inside the box ``[lo, hi]`` driving along unit ``back`` (k, 2): the
    distance to the box's edge and where they meet it, as a length along its perimeter (from
    ``lo``, counter-clockwise)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(back[:, 0] > 1e-9, (hi[0] - p[:, 0]) / back[:, 0],
                      np.where(back[:, 0] < -1e-9, (lo[0] - p[:, 0]) / back[:, 0], np.inf))
        ty = np.where(back[:, 1] > 1e-9, (hi[1] - p[:, 1]) / back[:, 1],
                      np.where(back[:, 1] < -1e-9, (lo[1] - p[:, 1]) / back[:, 1], np.inf))
    t = np.maximum(np.minimum(tx, ty), 0.0)
    q = np.clip(p + t[:, None] * back, lo, hi)
    w, h = hi - lo
    x, y = q[:, 0] - lo[0], q[:, 1] - lo[1]
    eps = 1e-6 * max(w, h, 1.0)
    s = np.where(y <= eps, x, np.where(x >= w - eps, w + y, np.where(y >= h - eps, w + h + (w - x), 2 * w + h + (h - y))))
    return t, s
