"""Issue 17: the overhang rule and the bridge logic agree, and a model gets the same findings
whether it is sliced alone (G-code, placed on a printer's bed) or planned for one robot (.coop,
on the floor): material laid as a bridge's thread (bridge infill, overhang perimeter) anchored at
both ends is no overhang; a bridge that runs out into the air is; other roles keep the rule. The
simulator's material is the G-code's E, round threads included."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cooprint.config import RobotProfile, SlicingSettings
from cooprint.program.commands import MOVE, coop_text, parse_coop
from cooprint.program.gcode import gcode_text
from cooprint.program.stream import canonical_program
from cooprint.simulation import SimInput, load_inputs, simulate, summary
from cooprint.simulation.timeline import SimRobot
from cooprint.slicing.paths import BRIDGE, OVERHANG, PERIMETER_OUTER, SKIN, TRAVEL, LayerPaths, flow_area

H = 0.2  # layer height, mm
W = 0.45  # line width, mm
LEGS = 10  # layers of the legs
BED = np.array([123.4, 87.65, 0.0])  # where "slice" puts the part (not on the overhang check's cells)


def _lines(x0: float, x1: float, y0: float, y1: float, spacing: float) -> list[np.ndarray]:
    """Lines along x from x0 to x1, every ``spacing`` in y, alternating direction (a zigzag's lines)."""
    ys = np.arange(y0, y1 + 1e-9, spacing)
    return [np.array([[x0, y], [x1, y]])[::1 - 2 * (k % 2)] for k, y in enumerate(ys)]


def _zigzag(x0: float, x1: float, y0: float, y1: float, spacing: float) -> np.ndarray:
    """One path: the lines joined at their ends (the slicer's zigzag), (k, 2)."""
    return np.vstack(_lines(x0, x1, y0, y1, spacing))


def _layer(z: float, paths: list[tuple[np.ndarray, int, float]]) -> LayerPaths:
    """A layer of ``paths``, a travel path between each two (as the slicer lays them out)."""
    out = [paths[0]]
    for p in paths[1:]:
        out += [(np.array([out[-1][0][-1], p[0][0]]), TRAVEL, 0.0), p]
    return LayerPaths.build(z, H, out)


def _model(legs: list[tuple[float, float]], slab: tuple[float, float], role: int,
           joined: bool = True) -> list[tuple[int, LayerPaths]]:
    """Legs (x ranges, 10 mm deep, LEGS layers of solid lines 2 mm apart) and on them one slab
    layer (x range, 10 mm deep) of lines 0.45 mm apart laid with ``role``: one zigzag path, or
    each line its own path (``joined=False``)."""
    layers = []
    for i in range(LEGS):
        paths = [(_zigzag(a, b, 0.0, 10.0, 2.0), SKIN, W) for a, b in legs]
        layers.append((i, _layer((i + 1) * H, paths)))
    top = _lines(slab[0], slab[1], 0.0, 10.0, W) if not joined else [_zigzag(slab[0], slab[1], 0.0, 10.0, W)]
    layers.append((LEGS, _layer((LEGS + 1) * H, [(p, role, W) for p in top])))
    return layers


def _overhangs(result) -> list[tuple[int, float]]:
    return sorted((f.count, round(f.position[2], 3)) for f in result.findings if f.kind == "overhang")


def _both_ways(layers, tmp_path) -> tuple[list, list, dict, dict]:
    """The model's overhang findings and summaries: as a G-code on a printer's bed (shifted by
    BED, read back by the simulator's G-code reader) and as a robot's .coop program on the floor."""
    s = SlicingSettings()
    prog = canonical_program("C", layers)
    on_bed = dataclasses.replace(prog, xyz=prog.xyz + BED)
    gcode = tmp_path / "part.gcode"
    gcode.write_text(gcode_text([on_bed], s))
    sliced = simulate(load_inputs([str(gcode)]))
    robot = SimRobot("A", parse_coop(coop_text(prog), "A"), None, np.array([0.0, 1.0]))
    planned = simulate(SimInput([robot], RobotProfile(), s, "test"))
    return _overhangs(sliced), _overhangs(planned), summary(sliced), summary(planned)


def test_an_anchored_bridge_is_no_overhang_either_way(tmp_path):
    """A table: two legs 20 mm apart and a slab laid across as bridge infill (each line from one
    leg to the other): no overhang, sliced or planned; the same slab as solid infill is one."""
    sliced, planned, _, _ = _both_ways(_model([(0.0, 10.0), (30.0, 40.0)], (0.0, 40.0), BRIDGE), tmp_path)
    assert sliced == planned == []
    sliced, planned, _, _ = _both_ways(_model([(0.0, 10.0), (30.0, 40.0)], (0.0, 40.0), SKIN), tmp_path)
    assert sliced == planned and sliced and all(z == pytest.approx((LEGS + 1) * H) for _, z in sliced)
    # lines laid one by one (a travel between them) are held as well as a zigzag's
    sliced, planned, _, _ = _both_ways(_model([(0.0, 10.0), (30.0, 40.0)], (0.0, 40.0), OVERHANG, joined=False),
                                       tmp_path)
    assert sliced == planned == []


def test_a_bridge_into_the_air_is_an_overhang_either_way(tmp_path):
    """A cantilever: one leg and a slab reaching 20 mm past it, as bridge infill or as solid
    infill: its tip is an overhang both ways, the same points. The zigzag goes out and back from
    the one leg, so each end of its stretches over air is on the leg: it does not run straight
    between them, and is not held either."""
    found = {}
    for role in (BRIDGE, SKIN):
        for joined in (True, False):
            sliced, planned, _, _ = _both_ways(_model([(0.0, 10.0)], (0.0, 30.0), role, joined), tmp_path)
            assert sliced == planned and sliced, (role, joined)
            found[role, joined] = sum(n for n, _ in sliced)
    # the same points whatever the role: a bridge's thread over air with one end free is no bridge
    assert found[BRIDGE, True] == found[SKIN, True] and found[BRIDGE, False] == found[SKIN, False]


def test_other_roles_keep_the_rule(tmp_path):
    """An outer perimeter laid across the gap between the legs is an overhang (only the round
    threads of bridges and overhang perimeters are held at their ends)."""
    sliced, planned, _, _ = _both_ways(_model([(0.0, 10.0), (30.0, 40.0)], (0.0, 40.0), PERIMETER_OUTER), tmp_path)
    assert sliced == planned and sliced


def test_the_material_of_a_bridge_is_its_round_thread_and_the_gcode_e(tmp_path):
    """A bridge's thread is a circle of its width (flow_area): the simulator's material is the
    G-code's E (filament area x E) read back, and the .coop program's, and the G-code reader
    gives the bridge moves their width back."""
    layers = _model([(0.0, 10.0), (30.0, 40.0)], (0.0, 40.0), BRIDGE)
    want = sum(float((flow_area(lp.width, lp.height, lp.role) * lp.lengths())[lp.role != TRAVEL].sum())
               for _, lp in layers)
    _, _, sliced, planned = _both_ways(layers, tmp_path)
    text = (tmp_path / "part.gcode").read_text()
    e = float(text.rsplit("; filament used [mm] = ", 1)[1])
    fil_area = np.pi * (SlicingSettings().filament_diameter / 2) ** 2
    assert sliced["robots"][0]["material_mm3"] == pytest.approx(want, rel=1e-5)  # E has 5 decimals
    assert planned["robots"][0]["material_mm3"] == pytest.approx(want, rel=1e-9)
    assert e * fil_area == pytest.approx(want, rel=1e-4)  # the total has 2 decimals
    (robot,) = load_inputs([str(tmp_path / "part.gcode")]).robots
    p = robot.program
    bridge = (p.kind == MOVE) & (p.role == BRIDGE) & (p.width > 0)
    assert bridge.sum() > 20 and np.allclose(p.width[bridge], W, atol=0.01)


def _table(legs: list[tuple[float, float]], slab: tuple[float, float]):
    """Legs (x ranges, 10 mm deep, 6 mm high) and a slab 2 mm thick on them (x range)."""
    import manifold3d as m3d

    parts = [m3d.Manifold.cube((b - a, 10.0, 6.0)).translate((a, 0.0, 0.0)) for a, b in legs]
    parts.append(m3d.Manifold.cube((slab[1] - slab[0], 10.0, 2.0)).translate((slab[0], 0.0, 6.0)))
    return m3d.Manifold.batch_boolean(parts, m3d.OpType.Add)


@pytest.mark.parametrize("legs, slab", [([(0.0, 10.0), (30.0, 40.0)], (0.0, 40.0)),  # a table
                                        ([(0.0, 10.0)], (0.0, 30.0))],  # a cantilever
                         ids=["table", "cantilever"])
def test_a_model_sliced_alone_and_planned_for_one_robot_gets_the_same_overhangs(tmp_path, legs, slab):
    """The slicer's own output both ways: `cooprint slice` (G-code, centred on the bed) and
    `cooprint run --robots 1` (a .coop program, the part where it stands), simulated: the same
    overhang points at the same heights. Bridge material is never among them unless the bridge
    runs into the air (the cantilever's slab)."""
    from solids import to_trimesh

    from cooprint.cli import main
    from cooprint.jobs import run

    stl = tmp_path / "part.stl"
    to_trimesh(_table(legs, slab)).export(stl)
    gcode = tmp_path / "part.gcode"
    assert main(["slice", str(stl), "--out", str(gcode), "-q", "--executor", "inline"]) == 0
    run(stl, tmp_path / "job", robots=1, picture=False)
    found, bridged = [], []
    for inputs in ([str(gcode)], [str(tmp_path / "job")]):
        res = simulate(load_inputs(inputs, programs=False))  # a bundle's programs piece by piece, as the CLI
        hits = [f for f in res.findings if f.kind == "overhang"]
        found.append((sum(f.count for f in hits), sorted({round(f.position[2], 2) for f in hits})))
        tl = res.timelines[res.robots[0].name]
        first_slab = tl.on & (np.abs(tl.p1[:, 2] - 6.2) < 1e-6)
        bridged.append(bool(np.isin(res.robots[0].program.role[tl.index[first_slab]], (BRIDGE,)).any()))
    # the same heights, and nearly the same points: the two programs are not the same to the
    # sample (the slicer lays infill on the bed's grid, so the part centred on the bed and the
    # part where it stands get paths a little apart)
    assert found[0][1] == found[1][1] and found[0][0] == pytest.approx(found[1][0], rel=0.03)
    assert bridged[0] == bridged[1]
    if len(legs) == 1:  # the cantilever's slab hangs 20 mm past its leg: found both ways, bridged or not
        assert found[0][0] > 0 and found[0][1][0] == pytest.approx(6.2)
    elif bridged[0]:  # the table's slab laid as a bridge from leg to leg: nothing found
        assert found[0][0] == found[1][0] == 0


def test_timelines_timed_piece_by_piece_hold_the_same_bridges():
    """A bundle's programs are timed piece by piece and their moves' lengths computed on demand
    (timeline.Lengths): the overhang check holds the same threads as with the lengths kept."""
    from cooprint.simulation.checks import STEP, Material, overhangs
    from cooprint.simulation.timeline import Lengths

    for legs, slab in (([(0.0, 10.0), (30.0, 40.0)], (0.0, 40.0)), ([(0.0, 10.0)], (0.0, 30.0))):
        for joined in (True, False):
            prog = canonical_program("C", _model(legs, slab, BRIDGE, joined))
            robot = SimRobot("A", prog, None, np.array([0.0, 1.0]))
            res = simulate(SimInput([robot], RobotProfile(), SlicingSettings(), "test"), checks=False)
            tl = res.timelines["A"]
            lazy = {"A": dataclasses.replace(tl, length=Lengths(tl.p0, tl.p1))}
            material = Material.sample(res.robots, res.timelines, STEP, H)
            kept = overhangs(res.robots, res.timelines, material, SlicingSettings())
            assert overhangs(res.robots, lazy, material, SlicingSettings()) == kept
            assert bool(kept) == (len(legs) == 1)
