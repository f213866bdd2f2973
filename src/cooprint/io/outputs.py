"""Output paths: checked before the work, and every failure to write as one line.

Every command that writes calls :func:`check_output` on its destination before any heavy work
(loading, cutting, slicing, simulating), so that a destination that cannot be written is refused
in a second, not after an hour. The rules, and their reasons:

* not under ``/proc`` or ``/sys``: virtual file systems, whose "files" are kernel interfaces;
* not a special file (character or block device such as ``/dev/full``, FIFO, socket), even with
  ``--force``: the atomic writer renames its finished file over the destination, which would
  replace the device node itself;
* not a dangling (or looping) symlink: what it names does not exist, and the rename would
  replace the link;
* the parent is a folder (not a plain file), exists (only the folders cooprint makes itself,
  ``sim/``, may be missing), and can be written: ``os.access`` on it and a real probe file
  created and removed (which also catches read-only mounts and immutable folders, and works
  when the process runs as root, where permission bits do not stop it);
* enough free space where ``shutil.disk_usage`` can tell, against a deliberately low estimate
  (refused only when clearly short).

A write that fails anyway (``ENOSPC``, ``EROFS``, ``EACCES`` ...) is turned by
:func:`write_error` into an :class:`~cooprint.errors.OutputError` naming the path, the OS reason
and its errno name; the atomic writers (:mod:`cooprint.io.bundle`) remove their temporary files
first. :func:`deferred_sigint` keeps Ctrl-C from cutting a rename sequence or a clean-up in half.
"""

from __future__ import annotations

import errno
import os
import shutil
import stat
import tempfile
from pathlib import Path
from typing import Iterable

from cooprint.errors import OutputError
from cooprint.interrupts import deferred_sigint

#: Virtual file systems: writing there talks to the kernel, never makes a file.
VIRTUAL_ROOTS = ("/proc", "/sys")
#: Prefix of every hidden temporary entry cooprint makes (probe files, temporary folders).
TMP_PREFIX = ".cooprint."

