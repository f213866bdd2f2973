"""Issue 12, deliverable 6 and the simulator-input half of 8: the robots' own G-code (heating after
the WAIT, no bed they do not have), its host lines in `simulate`, and .coop files without a
manifest (the seed's own sample program)."""

from __future__ import annotations

import dataclasses
import io
import json
import re
from pathlib import Path

import numpy as np
import pytest

from cooprint.cli import main
from cooprint.config import load_settings
from cooprint.jobs import run
from cooprint.program.commands import MOVE, TOOL_OFF, TOOL_ON, WAIT, make_program
from cooprint.program.gcode import Feeds, Heating, write_gcode
from cooprint.simulation import load_inputs, simulate, summary
from cooprint.simulation.gcode import gcode_rows
from cooprint.simulation.inputs import coop_facing
from cooprint.simulation.timeline import wait_estimates

from solids import COARSE, bar_bundle, box, to_trimesh



@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    """A two-robot plan of a 300 mm bar: A prints C then L1, B waits for C, then prints R1."""
    root = tmp_path_factory.mktemp("robotgcode")
    return bar_bundle(root, 20)


def _lines(path):
    return path.read_text(encoding="ascii").splitlines()


def _first(lines, pattern):
    return next(i for i, ln in enumerate(lines) if re.match(pattern, ln))


EXTRUDE = r"G1 X\S+ Y\S+ (Z\S+ )?E\d"  # a printing move (positive E)


def test_robot_b_heats_its_nozzle_after_the_wait_and_no_robot_heats_a_bed(bundle):
    a, b = _lines(bundle / "robots" / "A.gcode"), _lines(bundle / "robots" / "B.gcode")
    wait = b.index("M0 WAIT C")
    assert _first(b, r"M10[49] ") > wait  # not 7 h hot before its first line
    assert _first(b, r"M104 S210") < _first(b, r"M109 S210") < _first(b, EXTRUDE)
    for lines in (a, b):
        assert not [ln for ln in lines if re.match(r"M1(40|90)\b", ln)]
    # A heats right before its first extrusion, and has no WAIT to heat before
    assert _first(a, r"M104 S210") < _first(a, r"M109 S210") < _first(a, EXTRUDE)
    assert not [ln for ln in a[:_first(a, r"M104")] if ln.startswith("G1 ") and " E" in ln]
    for lines in (a, b):  # the end code turns the nozzle off, and no bed
        assert "M104 S0" in lines[-6:] and "M140 S0" not in lines


def test_a_robot_with_a_heated_bed_heats_it(tmp_path):
    to_trimesh(box(40, 420, 10)).export(tmp_path / "bar.stl")
    run(tmp_path / "bar.stl", tmp_path / "job", overrides={**COARSE, "robot.heated_bed": True}, picture=False)
    b = _lines(tmp_path / "job" / "robots" / "B.gcode")
    assert _first(b, r"M140 S60") < _first(b, r"M190 S60") < b.index("M0 WAIT C") < _first(b, r"M109 S210")
    assert "M140 S0" in b


def _program(wait_between: bool = True):
    """Print a line, WAIT for X, print another."""
    kind = [MOVE, TOOL_ON, MOVE, TOOL_OFF] + ([WAIT] if wait_between else []) + [MOVE, TOOL_ON, MOVE, TOOL_OFF]
    xyz = np.zeros((len(kind), 3))
    xyz[:, 2] = 0.2
    xyz[2, 0] = 10
    xyz[-4, 1] = xyz[-2, 1] = 10
    xyz[-2, 0] = 10
    return make_program("R", np.array(kind), xyz, width=0.45, height=0.2, layer=0,
                        events=(("X",),) if wait_between else ())


def _gcode(heating):
    s = load_settings().slicing
    buf = io.StringIO()
    write_gcode(buf, [_program()], s, Feeds.of_slicer(s), "t", home=False, heating=heating)
    return buf.getvalue().splitlines()


@pytest.mark.parametrize("wait_s, cools", [(1000.0, True), (600.0, False), (100.0, False), (None, True)])
def test_the_nozzle_is_kept_hot_across_a_wait_only_up_to_the_idle_limit(wait_s, cools):
    g = _gcode(Heating(210.0, None, 600.0, () if wait_s is None else (wait_s,)))  # None: no estimate = long
    wait = g.index("M0 WAIT X")
    first, second = _first(g, EXTRUDE), wait + _first(g[wait:], EXTRUDE)
    off = [i for i, ln in enumerate(g) if ln.startswith("M104 S0")]
    heats = [i for i, ln in enumerate(g) if ln.startswith("M109 S210")]
    if cools:
        assert first < off[0] < wait < heats[1] < second and len(heats) == 2
    else:
        assert heats == [heats[0]] and heats[0] < first and off[0] > second  # only the end code's
    assert not [ln for ln in g if ln.startswith(("M140", "M190"))]


def test_a_printer_still_heats_bed_and_nozzle_in_its_start_code():
    s = load_settings().slicing
    buf = io.StringIO()
    write_gcode(buf, [_program(False)], s, Feeds.of_slicer(s), "t")
    g = buf.getvalue().splitlines()
    assert g.index("M140 S60") < g.index("M190 S60") < g.index("M109 S210") < g.index("G28 ; home")
    assert "M140 S0" in g


