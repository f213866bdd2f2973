"""Jobs: the pipeline stages chained for one purpose, and the records they write.

``chunk_job`` runs mesh -> chunker -> scheduler; ``write_chunk_bundle`` writes the chunk part of
the output bundle (``job.json``, ``chunks/<id>.stl``, ``chunks.png``) atomically. The CLI and the
Python API both call these.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Iterable, Iterator, Sequence

import numpy as np

from cooprint.chunking import ChunkSet, cut_chunks, plan_chunks
from cooprint.config import JobSettings, SlicingSettings, load_settings
from cooprint.errors import UserError
from cooprint.io.bundle import atomic_dir, write_json, write_stl
from cooprint.io.mesh import Solid, load_mesh
from cooprint.scheduling import Assignment, assign

if TYPE_CHECKING:
    from cooprint.slicing import SlicedModel

#: ``progress(stage, done, total)``: called as work advances.
Progress = Callable[[str, int, int], None]


def robot_names(n: int) -> tuple[str, ...]:
    """``A``, ``B``, ... ``Z``, then ``R27``, ``R28``, ..."""
    return tuple(chr(ord("A") + i) if i < 26 else f"R{i + 1}" for i in range(n))


@dataclass(frozen=True)
class ChunkJob:
    """A chunked and assigned object: the chunker's and scheduler's output together."""

    solid: Solid
    settings: JobSettings
    chunks: ChunkSet
    assignment: Assignment


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
    if isinstance(mesh, Solid):
        solid = mesh
    else:
        if progress:
            progress("load", 0, 1)
        solid = load_mesh(mesh, settings.mesh)
        if progress:
            progress("load", 1, 1)
    plan = plan_chunks(solid.vertices, settings.robot, settings.chunking)
    cut_progress = (lambda d, t: progress("cut", d, t)) if progress else None
    chunks = cut_chunks(solid, plan, cut_progress)
    return ChunkJob(solid, settings, chunks, assign(chunks, robot_names(robots)))


def job_record(job: ChunkJob) -> dict[str, Any]:
    """The ``job.json`` content: settings, robots, chunk table, schedule, statistics."""
    ch, asg = job.chunks, job.assignment
    rows = []
    axis = np.asarray(ch.plan.axis)
    for c in ch.chunks:
        lo, hi = c.bounds
        rows.append({
            "id": c.id, "role": c.role, "robot": asg.robot_of(c.id), "order": asg.order_of(c.id),
            "deps": list(ch.deps[c.id]), "volume_mm3": c.volume,
            "reach_mm": float(np.ptp(c.vertices @ axis)),
            "bbox": [lo.tolist(), hi.tolist()], "triangles": int(len(c.faces)),
            "planes": [p.to_dict() for p in c.planes], "file": f"chunks/{c.id}.stl",
        })
    rel = abs(ch.volume - ch.solid_volume) / ch.solid_volume
    return {
        "format": "cooprint-job/1",
        "mesh": job.solid.report.to_dict(),
        "settings": job.settings.to_dict(),
        "plan": ch.plan.to_dict(),
        "robots": [{"name": r, "profile": job.settings.robot.name, "chunks": list(seq)}
                   for r, seq in asg.sequences.items()],
        "chunks": rows,
        "schedule": {"strategy": asg.strategy, "sequences": {r: list(s) for r, s in asg.sequences.items()},
                     "sync": [{"after": b, "before": a} for b, a in asg.cross_robot_deps(ch.deps)]},
        "stats": {"chunks": len(ch.chunks), "volume_mm3": ch.volume, "solid_volume_mm3": ch.solid_volume,
                  "volume_rel_error": rel},
    }


def write_chunk_bundle(job: ChunkJob, out: str | Path, force: bool = False, picture: bool = True,
                       progress: Progress | None = None) -> dict[str, Any]:
    """Write ``job.json``, ``chunks/<id>.stl`` and (``picture``) ``chunks.png`` into ``out``,
    atomically. Returns the job record written to ``job.json``."""
    out = Path(out)
    with atomic_dir(out, force) as tmp:
        (tmp / "chunks").mkdir()
        n = len(job.chunks.chunks)
        for i, c in enumerate(job.chunks.chunks):
            write_stl(tmp / "chunks" / f"{c.id}.stl", c.vertices, c.faces, name=c.id)
            if progress:
                progress("write", i + 1, n)
        record = job_record(job)
        if picture:
            from cooprint.render.chunks import render_chunks

            if progress:
                progress("render", 0, 1)
            render_chunks(job.chunks, tmp / "chunks.png")
            record["picture"] = "chunks.png"
            if progress:
                progress("render", 1, 1)
        write_json(tmp / "job.json", record)
    return record


def check_build_volume(solid: Solid, s: SlicingSettings) -> None:
    """Refuse a model that does not fit the single printer's build volume, naming both sizes."""
    size = np.ptp(solid.bounds, axis=0)
    box = np.array([s.build_x, s.build_y, s.build_z])
    if (size > box + 1e-9).any():
        raise UserError(f"{solid.report.path}: the model is {size[0]:.1f} x {size[1]:.1f} x {size[2]:.1f} mm, "
                        f"larger than the build volume {box[0]:g} x {box[1]:g} x {box[2]:g} mm "
                        "([slicing] build_x, build_y, build_z)")


