"""How big, how heavy and how long a ``cooprint run`` will be, told before the heavy work.

After chunking and before slicing, :func:`estimate_job` turns the chunk meshes and the slicing
settings into the expected output size (each robot's ``.coop`` and G-code, the chunk STLs), the
peak memory and the time of the rest of the run, so that ``cooprint run`` can say what is coming
(``estimate: 1.3 GB of output (A 640 MB, B 610 MB), about 1.1 GB of memory, about 2 min on 2
cores``) and refuse a run whose output cannot fit on the disk before spending an hour on it.

The model follows the slicer's geometry, each term a count that is cheap to take from a chunk's
triangles (:func:`chunk_features`):

* **section vertices** ``crossings``: a layer's section has one vertex per triangle the layer's
  plane crosses, so over all layers ``sum(z extent of each triangle) / layer height``; every
  perimeter loop repeats them (``perimeters x crossings`` MOVEs; curved parts have many);
* **loops** ``perimeters x layers``: each loop costs a travel, TOOL ON / OFF and annotations,
  however few its vertices (a box's quadrilaterals);
* **fill lines**: the area to fill over all layers (``volume / layer height`` less the perimeter
  band), solid where the skins are (the up- and down-facing area times the top / bottom layer
  counts), sparse (``infill_density``) elsewhere, as a length of lines ``area / extrusion
  width``, divided by the mean line length (the chord ``2 x volume / lateral area``: the width of
  a box's section, the thickness of a thin wall); each line is a few commands;
* **layers**: per-layer annotations and the travel to the layer's start.

``commands = VERTEX x perimeters x crossings + LOOP x perimeters x layers + LINE x fill lines +
LAYER x layers``, per chunk, summed over each robot's chunks; bytes are bytes per command of each
format; the STLs are exact (84 + 50 bytes per triangle). Time is a fixed start plus slicing
(per layer and per command, on ``cores`` processes) plus programs and writing (per command, one
core). Memory is the interpreter and libraries plus what a run holds per command: of the whole
job (today's ``coop_job`` keeps every chunk's layers and both programs until the files are
written) and of the largest chunks in flight (a streamed run holds only those).

Calibration (``benchmarks/calibrate_estimates.py``, which runs the same work as ``cooprint run``
under ``/usr/bin/time -v`` and fits these constants by least squares; re-run it after a change
of the slicer, the program builder or the writers, and paste its output into
:data:`CALIBRATION`): see :data:`CALIBRATION`'s comment for the parts, the machine and the error.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Sequence

import numpy as np

if TYPE_CHECKING:
    from cooprint.chunking import ChunkSet
    from cooprint.config import JobSettings, SlicingSettings


@dataclass(frozen=True)
class Calibration:
    """The fitted constants of the model (see the module docstring for the terms).

    Commands per feature: ``vertex`` (per perimeter-loop vertex), ``loop`` (per loop), ``line``
    (per fill line), ``layer`` (per chunk layer). Bytes per command: ``coop_bytes``,
    ``gcode_bytes``. Seconds: ``start_s`` (fixed: start-up, scheduling, picture, job.json),
    ``slice_layer_s`` and ``slice_command_s`` (slicing wall time with ``slice_cores``
    processes, scaled by ``slice_cores / cores`` for another count), ``program_command_s``
    (programs), ``write_command_s`` (writing the two files of each command). Bytes of memory:
    ``memory_base`` (interpreter, libraries, the part), ``memory_job_command`` (per command of the
    whole job held at once), ``memory_chunk_command`` (per command of a chunk in flight)."""

    vertex: float
    loop: float
    line: float
    layer: float
    coop_bytes: float
    gcode_bytes: float
    start_s: float
    slice_layer_s: float
    slice_command_s: float
    program_command_s: float
    write_command_s: float
    slice_cores: int
    memory_base: float
    memory_job_command: float
    memory_chunk_command: float


#: Fitted by ``benchmarks/calibrate_estimates.py`` on 2026-12-02, first on main ddd6d9a (every
#: chunk's layers and both programs held until the files were written), then again on the
#: streamed run (main after the merge of issue 15's parts: chunks spooled as they are sliced,
#: the files written piece by piece by the fast writers), on this machine (2 cores shared with
#: other jobs: the times are noisy), two robots each, from the runs of seven generated parts:
#: boxes 300 x 600 x 40, 200 x 1200 x 100 and 150 x 400 x 250 mm, a hollow box 400 x 600 x 120
#: mm with 10 mm walls, the car (``cooprint.models.car_manifold(700)``) with the default profile,
#: and a 600 x 1200 x 200 mm box and a 1500 mm car with a 1.0 mm nozzle, 0.6 mm layers, 1.1 mm
#: lines. Commands per robot within -13% .. +4% of the runs' (the hollow box the worst: its thin
#: walls' fill lines are longer than the chord assumes); the bundle's bytes within -15% .. +5%;
#: the loop and layer terms fitted to 0 (a box's loops are few beside its fill lines; the
#: simplified sections have fewer vertices than triangle crossings: ``vertex`` 0.24). Streamed,
#: the peak memory fits the largest chunks in flight (rms 9.0%: 189 MB and 74 bytes a command
#: of the three largest chunks) better than the whole job (rms 13.1%), so
#: ``memory_job_command`` is 0; the programs' stage takes no time of its own any more (a chunk's
#: commands are made as it arrives, inside the slicing stage); writing 1.5 µs a command. The
#: first fit (whole job held) was checked on the 600 x 4000 x 400 mm beam's bundle of that
#: revision (``--check``: 47.4 M commands, 2.44 GB, 8 min 59 s, 10.2 GB peak): commands +5%,
#: bytes +1%. Fitted again for issue 17's slicer (main 2026-12-02 after the regions merge: sparse
#: lines joined along the perimeters, so fewer and longer; solid spacing fitted per region; gap
#: fill, bridges), the same seven parts on the same loaded machine, then again once solid lines
#: were joined along their boundaries too (more commands per line on curved parts: the car's were
#: 1.55x the estimate): commands per robot within -11.7% .. +4.7% (the hollow box again the
#: worst), bytes -13% .. +6%, peak memory rms 4.0% (chunks in flight).
CALIBRATION = Calibration(
    vertex=0.418, loop=0.0, line=3.301, layer=0.0,
    coop_bytes=29.99, gcode_bytes=30.01,
    start_s=0.25, slice_layer_s=0.000943, slice_command_s=2.45e-06, program_command_s=2.36e-09,
    write_command_s=1.2e-06, slice_cores=2,
    memory_base=193e6, memory_job_command=0.0, memory_chunk_command=75.8,
)

#: Bytes of ``job.json`` per chunk (its row: bbox, planes, deps, times) and fixed (settings,
#: schedule), and of ``chunks.png``: small beside the programs, counted so that a tiny job's
#: estimate is not zero.
JSON_CHUNK_BYTES, JSON_BYTES, PICTURE_BYTES = 2500, 8000, 120_000


@dataclass(frozen=True)
class ChunkFeatures:
    """The counts of one chunk the model is made of (module docstring)."""

    id: str
    layers: float
    crossings: float
    loops: float
    fill_lines: float
    triangles: int

    def commands(self, c: Calibration) -> float:
        """Expected commands of this chunk's paths."""
        return (c.vertex * self.loops / max(self.layers, 1.0) * self.crossings + c.loop * self.loops
                + c.line * self.fill_lines + c.layer * self.layers)


