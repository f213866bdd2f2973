"""Typed, validated settings.

Each section of the TOML file is a frozen dataclass; every numeric field carries its allowed range
and unit in its metadata, so one validator gives every field the same clear message::

    robot.toml: robot.build_depth = -3.0: expected a number > 0 (mm)

Defaults live in ``defaults.toml`` next to this module. Files given by the user are merged over
them field by field, then command-line overrides (``{"chunking.theta_deg": 60}``) over those.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any, Mapping, Sequence

from cooprint.errors import ConfigError


def _num(lo: float | None = None, hi: float | None = None, *, unit: str = "", lo_open: bool = False,
         optional: bool = False, integer: bool = False, doc: str = "") -> dict[str, Any]:
    return {"lo": lo, "hi": hi, "unit": unit, "lo_open": lo_open, "optional": optional,
            "integer": integer, "doc": doc}


@dataclass(frozen=True)
class RobotProfile:
    """A mobile FDM printer (seed §2-3, Fig. 1 and 3). Lengths in mm, speeds in mm/s."""

    name: str = "mobile-fdm"
    build_depth: float = field(default=300.0, metadata=_num(0, 1e5, unit="mm", lo_open=True,
                               doc="nozzle to the front of the body, along the facing axis (bd)"))
    nozzle_height: float = field(default=100.0, metadata=_num(0, 1e4, unit="mm", lo_open=True,
                                 doc="nozzle tip to the lowest part of the printhead body (nh)"))
    nozzle_depth: float = field(default=25.0, metadata=_num(0, 1e4, unit="mm", lo_open=True,
                                doc="reach of the printhead body ahead of the nozzle (nd)"))
    body_width: float = field(default=300.0, metadata=_num(0, 1e5, unit="mm", lo_open=True))
    body_length: float = field(default=350.0, metadata=_num(0, 1e5, unit="mm", lo_open=True))
    print_speed: float = field(default=40.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True))
    travel_speed: float = field(default=120.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True))
    acceleration: float = field(default=500.0, metadata=_num(0, 1e6, unit="mm/s2", lo_open=True,
                                doc="for the simulator's acceleration model (simulate --accel)"))
    jerk: float = field(default=10.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True,
                        doc="largest instant change of speed at a corner, per axis"))
    # a mobile robot prints on the floor: no bed to heat unless its profile says it carries one
    heated_bed: bool = field(default=False, metadata={"boolean": True,
                             "doc": "the robot prints on a heated bed (G-code heats it to slicing.bed_temperature)"})


@dataclass(frozen=True)
class ChunkingSettings:
    """How the chunker cuts (seed §3). ``None`` means: derive from the robot and the mesh."""

    theta_deg: float | None = field(default=None, metadata=_num(0, 90, unit="deg", lo_open=True,
                                    optional=True, doc="slope of the chunk interfaces"))
    shift: float | None = field(default=None, metadata=_num(0, 1e6, unit="mm", lo_open=True,
                                optional=True, doc="distance between parallel cutting planes (s)"))
    top_width: float = field(default=0.0, metadata=_num(0, 1e6, unit="mm"))
    centre_angle_deg: float = field(default=0.0, metadata=_num(-360, 360, unit="deg"))
    centre_offset: float = field(default=0.0, metadata=_num(-1e6, 1e6, unit="mm"))


@dataclass(frozen=True)
class MeshSettings:
    """Mesh loading and repair."""

    max_hole_fraction: float = field(default=0.15, metadata=_num(0, 1, doc="largest hole closed "
                                     "silently, as perimeter / bounding-box diagonal"))


def _choice(*options: str, doc: str = "") -> dict[str, Any]:
    return {"choices": options, "doc": doc}


@dataclass(frozen=True)
class SlicingSettings:
    """How a chunk (or a whole model) becomes layers and tool paths (seed §4.2.1).

    Defaults are PrusaSlicer 2.5's for a 0.4 mm nozzle: 0.2 mm layers, 2 perimeters,
    4 top / 4 bottom solid layers, 20% rectilinear infill, 1.75 mm filament.
    """

    layer_height: float = field(default=0.2, metadata=_num(0, 10, unit="mm", lo_open=True))
    first_layer_height: float = field(default=0.2, metadata=_num(0, 10, unit="mm", lo_open=True))
    nozzle_diameter: float = field(default=0.4, metadata=_num(0, 10, unit="mm", lo_open=True))
    extrusion_width: float = field(default=0.45, metadata=_num(0, 20, unit="mm", lo_open=True))
    perimeters: int = field(default=2, metadata=_num(0, 100, integer=True))
    top_layers: int = field(default=4, metadata=_num(0, 1000, integer=True))
    bottom_layers: int = field(default=4, metadata=_num(0, 1000, integer=True))
    infill_density: float = field(default=0.2, metadata=_num(0, 1, doc="0 = hollow, 1 = solid"))
    infill_pattern: str = field(default="rectilinear", metadata=_choice("rectilinear", "grid", "triangles"))
    infill_angle_deg: float = field(default=45.0, metadata=_num(-360, 360, unit="deg"))
    solid_infill_below_area: float = field(default=70.0, metadata=_num(0, 1e6, unit="mm2",
                                           doc="sparse regions smaller than this are filled solid"))
    outer_perimeter_first: bool = field(default=False, metadata={"boolean": True})
    seam: str = field(default="aligned", metadata=_choice("aligned", "nearest", "rear"))
    min_area: float = field(default=0.05, metadata=_num(0, 1e6, unit="mm2",
                            doc="islands and infill regions smaller than this are not printed"))
    filament_diameter: float = field(default=1.75, metadata=_num(0, 10, unit="mm", lo_open=True))
    perimeter_speed: float = field(default=45.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True))
    infill_speed: float = field(default=80.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True))
    first_layer_speed: float = field(default=30.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True))
    travel_speed: float = field(default=130.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True))
    retract_length: float = field(default=0.8, metadata=_num(0, 50, unit="mm"))
    retract_speed: float = field(default=35.0, metadata=_num(0, 1e3, unit="mm/s", lo_open=True))
    retract_before_travel: float = field(default=2.0, metadata=_num(0, 1e4, unit="mm",
                                         doc="travels shorter than this do not retract"))
    nozzle_temperature: float = field(default=210.0, metadata=_num(0, 500, unit="C"))
    bed_temperature: float = field(default=60.0, metadata=_num(0, 200, unit="C"))
    build_x: float = field(default=1000.0, metadata=_num(0, 1e6, unit="mm", lo_open=True,
                           doc="printable size of a single-printer run (cooprint slice)"))
    build_y: float = field(default=1000.0, metadata=_num(0, 1e6, unit="mm", lo_open=True))
    build_z: float = field(default=1000.0, metadata=_num(0, 1e6, unit="mm", lo_open=True))


@dataclass(frozen=True)
class ProgramSettings:
    """How the robots' command streams are made (seed §4.2.2-4.3)."""

    clearance: float = field(default=5.0, metadata=_num(0, 1e4, unit="mm", lo_open=True,
                             doc="lift above the highest printed material nearby on a move between chunks"))
    heater_idle_limit_s: float = field(default=600.0, metadata=_num(0, 1e6, unit="s",
                                       doc="a robot's hot nozzle is turned off before a WAIT expected to "
                                           "last longer than this, and reheated after it"))


