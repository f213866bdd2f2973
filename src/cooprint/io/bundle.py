"""Output bundles and files, written atomically and without touching what cooprint did not write.

A bundle folder is recognised by its marker: ``job.json`` holding an object whose ``"format"``
starts with ``cooprint-job/``. The files cooprint writes in it are *its own* (:func:`owned`):
``job.json``, ``chunks.png``, ``chunks/<id>.stl``, ``robots/<robot>.coop`` and ``.gcode`` (or,
written with ``--compress``, ``.coop.gz`` and ``.gcode.gz``), the
derived outputs in ``sim/`` (``summary.json``, ``frames.npz``, ``gantt.png``, snapshots,
animations), and any file the old ``job.json`` names. Everything else in the folder is the
user's and is never removed or overwritten.

Writing a bundle (:func:`atomic_dir`):

* into a new folder: everything is written into a hidden temporary folder beside it, renamed
  into place only when complete (a failed or interrupted run leaves nothing);
* into an existing folder (empty, or a bundle with ``--force``; ``--out .`` included, which
  cannot be renamed): the new bundle is built whole in a hidden temporary folder *inside* it,
  then swapped in file by file with Ctrl-C held: the old bundle's own files are moved aside,
  the new ones renamed in (``job.json``, the marker, last), the old ones deleted. A failure
  before the swap leaves the old bundle as it was; a failure during it moves everything back.
  The user's files stay where they are and are reported ("kept 2 files that cooprint did not
  write: ...").

``--force`` is refused on a non-empty folder that is not a bundle, and on a folder that holds
an input of the command. cooprint never writes through a symlink: a bundle whose own entries
(``chunks/``, ``robots/``, ``sim/``, ``job.json``, any file it would replace, ``sim/summary.json``
...) are symlinks is refused before any work, since following them would change files outside
the bundle while reporting them as "kept". Single files (:func:`atomic_file`) are written beside their
destination and renamed over it; an existing file is replaced only with ``force``, or when it
is one of cooprint's derived outputs in a bundle's ``sim/``.
"""

from __future__ import annotations

import errno
import gzip
import json
import math
import mmap
import os
import queue
import re
import shutil
import stat
import sys
import tempfile
import threading
import zlib
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

import numpy as np

from cooprint.errors import OutputError
from cooprint.interrupts import check_interrupt, deferred_sigint
from cooprint.io.outputs import (TMP_PREFIX, check_output, check_writable, inputs_inside,
                                 remove_tree, same_file_as_input, special_kind, write_error)

#: ``job.json["format"]`` of every bundle starts with this.
BUNDLE_FORMAT = "cooprint-job/"
#: ``sim/summary.json["format"]`` starts with this.
SIM_FORMAT = "cooprint-sim/"
#: Folders of a bundle: cooprint writes into them, so a plain file there is in its way.
BUNDLE_FOLDERS = ("chunks", "robots", "sim")
#: The names of the derived outputs cooprint writes in ``sim/``.
SIM_NAMES = re.compile(r"summary\.json|frames\.npz|gantt\.png|snapshot(_\d+s)?\.png|animation\.(mp4|gif)|viewer\.html")
#: The first bytes of cooprint's ``sim/viewer.html`` (a file of that name without them is the user's).
VIEWER_MARKER = b"<!-- cooprint-viewer/"
_BUNDLE_NAMES = re.compile(r"job\.json|chunks\.png|chunks/(C|[LR]\d+)\.stl|robots/([A-Z]|R\d+)\.(coop|gcode)(\.gz)?")
#: job.json larger than this is not read to recognise a bundle (a marker is small).
_MARKER_LIMIT = 256 << 20

Notice = Callable[[str], None]


def read_json_object(path: Path) -> dict | None:
    """The JSON object in regular file ``path``, or None (missing, special, huge, not JSON)."""
    try:
        st = os.stat(path)
        if not stat.S_ISREG(st.st_mode) or st.st_size > _MARKER_LIMIT:
            return None  # a FIFO named job.json would block a reader forever
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):
        return None
    return data if isinstance(data, dict) else None


