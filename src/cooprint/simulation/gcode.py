"""The G-code reader's fast pass: one compiled sweep over a file's bytes (numba).

:func:`cooprint.simulation.inputs.read_gcode` reads a slicer's G-code; a big print has millions
of lines, nearly all of them ``G1 X.. Y.. E..``, comments or commands the simulator ignores. The
sweep follows the reader's machine state (``G90``/``G91``, ``M82``/``M83``, ``G92``, the feed
rate, the layer height) through the file and writes one row per ``G0``/``G1`` move; the rows are
then made into the program's commands with whole-array operations (:func:`gcode_rows`).

The line reader of :mod:`.inputs` (``_read_gcode_lines``) is the reference: the sweep gives the
same result for every file it takes, and it takes a file only when every line is in the plain
form. A ``G0``/``G1``/``G92`` line is plain when it holds only ASCII letters, digits, ``.``,
``+``, ``-``, blanks and tabs before its ``;`` comment, and each word's number is a plain decimal
(``-12.5``, ``+3``, ``.25``, ``7.``; at most 15 significant digits, no exponent; an empty number
only after ``G92``). Such a number is its digits as an integer (exact in float64) divided by a
power of ten (exact up to 10^22): one correctly rounded division, the same double that
``float()`` gives. Other lines only need their first word found and their line breaks counted
as Python counts them (``str.splitlines`` breaks lines at a few more characters than ``\\n`` and
``\\r``; a file with any of those falls back). Any line not taken (an error, an exponent, a
number word like ``Xabc``, a feed rate that is not positive) sends the whole file back to the
line reader, which reads it, or raises its error, exactly as before.

Host lines (``M0``/``M00``/``M1``/``M01`` and ``M118``: a fleet host's WAIT and NOTIFY, and plain
pauses and echoes) are not read by the sweep: it notes where each one is (its line number, its
bytes and how many moves came before it) and :func:`gcode_rows` reads those few lines with the
line reader's own :func:`~cooprint.simulation.inputs.host_line`, so that a robot's G-code, which
holds a few host lines among millions of moves, keeps the sweep's speed. A file with more than
``HOST_CAP`` host lines goes to the line reader.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

import numba
import numpy as np

from cooprint import jit
from cooprint.program.commands import MOVE, NOTIFY, TOOL_OFF, TOOL_ON, WAIT
from cooprint.program.scan import POW10, decimal
from cooprint.simulation.inputs import SimInputError
from cooprint.slicing.paths import (BRIDGE, GAP_FILL, INFILL, OVERHANG, PERIMETER_INNER, PERIMETER_OUTER,
                                    ROUND_ROLES, SKIN, TOP_SKIN, TRAVEL, extrusion_width, round_width)

jit.setup()  # Ctrl-C held while numba compiles; LLVM calls untimed (cooprint.jit)

# the first word of a line, as the sweep tells them apart
_OTHER, _G0, _G1, _G92, _G90, _G91, _M82, _M83, _HOST = range(9)
#: Most host lines (M0, M1, M118) the sweep notes; a file with more is read by the line reader.
HOST_CAP = 4096
#: Largest position and E step of a G-code file, mm (a 1 km floor; a larger one is an error, not a
#: plan: 1e308 would overflow every extent computed from it).
COORD_LIMIT = 1e6  # = cooprint.simulation.inputs.COORD_LIMIT (a start)

#: The helpers called for every word and line: inlined into the sweep (a call passes each array
#: with a reference count taken and dropped, atomic operations that cost more than the work).
_inline = numba.njit(cache=True, nogil=True, inline="always")


@_inline
def _end_of_line(c):
    return c == 10 or c == 13


@_inline
def _rest_of_line(buf, i):
    """The index of the line break (or the end) at or after ``i``, skipping text that does not
    matter (a comment, the rest of a line the reader ignores); -1 if the text holds a character
    that ``str.splitlines`` takes for a line break besides ``\\n`` and ``\\r``: VT, FF, FS, GS,
    RS, and in UTF-8 NEL (C2 85), LS (E2 80 A8) and PS (E2 80 A9)."""
    n = len(buf)
    while i < n:
        c = buf[i]
        if 32 <= c < 128 or c == 9:
            i += 1
            continue
        if c == 10 or c == 13:
            return i
        if c == 11 or c == 12 or 28 <= c <= 30:
            return -1
        if c == 0xC2 and i + 1 < n and buf[i + 1] == 0x85:
            return -1
        if c == 0xE2 and i + 2 < n and buf[i + 1] == 0x80 and (buf[i + 2] == 0xA8 or buf[i + 2] == 0xA9):
            return -1
        i += 1
    return i


@_inline
def _code(buf, a, b):
    """Which of the words the reader acts on ``buf[a:b]`` is (any case), or ``_OTHER``; the host
    words M0, M00, M1, M01 and M118 are ``_HOST``."""
    size = b - a
    if size < 2 or size > 4:
        return _OTHER
    c0 = buf[a] | 32  # lower case
    c1 = buf[a + 1]
    if size == 4:
        if c0 == 109 and c1 == 49 and buf[a + 2] == 49 and buf[a + 3] == 56:  # m118
            return _HOST
        return _OTHER
    if size == 2:
        if c0 == 103 and c1 == 48:  # g0
            return _G0
        if c0 == 103 and c1 == 49:  # g1
            return _G1
        if c0 == 109 and (c1 == 48 or c1 == 49):  # m0, m1
            return _HOST
        return _OTHER
    c2 = buf[a + 2]
    if c0 == 109 and c1 == 48 and (c2 == 48 or c2 == 49):  # m00, m01
        return _HOST
    if c0 == 103 and c1 == 57:  # g9.
        if c2 == 50:
            return _G92
        if c2 == 48:
            return _G90
        if c2 == 49:
            return _G91
    elif c0 == 109 and c1 == 56:  # m8.
        if c2 == 50:
            return _M82
        if c2 == 51:
            return _M83
    return _OTHER


@_inline
def _word_end(c):
    """Whether byte ``c`` ends a G-code word: a blank, a tab, ``;`` or a line break."""
    return c == 32 or c == 9 or c == 59 or c == 10 or c == 13


@_inline
def _number(buf, i, pow10):
    """The plain decimal number at ``buf[i:]``, up to the word's end: ``(value, next index,
    how many characters)``; ``(0.0, -1, 0)`` when it is not in the plain form."""
    v, j, size = decimal(buf, i, len(buf), pow10)
    if j >= 0 and j < len(buf) and not _word_end(buf[j]):
        return 0.0, -1, 0
    return v, j, size


@numba.njit(cache=True, nogil=True)
def _sweep(buf, pow10, host, limit):
    """Every ``G0``/``G1`` move of the G-code in ``buf``: ``(bad, count, xyz, feed, de, deposit,
    layer_h, hosts, starts)`` (``starts``: the byte each move's line starts at), where ``bad`` is 0 or the number of the first line not in the plain form (the
    rows are then incomplete). ``host`` (``(HOST_CAP, 4)`` int64) receives a row per host line:
    line number, start and end byte, moves before it; ``hosts`` is how many. A position or an E
    step beyond ``+-limit`` mm is a line not taken (the line reader words the error)."""
    n = len(buf)
    cap = 1
    for i in range(n):
        if buf[i] == 10 or buf[i] == 13:
            cap += 1
    xyz = np.empty((cap, 3))
    feeds = np.empty(cap)
    pushed = np.empty(cap)
    deposit = np.empty(cap, np.bool_)
    heights = np.empty(cap)
    starts = np.empty(cap, np.int64)  # the byte where each move's line starts (its role: the ;TYPE: before)
    # the reader's state: Marlin's defaults, absolute XYZ and E, homed at 0, 0, 0
    px, py, pz = 0.0, 0.0, 0.0
    rel_xyz, rel_e, e = False, False, 0.0
    feed = 1500.0 / 60.0
    layer_z, layer_h = 0.0, 0.2  # the height of the last layer that deposited, and its thickness
    m = 0
    nh = 0
    line = 0
    i = 0
    while i < n:
        line += 1
        while i < n and (buf[i] == 32 or buf[i] == 9):
            i += 1
        a = i
        while i < n and 33 <= buf[i] < 127 and buf[i] != 59:  # the first word: printable ASCII, not ';'
            i += 1
        code = _code(buf, a, i)
        if i < n and not _word_end(buf[i]):
            # a byte that may be Unicode white space or part of the word (or a control)
            if i == a or code != _OTHER:
                return line, m, xyz, feeds, pushed, deposit, heights, nh, starts
        if code == _G0 or code == _G1 or code == _G92:
            have_x, have_y, have_z, have_e, have_f = False, False, False, False, False
            vx, vy, vz, ve, vf = 0.0, 0.0, 0.0, 0.0, 0.0
            while True:
                while i < n and (buf[i] == 32 or buf[i] == 9):
                    i += 1
                if i == n or _end_of_line(buf[i]):
                    break
                k = buf[i]
                if k == 59:  # ';'
                    i = _rest_of_line(buf, i)
                    if i < 0:
                        return line, m, xyz, feeds, pushed, deposit, heights, nh, starts
                    break
                if 97 <= k <= 122:  # lower case
                    k -= 32
                if not (65 <= k <= 90 or 48 <= k <= 57 or k == 43 or k == 45 or k == 46):
                    return line, m, xyz, feeds, pushed, deposit, heights, nh, starts
                v, i, size = _number(buf, i + 1, pow10)
                if i < 0 or (size == 0 and code != _G92):  # G92 E: E0
                    return line, m, xyz, feeds, pushed, deposit, heights, nh, starts
                if k == 88:
                    have_x, vx = True, v
                elif k == 89:
                    have_y, vy = True, v
                elif k == 90:
                    have_z, vz = True, v
                elif k == 69:
                    have_e, ve = True, v
                elif k == 70:
                    have_f, vf = True, v
            if code == _G92:
                if have_e:
                    e = ve
            else:
                if have_f:
                    if not vf > 0:
                        return line, m, xyz, feeds, pushed, deposit, heights, nh, starts
                    feed = vf / 60.0
                tx, ty, tz = px, py, pz
                if have_x:
                    tx = (px + vx) if rel_xyz else vx
                if have_y:
                    ty = (py + vy) if rel_xyz else vy
                if have_z:
                    tz = (pz + vz) if rel_xyz else vz
                de = 0.0
                if have_e:
                    de = ve if (rel_xyz or rel_e) else ve - e
                    e += de
                if abs(tx) > limit or abs(ty) > limit or abs(tz) > limit or abs(de) > limit:
                    return line, m, xyz, feeds, pushed, deposit, heights, nh, starts  # the line reader's error
                dep = de > 0 and (tx != px or ty != py or tz != pz)
                if dep and tz != layer_z:
                    if tz > layer_z:
                        layer_h = tz - layer_z
                        if 1e-3 > layer_h:  # max(tz - layer_z, 1e-3)
                            layer_h = 1e-3
                    layer_z = tz
                xyz[m, 0], xyz[m, 1], xyz[m, 2] = tx, ty, tz
                feeds[m] = feed
                pushed[m] = de
                deposit[m] = dep
                heights[m] = layer_h
                starts[m] = a
                m += 1
                px, py, pz = tx, ty, tz
        else:
            if code == _G90 or code == _G91:
                rel_xyz = code == _G91
            elif code == _M82 or code == _M83:
                rel_e = code == _M83
            i = _rest_of_line(buf, i)
            if i < 0:
                return line, m, xyz, feeds, pushed, deposit, heights, nh, starts
            if code == _HOST:
                if nh == len(host):
                    return line, m, xyz, feeds, pushed, deposit, heights, nh, starts
                host[nh, 0], host[nh, 1], host[nh, 2], host[nh, 3] = line, a, i, m
                nh += 1
        # at the line break: CR LF, CR or LF ends the line
        if i < n:
            if buf[i] == 13 and i + 1 < n and buf[i + 1] == 10:
                i += 2
            else:
                i += 1
    return 0, m, xyz, feeds, pushed, deposit, heights, nh, starts


# ----------------------------------------------------------------------------------------------
# host lines: the fleet host's NOTIFY and WAIT (docs/program.md), plain pauses, echoes

#: The words of a host line: M0/M00 (stop, "unconditional"), M1/M01 (stop) and M118 (echo to the host).
HOST_WORDS = frozenset({"M0", "M00", "M1", "M01", "M118"})
#: An event name, as in a ``.coop`` file: letters, digits, ``_ : . -`` (ASCII), at most 100 characters.
EVENT_NAME = re.compile(r"[A-Za-z0-9_:.\-]{1,100}")


class HostLineError(SimInputError):
    """A NOTIFY or WAIT host line that does not name its events properly."""


def _clip(text: str, n: int = 40) -> str:
    return text if len(text) <= n else text[:n] + "..."


def host_line(line: str, where: str) -> tuple[int, tuple[str, ...]] | str | None:
    """What a host line (``M0``, ``M1``, ``M118``; comment removed) means to the simulator.

    * ``M118 NOTIFY e`` announces event ``e``: ``(NOTIFY, (e,))``;
    * ``M0 WAIT e[, f ...]`` (or ``M1``) blocks until every named event is announced:
      ``(WAIT, (e, f, ...))``; this is what cooprint writes after ``M400`` (docs/program.md);
    * ``M0 FACING d`` is a turn of a robot that prints both sides (the host turns it): nothing to
      simulate, since where a G-code robot's body stands is not known: ``None``;
    * any other ``M0``/``M1`` is a pause for an operator, which the simulation cannot honour: the
      word (``"M0"``) is returned, for a note in the summary;
    * any other ``M118`` is an echo to the host: ``None``.

    A ``NOTIFY``/``WAIT`` without proper event names raises :class:`HostLineError` naming ``where``.
    """
    words = line.split(None, 1)
    code = words[0].upper()
    rest = words[1].strip() if len(words) > 1 else ""
    head = rest.split(None, 1)
    word = head[0].upper() if head else ""
    args = head[1].strip() if len(head) > 1 else ""
    if code == "M118":
        if word != "NOTIFY":
            return None
        names = args.split()
        if len(names) != 1 or not EVENT_NAME.fullmatch(names[0]):
            raise HostLineError(f"{where}: '{_clip(line)}': expected M118 NOTIFY and one event name "
                                "(letters, digits, _ : . -)")
        return NOTIFY, (names[0],)
    if word == "FACING":  # a turn for the host (docs/program.md); a G-code robot's body is not placed
        return None
    if word != "WAIT":
        return code
    names = [x.strip() for x in args.split(",")]
    bad = [x for x in names if not EVENT_NAME.fullmatch(x)]
    if bad:
        got = f"'{_clip(bad[0])}'" if bad[0] else "an empty name"
        raise HostLineError(f"{where}: '{_clip(line)}': expected {code} WAIT and event names separated by commas "
                            f"(letters, digits, _ : . -), got {got}")
    return WAIT, tuple(names)


def pause_note(where: str, lines: list[int]) -> str:
    """The summary's note on the operator pauses of a G-code file (the simulation goes on)."""
    first = ", ".join(map(str, lines[:3])) + (", ..." if len(lines) > 3 else "")
    return (f"{where}: {len(lines)} pause line(s) (M0/M1 without WAIT, line {first}) ignored: "
            "the simulation does not stop for an operator")


