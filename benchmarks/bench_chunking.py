"""Chunking benchmark: ``cooprint chunk`` against the seed's Blender chunker, same planes.

Both tools cut along +Y through the bounding-box centre at min z with slope THETA_DEG, plane
spacing SHIFT_MM and top width 0, so they should produce the same chunks. Each is timed as a
whole process, runs alternating (cooprint 1, Blender 1, cooprint 2, ...), and the medians kept.
"""
from __future__ import annotations

import json
from pathlib import Path

from harness import (BenchContext, Measurement, SourceWatch, fmt, median, plural, prepare_mesh,
                     ratio, stl_triangles, summarise, time_process, timed, tool_version)

NAME = "chunking"
TITLE = "Chunking"
DEFAULT_MESHES = ["cylinder_tall.stl", "baja_car.stl", "nefertiti.stl", "benchy.stl",
                  "nefertiti_1p6M.stl.gz"]
PEER_PACKAGES = ["blender", "python3-numpy"]
THETA_DEG = 60.0
SHIFT_MM = 60.0
ROBOT_TOML = """\
# Written by benchmarks/bench_chunking.py: a robot big enough for THETA_DEG and SHIFT_MM.
[robot]
build_depth = 2000.0
nozzle_height = 100.0
nozzle_depth = 10.0
"""
SPEED_TARGET = 10.0
MEMORY_TARGET = 0.5


def run(ctx: BenchContext, meshes: list[Path]) -> dict:
    """Benchmark every mesh; the JSON-ready result that ``render`` turns into Markdown."""
    robot = ctx.work / "bench_robot.toml"
    robot.parent.mkdir(parents=True, exist_ok=True)
    robot.write_text(ROBOT_TOML)
    tools = {"cooprint": tool_version([str(ctx.cooprint), "--version"]).replace(", version", "")}
    if not ctx.skip_peers:
        tools["Blender"] = tool_version(["blender", "--version"])
    watch = SourceWatch(ctx.src)
    rows = [bench_mesh(ctx, source, robot, watch) for source in meshes]
    startup = {"cooprint": startup_s(ctx, [str(ctx.cooprint), "--version"], "cooprint")}
    if not ctx.skip_peers:
        startup["Blender"] = startup_s(ctx, ["blender", "-b", "--python-expr", "pass"], "blender")
    return {"theta_deg": THETA_DEG, "shift_mm": SHIFT_MM, "runs": ctx.runs, "startup_s": startup,
            "peer_script": str(blender_script(ctx)), "tools": tools,
            "sources_changed": watch.changed, "meshes": rows}


def startup_s(ctx: BenchContext, cmd: list[str], tool: str) -> float | None:
    """Median wall time of starting the tool and doing nothing: the floor under every run."""
    logs = ctx.work / NAME / "startup"
    return median([time_process(cmd, logs, f"{tool}_{i}").wall_s for i in range(1, ctx.runs + 1)])


def blender_script(ctx: BenchContext) -> Path:
    """The seed's chunker, run inside Blender."""
    return ctx.shared / "peers" / "blender_chunker.py"


def bench_mesh(ctx: BenchContext, source: Path, robot: Path, watch: SourceWatch) -> dict:
    """Alternating timed runs of both tools on one mesh, then their volumes compared."""
    mesh = prepare_mesh(source, ctx.work)
    out = ctx.work / NAME / mesh.stem
    coop_cmd = [str(ctx.cooprint), "chunk", str(mesh), "--out", str(out / "cooprint"),
                "--theta", str(THETA_DEG), "--shift", str(SHIFT_MM), "--robot", str(robot),
                "--no-picture", "--quiet", "--force"]
    blender_cmd = ["blender", "-b", "--python-exit-code", "1", "-P", str(blender_script(ctx)),
                   "--", str(mesh), str(out / "blender"), str(THETA_DEG), str(SHIFT_MM)]
    coop_runs: list[Measurement] = []
    blender_runs: list[Measurement] = []
    for i in range(1, ctx.runs + 1):
        watch.check()
        coop_runs.append(timed(coop_cmd, out, "cooprint", i, ctx.runs))
        watch.check()
        if not ctx.skip_peers:
            blender_runs.append(timed(blender_cmd, out, "blender", i, ctx.runs))
    coop = summarise(coop_runs) | cooprint_volumes(out / "cooprint" / "job.json", coop_runs)
    row = {"mesh": source.name, "triangles": stl_triangles(mesh), "cooprint": coop,
           "blender": None}
    if blender_runs:
        row["blender"] = summarise(blender_runs) | blender_volumes(blender_runs)
        row["chunk_diff"] = compare_chunks(coop["volumes"], row["blender"]["volumes"])
    return row


