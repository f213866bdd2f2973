"""Jobs: the pipeline stages chained for one purpose, and the records they write.

``chunk_job`` runs mesh -> chunker -> scheduler; ``write_chunk_bundle`` writes the chunk part of
the output bundle (``job.json``, ``chunks/<id>.stl``, ``chunks.png``) atomically. The CLI and the
Python API both call these.
"""

from __future__ import annotations

import os
from contextlib import closing
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable, Iterator, Mapping, Sequence

import numpy as np

from cooprint.config import JobSettings, SlicingSettings, load_settings
from cooprint.errors import UserError, warn
from cooprint.io.bundle import atomic_dir, open_output, program_files, write_json, write_stl
from cooprint.io.mesh import Solid, load_mesh
from cooprint.io.place import Placement, place

if TYPE_CHECKING:  # the chunker and the scheduler are imported where they run: `slice` needs neither
    from cooprint.chunking import ChunkSet
    from cooprint.scheduling import Assignment, Schedule
    from cooprint.io.estimate import JobEstimate
    from cooprint.scheduling import ChunkDAG
    from cooprint.slicing import SlicedModel

#: ``progress(stage, done, total)``: called as work advances.
Progress = Callable[[str, int, int], None]


def robot_names(n: int) -> tuple[str, ...]:
    """``A``, ``B``, ... ``Z``, then ``R27``, ``R28``, ..."""
    return tuple(chr(ord("A") + i) if i < 26 else f"R{i + 1}" for i in range(n))


#: The most robots a fleet may have (``--robots``).
MAX_ROBOTS = 64
#: Up to this many robots, :func:`_fleet_plan` tries every smaller fleet too.
FLEET_TRIALS = 9


@dataclass(frozen=True)
class ChunkJob:
    """A chunked and scheduled object: the chunker's and scheduler's output together.

    ``assignment`` is a :class:`~cooprint.scheduling.Schedule` (the sequences and their nominal
    times); ``dag`` the constraints it was made under (issue 14)."""

    solid: Solid
    settings: JobSettings
    chunks: ChunkSet
    assignment: Assignment
    placement: Placement | None = None
    dag: "ChunkDAG | None" = None


def load_placed(mesh: str | Path | Solid, settings: JobSettings, *, bed: bool = False,
                center: Sequence[float] | None = None, note: bool = True) -> tuple[Solid, Placement]:
    """Load (unless given a Solid), scale and place the part (:mod:`cooprint.io.place`): on the
    floor, and with ``bed`` centred on the bed (``cooprint slice``). The slicing settings are
    checked against each other here too (settings made in Python skip :func:`load_settings`).
    ``note``: say on stderr what the loader repaired (:func:`note_repairs`; `info` lists it in
    its report instead)."""
    from cooprint.config.settings import check_slicing

    check_slicing(settings.slicing)
    if isinstance(mesh, Solid):
        return place(mesh, settings.mesh, settings.slicing, bed=bed, center=center)
    solid = load_mesh(mesh, settings.mesh)
    if note:
        note_repairs(solid)
    return place(solid, settings.mesh, settings.slicing, bed=bed, center=center, own=True)


def note_repairs(solid: Solid) -> None:
    """One line on stderr listing what the loader repaired (counts), when it changed the
    surface: a part sliced from a repaired mesh is not quite the file's (merging duplicate
    vertices changes nothing and is not listed)."""
    import sys

    done = [r for r in solid.report.repairs if not r.startswith("merged ")]
    if done:
        print(f"cooprint: note: {solid.report.path}: repaired: {'; '.join(done)}", file=sys.stderr, flush=True)


def chunk_job(mesh: str | Path | Solid, settings: JobSettings | None = None, robots: int = 2,
              progress: Progress | None = None) -> ChunkJob:
    """Load (unless given a Solid), plan, cut and assign.

    Parameters
    ----------
    mesh
        A mesh file path or an already loaded :class:`Solid`.
    settings
        Defaults to the shipped defaults.
    robots
        Number of robots (the seed strategy: 1 or 2).
    """
    settings = settings or load_settings()
    solid, placement = _load_with_progress(mesh, settings, progress)
    return _chunk_placed(solid, placement, settings, robots, progress)


def _load_with_progress(mesh: str | Path | Solid, settings: JobSettings,
                        progress: Progress | None) -> tuple[Solid, Placement]:
    """:func:`load_placed` on the floor, as the ``load`` stage of the progress bars (in bytes of
    the file: the bar shows MB/s)."""
    size = os.path.getsize(mesh) if not isinstance(mesh, Solid) and os.path.isfile(mesh) else 1
    if progress:
        progress("load", 0, size)
    solid, placement = load_placed(mesh, settings)
    if progress:
        progress("load", size, size)
    return solid, placement


def _chunk_placed(solid: Solid, placement: Placement, settings: JobSettings, robots: int,
                  progress: Progress | None, preliminary: bool = False) -> ChunkJob:
    """Lay out (:func:`choose_layout`), cut and schedule a placed solid; the chunks' work is
    estimated from their volume here. ``preliminary``: :func:`coop_job` schedules again from the
    sliced paths, so an exact schedule is left for then (a list schedule stands in)."""
    from cooprint.chunking.planes import safe_top_width
    from cooprint.scheduling.graph import work_from_volume

    if not 1 <= robots <= MAX_ROBOTS:
        raise UserError(f"--robots {robots}: expected 1 to {MAX_ROBOTS}")
    cut_progress = (lambda d, t: progress("cut", d, t)) if progress else None
    chunks = choose_layout(solid, settings, robots, cut_progress)
    if chunks.layout == "seed2" and settings.chunking.column_width is not None:
        warn(f"chunking.column_width = {settings.chunking.column_width:g} mm is for the grid layout; the seed2 "
             "layout has no columns (--layout grid uses it)")
    if chunks.layout == "seed2":
        safe = safe_top_width(settings.robot, robots)
        if chunks.plan.mode == "cut" and chunks.plan.top_width < safe:
            warn(f"chunking.top_width = {chunks.plan.top_width:g} mm is narrower than the two printheads "
                 f"(2 x robot.nozzle_depth = {safe:g} mm): the robots printing the centre chunk's two neighbours "
                 "may meet near its top (the simulator's robots-collide says whether they do)")
    if progress:
        progress("schedule", 0, len(chunks.chunks))
    dag = chunk_dag(chunks, settings, work_from_volume(chunks, settings.robot, settings.slicing))
    quick = settings
    if preliminary and settings.scheduling.strategy == "exact":
        quick = replace(settings, scheduling=replace(settings.scheduling, strategy="list"))
    sched = make_schedule_for(dag, chunks, quick, robots)
    if progress:
        progress("schedule", len(chunks.chunks), len(chunks.chunks))
    return ChunkJob(solid, settings, chunks, sched, placement, dag)


