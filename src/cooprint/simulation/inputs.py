"""What the simulator reads: a bundle of ``cooprint run``, ``.coop`` files with a manifest, or
plain G-code files (one robot each, so that PrusaSlicer's or Cura's output simulates too)."""

from __future__ import annotations

import difflib
import io
import json
import math
import os
import re
import tomllib
from dataclasses import dataclass, fields, replace
from pathlib import Path, PurePosixPath, PureWindowsPath
from typing import TYPE_CHECKING, Any, Iterable, Iterator

import numpy as np

from cooprint.config import JobSettings, RobotProfile, SlicingSettings, load_settings, robot_profile
from cooprint.config.settings import check_replaced
from cooprint.geometry import unit_deg
from cooprint.io.schema import (SchemaError, check_list, check_number, check_object, check_string, check_vector, fail,
                                key_path, shown_key)
from cooprint.io.bundle import map_input, plain_name, release
from cooprint.io.files import path_kind, regular_file
from cooprint.program.commands import MOVE, NOTIFY, TOOL_OFF, TOOL_ON, WAIT, Program, iter_coop, make_program, read_coop
from cooprint.simulation.kinematics import MachineLimits
from cooprint.simulation.timeline import SimRobot
from cooprint.slicing.paths import INFILL, ROUND_ROLES, TRAVEL, extrusion_width, round_width

if TYPE_CHECKING:
    from cooprint.program.gcode import Feeds


class SimInputError(SchemaError):
    """A bundle, manifest or G-code file the simulator cannot use (the field checks of
    :mod:`cooprint.io.schema` raise its base, :class:`~cooprint.io.schema.SchemaError`)."""


@dataclass(frozen=True)
class SimInput:
    """Robots to simulate, with the profile that gives their speeds and body."""

    robots: list[SimRobot]
    profile: RobotProfile
    slicing: SlicingSettings
    source: str  # what was read, for messages and the summary
    limits: MachineLimits | None = None  # for the acceleration model; None: the robot profile's
    placed: bool = True  # the robots' starts and facings are known: the body checks apply
    notes: tuple[str, ...] = ()  # what was read and not acted on (for the summary)
    #: Each chunk's dependencies (job.json ``chunks[].deps``): the chunks whose material must be
    #: finished before its own is laid (the ``chunk-order`` check); ``None``: not known.
    deps: dict[str, tuple[str, ...]] | None = None
    #: What the scheduler promised (job.json ``schedule.lower_bound_s``, ``makespan_s``, ``gap``):
    #: the simulator repeats the bound and checks the plan's makespan against it; ``None``: none given.
    estimate: "ScheduleEstimate | None" = None
    # a bundle's chunk meshes (job.json chunks[].file), in job.json's order, and each robot's
    # chunk ids (robots[].chunks, or the chunks its program names): the outside-part check
    chunk_files: dict[str, Path] | None = None
    robot_chunks: dict[str, tuple[str, ...]] | None = None
    #: The schedule's critical path (job.json ``schedule.critical_path``, chunk ids), for the
    #: Gantt chart; ``None``: not in the bundle.
    critical_path: tuple[str, ...] | None = None
    #: A bundle read without its programs (``load_inputs(..., programs=False)``): each robot's
    #: ``.coop`` file by name, its ``program`` ``None`` until :func:`cooprint.simulation.simulate`
    #: times it piece by piece (or :meth:`with_programs` reads it whole).
    program_files: dict[str, Path] | None = None

    #: Each robot's command counts as job.json states them (``robots[].stats``: commands, moves,
    #: NOTIFY, WAIT), by name: a program read piece by piece is checked against them when its
    #: last piece is read (:meth:`program_pieces`); ``None``: not stated.
    program_counts: dict[str, dict[str, int]] | None = None
    #: The files read, each as ``[size, mtime_ns]`` when the input was loaded (:func:`fingerprint`),
    #: by path (a bundle's relative to it: ``job.json``, ``robots/A.coop``): sim/summary.json keeps
    #: it, so that ``cooprint view`` knows when the inputs changed since they were simulated.
    fingerprint: dict[str, list[int]] | None = None

    def with_programs(self) -> "SimInput":
        """This input with every robot's program read whole (itself when they are), each checked
        against job.json's counts (:func:`check_counts`)."""
        if self.program_files is None:
            return self
        robots = []
        for r in self.robots:
            program = read_coop(self.program_files[r.name], r.name)
            check_counts(self.program_files[r.name], program_counts(program), (self.program_counts or {}).get(r.name))
            robots.append(replace(r, program=program))
        return replace(self, robots=robots, program_files=None, robot_chunks=own_chunks(self.robot_chunks, robots))

    def program_pieces(self, name: str) -> Iterator[Program]:
        """Robot ``name``'s program read piece by piece from its file (:func:`iter_coop`), its
        commands counted on the way and checked against job.json's counts after the last piece
        (:func:`check_counts`): a truncated or replaced file is refused in the same read that times it."""
        assert self.program_files is not None
        path = self.program_files[name]
        counted = dict.fromkeys(COUNTED_KINDS, 0)
        for piece in iter_coop(path, name):
            for key, n in program_counts(piece).items():
                counted[key] += n
            yield piece
        check_counts(path, counted, (self.program_counts or {}).get(name))

    @property
    def lower_bound(self) -> float | None:
        """The schedule's lower bound, s (``estimate.lower_bound_s``), or ``None``."""
        return None if self.estimate is None else self.estimate.lower_bound_s

    def fleet(self) -> list[SimRobot]:
        """The robots, each with its own profile (the input's ``profile`` for those without)."""
        return [r if r.profile is not None else replace(r, profile=self.profile) for r in self.robots]

    def feeds(self, robots: Iterable[SimRobot] | None = None) -> "dict[str, Feeds]":
        """Each robot's speeds by name (``robots``: :meth:`fleet` by default): the slicer's per
        path role under its own profile's caps (:meth:`Feeds.of_robot`), what a robot without
        per-command speeds (a ``.coop`` program) moves at."""
        from cooprint.program.gcode import Feeds

        return {r.name: Feeds.of_robot(r.profile or self.profile, self.slicing)
                for r in (self.fleet() if robots is None else robots)}


