"""The robots' command language (``.coop``, one file per robot): the record, the writer, the parser.

The language (seed §4.3 and §5.1)::

    ; a comment, to the end of the line ('#' too)
    MOVE x, y, z          straight move to an absolute position, mm (commas optional)
    TOOL ON               deposit material along the following moves
    TOOL OFF
    NOTIFY [event]        announce an event; a bare NOTIFY is "<robot>:<n>", n counting this
                          robot's NOTIFYs from 1
    WAIT event [, event]  block until every named event has been announced (by any robot)

Keywords are case-insensitive; numbers are decimal in ASCII digits (``-1``, ``2.5``, ``.5``,
``1e3``; Python's ``float()`` would also read full-width and other Unicode digits, ``1_000``,
``nan`` and ``inf``, none of which is a number here), finite, and a coordinate at most
``MAX_COORD_MM`` (1 km) from 0; event and chunk names are letters, digits and ``_ : . -``, at
most ``MAX_NAME`` characters. An error message quotes at most ``cooprint.errors.CLIP``
characters of a token.

Annotations are comments a robot ignores and the tools read (as slicers read ``;TYPE:`` in
G-code): G-code export needs each extruding move's width and layer height, the simulator and the
viewers need to know which chunk a move prints::

    ;@chunk C             the following commands belong to chunk C ('-': between chunks)
    ;@layer 12 0.2        layer 12 of that chunk (from 0), 0.2 mm thick ('-': no layer)
    ;@path perimeter 0.45 the following moves print a perimeter 0.45 mm wide (roles: outer-perimeter,
                          perimeter, skin, infill, travel)
    ;@facing -90          before the next command the robot turns round about its nozzle, the
                          shorter way, to face -90 degrees (the direction from its body to the
                          nozzle); a robot may act on it, other readers ignore it (Program.turns)

Each field is checked: a layer index is a whole number from 0 to 2**31 - 1, a height above 0 and
a width from 0, both at most ``ANNOTATION_MAX_MM``; a role is one of the five words.

The writer emits an annotation wherever its value changes, so ``parse(write(p)) == p`` exactly:
coordinates are kept on a 1 µm grid (``quantize``) and written with three decimals. The parser
reads the plain MOVE and TOOL lines of a file (nearly all of them) in one compiled sweep
(:mod:`.scan`) and every other line with the line parser, which is the reference: whatever the
sweep cannot take as written, the line parser reads or refuses with ``file:line:column: message``.
"""

from __future__ import annotations

import io
import math
import mmap
import re
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, Iterable, Iterator, TextIO

import numpy as np

from cooprint.errors import UserError, clip
from cooprint.geometry import MAX_COORD_MM
from cooprint.slicing.paths import (BRIDGE, GAP_FILL, INFILL, OVERHANG, PERIMETER_INNER, PERIMETER_OUTER, SKIN,
                                    TOP_SKIN, TRAVEL)
from cooprint.io.files import regular_file
from cooprint.program.comment import comment_safe
from cooprint.program.numtext import NONE, Table, Templates, assemble

#: Command kinds.
MOVE, TOOL_ON, TOOL_OFF, NOTIFY, WAIT = range(5)
KIND_NAMES = ("MOVE", "TOOL ON", "TOOL OFF", "NOTIFY", "WAIT")
#: Path roles as annotations name them (index = role number of :mod:`cooprint.slicing.paths`).
ROLE_WORDS = {PERIMETER_OUTER: "outer-perimeter", PERIMETER_INNER: "perimeter", SKIN: "skin",
              INFILL: "infill", TRAVEL: "travel", TOP_SKIN: "top-skin", BRIDGE: "bridge", GAP_FILL: "gap-fill",
              OVERHANG: "overhang-perimeter"}
_ROLE_OF_WORD = {w: r for r, w in ROLE_WORDS.items()}
#: Coordinates of a program lie on this grid, mm (what the writer's three decimals hold).
RESOLUTION = 1e-3
FORMAT = "cooprint-coop/1"
#: The largest layer height and path width an annotation may state, mm (no nozzle lays a layer
#: or a line this thick; past it a file is wrong, and the G-code export would push absurd E).
ANNOTATION_MAX_MM = 50.0
#: The largest facing of a ``;@facing`` annotation, degrees (either way round).
FACING_MAX_DEG = 360.0
#: The longest event or chunk name.
MAX_NAME = 64
#: The per-command arrays of a :class:`Program`, in field order.
COLUMNS = ("kind", "xyz", "role", "width", "layer", "height", "chunk", "event")


class ProgramError(UserError):
    """A command file that is not valid: ``file:line:column: what is wrong``."""


def quantize(xyz: np.ndarray) -> np.ndarray:
    """Coordinates on the 1 µm grid: ``rint(x * 1000) / 1000`` is the double nearest to a
    three-decimal number, which is what ``'%.3f'`` writes and ``float()`` reads back."""
    return np.rint(np.asarray(xyz, dtype=np.float64) * 1000.0) / 1000.0


