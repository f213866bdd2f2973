"""Monte-Carlo robustness (issue 14, item 5): a plan played many times at speeds it was not
planned for.

A plan is correct only if it is correct whatever the real speeds are: its NOTIFY / WAIT pairs,
not the timing the scheduler assumed, must keep robots out of each other's way and chunks in
their order (seed §5: a centralised plan that relies on timing collides as soon as one robot is
slower). Each run scales every robot's speed by an independent random factor per stretch of its
program (:func:`span_ids`: each chunk it prints, and each travel between chunks), uniform in
``[1 - F, 1 + F]``, then plays and checks the plan as :func:`cooprint.simulation.simulate` does.

The runs are reproducible: run ``k``'s factors come from ``numpy.random.default_rng(s_k)``, its
own seed, and the seeds ``s_1 .. s_K`` from ``numpy.random.default_rng(seed)``; a run is
replayed alone from its seed (:func:`run_factors`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from cooprint.errors import UserError
from cooprint.program.commands import MOVE
from cooprint.simulation.inputs import SimInput
from cooprint.simulation.timeline import Finding, SimRobot, move_durations

if TYPE_CHECKING:
    from cooprint.program.gcode import Feeds

#: Most runs of one call (``--runs``): a run of a large plan takes a second or more.
MAX_RUNS = 10_000
#: Runs when ``--perturb`` is given without ``--runs`` (the issue's benchmark: K = 20).
DEFAULT_RUNS = 20
#: The seed when none is given: the same draws every time, so that a result can be reproduced.
DEFAULT_SEED = 0
#: Seeds are non-negative and below 2**63 (a run's own seed is drawn from that range).
SEED_LIMIT = 2 ** 63


def check_perturb_options(fraction: float | None, runs: int | None, seed: int | None) -> tuple[float, int, int] | None:
    """``--perturb F --runs K --seed S`` checked: ``F`` in (0, 1) (a factor 1 - F must stay a
    positive speed), ``K`` in 1..:data:`MAX_RUNS`, ``S`` in 0..2**63 - 1; ``--runs`` and
    ``--seed`` only with ``--perturb``. Returns ``(F, K, S)`` with the defaults filled in, or
    ``None`` without ``--perturb``; a bad value is a one-line :class:`UserError`."""
    if fraction is None:
        for name, value in (("--runs", runs), ("--seed", seed)):
            if value is not None:
                raise UserError(f"{name} {value}: needs --perturb F (the speed variation of each run, 0 < F < 1)")
        return None
    if not (np.isfinite(fraction) and 0.0 < fraction < 1.0):
        raise UserError(f"--perturb {fraction:g}: expected a fraction between 0 and 1, both excluded "
                        "(0.2: speeds scaled by 0.8 to 1.2)")
    runs = DEFAULT_RUNS if runs is None else runs
    if not 1 <= runs <= MAX_RUNS:
        raise UserError(f"--runs {runs}: expected a whole number of runs from 1 to {MAX_RUNS}")
    seed = DEFAULT_SEED if seed is None else seed
    if not 0 <= seed < SEED_LIMIT:
        raise UserError(f"--seed {seed}: expected a whole number from 0 to {SEED_LIMIT - 1}")
    return float(fraction), int(runs), int(seed)


def span_ids(chunk: np.ndarray) -> np.ndarray:
    """(n,) the stretch of a program each command is in, from 0: a new stretch wherever the
    ``chunk`` column (a program's, -1 between chunks) changes, so that each chunk a robot prints
    and each travel between two chunks is a stretch of its own (a program without chunks is one)."""
    c = np.asarray(chunk)
    if not len(c):
        return np.zeros(0, np.int64)
    return np.concatenate([[0], np.cumsum(c[1:] != c[:-1])]).astype(np.int64)


def command_speeds(r: SimRobot, feeds: "Feeds") -> np.ndarray:
    """(n,) the speed of each command of robot ``r`` at constant speed, mm/s, as
    :func:`~cooprint.simulation.timeline.move_durations` takes it: its own per-command speeds (a
    G-code file's feed rates), or ``feeds``' (the robot's speeds per path role); 0 for commands
    that are not moves."""
    n = len(r.program.kind)
    if r.speed is not None:
        return np.where(r.program.kind == MOVE, np.asarray(r.speed, dtype=np.float64), 0.0)
    mv, _, _, on, _, _ = move_durations(r, feeds)
    out = np.zeros(n)
    out[mv] = feeds.move_speeds(r.program.role[mv], r.program.layer[mv], on)
    return out


def perturbed_speeds(base: np.ndarray, spans: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """(n,) each command's speed ``base`` times its stretch's factor (``spans``: :func:`span_ids`;
    ``factors``: one per stretch)."""
    return np.asarray(base, dtype=np.float64) * np.asarray(factors, dtype=np.float64)[spans]


def run_factors(stretches: list[int], fraction: float, seed: int) -> list[np.ndarray]:
    """One run's factors: for each robot in order, one per stretch of its program
    (``stretches[i]`` of them), independent and uniform in ``[1 - fraction, 1 + fraction]``,
    from ``numpy.random.default_rng(seed)``."""
    rng = np.random.default_rng(seed)
    return [rng.uniform(1.0 - fraction, 1.0 + fraction, size=n) for n in stretches]


@dataclass(frozen=True)
class PerturbRun:
    """One perturbed run: its number (from 1), the seed of its factors, its makespan (s) and its
    findings."""

    run: int
    seed: int
    makespan: float
    findings: tuple[Finding, ...]

    def counts(self, kinds: tuple[str, ...]) -> dict[str, int]:
        """How many of each kind (each finding's ``count``), every kind of ``kinds`` listed."""
        return {k: sum(f.count for f in self.findings if f.kind == k) for k in kinds}


@dataclass(frozen=True)
class PerturbResult:
    """The runs of :func:`perturb_runs`: the variation ``fraction``, the ``seed`` their seeds
    were drawn from, the time model (``accel``), the kinds each run ``checked``, and the runs."""

    fraction: float
    seed: int
    accel: bool
    checked: tuple[str, ...]
    runs: tuple[PerturbRun, ...]

    @property
    def makespans(self) -> np.ndarray:
        return np.array([r.makespan for r in self.runs], dtype=np.float64)

    def distribution(self) -> dict[str, float]:
        """The makespans' min, median, 95th percentile (linear interpolation between runs) and
        max, s."""
        m = self.makespans
        return {"min": float(m.min()), "median": float(np.median(m)), "p95": float(np.percentile(m, 95)),
                "max": float(m.max())}

    def finding_counts(self) -> dict[str, int]:
        """Each kind's count summed over the runs (the ``finding_counts`` the CLI judges)."""
        from cooprint.simulation import KINDS

        return {k: sum(r.counts(KINDS)[k] for r in self.runs) for k in KINDS}

    def to_dict(self) -> dict[str, object]:
        """``summary.json``'s ``perturb`` object."""
        from cooprint.simulation import KINDS

        return {"fraction": self.fraction, "runs": len(self.runs), "seed": self.seed,
                "factors": f"uniform in [{1 - self.fraction:g}, {1 + self.fraction:g}] per robot and stretch "
                           "(each chunk, each travel between chunks), drawn anew each run",
                "time_model": "trapezoidal acceleration, jerk-limited corners" if self.accel else "length / speed",
                "checked": list(self.checked), "makespan_s": self.distribution(),
                "per_run": [{"run": r.run, "seed": r.seed, "makespan_s": r.makespan,
                             "finding_counts": r.counts(KINDS)} for r in self.runs],
                "finding_counts": self.finding_counts(),
                "findings": [{"run": r.run, "seed": r.seed, **f.to_dict()} for r in self.runs for f in r.findings]}


def perturb_runs(inp: SimInput, fraction: float, runs: int, seed: int = DEFAULT_SEED, accel: bool = False,
                 progress=None, executor=None) -> PerturbResult:
    """Play ``inp`` ``runs`` times, each run with every robot's speeds scaled per stretch of its
    program by factors uniform in ``[1 - fraction, 1 + fraction]`` (:func:`run_factors`; with
    ``accel`` the factor scales each move's requested speed, the cap of its trapezoid, and the
    accelerations stay), and check each run.

    A run is as cheap as the checks allow: no pictures, the constant-speed speeds worked out
    once, and only the checks whose findings timing can change (:data:`cooprint.simulation.
    TIME_INVARIANT` are the same at any speed and left to the constant-speed simulation).
    ``progress(done, total)`` is called after each run.

    ``executor`` (:mod:`cooprint.executors`; None: one run after the other here) runs them: the
    plan and its constant-speed speeds are its ``shared`` data (sent to each worker once), a
    run is a task ``(number, seed)``, and the runs come back in order. A run depends on its seed
    alone, so the result is the same whatever the executor."""
    if not 0.0 < fraction < 1.0:
        raise ValueError(f"fraction {fraction!r}: expected 0 < fraction < 1")
    if not 1 <= runs <= MAX_RUNS:
        raise ValueError(f"runs {runs!r}: expected 1 to {MAX_RUNS}")
    robots = inp.fleet()
    feeds = inp.feeds(robots)
    base = [command_speeds(r, feeds[r.name]) for r in robots]
    spans = [span_ids(r.program.chunk) for r in robots]
    stretches = [int(s[-1]) + 1 if len(s) else 0 for s in spans]
    seeds = np.random.default_rng(seed).integers(0, SEED_LIMIT, size=runs, dtype=np.int64).tolist()
    shared = _Plan(inp, robots, base, spans, stretches, float(fraction), accel)
    if executor is None:
        from cooprint.executors import InlineExecutor

        executor = InlineExecutor()
    out, checked = [], ()
    results = executor.map(_perturbed_run, list(enumerate(seeds, start=1)), shared=shared)
    try:
        for k, (run, checked) in enumerate(results, start=1):
            out.append(run)
            if progress is not None:
                progress(k, runs)
    finally:  # Ctrl-C or an error: the runs under way stop now
        results.close()
    return PerturbResult(float(fraction), int(seed), accel, checked, tuple(out))


@dataclass(frozen=True)
class _Plan:
    """What every perturbed run shares: the plan, its robots, their constant-speed speeds, the
    stretches of their programs, the variation and the time model."""

    inp: SimInput
    robots: list[SimRobot]
    base: list[np.ndarray]
    spans: list[np.ndarray]
    stretches: list[int]
    fraction: float
    accel: bool


def _perturbed_run(plan: _Plan, task: tuple[int, int]) -> tuple[PerturbRun, tuple[str, ...]]:
    """One run (a task of :func:`perturb_runs`): ``task`` is its number and its seed; returns
    the run and the kinds it checked."""
    from cooprint.simulation import play

    k, run_seed = task
    factors = run_factors(plan.stretches, plan.fraction, run_seed)
    moved = [replace(r, speed=perturbed_speeds(b, s, f))
             for r, b, s, f in zip(plan.robots, plan.base, plan.spans, factors)]
    res = play(plan.inp, moved, plan.accel, checks=True, chunks=None, invariant=False)
    return PerturbRun(k, int(run_seed), res.makespan, tuple(res.findings)), tuple(res.checked)


__all__ = ["DEFAULT_RUNS", "DEFAULT_SEED", "MAX_RUNS", "PerturbResult", "PerturbRun", "check_perturb_options",
           "command_speeds", "perturb_runs", "perturbed_speeds", "run_factors", "span_ids"]
