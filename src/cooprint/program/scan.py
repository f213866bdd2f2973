"""The ``.coop`` parser's fast pass: one compiled sweep over a file's bytes (numba).

Nearly every line of a program is ``MOVE x, y, z``, ``TOOL ON`` / ``TOOL OFF`` or a ``;@layer`` or
``;@path`` annotation; the sweep reads those, skips blank lines and plain comments, and hands
every other line (``;@chunk``, NOTIFY, WAIT, anything odd or wrong) to the line parser of
:mod:`.commands`, which is the reference. A
MOVE line is taken only in the plain form: the word ``MOVE`` at the start of the line, then three
decimal numbers (``-12.5``, ``+3``, ``.25``, ``7.``; at most 15 significant digits, no exponent)
separated by blanks or by single commas, nothing after them. Such a number is its digits as an
integer (exact in float64) divided by a power of ten (exact up to 10^22): one correctly rounded
division, the same double that ``float()`` gives.
"""

from __future__ import annotations

import numba
import numpy as np

from cooprint.program.commands import ROLE_WORDS

#: Line kinds the sweep reports.
OTHER, MOVE_LINE, TOOL_ON_LINE, TOOL_OFF_LINE, SKIP, LAYER_LINE, PATH_LINE = range(7)

_POW10 = np.array([10.0 ** k for k in range(23)])
# the annotation words the sweep knows: the path roles by number, then 'path' and 'layer'
_WORD_LIST = [ROLE_WORDS[r].encode() for r in range(len(ROLE_WORDS))] + [b"path", b"layer"]
_WORDS = np.frombuffer(b"".join(_WORD_LIST), np.uint8)
_WORD_STARTS = np.cumsum([0] + [len(w) for w in _WORD_LIST])


@numba.njit(cache=True, nogil=True)
def _blank(c):
    return c == 32 or c == 9


@numba.njit(cache=True, nogil=True)
def _number(buf, i, end, pow10):
    """The plain decimal number at ``buf[i:]`` (before ``end``): ``(value, next index)``, or
    ``(0.0, -1)`` when there is none in the plain form."""
    sign = 1.0
    c = buf[i] if i < end else 0
    if c == 45 or c == 43:  # '-' '+'
        if c == 45:
            sign = -1.0
        i += 1
    mant = 0.0
    digits = 0  # significant digits (leading zeros not counted)
    seen = 0  # digits of any kind
    frac = -1  # digits after the point; -1: no point yet
    while i < end:
        c = buf[i]
        if 48 <= c <= 57:
            seen += 1
            if digits or c != 48:
                digits += 1
            mant = mant * 10.0 + (c - 48)
            if frac >= 0:
                frac += 1
        elif c == 46 and frac < 0:  # '.'
            frac = 0
        else:
            break
        i += 1
    if seen == 0 or digits > 15 or frac > 22:
        return 0.0, -1
    if i < end:
        c = buf[i]
        if not (c == 32 or c == 9 or c == 44 or c == 13):  # blank, comma or CR: anything else is odd
            return 0.0, -1
    if frac > 0:
        mant = mant / pow10[frac]
    return sign * mant, i


@numba.njit(cache=True, nogil=True)
def _starts_with(buf, a, end, text):
    """Whether ``buf[a:end]`` begins with ``text``."""
    if end - a < len(text):
        return False
    for k in range(len(text)):
        if buf[a + k] != text[k]:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def _word_end(buf, i, end):
    """The end of the word at ``i`` (the next blank, carriage return or line end)."""
    while i < end and not (_blank(buf[i]) or buf[i] == 13):
        i += 1
    return i


@numba.njit(cache=True, nogil=True)
def _annotation(buf, a, end, pow10, words, word_starts):
    """The annotation at ``buf[a:end]`` (after its ``;@``) of a ``;@layer INDEX HEIGHT``,
    ``;@layer -`` or ``;@path ROLE WIDTH`` line in the plain form
    (lower case, a plain index and decimal number, blanks between): ``(kind, value, number)``
    with ``value`` the index (-1 for '-') or the role (the position of its word in ``words``),
    or ``(OTHER, 0, 0)``."""
    layer = _starts_with(buf, a, end, words[word_starts[-2]:word_starts[-1]])  # 'layer' is the last word
    if layer:
        i = a + 5
    elif _starts_with(buf, a, end, words[word_starts[-3]:word_starts[-2]]):  # 'path', the one before
        i = a + 4
    else:
        return OTHER, 0, 0.0
    if i >= end or not _blank(buf[i]):
        return OTHER, 0, 0.0
    while i < end and _blank(buf[i]):
        i += 1
    e = _word_end(buf, i, end)
    value = -2
    if layer:
        if e == i + 1 and buf[i] == 45:  # '-'
            value = -1
        elif e - i <= 9:
            value = 0
            for j in range(i, e):
                if not 48 <= buf[j] <= 57:
                    return OTHER, 0, 0.0
                value = value * 10 + buf[j] - 48
    else:
        for w in range(len(word_starts) - 3):  # the roles
            word = words[word_starts[w]:word_starts[w + 1]]
            if e - i == len(word) and _starts_with(buf, i, e, word):
                value = w
    if value == -2 or e == i:
        return OTHER, 0, 0.0
    i = e
    while i < end and _blank(buf[i]):
        i += 1
    number = 0.0
    if value != -1 or not layer:
        number, i = _number(buf, i, end, pow10)
        if i < 0 or not (number > 0 or (not layer and number == 0)):
            return OTHER, 0, 0.0
    while i < end and (_blank(buf[i]) or buf[i] == 13):
        i += 1
    if i != end:
        return OTHER, 0, 0.0
    return (LAYER_LINE if layer else PATH_LINE), value, number


