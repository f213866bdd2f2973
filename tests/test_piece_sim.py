"""Bounded simulation (issue 15, item 3): a bundle's programs read and timed piece by piece
(``load_inputs(..., programs=False)``, what ``cooprint simulate`` and ``render`` do) give the
same timelines, findings, summary.json bytes and pictures as the programs read whole, and the
robots keep only the columns the checks read (no targets, roles, layers)."""

from __future__ import annotations

import dataclasses
import gzip
import json
import shutil
from functools import partial

import numpy as np
import pytest

import solids
from cooprint import simulation
from cooprint.cli import main
from cooprint.io.bundle import write_json
from cooprint.program.commands import iter_coop
from cooprint.render import sim as render_sim
from cooprint.simulation import frames, load_inputs, simulate, summary


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    return solids.bar_bundle(tmp_path_factory.mktemp("pieces"), 6)


def _variant(bundle, tmp_path, kind: str):
    """The bundle as it is, with robot B turned and stuck at a WAIT no one answers half way
    (a deadlock, a facing turn), or with its programs gzip-compressed."""
    out = tmp_path / kind
    shutil.copytree(bundle, out)
    if kind == "deadlock":
        path = out / "robots" / "B.coop"
        lines = path.read_text().splitlines(keepends=True)
        half = next(i for i in range(len(lines) // 2, len(lines)) if lines[i].startswith("MOVE"))
        lines[half:half] = [";@facing 45\n", "WAIT nobody:7\n"]
        path.write_text("".join(lines))
        job = json.loads((out / "job.json").read_text())  # job.json edited to match (else refused)
        stats = job["robots"][1]["stats"]
        stats["commands"], stats["wait"] = stats["commands"] + 1, stats["wait"] + 1
        write_json(out / "job.json", job)
    elif kind == "gzip":
        job = json.loads((out / "job.json").read_text())
        for r in job["robots"]:
            src = out / r["program"]
            (out / (r["program"] + ".gz")).write_bytes(gzip.compress(src.read_bytes(), mtime=0))
            src.unlink()
            r["program"] += ".gz"
        write_json(out / "job.json", job)
    return out


def _small_pieces(monkeypatch, piece_bytes: int):
    """The simulation reads the programs in pieces of ``piece_bytes`` of text: many pieces."""
    monkeypatch.setattr(simulation.inputs, "iter_coop", partial(iter_coop, piece_bytes=piece_bytes))


@pytest.mark.parametrize("kind", ["bundle", "deadlock", "gzip"])
@pytest.mark.parametrize("piece_bytes", [1, 700, 1 << 22])
def test_programs_timed_piece_by_piece_give_the_same_plan(bundle, tmp_path, monkeypatch, kind, piece_bytes):
    folder = _variant(bundle, tmp_path, kind) if kind != "bundle" else bundle
    whole = simulate(load_inputs([str(folder)]))
    _small_pieces(monkeypatch, piece_bytes)
    lazy_inp = load_inputs([str(folder)], programs=False)
    assert all(r.program is None for r in lazy_inp.robots) and lazy_inp.program_files
    lazy = simulate(lazy_inp)
    if kind == "deadlock":
        assert summary(whole)["finding_counts"]["deadlock"] == 1
    assert json.dumps(summary(lazy)) == json.dumps(summary(whole))
    for r in whole.robots:
        a, b = whole.timelines[r.name], lazy.timelines[r.name]
        for f in ("t0", "t1", "p0", "p1", "on", "index", "length"):
            assert np.array_equal(getattr(a, f), getattr(b, f)), (r.name, f)
        assert (a.waits, a.notifies) == (b.waits, b.notifies)
    slim = {r.name: r.program for r in lazy.robots}
    for r in whole.robots:
        p = slim[r.name]
        assert (p.chunks, p.events, p.turns) == (r.program.chunks, r.program.events, r.program.turns)
        for f in simulation.timeline.KEPT_COLUMNS:
            assert np.array_equal(getattr(p, f), getattr(r.program, f)), f
            assert getattr(p, f).dtype == getattr(r.program, f).dtype
        # the columns no check reads take no memory
        assert all(s == 0 for f in ("xyz", "layer") for s in getattr(p, f).strides)
    fw, fl = frames(whole, whole.makespan / 37), frames(lazy, lazy.makespan / 37)
    for f in ("t", "position", "done", "material", "facing"):
        assert np.array_equal(getattr(fw, f), getattr(fl, f)), f
    for tag, res in (("whole", whole), ("lazy", lazy)):
        render_sim.render_snapshot(res, res.makespan * 0.6, tmp_path / f"{tag}.png", max_segments=500)
        render_sim.render_gantt(res, tmp_path / f"{tag}_gantt.png")
    for x in ("", "_gantt"):
        assert (tmp_path / f"whole{x}.png").read_bytes() == (tmp_path / f"lazy{x}.png").read_bytes()


def test_accelerated_runs_read_the_programs_whole(bundle):
    whole = simulate(load_inputs([str(bundle)]), accel=True)
    lazy = simulate(load_inputs([str(bundle)], programs=False), accel=True)
    assert json.dumps(summary(lazy)) == json.dumps(summary(whole))
    assert all(r.program.xyz.strides != (0, 0) for r in lazy.robots)


def test_cli_simulate_and_render_write_what_the_whole_programs_give(bundle, tmp_path, monkeypatch):
    """``cooprint simulate DIR --out OTHER`` (programs timed piece by piece) writes the summary
    the whole programs give, byte for byte (with the inputs it read); ``render --at`` the same
    picture."""
    _small_pieces(monkeypatch, 5000)
    inp = load_inputs([str(bundle)])
    whole = simulate(inp)
    # and what `cooprint view` needs to read the inputs again, and to know when they change
    inputs = {"paths": [str(bundle.resolve())], "manifest": None, "config": [], "accel": False,
              "fingerprint": inp.fingerprint}
    assert set(inp.fingerprint) >= {"job.json", "robots/A.coop", "robots/B.coop"}
    write_json(tmp_path / "expected.json", summary(whole) | {"inputs": inputs})
    assert main(["simulate", str(bundle), "--out", str(tmp_path / "o"), "--quiet"]) in (0, 1)
    assert (tmp_path / "o" / "sim" / "summary.json").read_bytes() == (tmp_path / "expected.json").read_bytes()
    at = whole.makespan * 0.4
    render_sim.render_snapshot(whole, at, tmp_path / "expected.png")
    assert main(["render", str(bundle), "--at", repr(at), "--out", str(tmp_path / "got.png")]) == 0
    assert (tmp_path / "got.png").read_bytes() == (tmp_path / "expected.png").read_bytes()


@pytest.mark.parametrize("seed", range(6))
def test_runs_index_as_the_array_they_stand_for(seed):
    """A :class:`Runs` column built piece by piece gives what the array gives: indices, slices,
    arrays of indices, ``np.maximum.reduceat`` (the widest line of a span), its array."""
    from cooprint.simulation.timeline import Runs, _RunsBuilder, changes, segment_max

    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 400))
    a = rng.choice([0.0, -0.0, 0.4, 0.45, 2.5], size=n)
    a = np.repeat(a, rng.integers(1, 6, size=n))[:n]
    b = _RunsBuilder(np.float64)
    cuts = np.sort(rng.integers(0, n + 1, size=5))
    for lo, hi in zip(np.r_[0, cuts], np.r_[cuts, n]):
        b.add(a[lo:hi])
    runs = b.runs()
    assert isinstance(runs, Runs) and len(runs) == n and runs.nbytes < a.nbytes + 16
    assert np.asarray(runs).tobytes() == a.tobytes()  # -0.0 kept apart from 0.0
    idx = rng.integers(-n, n, size=50)
    assert np.asarray(runs[idx]).tobytes() == a[idx].tobytes()
    assert runs[int(idx[0])] == a[int(idx[0])] and runs[-1] == a[-1]
    k = int(rng.integers(0, n))
    assert np.array_equal(runs[k:], a[k:]) and np.array_equal(runs[::3], a[::3])
    assert np.array_equal(runs[a > 1], a[a > 1])
    at = np.sort(rng.integers(0, n, size=int(rng.integers(1, 30))))
    assert np.array_equal(segment_max(runs, at), np.maximum.reduceat(a, at))
    index = np.unique(rng.integers(0, n, size=int(rng.integers(1, n + 1))))  # a timeline's commands
    assert np.array_equal(changes(runs, index), changes(a, index))
    c = a[index]
    assert np.array_equal(changes(a, index), np.flatnonzero(c[1:] != c[:-1]) + 1)
    with pytest.raises(IndexError):
        runs[n]


