"""The schedulers over the ChunkDAG (issue 14 item 3): list, exact (CP-SAT), the seed order timed,
make_schedule. Every schedule passes check_schedule (each precedence and body rule, no exclusive
pair at once, no robot in two places, makespan >= LB)."""

import itertools
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from cooprint.config.settings import SchedulingSettings
from cooprint.errors import ConfigError
from cooprint.scheduling import (SCHEDULERS, ChunkDAG, check_schedule, exact_schedule, list_schedule, make_schedule,
                                 seed_schedule, timed)
from cooprint.scheduling.listsched import Problem

from solids import car, to_trimesh

EXACT_FAST = SchedulingSettings(strategy="exact", time_limit_s=2.0)


def robots(n):
    return [chr(ord("A") + i) if i < 26 else f"R{i}" for i in range(n)]


def random_dag(seed, n, layers=3, p_dep=0.5, p_body=0.2, p_excl=0.2, speed=120.0):
    """A layered DAG: chunk i in a random layer, leaning on chunks of lower layers (a), some
    body rules (b) to lower layers, random exclusive pairs (c), random works, nozzle start and
    end points in a 3 m square, random facings."""
    rng = np.random.default_rng(seed)
    layer = np.sort(rng.integers(0, layers, n))
    ids = tuple(f"k{i}" for i in range(n))
    deps = {ids[i]: tuple(ids[j] for j in range(n) if layer[j] < layer[i] and rng.random() < p_dep)
            for i in range(n)}
    body = {ids[i]: tuple(ids[j] for j in range(n) if layer[j] < layer[i] and rng.random() < p_body)
            for i in range(n)}
    excl = tuple((ids[i], ids[j]) for i in range(n) for j in range(i + 1, n) if rng.random() < p_excl)
    ang = rng.uniform(0, 2 * np.pi, n)
    start = rng.uniform(0, 3000, (n, 3))
    end = rng.uniform(0, 3000, (n, 3))
    return ChunkDAG(ids, rng.uniform(10, 1000, n), np.c_[np.cos(ang), np.sin(ang)], start, end,
                    np.c_[start[:, :2] - 100, start[:, :2] + 100], deps, body, excl, travel_speed=speed)


def grid_dag(rows, cols, seed=0, pitch=500.0):
    """A stand-in for the grid layout: row k (0 the centre row, longer chunks) after row k - 1
    (each chunk after the one in its column), in each row the odd columns after both even
    neighbours (SPAR3), and a chunk exclusive with the neighbouring columns of the row before
    (their robots would stand side by side)."""
    rng = np.random.default_rng(seed)
    ids, work, pos, deps, excl = [], [], [], {}, []

    def name(k, c):
        return f"r{k}c{c}"

    for k in range(rows):
        for c in range(cols):
            cid = name(k, c)
            ids.append(cid)
            work.append(float(rng.uniform(800, 1200)) * (1.5 if k == 0 else 1.0))
            pos.append((c * pitch, k * pitch, 0.0))
            d = [name(k, cc) for cc in (c - 1, c + 1) if c % 2 == 1 and 0 <= cc < cols]
            deps[cid] = tuple(d + ([name(k - 1, c)] if k else []))
            excl += [(name(k - 1, cc), cid) for cc in (c - 1, c + 1) if k and 0 <= cc < cols]
    pos = np.array(pos)
    n = len(ids)
    return ChunkDAG(tuple(ids), np.array(work), np.tile([1.0, 0.0], (n, 1)), pos, pos + [100, 0, 0],
                    np.c_[pos[:, :2], pos[:, :2] + 400], deps, {}, tuple(excl))


def brute_force(dag, n_robots):
    """The optimum by enumeration (independent of the schedulers): every order to place the
    chunks in (after their preds) and every robot for each, each chunk at its earliest start
    after its preds, its robot's last chunk plus the drive and clear of the exclusive chunks
    placed before. Placing an optimal schedule's chunks by their start times never starts one
    later, so the minimum is the optimum."""
    ids = dag.ids
    preds = {c: dag.preds(c) for c in ids}
    excl = dag.exclusive_with()
    w = dict(zip(ids, dag.work.tolist()))
    best = float("inf")
    for perm in itertools.permutations(ids):
        pos = {c: k for k, c in enumerate(perm)}
        if any(pos[p] > pos[c] for c in ids for p in preds[c]):
            continue
        for robots_of in itertools.product(range(n_robots), repeat=len(ids) - 1):
            robot_of = (0,) + robots_of  # the robots are alike: the first chunk on robot 0
            start, end, last = {}, {}, [None] * n_robots
            for c, r in zip(perm, robot_of):
                t = max([end[p] for p in preds[c]] + [0.0])
                if last[r] is not None:
                    t = max(t, end[last[r]] + dag.travel(last[r], c))
                for s, e in sorted((start[x], end[x]) for x in excl[c] if x in start):
                    if e > t and s < t + w[c]:
                        t = e
                start[c], end[c], last[r] = t, t + w[c], c
            best = min(best, max(end.values()))
    return best


