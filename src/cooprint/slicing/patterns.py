"""Curved infill patterns and polyline clipping (issue 17).

CONTRACT (lead, issue 17; the helper that owns this module replaces the bodies):

``clip_polylines(polylines, rings)`` -> list of (k, 2) arrays: the parts of open polylines
  inside the region of closed ``rings`` (even-odd, as :func:`cooprint.slicing.infill.hatch`),
  each part a polyline with its ends on the boundary; whole-array work (numba or numpy), no
  Python loop per point.
``gyroid(rings, spacing, z, angle_deg)`` -> list of (k, 2) arrays: PrusaSlicer's gyroid pattern
  (FillGyroid) at height ``z``, line distance ``spacing`` (= line spacing / density), rotated by
  ``angle_deg``, clipped to ``rings``, on a global grid so that layers and chunks line up, in an
  order that keeps travel short (nearest next, each polyline possibly reversed).
"""

from __future__ import annotations

import numpy as np


def clip_polylines(polylines: list[np.ndarray], rings: list[np.ndarray]) -> list[np.ndarray]:
    """The parts of ``polylines`` inside ``rings`` (module docstring)."""
    raise NotImplementedError("clip_polylines: issue 17, helper")


def gyroid(rings: list[np.ndarray], spacing: float, z: float, angle_deg: float = 0.0) -> list[np.ndarray]:
    """PrusaSlicer's gyroid infill of the region ``rings`` at height ``z`` (module docstring)."""
    raise NotImplementedError("gyroid: issue 17, helper")
