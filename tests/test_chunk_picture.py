"""The chunk picture (issue 16): a robot has the same colour in it as in the simulation's pictures
(the plan's robot order, render/palette.py's robot_colours), and every chunk's label lies wholly
on its own chunk's visible pixels (not in a torus's hole, not over a neighbour or another label),
or is named in the footnote."""

from __future__ import annotations

from pathlib import Path

import manifold3d as m3d
import numpy as np
import pytest
import trimesh
from PIL import Image

import cooprint.render.chunks as rc
import fleet_layouts
from cooprint.chunking.cut import ChunkSet
from cooprint.io.mesh import solid_from_arrays
from cooprint.jobs import chunk_job, robot_names, run
from cooprint.models import car
from cooprint.render.palette import robot_colour, robot_colours
from cooprint.render.sim import render_gantt
from cooprint.scheduling import Assignment
from cooprint.simulation import load_inputs, simulate

#: A coarse print (2 mm nozzle, 1.6 mm layers): plans in seconds.
COARSE = {"slicing.nozzle_diameter": 2.0, "slicing.layer_height": 1.6, "slicing.first_layer_height": 1.6,
          "slicing.extrusion_width": 3.0, "slicing.infill_density": 0.05, "slicing.perimeters": 1,
          "slicing.top_layers": 1, "slicing.bottom_layers": 1}


def _pixels(path) -> np.ndarray:
    with Image.open(path) as im:
        return np.asarray(im.convert("RGB")).astype(float)


def _shaded(px: np.ndarray, colour, tol: float = 3.0) -> np.ndarray:
    """Which pixels are ``colour`` times a shade (the renderer's lighting), to a rounding."""
    c = np.asarray(colour, float)
    k = px @ c / (c @ c)
    return np.linalg.norm(px - k[..., None] * c, axis=-1) < tol


def _slab(x: float, y: float, z: float):
    mesh = m3d.Manifold.cube((x, y, z), center=True).translate((0, 0, z / 2)).to_mesh64()
    return solid_from_arrays(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts), path="<slab>",
                             fmt="generated")


@pytest.fixture(scope="module", params=["seed2 car, 2 robots", "grid slab, 4 robots"])
def planned(request, tmp_path_factory):
    """A plan run into a bundle and simulated, with the picture its chunks.png was saved from."""
    two = request.param.startswith("seed2")
    out = tmp_path_factory.mktemp("plan") / "job"
    drawn = []

    def keep(chunks, path, **kw):
        pic = rc.chunk_picture(chunks, **kw)
        pic.image.save(path)
        drawn.append((chunks, kw["schedule"], pic))
        return Path(path)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(rc, "render_chunks", keep)
        record = run(car(420.0) if two else _slab(2400.0, 1000.0, 10.0), out, robots=2 if two else 4,
                     overrides=COARSE | ({} if two else {"chunking.layout": "grid"}))
    chunks, schedule, pic = drawn[0]
    return out, record, chunks, schedule, pic, simulate(load_inputs([str(out)]), checks=False)


def test_robot_colours_follow_the_plans_robot_order():
    assert robot_colours(["B", "A", "R3"]) == {"B": robot_colour(0), "A": robot_colour(1), "R3": robot_colour(2)}


def test_a_robot_has_one_colour_in_the_chunk_picture_and_the_gantt_chart(planned, tmp_path):
    out, record, chunks, schedule, pic, result = planned
    names = [r["name"] for r in record["robots"]]
    # one robot order: job.json's robots, the schedule's sequences, the simulation's robots
    assert names == list(schedule.sequences) == [r.name for r in result.robots]
    colours = robot_colours(names)
    busy = [n for n in names if schedule.sequences[n]]
    assert len(busy) == len(names)  # every robot prints (so every colour is tested)
    img = _pixels(out / "chunks.png")
    assert (img == np.asarray(pic.image)).all()  # the bundle's picture is the one examined
    bare = pic.ids.copy()
    for _, _, (x0, y0, x1, y1) in pic.labels:
        bare[y0:y1 + 1, x0:x1 + 1] = -2
    for k, ch in enumerate(chunks.chunks):
        px = img[bare == k]
        assert len(px) > 100 and _shaded(px, colours[schedule.robot_of(ch.id)]).all(), ch.id
    # the Gantt chart's rows, top to bottom, in the same order and the same colours
    gantt = _pixels(render_gantt(result, tmp_path / "gantt.png"))
    rows = [float(np.median(np.nonzero(np.abs(gantt - colours[n]).sum(axis=-1) < 1)[0])) for n in names]
    assert rows == sorted(rows) and len(set(rows)) == len(rows), rows


