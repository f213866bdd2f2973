"""Errors a user can cause and fix.

Every stage raises :class:`UserError` (or a subclass) for bad input; the CLI turns it into a
one-line message on stderr and exit code 2. Anything else is a bug and keeps its traceback.
"""

from __future__ import annotations


class UserError(Exception):
    """Bad input: a file, a field or a value the user can correct. Exit code 2."""

    exit_code = 2


class ConfigError(UserError):
    """A setting is missing, of the wrong type or out of range."""


class MeshError(UserError):
    """A mesh file cannot be read, or cannot be made into a watertight solid."""


class InfeasibleError(UserError):
    """The job cannot be printed by the given robots (slope or reach limits)."""


def warn(message: str) -> None:
    """A warning the user must see: one line ``cooprint: warning: ...`` on stderr (the command
    goes on). Used where a result is valid but probably not what was meant (a part in metres)."""
    import sys

    text = " ".join(str(message).split())
    print(f"cooprint: warning: {text}", file=sys.stderr, flush=True)


class OutputError(UserError):
    """An output path cannot be written: a special file, a folder of someone else's, no room, a
    read-only file system. One line naming the path and the reason; nothing is left behind."""


#: At most this many characters of an input token are quoted in an error message.
CLIP = 40


def clip(text: str, limit: int = CLIP) -> str:
    """A token of the input as an error message quotes it: at most ``limit`` characters, and how
    long it was (a 10 MB token is never echoed whole)."""
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"
