"""Slicer: exact layers on a cube, skins, infill inside the model, volume, G-code read back."""

import math
import re

import numpy as np
import pytest

from cooprint.cli import main
from cooprint.config import SlicingSettings
from cooprint.io.mesh import solid_from_arrays
from cooprint.program.build import layer_pieces
from cooprint.program.gcode import gcode_text
from cooprint.slicing import INFILL, PERIMETER_INNER, PERIMETER_OUTER, SKIN, TRAVEL, layer_tops, slice_solid
from cooprint.slicing.infill import hatch, hatch_flat
from cooprint.slicing.paths import BRIDGE, TOP_SKIN, extrusion_spacing, flow_area
from cooprint.slicing.slicer import layer_range

from solids import box, to_trimesh, tube


def solid(man):
    tm = to_trimesh(man)
    return solid_from_arrays(tm.vertices, tm.faces)


@pytest.fixture(scope="module")
def cube():
    return slice_solid(solid(box(20, 20, 10)), SlicingSettings())


def test_layer_count_and_heights():
    s = SlicingSettings(first_layer_height=0.3, layer_height=0.2)
    tops = layer_tops(10.0, s)
    assert len(tops) == 1 + math.ceil((10 - 0.3) / 0.2)
    assert tops[0] == pytest.approx(0.3) and np.allclose(np.diff(tops), 0.2)
    assert tops[-1] >= 10.0 - 1e-9


#: A unit cube's corners and outward triangles (scaled to a box of any height, in float64: a top at
#: exactly 10.1 mm is exactly the middle of the 51st 0.2 mm layer).
CORNERS = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float64)
CUBE_FACES = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                       [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])


@pytest.mark.parametrize("height, n", [(10.05, 50), (10.1, 51), (10.13, 51)])
def test_the_last_layer_is_the_last_whose_middle_is_under_the_top(height, n):
    """PrusaSlicer 2.5's layers (generate_object_layers): one more 0.2 mm layer while its middle
    is under the top. A 10.05 mm box has 50 (the 0.05 mm over the 50th is not printed; the 51st
    would be sliced above the box), a 10.13 mm box 51 (the 51st sliced at 10.1 mm, ending at
    10.2), and a 10.1 mm box 51 too: the 51st layer's plane is on the top face, which gives the
    section under it (as PrusaSlicer's slicer: occt_tr12j_housing, 320.5 mm, has 1,603 layers).
    Every count holds for the whole box and for its layer range, and the last layer prints the
    top: the outer loop round the whole 20 mm square, and top skin."""
    s = SlicingSettings()
    box20 = solid_from_arrays(CORNERS * [20.0, 20.0, height], CUBE_FACES)
    assert len(layer_tops(height, s)) == n and layer_range(box20, s) == (0, n)
    sliced = slice_solid(box20, s)
    assert sliced.n_layers == n
    last = sliced.layers[-1]
    assert last.z == pytest.approx(0.2 * n)
    outer = [last.path(k) for k in range(len(last)) if last.role[k] == PERIMETER_OUTER]
    assert len(outer) == 1
    span = outer[0].max(axis=0) - outer[0].min(axis=0)
    assert span == pytest.approx([20 - 0.45, 20 - 0.45], abs=1e-3)
    assert (last.role == TOP_SKIN).any()


def test_cube_perimeters_are_exact_squares(cube):
    assert extrusion_spacing(0.45, 0.2) == pytest.approx(0.45 - 0.2 * (1 - math.pi / 4))
    assert cube.n_layers == 50
    for i, layer in enumerate(cube.layers):
        w = 0.4 if i == 0 else 0.45  # the first layer's width (2 x its height), as PrusaSlicer
        sp = extrusion_spacing(w, 0.2)  # lines touch with their rounded sides: 0.407 mm apart
        outer = [layer.path(k) for k in range(len(layer)) if layer.role[k] == PERIMETER_OUTER]
        inner = [layer.path(k) for k in range(len(layer)) if layer.role[k] == PERIMETER_INNER]
        assert len(outer) == 1 and len(inner) == 1
        for ring, half in ((outer[0], 10 - w / 2), (inner[0], 10 - w / 2 - sp)):
            assert np.allclose(ring[0], ring[-1])  # closed loop
            assert np.allclose(np.abs(ring).max(axis=0), half)
            assert np.allclose(np.sort(np.abs(ring[:-1]), axis=0), half)  # only the four corners


