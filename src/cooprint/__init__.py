"""cooprint: cooperative 3D printing for fleets of mobile FDM printers.

Pipeline (one package per stage, data flowing one way)::

    mesh --io.load_mesh--> Solid --chunking.LAYOUTS (seed2 | grid)--> ChunkSet
         --slicing.iter_layers (each chunk)--> layers
         --scheduling.graph.build_dag--> ChunkDAG --scheduling.SCHEDULERS (list | exact | seed)--> Schedule
         --program.fleet (program.build for the seed's order)--> Program per robot
         --program.commands / program.gcode--> robots/<name>.coop, robots/<name>.gcode

The public API is re-exported here; :func:`run` is the whole pipeline (``cooprint run``).
"""

from __future__ import annotations

import importlib

from cooprint.errors import ConfigError, InfeasibleError, MeshError, UserError

TYPE_CHECKING = False  # not typing's: importing typing here would cost the command 10-60 ms
if TYPE_CHECKING:
    from typing import Any

    from cooprint.chunking import ChunkPlan, ChunkSet, Chunk, Plane, cut_chunks, plan_chunks, slope_limits
    from cooprint.config import JobSettings, RobotProfile, load_settings
    from cooprint.io.mesh import Solid, load_mesh, solid_from_trimesh

__version__ = "0.1.0"

#: Re-exported names and their modules, imported on first use (PEP 562): ``import cooprint``
#: (and so the ``cooprint`` command, before it can catch a Ctrl-C) does not load numpy, trimesh
#: and manifold3d until they are needed.
_LAZY = {**dict.fromkeys(("ChunkPlan", "ChunkSet", "Chunk", "Plane", "cut_chunks", "plan_chunks", "slope_limits"),
                         "cooprint.chunking"),
         **dict.fromkeys(("JobSettings", "RobotProfile", "load_settings"), "cooprint.config"),
         **dict.fromkeys(("Solid", "load_mesh", "solid_from_trimesh"), "cooprint.io.mesh")}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'cooprint' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def run(mesh, out, *, config=(), overrides=None, robots: int = 2, force: bool = False, picture: bool = True):
    """Plan a cooperative print of ``mesh`` and write the bundle to ``out`` (``cooprint run``):
    ``job.json``, ``chunks/<id>.stl``, ``robots/<name>.coop`` and ``.gcode``, ``chunks.png``.

    Parameters
    ----------
    config
        TOML files (robot profile, slicing and program settings), later ones win.
    overrides
        ``{"section.field": value}`` over the files, e.g. ``{"slicing.layer_height": 0.3}``.
    robots
        1 or 2 (the seed's strategy).

    Returns
    -------
    dict
        The job record written to ``out/job.json``.
    """
    from cooprint.jobs import run as _run

    return _run(mesh, out, config=config, overrides=overrides, robots=robots, force=force, picture=picture)

__all__ = [
    "Chunk",
    "ChunkPlan",
    "ChunkSet",
    "ConfigError",
    "InfeasibleError",
    "JobSettings",
    "MeshError",
    "Plane",
    "RobotProfile",
    "Solid",
    "UserError",
    "cut_chunks",
    "load_mesh",
    "load_settings",
    "plan_chunks",
    "run",
    "slope_limits",
    "solid_from_trimesh",
    "__version__",
]