@dataclass(frozen=True)
class GcodeRows:
    """A G-code file's commands, one row each (``TOOL ON``/``TOOL OFF`` where the deposit of
    the moves starts and stops): the columns :func:`~cooprint.program.commands.make_program` and
    :class:`~cooprint.simulation.timeline.SimRobot` take."""

    kind: np.ndarray  # (n,) uint8
    xyz: np.ndarray  # (n, 3) float64, NaN on the TOOL rows
    speed: np.ndarray  # (n,) mm/s, 0 on the TOOL rows
    width: np.ndarray  # (n,) mm, 0 but on deposit moves
    height: np.ndarray  # (n,) mm, 0 but on deposit moves
    de: np.ndarray  # (n,) filament pushed, mm
    role: np.ndarray  # (n,) uint8 path role (cooprint.slicing.paths) from the ;TYPE: comments; TRAVEL on other rows
    events: tuple[tuple[str, ...], ...] = ()  # of the NOTIFY / WAIT rows, in order
    pauses: list[int] = field(default_factory=list)  # line numbers of the operator pauses (M0/M1)


def _widths(area: np.ndarray, h: np.ndarray) -> np.ndarray:
    """``extrusion_width(area, h)`` element by element, as the reference computes it for each
    move: with a scalar height, whose ``(h / 2) ** 2`` is C's ``pow`` (not always the correctly
    rounded square that an array's ``** 2`` gives). Whole arrays, but for the heights (few) where
    the two differ."""
    w = extrusion_width(area, h)
    runs = np.flatnonzero(np.r_[True, h[1:] != h[:-1]]) if len(h) else np.zeros(0, np.int64)
    heights = np.unique(h[runs])
    scalar = np.array([float((np.asarray(v) / 2) ** 2) for v in heights.tolist()])
    odd = heights[scalar != (heights / 2) ** 2]
    if len(odd):
        at = np.flatnonzero(np.isin(h, odd))
        for v in odd.tolist():
            sel = at[h[at] == v]
            w[sel] = extrusion_width(area[sel], v)
    return w