def bundle_record(folder: str | Path) -> dict | None:
    """The ``job.json`` record if ``folder`` is a cooprint bundle, else None."""
    record = read_json_object(Path(folder) / "job.json")
    if record is not None and str(record.get("format", "")).startswith(BUNDLE_FORMAT):
        return record
    return None


def is_bundle(folder: str | Path) -> bool:
    """Whether ``folder`` holds cooprint's marker: a ``job.json`` with a ``cooprint-job/`` format."""
    return bundle_record(folder) is not None


def is_sim_folder(folder: str | Path) -> bool:
    """Whether ``folder`` is cooprint's ``sim/``: that of a bundle, or one holding a
    ``summary.json`` with a ``cooprint-sim/`` format."""
    folder = Path(os.path.abspath(folder))
    if folder.name == "sim" and is_bundle(folder.parent):
        return True
    summary = read_json_object(folder / "summary.json")
    return summary is not None and str(summary.get("format", "")).startswith(SIM_FORMAT)


def is_derived_output(path: str | Path) -> bool:
    """Whether ``path`` is one of cooprint's derived outputs (a ``SIM_NAMES`` file in cooprint's
    ``sim/``, and for ``summary.json`` one whose format is cooprint's): ``simulate`` and
    ``render`` rewrite those without ``--force``."""
    path = Path(os.path.abspath(path))
    if path.name == "summary.json" and path.exists():  # the derived outputs that say whose they are
        summary = read_json_object(path)
        if summary is None or not str(summary.get("format", "")).startswith(SIM_FORMAT):
            return False
    if not _says_ours(path):
        return False
    return bool(SIM_NAMES.fullmatch(path.name)) and is_sim_folder(path.parent)


def _says_ours(path: Path) -> bool:
    """False for a ``viewer.html`` that does not begin with cooprint's marker (a user's page of
    that name, never replaced without ``--force``); True for every other path."""
    if path.name != "viewer.html" or not os.path.lexists(path):
        return True
    try:
        with open(path, "rb") as f:
            return f.read(len(VIEWER_MARKER)) == VIEWER_MARKER
    except OSError:
        return False


def _listed_files(record: dict | None) -> set[str]:
    """Relative paths of the files an old ``job.json`` says cooprint wrote."""
    names: set[str] = set()
    if not record:
        return names
    rows = [r for key in ("chunks", "robots") for r in (record.get(key) or []) if isinstance(r, dict)]
    for value in [record.get("picture")] + [r.get(k) for r in rows for k in ("file", "program", "gcode")]:
        if isinstance(value, str) and value and not value.startswith("/") and ".." not in value.split("/"):
            names.add(value)
    return names


def owned(rel: str, listed: Iterable[str] = ()) -> bool:
    """Whether bundle-relative path ``rel`` (``/``-separated) is a file cooprint writes."""
    if _BUNDLE_NAMES.fullmatch(rel) or rel in listed:
        return True
    return rel.startswith("sim/") and bool(SIM_NAMES.fullmatch(rel[4:]))


def _sim_owned(rel: str, listed: Iterable[str] = ()) -> bool:
    return bool(SIM_NAMES.fullmatch(rel))


def _owned_in(folder: Path, is_owned: Callable[..., bool]) -> Callable[..., bool]:
    """``is_owned`` for the files of ``folder``, a ``viewer.html`` only when it is cooprint's
    (:func:`_says_ours`): a user's page of that name is kept."""
    return lambda rel, listed=(): is_owned(rel, listed) and _says_ours(folder / rel)


def check_destination(out: str | Path, force: bool = False, inputs: Iterable[str | Path] = (),
                      need_bytes: int = 0) -> None:
    """Check a bundle folder before the work: a writable path (:func:`check_output`), not
    holding an input, and either missing, empty, or a cooprint bundle with ``force``."""
    p = check_output(out, folder=True, probe=False)
    held = inputs_inside(p, inputs)
    if held is not None:
        raise OutputError(f"{out}: holds {held}, an input of this command; choose another --out "
                          "(cooprint does not write where its inputs are)")
    if p.exists() and _entries(p):
        _check_replaceable(p, out, force)
    check_writable(out, folder=True, need_bytes=need_bytes)


