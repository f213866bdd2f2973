"""Mixed fleets (issue 13 item 6) and the chunk order (item 4, ``chunk-order``).

A bundle (job.json ``robots[].profile``, an object of [robot] fields) or a manifest
(``[profiles.NAME]``) gives a robot its own profile; the simulator times and checks each robot
with its own speeds and geometry. A bundle's ``chunks[].deps`` say which chunks must be finished
before a chunk's material is laid: a plan that breaks that order is a ``chunk-order`` error.
"""

from __future__ import annotations

import dataclasses
import json
import shutil

import pytest

from cooprint.cli import main
from cooprint.config import load_settings
from cooprint.simulation import load_inputs, simulate, summary
from cooprint.simulation.checks import chunk_order
from cooprint.simulation.inputs import SimInput
from cooprint.simulation.timeline import schedule

from solids import COARSE, bar_bundle
from speeds import UNIFORM
from test_simulation import _robot


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    """A real two-robot bundle of `cooprint run` (A prints C then L1, B waits for C, then R1)."""
    return bar_bundle(tmp_path_factory.mktemp("fleet"), 6)


def _copy(bundle, tmp_path, edit=None):
    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    if edit:
        record = json.loads((job / "job.json").read_text())
        edit(record)
        (job / "job.json").write_text(json.dumps(record))
    return job


def _times(job_or_inputs):
    inp = load_inputs([str(job_or_inputs)]) if not isinstance(job_or_inputs, SimInput) else job_or_inputs
    return {r["name"]: r for r in summary(simulate(inp))["robots"]}


def _busy(robot):
    """A robot's summary without its idle time (which the makespan, the slowest robot's, sets)."""
    return {k: v for k, v in robot.items() if k != "idle_s"}


# ------------------------------------------------------------------------------------------------
# the profiles in a bundle

def test_run_writes_each_robots_whole_profile_and_reads_it_back(bundle):
    record = json.loads((bundle / "job.json").read_text())
    fleet = load_settings(overrides=COARSE).robot
    assert [r["profile"] for r in record["robots"]] == [dataclasses.asdict(fleet)] * 2
    inp = load_inputs([str(bundle)])
    assert [r.profile for r in inp.robots] == [inp.profile, inp.profile] == [fleet, fleet]


def test_a_bundle_that_names_its_profile_still_loads(bundle, tmp_path):
    # the records of cooprint before per-robot profiles: the profile's name
    def older(rec):
        for r in rec["robots"]:
            r["profile"] = "mobile-fdm"
    inp = load_inputs([str(_copy(bundle, tmp_path, older))])
    assert [r.profile for r in inp.robots] == [None, None]
    assert [r.profile for r in inp.fleet()] == [inp.profile] * 2
    assert not simulate(inp).findings


def _capped_b(bundle, tmp_path, cap):
    """The bundle with robot B's extrusions capped at ``cap`` mm/s (its own profile)."""
    def edit(rec):
        rec["robots"][1]["profile"] = {"max_print_speed": cap}
    inp = load_inputs([str(_copy(bundle, tmp_path / str(cap), edit))])
    a, b = inp.fleet()
    assert b.profile == dataclasses.replace(a.profile, max_print_speed=cap)
    return inp


def test_a_bundle_robot_with_half_the_print_speed_cap_prints_twice_as_long(bundle, tmp_path):
    # caps below every [slicing] speed (the slowest is top solid infill, 15 mm/s): B extrudes at the cap
    before, at10, at5 = _times(bundle), _times(_capped_b(bundle, tmp_path, 10.0)), _times(_capped_b(bundle, tmp_path, 5.0))
    assert before["B"]["printing_s"] > 100
    assert at10["B"]["printing_s"] > 1.5 * before["B"]["printing_s"]
    assert at5["B"]["printing_s"] == pytest.approx(2 * at10["B"]["printing_s"], rel=1e-9)
    assert at5["B"]["travelling_s"] == pytest.approx(before["B"]["travelling_s"], rel=1e-9)
    assert _busy(at5["A"]) == _busy(before["A"])  # A keeps the fleet's profile (only waits longer for B)
    # a cap above every speed changes nothing
    assert _busy(_times(_capped_b(bundle, tmp_path, 1000.0))["B"]) == _busy(before["B"])


