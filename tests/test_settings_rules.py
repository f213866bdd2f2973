"""Issue 12, deliverables 3-5: placement, settings that cannot make nonsense, one feasibility rule."""

from __future__ import annotations

import json
import math
import os
import re

import manifold3d as m3d
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings as hsettings, strategies as st

from cooprint.chunking import feasibility
from cooprint.cli import main
from cooprint.config import ChunkingSettings, RobotProfile, load_settings
from cooprint.config.settings import check_slicing, parse_assignment, parse_fraction, work_estimate
from cooprint.errors import ConfigError
from cooprint.io.bundle import write_stl
from cooprint.slicing.paths import extrusion_area, extrusion_spacing

from badinput import assert_rejected

COARSE = ["--layer-height", "1", "--first-layer-height", "1", "--nozzle", "1.2", "--extrusion-width", "1.6"]


def stl(path, man):
    mesh = man.to_mesh64()
    write_stl(path, np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts), name=path.stem)
    return path


def cube(x, y, z, at=(0.0, 0.0, 0.0)):
    return m3d.Manifold.cube((x, y, z)).translate(at)


def hexagon_nut(across=5.5, height=2.4, hole=1.5):
    r = across / 2 / math.cos(math.pi / 6)
    return m3d.Manifold.cylinder(height, r, r, 6) - m3d.Manifold.cylinder(height + 1, hole, hole, 32).translate((0, 0, -0.5))


def cli(args, capsys):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def gcode_moves(path):
    """(n, 4) X, Y, Z, E of every G0/G1 with X or Y (modal Z), and whether E was given."""
    rows, z = [], math.nan
    with open(path, encoding="ascii") as fh:
        lines = fh.read().splitlines()
    for line in lines:
        if not line.startswith(("G0 ", "G1 ")):
            continue
        words = dict((w[0], float(w[1:])) for w in line.split(";")[0].split()[1:])
        z = words.get("Z", z)
        if "X" in words or "Y" in words:
            rows.append((words.get("X", math.nan), words.get("Y", math.nan), z, words.get("E", 0.0)))
    return np.array(rows)


# --- placement -------------------------------------------------------------------------------

def test_a_mesh_below_the_floor_gives_no_negative_z(tmp_path, capsys):
    mesh = stl(tmp_path / "below.stl", cube(20, 20, 4, at=(-10, -10, -3)))
    out = tmp_path / "below.gcode"
    code, stdout, _ = cli(["slice", mesh, "--out", out], capsys)
    assert code == 0
    moves = gcode_moves(out)
    assert np.nanmin(moves[:, 2]) == pytest.approx(0.2)  # the first layer at first_layer_height
    assert (moves[:, 2] >= 0).all()
    code, stdout, _ = cli(["chunk", mesh, "--out", tmp_path / "job", "--no-picture"], capsys)
    job = json.loads((tmp_path / "job" / "job.json").read_text())
    assert job["mesh"]["bbox_min"][2] == 0.0 and job["mesh"]["placement"]["moved_mm"] == [0.0, 0.0, 3.0]
    assert "moved by (+0.000, +0.000, +3.000) mm" in stdout


def test_a_floating_mesh_prints_its_first_layer_at_first_layer_height(tmp_path, capsys):
    mesh = stl(tmp_path / "float.stl", cube(20, 20, 4, at=(0, 0, 50)))
    out = tmp_path / "float.gcode"
    assert cli(["slice", mesh, "--out", out, "--first-layer-height", "0.3"], capsys)[0] == 0
    z = gcode_moves(out)[:, 2]
    assert np.nanmin(z) == pytest.approx(0.3) and np.nanmax(z) <= 4.0 + 0.2 + 1e-6
    code, _, _ = cli(["run", mesh, "--out", tmp_path / "job", "-q", "--no-picture"], capsys)
    assert code == 0
    z = gcode_moves(tmp_path / "job" / "robots" / "A.gcode")[:, 2]
    assert np.nanmin(z) == pytest.approx(0.2)