def _check_replaceable(p: Path, out: str | Path, force: bool) -> None:
    if not is_bundle(p):
        if force:
            raise OutputError(f"{out}: is not a cooprint bundle (no job.json of cooprint's) and is not empty; "
                              "--force replaces only cooprint's own outputs: choose another --out")
        raise OutputError(f"{out}: folder exists, is not empty and is not a cooprint bundle; choose another --out")
    if not force:
        raise OutputError(f"{out}: holds a cooprint bundle; use --force to replace it "
                          "(files cooprint did not write are kept)")
    listed = _listed_files(bundle_record(p))
    _refuse_links(p, out, [*BUNDLE_FOLDERS, *(f for f in _walk(p)[0] if owned(f, listed))])
    _check_layout(p, out, BUNDLE_FOLDERS, ("job.json", "chunks.png"))


def _refuse_links(p: Path, shown: str | Path, names: Iterable[str]) -> None:
    """Refuse a symlink among the entries of ``p`` that cooprint replaces or writes into (a
    bundle's ``chunks/``, ``robots/``, ``sim/``, ``job.json`` ...): writing there would change
    files outside the bundle, which cooprint never does."""
    for name in names:
        if os.path.islink(p / name):
            raise OutputError(f"{Path(shown) / name}: is a symlink (to {os.readlink(p / name)}) where cooprint "
                              "writes its own output; cooprint never writes through symlinks: replace it "
                              "by a real file or folder, or choose another --out")


def check_sim_folder(folder: str | Path, need_bytes: int = 0) -> Path:
    """Check ``DIR/sim`` before writing derived outputs into it: it may be missing (it is made),
    must be a folder if it exists, and its parent must exist and be writable."""
    p = check_output(folder, folder=True, probe=False)
    _refuse_links(p.parent, Path(folder).parent, [p.name])  # a bundle's sim/ linked elsewhere
    if p.exists():
        _check_layout(p, folder, (), ())
        _refuse_links(p, folder, [n for n in os.listdir(p) if SIM_NAMES.fullmatch(n)])
    check_writable(folder, folder=True, need_bytes=need_bytes)
    return p


def _check_layout(p: Path, shown: str | Path, folders: Iterable[str], files: Iterable[str]) -> None:
    """Refuse plain files where cooprint writes folders, and folders where it writes files."""
    for name in folders:
        q = p / name
        if os.path.lexists(q) and not os.path.islink(q) and not q.is_dir():
            raise OutputError(f"{Path(shown) / name}: a file where cooprint writes a folder; move it away")
    for name in files:
        q = p / name
        if os.path.lexists(q):
            try:
                regular = stat.S_ISREG(os.stat(q).st_mode)
            except OSError:
                regular = False
            if not regular:
                raise OutputError(f"{Path(shown) / name}: not a regular file where cooprint writes one; move it away")


def _entries(folder: Path) -> list[str]:
    return [n for n in os.listdir(folder) if not n.startswith(TMP_PREFIX)]


def _walk(root: Path) -> tuple[list[str], list[str]]:
    """Files (and symlinks, and special files) under ``root`` as ``/``-separated relative paths,
    and the folders; cooprint's hidden temporary entries at the top are left out."""
    files, folders = [], []
    for here, dirs, names in os.walk(root):
        rel_here = os.path.relpath(here, root)
        prefix = "" if rel_here == "." else rel_here.replace(os.sep, "/") + "/"
        if not prefix:
            dirs[:] = [d for d in dirs if not d.startswith(TMP_PREFIX)]
            names = [n for n in names if not n.startswith(TMP_PREFIX)]
        links = [d for d in dirs if os.path.islink(os.path.join(here, d))]
        dirs[:] = sorted(d for d in dirs if d not in links)
        folders += [prefix + d for d in dirs]
        files += [prefix + n for n in sorted(names + links)]
    return files, folders


def _stderr_notice(message: str) -> None:
    print(f"cooprint: {message}", file=sys.stderr)


