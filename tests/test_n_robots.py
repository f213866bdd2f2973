"""N robots end to end (issue 14): `cooprint run --robots N --layout grid` writes a plan whose own
simulation is clean, at constant speed and with every robot's speed perturbed; job.json records the
DAG, the schedule, its lower bound and its gap; bad robot counts and layouts are refused."""

from __future__ import annotations

import json
from dataclasses import replace
import shutil

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import solids
from badinput import assert_rejected, restate_counts
from cooprint.cli import main
from cooprint.config import load_settings
from cooprint.io.bundle import write_stl
from cooprint.jobs import coop_job
from cooprint.simulation import load_inputs, simulate
from test_plans import as_solid

# a slab with a 2 mm nozzle: the same logic as the defaults at a fraction of the work
BIG = {"slicing.nozzle_diameter": 2.0, "slicing.layer_height": 1.6, "slicing.first_layer_height": 1.6,
       "slicing.extrusion_width": 3.0, "slicing.infill_density": 0.05, "slicing.top_layers": 1,
       "slicing.bottom_layers": 1, "slicing.perimeters": 1}
FLAGS = [f"--set={k}={v}" for k, v in BIG.items()]


@pytest.fixture(scope="module")
def slab(tmp_path_factory):
    """A 1500 x 800 x 20 mm slab as an STL file."""
    path = tmp_path_factory.mktemp("slab") / "slab.stl"
    mesh = solids.plate().to_mesh64()
    import numpy as np

    write_stl(path, np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts), name="slab")
    return path


@pytest.mark.parametrize("robots", [4, 9])
def test_grid_plan_is_clean_and_records_its_bound(slab, tmp_path, robots, capsys):
    out = tmp_path / f"n{robots}"
    code = main(["run", str(slab), "--out", str(out), "--robots", str(robots), "--layout", "grid", "--simulate",
                 "--strict", *FLAGS])
    text = capsys.readouterr().out
    assert code == 0, text
    record = json.loads((out / "job.json").read_text())
    assert record["plan"]["layout"] == "grid"
    sched = record["schedule"]
    # the schedule's estimate can never beat its own lower bound; the simulated makespan neither
    assert sched["makespan_s"] >= sched["lower_bound_s"] - 1e-6
    assert sched["gap"] == pytest.approx(sched["makespan_s"] / sched["lower_bound_s"] - 1, abs=1e-9)
    summary = json.loads((out / "sim" / "summary.json").read_text())
    assert summary["makespan_s"] >= sched["lower_bound_s"] * (1 - 1e-6)
    assert sum(summary["finding_counts"].values()) == 0
    assert "lower bound" in text
    busy = [r for r in record["robots"] if r["chunks"]]
    assert len(busy) >= min(robots, 2)
    # every chunk after its dependencies in the schedule's times
    times = {c["id"]: (c["start_s"], c["end_s"]) for c in record["chunks"]}
    for c in record["chunks"]:
        for d in c["deps"] + c["body_deps"]:
            assert times[d][1] <= times[c["id"]][0] + 1e-6
        for e in c["exclusive"]:
            a, b = times[c["id"]], times[e]
            assert a[1] <= b[0] + 1e-6 or b[1] <= a[0] + 1e-6


@pytest.fixture(scope="module")
def plan4(slab, tmp_path_factory):
    """The slab planned for four robots on the grid (no simulation)."""
    out = tmp_path_factory.mktemp("plan4") / "n4"
    assert main(["run", str(slab), "--out", str(out), "--robots", "4", "--layout", "grid", "-q", *FLAGS]) == 0
    return out


def test_grid_plan_is_clean_under_perturbation(plan4, tmp_path, capsys):
    sim = tmp_path / "sim"
    code = main(["simulate", str(plan4), "--out", str(sim), "--perturb", "0.3", "--runs", "5", "--seed", "1"])
    text = capsys.readouterr()
    assert code == 0, text.out + text.err
    perturb = json.loads((sim / "sim" / "summary.json").read_text())["perturb"]
    assert len(perturb["per_run"]) == 5
    assert all(sum(r["finding_counts"].values()) == 0 for r in perturb["per_run"])
    assert perturb["makespan_s"]["min"] <= perturb["makespan_s"]["median"] <= perturb["makespan_s"]["max"]


def test_without_its_guard_waits_the_plan_collides(plan4, tmp_path, capsys):
    """The WAITs on another robot's "<robot>:<n>" events (that robot announced it left a place)
    are what keeps the robots apart: removed, the perturbed runs find robots meeting and bodies
    on material."""
    bare = tmp_path / "bare"
    shutil.copytree(plan4, bare)
    removed = 0
    for f in (bare / "robots").glob("*.coop"):
        lines = []
        for line in f.read_text().splitlines(keepends=True):
            if line.startswith("WAIT "):
                events = [e.strip() for e in line[5:].split(",")]
                kept = [e for e in events if ":" not in e]  # chunk events stay: the precedences
                removed += len(events) - len(kept)
                if not kept:
                    continue
                line = "WAIT " + ", ".join(kept) + "\n"
            lines.append(line)
        f.write_text("".join(lines))
    assert removed > 0
    restate_counts(bare)  # job.json's counts follow the edit (else the programs are refused as truncated)
    code = main(["simulate", str(bare), "--perturb", "0.3", "--runs", "3", "--seed", "1", "-q"])
    capsys.readouterr()
    assert code == 1
    counts = json.loads((bare / "sim" / "summary.json").read_text())["perturb"]["finding_counts"]
    assert counts["robots-collide"] > 0


