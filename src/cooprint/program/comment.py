"""Text made safe for one comment line of a G-code or ``.coop`` file.

A comment runs to the end of its line, so any line break inside a text put there (a mesh file
named ``"evil\\nG28 X0.stl"``, a robot profile name, a note) would end the comment and make the
rest a live command. :func:`comment_safe` is the one place both writers (:mod:`cooprint.program.gcode`
and :func:`cooprint.program.commands.write_coop`) pass such texts through.
"""

from __future__ import annotations

import unicodedata

#: Longest text kept in one comment line (room for a long header line; a pathological text is cut).
COMMENT_LIMIT = 1000
_NAMED = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def _escape(ch: str) -> str:
    if ch in _NAMED:
        return _NAMED[ch]
    code = ord(ch)
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def comment_safe(text: object, *, ascii_only: bool = False, limit: int = COMMENT_LIMIT) -> str:
    """``text`` as one line: every control character (C0, DEL, C1 such as U+0085) and every
    line or paragraph separator (U+2028, U+2029) replaced by a visible escape (``\\n``,
    ``\\x1b``, ``\\u2028``); with ``ascii_only`` (G-code files are ASCII) every non-ASCII
    character too; cut to ``limit`` characters with ``...``."""
    out = []
    for ch in str(text):
        cat = unicodedata.category(ch)
        unsafe = cat in ("Cc", "Zl", "Zp", "Cs") or (ascii_only and ord(ch) > 0x7E)
        out.append(_escape(ch) if unsafe else ch)
    line = "".join(out)
    return line if len(line) <= limit else line[:limit - 3] + "..."


__all__ = ["COMMENT_LIMIT", "comment_safe"]