@contextmanager
def atomic_dir(out: str | Path, force: bool = False, *, inputs: Iterable[str | Path] = (),
               notice: Notice | None = _stderr_notice, sim: bool = False) -> Iterator[Path]:
    """Yield a temporary folder to fill; on success its files become ``out``'s.

    ``out`` missing: the folder is renamed into place. ``out`` existing (empty, or a bundle
    with ``force``; with ``sim``, a ``sim/`` folder of derived outputs): the files are swapped
    in (see the module docstring); files cooprint did not write are kept and reported through
    ``notice``. On any exception nothing is left behind and ``out`` is as it was; an OS error
    becomes a one-line :class:`OutputError`.
    """
    out = Path(out)
    inputs = tuple(inputs)
    p = check_sim_folder(out) if sim else Path(os.path.abspath(out))
    if not sim:
        check_destination(out, force, inputs)
    in_place = p.exists()
    listed = _listed_files(bundle_record(p)) if in_place and not sim else set()
    tmp: Path | None = None
    kept: list[str] = []
    try:
        with deferred_sigint():
            tmp = Path(tempfile.mkdtemp(prefix=TMP_PREFIX if in_place else f".{p.name}.", suffix=".tmp",
                                        dir=p if in_place else p.parent))
        new = tmp / "new" if in_place else tmp
        new.mkdir(exist_ok=True)
        yield new
        check_interrupt()  # a Ctrl-C some library swallowed: not committed
        with deferred_sigint():
            if in_place:
                kept = _swap_in(new, p, tmp / "old", _owned_in(p, _sim_owned if sim else owned), listed,
                                () if sim else BUNDLE_FOLDERS)
            else:
                _relax_permissions(tmp)
                os.rename(tmp, p)
                tmp = None
    except OSError as exc:
        raise output_error(out, exc, tmp) from None
    finally:
        if tmp is not None:
            remove_tree(tmp)
    if kept and notice is not None:
        if sim:  # named as from the bundle, where the user looks
            kept = [f"{p.name}/{rel}" for rel in kept]
        shown = ", ".join(kept[:5]) + (f" and {len(kept) - 5} more" if len(kept) > 5 else "")
        notice(f"kept {len(kept)} file{'s' if len(kept) > 1 else ''} that cooprint did not write: {shown}")


def _swap_in(new: Path, out: Path, old: Path, is_owned: Callable[..., bool], listed: set[str],
             folders: Iterable[str] = ()) -> list[str]:
    """Move the files under ``new`` into ``out`` in place of its cooprint files (moved to
    ``old`` first, deleted with it by the caller); undo everything on failure. Afterwards the
    ``folders`` of cooprint's (and those of the files it moved) that the new set does not
    have are removed if empty. Returns the files of ``out`` that are not cooprint's (kept)."""
    files, _ = _walk(out)
    mine = [f for f in files if is_owned(f, listed)]
    kept = [f for f in files if not is_owned(f, listed)]
    fresh, fresh_dirs = _walk(new)
    fresh.sort(key=lambda f: f == "job.json")  # the marker last: a half swap is still a bundle
    moved: list[str] = []
    installed: list[str] = []
    made: list[Path] = []
    marker_saved = False
    try:
        for rel in mine:
            (old / rel).parent.mkdir(parents=True, exist_ok=True)
            if rel == "job.json":  # keep the marker in place until the new one replaces it
                shutil.copy2(out / rel, old / rel)
                marker_saved = True
            else:
                os.replace(out / rel, old / rel)
                moved.append(rel)
        for rel in fresh:
            target = out / rel
            for parent in reversed(target.relative_to(out).parents[:-1]):
                d = out / parent
                if not d.is_dir():
                    d.mkdir()
                    made.append(d)
            os.replace(new / rel, target)
            installed.append(rel)
    except BaseException:
        for rel in reversed(installed):
            if rel == "job.json" and marker_saved:
                os.replace(old / rel, out / rel)
            else:
                (out / rel).unlink(missing_ok=True)
        for rel in reversed(moved):
            os.replace(old / rel, out / rel)
        for d in reversed(made):
            try:
                d.rmdir()
            except OSError:
                pass
        raise
    if marker_saved and "job.json" not in installed:
        (out / "job.json").unlink(missing_ok=True)  # the old marker, when the new bundle has none
    for name in sorted(set(folders) | {rel.split("/")[0] for rel in mine if "/" in rel}, reverse=True):
        d = out / name
        if d.is_dir() and name not in fresh_dirs and not any(d.iterdir()):
            d.rmdir()  # a folder of stale cooprint files only (robots/ after `chunk`)
    return kept


