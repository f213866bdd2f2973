"""Tool paths in the ragged layout (the seed's Fig. 12: robot -> chunk -> layer -> path).

A layer's paths share one flat point array; ``offsets`` delimit the paths, and every path has a
role, a width and a speed. Travel moves are paths of their own (role ``TRAVEL``), so the list is
the exact sequence the nozzle follows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Path roles (PrusaSlicer's extrusion roles, issue 17). ``SKIN`` is internal solid infill (the
#: solid layers under a top and over a bottom, and small sparse regions filled solid), ``INFILL``
#: sparse infill, ``TOP_SKIN`` the top surface itself, ``BRIDGE`` solid infill laid over air or
#: over sparse infill (bridge flow and speed), ``GAP_FILL`` the lines that fill what is left
#: between perimeters and thin walls too narrow for a loop, ``OVERHANG`` a perimeter, or the part
#: of one, with nothing under it (bridge flow and speed). The numbers are those of the ``.coop``
#: files and the simulator's arrays: new roles are appended, never renumbered.
PERIMETER_OUTER, PERIMETER_INNER, SKIN, INFILL, TRAVEL, TOP_SKIN, BRIDGE, GAP_FILL, OVERHANG = range(9)
ROLE_NAMES = ("outer perimeter", "perimeter", "solid infill", "infill", "travel", "top solid infill", "bridge",
              "gap fill", "overhang perimeter")
#: Roles laid as a round thread (a bridge: nothing under it squashes the bead): their cross-section
#: is a circle of the path's width (:func:`flow_area`), PrusaSlicer's "thick bridges".
ROUND_ROLES = (BRIDGE, OVERHANG)
#: Roles that are perimeters (walls) and roles that are solid fill, for speeds and statistics.
PERIMETER_ROLES = (PERIMETER_OUTER, PERIMETER_INNER, OVERHANG)
SOLID_ROLES = (SKIN, TOP_SKIN, BRIDGE)


@dataclass(frozen=True)
class LayerPaths:
    """Every path of one layer, in print order.

    Attributes
    ----------
    z : float
        Top of the layer (the nozzle height while printing it), mm.
    height : float
        Layer thickness, mm.
    points : (n, 2) float64
        XY of all paths, concatenated, mm.
    offsets : (m + 1,) int64
        Path k is ``points[offsets[k]:offsets[k + 1]]``.
    role : (m,) uint8
        One of the roles above (``PERIMETER_OUTER`` ... ``OVERHANG``).
    width : (m,) float64
        Extrusion width, mm (0 for travel); for a round role (``ROUND_ROLES``) the thread's
        diameter.
    """

    z: float
    height: float
    points: np.ndarray
    offsets: np.ndarray
    role: np.ndarray
    width: np.ndarray

    def __len__(self) -> int:
        return len(self.role)

    def path(self, k: int) -> np.ndarray:
        return self.points[self.offsets[k]:self.offsets[k + 1]]

    def lengths(self) -> np.ndarray:
        """(m,) length of every path, mm."""
        seg = np.linalg.norm(np.diff(self.points, axis=0), axis=1)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        return cum[self.offsets[1:] - 1] - cum[self.offsets[:-1]]

    @staticmethod
    def build(z: float, height: float, paths: list[tuple[np.ndarray, int, float]]) -> "LayerPaths":
        """From ``[(points (k, 2), role, width), ...]`` in print order."""
        if not paths:
            return LayerPaths(z, height, np.zeros((0, 2)), np.zeros(1, dtype=np.int64),
                              np.zeros(0, dtype=np.uint8), np.zeros(0))
        pts = [np.asarray(p, dtype=np.float64) for p, _, _ in paths]
        offsets = np.concatenate([[0], np.cumsum([len(p) for p in pts])]).astype(np.int64)
        return LayerPaths(z, height, np.concatenate(pts), offsets,
                          np.array([r for _, r, _ in paths], dtype=np.uint8),
                          np.array([w for _, _, w in paths], dtype=np.float64))


def extrusion_area(width: np.ndarray | float, height: float) -> np.ndarray | float:
    """Cross-section of an extruded line, mm^2: a rectangle with semicircular sides (the flow
    model of Slic3r and PrusaSlicer), ``(w - h) h + pi (h / 2)^2``."""
    return (np.asarray(width) - height) * height + np.pi * (height / 2) ** 2


def flow_area(width: np.ndarray | float, height: np.ndarray | float, role: np.ndarray | int) -> np.ndarray:
    """Cross-section of the line each path lays, mm^2: :func:`extrusion_area` (a squashed bead),
    or for a round role (``ROUND_ROLES``: bridges and overhang perimeters, laid in the air) a
    circle of diameter ``width``, whatever the layer height (PrusaSlicer's thick bridges)."""
    w, h = np.asarray(width, dtype=np.float64), np.asarray(height, dtype=np.float64)
    round_ = np.isin(np.asarray(role), ROUND_ROLES)
    return np.where(round_, np.pi * (w / 2) ** 2, (w - h) * h + np.pi * (h / 2) ** 2)


def extrusion_width(area: np.ndarray | float, height: np.ndarray | float) -> np.ndarray | float:
    """The width whose :func:`extrusion_area` at ``height`` is ``area``, mm (its inverse)."""
    h = np.asarray(height)
    return (np.asarray(area) - np.pi * (h / 2) ** 2) / h + h


def round_width(area: np.ndarray | float) -> np.ndarray | float:
    """The diameter of the round thread (a ``ROUND_ROLES`` path's width) whose cross-section is
    ``area``, mm: :func:`flow_area`'s inverse for those roles, ``2 sqrt(area / pi)``."""
    return np.sqrt(np.asarray(area) / np.pi) * 2.0


def extrusion_spacing(width: float, height: float) -> float:
    """Centre distance of two touching lines of that flow, mm: ``w - h (1 - pi / 4)``.

    Lines at this spacing overlap by their rounded sides, so that a row of them has the
    cross-section of a full rectangle: area / spacing = height.
    """
    return width - height * (1 - np.pi / 4)
