"""Slice a watertight solid into layers of ordered tool paths (seed §4.2.1, Fig. 7).

Stages, each on whole layers:

1. layer planes: a first layer of its own height, then equal layers; each sliced at mid-height
   (:mod:`.sections`: closed polygons with holes and islands nested, a block of layers at once);
2. regions: islands smaller than ``min_area`` dropped; N perimeters, the outer one's centre half a
   width inside the outline and the next ones a line spacing (``extrusion_spacing``: lines touch
   with their rounded sides) further in; the rest is the fill area;
3. skins: top and bottom surfaces (what the next or previous section does not cover), grown 3 mm
   into the fill area, are solid on ``top_layers`` / ``bottom_layers`` layers, as PrusaSlicer's
   top/bottom solid layers; small sparse regions are solid too;
4. infill: solid skin hatched at the line spacing, sparse infill by pattern and density;
5. order: islands nearest-first, perimeters with a seam, then skin and infill in scan order, with
   explicit travel paths between.
"""

from __future__ import annotations

import math
import threading
import uuid
from collections import OrderedDict
from dataclasses import dataclass
from typing import Callable, Iterator, Mapping

import manifold3d
import numpy as np

from cooprint.config import SlicingSettings
from cooprint.executors import Executor, InlineExecutor, ProcessExecutor, default_workers
from cooprint.io.mesh import Solid
from cooprint.slicing.infill import hatch
from cooprint.slicing.sections import LayerSlicer
from cooprint.slicing.paths import (INFILL, PERIMETER_INNER, PERIMETER_OUTER, SKIN, TRAVEL, LayerPaths,
                                    extrusion_spacing)

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


def _union(sections: list[CrossSection]) -> CrossSection:
    if len(sections) == 1:
        return sections[0]
    return CrossSection.batch_boolean(list(sections), manifold3d.OpType.Add) if sections else CrossSection()


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
#: Top and bottom surfaces are grown by this much into the fill area before they become solid
#: skin, mm (PrusaSlicer's EXTERNAL_INFILL_MARGIN): skins anchor on the sparse infill.
EXTERNAL_MARGIN = 3.0
#: Each perimeter loop's region is opened by this many line widths: a part of it thinner than a
#: quarter line (the two sides of the loop nearer than that: material laid twice, what the
#: simulator's double-deposit looks for within an eighth) gets no loop; a wall wider than a line
#: and a quarter keeps its one loop.
LOOP_OPENING = 0.125
#: From this many blocks on, slice_solid uses worker processes by default.
PARALLEL_BLOCKS = 3


def slice_solid(solid: Solid, settings: SlicingSettings,
                progress: Callable[[int, int], None] | None = None, workers: int | None = None) -> SlicedModel:
    """Layers of ordered tool paths for a watertight solid (all of :func:`iter_layers`).

    Returns
    -------
    SlicedModel
        One :class:`LayerPaths` per layer, bottom first; XY in the solid's frame, z absolute.
    """
    return SlicedModel(tuple(iter_layers(solid, settings, progress, workers)), settings)


def layer_range(solid: Solid, settings: SlicingSettings, base: float | None = None) -> tuple[int, int]:
    """Indices ``(first, end)`` of the layers that :func:`iter_layers` gives for ``solid``: all of
    them from a base at its own bottom; from a lower ``base`` (a chunk in its object's layer
    grid), those from the first layer whose top is above the solid's bottom."""
    zmin, zmax = float(solid.bounds[0, 2]), float(solid.bounds[1, 2])
    z0 = zmin if base is None else min(base, zmin)
    tops = layer_tops(zmax - z0, settings)
    return int(np.searchsorted(tops, zmin - z0, side="right")), len(tops)


def layer_blocks(first: int, end: int) -> list[tuple[int, int]]:
    """The blocks ``(lo, hi)`` of ``BLOCK`` layers that layers ``first .. end - 1`` are sliced in
    (the last one shorter): fixed by the layer range alone, whatever runs them."""
    return [(lo, min(lo + BLOCK, end)) for lo in range(first, end, BLOCK)]


