"""Slice a watertight solid into layers of ordered tool paths (seed §4.2.1, Fig. 7), with
PrusaSlicer 2.5's regions (issue 17).

Stages, each on whole layers (manifold3d CrossSection booleans and offsets, no Python per point):

1. layer planes: a first layer of its own height, then equal layers while their middle is under
   the top (:func:`layer_tops`); each sliced at mid-height, a plane through a horizontal face
   giving the section under it (:mod:`.sections`: closed polygons with holes and islands
   nested, a block of layers at once);
2. perimeters (PrusaSlicer's classic generator, per-role widths): islands smaller than
   ``min_area`` dropped; the outer loop half an external width inside the outline, the next
   ones a spacing further in, every loop's region opened by 0.6 x half a spacing; what that
   leaves between the loops is gap fill, a wall too thin for the outer loop a thin wall (both
   along :func:`~cooprint.slicing.gapfill.medial_lines`); loop parts over air are overhang
   perimeters; the fill area half a spacing inside the innermost loop, without the gaps;
3. surfaces (detect_surfaces_type, process_external_surfaces): a layer's top is what the next
   section does not cover (top solid infill), its bottom what the previous one does not (a
   bridge over air, in the direction :func:`~cooprint.slicing.bridge.bridge_angle` finds; solid
   on the first layer), both grown 3 mm into the fill area; sparse regions below
   ``solid_infill_below_area`` are solid;
4. shells (discover_horizontal_shells, or discover_vertical_shells with
   ``ensure_vertical_shell_thickness``): the top and bottom surfaces make the internal area of
   ``top_layers - 1`` layers under / ``bottom_layers - 1`` over them solid, narrow parts grown;
   solid over sparse infill is a bridge (bridge_over_infill);
5. fill: solid lines at a spacing adjusted to fill each region evenly, bridges as round
   threads, sparse infill by pattern (hatch, or :func:`~cooprint.slicing.patterns.gyroid`)
   anchored along the perimeters (:func:`~cooprint.slicing.anchor.join_infill`);
6. order: islands nearest-first, perimeters with a seam, gap fill, then the fills, with
   explicit travel paths between.

A block of ``BLOCK`` layers is sliced with the neighbours its surfaces need, so that every block
is independent of the others and of who slices it.
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
from cooprint.slicing.anchor import join_packed, unpacked
from cooprint.slicing.bridge import bridge_angle
from cooprint.slicing.gapfill import medial_lines, single_bead
from cooprint.slicing.infill import hatch, hatch_flat
from cooprint.slicing.paths import (BRIDGE, GAP_FILL, INFILL, OVERHANG, PERIMETER_INNER, PERIMETER_OUTER, SKIN,
                                    TOP_SKIN, TRAVEL, LayerPaths, extrusion_spacing)
from cooprint.slicing.patterns import CORRECTION_DEG, clip_polylines, gyroid
from cooprint.slicing import polysplit
from cooprint.slicing.polysplit import split_by_region
from cooprint.slicing.sections import LayerSlicer

CrossSection = manifold3d.CrossSection


@dataclass(frozen=True)
class SlicedModel:
    """All layers of one solid (a chunk or a whole model)."""

    layers: tuple[LayerPaths, ...]
    settings: SlicingSettings

    @property
    def n_layers(self) -> int:
        return len(self.layers)


#: Layers are sliced this far under their middle, mm: a plane through a horizontal face then gives
#: the section under the face, as PrusaSlicer's mesh slicer does (a triangle owns its top edge, not
#: its bottom one), whatever the rounding of the layer heights; far below any printed detail.
BELOW_MIDDLE = 1e-6


def layer_tops(height: float, settings: SlicingSettings) -> np.ndarray:
    """(n,) top of every layer above the object's base, mm: the first layer, then equal layers
    while a layer's slice plane (its middle, ``BELOW_MIDDLE`` under) is under the object's top,
    as PrusaSlicer's generate_object_layers. The last layer may reach up to half a layer above
    the top (an object 10.1 mm tall in 0.2 mm layers has 51, the last sliced just under its top
    face), and a top less than half a layer above the last layer is not printed (10.05 mm: 50)."""
    first, h = settings.first_layer_height, settings.layer_height
    n = 1 + max(0, math.ceil((height - first - h / 2 + BELOW_MIDDLE) / h))
    return first + h * np.arange(n, dtype=np.float64)


def _islands(cs: CrossSection, min_area: float) -> list[CrossSection]:
    return [isl for isl in cs.decompose() if isl.area() >= min_area]


def _rings(cs: CrossSection) -> list[np.ndarray]:
    return [np.asarray(p, dtype=np.float64) for p in cs.to_polygons() if len(p) >= 3]


def _equal(a: CrossSection, b: CrossSection) -> bool:
    """Whether ``a`` and ``b`` have the same contours, vertex for vertex."""
    pa, pb = a.to_polygons(), b.to_polygons()
    return len(pa) == len(pb) and all(np.array_equal(x, y) for x, y in zip(pa, pb))


def _union(sections: list[CrossSection]) -> CrossSection:
    if len(sections) == 1:
        return sections[0]
    return CrossSection.batch_boolean(list(sections), manifold3d.OpType.Add) if sections else CrossSection()


def _seam_start(ring: np.ndarray, settings: SlicingSettings, here: np.ndarray, rear: np.ndarray) -> int:
    if settings.seam == "rear":
        return int(np.argmax(ring[:, 1]))
    d = ring - (here if settings.seam == "nearest" else rear)
    d *= d  # squared distances by columns: a third of the time of a row sum on a long ring
    return int(np.argmin(d[:, 0] + d[:, 1]))


def _closed(ring: np.ndarray, start: int) -> np.ndarray:
    return np.concatenate([ring[start:], ring[:start + 1]])


#: Layers per unit of work. Fixed (not derived from the number of processes) so that the result
#: is the same whatever the parallelism: each block starts its travel from the same corner.
#: A block also slices the ~10 neighbouring layers its surfaces need, so larger blocks redo less;
#: 64 gives benchy (240 layers) 4 blocks and the 500-layer large part 8: whole rounds on 2 workers.
BLOCK = 64
#: Section outlines are simplified to this deviation, mm (PrusaSlicer's resolution is 0.0125).
SIMPLIFY = 0.0125
#: Section points within this of the segment between their neighbours are dropped before the
#: section is built, mm (:meth:`~cooprint.slicing.sections.LayerSlicer.rings`; at most 1,024 in a
#: row, so the dropped ones stay within 1 um of the result, a tenth of ``SIMPLIFY``). A section of
#: a finely tessellated mesh has a vertex wherever an edge of a flat face crosses the plane (20,000
#: per layer of the large benchmark part, 360 after simplifying): dropping those first makes
#: building and simplifying the cross-section 5x cheaper there, for the same simplified outline
#: (same vertex count and area). A larger value drops more (an STL's float32 noise is 1.5e-5 mm at
#: 250 mm) but moves benchy's bridges by 1%: the simplification is sensitive to the points it is given.
COLLINEAR = 1e-6
#: Top and bottom surfaces are grown by this much into the fill area before they become solid
#: skin, mm (PrusaSlicer's EXTERNAL_INFILL_MARGIN): skins anchor on the sparse infill.
EXTERNAL_MARGIN = 3.0
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
    if settings.overhangs:
        polysplit.warm()  # before the workers fork: they inherit the compiled kernels
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
                 progress: Callable[[int, int], None] | None = None, executor: Executor | None = None,
                 context: Solid | None = None) -> Iterator[tuple[str, list[tuple[int, LayerPaths]]]]:
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

    ``context``: the object the chunks were cut from (issue 17: the same findings sliced alone
    and planned). A chunk's surfaces then come from the object's sections, as ``cooprint
    slice`` of the whole part sees them: what is top or bottom, which bottom is a bridge and
    where it is anchored (the bridge area and its anchors across the cut), which perimeters
    overhang, and which layers the horizontal shells make solid; the chunk's own section still
    gives its islands, perimeters and fill area, so that everything it prints stays inside it.
    Without it, each chunk is sliced as a part of its own.

    ``progress(layers done, layers in all)`` after every block."""
    ranges = {cid: layer_range(sol, settings, base) for cid, sol in solids.items()}
    blocks = {cid: layer_blocks(first, end) for cid, (first, end) in ranges.items()}
    total = sum(end - first for first, end in ranges.values())
    shared = _Chunks(uuid.uuid4().hex, {cid: (sol.vertices, sol.faces, np.asarray(sol.bounds, dtype=np.float64))
                                        for cid, sol in solids.items()}, settings, base,
                     None if context is None else (context.vertices, context.faces,
                                                   np.asarray(context.bounds, dtype=np.float64)))
    tasks = [(cid, lo, hi) for cid, bs in blocks.items() for lo, hi in bs]
    own = executor is None
    ex = ProcessExecutor() if own else executor
    if settings.overhangs:
        polysplit.warm()  # before the workers fork: they inherit the compiled kernels
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
    faces, bounds)}``, the settings, the layer grid's base and the object's mesh (``context``,
    or None); ``token`` names the job in the workers' caches."""

    token: str
    meshes: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
    settings: SlicingSettings
    base: float
    context: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None


