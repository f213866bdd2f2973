"""Mesh input: read STL (binary/ASCII), OBJ, PLY and 3MF, each optionally gzipped, into a
watertight :class:`Solid`, repairing what slicer users expect to be repaired and reporting it.

Repairs done silently-but-reported (:mod:`cooprint.io.repair`): merging duplicate vertices, dropping
degenerate and duplicate triangles, splitting non-manifold edges (and dropping what that cuts
loose, and triangles connected to nothing), making the winding consistent and outward, closing
holes up to ``mesh.max_hole_fraction``. Anything that still is
not a closed 2-manifold after that is refused with a :class:`~cooprint.errors.MeshError` that says
what is wrong (open edges, hole sizes) and which setting would change the decision.
"""

from __future__ import annotations

import gzip
import io
import logging
import math
import re
import warnings
import zipfile
import zlib
from dataclasses import dataclass, field, fields
from functools import cached_property
from pathlib import Path

from typing import TYPE_CHECKING

import manifold3d
import numpy as np

from cooprint.config import MeshSettings
from cooprint.geometry import (MAX_COORD_MM, compact, edge_loops, edge_table, index_dtype, is_closed,
                               open_edges, signed_volume)
from cooprint.errors import MeshError, clip
from cooprint.io.files import regular_file

FORMATS = ("stl", "obj", "ply", "3mf")
#: Largest decompressed input read, bytes (a 20M-triangle binary STL is 1 GB).
MAX_BYTES = 2 * 1024**3
#: Largest coordinate accepted, mm (:data:`cooprint.geometry.MAX_COORD_MM`, 1 km: anything
#: larger is a unit or file error).
MAX_COORD = MAX_COORD_MM

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
    regular_file(path, "mesh file", MeshError)  # a FIFO would block the read for ever
    return fmt, gz


def _read_bytes(path: Path, gz: bool) -> bytes:
    """The file's (decompressed) bytes."""
    try:
        with (gzip.open(path, "rb") if gz else open(path, "rb")) as fh:
            data = fh.read(MAX_BYTES + 1)
    except (OSError, EOFError, gzip.BadGzipFile, zlib.error) as exc:  # zlib.error: corrupt deflate data
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
    except (OSError, EOFError, gzip.BadGzipFile, zlib.error):
        return None
    return corners.reshape(-1, 3)


def binary_stl_soup(path: str | Path) -> tuple[np.ndarray, np.ndarray] | None:
    """A binary STL as written, without merging or repairs: vertices (3n, 3) float64 (each
    triangle's corners) and faces (n, 3) (``3k, 3k + 1, 3k + 2``); ``None`` when the file is not
    exactly a binary STL (then :func:`load_mesh` reads it and says what is wrong). For files
    cooprint wrote itself and reads back (a bundle's chunks), where :func:`load_mesh`'s checks
    would cost more than the use."""
    corners = _read_binary_stl(Path(path), False)
    if corners is None or len(corners) == 0:
        return None
    return corners.astype(np.float64), np.arange(len(corners), dtype=np.int64).reshape(-1, 3)


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
    if head.startswith(b"solid") and b"endsolid" in data[-4096:].lower():
        raise MeshError(f"{path}: empty file (an ASCII STL without triangles)")
    if len(data) < 84:
        raise MeshError(f"{path}: too short for a binary STL ({len(data)} bytes, need at least 84)")
    raise MeshError(f"{path}: binary STL header says {n} triangles ({84 + 50 * n} bytes) but the "
                    f"file has {len(data)} bytes (truncated or not an STL)")


#: A number of a text mesh format: ASCII decimal digits only (Python's ``float()`` also takes
#: full-width and other Unicode digits, ``1_000``, ``nan`` and ``inf``; none of them is a
#: coordinate a mesh file holds).
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_NONFINITE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)
_NUMBER_BYTES = re.compile(_NUMBER.pattern.encode())
_INDEX = re.compile(r"[+-]?[0-9]+")


