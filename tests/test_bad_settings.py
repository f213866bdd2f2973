"""Bad settings and flags, for every command that takes them (info, chunk, run, slice): each is
exit 2, one line, no traceback, nothing written (tests/badinput.py's contract)."""

from __future__ import annotations

import os

import manifold3d as m3d
import numpy as np
import pytest

from cooprint.io.bundle import write_stl

from badinput import assert_rejected

#: (flags, a piece of the error line): rejected by every command that takes settings.
SETTINGS_CASES = [
    (["--layer-height", "0"], "slicing.layer_height = 0.0: expected a number >= 0.05"),
    (["--layer-height", "-0.2"], "slicing.layer_height = -0.2"),
    (["--layer-height", "1e-6"], "slicing.layer_height = 1e-06: expected a number >= 0.05"),
    (["--layer-height", "nan"], "slicing.layer_height = nan"),
    (["--layer-height", "inf"], "slicing.layer_height = inf"),
    (["--layer-height", "5"], "slicing.layer_height = 5 mm is thicker than slicing.nozzle_diameter = 0.4"),
    (["--layer-height", "0.45"], "is thicker than slicing.nozzle_diameter = 0.4"),
    (["--layer-height", "abc"], "'abc' is not a valid float"),
    (["--first-layer-height", "0.5"], "slicing.first_layer_height = 0.5 mm is thicker than"),
    (["--first-layer-height", "0.01"], "slicing.first_layer_height = 0.01: expected a number >= 0.05"),
    (["--nozzle", "0"], "slicing.nozzle_diameter = 0.0: expected a number >= 0.1"),
    (["--nozzle", "100"], "slicing.nozzle_diameter = 100.0"),
    (["--nozzle", "0.1"], "is thicker than slicing.nozzle_diameter = 0.1"),
    (["--nozzle", "1.2"], "slicing.extrusion_width = 0.45 mm: expected 1 to 3 x slicing.nozzle_diameter"),
    (["--nozzle", "0.8", "--layer-height", "0.6"], "(the default width; set --extrusion-width, e.g. 0.9 mm = 1.125 x "
                                                   "nozzle, PrusaSlicer's auto width)"),
    (["--extrusion-width", "0.1"], "slicing.extrusion_width = 0.1 mm: expected 1 to 3 x"),
    (["--extrusion-width", "2"], "slicing.extrusion_width = 2 mm: expected 1 to 3 x"),
    (["--extrusion-width", "-1"], "slicing.extrusion_width = -1.0: expected a number > 0"),
    (["--infill", "20"], "--infill 20: expected a fraction from 0 to 1 (0.2) or a percentage"),
    (["--infill", "150%"], "--infill 150%: expected a fraction"),
    (["--infill", "-5%"], "--infill -5%"),
    (["--infill", "abc"], "--infill 'abc'"),
    (["--infill", "1.5"], "--infill 1.5"),
    (["--infill", "nan"], "--infill nan"),
    (["--infill", "%"], "--infill '%'"),
    (["--infill-pattern", "honeycomb"], "'honeycomb' is not one of"),
    (["--infill-pattern", "gyroid", "--infill", "150%"], "--infill 150%: expected a fraction"),
    (["--infill-pattern", "gyroid", "--set", "slicing.infill_density=1.5"],
     "slicing.infill_density = 1.5: expected a number >= 0 and <= 1"),
    (["--set", "slicing.bridge_flow_ratio=0"], "slicing.bridge_flow_ratio = 0: expected a number > 0 and <= 2"),
    (["--set", "slicing.bridge_flow_ratio=2.5"], "slicing.bridge_flow_ratio = 2.5: expected a number > 0 and <= 2"),
    (["--set", "slicing.bridge_speed=0"], "slicing.bridge_speed = 0: expected a number > 0"),
    (["--set", "slicing.bridge_angle_deg=400"], "slicing.bridge_angle_deg = 400: expected a number >= -360 and <= 360"),
    (["--set", "slicing.top_infill_extrusion_width=0.2"],
     "slicing.top_infill_extrusion_width = 0.2 mm: expected 1 to 3 x slicing.nozzle_diameter = 0.4 to 1.2 mm"),
    (["--set", "slicing.external_perimeter_extrusion_width=0.3"],
     "slicing.external_perimeter_extrusion_width = 0.3 mm: expected 1 to 3 x slicing.nozzle_diameter"),
    (["--set", "slicing.first_layer_extrusion_width=1.5"],
     "slicing.first_layer_extrusion_width = 1.5 mm: expected 1 to 3 x slicing.nozzle_diameter"),
    (["--nozzle", "0.6", "--extrusion-width", "0.7", "--set", "slicing.infill_extrusion_width=0.5"],
     "slicing.infill_extrusion_width = 0.5 mm: expected 1 to 3 x slicing.nozzle_diameter = 0.6 to 1.8 mm"),
    (["--set", "slicing.infill_anchor=-1"], "slicing.infill_anchor = -1: expected a number >= 0"),
    (["--set", "slicing.infill_pattern=gyroi"], "(did you mean 'gyroid'?)"),
    (["--set", "slicing.gap_fill=1"], "slicing.gap_fill = 1: expected true or false"),
    (["--perimeters", "0", "--infill", "0", "--top-layers", "0", "--bottom-layers", "0"],
     "slicing.perimeters = 0, infill_density = 0, top_layers = 0 and bottom_layers = 0 print nothing"),
    (["--perimeters", "-1"], "slicing.perimeters = -1: expected a whole number >= 0 and <= 100"),
    (["--perimeters", "1000000000000000000"], "slicing.perimeters = 1e+18: expected a whole number"),
    (["--perimeters", "2.5"], "'2.5' is not a valid integer"),
    (["--top-layers", "-1"], "slicing.top_layers = -1: expected a whole number >= 0"),
    (["--bottom-layers", "99999"], "slicing.bottom_layers = 99999"),
    (["--units", "km"], "'km' is not one of"),
    (["--scale", "0"], "mesh.scale = 0.0: expected a number > 0"),
    (["--scale", "-1"], "mesh.scale = -1.0"),
    (["--scale", "nan"], "mesh.scale = nan"),
    (["--scale", "1e300"], "mesh.scale = 1e+300"),
    (["--set", "slicing.layer_hieght=0.3"], "unknown field slicing.layer_hieght; did you mean 'layer_height'?"),
    (["--set", "slicng.layer_height=0.3"], "unknown section [slicng]; did you mean 'slicing'?"),
    (["--set", "robot.layer_height=0.3"], "unknown field robot.layer_height; did you mean slicing.layer_height?"),
    (["--set", "robot.wheels=4"], "unknown field robot.wheels; expected one of:"),
    (["--set", "layer_height=0.3"], "expected SECTION.KEY=VALUE"),
    (["--set", "slicing.layer_height"], "expected SECTION.KEY=VALUE"),
    (["--set", "=3"], "expected SECTION.KEY=VALUE"),
    (["--set", "slicing.layer_height=1e-6"], "slicing.layer_height = 1e-06"),
    (["--set", "slicing.layer_height=thick"], "slicing.layer_height = 'thick': expected a number"),
    (["--set", "slicing.perimeters=1e18"], "slicing.perimeters = 1e+18: expected a whole number"),
    (["--set", "slicing.perimeters=99999999999999999999"], "slicing.perimeters = 1e+20"),
    (["--set", "slicing.top_layers=-1"], "slicing.top_layers = -1"),
    (["--set", "slicing.infill_pattern=honeycomb"], "slicing.infill_pattern = 'honeycomb': expected one of"),
    (["--set", "slicing.seam=alligned"], "(did you mean 'aligned'?)"),
    (["--set", "slicing.outer_perimeter_first=1"], "expected true or false"),
    (["--set", "slicing.infill_density=20%"], "slicing.infill_density = '20%': expected a number"),
    (["--set", "robot.build_depth=-3"], "robot.build_depth = -3: expected a number > 0"),
    (["--set", "robot.name="], "robot.name = '': expected a non-empty string"),
    (["--set", "robot.name=[1, 2]"], "robot.name = [1, 2]: expected a non-empty string"),
    (["--set", "robot.max_z=0"], "robot.max_z = 0: expected a number > 0"),
    (["--set", "robot.frame_width=-1"], "robot.frame_width = -1: expected a number > 0"),
    (["--set", "robot.nozzle_depth=400"], "robot.nozzle_depth = 400 mm, robot.build_depth = 300 mm: the printhead "
                                          "reaches into the body"),
    (["--set", "robot.max_print_speed=true"], "robot.max_print_speed = True"),
    (["--set", "robot.print_speed=40"], "--set: robot.print_speed was replaced by the per-role speeds of [slicing]"),
    (["--set", "slicing.perimeter_speed=0"], "slicing.perimeter_speed = 0: expected a number > 0"),
    (["--set", "mesh.units=km"], "mesh.units = 'km': expected one of"),
    (["--set", "mesh.place=yes"], "mesh.place = 'yes': expected true or false"),
    (["--set", "chunking.theta_deg=95"], "chunking.theta_deg = 95: expected a number > 0 and <= 90"),
    (["--set", "chunking.shift=1e-9"], "chunking.shift = 1e-09: expected a number >= 5"),
    (["--set", "program.clearance=-1"], "program.clearance = -1"),
]