_SPECIAL = ((stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
            (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISSOCK, "a socket"))


def special_kind(mode: int) -> str | None:
    """What kind of special file ``mode`` (from ``os.stat``) is, or ``None`` for a regular file,
    a folder or a symlink."""
    for test, name in _SPECIAL:
        if test(mode):
            return name
    return None


def write_error(path: str | Path, exc: OSError) -> OutputError:
    """An OS error while writing ``path`` as one line: path, reason, errno name."""
    code = errno.errorcode.get(exc.errno or 0, "")
    reason = exc.strerror or str(exc) or type(exc).__name__
    return OutputError(f"{path}: cannot write: {reason}" + (f" ({code})" if code else ""))


def _under(path: str, roots: Iterable[str]) -> str | None:
    for root in roots:
        if path == root or path.startswith(root + os.sep):
            return root
    return None


def _nearest_existing(path: Path, shown: str | Path) -> Path:
    """``path`` or its nearest ancestor that exists (following symlinks); a dangling symlink
    on the way is refused (a folder made there would fail, or land where it points)."""
    p = path
    while not os.path.exists(p) and p != p.parent:
        if os.path.islink(p):
            raise OutputError(f"{shown}: {p} is a dangling symlink (to {os.readlink(p)}); remove it or choose another --out")
        p = p.parent
    return p


def probe_write(folder: Path, name: str | Path) -> None:
    """Create and remove a hidden file in ``folder``; an :class:`OutputError` if that fails
    (read-only file system, immutable folder, no permission, no inodes left)."""
    with deferred_sigint():  # made and removed as one step: a Ctrl-C never leaves the probe behind
        try:
            fd, probe = tempfile.mkstemp(prefix=TMP_PREFIX + "probe.", dir=folder)
        except OSError as exc:
            raise OutputError(f"{name}: cannot write in {folder}: {exc.strerror or exc}"
                              + (f" ({errno.errorcode.get(exc.errno or 0, '')})" if exc.errno else "")) from None
        os.close(fd)
        try:
            os.unlink(probe)
        except OSError:
            pass


def check_output(path: str | Path, *, folder: bool, need_bytes: int = 0, create_parents: int = 0,
                 probe: bool = True) -> Path:
    """Check that ``path`` can be written as a folder (``folder``) or a file; return it absolute.

    ``create_parents`` is how many missing folders above ``path`` the caller will make itself
    (``DIR/sim/`` of a bundle not yet simulated: 1). ``need_bytes`` is a low estimate of what
    will be written. With ``probe`` (the default) it ends with :func:`check_writable`; callers
    with refusals of their own make those first and then call it, so that a refused command
    does not even touch the folder's modification time. Raises :class:`OutputError` (one line)
    for anything that cannot work; see the module docstring for the rules.
    """
    text = os.fspath(path)
    if not text:
        raise OutputError("--out '': an empty path; give a file or folder name")
    if "\x00" in text:
        raise OutputError(f"{text!r}: a path with a NUL character")
    p = Path(os.path.abspath(text))
    for shown in (str(p), os.path.realpath(p)):
        root = _under(shown, VIRTUAL_ROOTS)
        if root:
            raise OutputError(f"{path}: is under {root}, a virtual file system of the kernel; choose another --out")
    try:
        st = os.lstat(p)
    except FileNotFoundError:
        st = None
    except NotADirectoryError:
        st = None  # a component above is a file: reported below with its name
    except OSError as exc:
        raise write_error(path, exc) from None
    if st is not None and stat.S_ISLNK(st.st_mode):
        try:
            st = os.stat(p)
        except OSError:
            raise OutputError(f"{path}: is a dangling symlink (to {os.readlink(p)}); "
                              "remove it or choose another --out") from None
    if st is not None:
        kind = special_kind(st.st_mode)
        if kind:
            raise OutputError(f"{path}: is {kind}, not a regular {'folder' if folder else 'file'}; "
                              "cooprint never writes over special files, even with --force")
        if folder and not stat.S_ISDIR(st.st_mode):
            raise OutputError(f"{path}: exists and is not a folder; choose another --out")
        if not folder and stat.S_ISDIR(st.st_mode):
            raise OutputError(f"{path}: is a folder; give a file name")
    anchor = _nearest_existing(p.parent, path)
    if not anchor.is_dir():
        raise OutputError(f"{path}: {anchor} is a file, not a folder")
    missing = len(p.parent.relative_to(anchor).parts) if anchor != p.parent else 0
    if missing > create_parents:
        first_missing = anchor / p.parent.relative_to(anchor).parts[0]
        raise OutputError(f"{path}: parent folder {p.parent if create_parents == 0 else first_missing} does not exist")
    if probe:
        check_writable(path, folder=folder, need_bytes=need_bytes)
    return p


def check_writable(path: str | Path, *, folder: bool, need_bytes: int = 0) -> None:
    """The writing half of :func:`check_output` (which must have passed): the folder that will
    be written (an existing output folder itself, else the nearest existing parent) is
    writable (``os.access`` and a probe file made and removed) and has ``need_bytes`` free."""
    p = Path(os.path.abspath(path))
    here = p if folder and p.is_dir() else _nearest_existing(p.parent, path)
    if not os.access(here, os.W_OK | os.X_OK):
        raise OutputError(f"{path}: {here} is not writable (permission denied or read-only)")
    probe_write(here, path)
    if need_bytes > 0:
        try:
            free = shutil.disk_usage(here).free
        except OSError:
            free = None
        if free is not None and free < need_bytes:
            raise OutputError(f"{path}: about {_mb(need_bytes)} needed, only {_mb(free)} free on its file system")


def _mb(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n < 1e9 else f"{n / 1e9:.1f} GB"


def estimate_bytes(inputs: Iterable[str | Path], factor: float) -> int:
    """A low estimate of the output size: ``factor`` times the inputs' size (a gzipped mesh
    counted four times), plus 64 kB. Low on purpose: free space is refused only when clearly short."""
    total = 0
    for x in _paths(inputs):
        try:
            size = os.stat(x).st_size
        except (OSError, ValueError):
            continue
        total += size * (4 if str(x).lower().endswith(".gz") else 1)
    return int(total * factor) + 65536


def _paths(inputs: Iterable[object]) -> list[str | Path]:
    """The file paths among ``inputs`` (the Python API also takes loaded solids, and None)."""
    return [x for x in inputs if isinstance(x, (str, os.PathLike)) and os.fspath(x)]


def inputs_inside(folder: Path, inputs: Iterable[object]) -> str | None:
    """The first of ``inputs`` that lies in ``folder`` (or is it), symlinks resolved; else None."""
    root = os.path.realpath(folder)
    for x in _paths(inputs):
        if not os.path.exists(x):
            continue
        real = os.path.realpath(x)
        if real == root or real.startswith(root.rstrip(os.sep) + os.sep):
            return str(x)
    return None


def same_file_as_input(path: Path, inputs: Iterable[object]) -> str | None:
    """The first of ``inputs`` that is the same file as ``path`` (hard links too); else None."""
    if not os.path.exists(path):
        return None
    for x in _paths(inputs):
        try:
            if os.path.samefile(path, x):
                return str(x)
        except OSError:
            continue
    return None


def remove_tree(path: Path) -> None:
    """Remove a temporary file or folder, Ctrl-C held until it is gone."""
    with deferred_sigint():
        if os.path.isdir(path) and not os.path.islink(path):
            shutil.rmtree(path, ignore_errors=True)
        else:
            try:
                os.unlink(path)
            except FileNotFoundError:
                pass
            except OSError:
                pass
