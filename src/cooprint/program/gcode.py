"""Marlin-flavour G-code from a command stream (a writer only: no geometry decisions here).

The same :class:`~cooprint.program.commands.Program` that a robot's ``.coop`` file holds is
written here, piece by piece as it arrives (``cooprint slice`` streams one layer at a time,
``cooprint run`` a robot's program chunk by chunk); any split of a program into pieces gives the
bytes of the whole (:class:`GcodeWriter`):

* G21 (mm), G90 (absolute XYZ), M83 (relative E), temperatures, start and end code;
* a MOVE with the tool on is ``G1 X Y E`` with ``E = area(width, height) * length / filament
  area`` (Slic3r's flow cross-section); with the tool off it is a travel ``G0 X Y Z``;
* feed rates are mm/min, converted here and only here from :class:`Feeds` (mm/s);
* the filament is retracted before a travel of at least ``retract_before_travel`` and pushed
  back at the next ``TOOL ON``;
* ``;LAYER:<i>``, ``;Z:<z>``, ``;CHUNK:<id>`` and ``;TYPE:<role>`` comments, as slicers write them;
* NOTIFY and WAIT for a fleet host (docs/program.md): ``; NOTIFY e`` then ``M400`` (wait until the
  moves before are done) and ``M118 NOTIFY e`` (a line the host reads); ``; WAIT e`` then ``M400``
  and ``M0 WAIT e`` (the printer stops until the host resumes it once every event was announced);
* heating: a printer (``cooprint slice``) heats bed and nozzle in its start code; a mobile robot
  (:class:`Heating`) heats its nozzle only right before the first extrusion (``M104`` + ``M109`` at
  the first ``TOOL ON``), so that a robot whose program starts by waiting for another robot's
  chunk does not sit hot for hours; before a WAIT expected to last longer than the idle limit
  the hot nozzle is turned off (``M104 S0``) and it is heated again before the next extrusion. A
  robot heats a bed (``M140``/``M190``) only when its profile has one.
* a turn (``;@facing d``) as ``; FACING d``, ``M400`` and ``M0 FACING d``: the printer stops where
  the turn is, and the host turns the robot round about its nozzle to face ``d`` degrees, then
  resumes it.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from typing import BinaryIO, Iterable, TextIO

import numba
import numpy as np

from cooprint.config import RobotProfile, SlicingSettings
from cooprint.program.commands import MOVE, NOTIFY, TOOL_ON, WAIT, Program, program_rows
from cooprint.program.numtext import NONE, Table, Templates, assemble
from cooprint.program.comment import comment_safe
from cooprint.slicing.paths import (BRIDGE, GAP_FILL, INFILL, OVERHANG, PERIMETER_INNER, PERIMETER_OUTER, SKIN,
                                    TOP_SKIN, TRAVEL, flow_area)

#: ``;TYPE:`` names, PrusaSlicer's (its G-code viewer and cooprint's reader know them; travel has
#: none in PrusaSlicer, cooprint marks it as Cura does).
ROLE_TYPES = {PERIMETER_OUTER: "External perimeter", PERIMETER_INNER: "Perimeter", SKIN: "Solid infill",
              INFILL: "Internal infill", TRAVEL: "TRAVEL", TOP_SKIN: "Top solid infill", BRIDGE: "Bridge infill",
              GAP_FILL: "Gap fill", OVERHANG: "Overhang perimeter"}


#: The [slicing] field that gives each path role its feed rate (PrusaSlicer's: an overhang
#: perimeter at the bridge speed). An extrusion of role ``TRAVEL`` (no slicer makes one; a
#: hand-written ``.coop`` may) runs at the infill speed.
ROLE_SPEEDS = {PERIMETER_OUTER: "external_perimeter_speed", PERIMETER_INNER: "perimeter_speed",
               SKIN: "solid_infill_speed", INFILL: "infill_speed", TRAVEL: "infill_speed",
               TOP_SKIN: "top_solid_infill_speed", BRIDGE: "bridge_speed", GAP_FILL: "gap_fill_speed",
               OVERHANG: "bridge_speed"}


@dataclass(frozen=True)
class Feeds:
    """Feed rates, mm/s: the one time model of every command, for the G-code's ``F`` and for
    every estimate and simulation of a plan (issue 17).

    ``role[r]`` is the speed of an extrusion of path role ``r`` (:data:`ROLE_SPEEDS`); on the
    first layer (layer 0) every extrusion runs at ``first_layer`` (PrusaSlicer's
    ``first_layer_speed`` in mm/s: it is applied to all the print moves of the first layer), and
    ``travel`` is the speed of every move with the tool off.
    """

    role: tuple[float, ...]
    first_layer: float
    travel: float

    @staticmethod
    def of_slicer(s: SlicingSettings) -> "Feeds":
        """The slicer's speeds: a printer's (``cooprint slice``), each role at its ``*_speed``."""
        return Feeds(tuple(float(getattr(s, ROLE_SPEEDS[r])) for r in range(len(ROLE_SPEEDS))),
                     float(s.first_layer_speed), float(s.travel_speed))

    @staticmethod
    def of_robot(robot: RobotProfile, s: SlicingSettings) -> "Feeds":
        """A mobile robot's speeds: the slicer's, every extrusion at most the robot's
        ``max_print_speed`` and travel at most its ``max_travel_speed`` (absent: no cap)."""
        f = Feeds.of_slicer(s)
        cap = math.inf if robot.max_print_speed is None else robot.max_print_speed
        travel_cap = math.inf if robot.max_travel_speed is None else robot.max_travel_speed
        return Feeds(tuple(min(v, cap) for v in f.role), min(f.first_layer, cap), min(f.travel, travel_cap))

    def extrude(self, role: int, layer: int) -> float:
        """The speed of an extrusion of ``role`` on ``layer`` (0: the first layer's speed)."""
        return self.first_layer if layer == 0 else self.role[role]

    def move_speeds(self, role: np.ndarray, layer: np.ndarray, on: np.ndarray) -> np.ndarray:
        """(k,) mm/s of moves of path ``role`` on ``layer``, the tool ``on`` or off: :meth:`extrude`
        where it is on, ``travel`` where it is off (vectorised)."""
        table = np.array(self.role, dtype=np.float64)
        lut = np.stack([table, np.full_like(table, self.first_layer)])  # [first layer?, role]
        v = lut[(np.asarray(layer) == 0).astype(np.intp), np.asarray(role, dtype=np.intp)]
        v[~np.asarray(on, dtype=bool)] = self.travel
        return v

    def speeds(self, p: Program, tool: bool = False) -> np.ndarray:
        """(n,) mm/s: the feed rate at which the G-code runs each command of ``p`` (the tool on:
        :meth:`extrude` of its role and layer; off: travel): the time model of a program at
        constant speed, the G-code's and the simulator's. ``tool``: whether the tool is on
        before ``p`` (a piece of a program)."""
        return self.move_speeds(p.role, p.layer, p.tool_on(tool))


@dataclass(frozen=True)
class Heating:
    """When a mobile robot's heaters are on (a printer's are on from the start code).

    Attributes
    ----------
    nozzle : float
        Printing temperature, C.
    bed : float or None
        Bed temperature, C; ``None``: the robot has no heated bed (no M140/M190 at all).
    idle_limit : float
        Longest expected WAIT, s, across which a hot nozzle stays hot.
    waits : tuple of float
        Expected duration of each WAIT of the program, in order, s (the plan's constant-speed
        estimate; ``inf`` for a WAIT that never ends). A WAIT without an estimate counts as long.
    """

    nozzle: float
    bed: float | None
    idle_limit: float
    waits: tuple[float, ...] = ()

    @staticmethod
    def of_robot(robot: RobotProfile, s: SlicingSettings, idle_limit: float,
                 waits: Iterable[float] = ()) -> "Heating":
        return Heating(s.nozzle_temperature, s.bed_temperature if robot.heated_bed else None, idle_limit,
                       tuple(float(w) for w in waits))

    def wait_is_long(self, k: int) -> bool:
        """Whether WAIT number ``k`` (from 0) is expected to last longer than the idle limit."""
        return not (k < len(self.waits) and self.waits[k] <= self.idle_limit)


def start_code(s: SlicingSettings, name: str, notes: Iterable[str] = (), home: bool = True,
               heating: Heating | None = None) -> str:
    """Units, modes, temperatures; ``G28`` (home) for a printer, not for a mobile robot, which
    knows where it is on the floor. With ``heating`` (a robot) the nozzle is not heated here but
    before the first extrusion, and the bed only if the robot has one."""
    if heating is None:
        heat = [f"M140 S{s.bed_temperature:g}", f"M104 S{s.nozzle_temperature:g}",
                f"M190 S{s.bed_temperature:g}", f"M109 S{s.nozzle_temperature:g}"]
    elif heating.bed is not None:
        heat = [f"M140 S{heating.bed:g}", f"M190 S{heating.bed:g}", "; the nozzle is heated before the first extrusion"]
    else:
        heat = ["; no heated bed; the nozzle is heated before the first extrusion"]
    lines = [
        f"; generated by cooprint for {comment_safe(name, ascii_only=True)}",
        f"; layer_height = {s.layer_height}, first_layer_height = {s.first_layer_height}, "
        f"extrusion_width = {s.extrusion_width}, perimeters = {s.perimeters}, "
        f"top/bottom layers = {s.top_layers}/{s.bottom_layers}, infill = {s.infill_density:g} "
        f"{s.infill_pattern}, filament_diameter = {s.filament_diameter}",
        *(f"; {comment_safe(n, ascii_only=True)}" for n in notes),
        "G21 ; millimetres", "G90 ; absolute coordinates", "M83 ; relative extrusion",
        *heat, *(["G28 ; home"] if home else []), "G92 E0", "",
    ]
    return "\n".join(lines)


def end_code(bed: bool = True) -> str:
    """Heaters off (the bed's only if there is one), motors off."""
    return "\n".join(["; end", "M400", "M104 S0", *(["M140 S0"] if bed else []), "M84", ""])


@numba.njit(cache=True, nogil=True)
def _runs(kind, extr, moving, climbs, chunk, layer, role, turn_at, first_moved, prev_ext, prev_role):
    """Per command: whether it extrudes (a MOVE that lays material: ``extr`` of its move), is a
    travel line (a MOVE that goes somewhere, ``moving``, without extruding), its move's row, whether
    it moved to another chunk or layer than the command before (``first_moved`` for the first),
    whether it continues the extrusion run before it (same role, not moved, no turn before it),
    and its numeric line: -1 ``G1 X Y E``, -2 ``G1 X Y Z E`` (a run of which any move climbs),
    -3 ``G0``, ``NONE``."""
    n = len(kind)
    ext = np.zeros(n, np.bool_)
    go = np.zeros(n, np.bool_)
    zm = np.zeros(n, np.bool_)
    row = np.full(n, -1, np.int64)
    r = 0
    for i in range(n):
        if kind[i] == MOVE:
            row[i] = r
            ext[i] = extr[r]
            go[i] = moving[r] and not extr[r]
            zm[i] = climbs[r]
            r += 1
    moved = np.empty(n, np.bool_)
    cont = np.empty(n, np.bool_)
    for i in range(n):
        if i == 0:
            m = first_moved
            c = ext[0] and prev_ext and role[0] == prev_role
        else:
            m = chunk[i] != chunk[i - 1] or layer[i] != layer[i - 1]
            c = ext[i] and ext[i - 1] and role[i] == role[i - 1]
        moved[i] = m
        cont[i] = c and not m and not turn_at[i]
    numeric = np.full(n, NONE, np.int32)
    i = 0
    while i < n:  # segment by segment: a run of extruding moves, or one command
        j = i + 1
        while j < n and cont[j]:
            j += 1
        z = False
        for k in range(i, j):
            z = z or zm[k]
        for k in range(i, j):
            if ext[k]:
                numeric[k] = -2 if z else -1
            elif go[k]:
                numeric[k] = -3
        i = j
    return ext, go, row, moved, cont, numeric


@numba.njit(cache=True, nogil=True)
def _states(kind, long_wait, travel_pre, starts, role, hot0, retracted0, role0, can_retract):
    """The state in force before each command 0..n (n: after the last), each set by the last
    command that changes it: the nozzle is hot (TOOL ON heats it, a long WAIT cools it); the
    filament is retracted (by a travel that retracts, ``travel_pre`` and hot, or a long WAIT
    while hot; TOOL ON pushes it back); the role of the last extrusion run (set where one starts;
    a travel keeps it: a ``;TYPE:`` line is written where the role changes, as PrusaSlicer does,
    not again after every travel)."""
    n = len(kind)
    hot = np.empty(n + 1, np.bool_)
    retracted = np.empty(n + 1, np.bool_)
    last_role = np.empty(n + 1, np.int64)
    h, r, lr = hot0, retracted0, role0
    for i in range(n):
        hot[i], retracted[i], last_role[i] = h, r, lr
        if kind[i] == TOOL_ON:
            h, r = True, False
        elif long_wait[i]:
            if h and can_retract:
                r = True
            h = False
        elif travel_pre[i] and h:
            r = True
        if starts[i]:
            lr = role[i]
    hot[n], retracted[n], last_role[n] = h, r, lr
    return hot, retracted, last_role


def _exact_units(e: np.ndarray) -> int:
    """The exact sum of finite doubles, as an integer in units of 2**-1126 (every double is a
    whole number of those): a sum that does not depend on how the values were split into
    pieces, which a float sum does (in its last bits)."""
    if not len(e):
        return 0
    e = np.asarray(e, dtype=np.float64)
    m, ex = np.frexp(e[e != 0])
    mant = (m * 2.0**53).astype(np.int64)  # exact: e = mant * 2**(ex - 53)
    if not len(mant):
        return 0
    group = ex.astype(np.int64) + 1073  # e = mant * 2**(group - 1126), group >= 0
    low = int(group.min())
    group -= low
    total = 0
    for a in range(0, len(mant), 1 << 26):  # float sums of at most 2**26 numbers below 2**27: exact
        g, part = group[a:a + (1 << 26)], mant[a:a + (1 << 26)]
        hi = np.bincount(g, weights=part >> 26)
        lo = np.bincount(g, weights=part & ((1 << 26) - 1))
        total += sum(((int(h) << 26) + int(lo_)) << (low + k)
                     for k, (h, lo_) in enumerate(zip(hi.tolist(), lo.tolist())))
    return total


class GcodeWriter:
    """Writes a program piece after piece, the bytes the same for any split of it into pieces
    (``cooprint run`` streams each robot's program: a chunk's commands, a travel leg, a WAIT).

    Some lines depend on what comes after them: a run of extruding moves is written with Z on
    every line if any of its moves climbs; a travel retracts if its whole run of travel moves
    (which NOTIFY, WAIT and TOOL commands do not end) is at least ``retract_before_travel``
    long; a layer's ``;Z:`` names the height of its next move. What such a decision still waits
    for is held back (the last extrusion run, an undecided travel run, a ``;LAYER:`` with no
    move yet) and written with a later piece or by :meth:`flush`; everything else is written at
    once. The state between pieces (position, tool, heat, retraction, current layer and role,
    the last command) is kept here. ``filament`` is the length extruded so far, mm (an exact
    sum: the same for any split).

    Text is made by :mod:`.numtext` (all lines of a block of commands in one compiled pass) and
    written in blocks of at most ``BLOCK`` commands; ``out`` is a text or a binary file.
    """

    #: Commands formatted at once (bounds the text buffer: about 40 bytes a command).
    BLOCK = 1 << 17

    def __init__(self, out: TextIO | BinaryIO, s: SlicingSettings, feeds: Feeds, heating: Heating | None = None):
        self.out, self.s, self.feeds, self.heating = out, s, feeds, heating
        self.hot = heating is None  # a printer heated its nozzle in the start code
        self.waits = 0  # WAITs written so far
        self.fil_area = math.pi * (s.filament_diameter / 2) ** 2
        self.pos: np.ndarray | None = None
        self.tool = False
        self.retracted = False
        self.where: tuple = (None, None)  # (chunk id, layer) last announced
        self.role: int | None = None  # role of the extrusion in progress (None after a travel)
        self._units = 0  # filament so far, in units of 2**-1126 mm
        f = s.retract_speed * 60
        self.retract = f"G1 E{-s.retract_length:.5f} F{f:.0f}\n" if s.retract_length > 0 else ""
        self.unretract = f"G1 E{s.retract_length:.5f} F{f:.0f}\n" if s.retract_length > 0 else ""
        self.travel_f = f"F{feeds.travel * 60:.0f}"
        self._templates = Templates(["G1 X%.3f Y%.3f E%.5f\n", "G1 X%.3f Y%.3f Z%.3f E%.5f\n",
                                     f"G0 X%.3f Y%.3f Z%.3f {self.travel_f}\n"], [(0, 1, 3), (0, 1, 2, 3), (0, 1, 2)])
        self._text = isinstance(out, io.TextIOBase)
        self._tail: Program | None = None  # commands (and turns) not written yet
        self._prev: tuple | None = None  # (chunk id, layer, extruding, role) of the last command written
        self._last_move_off = False  # the last move written was a travel ...
        self._run_long = False  # ... of a run already known to be long enough to retract

    @property
    def filament(self) -> float:
        return self._units / (1 << 1126)

    def write(self, p: Program) -> None:
        """Append one program piece (written at once but for what later pieces decide)."""
        n = len(p)
        for a in range(0, max(n, 1), self.BLOCK):
            block = program_rows(p, a, min(a + self.BLOCK, n))
            self._emit(block if self._tail is None else Program.concat(p.robot, [self._tail, block]), final=False)

    def flush(self) -> None:
        """Write what is held back: the end of the program (nothing is written after it)."""
        if self._tail is not None:
            self._emit(self._tail, final=True)

    def _put(self, data: np.ndarray | bytes) -> None:
        if len(data):
            self.out.write(bytes(data).decode("ascii") if self._text else memoryview(data))

    def _emit(self, p: Program, final: bool) -> None:
        """Write the commands of ``p`` whose text is decided (all of them if ``final``), keep
        the rest as the tail. ``p`` starts where the last write stopped."""
        self._tail = None
        n = len(p)
        kind, xyz, role, layer, chunk = p.kind, p.xyz, p.role.astype(np.int64), p.layer, p.chunk
        heating, s = self.heating, self.s
        on = p.tool_on(self.tool)
        is_mv = kind == MOVE
        mv = np.flatnonzero(is_mv)
        at_mv = xyz[mv]
        prev = np.empty((len(mv), 3))
        if len(mv):
            prev[1:] = at_mv[:-1]
            prev[0] = self.pos if self.pos is not None else np.nan
        sq = (at_mv - prev) ** 2
        length = np.sqrt(sq[:, 0] + sq[:, 1] + sq[:, 2])  # NaN for a first move from nowhere (np.linalg.norm's sum)
        extr = on[mv] & (length > 0)
        with np.errstate(invalid="ignore"):  # (the first move from nowhere: no length)
            e = np.where(extr, flow_area(p.width[mv], p.height[mv], p.role[mv]) * length / self.fil_area, 0.0)
        names = [*p.chunks, None]  # chunk -1: between chunks
        turns: dict[int, list[float]] = {}  # command index -> the facings turned to before it
        for t, deg in p.turns:
            turns.setdefault(t, []).append(deg)
        turn_at = np.zeros(n, dtype=bool)
        turn_at[[t for t in turns if t < n]] = True
        first_moved = self._prev is None or (n > 0 and (names[chunk[0]], int(layer[0])) != self._prev[:2])
        prev_ext, prev_role = (False, -1) if self._prev is None else self._prev[2:]
        # extrusion runs: a new one wherever a command does not continue the one before it
        ext_cmd, go, row_of, moved, cont, numeric = _runs(
            kind, extr, ~(length <= 0), at_mv[:, 2] != prev[:, 2], chunk, layer, role, turn_at, first_moved,
            prev_ext, prev_role)
        seg = np.flatnonzero(~cont)  # segment starts: a run of extruding moves, or one command
        # travel runs (consecutive moves with the tool off; other commands do not end them), for
        # the retraction: a run continuing from the last piece counts as long if it was
        off = ~on[mv]
        new_run = np.r_[True, off[1:] != off[:-1]] if len(mv) else np.zeros(0, bool)
        run_id = np.cumsum(new_run) - 1
        run_sum = np.bincount(run_id, weights=np.where(off, np.nan_to_num(length), 0.0)) if len(mv) else np.zeros(0)
        continuing = len(mv) > 0 and self.pos is not None and self._last_move_off and bool(off[0])
        if continuing and self._run_long:
            run_sum[0] = np.inf
        run_len = run_sum[run_id]
        announce = np.flatnonzero(moved & (layer >= 0))  # segment starts that may name a new layer
        nxt = np.r_[mv, n][np.searchsorted(mv, announce)]  # the next move at or after each
        # how far the text is decided
        c = n
        if not final:
            if n and ext_cmd[-1]:
                c = min(c, int(seg[-1]))  # the last extrusion run may go on
            if self.retract and len(mv) and off[-1] and run_sum[-1] < s.retract_before_travel:
                c = min(c, int(mv[np.flatnonzero(new_run)[-1]]))  # the last travel run may grow long
            lonely = announce[nxt >= n]
            if len(lonely):
                c = min(c, int(lonely[0]))  # a layer whose first move is still to come
        # the state in force at each command (set by the last command that changes it)
        wait = kind == WAIT
        long_wait = np.zeros(n, dtype=bool)
        if heating is not None and wait.any():
            k0 = self.waits
            long_wait[wait] = [heating.wait_is_long(k0 + k) for k in range(int(wait.sum()))]
        tool_on = kind == TOOL_ON
        travel_pre = np.zeros(n, dtype=bool)  # a travel that retracts if the nozzle is hot
        if self.retract:
            travel_pre[mv] = off & (length > 0) & (run_len >= s.retract_before_travel)
        starts = ext_cmd & ~cont
        hot, retracted, last_role = _states(kind, long_wait, travel_pre, starts, role, self.hot, self.retracted,
                                            -1 if self.role is None else self.role, bool(self.retract))
        travel_retract = travel_pre & hot[:-1]
        # the operations, command by command: turns, layer, ;TYPE, feed, text, the numeric line
        table = Table()
        ops = np.full((c, 6), NONE, np.int32)  # per command: turns, layer, ;TYPE, feed, text, numeric line
        for t in sorted(turns):
            if t < c:
                ops[t, 0] = table.id("".join(f"; FACING {d:.3f}\nM400\nM0 FACING {d:.3f}\n" for d in turns[t]))
        ann_at, ann_op = [], []
        for i, z in zip(announce[announce < c].tolist(), nxt.tolist()):
            where = (names[chunk[i]], int(layer[i]))
            if where != self.where:
                text = f";CHUNK:{where[0]}\n" if where[0] != self.where[0] and where[0] is not None else ""
                text += f";LAYER:{where[1]}" + (f"\n;Z:{xyz[z, 2]:.3f}" if z < n else "") + "\n"
                ann_at.append(i)
                ann_op.append(table.id(text))
                self.where = where
        ops[ann_at, 1] = ann_op
        st = np.flatnonzero(starts[:c])
        if len(st):
            ty = role[st] != last_role[st]
            type_lut = np.array([table.id(f";TYPE:{ROLE_TYPES[r]}\n") if r in ROLE_TYPES else -1
                                 for r in range(int(role[st].max()) + 1)], np.int64)
            ops[st[ty], 2] = type_lut[role[st[ty]]]
            key = role[st] * 2 + (layer[st] == 0)  # the feed rate: by role, and on the first layer
            feed_lut = np.array([table.id(f"G1 F{self.feeds.extrude(k // 2, 0 if k % 2 else 1) * 60:.0f}\n")
                                 for k in range(int(key.max()) + 1)], np.int64)
            ops[st, 3] = feed_lut[key]
        text = ops[:, 4]  # a command's own text: a travel's retraction, TOOL ON's, a sync's
        text[travel_retract[:c] & ~retracted[:c]] = table.id(self.retract)
        ons = np.flatnonzero(tool_on[:c])
        if len(ons):
            heat = ""
            if heating is not None:
                heat = f"M104 S{heating.nozzle:g}\nM109 S{heating.nozzle:g} ; heat before extruding\n"
            combos = [table.id(h + u) for h in ("", heat) for u in ("", self.unretract)]
            text[ons] = np.array(combos, np.int64)[(~hot[ons]).astype(np.int64) * 2 + retracted[ons]]
        sync = np.flatnonzero(((kind == NOTIFY) | wait)[:c])
        if len(sync):
            idle = f"M104 S0 ; idle: a wait longer than {heating.idle_limit:g} s\n" if heating is not None else ""
            lines = []
            for i in sync.tolist():
                ev = ", ".join(p.events[int(p.event[i])])
                word, code = ("NOTIFY", "M118") if kind[i] == NOTIFY else ("WAIT", "M0")
                line = f"; {word} {ev}\nM400\n"
                if long_wait[i] and hot[i]:
                    line += (self.retract if not retracted[i] else "") + idle
                lines.append(table.id(line + f"{code} {word} {ev}\n"))
            text[sync] = lines
        ops[:, 5] = numeric[:c]  # a whole extrusion run with Z if any of its moves climbs
        values = np.empty((len(mv), 4))
        values[:, :3] = at_mv
        values[:, 3] = e
        self._put(assemble(ops, row_of[:c], table, self._templates, values))
        if final and n in turns:
            self._put("".join(f"; FACING {d:.3f}\nM400\nM0 FACING {d:.3f}\n" for d in turns[n]).encode())
        # the state after command c - 1
        done = int(np.searchsorted(mv, c))  # moves written
        self._units += _exact_units(e[:done])
        if c > 0:
            self._prev = (names[chunk[c - 1]], int(layer[c - 1]), bool(ext_cmd[c - 1]), int(role[c - 1]))
            self.tool = bool(on[c - 1])
        if done:
            self.pos = xyz[mv[done - 1]].copy()
            self._last_move_off = bool(off[done - 1])
            self._run_long = bool(run_sum[run_id[done - 1]] >= s.retract_before_travel)
        self.hot, self.retracted = bool(hot[c]), bool(retracted[c])
        self.role = None if last_role[c] < 0 else int(last_role[c])
        if heating is not None:
            self.waits += int(wait[:c].sum())
        if not final and (c < n or any(t >= c for t in turns)):
            self._tail = program_rows(p, c, n)


def _put_text(out: TextIO | BinaryIO, text: str) -> None:
    out.write(text if isinstance(out, io.TextIOBase) else text.encode("ascii"))


def write_gcode(out: TextIO | BinaryIO, pieces: Iterable[Program], s: SlicingSettings, feeds: Feeds, name: str,
                notes: Iterable[str] = (), home: bool = True, heating: Heating | None = None) -> float:
    """Start code, the pieces, end code and the filament total; returns filament used, mm.
    ``heating`` is a mobile robot's (heat on demand, its own bed or none); ``None`` a printer's.
    ``out`` is a text or a binary file (binary is faster)."""
    w = GcodeFile(out, s, feeds, name, notes, home, heating)
    for piece in pieces:
        w.write(piece)
    return w.close()


class GcodeFile:
    """A whole G-code file written piece by piece: the start code at once, :meth:`write` for
    each program piece (any split gives the same bytes), :meth:`close` for the end code and the
    filament total (it returns the filament used, mm; the file itself is the caller's to
    close)."""

    def __init__(self, out: TextIO | BinaryIO, s: SlicingSettings, feeds: Feeds, name: str,
                 notes: Iterable[str] = (), home: bool = True, heating: Heating | None = None):
        self.out, self.heating = out, heating
        _put_text(out, start_code(s, name, notes, home, heating))
        self.writer = GcodeWriter(out, s, feeds, heating)

    def write(self, piece: Program) -> None:
        self.writer.write(piece)

    def close(self) -> float:
        w = self.writer
        w.flush()
        _put_text(self.out, end_code(self.heating is None or self.heating.bed is not None))
        _put_text(self.out, f"; filament used [mm] = {w.filament:.2f}\n")
        return w.filament


def gcode_text(pieces: Iterable[Program], s: SlicingSettings, feeds: Feeds | None = None,
               name: str = "model") -> str:
    """The whole G-code as one string."""
    buf = io.StringIO()
    write_gcode(buf, pieces, s, feeds or Feeds.of_slicer(s), name)
    return buf.getvalue()


__all__ = ["Feeds", "ROLE_SPEEDS", "GcodeFile", "GcodeWriter", "Heating", "end_code", "gcode_text", "start_code", "write_gcode"]
