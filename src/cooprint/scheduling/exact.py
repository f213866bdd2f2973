"""Makespan-optimal schedules with OR-Tools CP-SAT (issue 14, strategy ``exact``).

The model, in integer time units (``unit`` seconds; the list schedule's makespan is about
:data:`UNITS` units, fine enough that rounding costs a few 1e-5 of the makespan):

* one interval per chunk (start, work, end) and, per robot, an optional copy of it whose
  presence literal says "this robot prints it"; exactly one presence per chunk;
* per robot a circuit (``AddCircuit``) through a depot node and the chunks it prints: the arc
  i -> j means j is the robot's next chunk after i, and forces ``start_j >= end_i + travel_ij``
  (travel as a sequence-dependent setup time); a robot's first chunk costs no drive (a robot
  starts where its first chunk begins, :meth:`ChunkDAG.travel`); a robot's optional intervals
  are also in one ``NoOverlap`` (redundant, it propagates better);
* precedence ``start_y >= end_x`` for every x in :meth:`ChunkDAG.preds` of y;
* every exclusive pair in one ``NoOverlap`` of their two chunk intervals;
* the robots are alike, so they are ordered by the index of their first chunk (idle robots
  last): every schedule has a relabelling of the robots that satisfies this;
* minimise the makespan, starting from the list schedule as a hint.

Work and travel are rounded *up* to whole units, so every solution of the model is feasible in
seconds; the solution's robot sequences are then re-timed in seconds in the order of the
solver's starts (:func:`~cooprint.scheduling.listsched.place_fixed`), which never makes a
chunk later. The solver's proven bound is in the rounded-up units: a real optimum can be up to
one unit per chunk of work and one per drive shorter along its critical chain, so the bound
reported in seconds is ``(bound - 2 n) unit`` (and never below the DAG's LB).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

import numpy as np

from cooprint.scheduling.dag import ChunkDAG
from cooprint.scheduling.listsched import Problem, Timing, best_timing, place_fixed, to_schedule
from cooprint.scheduling.schedule import Schedule

if TYPE_CHECKING:
    from cooprint.config.settings import SchedulingSettings

#: The list schedule's makespan in model time units.
UNITS = 200_000
#: Above this many arcs (robots x chunk pairs a robot could print one after the other) CP-SAT
#: spends its time limit building and propagating the model: the job is scheduled by list.
MAX_ARCS = 300_000
#: CP-SAT worker threads (this machine has two cores).
WORKERS = 2


def _successors_closure(p: Problem) -> list[set[int]]:
    """Every chunk after each chunk through preds (transitively): a robot can never print one of
    them before the chunk, so those arcs are left out of the circuits."""
    after: list[set[int]] = [set() for _ in range(p.n)]
    for i in reversed(p.topological()):
        for s in p.succ[i]:
            after[i].add(s)
            after[i] |= after[s]
    return after


def _fallback(dag: ChunkDAG, robots: Sequence[str], timing: Timing, note: str) -> Schedule:
    return to_schedule(dag, robots, timing, "exact", note=note)


def exact_schedule(dag: ChunkDAG, robots: Sequence[str], settings: "SchedulingSettings | None" = None) -> Schedule:
    """Schedule ``dag`` for ``robots`` with CP-SAT (module docstring), within
    ``settings.time_limit_s``. Falls back to the list schedule, saying why in the note, when
    OR-Tools is missing, the job is too big for the model, or no schedule is found in time."""
    from cooprint.config.settings import SchedulingSettings

    settings = settings or SchedulingSettings()
    p = Problem.of(dag)
    n, nr = p.n, len(robots)
    hint = best_timing(p, nr)
    if n == 0:
        return _fallback(dag, robots, hint, "")
    try:
        from ortools.sat.python import cp_model
    except ImportError:
        return _fallback(dag, robots, hint, "OR-Tools is not installed (pip install cooprint[exact]): list schedule")

    after = _successors_closure(p)
    pairs = [(i, j) for i in range(n) for j in range(n) if i != j and i not in after[j]]
    # Robots beyond the chunk count can only idle: one idle stands for them all.
    used = min(nr, n)
    arcs = used * len(pairs)
    if arcs > MAX_ARCS:
        return _fallback(dag, robots, hint, f"exact: {n} chunks x {used} robots make {arcs} sequencing "
                         f"arcs, more than CP-SAT handles in its time limit (at most {MAX_ARCS}): list schedule")

    unit = max(hint.makespan, 1e-9) / UNITS
    work = [max(1, math.ceil(w / unit)) for w in p.work]
    travel = np.ceil(p.travel / unit).astype(np.int64)
    horizon = int(sum(work) + n * int(travel.max(initial=0)))

    m = cp_model.CpModel()
    start = [m.NewIntVar(0, horizon, f"s{i}") for i in range(n)]
    end = [m.NewIntVar(0, horizon, f"e{i}") for i in range(n)]
    iv = [m.NewIntervalVar(start[i], work[i], end[i], f"iv{i}") for i in range(n)]
    on = [[m.NewBoolVar(f"on{r}_{i}") for i in range(n)] for r in range(used)]
    for i in range(n):
        m.AddExactlyOne(on[r][i] for r in range(used))
    first = []
    arc_lit: dict[tuple[int, int, int], object] = {}
    for r in range(used):
        m.AddNoOverlap([m.NewOptionalIntervalVar(start[i], work[i], end[i], on[r][i], f"o{r}_{i}")
                        for i in range(n)])
        idle = m.NewBoolVar(f"idle{r}")
        for i in range(n):
            m.AddImplication(on[r][i], idle.Not())
        m.AddBoolOr([idle] + on[r])
        circuit = [(0, 0, idle)]
        first_terms = []
        for i in range(n):
            circuit.append((i + 1, i + 1, on[r][i].Not()))
            lit_in = m.NewBoolVar(f"first{r}_{i}")
            lit_out = m.NewBoolVar(f"last{r}_{i}")
            circuit += [(0, i + 1, lit_in), (i + 1, 0, lit_out)]
            arc_lit[(r, -1, i)] = lit_in
            first_terms.append((i, lit_in))
        for i, j in pairs:
            lit = m.NewBoolVar(f"a{r}_{i}_{j}")
            circuit.append((i + 1, j + 1, lit))
            arc_lit[(r, i, j)] = lit
            m.Add(start[j] >= end[i] + int(travel[i, j])).OnlyEnforceIf(lit)
        m.AddCircuit(circuit)
        # Index of the robot's first chunk, n when idle: increasing over the robots.
        fr = m.NewIntVar(0, n, f"first{r}")
        m.Add(fr == sum(i * lit for i, lit in first_terms) + n * idle)
        first.append(fr)
    for r in range(used - 1):
        m.Add(first[r] <= first[r + 1])
    for y in range(n):
        for x in p.preds[y]:
            m.Add(start[y] >= end[x])
    for a in range(n):
        for b in p.excl[a]:
            if a < b:
                m.AddNoOverlap([iv[a], iv[b]])
    makespan = m.NewIntVar(0, horizon, "makespan")
    m.AddMaxEquality(makespan, end)
    m.Minimize(makespan)

    _hint(m, p, hint, work, travel, start, end, on, arc_lit, makespan, horizon)

    solver = cp_model.CpSolver()
    solver.parameters.max_time_in_seconds = float(settings.time_limit_s)
    solver.parameters.num_workers = WORKERS
    solver.parameters.random_seed = 0
    status = solver.Solve(m)
    if status not in (cp_model.OPTIMAL, cp_model.FEASIBLE):
        return _fallback(dag, robots, hint, f"exact found no schedule within {settings.time_limit_s:g} s: list schedule")

    seqs: list[list[int]] = []
    for r in range(used):
        mine = [i for i in range(n) if solver.BooleanValue(on[r][i])]
        seqs.append(sorted(mine, key=lambda i: (solver.Value(start[i]), i)))
    order = sorted(range(n), key=lambda i: (solver.Value(start[i]), i))
    timing = place_fixed(p, seqs, order)
    if timing.makespan > hint.makespan:  # the rounding cost more than the solver gained
        timing = hint
    bound = max(dag.lower_bound(nr), (solver.BestObjectiveBound() - 2 * n) * unit)
    bound = min(bound, timing.makespan)
    if status == cp_model.OPTIMAL:
        note = "optimal"
    else:
        note = (f"time limit reached: gap to proven bound "
                f"{100 * (timing.makespan / bound - 1) if bound > 0 else 0:.1f}%")
    return to_schedule(dag, robots, timing, "exact", note=note, bound=bound)


def _hint(m, p: Problem, hint: Timing, work: list[int], travel: np.ndarray, start, end, on, arc_lit,
          makespan, horizon: int) -> None:
    """The list schedule in model units as CP-SAT's hint: its sequences and placement order
    re-timed with the rounded-up work and travel, so the hint is a whole, feasible solution."""
    n = p.n
    ip = Problem(tuple(float(w) for w in work), p.preds, p.succ, p.excl, travel.astype(float))
    # Robots in the order of their first chunk, as the symmetry breaking wants.
    seqs = sorted((s for s in hint.seqs if s), key=lambda s: s[0])
    order = sorted(range(n), key=lambda i: (hint.start[i], i))
    t = place_fixed(ip, seqs, order)
    if t.makespan > horizon:
        return
    robot_of = {i: r for r, s in enumerate(seqs) for i in s}
    for i in range(n):
        m.AddHint(start[i], int(round(t.start[i])))
        m.AddHint(end[i], int(round(t.end[i])))
    for r in range(len(on)):
        for i in range(n):
            m.AddHint(on[r][i], robot_of.get(i) == r)
    nxt = {}
    for r, s in enumerate(seqs):
        for a, b in zip([-1] + s, s):
            nxt[(r, a, b)] = True
    for key, lit in arc_lit.items():
        m.AddHint(lit, key in nxt)
    m.AddHint(makespan, int(round(t.makespan)))
