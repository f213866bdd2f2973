"""Infill lines anchored along the perimeters (issue 17, PrusaSlicer's ``infill_anchor`` and
``infill_anchor_max``).

CONTRACT (lead, issue 17; the helper that owns this module replaces the body):

``anchor_infill(lines, rings, anchor, anchor_max)`` -> list of (k, 2) polylines.
  ``lines``: the sparse infill lines of one region in print order (a list of (k, 2) polylines,
  each with both ends on the region's boundary, as :func:`~cooprint.slicing.infill.hatch` and
  :func:`~cooprint.slicing.patterns.gyroid` give them); ``rings``: the region's boundary (closed
  rings, outlines and holes). Consecutive lines whose ends lie on the same ring at most
  ``anchor_max`` apart along it are joined by that stretch of the ring into one polyline
  (PrusaSlicer's connect_infill); a line end left unjoined gets an anchor: the ring followed from
  it for at most ``anchor`` mm (not into another line's end). ``anchor = 0`` and
  ``anchor_max = 0`` return ``lines`` unchanged. No added stretch leaves the region.
"""

from __future__ import annotations

import numpy as np


def anchor_infill(lines: list[np.ndarray], rings: list[np.ndarray], anchor: float, anchor_max: float
                  ) -> list[np.ndarray]:
    """``lines`` joined and anchored along ``rings`` (module docstring)."""
    return list(lines)
