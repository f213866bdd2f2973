"""Makespan-optimal schedules with OR-Tools CP-SAT (issue 14, strategy ``exact``).

The model, in integer time units (``unit`` seconds; the list schedule's makespan is about
:data:`UNITS` units, fine enough that rounding costs a few 1e-5 of the makespan):

* one interval per chunk (start, work, end);
* the robots' sequences as *routes* through a depot (``AddMultipleCircuit``, as in vehicle
  routing): the arc depot -> i makes i a robot's first chunk, i -> j makes j the next chunk of
  the robot that printed i and forces ``start_j >= end_i + travel_ij`` (travel as a
  sequence-dependent setup time), i -> depot makes i its last; at most one route per robot.
  A robot starts where its first chunk begins (:meth:`ChunkDAG.travel` from nowhere is 0), so
  the robots are alike and a route is a robot: this needs no robot x chunk presence literals
  and has none of the N! relabellings of the robots that a per-robot model (one optional
  interval and one circuit per robot and chunk) must break. Measured on grid DAGs, the
  per-robot model with symmetry breaking found no schedule in 10 s for 18 chunks and 16
  robots, where this one proves the optimum in 0.1 s; for 24 chunks and 4 robots it needed
  10 s for the schedule this one finds in 2 s;
* no arc i -> j where j comes before i through the preds (it could never be used);
* precedence ``start_y >= end_x`` for every x in :meth:`ChunkDAG.preds` of y;
* every exclusive pair in one ``NoOverlap`` of their two chunk intervals;
* redundant, for propagation: at most N chunks at once (``AddCumulative``) and makespan x N >=
  total work;
* minimise the makespan, starting from the list schedule as a (complete, feasible) hint.

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
#: Arcs (chunk pairs a robot could print one after the other) per second of the time limit:
#: above that CP-SAT spends its time presolving (measured: a 200-chunk grid, 37855 arcs, found
#: nothing in 10 s; 60 chunks proved optimal in 5 s), so the job is scheduled by list.
ARCS_PER_S = 2_000
#: ... but a model this small is always tried.
MIN_ARCS = 1_000
#: CP-SAT worker threads (this machine has two cores).
WORKERS = 2


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

    after = p.after  # no arc i -> j when i comes after j: a robot could never use it
    pairs = [(i, j) for i in range(n) for j in range(n) if i != j and not (after[j] >> i) & 1]
    most = max(MIN_ARCS, int(ARCS_PER_S * settings.time_limit_s))
    if len(pairs) > most:
        return _fallback(dag, robots, hint, f"exact: {n} chunks make {len(pairs)} sequencing arcs, more than "
                         f"CP-SAT handles in {settings.time_limit_s:g} s (about {most}): list schedule")

    unit = max(hint.makespan, 1e-9) / UNITS
    work = [max(1, math.ceil(w / unit)) for w in p.work]
    travel = np.ceil(p.travel / unit).astype(np.int64)
    horizon = int(sum(work) + n * int(travel.max(initial=0)))

    m = cp_model.CpModel()
    start = [m.NewIntVar(0, horizon, f"s{i}") for i in range(n)]
    end = [m.NewIntVar(0, horizon, f"e{i}") for i in range(n)]
    iv = [m.NewIntervalVar(start[i], work[i], end[i], f"iv{i}") for i in range(n)]
    arcs: list[tuple[int, int, object]] = []
    lit: dict[tuple[int, int], object] = {}
    for i in range(n):  # node 0 the depot, chunk i node i + 1
        lit[(-1, i)] = m.NewBoolVar(f"first{i}")
        lit[(i, -1)] = m.NewBoolVar(f"last{i}")
        arcs += [(0, i + 1, lit[(-1, i)]), (i + 1, 0, lit[(i, -1)])]
    for i, j in pairs:
        lit[(i, j)] = m.NewBoolVar(f"a{i}_{j}")
        arcs.append((i + 1, j + 1, lit[(i, j)]))
        m.Add(start[j] >= end[i] + int(travel[i, j])).OnlyEnforceIf(lit[(i, j)])
    m.AddMultipleCircuit(arcs)
    m.Add(sum(lit[(-1, i)] for i in range(n)) <= nr)  # at most one route per robot
    m.AddCumulative(iv, [1] * n, nr)  # redundant: at most nr chunks at once
    for y in range(n):
        for x in p.preds[y]:
            m.Add(start[y] >= end[x])
    for a in range(n):
        for b in p.excl[a]:
            if a < b:
                m.AddNoOverlap([iv[a], iv[b]])
    makespan = m.NewIntVar(0, horizon, "makespan")
    m.AddMaxEquality(makespan, end)
    m.Add(makespan * nr >= sum(work))  # redundant: the work bound, so reaching it proves optimality
    m.Minimize(makespan)

    _hint(m, p, hint, work, travel, start, end, lit, makespan, horizon)

    solver = cp_model.CpSolver()
    solver.parameters.max_time_in_seconds = float(settings.time_limit_s)
    solver.parameters.num_workers = WORKERS
    solver.parameters.random_seed = 0
    status = solver.Solve(m)
    if status not in (cp_model.OPTIMAL, cp_model.FEASIBLE):
        return _fallback(dag, robots, hint, f"exact found no schedule within {settings.time_limit_s:g} s: list schedule")

    seqs: list[list[int]] = []
    for i in range(n):  # each route from the depot is one robot's sequence
        if solver.BooleanValue(lit[(-1, i)]):
            seq = [i]
            while not solver.BooleanValue(lit[(seq[-1], -1)]):
                seq.append(next(j for j in range(n) if (seq[-1], j) in lit and solver.BooleanValue(lit[(seq[-1], j)])))
            seqs.append(seq)
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


def _hint(m, p: Problem, hint: Timing, work: list[int], travel: np.ndarray, start, end, lit, makespan,
          horizon: int) -> None:
    """The list schedule in model units as CP-SAT's hint: its sequences and placement order
    re-timed with the rounded-up work and travel, so the hint is a whole, feasible solution."""
    n = p.n
    ip = Problem(tuple(float(w) for w in work), p.preds, p.succ, p.excl, travel.astype(float))
    seqs = [s for s in hint.seqs if s]
    order = sorted(range(n), key=lambda i: (hint.start[i], i))
    t = place_fixed(ip, seqs, order)
    if t.makespan > horizon:
        return
    taken = {(a, b) for s in seqs for a, b in zip([-1] + s, s + [-1])}
    for key, var in lit.items():
        m.AddHint(var, key in taken)
    for i in range(n):
        m.AddHint(start[i], int(round(t.start[i])))
        m.AddHint(end[i], int(round(t.end[i])))
    m.AddHint(makespan, int(round(t.makespan)))