def _label_checks(pic: rc.ChunkPicture, chunks: ChunkSet) -> None:
    """Every label drawn lies wholly on its own chunk's visible pixels, no two overlap, and every
    chunk is labelled or named among those left out."""
    index = {c.id: k for k, c in enumerate(chunks.chunks)}
    for cid, text, (x0, y0, x1, y1) in pic.labels:
        assert x1 > x0 + 8 and y1 > y0 + 8, text
        assert (pic.ids[y0:y1 + 1, x0:x1 + 1] == index[cid]).all(), text
    boxes = [b for _, _, b in pic.labels]
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            assert a[2] < b[0] or b[2] < a[0] or a[3] < b[1] or b[3] < a[1], (a, b)
    assert len(pic.labels) + len(pic.left_out) == len(chunks.chunks)


def test_labels_lie_on_their_own_chunk_in_the_bundles_picture(planned):
    _, _, chunks, schedule, pic, _ = planned
    _label_checks(pic, chunks)
    assert not pic.left_out
    # the chunk's id first (as the Gantt chart and the viewer name it), then its robot and order;
    # the id alone on a chunk too small for both
    full = {c.id: f"{c.id} · {rc.order_label(schedule.robot_of(c.id), schedule.order_of(c.id))}"
            for c in chunks.chunks}
    assert sorted(cid for cid, _, _ in pic.labels) == sorted(full)
    assert all(t in (full[cid], cid) for cid, t, _ in pic.labels)
    assert sum(t == full[cid] for cid, t, _ in pic.labels) >= len(full) / 2


def test_a_torus_chunk_is_labelled_on_the_ring_not_in_its_hole():
    ring = trimesh.creation.torus(100.0, 30.0, major_sections=64, minor_sections=24)
    ring.apply_translation([0.0, 0.0, 30.0])
    job = chunk_job(solid_from_arrays(np.asarray(ring.vertices), np.asarray(ring.faces)), robots=1)
    assert [c.id for c in job.chunks.chunks] == ["C"]
    pic = rc.chunk_picture(job.chunks, schedule=job.assignment)
    _label_checks(pic, job.chunks)
    (_, _, (x0, y0, x1, y1)), = pic.labels
    assert pic.ids[(y0 + y1) // 2, (x0 + x1) // 2] == 0
    # the hole shows: background between the ring's left and right halves on the ring's middle row
    rows, cols = np.nonzero(pic.ids == 0)
    middle = pic.ids[(rows.min() + rows.max()) // 2, cols.min():cols.max() + 1]
    assert (middle == -1).sum() > 50


def test_labels_of_a_seed2_car_of_five_chunks_stay_on_their_chunks():
    job = chunk_job(car(700.0), robots=2)
    for schedule in (job.assignment, None):  # by id and robot ("L1 · A2"), and by id ("C", "L1")
        pic = rc.chunk_picture(job.chunks, schedule=schedule)
        _label_checks(pic, job.chunks)
        assert len(pic.labels) == 5




def test_labels_of_a_64_chunk_grid_never_overlap():
    chunks = fleet_layouts.box_grid(8, 8)
    ids = [c.id for c in chunks.chunks]
    sched = Assignment({r: tuple(ids[k::8]) for k, r in enumerate(robot_names(8))}, "test")
    pic = rc.chunk_picture(chunks, schedule=sched)
    _label_checks(pic, chunks)
    assert len(pic.labels) == 64


def test_a_chunk_too_small_for_its_label_is_named_in_the_footnote():
    chunks = fleet_layouts.box_grid(3, 1, tiny=(1, 0))
    pic = rc.chunk_picture(chunks)
    _label_checks(pic, chunks)
    assert pic.left_out == ["r0c1"] and sorted(c for c, _, _ in pic.labels) == ["r0c0", "r0c2"]
    foot = np.asarray(pic.image)[-40:].astype(int)
    assert (np.abs(foot - rc.BACKGROUND).sum(axis=-1) > 100).sum() > 200  # its text
    plain = rc.chunk_picture(fleet_layouts.box_grid(3, 1))
    assert not plain.left_out and (np.asarray(plain.image)[-40:] == rc.BACKGROUND).all()


def test_the_title_writes_the_makespan_as_the_gantt_chart_does():
    from types import SimpleNamespace

    short = SimpleNamespace(strategy="list", makespan=43.0, lower_bound=42.6)
    assert rc.schedule_title(3, 2, short) == "3 chunks, 2 robots, schedule list, makespan 0:00:43 (LB 0:00:43)"
    long = SimpleNamespace(strategy="exact", makespan=2 * 86400 + 11 * 3600 + 12 * 60 + 52, lower_bound=3600.0)
    assert rc.schedule_title(1, 1, long).endswith("makespan 2 d 11:12:52 (LB 1:00:00)")