def test_wait_estimates_are_the_constant_speed_schedule(bundle):
    inp = load_inputs([str(bundle)])
    est = wait_estimates(inp.robots, inp.feeds())
    (w,) = simulate(inp, checks=False).timelines["B"].waits
    assert est == {"A": [], "B": [pytest.approx(w[1] - w[0])]} and w[1] - w[0] > 10
    # the same as at the G-code's feed rates (one time model, per role): the wait of the G-code
    # files simulated (which also retract and push back filament)
    s = load_settings(overrides=COARSE)
    feeds = Feeds.of_robot(s.robot, s.slicing)
    robots = [dataclasses.replace(r, speed=feeds.speeds(r.program)) for r in inp.robots]
    assert wait_estimates(robots, feeds) == est
    files = [str(bundle / "robots" / f"{r}.gcode") for r in "AB"]
    (g,) = simulate(load_inputs(files), checks=False).timelines["B"].waits
    assert est["B"] == [pytest.approx(g[1] - g[0], rel=0.01)]


def _events(result):
    return [(e["kind"], e["robot"], e["events"]) for e in summary(result)["events"]]


def _first_print(result, robot):
    tl = result.timelines[robot]
    return float(tl.t0[tl.on][0])


def test_robot_gcode_simulates_with_its_host_lines_as_the_bundle(bundle):
    files = [str(bundle / "robots" / f"{r}.gcode") for r in "AB"]
    for f in files:  # the sweep keeps them (no fall back to the line reader)
        rows = gcode_rows(Path(f).read_bytes(), 1.75)
        assert rows is not None and rows.events == (("C",),)
    gres, bres = simulate(load_inputs(files), checks=False), simulate(load_inputs([str(bundle)]), checks=False)
    assert _events(gres) == _events(bres) == [("wait", "B", ["C"]), ("notify", "A", ["C"])]
    for res in (gres, bres):
        (t_c,) = [t for t, e in res.timelines["A"].notifies if e == "C"]
        assert _first_print(res, "B") >= t_c > 60
        assert not [f for f in res.findings if f.kind == "deadlock"]


def test_without_the_notify_line_b_deadlocks(bundle, tmp_path, capsys):
    a = (bundle / "robots" / "A.gcode").read_text()
    assert a.count("M118 NOTIFY C\n") == 1
    (tmp_path / "A.gcode").write_text(a.replace("M118 NOTIFY C\n", ""))
    (tmp_path / "B.gcode").write_text((bundle / "robots" / "B.gcode").read_text())
    res = simulate(load_inputs([str(tmp_path / "A.gcode"), str(tmp_path / "B.gcode")]))
    (dead,) = [f for f in res.findings if f.kind == "deadlock"]
    assert dead.robot == "B" and "WAIT C" in dead.detail and dead.severity == "error"
    assert not res.timelines["B"].on.any()  # B never prints
    code = main(["simulate", str(tmp_path / "A.gcode"), str(tmp_path / "B.gcode"), "--out", str(tmp_path / "o"),
                 "--strict"])
    assert code == 1 and "deadlock 1" in capsys.readouterr().out


def test_operator_pauses_are_noted_not_dropped(tmp_path, capsys):
    (tmp_path / "p.gcode").write_text("G1 X10 Y0 F600\nM0 ; change filament\nG1 X20\nM1 S5\nM118 hello\n")
    code = main(["simulate", str(tmp_path / "p.gcode"), "--out", str(tmp_path / "o")])
    out = capsys.readouterr().out
    assert code == 0
    (note,) = json.loads((tmp_path / "o" / "sim" / "summary.json").read_text())["notes"]
    assert "2 pause line(s)" in note and "line 2, 4" in note and "p.gcode" in note
    assert f"note: {note}" in out


# ------------------------------------------------------------------------------------------------
# .coop files without a manifest

#: The seed paper's sample program (§5.1, Fig. 14), as printed there (with its trailing blanks).
SEED_SAMPLE = "MOVE 0, 0, 0  \nTOOL ON  \nMOVE 1, 0, 0  \nMOVE 1, 1, 0  \nMOVE 0, 1, 0  \nTOOL OFF\n"