def _text(path: Path, data: bytes, fmt: str) -> str:
    """The text of a text mesh file (UTF-8), or a :class:`MeshError` naming the line of the first
    byte that is not UTF-8."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise MeshError(f"{path}:{line}: not UTF-8 text (byte 0x{data[exc.start]:02x}); is this an {fmt} "
                        "file?") from None


def _coordinate(path: Path, lineno: int, tok: str) -> float:
    """One coordinate of a text mesh file: an ASCII decimal number, finite and at most
    :data:`MAX_COORD` from 0."""
    if not _NUMBER.fullmatch(tok):
        if _NONFINITE.fullmatch(tok):
            raise MeshError(f"{path}:{lineno}: coordinate '{tok}' is NaN or infinite")
        raise MeshError(f"{path}:{lineno}: '{clip(tok)}' is not a number")
    x = float(tok)
    if not abs(x) <= MAX_COORD:
        raise MeshError(f"{path}:{lineno}: coordinate {clip(tok)} is beyond {MAX_COORD:.0e} mm (wrong units?)")
    return x


#: OBJ statements read (``v``, ``f``) and those that carry nothing a solid needs (texture and
#: normal vertices, groups, materials, smoothing, lines and points, free-form geometry): any
#: other first word is refused, so that a file that is not OBJ is not read as an empty one.
_OBJ_IGNORED = frozenset({"vt", "vn", "vp", "g", "o", "s", "usemtl", "mtllib", "l", "p", "mg", "lod", "bevel",
                          "c_interp", "d_interp", "shadow_obj", "trace_obj", "usemap", "maplib", "cstype", "deg",
                          "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole", "scrv", "sp", "end",
                          "con", "ctech", "stech", "call", "csh"})


def _read_obj(path: Path, data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles of an OBJ file, by the format's rules: ``v x y z [w]`` (a colour
    may follow), ``f a b c ...`` with 1-based vertex indices (``a/t/n`` forms too; a negative
    index counts back from the last vertex read so far); a polygon becomes a fan of triangles.

    An index of 0 (a 0-based file, which would otherwise read as a different solid), a vertex
    with fewer than three coordinates, a face with fewer than three vertices, an index past the
    vertices, a token that is not a number: a :class:`MeshError` naming the line."""
    text = _text(path, data, "OBJ")
    fast = _read_obj_fast(data)
    if fast is not None:
        return fast
    coords: list[float] = []
    vlines: list[int] = []
    tris: list[int] = []
    pending: list[tuple[int, int]] = []  # (largest positive index, line) of faces, checked at the end
    top = 0
    for lineno, line in enumerate(text.splitlines(), start=1):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        key = words[0]
        if key == "v":
            if not 4 <= len(words) <= 8:
                raise MeshError(f"{path}:{lineno}: a vertex needs 3 coordinates (v x y z), got {len(words) - 1}")
            coords += (_coordinate(path, lineno, w) for w in words[1:4])
            vlines.append(lineno)
        elif key == "f":
            if len(words) < 4:
                raise MeshError(f"{path}:{lineno}: a face needs at least 3 vertices, got {len(words) - 1}")
            n = len(vlines)
            ring = []
            for w in words[1:]:
                ref, *rest = w.split("/")
                if not _INDEX.fullmatch(ref) or len(rest) > 2 or any(r and not _INDEX.fullmatch(r) for r in rest):
                    raise MeshError(f"{path}:{lineno}: '{clip(w)}' is not a vertex index")
                k = int(ref)
                if k == 0:
                    raise MeshError(f"{path}:{lineno}: vertex index 0: OBJ indices start at 1 (a 0-based file?)")
                if k < 0:
                    if -k > n:
                        raise MeshError(f"{path}:{lineno}: vertex index {k} reaches before the first vertex "
                                        f"({n} read so far)")
                    k = n + k
                else:
                    top = max(top, k)
                    if k > n:
                        pending.append((k, lineno))
                    k -= 1
                ring.append(k)
            for j in range(1, len(ring) - 1):
                tris += (ring[0], ring[j], ring[j + 1])
        elif key not in _OBJ_IGNORED:
            raise MeshError(f"{path}:{lineno}: unknown OBJ statement '{clip(key)}'")
    for k, lineno in pending:
        if k > len(vlines):
            raise MeshError(f"{path}:{lineno}: vertex index {k} but the file has {len(vlines)} vertices")
    if not tris:
        raise MeshError(f"{path}: contains no triangles")
    return np.array(coords, dtype=np.float64).reshape(-1, 3), np.array(tris, dtype=np.int64).reshape(-1, 3)


_PLAIN_NUMBERS = re.compile(rb"[0-9eE.+\- \t\r]*")
_PLAIN_INDICES = re.compile(rb"[0-9 \t\r]*")