def chunk_dag(chunks: ChunkSet, settings: JobSettings, work: dict[str, float],
              ends: dict[str, tuple[np.ndarray, np.ndarray]] | None = None) -> "ChunkDAG":
    """The scheduling record of ``chunks`` (:func:`cooprint.scheduling.graph.build_dag`): the
    precedences, the body rule and the exclusions for this robot, with ``work`` (s per chunk).

    Two chunks are exclusive when their robots' outlines come closer than ``[program] clearance``:
    the margin the programs keep between robots (:mod:`cooprint.program.fleet` makes a robot wait
    wherever its outline would come nearer another's), so that the schedule knows the waits the
    programs will have."""
    from cooprint.program.gcode import Feeds
    from cooprint.scheduling.graph import build_dag

    travel = Feeds.of_robot(settings.robot, settings.slicing).travel  # the robots' travel between chunks
    return build_dag(chunks, settings.robot, settings.program.clearance, work, travel, ends)


def make_schedule_for(dag: "ChunkDAG", chunks: ChunkSet, settings: JobSettings, robots: int) -> Schedule:
    """Schedule ``dag`` for ``robots`` robots with the strategy of ``settings.scheduling``
    (``auto``: the seed's order for the seed2 layout, list scheduling otherwise)."""
    from cooprint.scheduling import make_schedule

    strategy = settings.scheduling.strategy
    if strategy == "auto":
        strategy = "seed" if chunks.layout == "seed2" else "list"
    if strategy == "seed" and chunks.layout != "seed2":
        raise UserError(f"scheduling.strategy = seed: the seed's order is for the seed2 layout, this is "
                        f"{chunks.layout}; use list or exact")
    if strategy == "seed":
        # the seed's builder (program.build.robot_programs) prints L1 and R1 side by side, their
        # printheads kept apart by the centre chunk's top width, not by a clearance: its times
        # know no exclusion
        dag = replace(dag, exclusive=())
    return make_schedule(dag, robot_names(robots), replace(settings.scheduling, strategy=strategy), chunks)


def choose_layout(solid: Solid, settings: JobSettings, robots: int,
                  progress: Callable[[int, int], None] | None = None) -> ChunkSet:
    """The chunk layout of ``settings.chunking.layout``; ``auto``: the seed's (seed2) for one or
    two robots when the part fits it (the issue's default), else the grid with the column width
    whose list schedule (volume-estimated work) finishes first."""
    from cooprint.chunking.layouts import LAYOUTS
    from cooprint.scheduling.graph import work_from_volume

    name = settings.chunking.layout
    if name != "auto":
        return LAYOUTS[name](solid, settings, robots, progress)
    if robots <= 2:  # the grid's rows are seed2's: a part seed2 refuses, the grid refuses too
        seed2 = LAYOUTS["seed2"](solid, settings, robots, progress)
        if robots == 1 or len(seed2.chunks) > 1:
            return seed2
        # seed2 leaves the second robot idle (the part fits the build depth: one chunk): the
        # grid's columns give it work, if the part is long enough for two
        try:
            grid = LAYOUTS["grid"](solid, settings, robots, None)
        except UserError:
            return seed2
        return grid if len(grid.chunks) > 1 else seed2
    if settings.chunking.column_width is not None:
        return LAYOUTS["grid"](solid, settings, robots, progress)
    best: tuple[float, ChunkSet] | None = None
    first = LAYOUTS["grid"](solid, settings, robots, progress)
    widths = [None] + _other_columns(first)
    for width in widths:
        try:
            chunks = first if width is None else LAYOUTS["grid"](
                solid, replace(settings, chunking=replace(settings.chunking, column_width=width)), robots, None)
        except UserError:
            continue
        dag = chunk_dag(chunks, settings, work_from_volume(chunks, settings.robot, settings.slicing))
        est = make_schedule_for(dag, chunks, replace(settings, scheduling=replace(settings.scheduling,
                                                                                  strategy="list")), robots)
        if best is None or est.makespan < best[0] * (1 - 1e-9):
            best = (est.makespan, chunks)
    assert best is not None
    return best[1]


def _other_columns(chunks: ChunkSet) -> list[float]:
    """Other column widths (half a period) for ``auto`` to weigh against the grid's default: the
    narrowest the robots' lane allows (more columns: more robots at work) and 1.5x and 2x the
    default (fewer, larger columns: less waiting on neighbours)."""
    columns = getattr(chunks.plan, "columns", None)
    if columns is None or not np.isfinite(columns.period):
        return []
    narrowest = (columns.lane + columns.run) * (1 + 1e-9)
    widths = [narrowest] if narrowest < columns.period / 2 * (1 - 1e-6) else []
    return widths + ([0.75 * columns.period, 1.0 * columns.period] if columns.count >= 3 else [])


def job_record(job: ChunkJob) -> dict[str, Any]:
    """The ``job.json`` content: settings, robots, chunk table (with each chunk's place, its
    constraints and its scheduled times), schedule (with the lower bound, the gap to it and the
    critical path), statistics."""
    from cooprint.scheduling import Schedule

    ch, asg = job.chunks, job.assignment
    rows = []
    axis = np.asarray(ch.plan.axis)
    dag = job.dag
    excl = dag.exclusive_with() if dag is not None else {}
    for c in ch.chunks:
        lo, hi = c.bounds
        row: dict[str, Any] = {
            "id": c.id, "role": c.role, "row": c.row, "col": c.col,
            "facing": None if c.facing is None else list(c.facing),
            "robot": asg.robot_of(c.id), "order": asg.order_of(c.id),
            "deps": list(ch.deps[c.id]), "volume_mm3": c.volume,
            "reach_mm": float(np.ptp(c.vertices @ axis)),
            "bbox": [lo.tolist(), hi.tolist()], "triangles": int(len(c.faces)),
            "planes": [p.to_dict() for p in c.planes], "file": f"chunks/{c.id}.stl",
        }
        if dag is not None:
            row |= {"body_deps": list(dag.body_deps.get(c.id, ())), "exclusive": sorted(excl[c.id]),
                    "work_s": float(dag.work[dag.index[c.id]])}
        if isinstance(asg, Schedule):
            row |= {"start_s": asg.start[c.id], "end_s": asg.end[c.id]}
        rows.append(row)
    rel = abs(ch.volume - ch.solid_volume) / ch.solid_volume
    schedule: dict[str, Any] = {
        "strategy": asg.strategy, "sequences": {r: list(s) for r, s in asg.sequences.items()},
        "sync": [{"after": b, "before": a} for b, a in asg.cross_robot_deps(ch.deps)]}
    if isinstance(asg, Schedule):
        schedule |= asg.to_dict()
    if dag is not None:
        length, path = dag.critical_path()
        schedule |= {"critical_path": list(path), "critical_path_s": length,
                     "total_work_s": float(dag.work.sum()), "exclusive_pairs": len(dag.exclusive)}
    return {
        "format": "cooprint-job/1",
        "mesh": job.solid.report.to_dict() | ({"placement": job.placement.to_dict()} if job.placement else {}),
        "settings": job.settings.to_dict(),
        "plan": ch.plan.to_dict() | {"layout": ch.layout},
        "robots": [{"name": r, "profile": job.settings.robot.name, "chunks": list(seq)}
                   for r, seq in asg.sequences.items()],
        "chunks": rows,
        "schedule": schedule,
        "stats": {"chunks": len(ch.chunks), "volume_mm3": ch.volume, "solid_volume_mm3": ch.solid_volume,
                  "volume_rel_error": rel},
    }