@dataclass(frozen=True, eq=False)
class Program:
    """A robot's command stream (or a piece of one), one row per command.

    Attributes
    ----------
    robot : str
        The robot's name.
    kind : (n,) uint8
        ``MOVE, TOOL_ON, TOOL_OFF, NOTIFY, WAIT``.
    xyz : (n, 3) float64
        Target of a MOVE, mm, on the 1 µm grid; NaN for other commands.
    role : (n,) uint8
        Path role of the command (``cooprint.slicing.paths``; ``TRAVEL`` outside paths).
    width : (n,) float64
        Extrusion width, mm (0 outside extruding paths).
    layer : (n,) int32
        Layer index within the chunk, from 0 (-1: not in a layer).
    height : (n,) float64
        Layer thickness, mm (0: not in a layer).
    chunk : (n,) int16
        Index into ``chunks`` (-1: between chunks).
    event : (n,) int32
        For NOTIFY and WAIT, index into ``events``; -1 otherwise.
    chunks : tuple of str
        Chunk ids.
    events : tuple of tuple of str
        The event names of each NOTIFY / WAIT, in order (a NOTIFY has one).
    turns : tuple of (int, float)
        ``(i, degrees)``: before command ``i`` the robot turns about its nozzle, the shorter way,
        to face ``degrees`` (from +X, the direction from its body to the nozzle); ``i`` in order,
        ``len(self)`` for a turn after the last command. Empty: it keeps the facing it started
        with (the plan's ``facing_deg``) throughout.
    """

    robot: str
    kind: np.ndarray
    xyz: np.ndarray
    role: np.ndarray
    width: np.ndarray
    layer: np.ndarray
    height: np.ndarray
    chunk: np.ndarray
    event: np.ndarray
    chunks: tuple[str, ...] = ()
    events: tuple[tuple[str, ...], ...] = ()
    turns: tuple[tuple[int, float], ...] = ()

    def __len__(self) -> int:
        return len(self.kind)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Program):
            return NotImplemented
        return (self.robot == other.robot and self.chunks == other.chunks and self.events == other.events
                and self.turns == other.turns
                and all(np.array_equal(getattr(self, f), getattr(other, f), equal_nan=f == "xyz")
                        for f in COLUMNS))

    __hash__ = None  # type: ignore[assignment]

    @property
    def moves(self) -> np.ndarray:
        """(n,) bool: which commands are MOVEs."""
        return self.kind == MOVE

    def tool_on(self, start: bool = False) -> np.ndarray:
        """(n,) bool: the tool is on while each command runs (a MOVE with it on deposits)."""
        change = np.where(self.kind == TOOL_ON, 1, np.where(self.kind == TOOL_OFF, 0, -1))
        idx = np.where(change >= 0, np.arange(len(change)), -1)
        last = np.maximum.accumulate(idx) if len(idx) else idx
        return np.where(last >= 0, change[np.maximum(last, 0)] == 1, start)

    @staticmethod
    def empty(robot: str) -> "Program":
        return Program(robot, np.zeros(0, np.uint8), np.zeros((0, 3)), np.zeros(0, np.uint8), np.zeros(0),
                       np.zeros(0, np.int32), np.zeros(0), np.zeros(0, np.int16), np.zeros(0, np.int32))

    @staticmethod
    def concat(robot: str, pieces: Iterable["Program"]) -> "Program":
        """One program from pieces in order (their chunk tables merged, events renumbered)."""
        pieces = list(pieces)
        if not pieces:
            return Program.empty(robot)
        chunks: list[str] = []
        for p in pieces:
            chunks += [c for c in p.chunks if c not in chunks]
        cols: dict[str, list[np.ndarray]] = {f: [] for f in COLUMNS}
        events: list[tuple[str, ...]] = []
        turns: list[tuple[int, float]] = []
        at = 0  # commands before the piece
        for p in pieces:
            turns += [(i + at, deg) for i, deg in p.turns]
            at += len(p)
            remap = np.array([chunks.index(c) for c in p.chunks] + [-1], dtype=np.int16)
            for f in COLUMNS[:6]:  # as they are; chunk and event renumbered
                cols[f].append(getattr(p, f))
            cols["chunk"].append(remap[p.chunk])  # -1 indexes the appended -1
            cols["event"].append(np.where(p.event >= 0, p.event + len(events), -1).astype(np.int32))
            events += p.events
        return Program(robot, *(np.concatenate(cols[f]) for f in cols), chunks=tuple(chunks),
                       events=tuple(events), turns=tuple(turns))



