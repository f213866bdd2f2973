import pytest

from cooprint.config import JobSettings, load_settings
from cooprint.errors import ConfigError


def test_defaults_match_dataclass_defaults():
    # the shipped TOML and the dataclass defaults describe the same robot
    assert load_settings() == JobSettings()


def test_file_overrides_defaults(tmp_path):
    f = tmp_path / "r.toml"
    f.write_text("[robot]\nname = 'big'\nbuild_depth = 900\n[chunking]\ntheta_deg = 50\n")
    s = load_settings(f)
    assert s.robot.name == "big" and s.robot.build_depth == 900.0
    assert s.robot.nozzle_height == JobSettings().robot.nozzle_height
    assert s.chunking.theta_deg == 50.0


def test_overrides_win_over_files_and_none_is_ignored(tmp_path):
    f = tmp_path / "r.toml"
    f.write_text("[chunking]\nshift = 10\n")
    s = load_settings(f, overrides={"chunking.shift": 20.0, "chunking.theta_deg": None})
    assert s.chunking.shift == 20.0 and s.chunking.theta_deg is None


@pytest.mark.parametrize("text, needle", [
    ("[robot]\nbuild_depth = -3\n", "robot.build_depth = -3: expected a number > 0 and <= 100000 (mm)"),
    ("[robot]\nnozzle_height = 'tall'\n", "robot.nozzle_height = 'tall': expected a number"),
    ("[robot]\nbuild_depth = nan\n", "robot.build_depth = nan"),
    ("[robot]\nmax_print_speed = true\n", "robot.max_print_speed = True"),
    ("[robot]\nmax_travel_speed = 0\n", "robot.max_travel_speed = 0: expected a number > 0 and <= 10000 (mm/s)"),
    ("[slicing]\nbridge_speed = -60\n", "slicing.bridge_speed = -60: expected a number > 0 and <= 10000 (mm/s)"),
    # the fields cooprint no longer reads: what replaced them (issue 17)
    ("[robot]\nprint_speed = 40\n", "robot.print_speed was replaced by the per-role speeds of [slicing] "
                                     "(perimeter_speed, infill_speed, ...; docs/slicer.md) and the cap "
                                     "robot.max_print_speed"),
    ("[robot]\ntravel_speed = 120\n", "robot.travel_speed was replaced by slicing.travel_speed and the cap "
                                       "robot.max_travel_speed"),
    ("[chunking]\ntheta_deg = 95\n", "chunking.theta_deg = 95: expected a number > 0 and <= 90 (deg)"),
    ("[robot]\nwheels = 4\n", "unknown field robot.wheels; expected one of:"),
    ("[printer]\nx = 1\n", "unknown section [printer]"),
    ("[robot]\nname = ''\n", "robot.name = '': expected a non-empty string"),
    ("[robot\n", "invalid TOML"),
    ('[slicing]\ninfill_pattern = "honeycomb"\n', "slicing.infill_pattern = 'honeycomb': expected one of"),
    ("[slicing]\nperimeters = 2.5\n", "slicing.perimeters = 2.5: expected a whole number"),
    ("[slicing]\nouter_perimeter_first = 1\n", "slicing.outer_perimeter_first = 1: expected true or false"),
    ("[slicing]\ninfill_density = 1.5\n", "slicing.infill_density = 1.5: expected a number >= 0 and <= 1"),
])
def test_bad_fields_name_file_field_value_and_range(tmp_path, text, needle):
    f = tmp_path / "bad.toml"
    f.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_settings(f)
    msg = str(err.value)
    assert str(f) in msg and needle in msg
    assert "\n" not in msg


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="no such settings file"):
        load_settings(tmp_path / "nope.toml")


def test_bad_override_is_named_as_option():
    with pytest.raises(ConfigError, match=r"option: chunking.shift = -1"):
        load_settings(overrides={"chunking.shift": -1})
