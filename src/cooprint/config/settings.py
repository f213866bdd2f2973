"""Typed, validated settings.

Each section of the TOML file is a frozen dataclass; every numeric field carries its allowed range
and unit in its metadata, so one validator gives every field the same clear message::

    robot.toml: robot.build_depth = -3.0: expected a number > 0 (mm)

Defaults live in ``defaults.toml`` next to this module. Files given by the user are merged over
them field by field, then command-line overrides (``{"chunking.theta_deg": 60}``) over those.

Rules between fields (checked on the merged result, :func:`check_slicing`), so that no accepted
combination can make nonsense:

* ``layer_height`` and ``first_layer_height`` are at least ``MIN_LAYER_HEIGHT`` (0.05 mm) and at
  most ``nozzle_diameter`` (PrusaSlicer's own hard limit, "layer height can't be greater than
  nozzle diameter"; its variable-layer-height default of 0.75 x nozzle is a quality guide, not a
  limit);
* ``extrusion_width`` is from ``nozzle_diameter`` to ``3 x nozzle_diameter`` (PrusaSlicer refuses
  3 x nozzle and more; a line narrower than its nozzle is not a line it can lay);
* at least one of ``perimeters``, ``infill_density``, ``top_layers``, ``bottom_layers`` is non-zero
  (otherwise every layer is empty and the plan prints nothing).

Hence ``width >= nozzle >= height``, and the bead's cross-section
``(w - h) h + pi (h / 2)^2 >= pi h^2 / 4 > 0`` (:func:`cooprint.slicing.paths.extrusion_area`): E is
never negative, nor the line spacing ``w - h (1 - pi / 4)``. ``chunking.shift`` is at least
``MIN_SHIFT`` (5 mm). The robot's outline is whole (:func:`check_robot`): ``nozzle_depth <
build_depth``, the printhead ends before the body's front. :func:`work_estimate` bounds what a part asks for (layers, path length).
"""

from __future__ import annotations

import difflib
import math
import tomllib
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Iterable, Mapping, Sequence

from cooprint.errors import ConfigError

#: Thinnest layer accepted, mm: below it the number of layers (the work) is unbounded and no
#: FDM nozzle lays a meaningful bead (PrusaSlicer's min_layer_height default is 0.07).
MIN_LAYER_HEIGHT = 0.05
#: Smallest distance between parallel cutting planes, mm: the number of chunks stays bounded.
MIN_SHIFT = 5.0
#: Layer heights at most this many nozzle diameters (PrusaSlicer's hard limit).
MAX_LAYER_PER_NOZZLE = 1.0
#: Extrusion width from this many nozzle diameters ...
MIN_WIDTH_PER_NOZZLE = 1.0
#: ... to this many (PrusaSlicer refuses 3 x nozzle and more).
MAX_WIDTH_PER_NOZZLE = 3.0
#: PrusaSlicer's auto extrusion width, in nozzle diameters (Flow::auto_extrusion_width).
AUTO_WIDTH_PER_NOZZLE = 1.125
#: The slicing fields that are extrusion widths (each within the nozzle's range, :func:`check_slicing`).
WIDTH_FIELDS = ("extrusion_width", "external_perimeter_extrusion_width", "perimeter_extrusion_width",
                "infill_extrusion_width", "solid_infill_extrusion_width", "top_infill_extrusion_width",
                "first_layer_extrusion_width")
#: Most layers a part may ask for (1.5 m at 0.05 mm is 30,000).
MAX_LAYERS = 200_000
#: Longest total tool path a part may ask for, mm (its upper bound volume / (width x height)):
#: 20,000 km, weeks of printing for a robot.
MAX_PATH_MM = 2e10
#: Largest settings file read, bytes.
MAX_SETTINGS_BYTES = 1 << 20


def _num(lo: float | None = None, hi: float | None = None, *, unit: str = "", lo_open: bool = False,
         optional: bool = False, integer: bool = False, doc: str = "") -> dict[str, Any]:
    return {"lo": lo, "hi": hi, "unit": unit, "lo_open": lo_open, "optional": optional,
            "integer": integer, "doc": doc}