def check_file_destination(out: str | Path, force: bool = False, inputs: Iterable[str | Path] = (),
                           need_bytes: int = 0, create_parents: int = 0) -> Path:
    """Check a single output file before the work: a writable path (:func:`check_output`),
    not an input of the command, and not an existing file unless ``force`` or it is one of
    cooprint's derived outputs (:func:`is_derived_output`). Returns the absolute path."""
    p = check_output(out, folder=False, create_parents=create_parents, probe=False)
    if p.parent.name == "sim" and SIM_NAMES.fullmatch(p.name):  # a derived output: never through a link
        _refuse_links(p.parent.parent, Path(out).parent.parent, ["sim"])
        _refuse_links(p.parent, Path(out).parent, [p.name])
    same = same_file_as_input(p, inputs)
    if same is not None:
        raise OutputError(f"{out}: is {same}, an input of this command; choose another --out")
    for folder in (p.parent, p.parent.parent):  # job.json, chunks/C.stl, robots/A.gcode of a bundle
        rel = p.relative_to(folder).as_posix()
        if not rel.startswith("sim/") and owned(rel) and is_bundle(folder):
            raise OutputError(f"{out}: is part of the cooprint bundle {folder}; choose another --out")
    if p.exists() and not force and not is_derived_output(p):
        raise OutputError(f"{out}: exists; use --force to replace it")
    check_writable(out, folder=False, need_bytes=need_bytes)
    return p


@contextmanager
def atomic_file(out: str | Path, force: bool = False, *, inputs: Iterable[str | Path] = (),
                create_parents: int = 0) -> Iterator[Path]:
    """Yield a temporary path beside ``out`` (same suffix: encoders name their format from
    it); on success it is renamed to ``out``. ``out`` is checked as by
    :func:`check_file_destination`; missing parent folders (at most ``create_parents``) are
    made. On failure nothing is left behind (the folders made are removed again) and an OS
    error becomes a one-line :class:`OutputError`."""
    out = Path(out)
    p = check_file_destination(out, force, inputs, create_parents=create_parents)
    made: list[Path] = []
    tmp: Path | None = None
    try:
        for parent in reversed(p.parents):
            if len(made) < create_parents and not parent.exists():
                parent.mkdir()
                made.append(parent)
        with deferred_sigint():
            fd, name = tempfile.mkstemp(prefix=f".{p.name}.", suffix=f".tmp{p.suffix}", dir=p.parent)
            os.close(fd)
            tmp = Path(name)
        yield tmp
        check_interrupt()
        with deferred_sigint():
            _relax_permissions(tmp, 0o666)
            if os.path.lexists(p) and special_kind(os.lstat(p).st_mode):  # made since the check
                raise OutputError(f"{out}: became a special file while cooprint worked; nothing written")
            os.replace(tmp, p)
            tmp = None
            made.clear()
    except OSError as exc:
        raise output_error(out, exc, None) from None
    finally:
        if tmp is not None:
            remove_tree(tmp)
        for d in reversed(made):
            try:
                d.rmdir()
            except OSError:
                pass


def _relax_permissions(root: Path, mode: int = 0o777) -> None:
    """mkdtemp/mkstemp make private 0700/0600 entries; give them the user's usual permissions."""
    mask = os.umask(0)
    os.umask(mask)
    root.chmod(mode & ~mask)


