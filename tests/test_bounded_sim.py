"""Bounded simulation (issue 15, item 3): the checks and the pictures look at a robot's moves a
block at a time, and give the same findings, numbers and pictures whatever the block; the memory
``simulate`` needs beyond the timelines it returns does not grow with a copy per move."""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
import pytest

import solids
from cooprint.config import RobotProfile, SlicingSettings
from cooprint.program.gcode import Feeds
from cooprint.program.commands import (MOVE, TOOL_OFF, TOOL_ON, Program, ProgramError, iter_coop, make_program,
                                       parse_coop, read_coop)
from cooprint.render import sim as render_sim
from cooprint.simulation import SimInput, SimResult, checks, load_inputs, simulate, summary
from cooprint.simulation.inputs import load_manifest
from cooprint.simulation.timeline import SimRobot, schedule


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    """A real two-robot bundle of `cooprint run` (a 40 x 420 x 6 mm bar: A prints C and L1, B
    waits for C and prints R1)."""
    return solids.bar_bundle(tmp_path_factory.mktemp("bounded"), 6)


def _crowded(bundle, tmp_path):
    """A plan full of findings: the bundle's robots with B turned to face +Y (its body over
    the material A laid before), and a robot C running A's program beside A (robots collide,
    material laid twice)."""
    job = json.loads((bundle / "job.json").read_text())
    start = {r["name"]: r["start"] for r in job["robots"]}
    beside = [start["A"][0] + 30, start["A"][1], start["A"][2]]
    rows = (("A", "A", start["A"], 90), ("B", "B", start["B"], 90), ("C", "A", beside, 0))
    manifest = tmp_path / "crowd.toml"
    manifest.write_text("".join(f'[[robots]]\nname = "{n}"\nprogram = "{(bundle / "robots" / (p + ".coop")).as_posix()}"\n'
                                f"start = {list(s)}\nfacing_deg = {f}\n\n" for n, p, s, f in rows))
    return load_manifest(manifest)


def _tiny_blocks(monkeypatch):
    """Blocks far smaller than the plans: every block loop runs many times."""
    monkeypatch.setattr(checks, "BLOCK_MOVES", 97)
    monkeypatch.setattr(checks, "COLLIDE_BLOCK", 31)
    monkeypatch.setattr(render_sim, "BLOCK_MOVES", 89)


def test_findings_numbers_and_pictures_are_the_same_a_block_at_a_time(bundle, tmp_path, monkeypatch):
    plans = {"bundle": load_inputs([str(bundle)]), "crowded": _crowded(bundle, tmp_path)}
    whole = {k: simulate(inp) for k, inp in plans.items()}
    assert {k for k, v in summary(whole["crowded"])["finding_counts"].items() if v} >= \
        {"robots-collide", "body-on-material", "double-deposit"}  # the checks that sweep have work to do
    def pictures(res, k, tag):
        render_sim.render_snapshot(res, res.makespan * 0.6, tmp_path / f"{k}_{tag}.png", max_segments=500)
        render_sim.render_gantt(res, tmp_path / f"{k}_{tag}_gantt.png")
        return [(tmp_path / f"{k}_{tag}{x}.png").read_bytes() for x in ("", "_gantt")]

    drawn = {k: pictures(res, k, "whole") for k, res in whole.items()}
    _tiny_blocks(monkeypatch)
    for k, inp in plans.items():
        res = simulate(inp)
        assert summary(res) == summary(whole[k]), k
        assert pictures(res, k, "blocks") == drawn[k], k


def test_reading_a_program_gives_the_same_columns_as_the_line_parser_would(bundle):
    """The reader moves commands to the front in place and repeats the annotations in their own
    dtypes: the program equals the one parsed from the text with every line odd enough for the
    line parser (a trailing comment on each MOVE)."""
    path = bundle / "robots" / "B.coop"
    fast = read_coop(path)
    text = path.read_text()
    slow = parse_coop("".join(line + " ; x\n" if line.startswith("MOVE") else line + "\n"
                              for line in text.splitlines()), "B")
    assert fast == slow and len(fast) > 1000
    assert [getattr(fast, f).dtype for f in ("kind", "role", "layer", "chunk", "event")] == \
        [np.uint8, np.uint8, np.int32, np.int16, np.int32]