@dataclass(frozen=True)
class ScheduleEstimate:
    """The scheduler's record of a bundle (job.json ``schedule``), each field ``None`` when absent:
    ``lower_bound_s`` (no schedule of the fleet can be shorter: the critical path or the work per
    robot), ``makespan_s`` (the scheduler's own estimate of the plan's makespan) and ``gap``
    (its estimate over the bound, minus 1)."""

    lower_bound_s: float | None = None
    makespan_s: float | None = None
    gap: float | None = None


#: job.json ``schedule`` fields the simulator reads (optional numbers >= 0; ``null`` as absent).
SCHEDULE_NUMBERS = {"lower_bound_s": "s", "makespan_s": "s", "gap": "a fraction: makespan / lower bound - 1"}
#: A ``gap`` this little below 0 is a makespan equal to its bound in floating point (read as 0).
GAP_ROUNDING = 1e-9


#: The counts of job.json's ``robots[].stats`` that a robot's program is checked against, and
#: how a message names each.
COUNTED_KINDS = {"commands": "commands", "moves": "moves", "notify": "NOTIFY", "wait": "WAIT"}


def fingerprint(files: Iterable[Path], root: Path | None = None) -> dict[str, list[int]]:
    """Each file's ``[size, mtime_ns]`` by path (relative to ``root`` when given, ``/``-separated;
    else absolute): cheap (a stat each), and any write to a file changes its mtime."""
    out = {}
    for f in files:
        try:
            st = os.stat(f)
        except (OSError, ValueError):  # not there: its reader says so
            continue
        key = Path(os.path.relpath(f, root)).as_posix() if root is not None else os.path.abspath(f)
        out[key] = [int(st.st_size), int(st.st_mtime_ns)]
    return out


def program_counts(program: Program) -> dict[str, int]:
    """A program's (or a piece's) commands, moves, NOTIFYs and WAITs (job.json ``stats``' counts)."""
    kind = program.kind
    return {"commands": len(kind), "moves": int(np.count_nonzero(kind == MOVE)),
            "notify": int(np.count_nonzero(kind == NOTIFY)), "wait": int(np.count_nonzero(kind == WAIT))}


def check_counts(path: Path, counted: dict[str, int], stated: dict[str, int] | None) -> None:
    """Refuse a bundle's program whose counts (:func:`program_counts`) are not those job.json
    states for it (``stated``; ``None``: nothing stated, nothing to check): the file was cut
    short, emptied or replaced after ``cooprint run`` wrote it, and simulating it would report a
    plan that is not the bundle's."""
    for key, what in COUNTED_KINDS.items():
        if stated is not None and key in stated and counted[key] != stated[key]:
            raise SimInputError(f"{path}: {counted[key]:,} {what}, job.json says {stated[key]:,}: the file was "
                                "truncated or replaced; re-run `cooprint run`")


def _stated_counts(e: dict[str, Any], where: str, at: str) -> dict[str, int] | None:
    """The counts of a job.json robot's ``stats`` (:data:`COUNTED_KINDS`, each an integer >= 0
    when present), ``None`` without ``stats``."""
    if "stats" not in e:
        return None
    stats = check_object(e["stats"], where, at + ".stats", unknown="ignore")
    out = {}
    for key in COUNTED_KINDS:
        if key in stats:
            value = stats[key]
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise fail(where, f"{at}.stats.{key}", "expected a count (an integer >= 0)", value)
            out[key] = value
    return out


_facing = unit_deg  # a robot's facing in degrees (job.json facing_deg) as its unit vector


# ----------------------------------------------------------------------------------------------
# the schemas of the simulator's inputs (docs/simulator.md): extend them here, in one place

#: A robot's name: it names the robot's bare NOTIFY events (``<robot>:<n>``), so it is an event name.
ROBOT_NAME = re.compile(r"[A-Za-z0-9_:.\-]{1,64}")
#: Largest coordinate of a start, mm; largest facing, degrees.
COORD_LIMIT, FACING_LIMIT = 1e6, 360.0
#: Most robots in one simulation.
MAX_ROBOTS = 1000
#: A bundle's job.json: the keys the simulator reads (format, settings, robots) are checked in
#: full; the other top-level keys (mesh, plan, chunks, schedule, stats, picture) are the plan's
#: record, checked for their types. A top-level key outside these is an error (did you mean ...).
BUNDLE_FORMAT = re.compile(r"cooprint-job/([0-9]{1,6})")
#: The job formats this cooprint writes and reads back (``cooprint-job/1`` is a chunk bundle).
BUNDLE_VERSIONS = (2,)
BUNDLE_REQUIRED = ("format", "settings", "robots")
BUNDLE_OPTIONAL = ("mesh", "plan", "chunks", "schedule", "stats", "picture")
#: The top-level keys that hold an object.
BUNDLE_OBJECTS = ("mesh", "plan", "schedule", "stats")
#: The sides a robot stands on (``both``: one robot prints both sides).
BUNDLE_SIDES = ("left", "right", "both")
#: How far a stored ``facing`` may be from the unit vector of ``facing_deg``.
FACING_TOLERANCE = 1e-6
#: Keys of an entry of job.json's ``robots``: those the simulator needs, and those cooprint writes
#: besides (checked when they matter, ``facings`` for per-chunk facings). A key in neither is
#: ignored (a newer cooprint may add one) unless it looks like a misspelt known key.
BUNDLE_ROBOT_REQUIRED = ("name", "program", "start", "facing_deg")
BUNDLE_ROBOT_OPTIONAL = ("side", "facing", "gcode", "stats", "profile", "chunks", "facings")
#: A manifest (TOML): its sections and the keys of a ``[[robots]]`` entry; unknown keys are errors.
MANIFEST_SECTIONS = ("robot", "slicing", "robots", "profiles")
MANIFEST_ROBOT_REQUIRED = ("name", "program")
MANIFEST_ROBOT_OPTIONAL = ("start", "facing_deg")
#: The fields of a robot's own profile (job.json ``robots[].profile``, a manifest's
#: ``[profiles.NAME]``): those of the [robot] section.
ROBOT_FIELDS = tuple(f.name for f in fields(RobotProfile))


