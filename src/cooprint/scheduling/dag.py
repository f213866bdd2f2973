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
        mm/s, for :meth:`travel`.
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
    travel_speed: float = 120.0

    def __post_init__(self) -> None:
        n = len(self.ids)
        for name in ("work", "facing", "start", "end", "footprint"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"ChunkDAG.{name} has {len(getattr(self, name))} rows for {n} chunks")

    @property
    def index(self) -> dict[str, int]:
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
        """Seconds to drive from the end of chunk ``a`` to the start of chunk ``b`` (straight,
        at ``travel_speed``); 0 from nowhere (``a`` None: a robot starts where its first chunk
        begins)."""
        if a is None:
            return 0.0
        i, j = self.index[a], self.index[b]
        return float(np.linalg.norm(self.end[i, :2] - self.start[j, :2])) / self.travel_speed

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
