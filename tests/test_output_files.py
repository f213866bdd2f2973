"""Issue 15, item 2 and its bad input: ``run --compress`` writes gzip programs that every reader
takes as they are (same results as uncompressed), and a disk that fills up while a bundle is
written gives one clear line and leaves nothing behind."""

from __future__ import annotations

import errno
import gzip
import json
import os
import subprocess
from pathlib import Path

import pytest

from cooprint.cli import main
from cooprint.io import bundle
from cooprint.jobs import run

from badinput import assert_rejected, snapshot
from solids import COARSE, box, to_trimesh

COARSE_TOML = "[slicing]\n" + "".join(f"{k.split('.')[1]} = {v}\n" for k, v in COARSE.items())


@pytest.fixture(scope="module")
def bundles(tmp_path_factory):
    """The same two-robot plan of a 40 x 420 mm bar written plain and with --compress."""
    root = tmp_path_factory.mktemp("compress")
    to_trimesh(box(40, 420, 12)).export(root / "bar.stl")
    (root / "coarse.toml").write_text(COARSE_TOML)
    assert main(["run", str(root / "bar.stl"), "--out", str(root / "plain"), "--config", str(root / "coarse.toml"),
                 "--no-picture", "-q"]) == 0
    assert main(["run", str(root / "bar.stl"), "--out", str(root / "gz"), "--config", str(root / "coarse.toml"),
                 "--no-picture", "-q", "--compress"]) == 0
    return root


def _summary(path: Path) -> dict:
    s = json.loads(path.read_text())
    s.pop("source", None)
    s.pop("inputs", None)  # the input paths, as source
    return s


def test_compressed_bundle_holds_the_same_programs(bundles):
    plain, gz = bundles / "plain", bundles / "gz"
    rec = json.loads((gz / "job.json").read_text())
    assert [(r["program"], r["gcode"]) for r in rec["robots"]] == \
        [(f"robots/{n}.coop.gz", f"robots/{n}.gcode.gz") for n in ("A", "B")]
    assert sorted(os.listdir(gz / "robots")) == ["A.coop.gz", "A.gcode.gz", "B.coop.gz", "B.gcode.gz"]
    # job.json is the plain one's but for the names
    assert (gz / "job.json").read_text().replace(".gz", "") == (plain / "job.json").read_text()
    for name in ("A.coop", "A.gcode", "B.coop", "B.gcode"):
        data = (gz / "robots" / f"{name}.gz").read_bytes()
        assert gzip.decompress(data) == (plain / "robots" / name).read_bytes()
        # deterministic: no file name in the header (FLG 0), mtime 0
        assert data[:4] == b"\x1f\x8b\x08\x00" and data[4:8] == b"\0\0\0\0"
        assert len(data) * 3 < len(gzip.decompress(data))


def test_compressed_output_is_deterministic(bundles, tmp_path):
    assert main(["run", str(bundles / "bar.stl"), "--out", str(tmp_path / "again"), "--config",
                 str(bundles / "coarse.toml"), "--no-picture", "-q", "--compress"]) == 0
    for name in ("A.coop.gz", "A.gcode.gz", "B.coop.gz", "B.gcode.gz"):
        assert (tmp_path / "again" / "robots" / name).read_bytes() == (bundles / "gz" / "robots" / name).read_bytes()


def test_simulate_and_render_read_compressed_programs(bundles, tmp_path):
    plain, gz = bundles / "plain", bundles / "gz"
    out = {}
    for name, src in (("plain", plain), ("gz", gz)):
        assert main(["simulate", str(src), "-q", "--force"]) == 0
        out[name] = _summary(src / "sim" / "summary.json")
    assert out["gz"] == out["plain"]
    # the .coop and G-code files themselves, and a manifest naming .coop.gz files
    for suffix in ("coop", "gcode"):
        for name, src in (("plain", plain / "robots"), ("gz", gz / "robots")):
            gzs = ".gz" if name == "gz" else ""
            files = [str(src / f"{r}.{suffix}{gzs}") for r in ("A", "B")]
            assert main(["simulate", *files, "--out", str(tmp_path / f"{suffix}-{name}"), "-q"]) in (0, 1)
            out[suffix, name] = _summary(tmp_path / f"{suffix}-{name}" / "sim" / "summary.json")
        assert out[suffix, "gz"] == out[suffix, "plain"]
        assert [r["name"] for r in out[suffix, "gz"]["robots"]] == ["A", "B"]  # A.coop.gz is robot A
    m = tmp_path / "m.toml"
    rec = json.loads((gz / "job.json").read_text())
    m.write_text("".join(f'[[robots]]\nname = "{r["name"]}"\nprogram = "{gz / r["program"]}"\n'
                         f'start = {list(r["start"])}\nfacing_deg = {r["facing_deg"]}\n' for r in rec["robots"]))
    assert main(["simulate", "--manifest", str(m), "--out", str(tmp_path / "man"), "-q"]) in (0, 1)
    m2 = tmp_path / "m2.toml"
    m2.write_text(m.read_text().replace(".gz", "").replace(str(gz), str(plain)))
    assert main(["simulate", "--manifest", str(m2), "--out", str(tmp_path / "man2"), "-q"]) in (0, 1)
    assert _summary(tmp_path / "man" / "sim" / "summary.json") == _summary(tmp_path / "man2" / "sim" / "summary.json")
    # render reads them too: the same picture
    for name, src in (("plain", plain), ("gz", gz)):
        assert main(["render", str(src), "--format", "gantt", "--out", str(tmp_path / f"{name}.png")]) == 0
    assert (tmp_path / "gz.png").read_bytes() == (tmp_path / "plain.png").read_bytes()


