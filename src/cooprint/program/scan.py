"""The ``.coop`` parser's fast pass: one compiled sweep over a file's bytes (numba).

Nearly every line of a program is ``MOVE x, y, z``, ``TOOL ON`` / ``TOOL OFF`` or a ``;@layer`` or
``;@path`` annotation; the sweep reads those, skips blank lines and plain comments, and hands
every other line (``;@chunk``, NOTIFY, WAIT, anything odd or wrong) to the line parser of
:mod:`.commands`, which is the reference. A MOVE line is taken only in the plain form: the word
``MOVE`` at the start of the line, then three decimal numbers (``-12.5``, ``+3``, ``.25``, ``7.``; at most 15 significant digits, no exponent)
separated by blanks or by single commas, nothing after them, each at most ``MAX_COORD_MM`` from 0
(a MOVE past it goes to the line parser, which refuses it). Such a number is its digits as an
integer (exact in float64) divided by a power of ten (exact up to 10^22): one correctly rounded
division, the same double that ``float()`` gives.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from cooprint.geometry import MAX_COORD_MM
from cooprint import jit
from cooprint.program.commands import ANNOTATION_MAX_MM, MOVE, ROLE_WORDS, TOOL_OFF, TOOL_ON

jit.setup()  # Ctrl-C held while numba compiles; LLVM calls untimed (cooprint.jit)

#: Kinds of line the sweep tells apart.
OTHER, MOVE_LINE, TOOL_ON_LINE, TOOL_OFF_LINE, SKIP, LAYER_LINE, PATH_LINE = range(7)

#: 10**0 .. 10**22, all exact in float64: a plain decimal's digits over one of them is the
#: correctly rounded value, the double ``float()`` gives.
POW10 = np.array([10.0 ** k for k in range(23)])
# the annotation words the sweep knows: the path roles by number, then 'path' and 'layer'
_WORD_LIST = [ROLE_WORDS[r].encode() for r in range(len(ROLE_WORDS))] + [b"path", b"layer"]
_WORDS = np.frombuffer(b"".join(_WORD_LIST), np.uint8)
_WORD_STARTS = np.cumsum([0] + [len(w) for w in _WORD_LIST])
#: The largest coordinate and the largest annotation number the sweep takes.
_LIMITS = np.array([MAX_COORD_MM, ANNOTATION_MAX_MM])
#: The helpers called for every number and word: inlined into the sweep (a call passes each
#: array with a reference count taken and dropped, atomic operations that cost more than the
#: helper's work: nefertiti's 63 MB program was read in 0.31 s, 165 ns a MOVE line).
_inline = numba.njit(cache=True, nogil=True, inline="always")


@_inline
def _blank(c):
    return c == 32 or c == 9


@_inline
def decimal(buf, i, end, pow10):
    """The plain decimal number at ``buf[i:end]`` (a sign, digits, at most one point; at most 15
    significant digits and 22 after the point), up to the first byte that cannot continue it:
    ``(value, next index, bytes read)``; ``(0.0, i, 0)`` when there is nothing of a number there,
    and a next index of -1 when what is there is not a plain number (a lone sign or point, too
    many digits). ``pow10`` holds 10**0 .. 10**22 (:data:`POW10`)."""
    a = i
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
    if i == a:
        return 0.0, i, 0
    if seen == 0 or digits > 15 or frac > 22:
        return 0.0, -1, 0
    if frac > 0:
        mant = mant / pow10[frac]
    return sign * mant, i, i - a


@_inline
def _number(buf, i, end, pow10):
    """The plain decimal number at ``buf[i:]`` (before ``end``) followed by a blank, a comma, a
    carriage return or the end: ``(value, next index)``, or ``(0.0, -1)`` when there is none."""
    v, i, size = decimal(buf, i, end, pow10)
    if i < 0 or size == 0 or (i < end and not (_blank(buf[i]) or buf[i] == 44 or buf[i] == 13)):
        return 0.0, -1
    return v, i


@_inline
def _starts_with(buf, a, end, text):
    """Whether ``buf[a:end]`` begins with ``text``."""
    if end - a < len(text):
        return False
    for k in range(len(text)):
        if buf[a + k] != text[k]:
            return False
    return True


@_inline
def _word_end(buf, i, end):
    """The end of the word at ``i`` (the next blank, carriage return or line end)."""
    while i < end and not (_blank(buf[i]) or buf[i] == 13):
        i += 1
    return i


@numba.njit(cache=True, nogil=True)
def _annotation(buf, a, end, pow10, words, word_starts, top):
    """The annotation at ``buf[a:end]`` (after its ``;@``) of a ``;@layer INDEX HEIGHT``,
    ``;@layer -`` or ``;@path ROLE WIDTH`` line in the plain form
    (lower case, a plain index and decimal number, blanks between; the number at most ``top``
    mm, a height above 0, a width at least 0): ``(kind, value, number)``
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
        if i < 0 or not (number > 0 or (not layer and number == 0)) or number > top:
            return OTHER, 0, 0.0
    while i < end and (_blank(buf[i]) or buf[i] == 13):
        i += 1
    if i != end:
        return OTHER, 0, 0.0
    return (LAYER_LINE if layer else PATH_LINE), value, number


@_inline
def _is_text(buf, a, end, text):
    """Whether ``buf[a:end]`` is ``text`` (a trailing carriage return ignored)."""
    if end > a and buf[end - 1] == 13:
        end -= 1
    return end - a == len(text) and _starts_with(buf, a, end, text)


@numba.njit(cache=True, nogil=True)
def _lines(buf):
    """How many lines ``buf`` has (its newlines plus one)."""
    k = 1
    for c in buf:
        if c == 10:
            k += 1
    return k