# --- list scheduling ---------------------------------------------------------------------------

@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 12), n_robots=st.integers(1, 8),
       p_excl=st.sampled_from([0.0, 0.2, 0.6]))
def test_list_schedule_keeps_every_rule(seed, n, n_robots, p_excl):
    dag = random_dag(seed, n, p_excl=p_excl)
    names = robots(n_robots)
    sched = list_schedule(dag, names)
    check_schedule(dag, sched)  # preds, exclusions, travel, one chunk at a time, makespan >= LB
    assert list(sched.sequences) == names  # every robot a key, idle ones empty
    assert sched.strategy == "list"
    assert sched.lower_bound == pytest.approx(dag.lower_bound(n_robots))
    assert sched.makespan >= dag.critical_path()[0] - 1e-6
    assert sched.makespan >= sched.lower_bound - 1e-6
    assert sched.gap >= -1e-9
    assert list_schedule(dag, names) == sched  # seeded: the same job, the same schedule


def test_one_robot_prints_everything_back_to_back():
    dag = random_dag(7, 10, p_excl=0.5)
    sched = list_schedule(dag, ["A"])
    seq = sched.sequences["A"]
    drive = sum(dag.travel(a, b) for a, b in zip(seq, seq[1:]))
    assert sched.makespan == pytest.approx(float(dag.work.sum()) + drive, abs=1e-6)
    check_schedule(dag, sched)


def test_more_robots_than_chunks_leaves_idle_robots():
    dag = random_dag(3, 4, p_dep=0.0, p_body=0.0, p_excl=0.0)
    sched = list_schedule(dag, robots(10))
    check_schedule(dag, sched)
    assert len(sched.sequences) == 10
    assert len(sched.idle_robots) == 6  # four independent chunks: one robot each, all at 0
    assert sched.makespan == pytest.approx(float(dag.work.max()))
    assert sched.gap == pytest.approx(0.0)


def test_exclusive_chunks_take_turns():
    dag = random_dag(1, 2, p_dep=0.0, p_body=0.0, p_excl=1.0)  # two free chunks never at once
    sched = list_schedule(dag, ["A", "B"])
    check_schedule(dag, sched)
    assert sched.makespan >= float(dag.work.sum()) - 1e-6
    assert dag.lower_bound(2) < float(dag.work.sum())  # LB ignores exclusions: above it here