def iter_layers(solid: Solid, settings: SlicingSettings, progress: Callable[[int, int], None] | None = None,
                workers: int | None = None, base: float | None = None,
                executor: Executor | None = None) -> Iterator[LayerPaths]:
    """The layers of :func:`slice_solid`, bottom first, as they are ready: a consumer that writes
    them out (G-code) never holds the whole model.

    Parameters
    ----------
    base
        Bottom of the layer grid, mm (default: the solid's bottom). A chunk is sliced in its
        object's grid, so that the layers of neighbouring chunks line up; the layers below the
        chunk are left out (:func:`layer_range` gives the indices of those that are not).
    workers
        Processes to use when no ``executor`` is given (default: one per CPU, at most 4, from
        ``PARALLEL_BLOCKS`` blocks on); blocks of ``BLOCK`` layers are sliced independently, so
        1 and N workers give identical results.
    executor
        Where the blocks are sliced (:mod:`cooprint.executors`; default: local processes as
        ``workers`` says). The mesh prepared for slicing is the executor's ``shared`` data.
    progress
        Called with (layers done, layers in all) after every block.
    """
    first, n = layer_range(solid, settings, base)
    blocks = layer_blocks(first, n)
    job = _Job(solid.vertices, solid.faces, np.asarray(solid.bounds, dtype=np.float64), settings, base)
    del solid  # the job has what it needs: a caller that let go of the solid gets its memory back
    own = executor is None
    if own:
        if workers is None:  # a pool costs ~0.3 s to start: worth it from a few hundred layers on
            workers = default_workers() if len(blocks) >= PARALLEL_BLOCKS else 1
        executor = ProcessExecutor(workers, min_tasks=2) if workers > 1 else InlineExecutor()
    results = executor.map(_job_block, blocks, shared=job)
    del job  # the executor holds it while the blocks run
    done = 0
    try:
        for packed in results:
            layers = unpack_layers(packed)
            done += len(layers)
            if progress:
                progress(done, n - first)
            yield from layers
    finally:  # Ctrl-C, an error, or the consumer stopped early: the workers stop now
        results.close()
        if own:
            executor.close()


def slice_chunks(solids: Mapping[str, Solid], settings: SlicingSettings, base: float,
                 progress: Callable[[int, int], None] | None = None, executor: Executor | None = None
                 ) -> Iterator[tuple[str, list[tuple[int, LayerPaths]]]]:
    """Each chunk's layers in the object's layer grid (``base``: the object's bottom), chunk after
    chunk in the order of ``solids``: ``(chunk id, [(layer index, LayerPaths), ...])``, a chunk
    as soon as all its layers are sliced, so that a consumer that writes each one out and lets
    it go holds one chunk at a time (issue 15: memory bounded by the chunks in flight).

    The tasks are the blocks of ``BLOCK`` layers of every chunk (:func:`layer_blocks`), all
    chunks' in one stream, so that every worker is busy even on a job of one chunk and the next
    chunk starts while the last blocks of one finish. ``executor`` (:mod:`cooprint.executors`;
    None: local processes) gets the chunk meshes once as its ``shared`` data; each worker
    prepares a chunk's mesh for slicing once and keeps it for that chunk's next blocks; a block
    comes back as a few flat arrays (:class:`PackedLayers`). The layers are the same whatever
    the executor: the blocks are fixed, and each depends on its chunk and its layers alone.

    ``progress(layers done, layers in all)`` after every block."""
    ranges = {cid: layer_range(sol, settings, base) for cid, sol in solids.items()}
    blocks = {cid: layer_blocks(first, end) for cid, (first, end) in ranges.items()}
    total = sum(end - first for first, end in ranges.values())
    shared = _Chunks(uuid.uuid4().hex, {cid: (sol.vertices, sol.faces, np.asarray(sol.bounds, dtype=np.float64))
                                        for cid, sol in solids.items()}, settings, base)
    tasks = [(cid, lo, hi) for cid, bs in blocks.items() for lo, hi in bs]
    own = executor is None
    ex = ProcessExecutor() if own else executor
    results = ex.map(_chunk_block, tasks, shared=shared)
    done = 0
    try:
        for cid in solids:
            first = ranges[cid][0]
            layers: list[tuple[int, LayerPaths]] = []
            for _ in blocks[cid]:
                for layer in unpack_layers(next(results)):
                    layers.append((first + len(layers), layer))
                if progress:
                    progress(done + len(layers), total)
            done += len(layers)
            yield cid, layers
            del layers
    finally:  # Ctrl-C, an error, or the consumer stopped early: the workers stop now
        results.close()
        _forget(shared.token)
        if own:
            ex.close()


