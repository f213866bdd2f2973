"""The small part of a plan's viewer page: what its panels show (the summary, per robot times and
colours, the findings, the NOTIFY/WAIT events, the Gantt chart's bars), as one JSON-able dict.

The geometry (material, travel, the robots' tracks) goes into binary buffers (``geometry.py``);
this record stays small whatever the plan's size: the Gantt chart's bars are merged at
``GANTT_BINS`` across the makespan, as the PNG Gantt chart merges them at its pixels.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from cooprint.render.palette import robot_colour
from cooprint.render.sim import BLOCK_MOVES, _chunk_spans, _runs
from cooprint.simulation import SimResult

#: The Gantt chart's resolution: intervals closer than makespan / GANTT_BINS are merged.
GANTT_BINS = 4000


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


def gantt_rows(result: SimResult, bins: int = GANTT_BINS) -> list[dict[str, Any]]:
    """Per robot: ``print`` and ``travel`` intervals ``[a, b]`` s merged where closer than
    makespan / ``bins``, ``wait`` ``[a, b, "event, event"]`` and ``chunks`` ``[id, first print
    start, last print end]``."""
    span = max(result.makespan, 1e-9)
    scale = bins / span  # _runs merges within 1 unit
    rows = []
    for r in result.robots:
        tl = result.timelines[r.name]
        row: dict[str, Any] = {"name": r.name}
        for key, on in (("print", True), ("travel", False)):
            bars = ((tl.t0[c:c + BLOCK_MOVES][sel] * scale, tl.t1[c:c + BLOCK_MOVES][sel] * scale)
                    for c in range(0, len(tl.t0), BLOCK_MOVES) for sel in [tl.on[c:c + BLOCK_MOVES] == on])
            row[key] = [[a / scale, b / scale] for a, b in _runs(bars)]
        row["wait"] = [[float(a), float(b), ", ".join(ev)] for a, b, ev in tl.waits]
        row["chunks"] = [[cid, a, b] for cid, a, b in _chunk_spans(r, tl)]
        rows.append(row)
    return rows


def viewer_meta(result: SimResult, record: dict[str, Any], critical: Sequence[str] | None = None,
                lower_bound: float | None = None, title: str = "") -> dict[str, Any]:
    """Everything the viewer's panels need: ``record`` is the simulation's summary
    (:func:`cooprint.simulation.summary`, what sim/summary.json holds)."""
    return {
        "format": "cooprint-viewer/1",
        "title": title or str(result.source),
        "source": str(result.source),
        "makespan": float(result.makespan),
        "accel": bool(result.accel),
        "placed": bool(result.placed),
        "robots": [robot_record(result, i) for i in range(len(result.robots))],
        "summary": {k: record[k] for k in ("makespan_s", "time_model", "robots", "finding_counts", "checked",
                                           "notes") if k in record} | (
            {"schedule": record["schedule"]} if "schedule" in record else {}),
        "findings": record.get("findings", []),
        "events": record.get("events", []),
        "gantt": gantt_rows(result),
        "critical_path": list(critical or ()),
        "lower_bound": lower_bound,
    }