def test_timing_programs_piece_by_piece_holds_no_program(tmp_path):
    """Timing programs from their files piece by piece holds, beyond the timelines it returns,
    less than half of what the programs read whole would take (52 bytes a command) at any
    moment, the moves' columns growing as the pieces come (given no room, they double: a
    resize holds old and new; ``simulate`` gives room for a command every 7 bytes of file,
    pages never written never backed); the robots it returns keep the kinds (a byte a command)
    and their annotations as runs."""
    import tracemalloc

    from test_bounded_sim import _plan

    from cooprint.program.commands import write_coop
    from cooprint.simulation.timeline import schedule, schedule_pieces

    inp = _plan(300)  # 780,000 commands, 660,000 moves
    files = {}
    for r in inp.robots:
        files[r.name] = tmp_path / f"{r.name}.coop"
        with open(files[r.name], "w") as f:
            write_coop(f, r.program)
    robots, feeds = inp.fleet(), inp.feeds()
    commands = sum(len(r.program) for r in robots)
    expected, _ = schedule(robots, feeds)
    bare = [dataclasses.replace(r, program=None) for r in robots]
    pieces = {name: partial(iter_coop, f, name, piece_bytes=256 << 10) for name, f in files.items()}
    schedule_pieces(bare[:1], pieces, feeds)  # the compiled kernels loaded
    tracemalloc.start()
    try:
        slim, timelines, findings = schedule_pieces(bare, pieces, feeds)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    held = sum(a.nbytes for tl in timelines.values() for a in (tl.t0, tl.t1, tl.on, tl.index))  # lengths: not held
    held += sum(tl.p0.nbytes + 24 for tl in timelines.values())  # p0 and p1: views of one array of ends
    assert peak - held < 26 * commands, f"{(peak - held) / commands:.1f} bytes a command"
    assert sum(getattr(r.program, f).nbytes for r in slim for f in simulation.timeline.KEPT_COLUMNS) \
        < 1.1 * commands
    for r in robots:
        assert np.array_equal(timelines[r.name].t1, expected[r.name].t1)
        assert np.array_equal(timelines[r.name].p0, expected[r.name].p0)