def test_a_damaged_compressed_program_is_one_line(bundles, tmp_path, capsys):
    bad = tmp_path / "A.coop.gz"
    bad.write_bytes((bundles / "gz" / "robots" / "A.coop.gz").read_bytes()[:200])  # cut short
    line = assert_rejected(["simulate", bad, "--out", tmp_path / "o"], capsys, watch=[tmp_path])
    assert "A.coop.gz: not a valid gzip file" in line
    bad = tmp_path / "B.gcode.gz"
    bad.write_bytes(b"\x1f\x8b" + b"not gzip at all")
    line = assert_rejected(["simulate", bad, "--out", tmp_path / "o"], capsys, watch=[tmp_path])
    assert "B.gcode.gz: not a valid gzip file" in line


class _FillingFile:
    """A file on a disk with ``room`` bytes left: a write past them fails as a full disk does."""

    def __init__(self, path, room: int, code: int):
        self.fh = open(path, "wb")
        self.room, self.code = room, code

    def write(self, data) -> int:
        n = len(memoryview(data).cast("B"))
        if n > self.room:
            raise OSError(self.code, os.strerror(self.code))
        self.room -= n
        return self.fh.write(data)

    def close(self) -> None:
        self.fh.close()


def _filling(target: str, code: int = errno.ENOSPC):
    real = bundle._open_raw

    def opener(path, mode="r", buffering=-1):
        if str(path).endswith(target):
            return _FillingFile(path, 4000, code)
        return real(path, mode, buffering=buffering)

    return opener


@pytest.mark.parametrize("target, code, compress", [("robots/A.gcode", errno.ENOSPC, False),
                                                    ("robots/B.coop.gz", errno.ENOSPC, True),
                                                    ("job.json", errno.EDQUOT, False)])
def test_a_full_disk_is_one_line_and_leaves_nothing(bundles, tmp_path, capsys, monkeypatch, target, code, compress):
    monkeypatch.setattr(bundle, "_open_raw", _filling(target, code))
    out = tmp_path / "job"
    args = ["run", bundles / "bar.stl", "--out", out, "--config", bundles / "coarse.toml", "--no-picture"]
    line = assert_rejected(args + (["--compress"] if compress else []), capsys, watch=[tmp_path])
    reason = "the disk is full (no space left on device)" if code == errno.ENOSPC else "the disk quota is exceeded"
    assert line.startswith(f"cooprint: error: {out}: {reason}"), line
    assert f"while writing {target}; nothing was written" in line
    assert os.listdir(tmp_path) == []  # no temporary bundle left


def test_a_full_disk_keeps_the_old_bundle(bundles, tmp_path, capsys, monkeypatch):
    """Replacing a bundle (--force) on a full disk: the old bundle is as it was."""
    out = tmp_path / "job"
    run(bundles / "bar.stl", out, overrides=COARSE, picture=False)
    monkeypatch.setattr(bundle, "_open_raw", _filling("robots/B.gcode"))
    line = assert_rejected(["run", bundles / "bar.stl", "--out", out, "--config", bundles / "coarse.toml",
                            "--no-picture", "--force"], capsys, watch=[tmp_path])
    assert "the disk is full (no space left on device) while writing robots/B.gcode" in line


def _mount_tmpfs(where: Path, size: str) -> bool:
    if os.geteuid() != 0:
        return False
    try:
        return subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                              capture_output=True, timeout=20).returncode == 0
    except (OSError, subprocess.SubprocessError):
        return False


def test_a_really_full_disk(bundles, tmp_path, capsys, monkeypatch):
    """On a real 256 KiB file system (a tmpfs; root only): the programs do not fit (the run's
    estimate, which would refuse it before slicing, is left out: the disk fills for real)."""
    import cooprint.io.estimate as estimate

    monkeypatch.setattr(estimate, "check_room", lambda out, est: None)
    small = tmp_path / "small"
    small.mkdir()
    if not _mount_tmpfs(small, "256k"):
        pytest.skip("cannot mount a small tmpfs here (needs root and mount rights)")
    try:
        before = snapshot(small)
        code = main(["run", str(bundles / "bar.stl"), "--out", str(small / "job"), "--config",
                     str(bundles / "coarse.toml"), "--no-picture"])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1, err
        assert err[0].startswith(f"cooprint: error: {small / 'job'}: the disk is full (no space left on device)")
        assert err[0].endswith("; nothing was written")
        assert snapshot(small) == before and os.listdir(small) == []
    finally:
        subprocess.run(["umount", str(small)], capture_output=True, timeout=20)


def test_force_swaps_plain_and_compressed_programs(bundles, tmp_path):
    """--force replaces a bundle's programs whichever way they were written: no stale file stays."""
    out = tmp_path / "job"
    args = ["run", str(bundles / "bar.stl"), "--out", str(out), "--config", str(bundles / "coarse.toml"),
            "--no-picture", "-q", "--force"]
    assert main(args) == 0
    assert sorted(os.listdir(out / "robots")) == ["A.coop", "A.gcode", "B.coop", "B.gcode"]
    assert main(args + ["--compress"]) == 0
    assert sorted(os.listdir(out / "robots")) == ["A.coop.gz", "A.gcode.gz", "B.coop.gz", "B.gcode.gz"]
    assert main(args) == 0
    assert sorted(os.listdir(out / "robots")) == ["A.coop", "A.gcode", "B.coop", "B.gcode"]
