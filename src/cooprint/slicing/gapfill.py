"""Lines along the middle of thin regions (issue 17): gap fill between perimeters and thin walls.

CONTRACT (lead, issue 17; the helper that owns this module replaces the body):

``medial_lines(region, min_width, max_width)`` -> list of ``(points (k, 2), width)``.
  ``region``: a CrossSection (mm) of thin parts (what is left between perimeters, or a wall too
  thin for a loop); the result follows its medial axis (the centres of its largest inscribed
  circles) where the local width (twice the distance to the boundary) is from ``min_width`` to
  ``max_width``; each piece is a polyline laid at one width, the local width averaged over the
  piece (a new piece where it changes by more than 10%), so that ``width x length`` covers the
  region's area (PrusaSlicer's gap fill: ThickPolylines of variable width). Pieces shorter than
  ``min_width`` are dropped. Whole-array work; no Python loop per point.
"""

from __future__ import annotations

import manifold3d
import numpy as np


def medial_lines(region: manifold3d.CrossSection, min_width: float, max_width: float
                 ) -> list[tuple[np.ndarray, float]]:
    """Centre lines of ``region`` with their widths (module docstring)."""
    return []
