"""Marlin-flavour G-code from a command stream (a writer only: no geometry decisions here).

The same :class:`~cooprint.program.commands.Program` that a robot's ``.coop`` file holds is
written here, piece by piece as it arrives (``cooprint slice`` streams one layer at a time):

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
from typing import Iterable, TextIO

import numpy as np

from cooprint.config import RobotProfile, SlicingSettings
from cooprint.program.commands import MOVE, NOTIFY, TOOL_ON, WAIT, Program
from cooprint.program.comment import comment_safe
from cooprint.slicing.paths import INFILL, PERIMETER_INNER, PERIMETER_OUTER, SKIN, TRAVEL, extrusion_area

ROLE_TYPES = {PERIMETER_OUTER: "WALL-OUTER", PERIMETER_INNER: "WALL-INNER", SKIN: "SKIN", INFILL: "FILL",
              TRAVEL: "TRAVEL"}
_G1 = "G1 X%.3f Y%.3f E%.5f\n"
_G1Z = "G1 X%.3f Y%.3f Z%.3f E%.5f\n"


@dataclass(frozen=True)
class Feeds:
    """Feed rates, mm/s: by path role, on the first layer, and for travel."""

    perimeter: float
    infill: float
    first_layer: float
    travel: float

    @staticmethod
    def of_slicer(s: SlicingSettings) -> "Feeds":
        """A printer's speeds (``cooprint slice``)."""
        return Feeds(s.perimeter_speed, s.infill_speed, s.first_layer_speed, s.travel_speed)

    @staticmethod
    def of_robot(robot: RobotProfile, s: SlicingSettings) -> "Feeds":
        """A mobile robot prints at its ``print_speed`` (no faster than the slicer's first-layer
        speed on the first layer) and travels at its ``travel_speed``."""
        return Feeds(robot.print_speed, robot.print_speed, min(s.first_layer_speed, robot.print_speed),
                     robot.travel_speed)

    def extrude(self, role: int, layer: int) -> float:
        if layer == 0:
            return self.first_layer
        return self.perimeter if role in (PERIMETER_OUTER, PERIMETER_INNER) else self.infill

    def speeds(self, p: Program, tool: bool = False) -> np.ndarray:
        """(n,) mm/s: the feed rate at which the G-code runs each command of ``p`` (MOVEs with the
        tool on as :meth:`extrude`, the others at travel speed): the time model of the written
        G-code at constant speed. ``tool``: whether the tool is on before ``p`` (a piece of a
        program)."""
        perimeter = (p.role == PERIMETER_OUTER) | (p.role == PERIMETER_INNER)
        extrude = np.where(p.layer == 0, self.first_layer, np.where(perimeter, self.perimeter, self.infill))
        return np.where(p.tool_on(tool), extrude, self.travel).astype(np.float64)


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


