"""Simulation benchmark: how fast cooprint plays and checks a plan, how fast it animates one, and
how close its print time comes to PrusaSlicer's own estimate for PrusaSlicer's G-code."""
from __future__ import annotations

import json
import re
from pathlib import Path

from harness import (BenchContext, fmt, plural, prepare_mesh, summarise, timed, tool_version)

NAME = "simulation"
TITLE = "Simulation"
DEFAULT_MESHES = ["benchy.stl", "nefertiti.stl", "occt_tr12j_housing.stl"]
PEER_PACKAGES = ["prusa-slicer"]
FRAMES = (10.0, 24.0)  # seconds, frames per second of the timed animation
PRUSA_ESTIMATE = re.compile(r"^; estimated printing time \(normal mode\) = (.+)$", re.M)
TARGET_CMDS = 1_000_000  # commands/s, for programs of at least TARGET_SIZE commands
TARGET_SIZE = 1_000_000


def sim_runs(runs: int) -> int:
    """Timed `simulate` runs: at least 5 (each takes seconds; on this kind of machine one run's
    wall time varies by up to 40% with how much of its memory the host must hand back first)."""
    return max(runs, 5)
TARGET_FPS = 10.0
TARGET_TIME = 0.05  # relative difference to PrusaSlicer's estimate


def run(ctx: BenchContext, meshes: list[Path]) -> dict:
    """For every mesh: plan it (not timed), then time `simulate` and `render --format mp4` on the
    plan, and `simulate --accel` on PrusaSlicer's G-code of it against PrusaSlicer's estimate."""
    cp = str(ctx.cooprint)
    tools = {"cooprint": tool_version([cp, "--version"]).replace(", version", "")}
    rows = []
    for source in meshes:
        mesh = prepare_mesh(source, ctx.work)
        out = ctx.work / NAME / mesh.stem
        job = out / "job"
        out.mkdir(parents=True, exist_ok=True)
        print(f"  {mesh.stem}: planning with cooprint run", flush=True)
        setup = timed([cp, "run", str(mesh), "--out", str(job), "-q", "--no-picture", "--force"], out, "plan", 1, 1)
        if setup.returncode != 0:
            rows.append({"mesh": source.name, "error": setup.error_line})
            continue
        record = json.loads((job / "job.json").read_text())
        commands = sum(r["stats"]["commands"] for r in record["robots"])
        deposits = sum(r["stats"]["moves"] for r in record["robots"])
        # one untimed run first: the kernels compiled for these arrays' types are then in numba's cache
        timed([cp, "simulate", str(job), "-q", "--force"], out, "warm-up", 1, 1)
        sim = [timed([cp, "simulate", str(job), "-q", "--force"], out, "simulate", i + 1, sim_runs(ctx.runs))
               for i in range(sim_runs(ctx.runs))]
        summary = json.loads((job / "sim" / "summary.json").read_text())
        duration, fps = FRAMES
        anim = [timed([cp, "render", str(job), "--format", "mp4", "--duration", str(duration), "--fps", str(fps),
                       "--force"], out, "mp4", i + 1, ctx.runs) for i in range(ctx.runs)]
        row = {"mesh": source.name, "commands": commands, "moves": deposits,
               "makespan_s": summary["makespan_s"], "findings": summary["finding_counts"],
               "simulate": summarise(sim), "mp4": summarise(anim), "frames": int(duration * fps)}
        if not ctx.skip_peers:
            row["prusa"] = versus_prusa(ctx, mesh, out)
            tools["PrusaSlicer"] = "PrusaSlicer " + _prusa_version()
        rows.append(row)
    return {"runs": ctx.runs, "tools": tools, "sources_changed": False, "meshes": rows}


def _prusa_version() -> str:
    import subprocess

    out = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "prusa-slicer"], capture_output=True, text=True)
    return out.stdout.split("+")[0] or "?"