def gcode_rows(data: bytes, filament_diameter: float, where: str = "G-code") -> GcodeRows | None:
    """The commands of the G-code ``data`` (file ``where``, for messages), or ``None`` if a line is
    not in the plain form (the line reader is then the one to read the file)."""
    buf = np.frombuffer(data, dtype=np.uint8)
    hosts = np.empty((HOST_CAP, 4), np.int64)
    bad, m, xyz, feed, de, dep, layer_h, nh, starts = _sweep(buf, POW10, hosts, COORD_LIMIT)
    if bad:
        return None
    at, roles = type_comments(data)
    k = np.searchsorted(at, starts[:m], side="right") - 1  # the ;TYPE: line in force at each move
    role = np.where(k >= 0, roles[np.maximum(k, 0)], INFILL).astype(np.uint8) if len(at) else np.full(m, INFILL, np.uint8)
    rows = _move_rows(m, xyz[:m], feed[:m], de[:m], dep[:m], layer_h[:m], filament_diameter, role)
    return _with_host_lines(rows, data, hosts[:nh], where)


#: Feature types of the slicers' ``;TYPE:`` comments (PrusaSlicer and SuperSlicer, Orca and
#: Bambu Studio, Cura and cooprint's own G-code), lower case, as cooprint's path roles
#: (:mod:`cooprint.slicing.paths`); any other type (support, skirt, brim, wipe tower, custom)
#: is infill, as material with no type is.
TYPE_ROLES = {
    **dict.fromkeys(("external perimeter", "wall-outer", "outer wall"), PERIMETER_OUTER),
    **dict.fromkeys(("perimeter", "wall-inner", "inner wall"), PERIMETER_INNER),
    **dict.fromkeys(("overhang perimeter", "overhang wall"), OVERHANG),
    **dict.fromkeys(("solid infill", "skin", "internal solid infill", "bottom surface"), SKIN),
    **dict.fromkeys(("top solid infill", "top surface", "ironing"), TOP_SKIN),
    **dict.fromkeys(("bridge infill", "internal bridge infill", "bridge"), BRIDGE),
    **dict.fromkeys(("gap fill", "gap infill"), GAP_FILL),
    **dict.fromkeys(("internal infill", "fill", "sparse infill"), INFILL),
}


