"""Measure :data:`cooprint.scheduling.graph.VOLUME_FACTOR`: per chunk, the time of its sliced
layers (``work_from_layers``, every move at the robot's speed of its path role) over the
printed-volume model without the factor (``work_from_volume / VOLUME_FACTOR``), on generated parts
cut by the seed2 layout for two robots, default robot and slicing settings. Prints each chunk's
ratio and their median, range and coefficient of variation (the numbers the constant's comment
quotes). About a minute on one core.

    PYTHONPATH=src .venv/bin/python benchmarks/calibrate_volume_factor.py
"""
from __future__ import annotations

import manifold3d as m3d
import numpy as np
import trimesh

from cooprint.config import load_settings
from cooprint.io.mesh import solid_from_trimesh
from cooprint.jobs import chunk_job
from cooprint.models import car, cylinder
from cooprint.scheduling.graph import VOLUME_FACTOR, work_from_layers, work_from_volume
from cooprint.slicing import slice_chunks


def _box(x: float, y: float, z: float, at: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> m3d.Manifold:
    return m3d.Manifold.cube((x, y, z), center=True).translate((at[0], at[1], at[2] + z / 2))


def _solid(man: m3d.Manifold):
    mesh = man.to_mesh64()
    return solid_from_trimesh(trimesh.Trimesh(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts),
                                              process=False))


PARTS = {
    "car 420": lambda: car(420.0),
    "box 300 x 900 x 60": lambda: _solid(_box(300, 900, 60)),
    "cylinder r 60 h 120": lambda: cylinder(60.0, 120.0),
    "hollow box 300 x 600 x 60, 10 mm walls": lambda: _solid(_box(300, 600, 60) - _box(280, 580, 70, (0, 0, 10))),
    "plate 900 x 400 x 10": lambda: _solid(_box(400, 900, 10)),
    "post 20 x 20 x 150": lambda: _solid(_box(20, 20, 150)),
}


def main() -> None:
    settings = load_settings()
    ratios = []
    for name, make in PARTS.items():
        job = chunk_job(make(), settings, robots=2)
        chunks = job.chunks
        base = float(job.solid.bounds[0, 2])
        layers = dict(slice_chunks({c.id: c.as_solid() for c in chunks.chunks}, settings.slicing, base))
        sliced = work_from_layers(layers, settings.robot, settings.slicing)
        model = work_from_volume(chunks, settings.robot, settings.slicing)
        for cid in chunks.ids:
            ratio = sliced[cid] / (model[cid] / VOLUME_FACTOR)
            ratios.append(ratio)
            print(f"{name}, {cid}: sliced {sliced[cid]:,.0f} s, volume model {model[cid] / VOLUME_FACTOR:,.0f} s, "
                  f"ratio {ratio:.3f}", flush=True)
    r = np.array(ratios)
    print(f"{len(r)} chunks: median {np.median(r):.3f}, range {r.min():.3f} to {r.max():.3f}, "
          f"coefficient of variation {r.std() / r.mean():.1%} (VOLUME_FACTOR = {VOLUME_FACTOR})")


if __name__ == "__main__":
    main()
