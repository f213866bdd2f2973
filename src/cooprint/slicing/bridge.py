"""Bridge direction (issue 17): the angle at which a bridge's lines are best anchored, as
PrusaSlicer's BridgeDetector chooses it.

CONTRACT (lead, issue 17; the helper that owns this module replaces the body):

``bridge_angle(area, anchors, spacing)`` -> degrees or ``None``.
  ``area``: the bridge region (a CrossSection, mm); ``anchors``: where its lines may rest (the
  lower layer's material under and around it, a CrossSection); ``spacing``: line spacing, mm.
  Candidate directions every 5 degrees plus the directions of the bridge outline's edges; for
  each, lines across ``area`` at ``spacing``; a line counts when both of its ends lie on
  ``anchors``; the best direction has the most anchored length (ties: the shortest longest
  line). ``None`` when no line is anchored at both ends (a cantilever: the caller uses its
  default angle).
"""

from __future__ import annotations

import manifold3d


def bridge_angle(area: manifold3d.CrossSection, anchors: manifold3d.CrossSection, spacing: float) -> float | None:
    """Direction of ``area``'s bridge lines, degrees in [0, 180), or ``None`` (module docstring)."""
    return None