def test_more_robots_than_work_are_idle_not_an_error():
    settings = load_settings(overrides=BIG)
    from cooprint.jobs import chunk_job

    job = chunk_job(as_solid(solids.box(200.0, 200.0, 20.0), "small"), settings, robots=12)
    idle = job.assignment.idle_robots
    assert len(idle) >= 12 - len(job.chunks.chunks)


@pytest.mark.parametrize("args, words", [
    (["--robots", "0"], "0"),
    (["--robots", "65"], "65"),
    (["--robots", "3", "--layout", "seed2"], "seed2"),
    (["--layout", "grid", "--schedule", "seed"], "seed"),
    (["--layout", "grid", "--column-width", "100"], "column"),
])
def test_bad_fleet_settings_are_refused(slab, tmp_path, capsys, args, words):
    line = assert_rejected(["run", str(slab), "--out", str(tmp_path / "o"), *args, *FLAGS], capsys, watch=[tmp_path])
    assert words in line


def test_exact_schedule_reports_its_bound(slab, tmp_path):
    settings = load_settings(overrides={**BIG, "chunking.layout": "grid", "scheduling.strategy": "exact",
                                        "scheduling.time_limit_s": 5.0})
    job = coop_job(as_solid(solids.plate(), "slab"), settings, robots=4)
    sched = job.chunked.assignment
    assert sched.strategy in ("exact", "list")
    if sched.strategy == "exact":
        assert sched.bound is not None and sched.bound <= sched.makespan + 1e-6
    else:
        assert sched.note  # a fallback is said
    assert sched.makespan >= sched.lower_bound - 1e-6
    result = simulate(load_inputs_from_job(job, tmp_path))
    assert not [f for f in result.findings if f.severity == "error"]


def load_inputs_from_job(job, tmp_path):
    from cooprint.jobs import write_coop_bundle

    out = tmp_path / "bundle"
    write_coop_bundle(job, out, picture=False)
    return load_inputs([str(out)])


@settings(max_examples=12, deadline=None)
@given(x=st.floats(300.0, 4000.0), y=st.floats(200.0, 2500.0), z=st.floats(5.0, 150.0),
       robots=st.integers(1, 20), body=st.floats(150.0, 500.0), frame=st.floats(100.0, 500.0))
def test_any_layout_size_fleet_and_outline_gives_a_valid_schedule(x, y, z, robots, body, frame):
    """Layout -> DAG -> schedule for boxes of any size, any fleet and robot outline: every
    precedence and body rule respected, no exclusive pair at the same time, no robot doing two
    things at once, makespan >= LB (check_schedule, run on every schedule), every chunk placed."""
    from cooprint.errors import UserError
    from cooprint.jobs import chunk_job
    from cooprint.scheduling import check_schedule
    overrides = {**BIG, "robot.body_width": body, "robot.frame_width": frame}
    try:
        job = chunk_job(as_solid(solids.box(x, y, z), "box"), load_settings(overrides=overrides), robots=robots)
    except UserError as exc:  # a part or outline the layout cannot take: said in one line
        assert "\n" not in str(exc)
        return
    sched = job.assignment
    # the seed's order knows no exclusions (its builder keeps L1 and R1 apart by the centre
    # chunk's top): it is checked on the rest
    dag = replace(job.dag, exclusive=()) if sched.strategy == "seed" else job.dag
    check_schedule(dag, sched)
    assert sched.makespan >= job.dag.lower_bound(robots) - 1e-6
    assert sorted(c for seq in sched.sequences.values() for c in seq) == sorted(job.chunks.ids)
    assert len(sched.sequences) == robots


def test_more_robots_are_never_slower_than_fewer():
    """`run` writes the programs of the fastest fleet up to N (the robots it leaves out idle), so
    six robots never finish after three on the same part (a stranger found them slower before)."""
    from cooprint.jobs import _programs_makespan

    spans = {}
    for n in (3, 6):
        job = coop_job(as_solid(solids.plate(), "slab"), load_settings(overrides={**BIG, "chunking.layout": "grid"}),
                       robots=n)
        spans[n] = _programs_makespan(job.programs, job.placements, job.chunked.settings)
        assert len(job.programs) == n
        busy = [r for r, seq in job.chunked.assignment.sequences.items() if seq]
        assert 2 <= len(busy) <= n
        assert job.chunked.assignment.lower_bound == pytest.approx(job.chunked.dag.lower_bound(n))
    assert spans[6] <= spans[3] * (1 + 1e-9)