def chunk_features(vertices: np.ndarray, faces: np.ndarray, s: "SlicingSettings", cid: str = "") -> ChunkFeatures:
    """:class:`ChunkFeatures` of a closed triangle mesh sliced with ``s``.

    ``crossings`` counts the vertices of a single loop over all layers (the vertex term
    multiplies them by ``perimeters``, through ``loops / layers``)."""
    v = np.asarray(vertices, dtype=np.float64)
    tri = v[np.asarray(faces, dtype=np.int64)]
    h = float(s.layer_height)
    w = float(s.extrusion_width)
    zmin, zmax = (float(v[:, 2].min()), float(v[:, 2].max())) if len(v) else (0.0, 0.0)
    height = max(zmax - zmin, 0.0)
    layers = max(math.ceil(height / h - 1e-9), 1) if height > 0 else 0
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area2 = np.linalg.norm(cross, axis=1)  # twice each triangle's area
    area = 0.5 * area2
    nz = np.divide(cross[:, 2], area2, out=np.zeros(len(area2)), where=area2 > 0)
    volume = abs(float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum()) / 6.0)
    lateral = float((area * np.sqrt(np.clip(1.0 - nz ** 2, 0.0, 1.0))).sum())
    up = float((area * np.clip(nz, 0.0, None)).sum())
    down = float((area * np.clip(-nz, 0.0, None)).sum())
    crossings = float(np.ptp(tri[:, :, 2], axis=1).sum() / h) if len(tri) else 0.0
    section = volume / h  # the sections' area summed over the layers, mm^2
    band = min(s.perimeters * w * lateral / h, section)
    skin = min(up * s.top_layers + down * s.bottom_layers, section - band)
    sparse = max(section - band - skin, 0.0)
    length = (skin + s.infill_density * sparse) / w  # mm of fill lines
    chord = max(2.0 * volume / lateral if lateral > 0 else math.sqrt(max(volume / max(height, h), 0.0)), w)
    return ChunkFeatures(cid, float(layers), crossings, float(s.perimeters * layers), length / chord, int(len(faces)))


