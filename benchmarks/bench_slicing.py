"""Slicing benchmark: ``cooprint slice`` against CuraEngine, PrusaSlicer and Slic3r.

All four slice the same STL with the same settings (0.2 mm layers, 2 perimeters, 4 top/bottom
layers, 20% infill, 0.4 mm nozzle, 1.75 mm filament); the peers run through the team's scripts
in ``../shared/peers``. Each tool is timed as a whole process, runs alternating (cooprint 1,
CuraEngine 1, PrusaSlicer 1, Slic3r 1, cooprint 2, ...), and the medians kept. The G-code of
each tool's last run is then read by the small reader below (independent of cooprint's code):
layers and extruded filament, compared with PrusaSlicer's.
"""
from __future__ import annotations

import math
import os
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path

from harness import (TIMED_OUT, TIMEOUT_S, BenchContext, Measurement, SourceWatch, fmt, plural,
                     prepare_mesh, ratio, stl_triangles, summarise, timed, tool_version)

NAME = "slicing"
TITLE = "Slicing"
DEFAULT_MESHES = ["benchy.stl", "nefertiti_1p6M.stl.gz"]
PEER_PACKAGES = ["cura-engine", "prusa-slicer", "slic3r"]
FILAMENT_MM = 1.75
SINGLE_RUN_TRIANGLES = 1_000_000
VOLUME_TOLERANCE = 0.10


@dataclass(frozen=True)
class Peer:
    """A peer slicer: display name, Debian package, script in ``shared/peers``, time limit."""

    name: str
    package: str
    script: str
    timeout_s: float = TIMEOUT_S


PEERS = [Peer("CuraEngine", "cura-engine", "cura_slice.sh"),
         Peer("PrusaSlicer", "prusa-slicer", "prusa_slice.sh"),
         Peer("Slic3r", "slic3r", "slic3r_slice.sh", timeout_s=600.0)]
REFERENCE = "PrusaSlicer"
SPEED_PEER = "CuraEngine"
MOVE = re.compile(r"^G[0-3](?!\d)")
WORD = re.compile(r"([XYZEF])(-?\d*\.?\d+)")
PRUSA_ESTIMATE = re.compile(r"^; estimated printing time \(normal mode\) = (.+)$", re.M)


def run(ctx: BenchContext, meshes: list[Path]) -> dict:
    """Benchmark every mesh; the JSON-ready result that ``render`` turns into Markdown."""
    version = tool_version([str(ctx.cooprint), "--version"]).replace(", version", "")
    tools = {"cooprint": version}
    peers = [] if ctx.skip_peers else PEERS
    env = []
    if peers:
        tools |= {p.name: f"{p.name} {package_version(p.package)}" for p in peers}
        env = ["env", f"CURA_DEB_DIR={cura_definitions(ctx.work)}"]
    commands = {"cooprint": lambda mesh, gcode: [str(ctx.cooprint), "slice", str(mesh), "--out",
                                                 str(gcode), "-q", "--force"]}
    for peer in peers:
        script = str(ctx.shared / "peers" / peer.script)
        commands[peer.name] = lambda mesh, gcode, script=script: [*env, script, str(mesh),
                                                                  str(gcode)]
    timeouts = {p.name: p.timeout_s for p in peers} | {"cooprint": TIMEOUT_S}
    watch = SourceWatch(ctx.src)
    rows = [bench_mesh(ctx, source, commands, timeouts, watch) for source in meshes]
    return {"runs": ctx.runs, "single_run_triangles": SINGLE_RUN_TRIANGLES, "tools": tools,
            "timeouts_s": timeouts, "sources_changed": watch.changed, "meshes": rows}


def package_version(package: str) -> str:
    """Upstream version of an installed Debian package (no epoch, no Debian revision)."""
    out = subprocess.run(["dpkg-query", "-W", "-f=${Version}", package], capture_output=True,
                         text=True, check=True).stdout
    return re.sub(r"^\d+:|[+-].*$", "", out)


def cura_definitions(work: Path) -> Path:
    """A folder holding the ``cura`` .deb's fdmprinter.def.json, which CuraEngine needs.

    ``$CURA_DEB_DIR`` or ``~/.cache/cura-deb`` when they have it, else the .deb is downloaded
    and unpacked once into ``work/cura-deb``.
    """
    definition = Path("usr/share/cura/resources/definitions/fdmprinter.def.json")
    candidates = [Path(p) for p in (os.environ.get("CURA_DEB_DIR"),
                                    Path.home() / ".cache" / "cura-deb") if p]
    found = next((d for d in candidates if (d / definition).is_file()), None)
    if found:
        return found
    target = work / "cura-deb"
    if not (target / definition).is_file():
        target.mkdir(parents=True, exist_ok=True)
        print(f"downloading the cura .deb into {target}", flush=True)
        subprocess.run(["apt-get", "download", "cura"], cwd=target, check=True)
        deb = max(target.glob("cura_*.deb"))
        subprocess.run(["dpkg", "-x", str(deb), str(target)], check=True)
    return target