def test_list_is_fast_on_big_jobs():
    """Hundreds of chunks for 16 robots: the scheduler, not the pipeline, in well under seconds
    (measured 0.2 s for 200 chunks, 0.4 s for 1000 on an idle core; the limits leave room for
    a loaded machine)."""
    import time

    for n, limit in ((200, 3.0), (1000, 12.0)):
        dag = random_dag(5, n, layers=n // 10, p_dep=3 / n, p_body=1 / n, p_excl=3 / n)
        t0 = time.perf_counter()
        sched = list_schedule(dag, robots(16))
        assert time.perf_counter() - t0 < limit
        check_schedule(dag, sched)


# --- fixed sequences and the seed order --------------------------------------------------------

def test_timed_keeps_the_given_sequences():
    dag = random_dag(11, 8, p_excl=0.3)
    order = dag.topological_order()
    seqs = {"A": tuple(order[0::2]), "B": tuple(order[1::2])}
    sched = timed(dag, seqs, "mine")
    check_schedule(dag, sched)
    assert sched.sequences == seqs and sched.strategy == "mine"


def test_timed_refuses_sequences_that_wait_on_each_other():
    dag = ChunkDAG(("a", "b"), np.array([1.0, 1.0]), np.zeros((2, 2)), np.zeros((2, 3)), np.zeros((2, 3)),
                   np.zeros((2, 4)), {"b": ("a",)})
    with pytest.raises(ValueError, match="wait on each other"):
        timed(dag, {"A": ("b", "a")}, "bad")
    with pytest.raises(ValueError, match=r"bad: the sequences hold \['a'\], the DAG's chunks are \['a', 'b'\]"):
        timed(dag, {"A": ("a",), "B": ()}, "bad")


@pytest.fixture(scope="module")
def seed2_job():
    """A real seed2 chunk set (the generated car for two robots) and a DAG over its chunks:
    work from the volumes, start and end at the chunk's ends along the axis."""
    from cooprint.chunking import cut_chunks, plan_chunks
    from cooprint.config import ChunkingSettings, RobotProfile
    from cooprint.io.mesh import solid_from_trimesh

    solid = solid_from_trimesh(to_trimesh(car(700)))
    chunks = cut_chunks(solid, plan_chunks(solid.vertices, RobotProfile(), ChunkingSettings(), 2))
    lo = np.array([c.vertices.min(axis=0) for c in chunks.chunks])
    hi = np.array([c.vertices.max(axis=0) for c in chunks.chunks])
    n = len(chunks.chunks)
    dag = ChunkDAG(tuple(chunks.ids), np.array([c.volume for c in chunks.chunks]) / 50.0,
                   np.tile([1.0, 0.0], (n, 1)), lo, hi, np.c_[lo[:, :2], hi[:, :2]], dict(chunks.deps))
    return chunks, dag


def test_seed_schedule_times_the_seed_order(seed2_job):
    chunks, dag = seed2_job
    sched = seed_schedule(dag, ["A", "B"], chunks)
    check_schedule(dag, sched)
    assert sched.strategy == "seed"
    assert sched.sequences["A"][0] == "C" and all(c.startswith("L") for c in sched.sequences["A"][1:])
    assert all(c.startswith("R") for c in sched.sequences["B"])
    assert sched.start["R1"] == pytest.approx(sched.end["C"])  # B waits for the centre chunk
    assert make_schedule(dag, ["A", "B"], SchedulingSettings(strategy="auto"), chunks) == sched


def test_seed_strategy_refuses_other_jobs(seed2_job):
    chunks, dag = seed2_job
    with pytest.raises(ConfigError, match=r"scheduling.strategy = 'seed'.*seed2 layout for 1 or 2 robots.*3 robots"):
        make_schedule(dag, robots(3), SchedulingSettings(strategy="seed"), chunks)
    with pytest.raises(ConfigError, match=r"strategy = 'seed'"):
        make_schedule(dag, ["A", "B"], SchedulingSettings(strategy="seed"))  # no chunk set


@pytest.mark.parametrize("count", [0, 65])
def test_make_schedule_refuses_robot_counts(count):
    with pytest.raises(ConfigError, match=rf"robots = {count}: expected 1 to 64"):
        make_schedule(random_dag(1, 3), robots(count))


def test_make_schedule_auto_is_list_beyond_seed2():
    dag = grid_dag(2, 6)
    sched = make_schedule(dag, robots(64), SchedulingSettings(strategy="auto"))
    assert sched.strategy == "list" and len(sched.sequences) == 64
    assert set(SCHEDULERS) == {"list", "exact"}


# --- exact (CP-SAT) ----------------------------------------------------------------------------

@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 5), p_excl=st.sampled_from([0.0, 0.3, 0.7]))
def test_exact_is_the_brute_force_optimum(seed, n, p_excl):
    dag = random_dag(seed, n, p_excl=p_excl)
    sched = exact_schedule(dag, ["A", "B"], EXACT_FAST)
    check_schedule(dag, sched)
    assert sched.note == "optimal"
    best = brute_force(dag, 2)
    # Times are whole model units of makespan / 200000 in the solver: within 2 n units.
    assert sched.makespan == pytest.approx(best, rel=1e-4, abs=1e-6)
    assert sched.bound is not None and sched.lower_bound - 1e-6 <= sched.bound <= best + 1e-6


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 9), n_robots=st.integers(1, 8),
       p_excl=st.sampled_from([0.0, 0.3]))
def test_exact_keeps_every_rule_and_never_loses_to_list(seed, n, n_robots, p_excl):
    dag = random_dag(seed, n, p_excl=p_excl)
    names = robots(n_robots)
    sched = exact_schedule(dag, names, SchedulingSettings(time_limit_s=1.0))
    check_schedule(dag, sched)
    assert list(sched.sequences) == names and sched.strategy == "exact"
    assert sched.makespan <= list_schedule(dag, names).makespan + 1e-6
    assert sched.makespan >= dag.critical_path()[0] - 1e-6
    if sched.bound is not None:
        assert sched.lower_bound - 1e-6 <= sched.bound <= sched.makespan + 1e-6


def test_exact_without_a_solution_in_time_falls_back_to_list():
    dag = grid_dag(3, 8)
    sched = exact_schedule(dag, robots(4), SchedulingSettings(time_limit_s=1e-3))
    assert sched.note == "exact found no schedule within 0.001 s: list schedule"
    assert sched.makespan == pytest.approx(list_schedule(dag, robots(4)).makespan)
    assert sched.bound is None
    check_schedule(dag, sched)