def _settings_fields() -> dict[str, tuple[str, ...]]:
    """Every settings section and its fields (cooprint.config's records)."""
    job = JobSettings()
    return {f.name: tuple(g.name for g in fields(getattr(job, f.name))) for f in fields(job)}


def check_settings(data: Any, where: str, path: str, sections: Iterable[str] | None = None) -> JobSettings:
    """Settings given as ``{section: {field: value}}`` inside a file (job.json's ``settings``, a
    manifest's ``[robot]`` and ``[slicing]``): known sections and fields (did you mean ...), then
    each value validated by :func:`cooprint.config.load_settings`, over the defaults."""
    known = _settings_fields()
    allowed = list(known if sections is None else sections)
    check_object(data, where, path, optional=allowed)
    prefix = f"{where}: {path}." if path else f"{where}: "
    for sec, values in data.items():
        if isinstance(values, dict):  # a field cooprint replaced: what replaced it, not a did-you-mean
            check_replaced(sec, values, prefix)
        check_object(values, where, key_path(path, sec), optional=known[sec])
    return load_settings(tables=[(prefix, data)])


def _read_structured(path: Path, kind: str, parse) -> Any:
    """The parsed content of a JSON or TOML file, or a one-line error naming it."""
    regular_file(path, kind, SimInputError)  # a FIFO would block the read for ever
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SimInputError(f"{path}: no such {kind}") from None
    except IsADirectoryError:
        raise SimInputError(f"{path}: a folder, not a {kind}") from None
    except UnicodeDecodeError as exc:
        raise SimInputError(f"{path}: not UTF-8 text (byte {exc.start})") from None
    except OSError as exc:
        raise SimInputError(f"{path}: cannot read ({exc.strerror or exc})") from None
    try:
        return parse(text)
    except RecursionError:
        raise SimInputError(f"{path}: nested too deeply to be a {kind}") from None
    except (ValueError, tomllib.TOMLDecodeError) as exc:  # json.JSONDecodeError is a ValueError
        raise SimInputError(f"{path}: not a valid {kind} ({str(exc)[:120]})") from None


def _program_in(folder: Path, value: Any, where: str, path: str, what: str = "program file") -> Path:
    """A bundle's program (or other ``what``) path: relative, inside the bundle (no ``..``, no
    symlink out), a file."""
    text = check_string(value, where, path, what="a path relative to the bundle")
    rel = PurePosixPath(text)
    if rel.is_absolute() or PureWindowsPath(text).drive or ".." in rel.parts or "\x00" in text or "\\" in text:
        raise fail(where, path, "expected a path inside the bundle (relative, without '..')", value)
    full = folder / rel
    try:
        inside = full.resolve().is_relative_to(folder.resolve())
    except (OSError, RuntimeError):  # a symlink loop
        inside = False
    if not inside:
        raise fail(where, path, "expected a path inside the bundle (it leads outside)", value)
    kind = path_kind(full, SimInputError)
    if kind != "file":
        raise fail(where, path, f"no such {what} in the bundle" if kind == "missing" else
                   f"expected a {what} in the bundle, not a folder, a named pipe (FIFO) or a device", value)
    return full


def own_chunks(robot_chunks: dict[str, tuple[str, ...] | None] | None, robots: list[SimRobot]
                ) -> dict[str, tuple[str, ...]] | None:
    """Each robot's chunk ids, those job.json does not state (``None``) from its program."""
    if robot_chunks is None:
        return None
    return {name: ids if ids is not None else tuple(next(r for r in robots if r.name == name).program.chunks)
            for name, ids in robot_chunks.items()}


