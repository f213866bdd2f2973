"""The scheduler's output for N robots (issue 14): who prints which chunk, when, and how far
that is from the best possible."""

from __future__ import annotations

from dataclasses import dataclass, field

from cooprint.scheduling.assign import Assignment
from cooprint.scheduling.dag import ChunkDAG

#: Slack for comparing schedule times, s (times are sums of floats).
TIME_EPS = 1e-6


@dataclass(frozen=True)
class Schedule(Assignment):
    """An :class:`Assignment` with times.

    Attributes
    ----------
    start, end : dict
        ``{chunk id: s}``: when its robot starts and finishes printing it (nominal speeds; the
        robot drives there before ``start``).
    makespan : float
        When the last chunk is finished, s.
    lower_bound : float
        LB = max(critical path, total work / robots) (:meth:`ChunkDAG.lower_bound`).
    bound : float or None
        A proven lower bound on the optimal makespan from an exact solver (``>= lower_bound``),
        ``None`` when none was proven.
    note : str
        What the scheduler wants said (a fallback, a time limit reached), or ``""``.
    """

    start: dict[str, float] = field(default_factory=dict)
    end: dict[str, float] = field(default_factory=dict)
    makespan: float = 0.0
    lower_bound: float = 0.0
    bound: float | None = None
    note: str = ""

    @property
    def gap(self) -> float:
        """Makespan over the lower bound LB, less one (0.05: 5% above it)."""
        return self.makespan / self.lower_bound - 1.0 if self.lower_bound > 0 else 0.0

    @property
    def bound_gap(self) -> float | None:
        """Makespan over the exact solver's proven bound, less one (0: proven optimal); ``None``
        without a proven bound."""
        return self.makespan / self.bound - 1.0 if self.bound else None

    @property
    def idle_robots(self) -> tuple[str, ...]:
        """Robots with no chunk (more robots than the part has work for)."""
        return tuple(r for r, seq in self.sequences.items() if not seq)

    def to_dict(self) -> dict[str, object]:
        """job.json's ``schedule`` numbers (each chunk's times go in its own row, ``start_s`` and
        ``end_s``)."""
        return {"strategy": self.strategy, "sequences": {r: list(s) for r, s in self.sequences.items()},
                "makespan_s": self.makespan, "lower_bound_s": self.lower_bound, "gap": self.gap,
                "bound_s": self.bound, "bound_gap": self.bound_gap, "note": self.note,
                "idle_robots": list(self.idle_robots)}


def check_schedule(dag: ChunkDAG, sched: Schedule) -> None:
    """Raise ``AssertionError`` naming the first broken rule: every chunk placed once for its
    work, every precedence (a) and body rule (b) respected, no exclusive pair (c) overlapping in
    time, no robot doing two things at once (with travel between them), makespan >= LB."""
    placed = sorted(c for seq in sched.sequences.values() for c in seq)
    if placed != sorted(dag.ids):
        raise AssertionError(f"{sched.strategy}: placed {placed}, chunks are {sorted(dag.ids)}")
    idx = dag.index
    for c in dag.ids:
        if sched.end[c] - sched.start[c] < dag.work[idx[c]] - TIME_EPS:
            raise AssertionError(f"{sched.strategy}: {c} lasts {sched.end[c] - sched.start[c]:.3f} s "
                                 f"< its work {dag.work[idx[c]]:.3f} s")
        for p in dag.preds(c):
            if sched.start[c] < sched.end[p] - TIME_EPS:
                raise AssertionError(f"{sched.strategy}: {c} starts at {sched.start[c]:.3f} s before {p} ends "
                                     f"at {sched.end[p]:.3f} s")
    for a, b in dag.exclusive:
        if sched.start[a] < sched.end[b] - TIME_EPS and sched.start[b] < sched.end[a] - TIME_EPS:
            raise AssertionError(f"{sched.strategy}: exclusive {a} and {b} overlap in time")
    for r, seq in sched.sequences.items():
        prev = None
        for c in seq:
            if prev is not None and sched.start[c] < sched.end[prev] + dag.travel(prev, c) - TIME_EPS:
                raise AssertionError(f"{sched.strategy}: robot {r} starts {c} before it can get there from {prev}")
            prev = c
    last = max(sched.end.values(), default=0.0)
    if abs(last - sched.makespan) > TIME_EPS * max(1.0, last):
        raise AssertionError(f"{sched.strategy}: makespan {sched.makespan} but the last chunk ends at {last}")
    if sched.makespan < dag.lower_bound(len(sched.sequences)) - TIME_EPS:
        raise AssertionError(f"{sched.strategy}: makespan {sched.makespan:.3f} s below the lower bound "
                             f"{dag.lower_bound(len(sched.sequences)):.3f} s")
