import json
import subprocess
import sys

import numpy as np
import pytest
import trimesh
from PIL import Image

from cooprint.cli import main
from cooprint.jobs import run_chunk
from cooprint.render.palette import robot_colours

from solids import car, to_trimesh


@pytest.fixture(scope="module")
def car_stl(tmp_path_factory):
    p = tmp_path_factory.mktemp("mesh") / "car.stl"
    to_trimesh(car(600)).export(p)
    return p


def run_cli(args, capsys):
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_chunk_writes_the_bundle(tmp_path, car_stl, capsys):
    out = tmp_path / "job"
    code, stdout, _ = run_cli(["chunk", car_stl, "--out", out, "--theta", "60", "--shift", "120"], capsys)
    assert code == 0
    assert "robot A: C -> L1 -> L2" in stdout and "robot B: R1 -> R2" in stdout
    job = json.loads((out / "job.json").read_text())
    assert job["plan"]["theta_deg"] == 60.0 and job["plan"]["shift_mm"] == 120.0
    assert job["stats"]["volume_rel_error"] < 1e-9
    total = 0.0
    for row in job["chunks"]:
        assert set(row) >= {"id", "role", "robot", "order", "deps", "volume_mm3", "bbox", "planes", "file"}
        tm = trimesh.load(out / row["file"])
        assert tm.is_watertight
        assert tm.volume == pytest.approx(row["volume_mm3"], rel=1e-5)  # float32 STL
        for p in row["planes"]:
            d = (np.asarray(tm.vertices) - p["point"]) @ np.asarray(p["normal"])
            assert d.max() < 1e-3
        assert row["reach_mm"] <= job["settings"]["robot"]["build_depth"]
        total += row["volume_mm3"]
    assert total == pytest.approx(job["mesh"]["volume_mm3"], rel=1e-9)
    c = next(r for r in job["chunks"] if r["id"] == "C")
    assert c["robot"] == "A" and c["order"] == 0 and c["deps"] == []
    assert job["schedule"]["sync"] == [{"after": "C", "before": "R1"}]
    img = np.asarray(Image.open(out / "chunks.png").convert("RGB")).astype(int)
    assert img.shape == (800, 1200, 3)
    # drawn by robot as `run` draws it: each robot's legend swatch (16 x 16) in its colour
    for name, colour in robot_colours([r["name"] for r in job["robots"]]).items():
        assert (np.abs(img[:100] - colour).sum(axis=-1) == 0).sum() >= 200, name


def test_same_input_gives_identical_bundle(tmp_path, car_stl):
    a = run_chunk(car_stl, tmp_path / "a", overrides={"chunking.shift": 150.0}, picture=False)
    b = run_chunk(car_stl, tmp_path / "b", overrides={"chunking.shift": 150.0}, picture=False)
    assert a["chunks"] == b["chunks"]
    for row in a["chunks"]:
        assert (tmp_path / "a" / row["file"]).read_bytes() == (tmp_path / "b" / row["file"]).read_bytes()
    assert (tmp_path / "a/job.json").read_text().replace("/a", "/b") == \
        (tmp_path / "b/job.json").read_text().replace("/a", "/b")


def test_existing_output_is_kept_unless_force(tmp_path, car_stl, capsys):
    out = tmp_path / "job"
    out.mkdir()
    (out / "mine.txt").write_text("precious")
    code, _, err = run_cli(["chunk", car_stl, "--out", out, "-q"], capsys)
    assert code == 2 and "not a cooprint bundle" in err
    assert (out / "mine.txt").read_text() == "precious"
    # --force replaces only cooprint's own outputs: a folder that is not a bundle is refused
    code, _, err = run_cli(["chunk", car_stl, "--out", out, "-q", "--force", "--no-picture"], capsys)
    assert code == 2 and "--force replaces only cooprint's own outputs" in err
    assert sorted(p.name for p in out.iterdir()) == ["mine.txt"]
    # a bundle: refused without --force, replaced with it, the user's file kept
    (out / "mine.txt").unlink()
    assert run_cli(["chunk", car_stl, "--out", out, "-q", "--no-picture"], capsys)[0] == 0
    (out / "mine.txt").write_text("precious")
    code, _, err = run_cli(["chunk", car_stl, "--out", out, "-q", "--no-picture"], capsys)
    assert code == 2 and "use --force" in err
    code, _, err = run_cli(["chunk", car_stl, "--out", out, "-q", "--force", "--no-picture"], capsys)
    assert code == 0 and (out / "job.json").exists() and (out / "mine.txt").read_text() == "precious"
    assert "kept 1 file that cooprint did not write: mine.txt" in err