@dataclass(frozen=True)
class PackedLayers:
    """A block of layers as a few flat arrays (what a worker sends back): every layer's ``z``,
    ``height``, number of paths and of points, and all layers' points, path ends (each layer's
    ``offsets[1:]``), roles and widths concatenated. :func:`unpack_layers` gives back the
    :class:`LayerPaths`, equal array for array."""

    z: np.ndarray
    height: np.ndarray
    n_paths: np.ndarray
    n_points: np.ndarray
    points: np.ndarray
    ends: np.ndarray
    role: np.ndarray
    width: np.ndarray


def pack_layers(layers: list[LayerPaths]) -> PackedLayers:
    """:class:`PackedLayers` of ``layers``."""
    def cat(arrays: list[np.ndarray], empty: np.ndarray) -> np.ndarray:
        return np.concatenate(arrays) if arrays else empty

    return PackedLayers(
        np.array([lp.z for lp in layers], dtype=np.float64), np.array([lp.height for lp in layers], dtype=np.float64),
        np.array([len(lp.role) for lp in layers], dtype=np.int64),
        np.array([len(lp.points) for lp in layers], dtype=np.int64),
        cat([lp.points for lp in layers], np.zeros((0, 2))), cat([lp.offsets[1:] for lp in layers],
                                                                 np.zeros(0, np.int64)),
        cat([lp.role for lp in layers], np.zeros(0, np.uint8)), cat([lp.width for lp in layers], np.zeros(0)))


def unpack_layers(p: PackedLayers) -> list[LayerPaths]:
    """The :class:`LayerPaths` of a :class:`PackedLayers` (their points, roles and widths are
    views of its arrays)."""
    out = []
    a = b = 0
    for k in range(len(p.z)):
        m, q = int(p.n_paths[k]), int(p.n_points[k])
        offsets = np.concatenate([np.zeros(1, np.int64), p.ends[a:a + m]]).astype(np.int64, copy=False)
        out.append(LayerPaths(float(p.z[k]), float(p.height[k]), p.points[b:b + q], offsets, p.role[a:a + m],
                              p.width[a:a + m]))
        a, b = a + m, b + q
    return out


@dataclass(frozen=True)
class _Chunks:
    """What every task of :func:`slice_chunks` shares: the chunk meshes ``{id: (vertices,
    faces, bounds)}``, the settings and the layer grid's base; ``token`` names the job in the
    workers' caches."""

    token: str
    meshes: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
    settings: SlicingSettings
    base: float


#: Chunks prepared for slicing in this process (a worker's cache): ``(token, chunk id) -> _Job``,
#: the most recently used last. A worker slices a chunk's blocks one after another (the tasks
#: come chunk by chunk), so a few entries serve every block; a worker with several threads works
#: on as many chunks at once at most.
_PREPARED: OrderedDict[tuple[str, str], "_Job"] = OrderedDict()
_PREPARED_MAX = 4
_PREPARED_LOCK = threading.Lock()


def _prepared(chunks: _Chunks, cid: str) -> "_Job":
    """The chunk ``cid`` of ``chunks`` prepared for slicing, made once per process."""
    key = (chunks.token, cid)
    with _PREPARED_LOCK:
        job = _PREPARED.get(key)
        if job is not None:
            _PREPARED.move_to_end(key)
            return job
        vertices, faces, bounds = chunks.meshes[cid]
        job = _Job(vertices, faces, bounds, chunks.settings, chunks.base)
        _PREPARED[key] = job
        while len(_PREPARED) > _PREPARED_MAX:
            _PREPARED.popitem(last=False)
        return job