def load_bundle(folder: str | Path, programs: bool = True) -> SimInput:
    """A ``cooprint run`` bundle: ``job.json`` and the ``robots/*.coop`` it names, each field
    checked (docs/simulator.md, "Inputs"). ``programs=False``: the programs are not read (their
    files in :attr:`SimInput.program_files`, each robot's ``program`` ``None``): the simulation
    reads them piece by piece."""
    d = Path(folder)
    path = d / "job.json"
    if not path.exists():
        raise SimInputError(f"{d}: no job.json (not a cooprint run bundle)")
    where = str(path)
    record = check_object(_read_structured(path, "job.json", json.loads), where, "",
                          required=("format",), unknown="ignore")
    fmt = check_string(record["format"], where, "format", what="a cooprint job format ('cooprint-job/2')")
    version = BUNDLE_FORMAT.fullmatch(fmt)
    if version is None:
        raise fail(where, "format", "expected a cooprint job format ('cooprint-job/2')", fmt)
    if int(version.group(1)) < 2 or "robots" in record and isinstance(record["robots"], list) and \
            record["robots"] and all(isinstance(r, dict) and "program" not in r for r in record["robots"]):
        raise SimInputError(f"{where}: a bundle of `cooprint chunk` (no robot programs); plan it with `cooprint run`")
    if int(version.group(1)) not in BUNDLE_VERSIONS:
        raise fail(where, "format", f"written by a newer cooprint; this one reads "
                   f"{', '.join(f'cooprint-job/{v}' for v in BUNDLE_VERSIONS)}", fmt)
    check_object(record, where, "", required=BUNDLE_REQUIRED, optional=BUNDLE_OPTIONAL)
    for key in BUNDLE_OBJECTS:
        if key in record:
            check_object(record[key], where, key, unknown="ignore")
    if "picture" in record and record["picture"] is not None:
        check_string(record["picture"], where, "picture", what="a file name or null")
    chunk_ids = _chunk_ids(record, where)
    chunk_files = _chunk_files(record, d, where)
    settings = check_settings(record["settings"], where, "settings")
    entries = check_list(record["robots"], where, "robots", min_len=1, max_len=MAX_ROBOTS, what="robot objects")
    robots, names, robot_chunks, files, counts = [], set(), {}, {}, {}
    for n, e in enumerate(entries):
        at = key_path("robots", n)
        check_object(e, where, at, required=BUNDLE_ROBOT_REQUIRED, optional=BUNDLE_ROBOT_OPTIONAL, unknown="typo")
        name = check_string(e["name"], where, at + ".name", pattern=ROBOT_NAME,
                            what="a robot name (letters, digits, _ : . -; at most 64)")
        if name in names:
            raise fail(where, at + ".name", "a second robot of that name", name)
        names.add(name)
        program_path = _program_in(d, e["program"], where, at + ".program")
        start = check_vector(e["start"], where, at + ".start", 3, COORD_LIMIT)
        facing = check_number(e["facing_deg"], where, at + ".facing_deg", lo=-FACING_LIMIT, hi=FACING_LIMIT,
                              unit="degrees")
        _check_robot_record(e, facing, chunk_ids, where, at)
        profile = _bundle_profile(e.get("profile"), settings.robot, where, at)
        counts[name] = _stated_counts(e, where, at)
        program = read_coop(program_path, name) if programs else None
        if program is not None:
            check_counts(program_path, program_counts(program), counts[name])
        elif program_path.stat().st_size == 0:  # emptied: refused now, before any work
            check_counts(program_path, dict.fromkeys(COUNTED_KINDS, 0), counts[name])
        files[name] = program_path
        robots.append(SimRobot(name, program, np.asarray(start, dtype=np.float64), _facing(facing),
                               profile=profile))
        robot_chunks[name] = (tuple(e["chunks"]) if "chunks" in e else
                              tuple(program.chunks) if program is not None else None)
    critical = _critical_path(record, chunk_ids, where)
    stamp = fingerprint([path, *files.values(), *(chunk_files or {}).values()], d)
    return SimInput(robots, settings.robot, settings.slicing, str(d), deps=_chunk_deps(record, chunk_ids, where),
                    estimate=_schedule_estimate(record, where), chunk_files=chunk_files,
                    robot_chunks=robot_chunks if chunk_files is not None else None, critical_path=critical,
                    program_files=None if programs else files,
                    program_counts={k: v for k, v in counts.items() if v is not None}, fingerprint=stamp)


def _critical_path(record: dict[str, Any], chunk_ids: set[str] | None, where: str) -> tuple[str, ...] | None:
    """The schedule's critical path (``schedule.critical_path``: ids of the bundle's chunks),
    ``None`` when absent (bundles of the seed's two-robot schedule have none); the Gantt chart
    marks it."""
    sched = record.get("schedule")
    if not isinstance(sched, dict) or sched.get("critical_path") is None:
        return None
    items = check_list(sched["critical_path"], where, "schedule.critical_path", what="chunk ids")
    for k, cid in enumerate(items):
        if not isinstance(cid, str) or (chunk_ids is not None and cid not in chunk_ids):
            raise fail(where, key_path("schedule.critical_path", k), "expected the id of one of the bundle's "
                       "chunks", cid)
    return tuple(items)


def _bundle_profile(value: Any, fleet: RobotProfile, where: str, at: str) -> RobotProfile | None:
    """A job.json robot's own profile: an object of [robot] fields over the bundle's
    ``settings.robot`` (what ``cooprint run`` writes: the robot's whole profile), or the
    profile's name (older bundles: the robot has the bundle's profile; ``None`` here)."""
    if value is None:
        return None
    if isinstance(value, str):
        check_string(value, where, at + ".profile", what="a profile name or an object of [robot] fields")
        return None
    if not isinstance(value, dict):
        raise fail(where, at + ".profile", "expected a profile name or an object of [robot] fields", value)
    check_replaced("robot", value, f"{where}: {at}.", "profile")
    check_object(value, where, at + ".profile", optional=ROBOT_FIELDS)  # a misspelt field: did you mean
    return robot_profile(value, f"{where}: {at}.", "profile", fleet)


#: The keys of a job.json chunk that list chunks to finish first: ``deps`` (the chunks it leans
#: on) and ``body_deps`` (the chunks its robot's body would sweep over: printed first, while the
#: way is free). The chunk-order check holds a chunk to both.
DEP_KEYS = ("deps", "body_deps")