def _read_obj_fast(data: bytes) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`_read_obj` of the common file (every ``v`` line three plain numbers, every ``f``
    line three positive plain indices, each at the start of its line; the other lines blank,
    comments or statements it ignores) in whole-array steps; ``None`` for any other file, which
    the line reader then reads or refuses, naming the line."""
    lines = data.split(b"\n")
    v = [ln[2:] for ln in lines if ln[:2] == b"v "]
    f = [ln[2:] for ln in lines if ln[:2] == b"f "]
    if not f or len(v) + len(f) < len(lines) and not all(
            not w or w[0].startswith(b"#") or w[0].decode("utf-8", "replace") in _OBJ_IGNORED
            for w in (ln.split(None, 1) for ln in lines if ln[:2] not in (b"v ", b"f "))):
        return None
    vtext, ftext = b" ".join(v), b" ".join(f)
    if b"#" in vtext or b"#" in ftext or not _PLAIN_NUMBERS.fullmatch(vtext) or not _PLAIN_INDICES.fullmatch(ftext):
        return None
    vt, ft = vtext.split(), ftext.split()
    if len(vt) != 3 * len(v) or len(ft) != 3 * len(f):
        return None
    try:
        verts = np.array(vt, dtype=np.float64).reshape(-1, 3)
        faces = np.array(ft, dtype=np.int64).reshape(-1, 3)
    except (ValueError, OverflowError):
        return None
    if not (np.abs(verts) <= MAX_COORD).all() or faces.min() < 1 or faces.max() > len(verts):
        return None
    return verts, faces - 1


_STL_VERTEX = re.compile(rb"^[ \t]*vertex[ \t]+(\S+)[ \t]+(\S+)[ \t]+(\S+)[ \t]*\r?$", re.M | re.I)
_STL_WORD = re.compile(rb"^[ \t]*(vertex|endloop)\b", re.M | re.I)


def _read_ascii_stl(path: Path, data: bytes) -> np.ndarray:
    """The corners (3n, 3) of an ASCII STL: every ``vertex x y z`` line, three per ``outer loop``.
    A vertex line of another form, a loop without three vertices, a coordinate that is not an
    ASCII number: a :class:`MeshError` naming the line."""
    _text(path, data, "STL")
    found = _STL_VERTEX.findall(data)
    words = _STL_WORD.findall(data)
    n_vertex = sum(1 for w in words if w.lower() == b"vertex")
    if n_vertex != len(found) or n_vertex != 3 * (len(words) - n_vertex):
        _locate_ascii_stl(path, data)
    tokens = [t for row in found for t in row]
    if not all(_NUMBER_BYTES.fullmatch(t) for t in tokens):
        _locate_ascii_stl(path, data)
    v = np.array([float(t) for t in tokens], dtype=np.float64).reshape(-1, 3)
    bad = np.flatnonzero(~(np.abs(v) <= MAX_COORD).all(axis=1))
    if len(bad):
        _locate_ascii_stl(path, data)
    if len(v) == 0:
        raise MeshError(f"{path}: contains no triangles")
    return v


def _locate_ascii_stl(path: Path, data: bytes) -> None:
    """Raise the :class:`MeshError` of the first bad line of an ASCII STL (the slow path of
    :func:`_read_ascii_stl`, only for a file it refuses)."""
    in_loop = None
    for lineno, raw in enumerate(data.decode("utf-8").splitlines(), start=1):
        words = raw.split()
        if not words:
            continue
        key = words[0].lower()
        if key == "vertex":
            if in_loop is None:
                raise MeshError(f"{path}:{lineno}: a vertex outside an 'outer loop'")
            if len(words) != 4:
                raise MeshError(f"{path}:{lineno}: a vertex needs 3 coordinates (vertex x y z), got {len(words) - 1}")
            for w in words[1:]:
                _coordinate(path, lineno, w)
            in_loop += 1
        elif key == "outer":
            in_loop = 0
        elif key == "endloop":
            if in_loop != 3:
                raise MeshError(f"{path}:{lineno}: a loop of {in_loop or 0} vertices (a facet needs 3)")
            in_loop = None
    raise MeshError(f"{path}: malformed ASCII STL (vertex lines not in loops of three)")


_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
              "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}


def _check_ply(path: Path, data: bytes) -> None:
    """Refuse a PLY whose header does not describe its body before a reader trusts it: no
    ``end_header``, an unknown format or property type, an element count that is not a number,
    or more rows than the body can hold (an ASCII row takes a line, a binary row at least its
    fixed-size properties); an ASCII body must have exactly the rows the header declares."""
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise MeshError(f"{path}: not a PLY file (no 'ply' ... 'end_header' header)")
    body_at = data.find(b"\n", end)
    body_at = len(data) if body_at < 0 else body_at + 1
    try:
        header = data[:end].decode("ascii").splitlines()
    except UnicodeDecodeError:
        raise MeshError(f"{path}: PLY header is not ASCII text") from None
    fmt, elements = None, []  # (name, count, fixed bytes per row, has a list)
    for lineno, line in enumerate(header, start=1):
        w = line.split()
        if not w or w[0] in ("ply", "comment", "obj_info"):
            continue
        if w[0] == "format":
            if len(w) < 2 or w[1] not in ("ascii", "binary_little_endian", "binary_big_endian"):
                raise MeshError(f"{path}:{lineno}: unknown PLY format '{clip(line.strip())}'")
            fmt = w[1]
        elif w[0] == "element":
            if len(w) != 3 or not w[2].isascii() or not w[2].isdigit():
                raise MeshError(f"{path}:{lineno}: expected 'element NAME COUNT', got '{clip(line.strip())}'")
            elements.append([w[1], int(w[2]), 0, False])
        elif w[0] == "property":
            if not elements:
                raise MeshError(f"{path}:{lineno}: a property before any element")
            types = w[2:4] if len(w) >= 2 and w[1] == "list" else w[1:2]
            if len(w) < (5 if w[1:2] == ["list"] else 3) or any(t not in _PLY_SIZES for t in types):
                raise MeshError(f"{path}:{lineno}: expected 'property TYPE NAME' with a PLY type, got "
                                f"'{clip(line.strip())}'")
            if w[1] == "list":
                elements[-1][2] += _PLY_SIZES[w[2]]
                elements[-1][3] = True
            else:
                elements[-1][2] += _PLY_SIZES[w[1]]
        else:
            raise MeshError(f"{path}:{lineno}: unknown PLY header line '{clip(line.strip())}'")
    if fmt is None:
        raise MeshError(f"{path}: PLY header has no 'format' line")
    body = len(data) - body_at
    rows = sum(e[1] for e in elements)
    if fmt == "ascii":
        lines = sum(1 for ln in data[body_at:].splitlines() if ln.strip())
        if lines != rows:
            raise MeshError(f"{path}: PLY header declares {rows} rows ("
                            + ", ".join(f"{e[1]} {e[0]}" for e in elements) + f") but the body has {lines} lines")
    elif sum(e[1] * e[2] for e in elements) > body:
        raise MeshError(f"{path}: PLY header declares " + ", ".join(f"{e[1]} {e[0]}" for e in elements)
                        + f": more than the {body} bytes after it hold (truncated?)")


#: The units of the 3MF specification (the ``unit`` attribute of ``<model>``), in mm.
UNITS_3MF = {"micron": 1e-3, "millimeter": 1.0, "centimeter": 10.0, "inch": 25.4, "foot": 304.8, "meter": 1000.0}
_UNIT_3MF = re.compile(rb"<(?:\w+:)?model\b[^>]*?\sunit\s*=\s*[\"']([^\"']*)[\"']", re.S)


def _check_3mf(path: Path, data: bytes) -> float:
    """Refuse a 3MF that is not a zip, has no model part, or would decompress past
    :data:`MAX_BYTES` (a zip bomb), before a reader unpacks it; return the model's unit in mm
    (its ``<model unit="...">``, millimeter when absent, as the specification says)."""
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            infos = z.infolist()
            models = [i for i in infos if i.filename.lower().endswith(".model")]
            if not models:
                raise MeshError(f"{path}: 3MF archive has no model part (3D/3dmodel.model)")
            size = sum(i.file_size for i in infos)
            if size > MAX_BYTES:
                raise MeshError(f"{path}: 3MF archive unpacks to {size / 1024**2:.0f} MiB, more than "
                                f"{MAX_BYTES // 1024**2} MiB; refusing to load")
            with z.open(models[0]) as fh:
                head = fh.read(4096)  # the <model> element opens the part
    except (zipfile.BadZipFile, zipfile.LargeZipFile, ValueError, OSError, EOFError, zlib.error) as exc:
        raise MeshError(f"{path}: not a 3MF file (not a readable zip archive: {exc})") from None
    m = _UNIT_3MF.search(head)
    unit = m.group(1).decode("ascii", "replace").strip().lower() if m else "millimeter"
    if unit not in UNITS_3MF:
        raise MeshError(f"{path}: 3MF model unit {clip(unit)!r}; expected one of " + ", ".join(UNITS_3MF))
    return UNITS_3MF[unit]


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
        return _read_ascii_stl(path, data), None
    if fmt == "obj":
        return _read_obj(path, data)
    if fmt == "ply":
        _check_ply(path, data)
    unit = 1.0
    if fmt == "3mf":
        unit = _check_3mf(path, data)
    import trimesh

    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):  # a warning on stderr is a second line
            warnings.simplefilter("ignore")
            loaded = trimesh.load(io.BytesIO(data), file_type=fmt, force="mesh", process=False)
    except Exception as exc:  # any reader failure on a user file is a user error
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise MeshError(f"{path}: cannot read as {fmt.upper()}: {msg}") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise MeshError(f"{path}: contains no triangles")
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    if unit != 1.0:  # a 3MF says its unit: read in mm (`--units`/`--scale` apply after)
        vertices = vertices * unit
    return vertices, np.asarray(loaded.faces, dtype=np.int64)


def _hole_hint(fraction: float) -> str:
    """What closes a hole whose perimeter is ``fraction`` x the bounding-box diagonal: the least
    ``mesh.max_hole_fraction`` (2 decimals, rounded up) and a round value to type; or, beyond the
    field's largest value, that the mesh needs a repair elsewhere."""
    hi = next(f.metadata["hi"] for f in fields(MeshSettings) if f.name == "max_hole_fraction")
    need = math.ceil(fraction * 100 - 1e-9) / 100
    if not need <= hi:
        return f"a hole of {fraction:.3g} x the diagonal is more than mesh.max_hole_fraction allows ({hi:g}); " \
               f"repair the mesh"
    typed = min(hi, math.ceil(fraction * 10 - 1e-9) / 10)
    return f"set mesh.max_hole_fraction >= {need:.2f} (--set mesh.max_hole_fraction={typed:g}) to close it"