def bench_mesh(ctx: BenchContext, source: Path, commands: dict, timeouts: dict,
               watch: SourceWatch) -> dict:
    """Alternating timed runs of every tool on one mesh, then their G-code read."""
    mesh = prepare_mesh(source, ctx.work)
    triangles = stl_triangles(mesh)
    runs = 1 if (triangles or 0) > SINGLE_RUN_TRIANGLES else ctx.runs
    out = ctx.work / NAME / mesh.stem
    gcodes = {tool: out / f"{tool}.gcode" for tool in commands}
    measured: dict[str, list[Measurement]] = {tool: [] for tool in commands}
    for i in range(1, runs + 1):
        for tool, command in commands.items():
            gcodes[tool].unlink(missing_ok=True)
            if tool == "cooprint":
                watch.check()
            measured[tool].append(timed(command(mesh, gcodes[tool]), out, tool, i, runs,
                                        timeouts[tool]))
            if tool == "cooprint":
                watch.check()
    tools = {}
    for tool, results in measured.items():
        ok = results[-1].returncode == 0 and gcodes[tool].exists()
        tools[tool] = summarise(results) | (read_gcode(gcodes[tool]) if ok else {})
    return {"mesh": source.name, "triangles": triangles, "runs": runs, "tools": tools}


def read_gcode(path: Path) -> dict:
    """Layers and filament of a G-code file.

    Extrusion is a positive E step on a move that also goes in X or Y, so retractions and the
    pure-E moves that undo them do not count. E is relative after M83 and absolute after M82
    (the default); G92 sets the E origin. Layers are the distinct heights (to 1 µm) at which
    something is extruded.
    """
    pos = {"X": 0.0, "Y": 0.0, "Z": 0.0, "E": 0.0}
    relative_e = False
    filament = 0.0
    heights = set()
    with open(path) as f:
        for raw in f:
            line = raw.split(";", 1)[0].strip()
            if not line:
                continue
            if line.startswith("M83"):
                relative_e = True
            elif line.startswith("M82"):
                relative_e = False
            elif re.match(r"G92(?!\d)", line):
                pos |= {k: float(v) for k, v in WORD.findall(line)} or dict.fromkeys(pos, 0.0)
            elif MOVE.match(line):
                words = {k: float(v) for k, v in WORD.findall(line)}
                e_step = 0.0
                if "E" in words:
                    e_step = words["E"] if relative_e else words["E"] - pos["E"]
                    pos["E"] = pos["E"] + e_step if relative_e else words["E"]
                moved = any(k in words and words[k] != pos[k] for k in "XY")
                pos |= {k: words[k] for k in "XYZ" if k in words}
                if e_step > 0 and moved:
                    filament += e_step
                    heights.add(round(pos["Z"], 3))
    text_tail = tail(path)
    estimate = PRUSA_ESTIMATE.search(text_tail)
    return {"layers": len(heights), "filament_mm": round(filament, 2),
            "volume_mm3": round(filament * math.pi * (FILAMENT_MM / 2) ** 2, 1),
            "estimated_time": estimate.group(1) if estimate else None}


def tail(path: Path, size: int = 1 << 16) -> str:
    """The last ``size`` bytes of a text file (where slicers put their summary comments)."""
    with open(path, "rb") as f:
        f.seek(max(0, path.stat().st_size - size))
        return f.read().decode(errors="replace")


