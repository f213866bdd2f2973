"""Shared helpers of the stage benchmarks: timing whole processes and preparing meshes.

Every tool is timed as a whole process under GNU ``/usr/bin/time -v``, so start-up, file
reading and writing count exactly as a user sees them, and the peak memory is the kernel's
maximum resident set size of the process.
"""
from __future__ import annotations

import gzip
import hashlib
import os
import re
import shutil
import signal
import statistics
import struct
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

GNU_TIME = "/usr/bin/time"
TIMEOUT_S = 1800
TIMED_OUT = "timed out after"
EXCEPTION_LINE = re.compile(r"^[A-Za-z_.]+(Error|Exception): ")


@dataclass(frozen=True)
class BenchContext:
    """What every stage benchmark gets from ``run.py``.

    shared: the team's shared folder (meshes, peers); work: git-ignored scratch folder;
    cooprint: the CLI to time; src: its sources (an editable install runs whatever is there);
    runs: timed runs per tool; skip_peers: time cooprint only.
    """

    shared: Path
    work: Path
    cooprint: Path
    src: Path
    runs: int
    skip_peers: bool


def resolve_meshes(shared: Path, names: list[str], work: Path | None = None,
                   generated: dict[str, Callable[[Path], Path]] | None = None) -> list[Path]:
    """Paths of the named meshes in ``shared/meshes`` (``.stl``/``.stl.gz`` may be left off).

    A name of ``generated`` (a stage's meshes made in code) is made by its function, which gets
    the ``work`` folder and returns the mesh's path there. Absent meshes are reported and skipped.
    """
    found = []
    for name in names:
        make = next((generated[n] for n in (name, name + ".stl") if n in (generated or {})), None)
        if make is not None and work is not None:
            found.append(make(work))
            continue
        candidates = [shared / "meshes" / (name + ext) for ext in ("", ".stl", ".stl.gz")]
        path = next((p for p in candidates if p.is_file()), None)
        if path is None:
            print(f"  skipping mesh {name!r}: not in {shared / 'meshes'}", flush=True)
        else:
            found.append(path)
    return found


class SourceWatch:
    """Notices an edit of cooprint's sources between its timed runs: with an editable install
    each run uses the code on disk when it starts, so such runs would mix versions."""

    def __init__(self, src: Path):
        self.src = src
        self.seen: set[str] = set()

    def check(self) -> None:
        """Record the current state of the sources."""
        self.seen.add(source_digest(self.src))

    @property
    def changed(self) -> bool:
        """Whether two checks saw different sources."""
        return len(self.seen) > 1


def source_digest(src: Path) -> str:
    """SHA-1 of the .py and .toml files under ``src``."""
    sha = hashlib.sha1()
    for path in sorted(p for p in src.rglob("*") if p.suffix in (".py", ".toml")):
        sha.update(str(path.relative_to(src)).encode() + b"\0" + path.read_bytes())
    return sha.hexdigest()


@dataclass(frozen=True)
class Measurement:
    """One timed process: wall seconds, peak RSS in MB (2**20 bytes), exit code, stdout, the
    line of its output most likely to say what went wrong, and CPU seconds (user + system, all
    its threads: above the wall time only when it used more than one core)."""

    wall_s: float
    peak_mb: float
    returncode: int
    stdout: str
    error_line: str
    cpu_s: float = float("nan")


def time_process(cmd: list[str], log_dir: Path, tag: str,
                 timeout_s: float = TIMEOUT_S) -> Measurement:
    """Run ``cmd`` under ``/usr/bin/time -v``; keep its output in ``log_dir/tag.*``.

    After ``timeout_s`` the whole process group is killed (``time`` and the tool it runs) and
    the measurement says ``timed out after ... s``.
    """
    log_dir.mkdir(parents=True, exist_ok=True)
    report = log_dir / f"{tag}.time"
    with subprocess.Popen([GNU_TIME, "-v", "-o", str(report), *cmd], stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True, start_new_session=True) as proc:
        try:
            stdout, stderr = proc.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            return Measurement(float(timeout_s), 0.0, -1, "", f"{TIMED_OUT} {timeout_s:g} s")
    (log_dir / f"{tag}.out").write_text(stdout)
    (log_dir / f"{tag}.err").write_text(stderr)
    wall_s, peak_kb, cpu_s = parse_gnu_time(report.read_text())
    return Measurement(wall_s, peak_kb / 1024.0, proc.returncode, stdout, error_line(stdout, stderr), cpu_s)


