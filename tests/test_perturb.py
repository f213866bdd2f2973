"""Monte-Carlo robustness (issue 14, item 5: ``simulate --perturb F --runs K --seed S``) and the
scheduler's record a bundle's job.json carries (``chunks[].body_deps``, ``schedule.lower_bound_s``).

The two-robot plan: A works in a shared region (chunk A1 at x = 0, 6 strokes of 100 mm at the
travel speed, 10 s), then leaves along +X and announces CLEAR once 600 mm away; B comes in along
the same line from x = -1560 (its bodies and A's are 300 mm wide: they meet when their nozzles
are less than 300 mm apart) and works there (chunk B1). With ``WAIT CLEAR`` B starts only once A
is out of the way; without it, B is timed to trail A by 360 mm at constant speed (60 mm spare):
clean as planned, a collision as soon as A works slower or B drives faster.
"""

import json

import numpy as np
import pytest

from badinput import assert_rejected
from cooprint.cli import main
from cooprint.config import RobotProfile
from cooprint.program.commands import parse_coop
from cooprint.simulation import KINDS, SimInput, load_inputs, simulate, summary
from cooprint.simulation.perturb import (check_perturb_options, command_speeds, perturb_runs, perturbed_speeds,
                                         run_factors, span_ids)
from cooprint.simulation.timeline import SimRobot
from cooprint.errors import UserError
from speeds import UNIFORM, UNIFORM_SLICING, UNIFORM_SPEEDS

WORK = 6  # strokes of A's chunk: 6 x 200 mm at 120 mm/s = 10 s
A_TEXT = (";@chunk A1\n" + "MOVE 0 100 5\nMOVE 0 0 5\n" * WORK
          + ";@chunk -\nMOVE 600 0 5\nNOTIFY CLEAR\nMOVE 1500 0 5\n")
B_START = -1560.0  # 1200 mm (A's 10 s of work at B's 120 mm/s) + 300 mm (the bodies' widths) + 60 mm


def b_text(guard: bool) -> str:
    return ("WAIT CLEAR\n" if guard else "") + "MOVE 0 0 5\n;@chunk B1\n" + "MOVE 0 100 5\nMOVE 0 0 5\n" * 2


def fleet(guard: bool) -> SimInput:
    up = np.array([0.0, 1.0])
    return SimInput([SimRobot("A", parse_coop(A_TEXT, "A"), np.array([0.0, 0.0, 5.0]), up),
                     SimRobot("B", parse_coop(b_text(guard), "B"), np.array([B_START, 0.0, 5.0]), up)],
                    RobotProfile(), UNIFORM_SLICING, "test")


def collided(result):
    return [r.run for r in result.runs if any(f.kind == "robots-collide" for f in r.findings)]


def test_each_chunk_and_each_travel_between_chunks_is_a_stretch_with_its_own_factor():
    np.testing.assert_array_equal(span_ids(np.array([-1, 0, 0, -1, -1, 1, 1, -1])), [0, 1, 1, 2, 2, 3, 3, 4])
    assert span_ids(np.zeros(0, np.int16)).shape == (0,)
    a = fleet(True).fleet()[0]
    spans = span_ids(a.program.chunk)
    assert spans.max() == 1  # chunk A1, then the travel away
    base = command_speeds(a, UNIFORM)
    moves = a.program.kind == 0
    assert np.all(base[moves] == 120.0) and np.all(base[~moves] == 0.0)  # tool off: the travel speed
    got = perturbed_speeds(base, spans, np.array([0.8, 1.25]))
    np.testing.assert_allclose(got[moves & (spans == 0)], 96.0)
    np.testing.assert_allclose(got[moves & (spans == 1)], 150.0)
    f1, f2 = run_factors([3, 1000], 0.3, 42), run_factors([3, 1000], 0.3, 42)
    assert all(np.array_equal(x, y) for x, y in zip(f1, f2))  # a run replays from its seed
    assert f1[1].min() >= 0.7 and f1[1].max() <= 1.3 and f1[1].std() > 0.1  # uniform over the whole range


def test_the_guard_wait_keeps_every_perturbed_run_clean():
    assert simulate(fleet(True)).findings == []
    res = perturb_runs(fleet(True), 0.3, 5, seed=0)
    assert [r.run for r in res.runs] == [1, 2, 3, 4, 5]
    assert all(r.findings == () for r in res.runs)
    assert len(set(res.makespans.round(6))) == 5  # every run at its own speeds
    assert "robots-collide" in res.checked and "outside-part" not in res.checked


