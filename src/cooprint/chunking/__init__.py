"""Chunker (seed §3): sloped planes cut a solid into watertight chunks with a dependency graph.

``plan_chunks`` decides the geometry (slope limits, planes, counts) from the robot and the mesh;
``cut_chunks`` makes the cuts. Both are pure functions of frozen records. The layouts (``seed2``,
``grid``: :data:`LAYOUTS`, :func:`layout_feasibility`) are the chunker's strategies, each a pure
function ``(solid, settings, robots, progress) -> ChunkSet``.
"""

from cooprint.chunking.cut import Chunk, ChunkSet, cut_chunks, dependencies
from cooprint.chunking.grid import ColumnPlan, GridPlan
from cooprint.chunking.layouts import LAYOUTS, get_layout, layout_feasibility
from cooprint.chunking.planes import ChunkPlan, Feasibility, Plane, SlopeLimits, feasibility, plan_chunks, slope_limits

__all__ = ["Chunk", "ChunkPlan", "ChunkSet", "ColumnPlan", "Feasibility", "GridPlan", "LAYOUTS", "Plane", "SlopeLimits",
           "cut_chunks", "dependencies", "feasibility", "get_layout", "layout_feasibility", "plan_chunks", "slope_limits"]