def test_the_seeds_sample_program_simulates_as_written(tmp_path, capsys):
    (tmp_path / "sample.coop").write_text(SEED_SAMPLE)
    assert main(["simulate", str(tmp_path / "sample.coop"), "--out", str(tmp_path / "o")]) == 0
    record = json.loads((tmp_path / "o" / "sim" / "summary.json").read_text())
    (robot,) = record["robots"]
    # 3 mm of a path without a role: at the slicer's infill speed, 80 mm/s
    assert robot["name"] == "sample" and robot["printing_s"] == pytest.approx(3 / 80.0)
    res = simulate(load_inputs([str(tmp_path / "sample.coop")]))
    tl = res.timelines["sample"]
    assert np.array_equal(tl.p1, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    assert tl.on.tolist() == [False, True, True, True] and tl.t0[0] == 0 and tl.t1[0] == 0
    # with a profile of its own (--robot): 3 mm at its cap, 20 mm/s
    (tmp_path / "slow.toml").write_text("[robot]\nmax_print_speed = 20\n")
    assert main(["simulate", str(tmp_path / "sample.coop"), "--robot", str(tmp_path / "slow.toml"),
                 "--out", str(tmp_path / "o2")]) == 0
    (robot,) = json.loads((tmp_path / "o2" / "sim" / "summary.json").read_text())["robots"]
    assert robot["printing_s"] == pytest.approx(3 / 20.0)


def test_coop_files_of_a_bundle_simulate_as_the_bundle_without_a_manifest(bundle):
    files = [str(bundle / "robots" / f"{r}.coop") for r in "AB"]
    inp, binp = load_inputs(files), load_inputs([str(bundle)])
    assert [r.name for r in inp.robots] == ["A", "B"]
    assert [coop_facing(r.program) for r in inp.robots] == [90.0, -90.0]
    for r, b in zip(inp.robots, binp.robots):
        assert np.allclose(r.facing, b.facing)
    res, bres = simulate(inp), simulate(binp)
    assert res.makespan == pytest.approx(bres.makespan)
    assert _events(res) == _events(bres)
    assert [(f.kind, f.robot) for f in res.findings] == [(f.kind, f.robot) for f in bres.findings]


def test_a_bundle_robot_may_carry_keys_a_newer_cooprint_writes(bundle, tmp_path):
    import shutil

    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    record = json.loads((job / "job.json").read_text())
    record["robots"][0]["facings"] = [{"from_chunk": "C", "facing_deg": 90.0, "way": "round"}]  # a key of a newer one
    record["robots"][0]["max_height_mm"] = 123.0  # unknown, not like a known key: ignored
    (job / "job.json").write_text(json.dumps(record))
    assert [r.name for r in load_inputs([str(job)]).robots] == ["A", "B"]



def test_more_host_lines_than_the_sweep_notes_go_to_the_line_reader(tmp_path):
    from cooprint.simulation.gcode import HOST_CAP
    from cooprint.simulation.inputs import _read_gcode_lines, read_gcode

    g = tmp_path / "many.gcode"
    g.write_text("".join(f"G1 X{i} Y0 E0.1\nM400\nM118 NOTIFY e{i}\n" for i in range(HOST_CAP + 1)))
    assert gcode_rows(g.read_bytes(), 1.75) is None
    r = read_gcode(g)
    assert r.program == _read_gcode_lines(g, g.read_text()).program
    assert len(r.program.events) == HOST_CAP + 1 and r.program.events[-1] == (f"e{HOST_CAP}",)
    g.write_text("".join(f"G1 X{i} Y0 E0.1\nM400\nM118 NOTIFY e{i}\n" for i in range(HOST_CAP)))
    assert gcode_rows(g.read_bytes(), 1.75).events == read_gcode(g).program.events


from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_step = st.one_of(st.tuples(st.just("print"), st.integers(1, 4)), st.tuples(st.just("travel"), st.integers(1, 60)),
                  st.tuples(st.just("wait"), st.floats(0, 2000)))


@settings(max_examples=80, deadline=None)
@given(steps=st.lists(_step, max_size=12), limit=st.floats(0, 1500))
def test_no_filament_moves_while_cold_and_waits_keep_heat_only_up_to_the_limit(steps, limit):
    kind, xyz, waits, x = [MOVE], [[0.0, 0.0, 0.2]], [], 0.0
    for what, v in steps:
        if what == "wait":
            kind.append(WAIT)
            xyz.append([np.nan] * 3)
            waits.append(v)
            continue
        if what == "print":
            kind.append(TOOL_ON)
            xyz.append([np.nan] * 3)
        for _ in range(v if what == "print" else 1):
            x += 3.0 if what == "print" else float(v)
            kind.append(MOVE)
            xyz.append([x, 0.0, 0.2])
        if what == "print":
            kind.append(TOOL_OFF)
            xyz.append([np.nan] * 3)
    p = make_program("R", np.array(kind), np.array(xyz), width=0.45, height=0.2, layer=1,
                     events=tuple(("X",) for _ in waits))
    s = load_settings().slicing
    buf = io.StringIO()
    write_gcode(buf, [p], s, Feeds.of_slicer(s), "t", home=False, heating=Heating(210.0, None, limit, tuple(waits)))
    hot, hot_before, k = False, False, 0
    for line in buf.getvalue().splitlines():
        if line.startswith("M109 S210"):
            hot = True
        elif line.startswith("M104 S0"):
            hot = False
        elif line.startswith("G1") and " E" in line:
            assert hot, line  # extrusion, retraction or its undoing: only with a hot nozzle
        elif line.startswith("; WAIT"):
            hot_before = hot
        elif line.startswith("M0 WAIT"):
            assert not (hot and waits[k] > limit)  # hot across a long wait: never
            assert hot == hot_before or waits[k] > limit  # across a short one: as it was
            k += 1
        assert not line.startswith(("M140", "M190"))
    assert k == len(waits)