#: Chunks prepared for slicing in this process (a worker's cache): ``(token, chunk id) -> _Job``,
#: the most recently used last. A worker slices a chunk's blocks one after another (the tasks
#: come chunk by chunk), so a few entries serve every block; a worker with several threads works
#: on as many chunks at once at most.
_PREPARED: OrderedDict[tuple[str, str], "_Job"] = OrderedDict()
_PREPARED_MAX = 4
_PREPARED_LOCK = threading.Lock()
#: The object's mesh prepared for slicing in this process, for the chunks' surfaces: ``(token,
#: LayerSlicer)`` of the last job (one object per job).
_CONTEXT: list = [None, None]


def _prepared(chunks: _Chunks, cid: str) -> "_Job":
    """The chunk ``cid`` of ``chunks`` prepared for slicing, made once per process."""
    key = (chunks.token, cid)
    with _PREPARED_LOCK:
        job = _PREPARED.get(key)
        if job is not None:
            _PREPARED.move_to_end(key)
            return job
        vertices, faces, bounds = chunks.meshes[cid]
        context = None
        if chunks.context is not None:
            if _CONTEXT[0] != chunks.token:
                _CONTEXT[:] = [chunks.token, LayerSlicer(chunks.context[0], chunks.context[1])]
            context = (_CONTEXT[1], chunks.context[2])
        job = _Job(vertices, faces, bounds, chunks.settings, chunks.base, context)
        _PREPARED[key] = job
        while len(_PREPARED) > _PREPARED_MAX:
            _PREPARED.popitem(last=False)
        return job


def _forget(token: str) -> None:
    """Drop this process's prepared chunks of a job (the inline executor's, at its end)."""
    with _PREPARED_LOCK:
        for key in [k for k in _PREPARED if k[0] == token]:
            del _PREPARED[key]
        if _CONTEXT[0] == token:
            _CONTEXT[:] = [None, None]


def _chunk_block(chunks: _Chunks, task: tuple[str, int, int]) -> PackedLayers:
    """A task of :func:`slice_chunks`: layers ``lo .. hi - 1`` of chunk ``cid``."""
    cid, lo, hi = task
    return pack_layers(_prepared(chunks, cid).block(lo, hi))


def _job_block(job: "_Job", block: tuple[int, int]) -> PackedLayers:
    """A task of :func:`iter_layers`: layers ``lo .. hi - 1`` of its prepared solid."""
    return pack_layers(job.block(*block))


@dataclass(frozen=True)
class _Flows:
    """Extrusion widths of one layer's roles, mm (``SlicingSettings.role_width``), and the layer
    height: the spacing of touching lines of each is :func:`extrusion_spacing`."""

    ext: float
    per: float
    solid: float
    top: float
    height: float

    def spacing(self, width: float) -> float:
        return extrusion_spacing(width, self.height)


@dataclass
class _Island:
    """One island's perimeter geometry (PrusaSlicer's classic perimeter generator): the loops
    ``[(depth, rings)]`` (depth 0 the outer one), the fill area inside them, and for the layers
    that are printed, what is left for gap fill between the loops and for thin walls."""

    cs: CrossSection
    loops: list[tuple[int, list[np.ndarray]]]
    fill: CrossSection
    gaps: CrossSection | None = None
    thin: CrossSection | None = None


@dataclass
class _Surfaces:
    """A layer's surfaces as PrusaSlicer's detect_surfaces_type and process_external_surfaces
    type them.

    ``top`` / ``bottom``: the parts of the section not covered by the next / previous section
    (the perimeter zone included); ``top_g``, ``bottom_g`` (the first layer's) and ``bridge_g``
    (a bottom over air on a higher layer): those parts of the fill area grown by
    ``EXTERNAL_MARGIN`` within it; ``bridge_seed``: the bridges before growing (where their
    direction is found); ``internal``: the rest of the fill area; ``small``: its parts below
    ``solid_infill_below_area`` (solid)."""

    islands: list[_Island]
    fill: CrossSection
    top: CrossSection
    bottom: CrossSection
    top_g: CrossSection
    bottom_g: CrossSection
    bridge_g: CrossSection
    bridge_seed: CrossSection
    internal: CrossSection
    small: CrossSection

    def source(self, top: bool) -> CrossSection:
        """What this layer's top (``top``) or bottom surfaces make solid on its neighbours:
        the exposed part of the whole section and the grown fill surfaces (PrusaSlicer's
        discover_horizontal_shells takes both)."""
        return _union([self.top, self.top_g] if top else [self.bottom, self.bottom_g, self.bridge_g])


