"""The cooperative pipeline end to end (`cooprint run`): programs, transitions, sync, bundle."""

import json

import numpy as np
import pytest

from cooprint.cli import main
from cooprint.config import load_settings
from cooprint.jobs import coop_job, run, write_coop_bundle
from cooprint.program.commands import MOVE, NOTIFY, WAIT, read_coop
from cooprint.slicing import flow_area, iter_layers
from cooprint.slicing.sections import LayerSlicer

from solids import COARSE


@pytest.fixture(scope="module")
def job(car_stl):
    return coop_job(car_stl, load_settings(overrides=COARSE), robots=2)


@pytest.fixture(scope="module")
def bundle(job, tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "job"
    record = write_coop_bundle(job, out, picture=False)
    return out, record


def _deposits(program, upto=None):
    """(k, 2, 3) segments a program deposits along (tool on, moving), their chunks and widths;
    with ``upto``, only those of the commands up to that index."""
    kinds = program.kind if upto is None else program.kind[:upto + 1]
    mv = np.flatnonzero(kinds == MOVE)
    on = program.tool_on()[mv][1:]
    seg = np.stack([program.xyz[mv][:-1], program.xyz[mv][1:]], axis=1)
    moving = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) > 0
    return seg[on & moving], program.chunk[mv][1:][on & moving], program.width[mv][1:][on & moving]


def _inside(points, rings):
    """(n,) bool: even-odd point in polygon, vectorised over points and edges."""
    inside = np.zeros(len(points), dtype=bool)
    for r in rings:
        a, b = r, np.roll(r, -1, axis=0)
        x, y = points[:, :1], points[:, 1:2]
        crosses = (a[:, 1] > y) != (b[:, 1] > y)
        t = (y - a[:, 1]) / np.where(b[:, 1] != a[:, 1], b[:, 1] - a[:, 1], 1.0)
        xc = a[:, 0] + t * (b[:, 0] - a[:, 0])
        inside ^= (crosses & (x < xc)).sum(axis=1) % 2 == 1
    return inside


def test_two_robots_split_the_chunks_as_the_seed_does(job, bundle):
    _, record = bundle
    seq = job.chunked.assignment.sequences
    assert seq["A"][0] == "C" and all(c.startswith("L") for c in seq["A"][1:])
    assert seq["B"] and all(c.startswith("R") for c in seq["B"])
    robots = {r["name"]: r for r in record["robots"]}
    assert robots["A"]["side"] == "left" and robots["B"]["side"] == "right"
    # each faces the centre: A (on -y) looks along +y, B along -y
    assert robots["A"]["facing_deg"] == pytest.approx(90.0) and robots["B"]["facing_deg"] == pytest.approx(-90.0)
    # the seed's single NOTIFY after the centre chunk, and B's single WAIT for it
    a, b = job.programs["A"], job.programs["B"]
    assert [a.events[e] for e in a.event[a.kind == NOTIFY]] == [("C",)]
    assert [b.events[e] for e in b.event[b.kind == WAIT]] == [("C",)]
    first_b = np.flatnonzero((b.kind == MOVE) & (b.chunk >= 0))[0]
    assert np.flatnonzero(b.kind == WAIT)[0] < first_b
    last_c = np.flatnonzero((a.kind == MOVE) & (a.chunk == a.chunks.index("C")))[-1]
    assert np.flatnonzero(a.kind == NOTIFY)[0] == last_c + 2  # after the TOOL OFF that ends C


def test_every_wait_has_a_notify_of_another_robot(job):
    announced = {name: {e for i in np.flatnonzero(p.kind == NOTIFY) for e in p.events[p.event[i]]}
                 for name, p in job.programs.items()}
    for name, p in job.programs.items():
        for i in np.flatnonzero(p.kind == WAIT):
            for e in p.events[p.event[i]]:
                assert any(e in ev for other, ev in announced.items() if other != name), (name, e)


def test_tool_on_moves_lie_inside_the_robots_own_chunks(job):
    base = float(job.chunked.solid.bounds[0, 2])
    for name, p in job.programs.items():
        seg, chunk, width = _deposits(p)
        own = set(job.chunked.assignment.sequences[name])
        assert {p.chunks[c] for c in np.unique(chunk)} == own
        for ci in np.unique(chunk):
            ch = job.chunked.chunks[p.chunks[ci]]
            slicer = LayerSlicer(ch.vertices, ch.faces)
            pts = seg[chunk == ci].reshape(-1, 3)
            for z in np.unique(pts[:, 2])[::7]:  # every 7th layer
                at = pts[pts[:, 2] == z]
                rings = slicer.rings(np.array([z - 0.5]))[0]  # the layer's middle
                assert _inside(at[:, :2], rings).all(), (name, p.chunks[ci], z)
        assert np.all(seg[:, :, 2] >= base)