#: The distinct vertices are ordered by a group chosen by a hash of their bits (one of this
#: many), then by their bits: the vertex numbering the loader has always given.
MERGE_GROUPS = 16


def _merge_vertices(v: np.ndarray, f: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Merge bit-identical vertices (STL stores every corner of every triangle, so this is what
    turns a soup into a mesh).

    ``v`` is float32 or float64 (modified in place: -0.0 becomes 0.0); ``f`` is ``None`` for a
    soup (vertices 3k, 3k+1, 3k+2 make triangle k). One pass with a hash table finds every
    vertex's first copy (:func:`~cooprint.io.mesh_kernels.first_copies`), so that only the
    distinct vertices (a sixth of a soup's) are sorted: by a group of ``MERGE_GROUPS`` chosen by
    a hash of their bits, then by their bit patterns. Returns the distinct vertices as float64
    in that order (the faces' vertex numbers, which the slicer's sections follow) and the faces
    re-indexed, in :func:`~cooprint.geometry.index_dtype`.
    """
    from cooprint.io.mesh_kernels import MIX, first_copies  # numba: on first use

    v += v.dtype.type(0)  # -0.0 -> 0.0, in place
    bits = v.view(np.uint32 if v.dtype == np.float32 else np.uint64).reshape(-1, 3)
    n = len(bits)
    dtype = index_dtype(n)
    local = np.empty(n, dtype=dtype)
    # a table at least twice the distinct vertices: a soup has about n / 6 of them, others up to n
    size_log2 = max(4, math.ceil(math.log2(max(n, 2))) + (-1 if f is None else 1))
    while True:
        first = np.empty(1 << (size_log2 - 1), dtype=dtype)
        u = first_copies(bits, size_log2, local, first)
        if u >= 0:
            break
        size_log2 += 2
    first = first[:u]
    ub = bits[first]
    mix = [np.uint64(m) for m in MIX]
    group = ub[:, 0].astype(np.uint64) * mix[0]  # wraps modulo 2**64
    group ^= ub[:, 1].astype(np.uint64) * mix[1]
    group ^= ub[:, 2].astype(np.uint64) * mix[2]
    group >>= np.uint64(64 - int(math.log2(MERGE_GROUPS)))
    if ub.dtype == np.uint32:  # two 64-bit keys: (group, x bits), (y bits, z bits)
        group <<= np.uint64(32)
        group |= ub[:, 0]
        order = np.lexsort(((ub[:, 1].astype(np.uint64) << np.uint64(32)) | ub[:, 2], group))
    else:
        order = np.lexsort((ub[:, 2], ub[:, 1], ub[:, 0], group))
    del ub, group
    rank = np.empty(u, dtype=dtype)
    rank[order] = np.arange(u, dtype=dtype)
    for lo in range(0, n, 1 << 16):  # in place, a slice at a time: the corners' vertex numbers
        local[lo:lo + (1 << 16)] = rank[local[lo:lo + (1 << 16)]]
    inverse = local
    del rank
    verts = np.take(v, first[order], axis=0).astype(np.float64)  # (take: 2-3x faster than indexing rows)
    return verts, (inverse.reshape(-1, 3) if f is None else inverse[f])


def to_manifold(vertices: np.ndarray, faces: np.ndarray) -> manifold3d.Manifold:
    """A closed mesh as a manifold3d object (about 1.5 s per million triangles)."""
    mesh = manifold3d.Mesh64(vert_properties=np.ascontiguousarray(vertices, dtype=np.float64),
                             tri_verts=np.ascontiguousarray(faces, dtype=np.uint64))
    return manifold3d.Manifold(mesh)


def _proper_faces(verts: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(m,) bool: triangles with three distinct corners, non-zero area, and not a repeat of an
    earlier triangle over the same three vertices (one compiled pass with a hash table of the
    triangles: :func:`~cooprint.io.mesh_kernels.proper_faces`)."""
    from cooprint.io.mesh_kernels import proper_faces  # numba: on first use

    keep = np.empty(len(faces), dtype=bool)
    proper_faces(np.asarray(verts, dtype=np.float64), faces, max(4, math.ceil(math.log2(max(2 * len(faces), 2)))), keep)
    return keep


def _repair(mesh: list, settings: MeshSettings, path: str, repairs: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """The slow path, for meshes that are not already closed and consistently wound: drop
    duplicate and zero-area triangles, fix the winding, close small holes. Takes ownership of
    ``mesh = [(vertices, faces)]`` (popped, so that replaced arrays die at once)."""
    from cooprint.io.repair import fill_loop, separate  # numba: the slow path only

    verts, faces = mesh.pop()
    keep = _proper_faces(verts, faces)
    if not keep.all():
        repairs.append(f"removed {int((~keep).sum())} degenerate or duplicate triangles")
        verts, faces = compact(verts, faces[keep])
    if len(faces) < 4:
        raise MeshError(f"{path}: only {len(faces)} usable triangles; not a solid")
    verts, faces, n_split, n_cut = separate(verts, faces)
    if n_split:
        repairs.append(f"split {n_split} non-manifold edges (shared by more than two triangles)")
    if n_cut:
        repairs.append(f"removed {n_cut} unconnected triangles (sharing no edge, or cut loose by the split)")
    if n_split or n_cut:
        verts, faces = compact(verts, faces)
    if len(faces) < 4:
        raise MeshError(f"{path}: only {len(faces)} connected triangles; not a solid")
    edges = open_edges(faces)  # None: a directed edge repeats, i.e. the winding is not consistent
    if edges is None:
        import trimesh  # ~1 s to import (scipy): only for this rare repair

        tm = trimesh.Trimesh(verts, faces, process=False, validate=False)
        trimesh.repair.fix_winding(tm)
        fixed = np.asarray(tm.faces, dtype=faces.dtype)
        flipped = int((fixed != faces).any(axis=1).sum())
        faces = fixed
        repairs.append(f"made triangle winding consistent ({flipped} triangles turned over)")
        edges = open_edges(faces)
    loops = None if edges is None else edge_loops(*edges)  # None: the boundary is not closed loops
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
                f"mesh.max_hole_fraction {settings.max_hole_fraction:g} x diagonal = {limit:.1f} mm); "
                + _hole_hint(max(perims) / diag if diag > 0 else math.inf))
        rim = np.zeros(len(verts), dtype=bool)
        rim[np.concatenate(loops)] = True
        e = faces[rim[faces].sum(axis=1) >= 2][:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2).astype(np.int64)
        e = np.sort(e[rim[e].all(axis=1)], axis=1)
        keys = np.unique(e[:, 0] * len(verts) + e[:, 1])  # the edges between boundary vertices
        del e, rim
        added, caps = [], []
        for lp in loops:
            new_v, cap = fill_loop(verts, lp, keys)
            cap[cap < 0] = len(verts) + sum(len(x) for x in added)  # the cap's new centre vertex
            added.append(new_v)
            caps.append(cap)
        verts = np.vstack([verts, *added])
        faces = np.vstack([faces, *(c.astype(faces.dtype) for c in caps)])
        repairs.append(f"closed {len(loops)} holes ({sum(len(lp) for lp in loops)} open edges, "
                       f"{sum(len(c) for c in caps)} triangles added)")
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