def cooprint_volumes(job_json: Path, runs: list[Measurement]) -> dict:
    """Chunk volumes and volume error from the job.json of cooprint's last run."""
    if runs[-1].returncode != 0 or not job_json.exists():
        return {"chunks": None, "vol_err": None, "volumes": {}}
    job = json.loads(job_json.read_text())
    volumes = {c["id"]: c["volume_mm3"] for c in job["chunks"]}
    return {"chunks": len(volumes), "vol_err": job["stats"]["volume_rel_error"],
            "volumes": volumes}


def blender_volumes(runs: list[Measurement]) -> dict:
    """Chunk volumes and volume error from the JSON lines of Blender's last run.

    Chunk ``center`` is cooprint's ``C``; side chunks keep their names (``L1``, ``R2``...).
    Chunks the script planned but found empty (no triangles) are counted apart.
    """
    if runs[-1].returncode != 0:
        return {"chunks": None, "empty_chunks": None, "vol_err": None, "volumes": {}}
    lines = [json.loads(s) for s in runs[-1].stdout.splitlines() if s.startswith("{")]
    chunks = [d for d in lines if "chunk" in d]
    summary = next(d for d in lines if d.get("summary"))
    volumes = {("C" if d["chunk"] == "center" else d["chunk"]): d["volume"]
               for d in chunks if d["triangles"] > 0}
    return {"chunks": len(volumes), "empty_chunks": len(chunks) - len(volumes),
            "vol_err": summary["rel_err"], "volumes": volumes}


def compare_chunks(coop: dict[str, float], blender: dict[str, float]) -> dict:
    """Largest |V_cooprint - V_Blender| / V_Blender over the chunk ids both tools produced."""
    common = sorted(set(coop) & set(blender))
    diffs = {cid: abs(coop[cid] - blender[cid]) / abs(blender[cid]) for cid in common}
    worst = max(diffs, key=diffs.get) if diffs else None
    return {"max_rel": diffs.get(worst), "worst_chunk": worst, "compared": len(common),
            "only_cooprint": sorted(set(coop) - set(blender)),
            "only_blender": sorted(set(blender) - set(coop))}


def render(result: dict) -> str:
    """Markdown section (without its heading) for one chunking result."""
    rows = result["meshes"]
    lines = [
        f"Both tools cut each mesh along +Y with slope θ = {result['theta_deg']:g}°, plane "
        f"spacing s = {result['shift_mm']:g} mm and top width 0, through the bounding-box "
        "centre at min z (the seed's planes). Blender runs the seed's method, "
        "`../shared/peers/blender_chunker.py` (bmesh bisect + `holes_fill` caps). cooprint gets "
        "`--robot benchmarks/_work/bench_robot.toml` (build depth 2000 mm) so that it accepts "
        "these planes. Gzipped meshes are unzipped once and both tools read the same STL.",
        "",
        "Each tool runs as a whole process under `/usr/bin/time -v`, "
        f"{plural(result['runs'], 'run')} alternating between the tools; the table gives "
        "medians of wall time and of peak resident memory (MB = 2²⁰ bytes).",
        "",
        f"**Target (issue):** cooprint at least {SPEED_TARGET:g}× faster than Blender and at "
        f"most {MEMORY_TARGET:g}× its memory, with the same volumes.",
        "",
        "| mesh | triangles | chunks | cooprint wall s | Blender wall s | speed-up "
        "(Blender/cooprint) | cooprint peak MB | Blender peak MB | memory ratio "
        "(cooprint/Blender) | cooprint vol err | Blender vol err | max per-chunk vol diff |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
        *[table_row(row) for row in rows],
        "",
        "Volume error: |Σ chunk volumes − mesh volume| / mesh volume, as each tool reports it "
        "(cooprint: `stats.volume_rel_error` of job.json; Blender: `rel_err` of its summary "
        "line). Per-chunk diff: largest |V_cooprint − V_Blender| / V_Blender over the chunk ids "
        "both tools produced (Blender's `chunk_center` is cooprint's `C`).",
        "",
        *verdict(rows),
        *startup_note(result.get("startup_s") or {}),
    ]
    notes = [note for row in rows for note in mesh_notes(row)]
    if notes:
        lines += ["", "Notes:", "", *notes]
    return "\n".join(lines) + "\n"


