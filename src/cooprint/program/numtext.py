"""Text of many lines at once: the writers' fast path (numba), byte for byte what ``%`` writes.

The ``.coop`` and G-code writers emit millions of lines such as ``MOVE 12.345, 6.000, 0.300``
and ``G1 X12.345 Y6.000 E0.02694``. Python's ``%`` formats about 3 numbers a microsecond, far
from disk speed; here a writer describes its output as a list of *operations* in order, each
either a string of a small table (annotations, comments, host lines) or a numeric line (a
template such as ``"G1 X%.3f Y%.3f E%.5f\\n"`` and a row of values), and one compiled pass
(:func:`assemble`) writes them all into one byte buffer.

Exactly what ``'%.Nf' % v`` writes: ``%`` rounds the binary value of ``v`` correctly (half to
even) to N decimals and keeps the sign of a negative value that rounds to zero (``-0.000``).
:func:`fixed` turns each value into that rounded magnitude as an integer (``rint(|v| * 10**N)``,
exact unless ``|v| * 10**N`` lies within 1e-6 of a half, where the product's rounding error
could decide, or is beyond 1e9) and its sign bit; the few values outside that safe range are
formatted by ``%`` itself and read back; NaN and infinities are written as ``%`` writes them.
"""

from __future__ import annotations

import re
from typing import Sequence

import numba
import numpy as np

from cooprint import jit

jit.setup()  # Ctrl-C held while numba compiles; LLVM calls untimed (cooprint.jit)

_FIELD = re.compile(r"%\.(\d)f")
#: Beyond this, ``|v| * 10**N`` is not known to within 1e-6 of its rounding (doubles there are
#: 2**-23 apart) and the value is formatted by ``%``.
_SAFE = 1e9
#: Beyond this a rounded magnitude does not fit 64 bits: :func:`assemble` takes the slow path.
_HUGE = 9e18


@numba.njit(cache=True, nogil=True)
def _round(v, scale, cols):
    """Per value of columns ``cols`` of ``v`` (scaled by ``scale[j]`` in column ``j``):
    ``rint(|v| * scale)``, the sign bit, and a code: 0 that rounding is sure, 1 not sure (``%``
    decides), 2 NaN, 3 infinite."""
    n, m = v.shape
    mag = np.zeros((n, m), np.int64)
    neg = np.zeros((n, m), np.bool_)
    code = np.zeros((n, m), np.int8)
    for i in range(n):
        for j in cols:
            x = v[i, j]
            neg[i, j] = np.signbit(x)
            if np.isnan(x):
                code[i, j] = 2
                neg[i, j] = False  # '%' writes NaN without a sign
                continue
            if np.isinf(x):
                code[i, j] = 3
                continue
            a = abs(x) * scale[j]
            if not a < _SAFE:
                code[i, j] = 1
                continue
            mag[i, j] = np.int64(np.rint(a))
            if abs(a - np.floor(a) - 0.5) < 1e-6:
                code[i, j] = 1
    return mag, neg, code