def versus_prusa(ctx: BenchContext, mesh: Path, out: Path) -> dict:
    """Slice with PrusaSlicer (the peers' script), simulate its G-code with acceleration, compare
    with the estimate PrusaSlicer writes at its end."""
    gcode = out / "PrusaSlicer.gcode"
    if not gcode.exists():
        m = timed([str(ctx.shared / "peers" / "prusa_slice.sh"), str(mesh), str(gcode)], out, "prusa", 1, 1)
        if m.returncode != 0:
            return {"error": m.error_line}
    found = PRUSA_ESTIMATE.search(gcode.read_text(errors="replace")[-200_000:])
    estimate = _seconds(found.group(1)) if found else None
    sim_dir = out / "prusa_sim"
    runs = [timed([str(ctx.cooprint), "simulate", str(gcode), "--out", str(sim_dir), "--accel", "-q", "--force"],
                  out, "prusa_simulate", i + 1, ctx.runs) for i in range(ctx.runs)]
    ours = json.loads((sim_dir / "sim" / "summary.json").read_text())["makespan_s"]
    flat = out / "prusa_flat"
    timed([str(ctx.cooprint), "simulate", str(gcode), "--out", str(flat), "-q", "--force"], out, "prusa_flat", 1, 1)
    constant = json.loads((flat / "sim" / "summary.json").read_text())["makespan_s"]
    return {"estimate_s": estimate, "ours_s": ours, "constant_speed_s": constant, "simulate": summarise(runs)}


def _errors(counts: dict) -> int:
    """Findings of the kinds that make a plan unprintable (all but the overhang warnings)."""
    return sum(v for k, v in counts.items() if k != "overhang")


def _seconds(text: str) -> float:
    units = {"d": 86400, "h": 3600, "m": 60, "s": 1}
    return float(sum(int(n) * units[u] for n, u in re.findall(r"(\d+)([dhms])", text)))


