"""Outputs a user can trust: ``--force`` replaces only cooprint's own files, derived outputs are
rewritten without it, a failed write leaves everything as it was, and Ctrl-C leaves no process
and no temporary file behind (issue 12, deliverables 1, 7 and 8)."""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from badinput import assert_rejected
from cooprint.cli import main

from solids import ball, box, to_trimesh

SRC = Path(__file__).resolve().parents[1] / "src"


def cli(args, capsys):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def contents(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (hidden ones too) with its bytes."""
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def hidden(*folders: Path) -> list[str]:
    """Hidden entries (cooprint's temporary files and folders are hidden) in ``folders``."""
    return [str(p) for f in folders if f.is_dir() for p in f.rglob(".*")]


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    root = tmp_path_factory.mktemp("meshes")
    to_trimesh(box(20, 420, 10)).export(root / "spot.stl")
    to_trimesh(box(20, 640, 12)).export(root / "other.stl")  # another plan: other chunks
    return root


@pytest.fixture(scope="module")
def planned(meshes, tmp_path_factory):
    """A `cooprint run` bundle (not simulated), to copy."""
    out = tmp_path_factory.mktemp("planned") / "job"
    assert main(["run", str(meshes / "spot.stl"), "--out", str(out), "-q", "--no-picture"]) == 0
    return out


def test_force_keeps_the_input_mesh_and_the_users_notes(meshes, tmp_path, capsys, monkeypatch):
    # the case: `cooprint chunk spot.stl --out DIR --force` with spot.stl and notes.txt in DIR
    monkeypatch.chdir(tmp_path)
    shutil.copy(meshes / "spot.stl", "spot.stl")
    assert cli(["chunk", "spot.stl", "--out", "DIR", "-q", "--no-picture"], capsys)[0] == 0
    shutil.copy(meshes / "spot.stl", "DIR/spot.stl")
    Path("DIR/notes.txt").write_text("my notes")
    before = json.loads(Path("DIR/job.json").read_text())
    code, _, err = cli(["chunk", "spot.stl", "--out", "DIR", "-q", "--force", "--theta", "70"], capsys)
    assert code == 0, err
    assert Path("DIR/notes.txt").read_text() == "my notes"
    assert Path("DIR/spot.stl").read_bytes() == (meshes / "spot.stl").read_bytes()
    assert err.strip() == "cooprint: kept 2 files that cooprint did not write: notes.txt, spot.stl"
    after = json.loads(Path("DIR/job.json").read_text())
    assert after["plan"]["theta_deg"] == 70.0 != before["plan"]["theta_deg"]
    assert Path("DIR/chunks.png").is_file()
    assert hidden(tmp_path) == []


def test_force_refuses_a_folder_that_is_not_a_bundle_or_holds_the_input(meshes, tmp_path, capsys):
    folder = tmp_path / "DIR"
    folder.mkdir()
    shutil.copy(meshes / "spot.stl", folder / "spot.stl")
    (folder / "notes.txt").write_text("my notes")
    line = assert_rejected(["chunk", meshes / "spot.stl", "--out", folder, "-q", "--force"], capsys, watch=[tmp_path])
    assert "not a cooprint bundle" in line
    # a bundle, but the mesh given on the command line is in it
    assert cli(["chunk", meshes / "spot.stl", "--out", tmp_path / "job", "-q", "--no-picture"], capsys)[0] == 0
    shutil.copy(meshes / "spot.stl", tmp_path / "job" / "spot.stl")
    line = assert_rejected(["chunk", tmp_path / "job" / "spot.stl", "--out", tmp_path / "job", "-q", "--force"],
                           capsys, watch=[tmp_path])
    assert "spot.stl, an input of this command" in line


def test_force_removes_stale_cooprint_files_and_keeps_the_rest(meshes, planned, tmp_path, capsys):
    job = Path(shutil.copytree(planned, tmp_path / "job"))
    shutil.copy(job / "chunks" / "R1.stl", job / "chunks" / "R7.stl")  # a chunk of an older plan
    (job / "chunks" / "readme.txt").write_text("mine")
    (job / "robots" / "notes.txt").write_text("mine")
    (job / "sim").mkdir()
    (job / "sim" / "summary.json").write_text('{"format": "cooprint-sim/1"}')
    (job / "sim" / "gantt.png").write_bytes(b"old")
    (job / "sim" / "mine.png").write_bytes(b"mine")
    code, _, err = cli(["chunk", meshes / "other.stl", "--out", job, "-q", "--force", "--no-picture"], capsys)
    assert code == 0, err
    record = json.loads((job / "job.json").read_text())
    assert record["format"] == "cooprint-job/1"
    assert sorted(p.name for p in (job / "chunks").iterdir()) == sorted(
        [Path(r["file"]).name for r in record["chunks"]] + ["readme.txt"])
    assert sorted(p.name for p in (job / "robots").iterdir()) == ["notes.txt"]  # the programs of the old plan went
    assert sorted(p.name for p in (job / "sim").iterdir()) == ["mine.png"]  # so did its simulation
    assert "kept 3 files that cooprint did not write: chunks/readme.txt, robots/notes.txt, sim/mine.png" in err
    assert hidden(tmp_path) == []
    # and from a `chunk` bundle back to a `run` bundle, empty folders of stale files go
    (job / "robots" / "notes.txt").unlink()
    assert cli(["chunk", meshes / "spot.stl", "--out", job, "-q", "--force", "--no-picture"], capsys)[0] == 0
    assert not (job / "robots").exists()


def test_out_dot_works_in_an_empty_folder_and_in_a_bundle(meshes, tmp_path, capsys, monkeypatch):
    here = tmp_path / "here"
    here.mkdir()
    monkeypatch.chdir(here)
    code, _, err = cli(["chunk", meshes / "spot.stl", "--out", ".", "-q"], capsys)
    assert code == 0, err
    first = contents(here)
    assert "job.json" in first and "chunks.png" in first
    assert cli(["chunk", meshes / "spot.stl", "--out", ".", "-q"], capsys)[0] == 2  # a bundle: needs --force
    code, _, err = cli(["run", meshes / "other.stl", "--out", ".", "-q", "--force"], capsys)
    assert code == 0, err
    assert err == ""  # nothing of the user's to report
    assert json.loads(Path("job.json").read_text())["format"] == "cooprint-job/2"
    assert Path("robots/A.coop").is_file() and Path.cwd() == here and here.is_dir()
    assert sorted(os.listdir(tmp_path)) == ["here"]  # no `..XXXX.old` beside it
    assert hidden(here) == []


def _fail_on(n: int, real, err: int = errno.ENOSPC):
    """``real`` that raises OSError(err) on its ``n``-th call."""
    calls = [0]

    def wrapped(*args, **kwargs):
        calls[0] += 1
        if calls[0] == n:
            raise OSError(err, os.strerror(err), str(args[0]) if args else None)
        return real(*args, **kwargs)

    return wrapped


def test_a_full_disk_while_writing_leaves_nothing(meshes, planned, tmp_path, capsys, monkeypatch):
    import cooprint.jobs

    monkeypatch.setattr(cooprint.jobs, "write_stl", _fail_on(2, cooprint.jobs.write_stl))
    line = assert_rejected(["chunk", meshes / "spot.stl", "--out", tmp_path / "new", "-q"], capsys, watch=[tmp_path])
    assert "new: the disk is full (no space left on device) while writing chunks/" in line  # (issue 15)
    assert line.endswith(".stl; nothing was written")
    assert os.listdir(tmp_path) == []
    # an existing bundle replaced with --force: the old one stays as it was
    job = Path(shutil.copytree(planned, tmp_path / "job"))
    (job / "notes.txt").write_text("mine")
    before = contents(job)
    monkeypatch.setattr(cooprint.jobs, "write_stl", _fail_on(1, cooprint.jobs.write_stl, errno.EROFS))
    line = assert_rejected(["chunk", meshes / "other.stl", "--out", job, "-q", "--force"], capsys, watch=[job])
    assert "Read-only file system (EROFS)" in line
    assert contents(job) == before and hidden(tmp_path) == []


@pytest.mark.parametrize("n", [1, 3, 9])
def test_a_failure_during_the_swap_puts_the_old_bundle_back(meshes, planned, tmp_path, capsys, monkeypatch, n):
    job = Path(shutil.copytree(planned, tmp_path / "job"))
    (job / "notes.txt").write_text("mine")
    before = contents(job)
    real = os.replace
    calls = [0]

    def flaky(src, dst, *args, **kwargs):  # the swap's n-th rename fails
        if ".cooprint." in str(src) or ".cooprint." in str(dst):
            calls[0] += 1
            if calls[0] == n:
                raise OSError(errno.EIO, "Input/output error", str(dst))
        return real(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "replace", flaky)
    line = assert_rejected(["chunk", meshes / "other.stl", "--out", job, "-q", "--force", "--no-picture"], capsys,
                           watch=[])
    assert "Input/output error (EIO)" in line
    assert contents(job) == before and hidden(tmp_path) == []


def test_slice_write_failure_and_special_files(meshes, tmp_path, capsys, monkeypatch):
    import cooprint.program.gcode

    out = tmp_path / "part.gcode"
    out.write_text("; my old G-code\n")

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(cooprint.program.gcode, "write_gcode", read_only)
    line = assert_rejected(["slice", meshes / "spot.stl", "--out", out, "-q", "--force"], capsys, watch=[tmp_path])
    assert line.endswith("part.gcode: cannot write: Read-only file system (EROFS)")
    assert out.read_text() == "; my old G-code\n" and hidden(tmp_path) == []
    monkeypatch.undo()
    # /dev/full stays a device node, even with --force
    line = assert_rejected(["slice", meshes / "spot.stl", "--out", "/dev/full", "-q", "--force"], capsys)
    assert "character device" in line and Path("/dev/full").is_char_device()


def test_a_write_failure_mid_slice_stops_the_workers(tmp_path, capsys, monkeypatch):
    import multiprocessing

    import cooprint.program.gcode

    mesh = tmp_path / "tall.stl"
    to_trimesh(box(20, 20, 40)).export(mesh)  # 200 layers: 4 blocks, sliced by worker processes
    real = cooprint.program.gcode.write_gcode
    from cooprint.program.build import LAYERS_PER_PIECE

    def fails_after_a_while(fh, pieces, *args, **kwargs):
        def some(pieces):
            for k, piece in enumerate(pieces):
                if k == 60 // LAYERS_PER_PIECE:  # ~60 layers written, later blocks still slicing
                    raise OSError(errno.ENOSPC, "No space left on device")
                yield piece
        return real(fh, some(pieces), *args, **kwargs)

    monkeypatch.setattr(cooprint.program.gcode, "write_gcode", fails_after_a_while)
    before = {p.pid for p in multiprocessing.active_children()}  # an earlier test's, not this slice's
    line = assert_rejected(["slice", mesh, "--out", tmp_path / "tall.gcode", "-q"], capsys, watch=[])
    assert "tall.gcode: the disk is full (no space left on device); nothing was written" in line
    assert [p for p in multiprocessing.active_children() if p.pid not in before] == []
    assert sorted(os.listdir(tmp_path)) == ["tall.stl"]


def test_simulate_and_render_rewrite_their_own_outputs_without_force(planned, tmp_path, capsys):
    job = Path(shutil.copytree(planned, tmp_path / "job"))
    # render on a bundle not yet simulated makes sim/
    code, out, err = cli(["render", job, "--format", "gantt"], capsys)
    assert code == 0, err
    assert (job / "sim" / "gantt.png").is_file()
    assert cli(["render", job, "--format", "gantt"], capsys)[0] == 0  # again: cooprint's own picture
    (job / "sim" / "notes.txt").write_text("mine")
    for _ in range(2):
        code, _, err = cli(["simulate", job, "-q", "--frames", "600"], capsys)
        assert code == 0, err
    assert json.loads((job / "sim" / "summary.json").read_text())["format"].startswith("cooprint-sim/")
    assert (job / "sim" / "frames.npz").is_file() and (job / "sim" / "notes.txt").read_text() == "mine"
    # a user's file named by --out is replaced only with --force
    mine = tmp_path / "picture.png"
    mine.write_bytes(b"my picture")
    line = assert_rejected(["render", job, "--format", "gantt", "--out", mine], capsys, watch=[tmp_path])
    assert "use --force" in line
    assert cli(["render", job, "--format", "gantt", "--out", mine, "--force"], capsys)[0] == 0
    assert mine.read_bytes()[:4] == b"\x89PNG"
    # files simulated into a folder of their own: the second run replaces cooprint's summary
    other = tmp_path / "other"
    for _ in range(2):
        assert cli(["simulate", job / "robots" / "A.gcode", "--out", other, "-q"], capsys)[0] == 0
    assert hidden(tmp_path) == []


def test_a_failed_summary_write_leaves_no_sim_folder(planned, tmp_path, capsys, monkeypatch):
    import cooprint.io.bundle

    job = Path(shutil.copytree(planned, tmp_path / "job"))
    before = contents(job)
    monkeypatch.setattr(cooprint.io.bundle, "write_json", _fail_on(1, cooprint.io.bundle.write_json))
    # written and removed again: the folder's times change, its contents do not
    line = assert_rejected(["simulate", job, "-q"], capsys)
    assert "summary.json: the disk is full (no space left on device); nothing was written" in line
    assert not (job / "sim").exists() and contents(job) == before and hidden(tmp_path) == []


def test_simulate_bundle_keeps_the_users_files_in_sim(planned, tmp_path, capsys):
    from cooprint.jobs import simulate_bundle

    job = Path(shutil.copytree(planned, tmp_path / "job"))
    simulate_bundle(job)
    (job / "sim" / "notes.txt").write_text("mine")
    (job / "sim" / "snapshot.png").write_bytes(b"old")
    simulate_bundle(job)
    assert (job / "sim" / "notes.txt").read_text() == "mine"
    assert (job / "sim" / "snapshot.png").read_bytes()[:4] == b"\x89PNG"
    assert "kept 1 file that cooprint did not write: sim/notes.txt" in capsys.readouterr().err
    assert hidden(tmp_path) == []


# --- Ctrl-C ------------------------------------------------------------------------------------

def _gone(pgid: int, wait: float = 3.0) -> bool:
    """Whether every process of the group (session) ``pgid`` has ended (zombies count as there:
    a worker its parent did not reap)."""
    end = time.monotonic() + wait
    while time.monotonic() < end:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def test_ctrl_c_leaves_no_process_and_no_temporary_file(tmp_path):
    """`slice` and `run` (both slice with a pool of worker processes) interrupted at spread
    moments, the signal sent to the process alone or to its whole group as a terminal does:
    exit 130 and one line (or 0 if it had finished), no process of it left, nothing hidden or
    half-written beside the outputs."""
    # every layer a different section (prismatic parts slice from their first layers' work: ~1 s)
    to_trimesh(ball(100)).export(tmp_path / "ball.stl")  # 1000 layers: ~3.4 s to slice
    to_trimesh(ball(80)).export(tmp_path / "small_ball.stl")  # ~5 s to plan
    env = dict(os.environ, PYTHONPATH=str(SRC) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    delays = [0.4, 0.7, 1.0, 1.5, 2.1, 2.9, 4.0, 5.5]  # from 0.4 s: Python itself is up
    outcomes = []
    for k, delay in enumerate(delays):
        procs = {}
        for cmd, args in (("slice", ["ball.stl", "--out", f"s{k}.gcode", "-q"]),
                          ("run", ["small_ball.stl", "--out", f"r{k}", "-q", "--no-picture"])):
            procs[cmd] = subprocess.Popen(
                [sys.executable, "-m", "cooprint", cmd, *args], cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
        time.sleep(delay)
        for p in procs.values():
            try:
                (os.killpg if k % 2 else os.kill)(p.pid, signal.SIGINT)
            except ProcessLookupError:
                pass
        for cmd, p in procs.items():
            _, err = p.communicate(timeout=60)
            err = err.decode()
            outcomes.append((cmd, delay, p.returncode))
            assert p.returncode in (0, 130), (cmd, delay, p.returncode, err[-2000:])
            assert "Traceback" not in err and "Exception" not in err, err[-2000:]
            if p.returncode == 130:
                assert [ln for ln in err.splitlines() if ln.strip()] == ["cooprint: interrupted"], err
            assert _gone(p.pid), f"{cmd} interrupted after {delay} s left processes running"
        assert hidden(tmp_path) == [], hidden(tmp_path)
        for cmd, code in ((c, p.returncode) for c, p in procs.items()):
            out = tmp_path / (f"s{k}.gcode" if cmd == "slice" else f"r{k}")
            if code == 0:
                assert out.exists(), (cmd, delay)
            if out.exists():  # whole (a Ctrl-C just after the final rename still exits 130) or not at all
                if cmd == "run":
                    assert json.loads((out / "job.json").read_text())["format"].startswith("cooprint-job/")
                else:
                    assert out.stat().st_size > 0
    assert sum(code == 130 for _, _, code in outcomes) >= len(outcomes) // 2, outcomes


def test_an_mp4_is_written_quietly(planned, tmp_path, capfd):
    """ffmpeg's own output (a warning for a 2-frame video) never reaches the terminal."""
    out = tmp_path / "short.mp4"
    assert main(["render", str(planned), "--format", "mp4", "--duration", "0.5", "--fps", "4", "--out", str(out)]) == 0
    captured = capfd.readouterr()
    assert captured.err == "" and f"wrote {out}" in captured.out
    assert out.stat().st_size > 0 and os.listdir(tmp_path) == ["short.mp4"]


FFMPEG_FAILURES = [  # (what the fake ffmpeg says last, the one line expected)
    ("av_interleaved_write_frame(): No space left on device",
     "a.mp4: the disk is full (no space left on device); nothing was written"),
    ("Unknown encoder 'libx264'", "a.mp4: cannot write: ffmpeg failed (exit 1): Unknown encoder 'libx264'"),
]


@pytest.mark.parametrize("said, expected", FFMPEG_FAILURES, ids=["full-disk", "no-encoder"])
def test_an_mp4_that_ffmpeg_cannot_write_is_one_line(planned, tmp_path, capfd, monkeypatch, said, expected):
    """ffmpeg failing (a full disk, faked by an ffmpeg that prints six lines and stops) is one
    line naming the file and ffmpeg's reason; nothing is left behind, nothing reaches stderr else."""
    import imageio_ffmpeg

    fake = tmp_path / "bin" / "ffmpeg"
    fake.parent.mkdir()
    fake.write_text("#!/bin/sh\nfor i in 1 2 3 4 5; do echo \"ffmpeg line $i\" >&2; done\n"
                    f"echo \"{said}\" >&2\nexit 1\n")
    fake.chmod(0o755)
    monkeypatch.setattr(imageio_ffmpeg, "get_ffmpeg_exe", lambda: str(fake))
    (tmp_path / "out").mkdir()
    code = main(["render", str(planned), "--format", "mp4", "--duration", "2", "--out", str(tmp_path / "out" / "a.mp4")])
    err = capfd.readouterr().err
    assert code == 2 and err.splitlines() == [f"cooprint: error: {tmp_path / 'out'}/{expected}"], err
    assert os.listdir(tmp_path / "out") == []


def test_ctrl_c_waits_for_numba_to_compile():
    """While numba compiles a kernel (its compiler lock held), SIGINT is blocked in the main
    thread (a KeyboardInterrupt inside the compiler left a half-made function: a segmentation
    fault instead of exit 130); after it, it is not."""
    import numba
    from numba.core import event

    from cooprint.interrupts import hold_compiles

    hold_compiles()
    seen = []

    class Watch(event.Listener):
        def on_start(self, ev):
            seen.append(signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, set()))

        def on_end(self, ev):
            pass

    watch = Watch()
    event.register("numba:compile", watch)
    try:
        numba.njit(lambda x: x * 3 + 1)(2)  # a new function: compiled now
    finally:
        event.unregister("numba:compile", watch)
    assert seen and all(seen)
    assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, set())