def _forget(token: str) -> None:
    """Drop this process's prepared chunks of a job (the inline executor's, at its end)."""
    with _PREPARED_LOCK:
        for key in [k for k in _PREPARED if k[0] == token]:
            del _PREPARED[key]


def _chunk_block(chunks: _Chunks, task: tuple[str, int, int]) -> PackedLayers:
    """A task of :func:`slice_chunks`: layers ``lo .. hi - 1`` of chunk ``cid``."""
    cid, lo, hi = task
    return pack_layers(_prepared(chunks, cid).block(lo, hi))


def _job_block(job: "_Job", block: tuple[int, int]) -> PackedLayers:
    """A task of :func:`iter_layers`: layers ``lo .. hi - 1`` of its prepared solid."""
    return pack_layers(job.block(*block))


class _Job:
    """Everything a block of layers needs: the mesh prepared for slicing, the layer planes."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, bounds: np.ndarray, settings: SlicingSettings,
                 base: float | None = None):
        self.s = settings
        self.slicer = LayerSlicer(vertices, faces)
        lo, hi = bounds
        self.zmin = float(lo[2]) if base is None else min(base, float(lo[2]))
        self.tops = layer_tops(float(hi[2]) - self.zmin, settings)
        self.heights = np.where(np.arange(len(self.tops)) == 0, settings.first_layer_height,
                                settings.layer_height)
        self.start = np.array([lo[0], lo[1]])
        self.rear = np.array([hi[0], hi[1]])

    def sections(self, lo: int, hi: int) -> dict[int, CrossSection]:
        """Sections of layers ``lo .. hi - 1`` at their mid-heights, simplified."""
        mids = self.zmin + self.tops[lo:hi] - self.heights[lo:hi] / 2
        return {lo + k: cs.simplify(SIMPLIFY) for k, cs in enumerate(self.slicer.sections(mids))}

    def fill_inset(self, i: int) -> float:
        """Distance from the outline to the edge of the fill area on layer ``i``, mm: the outer
        perimeter's centre at w/2, the next ones a line spacing further in each, the fill starting
        half a spacing inside the last one, overlapping it by a quarter spacing (PrusaSlicer's
        25% infill overlap)."""
        s = self.s
        if not s.perimeters:
            return 0.0
        sp = extrusion_spacing(s.extrusion_width, float(self.heights[i]))
        return s.extrusion_width / 2 + (s.perimeters - 0.75) * sp

    def block(self, lo: int, hi: int) -> list[LayerPaths]:
        """Layers ``lo .. hi - 1``, sliced with the neighbours their skins need.

        Solid skin (PrusaSlicer's top/bottom solid layers): a layer's top surface is the part of
        its section not covered by the next section, its bottom surface the part not on the
        previous one (both without slivers thinner than a tenth of the line width), clipped to the
        layer's fill area. Each is grown by ``EXTERNAL_MARGIN`` within that fill area, for anchoring, and made solid on
        ``top_layers`` layers down from a top surface and ``bottom_layers`` layers up from a
        bottom one.
        """
        s, n = self.s, len(self.tops)
        first, last = max(0, lo - s.bottom_layers), min(n, hi + s.top_layers)
        sections = self.sections(max(0, first - 1), min(n, last + 1))
        islands = {i: _islands(sections[i], s.min_area) for i in range(first, last)}
        kept = {i: _union(islands[i]) for i in islands}
        fills = {i: kept[i].offset(-self.fill_inset(i), manifold3d.JoinType.Miter) for i in kept}
        sliver = s.extrusion_width / 10

        def exposed(i: int, other: int) -> CrossSection:
            bare = kept[i] - sections[other] if other in sections else kept[i]
            bare = bare.offset(-sliver, manifold3d.JoinType.Miter).offset(sliver, manifold3d.JoinType.Miter)
            bare = bare ^ fills[i]  # a surface under the perimeters only is not grown
            if bare.is_empty():
                return bare
            return bare.offset(EXTERNAL_MARGIN, manifold3d.JoinType.Round) ^ fills[i]

        top = {i: exposed(i, i + 1) for i in range(lo, min(n, hi + s.top_layers - 1))}
        bottom = {i: exposed(i, i - 1) for i in range(max(0, lo - s.bottom_layers + 1), hi)}
        here = self.start
        out = []
        for i in range(lo, hi):
            shells = [top[k] for k in range(i, min(n, i + s.top_layers))]
            shells += [bottom[k] for k in range(max(0, i - s.bottom_layers + 1), i + 1)]
            solid = _union(shells) ^ fills[i] if shells else CrossSection()
            paths: list[tuple[np.ndarray, int, float]] = []
            remaining = list(islands[i])
            while remaining:  # islands nearest-first from where the nozzle is
                b = np.array([isl.bounds() for isl in remaining])  # xmin, ymin, xmax, ymax
                centres = (b[:, :2] + b[:, 2:]) / 2
                k = int(np.argmin(((centres - here) ** 2).sum(axis=1)))
                here = self.island_paths(remaining.pop(k), i, solid, paths, here)
            out.append(_with_travel(self.zmin + float(self.tops[i]), float(self.heights[i]), paths))
        return out

    def island_paths(self, isl: CrossSection, layer: int, solid: CrossSection,
                     paths: list, here: np.ndarray) -> np.ndarray:
        """Append one island's perimeters, skin and infill to ``paths``; return the nozzle position."""
        s = self.s
        w = s.extrusion_width
        sp = extrusion_spacing(w, float(self.heights[layer]))
        loops = []
        for p in range(s.perimeters):
            # each loop's region is opened (offset in by ``r`` more, then back out), so that a
            # sliver of it thinner than 2 r (between a hole and a chunk's cut face) gets no loop,
            # whose two sides would lay material twice (PrusaSlicer's perimeter generator opens
            # by half a spacing and gap-fills what that leaves; cooprint has no gap fill yet, so
            # it removes only the slivers whose sides nearly coincide)
            r = LOOP_OPENING * w
            rings = _rings(isl.offset(-(w / 2 + p * sp + r), manifold3d.JoinType.Miter)
                           .offset(r, manifold3d.JoinType.Miter))
            if not rings:
                break
            loops.append((p, rings))
        order = loops if s.outer_perimeter_first else loops[::-1]
        for p, rings in order:
            role = PERIMETER_OUTER if p == 0 else PERIMETER_INNER
            for ring in rings:
                start = _seam_start(ring, s, here, self.rear)
                closed = _closed(ring, start)
                paths.append((closed, role, w))
                here = closed[-1]
        fill = isl.offset(-self.fill_inset(layer), manifold3d.JoinType.Miter)
        if fill.is_empty() or fill.area() < s.min_area:
            return here
        solid_part, sparse = fill ^ solid, fill - solid
        small = [p for p in sparse.decompose() if p.area() < s.solid_infill_below_area]
        if small:  # PrusaSlicer's solid infill threshold: small sparse regions are filled solid
            solid_part = _union([solid_part, *small])
            sparse = sparse - _union(small)
        angle = s.infill_angle_deg + 90.0 * (layer % 2)
        for seg in hatch(_rings(solid_part), sp, angle) if not solid_part.is_empty() else []:
            paths.append((seg, SKIN, w))
        if s.infill_density > 0 and not sparse.is_empty() and sparse.area() >= s.min_area:
            rings = _rings(sparse)
            if s.infill_pattern == "rectilinear":
                dirs = [(angle, sp / s.infill_density)]
            elif s.infill_pattern == "grid":
                dirs = [(s.infill_angle_deg, 2 * sp / s.infill_density),
                        (s.infill_angle_deg + 90, 2 * sp / s.infill_density)]
            else:  # triangles
                dirs = [(s.infill_angle_deg + d, 3 * sp / s.infill_density) for d in (0.0, 60.0, 120.0)]
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