def type_role(name: str) -> int:
    """The path role of a ``;TYPE:`` comment's feature name (:data:`TYPE_ROLES`; others: infill)."""
    return TYPE_ROLES.get(name.strip().lower(), INFILL)


def type_comments(data) -> tuple[np.ndarray, np.ndarray]:
    """The ``;TYPE:<name>`` comment lines of G-code ``data`` (a comment alone on its line, blanks
    before it allowed): the byte each starts at and its role (:func:`type_role`), in order. A
    compiled pass finds them and keys each name by a hash; only one name of each hash is decoded."""
    buf = np.frombuffer(data, dtype=np.uint8)
    at, first, end, key = _type_lines(buf, np.frombuffer(b";TYPE:", np.uint8))
    roles = np.full(len(at), INFILL, np.uint8)
    if len(at):
        keys, where, inverse = np.unique(key, return_index=True, return_inverse=True)
        lut = np.array([type_role(bytes(buf[first[k]:end[k]]).decode("utf-8", errors="replace"))
                        for k in where.tolist()], np.uint8)
        roles = lut[inverse.reshape(-1)]
    return at, roles


@numba.njit(cache=True, nogil=True)
def _type_lines(buf, tag):
    """The lines of ``buf`` that are blanks then ``tag`` (``;TYPE:``): where each starts, where
    its name starts and ends (before a ``;`` or the line break), and a hash of the name (FNV-1a
    over its bytes in lower case, blanks at its end left out)."""
    n, t = len(buf), len(tag)
    count = 0
    at = np.empty(16, np.int64)
    first = np.empty(16, np.int64)
    end = np.empty(16, np.int64)
    key = np.empty(16, np.uint64)
    i = 0
    while i < n:
        a = i
        while i < n and (buf[i] == 32 or buf[i] == 9):
            i += 1
        match = i + t <= n
        if match:
            for k in range(t):
                if buf[i + k] != tag[k]:
                    match = False
                    break
        if match:
            b = i + t
            e = b
            while e < n and buf[e] != 10 and buf[e] != 13 and buf[e] != 59:
                e += 1
            c = e
            while c > b and (buf[c - 1] == 32 or buf[c - 1] == 9):
                c -= 1
            h = np.uint64(14695981039346656037)
            for k in range(b, c):
                v = buf[k]
                if 65 <= v <= 90:
                    v += 32
                h = (h ^ np.uint64(v)) * np.uint64(1099511628211)
            if count == len(at):
                at, first, end, key = (np.concatenate((at, np.empty(count, np.int64))),
                                       np.concatenate((first, np.empty(count, np.int64))),
                                       np.concatenate((end, np.empty(count, np.int64))),
                                       np.concatenate((key, np.empty(count, np.uint64))))
            at[count], first[count], end[count], key[count] = a, b, c, h
            count += 1
            i = e
        while i < n and buf[i] != 10 and buf[i] != 13:
            i += 1
        i += 1
    return at[:count], first[:count], end[:count], key[:count]