def timed(cmd: list[str], out: Path, tool: str, i: int, runs: int,
          timeout_s: float = TIMEOUT_S) -> Measurement:
    """One timed run (logs in ``out/logs``), with a progress line."""
    m = time_process(cmd, out / "logs", f"{tool}_{i}", timeout_s)
    status = "ok" if m.returncode == 0 else f"FAILED (exit {m.returncode})"
    print(f"  {out.name:<20} {tool:<8} run {i}/{runs}: {m.wall_s:7.2f} s "
          f"{m.peak_mb:7.0f} MB  {status}", flush=True)
    return m


def summarise(runs: list[Measurement]) -> dict:
    """Per-run numbers and the medians over the successful runs."""
    ok = [m for m in runs if m.returncode == 0]
    failed = [m for m in runs if m.returncode != 0]
    return {"wall_s": [m.wall_s for m in runs], "peak_mb": [round(m.peak_mb, 1) for m in runs],
            "returncodes": [m.returncode for m in runs],
            "wall_median_s": median([m.wall_s for m in ok]),
            "peak_median_mb": median([m.peak_mb for m in ok]),
            "cpu_median_s": median([m.cpu_s for m in ok]),
            "error": (failed[-1].error_line or f"exit code {failed[-1].returncode}")
            if failed else None}


def tool_version(cmd: list[str]) -> str:
    """First line that ``cmd`` prints."""
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    return out.strip().splitlines()[0]


def error_line(stdout: str, stderr: str) -> str:
    """The last Python exception line (``ValueError: ...``) of the output, else the last line
    of stderr, else of stdout (Blender prints its tracebacks on stdout)."""
    lines = [s.strip() for s in (stdout + "\n" + stderr).splitlines() if s.strip()]
    raised = [s for s in lines if EXCEPTION_LINE.match(s)]
    last_err = stderr.strip().splitlines()[-1:] or lines[-1:] or [""]
    return (raised or last_err)[-1]


def parse_gnu_time(text: str) -> tuple[float, int, float]:
    """(wall seconds, max RSS kB, user + system CPU seconds) from the report of
    ``/usr/bin/time -v``."""
    wall_s, peak_kb, cpu_s = float("nan"), 0, 0.0
    for line in text.splitlines():
        key, _, value = line.strip().rpartition(": ")
        if key.startswith("Elapsed (wall clock) time"):
            wall_s = sum(float(part) * 60 ** i for i, part in enumerate(reversed(value.split(":"))))
        elif key == "Maximum resident set size (kbytes)":
            peak_kb = int(value)
        elif key in ("User time (seconds)", "System time (seconds)"):
            cpu_s += float(value)
    return wall_s, peak_kb, cpu_s


def median(values: list[float]) -> float | None:
    """Median of the values, None when there are none."""
    return statistics.median(values) if values else None


def fmt(value, spec: str) -> str:
    """``value`` formatted, or an em dash when it is missing."""
    return "—" if value is None else format(value, spec)


def ratio(num: float | None, den: float | None, unit: str) -> str:
    """num / den with two decimals and ``unit``, or a dash."""
    return "—" if num is None or not den else f"{num / den:.2f}{unit}"


def plural(n: int, word: str) -> str:
    """'1 run', '3 runs'."""
    return f"{n} {word}" + ("" if n == 1 else "s")


def prepare_mesh(path: Path, work: Path) -> Path:
    """Path of an uncompressed copy of ``path``: ``*.gz`` is gunzipped once into ``work/meshes``."""
    if path.suffix != ".gz":
        return path
    target = work / "meshes" / path.stem
    if not target.exists() or target.stat().st_mtime < path.stat().st_mtime:
        target.parent.mkdir(parents=True, exist_ok=True)
        partial = target.with_suffix(".part")
        with gzip.open(path, "rb") as src, open(partial, "wb") as dst:
            shutil.copyfileobj(src, dst, 1 << 20)
        partial.replace(target)
    return target


def stl_triangles(path: Path) -> int | None:
    """Triangle count of a binary STL from its header, None for an ASCII STL."""
    with open(path, "rb") as f:
        head = f.read(84)
    if len(head) < 84:
        return None
    count = struct.unpack("<I", head[80:84])[0]
    return count if 84 + 50 * count == path.stat().st_size else None
