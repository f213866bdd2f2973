"""Cut a solid into watertight chunks along a :class:`ChunkPlan` (seed §3.2, Fig. 4).

The seed bisected with Blender and capped the cuts by hand; here every cut is an exact
half-space split that leaves both halves closed (:mod:`cooprint.chunking.split`, in numpy, with
manifold3d's kernel as the fallback for self-intersecting input), so each chunk is a closed
2-manifold and the chunk volumes add up to the solid's volume. Ordered planes (parallel ones on
one side, or a row's column faces) are applied by recursive halving (middle plane first), which
measured about 2x faster than peeling one chunk at a time (see DESIGN.md).

The machinery every layout shares: a layout turns a kernel into :class:`Piece` records (its cuts,
made with :func:`split_ordered` and the kernel's ``split``), and :func:`cut_pieces` runs it with the
numpy kernel, falls back to manifold3d's when a section is not a valid polygon set, and extracts
the non-empty pieces as :class:`Chunk` records. ``seed2`` (:func:`cut_chunks`) and ``grid``
(:mod:`cooprint.chunking.grid`) are two such layouts.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import manifold3d
import numpy as np

from cooprint.chunking.planes import ChunkPlan, Plane
from cooprint.chunking.split import CapError, Mesh, split_mesh
from cooprint.geometry import compact, signed_volume
from cooprint.io.mesh import MeshReport, Solid

#: A chunk whose volume is below this fraction of the solid's is numerical dust, not a chunk (a
#: sliver of a corner between two cuts: 0.01 mm3 of a 97-litre bar was seen; a bead of 0.4 x 0.2 mm
#: is a hundred times more per mm).
DUST = 1e-9
#: Section points this close to a mesh vertex (times the bounding-box diagonal) become that
#: vertex; single-precision STL resolves about 6e-8 of the diagonal.
SNAP = 1e-6


@dataclass(frozen=True)
class Chunk:
    """One watertight piece of the object, printed in one go by one robot.

    Attributes
    ----------
    id : str
        ``C``, ``L1``, ``L2``, ..., ``R1``, ``R2``, ... (index = plane index on that side); in the
        grid layout the row's name, ``-`` and the column (``C-0``, ``L1-3``).
    role : str
        ``centre``, ``left`` or ``right`` (the row's side).
    index : int
        0 for the centre chunk, k for Lk / Rk.
    vertices : (n, 3) float64
        mm.
    faces : (m, 3) int64
        Outward-wound triangles.
    volume : float
        mm^3.
    planes : tuple of Plane
        The cutting planes that bound it, each normal pointing away from the chunk (so every
        vertex has signed distance <= 0 to every plane).
    row, col : int
        Where it lies (issue 14): ``row`` 0 for the centre row, ``-k`` for the k-th row on the
        left (-axis) side, ``+k`` on the right; ``col`` the column along the centre line, from 0
        at its -u end (the seed2 layout: one column, 0).
    facing : (2,) float or None
        The direction its robot faces while printing it (unit XY, from the body to the nozzle):
        from the unprinted side towards the faces it leans on. ``None``: the layout leaves it
        to the scheduler (seed2's centre chunk, printed from either side).
    """

    id: str
    role: str
    index: int
    vertices: np.ndarray
    faces: np.ndarray
    volume: float
    planes: tuple[Plane, ...]
    row: int = 0
    col: int = 0
    facing: tuple[float, float] | None = None

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float64 bounding-box corners."""
        return np.array([self.vertices.min(axis=0), self.vertices.max(axis=0)])

    @property
    def side(self) -> str:
        return {"centre": "C", "left": "L", "right": "R"}[self.role]

    def as_solid(self) -> Solid:
        """The chunk as a :class:`Solid` (what the slicer takes)."""
        lo, hi = self.bounds
        report = MeshReport(path=f"<chunk {self.id}>", format="chunk", triangles_read=len(self.faces),
                            triangles=len(self.faces), vertices=len(self.vertices),
                            bbox_min=tuple(float(x) for x in lo), bbox_max=tuple(float(x) for x in hi),  # type: ignore[arg-type]
                            volume_mm3=self.volume, watertight_as_read=True, repairs=())
        return Solid(self.vertices, self.faces, report)


@dataclass(frozen=True)
class ChunkSet:
    """The chunker's output: chunks in print-dependency order, and who waits for whom.

    Attributes
    ----------
    plan : ChunkPlan
    chunks : tuple of Chunk
        ``C`` first (when not empty), then ``L1, L2, ...``, then ``R1, R2, ...``; the grid layout
        the same rows, each with its even columns then its odd ones. Every chunk comes after the
        chunks in its ``deps``.
    deps : dict
        ``{chunk id: tuple of chunk ids that must be finished first}`` (precedence (a) of issue
        14: the chunks whose faces it leans on). seed2: every side chunk depends on its inner
        neighbour (the nearest non-empty chunk towards the centre): it leans on that chunk's
        sloped face, and its robot stands where the next chunk out will be. grid:
        :func:`cooprint.chunking.grid.grid_dependencies`.
    solid_volume : float
        Volume of the uncut solid, mm^3.
    layout : str
        The layout strategy that made it (``seed2``, ``grid``).
    """

    plan: ChunkPlan
    chunks: tuple[Chunk, ...]
    deps: dict[str, tuple[str, ...]]
    solid_volume: float
    layout: str = "seed2"

    def __getitem__(self, cid: str) -> Chunk:
        for ch in self.chunks:
            if ch.id == cid:
                return ch
        raise KeyError(cid)

    @property
    def ids(self) -> list[str]:
        return [c.id for c in self.chunks]

    @property
    def volume(self) -> float:
        return float(sum(c.volume for c in self.chunks))


class _NumpyKernel:
    """Pieces are face arrays over one shared, growing vertex pool (see :mod:`.split`)."""

    def __init__(self, solid: Solid):
        self.pool = Mesh(solid.vertices)
        self.whole = np.asarray(solid.faces, dtype=np.int64)
        self.snap = SNAP * float(np.linalg.norm(np.ptp(solid.vertices, axis=0)))

    def split(self, piece: np.ndarray, plane: Plane) -> tuple[np.ndarray, np.ndarray]:
        return split_mesh(self.pool, piece, plane.normal, plane.offset, self.snap)

    def points(self, piece: np.ndarray) -> np.ndarray:
        """(k, 3) float64 vertices of a piece (a linear function is extreme at one of them)."""
        verts = self.pool.vertices
        used = np.zeros(len(verts), dtype=bool)
        used[piece.ravel()] = True  # a mask, not np.unique: no sort over the piece's corners
        return verts[used]

    def extract(self, piece: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        if len(piece) == 0:
            return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), 0.0
        verts, faces = compact(self.pool.vertices, piece)
        return verts, faces, signed_volume(verts, faces)


class _ManifoldKernel:
    """Pieces are manifold3d objects: slower, but robust to self-intersecting input."""

    def __init__(self, solid: Solid):
        self.whole = solid.manifold

    def split(self, piece: manifold3d.Manifold, plane: Plane) -> tuple[manifold3d.Manifold, manifold3d.Manifold]:
        return piece.split_by_plane(plane.normal, plane.offset)

    def points(self, piece: manifold3d.Manifold) -> np.ndarray:
        """(k, 3) float64 vertices of a piece."""
        return np.asarray(piece.to_mesh64().vert_properties, dtype=np.float64)[:, :3]

    def extract(self, piece: manifold3d.Manifold) -> tuple[np.ndarray, np.ndarray, float]:
        mesh = piece.to_mesh64()
        return (np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3],
                np.asarray(mesh.tri_verts, dtype=np.int64), float(piece.volume()))


def split_ordered(kernel: Any, piece: Any, planes: list[Plane]) -> list[Any]:
    """Pieces between consecutive ordered planes: ``len(planes) + 1`` pieces, the one behind
    ``planes[0]`` (opposite its normal) first, the one beyond the last plane last. Middle plane
    first (recursive halving).

    The planes must be ordered within the piece: each plane's normal points to the side where
    the later planes lie, and no two planes cross inside the piece. Parallel planes with
    increasing offset are the seed's case; a row's column faces (slopes alternating, never
    crossing within the part's height) the grid's."""
    if not planes:
        return [piece]
    mid = len(planes) // 2
    outer, inner = kernel.split(piece, planes[mid])
    return split_ordered(kernel, inner, planes[:mid]) + split_ordered(kernel, outer, planes[mid + 1:])


@dataclass(frozen=True)
class Piece:
    """A chunk before extraction: what the layout knows of it, and the kernel's piece.

    ``planes`` are the cuts that bound it, each normal pointing away from it; ``row``, ``col``,
    ``facing`` as in :class:`Chunk`."""

    id: str
    role: str
    index: int
    piece: Any
    planes: tuple[Plane, ...]
    row: int = 0
    col: int = 0
    facing: tuple[float, float] | None = None


def row_pieces(kernel: Any, plan: ChunkPlan) -> list[Piece]:
    """The seed's chunks (the grid's rows): ``C`` first, then ``L1, L2, ...``, then ``R1, ...``."""
    right_planes = [plan.plane("R", k) for k in range(plan.n_right)]
    left_planes = [plan.plane("L", k) for k in range(plan.n_left)]
    r0, l0 = plan.plane("R", 0), plan.plane("L", 0)
    centre = kernel.whole
    right_pieces: list[Any] = []
    left_pieces: list[Any] = []
    if plan.n_right:  # else nothing (beyond numerical slack) lies past R_0: keep it all in C
        right_side, centre = kernel.split(centre, r0)
        right_pieces = split_ordered(kernel, right_side, right_planes[1:])
    if plan.n_left:
        left_side, centre = kernel.split(centre, l0)
        left_pieces = split_ordered(kernel, left_side, left_planes[1:])
    centre_bounds = ((r0,) if plan.n_right else ()) + ((l0,) if plan.n_left else ())  # the cuts made
    specs = [Piece("C", "centre", 0, centre, centre_bounds, 0, 0, _seed_facing("centre", plan))]
    for role, side, pieces, planes in (("left", "L", left_pieces, left_planes),
                                       ("right", "R", right_pieces, right_planes)):
        for k, piece in enumerate(pieces, start=1):
            bounds = (planes[k - 1].flipped(),) + ((planes[k],) if k < len(planes) else ())
            row = -k if role == "left" else k
            specs.append(Piece(f"{side}{k}", role, k, piece, bounds, row, 0, _seed_facing(role, plan)))
    return specs


def dependencies(chunks: tuple[Chunk, ...]) -> dict[str, tuple[str, ...]]:
    """Each side chunk waits for its inner neighbour (see :class:`ChunkSet`)."""
    deps: dict[str, tuple[str, ...]] = {}
    has_centre = any(c.role == "centre" for c in chunks)
    for ch in chunks:
        if ch.role == "centre":
            deps[ch.id] = ()
            continue
        inner = [c for c in chunks if c.role == ch.role and c.index < ch.index]
        if inner:
            deps[ch.id] = (max(inner, key=lambda c: c.index).id,)
        else:
            deps[ch.id] = ("C",) if has_centre else ()
    return deps


def _seed_facing(role: str, plan: ChunkPlan) -> tuple[float, float] | None:
    """A side chunk is printed from outside, towards the centre (a left chunk along ``+axis``, a
    right one against it); the centre chunk from either side (``None``)."""
    if role == "centre":
        return None
    sign = 1.0 if role == "left" else -1.0
    return (sign * float(plan.axis[0]), sign * float(plan.axis[1]))


def cut_pieces(solid: Solid, make_pieces: Callable[[Any], list[Piece]],
               progress: Callable[[int, int], None] | None = None) -> tuple[Chunk, ...]:
    """Run a layout's cuts (``make_pieces(kernel)``) on ``solid`` and extract its chunks.

    The numpy kernel first; when one of its sections is not a valid polygon set (a
    self-intersecting mesh, :class:`CapError`) the whole layout is cut again with manifold3d's.
    Chunks whose volume is dust (below ``DUST`` of the solid's) are dropped; the others keep the
    layout's ids, so an id never changes because a neighbour turned out empty. ``progress(done,
    total)`` is called after each piece is extracted."""
    kernel: Any = _NumpyKernel(solid)
    try:
        specs = make_pieces(kernel)
    except CapError:  # a section that is not a valid polygon set (self-intersecting mesh)
        kernel = _ManifoldKernel(solid)
        specs = make_pieces(kernel)
    chunks: list[Chunk] = []
    dust = DUST * solid.volume
    for i, sp in enumerate(specs):
        verts, faces, vol = kernel.extract(sp.piece)
        if vol > dust:
            chunks.append(Chunk(sp.id, sp.role, sp.index, verts, faces, vol, sp.planes, sp.row, sp.col, sp.facing))
        if progress:
            progress(i + 1, len(specs))
    return tuple(chunks)


def cut_chunks(solid: Solid, plan: ChunkPlan,
               progress: Callable[[int, int], None] | None = None) -> ChunkSet:
    """Cut ``solid`` along ``plan`` into watertight chunks (the ``seed2`` layout).

    Parameters
    ----------
    solid
        A watertight solid from :func:`cooprint.io.mesh.load_mesh`.
    plan
        From :func:`cooprint.chunking.plan_chunks` for the same solid.
    progress
        Called as ``progress(done, total)`` after each chunk is extracted.

    Returns
    -------
    ChunkSet
        Non-empty chunks only; ids keep their plane index even if a chunk between is empty.
    """
    chunks = cut_pieces(solid, lambda kernel: row_pieces(kernel, plan), progress)
    return ChunkSet(plan, chunks, dependencies(chunks), solid.volume, "seed2")