def _choice(*options: str, doc: str = "") -> dict[str, Any]:
    return {"choices": options, "doc": doc}


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
    frame_width: float | None = field(default=None, metadata=_num(0, 1e5, unit="mm", lo_open=True, optional=True,
                                      doc="width of the frame that carries the printhead over the print, "
                                          "across the facing axis; absent: body_width"))
    # the robot's limits on the slicer's speeds ([slicing] *_speed, the one source of every feed
    # rate, per path role: cooprint.program.gcode.Feeds); absent: no limit
    max_print_speed: float | None = field(default=None, metadata=_num(
        0, 1e4, unit="mm/s", lo_open=True, optional=True,
        doc="fastest this robot extrudes: caps every [slicing] extrusion speed; absent: no cap"))
    max_travel_speed: float | None = field(default=None, metadata=_num(
        0, 1e4, unit="mm/s", lo_open=True, optional=True,
        doc="fastest this robot travels: caps slicing.travel_speed; absent: no cap"))
    acceleration: float = field(default=500.0, metadata=_num(0, 1e6, unit="mm/s2", lo_open=True,
                                doc="for the simulator's acceleration model (simulate --accel)"))
    jerk: float = field(default=10.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True,
                        doc="largest instant change of speed at a corner, per axis"))
    max_z: float = field(default=2000.0, metadata=_num(0, 1e5, unit="mm", lo_open=True,
                         doc="highest the nozzle can print above the floor: the tallest part"))
    # a mobile robot prints on the floor: no bed to heat unless its profile says it carries one
    heated_bed: bool = field(default=False, metadata={"boolean": True,
                             "doc": "the robot prints on a heated bed (G-code heats it to slicing.bed_temperature)"})

    @property
    def resolved_frame_width(self) -> float:
        """The frame's width, mm: ``frame_width``, or the body's width when it is not given."""
        return self.body_width if self.frame_width is None else self.frame_width

    def outline(self) -> dict[str, tuple[float, float, float, float]]:
        """The robot's outline (:func:`outline_rects`) from this profile."""
        return outline_rects(self.build_depth, self.body_length, self.body_width, self.resolved_frame_width,
                             self.nozzle_depth)

    def outline_radius(self) -> float:
        """How far the outline reaches from the nozzle, mm: its farthest corner (a robot turning
        about its nozzle sweeps the disc of this radius)."""
        return max(math.hypot(u, v) for u_lo, u_hi, v_lo, v_hi in self.outline().values()
                   for u in (u_lo, u_hi) for v in (v_lo, v_hi))


def outline_rects(build_depth: float, body_length: float, body_width: float, frame_width: float,
                  nozzle_depth: float) -> dict[str, tuple[float, float, float, float]]:
    """A robot's outline (seed Fig. 1 and 3; docs/simulator.md): part -> ``(u_lo, u_hi, v_lo,
    v_hi)`` relative to the nozzle in the robot's frame (``u`` along its facing, from the body to
    the nozzle; ``v`` to its left), mm. Each part is a vertical prism, so two robots meet where
    their rectangles overlap in XY: the ``body`` on its wheels, its front ``build_depth`` behind
    the nozzle; the ``frame`` from the body's front over the print to the printhead; the
    ``printhead``, half-side ``nozzle_depth`` around the nozzle (from ``nozzle_height`` above the
    tip up). The one definition the planner and the simulator share."""
    bd, bl, nd = build_depth, body_length, nozzle_depth
    return {"body": (-bd - bl, -bd, -body_width / 2, body_width / 2),
            "frame": (-bd, -nd, -frame_width / 2, frame_width / 2),
            "printhead": (-nd, nd, -nd, nd)}


@dataclass(frozen=True)
class ChunkingSettings:
    """How the chunker cuts (seed §3). ``None`` means: derive from the robot and the mesh."""

    theta_deg: float | None = field(default=None, metadata=_num(0, 90, unit="deg", lo_open=True,
                                    optional=True, doc="slope of the chunk interfaces"))
    shift: float | None = field(default=None, metadata=_num(MIN_SHIFT, 1e6, unit="mm",
                                optional=True, doc="distance between parallel cutting planes (s)"))
    top_width: float | None = field(default=None, metadata=_num(0, 1e6, unit="mm", optional=True,
                                    doc="width of the centre chunk at the object's top; absent: 0 for one robot, "
                                    "2 x robot.nozzle_depth for two (their printheads never meet)"))
    centre_angle_deg: float = field(default=0.0, metadata=_num(-360, 360, unit="deg"))
    centre_offset: float = field(default=0.0, metadata=_num(-1e6, 1e6, unit="mm"))
    layout: str = field(default="auto", metadata=_choice("auto", "seed2", "grid", doc="chunk layout: seed2 (the "
                        "seed's centre and side chunks, 1 or 2 robots), grid (rows cut into columns, any number of "
                        "robots) or auto (the one with the shorter estimated makespan)"))
    column_width: float | None = field(default=None, metadata=_num(MIN_SHIFT, 1e6, unit="mm", optional=True,
                                       doc="grid layout: width of a column along the centre line at mid height "
                                           "(half the period of an even and an odd column); absent: from the robots' "
                                           "outline and their number"))