@pytest.mark.parametrize("gap, loops", [(0.05, 0), (0.2, 0), (0.3, 1)])
def test_a_perimeter_loop_is_not_laid_in_a_sliver_whose_sides_nearly_coincide(gap, loops):
    """A strip whose inner loop's region is ``gap`` wide: 0.05 mm (the OCCT housing's sliver
    between a hole and a cut face, where two loop sides 0.05 mm apart laid material twice) gets
    no inner loop, nor does 0.2 mm (PrusaSlicer opens a loop's region by 0.6 x half a spacing,
    0.12 mm: what is narrower is gap fill); 0.3 mm keeps it."""
    w = 0.45
    sp = extrusion_spacing(w, 0.2)
    wide = w + 2 * sp + gap  # the inner loop's centre line region: gap wide
    layers = slice_solid(solid(box(wide, 20, 1)), SlicingSettings()).layers
    for layer in layers[1:]:  # the first layer's lines are narrower
        roles = [layer.role[k] for k in range(len(layer))]
        assert roles.count(PERIMETER_OUTER) == 1 and roles.count(PERIMETER_INNER) == loops


def test_skins_on_top_and_bottom_layers_only(cube):
    """4 solid layers at the bottom, 4 at the top (the first over the sparse infill a bridge,
    the last the top surface, as PrusaSlicer's bridge over infill and top solid infill)."""
    roles = [set(layer.role.tolist()) - {PERIMETER_OUTER, PERIMETER_INNER, TRAVEL} for layer in cube.layers]
    assert roles[:4] == [{SKIN}] * 4
    assert roles[4:46] == [{INFILL}] * 42
    assert roles[46:] == [{BRIDGE}, {SKIN}, {SKIN}, {TOP_SKIN}]


def test_rectilinear_infill_alternates_direction(cube):
    def direction(layer):  # of the longest infill segment (the ends are anchored along the perimeters)
        d = np.concatenate([np.diff(layer.path(k), axis=0) for k in range(len(layer)) if layer.role[k] == INFILL])
        d = d[np.argmax(np.linalg.norm(d, axis=1))]
        return round(math.degrees(math.atan2(abs(d[1]), d[0]))) % 180

    assert {direction(cube.layers[10]), direction(cube.layers[11])} == {45, 135}


def test_every_extrusion_inside_the_cross_section():
    t = tube(25, 10, 20)
    sliced = slice_solid(solid(t), SlicingSettings())
    for layer in sliced.layers:
        for k in range(len(layer)):
            if layer.role[k] == TRAVEL:
                continue
            p = layer.path(k)
            r = np.linalg.norm(p, axis=1)
            half = layer.width[k] / 2
            assert r.max() <= 25 - half + 0.05 and r.min() >= 10 + half - 0.05
            mid = np.linalg.norm((p[1:] + p[:-1]) / 2, axis=1)
            assert mid.min() >= 10 + half - 0.05  # no line crosses the hole


def test_solid_infill_extrudes_the_model_volume():
    s = SlicingSettings(infill_density=1.0)
    sliced = slice_solid(solid(box(20, 20, 10)), s)
    vol = 0.0
    for layer in sliced.layers:
        lengths = layer.lengths()
        printing = layer.role != TRAVEL
        vol += float((flow_area(layer.width, layer.height, layer.role) * lengths)[printing].sum())
    assert vol == pytest.approx(20 * 20 * 10, rel=0.08)


def test_parallel_slicing_gives_the_same_layers():
    sol = solid(tube(25, 10, 12))  # 60 layers: two blocks
    one = slice_solid(sol, SlicingSettings(), workers=1)
    two = slice_solid(sol, SlicingSettings(), workers=2)
    assert one.n_layers == two.n_layers == 60
    for a, b in zip(one.layers, two.layers):
        assert np.array_equal(a.points, b.points) and np.array_equal(a.role, b.role)


def test_hatch_square():
    sq = [np.array([[0, 0], [10, 0], [10, 10], [0, 10]], dtype=float)]
    seg = hatch(sq, 1.0, 0.0)
    assert len(seg) == 10  # y = 0..9 (half-open at the top edge)
    assert np.allclose(np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1), 10.0)
    # boustrophedon: consecutive lines run in opposite directions
    dx = seg[:, 1, 0] - seg[:, 0, 0]
    assert np.all(np.sign(dx[1:]) == -np.sign(dx[:-1]))
    holed = sq + [np.array([[3, 3], [3, 7], [7, 7], [7, 3]], dtype=float)]
    seg = hatch(holed, 1.0, 0.0)
    assert len(seg) == 14  # four lines through the hole are split in two
    assert np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1).sum() == pytest.approx(100 - 4 * 4)
    # the same rings as one array of points and their sizes
    np.testing.assert_array_equal(hatch_flat(np.concatenate(holed), np.array([4, 4]), 1.0, 0.0), seg)