def test_a_partial_bundle_profile_lies_over_the_bundles_settings(bundle, tmp_path):
    whole_b = json.loads((bundle / "job.json").read_text())["robots"][1]["profile"]

    def edit(rec):
        rec["settings"]["robot"]["max_travel_speed"] = 90.0
        rec["robots"][0]["profile"] = {"body_width": 420.0, "name": "wide"}
        rec["robots"][1]["profile"] = whole_b  # as cooprint run wrote it: B's own, whatever the settings say
    inp = load_inputs([str(_copy(bundle, tmp_path, edit))])
    a, b = inp.fleet()
    assert (a.profile.name, a.profile.body_width, a.profile.max_travel_speed) == ("wide", 420.0, 90.0)
    assert (b.profile.body_width, b.profile.max_travel_speed) == (300.0, None)
    feeds = inp.feeds()
    assert (feeds["A"].travel, feeds["B"].travel) == (90.0, inp.slicing.travel_speed)


# ------------------------------------------------------------------------------------------------
# the same mixed fleets from a manifest and from a hand-made bundle

# A prints a 100 mm line along X at y = 0 (facing +Y: its body stands behind, at y < -300), then
# drives away and announces it; B waits far off, then comes to print 10 mm at (500, 200) facing
# +X: its body (300 mm behind the nozzle) spans x -150..200 and, 300 mm wide, y 50..350, clear of
# A's line; 430 mm wide it spans y -15..415 and stands on the line (and on nothing else: A is gone).
A_PROGRAM = ("MOVE 0, 0, 0.2\nTOOL ON\nMOVE 100, 0, 0.2\nTOOL OFF\nMOVE 100, 0, 10\nMOVE 100, -1000, 10\n"
             "NOTIFY DONE\n")
B_PROGRAM = ("WAIT DONE\nMOVE 500, 200, 5\nMOVE 500, 200, 0.2\nTOOL ON\nMOVE 510, 200, 0.2\nTOOL OFF\n"
             "MOVE 510, 200, 10\n")
STARTS = {"A": ([0.0, 0.0, 0.2], 90.0), "B": ([1500.0, 200.0, 5.0], 0.0)}


def _manifest(folder, profiles: dict[str, dict]) -> str:
    folder.mkdir(exist_ok=True)
    text = ""
    for name, program in (("A", A_PROGRAM), ("B", B_PROGRAM)):
        (folder / f"{name}.coop").write_text(program)
        start, facing = STARTS[name]
        text += f'[[robots]]\nname = "{name}"\nprogram = "{name}.coop"\nstart = {start}\nfacing_deg = {facing}\n'
    for name, values in profiles.items():
        text += f"[profiles.{name}]\n" + "".join(f"{k} = {v!r}\n" for k, v in values.items())
    (folder / "fleet.toml").write_text(text)
    return str(folder / "fleet.toml")


def _hand_bundle(folder, profiles: dict[str, dict]) -> str:
    (folder / "robots").mkdir(parents=True, exist_ok=True)
    robots = []
    for name, program in (("A", A_PROGRAM), ("B", B_PROGRAM)):
        (folder / "robots" / f"{name}.coop").write_text(program)
        start, facing = STARTS[name]
        robots.append({"name": name, "program": f"robots/{name}.coop", "start": start, "facing_deg": facing}
                      | ({"profile": profiles[name]} if name in profiles else {}))
    (folder / "job.json").write_text(json.dumps({"format": "cooprint-job/2", "settings": {}, "robots": robots}))
    return str(folder)


def _load(kind, folder, profiles):
    if kind == "manifest":
        return load_inputs([], manifest=_manifest(folder, profiles))
    return load_inputs([_hand_bundle(folder, profiles)])