def program_rows(p: Program, a: int, b: int, last: bool | None = None) -> Program:
    """Commands ``a`` to ``b - 1`` of ``p`` as a program piece: the turns before them (and,
    if ``last``, by default when ``b`` is the end, those after the last command), the events
    they name renumbered from 0, the chunk table kept. Splitting a program at any points and writing the pieces in
    order writes the whole program (:class:`CoopWriter`, :class:`~.gcode.GcodeWriter`)."""
    n = len(p)
    a, b = max(0, min(a, n)), max(0, min(b, n))
    ev = p.event[a:b]
    used = ev[ev >= 0]
    first = int(used[0]) if len(used) else 0
    events = p.events[first:int(used[-1]) + 1] if len(used) else ()
    last = b == n if last is None else last
    turns = tuple((i - a, d) for i, d in p.turns if a <= i < b or (last and i == n and b == n))
    return Program(p.robot, p.kind[a:b], p.xyz[a:b], p.role[a:b], p.width[a:b], p.layer[a:b], p.height[a:b],
                   p.chunk[a:b], np.where(ev >= 0, ev - first, -1).astype(np.int32), p.chunks, events, turns)


def make_program(robot: str, kind: np.ndarray, xyz: np.ndarray | None = None, *, role=TRAVEL, width=0.0,
                 layer=-1, height=0.0, chunk=-1, chunks: tuple[str, ...] = (),
                 events: tuple[tuple[str, ...], ...] = (), turns: tuple[tuple[int, float], ...] = ()) -> Program:
    """A :class:`Program` from a kind array and (n, 3) MOVE targets (rows of other commands are
    ignored); the metadata are scalars or (n,) arrays. Events number the NOTIFY / WAIT commands in
    order; ``turns`` are :attr:`Program.turns`."""
    kind = np.asarray(kind, dtype=np.uint8)
    n = len(kind)
    pos = np.full((n, 3), np.nan)
    if xyz is not None:
        m = kind == MOVE
        pos[m] = quantize(np.asarray(xyz, dtype=np.float64).reshape(n, 3)[m])
    sync = (kind == NOTIFY) | (kind == WAIT)
    event = np.full(n, -1, np.int32)
    event[sync] = np.arange(int(sync.sum()), dtype=np.int32)
    if len(events) != int(sync.sum()):
        raise ValueError(f"{int(sync.sum())} NOTIFY/WAIT commands but {len(events)} event lists")

    def full(v, dtype):
        return np.broadcast_to(np.asarray(v, dtype=dtype), (n,)).copy()

    return Program(robot, kind, pos, full(role, np.uint8), full(width, np.float64), full(layer, np.int32),
                   full(height, np.float64), full(chunk, np.int16), event, tuple(chunks), tuple(events),
                   tuple((int(i), float(d)) for i, d in turns))


# ----------------------------------------------------------------------------------------------
# writing


#: State before the first command: what the parser assumes until an annotation says otherwise
#: (chunk id, None between chunks; layer and height; role and width).
_START = (None, (-1, 0.0), (TRAVEL, 0.0))


def _changes(cols: list[np.ndarray], before: tuple) -> np.ndarray:
    """(n,) bool: the commands where any of ``cols`` differs from the command before (the
    first compared with ``before``, the values of the last command of the previous piece)."""
    n = len(cols[0])
    out = np.zeros(n, dtype=bool)
    for col, b in zip(cols, before):
        out[1:] |= col[1:] != col[:-1]
        out[0] |= bool(col[0] != b)
    return out