def test_slice_centres_the_part_on_the_bed(tmp_path, capsys):
    mesh = stl(tmp_path / "centred.stl", m3d.Manifold.cube((30, 20, 4), center=True))
    out = tmp_path / "c.gcode"
    assert cli(["slice", mesh, "--out", out, "--set", "slicing.build_x=250", "--set", "slicing.build_y=210"],
               capsys)[0] == 0
    xy = gcode_moves(out)[:, :2]
    assert np.nanmin(xy) >= 0 and np.nanmax(xy[:, 0]) <= 250 and np.nanmax(xy[:, 1]) <= 210
    printed = gcode_moves(out)
    printed = printed[printed[:, 3] > 0]
    centre = (printed[:, :2].min(axis=0) + printed[:, :2].max(axis=0)) / 2
    assert centre == pytest.approx([125, 105], abs=0.5)
    out2 = tmp_path / "c2.gcode"
    code, stdout, _ = cli(["slice", mesh, "--out", out2, "--center", "40,30"], capsys)
    assert code == 0 and "placed on the floor and centred on the bed: moved by (+40.000, +30.000, +2.000) mm" in stdout
    printed = gcode_moves(out2)
    printed = printed[printed[:, 3] > 0]
    assert (printed[:, :2].min(axis=0) + printed[:, :2].max(axis=0)) / 2 == pytest.approx([40, 30], abs=0.5)


def test_no_place_keeps_the_frame_refuses_below_floor_and_warns_when_floating(tmp_path, capsys):
    below = stl(tmp_path / "below.stl", cube(20, 20, 4, at=(0, 0, -1)))
    line = assert_rejected(["chunk", below, "--out", tmp_path / "o", "-q", "--no-place"], capsys, [tmp_path])
    assert "below the floor" in line and "--no-place" in line
    floating = stl(tmp_path / "float.stl", cube(20, 20, 4, at=(0, 0, 50)))
    code, stdout, err = cli(["info", floating, "--no-place"], capsys)
    assert code == 0 and "cooprint: warning:" in err and "floats at z = 50.000" in err
    assert "kept in the file's frame" in stdout


def test_a_part_in_metres_is_an_error_with_the_units_hint(tmp_path, capsys):
    tiny = stl(tmp_path / "tiny.stl", cube(0.2, 0.2, 0.2))
    for cmd in (["info", tiny], ["chunk", tiny, "--out", tmp_path / "o", "-q"], ["run", tiny, "--out", tmp_path / "o", "-q"],
                ["slice", tiny, "--out", tmp_path / "o.gcode", "-q"]):
        line = assert_rejected(cmd, capsys, [tmp_path])
        assert "too small to print" in line and "--units" in line and "--scale" in line
        assert "m: 200 x 200 x 200 mm" in line
    code, stdout, _ = cli(["info", tiny, "--units", "m"], capsys)
    assert code == 0 and "size 200.0 x 200.0 x 200.0 mm" in stdout and "scaled x1000 (m)" in stdout
    code, stdout, _ = cli(["info", tiny, "--scale", "500"], capsys)
    assert code == 0 and "size 100.0 x 100.0 x 100.0 mm" in stdout


def test_a_thin_wall_is_a_part_and_a_flat_sheet_gets_no_units_hint(tmp_path, capsys):
    """A 100 x 0.5 x 20 mm wall is narrower than 3 lines in Y only: it is a part, printed (a thin
    wall: one line along its middle); a 0.3 mm foil too (a thin wall from a third of the nozzle
    on, PrusaSlicer's limit); a 0.1 mm foil is sliced to nothing, and said so; a 100 x 100 x 0.05 mm sheet is lower than the first layer, refused without a units hint (it is
    large across); a 0.2 mm cube keeps the hint (the metres case above)."""
    wall = stl(tmp_path / "wall.stl", cube(100, 0.5, 20))
    code, stdout, err = cli(["info", wall], capsys)
    assert code == 0 and "size 100.0 x 0.5 x 20.0 mm" in stdout and "--units" not in err
    code, stdout, _ = cli(["slice", wall, "--out", tmp_path / "wall.gcode", "-q"], capsys)
    assert code == 0 and (tmp_path / "wall.gcode").exists()
    foil = stl(tmp_path / "foil.stl", cube(100, 0.3, 20))  # thinner than a line: a thin wall
    code, _, err = cli(["slice", foil, "--out", tmp_path / "foil.gcode", "-q"], capsys)
    assert code == 0 and "nothing to print" not in err and "Internal" not in (tmp_path / "foil.gcode").read_text()
    assert ";TYPE:External perimeter" in (tmp_path / "foil.gcode").read_text()
    foil = stl(tmp_path / "foil.stl", cube(100, 0.1, 20))  # under a third of the nozzle: sliced to nothing, said so
    code, _, err = cli(["slice", foil, "--out", tmp_path / "foil.gcode", "-q", "--force"], capsys)
    assert code == 0 and "cooprint: warning:" in err and "nothing to print" in err
    sheet = stl(tmp_path / "sheet.stl", cube(100, 100, 0.05))
    line = assert_rejected(["info", sheet], capsys, [tmp_path])
    assert "lower than the first layer (0.2 mm)" in line and "--units" not in line and "narrower" not in line
    needle = stl(tmp_path / "needle.stl", cube(1, 1, 50))
    line = assert_rejected(["info", needle], capsys, [tmp_path])
    assert "narrower than 3 line widths (1.35 mm) in both X and Y" in line and "--units" not in line