def _plan(layers: int, lines: int = 100, length: float = 100.0) -> SimInput:
    """Two robots printing 100 x 45 mm blocks of lines face to face, 200 mm apart: 13 commands a
    line (a travel, TOOL ON, ten moves, TOOL OFF), a layer of ``lines`` lines each."""
    line_kind = np.array([MOVE, TOOL_ON] + [MOVE] * 10 + [TOOL_OFF], np.uint8)
    i = np.arange(lines)
    seg = np.linspace(0.0, length, 11)
    xs = np.where((i % 2 == 0)[:, None], seg, seg[::-1])
    line = np.full((lines, 13, 3), np.nan)
    moves = [0] + list(range(2, 12))
    line[:, 0, 0], line[:, 2:12, 0] = xs[:, 0], xs[:, 1:]
    line[:, moves, 1] = (0.45 * i)[:, None]
    robots = []
    for name, y0, facing in (("A", 0.0, 90.0), ("B", 200.0, -90.0)):
        xyz = np.tile(line, (layers, 1, 1, 1)).reshape(layers, lines * 13, 3)
        xyz[:, :, 1] += y0
        xyz[:, :, 2] = np.where(np.isnan(xyz[:, :, 0]), np.nan, 0.2 * (np.arange(layers) + 1)[:, None])
        xyz = xyz.reshape(-1, 3)
        program = make_program(name, np.tile(line_kind, layers * lines), xyz, role=2, width=0.45, layer=0,
                               height=0.2, chunk=0, chunks=(f"C{name}",))
        a = np.radians(facing)
        robots.append(SimRobot(name, program, xyz[0].copy(), np.array([np.cos(a), np.sin(a)])))
    return SimInput(robots, RobotProfile(), SlicingSettings(), "two blocks of lines")


def test_no_stage_of_simulate_holds_a_copy_per_move(monkeypatch):
    """Each stage of a simulation (the schedule, the checks that sweep every move, the summary)
    needs, beyond what it returns, at most 2 bytes a command plus 1 MB at any moment, with
    blocks of 4096 moves: an array of a float64 per move (8 bytes a move, 6.8 a command here)
    fails it. Before issue 15 each of them made several (per-command times in the schedule,
    chunk slots, sample counts and move selections in the footprint check, first deposits in
    chunk-order, speeds in the collision check, durations and beads in the summary: 3.6 to 21
    bytes a command). The footprint, height-field and overhang checks keep rasters and work
    space bounded by MAX_CELLS, MATERIAL_CELLS and the material's samples, not looked at here;
    the material's samples (at least one a deposit) and the collision check's instants are
    capped small so that they weigh little."""
    monkeypatch.setattr(checks, "MAX_SAMPLES", 20_000)
    monkeypatch.setattr(checks, "MAX_INSTANTS", 20_000)
    monkeypatch.setattr(checks, "BLOCK_MOVES", 4096)
    inp = _plan(300)  # 780,000 commands, 660,000 moves
    simulate(_plan(2))  # the compiled kernels loaded before the count
    commands = sum(len(r.program) for r in inp.robots)
    robots, p = inp.fleet(), inp.profile
    held = {}

    def stage(name, work):
        tracemalloc.start()
        try:
            before = tracemalloc.get_traced_memory()[0]
            out = work()
            now, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
        held[name] = peak - max(now, before)  # beyond what it started with and what it returns
        return out

    feeds = inp.feeds(robots)
    timelines, findings = stage("schedule", lambda: schedule(robots, feeds))
    stage("chunk-order", lambda: checks.chunk_order(robots, timelines, {"CA": ("CB",)}))
    stage("below-floor", lambda: checks.below_floor(robots, timelines))
    material = stage("material", lambda: checks.Material.sample(robots, timelines, checks.STEP, 0.2))
    stage("robots-collide", lambda: checks.robots_collide(robots, timelines, p))
    result = SimResult(robots, timelines, findings, p, inp.slicing, inp.source)
    record = stage("summary", lambda: summary(result))
    assert record["robots"][0]["moves"] == 330_000 and len(material.t) >= 600_000
    # the collision check's windows between instants are refined down to MAX_INSTANTS at a time
    # (robots 200 mm apart are close at 120 mm/s): 2 MB more for that work
    assert all(v < 2 * commands + (1 << 20) + (2 << 20) * (k == "robots-collide") for k, v in held.items()), \
        {k: f"{v / commands:.1f} bytes a command" for k, v in held.items()}


