"""Mesh input: read STL (binary/ASCII), OBJ, PLY and 3MF, each optionally gzipped, into a
watertight :class:`Solid`, repairing what slicer users expect to be repaired and reporting it.

Repairs done silently-but-reported: merging duplicate vertices, dropping degenerate and duplicate
triangles, making the winding consistent and outward, closing small holes. Anything that still is
not a closed 2-manifold after that is refused with a :class:`~cooprint.errors.MeshError` that says
what is wrong (open edges, hole sizes) and which setting would change the decision.
"""

from __future__ import annotations

import gzip
import io
import logging
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

from typing import TYPE_CHECKING

import manifold3d
import numpy as np

from cooprint.config import MeshSettings
from cooprint.geometry import (compact, distinct_corners, edge_loops, edge_table, index_dtype, is_closed,
                               open_edges, signed_volume, winding_consistent)
from cooprint.errors import MeshError

FORMATS = ("stl", "obj", "ply", "3mf")
#: Largest decompressed input read, bytes (a 20M-triangle binary STL is 1 GB).
MAX_BYTES = 2 * 1024**3
#: Largest coordinate accepted, mm (10 km: anything larger is a unit or file error).
MAX_COORD = 1e7

logging.getLogger("trimesh").setLevel(logging.ERROR)

if TYPE_CHECKING:  # trimesh (and scipy behind it) costs ~1 s to import: only the slow paths load it
    import trimesh


@dataclass(frozen=True)
class MeshReport:
    """What the loader found and did."""

    path: str
    format: str
    triangles_read: int
    triangles: int
    vertices: int
    bbox_min: tuple[float, float, float]
    bbox_max: tuple[float, float, float]
    volume_mm3: float
    watertight_as_read: bool
    repairs: tuple[str, ...]

    def to_dict(self) -> dict[str, object]:
        return {
            "path": self.path, "format": self.format, "triangles_read": self.triangles_read,
            "triangles": self.triangles, "vertices": self.vertices,
            "bbox_min": list(self.bbox_min), "bbox_max": list(self.bbox_max),
            "volume_mm3": self.volume_mm3, "watertight_as_read": self.watertight_as_read,
            "repairs": list(self.repairs),
        }


@dataclass(frozen=True)
class Solid:
    """A closed, consistently wound, outward-facing triangle mesh.

    Attributes
    ----------
    vertices : (n, 3) float64
        Vertex positions, mm.
    faces : (m, 3) int32 (int64 from 2**31 vertices on, :func:`~cooprint.geometry.index_dtype`)
        Triangles as vertex indices, counter-clockwise seen from outside.
    report : MeshReport
        Where it came from and what was repaired.
    """

    vertices: np.ndarray = field(repr=False)
    faces: np.ndarray = field(repr=False)
    report: MeshReport

    @cached_property
    def manifold(self) -> manifold3d.Manifold:
        """The same solid as a manifold3d object, built on first use (it costs about 1.5 s per
        million triangles, so the fast paths do without it)."""
        return to_manifold(self.vertices, self.faces)

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float64: bounding-box min and max corners."""
        return np.array([self.report.bbox_min, self.report.bbox_max])

    @property
    def volume(self) -> float:
        return self.report.volume_mm3


def _format(path: Path) -> tuple[str, bool]:
    """The file's format name and whether it is gzipped; refuse unknown extensions and missing
    files."""
    suffixes = [s.lower() for s in path.suffixes]
    gz = bool(suffixes) and suffixes[-1] == ".gz"
    fmt = (suffixes[-2] if gz and len(suffixes) > 1 else suffixes[-1] if suffixes else "").lstrip(".")
    if fmt not in FORMATS:
        raise MeshError(f"{path}: unknown mesh format {fmt or '(no extension)'!r}; expected one of "
                        + ", ".join(f".{f}" for f in FORMATS) + " (optionally .gz)")
    if not path.is_file():
        raise MeshError(f"{path}: no such file")
    return fmt, gz


def _read_bytes(path: Path, gz: bool) -> bytes:
    """The file's (decompressed) bytes."""
    try:
        with (gzip.open(path, "rb") if gz else open(path, "rb")) as fh:
            data = fh.read(MAX_BYTES + 1)
    except (OSError, EOFError, gzip.BadGzipFile) as exc:
        raise MeshError(f"{path}: cannot read{' gzip' if gz else ''} file ({exc})") from None
    if len(data) > MAX_BYTES:
        raise MeshError(f"{path}: larger than {MAX_BYTES // 1024**2} MiB decompressed; refusing to load")
    if not data.strip():
        raise MeshError(f"{path}: file is empty")
    return data