#: TOML files given as --config, and a piece of the error line.
CONFIG_CASES = [
    ("[slicing]\nperimeters = 1000000000000000000\n", "slicing.perimeters = 1e+18"),
    ("[slicing]\ntop_layers = -1\n", "slicing.top_layers = -1"),
    ("[slicing]\nperimeters = 99999999999999999999999\n", "slicing.perimeters = 1e+23"),
    ("[slicing]\nlayer_height = 5\n", "slicing.layer_height = 5 mm is thicker than"),
    ("[slicing]\nlayer_height = 1e-6\n", "slicing.layer_height = 1e-06"),
    ("[slicing]\nextrusion_width = 0.1\n", "slicing.extrusion_width = 0.1 mm"),
    ("[slicing]\nlayer_hieght = 0.3\n", "did you mean 'layer_height'?"),
    ("[robot]\nprint_speed = 40.0\ntravel_speed = 120.0\n", "robot.print_speed was replaced by the per-role speeds"),
    ("[robot]\ntravel_speed = 120.0\n", "robot.travel_speed was replaced by slicing.travel_speed and the cap"),
    ("[slicer]\nlayer_height = 0.3\n", "unknown section [slicer]; did you mean 'slicing'?"),
    ("[chunking]\nshift = 1e-9\n", "chunking.shift = 1e-09"),
    ("[robot]\nname = 'x'\nmax_z = -1\n", "robot.max_z = -1"),
    ("[robot]\nframe_width = 0\n", "robot.frame_width = 0: expected a number > 0"),
    ("[robot]\nbuild_depth = 25\n", "robot.nozzle_depth = 25 mm, robot.build_depth = 25 mm"),
    ("[mesh]\nunits = 'inch'\n", "mesh.units = 'inch': expected one of 'mm', 'cm', 'm', 'in' (did you mean 'in'?)"),
    ("slicing = 3\n", "slicing must be a table"),
    ("[slicing\n", "invalid TOML"),
    ("\xff\xfe garbage", "cannot read settings file"),
]