def test_without_the_wait_the_plan_collides_under_perturbation():
    """The WAIT is what keeps B out of A's way: the same plan without it is clean at the planned
    speeds (B trails A by 360 mm) and collides in run 1 of seed 0 (A worked slower, or B drove
    faster, than planned): the proof that guard WAITs matter."""
    plain = simulate(fleet(False))
    assert plain.findings == [] and "robots-collide" in plain.checked
    res = perturb_runs(fleet(False), 0.3, 5, seed=0)
    assert collided(res) == [1]
    (f,) = res.runs[0].findings
    assert f.kind == "robots-collide" and f.severity == "error" and {"A", "B"} <= set(f.robot + f.detail)
    # the run's own seed replays it: A's work stretched against B's approach
    a_work, a_away = run_factors([2, 2], 0.3, res.runs[0].seed)[0]
    b_travel, _ = run_factors([2, 2], 0.3, res.runs[0].seed)[1]
    assert 1200 / (120 * a_work) * 120 * b_travel > B_START * -1 - 300  # B closes in before A has left
    # at a small variation, the 60 mm to spare hold
    assert collided(perturb_runs(fleet(False), 0.01, 5, seed=0)) == []


def test_runs_are_reproducible_from_the_seed_and_the_distribution_is_ordered():
    one, two = perturb_runs(fleet(False), 0.3, 6, seed=3), perturb_runs(fleet(False), 0.3, 6, seed=3)
    np.testing.assert_array_equal(one.makespans, two.makespans)
    assert [r.seed for r in one.runs] == [r.seed for r in two.runs]
    assert [r.findings for r in one.runs] == [r.findings for r in two.runs]
    other = perturb_runs(fleet(False), 0.3, 6, seed=4)
    assert not np.array_equal(one.makespans, other.makespans)
    d = one.distribution()
    assert d["min"] <= d["median"] <= d["p95"] <= d["max"]
    assert d["min"] == one.makespans.min() and d["max"] == one.makespans.max()
    assert d["median"] == pytest.approx(np.median(one.makespans))
    # the spread comes from the factors: every run within what +-30% on every stretch allows
    span = simulate(fleet(False)).makespan
    assert span / 1.3 - 1e-9 <= d["min"] and d["max"] <= span / 0.7 + 1e-9
    rec = summary(simulate(fleet(False)), one)["perturb"]
    assert rec["fraction"] == 0.3 and rec["runs"] == 6 and rec["seed"] == 3
    assert rec["makespan_s"] == d and [r["makespan_s"] for r in rec["per_run"]] == one.makespans.tolist()
    assert list(rec["finding_counts"]) == list(KINDS)
    assert all(f["run"] in range(1, 7) and f["seed"] == one.runs[f["run"] - 1].seed for f in rec["findings"])


def test_with_acceleration_the_factor_scales_the_speed_cap():
    res = perturb_runs(fleet(True), 0.3, 3, seed=1, accel=True)
    assert all(r.findings == () for r in res.runs)
    assert res.accel and all(r.makespan > 0 for r in res.runs)
    assert res.makespans.min() < simulate(fleet(True), accel=True).makespan * 1.3
    assert res.to_dict()["time_model"].startswith("trapezoidal")


def write_manifest(folder, guard):
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "A.coop").write_text(A_TEXT)
    (folder / "B.coop").write_text(b_text(guard))
    m = folder / "m.toml"
    m.write_text('[[robots]]\nname = "A"\nprogram = "A.coop"\nstart = [0, 0, 5]\n'
                 f'[[robots]]\nname = "B"\nprogram = "B.coop"\nstart = [{B_START}, 0, 5]\n')
    return m