#: One binary STL triangle record: normal, three corners, attribute bytes.
STL_RECORD = np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
#: Records read per step by the streaming binary STL reader (about 3 MB).
STL_STEP = 1 << 16


def _read_binary_stl(path: Path, gz: bool) -> np.ndarray | None:
    """The corners (3n, 3) float32 of a binary STL, read straight from the file a few MB at a
    time (the file's bytes are never held whole). ``None`` when the file is not exactly a binary
    STL of the size its header gives (ASCII, truncated, padded, unreadable): the general reader
    then decides and explains."""
    try:
        with (gzip.open(path, "rb") if gz else open(path, "rb")) as fh:
            head = fh.read(84)
            if len(head) < 84:
                return None
            n = int(np.frombuffer(head, "<u4", count=1, offset=80)[0])
            if 84 + STL_RECORD.itemsize * n > MAX_BYTES or (
                    not gz and path.stat().st_size != 84 + STL_RECORD.itemsize * n):
                return None
            corners = np.empty((n, 3, 3), dtype=np.float32)
            raw = np.empty(STL_RECORD.itemsize * min(n, STL_STEP), dtype=np.uint8)
            for lo in range(0, n, STL_STEP):
                k = min(STL_STEP, n - lo)
                if fh.readinto(raw[:STL_RECORD.itemsize * k]) != STL_RECORD.itemsize * k:
                    return None
                corners[lo:lo + k] = raw[:STL_RECORD.itemsize * k].view(STL_RECORD)["v"]
            if gz and fh.read(1):
                return None
    except (OSError, EOFError, gzip.BadGzipFile):
        return None
    return corners.reshape(-1, 3)


def _check_stl(path: Path, data: bytes) -> int | None:
    """The triangle count of a binary STL, ``None`` for a plausible ASCII STL; refuse truncated
    or padded binary STL before a reader guesses."""
    n = 0
    if len(data) >= 84:
        n = int(np.frombuffer(data, "<u4", count=1, offset=80)[0])
        if 84 + 50 * n == len(data):
            return n
    head = data[:1024].lstrip().lower()
    if head.startswith(b"solid") and b"facet" in data[:4096].lower():
        if b"endsolid" not in data[-4096:].lower():
            raise MeshError(f"{path}: ASCII STL has no 'endsolid' line (truncated?)")
        return None
    if len(data) < 84:
        raise MeshError(f"{path}: too short for a binary STL ({len(data)} bytes, need at least 84)")
    raise MeshError(f"{path}: binary STL header says {n} triangles ({84 + 50 * n} bytes) but the "
                    f"file has {len(data)} bytes (truncated or not an STL)")