def test_a_small_part_gets_a_units_warning(tmp_path, capsys):
    nut = stl(tmp_path / "nut.stl", hexagon_nut())
    code, _, err = cli(["info", nut], capsys)
    assert code == 0
    warn = [ln for ln in err.splitlines() if ln.startswith("cooprint: warning:")]
    assert len(warn) == 1 and "--units" in warn[0] and "in: " in warn[0]
    code, _, err = cli(["info", nut, "--units", "in"], capsys)
    assert code == 0 and "warning" not in err


# --- feasibility ------------------------------------------------------------------------------

def test_800_mm_block_info_and_chunk_agree_and_state_the_height_limit(tmp_path, capsys):
    """Two robots (the default) keep the centre chunk 2 x nozzle_depth = 50 mm wide at the top:
    (300 - 50) x 4 / 2 = 500 mm; one robot prints a wedge: 300 x 4 / 2 = 600 mm."""
    block = stl(tmp_path / "block.stl", cube(800, 800, 800))
    code, stdout, _ = cli(["info", block], capsys)
    assert code == 1 and "not feasible" in stdout and "largest printable height 500.0 mm" in stdout
    code, stdout, _ = cli(["info", block, "--robots", "1"], capsys)
    assert code == 1 and "largest printable height 600.0 mm" in stdout
    line = assert_rejected(["chunk", block, "--out", tmp_path / "o", "-q"], capsys, [tmp_path])
    assert "largest printable height 500.0 mm" in line and "steeper" not in line and "theta_deg" not in line
    assert "robot.build_depth >= 450 or" in line and "robot.nozzle_height >= 160" in line
    line = assert_rejected(["chunk", block, "--out", tmp_path / "o", "-q", "--robots", "1"], capsys, [tmp_path])
    assert "robot.build_depth >= 400 or" in line and "robot.nozzle_height >= 133.4" in line
    assert "largest printable height 500.0 mm" in assert_rejected(["run", block, "--out", tmp_path / "o", "-q"], capsys,
                                                                   [tmp_path])


def test_a_steeper_slope_is_advised_only_when_it_helps():
    v = np.array([[0, 0, 0], [500, 500, 500]], dtype=float)
    f = feasibility(v, RobotProfile(), ChunkingSettings(theta_deg=60.0), robots=1)
    assert not f.feasible and any(h.startswith("chunking.theta_deg >= 73.30") for h in f.hints)
    f = feasibility(v * 1.6, RobotProfile(), ChunkingSettings(theta_deg=60.0), robots=1)  # 800 tall: theta_max is too shallow too
    assert not f.feasible and not any("theta_deg >=" in h for h in f.hints)
    assert f.max_height == pytest.approx(300 * 4 / 2 * math.tan(math.radians(60)) / 4)  # at theta 60


def test_two_robots_keep_the_centre_chunk_two_printheads_wide_at_the_top():
    """Default top_width: 0 for one robot (the seed's wedge), 2 x nozzle_depth for two, so the
    printheads of the robots printing L1 and R1 at once never meet; a set value wins."""
    from cooprint.chunking.planes import top_width

    robot = RobotProfile(nozzle_depth=30, build_depth=300)
    assert top_width(robot, ChunkingSettings(), 1) == 0.0
    assert top_width(robot, ChunkingSettings(), 2) == 60.0
    assert top_width(robot, ChunkingSettings(top_width=12.0), 2) == 12.0
    v = np.array([[0, 0, 0], [10, 400, 100.0]])
    two, one = feasibility(v, robot, ChunkingSettings(), 2), feasibility(v, robot, ChunkingSettings(), 1)
    assert two.max_height == pytest.approx((300 - 60) * (100 / 30) / 2)
    assert one.max_height == pytest.approx(300 * (100 / 30) / 2)


