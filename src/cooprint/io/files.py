"""Input files are checked to be regular files before they are opened.

Opening a named pipe (FIFO) for reading blocks until some other process opens it for writing,
which may be never; a character device (``/dev/zero``) never ends; a folder cannot be read. So
every reader of cooprint (meshes, ``.coop`` and G-code programs, manifests, ``job.json``,
settings files) calls :func:`regular_file` first and says in one line what the path is instead.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from cooprint.errors import UserError


class InputFileError(UserError):
    """An input path that is not a regular file (missing, a folder, a FIFO, a device)."""


_KINDS = ((stat.S_ISDIR, "is a folder"), (stat.S_ISFIFO, "is a named pipe (FIFO)"),
          (stat.S_ISCHR, "is a device"), (stat.S_ISBLK, "is a device"), (stat.S_ISSOCK, "is a socket"))


def regular_file(path: str | Path, what: str = "file",
                 error: type[UserError] = InputFileError) -> os.stat_result:
    """The ``os.stat`` of ``path`` (symlinks followed) if it is a regular file; otherwise
    ``error`` with one line: ``PATH: no such WHAT``, ``PATH: is a named pipe (FIFO), not a
    WHAT``, ``... is a folder ...``, ``... is a device ...``. Does not open the file."""
    try:
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        raise error(f"{path}: no such {what}") from None
    except OSError as exc:  # permission denied on a folder above, a symlink loop, a NUL in the name
        raise error(f"{path}: cannot read ({exc.strerror or exc})") from None
    except ValueError:
        raise error(f"{path!r}: not a valid path") from None
    if not stat.S_ISREG(st.st_mode):
        kind = next((name for test, name in _KINDS if test(st.st_mode)), "is not a regular file")
        raise error(f"{path}: {kind}, not a {what}")
    return st


def path_kind(path: str | Path, error: type[UserError] = InputFileError) -> str:
    """What ``path`` names (symlinks followed): ``"file"`` (regular), ``"folder"``, ``"missing"``
    or ``"other"`` (a FIFO, a device, a socket). A path that cannot be looked at (a name too
    long, a symlink loop, no permission on a folder above) is ``error`` in one line, never the
    ``OSError`` that ``Path.exists()`` lets through."""
    try:
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        return "missing"
    except OSError as exc:
        raise error(f"{str(path)[:80]}: cannot use this path ({exc.strerror or exc})") from None
    except ValueError:
        raise error(f"{str(path)[:80]!r}: not a valid path") from None
    return "file" if stat.S_ISREG(st.st_mode) else "folder" if stat.S_ISDIR(st.st_mode) else "other"


__all__ = ["InputFileError", "path_kind", "regular_file"]