#: Bytes a command of a chunk's program takes in the spool (its columns: kind 1, xyz 24, role 1,
#: width 8, layer 4, height 8, chunk 2, event 4; :class:`cooprint.program.stream.ChunkStore`).
PROGRAM_BYTES = 52
#: A program's compressed size over its text's (``--compress``, gzip level 2), measured on
#: 2026-12-02: 0.14 on the 420 mm car, 0.16 on a 300 x 2000 x 40 mm box (two robots each).
COMPRESSED = 0.16


@dataclass(frozen=True)
class JobEstimate:
    """What a run is expected to write, hold and take (:func:`estimate_job`).

    ``robot_bytes``: each robot's ``.coop`` + G-code; ``chunk_bytes``: the chunk STLs, job.json
    and the picture; ``memory_bytes``: the peak resident memory; ``seconds``: from the estimate
    to the end of writing, on ``cores`` processes."""

    robot_bytes: dict[str, int]
    chunk_bytes: int
    commands: dict[str, int]
    memory_bytes: int
    seconds: float
    cores: int
    features: tuple[ChunkFeatures, ...] = field(default=(), repr=False)

    @property
    def bytes(self) -> int:
        """The whole bundle, bytes."""
        return sum(self.robot_bytes.values()) + self.chunk_bytes

    @property
    def spool_bytes(self) -> int:
        """The chunks' commands spooled in the bundle's temporary folder while it is written
        (``PROGRAM_BYTES`` a command; removed before the bundle is complete): the disk a run
        needs is this and the bundle."""
        return int(PROGRAM_BYTES * sum(self.commands.values()))

    def compressed(self) -> "JobEstimate":
        """The same run with ``--compress``: the programs gzip-compressed (``COMPRESSED`` of their
        size)."""
        return replace(self, robot_bytes={r: int(b * COMPRESSED) for r, b in self.robot_bytes.items()})

    def describe(self, robots_shown: int = 6) -> str:
        """One line: ``estimate: 1.3 GB of output (A 640 MB, B 610 MB), about 1.1 GB of memory,
        about 2 min on 2 cores`` (the largest robots first when there are many)."""
        busy = [(r, b) for r, b in self.robot_bytes.items() if self.commands.get(r, 0) > 0]
        if len(busy) > robots_shown:
            busy = sorted(busy, key=lambda rb: -rb[1])[:robots_shown]
            more = f", {len(self.robot_bytes) - robots_shown} more"
        else:
            more = ""
        per = ", ".join(f"{r} {human_bytes(b)}" for r, b in busy)
        return (f"estimate: {human_bytes(self.bytes)} of output" + (f" ({per}{more})" if per else "")
                + f", about {human_bytes(self.memory_bytes)} of memory, about {human_seconds(self.seconds)} "
                f"on {self.cores} core{'s' if self.cores != 1 else ''}")