#: PrusaSlicer's INSET_OVERLAP_TOLERANCE: a perimeter loop's region is opened by (1 - this) x half
#: a line spacing (parts narrower than that get no loop but gap fill), and the fill area by as
#: much of the solid infill spacing.
INSET_OVERLAP = 0.4
#: Gap fill is laid in gaps from this many perimeter widths (x (1 - INSET_OVERLAP)) to two
#: perimeter spacings wide (PrusaSlicer's classic gap fill); the gaps are not fill area.
GAP_MIN = 0.2
#: Overlap of the fill area with the innermost loop, as a fraction of half their spacings
#: (PrusaSlicer's infill_overlap, 25%).
INFILL_OVERLAP = 0.25
#: Gap between the round threads of a bridge, mm: line spacing = diameter + this (PrusaSlicer's
#: BRIDGE_EXTRA_SPACING of thick bridges).
BRIDGE_GAP = 0.05
#: A solid region propagated from a top or bottom surface that is narrower than twice this many
#: solid line widths is grown by as much within the neighbour's internal area (PrusaSlicer's
#: "too narrow" rule in discover_horizontal_shells: solid shells that would collapse).
NARROW_WIDTHS = 3.0
#: Internal solid over sparse infill is a bridge where it is wider than twice this many bridge
#: widths (PrusaSlicer's bridge_over_infill opening).
BRIDGE_OVER_INFILL_WIDTHS = 3.0
#: Solid infill spacing is widened to fill a region with a whole number of lines, at most by this
#: factor (PrusaSlicer's _adjust_solid_spacing).
SOLID_SPACING_MAX = 1.2

_MITER = manifold3d.JoinType.Miter
_SQUARE = manifold3d.JoinType.Square


def _opening(cs: CrossSection, r: float) -> CrossSection:
    """``cs`` without its parts narrower than ``2 r``."""
    core = cs.offset(-r, _MITER)
    return core if core.is_empty() else core.offset(r, _MITER)


def _apart(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> bool:
    """Whether bounding boxes ``a`` and ``b`` (xmin, ymin, xmax, ymax) are apart: the
    cross-sections they bound have nothing in common (a boolean spared)."""
    return a[0] > b[2] or b[0] > a[2] or a[1] > b[3] or b[1] > a[3]


#: A thin wall's end this close to another chunk's material (mm) lies on a cut between them;
#: slivers of the object's section beside a chunk's narrower than twice this are no chunk
#: (the two sections are simplified apart, by up to ``SIMPLIFY`` each).
CUT_TOL = 0.05


def _off_cuts(lines: list[tuple[np.ndarray, float]], whole: CrossSection, own: CrossSection, bead: float,
              min_length: float) -> list[tuple[np.ndarray, float]]:
    """A chunk's thin-wall lines (``medial_lines``, widths less ``bead``) with every free end
    that :func:`~cooprint.slicing.gapfill.medial_lines` carried to a cut (its end within
    ``CUT_TOL`` of the object's section ``whole`` outside the island ``own``: another chunk's
    material) pulled back along the line by half its bead, so that the bead ends at the cut;
    lines left shorter than ``min_length`` are dropped. Why: an end carried to the part's outline
    lays its half bead beyond it, as PrusaSlicer's; beyond a cut it is material in the
    neighbouring chunk. Where the cut slopes over the earlier chunk, that chunk's layers above
    the later one's then stick out over it, and the later chunk's nozzle runs into them (the
    bench's slab for one robot: its centre row is a wedge whose top layers are thin walls, cut
    across between its two columns; the second column's nozzle ran through 11 cells of the
    first's layer ends)."""
    if not lines:
        return lines
    lo = np.min([p.min(axis=0) for p, _ in lines], axis=0) - 1.0
    hi = np.max([p.max(axis=0) for p, _ in lines], axis=0) + 1.0
    box = CrossSection.square((float(hi[0] - lo[0]), float(hi[1] - lo[1]))).translate((float(lo[0]), float(lo[1])))
    cut = _opening((whole ^ box) - own, CUT_TOL)
    if cut.is_empty():
        return lines
    probe = CrossSection.square((2 * CUT_TOL, 2 * CUT_TOL), center=True)

    def on_cut(p: np.ndarray) -> bool:
        return not (cut ^ probe.translate((float(p[0]), float(p[1])))).is_empty()

    out = []
    for pts, width in lines:
        if np.array_equal(pts[0], pts[-1]):  # a closed loop has no end
            out.append((pts, width))
            continue
        half = (width + bead) / 2
        a, b = (half if on_cut(pts[0]) else 0.0), (half if on_cut(pts[-1]) else 0.0)
        if a == b == 0.0:
            out.append((pts, width))
            continue
        s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(pts, axis=0).T))]  # arc length at each point
        if s[-1] - a - b < min_length:
            continue
        t = np.r_[a, s[(s > a) & (s < s[-1] - b)], s[-1] - b]
        out.append((np.column_stack([np.interp(t, s, pts[:, 0]), np.interp(t, s, pts[:, 1])]), width))
    return out


def _nonempty(cs: CrossSection | None) -> bool:
    return cs is not None and not cs.is_empty()


#: A chunk's context (the object's sections, for its tops, bottoms and shells) is clipped to the
#: chunk's footprint grown by this much, mm, so that the booleans on a big object's layers stay
#: local (a chunk's bridges look at the whole object's layers: a bridge may be long).
CONTEXT_MARGIN = 25.0