def test_lengths_computed_when_asked_are_the_move_tables(bundle):
    """A timeline timed piece by piece computes its moves' lengths from its ends when asked
    (:class:`Lengths`): the move table's numbers to the last bit (random moves on the 1 µm grid
    and off it, 0 to 1 km long), whatever the index; ``sum()`` numpy's sum of the array."""
    from cooprint.simulation.kernels import move_table
    from cooprint.simulation.timeline import Lengths

    rng = np.random.default_rng(3)
    n = 200_000
    xyz = rng.uniform(-500, 500, (n, 3)) * rng.choice([1e-3, 1.0, 1.0], (n, 1))
    xyz[::2] = np.rint(xyz[::2] * 1000) / 1000
    xyz[5] = xyz[4]  # a move of length 0
    kind = np.zeros(n, np.uint8)
    ends = np.empty((n + 1, 3))
    mv, on, length = np.empty(n, np.int64), np.empty(n, bool), np.empty(n)
    move_table(kind, xyz, np.array([1.5, -2.25, 0.2]), True, mv, ends[:-1], ends[1:], on, length)
    lazy = Lengths(ends[:-1], ends[1:])
    assert np.asarray(lazy).tobytes() == length.tobytes() and len(lazy) == n
    sel = rng.integers(0, n, 1000)
    assert lazy[sel].tobytes() == length[sel].tobytes()
    assert lazy[length > 3].tobytes() == length[length > 3].tobytes()
    assert lazy[10:5000].tobytes() == length[10:5000].tobytes()
    assert lazy.sum() == length.sum()
    lazy_tl = simulate(load_inputs([str(bundle)], programs=False)).timelines["A"]
    assert isinstance(lazy_tl.length, Lengths)


def test_command_indices_past_int32_are_kept_in_int64(bundle, monkeypatch):
    """A robot timed piece by piece keeps its moves' command indices in 4 bytes while they fit;
    past the bound (made small here) in 8, the same numbers."""
    from cooprint.simulation import timeline

    whole = simulate(load_inputs([str(bundle)]), checks=False)
    _small_pieces(monkeypatch, 3000)
    small = simulate(load_inputs([str(bundle)], programs=False), checks=False)
    monkeypatch.setattr(timeline, "INT32_COMMANDS", 1000)
    inp = load_inputs([str(bundle)], programs=False)
    pieces = {r.name: partial(iter_coop, inp.program_files[r.name], r.name, piece_bytes=3000) for r in inp.robots}
    # no room given: the columns grow as the pieces come, the indices turn int64 past 1000 commands
    _, big, _ = timeline.schedule_pieces(inp.fleet(), pieces, inp.feeds())
    for name, tl in whole.timelines.items():
        assert small.timelines[name].index.dtype == np.int32 and big[name].index.dtype == np.int64
        assert np.array_equal(small.timelines[name].index, tl.index)
        for f in ("index", "t0", "t1", "p1"):
            assert np.array_equal(getattr(big[name], f), getattr(tl, f))
    assert json.dumps(summary(small)) == json.dumps(summary(whole))
