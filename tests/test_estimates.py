"""Estimates before the heavy work and progress bars with rates (issue 15 item 5)."""

from __future__ import annotations

import io
import re
import shutil
from pathlib import Path

import pytest

from badinput import assert_rejected
from cooprint.cli import main, stage_progress
from cooprint.config import load_settings
from cooprint.io.bundle import write_stl
from cooprint.io.estimate import JobEstimate, estimate_job, human_bytes
from cooprint.jobs import coop_job, simulate_bundle, write_coop_bundle
from cooprint.models import car
from cooprint.progress import ByteMeter
from solids import box, hollow, to_trimesh

#: The large-nozzle profile (1.0 mm nozzle, 0.6 mm layers, 1.1 mm lines).
LARGE = {"slicing.nozzle_diameter": 1.0, "slicing.layer_height": 0.6, "slicing.first_layer_height": 0.6,
         "slicing.extrusion_width": 1.1}
ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]")


def _stl(folder: Path, name: str, mesh) -> Path:
    path = folder / f"{name}.stl"
    write_stl(path, mesh.vertices, mesh.faces)
    return path


def _bundle_bytes(out: Path) -> int:
    return sum(p.stat().st_size for p in out.rglob("*") if p.is_file())


@pytest.fixture(scope="module")
def parts(tmp_path_factory):
    folder = tmp_path_factory.mktemp("parts")
    return {"box": (_stl(folder, "box", to_trimesh(box(200, 500, 30))), {}),
            "hollow": (_stl(folder, "hollow", to_trimesh(hollow(160, 420, 40, 8))), {}),
            "car": (_stl(folder, "car", car(420.0)), {}),
            "large": (_stl(folder, "large", to_trimesh(box(300, 700, 60))), LARGE)}


@pytest.mark.parametrize("name", ["box", "hollow", "car", "large"])
def test_the_estimate_is_within_a_factor_of_the_real_run(parts, name, tmp_path):
    """A box, a thin-walled hollow box, the curved car and the large-nozzle profile: the
    estimated bundle within 0.67x-1.5x of the bytes written, each robot's commands too, and the
    estimate is made after chunking, before slicing."""
    mesh, overrides = parts[name]
    seen: list[str] = []
    estimates: list[JobEstimate] = []

    def progress(stage, done, total):
        seen.append(stage)

    def on_estimate(est):
        assert "slice" not in seen and "cut" in seen  # after the cuts, before the heavy work
        estimates.append(est)

    job = coop_job(mesh, load_settings(overrides=overrides), 2, progress, on_estimate=on_estimate)
    out = tmp_path / "job"
    write_coop_bundle(job, out, picture=True)
    (est,) = estimates
    real = _bundle_bytes(out)
    assert 0.67 < est.bytes / real < 1.5, (name, est.bytes, real)
    for robot, program in job.programs.items():
        if len(program) > 1000:
            assert 0.67 < est.commands[robot] / len(program) < 1.5, (name, robot)
    assert est.memory_bytes > 100e6 and est.seconds > 0
    assert est.describe().startswith(f"estimate: {human_bytes(est.bytes)} of output (A ")


def test_the_estimate_is_a_function_of_the_chunks_and_settings(parts):
    """Pure: the same chunks give the same estimate; a robot count spreads the commands; finer
    layers mean more commands and bytes; more cores, less time."""
    from cooprint.jobs import chunk_job

    chunked = chunk_job(parts["box"][0], load_settings())
    s = chunked.settings
    seqs = chunked.assignment.sequences
    a, b = estimate_job(chunked.chunks, s, seqs), estimate_job(chunked.chunks, s, seqs)
    assert a.describe() == b.describe() and a.bytes == b.bytes
    even = estimate_job(chunked.chunks, s, 2)
    # each robot's count is rounded: the sums agree to one command a robot
    assert sum(even.commands.values()) == pytest.approx(sum(a.commands.values()), abs=len(even.commands))
    fine = estimate_job(chunked.chunks, load_settings(overrides={"slicing.layer_height": 0.1,
                                                                 "slicing.first_layer_height": 0.1}), seqs)
    assert fine.bytes > 1.6 * a.bytes
    assert estimate_job(chunked.chunks, s, seqs, cores=4).seconds < estimate_job(chunked.chunks, s, seqs,
                                                                                 cores=1).seconds