COMMANDS = ["info", "chunk", "run", "slice"]


@pytest.fixture(scope="module")
def part(tmp_path_factory):
    folder = tmp_path_factory.mktemp("part")
    path = folder / "part.stl"
    mesh = m3d.Manifold.cube((20, 20, 5)).to_mesh64()
    write_stl(path, np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts), name="part")
    tiny = folder / "tiny.stl"
    mesh = m3d.Manifold.cube((0.2, 0.2, 0.2)).to_mesh64()
    write_stl(tiny, np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts), name="tiny")
    return path


def command(name: str, mesh, out, flags) -> list:
    if name == "info":
        return ["info", mesh, *flags]
    target = out.with_suffix(".gcode") if name == "slice" else out
    return [name, mesh, "--out", target, "-q", *flags]


@pytest.mark.parametrize("name", COMMANDS)
@pytest.mark.parametrize("flags, needle", SETTINGS_CASES, ids=[" ".join(f)[:40] for f, _ in SETTINGS_CASES])
def test_bad_settings_flags(tmp_path, capsys, part, name, flags, needle):
    assert_rejected(command(name, part, tmp_path / "out", flags), capsys, [tmp_path, part.parent], contains=needle)


@pytest.mark.parametrize("name", COMMANDS)
@pytest.mark.parametrize("text, needle", CONFIG_CASES, ids=[t[:30] for t, _ in CONFIG_CASES])
def test_bad_settings_files(tmp_path, capsys, part, name, text, needle):
    cfg = tmp_path / "bad.toml"
    cfg.write_bytes(text.encode("latin-1"))
    line = assert_rejected(command(name, part, tmp_path / "out", ["--config", cfg]), capsys, [tmp_path, part.parent],
                           contains=needle)
    assert str(cfg) in line or "--config" in line


@pytest.mark.parametrize("name", COMMANDS)
def test_a_fifo_as_config_is_refused_without_blocking(tmp_path, capsys, part, name):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs here")
    fifo = tmp_path / "settings.toml"
    os.mkfifo(fifo)  # nobody ever writes to it: reading it would block forever
    assert_rejected(command(name, part, tmp_path / "out", ["--config", fifo]), capsys, [part.parent],
                    contains="settings.toml: is a named pipe (FIFO), not a settings file")


@pytest.mark.parametrize("name", COMMANDS)
@pytest.mark.parametrize("special, needle", [("folder", "is a folder"), ("/dev/null", "is a device"),
                                             ("missing", "no such settings file")])
def test_a_config_that_is_not_a_file(tmp_path, capsys, part, name, special, needle):
    cfg = {"folder": tmp_path / "cfg.d", "missing": tmp_path / "missing.toml"}.get(special, special)
    if special == "folder":
        cfg.mkdir()
    if special == "/dev/null" and not os.path.exists("/dev/null"):
        pytest.skip("no /dev/null")
    # click refuses a folder for --config itself (dir_okay=False) or cooprint does: either way one line
    line = assert_rejected(command(name, part, tmp_path / "out", ["--config", cfg]), capsys, [tmp_path, part.parent])
    assert needle in line or "is a directory" in line