def write_chunk_bundle(job: ChunkJob, out: str | Path, force: bool = False, picture: bool = True,
                       progress: Progress | None = None) -> dict[str, Any]:
    """Write ``job.json``, ``chunks/<id>.stl`` and (``picture``) ``chunks.png`` into ``out``,
    atomically; with ``force`` an existing bundle's own files are replaced and the rest kept
    (:func:`cooprint.io.bundle.atomic_dir`). Returns the job record written to ``job.json``."""
    from cooprint.progress import ByteMeter

    out = Path(out)
    with atomic_dir(out, force, inputs=_input_paths(job.solid)) as tmp:
        (tmp / "chunks").mkdir()
        meter = ByteMeter(progress, sum(stl_bytes(c.faces) for c in job.chunks.chunks))
        for c in job.chunks.chunks:
            write_stl(tmp / "chunks" / f"{c.id}.stl", c.vertices, c.faces, name=c.id)
            meter.add(stl_bytes(c.faces))
        meter.finish()
        record = job_record(job)
        if picture:
            from cooprint.render.chunks import render_chunks

            if progress:
                progress("render", 0, 1)
            render_chunks(job.chunks, tmp / "chunks.png", schedule=job.assignment)  # by robot, as `run` draws it
            record["picture"] = "chunks.png"
            if progress:
                progress("render", 1, 1)
        write_json(tmp / "job.json", record)
    return record


def stl_bytes(faces: np.ndarray) -> int:
    """Size of a binary STL of ``faces``: 80-byte header, count, 50 bytes a triangle."""
    return 84 + 50 * len(faces)


def _input_paths(solid: Solid) -> tuple[str, ...]:
    """The mesh file a job was read from (an output folder must not hold it)."""
    path = getattr(solid.report, "path", None)
    return (path,) if isinstance(path, str) and os.path.exists(path) else ()


def _check_work(solid: Solid, s: SlicingSettings) -> None:
    """Refuse a part whose slicing would ask for unbounded work (:func:`~cooprint.config.settings.work_estimate`)."""
    from cooprint.config.settings import work_estimate

    work_estimate(np.ptp(solid.bounds, axis=0), solid.volume, s)


def _placed_on_bed(mesh: str | Path | Solid, settings: JobSettings,
                   center: Sequence[float] | None) -> tuple[Solid, Placement]:
    """A part loaded and placed on a single printer's bed (at ``center``, default the bed
    centre), checked against its build volume and the work it asks for."""
    solid, placement = load_placed(mesh, settings, bed=True, center=center)
    check_build_volume(solid, settings.slicing)
    _check_work(solid, settings.slicing)
    return solid, placement


def check_build_volume(solid: Solid, s: SlicingSettings) -> None:
    """Refuse a model that does not fit the single printer's build volume, naming both sizes."""
    size = np.ptp(solid.bounds, axis=0)
    box = np.array([s.build_x, s.build_y, s.build_z])
    if (size > box + 1e-9).any():
        raise UserError(f"{solid.report.path}: the model is {size[0]:.1f} x {size[1]:.1f} x {size[2]:.1f} mm, "
                        f"larger than the build volume {box[0]:g} x {box[1]:g} x {box[2]:g} mm "
                        "([slicing] build_x, build_y, build_z)")


def slice_job(mesh: str | Path | Solid, settings: JobSettings | None = None,
              progress: Progress | None = None, center: Sequence[float] | None = None) -> tuple[Solid, "SlicedModel"]:
    """Load (unless given a Solid), place on the bed (at ``center``, default the bed centre) and
    slice a whole model for one printer."""
    from cooprint.slicing import slice_solid

    settings = settings or load_settings()
    solid, _ = _placed_on_bed(mesh, settings, center)
    layer_progress = (lambda d, t: progress("slice", d, t)) if progress else None
    return solid, slice_solid(solid, settings.slicing, layer_progress)


def slice_to_gcode(mesh: str | Path, out: str | Path, settings: JobSettings | None = None,
                   progress: Progress | None = None, force: bool = False,
                   center: Sequence[float] | None = None,
                   placed: Callable[[Placement], None] | None = None, executor: Any = None) -> tuple[int, float]:
    """Load, place on the bed (at ``center``, default the bed centre: PrusaSlicer's
    ``--center``), slice and write G-code to ``out`` atomically, layer block by layer block (the
    model is never held whole); return the number of layers and the filament used, mm.
    ``placed(placement)`` is told where the part was put before the slicing starts; ``executor``:
    where the blocks of layers are sliced (:func:`cooprint.slicing.iter_layers`)."""
    from cooprint.io.bundle import atomic_file
    from cooprint.program.build import layer_pieces
    from cooprint.program.gcode import Feeds, write_gcode
    from cooprint.slicing import iter_layers

    settings = settings or load_settings()
    solid, placement = _placed_on_bed(mesh, settings, center)
    if placed:
        placed(placement)
    layer_progress = (lambda d, t: progress("slice", d, t)) if progress else None
    layers = iter_layers(solid, settings.slicing, layer_progress, executor=executor)
    counted = _Counted(layers)
    del solid  # iter_layers keeps only what slicing needs, not the whole Solid
    s = settings.slicing
    # closing: on any failure (Ctrl-C included) the slicer's worker processes stop now, not
    # whenever the generator is collected
    with closing(layers), atomic_file(out, force, inputs=(mesh,)) as tmp, open_output(tmp) as fh:
        used = write_gcode(fh, layer_pieces(counted), s, Feeds.of_slicer(s), Path(mesh).name)
    if used <= 0:  # valid, but surely not what was meant: a part thinner than one line everywhere
        from cooprint.errors import warn

        warn(f"{mesh}: nothing to print: no layer holds a line {s.extrusion_width:g} mm wide (the part is thinner "
             f"than a line); the G-code only moves")
    return counted.n, used