@dataclass(frozen=True)
class MeshSettings:
    """Mesh loading and repair."""

    max_hole_fraction: float = field(default=0.15, metadata=_num(0, 10, doc="largest hole closed "
                                     "silently, as perimeter / bounding-box diagonal"))
    units: str = field(default="mm", metadata=_choice("mm", "cm", "m", "in", doc="unit of the file's coordinates"))
    scale: float = field(default=1.0, metadata=_num(0, 1e6, lo_open=True, doc="factor applied after units"))
    place: bool = field(default=True, metadata={"boolean": True, "doc": "put the part on the floor "
                        "(min z = 0) and, for `slice`, centre it on the bed; false keeps the file's frame"})


@dataclass(frozen=True)
class SlicingSettings:
    """How a chunk (or a whole model) becomes layers and tool paths (seed §4.2.1).

    Defaults are PrusaSlicer 2.5's for a 0.4 mm nozzle: 0.2 mm layers, 2 perimeters,
    4 top / 4 bottom solid layers, 20% rectilinear infill, 1.75 mm filament.
    """

    layer_height: float = field(default=0.2, metadata=_num(MIN_LAYER_HEIGHT, 10, unit="mm",
                                doc="at most nozzle_diameter"))
    first_layer_height: float = field(default=0.2, metadata=_num(MIN_LAYER_HEIGHT, 10, unit="mm",
                                      doc="at most nozzle_diameter"))
    nozzle_diameter: float = field(default=0.4, metadata=_num(0.1, 10, unit="mm"))
    extrusion_width: float = field(default=0.45, metadata=_num(0, 30, unit="mm", lo_open=True,
                                   doc="1 to 3 x nozzle_diameter"))
    perimeters: int = field(default=2, metadata=_num(0, 100, integer=True))
    top_layers: int = field(default=4, metadata=_num(0, 1000, integer=True))
    bottom_layers: int = field(default=4, metadata=_num(0, 1000, integer=True))
    infill_density: float = field(default=0.2, metadata=_num(0, 1, doc="0 = hollow, 1 = solid"))
    infill_pattern: str = field(default="rectilinear", metadata=_choice("rectilinear", "grid", "triangles", "gyroid"))
    infill_angle_deg: float = field(default=45.0, metadata=_num(-360, 360, unit="deg"))
    solid_infill_below_area: float = field(default=70.0, metadata=_num(0, 1e6, unit="mm2",
                                           doc="sparse regions smaller than this are filled solid"))
    outer_perimeter_first: bool = field(default=False, metadata={"boolean": True})
    seam: str = field(default="aligned", metadata=_choice("aligned", "nearest", "rear"))
    min_area: float = field(default=0.05, metadata=_num(0, 1e6, unit="mm2",
                            doc="islands and infill regions smaller than this are not printed"))
    filament_diameter: float = field(default=1.75, metadata=_num(0, 10, unit="mm", lo_open=True))
    # per-role extrusion widths (issue 17); absent: extrusion_width (top solid infill: the nozzle's
    # diameter, the first layer: 2 x first_layer_height within the width rule), as PrusaSlicer 2.5
    external_perimeter_extrusion_width: float | None = field(default=None, metadata=_num(
        0, 30, unit="mm", lo_open=True, optional=True, doc="outer perimeter; absent: extrusion_width"))
    perimeter_extrusion_width: float | None = field(default=None, metadata=_num(
        0, 30, unit="mm", lo_open=True, optional=True, doc="inner perimeters; absent: extrusion_width"))
    infill_extrusion_width: float | None = field(default=None, metadata=_num(
        0, 30, unit="mm", lo_open=True, optional=True, doc="sparse infill; absent: extrusion_width"))
    solid_infill_extrusion_width: float | None = field(default=None, metadata=_num(
        0, 30, unit="mm", lo_open=True, optional=True, doc="solid infill; absent: extrusion_width"))
    top_infill_extrusion_width: float | None = field(default=None, metadata=_num(
        0, 30, unit="mm", lo_open=True, optional=True, doc="top solid infill; absent: nozzle_diameter"))
    first_layer_extrusion_width: float | None = field(default=None, metadata=_num(
        0, 30, unit="mm", lo_open=True, optional=True,
        doc="every role on the first layer; absent: 2 x first_layer_height, within 1 to 3 x nozzle_diameter"))
    # bridges (issue 17): over air or over sparse infill, a round thread of bridge_flow_ratio x the
    # nozzle's cross-section, in the direction that anchors best (absent bridge_angle_deg)
    bridge_flow_ratio: float = field(default=1.0, metadata=_num(0, 2, lo_open=True,
                                     doc="bridge thread cross-section / the nozzle's (PrusaSlicer: 1)"))
    bridge_angle_deg: float | None = field(default=None, metadata=_num(-360, 360, unit="deg", optional=True,
                                           doc="direction of every bridge's lines; absent: detected per bridge"))
    overhangs: bool = field(default=True, metadata={"boolean": True, "doc": "perimeters with nothing under "
                            "them are laid with bridge flow and speed (overhang perimeter)"})
    gap_fill: bool = field(default=True, metadata={"boolean": True, "doc": "fill the gaps between perimeters "
                           "too narrow for another loop"})
    thin_walls: bool = field(default=True, metadata={"boolean": True, "doc": "walls too thin for two sides of a "
                             "perimeter are printed as one line along their middle"})
    infill_anchor: float = field(default=2.7, metadata=_num(0, 1000, unit="mm", doc="sparse infill lines are "
                                 "anchored along the perimeters by up to this much (PrusaSlicer: 600% of the infill "
                                 "width); 0: not anchored"))
    infill_anchor_max: float = field(default=50.0, metadata=_num(0, 1000, unit="mm", doc="two infill lines whose "
                                     "ends are at most this far apart along the perimeter are joined; 0: never"))
    ensure_vertical_shell_thickness: bool = field(default=False, metadata={"boolean": True, "doc": "add solid "
                                                  "infill where a sloped wall would be thinner than the perimeters"})
    # speeds per role, mm/s (issue 17: the one source of every feed rate; a robot's own
    # max_print_speed / max_travel_speed only cap them). PrusaSlicer 2.5's defaults.
    perimeter_speed: float = field(default=60.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True))
    external_perimeter_speed: float = field(default=30.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True))
    infill_speed: float = field(default=80.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True))
    solid_infill_speed: float = field(default=20.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True))
    top_solid_infill_speed: float = field(default=15.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True))
    bridge_speed: float = field(default=60.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True,
                                doc="bridges and overhang perimeters"))
    gap_fill_speed: float = field(default=20.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True))
    first_layer_speed: float = field(default=30.0, metadata=_num(0, 1e4, unit="mm/s", lo_open=True,
                                     doc="every extrusion of the first layer, whatever its role"))
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

    def role_width(self, role: str, first_layer: bool = False) -> float:
        """The extrusion width of a role, mm: ``external_perimeter``, ``perimeter``, ``infill``,
        ``solid_infill``, ``top_infill`` (the ``*_extrusion_width`` fields, absent ones resolved as
        PrusaSlicer 2.5 does), or any role on the first layer (``first_layer=True``)."""
        if first_layer:
            if self.first_layer_extrusion_width is not None:
                return self.first_layer_extrusion_width
            d = self.nozzle_diameter
            return min(max(2 * self.first_layer_height, MIN_WIDTH_PER_NOZZLE * d), MAX_WIDTH_PER_NOZZLE * d * 0.999)
        own = getattr(self, f"{role}_extrusion_width")
        if own is not None:
            return own
        return self.nozzle_diameter if role == "top_infill" else self.extrusion_width