@pytest.mark.parametrize("name", ["chunk", "run", "info"])
@pytest.mark.parametrize("flags, needle", [
    (["--shift", "1e-9"], "chunking.shift = 1e-09: expected a number >= 5"),
    (["--shift", "0"], "chunking.shift = 0.0"),
    (["--theta", "95"], "chunking.theta_deg = 95.0"),
    (["--theta", "0"], "chunking.theta_deg = 0.0: expected a number > 0"),
    (["--theta", "nan"], "chunking.theta_deg = nan"),
    (["--top-width", "-1"], "chunking.top_width = -1.0"),
    (["--centre-angle", "1000"], "chunking.centre_angle_deg = 1000.0"),
    (["--robots", "65"], "65 is not in the range"),
    (["--robots", "0"], "0 is not in the range"),
])
def test_bad_chunking_flags(tmp_path, capsys, part, name, flags, needle):
    assert_rejected(command(name, part, tmp_path / "out", flags), capsys, [tmp_path, part.parent], contains=needle)


def test_a_valid_slope_outside_the_robots_range_fails_the_plan(tmp_path, capsys, part):
    assert_rejected(["chunk", part, "--out", tmp_path / "out", "-q", "--theta", "89", "--shift", "5"], capsys,
                    [tmp_path, part.parent], contains="outside the printable range")


def test_center_with_no_place_is_refused(tmp_path, capsys, part):
    """--center puts the part on the bed, --no-place keeps its frame: one of them would be ignored."""
    assert_rejected(["slice", part, "--out", tmp_path / "o.gcode", "-q", "--center", "100,100", "--no-place"], capsys,
                    [tmp_path, part.parent], contains="--center 100,100 puts the part on the bed, --no-place")


def test_strict_without_simulate_is_refused(tmp_path, capsys, part):
    assert_rejected(["run", part, "--out", tmp_path / "out", "-q", "--strict"], capsys, [tmp_path, part.parent],
                    contains="--strict needs --simulate")


@pytest.mark.parametrize("center, needle", [
    ("abc", "--center 'abc': expected X,Y in mm"),
    ("1,2,3", "--center '1,2,3'"),
    ("1;2", "--center '1;2'"),
    ("nan,0", "--center 'nan,0'"),
    ("inf,5", "--center 'inf,5'"),
    ("", "--center ''"),
    ("5000,5000", "is off the bed [0, 1000] x [0, 1000] mm"),
    ("-100,50", "is off the bed"),
    ("5,5", "is off the bed"),
])
def test_bad_center(tmp_path, capsys, part, center, needle):
    assert_rejected(["slice", part, "--out", tmp_path / "o.gcode", "-q", "--center", center], capsys,
                    [tmp_path, part.parent], contains=needle)


@pytest.mark.parametrize("name", COMMANDS)
@pytest.mark.parametrize("flags, needle", [
    ([], "too small to print"),
    (["--units", "mm"], "m: 200 x 200 x 200 mm"),
    (["--scale", "2"], "too small to print"),
    (["--units", "in", "--scale", "0.1"], "use --units mm|cm|m|in or --scale FACTOR"),
])
def test_a_part_too_small_names_units_and_scale(tmp_path, capsys, part, name, flags, needle):
    tiny = part.parent / "tiny.stl"
    assert_rejected(command(name, tiny, tmp_path / "out", flags), capsys, [tmp_path, part.parent], contains=needle)


@pytest.mark.parametrize("name", ["chunk", "run", "slice"])
@pytest.mark.parametrize("flags, needle", [
    (["--units", "m"], None),    # 20 m wide, 5 m tall: taller than the robot reaches / larger than the bed
    (["--scale", "1e6"], "reaches"),  # 20 km: past the coordinate limit
])
def test_a_part_scaled_too_large(tmp_path, capsys, part, name, flags, needle):
    line = assert_rejected(command(name, part, tmp_path / "out", flags), capsys, [tmp_path, part.parent],
                           contains=needle)
    assert "mm" in line


def test_the_infill_pattern_flag_offers_every_pattern_the_settings_take():
    """``--infill-pattern`` and ``[slicing] infill_pattern`` accept the same patterns (gyroid too)."""
    import dataclasses

    from cooprint.cli import SETTING_FLAGS
    from cooprint.config import SlicingSettings

    flag = next(f for f in SETTING_FLAGS if f[0] == "--infill-pattern")
    field = next(f for f in dataclasses.fields(SlicingSettings) if f.name == "infill_pattern")
    assert list(flag[3].choices) == list(field.metadata["choices"])
