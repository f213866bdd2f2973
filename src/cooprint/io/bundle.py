"""Atomic output folders.

A run writes its whole bundle into a hidden temporary folder beside the destination and renames it
into place only when everything succeeded, so a failed or interrupted run leaves no half-written
bundle, and an existing folder is replaced only when the user asked for it (``force``).
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import numpy as np

from cooprint.errors import UserError


def check_destination(out: Path, force: bool) -> None:
    """Refuse to touch an existing, non-empty ``out`` unless ``force``; fail early, before work."""
    if out.exists() and not out.is_dir():
        raise UserError(f"{out}: exists and is not a folder; choose another --out")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise UserError(f"{out}: folder exists and is not empty; use --force to replace it")
    parent = out.resolve().parent
    if not parent.is_dir():
        raise UserError(f"{out}: parent folder {parent} does not exist")


@contextmanager
def atomic_dir(out: str | Path, force: bool = False) -> Iterator[Path]:
    """Yield a temporary folder; on success it becomes ``out`` (replacing it if ``force``).

    On any exception the temporary folder is removed and ``out`` is left as it was.
    """
    out = Path(out)
    check_destination(out, force)
    parent = out.resolve().parent
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=parent))
    try:
        yield tmp
        _relax_permissions(tmp)
        old = None
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".old", dir=parent))
            out.replace(old / "x")
        tmp.replace(out)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def check_file_destination(out: Path, force: bool) -> None:
    """Refuse an existing file unless ``force``, a folder, or a missing parent; fail early."""
    if out.is_dir():
        raise UserError(f"{out}: is a folder; give a file name")
    if out.exists() and not force:
        raise UserError(f"{out}: exists; use --force to replace it")
    if not out.resolve().parent.is_dir():
        raise UserError(f"{out}: parent folder {out.resolve().parent} does not exist")


@contextmanager
def atomic_file(out: str | Path, force: bool = False) -> Iterator[Path]:
    """Yield a temporary path beside ``out``; on success it is renamed to ``out``. An existing
    ``out`` is refused unless ``force``; on failure nothing is left behind."""
    out = Path(out)
    check_file_destination(out, force)
    fd, name = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.resolve().parent)
    import os

    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        _relax_permissions(tmp, 0o666)
        tmp.replace(out)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def _relax_permissions(root: Path, mode: int = 0o777) -> None:
    """mkdtemp/mkstemp make private 0700/0600 entries; give them the user's usual permissions."""
    import os

    mask = os.umask(0)
    os.umask(mask)
    root.chmod(mode & ~mask)


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        f = float(obj)
        return round(f, 9) if math.isfinite(f) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def write_json(path: Path, data: Any) -> None:
    """Deterministic JSON: sorted keys are not used (order is meaningful); floats rounded to 1e-9."""
    path.write_text(json.dumps(_jsonable(data), indent=2) + "\n", encoding="utf-8")


def write_stl(path: Path, vertices: np.ndarray, faces: np.ndarray, name: str = "cooprint") -> None:
    """Binary STL of a triangle mesh, written with one numpy record array (no per-face Python)."""
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    rec = np.zeros(len(tri), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")])
    rec["n"] = normals
    rec["v"] = tri
    header = f"{name} (cooprint)".encode("ascii", "replace")[:80].ljust(80, b" ")
    with open(path, "wb") as fh:
        fh.write(header)
        fh.write(np.uint32(len(tri)).tobytes())
        fh.write(rec.tobytes())