def test_exact_falls_back_on_jobs_too_big_for_the_time_limit():
    dag = grid_dag(10, 20)  # 200 chunks: 37855 arcs
    sched = exact_schedule(dag, robots(16), SchedulingSettings(time_limit_s=10.0))
    assert sched.note == ("exact: 200 chunks make 37855 sequencing arcs, more than CP-SAT handles in 10 s "
                          "(about 20000): list schedule")
    check_schedule(dag, sched)


def test_exact_without_ortools_falls_back_to_list(monkeypatch):
    monkeypatch.setitem(sys.modules, "ortools.sat.python", None)  # import fails
    dag = random_dag(2, 6)
    sched = make_schedule(dag, robots(2), SchedulingSettings(strategy="exact"))
    assert sched.note == "OR-Tools is not installed (pip install cooprint[exact]): list schedule"
    assert sched.makespan == pytest.approx(list_schedule(dag, robots(2)).makespan)


# --- the grid: gap to the lower bound ----------------------------------------------------------

@pytest.mark.parametrize("rows, cols, n_robots", [(2, 8, 4), (3, 8, 4), (3, 6, 16), (5, 8, 16)])
def test_grid_gaps(rows, cols, n_robots, capsys):
    """The issue's targets on a grid-like DAG: list within 10% and exact within 3% of the best
    bound known (LB, or the exact solver's proven bound where exclusions put the optimum above
    LB: with 16 robots the chain of rows and the exclusions between them, not the work, set the
    makespan). Measured: 2x8/4 list = exact = proven optimum, +7.6% LB; 3x8/4 list +4.7% LB,
    exact +1.5% LB (proven optimal in ~2 s); 3x6/16 and 5x8/16 list already optimal (+21% and
    +16% above LB, proven by exact)."""
    dag = grid_dag(rows, cols)
    names = robots(n_robots)
    lst = make_schedule(dag, names, SchedulingSettings(strategy="list"))
    ex = make_schedule(dag, names, SchedulingSettings(strategy="exact", time_limit_s=10.0))
    best_bound = max(lst.lower_bound, ex.bound or 0.0)
    with capsys.disabled():
        print(f"\ngrid {rows}x{cols}, {n_robots} robots: LB {lst.lower_bound:.0f} s, list {lst.makespan:.0f} s "
              f"({lst.makespan / lst.lower_bound - 1:+.1%} LB), exact {ex.makespan:.0f} s "
              f"({ex.makespan / ex.lower_bound - 1:+.1%} LB, proven bound {ex.bound or 0:.0f} s, {ex.note})")
    assert ex.makespan <= lst.makespan + 1e-6
    assert lst.makespan / best_bound - 1 <= 0.10
    assert ex.makespan / best_bound - 1 <= 0.03
    assert ex.gap == pytest.approx(ex.makespan / ex.lower_bound - 1)  # the gap is to LB
    assert ex.bound_gap is not None and ex.bound_gap <= 0.03  # and to the proven bound


def test_problem_reversal_mirrors_time():
    p = Problem.of(grid_dag(2, 4))
    r = p.reversed
    assert r.preds == p.succ and r.succ == p.preds
    assert np.array_equal(r.travel, p.travel.T)


def test_of_equal_makespans_the_list_scheduler_keeps_the_one_that_drives_least():
    """Many schedules reach the lower bound; the one kept drives least (robots near their work,
    where their programs' ways cross least: a wall's robots sent end to end waited 57 h)."""
    from dataclasses import replace as dc_replace

    from cooprint.scheduling.listsched import Problem, Timing, _better, _driving, best_timing

    dag = dc_replace(grid_dag(1, 8), work=np.full(8, 1000.0))  # a wall: 4 even, then 4 odd columns
    p = Problem.of(dag)
    t = best_timing(p, 4)
    assert t.makespan == pytest.approx(2000.0 + max(p.travel[a, b] for seq in t.seqs for a, b in zip(seq, seq[1:])))
    for seq in t.seqs:
        for a, b in zip(seq, seq[1:]):  # each robot's odd column is next to its even one
            assert abs(a - b) == 1, t.seqs
    near = Timing([[0, 1], [2, 3]], [0.0] * 4, [1.0] * 4)
    far = Timing([[0, 3], [2, 1]], [0.0] * 4, [1.0] * 4)
    assert _driving(p, near) < _driving(p, far)
    assert _better(p, near, far) and not _better(p, far, near)