def test_cli_simulate_perturb_end_to_end(tmp_path, capsys):
    guarded = write_manifest(tmp_path / "guarded", True)
    out = tmp_path / "o1"
    assert main(["simulate", "--manifest", str(guarded), "--out", str(out), "--perturb", "0.3", "--runs", "5",
                 "--seed", "0"]) == 0
    lines = capsys.readouterr().out.splitlines()
    dist = [ln for ln in lines if ln.startswith("perturbed +-30% x 5 runs (seed 0): makespan min ")]
    assert len(dist) == 1 and " median " in dist[0] and " p95 " in dist[0] and " max " in dist[0]
    assert "perturbed findings: none" in lines
    s = json.loads((out / "sim" / "summary.json").read_text())
    p = s["perturb"]
    assert (p["fraction"], p["runs"], p["seed"]) == (0.3, 5, 0) and len(p["per_run"]) == 5 and p["findings"] == []
    assert set(p["makespan_s"]) == {"min", "median", "p95", "max"}
    # without the WAIT: clean at constant speed (exit 0), invalid under perturbation (exit 1)
    plain = write_manifest(tmp_path / "plain", False)
    assert main(["simulate", "--manifest", str(plain), "--out", str(tmp_path / "o2"), "-q"]) == 0
    assert "perturb" not in json.loads((tmp_path / "o2" / "sim" / "summary.json").read_text())
    capsys.readouterr()
    assert main(["simulate", "--manifest", str(plain), "--out", str(tmp_path / "o3"), "--perturb", "0.3",
                 "--runs", "5", "--seed", "0"]) == 1
    got = capsys.readouterr()
    assert "perturbed findings: robots-collide" in got.out
    assert any(ln.startswith("  run 1 (seed ") and "robots-collide (error)" in ln for ln in got.out.splitlines())
    assert got.err.startswith("cooprint: the plan is INVALID: the simulation and its 5 perturbed runs found errors "
                              "(robots-collide")
    s = json.loads((tmp_path / "o3" / "sim" / "summary.json").read_text())
    assert s["finding_counts"]["robots-collide"] == 0  # the plan as planned
    (f,) = s["perturb"]["findings"]
    assert f["run"] == 1 and f["kind"] == "robots-collide" and f["seed"] == s["perturb"]["per_run"][0]["seed"]
    assert s["perturb"]["per_run"][0]["finding_counts"]["robots-collide"] == f["count"]
    # --quiet: the findings line and the verdict on stderr only
    assert main(["simulate", "--manifest", str(plain), "--out", str(tmp_path / "o3"), "--perturb", "0.3",
                 "--runs", "5", "--seed", "0", "-q"]) == 1
    got = capsys.readouterr()
    assert got.out == "" and "INVALID" in got.err


def test_cli_perturb_warnings_fail_only_with_strict(tmp_path, capsys):
    # a line printed in the air (z 5 mm, nothing below): an overhang warning in every run
    (tmp_path / "A.coop").write_text("MOVE 0 0 5\nTOOL ON\nMOVE 0 50 5\nTOOL OFF\n")
    args = ["simulate", str(tmp_path / "A.coop"), "--out", str(tmp_path / "o"), "--perturb", "0.2", "--runs", "2",
            "--force", "-q"]
    assert main(args) == 0
    assert json.loads((tmp_path / "o" / "sim" / "summary.json").read_text())["perturb"]["finding_counts"][
        "overhang"] > 0
    capsys.readouterr()
    assert main(args + ["--strict"]) == 1 and "fails --strict" in capsys.readouterr().err
    assert main(args + ["--fail-on", "warnings"]) == 1


@pytest.mark.parametrize("extra, says", [
    (["--perturb", "0"], "--perturb 0: expected a fraction between 0 and 1"),
    (["--perturb", "1"], "--perturb 1: expected a fraction between 0 and 1"),
    (["--perturb", "-0.2"], "--perturb -0.2"),
    (["--perturb", "nan"], "--perturb nan"),
    (["--perturb", "0.2", "--runs", "0"], "--runs 0: expected a whole number of runs from 1 to 10000"),
    (["--perturb", "0.2", "--runs", "10001"], "--runs 10001"),
    (["--runs", "5"], "--runs 5: needs --perturb"),
    (["--seed", "3"], "--seed 3: needs --perturb"),
    (["--perturb", "0.2", "--seed", "-1"], "--seed -1"),
    (["--perturb", "x"], "--perturb"),
])
def test_bad_perturb_options_are_refused(tmp_path, capsys, extra, says):
    m = write_manifest(tmp_path / "in", True)
    assert_rejected(["simulate", "--manifest", m, "--out", tmp_path / "o", *extra], capsys,
                    watch=[tmp_path], contains=says)


def test_check_perturb_options_fills_in_the_defaults():
    assert check_perturb_options(None, None, None) is None
    assert check_perturb_options(0.2, None, None) == (0.2, 20, 0)
    with pytest.raises(UserError):
        check_perturb_options(0.2, 2, 2 ** 63)
    with pytest.raises(ValueError):
        perturb_runs(fleet(True), 1.0, 2)


