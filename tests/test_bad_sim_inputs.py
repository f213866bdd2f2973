"""A corpus of bad simulator inputs (issue 12, deliverable 8): broken job.json of a real bundle,
broken manifests, G-code with bad host lines, inputs mixed wrongly. Each must give exit 2, one
line naming the file and the field, no traceback, and leave the bundle or folder untouched."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
import shutil

import pytest

import cooprint
from badinput import assert_rejected

from solids import bar_bundle, box, to_trimesh



@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    """A real two-robot bundle of `cooprint run`, written once for the module."""
    root = tmp_path_factory.mktemp("badsim")
    return bar_bundle(root, 6)


def _set(path, value):
    """A mutation: set the value at ``path`` (keys and indices) of job.json."""
    def apply(rec):
        d = rec
        for k in path[:-1]:
            d = d[k]
        d[path[-1]] = value
    return apply


def _drop(path):
    def apply(rec):
        d = rec
        for k in path[:-1]:
            d = d[k]
        del d[path[-1]]
    return apply


def _rename(path, new):
    def apply(rec):
        d = rec
        for k in path[:-1]:
            d = d[k]
        d[new] = d.pop(path[-1])
    return apply


R0, R1 = ("robots", 0), ("robots", 1)
HUGE_INT = 10 ** 400

# (id, mutation of the record or raw text of job.json, text the error line must hold)
JOB_CASES = [
    ("not-json", "{", "not a valid job.json"),
    ("empty", "", "not a valid job.json"),
    ("not-utf8", b"\xff\xfe{}", "not UTF-8"),
    ("top-list", "[]", "job.json: expected an object, got []"),
    ("top-null", "null", "expected an object, got null"),
    ("top-number", "3", "expected an object"),
    ("deep-nesting", "[" * 100000 + "]" * 100000, "nested too deeply"),
    ("deep-object", '{"a":' * 50000 + "1" + "}" * 50000, "nested too deeply"),
    ("no-format", _drop(("format",)), "format: missing"),
    ("format-other", _set(("format",), "other-tool/2"), "format: expected a cooprint job format"),
    ("format-number", _set(("format",), 2), "format: expected a cooprint job format"),
    ("format-null", _set(("format",), None), "format: expected"),
    ("format-chunk-bundle", _set(("format",), "cooprint-job/1"), "plan it with `cooprint run`"),
    ("no-settings", _drop(("settings",)), "settings: missing"),
    ("settings-null", _set(("settings",), None), "settings: expected an object, got null"),
    ("settings-list", _set(("settings",), []), "settings: expected an object"),
    ("settings-robot-list", _set(("settings", "robot"), [1, 2]), "settings.robot: expected an object"),
    ("settings-robot-null", _set(("settings", "robot"), None), "settings.robot: expected an object"),
    ("section-typo", _rename(("settings", "robot"), "robt"), "did you mean 'robot'"),
    ("field-typo", _rename(("settings", "robot", "acceleration"), "acceleraton"), "did you mean 'acceleration'"),
    ("max-print-speed-0", _set(("settings", "robot", "max_print_speed"), 0), "settings.robot.max_print_speed = 0"),
    ("max-print-speed-negative", _set(("settings", "robot", "max_print_speed"), -40), "robot.max_print_speed = -40"),
    ("max-travel-speed-negative", _set(("settings", "robot", "max_travel_speed"), -1.5), "robot.max_travel_speed"),
    ("max-print-speed-string", _set(("settings", "robot", "max_print_speed"), "fast"),
     "robot.max_print_speed = 'fast'"),
    ("max-print-speed-bool", _set(("settings", "robot", "max_print_speed"), True), "robot.max_print_speed = True"),
    ("max-print-speed-huge", _set(("settings", "robot", "max_print_speed"), 1e308), "robot.max_print_speed"),
    ("max-print-speed-huge-int", _set(("settings", "robot", "max_print_speed"), HUGE_INT), "robot.max_print_speed"),
    ("max-print-speed-nan", _set(("settings", "robot", "max_print_speed"), float("nan")),
     "robot.max_print_speed = nan"),
    ("max-print-speed-inf", _set(("settings", "robot", "max_print_speed"), float("inf")),
     "robot.max_print_speed = inf"),
    ("perimeter-speed-0", _set(("settings", "slicing", "perimeter_speed"), 0), "settings.slicing.perimeter_speed = 0"),
    # a bundle of cooprint before issue 17: the robot's speeds are the slicer's per role now
    ("print-speed-replaced", _set(("settings", "robot", "print_speed"), 40.0),
     "job.json: settings.robot.print_speed was replaced by the per-role speeds of [slicing] (perimeter_speed, "),
    ("travel-speed-replaced", _set(("settings", "robot", "travel_speed"), 120.0),
     "job.json: settings.robot.travel_speed was replaced by slicing.travel_speed and the cap robot.max_travel_speed"),
    ("acceleration-0", _set(("settings", "robot", "acceleration"), 0), "robot.acceleration = 0"),
    ("jerk-negative", _set(("settings", "robot", "jerk"), -1), "robot.jerk = -1"),
    ("build-depth-negative", _set(("settings", "robot", "build_depth"), -3), "robot.build_depth"),
    ("robot-name-empty", _set(("settings", "robot", "name"), ""), "robot.name"),
    ("heated-bed-string", _set(("settings", "robot", "heated_bed"), "yes"), "robot.heated_bed"),
    ("layer-height-0", _set(("settings", "slicing", "layer_height"), 0), "slicing.layer_height = 0"),
    ("perimeters-huge", _set(("settings", "slicing", "perimeters"), 10 ** 18), "slicing.perimeters"),
    ("perimeters-fraction", _set(("settings", "slicing", "perimeters"), 1.5), "slicing.perimeters = 1.5"),
    ("infill-pattern", _set(("settings", "slicing", "infill_pattern"), "zigzag"), "slicing.infill_pattern"),
    ("program-clearance-0", _set(("settings", "program", "clearance"), 0), "program.clearance = 0"),
    ("no-robots", _drop(("robots",)), "robots: missing"),
    ("robots-null", _set(("robots",), None), "robots: expected a list"),
    ("robots-object", _set(("robots",), {"A": {}}), "robots: expected a list"),
    ("robots-empty", _set(("robots",), []), "robots: expected a list of 1 to 1000 robot objects, got []"),
    ("robot-null", _set(R0, None), "robots[0]: expected an object, got null"),
    ("robot-list", _set(R0, []), "robots[0]: expected an object"),
    ("robot-number", _set(R1, 5), "robots[1]: expected an object, got 5"),
    ("robot-no-start", _drop(R0 + ("start",)), "robots[0].start: missing"),
    ("robot-no-name", _drop(R1 + ("name",)), "robots[1].name: missing"),
    ("robot-no-program", _drop(R0 + ("program",)), "robots[0].program: missing"),
    ("robot-no-facing", _drop(R0 + ("facing_deg",)), "robots[0].facing_deg: missing"),
    ("facing-typo", _rename(R0 + ("facing_deg",), "facng_deg"), "did you mean 'facing_deg'"),
    ("start-typo", _rename(R1 + ("start",), "strt"), "did you mean 'start'"),
    ("name-empty", _set(R0 + ("name",), ""), "robots[0].name: expected a robot name"),
    ("name-number", _set(R0 + ("name",), 7), "robots[0].name: expected a robot name (letters, digits, _ : . -; at most 64), got 7"),
    ("name-blank", _set(R0 + ("name",), "robot A"), "robots[0].name"),
    ("name-long", _set(R0 + ("name",), "A" * 10000), "robots[0].name"),
    ("name-duplicate", _set(R1 + ("name",), "A"), "robots[1].name: a second robot of that name"),
    ("program-absolute", _set(R0 + ("program",), "/etc/passwd"), "robots[0].program: expected a path inside"),
    ("program-parent", _set(R0 + ("program",), "../job/robots/A.coop"), "robots[0].program: expected a path inside"),
    ("program-dotdot", _set(R1 + ("program",), "robots/../../x.coop"), "robots[1].program"),
    ("program-backslash", _set(R1 + ("program",), "robots\\B.coop"), "robots[1].program"),
    ("program-missing", _set(R0 + ("program",), "robots/nope.coop"), "no such program file"),
    ("program-folder", _set(R0 + ("program",), "robots"),
     "robots[0].program: expected a program file in the bundle, not a folder"),
    ("program-number", _set(R0 + ("program",), 7), "robots[0].program: expected a path"),
    ("program-empty", _set(R0 + ("program",), ""), "robots[0].program"),
    ("program-nul", _set(R0 + ("program",), "robots/A.coop\x00"), "robots[0].program"),
    ("start-string-item", _set(R1 + ("start",), [0, "a", 0]), 'robots[1].start: expected 3 finite numbers'),
    ("start-short", _set(R1 + ("start",), [0, 0]), "robots[1].start: expected 3 finite numbers"),
    ("start-long", _set(R1 + ("start",), [0, 0, 0, 0]), "robots[1].start"),
    ("start-nan", _set(R0 + ("start",), [float("nan"), 0, 0]), "got [NaN, 0, 0]"),
    ("start-inf", _set(R0 + ("start",), [0, float("-inf"), 0]), "robots[0].start"),
    ("start-huge", _set(R0 + ("start",), [1e300, 0, 0]), "within +-1e+06"),
    ("start-huge-int", _set(R0 + ("start",), [HUGE_INT, 0, 0]), "robots[0].start"),
    ("start-string", _set(R0 + ("start",), "0,0,0"), "robots[0].start"),
    ("start-null", _set(R0 + ("start",), None), "robots[0].start"),
    ("start-bool", _set(R0 + ("start",), [True, 0, 0]), "robots[0].start"),
    ("start-object", _set(R0 + ("start",), {"x": 0}), "robots[0].start"),
    ("facing-nan", _set(R0 + ("facing_deg",), float("nan")), "robots[0].facing_deg"),
    ("facing-inf", _set(R1 + ("facing_deg",), float("inf")), "robots[1].facing_deg"),
    ("facing-string", _set(R0 + ("facing_deg",), "north"), "robots[0].facing_deg"),
    ("facing-null", _set(R0 + ("facing_deg",), None), "robots[0].facing_deg"),
    ("facing-huge", _set(R0 + ("facing_deg",), 1e9), "robots[0].facing_deg"),
    ("facings-number", _set(R0 + ("facings",), 5), "robots[0].facings: expected a list"),
    # the record's own fields: known keys, their types, the versions written, consistent facings
    ("top-key-typo", _rename(("robots",), "robts"), "robts: unknown key (did you mean 'robots'?)"),
    ("top-key-unknown", _set(("colour",), "red"), "colour: unknown key; expected one of: format"),
    ("chunks-null", _set(("chunks",), None), "chunks: expected a list"),
    ("chunks-item-number", _set(("chunks", 0), 3), "chunks[0]: expected an object, got 3"),
    ("chunks-no-id", _drop(("chunks", 0, "id")), "chunks[0].id: missing"),
    ("schedule-null", _set(("schedule",), None), "schedule: expected an object, got null"),
    ("stats-string", _set(("stats",), "x"), 'stats: expected an object, got "x"'),
    ("mesh-list", _set(("mesh",), []), "mesh: expected an object"),
    ("plan-number", _set(("plan",), 1), "plan: expected an object"),
    ("format-newer", _set(("format",), "cooprint-job/99"), "format: written by a newer cooprint"),
    ("facing-contradicts", _set(R0 + ("facing",), [5, 5]), "robots[0].facing: expected 2 finite numbers"),
    ("facing-not-unit", _set(R0 + ("facing",), [0.6, 0.8]), "robots[0].facing: expected [6.12323e-17, 1]"),
    ("facing-deg-edited", _set(R0 + ("facing_deg",), 0.0), "robots[0].facing: expected [1, 0], the unit vector"),
    ("side-up", _set(R0 + ("side",), "up"), "robots[0].side: expected one of left, right, both"),
    ("facings-unknown-chunk", _set(R0 + ("facings",), [{"from_chunk": "Z9", "facing_deg": 90.0}]),
     "robots[0].facings[0].from_chunk: expected the id of one of this robot's chunks"),
    ("facings-other-robots-chunk", _set(R0 + ("facings",), [{"from_chunk": "R1", "facing_deg": 90.0}]),
     "robots[0].facings[0].from_chunk"),
    ("facings-nan", _set(R0 + ("facings",), [{"from_chunk": "L1", "facing_deg": float("nan")}]),
     "robots[0].facings[0].facing_deg"),
    ("facings-key-typo", _set(R0 + ("facings",), [{"chunk": "L1", "facing_deg": 90.0}]),
     "robots[0].facings[0].chunk: unknown key (did you mean 'from_chunk'?)"),
    ("facings-item-string", _set(R0 + ("facings",), ["L1"]), "robots[0].facings[0]: expected an object"),
    ("robot-chunks-unknown", _set(R0 + ("chunks",), ["Q7"]), "robots[0].chunks[0]: expected the id of one"),
    # a robot's own profile (issue 13): a name, or an object of [robot] fields, each checked
    ("profile-number", _set(R1 + ("profile",), 5), "robots[1].profile: expected a profile name or an object"),
    ("profile-list", _set(R1 + ("profile",), [40]), "robots[1].profile: expected a profile name or an object"),
    ("profile-name-empty", _set(R0 + ("profile",), ""), "robots[0].profile: expected a profile name"),
    ("profile-typo", _rename(R1 + ("profile", "nozzle_depth"), "nozle_depth"),
     "robots[1].profile.nozle_depth: unknown key (did you mean 'nozzle_depth'?)"),
    ("profile-slicing-field", _set(R1 + ("profile", "layer_height"), 0.2), "robots[1].profile.layer_height: unknown key"),
    ("profile-nozzle-depth-negative", _set(R1 + ("profile", "nozzle_depth"), -1),
     "robots[1].profile.nozzle_depth = -1: expected a number > 0 and <= 10000 (mm)"),
    ("profile-print-speed-0", _set(R0 + ("profile",), {"max_print_speed": 0}), "robots[0].profile.max_print_speed = 0"),
    ("profile-print-speed-replaced", _set(R0 + ("profile", "print_speed"), 40.0),
     "job.json: robots[0].profile.print_speed was replaced by the per-role speeds of [slicing]"),
    ("profile-body-width-string", _set(R0 + ("profile", "body_width"), "wide"), "robots[0].profile.body_width = 'wide'"),
    ("profile-body-nan", _set(R1 + ("profile", "body_length"), float("nan")), "robots[1].profile.body_length = nan"),
    ("profile-name-blank", _set(R1 + ("profile", "name"), " "), "robots[1].profile.name"),
    ("profile-heated-bed-number", _set(R1 + ("profile", "heated_bed"), 1), "robots[1].profile.heated_bed = 1"),
    # the chunks' dependencies (the chunk-order check)
    ("deps-unknown-chunk", _set(("chunks", 1, "deps"), ["Z9"]), "chunks[1].deps[0]: expected the id of one of the"),
    ("deps-number", _set(("chunks", 1, "deps"), 3), "chunks[1].deps: expected a list"),
    ("deps-item-number", _set(("chunks", 2, "deps"), [0]), "chunks[2].deps[0]: expected the id"),
    ("deps-itself", _set(("chunks", 1, "deps"), ["C", "L1"]), "chunks[1].deps[1]: a chunk cannot depend on itself"),
]


def _write_job(job, case):
    path = job / "job.json"
    if isinstance(case, (str, bytes)):
        path.write_bytes(case.encode() if isinstance(case, str) else case)
        return
    record = json.loads(path.read_text())
    case(record)
    path.write_text(json.dumps(record))  # NaN / Infinity as JSON extensions, as Python writes them


@pytest.mark.parametrize("case, needle", [c[1:] for c in JOB_CASES], ids=[c[0] for c in JOB_CASES])
def test_broken_job_json_is_one_line(bundle, tmp_path, capsys, case, needle):
    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    _write_job(job, case)
    line = assert_rejected(["simulate", job], capsys, watch=[job], contains=needle)
    assert "job.json" in line


def test_acceleration_0_with_accel(bundle, tmp_path, capsys):
    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    _write_job(job, _set(("settings", "robot", "acceleration"), 0))
    assert_rejected(["simulate", job, "--accel"], capsys, watch=[job], contains="robot.acceleration = 0")


def test_a_broken_program_in_the_bundle(bundle, tmp_path, capsys):
    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    (job / "robots" / "B.coop").write_text("MOVE 1, 2\n")
    assert_rejected(["simulate", job], capsys, watch=[job], contains="B.coop")


# ------------------------------------------------------------------------------------------------
# manifests

ROBOT = '[[robots]]\nname = "A"\nprogram = "A.coop"\n'
MANIFEST_CASES = [
    ("not-toml", "[[robots]\n", "not a valid manifest"),
    ("deep", "x = " + "[" * 5000 + "]" * 5000 + "\n", "nested too deeply"),
    ("section-typo", "[robt]\nmax_print_speed = 40\n" + ROBOT, "robt: unknown key (did you mean 'robot'?)"),
    ("program-section", "[program]\nclearance = 5\n" + ROBOT, "program: unknown key"),
    ("robot-not-table", "robot = 5\n" + ROBOT, "robot: expected an object, got 5"),
    ("max-print-speed-0", "[robot]\nmax_print_speed = 0\n" + ROBOT, "robot.max_print_speed = 0"),
    ("max-print-speed-negative", "[robot]\nmax_print_speed = -1\n" + ROBOT, "robot.max_print_speed = -1"),
    ("field-typo", "[robot]\nmax_print_sped = 40\n" + ROBOT, "did you mean 'max_print_speed'"),
    ("print-speed-replaced", "[robot]\nprint_speed = 40\n" + ROBOT,
     "m.toml: robot.print_speed was replaced by the per-role speeds of [slicing] (perimeter_speed, "),
    ("infill-speed-negative", "[slicing]\ninfill_speed = -80\n" + ROBOT, "m.toml: slicing.infill_speed = -80"),
    ("layer-height-negative", "[slicing]\nlayer_height = -1\n" + ROBOT, "slicing.layer_height = -1"),
    ("no-robots", "[robot]\nmax_print_speed = 40\n", "no [[robots]] entries"),
    ("robots-empty", "robots = []\n", "robots: expected a list of 1 to 1000 [[robots]] entries"),
    ("robots-number", "robots = 5\n", "robots: expected a list"),
    ("robot-item-number", "robots = [5]\n", "robots[0]: expected an object, got 5"),
    ("no-name", '[[robots]]\nprogram = "A.coop"\n', "robots[0].name: missing"),
    ("no-program", '[[robots]]\nname = "A"\n', "robots[0].program: missing"),
    ("facing-typo", ROBOT + "facing = 90\n", "robots[0].facing: unknown key (did you mean 'facing_deg'?)"),
    ("unknown-key", ROBOT + 'colour = "red"\n', "robots[0].colour: unknown key; expected one of: name, program"),
    ("unknown-key-1mb", ROBOT + "k" * 1_000_000 + " = 1\n", "robots[0].kkkkkkkk"),
    ("name-1mb", '[[robots]]\nname = "' + "n" * 1_000_000 + '"\nprogram = "A.coop"\n', "robots[0].name"),
    ("start-short", ROBOT + "start = [0, 0]\n", "robots[0].start: expected 3 finite numbers"),
    ("start-huge", ROBOT + "start = [1e300, 0, 0]\n", "robots[0].start"),
    ("start-nan", ROBOT + "start = [nan, 0, 0]\n", "robots[0].start"),
    ("start-string", ROBOT + 'start = "0 0 0"\n', "robots[0].start"),
    ("facing-inf", ROBOT + "facing_deg = inf\n", "robots[0].facing_deg"),
    ("facing-string", ROBOT + 'facing_deg = "north"\n', "robots[0].facing_deg"),
    ("name-duplicate", ROBOT + ROBOT, "robots[1].name: a second robot of that name"),
    ("name-number", '[[robots]]\nname = 1\nprogram = "A.coop"\n', "robots[0].name"),
    ("name-blank", '[[robots]]\nname = "a b"\nprogram = "A.coop"\n', "robots[0].name"),
    ("program-missing", '[[robots]]\nname = "A"\nprogram = "B.coop"\n', "robots[0].program: no such .coop file"),
    ("program-number", '[[robots]]\nname = "A"\nprogram = 3\n', "robots[0].program"),
    ("program-folder", '[[robots]]\nname = "A"\nprogram = "."\n', "robots[0].program"),
    # a robot's own profile (issue 13): [profiles.NAME] for a robot of [[robots]], [robot] fields
    ("profile-of-no-robot", ROBOT + "[profiles.C]\nmax_print_speed = 20\n",
     "m.toml: profiles.C: no robot C in [[robots]]"),
    ("profile-of-a-near-name", ROBOT + "[profiles.A1]\nmax_print_speed = 20\n",
     "profiles.A1: no robot A1 in [[robots]] (did you mean [profiles.A]?)"),
    ("profile-of-the-name-in-lower-case", ROBOT + "[profiles.a]\nmax_print_speed = 20\n",
     "profiles.a: no robot a in [[robots]] (did you mean [profiles.A]?)"),
    ("profile-typo", ROBOT + "[profiles.A]\nmax_print_sped = 20\n",
     "profiles.A.max_print_sped: unknown key (did you mean 'max_print_speed'?)"),
    ("profile-travel-speed-replaced", ROBOT + "[profiles.A]\ntravel_speed = 100\n",
     "m.toml: profiles.A.travel_speed was replaced by slicing.travel_speed and the cap robot.max_travel_speed"),
    ("profile-slicing-field", ROBOT + "[profiles.A]\nlayer_height = 0.2\n", "profiles.A.layer_height: unknown key"),
    ("profile-bad-value", ROBOT + "[profiles.A]\nnozzle_depth = -1\n",
     "m.toml: profiles.A.nozzle_depth = -1: expected a number > 0 and <= 10000 (mm)"),
    ("profile-string-value", ROBOT + '[profiles.A]\nbody_width = "wide"\n', "profiles.A.body_width = 'wide'"),
    ("profiles-not-table", "profiles = 5\n" + ROBOT, "profiles: expected an object, got 5"),
    ("profile-not-table", "profiles = {A = 5}\n" + ROBOT, "profiles.A: expected an object, got 5"),
    ("profiles-typo", "[profile.A]\nmax_print_speed = 20\n" + ROBOT, "profile: unknown key (did you mean 'profiles'?)"),
]


@pytest.mark.parametrize("text, needle", [c[1:] for c in MANIFEST_CASES], ids=[c[0] for c in MANIFEST_CASES])
def test_broken_manifest_is_one_line(tmp_path, capsys, text, needle):
    (tmp_path / "A.coop").write_text("MOVE 0, 0, 0.2\nTOOL ON\nMOVE 10, 0, 0.2\nTOOL OFF\n")
    (tmp_path / "m.toml").write_text(text)
    line = assert_rejected(["simulate", "--manifest", tmp_path / "m.toml", "--out", tmp_path / "o"], capsys,
                           watch=[tmp_path], contains=needle)
    assert "m.toml" in line


@pytest.mark.parametrize("content, needle", [(None, "no such manifest"), ("dir", "is a directory"),
                                             (b"\xff[robot]", "not UTF-8")], ids=["missing", "folder", "not-utf8"])
def test_unreadable_manifest(tmp_path, capsys, content, needle):
    m = tmp_path / "m.toml"
    if content == "dir":
        m.mkdir()
    elif content is not None:
        m.write_bytes(content)
    assert_rejected(["simulate", "--manifest", m, "--out", tmp_path / "o"], capsys, watch=[tmp_path], contains=needle)


# ------------------------------------------------------------------------------------------------
# G-code with bad host lines

MOVES = "G1 X0 Y0 Z0.2 F1200\nG1 X10 E1\n"
HOST_CASES = [
    ("notify-no-event", "M118 NOTIFY\n", "expected M118 NOTIFY and one event name"),
    ("notify-two-events", "M118 NOTIFY C D\n", "expected M118 NOTIFY and one event name"),
    ("notify-comma", "M118 NOTIFY C,D\n", "expected M118 NOTIFY"),
    ("notify-bad-char", "M118 NOTIFY C!\n", "expected M118 NOTIFY"),
    ("notify-unicode", "M118 NOTIFY Ç\n", "expected M118 NOTIFY"),
    ("notify-long", "M118 NOTIFY " + "x" * 5000 + "\n", "expected M118 NOTIFY"),
    ("wait-no-event", "M400\nM0 WAIT\n", "got an empty name"),
    ("wait-empty-item", "M0 WAIT C,,D\n", "got an empty name"),
    ("wait-trailing-comma", "M0 WAIT C,\n", "got an empty name"),
    ("wait-space", "M0 WAIT C D\n", "got 'C D'"),
    ("wait-bad-char", "M1 WAIT C;D\n", None),  # 'C' then a comment: a valid WAIT C; checked below
    ("wait-m1-unicode", "M1 WAIT é\n", "expected M1 WAIT"),
    ("wait-lower", "m0 wait c d\n", "expected M0 WAIT"),
    ("wait-long", "M0 WAIT " + "y" * 300 + "\n", "expected M0 WAIT"),
    ("coordinate-huge", "G1 X1e308 E1\n", "beyond +-1e+06 mm"),
    ("coordinate-huge-plain", "G1 X10000000 E1\n", "beyond +-1e+06 mm"),
    ("relative-walks-away", "G91\n" + "G1 X600000\n" * 3, "beyond +-1e+06 mm"),
    ("e-huge", "M83\nG1 X20 E1e9\n", "beyond +-1e+06 mm"),
    ("coordinate-nan", "G1 Xnan E1\n", "not a finite number"),
    ("feed-zero", "G1 X5 F0\n", "feed rate F0 is not positive"),
]


@pytest.mark.parametrize("text, needle", [c[1:] for c in HOST_CASES if c[2]],
                         ids=[c[0] for c in HOST_CASES if c[2]])
def test_gcode_with_a_bad_line_is_one_line(tmp_path, capsys, text, needle):
    g = tmp_path / "A.gcode"
    g.write_text(MOVES + text + MOVES, encoding="utf-8")
    line = assert_rejected(["simulate", g, "--out", tmp_path / "o"], capsys, watch=[tmp_path], contains=needle)
    assert "A.gcode:" in line and len(line) < 300


def test_a_wait_whose_comment_holds_a_semicolon_is_a_wait(tmp_path):
    from cooprint.simulation import load_inputs

    g = tmp_path / "A.gcode"
    g.write_text(MOVES + "M1 WAIT C;D\n" + MOVES)
    (r,) = load_inputs([str(g)]).robots
    assert r.program.events == (("C",),)


# ------------------------------------------------------------------------------------------------
# inputs mixed wrongly

def _files(tmp_path):
    (tmp_path / "A.coop").write_text("MOVE 0, 0, 0.2\n")
    (tmp_path / "B.gcode").write_text(MOVES)
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "B.gcode").write_text(MOVES)
    (tmp_path / "sub" / "A.coop").write_text("MOVE 0, 0, 0.2\n")
    (tmp_path / "a b.coop").write_text("MOVE 0, 0, 0.2\n")
    (tmp_path / "notes.txt").write_text("hello\n")
    (tmp_path / "empty").mkdir()
    (tmp_path / "m.toml").write_text(ROBOT)
    (tmp_path / "slow.toml").write_text("[robot]\nmax_print_speed = 20\n")


MIX_CASES = [
    ("coop-and-gcode", ["A.coop", "B.gcode"], "both .coop and G-code files"),
    ("bundle-and-file", ["BUNDLE", "B.gcode"], "a bundle folder is simulated alone"),
    ("two-bundles", ["BUNDLE", "BUNDLE"], "one bundle at a time"),
    ("two-bundles-no-out", ["BUNDLE", "BUNDLE", "NO-OUT"], "one bundle at a time"),
    ("manifest-and-file", ["--manifest", "m.toml", "A.coop"], "give no input files with it"),
    ("text-file", ["notes.txt"], "notes.txt: expected a bundle folder"),
    ("same-file-twice", ["B.gcode", "B.gcode"], "the same file given twice"),
    ("same-gcode-name", ["B.gcode", "sub/B.gcode"], "two G-code files with the same name"),
    ("same-coop-name", ["A.coop", "sub/A.coop"], "a second robot named 'A'"),
    ("coop-name-not-a-robot-name", ["a b.coop"], "is not a robot name"),
    ("missing-file", ["nope.gcode"], "nope.gcode: no such file or folder"),
    ("folder-not-a-bundle", ["empty"], "no job.json"),
    ("nothing", [], "nothing to simulate"),
    ("bundle-with-a-profile", ["BUNDLE", "--robot", "slow.toml"], "a bundle or a manifest carries its own settings"),
    ("manifest-with-a-profile", ["--manifest", "m.toml", "--robot", "slow.toml"], "carries its own settings"),
    ("profile-not-settings", ["A.coop", "--robot", "m.toml"], "unknown section [robots]"),
]


@pytest.mark.parametrize("args, needle", [c[1:] for c in MIX_CASES], ids=[c[0] for c in MIX_CASES])
def test_inputs_mixed_wrongly(bundle, tmp_path, capsys, monkeypatch, args, needle):
    _files(tmp_path)
    monkeypatch.chdir(tmp_path)
    out = [] if "NO-OUT" in args else ["--out", tmp_path / "o"]
    args = [str(bundle) if a == "BUNDLE" else a for a in args if a != "NO-OUT"]
    assert_rejected(["simulate", *args, *out], capsys, watch=[tmp_path, bundle], contains=needle)


# ------------------------------------------------------------------------------------------------
# any value anywhere in job.json: loaded, or one UserError; never another exception

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_json = st.recursive(
    st.none() | st.booleans() | st.integers(-(10 ** 30), 10 ** 30) | st.sampled_from([10 ** 400, -(10 ** 400)])
    | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=12), inner, max_size=4),
    max_leaves=12)
_PATHS = [(), ("format",), ("settings",), ("settings", "robot"), ("settings", "robot", "max_print_speed"),
          ("settings", "slicing", "perimeters"), ("settings", "slicing", "layer_height"), ("robots",), R0, R1,
          R0 + ("name",), R1 + ("name",), R0 + ("program",), R1 + ("start",), R0 + ("start", 1),
          R0 + ("facing_deg",), R1 + ("facings",), R0 + ("stats",), R0 + ("facing",), ("settings", "robt"),
          R0 + ("facng_deg",), R1 + ("profile",), R1 + ("profile", "body_width"), ("chunks", 1, "deps")]


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(path=st.sampled_from(_PATHS), value=_json)
def test_any_value_anywhere_in_job_json_loads_or_is_a_user_error(bundle, tmp_path_factory, path, value):
    from cooprint.errors import UserError
    from cooprint.simulation import load_inputs

    job = tmp_path_factory.getbasetemp() / "fuzzjob"
    if not job.exists():
        shutil.copytree(bundle, job)
    record = json.loads((bundle / "job.json").read_text())
    if path:
        d = record
        for k in path[:-1]:
            d = d[k]
        d[path[-1]] = value
    else:
        record = value
    (job / "job.json").write_text(json.dumps(record))
    try:
        inp = load_inputs([str(job)])
    except UserError as exc:
        assert "\n" not in str(exc) and len(str(exc)) < 600 and "job.json" in str(exc)
    else:
        assert [r.name for r in inp.robots] == [r["name"] for r in record["robots"]]


# ------------------------------------------------------------------------------------------------
# named pipes (FIFOs) as inputs: opening one for reading would block for ever, so each case runs
# the CLI in a subprocess with a timeout (a hang fails the test instead of hanging the suite)

def _fifo_case(root, bundle, case):
    """Make the FIFO of ``case`` under ``root``; return the arguments of ``cooprint``."""
    if case in ("job.json", "robots/A.coop"):
        copy = root / "job"
        shutil.copytree(bundle, copy)
        (copy / case).unlink()
        os.mkfifo(copy / case)
        return ["simulate", copy, "--out", root / "o"]
    os.mkfifo(root / case)
    (root / "m2.toml").write_text(ROBOT.replace("A.coop", "A2.coop"))
    return {
        "A2.coop": ["simulate", "--manifest", "m2.toml", "--out", "o"],
        "f.gcode": ["simulate", "f.gcode", "--out", "o"],
        "f.coop": ["simulate", "f.coop", "--out", "o"],
        "m.toml": ["simulate", "--manifest", "m.toml", "--out", "o"],
        "f.stl": ["run", "f.stl", "--out", "o"],
        "s.toml": ["chunk", "f2.stl", "--config", "s.toml", "--out", "o"],
    }[case]


FIFO_CASES = [("f.gcode", "f.gcode: is a named pipe (FIFO), not a G-code file"),
              ("f.coop", "f.coop: is a named pipe (FIFO), not a command file"),
              ("m.toml", "m.toml: is a named pipe (FIFO), not a manifest"),
              ("A2.coop", "robots[0].program: expected a .coop file, not a folder, a named pipe (FIFO)"),
              ("f.stl", "f.stl: is a named pipe (FIFO), not a mesh file"),
              ("s.toml", "s.toml: is a named pipe (FIFO), not a settings file"),
              ("job.json", "job.json: is a named pipe (FIFO), not a job.json"),
              ("robots/A.coop", "robots[0].program: expected a program file in the bundle, not a folder, a named pipe")]


@pytest.mark.parametrize("case, needle", FIFO_CASES, ids=[c[0] for c in FIFO_CASES])
def test_a_fifo_input_is_refused_at_once(bundle, tmp_path, case, needle):
    to_trimesh(box(10, 10, 10)).export(tmp_path / "f2.stl")
    args = [str(a) for a in _fifo_case(tmp_path, bundle, case)]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(Path(cooprint.__file__).parents[1]),
                                                       os.environ.get("PYTHONPATH", "")]))
    done = subprocess.run([sys.executable, "-m", "cooprint", *args], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=20)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr[-800:]
    assert lines[0].startswith("cooprint: error: ") and needle in lines[0], lines[0]
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("make", ["long-name", "symlink-loop", "manifest-long-program"])
def test_paths_that_cannot_be_looked_at_are_one_line(tmp_path, capsys, make):
    """A name longer than the file system allows, or a symlink loop, is an input error (the
    fuzz found `Path.is_file()` letting the OSError through for a manifest's program)."""
    long = "a" * 300
    if make == "long-name":
        args = ["simulate", tmp_path / f"{long}.gcode", "--out", tmp_path / "o"]
    elif make == "symlink-loop":
        (tmp_path / "l1.coop").symlink_to(tmp_path / "l2.coop")
        (tmp_path / "l2.coop").symlink_to(tmp_path / "l1.coop")
        args = ["simulate", tmp_path / "l1.coop", "--out", tmp_path / "o"]
    else:
        (tmp_path / "m.toml").write_text(f'[[robots]]\nname = "A"\nprogram = "{long}.coop"\n')
        args = ["simulate", "--manifest", tmp_path / "m.toml", "--out", tmp_path / "o"]
    assert_rejected(args, capsys, watch=[tmp_path], contains="cannot use this path")


# ------------------------------------------------------------------------------------------------
# a program that is not the one job.json describes (cut short, emptied, edited)

def _cut(text: str, how: str) -> str:
    lines = text.splitlines(keepends=True)
    if how == "emptied":
        return ""
    if how == "cut-at-a-line":
        return "".join(lines[:len(lines) // 2])
    at = next(i for i, ln in enumerate(lines) if ln.startswith("NOTIFY"))  # a NOTIFY edited into another command
    return "".join(lines[:at] + ["TOOL OFF\n"] + lines[at + 1:])


@pytest.mark.parametrize("how, says", [("emptied", "0 commands, job.json says "),
                                       ("cut-at-a-line", " commands, job.json says "),
                                       ("notify-removed", " NOTIFY, job.json says ")])
@pytest.mark.parametrize("command", [[], ["--accel"], ["--perturb", "0.1", "--runs", "2"]],
                         ids=["piecewise", "whole", "perturb"])
def test_a_program_that_job_json_does_not_describe_is_refused(bundle, tmp_path, capsys, how, says, command):
    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    program = job / "robots" / ("A.coop" if how == "notify-removed" else "B.coop")
    program.write_text(_cut(program.read_text(), how))
    line = assert_rejected(["simulate", job, *command], capsys, watch=[job], contains=f"{program}: ")
    assert says in line and "the file was truncated or replaced; re-run `cooprint run`" in line


def test_job_json_counts_must_be_counts(bundle, tmp_path, capsys):
    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    _write_job(job, _set(R1 + ("stats", "commands"), "many"))
    assert_rejected(["simulate", job], capsys, watch=[job], contains="robots[1].stats.commands: expected a count")