def _chunk_deps(record: dict[str, Any], chunk_ids: set[str] | None, where: str) -> dict[str, tuple[str, ...]] | None:
    """Each chunk's dependencies from job.json's ``chunks[].deps`` and ``chunks[].body_deps`` (ids
    of other chunks of the bundle), merged: every chunk named in either must be finished before
    the chunk starts. ``None`` when no chunk lists any (nothing to check the chunk order
    against). A chunk without them depends on none; a chunk that depends on itself could never
    be printed."""
    if chunk_ids is None or not any(isinstance(c, dict) and any(k in c for k in DEP_KEYS) for c in record["chunks"]):
        return None
    deps = {}
    for n, c in enumerate(record["chunks"]):
        at = key_path("chunks", n)
        own = c["id"]
        merged: list[str] = []
        for key in DEP_KEYS:
            items = check_list(c.get(key, []), where, f"{at}.{key}", what="chunk ids")
            for k, dep in enumerate(items):
                if not isinstance(dep, str) or dep not in chunk_ids:
                    raise fail(where, key_path(f"{at}.{key}", k), "expected the id of one of the bundle's chunks", dep)
                if dep == own:
                    raise fail(where, key_path(f"{at}.{key}", k), "a chunk cannot depend on itself", dep)
            merged += items
        deps[own] = tuple(dict.fromkeys(merged))  # in order, once each
    return deps


def _schedule_estimate(record: dict[str, Any], where: str) -> ScheduleEstimate | None:
    """The scheduler's numbers of job.json's ``schedule`` (:data:`SCHEDULE_NUMBERS`), each a
    finite number >= 0 when present (``null``: absent); ``None`` when it states none of them."""
    sched = record.get("schedule")
    if not isinstance(sched, dict):  # absent (checked as an object when present)
        return None
    got = {}
    for key, unit in SCHEDULE_NUMBERS.items():
        value = sched.get(key)
        if value is None:
            continue
        if key == "gap" and isinstance(value, float) and -GAP_ROUNDING <= value < 0:
            value = 0.0  # a makespan equal to its bound, over it minus 1 in floating point
        got[key] = check_number(value, where, f"schedule.{key}", lo=0.0, unit=unit)
    return ScheduleEstimate(**got) if got else None


def _chunk_files(record: dict[str, Any], folder: Path, where: str) -> dict[str, Path] | None:
    """Each chunk's mesh file (job.json ``chunks[].file``, a path inside the bundle that must
    name a file), by chunk id; ``None`` when the record has no chunk list or a chunk without a
    ``file`` (the part is then not known and the outside-part check is left out)."""
    if "chunks" not in record:
        return None
    files = {}
    for n, c in enumerate(record["chunks"]):  # checked by _chunk_ids: objects with a string id
        if "file" not in c:
            return None
        files[c["id"]] = _program_in(folder, c["file"], where, key_path("chunks", n) + ".file", "chunk mesh")
    return files


@dataclass(frozen=True)
class ChunkMesh:
    """A chunk's closed triangle mesh: vertices (n, 3) float64 and faces (m, 3), mm."""

    vertices: np.ndarray
    faces: np.ndarray


def read_chunk_meshes(inp: SimInput) -> dict[str, ChunkMesh] | None:
    """The chunk meshes of a bundle (:attr:`SimInput.chunk_files`) by chunk id; ``None`` when the
    input names none. A binary STL is taken as written (cooprint wrote it closed; its triangles
    are all the sections need); any other file goes through cooprint's mesh reader, and one that
    does not read as a closed mesh is a :class:`SimInputError` naming job.json's field and the
    file."""
    from cooprint.errors import UserError
    from cooprint.io.mesh import binary_stl_soup, load_mesh

    if inp.chunk_files is None:
        return None
    out = {}
    where = str(Path(inp.source) / "job.json")
    for n, (cid, path) in enumerate(inp.chunk_files.items()):
        soup = binary_stl_soup(path)
        if soup is not None:
            out[cid] = ChunkMesh(*soup)
            continue
        try:
            solid = load_mesh(path)
        except UserError as exc:
            raise SimInputError(f"{where}: {key_path('chunks', n)}.file: chunk {cid}'s mesh: {exc}") from None
        out[cid] = ChunkMesh(solid.vertices, solid.faces)
    return out


def _chunk_ids(record: dict[str, Any], where: str) -> set[str] | None:
    """The ids of job.json's ``chunks`` (a list of objects, each with a string ``id``); ``None``
    when the record has no chunk list."""
    if "chunks" not in record:
        return None
    ids = set()
    for n, c in enumerate(check_list(record["chunks"], where, "chunks", what="chunk objects")):
        at = key_path("chunks", n)
        check_object(c, where, at, required=("id",), unknown="ignore")
        ids.add(check_string(c["id"], where, at + ".id", what="a chunk id"))
    return ids


def _check_robot_record(e: dict[str, Any], facing_deg: float, chunk_ids: set[str] | None, where: str,
                        at: str) -> None:
    """The record fields of a job.json robot entry beside those the simulator needs: ``side``
    one of :data:`BUNDLE_SIDES`; ``facing`` the unit vector of ``facing_deg`` (within
    :data:`FACING_TOLERANCE`: an edit of one and not the other is a contradiction); ``chunks``
    ids of the bundle's chunks; ``facings`` ``{from_chunk, facing_deg}`` entries whose chunk is
    one of this robot's."""
    if "side" in e and e["side"] not in BUNDLE_SIDES:
        raise fail(where, at + ".side", f"expected one of {', '.join(BUNDLE_SIDES)}", e["side"])
    if "facing" in e:
        vec = check_vector(e["facing"], where, at + ".facing", 2, 1.0 + FACING_TOLERANCE)
        want = _facing(facing_deg)
        if float(np.abs(np.asarray(vec) - want).max()) > FACING_TOLERANCE:
            raise fail(where, at + ".facing", f"expected [{want[0]:.6g}, {want[1]:.6g}], the unit vector of "
                       f"facing_deg = {facing_deg:g}", e["facing"])
    own = None
    if "chunks" in e:
        own = check_list(e["chunks"], where, at + ".chunks", what="chunk ids")
        for k, cid in enumerate(own):
            if not isinstance(cid, str) or (chunk_ids is not None and cid not in chunk_ids):
                raise fail(where, key_path(at + ".chunks", k), "expected the id of one of the bundle's chunks", cid)
    if "facings" in e:
        for k, f in enumerate(check_list(e["facings"], where, at + ".facings", what="facings")):
            fat = key_path(at + ".facings", k)
            check_object(f, where, fat, required=("from_chunk", "facing_deg"), unknown="typo")
            known = own if own is not None else chunk_ids
            if not isinstance(f["from_chunk"], str) or (known is not None and f["from_chunk"] not in known):
                raise fail(where, fat + ".from_chunk", "expected the id of one of this robot's chunks",
                           f["from_chunk"])
            check_number(f["facing_deg"], where, fat + ".facing_deg", lo=-FACING_LIMIT, hi=FACING_LIMIT,
                         unit="degrees")


