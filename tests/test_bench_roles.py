"""The slicing benchmark's own G-code reader (volume per role from ``;TYPE:`` comments) and its
check that every extrusion lies inside the model, on tiny hand-written inputs."""
import math
import sys
from pathlib import Path

import manifold3d
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import bench_slicing  # noqa: E402
import large_part  # noqa: E402

AREA = math.pi * (1.75 / 2) ** 2

# PrusaSlicer's names, relative E, a retraction and its undo (not extrusion), two layers
PRUSA = """\
M83
G1 Z0.2 F600
;TYPE:External perimeter
G1 X10 Y0 E1.0
;TYPE:Overhang perimeter
G1 X10 Y10 E0.5
G1 E-0.8
G1 E0.8
;TYPE:Solid infill
G1 X0 Y10 E2.0
;TYPE:Bridge infill
G1 X0 Y0 E0.25
G1 Z0.4
;TYPE:Top solid infill
G1 X10 Y0 E0.75
;TYPE:Internal infill
G1 X10 Y10 E3.0
;TYPE:Gap fill
G1 X0 Y10 E0.125
;TYPE:Skirt/Brim
G1 X0 Y0 E0.5
"""

# CuraEngine's names, absolute E with G92, and an extrusion before the first ;TYPE:
CURA = """\
M82
G92 E0
G1 Z0.2 X1 Y1 E0.5
;TYPE:WALL-OUTER
G1 X10 Y1 E1.5
;TYPE:WALL-INNER
G1 X10 Y10 E2.5
;TYPE:SKIN
G92 E0
G1 X1 Y10 E4.0
;TYPE:FILL
G1 X1 Y1 E4.5
"""


def read(tmp_path, text, **kw):
    """The reader's answer for G-code ``text`` (volumes are rounded to 0.1 mm³, hence the
    tolerances of 0.03 mm of filament below)."""
    path = tmp_path / "x.gcode"
    path.write_text(text)
    return bench_slicing.read_gcode(path, **kw)


def test_prusaslicer_names_make_the_categories(tmp_path):
    summary, moves = read(tmp_path, PRUSA)
    roles = {k: v / AREA for k, v in summary["roles_mm3"].items()}
    assert roles == pytest.approx({"perimeters": 1.5, "solid": 2.75, "bridge": 0.25, "sparse": 3.0,
                                   "gap fill": 0.125, "other": 0.5}, abs=0.03)
    assert summary["filament_mm"] == pytest.approx(8.125, abs=0.01)
    assert summary["layers"] == 2
    assert moves is None


def test_curaengine_names_and_absolute_e(tmp_path):
    summary, _ = read(tmp_path, CURA)
    roles = {k: v / AREA for k, v in summary["roles_mm3"].items()}
    assert roles == pytest.approx({"perimeters": 2.0, "solid": 4.0, "bridge": 0.0, "sparse": 0.5,
                                   "gap fill": 0.0, "other": 0.5}, abs=0.03)
    assert summary["volume_mm3"] == pytest.approx(7.0 * AREA, abs=0.1)


def test_no_type_comments_gives_no_roles(tmp_path):
    summary, _ = read(tmp_path, "M83\nG1 Z0.2 X5 Y5 E1\nG1 X6 E1 ; perimeter\n")
    assert summary["roles_mm3"] is None
    assert summary["volume_mm3"] == pytest.approx(2 * AREA, abs=0.1)


def test_moves_kept_with_their_heights(tmp_path):
    _, moves = read(tmp_path, PRUSA, keep_moves=True)
    assert moves.shape == (8, 5)
    assert moves[0].tolist() == [0.0, 0.0, 10.0, 0.0, 0.2]
    assert moves[4].tolist() == [0.0, 0.0, 10.0, 0.0, 0.4]


@pytest.fixture(scope="module")
def cube_with_hole(tmp_path_factory):
    """A 20 mm cube with a 10 mm square hole through it, as a binary STL (centred at the origin:
    the check places it at the bed centre, 500, 500)."""
    part = manifold3d.Manifold.cube((20, 20, 20), center=True) - manifold3d.Manifold.cube((10, 10, 30), center=True)
    mesh = part.translate((0, 0, 10)).to_mesh()
    path = tmp_path_factory.mktemp("mesh") / "cube.stl"
    large_part.write_binary_stl(path, np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts))
    return path