def _parse(path: Path, data: bytes, fmt: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Vertices (n, 3) and faces (m, 3) of the file's triangles (float32 vertices for binary
    STL, which stores them so: merging them in that precision is exact and twice as fast).
    Faces ``None``: a triangle soup, every three vertices one triangle (binary STL)."""
    if fmt == "stl":
        n = _check_stl(path, data)
        if n is not None:  # binary STL: one record array, no per-triangle work
            corners = np.empty((n, 3, 3), dtype=np.float32)
            corners[...] = np.frombuffer(data, STL_RECORD, count=n, offset=84)["v"]  # the only copy
            return corners.reshape(-1, 3), None
    import trimesh

    try:
        loaded = trimesh.load(io.BytesIO(data), file_type=fmt, force="mesh", process=False)
    except Exception as exc:  # any reader failure on a user file is a user error
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise MeshError(f"{path}: cannot read as {fmt.upper()}: {msg}") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise MeshError(f"{path}: contains no triangles")
    return np.asarray(loaded.vertices, dtype=np.float64), np.asarray(loaded.faces, dtype=np.int64)


def _boundary_loops(faces: np.ndarray) -> list[np.ndarray] | None:
    """Ordered vertex loops of the open boundary, following the faces' own edge direction.

    Returns ``None`` when the boundary does not decompose into closed loops (an edge used by
    more than two faces, or a dangling boundary edge).
    """
    edges = open_edges(faces)
    return None if edges is None else edge_loops(*edges)


def _fill_loop(vertices: np.ndarray, loop: np.ndarray) -> np.ndarray | None:
    """Triangles closing one boundary loop, wound against the loop (so edges pair up)."""
    pts = vertices[loop]
    centred = pts - pts.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    uv = centred @ vt[:2].T
    try:
        tris = np.asarray(manifold3d.triangulate([uv.astype(np.float64)]), dtype=np.int64)
    except Exception:
        return None
    if len(tris) != len(loop) - 2:
        return None
    faces = loop[tris]
    # the loop runs along existing faces' edges a->b; the cap must hold b->a
    first = {(int(a), int(b)) for a, b in zip(loop, np.roll(loop, -1))}
    e = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    same = sum((int(a), int(b)) in first for a, b in e)
    if same > len(e) // 2:
        faces = faces[:, ::-1]
    return faces


#: Vertices are merged in this many groups, chosen by a hash of their coordinates (equal
#: vertices share a group): each group is sorted alone, so the sort's arrays are a fraction
#: of the mesh's.
MERGE_GROUPS = 16


def _merge_vertices(v: np.ndarray, f: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Merge bit-identical vertices (STL stores every corner of every triangle, so this is what
    turns a soup into a mesh).

    ``v`` is float32 or float64 (modified in place: -0.0 becomes 0.0); ``f`` is ``None`` for a
    soup (vertices 3k, 3k+1, 3k+2 make triangle k). The vertices are split into
    ``MERGE_GROUPS`` groups by a hash of their bits, and each group is merged by a lexicographic
    sort of its bit patterns, so that besides ``v`` only the face indices and a group's sort are
    in memory at once (on a large STL this step sets the loader's peak memory). Returns the
    unique vertices as float64 (group by group, sorted within a group) and the faces re-indexed,
    in :func:`~cooprint.geometry.index_dtype`.
    """
    v += v.dtype.type(0)  # -0.0 -> 0.0, in place
    bits = v.view(np.uint32 if v.dtype == np.float32 else np.uint64).reshape(-1, 3)
    group = np.empty(len(v), dtype=np.uint8)
    mix = np.array([0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9], dtype=np.uint64)
    for lo in range(0, len(v), 1 << 16):
        h = bits[lo:lo + (1 << 16)].astype(np.uint64) * mix  # wraps modulo 2**64
        group[lo:lo + (1 << 16)] = (h[:, 0] ^ h[:, 1] ^ h[:, 2]) >> np.uint64(60)
    inverse = np.empty(len(v), dtype=index_dtype(len(v)))
    unique: list[np.ndarray] = []
    done = 0
    for g in range(MERGE_GROUPS):
        members = np.flatnonzero(group == g)
        if len(members) == 0:
            continue
        b = bits[members]
        order = np.lexsort((b[:, 2], b[:, 1], b[:, 0]))
        b = b[order]
        new = np.r_[True, (b[1:] != b[:-1]).any(axis=1)]
        del b
        unique.append(v[members[order[new]]].astype(np.float64))
        rank = np.cumsum(new, dtype=inverse.dtype)
        rank += done - 1
        inverse[members[order]] = rank
        done += len(unique[-1])
    del group, bits
    verts = np.concatenate(unique)
    return verts, (inverse.reshape(-1, 3) if f is None else inverse[f])


def to_manifold(vertices: np.ndarray, faces: np.ndarray) -> manifold3d.Manifold:
    """A closed mesh as a manifold3d object (about 1.5 s per million triangles)."""
    mesh = manifold3d.Mesh64(vert_properties=np.ascontiguousarray(vertices, dtype=np.float64),
                             tri_verts=np.ascontiguousarray(faces, dtype=np.uint64))
    return manifold3d.Manifold(mesh)