def load_manifest(path: str | Path) -> SimInput:
    """``.coop`` files named by a TOML manifest (every key checked; a misspelt one is an error
    that names the key meant)::

        [robot]                 # the fleet's profile (any field of cooprint's [robot] section)
        max_print_speed = 40.0  # (speeds per role: [slicing]; the robot caps them)
        [[robots]]
        name = "A"
        program = "A.coop"      # relative to the manifest
        start = [0.0, 0.0, 5.0] # nozzle position at the start, mm (absent: the first MOVE)
        facing_deg = 90.0       # direction from the body to the nozzle at the start (absent: +Y;
                                # the program's ;@facing lines turn the robot on the way)
        [profiles.B]            # robot B's own profile: any [robot] field, over [robot]
        max_print_speed = 20.0  # (a mixed fleet: B is slower, and below, bigger)
        body_width = 400.0

    A robot without a ``[profiles.NAME]`` table has the ``[robot]`` profile. A profile table for
    a robot the manifest does not list is an error (a misspelt name would silently leave the
    robot with the fleet's profile).
    """
    p = Path(path)
    where = str(p)
    data = check_object(_read_structured(p, "manifest", tomllib.loads), where, "", optional=MANIFEST_SECTIONS)
    settings = check_settings({k: v for k, v in data.items() if k in ("robot", "slicing")}, where, "",
                              ("robot", "slicing"))
    if "robots" not in data:
        raise SimInputError(f"{where}: no [[robots]] entries")
    entries = check_list(data["robots"], where, "robots", min_len=1, max_len=MAX_ROBOTS, what="[[robots]] entries")
    robots, names, files = [], set(), [p]
    for n, e in enumerate(entries):  # counted from 0, as job.json's robots are
        at = key_path("robots", n)
        check_object(e, where, at, required=MANIFEST_ROBOT_REQUIRED, optional=MANIFEST_ROBOT_OPTIONAL)
        name = check_string(e["name"], where, at + ".name", pattern=ROBOT_NAME,
                            what="a robot name (letters, digits, _ : . -; at most 64)")
        if name in names:
            raise fail(where, at + ".name", "a second robot of that name", name)
        names.add(name)
        prog = check_string(e["program"], where, at + ".program", what="the path of a .coop file")
        start = None if "start" not in e else check_vector(e["start"], where, at + ".start", 3, COORD_LIMIT)
        facing = check_number(e.get("facing_deg", 90.0), where, at + ".facing_deg", lo=-FACING_LIMIT,
                              hi=FACING_LIMIT, unit="degrees")
        file = p.parent / prog
        kind = path_kind(file, SimInputError)
        if kind != "file":
            raise fail(where, at + ".program", f"no such .coop file ({file})" if kind == "missing" else
                       f"expected a .coop file, not a folder, a named pipe (FIFO) or a device ({file})", prog)
        files.append(file)
        program = read_coop(file, name)
        robots.append(SimRobot(name, program, None if start is None else np.asarray(start, float), _facing(facing)))
    profiles = _manifest_profiles(data.get("profiles", {}), [r.name for r in robots], settings.robot, where)
    robots = [replace(r, profile=profiles[r.name]) if r.name in profiles else r for r in robots]
    return SimInput(robots, settings.robot, settings.slicing, where, fingerprint=fingerprint(files))


def _manifest_profiles(data: Any, names: list[str], fleet: RobotProfile, where: str) -> dict[str, RobotProfile]:
    """A manifest's ``[profiles.NAME]`` tables: robot NAME's own profile, its [robot] fields over
    the manifest's ``[robot]`` (each checked; a misspelt field gets a did-you-mean). A table for
    a robot that ``[[robots]]`` does not list is an error naming it (and the robot meant)."""
    check_object(data, where, "profiles", unknown="ignore")
    out = {}
    for name, values in data.items():
        at = key_path("profiles", str(name))
        if name not in names:
            # names are case-sensitive; one letter in the wrong case is the likeliest slip
            close = [n for n in names if n.lower() == str(name).lower()] or \
                difflib.get_close_matches(str(name), names, n=1, cutoff=0.6)
            raise SimInputError(f"{where}: {shown_key(at, 60)}: no robot {shown_key(str(name), 60)} in [[robots]]"
                                + (f" (did you mean [profiles.{close[0]}]?)" if close else ""))
        if isinstance(values, dict):
            check_replaced("robot", values, f"{where}: profiles.", str(name))
        check_object(values, where, at, optional=ROBOT_FIELDS)  # a misspelt field: did you mean
        out[name] = robot_profile(values, f"{where}: profiles.", str(name), fleet)
    return out


