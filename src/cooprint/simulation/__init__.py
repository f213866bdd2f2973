"""Simulator (seed §5): every robot's program played in true time, with physical checks.

``inputs`` reads a bundle, ``.coop`` files with a manifest, or G-code files; ``timeline`` puts
every move in time and resolves NOTIFY / WAIT (deadlocks found from the commands alone);
``checks`` finds bodies on material and robots that collide; :func:`simulate` runs it all and
:func:`summary` is what ``sim/summary.json`` holds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cooprint.config import RobotProfile, SlicingSettings
from cooprint.simulation.checks import STEP, Material, footprint_checks, overhangs, robots_collide
from cooprint.simulation.inputs import SimInput, SimInputError, load_inputs
from cooprint.simulation.kinematics import MachineLimits
from cooprint.simulation.timeline import Finding, SimRobot, Timeline, schedule
from cooprint.slicing.paths import extrusion_area

#: Finding kinds, in the order of the issue's checks (a)-(e).
KINDS = ("body-on-material", "robots-collide", "printhead-hits-material", "deadlock", "overhang")


@dataclass(frozen=True)
class SimResult:
    """A simulated plan: the robots, their timelines, the findings."""

    robots: list[SimRobot]
    timelines: dict[str, Timeline]
    findings: list[Finding]
    profile: RobotProfile
    slicing: SlicingSettings
    source: str
    accel: bool = False
    checked: tuple[str, ...] = ()  # the finding kinds that were looked for

    @property
    def makespan(self) -> float:
        return max((tl.end for tl in self.timelines.values()), default=0.0)


def simulate(inp: SimInput, checks: bool = True, accel: bool = False) -> SimResult:
    """Put every robot's program in time and check the plan.

    ``accel``: moves accelerate and decelerate (trapezoids joined at jerk-limited corner speeds,
    :mod:`.kinematics`) with the input's machine limits (G-code: PrusaSlicer's) or the robot
    profile's ``acceleration`` and ``jerk``; otherwise each move takes length / speed.
    """
    p = inp.profile
    limits = (inp.limits or MachineLimits.planar(p.acceleration, p.jerk)) if accel else None
    timelines, findings = schedule(inp.robots, p.print_speed, p.travel_speed, limits)
    checked = ["deadlock"]
    if checks:
        material = Material.sample(inp.robots, timelines, STEP, inp.slicing.layer_height)
        # where a printer's body stands is not known: its G-code gets the printhead check only
        findings += footprint_checks(inp.robots, timelines, p, material, body=inp.placed)
        if inp.placed:
            findings += robots_collide(inp.robots, timelines, p)
            checked += ["body-on-material", "robots-collide"]
        findings += overhangs(inp.robots, timelines, material, inp.slicing)
        checked += ["printhead-hits-material", "overhang"]
    findings.sort(key=lambda f: (KINDS.index(f.kind), f.time, f.robot))
    return SimResult(inp.robots, timelines, findings, p, inp.slicing, inp.source, accel,
                     tuple(k for k in KINDS if k in checked))


def deposited_volume(r: SimRobot, tl: Timeline, s: SlicingSettings) -> float:
    """mm^3 a robot lays down: width x height x length of its moves with the tool on (a program
    without width and height annotations prints at the slicing settings' width and layer)."""
    w, h = r.bead(tl.index[tl.on], s.extrusion_width, s.layer_height)
    return float((extrusion_area(w, h) * tl.length[tl.on]).sum())


def findings_line(counts: dict[str, int]) -> str:
    """``finding_counts`` of a summary in a few words: the kinds found and how many, or none."""
    found = [f"{k} {v}" for k, v in counts.items() if v]
    return ", ".join(found) if found else "none"


def summary(result: SimResult) -> dict[str, object]:
    """What ``sim/summary.json`` holds: makespan, per robot times and material, the NOTIFY / WAIT
    timeline, every finding."""
    span = result.makespan
    robots = []
    events = []
    for r in result.robots:
        tl = result.timelines[r.name]
        dur = tl.t1 - tl.t0
        printing, travelling = float(dur[tl.on].sum()), float(dur[~tl.on].sum())
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
                           "length / speed (print_speed with the tool on, travel_speed off, or the G-code's F)"),
            "checked": list(result.checked), "robots": robots, "events": events, "finding_counts": counts,
            "findings": [f.to_dict() for f in result.findings]}


__all__ = ["KINDS", "SimInput", "SimInputError", "SimResult", "deposited_volume", "findings_line", "load_inputs",
           "simulate", "summary"]
