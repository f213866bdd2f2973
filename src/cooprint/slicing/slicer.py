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
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from contextlib import nullcontext
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


#: Layers per unit of work. Fixed (not derived from the number of processes) so that the result
#: is the same whatever the parallelism: each block starts its travel from the same corner.
BLOCK = 48
#: Section outlines are simplified to this deviation, mm (PrusaSlicer's resolution is 0.0125).
SIMPLIFY = 0.0125
#: From this many blocks on, slice_solid uses worker processes by default.
PARALLEL_BLOCKS = 3


def slice_solid(solid: Solid, settings: SlicingSettings,
                progress: Callable[[int, int], None] | None = None, workers: int | None = None) -> SlicedModel:
    """Layers of ordered tool paths for a watertight solid.

    Parameters
    ----------
    workers
        Processes to use (default: one per CPU, at most 4); blocks of ``BLOCK`` layers are sliced
        independently, so 1 and N workers give identical results.

    Returns
    -------
    SlicedModel
        One :class:`LayerPaths` per layer, bottom first; XY in the solid's frame, z absolute.
    """
    zmin, zmax = float(solid.bounds[0, 2]), float(solid.bounds[1, 2])
    n = len(layer_tops(zmax - zmin, settings))
    blocks = [(lo, min(lo + BLOCK, n)) for lo in range(0, n, BLOCK)]
    if workers is None:  # a pool costs ~0.3 s to start: worth it from a few hundred layers on
        workers = min(os.cpu_count() or 1, 4) if len(blocks) >= PARALLEL_BLOCKS else 1
    workers = min(workers, len(blocks))
    global _WORKER
    _WORKER = _Job(solid, settings)  # forked workers share it (and its manifold) copy-on-write
    layers: list[LayerPaths] = []
    try:
        with (ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"))
              if workers > 1 else nullcontext()) as pool:
            for part in (pool.map if pool else map)(_work_block, blocks):
                layers += part
                if progress:
                    progress(len(layers), n)
    finally:
        _WORKER = None
    return SlicedModel(tuple(layers), settings)


class _Job:
    """Everything a block of layers needs: the solid as manifold3d, the layer planes."""

    def __init__(self, solid: Solid, settings: SlicingSettings):
        self.s = settings
        self.man = solid.manifold
        lo, hi = solid.bounds
        self.zmin = float(lo[2])
        self.tops = layer_tops(float(hi[2] - lo[2]), settings)
        self.heights = np.diff(np.concatenate([[0.0], self.tops]))
        self.start = np.array([lo[0], lo[1]])
        self.rear = np.array([hi[0], hi[1]])

    def section(self, i: int) -> CrossSection:
        cs = self.man.slice(self.zmin + float(self.tops[i] - self.heights[i] / 2))
        return cs.simplify(SIMPLIFY)

    def block(self, lo: int, hi: int) -> list[LayerPaths]:
        """Layers ``lo .. hi - 1``, sliced with the neighbours their skins need."""
        s, n = self.s, len(self.tops)
        first, last = max(0, lo - s.bottom_layers), min(n, hi + s.top_layers)
        sections = {i: self.section(i) for i in range(first, last)}
        here = self.start
        out = []
        for i in range(lo, hi):
            # sparse where the next top_layers and the previous bottom_layers sections all cover
            # (PrusaSlicer's rule); solid skin elsewhere: at the top, the bottom, and near both
            above = [sections[k] for k in range(i + 1, min(n, i + 1 + s.top_layers))]
            below = [sections[k] for k in range(max(0, i - s.bottom_layers), i)]
            full = len(above) == s.top_layers and len(below) == s.bottom_layers
            covered = _intersection(above + below) if full and above + below else None
            paths: list[tuple[np.ndarray, int, float]] = []
            remaining = _islands(sections[i], s.min_area)
            while remaining:  # islands nearest-first from where the nozzle is
                b = np.array([isl.bounds() for isl in remaining])  # xmin, ymin, xmax, ymax
                centres = (b[:, :2] + b[:, 2:]) / 2
                k = int(np.argmin(((centres - here) ** 2).sum(axis=1)))
                here = _island_paths(remaining.pop(k), i, s, covered, paths, here, self.rear)
            out.append(_with_travel(self.zmin + float(self.tops[i]), float(self.heights[i]), paths))
        return out


_WORKER: _Job | None = None


def _work_block(block: tuple[int, int]) -> list[LayerPaths]:
    assert _WORKER is not None
    return _WORKER.block(*block)


def _island_paths(isl: CrossSection, layer: int, s: SlicingSettings, covered: CrossSection | None,
                  paths: list, here: np.ndarray, rear: np.ndarray) -> np.ndarray:
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
    if covered is None or covered.is_empty():
        solid_part, sparse = fill, CrossSection()
    else:
        solid_part, sparse = fill - covered, fill ^ covered
        small = [p for p in sparse.decompose() if p.area() < s.solid_infill_below_area]
        if small:  # PrusaSlicer's solid infill threshold: small sparse regions are filled solid
            solid_part = CrossSection.batch_boolean([solid_part, *small], manifold3d.OpType.Add)
            sparse = sparse - CrossSection.batch_boolean(small, manifold3d.OpType.Add)
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