def render(result: dict) -> str:
    """The Markdown section for docs/benchmarks.md."""
    lines = [
        "Each mesh is first planned for two robots with `cooprint run MESH --out JOB -q --no-picture` (not "
        "timed). Then, as whole processes under `/usr/bin/time -v`, "
        f"{plural(sim_runs(result['runs']), 'run')} of `cooprint simulate JOB -q --force` (read every `.coop` "
        "file, put every move in time, resolve NOTIFY/WAIT, run the checks, write `sim/summary.json`) and "
        f"{plural(result['runs'], 'run')} of `cooprint render JOB --format mp4 --duration {FRAMES[0]:g} "
        f"--fps {FRAMES[1]:g} --force` ({int(FRAMES[0] * FRAMES[1])} frames at 1280x720). Medians; "
        "commands/s and frames/s include the process start (about 0.5 s: Python, numpy, numba and its "
        "cached kernels). CPU s is user + system time: `simulate` runs its checks in two groups on two "
        "threads on this two-core machine (docs/simulator.md), so it may exceed the wall time; the system "
        "time is mostly page faults (on this virtual machine, memory a process frees "
        "goes back to the host within seconds, and the next process pays to get it again: 0.3-2 s for "
        "nefertiti's 0.9 GB). One untimed `simulate` runs first, so that numba's cache holds the kernels "
        "(the first run after installing compiles them: about 13 s).",
        "",
        f"**Targets (issues 5 and 13):** at least {TARGET_CMDS:,} commands/s for simulate (for a program "
        f"of at least {TARGET_SIZE:,} commands), at least {TARGET_FPS:g} frames/s for the MP4, and a print "
        f"time within ±{TARGET_TIME:.0%} of PrusaSlicer's estimate. Issue 5 asked for the rate on one core: "
        "commands per CPU second is that rate (what one core would do), judged apart.",
        "",
        "| mesh | commands | makespan h | findings: errors, overhang warnings | simulate s | CPU s | commands/s "
        "| commands per CPU s "
        "| peak MB | MP4 s | frames/s | MP4 peak MB |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    prusa_rows = []
    for row in result["meshes"]:
        if "error" in row:
            lines.append(f"| `{row['mesh']}` | failed: {row['error']} ||||||||||")
            continue
        sim, mp4 = row["simulate"], row["mp4"]
        rate = row["commands"] / sim["wall_median_s"] if sim["wall_median_s"] else None
        per_cpu = row["commands"] / sim["cpu_median_s"] if sim.get("cpu_median_s") else None
        fps = row["frames"] / mp4["wall_median_s"] if mp4["wall_median_s"] else None
        lines.append(f"| `{row['mesh']}` | {row['commands']:,} | {row['makespan_s'] / 3600:.1f} | "
                     f"{_errors(row['findings'])}, {row['findings'].get('overhang', 0):,} | "
                     f"{fmt(sim['wall_median_s'], '.2f')} | {fmt(sim.get('cpu_median_s'), '.2f')} | "
                     f"{fmt(rate, ',.0f')} | {fmt(per_cpu, ',.0f')} | "
                     f"{fmt(sim['peak_median_mb'], '.0f')} | {fmt(mp4['wall_median_s'], '.2f')} | {fmt(fps, '.1f')} | "
                     f"{fmt(mp4['peak_median_mb'], '.0f')} |")
        p = row.get("prusa")
        if p and "error" not in p and p.get("estimate_s"):
            prusa_rows.append(f"| `{row['mesh']}` | {p['estimate_s']:,.0f} | {p['ours_s']:,.0f} | "
                              f"{p['ours_s'] / p['estimate_s'] - 1:+.1%} | {p['constant_speed_s']:,.0f} | "
                              f"{p['constant_speed_s'] / p['estimate_s'] - 1:+.1%} | "
                              f"{fmt(p['simulate']['wall_median_s'], '.2f')} |")
        elif p:
            prusa_rows.append(f"| `{row['mesh']}` | failed: {p.get('error', 'no estimate in the G-code')} ||||||")
    if prusa_rows:
        lines += ["", "PrusaSlicer 2.5 slices the mesh (`../shared/peers/prusa_slice.sh`, the slicing settings above); "
                  "`cooprint simulate PrusaSlicer.gcode --out DIR --accel` plays its G-code with PrusaSlicer's machine "
                  "limits (normal mode: 1500 mm/s² extruding, retracting and travelling, jerk 10/10/0.2/2.5 mm/s, "
                  "the limits its G-code lists), and without acceleration for comparison; PrusaSlicer's own figure is "
                  "the `; estimated printing time (normal mode)` line at the end of its G-code.", "",
                  "| mesh | PrusaSlicer estimate s | cooprint --accel s | difference | cooprint constant speed s | "
                  "difference | simulate --accel wall s |",
                  "|---|---:|---:|---:|---:|---:|---:|", *prusa_rows]
    lines += ["", "Targets per mesh:", ""]
    for row in result["meshes"]:
        if "error" in row:
            continue
        rate = row["commands"] / row["simulate"]["wall_median_s"]
        fps = row["frames"] / row["mp4"]["wall_median_s"]
        p = row.get("prusa") or {}
        close = (abs(p["ours_s"] / p["estimate_s"] - 1) <= TARGET_TIME) if p.get("estimate_s") else None
        cpu = row["simulate"].get("cpu_median_s")
        one_core = f"; one core {'met' if row['commands'] / cpu >= TARGET_CMDS else 'missed'} " \
            f"({row['commands'] / cpu:,.0f} commands per CPU second)" if cpu and row["commands"] >= TARGET_SIZE else ""
        speed = ("met" if rate >= TARGET_CMDS else "missed") if row["commands"] >= TARGET_SIZE else \
            f"not judged: {row['commands']:,} commands, under {TARGET_SIZE:,}"
        lines.append(f"- `{row['mesh']}`: simulate {speed} "
                     f"({rate:,.0f} commands/s{one_core}), MP4 {'met' if fps >= TARGET_FPS else 'missed'} ({fps:.1f} frames/s)"
                     + ("" if close is None else f", time estimate {'met' if close else 'missed'}") + ".")
    return "\n".join(lines) + "\n"
