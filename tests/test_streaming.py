"""A streamed `cooprint run` (issue 15 item 1): chunks spooled as they are sliced, robot files
written piece by piece, the same bytes as the job made whole in memory, in bounded memory."""

import gc
import json
import types
import weakref
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings as hsettings, strategies as st

from cooprint.config import load_settings
from cooprint.errors import UserError
from cooprint.jobs import SPOOL, coop_job, run_job, write_coop_bundle
from cooprint.program.build import layer_program
from cooprint.program.commands import MOVE, TOOL_OFF, Program, program_rows
from cooprint.program.stream import ChunkStore, canonical_program, entered, hull_points
from cooprint.simulation.timeline import PieceRobot, SimRobot, event_times, schedule
from cooprint.program.gcode import Feeds
from cooprint.slicing import iter_layers

from solids import COARSE, box, plate
from test_plans import as_solid
from test_n_robots import BIG


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _same_record(a: dict, b: dict) -> None:
    """job.json of two runs: equal, but for the program statistics' sums (added up in another
    order: equal to rounding)."""
    sa = [r.pop("stats") for r in a["robots"]]
    sb = [r.pop("stats") for r in b["robots"]]
    assert a == b
    for x, y in zip(sa, sb):
        assert x.keys() == y.keys()
        for k in x:
            assert x[k] == pytest.approx(y[k], rel=1e-12, abs=1e-9), k


@pytest.mark.parametrize("robots, overrides", [(2, COARSE), (4, {**BIG, "chunking.layout": "grid"})],
                         ids=["seed2-2-robots", "grid-4-robots"])
def test_streamed_bundle_is_the_in_memory_bundle(car_stl, tmp_path, robots, overrides):
    """The seed's builder (2 robots) and the fleet's (4 robots, pieces of chunks between WAITs):
    the streamed run writes the very bytes the job made whole in memory writes, and leaves no
    spool behind."""
    settings = load_settings(overrides=overrides)
    memory = coop_job(car_stl, settings, robots=robots)
    assert memory.layers is not None and memory.store.folder is None
    write_coop_bundle(memory, tmp_path / "memory", picture=False)
    run_job(car_stl, settings, tmp_path / "streamed", robots, picture=False)
    a, b = _files(tmp_path / "memory"), _files(tmp_path / "streamed")
    assert a.keys() == b.keys()
    assert not any(SPOOL in name for name in b)
    robot_files = [n for n in a if n.startswith("robots/")]
    assert len(robot_files) == 2 * robots
    for name in robot_files:
        assert a[name] == b[name], name
    _same_record(json.loads(a.pop("job.json")), json.loads(b.pop("job.json")))
    assert a == b  # the chunk meshes


def test_streamed_programs_are_the_whole_programs(car_stl):
    """A job's streams made whole are the programs the builders made whole, and the programs
    made whole from a spool on disk are those made in memory."""
    settings = load_settings(overrides=COARSE)
    job = coop_job(car_stl, settings, robots=2)
    for robot, stream in job.streams.items():
        pieces = list(stream.programs(job.store))
        assert Program.concat(robot, pieces) == job.programs[robot]
        assert sum(len(p) for p in pieces) == len(job.programs[robot])


def test_spooled_job_keeps_no_layers(car_stl, tmp_path):
    settings = load_settings(overrides=COARSE)
    spooled = coop_job(car_stl, settings, robots=2, spool=tmp_path / "spool")
    memory = coop_job(car_stl, settings, robots=2)
    assert spooled.layers is None
    assert len(list((tmp_path / "spool").iterdir())) == len(spooled.chunked.chunks.chunks)
    for robot in memory.programs:
        assert spooled.programs[robot] == memory.programs[robot]


def test_failed_run_leaves_nothing(car_stl, tmp_path, monkeypatch):
    """A run that fails while writing (after the spool was filled) leaves no bundle, no
    temporary folder and no spool."""
    import cooprint.jobs as jobs

    def boom(*args, **kwargs):
        raise UserError("stop here")

    monkeypatch.setattr(jobs, "write_coop_files", boom)
    with pytest.raises(UserError):
        run_job(car_stl, load_settings(overrides=COARSE), tmp_path / "out", 2, picture=False)
    assert list(tmp_path.iterdir()) == []


def _array_bytes(obj) -> int:
    """Bytes of the numpy arrays reachable from ``obj`` (not through modules, classes or functions)."""
    seen, stack, total = set(), [obj], 0
    while stack:
        o = stack.pop()
        if id(o) in seen or isinstance(o, (type, types.ModuleType, types.FunctionType, types.MethodType, str, bytes)):
            continue
        seen.add(id(o))
        if isinstance(o, np.ndarray):
            total += o.nbytes
            continue
        stack.extend(gc.get_referents(o))
    return total