@pytest.mark.parametrize("args, needle", [
    (["--theta", "89"], "outside the printable range"),
    (["--shift", "-5"], "option: chunking.shift = -5.0: expected a number >= 5"),
    (["--robot", "missing.toml"], "missing.toml: no such settings file"),
])
def test_user_errors_exit_2_with_one_line_and_write_nothing(tmp_path, car_stl, capsys, args, needle):
    out = tmp_path / "job"
    code, _, err = run_cli(["chunk", car_stl, "--out", out, "-q", *args], capsys)
    assert code == 2
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("cooprint: error:") and needle in lines[0]
    assert "Traceback" not in err
    assert not out.exists()
    assert not any(p.name.startswith(".job.") for p in tmp_path.iterdir())


def test_bad_mesh_file_exits_2(tmp_path, capsys):
    bad = tmp_path / "bad.stl"
    bad.write_bytes(b"\x00" * 500)
    code, _, err = run_cli(["chunk", bad, "--out", tmp_path / "o", "-q"], capsys)
    assert code == 2 and "bad.stl" in err and "Traceback" not in err


@pytest.mark.parametrize("where", ["front", "end"])
def test_verbose_shows_the_traceback(tmp_path, where):
    bad = tmp_path / "bad.stl"
    bad.write_bytes(b"\x00" * 500)
    args = ["chunk", str(bad), "--out", str(tmp_path / "o"), "-q"]
    args = ["--verbose", *args] if where == "front" else [*args, "--verbose"]
    r = subprocess.run([sys.executable, "-m", "cooprint", *args], capture_output=True, text=True)
    assert r.returncode != 0 and "Traceback" in r.stderr and "MeshError" in r.stderr


def test_failure_midway_leaves_no_partial_output(tmp_path, car_stl, monkeypatch):
    import cooprint.render.chunks as rc

    def boom(*a, **k):
        raise RuntimeError("disk full")

    monkeypatch.setattr(rc, "render_chunks", boom)
    with pytest.raises(RuntimeError):
        run_chunk(car_stl, tmp_path / "job")
    assert list(tmp_path.iterdir()) == []


def test_info_reports_mesh_and_limits(car_stl, capsys):
    code, out, _ = run_cli(["info", car_stl], capsys)
    assert code == 0
    assert "triangles" in out and "volume" in out and "theta_max 75.96 deg" in out


def test_no_arguments_prints_the_help(capsys):
    """`cooprint` alone prints the usual multi-line help on stdout, exit 0; a command missing its
    argument stays a one-line usage error, exit 2."""
    code, out, err = run_cli([], capsys)
    assert code == 0 and out.startswith("Usage: cooprint") and "Commands:" in out and not err
    assert len(out.splitlines()) > 5
    code, out, err = run_cli(["run"], capsys)
    assert code == 2 and err.strip().splitlines() == ["cooprint: error: Missing argument 'MESH'."]
    code, out, err = run_cli(["-v"], capsys)  # it raised "Missing command" with a traceback
    assert code == 0 and out.startswith("Usage: cooprint") and not err


def test_help_on_every_command(capsys):
    for args in (["--help"], ["chunk", "--help"], ["info", "--help"]):
        code, out, _ = run_cli(args, capsys)
        assert code == 0 and "Usage:" in out
