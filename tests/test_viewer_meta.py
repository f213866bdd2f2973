"""The viewer's panel record (render/viewer/meta.py): the Gantt chart's bars are the timelines'
merged within the chart's resolution, its waits the timelines' own, the robots' colours the one
palette's, the shares add up, and the record stays small however many moves a plan has."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cooprint.config import RobotProfile, SlicingSettings
from cooprint.jobs import robot_names
from cooprint.program.commands import parse_coop
from cooprint.render.palette import robot_colour
from cooprint.render.sim import BOUND_COLOUR, CRITICAL_COLOUR, TRAVEL_COLOUR, WAIT_COLOUR, simulated_critical_path
from cooprint.render.viewer.meta import (GANTT_BINS, SHARE_BINS, SHARE_MIN_BINS, fleet_share_bins, gantt_rows,
                                         viewer_meta)
from cooprint.simulation import SimInput, simulate, summary
from cooprint.simulation.timeline import SimRobot


def _plan(robots: int, moves: int, seed: int = 1, drives: float = 0.01, drive_mm: float = 600.0):
    """``robots`` robots of ``moves`` random moves each (printing lines 2 to 200 mm, travels
    1 to 30 mm, a ``drives`` share of them ``drive_mm`` drives), three chunks each; robot k > 0
    first waits for robot k-1's first chunk."""
    rng = np.random.default_rng(seed)
    names = robot_names(robots)
    out = []
    for i, name in enumerate(names):
        y = 1000.0 * i
        lines = [f"MOVE 0 {y} 0"] + ([f"WAIT {names[i - 1]}:c0"] if i else [])
        x = 0.0
        for m in range(moves):
            if m % max(moves // 3, 1) == 0:
                lines.append(f";@chunk {name}c{m // max(moves // 3, 1)}")
            printing = m % 2 == 0
            step = rng.uniform(2, 200) if printing else (drive_mm if rng.random() < drives else rng.uniform(1, 30))
            x = x + step if x < 5000 else x - step
            lines += ["TOOL ON", f"MOVE {x:.3f} {y} 0", "TOOL OFF"] if printing else [f"MOVE {x:.3f} {y + 5} 0"]
            if m == max(moves // 3, 1) - 1:
                lines.append(f"NOTIFY {name}:c0")
        text = "\n".join(lines) + "\n;@chunk -\n"
        out.append(SimRobot(name, parse_coop(text, name), np.array([0, y, 0.0]), np.array([0.0, 1.0])))
    return simulate(SimInput(out, RobotProfile(), SlicingSettings(), "test"), checks=False)


@pytest.fixture(scope="module")
def plan():
    return _plan(3, 4000)


@pytest.fixture(scope="module")
def meta(plan):
    return viewer_meta(plan, summary(plan), critical=["Ac0", "Bc1"], lower_bound=0.9 * plan.makespan, title="t")


def _covered(intervals: list, t0: np.ndarray, t1: np.ndarray, res: float, tol: float) -> None:
    """``intervals`` are the moves ``[t0, t1]`` merged where closer than ``res`` (ends within ``tol``)."""
    iv = np.asarray(intervals, float).reshape(-1, 2)
    assert np.all(iv[:, 1] >= iv[:, 0]) and np.all(np.diff(iv[:, 0]) > 0)
    assert np.all(iv[1:, 0] - iv[:-1, 1] > res - 2 * tol)  # apart: else they would have been merged
    k = np.searchsorted(iv[:, 0], t0 + tol, side="right") - 1  # each move's interval
    assert np.all(k >= 0) and np.all(t1 <= iv[k, 1] + tol)  # every move inside one
    assert np.all(np.bincount(k, minlength=len(iv)) > 0)  # every interval holds moves
    for j in range(len(iv)):  # ... starts at its first, ends at its last, gaps inside under res
        a, b = t0[k == j], t1[k == j]
        assert abs(a.min() - iv[j, 0]) <= tol and abs(b.max() - iv[j, 1]) <= tol
        assert np.all(a[1:] - np.maximum.accumulate(b)[:-1] <= res + tol)


def test_gantt_bars_are_the_timelines_merged_within_the_resolution(plan, meta):
    res = plan.makespan / GANTT_BINS
    assert meta["gantt_resolution_s"] == pytest.approx(res)
    for row, r in zip(meta["gantt"], plan.robots):
        tl = plan.timelines[r.name]
        assert row["name"] == r.name
        for key, on in (("print", True), ("travel", False)):
            _covered(row[key], tl.t0[tl.on == on], tl.t1[tl.on == on], res, tol=res / 10)
        printing = float((tl.t1 - tl.t0)[tl.on].sum())
        bars = sum(b - a for a, b in row["print"])
        assert printing - 1e-6 <= bars + len(row["print"]) * res / 10
        assert len(row["print"]) > 3 and len(row["travel"]) > len(row["print"])  # the drives break the runs


def test_gantt_waits_and_chunks_are_the_timelines(plan, meta):
    for row, r in zip(meta["gantt"], plan.robots):
        tl = plan.timelines[r.name]
        assert row["wait"] == [[a, b, ", ".join(ev)] for a, b, ev in tl.waits]
        assert [c[0] for c in row["chunks"]] == [f"{r.name}c{k}" for k in range(3)]
        for cid, a, b in row["chunks"]:
            assert a < b and any(abs(a - t) < 1e-3 for t in tl.t0[tl.on])
    a, b, events = meta["gantt"][1]["wait"][0]
    assert meta["gantt"][0]["wait"] == [] and events == "A:c0" and b > a


def test_shares_add_up_to_the_summary(plan, meta):
    span = plan.makespan
    for row, rec in zip(meta["gantt"], meta["summary"]["robots"]):
        sh = row["share"]
        assert len(sh["print"]) == len(sh["travel"]) == SHARE_BINS and sh["bin_s"] == pytest.approx(span / SHARE_BINS)
        p, t = np.array(sh["print"]), np.array(sh["travel"])
        assert p.min() >= 0 and (p + t).max() <= 101  # rounded percent
        assert p.sum() * sh["bin_s"] / 100 == pytest.approx(rec["printing_s"], abs=0.005 * span)
        assert t.sum() * sh["bin_s"] / 100 == pytest.approx(rec["travelling_s"], abs=0.005 * span)
        assert sum(rec["share"].values()) == pytest.approx(1.0)
        assert rec["share"]["printing"] == pytest.approx(rec["printing_s"] / span)
    assert meta["summary"]["robots"][1]["share"]["waiting"] > 0


def test_shares_are_each_bins_time_printing_and_travelling(plan, meta):
    for row, r in zip(meta["gantt"], plan.robots):
        tl = plan.timelines[r.name]
        edges = np.arange(len(row["share"]["print"]) + 1) * row["share"]["bin_s"]
        for key, on in (("print", tl.on), ("travel", ~tl.on)):
            done = np.clip(edges[:, None] - tl.t0[on], 0, tl.t1[on] - tl.t0[on]).sum(axis=1)  # by each edge
            assert np.abs(np.array(row["share"][key]) - 100 * np.diff(done) / row["share"]["bin_s"]).max() <= 0.5 + 1e-6


def test_robot_colours_are_the_palettes_and_the_record_is_json(plan, meta):
    assert [r["colour"] for r in meta["robots"]] == [list(robot_colour(i)) for i in range(3)]
    assert meta["colours"] == {"travelling": list(TRAVEL_COLOUR), "waiting": list(WAIT_COLOUR),
                               "critical": list(CRITICAL_COLOUR), "bound": list(BOUND_COLOUR)}
    # the chain that sets the simulated makespan, as the PNG Gantt chart frames it, when the plan has a schedule
    assert meta["critical_path"] == simulated_critical_path(plan) and meta["critical_path"]
    assert meta["lower_bound"] == pytest.approx(0.9 * plan.makespan)
    assert meta["summary"]["severity"]["overhang"] == "warning" and meta["summary"]["severity"]["robots-collide"] == "error"
    assert json.loads(json.dumps(meta, allow_nan=False)) == meta
    sixteen = _plan(16, 4)
    colours = [r["colour"] for r in viewer_meta(sixteen, summary(sixteen))["robots"]]
    assert colours == [list(robot_colour(i)) for i in range(16)] and len({tuple(c) for c in colours}) == 16


def test_the_record_stays_small_however_many_moves():
    # 120k moves, 1500 drives per robot each longer than a bin: as many bars as the bins allow
    big = _plan(2, 60000, seed=3, drives=0.05, drive_mm=12000.0)
    meta = viewer_meta(big, summary(big))
    rows = meta["gantt"]
    assert all(1000 < len(r["print"]) <= GANTT_BINS and len(r["travel"]) <= GANTT_BINS for r in rows)
    assert len(json.dumps(rows[0]["print"])) < 24 * len(rows[0]["print"])  # ends rounded, not 17 digits
    assert len(json.dumps(meta)) < 150_000
    # a big fleet: fewer share bins, never fewer than SHARE_MIN_BINS
    assert fleet_share_bins(2) == SHARE_BINS and fleet_share_bins(64) == SHARE_MIN_BINS
    assert SHARE_MIN_BINS <= fleet_share_bins(32) < SHARE_BINS
    assert len(gantt_rows(_plan(20, 4))[0]["share"]["print"]) == fleet_share_bins(20) < SHARE_BINS