def fixed(values: np.ndarray, decimals: int | dict[int, int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(magnitude, negative, special)``: ``'%.{decimals}f' % v`` is ``'-' * negative``
    followed by ``magnitude`` with a point before its last ``decimals`` digits (at least one
    digit before the point), for every ``v`` of ``values``; ``special`` is 2 for NaN (``nan``,
    no sign) and 3 for an infinity (``inf``, signed), else 0. For an (n, m) array, ``decimals``
    maps the columns to format to their decimals (the others are left 0)."""
    v = np.asarray(values, dtype=np.float64)
    flat = v.ndim == 1
    v = np.ascontiguousarray(v.reshape(-1, 1) if flat else v)
    dec = {0: decimals} if flat else dict(decimals)
    scale = np.ones(v.shape[1])
    for j, d in dec.items():
        scale[j] = 10.0 ** d
    k, neg, code = _round(v, scale, np.array(sorted(dec), np.int64))
    unsure = np.argwhere(code == 1)
    for i, j in unsure.tolist():
        x = abs(float(v[i, j]))
        if x >= _HUGE / scale[j]:
            raise OverflowError("a value too large for a 64-bit fixed-point number")
        k[i, j] = int((f"%.{dec[j]}f" % x).replace(".", ""))
        code[i, j] = 0
    return (k[:, 0], neg[:, 0], code[:, 0]) if flat else (k, neg, code)


class Templates:
    """Numeric line templates (``%.Nf`` fields only, e.g. ``"G1 X%.3f Y%.3f E%.5f\\n"``), each
    field reading one column of the value rows (``columns``; default 0, 1, 2 ...)."""

    def __init__(self, templates: Sequence[str], columns: Sequence[Sequence[int]] | None = None):
        lit: list[bytes] = []
        self.text = list(templates)
        nfield = max(len(_FIELD.findall(t)) for t in templates)
        self.count = np.zeros(len(templates), np.int64)
        self.decimals = np.zeros((len(templates), max(nfield, 1)), np.int64)
        self.column = np.zeros((len(templates), max(nfield, 1)), np.int64)
        self.lit_at = np.zeros((len(templates), nfield + 2), np.int64)
        at = 0
        for t, text in enumerate(templates):
            parts = _FIELD.split(text)  # literal, N, literal, N, ..., literal
            fields = parts[1::2]
            self.count[t] = len(fields)
            cols = list(columns[t]) if columns is not None else list(range(len(fields)))
            for f, n in enumerate(fields):
                self.decimals[t, f] = int(n)
                self.column[t, f] = cols[f]
            for f, piece in enumerate(parts[0::2]):
                self.lit_at[t, f] = at
                lit.append(piece.encode("ascii"))
                at += len(lit[-1])
            self.lit_at[t, len(fields) + 1] = at
        #: the decimals of each column read (one count a column: its digits are made once)
        self.column_decimals: dict[int, int] = {}
        for t in range(len(templates)):
            for f in range(int(self.count[t])):
                c, d = int(self.column[t, f]), int(self.decimals[t, f])
                if self.column_decimals.setdefault(c, d) != d:
                    raise ValueError(f"column {c} written with {self.column_decimals[c]} and with {d} decimals")
        self.lit = np.frombuffer(b"".join(lit) or b"\0", np.uint8)


_POW10 = 10 ** np.arange(19, dtype=np.int64)
#: "00", "01" ... "99": two digits at a time.
_PAIRS = np.frombuffer("".join(f"{i:02d}" for i in range(100)).encode(), np.uint8)
#: An empty slot of an operation matrix.
NONE = -(1 << 30)


@numba.njit(cache=True, nogil=True)
def _assemble(op, row, tab, tab_at, lit, lit_at, count, decimals, column, mag, neg, special):
    """One pass over the operation matrix (row by row, slot by slot) into a buffer of the
    largest size the operations can take (a number at most 19 digits, a sign and a point),
    cut to what was written."""
    bound = 0
    for i in range(op.shape[0]):
        for k in range(op.shape[1]):
            o = op[i, k]
            if o >= 0:
                bound += tab_at[o + 1] - tab_at[o]
            elif o != NONE:
                t = -1 - o
                bound += lit_at[t, count[t] + 1] - lit_at[t, 0] + 21 * count[t]
    buf = np.empty(bound, np.uint8)
    w = 0
    for i in range(op.shape[0]):
        for k in range(op.shape[1]):
            o = op[i, k]
            if o == NONE:
                continue
            if o >= 0:
                for j in range(tab_at[o], tab_at[o + 1]):
                    buf[w] = tab[j]
                    w += 1
                continue
            t = -1 - o
            r = row[i]
            nf = count[t]
            for f in range(nf + 1):
                for j in range(lit_at[t, f], lit_at[t, f + 1]):
                    buf[w] = lit[j]
                    w += 1
                if f == nf:
                    break
                c = column[t, f]
                d = decimals[t, f]
                m = mag[r, c]
                if neg[r, c]:
                    buf[w] = 45  # '-'
                    w += 1
                if special[r, c] != 0:  # nan, inf
                    for ch in (110, 97, 110) if special[r, c] == 2 else (105, 110, 102):
                        buf[w] = ch
                        w += 1
                    continue
                # the whole part, then the point and d decimals, two digits at a time from the last
                p10 = _POW10[d]
                q = m // p10
                f = m - q * p10
                nd = 1
                while nd < 19 and q >= _POW10[nd]:
                    nd += 1
                at = w + nd - 1
                while q >= 100:
                    k = (q % 100) * 2
                    q //= 100
                    buf[at] = _PAIRS[k + 1]
                    buf[at - 1] = _PAIRS[k]
                    at -= 2
                if q >= 10:
                    buf[at] = _PAIRS[q * 2 + 1]
                    buf[at - 1] = _PAIRS[q * 2]
                else:
                    buf[at] = 48 + q
                w += nd
                if d > 0:
                    buf[w] = 46  # '.'
                    w += 1
                    at = w + d - 1
                    for _ in range(d // 2):
                        k = (f % 100) * 2
                        f //= 100
                        buf[at] = _PAIRS[k + 1]
                        buf[at - 1] = _PAIRS[k]
                        at -= 2
                    if d % 2:
                        buf[at] = 48 + f % 10
                    w += d
    return buf[:w]


class Table:
    """The strings of one assembly, each given an id once (ids from 0)."""

    def __init__(self, strings: Sequence[str] = ()):
        self.ids: dict[str, int] = {}
        for s in strings:
            self.id(s)

    def id(self, s: str) -> int:
        got = self.ids.get(s)
        if got is None:
            got = self.ids[s] = len(self.ids)
        return got

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        data = [s.encode("utf-8") for s in self.ids]
        at = np.zeros(len(data) + 1, np.int64)
        at[1:] = np.cumsum([len(d) for d in data])
        return np.frombuffer(b"".join(data) or b"\0", np.uint8), at


def _assemble_slow(op, row, table: Table, templates: Templates, values: np.ndarray) -> np.ndarray:
    """:func:`assemble` by ``%``, operation by operation."""
    strings = list(table.ids)
    out = []
    for ops, r in zip(op.tolist(), row.tolist()):
        for o in ops:
            if o == NONE:
                continue
            if o >= 0:
                out.append(strings[o])
            else:
                t = -1 - o
                cols = templates.column[t, :templates.count[t]].tolist()
                out.append(templates.text[t] % tuple(values[r, cols].tolist()))
    return np.frombuffer("".join(out).encode("utf-8"), np.uint8)


def assemble(op: np.ndarray, row: np.ndarray, table: Table, templates: Templates, values: np.ndarray) -> np.ndarray:
    """The text (UTF-8 bytes as a uint8 array: a file writes it without a copy) of the
    operations ``op``, an (n, k) matrix read row by row (or an (n,) vector): ``op >= 0`` is
    string ``op`` of ``table``; ``NONE`` nothing; another ``op < 0`` is template ``-1 - op``
    of ``templates`` filled from row ``row[i]`` of ``values``. Byte for byte what ``%`` would
    write."""
    op = np.asarray(op)
    op = np.ascontiguousarray(op if op.ndim == 2 else op.reshape(-1, 1), np.int32)
    values = np.asarray(values, dtype=np.float64)
    values = values.reshape(len(values), -1) if values.ndim < 2 else values
    try:  # every column a template reads (a row no line writes may hold anything, NaN too)
        mag, neg, special = fixed(values, templates.column_decimals)
    except OverflowError:  # a number of more than 18 digits: no writer makes one; '%' writes it
        return _assemble_slow(op, row, table, templates, values)
    tab, tab_at = table.arrays()
    return _assemble(op, np.ascontiguousarray(row, np.int64), tab, tab_at, templates.lit, templates.lit_at,
                     templates.count, templates.decimals, templates.column, mag, neg, special)


__all__ = ["NONE", "Table", "Templates", "assemble", "fixed"]
