"""Run the stage benchmarks and regenerate docs/benchmarks.md (``make bench``).

    .venv/bin/python benchmarks/run.py [--runs N] [--meshes NAME...] [--stages NAME...]
                                       [--skip-peers]

A stage is a module ``bench_<stage>.py`` with NAME, TITLE, DEFAULT_MESHES, PEER_PACKAGES
(Debian packages of its peers), optionally GENERATED (mesh name -> function that makes the mesh
in the work folder and returns its path), ``run(ctx, meshes) -> dict`` (JSON-ready, with at
least ``runs``, ``tools`` and ``sources_changed``) and ``render(result) -> str``; add it to
STAGES.
Each stage's result is kept in docs/bench/<NAME>.json and the page is rebuilt from all of them,
so re-running one stage keeps the sections of the others.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

import bench_chunking
import bench_cooperative
import bench_plans
import bench_scale
import bench_simulation
import bench_slicing
import bench_viewer
from harness import BenchContext, plural, resolve_meshes

STAGES = [bench_chunking, bench_slicing, bench_simulation, bench_plans, bench_cooperative, bench_scale,
          bench_viewer]
REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
WORK = REPO / "benchmarks" / "_work"
RESULTS = REPO / "docs" / "bench"
PAGE = REPO / "docs" / "benchmarks.md"
COOPRINT = REPO / ".venv" / "bin" / "cooprint"


def main(argv: list[str] | None = None) -> int:
    """Run the selected stages, save their results, rewrite the page."""
    args = parse_args(argv)
    if not SHARED.is_dir():
        print(f"benchmarks: {SHARED} not found (it holds the meshes and the peer tools); "
              "nothing was run and nothing written.")
        return 0
    if not COOPRINT.exists():
        print(f"benchmarks: {COOPRINT} not found; run `make test` or `make demo` first.")
        return 1
    stages = [s for s in STAGES if s.NAME in args.stages]
    ensure_packages(["time"] + ([] if args.skip_peers else peer_packages(stages)))
    ctx = BenchContext(shared=SHARED, work=WORK, cooprint=COOPRINT, src=REPO / "src",
                       runs=args.runs, skip_peers=args.skip_peers)
    machine = machine_info()
    prepare(ctx)
    for stage in stages:
        print(f"== {stage.TITLE}", flush=True)
        meshes = resolve_meshes(SHARED, args.meshes or stage.DEFAULT_MESHES, WORK,
                                getattr(stage, "GENERATED", None))
        result = stage.run(ctx, meshes)
        result.update(stage=stage.NAME, date=now(), machine=machine, revision=revision())
        if result["sources_changed"]:
            print("warning: cooprint's sources changed between its timed runs; re-run for clean "
                  "numbers")
        RESULTS.mkdir(parents=True, exist_ok=True)
        (RESULTS / f"{stage.NAME}.json").write_text(json.dumps(result, indent=1) + "\n")
    PAGE.write_text(render_page(load_results(), machine))
    print(f"wrote {PAGE.relative_to(REPO)}")
    return 0


#: Writes the warm-up part to argv[1] (run by the venv's Python: manifold3d and trimesh).
WARM_PART = """
import sys, trimesh
from manifold3d import Manifold
part = (Manifold.cube([20, 20, 10]) - Manifold.cube([24, 6, 4]).translate([-2, 7, 0.6])
        + Manifold.cube([0.7, 16, 8]).translate([24, 2, 0]) + Manifold.cube([1.2, 16, 8]).translate([28, 2, 0]))
mesh = part.to_mesh()
trimesh.Trimesh(mesh.vert_properties[:, :3], mesh.tri_verts).export(sys.argv[1])
"""


def prepare(ctx: BenchContext) -> None:
    """Make cooprint as an installed copy is after its first command, so that no timed run pays
    a one-time cost: its bytecode written (an editable install writes none, and with
    PYTHONDONTWRITEBYTECODE set none is ever cached) and its numba kernels compiled into their
    on-disk cache by slicing a small part (30-50 s after an install or a change of a kernel): a
    block with a tunnel (a bridge over it, overhanging perimeters at its ends) and a thin fin
    (thin wall, gap fill), so that the kernels of every role are compiled."""
    subprocess.run([sys.executable, "-m", "compileall", "-q", str(ctx.src)], check=True)
    ctx.work.mkdir(parents=True, exist_ok=True)
    box = ctx.work / "warm_part.stl"
    subprocess.run([sys.executable, "-c", WARM_PART, str(box)], check=True)
    subprocess.run([str(ctx.cooprint), "slice", str(box), "--out", str(ctx.work / "warm_part.gcode"),
                    "-q", "--force"], check=True)


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line options."""
    names = [s.NAME for s in STAGES]
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=3, help="timed runs per tool and mesh (default 3)")
    p.add_argument("--meshes", nargs="+", metavar="NAME",
                   help="meshes of ../shared/meshes (default: each stage's list, absent skipped)")
    p.add_argument("--stages", nargs="+", choices=names, default=names,
                   help="stages to run (default: all); the others keep their saved results")
    p.add_argument("--skip-peers", action="store_true", help="time cooprint only")
    args = p.parse_args(argv)
    if args.runs < 1:
        p.error("--runs must be at least 1")
    return args


