"""What the simulator reads: a bundle of ``cooprint run``, ``.coop`` files with a manifest, or
plain G-code files (one robot each, so that PrusaSlicer's or Cura's output simulates too)."""

from __future__ import annotations

import io
import json
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cooprint.config import RobotProfile, SlicingSettings, load_settings
from cooprint.errors import UserError
from cooprint.program.commands import MOVE, TOOL_OFF, TOOL_ON, make_program, read_coop
from cooprint.simulation.kinematics import MachineLimits
from cooprint.simulation.timeline import SimRobot
from cooprint.slicing.paths import INFILL, TRAVEL, extrusion_width


class SimInputError(UserError):
    """A bundle, manifest or G-code file the simulator cannot use."""


@dataclass(frozen=True)
class SimInput:
    """Robots to simulate, with the profile that gives their speeds and body."""

    robots: list[SimRobot]
    profile: RobotProfile
    slicing: SlicingSettings
    source: str  # what was read, for messages and the summary
    limits: MachineLimits | None = None  # for the acceleration model; None: the robot profile's
    placed: bool = True  # the robots' starts and facings are known: the body checks apply


def _facing(deg: float) -> np.ndarray:
    return np.array([math.cos(math.radians(deg)), math.sin(math.radians(deg))])


def load_bundle(folder: str | Path) -> SimInput:
    """A ``cooprint run`` bundle: ``job.json`` and the ``robots/*.coop`` it names."""
    d = Path(folder)
    path = d / "job.json"
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SimInputError(f"{d}: no job.json (not a cooprint run bundle)") from None
    except (OSError, ValueError) as exc:
        raise SimInputError(f"{path}: cannot read ({exc})") from None
    robots_rec = record.get("robots")
    if not isinstance(robots_rec, list) or not all("program" in r for r in robots_rec):
        raise SimInputError(f"{path}: no robots with programs (written by `cooprint chunk`? use `cooprint run`)")
    settings = record.get("settings", {})
    try:
        profile = RobotProfile(**settings.get("robot", {}))
        slicing = SlicingSettings(**settings.get("slicing", {}))
    except TypeError as exc:
        raise SimInputError(f"{path}: settings not understood ({exc})") from None
    robots = []
    for r in robots_rec:
        program = read_coop(d / r["program"], r["name"])
        robots.append(SimRobot(r["name"], program, np.asarray(r["start"], dtype=np.float64),
                               _facing(float(r["facing_deg"]))))
    return SimInput(robots, profile, slicing, str(d))


def load_manifest(path: str | Path) -> SimInput:
    """``.coop`` files named by a TOML manifest::

        [robot]                 # the profile (any field of cooprint's [robot] section)
        print_speed = 40.0
        [[robots]]
        name = "A"
        program = "A.coop"      # relative to the manifest
        start = [0.0, 0.0, 5.0] # nozzle position at the start, mm
        facing_deg = 90.0       # direction from the body to the nozzle, at the start (the
                                # program's ;@facing lines turn the robot on the way)
    """
    p = Path(path)
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise SimInputError(f"{p}: no such manifest") from None
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise SimInputError(f"{p}: cannot read the manifest ({exc})") from None
    unknown = set(data) - {"robot", "robots", "slicing"}
    if unknown:
        raise SimInputError(f"{p}: unknown section(s) {', '.join(sorted(unknown))}; expected [robot], [slicing], "
                            "[[robots]]")
    robot_file = {k: v for k, v in data.items() if k in ("robot", "slicing")}
    settings = load_settings(overrides={f"{s}.{k}": v for s, sec in robot_file.items() for k, v in sec.items()})
    entries = data.get("robots")
    if not isinstance(entries, list) or not entries:
        raise SimInputError(f"{p}: no [[robots]] entries")
    robots, names = [], set()
    for n, e in enumerate(entries, start=1):
        where = f"{p}: robots[{n}]"
        if not isinstance(e.get("name"), str) or not e["name"]:
            raise SimInputError(f"{where}.name: expected a robot name")
        if e["name"] in names:
            raise SimInputError(f"{where}.name = {e['name']!r}: a second robot of that name")
        names.add(e["name"])
        if not isinstance(e.get("program"), str):
            raise SimInputError(f"{where}.program: expected the path of a .coop file")
        start = e.get("start")
        if start is not None and not (isinstance(start, list) and len(start) == 3
                                      and all(isinstance(x, (int, float)) and math.isfinite(x) for x in start)):
            raise SimInputError(f"{where}.start = {start!r}: expected [x, y, z] in mm")
        facing = e.get("facing_deg", 90.0)
        if isinstance(facing, bool) or not isinstance(facing, (int, float)) or not math.isfinite(facing):
            raise SimInputError(f"{where}.facing_deg = {facing!r}: expected a number of degrees")
        program = read_coop(p.parent / e["program"], e["name"])
        robots.append(SimRobot(e["name"], program, None if start is None else np.asarray(start, float),
                               _facing(float(facing))))
    return SimInput(robots, settings.robot, settings.slicing, str(p))


