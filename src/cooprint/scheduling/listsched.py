"""List scheduling over a :class:`~cooprint.scheduling.dag.ChunkDAG` (issue 14, strategy ``list``).

A *serial schedule generation scheme*: chunks are placed one at a time, each at the earliest time
any robot can print it, never moving a chunk already placed. The order in which chunks are taken
is the *priority rule*; the first rule is the critical-path priority (:meth:`ChunkDAG.tails`:
work plus the longest chain of work after the chunk), the classic rule that keeps the longest
chain moving. A chunk is *ready* when every chunk in :meth:`ChunkDAG.preds` is placed. For each
robot the earliest start is

    max(end of its preds, the robot's free time + travel from its last chunk),

then pushed past every placed chunk it is exclusive with (:meth:`ChunkDAG.exclusive_with`) whose
interval it would overlap (the earliest gap that fits). The chunk goes to the robot that
finishes it first (ties: the shorter drive, then the robot order). A robot that has printed
nothing yet starts where the chunk begins (:meth:`ChunkDAG.travel` from nowhere is 0), so all
such robots are the same and only the first is tried.

Several priority rules are run (critical path, with travel and exclusion tie-breaks, and the
positional weight: work plus all the work after the chunk), each improved by forward-backward
passes (*justification*): the schedule is rebuilt backwards in time (the DAG reversed, chunks
taken latest end first) and forwards again (earliest start first), which closes idle gaps a
greedy forward pass leaves, while the makespan improves. Last, a bounded number of randomised
priority lists (seeded, so a job always gets the same schedule; fewer for bigger jobs,
:func:`samples`) each get one such round. Measured on grid-like DAGs (tests/test_scheduling.py
``grid_dag``): 3 x 8 chunks for 4 robots, the plain critical-path schedule is 29% above LB, this
one 4.7% (the optimum 1.5%) in 0.1 s; 10 x 20 for 16 robots 76% -> 20% in 0.4 s; 20 x 50 for 64
robots 17% -> 4.8% in 1.8 s.

:func:`timed` gives times to fixed per-robot sequences (the seed's two-robot order):
:func:`seed_schedule`.
"""

from __future__ import annotations

import heapq
import random
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Callable, Mapping, Sequence

import numpy as np

from cooprint.scheduling.dag import ChunkDAG
from cooprint.scheduling.schedule import Schedule

if TYPE_CHECKING:
    from cooprint.chunking import ChunkSet
    from cooprint.config.settings import SchedulingSettings

#: At most this many forward-backward rounds after the priority rules.
FB_ROUNDS = 4
#: Randomised list schedules tried: about this many (chunk, robot) evaluations in all ...
SAMPLE_WORK = 100_000
#: ... and at most this many.
MAX_SAMPLES = 300


@dataclass(frozen=True, eq=False)
class Problem:
    """A :class:`ChunkDAG` as index arrays, the form the schedulers compute on.

    ``travel[i, j]`` is the drive from the end of chunk i to the start of chunk j, s (exactly
    :meth:`ChunkDAG.travel`); ``preds``/``succ`` are index tuples, ``excl`` the exclusive
    partners of each chunk. :meth:`reversed` swaps time's direction (preds and successors, and
    the travel matrix transposed), so a forward scheduler run on it builds a schedule backwards.
    """

    work: tuple[float, ...]
    preds: tuple[tuple[int, ...], ...]
    succ: tuple[tuple[int, ...], ...]
    excl: tuple[tuple[int, ...], ...]
    travel: np.ndarray

    def __post_init__(self) -> None:
        # Python lists for the schedulers' inner loops (numpy scalar indexing is ~10x slower).
        object.__setattr__(self, "rows", self.travel.tolist())

    @property
    def n(self) -> int:
        return len(self.work)

    @classmethod
    def of(cls, dag: ChunkDAG) -> "Problem":
        idx = dag.index
        n = len(dag.ids)
        preds = tuple(tuple(idx[p] for p in dag.preds(c)) for c in dag.ids)
        succ: list[list[int]] = [[] for _ in range(n)]
        for i, ps in enumerate(preds):
            for p in ps:
                succ[p].append(i)
        excl_sets = dag.exclusive_with()
        excl = tuple(tuple(sorted(idx[x] for x in excl_sets[c])) for c in dag.ids)
        travel = dag.travel_matrix() if n else np.zeros((0, 0))
        return cls(tuple(float(w) for w in dag.work), preds, tuple(tuple(s) for s in succ), excl, travel)

    @cached_property
    def reversed(self) -> "Problem":
        """The same chunks with time running backwards (computed once)."""
        return Problem(self.work, self.succ, self.preds, self.excl, self.travel.T)

    def topological(self) -> list[int]:
        indeg = [len(p) for p in self.preds]
        ready = [i for i in range(self.n) if indeg[i] == 0]
        heapq.heapify(ready)
        order = []
        while ready:
            i = heapq.heappop(ready)
            order.append(i)
            for s in self.succ[i]:
                indeg[s] -= 1
                if indeg[s] == 0:
                    heapq.heappush(ready, s)
        if len(order) != self.n:
            raise ValueError("the chunk constraints form a cycle")
        return order

    def tails(self, with_travel: bool = False) -> list[float]:
        """Work plus the longest chain of work after each chunk (:meth:`ChunkDAG.tails`);
        ``with_travel`` adds to each link the drive to that successor (what the chain costs when
        one robot prints it: a tie-break, not a bound)."""
        tail = [0.0] * self.n
        for i in reversed(self.topological()):
            tail[i] = self.work[i] + max(
                (tail[s] + (float(self.travel[i, s]) if with_travel else 0.0) for s in self.succ[i]), default=0.0)
        return tail

    @cached_property
    def after(self) -> list[int]:
        """Bit j of ``after[i]`` is set when chunk j comes after chunk i through the preds
        (transitively)."""
        below = [0] * self.n
        for i in reversed(self.topological()):
            for s in self.succ[i]:
                below[i] |= below[s] | (1 << s)
        return below

    def weights(self) -> list[float]:
        """Positional weight: work plus the work of every chunk after it (:attr:`after`): the
        rule that favours chunks that open the most work."""
        return [self.work[i] + sum(self.work[j] for j in _bits(self.after[i])) for i in range(self.n)]