def test_a_part_too_tall_for_two_robots_is_advised_one_not_a_narrower_top():
    """550 mm: two robots keep C 50 mm wide at the top (500 mm at most); the fix offered is one
    robot's wedge, not a top width that would bring the printheads together."""
    v = np.array([[0, 0, 0], [100, 400, 550.0]])
    two = feasibility(v, RobotProfile(), ChunkingSettings(), 2)
    assert not two.feasible and two.max_height == pytest.approx(500.0)
    assert two.hints[0].startswith("--robots 1") and not any(h.startswith("chunking.top_width") for h in two.hints)
    assert feasibility(v, RobotProfile(), ChunkingSettings(), 1).feasible
    given = feasibility(v, RobotProfile(), ChunkingSettings(top_width=50.0), 2)  # set by the user: it may go lower
    assert any(h.startswith("chunking.top_width <= 25.0") for h in given.hints)


def test_a_top_narrower_than_two_printheads_for_two_robots_is_warned(tmp_path, capsys):
    bar = stl(tmp_path / "bar.stl", cube(40, 420, 30))
    for args, warned in (([], False), (["--set", "chunking.top_width=0"], True),
                         (["--set", "chunking.top_width=0", "--robots", "1"], False)):
        code, _, err = cli(["chunk", bar, "--out", tmp_path / "o", "--force", "-q", *args], capsys)
        assert code == 0 and ("narrower than the two printheads" in err) == warned, (args, err)


def test_largest_printable_height_is_the_centre_chunk_bound():
    robot = RobotProfile(build_depth=300, nozzle_height=100, nozzle_depth=25)
    f = feasibility(np.array([[0, 0, 0], [10, 400, 100.0]]), robot, ChunkingSettings(top_width=20.0))
    assert f.feasible and f.mode == "cut"
    assert f.max_height == pytest.approx((300 - 20) * 4 / 2)
    assert f.chunks >= 3


def test_a_tall_slender_tower_is_one_chunk_and_plans(tmp_path, capsys):
    tower = stl(tmp_path / "tower.stl", cube(40, 40, 1500))
    code, stdout, _ = cli(["info", tower], capsys)
    assert code == 0 and "feasible: 1 chunk" in stdout and "largest printable height 2000.0 mm" in stdout
    out = tmp_path / "job"
    code, stdout, _ = cli(["run", tower, "--out", out, "--no-picture", "--infill", "10%", *COARSE], capsys)
    assert code == 0, stdout
    job = json.loads((out / "job.json").read_text())
    assert [c["id"] for c in job["chunks"]] == ["C"] and job["plan"]["mode"] == "whole"
    assert job["chunks"][0]["layers"] == 1500
    line = assert_rejected(["chunk", tower, "--out", tmp_path / "o", "-q", "--set", "robot.max_z=1000"], capsys,
                           [tmp_path])
    assert "robot.max_z = 1000" in line and "robot.max_z >= 1500 mm" in line


def test_a_nut_is_one_chunk_and_the_idle_robot_parks_off_it(tmp_path, capsys):
    nut = stl(tmp_path / "nut.stl", hexagon_nut())
    out = tmp_path / "job"
    code, stdout, _ = cli(["run", nut, "--out", out, "--robots", "2", "--no-picture", "--simulate"], capsys)
    assert code == 0
    job = json.loads((out / "job.json").read_text())
    assert [c["id"] for c in job["chunks"]] == ["C"]
    a, b = job["robots"]
    assert a["chunks"] == ["C"] and b["chunks"] == [] and b["stats"]["commands"] == 0
    assert b["start"][1] > job["mesh"]["bbox_max"][1]  # beyond the part along +Y, facing it
    assert b["facing"] == pytest.approx([0.0, -1.0])
    summary = json.loads((out / "sim" / "summary.json").read_text())
    assert summary["finding_counts"]["robots-collide"] == 0 and summary["finding_counts"]["body-on-material"] == 0
    assert "idle (1): B" in stdout