def coop_facing(program: Any) -> float:
    """The facing of a robot whose program comes without a manifest, degrees: as ``cooprint run``
    places robots with the default chunking axis (+Y), a robot whose first chunk is a right-hand
    one (``;@chunk R1``, ...) faces -Y and any other (centre ``C``, left ``L1``, ...) +Y; +Y when
    the program names no chunk."""
    at = np.flatnonzero(program.chunk >= 0)
    if len(at) and program.chunks[int(program.chunk[at[0]])].upper().startswith("R"):
        return -90.0
    return 90.0


def load_coop_files(paths: list[str | Path], settings: JobSettings | None = None) -> SimInput:
    """``.coop`` files without a manifest (the seed's own sample program simulates as written):
    each file is a robot named by its file name (``A.coop``: robot A), with the profile of
    ``settings`` (the defaults), starting at its first MOVE, facing as :func:`coop_facing` says."""
    settings = settings or load_settings()
    robots, names = [], {}
    stamp = fingerprint(paths)  # before the files are read
    for x in paths:
        p = Path(x)
        name = plain_name(p).stem  # A.coop and A.coop.gz: robot A
        if not ROBOT_NAME.fullmatch(name):
            raise SimInputError(f"{p}: the file name '{name[:40]}' is not a robot name (letters, digits, _ : . -; "
                                "at most 64); rename the file or use --manifest")
        if name in names:
            raise SimInputError(f"{p}: a second robot named '{name}' (also {names[name]}); rename one or use --manifest")
        names[name] = p
        program = read_coop(p, name)
        robots.append(SimRobot(name, program, None, _facing(coop_facing(program))))
    return SimInput(robots, settings.robot, settings.slicing, ", ".join(map(str, paths)), fingerprint=stamp)


def load_gcode_files(paths: list[str | Path], profile: RobotProfile | None = None,
                     slicing: SlicingSettings | None = None) -> SimInput:
    """Plain G-code files, one robot each (named by the file's stem). Nothing says where a
    robot's body stands, so the body checks are left out (``placed`` is false): the result is
    the timing, the material and the deadlock check."""
    stamp = fingerprint(paths)  # before the files are read
    robots = [read_gcode(p) for p in paths]
    names = [r.name for r in robots]
    if len(set(names)) != len(names):
        raise SimInputError(f"two G-code files with the same name: {', '.join(names)}")
    # a printer's G-code: PrusaSlicer's machine limits; no robot body stands anywhere known
    return SimInput(robots, profile or RobotProfile(), slicing or SlicingSettings(), ", ".join(map(str, paths)),
                    MachineLimits(), placed=False, notes=tuple(n for r in robots for n in r.notes), fingerprint=stamp)


def read_gcode(path: str | Path, filament_diameter: float = 1.75) -> SimRobot:
    """A Marlin-flavour G-code file as a program: ``G0``/``G1`` moves (``G90``/``G91``,
    ``M82``/``M83``, ``G92``), moves that push filament become moves with the tool on (width
    from the filament pushed, height from the layer), ``F`` gives each move's speed, and each
    move keeps its E (a move that only moves the filament, a retraction, takes ``|E| / F``).

    Host lines (docs/program.md): ``M118 NOTIFY e`` is a NOTIFY of event ``e`` and ``M0 WAIT e, f``
    a WAIT for ``e`` and ``f``, as in a ``.coop`` file, so that the robots' own G-code files
    simulate together; any other ``M0``/``M1`` (a pause for an operator) is ignored and noted.

    A compiled sweep (:mod:`cooprint.simulation.gcode`) reads files whose lines are all in the
    plain form (a slicer's output); any other file is read line by line (``_read_gcode_lines``,
    the reference, which also words the errors)."""
    from cooprint.simulation.gcode import gcode_rows  # numba: on first use

    p = Path(path)
    regular_file(p, "G-code file", SimInputError)  # a FIFO would block the read for ever
    try:
        data = map_input(p, SimInputError)  # mapped, not copied (decompressed if gzip)
    except FileNotFoundError:
        raise SimInputError(f"{p}: no such G-code file") from None
    except IsADirectoryError:
        raise SimInputError(f"{p}: a folder, not a G-code file") from None
    except OSError as exc:
        raise SimInputError(f"{p}: cannot read ({exc.strerror or exc})") from None
    try:
        rows = gcode_rows(data, filament_diameter, str(p))
        if rows is None:
            return _read_gcode_lines(p, _gcode_text(bytes(data)), filament_diameter)
    finally:
        release(data)
    prog = make_program(plain_name(p).stem, rows.kind, rows.xyz if len(rows.kind) else None,
                        role=rows.role, width=rows.width, height=rows.height,
                        events=rows.events)
    # homed: at 0, 0, 0; a move that only pushes or pulls filament takes |E| / F
    return SimRobot(plain_name(p).stem, prog, np.zeros(3), _facing(90.0), rows.speed, rows.de, _notes(p, rows.pauses))


def _notes(p: Path, pauses: list[int]) -> tuple[str, ...]:
    from cooprint.simulation.gcode import pause_note

    return (pause_note(str(p), pauses),) if pauses else ()


def _gcode_text(data: bytes) -> str:
    """The text of a G-code file's bytes, as ``Path.read_text(encoding="utf-8", errors="replace")``
    gives it (universal newlines)."""
    return io.TextIOWrapper(io.BytesIO(data), encoding="utf-8", errors="replace").read()