class _Counted:
    """An iterable of layers that counts the non-empty ones that went through it."""

    def __init__(self, items: Iterable[Any]):
        self.items, self.n = items, 0

    def __iter__(self) -> Iterator[Any]:
        for item in self.items:
            self.n += bool(len(item))  # the layers with something to print (the G-code's ;LAYER lines)
            yield item


def write_gcode(sliced: "SlicedModel", out: str | Path, name: str, force: bool = False) -> float:
    """Write ``sliced`` as Marlin G-code to ``out`` atomically; return filament used, mm."""
    from cooprint.io.bundle import atomic_file
    from cooprint.program.build import layer_pieces
    from cooprint.program.gcode import Feeds, write_gcode

    s = sliced.settings
    with atomic_file(out, force) as tmp, open_output(tmp) as fh:
        return write_gcode(fh, layer_pieces(sliced.layers), s, Feeds.of_slicer(s), name)


def run_chunk(mesh: str | Path, out: str | Path, *, config: Sequence[str | Path] = (),
              overrides: dict[str, Any] | None = None, robots: int = 2, force: bool = False,
              picture: bool = True) -> dict[str, Any]:
    """Python twin of ``cooprint chunk``: returns the job record that was written."""
    from cooprint.io.bundle import check_destination

    check_destination(Path(out), force, inputs=(mesh, *config))
    job = chunk_job(mesh, load_settings(*config, overrides=overrides), robots)
    return write_chunk_bundle(job, out, force, picture)


@dataclass(frozen=True)
class CoopJob:
    """A cooperative job: chunks, their commands and every robot's command stream.

    Attributes
    ----------
    chunked : ChunkJob
        The chunker's and scheduler's output.
    store : ChunkStore
        Each chunk's commands (in memory, or spooled to disk for a big job) and summary
        (:mod:`cooprint.program.stream`).
    streams : dict
        ``{robot: RobotStream}``: each robot's program as pieces in order (chunk pieces read
        from ``store`` as they are needed).
    placements : dict
        ``{robot: RobotPlacement}``: side, facing, start position.
    layers : dict or None
        ``{chunk id: [(layer index, LayerPaths), ...]}``, indices in the object's layer grid;
        kept by a job made in memory, None for a spooled one (its layers are not kept).
    """

    chunked: ChunkJob
    store: Any
    streams: dict[str, Any]
    placements: dict[str, Any]
    layers: dict[str, list] | None = None

    @cached_property
    def programs(self) -> Mapping[str, Any]:
        """``{robot: Program}``, each made whole on first use (for small jobs: a big job's
        programs are streamed, :attr:`streams`)."""
        from cooprint.program.stream import Programs

        return Programs(self.streams, self.store)


def coop_job(mesh: str | Path | Solid, settings: JobSettings | None = None, robots: int = 2,
             progress: Progress | None = None, executor: Any = None, spool: str | Path | None = None,
             on_estimate: "Callable[[JobEstimate], None] | None" = None) -> CoopJob:
    """Chunk, assign, slice every chunk in the object's layer grid, and make each robot's
    command stream (transitions, NOTIFY / WAIT).

    Parameters
    ----------
    executor
        Where the chunks' layers are sliced (:func:`cooprint.slicing.slice_chunks`; None: a pool
        of local processes).
    spool
        A folder for the chunks' commands (:class:`~cooprint.program.stream.ChunkStore`): each
        chunk is written there as soon as it is sliced and let go, so that memory holds the
        chunks in flight, not the job (``cooprint run``). None: everything in memory, the
        layers kept too (:attr:`CoopJob.layers`).
    on_estimate
        Called with the run's :class:`~cooprint.io.estimate.JobEstimate` (output size, memory,
        time) after chunking, before the heavy work (the CLI prints it and checks the free disk
        space against it; it may raise to stop the run).
    """
    from cooprint.io.estimate import estimate_job
    from cooprint.program.build import BodySize, MaterialIndex, robot_streams
    from cooprint.program.stream import ChunkStore
    from cooprint.scheduling.graph import work_from_program
    from cooprint.slicing import slice_chunks

    settings = settings or load_settings()
    solid, placement = _load_with_progress(mesh, settings, progress)
    _check_work(solid, settings.slicing)  # before the cuts
    chunked = _chunk_placed(solid, placement, settings, robots, progress, preliminary=True)
    s = settings.slicing
    base = float(chunked.solid.bounds[0, 2])
    # estimate: the output's size, the memory and the time, before the heavy work (issue 15 item 5)
    if on_estimate:
        on_estimate(estimate_job(chunked.chunks, settings, chunked.assignment.sequences))
    store = ChunkStore(spool)
    layers: dict[str, list] | None = {} if spool is None else None
    work: dict[str, float] = {}
    ends: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    solids = {c.id: c.as_solid() for c in chunked.chunks.chunks}
    slice_progress = (lambda d, t: progress("slice", d, t)) if progress else None
    for cid, chunk_layers in slice_chunks(solids, s, base, slice_progress, executor, context=chunked.solid):
        # what the later stages need of a chunk, while its layers are here: its work and ends
        # (the schedule again), its commands (the store) and their summary
        canon = store.put(cid, chunk_layers)
        work[cid] = work_from_program(canon, settings.robot, s)
        first, last = store.summary(cid).first, store.summary(cid).last
        if first is not None and last is not None:
            ends[cid] = (first, last)
        if layers is not None:
            layers[cid] = chunk_layers
        del chunk_layers, canon
    del solids
    n_chunks = len(chunked.chunks.chunks)
    if progress:
        progress("program", 0, n_chunks)
    chunked = _rescheduled(chunked, work, ends, robots)
    material = MaterialIndex.of(chunked.chunks.chunks, margin=max(s.layer_height, s.first_layer_height))
    if chunked.assignment.strategy == "seed":
        streams, placements = robot_streams(
            dict(chunked.assignment.sequences), store, chunked.chunks.deps, material,
            reach=settings.robot.nozzle_depth, clearance=settings.program.clearance,
            axis=chunked.chunks.plan.axis, roles={c.id: c.role for c in chunked.chunks.chunks},
            body=BodySize(settings.robot.build_depth, settings.robot.body_length, settings.robot.body_width,
                          settings.robot.frame_width))  # None: as wide as the body
    else:
        chunked, streams, placements = _fleet_plan(chunked, store, material, robots)
    if progress:
        progress("program", n_chunks, n_chunks)
    return CoopJob(chunked, store, streams, placements, layers)