def ensure_packages(packages: list[str]) -> None:
    """apt-get install the Debian packages that are missing (apt-get update first if needed)."""
    missing = [p for p in packages if not installed(p)]
    if not missing:
        return
    install = ["apt-get", "install", "-y", *missing]
    print("installing " + " ".join(missing), flush=True)
    if subprocess.run(install).returncode != 0:
        subprocess.run(["apt-get", "update"], check=True)
        subprocess.run(install, check=True)


def peer_packages(stages: list) -> list[str]:
    """The Debian packages of the stages' peers, each once."""
    return list(dict.fromkeys(p for s in stages for p in s.PEER_PACKAGES))


def installed(package: str) -> bool:
    """Whether dpkg has ``package`` installed."""
    proc = subprocess.run(["dpkg-query", "-W", "-f=${Status}", package], capture_output=True,
                          text=True)
    return proc.returncode == 0 and proc.stdout.endswith(" installed")


def machine_info() -> dict:
    """CPU count, CPU model, RAM and Python version of this machine."""
    cpuinfo = Path("/proc/cpuinfo").read_text()
    model = next((line.split(":", 1)[1].strip() for line in cpuinfo.splitlines()
                  if line.startswith("model name")), platform.processor() or "unknown")
    meminfo = Path("/proc/meminfo").read_text().split()
    ram_kb = int(meminfo[meminfo.index("MemTotal:") + 1])
    return {"nproc": len(os.sched_getaffinity(0)), "cpu": model,
            "ram_gib": round(ram_kb / 2 ** 20, 1), "python": platform.python_version()}


def revision() -> str:
    """``git describe --always --dirty`` of the checkout, or 'unknown'."""
    proc = subprocess.run(["git", "-C", str(REPO), "describe", "--always", "--dirty"],
                          capture_output=True, text=True)
    return proc.stdout.strip() if proc.returncode == 0 else "unknown"


def now() -> str:
    """Local date and time, to the minute, with the time zone."""
    return datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")


def load_results() -> list[dict]:
    """Saved results of the known stages, in STAGES order."""
    paths = [RESULTS / f"{s.NAME}.json" for s in STAGES]
    return [json.loads(p.read_text()) for p in paths if p.exists()]


def describe(machine: dict) -> str:
    """One-line description of a machine."""
    return (f"{machine['nproc']} CPUs ({machine['cpu']}), {machine['ram_gib']:g} GiB RAM, "
            f"Python {machine['python']}")


def tool_versions(results: list[dict]) -> str:
    """Versions of every tool the saved results used, a tool measured at two versions twice."""
    versions: dict[str, list[str]] = {}
    for result in results:
        for tool, version in result["tools"].items():
            if version not in versions.setdefault(tool, []):
                versions[tool].append(version)
    return "; ".join(" / ".join(v) for v in versions.values()) or "—"


def render_page(results: list[dict], machine: dict) -> str:
    """The whole of docs/benchmarks.md."""
    modules = {s.NAME: s for s in STAGES}
    parts = [
        "# cooprint benchmarks",
        "",
        "_Generated by `benchmarks/run.py`; do not edit by hand._",
        "",
        "Re-run with `make bench` (or `.venv/bin/python benchmarks/run.py --runs 3`). Options: "
        "`--runs N` timed runs per tool (default 3), `--meshes NAME...` (default: each stage's "
        "list; meshes absent from `../shared/meshes` are skipped), `--stages NAME...` "
        f"(default: all of {', '.join(modules)}), `--skip-peers` (time cooprint only). The "
        "peers are installed with `apt-get install -y "
        + " ".join(["time", *peer_packages(STAGES)]) + "` when missing. Each stage's raw "
        "numbers are kept in `docs/bench/<stage>.json` and this page is rebuilt from all of "
        "them, so re-running one stage keeps the others' sections.",
        "",
        f"- **Date:** {now()}",
        f"- **Machine:** {describe(machine)}",
        f"- **Tools:** {tool_versions(results)}",
    ]
    for result in results:
        stage = modules[result["stage"]]
        parts += ["", f"## {stage.TITLE}", "", measured(result, machine), "",
                  stage.render(result).rstrip("\n")]
    return "\n".join(parts) + "\n"


def measured(result: dict, machine: dict) -> str:
    """When, where and on which cooprint revision a stage was measured."""
    where = "" if result["machine"] == machine else f" on {describe(result['machine'])}"
    line = (f"_Measured {result['date']}{where} at cooprint revision `{result['revision']}`, "
            f"median of {plural(result['runs'], 'run')} per tool._")
    if result["sources_changed"]:
        line += ("\n\n**Warning:** cooprint's sources changed between its timed runs, so they "
                 "mix versions; re-run this stage.")
    return line


if __name__ == "__main__":
    sys.exit(main())