def _read_gcode_lines(p: Path, text: str, filament_diameter: float = 1.75) -> SimRobot:
    """:func:`read_gcode` of the text of G-code file ``p``, line by line: the reference of the
    compiled sweep, and the reader of the files it does not take (and of their errors)."""
    from cooprint.simulation.gcode import HOST_WORDS, host_line, type_role

    fil_area = math.pi * (filament_diameter / 2) ** 2
    pos = np.zeros(3)
    rel_xyz, rel_e, e = False, False, 0.0  # Marlin's defaults: absolute XYZ and E
    feed = 1500.0 / 60.0
    kinds, xyz, speeds, widths, heights, pushed, roles = [], [], [], [], [], [], []
    events, pauses = [], []
    tool, role = False, INFILL  # the role of the ;TYPE: comment in force
    layer_z, layer_h = 0.0, 0.2  # the height of the last layer that deposited, and its thickness
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = raw.split(";", 1)[0].strip()
        if not line:
            if raw.lstrip(" \t").startswith(";TYPE:"):
                role = type_role(raw.lstrip(" \t")[6:].split(";", 1)[0])
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
            if max(abs(float(target.max())), abs(float(target.min())), abs(de)) > COORD_LIMIT:
                raise SimInputError(f"{p}:{lineno}: a position or E step beyond +-{COORD_LIMIT:g} mm "
                                    f"(X{target[0]:g} Y{target[1]:g} Z{target[2]:g}, E step {de:g})")
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
            roles.append(role)
            xyz.append(tuple(target))
            speeds.append(feed)
            # the width whose flow cross-section (flow_area, by role) carries the filament pushed
            area = de * fil_area / length if deposit else 0.0
            widths.append(0.0 if not deposit else float(round_width(area)) if role in ROUND_ROLES
                          else float(extrusion_width(area, layer_h)))
            heights.append(layer_h if deposit else 0.0)
            pushed.append(de)
            pos = target
        elif code in ("G90", "G91"):
            rel_xyz = code == "G91"
        elif code in ("M82", "M83"):
            rel_e = code == "M83"
        elif code in HOST_WORDS:
            got = host_line(line, f"{p}:{lineno}")
            if isinstance(got, str):
                pauses.append(lineno)
            elif got is not None:
                kinds.append(got[0])
                events.append(got[1])
                xyz.append((np.nan,) * 3)
                speeds.append(0.0)
                widths.append(0.0)
                heights.append(0.0)
                pushed.append(0.0)
    kind = np.array(kinds, dtype=np.uint8)
    role_col = np.full(len(kind), TRAVEL, np.uint8)
    role_col[kind == MOVE] = roles
    prog = make_program(plain_name(p).stem, kind, np.array(xyz).reshape(-1, 3) if xyz else None,
                        role=role_col, width=np.array(widths),
                        height=np.array(heights), events=tuple(events))
    speed = np.array(speeds)
    # homed: at 0, 0, 0; a move that only pushes or pulls filament takes |E| / F
    return SimRobot(plain_name(p).stem, prog, np.zeros(3), _facing(90.0), speed, np.array(pushed), _notes(p, pauses))


GCODE_SUFFIXES = (".gcode", ".gco", ".g")


def load_inputs(paths: list[str], manifest: str | None = None, settings: JobSettings | None = None,
                programs: bool = True) -> SimInput:
    """A bundle folder (alone), ``.coop`` files with or without a manifest, or G-code files.
    ``.coop`` and G-code files are not mixed: a G-code file's robot stands nowhere known and
    moves at its file's feed rates, a ``.coop`` robot at its speeds per path role where it is placed;
    simulating both kinds together would compare two different time and body models. ``settings``
    (``--robot``/``--config``) give the profile of ``.coop`` and G-code robots. ``programs=False``:
    a bundle's programs are left to be read piece by piece (:func:`load_bundle`)."""
    found = {x: path_kind(x, SimInputError) for x in paths}  # file, folder, missing or other
    if settings is not None and (manifest or "folder" in found.values()):
        raise SimInputError("--robot/--config apply to .coop and G-code files; a bundle or a manifest "
                            "carries its own settings")
    if manifest:
        if paths:
            raise SimInputError(f"--manifest {manifest} names the programs; give no input files with it "
                                f"(got {paths[0]})")
        return load_manifest(manifest)
    dirs = [x for x in paths if found[x] == "folder"]
    if dirs:
        if len(paths) > 1:
            raise SimInputError(f"{dirs[0]}: a bundle folder is simulated alone (one bundle at a time), "
                                 "not with other inputs")
        return load_bundle(paths[0], programs)
    missing = [x for x in paths if found[x] == "missing"]
    if missing:
        raise SimInputError(f"{missing[0]}: no such file or folder")
    suffix = {x: plain_name(x).suffix.lower() for x in paths}  # (of A.gcode.gz: .gcode)
    kinds = {x: ("gcode" if suffix[x] in GCODE_SUFFIXES else "coop" if suffix[x] == ".coop" else None) for x in paths}
    other = [x for x, k in kinds.items() if k is None]
    if other:
        raise SimInputError(f"{other[0]}: expected a bundle folder, G-code files (.gcode) or .coop files")
    if len(set(kinds.values())) > 1:
        raise SimInputError("both .coop and G-code files given: simulate one kind at a time (a G-code robot "
                            "stands nowhere known and runs at its feed rates, a .coop robot is placed)")
    if len({str(Path(x).resolve()) for x in paths}) != len(paths):
        raise SimInputError("the same file given twice: each file is one robot")
    if set(kinds.values()) == {"gcode"}:
        return load_gcode_files(list(paths), *((settings.robot, settings.slicing) if settings else ()))
    return load_coop_files(list(paths), settings)


__all__ = ["BUNDLE_ROBOT_OPTIONAL", "BUNDLE_ROBOT_REQUIRED", "ChunkMesh", "DEP_KEYS", "ScheduleEstimate", "SimInput",
           "SimInputError", "check_settings", "coop_facing",
           "load_bundle", "load_coop_files", "load_gcode_files", "load_inputs", "load_manifest", "read_chunk_meshes",
           "read_gcode"]