def read_gcode(text):
    """An independent reader: absolute XYZ, relative E; returns extruding moves and totals."""
    x = y = z = 0.0
    relative = False
    moves, e_total, retracted = [], 0.0, 0.0
    for line in text.splitlines():
        line = line.split(";", 1)[0].strip()
        if not line:
            continue
        cmd = line.split()[0]
        words = dict((w[0], float(w[1:])) for w in line.split()[1:] if w[0] in "XYZEFS")
        if cmd in ("G90", "G91"):
            relative = cmd == "G91"
        elif cmd in ("G0", "G1"):
            if relative:
                nx, ny, nz = x + words.get("X", 0), y + words.get("Y", 0), z + words.get("Z", 0)
            else:
                nx, ny, nz = words.get("X", x), words.get("Y", y), words.get("Z", z)
            e = words.get("E", 0.0)
            if e > 0 and (nx, ny) != (x, y):  # unretracts (E without XY) only undo retracts
                moves.append((x, y, nx, ny, nz, e))
                e_total += e
            retracted += -e if (nx, ny) == (x, y) else 0.0
            x, y, z = nx, ny, nz
    assert abs(retracted) < 1e-6  # every retract is undone
    moves = np.array(moves)
    return moves, e_total, len(np.unique(moves[:, 4]))


def test_gcode_reads_back(cube):
    text = gcode_text(layer_pieces(cube.layers), cube.settings, name="cube")
    for must in ("G21", "G90", "M83", "M104 S210", "M140 S60", ";LAYER:0", ";LAYER:49"):
        assert must in text
    moves, e_total, layers = read_gcode(text)
    assert layers == 50
    assert np.abs(moves[:, [0, 1, 2, 3]]).max() <= 10.0
    fil = math.pi * (1.75 / 2) ** 2
    expected = sum(float((flow_area(L.width, L.height, L.role) * L.lengths())[L.role != TRAVEL].sum())
                   for L in cube.layers)
    assert e_total * fil == pytest.approx(expected, rel=1e-3)
    m = re.search(r"; filament used \[mm\] = ([0-9.]+)", text)
    assert float(m.group(1)) == pytest.approx(e_total, rel=1e-4)