def _bits(mask: int) -> list[int]:
    out = []
    while mask:
        low = mask & -mask
        out.append(low.bit_length() - 1)
        mask ^= low
    return out


@dataclass
class Timing:
    """A schedule over a :class:`Problem`: robot sequences (chunk indices in order) and times."""

    seqs: list[list[int]]
    start: list[float]
    end: list[float]

    @property
    def makespan(self) -> float:
        return max(self.end, default=0.0)


def _fit(t: float, w: float, busy: list[tuple[float, float]]) -> float:
    """The earliest start >= ``t`` of an interval of length ``w`` that overlaps none of ``busy``
    (intervals sorted by start). Every start in ``[t, e)`` of a clashing interval ``(s, e)``
    clashes too, so jumping to ``e`` skips no feasible start."""
    for s, e in busy:
        if e <= t:
            continue
        if s >= t + w:
            break
        t = e
    return t


def _busy(i: int, p: Problem, placed: list[bool], start: list[float], end: list[float]) -> list[tuple[float, float]]:
    return sorted((start[j], end[j]) for j in p.excl[i] if placed[j])


def serial(p: Problem, robots: int, key: Sequence[float]) -> Timing:
    """Serial list scheduling: take the ready chunk with the smallest ``key`` (ties: the lower
    index), place it at its earliest finish over all robots (module docstring)."""
    n = p.n
    start = [0.0] * n
    end = [0.0] * n
    placed = [False] * n
    missing = [len(ps) for ps in p.preds]
    ready = [(key[i], i) for i in range(n) if missing[i] == 0]
    heapq.heapify(ready)
    free = [0.0] * robots
    last = [-1] * robots
    seqs: list[list[int]] = [[] for _ in range(robots)]
    travel = p.rows  # type: ignore[attr-defined]
    while ready:
        _, i = heapq.heappop(ready)
        w = p.work[i]
        after = max((end[q] for q in p.preds[i]), default=0.0)
        busy = _busy(i, p, placed, start, end)
        best: tuple[float, float, int] | None = None
        best_t = 0.0
        fresh_seen = False
        for r in range(robots):
            if last[r] < 0:
                if fresh_seen:
                    continue
                fresh_seen = True
                drive, t0 = 0.0, after
            else:
                drive = travel[last[r]][i]
                t0 = max(after, free[r] + drive)
            t = _fit(t0, w, busy) if busy else t0
            cand = (t + w, drive, r)
            if best is None or cand < best:
                best, best_t = cand, t
        assert best is not None
        r = best[2]
        start[i], end[i] = best_t, best_t + w
        placed[i] = True
        free[r], last[r] = end[i], i
        seqs[r].append(i)
        for s in p.succ[i]:
            missing[s] -= 1
            if missing[s] == 0:
                heapq.heappush(ready, (key[s], s))
    if not all(placed):
        raise ValueError("the chunk constraints form a cycle")
    return Timing(seqs, start, end)