def _with_host_lines(rows: GcodeRows, data: bytes, hosts: np.ndarray, where: str) -> GcodeRows:
    """``rows`` with a NOTIFY / WAIT row for each host line that is one (before the rows of the
    move that follows it, as the line reader appends them), and the pauses noted."""
    if not len(hosts):
        return rows
    sync_at, kinds, events, pauses = [], [], [], []
    # the row of each move: the first row at or after it that is a MOVE
    move_rows = np.flatnonzero(rows.kind == MOVE)
    for line, a, b, before in hosts.tolist():
        text = data[a:b].decode("utf-8", errors="replace").split(";", 1)[0].strip()
        got = host_line(text, f"{where}:{line}")
        if isinstance(got, str):
            pauses.append(line)
        elif got is not None:
            # before the move that follows (and its TOOL row, which the line reader adds with it)
            at = len(rows.kind) if before >= len(move_rows) else int(move_rows[before])
            if before < len(move_rows) and at > 0 and rows.kind[at - 1] != MOVE:
                at -= 1
            sync_at.append(at)
            kinds.append(got[0])
            events.append(got[1])
    if not sync_at:
        return GcodeRows(rows.kind, rows.xyz, rows.speed, rows.width, rows.height, rows.de, rows.role, (), pauses)
    at = np.array(sync_at)

    def put(col: np.ndarray, value) -> np.ndarray:
        return np.insert(col, at, value, axis=0)

    return GcodeRows(put(rows.kind, np.array(kinds, np.uint8)), put(rows.xyz, np.nan), put(rows.speed, 0.0),
                     put(rows.width, 0.0), put(rows.height, 0.0), put(rows.de, 0.0), put(rows.role, TRAVEL),
                     tuple(events), pauses)