def load_gcode_files(paths: list[str | Path], profile: RobotProfile | None = None,
                     slicing: SlicingSettings | None = None) -> SimInput:
    """Plain G-code files, one robot each (named by the file's stem). Nothing says where a
    robot's body stands, so the body checks are left out (``placed`` is false): the result is
    the timing, the material and the deadlock check."""
    robots = [read_gcode(p) for p in paths]
    names = [r.name for r in robots]
    if len(set(names)) != len(names):
        raise SimInputError(f"two G-code files with the same name: {', '.join(names)}")
    # a printer's G-code: PrusaSlicer's machine limits; no robot body stands anywhere known
    return SimInput(robots, profile or RobotProfile(), slicing or SlicingSettings(), ", ".join(map(str, paths)),
                    MachineLimits(), placed=False)


def read_gcode(path: str | Path, filament_diameter: float = 1.75) -> SimRobot:
    """A Marlin-flavour G-code file as a program: ``G0``/``G1`` moves (``G90``/``G91``,
    ``M82``/``M83``, ``G92``), moves that push filament become moves with the tool on (width
    from the filament pushed, height from the layer), ``F`` gives each move's speed, and each
    move keeps its E (a move that only moves the filament, a retraction, takes ``|E| / F``).

    A compiled sweep (:mod:`cooprint.simulation.gcode`) reads files whose lines are all in the
    plain form (a slicer's output); any other file is read line by line (``_read_gcode_lines``,
    the reference, which also words the errors)."""
    from cooprint.simulation.gcode import gcode_rows  # numba: on first use

    p = Path(path)
    try:
        data = p.read_bytes()
    except FileNotFoundError:
        raise SimInputError(f"{p}: no such G-code file") from None
    rows = gcode_rows(data, filament_diameter)
    if rows is None:
        return _read_gcode_lines(p, _gcode_text(data), filament_diameter)
    prog = make_program(p.stem, rows.kind, rows.xyz if len(rows.kind) else None,
                        role=np.where(rows.kind == MOVE, INFILL, TRAVEL), width=rows.width, height=rows.height)
    # homed: at 0, 0, 0; a move that only pushes or pulls filament takes |E| / F
    return SimRobot(p.stem, prog, np.zeros(3), _facing(90.0), rows.speed, rows.de)


def _gcode_text(data: bytes) -> str:
    """The text of a G-code file's bytes, as ``Path.read_text(encoding="utf-8", errors="replace")``
    gives it (universal newlines)."""
    return io.TextIOWrapper(io.BytesIO(data), encoding="utf-8", errors="replace").read()