@pytest.mark.parametrize("block", [97, 4096])
def test_block_sums_are_numpys_sums_to_the_last_bit(monkeypatch, block):
    """summary.json's times and volumes are sums of per-move values made a block at a time: the
    same doubles as numpy's sum of the whole array (a change of numpy's summation shows here)."""
    monkeypatch.setattr(checks, "BLOCK_MOVES", block)
    rng = np.random.default_rng(7)
    for n in (0, 1, 7, 128, 129, 1000, 54_321, 300_001):
        x = rng.random(n) * 10.0 ** rng.uniform(-3, 6, n)
        m = rng.random(n) < 0.7
        assert checks.block_sum(lambda a, e: x[a:e], n) == np.sum(x)
        assert checks.block_sum(lambda a, e: x[a:e], n, lambda a, e: m[a:e]) == np.sum(x[m])


ODD = ("\ufeff; cooprint-coop/1 program for robot A\r\n;@chunk C\n;@layer 0 0.2\n;@path skin 0.45\nTOOL ON\n"
       "MOVE 1, 2, 0.2\nMOVE 3 4 0.2 ; a comment\n;@facing -90\nNOTIFY\n# hash comment\n\n;@chunk L1\n"
       ";@layer 1 0.25\nmove 5, 6, 0.45\nTOOL OFF\n;@path travel 0\nWAIT B:1, C\n;@layer -\nNOTIFY done\n"
       ";@chunk C\n;@path perimeter 0.4\nTOOL ON\nMOVE 7, 8, 0.45\n;@facing 90\n;@chunk -\nMOVE 9, 9, 1\nNOTIFY")


@pytest.mark.parametrize("piece", [1, 7, 40, 1 << 20])
def test_a_program_read_in_pieces_is_the_whole_program(bundle, tmp_path, piece):
    """iter_coop: the pieces of whole lines, concatenated, are read_coop's program (annotations,
    chunk names, bare NOTIFY numbers and turns carried across pieces, a BOM, CRLF, comments)."""
    odd = tmp_path / "A.coop"
    odd.write_bytes(ODD.encode())
    for path in (odd, bundle / "robots" / "B.coop"):
        pieces = list(iter_coop(path, piece_bytes=piece))
        whole = parse_coop(path.read_bytes(), path.stem, str(path))
        assert Program.concat(path.stem, pieces) == whole == read_coop(path)
    assert piece > 100 or len(pieces) > 100  # small pieces: many of them


@pytest.mark.parametrize("piece", [1, 25, 1 << 20])
def test_an_error_in_a_later_piece_names_its_line(tmp_path, piece):
    bad = tmp_path / "A.coop"
    bad.write_text("".join(f"MOVE {i}, 0, 1\n" for i in range(50)) + "MOVE 1, 2\n")
    with pytest.raises(ProgramError, match=r"A\.coop:51:10: MOVE needs 3 numbers"):
        list(iter_coop(bad, piece_bytes=piece))
    with pytest.raises(ProgramError, match=r"A\.coop:51:10: MOVE needs 3 numbers"):
        read_coop(bad)


def test_a_robot_stuck_at_a_later_wait_keeps_the_delays_of_its_earlier_waits():
    """The schedule adds each WAIT's delay to the moves after it, run by run: a robot that
    deadlocks at its second WAIT still starts the moves after its first one when that WAIT ends
    (the per-command arrays this replaced looked the delays up with the stuck robot's position
    instead of its WAITs' indices: those moves started at 0 s)."""
    up = np.array([0.0, 1.0])
    a = SimRobot("A", parse_coop("MOVE 0 0 0\nMOVE 400 0 0\nNOTIFY\n", "A"), np.zeros(3), up)
    b = SimRobot("B", parse_coop("MOVE 0 1000 0\nWAIT A:1\nMOVE 40 1000 0\nWAIT never\nMOVE 80 1000 0\n", "B"),
                 np.array([0.0, 1000.0, 0.0]), up)
    timelines, findings = schedule([a, b], Feeds((40.0,) * 9, 40.0, 40.0))  # every move at 40 mm/s
    assert [f.kind for f in findings] == ["deadlock"] and findings[0].time == 11.0
    np.testing.assert_array_equal(timelines["B"].t0, [0.0, 10.0])
    np.testing.assert_array_equal(timelines["B"].t1, [0.0, 11.0])