def human_bytes(n: float) -> str:
    """``640 MB``, ``1.3 GB``, ``12 kB`` (decimal units, as ``du --si`` and disk makers)."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            value = n / scale
            return f"{value:.1f} {unit}" if value < 10 else f"{value:.0f} {unit}"
    return f"{int(n)} B"


def human_seconds(s: float) -> str:
    """``40 s``, ``2 min``, ``1.5 h``."""
    if s < 90:
        return f"{max(s, 1):.0f} s"
    if s < 5400:
        return f"{s / 60:.0f} min"
    return f"{s / 3600:.1f} h"


def default_cores() -> int:
    """The slicing processes a run uses: one per CPU it may run on, at most 4 (the slicer's pool)."""
    try:
        n = len(os.sched_getaffinity(0))
    except AttributeError:
        n = os.cpu_count() or 1
    return max(1, min(n, 4))


def estimate_job(chunks: "ChunkSet", settings: "JobSettings", robots: Mapping[str, Sequence[str]] | int,
                 *, cores: int | None = None, in_flight: int | None = None,
                 calibration: Calibration | None = None) -> JobEstimate:
    """The expected output size, peak memory and time of slicing, programming and writing
    ``chunks`` with ``settings`` (a pure function of its arguments).

    ``robots``: each robot's chunk ids in order (the schedule's sequences: the robots' files are
    estimated one by one), or a robot count (the chunks spread evenly). ``cores``: slicing
    processes (default: :func:`default_cores`). ``in_flight``: chunks held at once by a streamed
    run (default ``cores + 1``)."""
    c = calibration or CALIBRATION
    s = settings.slicing
    cores = cores or default_cores()
    in_flight = in_flight or cores + 1
    feats = tuple(chunk_features(ch.vertices, ch.faces, s, ch.id) for ch in chunks.chunks)
    per_chunk = {f.id: f.commands(c) for f in feats}
    if isinstance(robots, int):
        from cooprint.jobs import robot_names

        names = robot_names(max(robots, 1))
        share = sum(per_chunk.values()) / len(names)
        commands = {r: share for r in names}
    else:
        commands = {r: sum(per_chunk.get(cid, 0.0) for cid in seq) for r, seq in robots.items()}
        missing = set(per_chunk) - {cid for seq in robots.values() for cid in seq}
        if missing and commands:  # chunks not (yet) assigned: counted on the first robot
            first = next(iter(commands))
            commands[first] += sum(per_chunk[cid] for cid in missing)
    total = sum(commands.values())
    robot_bytes = {r: int(round(n * (c.coop_bytes + c.gcode_bytes))) for r, n in commands.items()}
    chunk_bytes = sum(84 + 50 * f.triangles for f in feats) + JSON_BYTES + JSON_CHUNK_BYTES * len(feats) \
        + PICTURE_BYTES
    largest = sorted(per_chunk.values(), reverse=True)[:in_flight]
    memory = c.memory_base + c.memory_job_command * total + c.memory_chunk_command * sum(largest)
    layers = sum(f.layers for f in feats)
    slicing = (c.slice_layer_s * layers + c.slice_command_s * total) * c.slice_cores / cores
    seconds = c.start_s + slicing + (c.program_command_s + c.write_command_s) * total
    return JobEstimate({r: int(b) for r, b in robot_bytes.items()}, int(chunk_bytes),
                       {r: int(round(n)) for r, n in commands.items()}, int(memory), float(seconds), cores, feats)


def features_matrix(feats: Iterable[ChunkFeatures]) -> np.ndarray:
    """The four command terms of :meth:`ChunkFeatures.commands` summed over ``feats``:
    ``[perimeter vertices, loops, fill lines, layers]`` (the calibration's regressors)."""
    rows = [[f.loops / max(f.layers, 1.0) * f.crossings, f.loops, f.fill_lines, f.layers] for f in feats]
    return np.asarray(rows, dtype=np.float64).reshape(-1, 4).sum(axis=0)


def with_calibration(**changes: Any) -> Calibration:
    """:data:`CALIBRATION` with some constants changed (tests, a refit)."""
    return replace(CALIBRATION, **changes)


#: A run is refused when this fraction of its estimated output exceeds the free space: the
#: estimate is within about 20% on the calibration parts, and a run that might just fit is
#: let through (the writers still stop with a clear error on a full disk).
ROOM_FRACTION = 0.8


def check_room(out: "str | os.PathLike[str]", estimate: JobEstimate) -> None:
    """Raise :class:`~cooprint.errors.OutputError` (one line) when the file system of ``out``
    (or of its nearest existing parent) has less free space than :data:`ROOM_FRACTION` of the
    estimated output and spool; nothing when the free space cannot be told."""
    import shutil
    from pathlib import Path

    from cooprint.errors import OutputError

    here = Path(os.path.abspath(out))
    while not here.exists() and here != here.parent:
        here = here.parent
    try:
        free = shutil.disk_usage(here).free
    except OSError:
        return
    if ROOM_FRACTION * (estimate.bytes + estimate.spool_bytes) > free:
        raise OutputError(f"{out}: this run is estimated to write {human_bytes(estimate.bytes)} and to spool "
                          f"{human_bytes(estimate.spool_bytes)} of chunk commands beside it meanwhile, only "
                          f"{human_bytes(free)} free on its file system; free some space or choose another --out")