def _read_gcode_lines(p: Path, text: str, filament_diameter: float = 1.75) -> SimRobot:
    """:func:`read_gcode` of the text of G-code file ``p``, line by line: the reference of the
    compiled sweep, and the reader of the files it does not take (and of their errors)."""
    fil_area = math.pi * (filament_diameter / 2) ** 2
    pos = np.zeros(3)
    rel_xyz, rel_e, e = False, False, 0.0  # Marlin's defaults: absolute XYZ and E
    feed = 1500.0 / 60.0
    kinds, xyz, speeds, widths, heights, pushed = [], [], [], [], [], []
    tool = False
    layer_z, layer_h = 0.0, 0.2  # the height of the last layer that deposited, and its thickness
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split(";", 1)[0].strip()
        if not line:
            continue
        words = line.split()
        code = words[0].upper()
        if code in ("G0", "G1", "G92"):
            vals = {}
            for w in words[1:]:
                try:
                    vals[w[0].upper()] = float(w[1:] or (0 if code == "G92" else "x"))  # G92 E: E0
                except (ValueError, IndexError):
                    raise SimInputError(f"{p}:{lineno}: '{w}' is not a G-code word with a number") from None
            if not all(math.isfinite(v) for v in vals.values()):
                raise SimInputError(f"{p}:{lineno}: a coordinate that is not a finite number")
        if code == "G92":
            e = vals.get("E", e)
        elif code in ("G0", "G1"):
            if "F" in vals:
                if vals["F"] <= 0:
                    raise SimInputError(f"{p}:{lineno}: feed rate F{vals['F']:g} is not positive")
                feed = vals["F"] / 60.0
            target = pos.copy()
            for k, ax in enumerate("XYZ"):
                if ax in vals:
                    target[k] = (pos[k] + vals[ax]) if rel_xyz else vals[ax]
            de = 0.0
            if "E" in vals:
                de = vals["E"] if (rel_xyz or rel_e) else vals["E"] - e
                e += de
            length = float(np.linalg.norm(target - pos))
            deposit = de > 0 and length > 0
            if deposit != tool:
                kinds.append(TOOL_ON if deposit else TOOL_OFF)
                xyz.append((np.nan,) * 3)
                speeds.append(0.0)
                widths.append(0.0)
                heights.append(0.0)
                pushed.append(0.0)
                tool = deposit
            if deposit and target[2] != layer_z:
                layer_h = max(target[2] - layer_z, 1e-3) if target[2] > layer_z else layer_h
                layer_z = target[2]
            kinds.append(MOVE)
            xyz.append(tuple(target))
            speeds.append(feed)
            # the width whose flow cross-section carries the filament pushed
            widths.append(float(extrusion_width(de * fil_area / length, layer_h)) if deposit else 0.0)
            heights.append(layer_h if deposit else 0.0)
            pushed.append(de)
            pos = target
        elif code in ("G90", "G91"):
            rel_xyz = code == "G91"
        elif code in ("M82", "M83"):
            rel_e = code == "M83"
    kind = np.array(kinds, dtype=np.uint8)
    prog = make_program(p.stem, kind, np.array(xyz).reshape(-1, 3) if xyz else None,
                        role=np.where(kind == MOVE, INFILL, TRAVEL), width=np.array(widths),
                        height=np.array(heights))
    speed = np.array(speeds)
    # homed: at 0, 0, 0; a move that only pushes or pulls filament takes |E| / F
    return SimRobot(p.stem, prog, np.zeros(3), _facing(90.0), speed, np.array(pushed))


def load_inputs(paths: list[str], manifest: str | None = None) -> SimInput:
    """A bundle folder, ``.coop`` files with a manifest, or G-code files."""
    if manifest:
        return load_manifest(manifest)
    if len(paths) == 1 and Path(paths[0]).is_dir():
        return load_bundle(paths[0])
    missing = [x for x in paths if not Path(x).exists()]
    if missing:
        raise SimInputError(f"{missing[0]}: no such file or folder")
    if all(Path(x).suffix.lower() in (".gcode", ".gco", ".g") for x in paths):
        return load_gcode_files(paths)
    if any(Path(x).suffix.lower() == ".coop" for x in paths):
        raise SimInputError(".coop files need a manifest (--manifest FILE.toml) naming each robot's start "
                            "and facing; or simulate the folder `cooprint run` wrote")
    raise SimInputError(f"{paths[0]}: expected a bundle folder, G-code files or .coop files with --manifest")


__all__ = ["SimInput", "SimInputError", "load_bundle", "load_gcode_files", "load_inputs", "load_manifest",
           "read_gcode"]
