"""Chunk layouts: the strategies of the chunker (issue 14), in one registry.

A layout is a pure function ``(solid, settings, robots, progress=None) -> ChunkSet`` that plans
and cuts a placed solid for ``robots`` robots; :func:`layout_feasibility` is its rule for
``info`` (whether the part can be printed that way, why, how many chunks), the same rule the
layout applies before it cuts.

* ``seed2``: the seed's centre chunk and side chunks (§3), printed by one or two robots.
* ``grid``: the seed's rows, each cut into even and odd columns along the centre line, for any
  number of robots (:mod:`cooprint.chunking.grid`).

``auto`` (choosing by the scheduler's makespan estimate) is the job's decision, not a layout.
"""

from __future__ import annotations

from typing import Callable, Protocol

import numpy as np

from cooprint.chunking.cut import ChunkSet, cut_chunks
from cooprint.chunking.grid import grid_feasibility, grid_layout
from cooprint.chunking.planes import Feasibility, feasibility, plan_chunks
from cooprint.config import JobSettings
from cooprint.errors import ConfigError, InfeasibleError
from cooprint.io.mesh import Solid


class Layout(Protocol):
    def __call__(self, solid: Solid, settings: JobSettings, robots: int,
                 progress: Callable[[int, int], None] | None = None) -> ChunkSet: ...


#: Most robots the seed2 layout can keep busy: one on each side of the centre chunk.
SEED2_ROBOTS = 2


def _seed2_robots(robots: int) -> str | None:
    """Why seed2 cannot take ``robots`` robots (``None`` when it can)."""
    if 1 <= robots <= SEED2_ROBOTS:
        return None
    return f"the seed2 layout takes 1 or 2 robots, not {robots}; use --layout grid"


def seed2_layout(solid: Solid, settings: JobSettings, robots: int,
                 progress: Callable[[int, int], None] | None = None) -> ChunkSet:
    """The seed's chunks: :func:`cooprint.chunking.plan_chunks` then
    :func:`cooprint.chunking.cut_chunks` (``ChunkSet.layout = "seed2"``).

    Raises
    ------
    InfeasibleError
        More than two robots (the seed's plan has two sides), or the part outside the seed's
        limits (:func:`cooprint.chunking.feasibility`)."""
    why = _seed2_robots(robots)
    if why:
        raise InfeasibleError(why)
    return cut_chunks(solid, plan_chunks(solid.vertices, settings.robot, settings.chunking, robots), progress)


LAYOUTS: dict[str, Layout] = {"seed2": seed2_layout, "grid": grid_layout}


def _known(name: str) -> None:
    if name not in LAYOUTS:
        raise ConfigError(f"chunking.layout = {name!r}: expected one of {', '.join(LAYOUTS)}")


def get_layout(name: str) -> Layout:
    """The layout called ``name`` (``seed2``, ``grid``); :class:`ConfigError` for any other."""
    _known(name)
    return LAYOUTS[name]


def layout_feasibility(name: str, vertices: np.ndarray, settings: JobSettings, robots: int) -> Feasibility:
    """Whether ``robots`` robots like ``settings.robot`` can print the part with ``vertices`` in
    layout ``name``, why (with the numbers), the largest printable height and the number of
    chunks: seed2's :func:`cooprint.chunking.feasibility` (refused for more than two robots), the
    grid's :func:`cooprint.chunking.grid.grid_feasibility` (seed2's rows and the column limits)."""
    _known(name)
    if name == "grid":
        return grid_feasibility(vertices, settings, robots)
    record = feasibility(vertices, settings.robot, settings.chunking, min(max(robots, 1), SEED2_ROBOTS))
    why = _seed2_robots(robots)
    if why:
        return Feasibility(False, record.mode, why, record.height, record.extent, record.max_height, 0,
                           record.theta_deg, record.theta_min_deg, record.theta_max_deg, ("--layout grid",))
    return record