def _proper_faces(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(m,) bool: triangles with three distinct corners, non-zero area, and not a repeat of an
    earlier triangle over the same three vertices."""
    f = faces
    keep = distinct_corners(f)
    for lo in range(0, len(f), 1 << 16):  # in slices: no (m, 3) float temporaries
        g = f[lo:lo + (1 << 16)]
        area2 = np.linalg.norm(np.cross(verts[g[:, 1]] - verts[g[:, 0]], verts[g[:, 2]] - verts[g[:, 0]]), axis=1)
        keep[lo:lo + len(g)] &= area2 > 0
    if len(verts) < 2**21:  # three indices pack into one int64: a 1-D sort instead of rows
        key = np.empty(len(f), dtype=np.int64)
        for lo in range(0, len(f), 1 << 16):
            sf = np.sort(f[lo:lo + (1 << 16)], axis=1).astype(np.int64)
            key[lo:lo + len(sf)] = (sf[:, 0] << 42) | (sf[:, 1] << 21) | sf[:, 2]
        _, first = np.unique(key, return_index=True)
    else:
        _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    unique = np.zeros(len(f), dtype=bool)
    unique[first] = True
    return keep & unique


def _repair(mesh: list, settings: MeshSettings, path: str, repairs: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """The slow path, for meshes that are not already closed and consistently wound: drop
    duplicate and zero-area triangles, fix the winding, close small holes. Takes ownership of
    ``mesh = [(vertices, faces)]`` (popped, so that replaced arrays die at once)."""
    verts, faces = mesh.pop()
    keep = _proper_faces(verts, faces)
    if not keep.all():
        repairs.append(f"removed {int((~keep).sum())} degenerate or duplicate triangles")
        verts, faces = compact(verts, faces[keep])
    if len(faces) < 4:
        raise MeshError(f"{path}: only {len(faces)} usable triangles; not a solid")
    if not winding_consistent(faces):
        import trimesh  # ~1 s to import (scipy): only for this rare repair

        tm = trimesh.Trimesh(verts, faces, process=False, validate=False)
        trimesh.repair.fix_winding(tm)
        faces = np.asarray(tm.faces, dtype=faces.dtype)
        repairs.append("made triangle winding consistent")
    loops = _boundary_loops(faces)
    if loops is None:
        raise MeshError(_describe_open(path, faces))
    if loops:
        diag = float(np.linalg.norm(np.ptp(verts, axis=0)))
        limit = settings.max_hole_fraction * diag
        perims = [float(np.linalg.norm(verts[lp] - verts[np.roll(lp, -1)], axis=1).sum()) for lp in loops]
        if max(perims) > limit:
            big = sum(p > limit for p in perims)
            raise MeshError(
                f"{path}: not watertight: {sum(len(lp) for lp in loops)} open edges in {len(loops)} "
                f"holes; {big} too large to close (largest perimeter {max(perims):.1f} mm, limit "
                f"mesh.max_hole_fraction {settings.max_hole_fraction:g} x diagonal = {limit:.1f} mm)")
        caps = [_fill_loop(verts, lp) for lp in loops]
        if any(c is None for c in caps):
            raise MeshError(f"{path}: not watertight: {len(loops)} holes, some cannot be triangulated")
        faces = np.vstack([faces, *(c.astype(faces.dtype) for c in caps)])
        repairs.append(f"closed {len(loops)} holes ({sum(len(lp) for lp in loops)} open edges)")
    if not is_closed(faces):
        raise MeshError(_describe_open(path, faces))
    return verts, faces


def solid_from_arrays(vertices: np.ndarray, faces: np.ndarray, settings: MeshSettings | None = None,
                      *, path: str = "<mesh>", fmt: str = "mesh") -> Solid:
    """Validate and repair a triangle mesh into a :class:`Solid` (the loader's second half).

    Parameters
    ----------
    vertices : (n, 3) float
        mm (not modified).
    faces : (m, 3) int or None
        Vertex indices; duplicated vertices (a triangle soup, as in STL) are merged. ``None``:
        every three vertices are one triangle.
    """
    v = np.asarray(vertices)
    v = (v.copy() if v.dtype == np.float32 else v.astype(np.float64)).reshape(-1, 3)  # merged in place
    return _solid_from_parsed([(v, faces)], settings, path=path, fmt=fmt)


def _solid_from_parsed(parsed: list, settings: MeshSettings | None, *, path: str, fmt: str) -> Solid:
    """:func:`solid_from_arrays` taking ownership of ``parsed = [(vertices, faces)]`` (popped, so
    that the arrays die here as soon as they are merged, and modified in place)."""
    settings = settings or MeshSettings()
    v, faces = parsed.pop()
    f = None if faces is None else np.asarray(faces).reshape(-1, 3).astype(index_dtype(len(v)), copy=False)
    del faces
    if f is None:
        v = v[: len(v) // 3 * 3]
    n_read = len(v) // 3 if f is None else len(f)
    if n_read == 0:
        raise MeshError(f"{path}: contains no triangles")
    if not np.isfinite(v).all():
        bad = int((~np.isfinite(v).all(axis=1)).sum())
        raise MeshError(f"{path}: {bad} vertices have NaN or infinite coordinates")
    reach = max(float(v.max()), -float(v.min()))
    if reach > MAX_COORD:
        raise MeshError(f"{path}: coordinates up to {reach:.3g} mm exceed {MAX_COORD:.0e} mm (wrong units?)")
    if f is not None and (f.min() < 0 or f.max() >= len(v)):
        raise MeshError(f"{path}: face indices out of range (0..{len(v) - 1})")

    repairs: list[str] = []
    if f is not None:
        v, f = compact(v, f)  # unreferenced vertices would distort the bounding box
    n_in = len(v)
    verts, faces = _merge_vertices(v, f)
    del v, f
    if fmt != "stl" and len(verts) < n_in:  # STL always repeats vertices: not a repair
        repairs.append(f"merged {n_in - len(verts)} duplicate vertices")
    watertight_as_read = is_closed(faces)
    if not watertight_as_read:
        mesh = [(verts, faces)]
        del verts, faces
        verts, faces = _repair(mesh, settings, path, repairs)
    volume = signed_volume(verts, faces)
    if volume < 0:  # closed but inside out
        faces = faces[:, ::-1].copy()
        volume = -volume
        repairs.append("turned inside-out normals outward")

    lo, hi = verts.min(axis=0), verts.max(axis=0)
    if volume <= 1e-12 * float(np.prod(np.maximum(hi - lo, 1e-9))):
        raise MeshError(f"{path}: encloses no volume (flat or zero-size mesh)")
    report = MeshReport(
        path=path, format=fmt, triangles_read=n_read, triangles=len(faces), vertices=len(verts),
        bbox_min=tuple(float(x) for x in lo), bbox_max=tuple(float(x) for x in hi),
        volume_mm3=volume, watertight_as_read=watertight_as_read, repairs=tuple(repairs))
    return Solid(verts, faces, report)


def solid_from_trimesh(mesh: "trimesh.Trimesh", settings: MeshSettings | None = None, *,
                       path: str = "<mesh>", fmt: str = "mesh") -> Solid:
    """:func:`solid_from_arrays` for a trimesh object."""
    return solid_from_arrays(mesh.vertices, mesh.faces, settings, path=path, fmt=fmt)


def _describe_open(path: str, faces: np.ndarray) -> str:
    _, uses, consistent = edge_table(faces)
    n_open, n_nm = int((uses == 1).sum()), int((uses > 2).sum() // 3)
    parts = []
    if n_open:
        parts.append(f"{n_open} open edges")
    if n_nm:
        parts.append(f"{n_nm} non-manifold edges (shared by more than two triangles)")
    if not parts and not consistent:
        parts.append("inconsistent triangle winding")
    return f"{path}: not watertight and cannot be repaired automatically: {' and '.join(parts)}"


def load_mesh(path: str | Path, settings: MeshSettings | None = None) -> Solid:
    """Read a mesh file into a watertight :class:`Solid`.

    Parameters
    ----------
    path
        ``.stl``, ``.obj``, ``.ply`` or ``.3mf``, optionally with ``.gz`` appended.
    settings
        Repair limits; defaults to :class:`~cooprint.config.MeshSettings`.

    Raises
    ------
    MeshError
        One line naming the file and what is wrong with it.
    """
    p = Path(path)
    fmt, gz = _format(p)
    corners = _read_binary_stl(p, gz) if fmt == "stl" else None
    if corners is not None:
        parsed = [(corners, None)]
        del corners
    else:
        data = _read_bytes(p, gz)
        parsed = [_parse(p, data, fmt)]
        del data
    return _solid_from_parsed(parsed, settings, path=str(p), fmt=fmt)


def fmt_report(r: MeshReport) -> str:
    """Human summary of a load, a few lines."""
    size = np.subtract(r.bbox_max, r.bbox_min)
    lines = [
        f"{r.path}: {r.triangles:,} triangles ({r.format.upper()}, {r.triangles_read:,} read)",
        f"  size {size[0]:.1f} x {size[1]:.1f} x {size[2]:.1f} mm, volume {r.volume_mm3 / 1000:.2f} cm3, "
        f"watertight as read: {'yes' if r.watertight_as_read else 'no'}",
    ]
    lines += [f"  repaired: {x}" for x in r.repairs]
    return "\n".join(lines)


__all__ = ["FORMATS", "MeshReport", "Solid", "fmt_report", "load_mesh", "solid_from_arrays",
           "solid_from_trimesh"]