@numba.njit(cache=True, nogil=True)
def _is_text(buf, a, end, text):
    """Whether ``buf[a:end]`` is ``text`` (a trailing carriage return ignored)."""
    n = len(text)
    if end > a and buf[end - 1] == 13:
        end -= 1
    if end - a != n:
        return False
    for k in range(n):
        if buf[a + k] != text[k]:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def _sweep(buf, pow10, tool_on, tool_off, words, word_starts, kind, starts, xyz):
    n = len(buf)
    lines = len(kind)
    a = 0
    for li in range(lines):
        end = a
        while end < n and buf[end] != 10:
            end += 1
        starts[li] = a
        k = OTHER
        if end - a >= 5 and buf[a] == 77 and buf[a + 1] == 79 and buf[a + 2] == 86 and buf[a + 3] == 69 \
                and _blank(buf[a + 4]):  # 'MOVE '
            i = a + 5
            ok = True
            for j in range(3):
                while i < end and _blank(buf[i]):
                    i += 1
                if j > 0 and i < end and buf[i] == 44:  # one comma between numbers
                    i += 1
                    while i < end and _blank(buf[i]):
                        i += 1
                v, i = _number(buf, i, end, pow10)
                if i < 0:
                    ok = False
                    break
                xyz[li, j] = v
            if ok:
                while i < end and (_blank(buf[i]) or buf[i] == 13):
                    i += 1
                if i == end:
                    k = MOVE_LINE
        elif end - a >= 7 and buf[a] == 84 and _is_text(buf, a, end, tool_on):
            k = TOOL_ON_LINE
        elif end - a >= 8 and buf[a] == 84 and _is_text(buf, a, end, tool_off):
            k = TOOL_OFF_LINE
        else:
            i = a
            while i < end and (_blank(buf[i]) or buf[i] == 13):
                i += 1
            if i == end:
                k = SKIP
            elif i == a and end - a > 2 and buf[a] == 59 and buf[a + 1] == 64:  # ';@' at the start
                k, value, number = _annotation(buf, a + 2, end, pow10, words, word_starts)
                xyz[li, 0], xyz[li, 1] = value, number
            elif buf[i] == 35 or (buf[i] == 59 and not (i + 1 < end and buf[i + 1] == 64)):  # '#', ';' not ';@'
                k = SKIP
                for j in range(i, end):  # non-ASCII text: the line parser checks it is UTF-8
                    if buf[j] >= 128:
                        k = OTHER
                        break
        kind[li] = k
        a = end + 1
    starts[lines] = n + 1


def sweep(data: bytes) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Classify every line of ``data`` and read its plain MOVEs.

    Returns
    -------
    kind : (lines,) int8
        ``OTHER`` (for the line parser), ``MOVE_LINE``, ``TOOL_ON_LINE``, ``TOOL_OFF_LINE``,
        ``SKIP`` (blank, or a comment that is not an annotation), ``LAYER_LINE`` or
        ``PATH_LINE``.
    starts : (lines + 1,) int64
        Where each line begins; line ``i`` is ``data[starts[i]:starts[i + 1] - 1]``.
    xyz : (lines, 3) float64
        The coordinates of the ``MOVE_LINE`` lines; of a ``LAYER_LINE``, the index (-1: '-') and
        the height; of a ``PATH_LINE``, the role (``cooprint.slicing.paths``) and the width
        (other rows undefined).
    """
    buf = np.frombuffer(data, dtype=np.uint8)
    lines = data.count(b"\n") + 1
    # the results allocated here: numpy asks the OS for huge pages for large arrays
    kind, starts, xyz = np.empty(lines, np.int8), np.empty(lines + 1, np.int64), np.empty((lines, 3))
    _sweep(buf, _POW10, np.frombuffer(b"TOOL ON", np.uint8), np.frombuffer(b"TOOL OFF", np.uint8), _WORDS,
           _WORD_STARTS, kind, starts, xyz)
    return kind, starts, xyz


__all__ = ["LAYER_LINE", "MOVE_LINE", "OTHER", "PATH_LINE", "SKIP", "TOOL_OFF_LINE", "TOOL_ON_LINE", "sweep"]