class GcodeWriter:
    """Writes programs, piece after piece, keeping the state between them (position, tool,
    retraction, current layer and role). ``filament`` is the length extruded so far, mm."""

    def __init__(self, out: TextIO, s: SlicingSettings, feeds: Feeds, heating: Heating | None = None):
        self.out, self.s, self.feeds, self.heating = out, s, feeds, heating
        self.hot = heating is None  # a printer heated its nozzle in the start code
        self.waits = 0  # WAITs written so far
        self.fil_area = math.pi * (s.filament_diameter / 2) ** 2
        self.pos: np.ndarray | None = None
        self.tool = False
        self.retracted = False
        self.where: tuple = (None, None)  # (chunk id, layer) last announced
        self.role: int | None = None  # role of the extrusion in progress (None after a travel)
        self.filament = 0.0
        f = s.retract_speed * 60
        self.retract = f"G1 E{-s.retract_length:.5f} F{f:.0f}\n" if s.retract_length > 0 else ""
        self.unretract = f"G1 E{s.retract_length:.5f} F{f:.0f}\n" if s.retract_length > 0 else ""
        self.travel_f = f"F{feeds.travel * 60:.0f}"

    def write(self, p: Program) -> None:
        """Append one program piece.

        Lengths and E values are computed for the whole piece at once; each run of extruding
        moves (one role, layer and chunk) is then one ``%`` format, other commands a line each.
        """
        n = len(p)
        if n == 0:
            for _, deg in p.turns:  # a piece that is only a turn
                self._turn([deg])
            return
        kind, xyz = p.kind, p.xyz
        on = p.tool_on(self.tool)
        mv = np.flatnonzero(kind == MOVE)
        prev = np.empty((len(mv), 3))
        if len(mv):  # a piece may hold no move at all (only dwells or turns)
            prev[1:] = xyz[mv[:-1]]
            prev[0] = self.pos if self.pos is not None else np.nan
        length = np.linalg.norm(xyz[mv] - prev, axis=1)  # NaN for a first move from nowhere
        extr = on[mv] & (length > 0)
        e = np.zeros(len(mv))
        e[extr] = extrusion_area(p.width[mv[extr]], p.height[mv[extr]]) * length[extr] / self.fil_area
        self.filament += float(e.sum())
        ext_cmd = np.zeros(n, dtype=bool)
        ext_cmd[mv[extr]] = True
        xye = np.column_stack([xyz[mv, :2], e]).ravel().tolist()
        row_of = np.full(n, -1)
        row_of[mv] = np.arange(len(mv))
        zmove = np.zeros(n, dtype=bool)
        zmove[mv] = xyz[mv, 2] != prev[:, 2]
        # length of each run of travel moves, for the retraction decision
        off_mv = ~on[mv]
        run_id = np.cumsum(np.r_[True, off_mv[1:] != off_mv[:-1]]) if len(mv) else np.zeros(0, np.int64)
        run_len = np.bincount(run_id, weights=np.where(off_mv, np.nan_to_num(length), 0.0))[run_id]
        # runs: a new one wherever a command does not continue the extrusion before it
        moved = np.r_[True, (p.chunk[1:] != p.chunk[:-1]) | (p.layer[1:] != p.layer[:-1])]
        cont = np.r_[False, ext_cmd[1:] & ext_cmd[:-1] & (p.role[1:] == p.role[:-1])] & ~moved
        turns: dict[int, list[float]] = {}  # command index -> the facings turned to before it
        for t, deg in p.turns:
            turns.setdefault(t, []).append(deg)
        cont[[t for t in turns if t < n]] = False
        starts = np.flatnonzero(~cont).tolist() + [n]
        out, s = self.out, self.s
        for i, j in zip(starts[:-1], starts[1:]):
            if i in turns:
                self._turn(turns[i])
            if moved[i] and p.layer[i] >= 0:
                where = (p.chunks[p.chunk[i]] if p.chunk[i] >= 0 else None, int(p.layer[i]))
                if where != self.where:
                    self._announce(where, xyz, kind, i)
            k = int(kind[i])
            if ext_cmd[i]:
                role = int(p.role[i])
                if role != self.role:
                    out.write(f";TYPE:{ROLE_TYPES[role]}\n")
                    self.role = role
                out.write(f"G1 F{self.feeds.extrude(role, int(p.layer[i])) * 60:.0f}\n")
                r0, r1 = int(row_of[i]), int(row_of[j - 1]) + 1
                if zmove[i:j].any():
                    out.write(_G1Z * (j - i) % tuple(np.column_stack([xyz[mv[r0:r1]], e[r0:r1]]).ravel().tolist()))
                else:
                    out.write(_G1 * (j - i) % tuple(xye[3 * r0:3 * r1]))
            elif k == MOVE:
                r = int(row_of[i])
                if length[r] > 0 and not on[i] and self.retract and not self.retracted and self.hot \
                        and run_len[r] >= s.retract_before_travel:  # (firmware refuses cold E moves)
                    out.write(self.retract)
                    self.retracted = True
                if not length[r] <= 0:  # a travel, or the first move (from nowhere): go there
                    out.write(f"G0 X{xyz[i, 0]:.3f} Y{xyz[i, 1]:.3f} Z{xyz[i, 2]:.3f} {self.travel_f}\n")
                    self.role = None
            elif k == TOOL_ON:
                if not self.hot:
                    t = self.heating.nozzle  # type: ignore[union-attr]
                    out.write(f"M104 S{t:g}\nM109 S{t:g} ; heat before extruding\n")
                    self.hot = True
                if self.retracted:
                    out.write(self.unretract)
                    self.retracted = False
            elif k in (NOTIFY, WAIT):
                ev = ", ".join(p.events[int(p.event[i])])
                word, code = ("NOTIFY", "M118") if k == NOTIFY else ("WAIT", "M0")
                out.write(f"; {word} {ev}\nM400\n")
                if k == WAIT and self.heating is not None:
                    if self.hot and self.heating.wait_is_long(self.waits):
                        if self.retract and not self.retracted:  # no ooze while it cools and heats again
                            out.write(self.retract)
                            self.retracted = True
                        out.write(f"M104 S0 ; idle: a wait longer than {self.heating.idle_limit:g} s\n")
                        self.hot = False
                    self.waits += 1
                out.write(f"{code} {word} {ev}\n")
        if n in turns:
            self._turn(turns[n])
        self.tool = bool(on[-1])
        if len(mv):
            self.pos = xyz[mv[-1]]

    def _turn(self, facings: list[float]) -> None:
        """Host lines of a turn: the printer finishes its moves and stops; the host turns the
        robot (through each facing in order) and resumes it."""
        for deg in facings:
            self.out.write(f"; FACING {deg:.3f}\nM400\nM0 FACING {deg:.3f}\n")

    def _announce(self, where: tuple, xyz: np.ndarray, kind: np.ndarray, i: int) -> None:
        chunk, layer = where
        if chunk != self.where[0] and chunk is not None:
            self.out.write(f";CHUNK:{chunk}\n")
        nxt = i + int(np.argmax(kind[i:] == MOVE)) if (kind[i:] == MOVE).any() else None
        z = f"\n;Z:{xyz[nxt, 2]:.3f}" if nxt is not None else ""
        self.out.write(f";LAYER:{layer}{z}\n")
        self.where = where


def write_gcode(out: TextIO, pieces: Iterable[Program], s: SlicingSettings, feeds: Feeds, name: str,
                notes: Iterable[str] = (), home: bool = True, heating: Heating | None = None) -> float:
    """Start code, the pieces, end code and the filament total; returns filament used, mm.
    ``heating`` is a mobile robot's (heat on demand, its own bed or none); ``None`` a printer's."""
    out.write(start_code(s, name, notes, home, heating))
    w = GcodeWriter(out, s, feeds, heating)
    for piece in pieces:
        w.write(piece)
    out.write(end_code(heating is None or heating.bed is not None))
    out.write(f"; filament used [mm] = {w.filament:.2f}\n")
    return w.filament


def gcode_text(pieces: Iterable[Program], s: SlicingSettings, feeds: Feeds | None = None,
               name: str = "model") -> str:
    """The whole G-code as one string."""
    buf = io.StringIO()
    write_gcode(buf, pieces, s, feeds or Feeds.of_slicer(s), name)
    return buf.getvalue()


__all__ = ["Feeds", "GcodeWriter", "Heating", "end_code", "gcode_text", "start_code", "write_gcode"]