def test_extrusions_inside_and_outside_the_model(cube_with_hole):
    z = 0.4
    moves = np.array([
        [491.0, 491.0, 509.0, 491.0, z],     # along the outer wall, inside: 3 points in
        [491.0, 491.0, 490.9, 509.0, z],     # ends 0.1 mm outside: within half a width
        [497.0, 491.0, 497.0, 496.0, z],     # ends 1 mm into the hole: outside
        [520.0, 520.0, 521.0, 521.0, z],     # far away: 3 points out
        [491.0, 491.0, 492.0, 492.0, 25.0],  # above the part: no section, 3 points out
    ])
    found = bench_slicing.extrusions_outside(cube_with_hole, moves)
    assert found["points"] == 15
    assert found["outside"] == 1 + 3 + 3


def test_large_part_is_the_size_asked():
    part = large_part.coarse_part()
    assert part.bounding_box() == pytest.approx((0, 0, 0, *large_part.SIZE))
    assert part.genus() == 5  # four through holes and the through-window


def test_types_kept_as_written(tmp_path):
    summary, _ = read(tmp_path, CURA)
    assert set(summary["types_mm3"]) == {"(before any ;TYPE:)", "WALL-OUTER", "WALL-INNER", "SKIN", "FILL"}
    assert "(before any ;TYPE:)" not in read(tmp_path, PRUSA)[0]["types_mm3"]
    assert summary["types_mm3"]["SKIN"] == pytest.approx(4.0 * AREA, abs=0.1)


def tool(wall, peak, volume, roles, layers=100, **extra):
    """One tool's entry in a result, as ``bench_mesh`` makes it."""
    return {"wall_median_s": wall, "peak_median_mb": peak, "error": None, "returncodes": [0],
            "volume_mm3": volume, "layers": layers, "roles_mm3": roles, **extra}


def roles(perimeters, solid, bridge, sparse):
    return {"perimeters": perimeters, "solid": solid, "bridge": bridge, "sparse": sparse,
            "gap fill": 0.0, "other": 0.0}


def test_verdict_checks_the_issue_targets():
    row = {"mesh": "large.stl", "triangles": 1_500_000, "generated": False, "tools": {
        "cooprint": tool(40.0, 500.0, 1000.0, roles(300, 185, 0, 520),
                         inside={"points": 3000, "outside": 2}),
        "CuraEngine": tool(100.0, 400.0, 990.0, roles(300, 200, 0, 490)),
        "PrusaSlicer": tool(300.0, 700.0, 1040.0, roles(300, 150, 50, 540), layers=101)}}
    found = dict((what.split(" ")[0], ok) for what, ok in bench_slicing.checks(row))
    # total 1000/1040 = 0.96: met; solid + bridge 185/200 = 0.93: met; sparse 0.96: met;
    # layers 100 vs 101: missed; 2 points outside: missed; wall 0.4x <= 0.5x: met; memory 1.25x: missed
    assert found == {"total": True, "solid": True, "sparse": True, "layers": False, "outside": False,
                     "wall": True, "memory": False}
    assert "3 of 7 targets missed" in bench_slicing.verdict(row)
    benchy = row | {"mesh": "benchy.stl", "triangles": 225_154}
    assert ("wall 0.40× (≤ 0.8×)", True) in bench_slicing.checks(benchy)
    other = row | {"mesh": "spot.stl", "triangles": 5_856}
    assert not any(what.startswith("wall") for what, _ in bench_slicing.checks(other))


def test_role_table_marks_what_a_tool_cannot_tell():
    row = {"mesh": "m.stl", "triangles": 10, "generated": True, "tools": {
        "CuraEngine": tool(1.0, 1.0, 990.0, roles(300, 200, 0, 490)),
        "PrusaSlicer": tool(1.0, 1.0, 1040.0, roles(300, 150, 50, 540)),
        "Slic3r": tool(1.0, 1.0, 1100.0, None)}}
    cura, prusa, slic3r = bench_slicing.role_rows(row)
    assert "in solid (SKIN)" in cura and "200 (1.00×)" in cura  # SKIN against solid + bridge
    assert prusa.startswith("| `m.stl` (generated) | PrusaSlicer | 300 (1.00×) | 150 (1.00×) | 50 (1.00×)")
    assert "no `;TYPE:` comments" in slic3r and "1,100 (1.06×)" in slic3r