def test_info_states_the_number_of_chunks_that_chunk_makes(tmp_path, capsys):
    slab = stl(tmp_path / "slab.stl", cube(40, 900, 30))
    code, stdout, _ = cli(["info", slab], capsys)
    n = int(re.search(r"feasible: (\d+) chunks", stdout).group(1))
    assert code == 0 and n > 1
    code, _, _ = cli(["chunk", slab, "--out", tmp_path / "job", "-q", "--no-picture"], capsys)
    assert code == 0 and len(json.loads((tmp_path / "job" / "job.json").read_text())["chunks"]) == n


def test_explicit_planes_still_cut_a_part_that_fits():
    v = np.array([[0, 0, 0], [40, 300, 30.0]])
    assert feasibility(v, RobotProfile(), ChunkingSettings()).chunks == 1
    assert feasibility(v, RobotProfile(), ChunkingSettings(theta_deg=60.0, shift=50.0)).chunks > 1


# --- settings ---------------------------------------------------------------------------------

@pytest.mark.parametrize("key, value", [("slicing.perimeters", 10**18), ("slicing.top_layers", -1),
                                        ("slicing.bottom_layers", 10**400), ("slicing.perimeters", 1e300)])
def test_integer_fields_are_range_checked(key, value):
    with pytest.raises(ConfigError, match=re.escape(key) + r" = .*expected a whole number"):
        load_settings(overrides={key: value})


def test_layer_thicker_than_the_nozzle_is_refused_and_names_both_fields():
    with pytest.raises(ConfigError, match=r"slicing.layer_height = 5 mm is thicker than slicing.nozzle_diameter = 0.4"):
        load_settings(overrides={"slicing.layer_height": 5.0, "slicing.first_layer_height": 0.2})
    with pytest.raises(ConfigError, match=r"extrusion_width = 0.1 mm: expected 1 to 3 x slicing.nozzle_diameter"):
        load_settings(overrides={"slicing.extrusion_width": 0.1})


def test_settings_from_separate_sources_are_checked_together(tmp_path):
    f = tmp_path / "coarse.toml"
    f.write_text("[slicing]\nlayer_height = 0.6\nfirst_layer_height = 0.6\n")  # needs a larger nozzle ...
    s = load_settings(f, overrides={"slicing.nozzle_diameter": 0.8, "slicing.extrusion_width": 1.0})  # ... given here
    assert s.slicing.layer_height == 0.6


@hsettings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(nozzle=st.floats(0.0, 12.0), layer=st.floats(-1.0, 12.0), first=st.floats(-1.0, 12.0),
       width=st.floats(-1.0, 40.0))
def test_no_accepted_combination_gives_negative_e_or_a_layer_thicker_than_the_nozzle(nozzle, layer, first, width):
    try:
        s = load_settings(overrides={"slicing.nozzle_diameter": nozzle, "slicing.layer_height": layer,
                                     "slicing.first_layer_height": first, "slicing.extrusion_width": width}).slicing
    except ConfigError:
        return
    for h in (s.layer_height, s.first_layer_height):
        assert 0.05 <= h <= s.nozzle_diameter
        assert extrusion_area(s.extrusion_width, h) > 0
        assert extrusion_spacing(s.extrusion_width, h) > 0


@pytest.mark.parametrize("layer, first, nozzle, width", [(0.05, 0.05, 0.4, 1.2), (0.4, 0.4, 0.4, 0.4),
                                                         (0.05, 0.4, 0.4, 0.4), (1.2, 1.2, 1.2, 1.2)])
def test_extreme_accepted_settings_slice_without_negative_e(tmp_path, capsys, layer, first, nozzle, width):
    mesh = stl(tmp_path / "part.stl", cube(12, 10, 3))
    out = tmp_path / "part.gcode"
    code, stdout, err = cli(["slice", mesh, "--out", out, "--layer-height", layer, "--first-layer-height", first,
                             "--nozzle", nozzle, "--extrusion-width", width], capsys)
    assert code == 0, err
    moves = gcode_moves(out)
    assert (moves[:, 3] >= 0).all() and (moves[:, 3] > 0).any()
    assert float(re.search(r"filament ([-0-9.]+) m", stdout).group(1)) > 0


