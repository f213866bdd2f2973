"""The slicing benchmark's large-area part (issue 17), generated in code.

A 500 x 300 x 100 mm block with the features a real large part has, so that every role of a
slicer is exercised on big cross-sections:

* a deep rectangular pocket from the top with ribs standing in it, 1.5, 3 and 6 mm thick (the
  thinnest is narrower than two perimeters: gap fill / thin walls), their tops 10 mm below the
  part's top (small top surfaces);
* round pockets of several depths and four through holes from the top;
* a 40 mm wide through-window along Y, 30 mm high, whose ceiling is a 40 mm bridge;
* a 34° chamfer along the +X end (a sloped face: a solid step under every exposed layer).

The booleans are made with manifold3d; every edge is then split into ``n`` pieces
(``Manifold.refine``, which keeps flat faces flat: the shape is unchanged) with ``n`` chosen to
reach about ``TARGET_FACES`` triangles, as a CAD export of a large part has. The result is
deterministic (same manifold3d, same file). Written as binary STL, centred in X and Y, standing
on z = 0, like the meshes of ``../shared/meshes``.

    python benchmarks/large_part.py OUT.stl      # writes it, prints its triangle count
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import manifold3d
import numpy as np

NAME = "large_part.stl"
SIZE = (500.0, 300.0, 100.0)
TARGET_FACES = 1_500_000
#: Segments of a circle: round holes as a CAD exporter tessellates them (0.1 mm chord error on
#: a 40 mm hole needs about 60).
SEGMENTS = 64


def box(x0: float, y0: float, z0: float, x1: float, y1: float, z1: float) -> manifold3d.Manifold:
    """The axis-aligned box between two corners."""
    return manifold3d.Manifold.cube((x1 - x0, y1 - y0, z1 - z0)).translate((x0, y0, z0))


def hole(x: float, y: float, diameter: float, z0: float, z1: float) -> manifold3d.Manifold:
    """A vertical cylinder of ``diameter`` centred at (x, y) from z0 to z1."""
    return manifold3d.Manifold.cylinder(z1 - z0, diameter / 2, circular_segments=SEGMENTS).translate((x, y, z0))


def coarse_part() -> manifold3d.Manifold:
    """The part before refinement (corner at the origin, a few thousand triangles)."""
    sx, sy, sz = SIZE
    block = box(0, 0, 0, sx, sy, sz)
    # the chamfer: everything above the plane through (440, y, 100) and (500, y, 60) removed
    angle = math.atan2(40.0, 60.0)
    normal = (-math.sin(angle), 0.0, -math.cos(angle))
    block = block.trim_by_plane(normal, normal[0] * 440.0 + normal[2] * 100.0)
    cuts = [box(20, 40, 40, 200, 260, sz + 1), box(250, -1, 10, 290, sy + 1, 40),
            hole(240, 70, 40, 50, sz + 1), hole(240, 230, 40, 70, sz + 1), hole(340, 150, 80, 30, sz + 1),
            *[hole(x, y, 12, -1, sz + 1) for x in (320.0, 400.0) for y in (30.0, 270.0)]]
    ribs = [box(20, y, 40, 200, y + t, sz - 10) for y, t in ((80, 1.5), (120, 3.0), (160, 6.0), (200, 3.0))]
    ribs.append(box(110, 40, 40, 113, 260, sz - 10))   # a cross rib
    part = manifold3d.Manifold.batch_boolean([block, *cuts], manifold3d.OpType.Subtract)
    return manifold3d.Manifold.batch_boolean([part, *ribs], manifold3d.OpType.Add)


def make(target_faces: int = TARGET_FACES) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (n, 3) float64, faces (m, 3)) of the refined part, centred in X and Y on z = 0.

    Every edge is split into the ``n`` pieces that bring the triangle count nearest to
    ``target_faces`` (each triangle becomes n² of them)."""
    part = coarse_part()
    n = max(2, round(math.sqrt(target_faces / part.num_tri())))
    mesh = part.refine(n).to_mesh()
    vertices = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    vertices = vertices - [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]]
    return vertices, np.asarray(mesh.tri_verts)


def write_binary_stl(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    """Binary STL of the triangles (float32, unit normals), written atomically."""
    tri = vertices[faces].astype(np.float32)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-30)
    record = np.zeros(len(tri), dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])
    record["n"], record["v"] = normal, tri
    partial = path.with_suffix(".part")
    with open(partial, "wb") as f:
        f.write(b"cooprint benchmark large-area part".ljust(80, b" "))
        f.write(np.uint32(len(tri)).tobytes())
        f.write(record.tobytes())
    partial.replace(path)


def write(path: Path) -> Path:
    """Generate the part into ``path`` (folders made); returns ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    write_binary_stl(path, *make())
    return path


def ensure(work: Path) -> Path:
    """The part in ``work/meshes``, generated when absent or older than this file."""
    path = work / "meshes" / NAME
    if not path.exists() or path.stat().st_mtime < Path(__file__).stat().st_mtime:
        print(f"  generating {path}", flush=True)
        write(path)
    return path


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__.rstrip().splitlines()[-1].strip())
    target = write(Path(sys.argv[1]))
    print(f"{target}: {(target.stat().st_size - 84) // 50:,} triangles")