@pytest.mark.parametrize("kind", ["manifest", "bundle"])
def test_only_the_bigger_robots_body_reaches_the_material(kind, tmp_path):
    same = simulate(_load(kind, tmp_path / "same", {}))
    assert not [f for f in same.findings if f.kind == "body-on-material"]
    mixed = simulate(_load(kind, tmp_path / "mixed", {"B": {"body_width": 430.0}}))
    assert [r.profile.body_width for r in mixed.robots] == [300.0, 430.0]
    (hit,) = [f for f in mixed.findings if f.kind == "body-on-material"]
    assert hit.robot == "B" and 500 <= hit.position[0] <= 760 and hit.position[1] == 200  # as it drives in
    # a body as wide on A changes nothing: A's body never comes near the line it prints
    wide_a = simulate(_load(kind, tmp_path / "wide_a", {"A": {"body_width": 430.0}}))
    assert not [f for f in wide_a.findings if f.kind == "body-on-material"]


@pytest.mark.parametrize("kind", ["manifest", "bundle"])
def test_a_robot_with_half_the_print_speed_prints_twice_as_long(kind, tmp_path):
    # the programs' extrusions name no path role: they print at the infill speed (80 mm/s), which
    # B's own max_print_speed = 40 halves
    before = _times(_load(kind, tmp_path / "same", {}))
    after = _times(_load(kind, tmp_path / "slow", {"B": {"max_print_speed": 40.0}}))
    assert before["B"]["printing_s"] == pytest.approx(10 / 80)
    assert after["B"]["printing_s"] == pytest.approx(2 * before["B"]["printing_s"], rel=1e-12)
    assert after["B"]["travelling_s"] == pytest.approx(before["B"]["travelling_s"], rel=1e-12)
    assert _busy(after["A"]) == _busy(before["A"])


def test_a_manifest_profile_lies_over_its_robot_section(tmp_path):
    path = _manifest(tmp_path, {"B": {"nozzle_depth": 40.0}})
    with open(path, "a") as fh:
        fh.write("[robot]\nmax_print_speed = 30.0\n")
    a, b = load_inputs([], manifest=path).fleet()
    assert (a.profile.max_print_speed, a.profile.nozzle_depth) == (30.0, 25.0)
    assert (b.profile.max_print_speed, b.profile.nozzle_depth) == (30.0, 40.0)


# ------------------------------------------------------------------------------------------------
# chunk-order

def test_a_robot_that_does_not_wait_for_the_chunk_it_leans_on_is_caught(bundle, tmp_path, capsys):
    job = _copy(bundle, tmp_path)
    program = job / "robots" / "B.coop"
    lines = program.read_text().splitlines(keepends=True)
    assert "WAIT C\n" in lines
    program.write_text("".join(ln for ln in lines if ln != "WAIT C\n"))
    record = json.loads((job / "job.json").read_text())  # job.json edited to match (else refused)
    stats = record["robots"][1]["stats"]
    stats["commands"], stats["wait"] = stats["commands"] - 1, stats["wait"] - 1
    (job / "job.json").write_text(json.dumps(record))
    res = simulate(load_inputs([str(job)]))
    assert "chunk-order" in res.checked
    (f,) = [f for f in res.findings if f.kind == "chunk-order"]
    record = json.loads((job / "job.json").read_text())
    assert {c["id"]: c["deps"] for c in record["chunks"]}["R1"] == ["C"]
    assert (f.robot, f.chunk, f.count) == ("B", "R1", 1)
    c_end = max(float(t1) for t1, on, k in zip(res.timelines["A"].t1, res.timelines["A"].on,
                                              res.timelines["A"].index)
                if on and res.robots[0].program.chunks[res.robots[0].program.chunk[k]] == "C")
    assert f.time < c_end
    assert f.detail == f"laid down before the chunks it depends on are finished: C ({c_end - f.time:.3f} s early)"
    assert f.severity == "error"
    assert main(["simulate", str(job)]) == 1
    out = capsys.readouterr()
    assert "chunk-order 1" in out.out + out.err
    assert json.loads((job / "sim" / "summary.json").read_text())["finding_counts"]["chunk-order"] == 1


def test_a_notify_announced_too_early_is_caught(bundle, tmp_path):
    # A announces C before printing it: B's WAIT ends at once, and B's R1 leans on nothing
    job = _copy(bundle, tmp_path)
    program = job / "robots" / "A.coop"
    lines = program.read_text().splitlines(keepends=True)
    lines.remove("NOTIFY C\n")
    program.write_text("NOTIFY C\n" + "".join(lines))
    (f,) = [f for f in simulate(load_inputs([str(job)])).findings if f.kind == "chunk-order"]
    assert (f.robot, f.chunk) == ("B", "R1") and "C (" in f.detail


