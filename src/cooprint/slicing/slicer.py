"""Slice a watertight solid into layers of ordered tool paths (seed §4.2.1, Fig. 7).

Stages, each on whole layers:

1. layer planes: a first layer of its own height, then equal layers; each sliced at mid-height
   (manifold3d ``slice``: closed polygons with holes and islands nested);
2. regions: islands smaller than ``min_area`` dropped; N perimeters as inward offsets by the
   extrusion width; the rest is the fill area;
3. skins: the part of a layer's fill area not covered by all of the next ``top_layers`` (or the
   previous ``bottom_layers``) cross-sections is solid, as PrusaSlicer's top/bottom solid layers;
4. infill: solid skin hatched at the extrusion width, sparse infill by pattern and density;
5. order: islands nearest-first, perimeters with a seam, then skin and infill in scan order, with
   explicit travel paths between.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import manifold3d
import numpy as np

from cooprint.config import SlicingSettings
from cooprint.io.mesh import Solid
from cooprint.slicing.infill import hatch
from cooprint.slicing.paths import INFILL, PERIMETER_INNER, PERIMETER_OUTER, SKIN, TRAVEL, LayerPaths

CrossSection = manifold3d.CrossSection


@dataclass(frozen=True)
class SlicedModel:
    """All layers of one solid (a chunk or a whole model)."""

    layers: tuple[LayerPaths, ...]
    settings: SlicingSettings

    @property
    def n_layers(self) -> int:
        return len(self.layers)


def layer_tops(height: float, settings: SlicingSettings) -> np.ndarray:
    """(n,) top of every layer above the object's base, mm: the first layer, then equal layers
    until the object's height is covered."""
    first, h = settings.first_layer_height, settings.layer_height
    n = 1 + max(0, math.ceil((height - first) / h - 1e-9))
    return first + h * np.arange(n, dtype=np.float64)


def _islands(cs: CrossSection, min_area: float) -> list[CrossSection]:
    return [isl for isl in cs.decompose() if isl.area() >= min_area]


def _rings(cs: CrossSection) -> list[np.ndarray]:
    return [np.asarray(p, dtype=np.float64) for p in cs.to_polygons() if len(p) >= 3]


def _intersection(sections: list[CrossSection]) -> CrossSection:
    return CrossSection.batch_boolean(list(sections), manifold3d.OpType.Intersect)


def _seam_start(ring: np.ndarray, settings: SlicingSettings, here: np.ndarray, rear: np.ndarray) -> int:
    if settings.seam == "rear":
        return int(np.argmax(ring[:, 1]))
    target = here if settings.seam == "nearest" else rear
    return int(np.argmin(((ring - target) ** 2).sum(axis=1)))


def _closed(ring: np.ndarray, start: int) -> np.ndarray:
    r = np.roll(ring, -start, axis=0)
    return np.vstack([r, r[:1]])


def slice_solid(solid: Solid, settings: SlicingSettings,
                progress: Callable[[int, int], None] | None = None) -> SlicedModel:
    """Layers of ordered tool paths for a watertight solid.

    Returns
    -------
    SlicedModel
        One :class:`LayerPaths` per layer, bottom first; XY in the solid's frame, z absolute.
    """
    s = settings
    zmin, zmax = float(solid.bounds[0, 2]), float(solid.bounds[1, 2])
    tops = layer_tops(zmax - zmin, s)
    heights = np.diff(np.concatenate([[0.0], tops]))
    man = solid.manifold
    sections = [man.slice(zmin + t - hh / 2) for t, hh in zip(tops, heights)]
    n = len(tops)
    rear = np.array([solid.bounds[1, 0], solid.bounds[1, 1]])

    layers = []
    here = np.array([solid.bounds[0, 0], solid.bounds[0, 1]])
    for i in range(n):
        cs = sections[i]
        above = sections[i + 1:i + 1 + s.top_layers]
        below = sections[max(0, i - s.bottom_layers):i]
        covered_above = _intersection(above) if len(above) == s.top_layers and above else CrossSection()
        covered_below = _intersection(below) if len(below) == s.bottom_layers and below else CrossSection()
        paths: list[tuple[np.ndarray, int, float]] = []
        islands = _islands(cs, s.min_area)
        # islands nearest-first from where the nozzle is
        remaining = list(islands)
        while remaining:
            centres = np.array([np.mean(_rings(isl)[0], axis=0) if _rings(isl) else here for isl in remaining])
            k = int(np.argmin(((centres - here) ** 2).sum(axis=1)))
            isl = remaining.pop(k)
            here = _island_paths(isl, i, s, covered_above, covered_below, paths, here, rear)
        layers.append(_with_travel(zmin + float(tops[i]), float(heights[i]), paths))
        if progress:
            progress(i + 1, n)
    return SlicedModel(tuple(layers), s)


def _island_paths(isl: CrossSection, layer: int, s: SlicingSettings, covered_above: CrossSection,
                  covered_below: CrossSection, paths: list, here: np.ndarray, rear: np.ndarray) -> np.ndarray:
    """Append one island's perimeters, skin and infill to ``paths``; return the nozzle position."""
    w = s.extrusion_width
    loops = []
    for p in range(s.perimeters):
        ring_cs = isl.offset(-(w / 2 + p * w), manifold3d.JoinType.Miter)
        rings = _rings(ring_cs)
        if not rings:
            break
        loops.append((p, rings))
    order = loops if s.outer_perimeter_first else loops[::-1]
    for p, rings in order:
        role = PERIMETER_OUTER if p == 0 else PERIMETER_INNER
        for ring in rings:
            start = _seam_start(ring, s, here, rear)
            closed = _closed(ring, start)
            paths.append((closed, role, w))
            here = closed[-1]
    fill = isl.offset(-(s.perimeters * w) + 0.25 * w, manifold3d.JoinType.Miter) if s.perimeters else isl
    if fill.is_empty() or fill.area() < s.min_area:
        return here
    solid_part = (fill - covered_above) + (fill - covered_below)
    solid_part = solid_part ^ fill
    sparse = fill - solid_part
    angle = s.infill_angle_deg + 90.0 * (layer % 2)
    for seg in hatch(_rings(solid_part), w, angle) if not solid_part.is_empty() else []:
        paths.append((seg, SKIN, w))
    if s.infill_density > 0 and not sparse.is_empty() and sparse.area() >= s.min_area:
        rings = _rings(sparse)
        if s.infill_pattern == "rectilinear":
            dirs = [(angle, w / s.infill_density)]
        elif s.infill_pattern == "grid":
            dirs = [(s.infill_angle_deg, 2 * w / s.infill_density),
                    (s.infill_angle_deg + 90, 2 * w / s.infill_density)]
        else:  # triangles
            dirs = [(s.infill_angle_deg + d, 3 * w / s.infill_density) for d in (0.0, 60.0, 120.0)]
        for ang, spacing in dirs:
            for seg in hatch(rings, spacing, ang):
                paths.append((seg, INFILL, w))
    if paths:
        here = paths[-1][0][-1]
    return here


def _with_travel(z: float, height: float, paths: list[tuple[np.ndarray, int, float]]) -> LayerPaths:
    """Insert a travel path wherever one path does not start where the previous one ended."""
    out: list[tuple[np.ndarray, int, float]] = []
    prev = None
    for pts, role, width in paths:
        if prev is not None and np.linalg.norm(pts[0] - prev) > 1e-9:
            out.append((np.stack([prev, pts[0]]), TRAVEL, 0.0))
        out.append((pts, role, width))
        prev = pts[-1]
    return LayerPaths.build(z, height, out)