def jsonable(obj: Any) -> Any:
    """``obj`` as JSON takes it: numpy values as Python's, floats rounded to 1e-9, NaN and
    infinities as ``None`` (what :func:`write_json` writes; the viewer's record too)."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, (np.floating, float)):
        f = float(obj)
        return round(f, 9) if math.isfinite(f) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def write_json(path: Path, data: Any) -> None:
    """Deterministic JSON: sorted keys are not used (order is meaningful); floats rounded to 1e-9."""
    with OutputFile(path) as fh:
        fh.write((json.dumps(jsonable(data), indent=2) + "\n").encode("utf-8"))


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
    with OutputFile(path) as fh:
        fh.write(header)
        fh.write(np.uint32(len(tri)).tobytes())
        fh.write(rec.tobytes())


# ----------------------------------------------------------------------------------------------
# output files: plain or gzip-compressed, and what a full disk says

#: zlib level of ``--compress``. Levels 1-3 are zlib's fast deflate: on the writers' output
#: level 2 compressed at about 180 MB/s (G-code 6.7x smaller, .coop 6x), level 6 (gzip's default)
#: at 50 MB/s for files only 20% smaller: the default would make compression the slowest step of
#: writing a plan.
GZIP_LEVEL = 2
#: The first two bytes of every gzip file.
GZIP_MAGIC = b"\x1f\x8b"
#: Errors of a file system that has no room left: the disk (ENOSPC) or the user's quota (EDQUOT).
_FULL = {errno.ENOSPC: "the disk is full (no space left on device)",
         **({errno.EDQUOT: "the disk quota is exceeded (EDQUOT)"} if hasattr(errno, "EDQUOT") else {})}
#: The opener of output files (tests put a file that fills up in its place).
_open_raw = open


def _named(exc: OSError, path: str | Path) -> OSError:
    """``exc`` naming the file it happened to (a write's error names none)."""
    if exc.filename is not None:
        return exc
    return OSError(exc.errno, exc.strerror or str(exc), str(path))


class OutputFile:
    """A binary output file, gzip-compressed (deterministically: no name, mtime 0) when
    ``compress``; written in large blocks. An OS error while writing or closing it names the
    file (:func:`output_error` turns it into one line).

    Compression runs on a thread of its own (zlib lets go of the interpreter while it works):
    the writer formats the next block while the last one is compressed. Blocks are handed over
    as copies, at most ``QUEUE`` waiting; an error of the thread is raised by the next
    :meth:`write` or by :meth:`close`.
    """

    QUEUE = 4

    def __init__(self, path: str | Path, compress: bool = False):
        self.path = Path(path)
        self._raw = _open_raw(self.path, "wb", buffering=1 << 20)
        self._gz = gzip.GzipFile(filename="", mode="wb", fileobj=self._raw, compresslevel=GZIP_LEVEL,
                                 mtime=0) if compress else None
        self._error: BaseException | None = None
        self._queue: queue.Queue | None = None
        if compress:
            self._queue = queue.Queue(self.QUEUE)
            self._thread = threading.Thread(target=self._compress, name="cooprint-gzip", daemon=True)
            self._thread.start()

    def _compress(self) -> None:
        assert self._queue is not None and self._gz is not None
        while True:
            block = self._queue.get()
            if block is None:
                return
            if self._error is None:  # after an error the rest is dropped (the writer stops at the next write)
                try:
                    self._gz.write(block)
                except BaseException as exc:
                    self._error = exc

    def _raise(self) -> None:
        if self._error is not None:
            exc, self._error = self._error, None
            if isinstance(exc, OSError):
                raise _named(exc, self.path) from None
            raise exc

    def write(self, data) -> int:
        if self._queue is not None:
            self._raise()
            block = bytes(data)
            self._queue.put(block)
            return len(block)
        try:
            return self._raw.write(data)
        except OSError as exc:
            raise _named(exc, self.path) from None

    def close(self) -> None:
        try:
            try:
                if self._queue is not None:
                    self._queue.put(None)
                    self._thread.join()
                    self._queue = None
                    self._raise()
                if self._gz is not None:
                    self._gz.close()  # the last compressed block and the trailer
            finally:
                self._raw.close()
        except OSError as exc:
            raise _named(exc, self.path) from None

    def __enter__(self) -> "OutputFile":
        return self

    def __exit__(self, kind, value, trace) -> None:
        if kind is None:
            self.close()
            return
        try:  # the error that stopped the writing is the one to report, not the file's
            self.close()
        except OSError:
            pass


def program_files(robot: str, compress: bool = False) -> tuple[str, str]:
    """A robot's ``.coop`` and G-code files in a bundle, relative to it (``robots/A.coop``,
    ``robots/A.gcode``; with ``compress`` the same with ``.gz``): job.json names them so."""
    gz = ".gz" if compress else ""
    return f"robots/{robot}.coop{gz}", f"robots/{robot}.gcode{gz}"


def open_output(path: str | Path, compress: bool = False) -> OutputFile:
    """Open an output file for writing (binary; gzip-compressed if ``compress``)."""
    return OutputFile(path, compress)


def open_program_files(folder: str | Path, robot: str, compress: bool = False) -> tuple[OutputFile, OutputFile]:
    """Open a robot's ``.coop`` and G-code files in bundle folder ``folder`` (as
    :func:`program_files` names them) for writing; the caller closes both."""
    coop, gcode = program_files(robot, compress)
    first = open_output(Path(folder) / coop, compress)
    try:
        return first, open_output(Path(folder) / gcode, compress)
    except BaseException:
        first.close()
        raise


def read_output(path: str | Path, error: type[Exception] = OutputError) -> bytes:
    """The bytes of a file cooprint wrote, decompressed if it is gzip (its first bytes say so,
    whatever its name). A file that is not valid gzip is ``error`` in one line."""
    with open(path, "rb") as fh:
        data = fh.read()
    if data[:2] != GZIP_MAGIC:
        return data
    try:
        return gzip.decompress(data)
    except (OSError, EOFError, zlib.error) as exc:  # gzip.BadGzipFile is an OSError
        raise error(f"{path}: not a valid gzip file ({exc or type(exc).__name__})") from None


def map_input(path: str | Path, error: type[Exception] = OutputError) -> "bytes | mmap.mmap":
    """The bytes of a file to read: mapped, not copied (its pages stay the page cache's); read
    when it cannot be mapped (an empty file, a pipe); read and decompressed when it is gzip
    (:func:`read_output`). OS errors are the caller's to word; :func:`release` it when done."""
    with open(path, "rb") as f:
        try:
            data: bytes | mmap.mmap = mmap.mmap(f.fileno(), 0, access=mmap.ACCESS_READ)
        except (OSError, ValueError):  # empty, or not a regular file: read it
            data = f.read()
    if bytes(data[:2]) == GZIP_MAGIC:
        release(data)
        data = read_output(path, error)
    return data


def release(data: "bytes | mmap.mmap") -> None:
    """Close what :func:`map_input` mapped (nothing to do for bytes)."""
    if isinstance(data, mmap.mmap):
        try:
            data.close()
        except BufferError:  # a view still held (by a traceback): the collector closes it
            pass


def plain_name(path: str | Path) -> Path:
    """``path`` without a ``.gz`` ending: ``robots/A.coop.gz`` -> ``robots/A.coop`` (its stem
    names the robot, its suffix the kind of file)."""
    p = Path(path)
    return p.with_name(p.name[:-3]) if p.name.lower().endswith(".gz") and len(p.name) > 3 else p


def is_gzip(path: str | Path) -> bool:
    """Whether the file at ``path`` starts as a gzip file does."""
    with open(path, "rb") as fh:
        return fh.read(2) == GZIP_MAGIC


def output_error(out: str | Path, exc: OSError, tmp: Path | None) -> OutputError:
    """An OS error while writing output ``out`` (a bundle folder built in ``tmp``, or a file)
    as one line; a full disk says so and which file it was writing."""
    reason = _FULL.get(exc.errno or 0)
    if reason is None:
        return write_error(out, exc)
    what = ""  # (a single file: ``out`` is what was being written)
    if exc.filename is not None and tmp is not None:
        name = os.path.abspath(exc.filename)
        if name.startswith(os.path.abspath(tmp) + os.sep):
            parts = Path(os.path.relpath(name, tmp)).parts
            what = "/".join(parts[1:] if parts[0] == "new" else parts)  # (in place: tmp/new/...)
        else:
            what = os.path.basename(name)
    return OutputError(f"{out}: {reason}" + (f" while writing {what}" if what else "") + "; nothing was written")
