"""cooprint: cooperative 3D printing for fleets of mobile FDM printers.

Pipeline (one package per stage, data flowing one way)::

    mesh --io.load_mesh--> Solid --chunking.cut_chunks--> ChunkSet --> (scheduler, slicer, program,
    simulator: later stages)

The public API is re-exported here.
"""

from __future__ import annotations

from cooprint.chunking import ChunkPlan, ChunkSet, Chunk, Plane, cut_chunks, plan_chunks, slope_limits
from cooprint.config import JobSettings, RobotProfile, load_settings
from cooprint.errors import ConfigError, InfeasibleError, MeshError, UserError
from cooprint.io.mesh import Solid, load_mesh, solid_from_trimesh

__version__ = "0.1.0"

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
    "slope_limits",
    "solid_from_trimesh",
    "__version__",
]