def _fleet_plan(chunked: ChunkJob, store: Any, material: Any,
                robots: int) -> tuple[ChunkJob, dict[str, Any], dict[str, Any]]:
    """The programs of an N-robot schedule (:func:`cooprint.program.fleet.fleet_streams`), the
    fastest of a few: the schedule for all ``robots`` and for fewer of them (the rest idle), each
    made into programs and timed at constant speed as the simulator times them.

    The scheduler cannot see every wait its programs will have (a robot's way to its next chunk
    past robots at work, a finished robot's way out): with more robots those waits can cost more
    than the extra robot gives, and then fewer robots finish sooner. Choosing by the programs'
    own makespan means more robots are never slower than fewer (up to ``FLEET_TRIALS`` robots every
    smaller fleet is tried; above, N - 1, 3N/4, N/2, N/3 and N/4)."""
    from cooprint.program.fleet import fleet_streams
    from cooprint.scheduling import Schedule

    settings = chunked.settings
    assert chunked.dag is not None
    few = range(2, robots + 1) if robots <= FLEET_TRIALS else \
        (robots, robots - 1, -(-3 * robots // 4), -(-robots // 2), -(-robots // 3), -(-robots // 4))
    counts = sorted({n for n in few if n >= 2}, reverse=True)
    if robots <= 2 or chunked.assignment.strategy == "exact":
        counts = [robots]  # an exact schedule is the one asked for
    names = robot_names(robots)
    best: tuple[float, ChunkJob, dict[str, Any], dict[str, Any]] | None = None
    for n in counts:
        sched = chunked.assignment if n == robots else make_schedule_for(chunked.dag, chunked.chunks, settings, n)
        assert isinstance(sched, Schedule)
        if n < robots:  # the same schedule, with the robots it leaves out idle (LB is the fleet's)
            sched = replace(sched, sequences={r: sched.sequences.get(r, ()) for r in names},
                            lower_bound=chunked.dag.lower_bound(robots))
        programs, placements = fleet_streams(sched, chunked.dag, store, material,
                                             {r: settings.robot for r in names}, settings.program.clearance,
                                             settings.slicing)
        span = _programs_makespan(programs, placements, settings, store)
        if best is None or span < best[0] * (1 - 1e-6):
            best = (span, replace(chunked, assignment=sched), programs, placements)
    assert best is not None
    return best[1], best[2], best[3]


def sim_robots(programs: dict[str, Any], placements: dict[str, Any], settings: JobSettings) -> list[Any]:
    """The simulator's robots of a plan in memory, as :func:`cooprint.simulation.load_inputs`
    reads them from its bundle: each program at its placement's start and facing, in the job's
    robot profile."""
    from cooprint.simulation.timeline import SimRobot

    return [SimRobot(r, p, np.asarray(placements[r].start, float), np.asarray(placements[r].facing, float),
                     profile=settings.robot) for r, p in programs.items()]


def _programs_makespan(programs: Mapping[str, Any], placements: dict[str, Any], settings: JobSettings,
                       store: Any = None) -> float:
    """When the last of ``programs`` ends, s, timed as ``cooprint simulate`` times a bundle at
    constant speed (every move at its robot's speed for its path role, :func:`piece_robots`; WAITs
    on NOTIFYs). ``programs``:
    ``{robot: Program}``, or ``{robot: RobotStream}`` with the ``store`` of their chunks (read
    one piece at a time)."""
    from cooprint.simulation.timeline import event_times

    return event_times(piece_robots(programs, placements, settings, store)).makespan


def piece_robots(programs: Mapping[str, Any], placements: dict[str, Any], settings: JobSettings,
                 store: Any = None) -> list[Any]:
    """The robots of a plan for :func:`cooprint.simulation.timeline.event_times`: each program
    (or stream, read from ``store``) from its placement's start, at the job's speeds per command
    (:meth:`Feeds.of_robot`: the G-code's feed rates, the simulator's time model)."""
    from cooprint.program.gcode import Feeds
    from cooprint.program.stream import PIECE_COMMANDS
    from cooprint.simulation.timeline import PieceRobot

    def pieces(p: Any) -> Callable[[], Iterable[Any]]:
        return (lambda: [p]) if store is None else (lambda: p.programs(store, PIECE_COMMANDS))

    speed = Feeds.of_robot(settings.robot, settings.slicing).speeds
    return [PieceRobot(r, np.asarray(placements[r].start, float), pieces(p), speed) for r, p in programs.items()]


def _rescheduled(chunked: ChunkJob, work: dict[str, float], ends: dict[str, tuple[np.ndarray, np.ndarray]],
                 robots: int) -> ChunkJob:
    """The job scheduled again with each chunk's ``work`` timed from its sliced paths
    (:func:`~cooprint.scheduling.graph.work_from_layers`; the volume estimate of :func:`chunk_job`
    was for the choice of layout) and its real first and last points ``ends`` (for the travel
    between chunks); the DAG's constraints (geometry) are kept."""
    from cooprint.scheduling.graph import retimed

    assert chunked.dag is not None
    dag = retimed(chunked.dag, work, ends)
    return replace(chunked, dag=dag, assignment=make_schedule_for(dag, chunked.chunks, chunked.settings, robots))


def program_stats(program: Any, s: SlicingSettings) -> dict[str, Any]:
    """Counts and lengths of a command stream, and the material it deposits."""
    from cooprint.program.stream import ProgramStats

    return ProgramStats().add(program).to_dict(s.filament_diameter)


def coop_record(job: CoopJob, stats: dict[str, dict[str, Any]] | None = None, compress: bool = False) -> dict[str, Any]:
    """``job.json`` of a cooperative run: the chunk record, robots with their placement, their
    whole profile (so that the bundle says each robot's speed caps and geometry itself; a mixed fleet
    gives each its own) and program statistics (``stats``, as they were written; else counted
    here), and the synchronisation events. ``compress``: the programs are ``.coop.gz`` and
    ``.gcode.gz`` files."""
    from dataclasses import asdict

    from cooprint.program.commands import NOTIFY, Program
    from cooprint.program.stream import ProgramStats

    record = job_record(job.chunked)
    s = job.chunked.settings.slicing
    for r in record["robots"]:
        name = r["name"]
        r["profile"] = asdict(job.chunked.settings.robot)
        r.update(job.placements[name].to_dict())
        r["program"], r["gcode"] = program_files(name, compress)
        if stats is None:
            counted = ProgramStats()
            for piece in job.streams[name].programs(job.store):
                counted.add(piece)
            r["stats"] = counted.to_dict(s.filament_diameter)
        else:
            r["stats"] = stats[name]
    for row in record["chunks"]:
        row["layers"] = job.store.summary(row["id"]).layers
    record["format"] = "cooprint-job/2"
    record["schedule"]["events"] = [
        {"robot": name, "kind": "notify" if p.kind[i] == NOTIFY else "wait", "events": list(p.events[p.event[i]])}
        for name, stream in job.streams.items() for p in stream.parts if isinstance(p, Program)
        for i in np.flatnonzero(p.event >= 0).tolist()]
    return record


def write_coop_bundle(job: CoopJob, out: str | Path, force: bool = False, picture: bool = True,
                      progress: Progress | None = None, *, compress: bool = False) -> dict[str, Any]:
    """Write the whole bundle (job.json, chunks/, robots/<name>.coop and .gcode, chunks.png)
    atomically; returns the job record. ``compress``: the programs gzip-compressed
    (``robots/<name>.coop.gz`` and ``.gcode.gz``)."""
    with atomic_dir(Path(out), force, inputs=_input_paths(job.chunked.solid)) as tmp:
        return write_coop_files(job, tmp, picture, progress, compress)


def write_coop_files(job: CoopJob, tmp: Path, picture: bool = True, progress: Progress | None = None,
                     compress: bool = False) -> dict[str, Any]:
    """Write the bundle's files into the (new, empty) folder ``tmp``: each robot's ``.coop`` and
    G-code written as its stream's pieces come (at most ``PIECE_COMMANDS`` commands of one
    chunk in memory at a time), gzip-compressed with ``compress``. Returns the job record."""
    from cooprint.io.estimate import CALIBRATION
    from cooprint.program.commands import CoopWriter
    from cooprint.program.gcode import Feeds, Heating, write_gcode
    from cooprint.program.stream import PIECE_COMMANDS, ChunkPiece, ProgramStats
    from cooprint.progress import ByteMeter
    from cooprint.simulation.timeline import event_times

    settings = job.chunked.settings
    s = settings.slicing
    # how long each WAIT is expected to last, every move at the G-code's feed rate: the G-code
    # keeps a nozzle hot only across short ones
    feeds = Feeds.of_robot(settings.robot, s)
    waits = event_times(piece_robots(job.streams, job.placements, settings, job.store)).waits
    (tmp / "chunks").mkdir()
    (tmp / "robots").mkdir()
    # the write bar counts bytes (MB/s): the STLs' exact size, the programs' expected
    per_command = CALIBRATION.coop_bytes + CALIBRATION.gcode_bytes
    meter = ByteMeter(progress, sum(stl_bytes(c.faces) for c in job.chunked.chunks.chunks)
                      + int(per_command * sum(_stream_commands(st, job.store) for st in job.streams.values())))
    for c in job.chunked.chunks.chunks:
        write_stl(tmp / "chunks" / f"{c.id}.stl", c.vertices, c.faces, name=c.id)
        meter.add(stl_bytes(c.faces))
    name = Path(job.chunked.solid.report.path).name
    stats = {}
    for robot, stream in job.streams.items():
        place = job.placements[robot]
        turns = "".join(f", turns to {d:.1f} deg before {c}" for c, d in place.facings[1:])
        has_turns = any(not isinstance(p, ChunkPiece) and p.turns for p in stream.parts)
        header = [f"job: {name}, robot '{settings.robot.name}' as {robot}",
                  f"side {place.side}, facing {place.facing_deg:.1f} deg, "
                  f"start {place.start[0]:.3f}, {place.start[1]:.3f}, {place.start[2]:.3f}{turns}",
                  "annotations: ;@chunk ID, ;@layer INDEX HEIGHT, ;@path ROLE WIDTH"
                  + (", ;@facing DEGREES" if has_turns else "") + " (docs/program.md)"]
        counted = ProgramStats()
        coop_file, gcode_file = program_files(robot, compress)
        with open_output(tmp / coop_file, compress) as coop, open_output(tmp / gcode_file, compress) as gcode:
            writer = CoopWriter(meter.wrap(coop), robot, header)

            def pieces() -> Iterator[Any]:
                for piece in stream.programs(job.store, PIECE_COMMANDS):
                    writer.write(piece)
                    counted.add(piece)
                    yield piece

            write_gcode(meter.wrap(gcode), pieces(), s, feeds, f"{name}, robot {robot}", notes=header[:2], home=False,
                        heating=Heating.of_robot(settings.robot, s, settings.program.heater_idle_limit_s,
                                                 waits[robot]))
            writer.close()
        stats[robot] = counted.to_dict(s.filament_diameter)
    meter.finish()
    record = coop_record(job, stats, compress)
    if picture:
        from cooprint.render.chunks import render_chunks

        if progress:
            progress("render", 0, 1)
        render_chunks(job.chunked.chunks, tmp / "chunks.png", schedule=job.chunked.assignment)  # by robot
        record["picture"] = "chunks.png"
        if progress:
            progress("render", 1, 1)
    write_json(tmp / "job.json", record)
    return record


def _stream_commands(stream: Any, store: Any) -> int:
    """Commands of a robot's stream (its chunk pieces counted from the store's summaries)."""
    from cooprint.program.stream import ChunkPiece

    total = 0
    for p in stream.parts:
        if isinstance(p, ChunkPiece):
            whole = store.summary(p.chunk).commands + (1 if p.entry is not None else 0)
            total += (p.stop if p.stop is not None else whole) - p.start
        else:
            total += len(p)
    return total


def run(mesh: str | Path, out: str | Path, *, config: Sequence[str | Path] = (),
        overrides: dict[str, Any] | None = None, robots: int = 2, force: bool = False,
        picture: bool = True, progress: Progress | None = None, executor: Any = None,
        compress: bool = False) -> dict[str, Any]:
    """Python twin of ``cooprint run``: the whole cooperative pipeline; returns the job record
    written to ``out/job.json``."""
    from cooprint.io.bundle import check_destination

    check_destination(Path(out), force, inputs=(mesh, *config))
    return run_job(mesh, load_settings(*config, overrides=overrides), out, robots, force=force, picture=picture,
                   progress=progress, executor=executor, compress=compress)


#: The folder of a bundle being written that holds the chunks' commands meanwhile (removed
#: before the bundle is complete).
SPOOL = ".spool"


def run_job(mesh: str | Path | Solid, settings: JobSettings, out: str | Path, robots: int = 2, *,
            force: bool = False, picture: bool = True, progress: Progress | None = None,
            executor: Any = None, on_estimate: "Callable[[JobEstimate], None] | None" = None,
            compress: bool = False) -> dict[str, Any]:
    """Plan and write a cooperative job, streamed (issue 15): each chunk's commands are spooled
    into the bundle's temporary folder as soon as it is sliced, and each robot's files are
    written piece by piece from there, so that memory holds the chunks in flight, not the job.
    The bundle appears complete or not at all (:func:`~cooprint.io.bundle.atomic_dir`: an error
    or a Ctrl-C removes the temporary folder and the spool in it). Returns the job record."""
    import shutil

    inputs = (str(mesh),) if not isinstance(mesh, Solid) and os.path.exists(mesh) else ()
    with atomic_dir(Path(out), force, inputs=inputs) as tmp:
        job = coop_job(mesh, settings, robots, progress, executor, spool=tmp / SPOOL, on_estimate=on_estimate)
        record = write_coop_files(job, tmp, picture, progress, compress)
        shutil.rmtree(tmp / SPOOL)
    return record


def simulate_bundle(out: str | Path, snapshot_at: float | None = None, animation: bool = False,
                    progress: Progress | None = None, viewer: bool = True, inp: Any = None,
                    accel: bool = False) -> dict[str, Any]:
    """Simulate the bundle in ``out`` (written by :func:`run`) and write ``out/sim/``:
    ``summary.json``, ``gantt.png``, ``snapshot.png`` (at ``snapshot_at`` s, default half the
    makespan), with ``viewer`` the interactive ``viewer.html`` (:mod:`cooprint.render.viewer`)
    and, with ``animation``, ``animation.mp4`` (20 s at 24 frames/s); returns the summary.
    cooprint's earlier derived outputs in ``sim/`` are replaced, other files kept (a
    ``viewer.html`` that is not cooprint's is left as it is, and no viewer is written: a
    warning says so; so does one when the viewer's JavaScript is not built). ``progress``: the
    stages ``read`` (bytes of the programs), ``timelines``, ``checks`` and ``pictures``. ``inp``:
    the bundle already loaded without its programs (``load_inputs([out], programs=False)``).
    The summary's ``inputs`` (:func:`inputs_record`) say what was simulated and its files' sizes
    and times, so that ``cooprint view`` sees when they change. ``accel``: moves accelerate
    (``simulate --accel``), else each keeps its speed."""
    from cooprint.io.bundle import check_sim_folder, is_derived_output
    from cooprint.render.sim import render_animation, render_gantt, render_snapshot
    from cooprint.simulation import simulate, summary
    from cooprint.simulation.inputs import read_chunk_meshes

    out = Path(out)
    check_sim_folder(out / "sim")  # before the work, not after
    page = out / "sim" / "viewer.html"
    if viewer and page.exists() and not is_derived_output(page):
        warn(f"kept {page}, which cooprint did not write; no viewer written (`cooprint view {out} --force` "
             "replaces it)")
        viewer = False
    if viewer:
        from cooprint.render.viewer import check_assets, write_viewer

        try:
            check_assets()
        except UserError as exc:  # the plan is still simulated and drawn; `cooprint view` says what to do
            warn(f"no viewer written: {exc}")
            viewer = False
    if inp is None:
        inp = read_with_progress([str(out)], None, None, progress, programs=False)  # timed piece by piece
    result = simulate(inp, accel=accel, progress=progress)
    record = summary(result)
    record["inputs"] = inputs_record([str(out)], None, (), accel, inp)
    pictures = 2 + int(viewer) + int(animation)
    with atomic_dir(out / "sim", force=True, sim=True) as tmp:
        write_json(tmp / "summary.json", record)
        done = 0
        if progress:
            progress("pictures", done, pictures)

        def drawn() -> None:
            nonlocal done
            done += 1
            if progress:
                progress("pictures", done, pictures)

        render_gantt(result, tmp / "gantt.png", critical=inp.critical_path, lower_bound=inp.lower_bound)
        drawn()
        render_snapshot(result, result.makespan / 2 if snapshot_at is None else snapshot_at, tmp / "snapshot.png")
        drawn()
        if viewer:
            write_viewer(result, record, tmp / "viewer.html", chunks=read_chunk_meshes(inp), critical=inp.critical_path,
                         lower_bound=inp.lower_bound, title=out.resolve().name)
            drawn()
        if animation:
            render_animation(result, tmp / "animation.mp4", fps=24, duration=20)
            drawn()
    return record


def read_with_progress(inputs: list[str], manifest: str | None, settings: JobSettings | None,
                       progress: Progress | None, programs: bool = True) -> Any:
    """:func:`cooprint.simulation.load_inputs` as the ``read`` stage of the progress bars, in
    bytes of the programs (:func:`cooprint.progress.program_bytes`); ``programs=False``: a
    bundle's programs left to the simulation to read piece by piece."""
    from cooprint.progress import program_bytes
    from cooprint.simulation import load_inputs

    size = program_bytes(inputs) if progress else 0
    if progress:
        progress("read", 0, size)
    inp = load_inputs(inputs, manifest, settings, programs)
    if progress:
        progress("read", size, size)
    return inp


def inputs_record(paths: Sequence[str | Path], manifest: str | Path | None, config: Sequence[str | Path],
                  accel: bool, inp: Any = None) -> dict[str, Any]:
    """sim/summary.json's ``inputs``: what ``cooprint view`` and ``render`` need to read and time a
    simulation's inputs again (the input paths, the manifest and the ``--config`` files, absolute;
    whether moves accelerated) and to tell whether they changed since (``fingerprint``: each file
    read, ``[size, mtime_ns]``, from :attr:`SimInput.fingerprint` and the ``--config`` files)."""
    from cooprint.simulation.inputs import fingerprint

    record: dict[str, Any] = {"paths": [os.path.abspath(x) for x in paths],
                              "manifest": os.path.abspath(manifest) if manifest else None,
                              "config": [os.path.abspath(x) for x in config], "accel": bool(accel)}
    if inp is not None and inp.fingerprint is not None:
        record["fingerprint"] = dict(inp.fingerprint) | fingerprint([Path(x) for x in config])
    return record


class SummaryUnreadable(UserError):
    """A ``sim/summary.json`` that cooprint wrote (it is in a bundle's ``sim/``) but cannot read:
    cut short, emptied, not JSON. Not a user's file: simulating again replaces it."""


def read_summary(path: str | Path) -> dict[str, Any] | None:
    """The simulation summary at ``path`` (``DIR/sim/summary.json``), ``None`` when there is none.
    A file there that is JSON but not cooprint's (no ``cooprint-sim/`` format) is a
    :class:`UserError` (never replaced: it is the user's); one that does not read as JSON at all
    is :class:`SummaryUnreadable` (its message says why)."""
    import json

    from cooprint.io.bundle import SIM_FORMAT

    p = Path(path)
    if not os.path.lexists(p):
        return None
    try:
        if not p.is_file():
            raise UserError(f"{p}: not a regular file where cooprint keeps its simulation summary; move it away")
        data = json.loads(p.read_text(encoding="utf-8"))
    except UnicodeDecodeError as exc:
        raise SummaryUnreadable(f"{p}: unreadable (not UTF-8 text, byte {exc.start})") from None
    except (ValueError, RecursionError) as exc:
        why = ("empty" if not p.stat().st_size else f"not JSON at line {exc.lineno}, column {exc.colno}"
               if isinstance(exc, json.JSONDecodeError) else "not JSON")
        raise SummaryUnreadable(f"{p}: unreadable ({why})") from None
    except OSError as exc:
        raise UserError(f"{p}: cannot read ({exc.strerror or exc})") from None
    if not isinstance(data, dict) or not str(data.get("format", "")).startswith(SIM_FORMAT):
        raise UserError(f"{p}: not a cooprint simulation summary (no \"format\": \"{SIM_FORMAT}...\"); cooprint "
                        "does not replace it: move it away")
    return data


def changed_inputs(record: dict[str, Any], root: str | Path) -> str | None:
    """Which input of a simulation summary changed since it was simulated, in a few words
    (``robots/B.coop changed (its size or modification time)``, ``job.json is no longer there``): the first file of its
    ``inputs.fingerprint`` whose size or mtime differ now (a bundle's paths relative to ``root``);
    ``None`` when none did, or the summary records none (written by an older cooprint)."""
    inputs = record.get("inputs")
    stamp = inputs.get("fingerprint") if isinstance(inputs, dict) else None
    if not isinstance(stamp, dict):
        return None
    for key, was in stamp.items():
        p = Path(key) if os.path.isabs(key) else Path(root) / key
        try:
            st = os.stat(p)
        except OSError:
            return f"{key} is no longer there"
        if [int(st.st_size), int(st.st_mtime_ns)] != was:
            return f"{key} changed (its size or modification time)"
    return None


@dataclass(frozen=True)
class SimSources:
    """What a simulated folder's ``sim/summary.json`` says was simulated (:func:`sim_sources`):
    the inputs to read again (``paths``, ``manifest``, ``config``), whether moves accelerated,
    the summary itself, and ``changed``: the input that changed since (:func:`changed_inputs`),
    ``None`` when none did (or the summary cannot tell)."""

    paths: tuple[str, ...]
    manifest: str | None
    config: tuple[str, ...]
    accel: bool
    record: dict[str, Any]
    changed: str | None


def simulated_as_bundle(folder: str | Path, record: dict[str, Any] | None) -> bool:
    """Whether ``folder`` is simulated as a ``cooprint run`` bundle (itself), with ``record`` its
    sim/summary.json (``None``: none yet): a bundle, or a folder holding a ``job.json`` (one that
    does not read is still the bundle's: its loader says what is wrong with it) whose summary
    names no other inputs (a ``simulate FILES --out`` folder may hold a job.json too)."""
    from cooprint.io.bundle import is_bundle

    root = Path(folder)
    inputs = record.get("inputs") if record is not None else None
    others = (isinstance(inputs, dict) and isinstance(inputs.get("paths"), list)
              and inputs["paths"] != [os.path.abspath(root)])
    return is_bundle(root) or (os.path.lexists(root / "job.json") and not others)


def sim_sources(folder: str | Path, record: dict[str, Any] | None = None) -> SimSources:
    """The inputs of a simulated folder, to read and time them again (``cooprint view``,
    ``cooprint render DIR``): a ``cooprint run`` bundle (itself) or a folder written by
    ``cooprint simulate FILES --out FOLDER`` (the files its ``sim/summary.json`` names). Read
    them with ``read_with_progress(list(s.paths), s.manifest, load_settings(*s.config) if
    s.config else None, ...)`` and time them with ``simulate(..., accel=s.accel)``. ``record``:
    the summary already read (:func:`read_summary`). A missing or unreadable summary, one that
    does not say what it simulated, or inputs no longer there are a one-line :class:`UserError`."""
    root = Path(folder)
    summary_path = root / "sim" / "summary.json"
    if record is None:
        record = read_summary(summary_path)
    if record is None:
        raise UserError(f"{folder}: no simulation (sim/summary.json); run `cooprint simulate` first")
    inputs = record.get("inputs")
    saved = isinstance(inputs, dict) and isinstance(inputs.get("paths"), list)
    if simulated_as_bundle(root, record):
        accel = inputs.get("accel") if isinstance(inputs, dict) else None  # the bundle where it is now
        return SimSources((str(root),), None, (), bool(accel) if accel is not None else
                          str(record.get("time_model", "")).startswith("trapezoidal"), record,
                          changed_inputs(record, root))
    if not saved:
        raise UserError(f"{summary_path}: does not say which files were simulated (written by an older cooprint?); "
                        f"run `cooprint simulate FILES --out {folder}` again")
    manifest, config = inputs.get("manifest"), tuple(inputs.get("config") or ())
    for name in [*inputs["paths"], *([manifest] if manifest else []), *config]:
        if not Path(name).exists():
            raise UserError(f"{summary_path}: names {name}, which is no longer there; simulate again")
    return SimSources(tuple(inputs["paths"]), manifest, config, bool(inputs.get("accel")), record,
                      changed_inputs(record, root))