@numba.njit(cache=True, nogil=True)
def _sweep(buf, pow10, tool_on, tool_off, words, word_starts, limits, kind, xyz, other, ann, ann_val):
    """``limits``: the largest coordinate and annotation number taken (others go to the line
    parser). Fill ``kind``/``xyz`` (one slot a command, or a line the line parser reads), ``other``
    (line, start, end, slot of each such line) and ``ann``/``ann_val`` (line, slot, key;
    value, number of each annotation read here); return how many of each."""
    n = len(buf)
    slots, others, notes = 0, 0, 0
    a = 0
    li = 0
    while a <= n:
        end = a
        while end < n and buf[end] != 10:
            end += 1
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
                if i < 0 or abs(v) > limits[0]:
                    ok = False
                    break
                xyz[slots, j] = v
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
                k, value, number = _annotation(buf, a + 2, end, pow10, words, word_starts, limits[1])
                if k != OTHER:
                    ann[notes, 0], ann[notes, 1], ann[notes, 2] = li, slots, k
                    ann_val[notes, 0], ann_val[notes, 1] = value, number
                    notes += 1
            elif buf[i] == 35 or (buf[i] == 59 and not (i + 1 < end and buf[i + 1] == 64)):  # '#', ';' not ';@'
                k = SKIP
                for j in range(i, end):  # non-ASCII text (the line parser checks it is UTF-8), control characters
                    if buf[j] >= 128 or (buf[j] < 32 and buf[j] != 9 and not (buf[j] == 13 and j == end - 1)):
                        k = OTHER
                        break
        if k == MOVE_LINE:
            kind[slots] = MOVE
            slots += 1
        elif k == TOOL_ON_LINE or k == TOOL_OFF_LINE or k == OTHER:
            kind[slots] = TOOL_ON if k == TOOL_ON_LINE else (TOOL_OFF if k == TOOL_OFF_LINE else -1)
            xyz[slots, 0], xyz[slots, 1], xyz[slots, 2] = np.nan, np.nan, np.nan
            if k == OTHER:
                other[others, 0], other[others, 1], other[others, 2], other[others, 3] = li, a, end, slots
                others += 1
            slots += 1
        a = end + 1
        li += 1
    return slots, others, notes


@numba.njit(cache=True, nogil=True)
def commands_before(kind, slots, out):
    """``out[j]``: how many commands (``kind >= 0``) come before slot ``slots[j]``; ``slots`` in
    ascending order. One pass over ``kind``, no per-slot array."""
    k = 0  # commands before slot s
    s = 0
    for j in range(len(slots)):
        while s < slots[j]:
            if kind[s] >= 0:
                k += 1
            s += 1
        out[j] = k


@numba.njit(cache=True, nogil=True)
def compact(kind, xyz):
    """Move the command slots (``kind >= 0``) of ``kind`` and ``xyz`` to the front, in order, in
    place; return how many there are (the rest of the arrays is left as it was)."""
    m = 0
    for s in range(len(kind)):
        if kind[s] >= 0:
            if m != s:
                kind[m] = kind[s]
                xyz[m, 0], xyz[m, 1], xyz[m, 2] = xyz[s, 0], xyz[s, 1], xyz[s, 2]
            m += 1
    return m


@dataclass(frozen=True)
class Sweep:
    """What the sweep read of a ``.coop`` text.

    Attributes
    ----------
    kind : (slots,) int8
        A slot for each command line and each line left to the line parser, in line order:
        ``MOVE``, ``TOOL_ON``, ``TOOL_OFF`` (of :mod:`.commands`) or -1 (the line parser's).
    xyz : (slots, 3) float64
        The MOVEs' targets (NaN in the other slots).
    other : (k, 4) int64
        The lines left to the line parser: line index (from 0), start and end (byte offsets,
        without the newline), slot.
    notes : (m, 3) int64
        The ``;@layer`` and ``;@path`` annotations read here: line index, the slot before which
        they stand, ``LAYER_LINE`` or ``PATH_LINE``.
    values : (m, 2) float64
        Their values: layer index (-1 for '-') and height, or role (``cooprint.slicing.paths``)
        and width.
    lines : int
        How many lines the text has (its newlines plus one).
    """

    kind: np.ndarray
    xyz: np.ndarray
    other: np.ndarray
    notes: np.ndarray
    values: np.ndarray
    lines: int = 0


def sweep(data) -> Sweep:
    """Read the plain lines of ``data`` (bytes, or any buffer of them, such as an ``mmap``) and
    say which lines the line parser must read."""
    buf = np.frombuffer(data, dtype=np.uint8)
    lines = _lines(buf)
    # room for every line; pages never written are never backed by memory: the slots of the
    # lines that are not commands, the rows of other and notes
    kind, xyz = np.empty(lines, np.int8), np.empty((lines, 3))
    other, notes, values = np.empty((lines, 4), np.int64), np.empty((lines, 3), np.int64), np.empty((lines, 2))
    slots, others, annotations = _sweep(buf, POW10, np.frombuffer(b"TOOL ON", np.uint8),
                                        np.frombuffer(b"TOOL OFF", np.uint8), _WORDS, _WORD_STARTS, _LIMITS, kind, xyz,
                                        other, notes, values)
    del buf
    for arr, rows in ((kind, slots), (xyz, slots), (other, others), (notes, annotations), (values, annotations)):
        arr.resize((rows,) + arr.shape[1:], refcheck=False)  # in place: the rest goes back to the heap
    return Sweep(kind, xyz, other, notes, values, int(lines))


__all__ = ["LAYER_LINE", "commands_before", "compact", "MOVE_LINE", "OTHER", "PATH_LINE", "POW10", "SKIP", "TOOL_OFF_LINE", "TOOL_ON_LINE", "Sweep",
           "decimal", "sweep"]
