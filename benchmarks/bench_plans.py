"""Plan benchmark: does every plan cooprint writes pass its own simulator's checks?

Every closed mesh is planned for one and for two robots with ``cooprint run MESH --robots N
--simulate`` and the findings of the simulation are counted by kind. A check that cries wolf is
as useless as one that sleeps: an error-level finding on a plan cooprint made is either a planner
bug or a false alarm of the check, and both are failures of this stage. Overhang warnings are
counted too (they do not make a plan fail)."""
from __future__ import annotations

import json
from pathlib import Path

from harness import BenchContext, fmt, prepare_mesh, timed, tool_version

NAME = "plans"
TITLE = "Plans pass their own checks"
#: The closed meshes of ../shared/meshes (the open ones are repaired by the loader, and are not
#: the question here).
DEFAULT_MESHES = ["cylinder_tall.stl", "spot.stl", "baja_car.stl", "benchy.stl", "beetle_fixed.stl",
                  "occt_tr12j_housing.stl", "nefertiti.stl"]
PEER_PACKAGES: list[str] = []
ROBOTS = (1, 2)


def run(ctx: BenchContext, meshes: list[Path]) -> dict:
    """For every mesh and robot count: ``cooprint run --simulate`` once (timed, whole process),
    its summary's finding counts and makespan."""
    cp = str(ctx.cooprint)
    tools = {"cooprint": tool_version([cp, "--version"]).replace(", version", "")}
    rows = []
    for source in meshes:
        mesh = prepare_mesh(source, ctx.work)
        for n in ROBOTS:
            out = ctx.work / NAME / f"{mesh.stem}_{n}"
            job = out / "job"
            out.mkdir(parents=True, exist_ok=True)
            m = timed([cp, "run", str(mesh), "--robots", str(n), "--out", str(job), "--simulate", "-q",
                       "--no-picture", "--force"], out, "run", 1, 1)
            summary_path = job / "sim" / "summary.json"
            if m.returncode not in (0, 1) or not summary_path.exists():
                rows.append({"mesh": source.name, "robots": n, "error": m.error_line or f"exit {m.returncode}"})
                continue
            summary = json.loads(summary_path.read_text())
            rows.append({"mesh": source.name, "robots": n, "returncode": m.returncode, "wall_s": m.wall_s,
                         "peak_mb": round(m.peak_mb, 1), "makespan_s": summary["makespan_s"],
                         "checked": summary["checked"], "findings": summary["finding_counts"]})
    return {"runs": 1, "tools": tools, "sources_changed": False, "meshes": rows}


def _errors(counts: dict) -> dict:
    return {k: v for k, v in counts.items() if v and k != "overhang"}


def render(result: dict) -> str:
    """The Markdown section for docs/benchmarks.md."""
    lines = [
        "Each closed mesh of `../shared/meshes` is planned for one and for two robots with `cooprint run MESH "
        "--robots N --out JOB --simulate -q --no-picture` (one whole-process run, planning and simulation "
        "together) and the findings of its simulation are counted by kind.",
        "",
        "**Target (issue 13):** no error-level finding of any kind on any plan cooprint writes (an error on a "
        "plan cooprint made is a planner bug or a false alarm; both fail). Overhang warnings are listed, "
        "not judged.",
        "",
        "| mesh | robots | run --simulate s | peak MB | makespan h | error findings | overhang warnings | checks run |",
        "|---|---:|---:|---:|---:|---|---:|---|",
    ]
    verdicts = []
    for row in result["meshes"]:
        if "error" in row:
            lines.append(f"| `{row['mesh']}` | {row['robots']} | failed: {row['error']} ||||||")
            verdicts.append(f"- `{row['mesh']}`, {row['robots']} robot(s): failed to plan ({row['error']}).")
            continue
        errors = _errors(row["findings"])
        shown = ", ".join(f"{k} {v:,}" for k, v in errors.items()) or "none"
        lines.append(f"| `{row['mesh']}` | {row['robots']} | {fmt(row['wall_s'], '.1f')} | "
                     f"{fmt(row['peak_mb'], '.0f')} | {row['makespan_s'] / 3600:.2f} | {shown} | "
                     f"{row['findings'].get('overhang', 0):,} | {len(row['checked'])} |")
        if errors:
            verdicts.append(f"- `{row['mesh']}`, {row['robots']} robot(s): missed ({shown}).")
    lines += ["", "Checks run: " + ", ".join(result["meshes"][0]["checked"]) + "."
              if result["meshes"] and "checked" in result["meshes"][0] else ""]
    lines += ["", "Target: " + ("met on every plan." if not verdicts else "missed:"), *verdicts]
    return "\n".join(lines) + "\n"