def test_work_estimate_refuses_unbounded_work_with_the_numbers():
    s = load_settings(overrides={"slicing.layer_height": 0.05, "slicing.first_layer_height": 0.05}).slicing
    with pytest.raises(ConfigError, match=r"20000 mm tall in layers of 0.05 mm is 400,000 layers, more than the 200,000"):
        work_estimate((10, 10, 20000), 2e6, s)
    with pytest.raises(ConfigError, match=r"km of tool path"):
        work_estimate((1000, 1000, 1000), 1e9, s)
    est = work_estimate((10, 10, 10), 1000, s)
    assert est["layers"] == 200


def test_slice_refuses_a_tall_part_in_thin_layers_before_slicing(tmp_path, capsys):
    mesh = stl(tmp_path / "pole.stl", cube(10, 10, 15000))
    line = assert_rejected(["slice", mesh, "--out", tmp_path / "p.gcode", "-q", "--set", "slicing.build_z=20000",
                            "--layer-height", "0.05"], capsys, [tmp_path])
    assert "15000 mm tall in layers of 0.05 mm is 299,997 layers" in line  # 0.2 + 299,996 x 0.05


def test_set_parses_toml_values_and_strings(tmp_path, capsys):
    assert parse_assignment("robot.name=foo") == ("robot.name", "foo")
    assert parse_assignment("slicing.infill_pattern=grid") == ("slicing.infill_pattern", "grid")
    assert parse_assignment("slicing.layer_height=0.3") == ("slicing.layer_height", 0.3)
    assert parse_assignment("mesh.place=false") == ("mesh.place", False)
    mesh = stl(tmp_path / "part.stl", cube(40, 30, 5))
    out = tmp_path / "job"
    code, _, _ = cli(["chunk", mesh, "--out", out, "-q", "--no-picture", "--set", "robot.name=foo",
                      "--set", "slicing.infill_pattern=grid", "--infill", "35%", "--perimeters", "3"], capsys)
    assert code == 0
    s = json.loads((out / "job.json").read_text())["settings"]
    assert s["robot"]["name"] == "foo" and s["slicing"]["infill_pattern"] == "grid"
    assert s["slicing"]["infill_density"] == pytest.approx(0.35) and s["slicing"]["perimeters"] == 3


def test_run_takes_the_slicing_flags(tmp_path, capsys):
    mesh = stl(tmp_path / "part.stl", cube(30, 30, 6))
    out = tmp_path / "job"
    code, _, _ = cli(["run", mesh, "--out", out, "-q", "--no-picture", "--layer-height", "0.3", "--perimeters", "1",
                      "--infill", "0.5", "--top-layers", "2", "--bottom-layers", "2"], capsys)
    assert code == 0
    job = json.loads((out / "job.json").read_text())
    sl = job["settings"]["slicing"]
    assert (sl["layer_height"], sl["perimeters"], sl["infill_density"], sl["top_layers"]) == (0.3, 1, 0.5, 2)
    assert job["chunks"][0]["layers"] == 20  # 0.2 + 19 x 0.3 >= 6
    assert "; layer_height = 0.3" in (out / "robots" / "A.gcode").read_text()


@pytest.mark.parametrize("text, value", [("20%", 0.2), ("0.2", 0.2), ("0", 0.0), ("100%", 1.0), ("1", 1.0)])
def test_infill_accepts_fractions_and_percentages(text, value):
    assert parse_fraction(text) == pytest.approx(value)


def test_infill_20_without_percent_names_both_forms():
    with pytest.raises(ConfigError, match=r"--infill 20: expected a fraction from 0 to 1 \(0.2\) or a percentage.*"
                                          r"for 20% write 20%"):
        parse_fraction("20")


def test_unknown_keys_get_did_you_mean(tmp_path):
    f = tmp_path / "typo.toml"
    f.write_text("[slicing]\nlayer_hieght = 0.3\n")
    with pytest.raises(ConfigError, match=r"unknown field slicing.layer_hieght; did you mean 'layer_height'\?"):
        load_settings(f)
    f.write_text("[slicer]\nlayer_height = 0.3\n")
    with pytest.raises(ConfigError, match=r"unknown section \[slicer\]; did you mean 'slicing'\?"):
        load_settings(f)
    with pytest.raises(ConfigError, match=r"robot.layer_height; did you mean slicing.layer_height\?"):
        load_settings(overrides={"robot.layer_height": 0.3})


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_as_config_does_not_block(tmp_path):
    fifo = tmp_path / "settings.toml"
    os.mkfifo(fifo)
    with pytest.raises(ConfigError, match="is a named pipe \\(FIFO\\), not a settings file"):
        load_settings(fifo)