def place_fixed(p: Problem, seqs: Sequence[Sequence[int]], order: Sequence[int] | None = None) -> Timing:
    """Times for fixed robot sequences: each chunk at its earliest start after its preds, its
    robot's previous chunk plus the drive, and clear of the placed chunks it is exclusive with.

    ``order`` fixes the order chunks are placed in (a chunk after its preds and its robot's
    previous chunk); without it, the next placed is, among the robots' next chunks whose preds
    are placed, the one that can start first (ties: robot order). Placing a solution's chunks by
    their start times never starts one later than that solution did, so re-timing a schedule
    this way only tightens it."""
    n = p.n
    robot_of = [-1] * n
    pos = [0] * n
    for r, seq in enumerate(seqs):
        for k, i in enumerate(seq):
            if robot_of[i] >= 0:
                raise ValueError(f"chunk index {i} is in two sequences")
            robot_of[i], pos[i] = r, k
    if min(robot_of, default=0) < 0:
        raise ValueError(f"chunk index {robot_of.index(-1)} is in no sequence")
    start = [0.0] * n
    end = [0.0] * n
    placed = [False] * n
    head = [0] * len(seqs)

    def earliest(i: int) -> float | None:
        r = robot_of[i]
        if head[r] != pos[i] or not all(placed[q] for q in p.preds[i]):
            return None
        t = max((end[q] for q in p.preds[i]), default=0.0)
        if pos[i] > 0:
            prev = seqs[r][pos[i] - 1]
            t = max(t, end[prev] + p.rows[prev][i])  # type: ignore[attr-defined]
        busy = _busy(i, p, placed, start, end)
        return _fit(t, p.work[i], busy) if busy else t

    def put(i: int, t: float) -> None:
        start[i], end[i] = t, t + p.work[i]
        placed[i] = True
        head[robot_of[i]] += 1

    if order is not None:
        for i in order:
            t = earliest(i)
            if t is None:
                raise ValueError(f"chunk index {i} placed before its preds or its robot's previous chunk")
            put(i, t)
    else:
        for _ in range(n):
            best: tuple[float, int] | None = None
            for r, seq in enumerate(seqs):
                if head[r] < len(seq):
                    t = earliest(seq[head[r]])
                    if t is not None and (best is None or t < best[0]):
                        best = (t, seq[head[r]])
            if best is None:
                raise ValueError("the sequences wait on each other (a robot's chunk needs a later chunk of another)")
            put(best[1], best[0])
    return Timing([list(s) for s in seqs], start, end)


def _backward(p: Problem, robots: int, fwd: Timing) -> Timing:
    """Rebuild ``fwd`` backwards (latest end first on the reversed problem), then time it
    forwards again in the order of the mirrored starts."""
    rev = serial(p.reversed, robots, [-e for e in fwd.end])
    m = rev.makespan
    mirrored_start = [m - e for e in rev.end]
    seqs = [list(reversed(s)) for s in rev.seqs]
    order = sorted(range(p.n), key=lambda i: (mirrored_start[i], i))
    return place_fixed(p, seqs, order)


def _improve(p: Problem, robots: int, t: Timing, rounds: int) -> Timing:
    """Forward-backward rounds on ``t`` while they shorten it."""
    for _ in range(rounds):
        back = _backward(p, robots, t)
        fwd = serial(p, robots, back.start)
        cand = min((back, fwd), key=lambda x: x.makespan)
        if cand.makespan >= t.makespan - 1e-9:
            break
        t = cand
    return t


def best_timing(p: Problem, robots: int) -> Timing:
    """The shortest of: the priority rules' schedules improved by forward-backward rounds, then
    :func:`samples` randomised ones (seeded: the same job gets the same schedule), half with the
    critical-path priorities each scaled by a random factor in [0.75, 1] (biased sampling), half
    with the best schedule's starts jittered by up to 5% of its makespan (a search around it),
    each improved by one forward-backward round."""
    n = p.n
    topo = {i: k for k, i in enumerate(p.topological())}
    tails = p.tails()
    tails_t = p.tails(with_travel=True)
    weights = p.weights()
    eps = 1e-9 * max(max(tails, default=1.0), 1.0)
    # Tuples compare lexicographically: the tie-breaks of equal tails.
    rules: list[list[tuple[float, ...]]] = [
        [(-tails[i], topo[i]) for i in range(n)],
        [(-round(tails[i] / eps) * eps, -tails_t[i], topo[i]) for i in range(n)],
        [(-tails_t[i], topo[i]) for i in range(n)],
        [(-round(tails[i] / eps) * eps, -len(p.excl[i]), -len(p.succ[i]), topo[i]) for i in range(n)],
        [(-weights[i], topo[i]) for i in range(n)],
    ]
    best: Timing | None = None
    for key in rules:
        t = _improve(p, robots, serial(p, robots, key), FB_ROUNDS)  # type: ignore[arg-type]
        if best is None or _better(p, t, best):
            best = t
    assert best is not None
    rng = random.Random(0)
    for k in range(samples(n, robots)):
        if k % 3 == 0:
            key = [-tails[i] * rng.uniform(0.75, 1.0) for i in range(n)]
        elif k % 3 == 1:
            key = [-weights[i] * rng.uniform(0.75, 1.0) for i in range(n)]
        else:
            jitter = 0.05 * best.makespan
            key = [best.start[i] + rng.uniform(0.0, jitter) for i in range(n)]
        t = _improve(p, robots, serial(p, robots, key), 1)
        if _better(p, t, best):
            best = t
    return best