class _Job:
    """Everything a block of layers needs: the mesh prepared for slicing, the layer planes, and
    for a chunk of an object, the object's mesh (``context``: its LayerSlicer and bounds), whose
    sections give the chunk's surfaces (:func:`slice_chunks`); its layer planes are then the
    object's."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, bounds: np.ndarray, settings: SlicingSettings,
                 base: float | None = None, context: tuple[LayerSlicer, np.ndarray] | None = None):
        self.s = settings
        self.slicer = LayerSlicer(vertices, faces)
        lo, hi = bounds
        self.zmin = float(lo[2]) if base is None else min(base, float(lo[2]))
        self.context = None if context is None else context[0]
        self.clip = None
        z_top = float(hi[2])
        if context is not None:  # the object's layers: a chunk's surfaces look at its neighbours
            z_top = max(z_top, float(context[1][1][2]))
            m = CONTEXT_MARGIN
            self.clip = CrossSection.square((float(hi[0] - lo[0]) + 2 * m, float(hi[1] - lo[1]) + 2 * m)
                                            ).translate((float(lo[0]) - m, float(lo[1]) - m))
        self.tops = layer_tops(z_top - self.zmin, settings)
        self.heights = np.where(np.arange(len(self.tops)) == 0, settings.first_layer_height,
                                settings.layer_height)
        self.start = np.array([lo[0], lo[1]])
        self.rear = np.array([hi[0], hi[1]])
        s = settings
        self.bridge_w = s.nozzle_diameter * math.sqrt(s.bridge_flow_ratio)
        self.sparse_spacing = extrusion_spacing(s.role_width("infill"), s.layer_height)
        self._repeats: OrderedDict = OrderedDict()

    def sections(self, layers: range | list[int], context: bool = False, clip: bool = True) -> dict[int, CrossSection]:
        """Sections of ``layers`` (ascending) at their mid-heights (``BELOW_MIDDLE`` under),
        simplified (``context``: the object's, clipped to the chunk's surroundings unless not
        ``clip``). Each layer's section depends on that layer alone, whichever others are sliced
        with it. Equal sections (vertex for vertex: a prismatic part's layers) are one object, so
        that :meth:`block` works on each of them once."""
        idx = np.asarray(layers, dtype=np.int64)
        mids = self.zmin + self.tops[idx] - self.heights[idx] / 2 - BELOW_MIDDLE
        out = {}
        seen: dict[tuple[int, float], list[tuple[CrossSection, CrossSection]]] = {}
        for i, rings in zip(idx.tolist(), (self.context if context else self.slicer).rings(mids, COLLINEAR)):
            cs = CrossSection(rings, manifold3d.FillRule.Positive).simplify(SIMPLIFY) if rings else CrossSection()
            same = seen.setdefault((cs.num_vert(), cs.area()), [])
            got = next((o for c, o in same if _equal(c, cs)), None)
            if got is None:
                got = cs ^ self.clip if context and clip and not cs.is_empty() else cs
                same.append((cs, got))
            out[i] = got
        return out

    def object_sections(self, layers: range | list[int], clip: bool = True) -> dict[int, CrossSection]:
        """A chunk's context: the object's :meth:`sections` of ``layers`` without their islands
        under ``min_area`` (clipped to the chunk's surroundings unless not ``clip``)."""
        out, by_cs = {}, {}
        for i, cs in self.sections(layers, True, clip).items():
            if id(cs) not in by_cs:  # equal sections are one object, and so are their results
                by_cs[id(cs)] = _union(_islands(cs, self.s.min_area))
            out[i] = by_cs[id(cs)]
        return out

    def flows(self, i: int) -> _Flows:
        s, first = self.s, i == 0
        return _Flows(s.role_width("external_perimeter", first), s.role_width("perimeter", first),
                      s.role_width("solid_infill", first), s.role_width("top_infill", first), float(self.heights[i]))

    def shells(self, isl: CrossSection, i: int, printed: bool) -> _Island:
        """PrusaSlicer's classic perimeters of one island on layer ``i``: the outer loop's centre
        half an external width inside the outline, the next one the mean of the two spacings
        further in, the others a perimeter spacing each; every loop's region opened by
        ``INSET_OVERLAP`` of half a spacing (with thin walls on), what that leaves between two
        loops is gap, and a wall too thin for the outer loop is a thin wall. With gap fill on, an
        island where one more loop would not fit has no fill area (its middle is gap). The fill
        area: half a spacing inside the innermost loop, overlapping it by ``INFILL_OVERLAP``,
        opened by the solid infill spacing. ``printed``: also the gap and thin-wall regions."""
        s, f = self.s, self.flows(i)
        if s.perimeters == 0:
            return _Island(isl, [], isl)
        ext_sp, per_sp, sol_sp = f.spacing(f.ext), f.spacing(f.per), f.spacing(f.solid)
        ext_sp2 = (ext_sp + per_sp) / 2
        min_sp, ext_min = per_sp * (1 - INSET_OVERLAP), ext_sp * (1 - INSET_OVERLAP)
        with_gaps = s.gap_fill and s.infill_density > 0
        out = _Island(isl, [], CrossSection())
        gaps = []
        last = isl
        for k in range(s.perimeters + 1):
            # a loop's region: ``last`` offset in by d, opened by a (one offset in by d + a, one
            # back out by a); the gap: what half a spacing inside ``last`` the loop's band leaves
            if k == 0:
                d, a = f.ext / 2, (ext_min / 2 if s.thin_walls else 0.0)
            else:
                d, a = (ext_sp2 if k == 1 else per_sp), (min_sp / 2 if s.thin_walls else 0.0)
            shrunk = last.offset(-(d + a), _MITER)
            if k > 0 and with_gaps:
                # a gap only where the loop's band does not reach back to ``last`` (one offset
                # tells: the common case); there, half a spacing inside ``last`` less the band
                cover = shrunk.offset(a + d, _MITER) if not shrunk.is_empty() else CrossSection()
                if last.area() - cover.area() > 1e-3:
                    half = last.offset(-d / 2, _MITER)
                    reach = shrunk.offset(a + d / 2, _MITER) if not shrunk.is_empty() else CrossSection()
                    if half.area() - reach.area() > 1e-3:
                        gaps.append(half - reach)
            if printed and k == 0 and s.thin_walls:  # what the outer loop cannot cover
                covered = shrunk.offset(a + d, _MITER) if not shrunk.is_empty() else CrossSection()
                r = s.nozzle_diameter / 6
                if last.area() - covered.area() > 4 * r * r:
                    bare = _opening(last - covered, r)
                    out.thin = bare if not bare.is_empty() else None
            if shrunk.is_empty():
                last = CrossSection()
                break
            if k == s.perimeters:  # the extra round only looks for gaps
                break
            region = shrunk.offset(a, _MITER) if a else shrunk
            out.loops.append((k, _rings(region) if printed else []))
            last = region
            if k == s.perimeters - 1 and not with_gaps:
                break
        lo_w, hi_w = GAP_MIN * f.per * (1 - INSET_OVERLAP), 2 * per_sp
        if gaps:  # the gaps from lo_w to hi_w wide are gap fill, and not fill area
            g = _union(gaps)
            if g.area() > lo_w * hi_w:
                g = _opening(g, lo_w / 2) - _opening(g, hi_w / 2)
                if not g.is_empty():
                    out.gaps = g
                    if not last.is_empty():
                        last = last - g
        if not last.is_empty():
            inset = (ext_sp if len(out.loops) == 1 else per_sp) / 2
            inset -= INFILL_OVERLAP * (inset + sol_sp / 2)
            r = sol_sp * (1 - INSET_OVERLAP) / 2
            out.fill = last.offset(-(inset + r), _MITER).offset(r, _MITER)
        return out

    def exposed(self, i: int, here: CrossSection, around: dict[int, CrossSection]) -> tuple[CrossSection, CrossSection]:
        """The top and bottom of section ``here`` on layer ``i``: its parts not covered by the
        next / previous section of ``around`` (slivers narrower than a tenth of the external
        width dropped); a membrane (both) is a bottom."""
        n = len(self.tops)
        sliver = self.s.role_width("external_perimeter", i == 0) / 10

        def uncovered(by: CrossSection) -> CrossSection:  # an equal section is the same object
            return CrossSection() if by is here else _opening(here - by, sliver)

        top = uncovered(around[i + 1]) if i + 1 < n else here
        bottom = uncovered(around[i - 1]) if i > 0 else here
        if _nonempty(top) and _nonempty(bottom):
            top = top - bottom  # a membrane: bottom (bridged)
        return top, bottom

    def surfaces(self, i: int, kept: dict[int, CrossSection], islands: list[CrossSection],
                 printed: bool, around: dict[int, CrossSection] | None = None) -> _Surfaces:
        """Layer ``i``'s typed surfaces (:class:`_Surfaces`), from its section and its
        neighbours' (``kept``: the sections without their too small islands; ``around``: the
        object's, for a chunk: what covers it and what it stands on). An island of an equal
        section (the same object, :meth:`sections`) gets the shells already found for it."""
        s = self.s
        shells = []
        for isl in islands:  # an island equal to one of another layer's (same object): its shells
            key = (id(isl), i == 0, printed)
            if key not in self._shells:
                self._shells[key] = self.shells(isl, i, printed)
            shells.append(self._shells[key])
        fill = _union([sh.fill for sh in shells if not sh.fill.is_empty()])
        top, bottom = self.exposed(i, kept[i], kept if around is None else around)
        empty = CrossSection()
        top_f = top ^ fill if _nonempty(top) else empty
        bottom_f = bottom ^ fill if _nonempty(bottom) else empty
        internal = fill - _union([top_f, bottom_f]) if (_nonempty(top_f) or _nonempty(bottom_f)) else fill
        small = empty
        if s.infill_density > 0 and s.solid_infill_below_area > 0 and not internal.is_empty():
            pieces = [p for p in internal.decompose() if p.area() <= s.solid_infill_below_area]
            small = _union(pieces)
        top_g = (top_f.offset(EXTERNAL_MARGIN, _SQUARE) ^ fill) if _nonempty(top_f) else empty
        bottom_g = bridge_g = bridge_seed = empty
        if _nonempty(bottom_f):
            grown = bottom_f.offset(EXTERNAL_MARGIN, _SQUARE) ^ fill
            if i == 0:
                bottom_g = grown
            else:  # each bridge grown within its own island only
                pieces = grown.decompose()
                if len(pieces) > 1:
                    grown = _union([p for p in pieces if (p ^ bottom_f).area() > 0])
                bridge_g, bridge_seed = grown, bottom_f
        ext = [x for x in (top_g, bottom_g, bridge_g) if not x.is_empty()]
        if ext:
            e = _union(ext)
            internal = internal - e
            small = small - e if not small.is_empty() else small
        return _Surfaces(shells, fill, top, bottom, top_g, bottom_g, bridge_g, bridge_seed, internal, small)

    def solid_sparse(self, j: int, surf: dict[int, _Surfaces]) -> tuple[CrossSection, CrossSection]:
        """Internal solid and sparse areas of layer ``j`` (PrusaSlicer's discover_horizontal_shells):
        every top surface of the ``top_layers - 1`` layers above and bottom surface of the
        ``bottom_layers - 1`` below, where it lies on this layer's internal area, is solid; a
        piece of it narrower than ``2 x NARROW_WIDTHS`` solid widths is grown by
        ``NARROW_WIDTHS`` widths within that area."""
        s, me = self.s, surf[j]
        internal = me.internal
        solid = [me.small] if not me.small.is_empty() else []
        if internal.is_empty():
            return CrossSection(), CrossSection()
        m = NARROW_WIDTHS * self.flows(j).solid
        sources = [(k, True) for k in range(j + 1, min(len(self.tops), j + s.top_layers))]
        sources += [(k, False) for k in range(max(0, j - s.bottom_layers + 1), j)]
        if s.ensure_vertical_shell_thickness:
            return self.vertical_shells(j, surf, sources)
        narrow = []
        for k, top in sources:
            src = self._source(surf, k, top)
            if src.is_empty():
                continue
            x = src ^ internal
            if x.is_empty():
                continue
            solid.append(x)
            core = x.offset(-m, _MITER)
            if core.is_empty():  # all of it narrow (a step of a slope): grown with the others
                narrow.append(x)
            else:
                part = x - core.offset(m, _MITER)  # x - opening(x, m)
                if part.area() > 1e-6:
                    narrow.append(part)
        if narrow:  # growing each narrow part and uniting is growing their union
            solid.append(_union(narrow).offset(m, _MITER) ^ internal)
        if not solid:
            return CrossSection(), internal
        solid_cs = _union(solid)
        return solid_cs, internal - solid_cs

    def vertical_shells(self, j: int, surf: dict[int, _Surfaces], sources: list[tuple[int, bool]]
                        ) -> tuple[CrossSection, CrossSection]:
        """Internal solid and sparse areas of layer ``j`` with ``ensure_vertical_shell_thickness``
        (PrusaSlicer's discover_vertical_shells, which then replaces the horizontal shells): the
        top and bottom surfaces of the same neighbours grown by 1.05 solid spacings, and every
        part of this layer's internal area that is not fill area on all of them (there the wall
        above or below is thinner than this layer's perimeters), opened (in by half, out by
        0.8 of that distance) and clipped to the internal area, are solid."""
        me = surf[j]
        internal = me.internal
        g = 1.05 * self.flows(j).spacing(self.flows(j).solid)
        shell = [self._source(surf, k, top) for k, top in sources]
        shell = [x.offset(g, _SQUARE) for x in shell if not x.is_empty()]
        keep = me.fill
        for k, _ in sources:
            keep = keep ^ surf[k].fill
        parts = [_union(shell) ^ internal] if shell else []
        parts += [internal - keep] + ([me.small] if not me.small.is_empty() else [])
        solid = _union(parts).offset(-0.5 * g, _SQUARE).offset(0.8 * g, _SQUARE) ^ internal
        return solid, internal - solid

    def _source(self, surf: dict[int, _Surfaces], k: int, top: bool) -> CrossSection:
        """Layer ``k``'s :meth:`_Surfaces.source`; for a chunk, with the object's top or bottom
        there (a neighbour's surface over or under this chunk's layers makes them solid too)."""
        key = (k, top)
        got = self._sources.get(key)
        if got is None:
            got = surf[k].source(top)
            if self._around is not None:
                obj = self._around[k][0 if top else 1]
                if not obj.is_empty():
                    got = _union([got, obj]) if not got.is_empty() else obj
            self._sources[key] = got
        return got

    def block(self, lo: int, hi: int) -> list[LayerPaths]:
        """Layers ``lo .. hi - 1``, with the neighbours their surfaces need: a layer's solid
        comes from the top and bottom surfaces up to ``top_layers - 1`` / ``bottom_layers - 1``
        layers away, and its bridges over infill look at the sparse areas of the two layers
        under it. Layers between equal sections (the same objects) share their islands, shells
        and surfaces."""
        s, n = self.s, len(self.tops)
        f_lo = max(0, lo - 2)
        c_lo, c_hi = max(0, f_lo - max(s.bottom_layers - 1, 0)), min(n, hi + max(s.top_layers - 1, 0))
        sections = self.sections(range(max(0, c_lo - 1), min(n, c_hi + 1)))
        by_cs: dict[int, tuple[list[CrossSection], CrossSection]] = {}  # equal sections are one object
        for cs in sections.values():
            if id(cs) not in by_cs:
                isl = _islands(cs, s.min_area)
                by_cs[id(cs)] = isl, _union(isl)
        islands = {i: by_cs[id(cs)][0] for i, cs in sections.items()}
        kept = {i: by_cs[id(cs)][1] for i, cs in sections.items()}
        self._shells: dict[tuple[int, bool, bool], _Island] = {}
        around = None  # a chunk: the object's sections, and its top and bottom on every layer
        self._around: dict[int, tuple[CrossSection, CrossSection]] | None = None
        if self.context is not None:
            around = self.object_sections(range(max(0, c_lo - 1), min(n, c_hi + 1)))
            self._around = {i: self.exposed(i, around[i], around) for i in range(c_lo, c_hi)}
        self._object = around
        near = kept if around is None else around
        surf: dict[int, _Surfaces] = {}
        same: dict[tuple, _Surfaces] = {}  # a layer between the same sections as another: its surfaces
        for i in range(c_lo, c_hi):
            key = (i == 0, lo <= i < hi, id(kept[i]), id(near[i - 1]) if i > 0 else None,
                   id(near[i + 1]) if i + 1 < n else None)
            if key not in same:
                same[key] = self.surfaces(i, kept, islands[i], lo <= i < hi, around)
            surf[i] = same[key]
        self._sources: dict[tuple[int, bool], CrossSection] = {}
        final = {j: self.solid_sparse(j, surf) for j in range(f_lo, hi)}
        self._whole: dict[int, CrossSection] = {}
        if self.context is not None:  # a chunk's bridges look at the object's whole layers (not
            # clipped: a bridge may be long) on and under them: sliced once, only where needed
            need = sorted({j for i in range(max(lo, 1), hi) if not surf[i].bridge_g.is_empty() for j in (i - 1, i)})
            self._whole = self.object_sections(need, clip=False)
        here = self.start
        out = []
        for i in range(lo, hi):
            fills = self.fill_regions(i, surf, final)
            # PrusaSlicer's overhang perimeters: loop points more than half a nozzle from the layer
            # below. A loop point lies more than that inside the section, so its half-nozzle disc
            # is in the section: it is over air iff the disc is in the bottom surface, i.e. iff
            # it is in the bottom surface shrunk by half a nozzle (empty on a steep wall)
            over = None
            if s.overhangs and i > 0 and not surf[i].bottom.is_empty():
                over = surf[i].bottom.offset(-s.nozzle_diameter / 2, _MITER)
                over = None if over.is_empty() else over
            paths: list[tuple[np.ndarray, int, float]] = []
            remaining = list(surf[i].islands)
            while remaining:  # islands nearest-first from where the nozzle is
                b = np.array([isl.cs.bounds() for isl in remaining])  # xmin, ymin, xmax, ymax
                centres = (b[:, :2] + b[:, 2:]) / 2
                k = int(np.argmin(((centres - here) ** 2).sum(axis=1)))
                isl = remaining.pop(k)
                here = self.island_paths(isl, i, over, fills, len(surf[i].islands) == 1, paths, here)
            out.append(_with_travel(self.zmin + float(self.tops[i]), float(self.heights[i]), paths))
        del self._sources, self._around, self._whole, self._object, self._shells
        return out

    def fill_regions(self, i: int, surf: dict[int, _Surfaces], final: dict) -> list[tuple[CrossSection, int, float | None]]:
        """Layer ``i``'s fill regions in print order, ``[(region, role, bridge angle or None)]``:
        bridges over air (each with its direction), top solid, bottom solid (first layer),
        internal solid, bridges over sparse infill (PrusaSlicer's bridge_over_infill: internal
        solid over sparse infill on both layers under it, wider than ``2 x
        BRIDGE_OVER_INFILL_WIDTHS`` bridge widths) and sparse. Overlaps go to the first."""
        s, me = self.s, surf[i]
        solid, sparse = final[i]
        out: list[tuple[CrossSection, int, float | None]] = []
        taken: list[CrossSection] = []
        if not me.bridge_g.is_empty():
            if self._around is None:
                below = surf[i - 1].islands if i - 1 in surf else []
                anchors = _union([isl.cs for isl in below])
            else:  # a chunk: the object's whole bridge (not clipped: it may be long), anchored on the
                # object's layer below
                obj = self._whole
                f = self.flows(i)
                anchors, whole = obj[i - 1], _opening(obj[i] - obj[i - 1], f.ext / 10).decompose()
                # the object's fill area, about: inside its perimeters
                inner = obj[i].offset(-(f.ext + max(s.perimeters - 1, 0) * f.spacing(f.per)), _MITER)
            for group in me.bridge_g.decompose():
                angle = s.bridge_angle_deg
                if angle is None:
                    area = group ^ me.bridge_seed
                    if self._around is not None and not area.is_empty():
                        # the whole bridge this one is part of, across the cuts (not the chunks'
                        # perimeters along them), inside the object's perimeters
                        parts = [p for p in whole if not (p ^ area).is_empty()]
                        if parts:
                            area = _union([_union(parts) ^ inner, area])
                    angle = bridge_angle(area, anchors, self.bridge_w + BRIDGE_GAP)
                out.append((group, BRIDGE, angle))
            taken.append(me.bridge_g)
        for region, role in ((me.top_g, TOP_SKIN), (me.bottom_g, SKIN)):
            if not region.is_empty():
                out.append((region - _union(taken) if taken else region, role, None))
                taken.append(region)
        if not solid.is_empty() and i > 0 and s.infill_density < 1:
            lower = [final[j][1] for j in (i - 1, i - 2) if j >= 0 and j in final
                     and self.tops[j] >= self.tops[i] - self.bridge_w - 1e-6]
            cand = solid
            for sp in lower:
                cand = cand ^ sp if not cand.is_empty() else cand
            if not cand.is_empty():
                cand = _opening(cand, BRIDGE_OVER_INFILL_WIDTHS * self.bridge_w) ^ solid
            if not cand.is_empty() and cand.area() > 1e-6:
                out.append((solid - cand, SKIN, None))
                out.append((cand, BRIDGE, s.bridge_angle_deg))
                solid = CrossSection()
        if not solid.is_empty():
            out.append((solid, SKIN, None))
        if not sparse.is_empty():
            out.append((sparse, INFILL, None))
        return [(r, role, a) for r, role, a in out if not r.is_empty() and r.area() >= s.min_area]

    def repeated(self, params: tuple, region: CrossSection, compute: Callable[[], list]) -> list:
        """``compute()``, the paths of ``region`` (``params``: whatever else they depend on), or
        what it returned for the same region (the same outline, point for point) and ``params``
        among the last ``REPEATS`` calls. A prismatic part repeats its layers: on the generated
        large benchmark part 63% of the sparse infill regions and 98% of the gap fill regions
        come again within 4 layers, and a repeat then costs a lookup instead of offsetting,
        hatching and joining, or a medial axis. The paths are shared, never modified."""
        key = (params, tuple(p.tobytes() for p in region.to_polygons()))
        got = self._repeats.get(key)
        if got is None:
            got = self._repeats[key] = compute()
            if len(self._repeats) > REPEATS:
                self._repeats.popitem(last=False)
        else:
            self._repeats.move_to_end(key)
        return got

    def island_paths(self, isl: _Island, layer: int, over: CrossSection | None,
                     fills: list[tuple[CrossSection, int, float | None]], alone: bool,
                     paths: list, here: np.ndarray) -> np.ndarray:
        """Append one island's perimeters (overhanging parts as overhang perimeters), thin walls,
        gap fill, solid fills and sparse infill to ``paths``; return the nozzle position."""
        s, f = self.s, self.flows(layer)
        if over is not None and not alone:
            over = over ^ isl.cs if not _apart(over.bounds(), isl.cs.bounds()) else None
        over_rings = _rings(over) if over is not None and not over.is_empty() else None
        order = isl.loops if s.outer_perimeter_first else isl.loops[::-1]
        for depth, rings in order:
            role, w = (PERIMETER_OUTER, f.ext) if depth == 0 else (PERIMETER_INNER, f.per)
            for ring in rings:
                start = _seam_start(ring, s, here, self.rear)
                closed = _closed(ring, start)
                if over_rings is not None:
                    for piece, air in split_by_region(closed, over_rings):
                        paths.append((piece, OVERHANG, self.bridge_w) if air else (piece, role, w))
                else:
                    paths.append((closed, role, w))
                here = paths[-1][0][-1]
        # a medial line's local thickness is the spacing of its bead (PrusaSlicer's variable_width:
        # width = thickness + h (1 - pi / 4)), so that the bead fills the thickness: a 0.3 mm wall
        # gets its 0.3 x h of cross-section, not the less of a 0.3 mm wide bead
        bead = float(self.heights[layer]) * (1 - math.pi / 4)
        if isl.thin is not None and not isl.thin.is_empty():
            thin_w = (s.nozzle_diameter / 3, f.ext + (f.spacing(f.ext) + f.spacing(f.per)) / 2)
            walls = self.repeated(("thin",) + thin_w, isl.thin, lambda: medial_lines(isl.thin, *thin_w))
            if not walls and not isl.loops:  # too small for a loop and for a centre line: one bead
                walls = [b for b in [single_bead(isl.thin, *thin_w)] if b is not None]
            if self._object is not None:  # a chunk: no bead over its cuts
                walls = _off_cuts(walls, self._object[layer], isl.cs, bead, thin_w[0])
            for pts, width in walls:
                paths.append((pts, PERIMETER_OUTER, width + bead))
        if isl.gaps is not None:
            lo_w, hi_w = GAP_MIN * f.per * (1 - INSET_OVERLAP), 2 * f.spacing(f.per)
            for pts, width in self.repeated(("gaps", lo_w, hi_w), isl.gaps, lambda: medial_lines(isl.gaps, lo_w, hi_w)):
                paths.append((pts, GAP_FILL, width + bead))
        if isl.fill.is_empty():
            return _last_point(paths, here)
        angle = s.infill_angle_deg + 90.0 * (layer % 2)
        box = isl.fill.bounds()
        for region, role, bridge in fills:
            if not alone:
                if _apart(region.bounds(), box):  # another island's region: nothing in common
                    continue
                region = region ^ isl.fill
                if region.is_empty():
                    continue
            if role == INFILL:
                self.sparse_paths(region, layer, angle, paths)
            elif role == BRIDGE:
                self.solid_paths(region, role, bridge if bridge is not None else angle, self.bridge_w, f.height, paths)
            else:
                self.solid_paths(region, role, angle, f.top if role == TOP_SKIN else f.solid, f.height, paths)
        return _last_point(paths, here)

    def solid_paths(self, region: CrossSection, role: int, angle: float, width: float, height: float,
                    paths: list) -> None:
        """Solid lines over ``region`` at ``angle``: each connected piece gets a whole number of
        lines, the spacing widened by at most ``SOLID_SPACING_MAX`` and the width with it (the
        volume per area stays one layer height; PrusaSlicer's adjusted solid spacing). A bridge
        (round thread of diameter ``width``) keeps its ``BRIDGE_GAP`` between the threads.
        Solid and top lines (not bridges) end ``LINE_END`` spacings inside their piece and are
        joined along it (:func:`_joined`, without anchors)."""
        bridge = role == BRIDGE
        pieces = [(piece, r) for piece in region.decompose() for r in [_rings(piece)] if r]
        if not pieces:
            return
        rings = [r for _, r in pieces]
        a = math.radians(angle)
        rot = np.array([[math.cos(a), math.sin(a)], [-math.sin(a), math.cos(a)]])  # world -> (along, across)
        flat = [r for rs in rings for r in rs]
        sizes = np.array([len(r) for r in flat])
        piece = np.repeat(np.arange(len(rings)), [len(rs) for rs in rings])
        uv = np.concatenate(flat) @ rot.T
        owner = np.repeat(piece, sizes)
        firsts = np.concatenate(([0], np.flatnonzero(np.diff(owner)) + 1))
        lo_, hi_ = np.minimum.reduceat(uv[:, 1], firsts), np.maximum.reduceat(uv[:, 1], firsts)
        spacing = width + BRIDGE_GAP if bridge else extrusion_spacing(width, height)
        span = hi_ - lo_
        count = np.floor((span - 1e-9) / spacing)
        new = np.where(count > 0, span / np.maximum(count, 1), spacing)
        new = np.minimum(new, spacing * SOLID_SPACING_MAX)
        line_w = new - BRIDGE_GAP if bridge else width + (new - spacing)
        # every piece in a band of its own, scaled across the lines so that its lines (the first
        # half a spacing in) fall on whole numbers: one hatch for all pieces
        band = np.concatenate([[0], np.cumsum(np.ceil(span / new) + 2)])[:-1]
        uv[:, 1] = (uv[:, 1] - lo_[owner]) / new[owner] - 0.5 + band[owner]
        seg = hatch_flat(uv, sizes, 1.0, 0.0)
        if not len(seg):
            return
        k = seg[:, 0, 1]
        p = np.searchsorted(band, k + 0.25, side="right") - 1
        seg[:, :, 1] = ((k - band[p] + 0.5) * new[p] + lo_[p])[:, None]
        seg = seg @ rot
        if self.s.infill_anchor_max <= 0:
            paths.append((seg, role, line_w[p]))
            return
        # the lines of each piece joined along its boundary, as PrusaSlicer's rectilinear fill
        # does (no anchors): far fewer travels on ring-shaped solid areas
        for q in np.unique(p):
            inner, contour = _line_rings(pieces[q][0], spacing)
            lines = clip_polylines(seg[p == q], inner)
            lines = unpacked(*_joined(lines, contour, 0.0, self.s.infill_anchor_max, float(line_w[q]), spacing))
            paths.extend((line, role, float(line_w[q])) for line in lines)

    def sparse_paths(self, region: CrossSection, layer: int, angle: float, paths: list) -> None:
        """Sparse infill of ``region`` in ``infill_pattern`` at ``infill_density`` (line
        distance: the infill line spacing at the layer height over the density, on a global
        grid), joined and anchored along its boundary (:func:`_joined`); a region repeated from
        a recent layer takes that layer's paths (:meth:`repeated`)."""
        s = self.s
        if s.infill_density <= 0:
            return
        w = s.role_width("infill", layer == 0)
        z = self.zmin + float(self.tops[layer]) if s.infill_pattern == "gyroid" else None
        paths.extend(self.repeated(("sparse", angle, w, z), region, lambda: self._sparse(region, angle, w, z)))

    def _sparse(self, region: CrossSection, angle: float, w: float, z: float | None) -> list:
        """:meth:`sparse_paths` of ``region`` at ``angle`` (rectilinear), line width ``w``,
        height ``z`` (gyroid): the paths to append."""
        s, paths = self.s, []
        sp = self.sparse_spacing
        rings, contour = _line_rings(region, sp)
        if s.infill_pattern == "gyroid":
            lines = gyroid(rings, sp / s.infill_density, z,
                           s.infill_angle_deg + CORRECTION_DEG)  # PrusaSlicer's turn of its gyroid
        else:
            if s.infill_pattern == "rectilinear":
                dirs = [(angle, sp / s.infill_density)]
            elif s.infill_pattern == "grid":
                dirs = [(s.infill_angle_deg, 2 * sp / s.infill_density),
                        (s.infill_angle_deg + 90, 2 * sp / s.infill_density)]
            else:  # triangles
                dirs = [(s.infill_angle_deg + d, 3 * sp / s.infill_density) for d in (0.0, 60.0, 120.0)]
            lines = np.concatenate([hatch(rings, spacing, ang) for ang, spacing in dirs])  # (m, 2, 2)
        pts, off = _joined(lines, contour, s.infill_anchor, s.infill_anchor_max, w, sp)
        if len(off) > 1 and (np.diff(off) == 2).all():
            paths.append((pts.reshape(-1, 2, 2), INFILL, w))  # a batch of segments
        else:
            paths.extend((line, INFILL, w) for line in unpacked(pts, off))
        return paths


#: How many recent fill results (sparse infill, gap fill, thin walls) a block job keeps for
#: repeated layers (:meth:`_Job.repeated`); a repeat comes 1-2 layers later, a layer has a few.
REPEATS = 16

#: Infill lines end this many spacings inside their region; joins and anchors follow the region
#: shrunk by ``LINE_END + JOIN_TOL`` spacings (PrusaSlicer 2.5's FillRectilinear: 0.4 and 0.5),
#: so they lie beside the inner perimeter rather than on it.
LINE_END = 0.4
JOIN_TOL = 0.1


def _line_rings(region: CrossSection, spacing: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The rings the infill lines of ``region`` are clipped to, and the rings along which they
    are joined and anchored (``LINE_END``)."""
    return (_rings(region.offset(-LINE_END * spacing, _MITER)),
            _rings(region.offset(-(LINE_END + JOIN_TOL) * spacing, _MITER)))


def _joined(lines: list[np.ndarray] | np.ndarray, contour: list[np.ndarray], anchor: float, anchor_max: float,
            width: float, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """``lines`` (ending ``JOIN_TOL`` spacings off ``contour``) joined along ``contour`` as
    PrusaSlicer does: first snake-wise from line to line (its rectilinear fill's traversal), then
    the chains' ends shortest stretch first, with anchors (its connect_infill); packed,
    (points, offsets) as :func:`~cooprint.slicing.anchor.join_packed`."""
    return join_packed(lines, contour, anchor, anchor_max, width, 2 * JOIN_TOL * spacing)


def _last_point(paths: list, here: np.ndarray) -> np.ndarray:
    """Where the nozzle ends after ``paths`` (``here`` if there are none)."""
    if not paths:
        return here
    last = paths[-1][0]
    return last[-1, -1] if last.ndim == 3 else last[-1]


def _with_travel(z: float, height: float, paths: list[tuple[np.ndarray, int, float]]) -> LayerPaths:
    """The layer's :class:`LayerPaths`: ``paths`` in order (an entry is one path (k, 2), or a
    batch of paths of equal length (m, k, 2) with one role and one width), with a travel path
    inserted wherever one path does not start where the previous one ended."""
    if not paths:
        return LayerPaths.build(z, height, [])
    # one entry per path: a batch (m, k, 2) counts as m paths of k points, its role and width
    # repeated (lists first, one array each at the end: a layer has thousands of paths)
    many = [len(p) if p.ndim == 3 else 1 for p, _, _ in paths]
    lens = np.repeat([p.shape[1] if p.ndim == 3 else len(p) for p, _, _ in paths], many).astype(np.int64)
    role = np.repeat(np.array([r for _, r, _ in paths], dtype=np.uint8), many)
    ws = [w for _, _, w in paths]
    if not any(isinstance(w, np.ndarray) and w.ndim for w in ws):
        width = np.repeat(np.array(ws, dtype=np.float64), many)
    else:  # a batch may have a width per path
        width = np.concatenate([np.broadcast_to(np.asarray(w, dtype=np.float64), (m,)) for w, m in zip(ws, many)])
    pts = np.concatenate([p.reshape(-1, 2) if p.ndim == 3 else p for p, _, _ in paths])
    ends = np.cumsum(lens)
    first, last = pts[ends - lens], pts[ends - 1]
    jump = np.concatenate([[False], np.linalg.norm(first[1:] - last[:-1], axis=1) > 1e-9])
    # output: each path preceded by a 2-point travel where it jumps
    size = lens + 2 * jump
    start = np.cumsum(size) - size
    out = np.empty((int(size.sum()), 2))
    shift = start + 2 * jump - (ends - lens)
    out[np.arange(len(pts)) + np.repeat(shift, lens)] = pts
    j = np.flatnonzero(jump)
    out[start[j]] = last[j - 1]
    out[start[j] + 1] = first[j]
    n_out = len(lens) + len(j)
    seq = np.arange(len(lens)) + np.cumsum(jump)  # where each path lands among all paths
    lengths = np.empty(n_out, dtype=np.int64)
    roles_out = np.full(n_out, TRAVEL, dtype=np.uint8)
    widths_out = np.zeros(n_out)
    lengths[seq], roles_out[seq], widths_out[seq] = lens, role, width
    lengths[seq[j] - 1] = 2
    offsets = np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64)
    return LayerPaths(z, height, out, offsets, roles_out, widths_out)
