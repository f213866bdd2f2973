"""Simulator (seed §5): every robot's program played in true time, with physical checks.

``inputs`` reads a bundle, ``.coop`` files with a manifest, or G-code files; ``timeline`` puts
every move in time and resolves NOTIFY / WAIT (deadlocks found from the commands alone);
``checks`` finds bodies on material and robots that collide; :func:`simulate` runs it all and
:func:`summary` is what ``sim/summary.json`` holds.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from functools import partial
from typing import TYPE_CHECKING, Callable

import numpy as np

from cooprint.config import RobotProfile, SlicingSettings
from cooprint.simulation.checks import (STEP, Material, below_floor, block_sum, chunk_order, footprint_checks,
                                        material_checks, outside_part, overhangs, robots_collide)
from cooprint.simulation.inputs import (ScheduleEstimate, SimInput, SimInputError, own_chunks, load_inputs,
                                        read_chunk_meshes)
from cooprint.simulation.kinematics import MachineLimits
from cooprint.simulation.timeline import Finding, SimRobot, Timeline, schedule, schedule_pieces, severity
from cooprint.slicing.paths import ROUND_ROLES

#: Finding kinds, in the order summaries list them: the robot's outline against material and
#: other robots, the nozzle and the material it lays (in material, twice, in the chunks' order,
#: inside the part), the timing (deadlocks, a makespan below the scheduler's bound), the floor,
#: then the one warning. A kind is in a summary's
#: ``checked`` only when its check ran.
KINDS = ("body-on-material", "robots-collide", "printhead-hits-material", "nozzle-in-material", "double-deposit",
         "chunk-order", "outside-part", "deadlock", "below-lower-bound", "below-floor", "overhang")


@dataclass(frozen=True)
class SimResult:
    """A simulated plan: the robots (each with its own ``profile``), their timelines, the
    findings; ``profile`` is the input's (the fleet's default)."""

    robots: list[SimRobot]
    timelines: dict[str, Timeline]
    findings: list[Finding]
    profile: RobotProfile
    slicing: SlicingSettings
    source: str
    accel: bool = False
    checked: tuple[str, ...] = ()  # the finding kinds that were looked for
    notes: tuple[str, ...] = ()  # what the input held and the simulation did not act on
    placed: bool = True  # where the robots' bodies stand is known (not for G-code printers)
    estimate: ScheduleEstimate | None = None  # the scheduler's lower bound and makespan (job.json)

    @property
    def makespan(self) -> float:
        return max((tl.end for tl in self.timelines.values()), default=0.0)


def simulate(inp: SimInput, checks: bool = True, accel: bool = False,
             progress: Callable[[str, int, int], None] | None = None) -> SimResult:
    """Put every robot's program in time and check the plan.

    ``accel``: moves accelerate and decelerate (trapezoids joined at jerk-limited corner speeds,
    :mod:`.kinematics`) with the input's machine limits (G-code: PrusaSlicer's) or the robot
    profile's ``acceleration`` and ``jerk``; otherwise each move takes length / speed. A bundle
    whose job.json states the scheduler's lower bound is held to it (:func:`bound_findings`).
    ``progress(stage, done, total)``: the ``timelines`` (robots) and the ``checks`` as they end.
    """
    chunks = read_chunk_meshes(inp) if checks else None  # a bundle's part, read (and refused) before the work
    if accel:  # the acceleration model times whole programs
        inp = inp.with_programs()
    result = play(inp, inp.fleet(), accel, checks=checks, chunks=chunks, progress=progress)
    if checks and inp.estimate is not None and inp.estimate.lower_bound_s is not None and not accel:
        found = bound_findings(result, inp.estimate.lower_bound_s)
        findings = sorted(result.findings + found, key=lambda f: (KINDS.index(f.kind), f.time, f.robot))
        checked = tuple(k for k in KINDS if k in result.checked or k == "below-lower-bound")
        result = replace(result, findings=findings, checked=checked)
    return result


#: Kinds whose findings do not depend on when the moves happen, only on where they go: a plan
#: played at other speeds finds the same (:func:`play` with ``invariant=False`` leaves them out).
TIME_INVARIANT = ("below-floor", "outside-part")


def play(inp: SimInput, robots: list[SimRobot], accel: bool = False, checks: bool = True,
         chunks: dict | None = None, invariant: bool = True,
         progress: Callable[[str, int, int], None] | None = None) -> SimResult:
    """:func:`simulate`'s work for ``robots`` (``inp``'s fleet, or the same robots at other
    speeds: :mod:`.perturb`): their timelines and, with ``checks``, every check that applies
    (``chunks``: the bundle's chunk meshes, read once by the caller; ``None``: no outside-part
    check). ``invariant=False`` leaves out the checks of :data:`TIME_INVARIANT`, whose findings
    are the same at any speed (a perturbed run repeats only what timing can change)."""
    p = inp.profile
    feeds = inp.feeds(robots)  # each robot's speeds per role (a G-code robot moves at its own F)
    limits = ({r.name: inp.limits or MachineLimits.planar(r.profile.acceleration, r.profile.jerk) for r in robots}
              if accel else None)
    if progress:
        progress("timelines", 0, len(robots))
    if inp.program_files is not None:  # a bundle's programs, read and timed piece by piece (not held whole)
        if limits is not None:
            raise ValueError("the acceleration model times whole programs: read them first (SimInput.with_programs)")
        pieces = {r.name: partial(inp.program_pieces, r.name) for r in robots}  # checked against job.json
        room = {r.name: inp.program_files[r.name].stat().st_size // 7 + 1 for r in robots}  # read_coop's bound
        robots, timelines, findings = schedule_pieces(robots, pieces, feeds, room)
        inp = replace(inp, robot_chunks=own_chunks(inp.robot_chunks, robots))
    else:
        timelines, findings = schedule(robots, feeds, limits)
    if progress:
        progress("timelines", len(robots), len(robots))
    checked = ["deadlock"]
    if checks:
        if inp.deps is not None:  # a bundle: the order its chunks depend on is known
            findings += chunk_order(robots, timelines, inp.deps)
            checked.append("chunk-order")
        if invariant:
            findings += below_floor(robots, timelines)
            checked.append("below-floor")
        material = Material.sample(robots, timelines, STEP, inp.slicing.layer_height)
        # two independent groups of about equal work: the robot's outline and its nozzle
        # against material and other robots; what was laid down (supported, inside the part)
        outline = [lambda: footprint_checks(robots, timelines, p, material, body=inp.placed),  # a G-code's body:
                   lambda: material_checks(robots, timelines, inp.slicing)]                  # not known
        laid = [lambda: overhangs(robots, timelines, material, inp.slicing)]
        if inp.placed:
            outline.append(lambda: robots_collide(robots, timelines, p))
            checked += ["body-on-material", "robots-collide"]
        checked += ["printhead-hits-material", "nozzle-in-material", "double-deposit", "overhang"]
        if chunks is not None and invariant:  # the part is known: material must lie inside it, in its robot's chunks
            laid.append(lambda: outside_part(robots, timelines, material, chunks, inp.robot_chunks or {},
                                             inp.slicing.extrusion_width))
            checked.append("outside-part")
        findings += _concurrently(_counted([outline, laid], progress))
    findings.sort(key=lambda f: (KINDS.index(f.kind), f.time, f.robot))
    return SimResult(robots, timelines, findings, p, inp.slicing, inp.source, accel,
                     tuple(k for k in KINDS if k in checked), inp.notes, inp.placed, inp.estimate)


#: How far below the scheduler's lower bound a simulated makespan may come before the bound or
#: the plan is called wrong: the scheduler's chunk times are estimates of the same moves at the
#: same speeds, rounded (job.json keeps milliseconds), not the simulator's sums.
BOUND_TOLERANCE = 1e-3


def bound_findings(result: SimResult, lower_bound: float) -> list[Finding]:
    """``below-lower-bound`` (an error): the plan, played at constant speed, ends more than
    :data:`BOUND_TOLERANCE` (relative) before the scheduler's lower bound, which no plan of
    that work can do (the bound is the longest chain of chunk work, or the work per robot):
    either the bound is wrong (the chunks' work over-estimated, or a bound of another plan) or
    the plan leaves work out. One finding at the makespan, on the robot that ends last. Checked
    at constant speed only: with ``--accel`` moves take longer, never shorter, and a perturbed
    run's robots may go faster than the bound assumes."""
    span = result.makespan
    if not span < lower_bound * (1.0 - BOUND_TOLERANCE):
        return []
    last = max(result.robots, key=lambda r: result.timelines[r.name].end)
    tl = result.timelines[last.name]
    where = tuple(float(x) for x in tl.p1[-1]) if len(tl.p1) else (0.0, 0.0, 0.0)
    return [Finding("below-lower-bound", last.name, span, where, None,
                    f"the simulated makespan {span:.1f} s is {1 - span / lower_bound:.2%} below the scheduler's lower "
                    f"bound {lower_bound:.1f} s (job.json schedule.lower_bound_s): the bound or the plan is wrong")]


def _counted(groups: list[list], progress: Callable[[str, int, int], None] | None) -> list[list]:
    """``groups`` of checks, each reporting ``progress("checks", checks done, checks)`` when it
    ends (from whichever thread ran it)."""
    if progress is None:
        return groups
    total = sum(len(g) for g in groups)
    done = [0]
    lock = threading.Lock()
    progress("checks", 0, total)

    def counted(check: Callable[[], list[Finding]]) -> Callable[[], list[Finding]]:
        def run() -> list[Finding]:
            found = check()
            with lock:
                done[0] += 1
                progress("checks", done[0], total)
            return found
        return run

    return [[counted(c) for c in g] for g in groups]


def _concurrently(groups: list[list]) -> list[Finding]:
    """The findings of every check (callables), each group's in order on its own thread when the
    process may use more than one core: the checks' loops are compiled and release the GIL, and
    they only read what they share. One core: one after the other. Same findings either way
    (:func:`simulate` sorts them)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    if cores < 2:
        return [f for group in groups for check in group for f in check()]
    with ThreadPoolExecutor(max_workers=len(groups)) as pool:
        futures = [pool.submit(lambda g=group: [f for check in g for f in check()]) for group in groups]
        return [f for fut in futures for f in fut.result()]


def move_volumes(r: SimRobot, tl: Timeline, s: SlicingSettings, a: int = 0, e: int | None = None) -> np.ndarray:
    """(k,) mm^3 each move of a robot lays down (its moves ``a:e``, all by default): the flow
    cross-section of its role (:func:`~cooprint.slicing.paths.flow_area`: a squashed bead, or
    the round thread of a bridge or overhang perimeter) x length with the tool on, 0 without
    (a program without width and height annotations prints at the slicing settings' width and
    layer). The G-code writer's E is this area x length, so a summary's material is its E."""
    index = tl.index[a:e]
    w, h = r.bead(index, s.extrusion_width, s.layer_height)
    round_ = np.flatnonzero(np.isin(r.program.role[index], ROUND_ROLES))
    thread = np.pi * (w[round_] / 2) ** 2  # flow_area of the round roles
    # extrusion_area(w, h) * length, 0 where the tool is off, in w's array (the same operations
    # in the same order: the same numbers, without a temporary of each)
    np.subtract(w, h, out=w)
    w *= h
    h /= 2
    np.square(h, out=h)
    h *= np.pi
    w += h
    del h
    w[round_] = thread
    w *= tl.length[a:e]
    np.copyto(w, 0.0, where=~tl.on[a:e])
    return w


def deposited_volume(r: SimRobot, tl: Timeline, s: SlicingSettings) -> float:
    """mm^3 a robot lays down in all (the sum of :func:`move_volumes`, a block of moves at a time)."""
    return block_sum(lambda a, e: move_volumes(r, tl, s, a, e), len(tl.t0))


@dataclass(frozen=True)
class Frames:
    """The seed's Fig. 15 dataset: the state of every robot at a fixed time step.

    Attributes
    ----------
    t : (T,) float64
        Frame times, s: 0, dt, 2 dt, ... and the makespan last.
    robots : tuple of str
    position : (T, R, 3) float64
        Each robot's nozzle, mm.
    done : (T, R) int64
        How many of each robot's moves are finished (its timeline's ``[:done]``): the material
        so far is their deposits, and the move under way up to the nozzle.
    material : (T, R) float64
        mm^3 each robot has laid down (:func:`move_volumes`, the part of the move under way
        included).
    facing : (T, R, 2) float64
        The direction each robot faces (from its body to its nozzle), as its turns leave it.
    """

    t: np.ndarray
    robots: tuple[str, ...]
    position: np.ndarray
    done: np.ndarray
    material: np.ndarray
    facing: np.ndarray


def frames(result: SimResult, dt: float) -> Frames:
    """Every robot's state every ``dt`` seconds (seed Fig. 15: at each step as many commands as
    fit, the last one in part, material only with the tool on), computed from the timelines, so
    that frame ``i`` is exact at ``i * dt`` and nothing drifts."""
    if not dt > 0:
        raise ValueError(f"time step {dt!r}: expected a positive number of seconds")
    span = result.makespan
    t = np.arange(0.0, span, dt) if span > 0 else np.zeros(0)
    t = np.append(t, span)
    pos, done, material, facing = [], [], [], []
    for r in result.robots:
        tl = result.timelines[r.name]
        vol = move_volumes(r, tl, result.slicing)
        k = np.searchsorted(tl.t1, t, side="right")  # moves finished
        cur = np.minimum(k, max(len(tl.t1) - 1, 0))  # the move under way (if any)
        part = np.zeros(len(t))
        if len(tl.t1):
            span_k = tl.t1[cur] - tl.t0[cur]
            under_way = (k < len(tl.t1)) & (tl.t0[cur] < t) & (span_k > 0)
            part[under_way] = vol[cur[under_way]] * (t[under_way] - tl.t0[cur[under_way]]) / span_k[under_way]
        pos.append(tl.position(t))
        facing.append(r.facing_at(tl, t))
        done.append(k)
        material.append(np.concatenate([[0.0], np.cumsum(vol)])[k] + part)
    shape = (len(t), 0)
    return Frames(t, tuple(r.name for r in result.robots),
                  np.stack(pos, axis=1) if pos else np.zeros(shape + (3,)),
                  np.stack(done, axis=1) if done else np.zeros(shape, np.int64),
                  np.stack(material, axis=1) if material else np.zeros(shape),
                  np.stack(facing, axis=1) if facing else np.zeros(shape + (2,)))


def findings_line(counts: dict[str, int]) -> str:
    """``finding_counts`` of a summary in a few words: the kinds found and how many, or none."""
    found = [f"{k} {v}" for k, v in counts.items() if v]
    return ", ".join(found) if found else "none"


def failures(record: dict, strict: bool = False) -> dict[str, int]:
    """The ``finding_counts`` of a summary that make a plan fail: the error-level kinds found
    (every kind but overhang), and with ``strict`` the warnings too. Empty: the plan passes."""
    return {k: v for k, v in record["finding_counts"].items() if v and (strict or severity(k) == "error")}


def verdict(record: dict, strict: bool = False) -> str | None:
    """What a plan's checks say against it, in a few words (``errors (body-on-material 12)``,
    or ``warnings (overhang 3)`` under ``strict`` when there are no errors); ``None``: it passes."""
    errors = failures(record)
    if errors:
        return f"errors ({findings_line(errors)})"
    warnings = failures(record, strict)
    return f"warnings ({findings_line(warnings)})" if warnings else None


def schedule_record(result: SimResult) -> dict[str, float | None] | None:
    """The scheduler's numbers a bundle states (job.json ``schedule``: ``lower_bound_s``,
    ``makespan_s`` as ``planned_makespan_s``, ``gap`` as ``planned_gap``) beside the simulated
    makespan's gap to the bound (``gap_to_lower_bound``: makespan / bound - 1); ``None`` when
    the bundle states none."""
    est = result.estimate
    if est is None:
        return None
    lb = est.lower_bound_s
    return {"lower_bound_s": lb, "planned_makespan_s": est.makespan_s, "planned_gap": est.gap,
            "gap_to_lower_bound": result.makespan / lb - 1.0 if lb else None}


def bound_line(record: dict) -> str | None:
    """A summary's makespan against the scheduler's lower bound in a few words
    (``makespan 12.30 h, lower bound 11.80 h (+4.2%)``); ``None`` without a bound."""
    sched = record.get("schedule")
    if not sched or sched.get("lower_bound_s") is None:
        return None
    span, lb = record["makespan_s"], sched["lower_bound_s"]
    gap = f" ({sched['gap_to_lower_bound']:+.1%})" if sched.get("gap_to_lower_bound") is not None else ""
    planned = (f"; the scheduler planned {sched['planned_makespan_s'] / 3600:.2f} h"
               if sched.get("planned_makespan_s") is not None else "")
    return f"makespan {span / 3600:.2f} h, lower bound {lb / 3600:.2f} h{gap}{planned}"


def summary(result: SimResult, perturbed: "PerturbResult | None" = None) -> dict[str, object]:
    """What ``sim/summary.json`` holds: makespan, per robot times and material, the NOTIFY / WAIT
    timeline, every finding; the scheduler's bound when the bundle states one (``schedule``:
    :func:`schedule_record`), and with ``perturbed`` the Monte-Carlo runs (``perturb``:
    :meth:`PerturbResult.to_dict`)."""
    span = result.makespan
    robots = []
    events = []
    for r in result.robots:
        tl = result.timelines[r.name]
        dur = lambda a, e: tl.t1[a:e] - tl.t0[a:e]  # noqa: E731 (a block's durations)
        printing = block_sum(dur, len(tl.t0), lambda a, e: tl.on[a:e])
        travelling = block_sum(dur, len(tl.t0), lambda a, e: ~tl.on[a:e])
        waiting = float(sum(w[1] - w[0] for w in tl.waits))
        robots.append({"name": r.name, "printing_s": printing, "travelling_s": travelling, "waiting_s": waiting,
                       "idle_s": max(0.0, span - printing - travelling - waiting), "end_s": tl.end,
                       "moves": int(len(tl.t0)), "material_mm3": deposited_volume(r, tl, result.slicing)})
        events += [{"time_s": t, "robot": r.name, "kind": "notify", "events": [e]} for t, e in tl.notifies]
        events += [{"time_s": a, "until_s": b, "robot": r.name, "kind": "wait", "events": list(ev)}
                   for a, b, ev in tl.waits]
    events.sort(key=lambda e: (e["time_s"], e["robot"]))
    counts = {k: sum(f.count for f in result.findings if f.kind == k) for k in KINDS}
    return {"format": "cooprint-sim/1", "source": result.source, "makespan_s": span,
            "time_model": ("trapezoidal acceleration, jerk-limited corners" if result.accel else
                           "length / speed (the tool on: the [slicing] speed of the path's role, at most "
                           "first_layer_speed on the first layer; off: travel_speed; each under the robot's "
                           "max_print_speed / max_travel_speed; or the G-code's F)"),
            "checked": list(result.checked), "robots": robots, "events": events, "finding_counts": counts,
            "findings": [f.to_dict() for f in result.findings], "notes": list(result.notes),
            **({"schedule": schedule_record(result)} if result.estimate is not None else {}),
            **({"perturb": perturbed.to_dict()} if perturbed is not None else {})}


if TYPE_CHECKING:
    from cooprint.simulation.perturb import PerturbResult


__all__ = ["KINDS", "TIME_INVARIANT", "Frames", "SimInput", "SimInputError", "SimResult", "bound_findings", "bound_line",
           "deposited_volume", "failures", "findings_line", "play", "schedule_record",
           "frames", "load_inputs", "simulate", "summary", "verdict"]
