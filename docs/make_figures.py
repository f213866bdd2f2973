"""Regenerate the pictures in docs/img (run: .venv/bin/python docs/make_figures.py).

The seed's Fig. 5 cases, on models cooprint generates: a cylinder and a car, each with a short
build depth and a steep slope, and with a deep build depth and a moderate slope.
"""

from __future__ import annotations

from pathlib import Path

from cooprint.chunking import cut_chunks, plan_chunks
from cooprint.config import ChunkingSettings, RobotProfile
from cooprint.models import car, cylinder
from cooprint.config import SlicingSettings
from cooprint.io.mesh import solid_from_arrays
from cooprint.render.chunks import render_chunks
from cooprint.render.paths import render_layer, render_model
from cooprint.slicing import slice_solid

IMG = Path(__file__).parent / "img"

CASES = {
    "fig5a_cylinder_short_steep": (lambda: cylinder(150, 80), RobotProfile(build_depth=120), None),
    "fig5b_cylinder_deep_moderate": (lambda: cylinder(150, 80), RobotProfile(build_depth=300), 45.0),
    "fig5c_car_short_steep": (lambda: car(700), RobotProfile(build_depth=180), None),
    "fig5d_car_deep_moderate": (lambda: car(700), RobotProfile(build_depth=400), 50.0),
}


def main() -> None:
    IMG.mkdir(exist_ok=True)
    for name, (make, robot, theta) in CASES.items():
        solid = make()
        plan = plan_chunks(solid.vertices, robot, ChunkingSettings(theta_deg=theta))
        chunks = cut_chunks(solid, plan)
        render_chunks(chunks, IMG / f"{name}.png", size=(900, 560))
        print(f"{name}: {len(chunks.chunks)} chunks, theta {plan.theta_deg:.1f} deg, "
              f"shift {plan.shift:.1f} mm, build depth {robot.build_depth:g} mm")


def slicer_figures() -> None:
    """A block with a tunnel through it and thin fins on top, sliced (seed Fig. 7 and 9): a layer
    of bottom solid, the layer over the tunnel (a bridge with overhang perimeters), a layer of
    perimeters, gap fill and sparse infill, and the whole part; 0.3 mm layers so that lines show."""
    import manifold3d as m3d
    import numpy as np

    block = m3d.Manifold.cube((60, 40, 16), center=True).translate((0, 0, 8))
    tunnel = m3d.Manifold.cube((70, 14, 8), center=True).translate((0, 0, 8))
    fins = [m3d.Manifold.cube((40, w, 6), center=True).translate((0, y, 19)) for y, w in ((-12, 0.7), (-6, 1.2), (6, 2.2))]
    part = block - tunnel
    for fin in fins:
        part = part + fin
    mesh = part.to_mesh64()
    solid = solid_from_arrays(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts))
    s = SlicingSettings(layer_height=0.3, first_layer_height=0.3)
    sliced = slice_solid(solid, s)
    tops = np.array([layer.z for layer in sliced.layers])
    at = {z: int(np.argmin(abs(tops - z))) for z in (0.9, 12.3, 8.1, 18.0)}
    render_layer(sliced.layers[at[0.9]], IMG / "slice_layer.png", title="layer 3: bottom solid infill")
    render_layer(sliced.layers[at[12.3]], IMG / "slice_layer_bridge.png",
                 title="over the tunnel: a bridge laid across it, overhang perimeters")
    render_layer(sliced.layers[at[8.1]], IMG / "slice_layer_infill.png",
                 title="perimeters and 20% rectilinear infill anchored along them")
    render_layer(sliced.layers[at[18.0]], IMG / "slice_layer_fins.png",
                 title="fins 0.7, 1.2, 2.2 mm: a thin wall; a loop and gap fill; two loops and gap fill")
    render_model(sliced.layers, IMG / "slice_model.png", title="sliced part (0.3 mm layers)")


def simulation_figures() -> None:
    """The demo car planned for two robots and simulated: a frame and the Gantt chart (seed
    Fig. 16); 0.6 mm layers and 1 mm lines (a coarse print, so that the picture reads)."""
    import tempfile

    from cooprint.jobs import run, simulate_bundle
    from cooprint.render.sim import render_gantt, render_snapshot
    from cooprint.simulation import load_inputs, simulate

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "job"
        run(car(700), out, overrides={"slicing.layer_height": 0.6, "slicing.first_layer_height": 0.6,
                                      "slicing.extrusion_width": 1.0, "slicing.nozzle_diameter": 0.8},
            picture=False)
        simulate_bundle(out)
        result = simulate(load_inputs([str(out)]), checks=False)
        render_snapshot(result, 0.62 * result.makespan, IMG / "sim_frame.png")
        render_gantt(result, IMG / "sim_gantt.png")


def fleet_figures() -> None:
    """A 1500 x 800 x 20 mm slab planned for six robots on the grid (docs/fleet.md): the chunks
    by robot and order, and the Gantt chart with the critical path and the lower bound; a 2 mm
    nozzle (a coarse print, so that it plans in seconds)."""
    import shutil
    import tempfile

    import manifold3d as m3d
    import numpy as np

    from cooprint.jobs import run
    from cooprint.render.sim import render_gantt
    from cooprint.simulation import load_inputs, simulate

    mesh = m3d.Manifold.cube((1500.0, 800.0, 20.0), center=True).translate((0, 0, 10)).to_mesh64()
    slab = solid_from_arrays(np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts), path="<slab>",
                             fmt="generated")
    coarse = {"slicing.nozzle_diameter": 2.0, "slicing.layer_height": 1.6, "slicing.first_layer_height": 1.6,
              "slicing.extrusion_width": 3.0, "slicing.infill_density": 0.05, "slicing.perimeters": 1,
              "slicing.top_layers": 1, "slicing.bottom_layers": 1, "chunking.layout": "grid"}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "job"
        run(slab, out, overrides=coarse, robots=6)
        shutil.copy(out / "chunks.png", IMG / "fleet_chunks.png")
        inp = load_inputs([str(out)])
        result = simulate(inp, checks=False)
        render_gantt(result, IMG / "fleet_gantt.png", critical=inp.critical_path, lower_bound=inp.lower_bound)


if __name__ == "__main__":
    main()
    slicer_figures()
    simulation_figures()
    fleet_figures()