def test_run_prints_the_estimate_unless_quiet(parts, tmp_path, capsys, monkeypatch):
    """On stdout, first (stderr stays a failed run's one error line)."""
    monkeypatch.delenv("COOPRINT_PROGRESS", raising=False)
    mesh = parts["box"][0]
    assert main(["run", str(mesh), "--out", str(tmp_path / "a")]) == 0
    captured = capsys.readouterr()
    out, err = captured.out, captured.err
    assert out.startswith("estimate: ") and "estimate" not in err
    assert re.search(r"^estimate: [\d.]+ [kMG]B of output \(A [\d.]+ [kMG]B, B [\d.]+ [kMG]B\), about [\d.]+ [kMG]B "
                     r"of memory, about \d+ (s|min|h) on \d cores?$", out, re.M), out
    assert "slicing layers" not in err  # not a terminal: no bars
    assert main(["run", str(mesh), "--out", str(tmp_path / "b"), "-q"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and "estimate" not in captured.out


def test_a_run_whose_estimate_does_not_fit_on_the_disk_is_refused_before_slicing(parts, tmp_path, capsys,
                                                                                  monkeypatch):
    """The free space is above the early check's low estimate (from the mesh file's size) but
    below the run's estimate: refused with one line after chunking, nothing written."""
    mesh = parts["box"][0]
    real = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda p: real._replace(free=2_000_000))
    import cooprint.slicing as slicing

    def no_slicing(*a, **k):
        raise AssertionError("sliced before the refusal")
    monkeypatch.setattr(slicing, "slice_chunks", no_slicing)
    line = assert_rejected(["run", mesh, "--out", tmp_path / "job"], capsys, watch=[tmp_path])
    assert "this run is estimated to write" in line and "only 2.0 MB free" in line
    assert not (tmp_path / "job").exists()


def _bars(console_file: io.StringIO) -> str:
    return ANSI.sub("", console_file.getvalue().replace("\r", "\n"))


def test_every_stage_of_run_and_simulate_has_a_bar_with_rate_and_eta(parts, tmp_path):
    from rich.console import Console

    buf = io.StringIO()
    console = Console(file=buf, force_terminal=True, width=150, color_system=None)
    out = tmp_path / "job"
    with stage_progress(True, console=console) as progress:
        job = coop_job(parts["box"][0], load_settings(), 2, progress)
        write_coop_bundle(job, out, picture=True, progress=progress)
        simulate_bundle(out, progress=progress)
    text = _bars(buf)
    last = {}
    for line in text.splitlines():
        m = re.match(r"(\w[\w ]+?)\s{2,}\S*\s+(\d+)%\s+(\S+ [\w]+/s)\s+(\d+:\d\d:\d\d) eta (\d+:\d\d:\d\d|-:--:--)", line)
        if m:
            last[m.group(1)] = (int(m.group(2)), m.group(3))
    for label, unit in [("reading mesh", "MB/s"), ("cutting chunks", "chunks/s"), ("scheduling", "chunks/s"),
                        ("slicing layers", "layers/s"), ("robot programs", "chunks/s"), ("writing files", "MB/s"),
                        ("drawing picture", "pictures/s"), ("reading programs", "MB/s"), ("timelines", "robots/s"),
                        ("checks", "checks/s"), ("pictures", "pictures/s")]:
        assert label in last, (label, text[-3000:])
        done, rate = last[label]
        assert done == 100 and rate.endswith(unit) and not rate.startswith("-"), (label, rate)
    # the write stage counted the bytes of the files: its rate is the bundle over the stage's time
    mb_s = float(last["writing files"][1].split()[0])
    assert mb_s > 0.5


def test_simulate_draws_its_bars_when_forced_and_none_on_a_pipe(parts, tmp_path, capsys, monkeypatch):
    out = tmp_path / "job"
    assert main(["run", str(parts["box"][0]), "--out", str(out), "-q"]) == 0
    capsys.readouterr()
    monkeypatch.delenv("COOPRINT_PROGRESS", raising=False)
    assert main(["simulate", str(out), "--force"]) == 0
    assert "checks" not in capsys.readouterr().err
    monkeypatch.setenv("COOPRINT_PROGRESS", "1")
    assert main(["simulate", str(out), "--force"]) == 0
    err = ANSI.sub("", capsys.readouterr().err)
    for label in ("reading programs", "timelines", "checks"):
        assert re.search(label + r"\s+\S+\s+100%\s+[\d.]+ \w+/s .* eta ", err), label
    assert main(["render", str(out), "--format", "gif", "--duration", "1", "--fps", "5",
                 "--out", str(tmp_path / "a.gif")]) == 0
    err = ANSI.sub("", capsys.readouterr().err)
    assert re.search(r"animation frames\s+\S+\s+100%\s+[\d.]+ frames/s .* eta ", err), err[-2000:]


def test_the_byte_meter_counts_what_is_written(tmp_path):
    calls = []
    meter = ByteMeter(lambda *a: calls.append(a), total=100, step=10)
    with open(tmp_path / "f.txt", "w") as fh:
        w = meter.wrap(fh)
        for _ in range(7):
            w.write("abcd")  # 4 bytes each
        w.flush()  # passed through
    meter.finish()
    assert (tmp_path / "f.txt").stat().st_size == 28 == meter.done
    assert calls[0] == ("write", 0, 100) and calls[-1] == ("write", 28, 28)
    assert [c[1] for c in calls[1:-1]] == [12, 24]


def test_describe_names_the_largest_robots_of_a_big_fleet():
    est = JobEstimate({f"R{i}": i * 10_000_000 for i in range(1, 11)}, 5_000_000,
                      {f"R{i}": i * 200_000 for i in range(1, 11)}, 3_200_000_000, 5400.0, 4)
    assert est.bytes == 550_000_000 + 5_000_000
    assert est.describe(robots_shown=3) == ("estimate: 555 MB of output (R10 100 MB, R9 90 MB, R8 80 MB, 7 more), "
                                            "about 3.2 GB of memory, about 1.5 h on 4 cores")


def test_a_line_said_while_bars_are_drawn_goes_above_them(capsys):
    """The estimate is said through the progress: on the bars' console when they are drawn (a line
    on stdout would be erased by their next redraw, on a terminal), else on stdout."""
    from rich.console import Console


    buf = io.StringIO()
    with stage_progress(True, console=Console(file=buf, force_terminal=True, width=100)) as progress:
        progress("slice", 1, 4)
        progress.say("estimate: 1 MB of output")
    assert "estimate: 1 MB of output" in _bars(buf)
    assert capsys.readouterr().out == ""
    with stage_progress(False) as progress:
        progress.say("estimate: 2 MB of output")
    assert capsys.readouterr().out == "estimate: 2 MB of output\n"


def test_the_disk_a_run_needs_counts_the_spool_and_compression(parts, tmp_path, monkeypatch):
    """A streamed run spools its chunks' commands beside the bundle until it is complete: the
    free-space check wants both; --compress shrinks the programs' share (COMPRESSED)."""
    from cooprint.errors import OutputError
    from cooprint.io import estimate as est_mod
    from cooprint.jobs import chunk_job

    mesh, overrides = parts["box"]
    chunked = chunk_job(mesh, load_settings(overrides=overrides), 2)
    est = est_mod.estimate_job(chunked.chunks, chunked.settings, chunked.assignment.sequences)
    assert est.spool_bytes == est_mod.PROGRAM_BYTES * sum(est.commands.values()) > 0
    small = est.compressed()
    assert small.chunk_bytes == est.chunk_bytes
    assert sum(small.robot_bytes.values()) == pytest.approx(est_mod.COMPRESSED * sum(est.robot_bytes.values()), rel=1e-3)
    real = shutil.disk_usage(tmp_path)
    free = int((est.bytes + est.spool_bytes / 2))  # room for the bundle, not for the spool beside it
    monkeypatch.setattr(shutil, "disk_usage", lambda p: real._replace(free=free))
    with pytest.raises(OutputError, match="to spool"):
        est_mod.check_room(tmp_path / "job", est)