def test_memory_is_bounded_by_the_chunks_in_flight(tmp_path, monkeypatch):
    """A streamed run of a part of many chunks (17) holds one chunk's commands at a time, not
    the job's: the job it plans keeps only small summaries of its chunks (the commands are on
    disk), and writing the robots' files reads one chunk's commands, lets it go, then reads the
    next; the files are those of the job made in memory, byte for byte."""
    solid = as_solid(box(60.0, 4800.0, 10.0), "long")
    settings = load_settings(overrides={**COARSE, "slicing.infill_density": 0.5})
    memory = coop_job(solid, settings, robots=2)
    total = sum(len(memory.programs[r]) for r in memory.programs) * 52  # bytes per command of a Program
    biggest = max(s.commands for s in memory.store.summaries.values()) * 52
    assert len(memory.chunked.chunks.chunks) >= 12 and total >= 10 * biggest
    assert _array_bytes(memory) > total  # its layers and commands

    spooled = coop_job(solid, settings, robots=2, spool=tmp_path / "spool")
    assert _array_bytes(spooled) < total / 5
    live, most = [], [0]
    read = ChunkStore.program

    def counted(self, cid):
        prog = read(self, cid)
        if all(p() is not prog.kind for p in live):
            live.append(weakref.ref(prog.kind))  # its arrays live as long as someone holds them
        live[:] = [p for p in live if p() is not None]
        most[0] = max(most[0], len(live))
        return prog

    write_coop_bundle(memory, tmp_path / "memory", picture=False)
    monkeypatch.setattr(ChunkStore, "program", counted)
    del memory
    gc.collect()
    write_coop_bundle(spooled, tmp_path / "out", picture=False)
    assert 1 <= most[0] <= 2
    # and a job of many chunks streamed writes the bytes the job in memory writes
    for name in ("A.coop", "A.gcode", "B.coop", "B.gcode"):
        assert (tmp_path / "out" / "robots" / name).read_bytes() == (tmp_path / "memory" / "robots" / name).read_bytes()


def test_entered_is_layer_program_from_there():
    """A chunk's commands from any entry point: the canonical program with its way in replaced is
    what layer_program makes from there (from nowhere, from above the first point, from beside
    it at its height, from elsewhere)."""
    settings = load_settings(overrides=COARSE)
    solid = as_solid(box(30.0, 40.0, 6.0), "b")
    layers = list(enumerate(iter_layers(solid, settings.slicing, base=-2.0), start=2))
    canon = canonical_program("K", layers)
    first = next(layer for _, layer in layers if len(layer))
    x0, y0, z0 = first.points[0][0], first.points[0][1], first.z
    rng = np.random.default_rng(3)
    entries = [None, (x0, y0, z0), (x0, y0, z0 + 5.0), (x0 + 7.0, y0, z0), (x0, y0 - 2.0, z0 + 1.0)]
    entries += [tuple(rng.uniform(-80, 80, 3)) for _ in range(5)]
    for e in entries:
        here = np.full(3, np.nan) if e is None else np.asarray(e, float)
        parts = []
        for li, layer in layers:
            piece, here = layer_program(layer, here, index=li, chunk="K")
            parts.append(piece)
        assert entered(canon, None if e is None else np.asarray(e)) == Program.concat("", parts), e


@hsettings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(-1e3, 1e3), st.floats(-1e3, 1e3)), min_size=1, max_size=60),
       st.floats(0, 2 * np.pi))
def test_hull_points_keep_every_extreme(pts, angle):
    """The hull's points give the least and greatest of any linear function over the points
    (the parking and the fleet's footprints use only those); they are points of the set."""
    pts = np.array(pts)
    h = hull_points(pts)
    assert set(map(tuple, h)) <= set(map(tuple, pts))
    for f in (np.array([np.cos(angle), np.sin(angle)]), np.array([1.0, 0.0]), np.array([0.3, -0.7])):
        # (the same products, up to the rounding of matmul's kernels, which differ by shape)
        assert (h @ f).min() == pytest.approx((pts @ f).min(), rel=1e-14, abs=1e-12)
        assert (h @ f).max() == pytest.approx((pts @ f).max(), rel=1e-14, abs=1e-12)


def test_event_times_are_schedule_times():
    """WAIT durations and ends timed piece by piece (the pieces cut after TOOL OFFs, as a stream
    is) are those of schedule() on the whole programs, to the last bit."""
    settings = load_settings(overrides={**BIG, "chunking.layout": "grid"})
    job = coop_job(as_solid(plate(), "slab"), settings, robots=4)
    s = job.chunked.settings
    robots = [SimRobot(r, p, np.asarray(job.placements[r].start, float), np.zeros(2), profile=s.robot)
              for r, p in job.programs.items()]
    feeds = Feeds.of_robot(s.robot, s.slicing)
    timelines, _ = schedule(robots, feeds)
    rng = np.random.default_rng(5)

    def cut(p):
        offs = np.flatnonzero(p.kind == TOOL_OFF) + 1
        cuts = np.unique(np.r_[0, rng.choice(offs, min(len(offs), 9), replace=False) if len(offs) else [], len(p)])
        return [program_rows(p, int(a), int(b)) for a, b in zip(cuts[:-1], cuts[1:])]

    pieces = {r: cut(p) for r, p in job.programs.items()}
    got = event_times([PieceRobot(r, np.asarray(job.placements[r].start, float), (lambda r=r: pieces[r]), feeds.speeds)
                       for r in job.programs])
    for r, tl in timelines.items():
        assert got.ends[r] == tl.end
        assert got.waits[r] == [w[1] - w[0] for w in tl.waits]
    assert any(got.waits[r] for r in got.waits)  # the plan has WAITs to time


def test_store_reads_back_what_it_spooled(tmp_path):
    settings = load_settings(overrides=COARSE)
    layers = list(enumerate(iter_layers(as_solid(box(20.0, 30.0, 5.0), "b"), settings.slicing)))
    disk, memory = ChunkStore(tmp_path / "s"), ChunkStore()
    for store in (disk, memory):
        store.put("A", layers)
        store.put("B", layers[:2])
    assert disk.program("A") == memory.program("A") and disk.program("B") == memory.program("B")
    assert disk.summary("A").commands == len(memory.program("A"))
    assert disk.nbytes() > 0 and memory.nbytes() == 0
    assert (disk.program("A").kind == MOVE).any()
