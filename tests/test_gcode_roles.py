"""G-code's ``;TYPE:`` comments give the material its path roles (trial 16: a G-code preview
coloured all its material "infill"): PrusaSlicer's, Orca's, Cura's and cooprint's own names, in
the compiled sweep and in the line reader alike; material without a type stays infill."""

from __future__ import annotations

import numpy as np

from cooprint.program.commands import MOVE
from cooprint.simulation.inputs import _read_gcode_lines, read_gcode
from cooprint.slicing.paths import INFILL, PERIMETER_INNER, PERIMETER_OUTER, SKIN, TOP_SKIN, TRAVEL

GCODE = """G90
M83
G1 Z0.2 F600
G1 X10 Y10 F3000
G1 X20 Y10 E1.0 ; no type yet
;TYPE:External perimeter
G1 X20 Y20 E1.0
;TYPE:Perimeter
G1 X10 Y20 E1.0
G0 X12 Y12
  ;TYPE:Solid infill
G1 X18 Y12 E0.8
;TYPE:Internal infill
G1 X18 Y18 E0.8
;TYPE:WALL-OUTER
G1 X10 Y18 E0.8
;TYPE:WALL-INNER
G1 X10 Y12 E0.8
;TYPE:SKIN
G1 X12 Y14 E0.3
;TYPE:Top surface
G1 X14 Y14 E0.3
;TYPE:Support material
G1 X16 Y14 E0.3
G1 X16 Y16 ; TYPE:Perimeter in a comment after a move changes nothing
G1 X17 Y16 E0.3
"""
WANT = [INFILL, INFILL, INFILL, PERIMETER_OUTER, PERIMETER_INNER, PERIMETER_INNER, SKIN, INFILL, PERIMETER_OUTER,
        PERIMETER_INNER, SKIN, TOP_SKIN, INFILL, INFILL, INFILL]


def test_type_comments_give_the_moves_roles_in_both_readers(tmp_path):
    path = tmp_path / "part.gcode"
    path.write_text(GCODE)
    swept = read_gcode(path).program
    reference = _read_gcode_lines(path, GCODE).program
    for prog in (swept, reference):
        moves = prog.kind == MOVE
        assert prog.role[moves].tolist() == WANT
        assert np.all(prog.role[~moves] == TRAVEL)
    assert swept.role.tolist() == reference.role.tolist()
    on = swept.width > 0  # the material: all its roles, not only infill
    assert set(swept.role[on].tolist()) == {PERIMETER_OUTER, PERIMETER_INNER, SKIN, TOP_SKIN, INFILL}


def test_a_file_with_host_lines_keeps_its_roles(tmp_path):
    text = GCODE.replace(";TYPE:Perimeter\n", ";TYPE:Perimeter\nM118 NOTIFY half\n")
    path = tmp_path / "part.gcode"
    path.write_text(text)
    swept = read_gcode(path).program
    assert swept.role.tolist() == _read_gcode_lines(path, text).program.role.tolist()
    assert swept.role[swept.kind == MOVE].tolist() == WANT