def render(result: dict) -> str:
    """Markdown section (without its heading) for one slicing result."""
    rows = result["meshes"]
    slic3r_limit = result["timeouts_s"].get("Slic3r")
    lines = [
        "Every tool slices the same STL with the same settings: 0.2 mm layers (first layer "
        "0.2 mm), 2 perimeters, 4 top and 4 bottom layers, 20% rectilinear (CuraEngine: grid) "
        "infill, 0.4 mm nozzle, 1.75 mm filament, no skirt, brim or support. cooprint runs "
        "`cooprint slice MESH --out FILE.gcode -q --force` (its defaults are these settings); "
        "the peers run through `../shared/peers/{cura,prusa,slic3r}_slice.sh`. Gzipped meshes "
        "are unzipped once and every tool reads the same STL.",
        "",
        "Each tool runs as a whole process under `/usr/bin/time -v`, "
        f"{plural(result['runs'], 'run')} per tool alternating between the tools (meshes of "
        "more than "
        f"{result['single_run_triangles']:,} triangles: 1 run per tool, to bound the time); "
        "the table gives medians of wall time and of peak resident memory (MB = 2²⁰ bytes)"
        + (f". Slic3r is stopped after {slic3r_limit:g} s." if slic3r_limit else "."),
        "",
        "Layers and filament come from each tool's G-code, read by a small reader in "
        "`benchmarks/bench_slicing.py` (not cooprint's code): extruded filament is the sum of "
        "positive E steps on moves that also go in X or Y (so retract/unretract pairs do not "
        "count), with M82/M83 and G92 honoured; volume = length × π (1.75 mm / 2)²; layers "
        "are the distinct heights at which something is extruded.",
        "",
        f"**Target (issue):** cooprint's wall time and peak memory at most {SPEED_PEER}'s; "
        f"its extruded volume within ±{VOLUME_TOLERANCE:.0%} of {REFERENCE}'s.",
        "",
        f"| mesh | triangles | runs | tool | wall s | wall vs {SPEED_PEER} | peak MB | "
        f"peak vs {SPEED_PEER} | layers | filament mm | volume mm³ | volume vs {REFERENCE} |",
        "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|",
        *[line for row in rows for line in table_rows(row)],
        "",
        *verdict(rows),
    ]
    estimates = [f"`{row['mesh']}` {row['tools'][REFERENCE]['estimated_time']}" for row in rows
                 if (row["tools"].get(REFERENCE) or {}).get("estimated_time")]
    if estimates:
        lines += ["", f"{REFERENCE}'s own print-time estimate (normal mode), for information: "
                  + ", ".join(estimates) + "."]
    notes = [f"- `{row['mesh']}`: {tool} failed: `{data['error']}`" for row in rows
             for tool, data in row["tools"].items() if data["error"]]
    if notes:
        lines += ["", "Notes:", "", *notes]
    return "\n".join(lines) + "\n"


def table_rows(row: dict) -> list[str]:
    """The table lines of one mesh, one per tool."""
    speed = row["tools"].get(SPEED_PEER) or {}
    ref = row["tools"].get(REFERENCE) or {}
    lines = []
    for tool, data in row["tools"].items():
        status = failure(data)
        cells = [f"`{row['mesh']}`", fmt(row["triangles"], ",d"), str(row["runs"]), tool,
                 status or fmt(data["wall_median_s"], ".2f"),
                 ratio(data["wall_median_s"], speed.get("wall_median_s"), "×"),
                 status or fmt(data["peak_median_mb"], ".0f"),
                 ratio(data["peak_median_mb"], speed.get("peak_median_mb"), "×"),
                 fmt(data.get("layers"), "d"), fmt(data.get("filament_mm"), ",.0f"),
                 fmt(data.get("volume_mm3"), ",.0f"),
                 ratio(data.get("volume_mm3"), ref.get("volume_mm3"), "×")]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def failure(data: dict) -> str:
    """'timed out' or 'failed' when some run of the tool went wrong, else an empty string."""
    if not data["error"]:
        return ""
    word = "timed out" if data["error"].startswith(TIMED_OUT) else "failed"
    bad = sum(rc != 0 for rc in data["returncodes"])
    return word if len(data["returncodes"]) == 1 else f"{word} {bad}/{len(data['returncodes'])}"


def verdict(rows: list[dict]) -> list[str]:
    """Per mesh, whether cooprint meets the speed, memory and volume targets."""
    lines = []
    for row in rows:
        coop = row["tools"]["cooprint"]
        speed = row["tools"].get(SPEED_PEER) or {}
        ref = row["tools"].get(REFERENCE) or {}
        checks = []
        if coop["wall_median_s"] and speed.get("wall_median_s"):
            checks.append(("speed", coop["wall_median_s"] <= speed["wall_median_s"]))
            checks.append(("memory", coop["peak_median_mb"] <= speed["peak_median_mb"]))
        if coop.get("volume_mm3") and ref.get("volume_mm3"):
            off = abs(coop["volume_mm3"] / ref["volume_mm3"] - 1)
            checks.append(("volume", off <= VOLUME_TOLERANCE))
        met = ", ".join(f"{name} {'met' if ok else 'missed'}" for name, ok in checks)
        lines.append(f"- `{row['mesh']}`: {met or 'no comparison (a tool failed or was skipped)'}.")
    return ["Targets per mesh:", "", *lines] if lines else []