@dataclass(frozen=True)
class JobSettings:
    """Everything a job needs besides the mesh."""

    robot: RobotProfile = field(default_factory=RobotProfile)
    chunking: ChunkingSettings = field(default_factory=ChunkingSettings)
    mesh: MeshSettings = field(default_factory=MeshSettings)
    slicing: SlicingSettings = field(default_factory=SlicingSettings)
    program: ProgramSettings = field(default_factory=ProgramSettings)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict for job.json (``None`` fields dropped, as TOML has no null)."""
        return {k: {f: v for f, v in sec.items() if v is not None} for k, sec in asdict(self).items()}


_SECTIONS: dict[str, type] = {"robot": RobotProfile, "chunking": ChunkingSettings, "mesh": MeshSettings,
                              "slicing": SlicingSettings, "program": ProgramSettings}


def _shown(value: Any, limit: int = 60) -> str:
    """``repr(value)``, clipped: a huge list or string is not echoed whole in a message."""
    try:
        text = repr(value)
    except ValueError:  # an integer of more digits than Python converts
        return "a very large number"
    return text if len(text) <= limit else text[:limit] + "..."


def _check_value(where: str, name: str, value: Any, meta: Mapping[str, Any]) -> float | None:
    lo, hi, unit = meta["lo"], meta["hi"], meta["unit"]
    rng = []
    if lo is not None:
        rng.append(f"{'>' if meta['lo_open'] else '>='} {lo:g}")
    if hi is not None:
        rng.append(f"<= {hi:g}")
    kind = "a whole number " if meta["integer"] else "a number "
    expect = kind + " and ".join(rng) + (f" ({unit})" if unit else "")
    if value is None and meta["optional"]:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or (
            meta["integer"] and not float(value).is_integer()):
        raise ConfigError(f"{where}{name} = {_shown(value)}: expected {expect}")
    try:
        v = float(value)
    except OverflowError:  # an integer beyond float's range
        raise ConfigError(f"{where}{name} = {_shown(value)}: expected {expect}") from None
    ok = math.isfinite(v)
    if ok and lo is not None:
        ok = v > lo if meta["lo_open"] else v >= lo
    if ok and hi is not None:
        ok = v <= hi
    if not ok:
        raise ConfigError(f"{where}{name} = {_shown(value)}: expected {expect}")
    return int(value) if meta["integer"] else v  # type: ignore[return-value]


def _build(section: str, cls: type, values: Mapping[str, Any], where: str) -> Any:
    known = {f.name: f for f in fields(cls)}
    out: dict[str, Any] = {}
    for key, value in values.items():
        if key not in known:
            raise ConfigError(f"{where}unknown field {section}.{key}; expected one of: "
                              + ", ".join(sorted(known)))
        f = known[key]
        name = f"{section}.{key}"
        if "choices" in f.metadata:
            if value not in f.metadata["choices"]:
                raise ConfigError(f"{where}{name} = {_shown(value)}: expected one of "
                                  + ", ".join(repr(c) for c in f.metadata["choices"]))
            out[key] = value
        elif f.metadata.get("boolean"):
            if not isinstance(value, bool):
                raise ConfigError(f"{where}{name} = {_shown(value)}: expected true or false")
            out[key] = value
        elif f.metadata:
            out[key] = _check_value(where, name, value, f.metadata)
        elif not isinstance(value, str) or not value.strip():
            raise ConfigError(f"{where}{name} = {_shown(value)}: expected a non-empty string")
        else:
            out[key] = value
    return cls(**out)


def _read_toml(path: Path) -> dict[str, Any]:
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such settings file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read settings file ({exc})") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: invalid TOML: {exc}") from None


def _defaults() -> dict[str, Any]:
    # beside this module (package data); not importlib.resources, whose tempfile/shutil/bz2/lzma
    # imports cost every run about 1 MB and 10 ms
    text = (Path(__file__).parent / "defaults.toml").read_text(encoding="utf-8")
    return tomllib.loads(text)


def load_settings(*paths: str | Path, overrides: Mapping[str, Any] | None = None,
                  tables: Sequence[tuple[str, Mapping[str, Any]]] = ()) -> JobSettings:
    """Read the shipped defaults, then each TOML file in ``paths``, then each of ``tables``, then
    ``overrides``.

    Parameters
    ----------
    paths
        TOML files with any of the sections ``[robot]``, ``[chunking]``, ``[mesh]``, ``[slicing]``,
        ``[program]``.
    tables
        ``(where, {section: {field: value}})``: settings read from another file (a bundle's
        job.json, a simulator manifest), validated as a TOML file's and named ``where`` (a prefix
        of each message, e.g. ``"job/job.json: settings."``).
    overrides
        ``{"section.field": value}``, e.g. from command-line flags; ``None`` values are ignored.

    Raises
    ------
    ConfigError
        Naming the file, the field, the value given and what was expected.
    """
    merged: dict[str, dict[str, Any]] = {s: {} for s in _SECTIONS}
    layers: list[tuple[str, Mapping[str, Any]]] = [("defaults.toml: ", _defaults())]
    layers += [(f"{p}: ", _read_toml(Path(p))) for p in paths]
    layers += list(tables)
    for where, data in layers:
        for section, values in data.items():
            if section not in _SECTIONS:
                raise ConfigError(f"{where}unknown section [{section}]; expected one of: "
                                  + ", ".join(f"[{s}]" for s in _SECTIONS))
            if not isinstance(values, dict):
                raise ConfigError(f"{where}{section} must be a table [{section}]")
            _build(section, _SECTIONS[section], values, where)  # validate with its own file name
            merged[section].update(values)
    for key, value in (overrides or {}).items():
        if value is None:
            continue
        section, _, name = key.partition(".")
        _build(section, _SECTIONS[section], {name: value}, "option: ")
        merged[section][name] = value
    return JobSettings(**{s: _build(s, cls, merged[s], "") for s, cls in _SECTIONS.items()})
