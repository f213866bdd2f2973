"""Tool paths in the ragged layout (the seed's Fig. 12: robot -> chunk -> layer -> path).

A layer's paths share one flat point array; ``offsets`` delimit the paths, and every path has a
role, a width and a speed. Travel moves are paths of their own (role ``TRAVEL``), so the list is
the exact sequence the nozzle follows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Path roles.
PERIMETER_OUTER, PERIMETER_INNER, SKIN, INFILL, TRAVEL = range(5)
ROLE_NAMES = ("outer perimeter", "perimeter", "skin", "infill", "travel")


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
        One of ``PERIMETER_OUTER, PERIMETER_INNER, SKIN, INFILL, TRAVEL``.
    width : (m,) float64
        Extrusion width, mm (0 for travel).
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


def extrusion_width(area: np.ndarray | float, height: np.ndarray | float) -> np.ndarray | float:
    """The width whose :func:`extrusion_area` at ``height`` is ``area``, mm (its inverse)."""
    h = np.asarray(height)
    return (np.asarray(area) - np.pi * (h / 2) ** 2) / h + h


def extrusion_spacing(width: float, height: float) -> float:
    """Centre distance of two touching lines of that flow, mm: ``w - h (1 - pi / 4)``.

    Lines at this spacing overlap by their rounded sides, so that a row of them has the
    cross-section of a full rectangle: area / spacing = height.
    """
    return width - height * (1 - np.pi / 4)