def _keyed(table, a: np.ndarray, b: np.ndarray, text) -> np.ndarray:
    """The table ids of ``text(x, y)`` for the pairs of ``a`` and ``b``, each distinct pair
    formatted once."""
    if not len(a):
        return np.zeros(0, np.int64)
    def unique(x):  # floats by their bits: -0.0 is written as such
        bits = x.dtype.kind == "f"
        u, inv = np.unique(x.astype(np.float64).view(np.int64) if bits else x, return_inverse=True)
        return (u.view(np.float64) if bits else u), inv.ravel()

    ua, ia = unique(a)
    ub, ib = unique(b)
    key = ia.astype(np.int64) * len(ub) + ib
    uk, ik = np.unique(key, return_inverse=True)
    ids = np.array([table.id(text(ua[k // len(ub)].item(), ub[k % len(ub)].item())) for k in uk.tolist()], np.int64)
    return ids[ik.ravel()]


class CoopWriter:
    """Writes a robot's ``.coop`` file piece by piece: the same bytes for any split of the
    program into pieces (``cooprint run`` streams it: a chunk's commands, a travel leg, a
    WAIT).

    An annotation is written where its value differs from the command before, across pieces
    too; a turn is written after the annotations of the command it precedes, so turns after a
    piece's last command are held until the next command (or :meth:`close`). Text is made by
    :mod:`.numtext`, all lines of a block of at most ``BLOCK`` commands in one compiled pass;
    ``out`` is a text or a binary file. :meth:`close` ends the program (the file is the
    caller's to close).
    """

    BLOCK = 1 << 17

    def __init__(self, out: TextIO | BinaryIO, robot: str, header: Iterable[str] = ()):
        self.out = out
        self._text = isinstance(out, io.TextIOBase)
        self._state = _START
        self._held: list[float] = []  # facings turned to after the last command written
        self._templates = Templates(["MOVE %.3f, %.3f, %.3f\n"])
        self._put((f"; {FORMAT} program for robot {comment_safe(robot)}\n"
                   + "".join(f"; {comment_safe(line)}\n" for line in header)).encode("utf-8"))

    def _put(self, data: np.ndarray | bytes) -> None:
        if len(data):
            self.out.write(bytes(data).decode("utf-8") if self._text else memoryview(data))

    def write(self, piece: Program) -> None:
        n = len(piece)
        for a in range(0, max(n, 1), self.BLOCK):
            self._write(program_rows(piece, a, min(a + self.BLOCK, n)))

    def close(self) -> None:
        """Write the turns after the last command."""
        self._put("".join(f";@facing {d!r}\n" for d in self._held).encode())
        self._held = []

    def _write(self, p: Program) -> None:
        n = len(p)
        turns: dict[int, list[float]] = {}  # command index -> the facings turned to before it
        for i, deg in p.turns:
            turns.setdefault(i, []).append(deg)
        if n == 0:
            self._held += turns.get(0, [])
            return
        if self._held:
            turns[0] = self._held + turns.get(0, [])
        self._held = turns.pop(n, [])
        names = [*p.chunks, None]
        chunk = _changes([p.chunk], (-1,))
        chunk[0] = names[p.chunk[0]] != self._state[0]
        layer = _changes([p.layer, p.height], self._state[1])
        path = _changes([p.role, p.width], self._state[2])
        table = Table()
        ops = np.full((n, 5), NONE, np.int32)  # per command: ;@chunk, ;@layer, ;@path, ;@facing, the command
        at = np.flatnonzero(chunk)
        chunk_ids = np.array([table.id(f";@chunk {c if c is not None else '-'}\n") for c in names], np.int64)
        ops[at, 0] = chunk_ids[p.chunk[at]]
        at = np.flatnonzero(layer)
        ops[at, 1] = _keyed(table, p.layer[at], p.height[at],
                            lambda la, h: f";@layer {la} {h!r}\n" if la >= 0 else ";@layer -\n")
        at = np.flatnonzero(path)
        ops[at, 2] = _keyed(table, p.role[at], p.width[at], lambda r, w: f";@path {ROLE_WORDS[r]} {w!r}\n")
        for i, facings in turns.items():
            ops[i, 3] = table.id("".join(f";@facing {d!r}\n" for d in facings))
        kind = p.kind
        cmd = ops[:, 4]
        cmd[kind == MOVE] = -1  # the numeric template
        cmd[kind == TOOL_ON] = table.id("TOOL ON\n")
        cmd[kind == TOOL_OFF] = table.id("TOOL OFF\n")
        sync = np.flatnonzero(p.event >= 0)
        cmd[sync] = [table.id(f"{KIND_NAMES[kind[i]]} {', '.join(p.events[p.event[i]])}\n") for i in sync.tolist()]
        self._put(assemble(ops, np.arange(n), table, self._templates, p.xyz))
        last = n - 1
        self._state = (names[p.chunk[last]], (int(p.layer[last]), float(p.height[last])),
                       (int(p.role[last]), float(p.width[last])))


def write_coop(out: TextIO | BinaryIO, program: Program, header: Iterable[str] = ()) -> None:
    """Write ``program`` as ``.coop`` text (a header of comment lines first): a
    :class:`CoopWriter` given the whole program."""
    w = CoopWriter(out, program.robot, header)
    w.write(program)
    w.close()


def coop_text(program: Program, header: Iterable[str] = ()) -> str:
    buf = io.StringIO()
    write_coop(buf, program, header)
    return buf.getvalue()


# ----------------------------------------------------------------------------------------------
# parsing

_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")  # ASCII digits only
_INDEX = re.compile(r"[0-9]+")
_NONFINITE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)
_EVENT = re.compile(r"[A-Za-z0-9_:.\-]+")
_TOKEN = re.compile(r"[^\s,]+|,")
#: Characters no line holds: controls other than tab (a CR only at the end) and the Unicode line
#: and paragraph separators.
_CONTROL = re.compile("[\x00-\x08\x0b-\x1f\x7f\x85\u2028\u2029]")


class _Lines:
    """Parses lines one at a time (the reference parser), keeping the annotation state and the
    NOTIFY count."""

    def __init__(self, source: str, robot: str):
        self.source, self.robot = source, robot
        self.notifies = 0
        self.chunks: list[str] = []

    def error(self, lineno: int, col: int, msg: str) -> ProgramError:
        return ProgramError(f"{self.source}:{lineno}:{col}: {msg}")

    def parse(self, line: str, lineno: int):
        """``None`` (blank or comment), ``("ann", key, value)`` or ``(kind, payload)``."""
        bad = _CONTROL.search(line, 0, len(line) - line.endswith("\r"))
        if bad:  # a file with CR (old Mac) line ends would otherwise read as one line
            raise self.error(lineno, bad.start() + 1, f"control character U+{ord(bad.group()):04X} inside a line "
                                                      "(lines end with LF or CRLF)")
        cut = min((i for i in (line.find(";"), line.find("#")) if i >= 0), default=len(line))
        code, comment = line[:cut], line[cut:]
        tokens = [(m.group(), m.start() + 1) for m in _TOKEN.finditer(code)]
        if not tokens:
            return self.annotation(comment, lineno, cut) if comment.startswith(";@") else None
        word, col = tokens[0]
        w = word.upper()
        args = tokens[1:]
        if w == "MOVE":
            return MOVE, self.numbers(args, lineno, col, len(code.rstrip()) + 1)
        if w == "TOOL":
            words = [t for t in args if t[0] != ","]
            if len(words) != 1 or len(args) != 1 or words[0][0].upper() not in ("ON", "OFF"):
                at = args[0][1] if args else len(code.rstrip()) + 2
                got = f"'{clip(' '.join(t for t, _ in args))}'" if args else "nothing"
                raise self.error(lineno, at, f"TOOL needs ON or OFF, got {got}")
            return (TOOL_ON if words[0][0].upper() == "ON" else TOOL_OFF), None
        if w == "NOTIFY":
            if len(args) > 1 or (args and args[0][0] == ","):
                bad = args[1] if len(args) > 1 else args[0]
                raise self.error(lineno, bad[1], f"NOTIFY takes at most one event name, extra token '{clip(bad[0])}'")
            self.notifies += 1
            name = self.event_name(args[0], lineno) if args else f"{self.robot}:{self.notifies}"
            return NOTIFY, (name,)
        if w == "WAIT":
            names = self.separated(args, lineno, col, "WAIT", "event name", self.event_name)
            if not names:
                raise self.error(lineno, len(code.rstrip()) + 2, "WAIT needs at least one event name")
            return WAIT, tuple(names)
        raise self.error(lineno, col, f"unknown word '{clip(word)}' (expected MOVE, TOOL, NOTIFY or WAIT)")

    def separated(self, args, lineno, col, what, item, convert):
        """Items separated by whitespace or by single commas."""
        out, expect_item = [], True
        for tok, c in args:
            if tok == ",":
                if expect_item:
                    raise self.error(lineno, c, f"{what}: a comma where a {item} was expected")
                expect_item = True
                continue
            out.append(convert((tok, c), lineno))
            expect_item = False
        if out and expect_item:
            raise self.error(lineno, args[-1][1], f"{what}: a comma with no {item} after it")
        return out

    def number(self, tok, lineno: int) -> float:
        """A MOVE coordinate: an ASCII decimal number, finite, at most ``MAX_COORD_MM`` from 0."""
        text, col = tok
        value = self.decimal(tok, lineno, "")
        if not abs(value) <= MAX_COORD_MM:
            raise self.error(lineno, col, f"coordinate {clip(text)} is beyond +-{MAX_COORD_MM:g} mm (the largest "
                                          "coordinate cooprint accepts; wrong units?)")
        return value

    def decimal(self, tok, lineno: int, what: str) -> float:
        """A finite ASCII decimal number (``what`` names the field in the message)."""
        text, col = tok
        if _NONFINITE.fullmatch(text):
            raise self.error(lineno, col, f"{what}'{text}' is not a finite number")
        if not _NUMBER.fullmatch(text):
            raise self.error(lineno, col, f"{what}'{clip(text)}' is not a number (ASCII digits, e.g. -12.5)")
        value = float(text)
        if not math.isfinite(value):
            raise self.error(lineno, col, f"{what}'{clip(text)}' is not a finite number")
        return value

    def numbers(self, args, lineno: int, col: int, end: int) -> tuple[float, float, float]:
        values = self.separated(args, lineno, col, "MOVE", "number", self.number)
        if len(values) < 3:
            raise self.error(lineno, end, f"MOVE needs 3 numbers (x, y, z), got {len(values)}")
        if len(values) > 3:
            extra = [t for t in args if t[0] != ","][3]
            raise self.error(lineno, extra[1], f"MOVE takes 3 numbers (x, y, z), extra token '{clip(extra[0])}'")
        return values[0], values[1], values[2]

    def event_name(self, tok, lineno: int) -> str:
        text, col = tok
        if not _EVENT.fullmatch(text) or len(text) > MAX_NAME:
            raise self.error(lineno, col, f"'{clip(text)}' is not an event name (letters, digits, _ : . -; at "
                                          f"most {MAX_NAME})")
        return text

    def annotation(self, comment: str, lineno: int, cut: int):
        """``;@chunk``, ``;@layer``, ``;@path`` and ``;@facing`` checked field by field (any other ``;@`` word is
        an annotation of a later version: a comment here)."""
        parts = comment[2:].split()
        if not parts or parts[0].lower() not in ("chunk", "layer", "path", "facing"):
            return None
        key, vals = parts[0].lower(), parts[1:]
        form = {"chunk": "';@chunk ID' or ';@chunk -'", "layer": "';@layer INDEX HEIGHT' or ';@layer -'",
                "facing": "';@facing DEGREES' (a finite number)",
                "path": "';@path ROLE WIDTH' with ROLE one of " + ", ".join(_ROLE_OF_WORD)}[key]
        if len(vals) != (1 if key in ("chunk", "facing") or vals == ["-"] else 2):
            raise self.error(lineno, cut + 3, f"malformed annotation '{clip(comment.strip())}': expected {form}")
        at, pos = [], cut + 3 + len(parts[0])  # each field's column
        for v in vals:
            pos = comment.index(v, pos - cut - 1) + cut + 1
            at.append((v, pos))
            pos += len(v)
        if key == "chunk":
            if vals[0] == "-":
                return "ann", "chunk", -1
            if not _EVENT.fullmatch(vals[0]) or len(vals[0]) > MAX_NAME:
                raise self.error(lineno, at[0][1], f";@chunk ID '{clip(vals[0])}': expected a chunk name (letters, "
                                                   f"digits, _ : . -; at most {MAX_NAME})")
            if vals[0] not in self.chunks:
                self.chunks.append(vals[0])
            return "ann", "chunk", self.chunks.index(vals[0])
        if key == "facing":
            deg = self.decimal(at[0], lineno, ";@facing DEGREES ")
            if not -FACING_MAX_DEG <= deg <= FACING_MAX_DEG:
                raise self.error(lineno, at[0][1], f";@facing DEGREES {clip(vals[0])}: expected degrees from "
                                                   f"{-FACING_MAX_DEG:g} to {FACING_MAX_DEG:g}")
            return "ann", "facing", deg
        if key == "layer":
            if vals == ["-"]:
                return "ann", "layer", (-1, 0.0)
            if not _INDEX.fullmatch(vals[0]) or int(vals[0]) >= 2**31:
                raise self.error(lineno, at[0][1], f";@layer INDEX '{clip(vals[0])}': expected a whole number from "
                                                   f"0 to {2**31 - 1}")
            height = self.decimal(at[1], lineno, ";@layer HEIGHT ")
            if not 0 < height <= ANNOTATION_MAX_MM:
                raise self.error(lineno, at[1][1], f";@layer HEIGHT {clip(vals[1])}: expected mm above 0 and at "
                                                   f"most {ANNOTATION_MAX_MM:g}")
            return "ann", "layer", (int(vals[0]), height)
        if vals[0] not in _ROLE_OF_WORD:
            raise self.error(lineno, at[0][1], f";@path ROLE '{clip(vals[0])}': expected one of "
                                               + ", ".join(_ROLE_OF_WORD))
        width = self.decimal(at[1], lineno, ";@path WIDTH ")
        if not 0 <= width <= ANNOTATION_MAX_MM:
            raise self.error(lineno, at[1][1], f";@path WIDTH {clip(vals[1])}: expected mm from 0 to "
                                               f"{ANNOTATION_MAX_MM:g}")
        return "ann", "path", (_ROLE_OF_WORD[vals[0]], width)


#: The UTF-8 byte-order mark, which a ``.coop`` file may start with.
UTF8_BOM = b"\xef\xbb\xbf"


def parse_coop(text: str | bytes | mmap.mmap, robot: str, source: str = "<program>") -> Program:
    """Read ``.coop`` text into a :class:`Program`.

    Parameters
    ----------
    robot
        The robot's name (names its bare NOTIFYs).
    source
        Named in error messages (a file path).

    Raises
    ------
    ProgramError
        ``source:line:column: what is wrong`` for the first malformed line.
    """
    data = text.encode() if isinstance(text, str) else text
    if bytes(data[:3]) == UTF8_BOM:  # Windows editors start UTF-8 text with one: it is not part of line 1
        data = memoryview(data)[3:]  # for the compiled sweep and the line parser alike (no copy of an mmap)
    return _Piece(_Lines(source, robot)).parse(data)


class _Piece:
    """Reads a program a piece of text at a time (whole lines): the line parser (its chunk names
    and NOTIFY count), the annotations in force and the line number carry from one piece to the
    next, so that the pieces' programs, concatenated, are the whole text's."""

    def __init__(self, lines: _Lines):
        self.lines = lines
        self.line0 = 0  # lines before the piece
        # the annotations in force: chunk (index in lines.chunks), (layer, height), (role, width)
        self.start = {"chunk": (-1,), "layer": (-1, 0.0), "path": (TRAVEL, 0.0)}

    def parse(self, data) -> Program:
        """The program of ``data`` (bytes or a buffer of them: whole lines, the next piece)."""
        from cooprint.program.scan import LAYER_LINE, PATH_LINE, commands_before, compact, sweep  # numba: on first use

        lines, line0 = self.lines, self.line0
        robot = lines.robot
        swept = sweep(data)
        kind_of, xyz_of = swept.kind, swept.xyz  # per slot: a command, or a line for the line parser
        events = []
        ann: dict[str, list] = {"chunk": [], "layer": [], "path": [], "facing": []}  # (line, slot, value) of the line parser's
        for i, a, b, slot in swept.other.tolist():
            try:
                line = bytes(data[a:b]).decode("utf-8")
            except UnicodeDecodeError:
                raise lines.error(line0 + i + 1, 1, "not UTF-8 text") from None
            got = lines.parse(line, line0 + i + 1)
            if got is None:
                continue
            if got[0] == "ann":
                ann[got[1]].append((i, slot, got[2] if isinstance(got[2], tuple) else (got[2],)))
                continue
            kind, payload = got
            kind_of[slot] = kind
            if kind == MOVE:
                xyz_of[slot] = payload
            elif kind in (NOTIFY, WAIT):
                events.append(payload)
        # the line parser's slots that hold no command (annotations, blank lines in its share) leave:
        # the commands are moved to the front in place and the arrays cut there (no copy of the
        # program's columns), after each annotation's slot is turned into the commands above it
        def above(slots: np.ndarray) -> np.ndarray:
            """How many commands come before each of ``slots`` (ascending)."""
            out = np.empty(len(slots), np.int64)
            if len(slots):
                commands_before(kind_of, slots, out)
            return out

        def state(key: str, start: tuple, dtypes: tuple, fast: int = -1) -> tuple[list[np.ndarray], np.ndarray]:
            """Each annotation's values (the last one above each command holds), ``start`` before
            any, read by the sweep (``fast``) or by the line parser, in line order, as ``dtypes``;
            and how many commands each holds for."""
            mine = np.flatnonzero(swept.notes[:, 2] == fast)
            line = np.concatenate([np.array([x[0] for x in ann[key]], dtype=np.int64), swept.notes[mine, 0]])
            slot = np.concatenate([np.array([x[1] for x in ann[key]], dtype=np.int64), swept.notes[mine, 1]])
            order = np.argsort(line, kind="stable")
            held = np.diff(np.concatenate([[0], above(slot[order]), [commands]]))
            values = [np.concatenate([[s], np.array([x[2][j] for x in ann[key]], dtype=np.float64),
                                      swept.values[mine, j]])[np.r_[0, order + 1]].astype(dt)
                      for j, (s, dt) in enumerate(zip(start, dtypes))]
            return values, held

        commands = int(np.count_nonzero(kind_of >= 0))
        (chunk_v,), chunk_n = state("chunk", self.start["chunk"], (np.int64,))
        layer_v, layer_n = state("layer", self.start["layer"], (np.int32, np.float64), LAYER_LINE)
        path_v, path_n = state("path", self.start["path"], (np.uint8, np.float64), PATH_LINE)
        # in force after the piece: its last annotations; the next piece's first line
        self.start = {"chunk": (int(chunk_v[-1]),), "layer": (int(layer_v[0][-1]), float(layer_v[1][-1])),
                      "path": (int(path_v[0][-1]), float(path_v[1][-1]))}
        self.line0 += swept.lines - 1
        turn_at = above(np.array([x[1] for x in ann["facing"]], dtype=np.int64))
        if commands < len(kind_of):
            compact(kind_of, xyz_of)
            kind_of.resize(commands, refcheck=False)  # in place: the rest goes back to the heap
            xyz_of.resize((commands, 3), refcheck=False)
        kind_of = kind_of.view(np.uint8)  # 0..4 either way
        # the chunk table: the chunks that commands belong to, in the order they first appear
        used = chunk_v[(chunk_n > 0) & (chunk_v >= 0)]
        used = used[np.sort(np.unique(used, return_index=True)[1])]
        remap = np.full(len(lines.chunks) + 1, -1, dtype=np.int16)
        remap[used] = np.arange(len(used))
        chunk = np.repeat(remap[chunk_v], chunk_n)
        layer, height = (np.repeat(v, layer_n) for v in layer_v)
        role, width = (np.repeat(v, path_n) for v in path_v)
        event = np.full(commands, -1, np.int32)
        sync = np.flatnonzero(kind_of >= NOTIFY)  # NOTIFY and WAIT
        event[sync] = np.arange(len(sync), dtype=np.int32)
        # a turn comes before the first command below its line (the commands above its slot)
        turns = tuple((int(i), x[2][0]) for i, x in zip(turn_at.tolist(), ann["facing"]))
        return Program(robot, kind_of, xyz_of, role, width, layer, height, chunk, event,
                       tuple(lines.chunks[c] for c in used.tolist()), tuple(events), turns)


def read_coop(path: str | Path, robot: str | None = None) -> Program:
    """Read a ``.coop`` file, plain or gzip-compressed (``A.coop.gz``); the robot's name
    defaults to the file's stem (``A``). The file is mapped (a compressed one read and
    decompressed) and read a piece at a time (:func:`iter_coop`), each piece's commands written
    into the program's columns as they come: reading holds the program and one piece, not the
    file's pages nor the sweep's work space for the whole file."""
    from cooprint.io.bundle import plain_name

    p = Path(path)
    name = robot or plain_name(p).stem
    size = p.stat().st_size if p.is_file() else 0
    # at most a command every 7 bytes ('NOTIFY' and its newline): room for all; pages never
    # written are never backed by memory, and the columns are cut to size at the end
    cols = {f: None for f in COLUMNS}
    at, chunks, events, turns = 0, [], [], []
    for piece in iter_coop(p, name):
        n = len(piece)
        if cols["kind"] is None or at + n > len(cols["kind"]):  # first piece, or a file that grew
            room = max(at + n, size // 7 + 1, 2 * len(cols["kind"]) if cols["kind"] is not None else 0)
            for f in COLUMNS:
                col = getattr(piece, f)
                if cols[f] is None:
                    cols[f] = np.empty((room,) + col.shape[1:], col.dtype)
                else:
                    cols[f].resize((room,) + col.shape[1:], refcheck=False)
        chunks += [c for c in piece.chunks if c not in chunks]  # in the order they first appear
        remap = np.array([chunks.index(c) for c in piece.chunks] + [-1], dtype=np.int16)
        for f in COLUMNS[:6]:
            cols[f][at:at + n] = getattr(piece, f)
        cols["chunk"][at:at + n] = remap[piece.chunk]  # -1 indexes the appended -1
        cols["event"][at:at + n] = np.where(piece.event >= 0, piece.event + len(events), -1)
        events += piece.events
        turns += [(i + at, deg) for i, deg in piece.turns]
        at += n
    for f in COLUMNS:
        cols[f].resize((at,) + cols[f].shape[1:], refcheck=False)  # in place: the rest goes back
    return Program(name, *(cols[f] for f in COLUMNS), chunks=tuple(chunks), events=tuple(events), turns=tuple(turns))


#: How much text :func:`iter_coop` reads at a time, bytes (about 200,000 commands; small, so
#: that what a piece needs while it is read is little beside the program it is read into).
PIECE_BYTES = 4 << 20


def iter_coop(path: str | Path, robot: str | None = None, piece_bytes: int = PIECE_BYTES) -> Iterator[Program]:
    """A ``.coop`` file's program in pieces of whole lines, about ``piece_bytes`` of text each:
    ``Program.concat(robot, iter_coop(path))`` is ``read_coop(path)`` (each piece has its own
    chunk table and events; the annotations in force, the chunk names, the count of bare
    NOTIFYs and the line numbers of error messages carry over). The file is mapped, and the
    pages of each piece are given back once it is read: reading a program of any size holds a
    piece of its text and the piece's program at a time."""
    from cooprint.io.bundle import plain_name, release

    p = Path(path)
    name = robot or plain_name(p).stem
    data = _open_coop(p)
    try:
        n = len(data)
        a = 3 if n >= 3 and bytes(data[:3]) == UTF8_BOM else 0  # not part of line 1
        reader = _Piece(_Lines(str(p), name))
        first = True
        while a < n or first:  # an empty file is one empty piece
            first = False
            cut = data.find(b"\n", a + max(piece_bytes, 1) - 1) if a + piece_bytes < n else -1
            b = n if cut < 0 else cut + 1  # just after a newline, or the end
            with memoryview(data)[a:b] as piece:
                program = reader.parse(piece)
            if isinstance(data, mmap.mmap):  # the piece's whole pages: read, not needed again
                lo, hi = a - a % mmap.PAGESIZE, b - b % mmap.PAGESIZE
                if hi > lo:
                    data.madvise(mmap.MADV_DONTNEED, lo, hi - lo)
            a = b
            yield program
    finally:
        release(data)


def _open_coop(p: Path):
    """A command file mapped (or read: an empty file, a pipe; read and decompressed: a gzip
    file; :func:`cooprint.io.bundle.map_input`), or a one-line error."""
    from cooprint.io.bundle import map_input

    regular_file(p, "command file", ProgramError)  # a FIFO would block the read for ever
    try:
        return map_input(p, ProgramError)
    except FileNotFoundError:
        raise ProgramError(f"{p}: no such command file") from None
    except OSError as exc:
        raise ProgramError(f"{p}: cannot read ({exc})") from None


__all__ = ["CoopWriter", "FORMAT", "KIND_NAMES", "MOVE", "NOTIFY", "Program", "ProgramError", "RESOLUTION",
           "ROLE_WORDS", "TOOL_OFF", "TOOL_ON", "WAIT", "iter_coop", "make_program", "parse_coop", "program_rows",
           "coop_text", "quantize", "read_coop", "write_coop"]
