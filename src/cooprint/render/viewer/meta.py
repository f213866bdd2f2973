"""The small part of a plan's viewer page: what its panels show (the summary, per robot times and
colours, the findings, the NOTIFY/WAIT events, the Gantt chart's bars), as one JSON-able dict.

The geometry (material, travel, the robots' tracks) goes into binary buffers (``geometry.py``);
this record stays small whatever the plan's size: the Gantt chart's bars are merged at
``GANTT_BINS`` across the makespan and their ends rounded to a tenth of that resolution; the
share of each of ``SHARE_BINS`` bins (fewer for a large fleet) each robot spends printing and
travelling is kept in percent, for the chart's travelling strip and tooltip (as the PNG chart's
columns, ``render.sim._column_shares``). Nefertiti's two-robot plan (3.3 M commands): 17 kB,
0.1-0.25 s.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from cooprint.render.palette import robot_colour
from cooprint.render.sim import (BLOCK_MOVES, BOUND_COLOUR, CRITICAL_COLOUR, TRAVEL_COLOUR, WAIT_COLOUR,
                                 _chunk_spans, _column_shares, _runs, simulated_critical_path)
from cooprint.simulation import KINDS, SimResult
from cooprint.simulation.timeline import severity

#: The Gantt chart's resolution: intervals closer than makespan / GANTT_BINS are merged.
GANTT_BINS = 4000
#: Bins across the makespan of each robot's printing and travelling shares (percent): at most
#: SHARE_BINS, fewer from 17 robots on (SHARE_BUDGET over the fleet, never under SHARE_MIN_BINS).
SHARE_BINS, SHARE_BUDGET, SHARE_MIN_BINS = 1000, 16000, 250


def robot_record(result: SimResult, i: int) -> dict[str, Any]:
    """Robot ``i``'s name, colour and (when where it stands is known) the outline of its body,
    frame and printhead (``[u_lo, u_hi, v_lo, v_hi]`` mm from the nozzle along and across its
    facing), its printhead's height over the nozzle and its facing in time (``[[t, deg], ...]``)."""
    r = result.robots[i]
    profile = r.profile or result.profile
    rec: dict[str, Any] = {"name": r.name, "colour": list(robot_colour(i))}
    if result.placed:
        tl = result.timelines[r.name]
        facings = [[0.0, float(np.degrees(np.arctan2(r.facing[1], r.facing[0])))]]
        if r.program.turns:
            facings = [[float(sp.time), float(np.degrees(np.arctan2(sp.facing[1], sp.facing[0])))]
                       for sp in r.facing_spans(tl)]
        rec.update(outline={k: list(map(float, v)) for k, v in profile.outline().items()},
                   nozzle_height=float(profile.nozzle_height), facing=facings)
    return rec


def _decimals(step: float) -> int:
    """Decimal places that write times to ``step`` s or finer (negative: tens, hundreds...)."""
    return -math.floor(math.log10(step))


def fleet_share_bins(robots: int) -> int:
    """The share bins of a fleet of ``robots``: :data:`SHARE_BINS`, fewer from 17 robots on."""
    return max(SHARE_MIN_BINS, min(SHARE_BINS, SHARE_BUDGET // max(robots, 1)))


def gantt_rows(result: SimResult, bins: int = GANTT_BINS, share_bins: int | None = None) -> list[dict[str, Any]]:
    """Per robot: ``print`` and ``travel`` intervals ``[a, b]`` s merged where closer than
    makespan / ``bins`` (ends rounded to a tenth of that), ``wait`` ``[a, b, "event, event"]``,
    ``chunks`` ``[id, first print start, last print end]`` (ms) and ``share``: ``print`` and
    ``travel``, the percent of each of ``share_bins`` equal bins across the makespan spent so
    (``bin_s`` wide; default :func:`fleet_share_bins`)."""
    span = max(result.makespan, 1e-9)
    share_bins = share_bins or fleet_share_bins(len(result.robots))
    scale = bins / span  # _runs merges within 1 unit
    places = _decimals(span / bins / 10)
    rows = []
    for r in result.robots:
        tl = result.timelines[r.name]
        row: dict[str, Any] = {"name": r.name}
        for key, on in (("print", True), ("travel", False)):
            bars = ((tl.t0[c:c + BLOCK_MOVES][sel] * scale, tl.t1[c:c + BLOCK_MOVES][sel] * scale)
                    for c in range(0, len(tl.t0), BLOCK_MOVES) for sel in [tl.on[c:c + BLOCK_MOVES] == on])
            row[key] = [[round(a / scale, places), round(b / scale, places)] for a, b in _runs(bars)]
        printing, travel = _column_shares(tl, span, share_bins)  # as the PNG chart's columns
        share = {"bin_s": span / share_bins, "print": np.rint(100 * printing).astype(int).tolist(),
                 "travel": np.rint(100 * travel).astype(int).tolist()}
        row["wait"] = [[float(a), float(b), ", ".join(ev)] for a, b, ev in tl.waits]
        row["chunks"] = [[cid, round(a, 3), round(b, 3)] for cid, a, b in _chunk_spans(r, tl)]
        row["share"] = share
        rows.append(row)
    return rows


def _robot_summary(rec: dict[str, Any], span: float) -> dict[str, Any]:
    """A robot of summary.json with ``share``: its printing, travelling, waiting and idle time
    as fractions of the makespan."""
    keys = ("printing", "travelling", "waiting", "idle")
    return rec | {"share": {k: (rec.get(f"{k}_s", 0.0) / span if span > 0 else 0.0) for k in keys}}


def viewer_meta(result: SimResult, record: dict[str, Any], critical: Sequence[str] | None = None,
                lower_bound: float | None = None, title: str = "") -> dict[str, Any]:
    """Everything the viewer's panels need: ``record`` is the simulation's summary
    (:func:`cooprint.simulation.summary`, what sim/summary.json holds). Besides it, the robots'
    shares of the makespan (``summary.robots[i].share``), each finding kind's severity
    (``summary.severity``), the Gantt bars' merge resolution (``gantt_resolution_s``) and the
    Gantt chart's colours (``colours``: travelling, waiting,
    critical path, lower bound; the robots' are ``robots[i].colour``), the PNG chart's."""
    span = float(result.makespan)
    summary = {k: record[k] for k in ("makespan_s", "time_model", "finding_counts", "checked", "notes")
               if k in record}
    summary["robots"] = [_robot_summary(r, span) for r in record.get("robots", [])]
    summary["severity"] = {k: severity(k) for k in KINDS}
    if "schedule" in record:
        summary["schedule"] = record["schedule"]
    return {
        "format": "cooprint-viewer/1",
        "title": title or str(result.source),
        "source": str(result.source),
        "makespan": span,
        "accel": bool(result.accel),
        "placed": bool(result.placed),
        "robots": [robot_record(result, i) for i in range(len(result.robots))],
        "summary": summary,
        "findings": record.get("findings", []),
        "events": record.get("events", []),
        "gantt": gantt_rows(result),
        "gantt_resolution_s": max(span, 1e-9) / GANTT_BINS,
        # the chain that sets the simulated makespan, as the PNG Gantt chart frames it (the
        # schedule's precedence chain alone misses a robot's own last chunks)
        "critical_path": simulated_critical_path(result) if critical else [],
        "lower_bound": lower_bound,
        "colours": {"travelling": list(TRAVEL_COLOUR), "waiting": list(WAIT_COLOUR),
                    "critical": list(CRITICAL_COLOUR), "bound": list(BOUND_COLOUR)},
    }