def test_the_plan_as_written_keeps_its_chunk_order(bundle):
    res = simulate(load_inputs([str(bundle)]))
    assert "chunk-order" in res.checked
    assert not [f for f in res.findings if f.kind == "chunk-order"]


def test_chunk_order_is_looked_for_only_where_the_deps_are_known(tmp_path, bundle):
    res = simulate(load_inputs([], manifest=_manifest(tmp_path, {})))
    assert "chunk-order" not in res.checked
    job = _copy(bundle, tmp_path / "nodeps",
                lambda rec: [(c.pop("deps"), c.pop("body_deps", None)) for c in rec["chunks"]])
    assert load_inputs([str(job)]).deps is None
    assert load_inputs([str(bundle)]).deps == {"C": (), "L1": ("C",), "R1": ("C",)}


def _order(a_text, b_text, deps):
    robots = [_robot("A", a_text, start=[0, 0, 0.2]), _robot("B", b_text, start=[0, 900, 0.2], facing_deg=-90)]
    timelines, _ = schedule(robots, UNIFORM)
    return chunk_order(robots, timelines, deps)


def test_an_empty_chunk_is_finished_at_its_notify_or_at_once():
    # chunk E has no material: B's D leans on it, and E is done when A announces it (after 2.5 s
    # of printing chunk X), so B's D, printed at once, is 2.5 s early
    a = ";@chunk X\nTOOL ON\nMOVE 100, 0, 0.2\nTOOL OFF\n;@chunk E\nNOTIFY E\n"
    b = ";@chunk D\nTOOL ON\nMOVE 0, 800, 0.2\nTOOL OFF\n"
    (f,) = _order(a, b, {"D": ("E",), "E": (), "X": ()})
    assert (f.robot, f.chunk, f.time, f.position) == ("B", "D", 0.0, (0.0, 900.0, 0.2))
    assert "E (2.500 s early)" in f.detail
    # announced by nobody: finished at once; and B waiting for it: in order
    assert _order(a.replace("NOTIFY E\n", ""), b, {"D": ("E",)}) == []
    assert _order(a, "WAIT E\n" + b, {"D": ("E",)}) == []


def test_every_dependency_not_finished_is_named_and_counted():
    a = ";@chunk X\nTOOL ON\nMOVE 100, 0, 0.2\nTOOL OFF\n;@chunk Y\nTOOL ON\nMOVE 100, 40, 0.2\nTOOL OFF\n"
    b = ";@chunk D\nTOOL ON\nMOVE 0, 800, 0.2\nTOOL OFF\n"
    (f,) = _order(a, b, {"D": ("X", "Y"), "Y": ("X",)})
    assert f.count == 2 and "X (2.500 s early)" in f.detail and "Y (3.500 s early)" in f.detail
    # the same robot printing Y right after X: in order
    assert _order(a, "", {"Y": ("X",)}) == []
    # ... and before it
    (g,) = _order(a, "", {"X": ("Y",)})
    assert (g.chunk, g.robot, g.count) == ("X", "A", 1)



def test_a_profile_table_takes_robot_fields_only():
    from cooprint.config import RobotProfile, robot_profile
    from cooprint.errors import ConfigError

    base = RobotProfile(max_print_speed=10.0)
    assert robot_profile({"jerk": 5}, "x: ", "profile", base) == RobotProfile(max_print_speed=10.0, jerk=5.0)
    assert robot_profile({}, "x: ", "profile") == RobotProfile()
    with pytest.raises(ConfigError, match=r"^x: unknown field profile.layer_height \(a \[slicing\] field; it takes "
                                          r"\[robot\] fields only\)$"):
        robot_profile({"layer_height": 0.2}, "x: ", "profile", base)
    with pytest.raises(ConfigError, match=r"^x: unknown field profile.jrek; did you mean 'jerk'\?$"):
        robot_profile({"jrek": 5}, "x: ", "profile", base)
    with pytest.raises(ConfigError, match=r"^x: profile = 5: expected a table of \[robot\] fields$"):
        robot_profile(5, "x: ", "profile", base)
