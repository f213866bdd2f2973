"""Scale benchmark (issue 15): big parts through ``cooprint run`` and ``simulate``, as a user runs them.

Two parts generated in code: the 600 x 4000 x 400 mm beam and a 10000 x 300 x 300 mm wall, each
with the default robot and with a large-nozzle profile (1.0 mm nozzle, 0.6 mm layers, 1.1 mm
lines: ``--nozzle 1.0 --layer-height 0.6 --first-layer-height 0.6 --extrusion-width 1.1``).
For each: ``cooprint run`` with the processes executor (the default) and, when this cooprint has
the option, with a Dask LocalCluster of 2 workers (``--executor dask --scheduler local:2``), then
``cooprint simulate`` of the bundle. Every command runs as a child process under
``/usr/bin/time -v``: wall time, peak resident memory (the largest process of the command: the
main process, not the sum of its workers), exit code; and the bundle's size (G-code, .coop, the
rest). The G-code writer's speed is timed on its own: the beam's smaller robot program read back
and written again as G-code (MB/s of G-code).

The issue's targets are marked met or not: the beam's ``run`` <= 2 min and <= 1.5 GB peak (the
default profile), the wall's ``run`` to the end within 4 GB, ``simulate`` of the beam <= 1.5 GB,
G-code written at >= 100 MB/s, dask with 2 workers within 15% of the processes executor.

A guard stops a command whose processes together hold more than ``--memory-limit`` (default 16
GB, the machine is shared) and records it as stopped there: a target that needs less is not met.

    python benchmarks/run.py --stages scale            # the whole stage (tens of minutes), docs/benchmarks.md
    python benchmarks/bench_scale.py --smoke            # small parts: checks it runs, writes nothing
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from harness import GNU_TIME, BenchContext, error_line, fmt, parse_gnu_time

NAME = "scale"
TITLE = "Big parts: time, memory and output"
DEFAULT_MESHES: list[str] = []
PEER_PACKAGES: list[str] = []
#: Part name -> (x, y, z) mm of the box, standing on the floor, centred in x and y.
PARTS = {"beam": (600.0, 4000.0, 400.0), "wall": (10000.0, 300.0, 300.0)}
SMOKE_PARTS = {"beam": (300.0, 800.0, 60.0), "wall": (1500.0, 150.0, 60.0)}
#: Profile name -> the command-line flags that give it.
PROFILES = {"default": [],
            "large nozzle": ["--nozzle", "1.0", "--layer-height", "0.6", "--first-layer-height", "0.6",
                             "--extrusion-width", "1.1"]}
#: Executor name -> its flags (``None``: the option is missing from this cooprint: skipped).
DASK_FLAGS = ["--executor", "dask", "--scheduler", "local:2"]
TIMEOUT_S = 3600.0
MEMORY_LIMIT_GB = 16.0
#: Targets of issue 15.
BEAM_RUN_S, BEAM_RUN_GB, WALL_RUN_GB, BEAM_SIM_GB, GCODE_MB_S, DASK_SLOWER = 120.0, 1.5, 4.0, 1.5, 100.0, 0.15


# ---------------------------------------------------------------------------------------------
# measuring one command

def guarded(cmd: list[str], log_dir: Path, tag: str, timeout_s: float, limit_bytes: float) -> dict:
    """Run ``cmd`` under ``/usr/bin/time -v``; stop it (SIGKILL to every process of its session
    but ``time``) when they hold more than ``limit_bytes`` together or run past ``timeout_s``.
    Returns wall_s, peak_mb (the largest process, GNU time's), returncode, error and, when
    stopped, ``stopped`` (why)."""
    log_dir.mkdir(parents=True, exist_ok=True)
    report = log_dir / f"{tag}.time"
    out, err = open(log_dir / f"{tag}.out", "w"), open(log_dir / f"{tag}.err", "w")
    t0 = time.perf_counter()
    stopped = None
    top = 0.0
    with out, err, subprocess.Popen([GNU_TIME, "-v", "-o", str(report), *cmd], stdout=out, stderr=err,
                                    start_new_session=True) as proc:
        while proc.poll() is None:
            time.sleep(0.5)
            total = session_rss(proc.pid)
            top = max(top, total)
            why = (f"more than {limit_bytes / 1e9:g} GB held" if total > limit_bytes else
                   f"timed out after {timeout_s:.0f} s" if time.perf_counter() - t0 > timeout_s else None)
            if why:
                stopped = why
                kill_session_but(proc.pid)
                proc.wait()
    wall = time.perf_counter() - t0
    stdout, stderr = (log_dir / f"{tag}.out").read_text(), (log_dir / f"{tag}.err").read_text()
    wall_s, peak_kb, cpu_s = parse_gnu_time(report.read_text()) if report.exists() else (wall, 0, 0.0)
    row = {"wall_s": wall_s, "peak_mb": peak_kb / 1024.0, "session_peak_mb": top / 2 ** 20, "cpu_s": cpu_s,
           "returncode": proc.returncode if stopped is None else -9}
    if stopped:
        row["stopped"] = stopped
    if row["returncode"] != 0:
        row["error"] = stopped or error_line(stdout, stderr) or f"exit code {proc.returncode}"
    return row


def session_rss(sid: int) -> float:
    """Bytes resident in every process of session ``sid`` (the command and its workers)."""
    total = 0
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            if int(fields[3]) != sid:  # field 6 of stat: the session id
                continue
            total += int(fields[21]) * os.sysconf("SC_PAGE_SIZE")  # field 24: rss in pages
        except (OSError, ValueError, IndexError):
            continue
    return float(total)


def kill_session_but(keep: int) -> None:
    """SIGKILL every process of session ``keep`` except ``keep`` itself (GNU time, which then
    writes its report)."""
    for entry in os.listdir("/proc"):
        if not entry.isdigit() or int(entry) == keep:
            continue
        try:
            with open(f"/proc/{entry}/stat") as fh:
                fields = fh.read().rsplit(")", 1)[1].split()
            if int(fields[3]) == keep:
                os.kill(int(entry), signal.SIGKILL)
        except (OSError, ValueError, IndexError):
            continue


def bundle_sizes(out: Path) -> dict:
    """Bytes of a bundle: G-code, .coop (compressed or not), everything (``sim/`` left out)."""
    sizes = {"gcode": 0, "coop": 0, "total": 0}
    if not out.is_dir():
        return sizes
    for p in out.rglob("*"):
        if not p.is_file() or "sim" in p.relative_to(out).parts:
            continue
        n = p.stat().st_size
        sizes["total"] += n
        if ".gcode" in p.name:
            sizes["gcode"] += n
        elif ".coop" in p.name:
            sizes["coop"] += n
    return sizes


def has_dask_option(python: list[str], env: dict) -> bool:
    """Whether this cooprint's ``run`` has ``--executor dask`` and ``--scheduler`` (issue 15 item 4)."""
    proc = subprocess.run([*python, "-m", "cooprint", "run", "--help"], capture_output=True, text=True, env=env)
    return "--executor" in proc.stdout and "--scheduler" in proc.stdout and "dask" in proc.stdout


GCODE_RATE = r"""
import json, sys, time, tempfile, os
from pathlib import Path
from cooprint.config import load_settings
from cooprint.program.commands import read_coop
from cooprint.program.gcode import Feeds, write_gcode
bundle = Path(sys.argv[1])
job = json.loads((bundle / "job.json").read_text())
settings = load_settings(tables=[("job.json", job["settings"])])
files = sorted((p for p in (bundle / "robots").glob("*.coop") if p.stat().st_size > 1000), key=lambda p: p.stat().st_size)
program = read_coop(files[0])
feeds = Feeds.of_robot(settings.robot, settings.slicing)
with tempfile.TemporaryDirectory(dir=bundle) as tmp:
    t0 = time.perf_counter()
    with open(Path(tmp) / "x.gcode", "w", encoding="ascii") as fh:
        write_gcode(fh, [program], settings.slicing, feeds, "bench", home=False)
    dt = time.perf_counter() - t0
    size = os.path.getsize(Path(tmp) / "x.gcode")
print(json.dumps({"robot": files[0].stem, "commands": len(program), "bytes": size, "seconds": dt}))
"""


def gcode_rate(python: list[str], env: dict, bundle: Path) -> dict:
    """MB/s of the G-code writer on the bundle's smallest robot program (read back from .coop)."""
    proc = subprocess.run([*python, "-c", GCODE_RATE, str(bundle)], capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        return {"error": error_line(proc.stdout, proc.stderr)}
    data = json.loads(proc.stdout.strip().splitlines()[-1])
    data["mb_s"] = data["bytes"] / 1e6 / data["seconds"] if data["seconds"] > 0 else None
    return data


# ---------------------------------------------------------------------------------------------
# the stage

def make_part(name: str, size: tuple[float, float, float], folder: Path) -> Path:
    """The box ``size`` as a binary STL in ``folder``."""
    import trimesh

    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.stl"
    box = trimesh.creation.box(extents=size)
    box.apply_translation((0.0, 0.0, size[2] / 2))
    box.export(path)
    return path


def run(ctx: BenchContext, meshes: list[Path], parts: dict | None = None, timeout_s: float = TIMEOUT_S,
        memory_limit_gb: float = MEMORY_LIMIT_GB) -> dict:
    """Every part x profile x executor through ``run`` and ``simulate``; the targets judged."""
    from cooprint import __version__

    parts = parts or PARTS
    work = ctx.work / NAME
    python = [sys.executable]
    env = dict(os.environ, PYTHONPATH=str(ctx.src))
    env.pop("COOPRINT_PROGRESS", None)
    executors: dict[str, list[str] | None] = {"processes": [],
                                              "dask local:2": DASK_FLAGS if has_dask_option(python, env) else None}
    notes = []
    if executors["dask local:2"] is None:
        notes.append("dask: this cooprint has no `--executor dask --scheduler local:N` option yet: the dask rows "
                     "are skipped")
    limit = memory_limit_gb * 1e9
    rows = []
    for part, size in parts.items():
        mesh = make_part(part, size, work / "meshes")
        for profile, flags in PROFILES.items():
            for executor, ex_flags in executors.items():
                row: dict[str, Any] = {"part": part, "size_mm": list(size), "profile": profile, "executor": executor}
                if ex_flags is None:
                    row["skipped"] = "option missing"
                    rows.append(row)
                    continue
                out = work / "out" / f"{part}_{profile.replace(' ', '-')}_{executor.split()[0]}"
                tag = out.name
                out.parent.mkdir(parents=True, exist_ok=True)
                print(f"  {part} {profile} {executor}: run", flush=True)
                cmd = [*python, "-m", "cooprint", "run", str(mesh), "--out", str(out), "--force", "-q", *flags,
                       *ex_flags]
                row["run"] = guarded(cmd, work / "logs", tag + "_run", timeout_s, limit)
                row["run"].update(bundle_sizes(out))
                _print(row["run"])
                if row["run"]["returncode"] == 0 and executor == "processes":
                    print(f"  {part} {profile}: simulate", flush=True)
                    row["simulate"] = guarded([*python, "-m", "cooprint", "simulate", str(out), "--force", "-q"],
                                              work / "logs", tag + "_sim", timeout_s, limit)
                    _print(row["simulate"])
                    if part == "beam" and profile == "default":
                        row["gcode_rate"] = gcode_rate(python, env, out)
                rows.append(row)
                if executor != "processes":
                    shutil.rmtree(out, ignore_errors=True)  # the processes bundle is the one kept
    result = {"runs": 1, "tools": {"cooprint": f"cooprint {__version__}"}, "sources_changed": False,
              "parts": {k: list(v) for k, v in parts.items()}, "profiles": PROFILES, "notes": notes, "rows": rows,
              "memory_limit_gb": memory_limit_gb}
    result["targets"] = targets(rows)
    return result


def _print(m: dict) -> None:
    status = "ok" if m["returncode"] == 0 else f"FAILED ({m.get('error', '')})"
    size = f", {m['total'] / 1e9:.2f} GB written" if m.get("total") else ""
    print(f"    {m['wall_s']:8.1f} s {m['peak_mb'] * 2 ** 20 / 1e9:6.2f} GB peak{size}  {status}", flush=True)


def _find(rows: list[dict], part: str, profile: str, executor: str) -> dict | None:
    return next((r for r in rows if (r["part"], r["profile"], r["executor"]) == (part, profile, executor)), None)


def targets(rows: list[dict]) -> list[dict]:
    """The issue's targets, each with the measured value and met (True / False / None: not measured)."""
    out = []

    def add(name: str, value: str, met: bool | None) -> None:
        out.append({"target": name, "measured": value, "met": met})

    beam = _find(rows, "beam", "default", "processes")
    run_ = (beam or {}).get("run")
    ok = run_ is not None and run_["returncode"] == 0
    add(f"beam `run` <= {BEAM_RUN_S / 60:g} min", f"{run_['wall_s']:.0f} s" if run_ else "—",
        (ok and run_["wall_s"] <= BEAM_RUN_S) if run_ else None)
    add(f"beam `run` <= {BEAM_RUN_GB:g} GB peak", _gb(run_["peak_mb"] * 2 ** 20) if run_ else "—",
        (ok and run_["peak_mb"] * 2 ** 20 <= BEAM_RUN_GB * 1e9) if run_ else None)
    wall = (_find(rows, "wall", "default", "processes") or {}).get("run")
    add(f"wall `run` to the end within {WALL_RUN_GB:g} GB",
        (_gb(wall["peak_mb"] * 2 ** 20) + ("" if wall["returncode"] == 0 else f", {wall.get('error')}"))
        if wall else "—",
        (wall["returncode"] == 0 and wall["peak_mb"] * 2 ** 20 <= WALL_RUN_GB * 1e9) if wall else None)
    sim = (beam or {}).get("simulate")
    add(f"beam `simulate` <= {BEAM_SIM_GB:g} GB peak", _gb(sim["peak_mb"] * 2 ** 20) if sim else "—",
        (sim["returncode"] == 0 and sim["peak_mb"] * 2 ** 20 <= BEAM_SIM_GB * 1e9) if sim else None)
    rate = (beam or {}).get("gcode_rate") or {}
    add(f"G-code written at >= {GCODE_MB_S:g} MB/s", fmt(rate.get("mb_s"), ".0f") + " MB/s" if rate.get("mb_s")
        else rate.get("error", "—"), (rate["mb_s"] >= GCODE_MB_S) if rate.get("mb_s") else None)
    dask = (_find(rows, "beam", "default", "dask local:2") or {}).get("run")
    if dask and ok and dask["returncode"] == 0:
        ratio = dask["wall_s"] / run_["wall_s"]
        add(f"dask 2 workers within {DASK_SLOWER:.0%} of processes", f"{ratio:.2f}x", ratio <= 1 + DASK_SLOWER)
    else:
        add(f"dask 2 workers within {DASK_SLOWER:.0%} of processes",
            "not measured (option missing)" if dask is None else "dask run failed", None if dask is None else False)
    return out


def render(result: dict) -> str:
    """The Markdown section for docs/benchmarks.md."""
    parts = ", ".join(f"{k} {' x '.join(f'{v:g}' for v in size)} mm" for k, size in result["parts"].items())
    lines = [
        f"Generated boxes ({parts}) with the default robot and with a large-nozzle profile "
        f"(`{' '.join(PROFILES['large nozzle'])}`), two robots, planned with `cooprint run` (the processes "
        "executor; a Dask LocalCluster of 2 workers with `--executor dask --scheduler local:2` when this cooprint "
        "has it) and checked with `cooprint simulate`, each a child process under `/usr/bin/time -v`: wall time, "
        "peak resident memory of the largest process (the main one: the slicing workers are forks that hold "
        "little), and the bundle's size. G-code rate: the beam's smaller robot program read back from its .coop "
        f"and written as G-code alone. A command whose processes hold more than {result['memory_limit_gb']:g} GB "
        "together is stopped (the machine is shared).",
        "",
        "| target (issue 15) | measured | met |",
        "|---|---|---|",
    ]
    for t in result["targets"]:
        lines.append(f"| {t['target']} | {t['measured']} | "
                     f"{'yes' if t['met'] else 'no' if t['met'] is False else 'not measured'} |")
    lines += ["", "| part | profile | executor | run wall | run peak | bundle | G-code | .coop | simulate wall | "
              "simulate peak |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in result["rows"]:
        if r.get("skipped"):
            lines.append(f"| {r['part']} | {r['profile']} | {r['executor']} | skipped: {r['skipped']} "
                         "| | | | | | |")
            continue
        m, s = r["run"], r.get("simulate") or {}
        failed = "" if m["returncode"] == 0 else f" ({m.get('error', 'failed')})".replace("|", "/")
        lines.append(
            f"| {r['part']} | {r['profile']} | {r['executor']} | {_t(m['wall_s'])}{failed} | {_gb(m['peak_mb'] * 2 ** 20)} "
            f"({_gb(m.get('session_peak_mb', 0) * 2 ** 20)} all processes) "
            f"| {_gb(m.get('total'))} | {_gb(m.get('gcode'))} | {_gb(m.get('coop'))} | "
            f"{_t(s.get('wall_s'))} | {_gb(s['peak_mb'] * 2 ** 20) if s.get('peak_mb') else '—'} |")
    for note in result.get("notes", []):
        lines += ["", f"_Note: {note}_"]
    return "\n".join(lines) + "\n"


def _t(s: float | None) -> str:
    if s is None:
        return "—"
    return f"{s:.1f} s" if s < 120 else f"{int(s // 60)} min {s % 60:.0f} s"


def _gb(n: float | None) -> str:
    """Bytes in decimal GB (MB below 0.1 GB), as the targets state them."""
    if not n:
        return "—"
    return f"{n / 1e9:.2f} GB" if n >= 1e8 else f"{n / 1e6:.1f} MB"


# ---------------------------------------------------------------------------------------------
# a smoke test of the script itself

def smoke() -> int:
    """Small parts through every variant; the section printed, nothing written to docs."""
    t0 = time.perf_counter()
    repo = Path(__file__).resolve().parents[1]
    with tempfile.TemporaryDirectory() as tmp:
        ctx = BenchContext(shared=repo.parent / "shared", work=Path(tmp), cooprint=Path(sys.executable),
                           src=repo / "src", runs=1, skip_peers=True)
        result = run(ctx, [], parts=SMOKE_PARTS, timeout_s=600, memory_limit_gb=4)
    print(render(result))
    bad = [r for r in result["rows"] if not r.get("skipped") and r["run"]["returncode"] != 0]
    print(f"smoke run: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 1 if bad else 0


if __name__ == "__main__":
    p = argparse.ArgumentParser(description="the scale stage; run it with benchmarks/run.py")
    p.add_argument("--smoke", action="store_true", help="small parts, every variant, nothing written")
    if p.parse_args().smoke:
        sys.exit(smoke())