def _move_rows(m: int, xyz: np.ndarray, feed: np.ndarray, de: np.ndarray, dep: np.ndarray, layer_h: np.ndarray,
               filament_diameter: float, role: np.ndarray) -> GcodeRows:
    """The rows of the sweep's ``m`` moves: a TOOL row where the deposit changes, then the move
    (with its ``role``; the TOOL rows travel)."""
    fil_area = math.pi * (filament_diameter / 2) ** 2  # as the line reader
    # a TOOL ON / TOOL OFF row before each move whose deposit differs from the one before
    change = dep != np.r_[False, dep[:-1]]
    row = np.arange(m) + np.cumsum(change)  # each move's row
    rows = m + int(change.sum())
    kind = np.empty(rows, np.uint8)
    kind[row - change] = np.where(dep, TOOL_ON, TOOL_OFF)  # overwritten by the MOVE where no change
    kind[row] = MOVE
    out_xyz = np.full((rows, 3), np.nan)
    out_xyz[row] = xyz
    speed = np.zeros(rows)
    speed[row] = feed
    pushed = np.zeros(rows)
    pushed[row] = de
    # the width whose flow cross-section (flow_area, by role) carries the filament pushed: the
    # length as the line reader's np.linalg.norm (a BLAS dot, which np.vecdot calls too), then its
    # extrusion_width, or for a round role its round_width
    d = np.flatnonzero(dep)
    start = np.empty((len(d), 3))
    start[d > 0] = xyz[d[d > 0] - 1]
    start[d == 0] = 0.0
    step = xyz[d] - start
    length = np.sqrt(np.vecdot(step, step))
    width = np.zeros(rows)
    area = de[d] * fil_area / length
    w = _widths(area, layer_h[d])
    round_ = np.isin(role[d], ROUND_ROLES)  # a bridge's thread: the circle of that area (flow_area)
    w[round_] = round_width(area[round_])
    width[row[d]] = w
    height = np.zeros(rows)
    height[row[d]] = layer_h[d]
    roles = np.full(rows, TRAVEL, np.uint8)
    roles[row] = role
    return GcodeRows(kind, out_xyz, speed, width, height, pushed, roles)


__all__ = ["EVENT_NAME", "HOST_CAP", "HOST_WORDS", "TYPE_ROLES", "GcodeRows", "HostLineError", "gcode_rows", "host_line",
           "pause_note", "type_comments", "type_role"]
