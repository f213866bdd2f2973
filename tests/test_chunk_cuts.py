"""A chunk's beads stop at its cuts: the thin walls of a grid's centre row (a wedge whose top
layers are narrower than two lines, cut across into columns) end half a bead short of the cut,
so the later column's nozzle does not run under the earlier column's layers above it (the
bench's 3000 x 2000 x 40 mm slab planned for one robot had ``nozzle-in-material`` along 11 cells,
22 errors in the bench's two simulations)."""

from __future__ import annotations

import manifold3d as m3d
import numpy as np
import pytest

from cooprint.simulation import severity
from cooprint.slicing.paths import PERIMETER_OUTER, TRAVEL

#: The bench's large-part profile (benchmarks/bench_cooperative.py LARGE_PART): a 1 mm nozzle,
#: 1.1 mm lines of 0.6 mm layers; the grid layout with two columns of 320 mm.
TABLES = {"robot": {"name": "large-part", "max_print_speed": 60.0, "max_travel_speed": 150.0},
          "slicing": {"nozzle_diameter": 1.0, "layer_height": 0.6, "first_layer_height": 0.6,
                      "extrusion_width": 1.1, "min_area": 0.5},
          "chunking": {"layout": "grid", "column_width": 320.0},
          "scheduling": {"strategy": "list"}}


@pytest.fixture(scope="module")
def slab(tmp_path_factory):
    """A 640 x 400 x 5 mm box planned for one robot (centre row C-0, C-1 between the rows L1 and
    R1), its simulation input and its simulation."""
    from cooprint.config import load_settings
    from cooprint.io.bundle import write_stl
    from cooprint.io.mesh import solid_from_arrays
    from cooprint.jobs import coop_job, sim_robots
    from cooprint.simulation import SimInput, simulate

    mesh = m3d.Manifold.cube((640.0, 400.0, 5.0), center=True).translate((0, 0, 2.5)).to_mesh64()
    solid = solid_from_arrays(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts), path="<slab>",
                              fmt="generated")
    settings = load_settings(tables=[("test", TABLES)])
    job = coop_job(solid, settings, robots=1)
    folder = tmp_path_factory.mktemp("slab")
    files = {}
    for c in job.chunked.chunks.chunks:
        files[c.id] = folder / f"{c.id}.stl"
        write_stl(files[c.id], c.vertices, c.faces, name=c.id)
    dag = job.chunked.dag
    inp = SimInput(sim_robots(job.programs, job.placements, settings), settings.robot, settings.slicing, "<slab>",
                   deps={c: dag.preds(c) for c in dag.ids}, chunk_files=files,
                   robot_chunks={r: tuple(seq) for r, seq in job.chunked.assignment.sequences.items()})
    return job, simulate(inp)


def _thin_walls(layers) -> list[tuple[float, np.ndarray, float]]:
    """The open outer-perimeter paths (thin walls) of a chunk's layers: (z, points, width)."""
    out = []
    for _, lp in layers:
        for p in np.flatnonzero((lp.role == PERIMETER_OUTER) & (lp.role != TRAVEL)):
            pts = lp.points[lp.offsets[p]:lp.offsets[p + 1]]
            if not np.array_equal(pts[0], pts[-1]):
                out.append((float(lp.z), pts, float(lp.width[p])))
    return out


def test_the_centre_row_of_a_slab_planned_for_one_robot_passes_the_material_checks(slab):
    job, res = slab
    assert {c.id for c in job.chunked.chunks.chunks} >= {"C-0", "C-1"}
    assert [f for f in res.findings if f.kind == "nozzle-in-material"] == []
    assert [f for f in res.findings if severity(f.kind) == "error"] == []


def test_the_thin_walls_of_the_centre_row_end_half_a_bead_short_of_the_cut(slab):
    """The wedge's top layers are thin walls along x in both columns; the cut between them
    runs at x = 0 at the top, further out below (C-0 under it): every bead of C-0 ends
    before the cut and every bead of C-1 after it, on each layer."""
    job, _ = slab
    mesh = {c.id: c for c in job.chunked.chunks.chunks}
    walls = {cid: _thin_walls(job.layers[cid]) for cid in ("C-0", "C-1")}
    assert walls["C-0"] and walls["C-1"]  # the wedge's top is laid as thin walls
    v = mesh["C-0"].vertices
    top = v[:, 2].max()
    reach = v[np.isclose(v[:, 2], v[:, 2].min()), 0].max()  # the cut's x at the floor, 0 at the top
    for z, pts, w in walls["C-0"]:
        cut = reach * (1 - (z - 0.3) / top)  # at the layer's middle
        assert pts[:, 0].max() + w / 2 <= cut + 0.02
    for z, pts, w in walls["C-1"]:
        cut = reach * (1 - (z - 0.3) / top)
        assert pts[:, 0].min() - w / 2 >= cut - 0.02
