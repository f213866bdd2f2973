"""Test meshes made in code (the suite never reads ../shared)."""

from __future__ import annotations

import manifold3d as m3d
import numpy as np
import trimesh

from cooprint.models import car_manifold


def to_trimesh(man: m3d.Manifold) -> trimesh.Trimesh:
    mesh = man.to_mesh64()
    return trimesh.Trimesh(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts),
                           process=False)


def box(x: float = 40.0, y: float = 300.0, z: float = 30.0) -> m3d.Manifold:
    """Axis-aligned box centred in x, y, standing on z = 0."""
    return m3d.Manifold.cube((x, y, z), center=True).translate((0, 0, z / 2))


def cylinder(r: float = 20.0, h: float = 120.0, segments: int = 96) -> m3d.Manifold:
    return m3d.Manifold.cylinder(h, r, r, segments)


def ball(r: float = 50.0, segments: int = 256) -> m3d.Manifold:
    """A sphere standing on z = 0: every layer's section differs from the others."""
    return m3d.Manifold.sphere(r, segments).translate((0.0, 0.0, r))


def tube(r_out: float = 25.0, r_in: float = 10.0, h: float = 60.0, segments: int = 96) -> m3d.Manifold:
    """A pipe: every horizontal section has a hole."""
    return cylinder(r_out, h, segments) - cylinder(r_in, h + 2, segments).translate((0, 0, -1))


def lying_tube(r_out: float = 30.0, r_in: float = 18.0, length: float = 400.0) -> m3d.Manifold:
    """A pipe lying along Y: cuts across it have holes and islands."""
    t = tube(r_out, r_in, length)
    return t.rotate((90, 0, 0)).translate((0, length / 2, r_out))


def car(length: float = 420.0) -> m3d.Manifold:
    """A car-like union of boxes and cylinders, length along Y (the chunking direction)."""
    return car_manifold(length)


def thin_walls(length: float = 300.0) -> m3d.Manifold:
    """Two 1.2 mm walls on a base plate."""
    base = m3d.Manifold.cube((60, length, 2), center=True).translate((0, 0, 1))
    wall = m3d.Manifold.cube((1.2, length, 40), center=True)
    return base + wall.translate((-20, 0, 22)) + wall.translate((20, 0, 22))


def with_hole(man: m3d.Manifold, n_faces: int = 2) -> trimesh.Trimesh:
    """The mesh with ``n_faces`` adjacent triangles removed: a small hole."""
    tm = to_trimesh(man)
    keep = np.ones(len(tm.faces), dtype=bool)
    start = len(tm.faces) // 2
    keep[start:start + n_faces] = False
    tm.update_faces(keep)
    return tm


# hard cases for the planner (tests/test_plans.py)

def plate(x: float = 1500.0, y: float = 800.0, z: float = 20.0) -> m3d.Manifold:
    """A large flat plate: five chunks, wider (x) than a robot's body."""
    return box(x, y, z)


def slender(side: float = 30.0, height: float = 250.0) -> m3d.Manifold:
    """A tall, thin column."""
    return box(side, side, height)


def islands(rows: int = 4, cols: int = 3, r: float = 8.0, h: float = 20.0) -> m3d.Manifold:
    """Separate pegs in a grid over 120 x 480 mm: every chunk's layers have several islands."""
    out = m3d.Manifold()
    for x in np.linspace(-60, 60, cols):
        for y in np.linspace(-240, 240, rows):
            out = out + m3d.Manifold.cylinder(h, r, r, 32).translate((float(x), float(y), 0))
    return out


def hollow(x: float = 120.0, y: float = 300.0, z: float = 50.0, wall: float = 10.0) -> m3d.Manifold:
    """A closed box with a closed cavity inside (its roof is a bridge over air)."""
    cavity = m3d.Manifold.cube((x - 4 * wall, y - 4 * wall, z - 2 * wall), center=True).translate((0, 0, z / 2))
    return box(x, y, z) - cavity


def ledge(x: float = 120.0, y: float = 300.0, z: float = 30.0, reach: float = 12.0) -> m3d.Manifold:
    """A box with a ledge along its side at its top, sticking out ``reach`` mm over air: held on one
    side only (a cantilever, not a bridge), so its first layer is an overhang."""
    shelf = m3d.Manifold.cube((reach + 1.0, y, 3.0), center=True).translate((x / 2 + reach / 2 - 0.5, 0, z - 1.5))
    return box(x, y, z) + shelf


def sheet(x: float = 300.0, y: float = 600.0, z: float = 1.6) -> m3d.Manifold:
    """A sheet two coarse layers thick: its centre chunk (a thin wedge) has nothing to print."""
    return box(x, y, z)


#: Thick lines and layers for plans in tests: the same plan logic, a fraction of the work.
COARSE = {"slicing.layer_height": 1.0, "slicing.first_layer_height": 1.0, "slicing.extrusion_width": 1.6,
          "slicing.nozzle_diameter": 1.2}


def bar_bundle(root, height: float):
    """A real two-robot bundle of `cooprint run` in ``root / "job"``: a 40 x 420 mm bar
    (deeper than the build depth, so cut: A prints C then L1, B waits for C, then prints R1)."""
    from cooprint.jobs import run

    to_trimesh(box(40, 420, height)).export(root / "bar.stl")
    run(root / "bar.stl", root / "job", overrides=COARSE, picture=False)
    return root / "job"