def test_layers_grouped_into_pieces_write_the_same_gcode(cube):
    """layer_pieces hands the writer several layers a piece (fewer calls); any grouping, one
    layer a piece included, writes the same bytes."""
    one = gcode_text(layer_pieces(cube.layers, group=1), cube.settings, name="cube")
    for group in (7, 16, 1000):
        pieces = list(layer_pieces(cube.layers, group=group))
        assert len(pieces) == -(-len(cube.layers) // group)
        assert gcode_text(pieces, cube.settings, name="cube") == one
    # a cap on commands: a piece ends with the first layer that reaches it, whole layers only
    sizes = [len(p) for p in layer_pieces(cube.layers, group=1)]
    cap = int(np.median(sizes)) * 3
    pieces = list(layer_pieces(cube.layers, group=1000, commands=cap))
    layer_ends, piece_ends = np.cumsum(sizes), np.cumsum([len(p) for p in pieces])
    last = np.searchsorted(layer_ends, piece_ends)  # each piece's last layer
    assert np.array_equal(layer_ends[last], piece_ends)  # whole layers
    assert 1 < len(pieces) < len(cube.layers) and last[-1] == len(sizes) - 1
    for a, b in zip(np.r_[0, last[:-1] + 1], last):  # layers a..b make one piece
        assert sum(sizes[a:b]) < cap and (sum(sizes[a:b + 1]) >= cap or b == len(sizes) - 1)
    assert gcode_text(pieces, cube.settings, name="cube") == one


def test_slice_cli(tmp_path, capsys):
    stl = tmp_path / "c.stl"
    to_trimesh(box(20, 20, 10)).export(stl)
    out = tmp_path / "c.gcode"
    assert main(["slice", str(stl), "--out", str(out), "-q"]) == 0
    assert out.read_text().count(";LAYER:") == 50
    before = out.read_text()
    assert main(["slice", str(stl), "--out", str(out), "-q"]) == 2
    assert "use --force" in capsys.readouterr().err
    assert out.read_text() == before
    assert main(["slice", str(stl), "--out", str(out), "-q", "--force", "--layer-height", "0.25"]) == 0
    # 1 + ceil((10 - 0.2) / 0.25) = 41 layers cover the cube; the last one's middle (10.075 mm) is
    # above it, so it prints nothing and the G-code has no layer for it
    text = out.read_text()
    assert text.count(";LAYER:") == math.ceil((10 - 0.2) / 0.25) == 40
    assert ";Z:9.950" in text and ";Z:10.200" not in text


def test_small_sparse_regions_are_filled_solid():
    # a 6 x 6 mm column: its fill area (~26 mm2) is below the 70 mm2 threshold, as in PrusaSlicer
    sliced = slice_solid(solid(box(6, 6, 10)), SlicingSettings())
    middle = sliced.layers[25]
    assert SKIN in set(middle.role.tolist()) and INFILL not in set(middle.role.tolist())
    sparse = slice_solid(solid(box(6, 6, 10)), SlicingSettings(solid_infill_below_area=0.0)).layers[25]
    assert INFILL in set(sparse.role.tolist()) and SKIN not in set(sparse.role.tolist())


def test_long_travels_retract_and_unretract(cube):
    text = gcode_text(layer_pieces(cube.layers), cube.settings, name="cube")
    assert text.count("G1 E-0.80000 F2100") == text.count("G1 E0.80000 F2100") > 0
    assert "E0.00000" not in text  # no extruding move that does not move


def test_a_model_larger_than_the_build_volume_is_refused_with_both_sizes(tmp_path, capsys):
    stl = tmp_path / "long.stl"
    to_trimesh(box(120, 20, 10)).export(stl)
    out = tmp_path / "long.gcode"
    assert main(["slice", str(stl), "--out", str(out), "-q", "--config", str(_toml(tmp_path, "build_x = 100.0"))]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "120.0 x 20.0 x 10.0 mm" in err and "100 x 1000 x 1000 mm" in err and "build_x" in err
    assert not out.exists()


def _toml(tmp_path, line):
    path = tmp_path / "printer.toml"
    path.write_text(f"[slicing]\n{line}\n")
    return path


def test_streamed_gcode_equals_the_whole_model_written(tmp_path):
    stl = tmp_path / "t.stl"
    to_trimesh(tube(12, 5, 12)).export(stl)  # 60 layers: two blocks
    from cooprint.jobs import slice_job, slice_to_gcode, write_gcode

    n, used = slice_to_gcode(stl, tmp_path / "a.gcode")
    _, sliced = slice_job(stl)
    used_b = write_gcode(sliced, tmp_path / "b.gcode", "t.stl")
    assert n == sliced.n_layers == 60 and used == pytest.approx(used_b)
    assert (tmp_path / "a.gcode").read_text() == (tmp_path / "b.gcode").read_text()
    # the count is the layers the G-code prints (it said 39 for 38 ;LAYER lines when the slicer
    # made an empty layer at the top)
    assert n == (tmp_path / "a.gcode").read_text().count("\n;LAYER:")


def test_a_cone_tip_too_small_for_a_loop_gets_one_bead():
    """The top layers of a cone 4 mm across and 4 mm tall hold discs under a line width across:
    no loop fits and a disc has no centre line, so PrusaSlicer's classic walls print nothing
    there, its Arachne walls one bead. cooprint prints one bead as wide as the disc (its area
    as width x length plus round ends), so every layer whose section is over ``min_area`` prints
    something (the last, 0.1 mm across, is under it): the tip's beads lie on the axis and hold
    their disc's volume."""
    import manifold3d as m3d

    s = SlicingSettings()
    cone = solid(m3d.Manifold.cylinder(4.0, 2.0, 0.0, 256))
    sliced = slice_solid(cone, s)
    assert sliced.n_layers == len(layer_tops(4.0, s)) == 20
    disc = [math.pi * (0.5 * (4.0 - (layer.z - 0.1))) ** 2 for layer in sliced.layers]  # at mid-layer
    printed = [i for i, layer in enumerate(sliced.layers) if (layer.role != TRAVEL).any()]
    assert printed == [i for i in range(20) if disc[i] >= s.min_area] == list(range(19))
    for i in (17, 18):  # discs 0.5 and 0.3 mm across
        layer = sliced.layers[i]
        ks = [k for k in range(len(layer)) if layer.role[k] != TRAVEL]
        assert len(ks) == 1 and layer.role[ks[0]] == PERIMETER_OUTER
        bead, w = layer.path(ks[0]), float(layer.width[ks[0]])
        assert np.allclose(bead.mean(axis=0), 0.0, atol=1e-3)
        length = float(np.linalg.norm(bead[-1] - bead[0]))
        assert flow_area(w, 0.2, PERIMETER_OUTER) * length == pytest.approx(disc[i] * 0.2, rel=0.1)  # (the thin region is opened first)