def test_extruded_volume_is_the_sum_over_chunks_sliced_alone(job, bundle):
    s = job.chunked.settings.slicing
    base = float(job.chunked.solid.bounds[0, 2])
    alone = 0.0
    for ch in job.chunked.chunks.chunks:
        for layer in iter_layers(ch.as_solid(), s, base=base, workers=1):
            extr = layer.role != 4
            area = flow_area(layer.width[extr], layer.height, layer.role[extr])
            alone += float((area * layer.lengths()[extr]).sum())
    _, record = bundle
    programs = sum(r["stats"]["volume_mm3"] for r in record["robots"])
    assert programs == pytest.approx(alone, rel=1e-3)
    # shells and 20% infill: a good part of the solid, and less than all of it
    assert 0.2 * job.chunked.chunks.volume < programs < job.chunked.chunks.volume


def _clear(material, a, b, robot):
    """The nozzle tip above the material under it, and the printhead body (``nozzle_height`` up,
    ``nozzle_depth`` around) above the material around it, all along a -> b."""
    for t in np.linspace(0, 1, 40):
        q = a + t * (b - a)
        d = np.linalg.norm(material[:, :2] - q[:2], axis=1)
        if not ((material[d < 1.0, 2] <= q[2] + 1e-9).all()
                and (material[d < robot.nozzle_depth, 2] < q[2] + robot.nozzle_height).all()):
            return False
    return True


def test_no_transition_passes_through_printed_material(job):
    """Every tool-off move between chunks clears what is surely printed by then (the robot's own
    earlier paths, and the other robots' chunks it waited for); the moves across at the top of a
    transition clear even everything the other robots may have printed by then (which of their
    paths exist at that instant is the simulator's question)."""
    robot = job.chunked.settings.robot
    deposits = {name: _deposits(p) for name, p in job.programs.items()}
    checked = 0
    for name, p in job.programs.items():
        others_all = np.concatenate([d[0].reshape(-1, 3) for n, d in deposits.items() if n != name])
        mv = np.flatnonzero(p.kind == MOVE)
        tool = p.tool_on()
        for i, j in zip(mv[:-1], mv[1:]):
            if p.chunk[j] >= 0 and p.chunk[i] >= 0 or tool[j]:
                continue  # inside a chunk
            waited = {e for w in np.flatnonzero((p.kind == WAIT)[:j]) for e in p.events[p.event[w]]}
            sure = [_deposits(p, upto=i)[0].reshape(-1, 3)] + [
                seg[np.isin(chunk, [q.chunks.index(c) for c in waited if c in q.chunks])].reshape(-1, 3)
                for n, q in job.programs.items() if n != name for seg, chunk, _ in [deposits[n]]]
            a, b = p.xyz[i], p.xyz[j]
            assert _clear(np.vstack(sure), a, b, robot), (name, i, a, b)
            if a[2] == b[2] and p.chunk[i] < 0 and p.chunk[j] < 0:  # across, at the top
                assert _clear(np.vstack([sure[0], others_all]), a, b, robot), (name, i, a, b)
            checked += 1
    assert checked >= 6


def test_the_bundle_reads_back(job, bundle):
    out, record = bundle
    assert json.loads((out / "job.json").read_text())["format"] == "cooprint-job/2"
    for name, p in job.programs.items():
        assert read_coop(out / "robots" / f"{name}.coop") == p
        # the G-code says the same: its E total is the program's volume / filament area
        e = 0.0
        for line in (out / "robots" / f"{name}.gcode").read_text().splitlines():
            words = line.split(";")[0].split()
            if words[:1] == ["G1"] and any(w[0] in "XY" for w in words[1:]):
                e += sum(float(w[1:]) for w in words[1:] if w[0] == "E")
        stats = next(r for r in record["robots"] if r["name"] == name)["stats"]
        assert e == pytest.approx(stats["filament_mm"], rel=1e-4)
        assert "G28" not in (out / "robots" / f"{name}.gcode").read_text()


def test_same_inputs_give_the_same_bytes(car_stl, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    run(car_stl, a, overrides=COARSE, picture=False)
    run(car_stl, b, overrides=COARSE, picture=False)
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert len(files) >= 7
    for f in files:
        assert (a / f).read_bytes() == (b / f).read_bytes(), f


def test_cli_run_refuses_to_overwrite_and_reports_bad_input(car_stl, tmp_path, capsys):
    out = tmp_path / "job"
    out.mkdir()
    (out / "mine.txt").write_text("keep me")
    assert main(["run", str(car_stl), "--out", str(out), "-q"]) == 2
    assert "not a cooprint bundle" in capsys.readouterr().err
    assert main(["run", str(car_stl), "--out", str(out), "-q", "--force"]) == 2  # --force: only cooprint's own
    assert "--force replaces only cooprint's own outputs" in capsys.readouterr().err
    assert (out / "mine.txt").read_text() == "keep me"
    bad = tmp_path / "bad.toml"
    bad.write_text("[program]\nclearance = -1\n")
    assert main(["run", str(car_stl), "--out", str(tmp_path / "new"), "--config", str(bad), "-q"]) == 2
    err = capsys.readouterr().err
    assert "program.clearance = -1" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "new").exists()


def test_one_robot_prints_everything_without_waiting(car_stl, tmp_path):
    record = run(car_stl, tmp_path / "one", overrides=COARSE, robots=1, picture=False)
    (robot,) = record["robots"]
    assert robot["stats"]["wait"] == 0 and robot["stats"]["notify"] == 0
    assert set(robot["chunks"]) == {c["id"] for c in record["chunks"]}
