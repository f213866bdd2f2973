"""Issue 17: the same model sliced alone and planned for one robot gets the same findings. A
chunk's surfaces come from its object's sections (``slice_chunks(context=...)``): a bridge over a
tunnel that a cut crosses keeps the anchor on the other side of the cut and runs across the
tunnel in every chunk, and the chunks together lay the solid and bridge material the part sliced
alone lays."""

from __future__ import annotations

import manifold3d as m3d
import numpy as np
import pytest

from cooprint.slicing.paths import BRIDGE, SKIN, TOP_SKIN, flow_area

TUNNELS = (100.0, 185.0, 300.0)  # where the tunnels start along y; each 15 mm wide, z 2..8
SOLID = (SKIN, TOP_SKIN, BRIDGE)


def _tunnels() -> m3d.Manifold:
    """A 20 x 400 x 12 mm bar with three 15 mm tunnels across it (x), 6 mm high from z = 2; the
    planner's cut between the chunks L1 and C crosses the middle one."""
    bar = m3d.Manifold.cube((20.0, 400.0, 12.0))
    holes = [m3d.Manifold.cube((22.0, 15.0, 6.0)).translate((-1.0, y, 2.0)) for y in TUNNELS]
    return bar - m3d.Manifold.batch_boolean(holes, m3d.OpType.Add)


def _volume(layers, roles) -> float:
    """Volume laid with ``roles`` by ``layers`` (LayerPaths), mm3 (flow_area: round bridges)."""
    total = 0.0
    for lp in layers:
        sel = np.isin(lp.role, roles)
        total += float((lp.lengths()[sel] * flow_area(lp.width[sel], lp.height, lp.role[sel])).sum())
    return total


@pytest.fixture(scope="module")
def bar(tmp_path_factory):
    """The bar's STL, its G-code sliced alone, its one-robot job (`cooprint run`), and the job's
    chunks' layers with the part's own (made in memory)."""
    from solids import to_trimesh

    from cooprint.cli import main
    from cooprint.config import load_settings
    from cooprint.io.mesh import solid_from_arrays
    from cooprint.jobs import coop_job, run
    from cooprint.slicing import slice_solid

    tmp = tmp_path_factory.mktemp("tunnels")
    stl = tmp / "tunnels.stl"
    tm = to_trimesh(_tunnels())
    tm.export(stl)
    gcode = tmp / "tunnels.gcode"
    assert main(["slice", str(stl), "--out", str(gcode), "-q", "--executor", "inline"]) == 0
    run(stl, tmp / "job", robots=1, picture=False)
    job = coop_job(stl, load_settings(), robots=1)
    whole = slice_solid(solid_from_arrays(tm.vertices, tm.faces), load_settings().slicing, workers=1)
    chunks = {cid: [lp for _, lp in layers] for cid, layers in job.layers.items()}
    return gcode, tmp / "job", chunks, whole.layers


def test_the_tunnels_bar_planned_for_one_robot_gets_the_findings_it_gets_sliced_alone(bar):
    """`slice` + `simulate` and `run --robots 1 --simulate`: no overhang either way (before,
    the chunk whose cut crosses a tunnel laid that tunnel's roof at 45 degrees over the air: 12
    overhang findings)."""
    from cooprint.simulation import load_inputs, simulate

    gcode, job, _, _ = bar
    found = []
    for inputs in ([str(gcode)], [str(job)]):
        res = simulate(load_inputs(inputs, programs=False))
        found.append(sorted((f.chunk, f.count) for f in res.findings if f.kind == "overhang"))
    assert found == [[], []]


def test_every_chunk_bridges_its_tunnels_across_them(bar):
    """The roofs of the tunnels (the first layer over z = 8) are bridges in every chunk, every
    thread along y (90 degrees: from one side of the tunnel to the other), as in the part sliced
    alone; over the tunnel the cut crosses, the chunk before the cut lays its threads up to the
    cut, anchored on the far side (before: at 45 degrees, over the air)."""
    _, _, chunks, whole = bar
    assert len(chunks) >= 2
    for name, layers in [*chunks.items(), ("whole", whole)]:
        for lp in layers:
            if not 8.0 < lp.z < 8.0 + 1.5 * lp.height:  # the roof
                continue
            for k in np.flatnonzero(lp.role == BRIDGE):
                d = np.diff(lp.points[lp.offsets[k]:lp.offsets[k + 1]], axis=0)
                d = d[np.hypot(d[:, 0], d[:, 1]) > 1.0]
                angle = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 180.0
                assert np.all(np.abs(angle - 90.0) < 1.0), (name, lp.z, np.unique(np.round(angle)))
    roofs = [lp.points[lp.offsets[k]:lp.offsets[k + 1]] for layers in chunks.values() for lp in layers
             if 8.0 < lp.z < 8.0 + 1.5 * lp.height for k in np.flatnonzero(lp.role == BRIDGE)]
    y = np.concatenate(roofs)[:, 1]
    for y0 in TUNNELS:  # each tunnel's roof bridged from one side to (about) the other
        over = y[(y > y0 - 5.0) & (y < y0 + 20.0)]
        assert over.min() <= y0 + 1.0 and over.max() >= y0 + 13.0, (y0, over.min(), over.max())


def test_the_chunks_lay_the_solid_and_bridge_material_of_the_part(bar):
    """The chunks' solid + bridge volume (top solid, solid, bridge) is within 2% of the part's
    sliced alone: no bottoms where a chunk stands on its neighbour, no tops missed."""
    _, _, chunks, whole = bar
    part = _volume(whole, SOLID)
    planned = sum(_volume(layers, SOLID) for layers in chunks.values())
    assert planned == pytest.approx(part, rel=0.02)
    bridges = sum(_volume(layers, (BRIDGE,)) for layers in chunks.values())
    assert bridges == pytest.approx(_volume(whole, (BRIDGE,)), rel=0.05)
