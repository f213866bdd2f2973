"""Chunker (seed §3): sloped planes cut a solid into watertight chunks with a dependency graph.

``plan_chunks`` decides the geometry (slope limits, planes, counts) from the robot and the mesh;
``cut_chunks`` makes the cuts. Both are pure functions of frozen records.
"""

from cooprint.chunking.cut import Chunk, ChunkSet, cut_chunks, dependencies
from cooprint.chunking.planes import ChunkPlan, Feasibility, Plane, SlopeLimits, feasibility, plan_chunks, slope_limits

__all__ = ["Chunk", "ChunkPlan", "ChunkSet", "Feasibility", "Plane", "SlopeLimits", "cut_chunks", "dependencies",
           "feasibility", "plan_chunks", "slope_limits"]