# ------------------------------------------------------------------------------------------------
# job.json: chunks[].body_deps and the schedule's lower bound

A_PRINT = "MOVE 0 0 0.2\n;@chunk A1\nTOOL ON\nMOVE 0 100 0.2\nTOOL OFF\n;@chunk -\nNOTIFY A1\n"


def write_bundle(folder, chunks, schedule=None, guard=False):
    """A hand-made bundle: A prints chunk A1 (a 100 mm line, 2.5 s), B prints chunk B1 1.5 m away
    (with ``guard``: after A1 is announced)."""
    (folder / "robots").mkdir(parents=True)
    (folder / "robots" / "A.coop").write_text(A_PRINT)
    (folder / "robots" / "B.coop").write_text(("WAIT A1\n" if guard else "") + "MOVE -1500 0 0.2\n;@chunk B1\n"
                                              "TOOL ON\nMOVE -1500 100 0.2\nTOOL OFF\n")
    record = {"format": "cooprint-job/2", "settings": {"slicing": UNIFORM_SPEEDS},  # 40 mm/s, travel 120
              "robots": [{"name": "A", "program": "robots/A.coop", "start": [0, 0, 0.2], "facing_deg": 90},
                         {"name": "B", "program": "robots/B.coop", "start": [-1500, 0, 0.2], "facing_deg": 90}],
              "chunks": chunks}
    if schedule is not None:
        record["schedule"] = schedule
    (folder / "job.json").write_text(json.dumps(record))
    return folder


def test_body_deps_are_held_by_the_chunk_order_check(tmp_path):
    free = simulate(load_inputs([str(write_bundle(tmp_path / "free", [{"id": "A1"}, {"id": "B1"}]))]))
    assert free.findings == []  # no dependencies: B may print B1 at once
    body = write_bundle(tmp_path / "body", [{"id": "A1"}, {"id": "B1", "body_deps": ["A1"]}])
    inp = load_inputs([str(body)])
    assert inp.deps == {"A1": (), "B1": ("A1",)}
    (f,) = simulate(inp).findings
    assert f.kind == "chunk-order" and f.chunk == "B1" and f.robot == "B" and "A1 (2.500 s early)" in f.detail
    both = write_bundle(tmp_path / "both", [{"id": "A1"}, {"id": "B1", "deps": ["A1"], "body_deps": ["A1"]}])
    assert load_inputs([str(both)]).deps["B1"] == ("A1",)  # merged, once
    guarded = write_bundle(tmp_path / "guarded", [{"id": "A1"}, {"id": "B1", "body_deps": ["A1"]}], guard=True)
    res = simulate(load_inputs([str(guarded)]))
    assert res.findings == [] and "chunk-order" in res.checked


@pytest.mark.parametrize("chunks, schedule, says", [
    ([{"id": "A1"}, {"id": "B1", "body_deps": ["Z9"]}], None,
     "chunks[1].body_deps[0]: expected the id of one of the bundle's chunks"),
    ([{"id": "A1"}, {"id": "B1", "body_deps": ["B1"]}], None, "a chunk cannot depend on itself"),
    ([{"id": "A1"}, {"id": "B1", "body_deps": "A1"}], None, "chunks[1].body_deps"),
    ([{"id": "A1"}, {"id": "B1"}], {"lower_bound_s": -1}, "schedule.lower_bound_s: expected a finite number >= 0"),
    ([{"id": "A1"}, {"id": "B1"}], {"makespan_s": "long"}, "schedule.makespan_s"),
    ([{"id": "A1"}, {"id": "B1"}], {"gap": True}, "schedule.gap"),
    ([{"id": "A1"}, {"id": "B1"}], {"gap": -0.01}, "schedule.gap: expected a finite number >= 0"),
])
def test_bad_body_deps_and_schedule_numbers_are_refused(tmp_path, capsys, chunks, schedule, says):
    b = write_bundle(tmp_path / "b", chunks, schedule)
    assert_rejected(["simulate", b], capsys, watch=[tmp_path], contains=says)