def slice_job(mesh: str | Path | Solid, settings: JobSettings | None = None,
              progress: Progress | None = None) -> tuple[Solid, "SlicedModel"]:
    """Load (unless given a Solid) and slice a whole model for one robot."""
    from cooprint.slicing import slice_solid

    settings = settings or load_settings()
    solid = mesh if isinstance(mesh, Solid) else load_mesh(mesh, settings.mesh)
    check_build_volume(solid, settings.slicing)
    layer_progress = (lambda d, t: progress("slice", d, t)) if progress else None
    return solid, slice_solid(solid, settings.slicing, layer_progress)


def slice_to_gcode(mesh: str | Path, out: str | Path, settings: JobSettings | None = None,
                   progress: Progress | None = None, force: bool = False) -> tuple[int, float]:
    """Load, slice and write G-code to ``out`` atomically, layer block by layer block (the model
    is never held whole); return the number of layers and the filament used, mm."""
    from cooprint.io.bundle import atomic_file
    from cooprint.program.gcode import write_program
    from cooprint.slicing import iter_layers

    settings = settings or load_settings()
    solid = load_mesh(mesh, settings.mesh)
    check_build_volume(solid, settings.slicing)
    layer_progress = (lambda d, t: progress("slice", d, t)) if progress else None
    counted = _Counted(iter_layers(solid, settings.slicing, layer_progress))
    del solid  # iter_layers keeps only what slicing needs, not the whole Solid
    with atomic_file(out, force) as tmp, open(tmp, "w", encoding="ascii") as fh:
        used = write_program(fh, counted, settings.slicing, Path(mesh).name)
    return counted.n, used


class _Counted:
    """An iterable that counts what went through it."""

    def __init__(self, items: Iterable[Any]):
        self.items, self.n = items, 0

    def __iter__(self) -> Iterator[Any]:
        for item in self.items:
            self.n += 1
            yield item


def write_gcode(sliced: "SlicedModel", out: str | Path, name: str, force: bool = False) -> float:
    """Write ``sliced`` as Marlin G-code to ``out`` atomically; return filament used, mm."""
    from cooprint.io.bundle import atomic_file
    from cooprint.program.gcode import write_program

    with atomic_file(out, force) as tmp, open(tmp, "w", encoding="ascii") as fh:
        return write_program(fh, sliced.layers, sliced.settings, name)


def run_chunk(mesh: str | Path, out: str | Path, *, config: Sequence[str | Path] = (),
              overrides: dict[str, Any] | None = None, robots: int = 2, force: bool = False,
              picture: bool = True) -> dict[str, Any]:
    """Python twin of ``cooprint chunk``: returns the job record that was written."""
    from cooprint.io.bundle import check_destination

    check_destination(Path(out), force)
    job = chunk_job(mesh, load_settings(*config, overrides=overrides), robots)
    return write_chunk_bundle(job, out, force, picture)