def startup_note(startup: dict) -> list[str]:
    """What starting each tool costs before it reads a byte: on small meshes the speed-up can
    be no larger than the ratio of these."""
    if not startup:
        return []
    parts = [f"{tool} {fmt(sec, '.2f')} s" for tool, sec in startup.items()]
    return ["", "Start-up alone (median, doing nothing): " + ", ".join(parts) + ". On small meshes "
            "the whole run is mostly start-up (Python and numpy for cooprint), which bounds the "
            "speed-up there."]


def table_row(row: dict) -> str:
    """One table line."""
    c, b = row["cooprint"], row["blender"] or {}
    cells = [f"`{row['mesh']}`", fmt(row["triangles"], ",d"), chunk_count(c, b),
             wall(c), wall(b), ratio(b.get("wall_median_s"), c["wall_median_s"], "×"),
             peak(c), peak(b), ratio(c["peak_median_mb"], b.get("peak_median_mb"), ""),
             fmt(c["vol_err"], ".1e"), fmt(b.get("vol_err"), ".1e"), chunk_diff(row)]
    return "| " + " | ".join(cells) + " |"


def wall(tool: dict) -> str:
    """Median wall time, or why there is none."""
    return failed(tool) or fmt(tool.get("wall_median_s"), ".2f")


def peak(tool: dict) -> str:
    """Median peak memory, or why there is none."""
    return failed(tool) or fmt(tool.get("peak_median_mb"), ".0f")


def failed(tool: dict) -> str:
    """'failed' when some run of the tool failed, else an empty string."""
    bad = [rc for rc in tool.get("returncodes", []) if rc != 0]
    return f"failed {len(bad)}/{len(tool['returncodes'])}" if bad else ""


def chunk_count(c: dict, b: dict) -> str:
    """The chunk count, or 'cooprint / Blender' when they differ."""
    if not b or c["chunks"] == b.get("chunks"):
        return fmt(c["chunks"], "d")
    return f"{fmt(c['chunks'], 'd')} / {fmt(b.get('chunks'), 'd')}"


def chunk_diff(row: dict) -> str:
    """Largest per-chunk relative volume difference and the chunk it occurs in."""
    diff = row.get("chunk_diff")
    if not diff or diff["max_rel"] is None:
        return "—"
    return f"{diff['max_rel']:.1e} ({diff['worst_chunk']})"


def verdict(rows: list[dict]) -> list[str]:
    """Which meshes meet the speed and the memory target."""
    both = [r for r in rows if r["blender"] and r["blender"]["wall_median_s"]
            and r["cooprint"]["wall_median_s"]]
    if not both:
        skipped = not any(r["blender"] for r in rows)
        return ["No comparison: " + ("Blender was not run (`--skip-peers`)." if skipped
                                      else "no mesh where both tools succeeded.")]
    fast = [r["mesh"] for r in both
            if r["blender"]["wall_median_s"] / r["cooprint"]["wall_median_s"] >= SPEED_TARGET]
    lean = [r["mesh"] for r in both
            if r["cooprint"]["peak_median_mb"] / r["blender"]["peak_median_mb"] <= MEMORY_TARGET]
    return [f"Speed target met on {len(fast)} of {len(both)} meshes"
            f"{': ' + ', '.join(f'`{m}`' for m in fast) if fast else ''}. "
            f"Memory target met on {len(lean)} of {len(both)}"
            f"{': ' + ', '.join(f'`{m}`' for m in lean) if lean else ''}."]


def mesh_notes(row: dict) -> list[str]:
    """Bullet lines for failures and chunk sets that differ between the tools."""
    notes = []
    for tool, data in (("cooprint", row["cooprint"]), ("Blender", row["blender"])):
        if data and data["error"]:
            notes.append(f"- `{row['mesh']}`: {tool} failed: `{data['error']}`")
    diff = row.get("chunk_diff") or {}
    only = (("cooprint", diff.get("only_cooprint")), ("Blender", diff.get("only_blender")))
    for tool, ids in only:
        if ids:
            notes.append(f"- `{row['mesh']}`: chunks only {tool} produced: {', '.join(ids)}")
    empty = (row["blender"] or {}).get("empty_chunks")
    if empty:
        notes.append(f"- `{row['mesh']}`: Blender also planned {empty} empty side chunk(s) "
                     "(no triangles), not counted.")
    return notes