def test_the_lower_bound_is_repeated_and_a_makespan_below_it_is_an_error(tmp_path, capsys):
    chunks = [{"id": "A1"}, {"id": "B1", "body_deps": ["A1"]}]
    span = simulate(load_inputs([str(write_bundle(tmp_path / "x", chunks, guard=True))])).makespan
    assert span == pytest.approx(2.5 + 2.5 + 0.0)
    ok = write_bundle(tmp_path / "ok", chunks, {"lower_bound_s": 4.0, "makespan_s": 5.0, "gap": 0.25}, guard=True)
    assert main(["simulate", str(ok)]) == 0
    out = capsys.readouterr().out
    assert "makespan 0.00 h, lower bound 0.00 h (+25.0%); the scheduler planned 0.00 h" in out
    s = json.loads((ok / "sim" / "summary.json").read_text())
    assert s["schedule"] == {"lower_bound_s": 4.0, "planned_makespan_s": 5.0, "planned_gap": 0.25,
                             "gap_to_lower_bound": pytest.approx(0.25)}
    assert "below-lower-bound" in s["checked"] and s["finding_counts"]["below-lower-bound"] == 0
    # a bound the plan beats: the bound or the plan is wrong
    bad = write_bundle(tmp_path / "bad", chunks, {"lower_bound_s": 6.0}, guard=True)
    assert main(["simulate", str(bad), "-q"]) == 1
    assert "INVALID: the simulation found errors (below-lower-bound 1)" in capsys.readouterr().err
    (f,) = json.loads((bad / "sim" / "summary.json").read_text())["findings"]
    assert f["kind"] == "below-lower-bound" and f["severity"] == "error" and f["robot"] == "B"
    assert "16.67% below the scheduler's lower bound 6.0 s" in f["detail"] and f["time_s"] == pytest.approx(5.0)
    # within the tolerance of the scheduler's rounding: not a finding
    near = write_bundle(tmp_path / "near", chunks, {"lower_bound_s": 5.004}, guard=True)
    assert simulate(load_inputs([str(near)])).findings == []
    # a makespan equal to its bound: a gap of -2e-16 is 0, not an error
    tight = write_bundle(tmp_path / "tight", chunks, {"lower_bound_s": 5.0, "makespan_s": 5.0, "gap": -2.2e-16},
                         guard=True)
    assert load_inputs([str(tight)]).estimate.gap == 0.0
    # no bound stated: neither checked nor in the summary
    none = simulate(load_inputs([str(write_bundle(tmp_path / "none", chunks, {"makespan_s": None}, guard=True))]))
    assert "below-lower-bound" not in none.checked and "schedule" not in summary(none)


def test_a_plan_of_cooprint_run_is_clean_in_every_perturbed_run(tmp_path):
    """cooprint's own two-robot plan (a car cut in five chunks, B waiting for the centre chunk)
    keeps its order and its robots apart at speeds 30% off in every stretch: its WAITs, not its
    timing, make it safe."""
    from cooprint.jobs import run
    from cooprint.models import car

    out = tmp_path / "job"
    run(car(420.0), out, overrides={"slicing.layer_height": 1.0, "slicing.first_layer_height": 1.0,
                                    "slicing.extrusion_width": 1.6, "slicing.nozzle_diameter": 1.2}, picture=False)
    inp = load_inputs([str(out)])
    res = perturb_runs(inp, 0.3, 5, seed=0)
    errors = [(r.run, f.kind, f.robot, f.chunk) for r in res.runs for f in r.findings if f.severity == "error"]
    assert errors == []
    assert {"chunk-order", "robots-collide", "body-on-material"} <= set(res.checked)
    assert res.makespans.std() > 0 and len(res.runs) == 5


def test_a_gcode_robot_is_perturbed_at_its_own_feed_rates(tmp_path):
    from cooprint.simulation.inputs import read_gcode

    g = tmp_path / "P.gcode"
    g.write_text("G1 X10 F600\nG1 X20 F1200 E1\nG1 X30 F3000\n")
    r = read_gcode(g)
    base = command_speeds(r, UNIFORM)
    np.testing.assert_allclose(base[r.program.kind == 0], [10.0, 20.0, 50.0])  # F / 60, not the profile's
    assert span_ids(r.program.chunk).max() == 0  # no chunks: one stretch, one factor per run
    res = perturb_runs(load_inputs([str(g)]), 0.25, 4, seed=5)
    plain = simulate(load_inputs([str(g)])).makespan
    # one factor for the whole program: each makespan is the constant-speed one over that factor
    factors = [run_factors([1], 0.25, r.seed)[0][0] for r in res.runs]
    np.testing.assert_allclose(res.makespans, [plain / f for f in factors], rtol=1e-12)
