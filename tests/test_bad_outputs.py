"""Bad output destinations, for every command that writes: each is refused before any work with
exit 2, one line naming the destination, no traceback, and nothing written, moved or deleted in
the folders involved (the test folder, the input's folder, the bundle simulated or rendered).

Read-only and full file systems are simulated with monkeypatch (the suite may run as root, which
permission bits do not stop); /proc, /sys and /dev/full are the real thing.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import socket
import tempfile
from pathlib import Path

import pytest

from badinput import assert_rejected
from cooprint.cli import main

from solids import box, to_trimesh

COMMANDS = ("chunk", "run", "slice", "simulate", "render")
#: Commands whose --out is a folder (simulate: the folder for sim/), and those whose --out is a file.
FOLDER_COMMANDS = ("chunk", "run", "simulate")
FILE_COMMANDS = ("slice", "render")


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    """A small mesh in its own folder and a planned (not simulated) bundle of it."""
    root = tmp_path_factory.mktemp("outputs")
    (root / "in").mkdir()
    mesh = root / "in" / "part.stl"
    to_trimesh(box(20, 200, 10)).export(mesh)
    bundle = root / "bundle"
    assert main(["run", str(mesh), "--out", str(bundle), "-q", "--no-picture"]) == 0
    return {"mesh": mesh, "bundle": bundle}


def command(cmd: str, dest: object, world: dict, force: bool, mesh: Path | None = None) -> list[object]:
    mesh = mesh or world["mesh"]
    args: list[object] = {
        "chunk": ["chunk", mesh, "--out", dest, "-q", "--no-picture"],
        "run": ["run", mesh, "--out", dest, "-q", "--no-picture"],
        "slice": ["slice", mesh, "--out", dest, "-q"],
        "simulate": ["simulate", world["bundle"], "--out", dest, "-q"],
        "render": ["render", world["bundle"], "--out", dest, "--format", "gantt"],
    }[cmd]
    return args + (["--force"] if force else [])


def _fifo(tmp: Path) -> Path:
    os.mkfifo(tmp / "fifo")
    return tmp / "fifo"


def _socket(tmp: Path) -> Path:
    path = tmp / "sock"
    s = socket.socket(socket.AF_UNIX)
    s.bind(str(path))
    s.close()
    return path


def _dangling(tmp: Path) -> Path:
    (tmp / "dangling").symlink_to(tmp / "nowhere")
    return tmp / "dangling"


def _loop(tmp: Path) -> Path:
    (tmp / "loop").symlink_to(tmp / "loop")
    return tmp / "loop"


def _dangling_above(tmp: Path) -> Path:
    (tmp / "gone").symlink_to(tmp / "nowhere")
    return tmp / "gone" / "out"


def _under_file(tmp: Path) -> Path:
    (tmp / "plain.txt").write_text("a plain file")
    return tmp / "plain.txt" / "out"


def _read_only(tmp: Path, monkeypatch) -> Path:
    def refuse(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(tempfile, "mkstemp", refuse)
    return tmp / "out"


def _no_space(tmp: Path, monkeypatch) -> Path:
    monkeypatch.setattr(shutil, "disk_usage", lambda path: shutil._ntuple_diskusage(10**9, 10**9 - 1000, 1000))
    return tmp / "out"


#: (name, make(tmp, monkeypatch) -> destination, --force, expected words in the line)
COMMON = [
    ("proc", lambda t, m: "/proc/cooprint-test/out", True, "/proc"),
    ("proc-self", lambda t, m: "/proc/self/cooprint-out", False, "/proc"),
    ("sys", lambda t, m: "/sys/cooprint-test", True, "/sys"),
    ("sys-kernel", lambda t, m: "/sys/kernel/cooprint-out", False, "/sys"),
    ("dev-full", lambda t, m: "/dev/full", True, "/dev/full"),
    ("fifo", lambda t, m: _fifo(t), True, "fifo"),
    ("socket", lambda t, m: _socket(t), True, "sock"),
    ("dangling-symlink", lambda t, m: _dangling(t), True, "dangling symlink"),
    ("symlink-loop", lambda t, m: _loop(t), True, "loop"),
    ("dangling-symlink-above", lambda t, m: _dangling_above(t), False, "dangling symlink"),
    ("missing-parent", lambda t, m: t / "missing" / "deeper" / "still" / "out", False, "does not exist"),
    ("parent-is-a-file", lambda t, m: _under_file(t), True, "plain.txt"),
    ("name-too-long", lambda t, m: t / ("x" * 300), False, "File name too long"),
    ("read-only", _read_only, True, "Read-only file system"),
    ("no-space", _no_space, False, "free"),
    ("empty-path", lambda t, m: "", False, None),
]


@pytest.mark.parametrize("cmd", COMMANDS)
@pytest.mark.parametrize("name, make, force, words", COMMON, ids=[c[0] for c in COMMON])
def test_bad_destination_is_refused(cmd, name, make, force, words, world, tmp_path, capsys, monkeypatch):
    dest = make(tmp_path, monkeypatch)
    line = assert_rejected(command(cmd, dest, world, force), capsys,
                           watch=[tmp_path, world["mesh"].parent, world["bundle"]])
    if words:
        assert words in line, line
    if str(dest).startswith("/dev/"):
        assert not Path(dest).is_file()  # the device node is still a device node


def _plain_file(tmp: Path) -> Path:
    (tmp / "plain.txt").write_text("mine")
    return tmp / "plain.txt"


def _not_a_bundle(tmp: Path) -> Path:
    (tmp / "mine").mkdir()
    (tmp / "mine" / "notes.txt").write_text("mine")
    return tmp / "mine"


def _bundle_copy(tmp: Path, world: dict) -> Path:
    return Path(shutil.copytree(world["bundle"], tmp / "job"))


def _job_json(tmp: Path, content: str | None) -> Path:
    d = tmp / "other"
    d.mkdir()
    (d / "chunks").mkdir()
    (d / "chunks" / "C.stl").write_text("solid mine\nendsolid mine\n")
    if content is None:
        os.mkfifo(d / "job.json")  # must not block the check
    else:
        (d / "job.json").write_text(content)
    return d


def _file_where_folder(tmp: Path, world: dict, name: str) -> Path:
    job = _bundle_copy(tmp, world)
    shutil.rmtree(job / name, ignore_errors=True)
    (job / name).write_text("mine")
    return job


def _linked(tmp: Path, world: dict, name: str) -> Path:
    """A bundle whose own entry ``name`` (a folder or a file) is a symlink to a copy elsewhere:
    writing the bundle must not change the copy (the test folder is watched)."""
    job = _bundle_copy(tmp, world)
    (tmp / "elsewhere").mkdir()
    away = tmp / "elsewhere" / Path(name).name
    if (job / name).is_dir():
        shutil.copytree(job / name, away)
        shutil.rmtree(job / name)
    else:
        shutil.copy(job / name, away)
        (job / name).unlink()
    (job / name).symlink_to(away)
    return job


#: Folder destinations of `chunk` and `run`: (name, make(tmp, world) -> (destination, mesh or None), --force, words)
PLAN = [
    ("file-where-folder-belongs", lambda t, w: (_plain_file(t), None), True, "plain.txt"),
    ("not-a-bundle", lambda t, w: (_not_a_bundle(t), None), False, "not a cooprint bundle"),
    ("not-a-bundle-force", lambda t, w: (_not_a_bundle(t), None), True, "replaces only cooprint's own outputs"),
    ("job-json-other-format", lambda t, w: (_job_json(t, '{"format": "other/1"}'), None), True, "not a cooprint bundle"),
    ("job-json-a-list", lambda t, w: (_job_json(t, '["cooprint-job/2"]'), None), True, "not a cooprint bundle"),
    ("job-json-not-json", lambda t, w: (_job_json(t, "cooprint-job/2"), None), True, "not a cooprint bundle"),
    ("job-json-a-fifo", lambda t, w: (_job_json(t, None), None), True, "not a cooprint bundle"),
    ("bundle-without-force", lambda t, w: (_bundle_copy(t, w), None), False, "use --force"),
    ("chunks-is-a-file", lambda t, w: (_file_where_folder(t, w, "chunks"), None), True, "chunks: a file where"),
    ("robots-is-a-file", lambda t, w: (_file_where_folder(t, w, "robots"), None), True, "robots: a file where"),
    ("sim-is-a-file", lambda t, w: (_file_where_folder(t, w, "sim"), None), True, "sim: a file where"),
    ("chunks-is-a-symlink", lambda t, w: (_linked(t, w, "chunks"), None), True, "chunks: is a symlink"),
    ("robots-is-a-symlink", lambda t, w: (_linked(t, w, "robots"), None), True, "robots: is a symlink"),
    ("job-json-is-a-symlink", lambda t, w: (_linked(t, w, "job.json"), None), True, "job.json: is a symlink"),
    ("a-program-is-a-symlink", lambda t, w: (_linked(t, w, "robots/A.coop"), None), True, "A.coop: is a symlink"),
    ("input-folder-force", lambda t, w: (w["mesh"].parent, None), True, "an input of this command"),
    ("input-inside-bundle", lambda t, w: (_bundle_copy(t, w), "copy"), True, "an input of this command"),
]


@pytest.mark.parametrize("cmd", ("chunk", "run"))
@pytest.mark.parametrize("name, make, force, words", PLAN, ids=[c[0] for c in PLAN])
def test_bad_bundle_folder_is_refused(cmd, name, make, force, words, world, tmp_path, capsys):
    dest, mesh = make(tmp_path, world)
    if mesh == "copy":  # the input given on the command line lies in the bundle
        mesh = dest / "part.stl"
        shutil.copy(world["mesh"], mesh)
    line = assert_rejected(command(cmd, dest, world, force, mesh), capsys,
                           watch=[tmp_path, world["mesh"].parent, world["bundle"]])
    assert words in line, line


def _sim_file(tmp: Path, world: dict, kind: str) -> Path:
    job = _bundle_copy(tmp, world)
    sim = job / "sim"
    if kind == "sim-file":
        sim.write_text("mine")
        return job
    sim.mkdir()
    target = sim / "summary.json"
    if kind == "user-summary":
        target.write_text('{"mine": true}')
    elif kind == "summary-folder":
        target.mkdir()
    elif kind == "summary-fifo":
        os.mkfifo(target)
    elif kind == "summary-symlink":
        (tmp / "away.json").write_text('{"format": "cooprint-sim/1"}')
        target.symlink_to(tmp / "away.json")
    elif kind == "sim-symlink":
        sim.rmdir()
        (tmp / "away").mkdir()
        sim.symlink_to(tmp / "away")
    return job


#: `simulate` and `render` where their derived outputs belong: (name, args(job), words)
DERIVED = [
    ("simulate-sim-is-a-file", "sim-file", lambda j: ["simulate", j, "-q"], "not a folder"),
    ("simulate-sim-is-a-file-force", "sim-file", lambda j: ["simulate", j, "-q", "--force"], "not a folder"),
    ("render-sim-is-a-file", "sim-file", lambda j: ["render", j, "--format", "gantt"], "not a folder"),
    ("render-sim-is-a-file-force", "sim-file", lambda j: ["render", j, "--force"], "not a folder"),
    ("simulate-user-summary", "user-summary", lambda j: ["simulate", j, "-q"], "use --force"),
    ("simulate-summary-is-a-folder", "summary-folder", lambda j: ["simulate", j, "-q", "--force"], "is a folder"),
    ("simulate-summary-is-a-fifo", "summary-fifo", lambda j: ["simulate", j, "-q", "--force"], "FIFO"),
    ("simulate-sim-is-a-symlink", "sim-symlink", lambda j: ["simulate", j, "-q", "--force"], "sim: is a symlink"),
    ("render-sim-is-a-symlink", "sim-symlink", lambda j: ["render", j, "--format", "gantt"], "sim: is a symlink"),
    ("simulate-summary-is-a-symlink", "summary-symlink", lambda j: ["simulate", j, "-q"], "summary.json: is a symlink"),
    ("render-into-job-json", "none", lambda j: ["render", j, "--out", j / "job.json", "--force"], "part of the cooprint bundle"),
    ("render-into-a-program", "none", lambda j: ["render", j, "--out", j / "robots" / "A.gcode", "--force"],
     "part of the cooprint bundle"),
    ("slice-into-a-chunk", "none", lambda j: ["slice", j / "chunks" / "C.stl", "--out", j / "chunks" / "C.stl", "--force"],
     "an input of this command"),
]


@pytest.mark.parametrize("name, kind, args, words", DERIVED, ids=[c[0] for c in DERIVED])
def test_bad_derived_destination_is_refused(name, kind, args, words, world, tmp_path, capsys):
    job = _sim_file(tmp_path, world, kind)
    line = assert_rejected(args(job), capsys, watch=[tmp_path, world["bundle"]])
    assert words in line, line


#: File destinations of `slice` and `render`: (name, make(tmp, world) -> destination, --force, words)
FILES = [
    ("folder-where-file-belongs", lambda t, w: t, True, "directory"),  # click's own check, one line too
    ("users-file-without-force", lambda t, w: _plain_file(t), False, "use --force"),
    ("a-bundles-own-file", lambda t, w: _bundle_copy(t, w) / "chunks" / "C.stl", True, "part of the cooprint bundle"),
    ("a-bundles-marker", lambda t, w: _bundle_copy(t, w) / "job.json", True, "part of the cooprint bundle"),
]


@pytest.mark.parametrize("cmd", FILE_COMMANDS)
@pytest.mark.parametrize("name, make, force, words", FILES, ids=[c[0] for c in FILES])
def test_bad_file_destination_is_refused(cmd, name, make, force, words, world, tmp_path, capsys):
    dest = make(tmp_path, world)
    line = assert_rejected(command(cmd, dest, world, force), capsys,
                           watch=[tmp_path, world["mesh"].parent, world["bundle"]])
    assert words in line, line


def test_slice_onto_its_own_input_is_refused(world, tmp_path, capsys):
    mesh = Path(shutil.copy(world["mesh"], tmp_path / "part.stl"))
    line = assert_rejected(["slice", mesh, "--out", mesh, "--force", "-q"], capsys, watch=[tmp_path])
    assert "an input of this command" in line


def test_a_bundle_is_recognised_by_its_marker_only(world, tmp_path):
    from cooprint.io.bundle import is_bundle, is_derived_output

    assert is_bundle(world["bundle"])
    assert json.loads((world["bundle"] / "job.json").read_text())["format"].startswith("cooprint-job/")
    plain = tmp_path / "plain"
    (plain / "chunks").mkdir(parents=True)
    (plain / "job.json").write_text('{"format": "cooprint-sim/1"}')
    assert not is_bundle(plain) and not is_bundle(tmp_path)
    assert is_derived_output(world["bundle"] / "sim" / "gantt.png")
    assert not is_derived_output(world["bundle"] / "sim" / "notes.png")
    assert not is_derived_output(tmp_path / "sim" / "summary.json")


def test_a_line_break_in_the_mesh_name_stays_in_the_comment(world, tmp_path, capsys):
    """A file name holding newlines (and a Unicode line separator) is escaped in the G-code and
    .coop headers: no live G28/M104 line appears, and cooprint simulates its own bundle."""
    evil = tmp_path / "evil\nG28 X0\nM104 S999\u2028M84 é.stl"
    shutil.copy(world["mesh"], evil)
    gcode, bundle = tmp_path / "part.gcode", tmp_path / "bundle"
    assert main(["slice", str(evil), "--out", str(gcode), "-q"]) == 0
    assert main(["run", str(evil), "--out", str(bundle), "-q", "--no-picture"]) == 0
    for f in [gcode, *sorted((bundle / "robots").iterdir())]:
        text = f.read_text(encoding="utf-8")
        assert "\u2028" not in text and "\x85" not in text
        lines = text.splitlines()
        assert not any(ln.startswith(("G28 X0", "M104 S999", "M84 ")) for ln in lines), f
        assert any("evil\\nG28 X0\\nM104 S999" in ln and ln.startswith(";") for ln in lines), f
    capsys.readouterr()
    assert main(["simulate", str(bundle), "-q"]) == 0


@pytest.mark.parametrize("text, ascii_only, expected", [
    ("a\nb\rc\td", False, "a\\nb\\rc\\td"),
    ("x\x85y\u2028z\u2029w\x1b\x00\x7f", False, "x\\x85y\\u2028z\\u2029w\\x1b\\x00\\x7f"),
    ("pièce", False, "pièce"), ("pièce", True, "pi\\xe8ce"), ("\U0001f600", True, "\\U0001f600"),
])
def test_comment_safe_leaves_one_visible_line(text, ascii_only, expected):
    from cooprint.program.comment import COMMENT_LIMIT, comment_safe

    assert comment_safe(text, ascii_only=ascii_only) == expected
    long = comment_safe("\n" * 5000)
    assert len(long) == COMMENT_LIMIT and long.endswith("...") and "\n" not in long
