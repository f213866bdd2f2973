"""Parametric models built in code (manifold3d), for the demo, the docs and the tests.

Each returns a :class:`~cooprint.io.mesh.Solid` standing on z = 0, centred in x and y.
"""

from __future__ import annotations

import manifold3d as m3d
import numpy as np

from cooprint.io.mesh import Solid, solid_from_arrays


def _solid(man: m3d.Manifold, name: str) -> Solid:
    mesh = man.to_mesh64()
    return solid_from_arrays(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts),
                             path=f"<{name}>", fmt="generated")


def car_manifold(length: float = 420.0) -> m3d.Manifold:
    """A car-like union of boxes and cylinders, its length along Y (the chunking direction)."""
    body = m3d.Manifold.cube((120, length, 60), center=True).translate((0, 0, 55))
    cabin = m3d.Manifold.cube((100, length * 0.45, 50), center=True).translate((0, -length * 0.05, 105))
    wheels = m3d.Manifold()
    for yy in (-length * 0.32, length * 0.32):
        for xx in (-60, 60):
            w = m3d.Manifold.cylinder(24, 28, 28, 48, center=True).rotate((0, 90, 0))
            wheels = wheels + w.translate((xx, yy, 28))
    return body + cabin + wheels


def car(length: float = 420.0) -> Solid:
    """:func:`car_manifold` as a Solid."""
    return _solid(car_manifold(length), f"car {length:g} mm")


def cylinder(radius: float = 60.0, height: float = 120.0, segments: int = 128) -> Solid:
    """An upright cylinder (the seed's Fig. 5a-b)."""
    return _solid(m3d.Manifold.cylinder(height, radius, radius, segments), "cylinder")