def test_check_slicing_is_the_rule_load_settings_applies():
    s = load_settings().slicing
    check_slicing(s)
    from dataclasses import replace

    with pytest.raises(ConfigError, match="first_layer_height"):
        check_slicing(replace(s, first_layer_height=0.5))


# --- fix hints that can be followed (a newcomer's trial of main) ---------------------------------

def _every_hint_is_valid(f):
    """Each ``field op value`` hint names a value the field accepts (re-checked through load_settings)."""
    for hint in f.hints:
        m = re.fullmatch(r"(robot|chunking)\.(\w+) (>=|<=) ([0-9.e+-]+)( mm)?", hint)
        if m:
            load_settings(overrides={f"{m[1]}.{m[2]}": float(m[4])})  # raises if outside the range
        elif hint.startswith("--scale"):
            assert float(hint.split()[1]) > 0


def test_hints_outside_a_fields_range_are_left_out_and_small_values_keep_their_digits(tmp_path, capsys):
    long = stl(tmp_path / "long.stl", cube(40, 500, 15))
    code, stdout, _ = cli(["info", long, "--set", "robot.nozzle_height=0.001", "--robots", "1"], capsys)
    assert code == 1 and "not feasible" in stdout
    assert "<= 0.0 " not in stdout and "--scale 0 " not in stdout and not stdout.rstrip().endswith("--scale 0")
    assert "robot.nozzle_height >= 2.5" in stdout and "robot.nozzle_depth <= 0.01" in stdout
    assert "largest printable height 0.0055 mm" in stdout or "largest printable height 0.006 mm" in stdout
    f = feasibility(np.array([[0, 0, 0], [40, 500, 15.0]]), RobotProfile(nozzle_height=0.001), ChunkingSettings(),
                    robots=1)
    assert f.hints and all("build_depth" not in h for h in f.hints)  # 750,000 mm: beyond the field's 1e5
    _every_hint_is_valid(f)


def test_a_centre_offset_beyond_the_part_is_named(tmp_path, capsys):
    long = stl(tmp_path / "long.stl", cube(40, 500, 15))
    code, stdout, _ = cli(["info", long, "--set", "chunking.centre_offset=1e6"], capsys)
    assert code == 1 and "chunking.centre_offset = 1e+06 mm" in stdout and "within +-500 mm" in stdout
    assert "chunking.shift" not in stdout
    line = assert_rejected(["chunk", long, "--out", tmp_path / "o", "--set", "chunking.centre_offset=-600"], capsys,
                           [tmp_path])
    assert "chunking.centre_offset = -600 mm" in line


@pytest.mark.parametrize("args", [["--theta", "90"], ["--theta", "2"], ["--set", "robot.nozzle_height=1"],
                                  ["--set", "robot.build_depth=10", "--set", "robot.nozzle_height=0.5",
                                   "--set", "robot.nozzle_depth=5"],
                                  ["--set", "robot.max_z=10"]])
def test_every_refusal_line_is_whole_and_under_250_characters(tmp_path, capsys, args):
    block = stl(tmp_path / "block.stl", cube(60, 400, 30))
    line = assert_rejected(["chunk", block, "--out", tmp_path / "o", *args], capsys, [tmp_path])
    assert len(line) < 250 and " ... " not in line and "fix: " in line


def test_a_part_taller_than_max_z_and_deeper_than_the_build_depth_gives_the_cut_bound(tmp_path, capsys):
    """40 m deep in metres: the cut's bound (600 mm), not max_z's one-chunk height."""
    block = stl(tmp_path / "block.stl", cube(60, 40, 30))
    code, stdout, _ = cli(["info", block, "--units", "m", "--robots", "1"], capsys)
    assert code == 1 and "largest printable height 600.0 mm (cut)" in stdout and "(one chunk)" not in stdout
    assert "robot.max_z >=" not in stdout and "--scale 0.02" in stdout
    tower = stl(tmp_path / "tower.stl", cube(40, 40, 3))  # 3 m tall, 40 m... one chunk at 40 mm deep in mm units
    code, stdout, _ = cli(["info", tower, "--units", "m", "--set", "robot.build_depth=50000"], capsys)
    assert code == 1 and "(one chunk)" in stdout and "robot.max_z >= 3000 mm" in stdout