@dataclass(frozen=True)
class ProgramSettings:
    """How the robots' command streams are made (seed §4.2.2-4.3)."""

    clearance: float = field(default=5.0, metadata=_num(0, 1e4, unit="mm", lo_open=True,
                             doc="lift above the highest printed material nearby on a move between chunks"))
    heater_idle_limit_s: float = field(default=600.0, metadata=_num(0, 1e6, unit="s",
                                       doc="a robot's hot nozzle is turned off before a WAIT expected to "
                                           "last longer than this, and reheated after it"))


@dataclass(frozen=True)
class SchedulingSettings:
    """Which robot prints which chunk, when (issue 14, :mod:`cooprint.scheduling`)."""

    strategy: str = field(default="auto", metadata=_choice("auto", "seed", "list", "exact", doc="seed (the seed's "
                          "two-robot order, seed2 layout only), list (critical-path list scheduling), exact "
                          "(OR-Tools CP-SAT, falls back to list) or auto (seed for seed2, list otherwise)"))
    time_limit_s: float = field(default=10.0, metadata=_num(0, 86400, unit="s", lo_open=True,
                                doc="the exact scheduler's time limit"))


@dataclass(frozen=True)
class JobSettings:
    """Everything a job needs besides the mesh."""

    robot: RobotProfile = field(default_factory=RobotProfile)
    chunking: ChunkingSettings = field(default_factory=ChunkingSettings)
    mesh: MeshSettings = field(default_factory=MeshSettings)
    slicing: SlicingSettings = field(default_factory=SlicingSettings)
    program: ProgramSettings = field(default_factory=ProgramSettings)
    scheduling: SchedulingSettings = field(default_factory=SchedulingSettings)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict for job.json (``None`` fields dropped, as TOML has no null)."""
        return {k: {f: v for f, v in sec.items() if v is not None} for k, sec in asdict(self).items()}


_SECTIONS: dict[str, type] = {"robot": RobotProfile, "chunking": ChunkingSettings, "mesh": MeshSettings,
                              "slicing": SlicingSettings, "program": ProgramSettings,
                              "scheduling": SchedulingSettings}


def _expectation(meta: Mapping[str, Any]) -> str:
    lo, hi, unit = meta["lo"], meta["hi"], meta["unit"]
    rng = []
    if lo is not None:
        rng.append(f"{'>' if meta['lo_open'] else '>='} {lo:g}")
    if hi is not None:
        rng.append(f"<= {hi:g}")
    kind = "a whole number " if meta["integer"] else "a number "
    return kind + " and ".join(rng) + (f" ({unit})" if unit else "")


def _shown(value: Any, limit: int = 60) -> str:
    """``repr`` of a value for an error line, a huge integer shortened (``10**18`` stays
    readable, ``10**4000`` does not flood the line and does not trip Python's digit limit)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > 10**15:
        return f"{float(value):.3g}" if abs(value) < 10**300 else "an integer of more than 300 digits"
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + "..."  # a huge list or string is not echoed whole


def _check_value(where: str, name: str, value: Any, meta: Mapping[str, Any]) -> float | int | None:
    """One numeric field: type, whole number where required, finite, within its range.

    The range is checked for integer fields too, on the exact integer (``10**18`` is compared as
    itself, never through a float that could overflow)."""
    lo, hi = meta["lo"], meta["hi"]
    if value is None and meta["optional"]:
        return None
    bad = ConfigError(f"{where}{name} = {_shown(value)}: expected {_expectation(meta)}")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise bad
    if isinstance(value, float) and not math.isfinite(value):
        raise bad
    if meta["integer"] and isinstance(value, float):
        if not value.is_integer():
            raise bad
        value = int(value)
    ok = True
    if lo is not None:
        ok = value > lo if meta["lo_open"] else value >= lo
    if ok and hi is not None:
        ok = value <= hi
    if not ok:
        raise bad
    return int(value) if meta["integer"] else float(value)


def _did_you_mean(word: str, options: Iterable[str]) -> str:
    """``; did you mean 'x'?`` for the closest option (difflib), else the list of options."""
    options = list(options)
    close = difflib.get_close_matches(word, options, n=1, cutoff=0.6)
    if close:
        return f"; did you mean {close[0]!r}?"
    return "; expected one of: " + ", ".join(options)


#: Fields cooprint no longer reads, ``(section, field)``, and what replaced them: a file that still
#: sets one is refused (a speed silently ignored would print at another speed than the file says).
REPLACED_FIELDS = {
    ("robot", "print_speed"): "the per-role speeds of [slicing] (perimeter_speed, infill_speed, ...; "
                              "docs/slicer.md) and the cap robot.max_print_speed",
    ("robot", "travel_speed"): "slicing.travel_speed and the cap robot.max_travel_speed",
}


def check_replaced(section: str, keys: Iterable[Any], where: str, label: str | None = None) -> None:
    """Refuse a field of :data:`REPLACED_FIELDS` among ``keys`` of table ``section`` with one line
    naming it and what replaced it (``label``: what the message calls the table, as
    :func:`_field_for`)."""
    for key in keys:
        instead = REPLACED_FIELDS.get((section, str(key)))
        if instead is not None:
            raise ConfigError(f"{where}{label or section}.{key} was replaced by {instead}")


def _field_for(section: str, key: str, where: str, label: str | None = None) -> Any:
    """The dataclass field ``section.key``; unknown names get a did-you-mean, replaced ones
    (:data:`REPLACED_FIELDS`) what replaced them. ``label`` is what the messages call the table
    (``profile`` for a robot's own profile; the section's name)."""
    if section not in _SECTIONS:
        raise ConfigError(f"{where}unknown section [{section}]" + _did_you_mean(section, _SECTIONS))
    check_replaced(section, (key,), where, label)
    known = {f.name: f for f in fields(_SECTIONS[section])}
    shown = label or section
    if key not in known:
        for other, cls in _SECTIONS.items():  # a field of another section? (``layer_height`` under [robot])
            if key in {f.name for f in fields(cls)}:
                if label is not None:  # a table that holds [section] fields only
                    raise ConfigError(f"{where}unknown field {shown}.{key} (a [{other}] field; it takes "
                                      f"[{section}] fields only)")
                raise ConfigError(f"{where}unknown field {section}.{key}; did you mean {other}.{key}?")
        raise ConfigError(f"{where}unknown field {shown}.{key}" + _did_you_mean(key, sorted(known)))
    return known[key]


def _build(section: str, cls: type, values: Mapping[str, Any], where: str, label: str | None = None) -> Any:
    out: dict[str, Any] = {}
    for key, value in values.items():
        f = _field_for(section, str(key), where, label)
        name = f"{label or section}.{key}"
        if "choices" in f.metadata:
            if not isinstance(value, str) or value not in f.metadata["choices"]:
                close = difflib.get_close_matches(value, f.metadata["choices"], n=1) if isinstance(value, str) else []
                raise ConfigError(f"{where}{name} = {_shown(value)}: expected one of "
                                  + ", ".join(repr(c) for c in f.metadata["choices"])
                                  + (f" (did you mean {close[0]!r}?)" if close else ""))
            out[key] = value
        elif f.metadata.get("boolean"):
            if not isinstance(value, bool):
                raise ConfigError(f"{where}{name} = {_shown(value)}: expected true or false")
            out[key] = value
        elif f.metadata:
            out[key] = _check_value(where, name, value, f.metadata)
        elif not isinstance(value, str) or not value.strip() or len(value) > 200 or not value.isprintable():
            raise ConfigError(f"{where}{name} = {_shown(value)[:60]}: expected a non-empty string of at most "
                              "200 printable characters")
        else:
            out[key] = value
    return cls(**out)


def robot_profile(values: Any, where: str, label: str, base: RobotProfile | None = None) -> RobotProfile:
    """A robot's own profile: ``values`` (any subset of the [robot] fields, ``{field: value}``)
    over ``base`` (a fleet's shared profile; the defaults when ``None``), each value checked as a
    [robot] field of a settings file is. Messages name the table as ``where`` + ``label``
    (``"job/job.json: robots[1]."`` + ``"profile"``: ``job/job.json: robots[1].profile.nozzle_depth
    = -1: expected a number > 0 and <= 10000 (mm)``); a misspelt field gets a did-you-mean."""
    if not isinstance(values, Mapping):
        raise ConfigError(f"{where}{label} = {_shown(values)}: expected a table of [robot] fields")
    given = _build("robot", RobotProfile, values, where, label)  # every value checked, in its own type
    profile = replace(base or RobotProfile(), **{str(k): getattr(given, str(k)) for k in values})
    try:  # the rules between fields hold for each robot's own outline too
        check_robot(profile, {str(k): f"{where}{label}: " for k in values})
    except ConfigError as e:
        raise ConfigError(str(e) if str(e).startswith(where) else f"{where}{label}: {e}") from None
    return profile


def check_slicing(s: SlicingSettings, origin: Mapping[str, str] | None = None) -> None:
    """The rules between slicing fields (module docstring): layer heights within the nozzle,
    the extrusion width from 1 to 3 nozzle diameters. Each failure names both fields, their
    values and the bound, on one line, after where the first field was set (``origin``:
    ``{"layer_height": "bad.toml: "}``)."""
    given = {k: w for k, w in (origin or {}).items() if w != "defaults.toml: "}

    def where_of(*names: str) -> str:  # where the user set the first of these fields
        return next((given[n] for n in names if n in given), "")

    d = s.nozzle_diameter
    for name, h in (("layer_height", s.layer_height), ("first_layer_height", s.first_layer_height)):
        if h > MAX_LAYER_PER_NOZZLE * d + 1e-12:
            where = where_of(name, "nozzle_diameter")
            raise ConfigError(f"{where}slicing.{name} = {h:g} mm is thicker than slicing.nozzle_diameter = "
                              f"{d:g} mm allows (at most {MAX_LAYER_PER_NOZZLE:g} x nozzle = "
                              f"{MAX_LAYER_PER_NOZZLE * d:g} mm); use a thinner layer or a larger nozzle")
    if s.perimeters == 0 and s.infill_density == 0 and s.top_layers == 0 and s.bottom_layers == 0:
        # nothing would be printed: no walls, no infill and no solid skins, so every plan is empty
        where = where_of("perimeters", "infill_density", "top_layers", "bottom_layers")
        raise ConfigError(f"{where}slicing.perimeters = 0, infill_density = 0, top_layers = 0 and bottom_layers = 0 "
                          f"print nothing; expected at least one perimeter, some infill or a solid layer")
    lo, hi = MIN_WIDTH_PER_NOZZLE * d, MAX_WIDTH_PER_NOZZLE * d
    for name in WIDTH_FIELDS:  # every width, the per-role ones where they are given
        w = getattr(s, name)
        if w is not None and not lo - 1e-12 <= w <= hi + 1e-12:
            where = where_of(name, "nozzle_diameter")
            # a default width that no longer suits a nozzle the user changed: say which width to set
            hint = (f" (the default width; set --extrusion-width, e.g. {AUTO_WIDTH_PER_NOZZLE * d:g} mm = "
                    f"{AUTO_WIDTH_PER_NOZZLE:g} x nozzle, PrusaSlicer's auto width)" if name not in given else "")
            raise ConfigError(f"{where}slicing.{name} = {w:g} mm: expected {MIN_WIDTH_PER_NOZZLE:g} to "
                              f"{MAX_WIDTH_PER_NOZZLE:g} x slicing.nozzle_diameter = {lo:g} to {hi:g} mm{hint}")


def check_robot(r: RobotProfile, origin: Mapping[str, str] | None = None) -> None:
    """The rule between robot fields that keeps its outline whole (docs/simulator.md): the
    printhead (half-side ``nozzle_depth`` around the nozzle) ends before the body's front
    (``build_depth`` behind the nozzle), so that the frame between them has a length, and the
    printhead does not reach into the body. Every size is already > 0 by its own range (a frame
    narrower than zero or a zero body is refused there). The failure names both fields and their
    values on one line, after where the first was set (``origin``: ``{"nozzle_depth": "r.toml: "}``)."""
    if r.nozzle_depth >= r.build_depth:
        given = {k: w for k, w in (origin or {}).items() if w != "defaults.toml: "}
        where = next((given[n] for n in ("nozzle_depth", "build_depth") if n in given), "")
        raise ConfigError(f"{where}robot.nozzle_depth = {r.nozzle_depth:g} mm, robot.build_depth = {r.build_depth:g} mm: "
                          "the printhead reaches into the body; expected nozzle_depth < build_depth (the printhead, "
                          "nozzle_depth around the nozzle, ends before the body's front)")


def work_estimate(size: Any, volume: float, s: SlicingSettings) -> dict[str, float]:
    """What slicing a part of ``size`` (x, y, z mm) and ``volume`` (mm^3) asks for: the number of
    layers (height / layer height) and an upper bound of the tool path length (the volume laid
    as solid lines, volume / (width x layer height)), mm.

    Raises
    ------
    ConfigError
        Past ``MAX_LAYERS`` or ``MAX_PATH_MM``, with the numbers and the fields to change.
    """
    height = float(size[2])
    layers = 1 + max(0, math.ceil((height - s.first_layer_height) / s.layer_height))
    path = float(volume) / (s.extrusion_width * s.layer_height)
    if layers > MAX_LAYERS:
        raise ConfigError(f"a part {height:.6g} mm tall in layers of {s.layer_height:g} mm is {layers:,} layers, "
                          f"more than the {MAX_LAYERS:,} accepted; raise slicing.layer_height (or check --units)")
    if path > MAX_PATH_MM:
        raise ConfigError(f"a part of {volume / 1e9:.3g} m3 in {s.extrusion_width:g} x {s.layer_height:g} mm lines "
                          f"is up to {path / 1e6:,.0f} km of tool path, more than the {MAX_PATH_MM / 1e6:,.0f} km "
                          "accepted; use wider lines or thicker layers (or check --units)")
    return {"layers": layers, "path_mm_max": path}


def parse_value(text: str) -> Any:
    """A command-line value as TOML reads it (``0.3``, ``true``, ``"grid"``); anything TOML
    does not read as a value is the string itself (``grid``, ``my robot``)."""
    if not text.isprintable():  # a newline would let one value set other keys
        return text
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except (tomllib.TOMLDecodeError, RecursionError):
        return text


def parse_assignment(text: str) -> tuple[str, Any]:
    """``section.key=value`` (``--set``) into ``("section.key", value)``; the key is checked
    (unknown section or field: did you mean), the value later with its field."""
    key, eq, value = text.partition("=")
    key = key.strip()
    section, dot, name = key.partition(".")
    if not eq or not dot or not section or not name:
        raise ConfigError(f"--set {text[:80]!r}: expected SECTION.KEY=VALUE, e.g. slicing.infill_pattern=grid")
    _field_for(section, name, "--set: ")
    return key, parse_value(value.strip())


def parse_fraction(text: str, option: str = "--infill") -> float:
    """A density as PrusaSlicer writes it (``20%``) or as a fraction (``0.2``).

    A bare number above 1 (``20``) is refused: PrusaSlicer reads its percent options' bare numbers
    as percentages, cooprint's fields are fractions, and guessing either way could print 20x
    more or less material than meant."""
    t = text.strip()
    try:
        value = float(t[:-1]) / 100 if t.endswith("%") else float(t)
    except ValueError:
        raise ConfigError(f"{option} {text[:40]!r}: expected a fraction from 0 to 1 (0.2) or a percentage "
                          "(20%)") from None
    if not math.isfinite(value) or not 0 <= value <= 1:
        hint = f" (for {t}% write {t}%)" if not t.endswith("%") and math.isfinite(value) and 1 < value <= 100 else ""
        raise ConfigError(f"{option} {text[:40]}: expected a fraction from 0 to 1 (0.2) or a percentage "
                          f"from 0% to 100% (20%){hint}")
    return value


def _read_toml(path: Path) -> dict[str, Any]:
    """A settings file, which must be a regular file (a FIFO or a device would block the read or
    never end) of at most ``MAX_SETTINGS_BYTES``."""
    from cooprint.io.files import regular_file

    st = regular_file(path, "settings file", ConfigError)
    if st.st_size > MAX_SETTINGS_BYTES:
        raise ConfigError(f"{path}: {st.st_size:,} bytes; a settings file is at most {MAX_SETTINGS_BYTES:,}")
    try:
        with open(path, "rb") as fh:
            data = fh.read(MAX_SETTINGS_BYTES + 1)
        text = data.decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read settings file ({exc})") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: invalid TOML: {exc}") from None
    except RecursionError:
        raise ConfigError(f"{path}: invalid TOML: nested too deeply") from None


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
    origin: dict[str, str] = {}  # "section.field": where its value was set
    layers: list[tuple[str, Mapping[str, Any]]] = [("defaults.toml: ", _defaults())]
    layers += [(f"{p}: ", _read_toml(Path(p))) for p in paths]
    layers += list(tables)
    for where, data in layers:
        for section, values in data.items():
            if section not in _SECTIONS:
                raise ConfigError(f"{where}unknown section [{section}]" + _did_you_mean(section, _SECTIONS))
            if not isinstance(values, dict):
                raise ConfigError(f"{where}{section} must be a table [{section}]")
            _build(section, _SECTIONS[section], values, where)  # validate with its own file name
            merged[section].update(values)
            origin.update({f"{section}.{k}": where for k in values})
    for key, value in (overrides or {}).items():
        if value is None:
            continue
        section, _, name = key.partition(".")
        _field_for(section, name, "option: ")
        _build(section, _SECTIONS[section], {name: value}, "option: ")
        merged[section][name] = value
        origin[key] = "option: "
    settings = JobSettings(**{s: _build(s, cls, merged[s], "") for s, cls in _SECTIONS.items()})
    check_slicing(settings.slicing, {k.partition(".")[2]: w for k, w in origin.items() if k.startswith("slicing.")})
    check_robot(settings.robot, {k.partition(".")[2]: w for k, w in origin.items() if k.startswith("robot.")})
    return settings