def _better(p: Problem, t: Timing, best: Timing) -> bool:
    """Whether ``t`` beats ``best``: a shorter makespan, or one as short (within 1e-6 of it) with
    less driving between chunks. Many schedules reach the same makespan (the lower bound, often);
    of those the one whose robots drive least keeps each robot near its work, where the programs
    have the fewest ways crossing (a robot sent from one end of the part to the other waits for
    the robots it passes, which the makespan estimate cannot see)."""
    tol = 1e-6 * max(best.makespan, 1.0)
    if t.makespan < best.makespan - tol:
        return True
    return t.makespan <= best.makespan + tol and _driving(p, t) < _driving(p, best) - 1e-9


def _driving(p: Problem, t: Timing) -> float:
    """Total travel time between consecutive chunks of every robot, s."""
    return float(sum(p.travel[a, b] for seq in t.seqs for a, b in zip(seq, seq[1:])))


def samples(n: int, robots: int) -> int:
    """How many randomised schedules :func:`best_timing` tries: about :data:`SAMPLE_WORK` robot
    evaluations in all (a pass costs chunks x busy robots), at most :data:`MAX_SAMPLES`."""
    return min(MAX_SAMPLES, SAMPLE_WORK // max(1, n * min(robots, n)))


def to_schedule(dag: ChunkDAG, robots: Sequence[str], timing: Timing, strategy: str, note: str = "",
                bound: float | None = None) -> Schedule:
    """The :class:`Schedule` record of a :class:`Timing` (every robot a key, idle ones empty)."""
    ids = dag.ids
    seqs = {r: tuple(ids[i] for i in (timing.seqs[k] if k < len(timing.seqs) else ()))
            for k, r in enumerate(robots)}
    start = {ids[i]: float(timing.start[i]) for i in range(len(ids))}
    end = {ids[i]: float(timing.end[i]) for i in range(len(ids))}
    return Schedule(seqs, strategy, start=start, end=end, makespan=max(end.values(), default=0.0),
                    lower_bound=dag.lower_bound(len(robots)), bound=bound, note=note)


def list_schedule(dag: ChunkDAG, robots: Sequence[str], settings: "SchedulingSettings | None" = None) -> Schedule:
    """Critical-path list schedule of ``dag`` for ``robots`` (strategy ``list``; module
    docstring). ``settings`` is accepted for the common scheduler signature (list scheduling
    has no setting)."""
    p = Problem.of(dag)
    return to_schedule(dag, robots, best_timing(p, len(robots)), "list")


def timed(dag: ChunkDAG, sequences: Mapping[str, Sequence[str]], strategy: str) -> Schedule:
    """Times for fixed per-robot sequences (:func:`place_fixed` without an order): each chunk
    at its earliest start after its preds, its robot's previous chunk plus the drive, and clear
    of the exclusive chunks placed before it. Raises ``ValueError`` when the sequences miss or
    repeat a chunk or wait on each other."""
    p = Problem.of(dag)
    idx = dag.index
    robots = list(sequences)
    given = [c for r in robots for c in sequences[r]]
    if sorted(given) != sorted(dag.ids):
        raise ValueError(f"{strategy}: the sequences hold {sorted(given)}, the DAG's chunks are {sorted(dag.ids)}")
    seqs = [[idx[c] for c in sequences[r]] for r in robots]
    return to_schedule(dag, robots, place_fixed(p, seqs), strategy)


def seed_schedule(dag: ChunkDAG, robots: Sequence[str], chunks: "ChunkSet") -> Schedule:
    """The seed's two-robot order (:func:`~cooprint.scheduling.assign.seed_two_robots`: A the
    centre then the left chunks outwards, B the right chunks outwards), timed (strategy
    ``seed``)."""
    from cooprint.scheduling.assign import seed_two_robots

    return timed(dag, seed_two_robots(chunks, robots).sequences, "seed")


Scheduler = Callable[[ChunkDAG, Sequence[str], "SchedulingSettings | None"], Schedule]
