"""Calibrate the run estimate (:mod:`cooprint.io.estimate`) on generated parts.

Each part is planned and written as ``cooprint run`` does it (``coop_job`` + ``write_coop_bundle``,
the same malloc set-up), in a child process under ``/usr/bin/time -v`` (wall time, peak resident
memory), which also records when each stage started and ended, each robot's commands and the
model's features of its chunks, and the size of every file written. The constants of
:class:`~cooprint.io.estimate.Calibration` are then fitted by least squares and printed, with
each part's estimate against what the run did (the errors to quote in the docstring).

    PYTHONPATH=src .venv/bin/python benchmarks/calibrate_estimates.py            # every part (minutes)
    PYTHONPATH=src .venv/bin/python benchmarks/calibrate_estimates.py --parts box-s car
    PYTHONPATH=src .venv/bin/python benchmarks/calibrate_estimates.py --refit    # fit the saved runs again

Results are kept in ``benchmarks/_work/calibrate/<part>/result.json`` (``--refit`` reads them).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
#: Bytes per command of a Program's columns (kind 1, xyz 24, role 1, width 8, layer 4, height 8,
#: chunk 2, event 4).
PROGRAM_BYTES = 52
WORK = HERE / "_work" / "calibrate"
#: The large-nozzle profile's slicing settings (as benchmarks/bench_cooperative.py's large parts).
LARGE = {"slicing.nozzle_diameter": 1.0, "slicing.layer_height": 0.6, "slicing.first_layer_height": 0.6,
         "slicing.extrusion_width": 1.1}


def parts() -> dict[str, tuple[object, dict]]:
    """Part name -> (a function making its manifold, settings overrides). Boxes of several
    sizes and proportions, a hollow box (thin walls: short fill lines), the car (curved: many
    section vertices), and the large-nozzle profile on a box and a car."""
    import manifold3d as m3d

    from cooprint.models import car_manifold

    def box(x: float, y: float, z: float):
        return lambda: m3d.Manifold.cube((x, y, z), center=True).translate((0, 0, z / 2))

    def hollow(x: float, y: float, z: float, wall: float):
        def make():
            outer = m3d.Manifold.cube((x, y, z), center=True)
            inner = m3d.Manifold.cube((x - 2 * wall, y - 2 * wall, z + 2), center=True)
            return (outer - inner).translate((0, 0, z / 2))
        return make

    return {
        "box-s": (box(300, 600, 40), {}),
        "box-m": (box(200, 1200, 100), {}),
        "box-tall": (box(150, 400, 250), {}),
        "hollow": (hollow(400, 600, 120, 10), {}),
        "car": (lambda: car_manifold(700), {}),
        "box-large": (box(600, 1200, 200), LARGE),
        "car-large": (lambda: car_manifold(1500), LARGE),
    }


# ---------------------------------------------------------------------------------------------
# the child: one run, measured

def child(mesh: str, out: str, overrides_json: str, result_path: str) -> None:
    """Plan and write ``mesh`` as ``cooprint run`` does; write what was measured to ``result_path``."""
    from cooprint.cli import _lean_malloc
    from cooprint.config import load_settings
    from cooprint.io.estimate import chunk_features, estimate_job, features_matrix
    from cooprint.jobs import _stream_commands, coop_job, write_coop_bundle

    _lean_malloc()
    t0 = time.perf_counter()
    stages: dict[str, list[float]] = {}

    def progress(stage: str, done: int, total: int) -> None:
        now = time.perf_counter() - t0
        span = stages.setdefault(stage, [now, now])
        span[1] = now

    settings = load_settings(overrides=json.loads(overrides_json))
    # streamed as `cooprint run` (jobs.run_job): the chunks' commands spooled to disk as they
    # are sliced, the files written piece by piece from there
    spool = Path(out).parent / (Path(out).name + ".spool")
    shutil.rmtree(spool, ignore_errors=True)
    job = coop_job(mesh, settings, 2, progress, spool=spool)
    t_job = time.perf_counter() - t0
    write_coop_bundle(job, out, True, True, progress)
    t_end = time.perf_counter() - t0
    s = settings.slicing
    feats = {c.id: chunk_features(c.vertices, c.faces, s, c.id) for c in job.chunked.chunks.chunks}
    seqs = {r: list(seq) for r, seq in job.chunked.assignment.sequences.items()}
    robots = {}
    for r, stream in job.streams.items():
        commands = _stream_commands(stream, job.store)
        robots[r] = {"commands": int(commands), "chunks": seqs.get(r, []),
                     "features": features_matrix([feats[c] for c in seqs.get(r, [])]).tolist(),
                     "coop_bytes": os.path.getsize(Path(out) / "robots" / f"{r}.coop"),
                     "gcode_bytes": os.path.getsize(Path(out) / "robots" / f"{r}.gcode"),
                     "program_nbytes": int(commands * PROGRAM_BYTES)}
    layer_nbytes = 0  # a streamed job keeps no layers
    shutil.rmtree(spool, ignore_errors=True)
    sizes = {str(p.relative_to(out)): p.stat().st_size for p in Path(out).rglob("*") if p.is_file()}
    est = estimate_job(job.chunked.chunks, settings, seqs)
    Path(result_path).write_text(json.dumps({
        "stages": stages, "t_job": t_job, "t_end": t_end, "robots": robots, "sizes": sizes,
        "layers": sum(f.layers for f in feats.values()), "chunks": len(feats),
        "layer_nbytes": layer_nbytes, "overrides": json.loads(overrides_json),
        "chunk_features": {cid: features_matrix([f]).tolist() for cid, f in feats.items()},
        "estimate_bytes": est.bytes, "estimate_memory": est.memory_bytes, "estimate_seconds": est.seconds,
    }, indent=1))


# ---------------------------------------------------------------------------------------------
# the parent: run the parts, fit

def measure(name: str, make, overrides: dict) -> dict:
    """Run the child on ``name`` under ``/usr/bin/time -v``; its result with wall and peak RSS."""
    import trimesh

    folder = WORK / name
    folder.mkdir(parents=True, exist_ok=True)
    man = make().to_mesh64()
    mesh = folder / "part.stl"
    trimesh.Trimesh(np.asarray(man.vert_properties)[:, :3], np.asarray(man.tri_verts)).export(mesh)
    report, result = folder / "time.txt", folder / "result.json"
    env = dict(os.environ, PYTHONPATH=str(HERE.parent / "src"))
    cmd = ["/usr/bin/time", "-v", "-o", str(report), sys.executable, __file__, "--child", str(mesh),
           str(folder / "out"), json.dumps(overrides), str(result)]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"{name}: the run failed:\n{proc.stderr[-3000:]}")
    sys.path.insert(0, str(HERE))
    from harness import parse_gnu_time

    wall, peak_kb, cpu = parse_gnu_time(report.read_text())
    data = json.loads(result.read_text())
    data.update(name=name, wall_s=wall, peak_bytes=peak_kb * 1024, cpu_s=cpu)
    result.write_text(json.dumps(data, indent=1))
    print(f"  {name}: {time.perf_counter() - t0:.0f} s, peak {peak_kb / 1e6:.2f} GB, "
          f"{sum(r['commands'] for r in data['robots'].values()):,} commands", flush=True)
    return data


def _lstsq(x: np.ndarray, y: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Least squares of ``x @ c = y`` with relative weights, every coefficient >= 0 (a negative
    one is dropped and the rest fitted again: a count cannot make fewer commands)."""
    keep = list(range(x.shape[1]))
    while True:
        sol, *_ = np.linalg.lstsq(x[:, keep] * weights[:, None], y * weights, rcond=None)
        if (sol >= 0).all() or len(keep) == 1:
            out = np.zeros(x.shape[1])
            out[keep] = np.maximum(sol, 0)
            return out
        keep.pop(int(np.argmin(sol)))


def fit(results: list[dict]) -> None:
    """Fit the constants on ``results`` and print them, with each part's errors."""
    from cooprint.io.estimate import CALIBRATION, default_cores

    rows = [(d["name"], r) for d in results for r in d["robots"].values() if r["commands"] > 0]
    x = np.array([r["features"] for _, r in rows])
    y = np.array([r["commands"] for _, r in rows], float)
    k = _lstsq(x, y, 1.0 / y)  # relative errors: small and large parts weigh alike
    coop = sum(r["coop_bytes"] for _, r in rows) / y.sum()
    gcode = sum(r["gcode_bytes"] for _, r in rows) / y.sum()
    cmds = np.array([sum(r["commands"] for r in d["robots"].values()) for d in results], float)
    layers = np.array([d["layers"] for d in results], float)
    st = [d["stages"] for d in results]
    cut_end = np.array([s["cut"][1] for s in st])
    slice_s = np.array([s["slice"][1] for s in st]) - cut_end
    program_s = np.array([s["program"][1] - s["program"][0] for s in st])
    write_s = np.array([s["write"][1] - s["program"][1] for s in st])
    rest_s = np.array([d["t_end"] for d in results]) - cut_end
    sl = _lstsq(np.column_stack([layers, cmds]), slice_s, 1.0 / np.maximum(slice_s, 1.0))
    prog = float(program_s.sum() / cmds.sum())
    wr = float(write_s.sum() / cmds.sum())
    start = float(np.median(rest_s - slice_s - program_s - write_s))
    peak = np.array([d["peak_bytes"] for d in results], float)
    # the peak grows with the whole job (everything held until written: today's coop_job) or
    # with the largest chunks in flight (a streamed run): both fitted, the closer one kept
    mem = _lstsq(np.column_stack([np.ones_like(cmds), cmds]), peak, 1.0 / peak)
    job_err = float(np.sqrt(np.mean(((mem[0] + mem[1] * cmds) / peak - 1) ** 2)))
    chunk_mem = np.zeros(2)
    chunk_err = float("inf")
    if all("chunk_features" in d for d in results):
        flight = default_cores() + 1
        largest = np.array([sum(sorted((np.array(f) @ k for f in d["chunk_features"].values()), reverse=True)[:flight])
                            for d in results])
        chunk_mem = _lstsq(np.column_stack([np.ones_like(largest), largest]), peak, 1.0 / peak)
        chunk_err = float(np.sqrt(np.mean(((chunk_mem[0] + chunk_mem[1] * largest) / peak - 1) ** 2)))
    print(f"peak memory: whole-job model rms {job_err:.1%}, chunks-in-flight model rms {chunk_err:.1%}")
    if chunk_err < job_err:
        mem_base, job_cmd, chunk_cmd = chunk_mem[0], 0.0, chunk_mem[1]
    else:
        mem_base, job_cmd, chunk_cmd = mem[0], mem[1], 0.0
    cal = replace(CALIBRATION, vertex=round(float(k[0]), 3), loop=round(float(k[1]), 3), line=round(float(k[2]), 3), layer=round(float(k[3]), 3),
                  coop_bytes=round(float(coop), 2), gcode_bytes=round(float(gcode), 2), start_s=round(start, 2),
                  slice_layer_s=float(f"{sl[0]:.3g}"), slice_command_s=float(f"{sl[1]:.3g}"),
                  program_command_s=float(f"{prog:.3g}"), write_command_s=float(f"{wr:.3g}"), slice_cores=2,
                  memory_base=float(f"{mem_base:.3g}"), memory_job_command=float(f"{job_cmd:.3g}"),
                  memory_chunk_command=float(f"{chunk_cmd:.3g}"))
    print("\nCALIBRATION = Calibration(" + ", ".join(f"{k}={v!r}" for k, v in asdict(cal).items()) + ")\n")
    print(f"{'part':<10} {'robot':>5} {'commands':>10} {'fitted':>10} {'err':>6}")
    for (name, r), f, n in zip(rows, x @ k, y):
        print(f"{name:<10} {'':>5} {int(n):>10,} {int(f):>10,} {f / n - 1:+6.1%}")
    print(f"\n{'part':<10} {'bytes':>9} {'est':>9} {'peak GB':>8} {'est':>6} {'rest s':>7} {'est':>6} "
          f"(slice {'/'.join(['s'] * 1)}, program, write)")
    for d, n, lay, rs, s_, p_, w_, pk in zip(results, cmds, layers, rest_s, slice_s, program_s, write_s, peak):
        f = sum(np.array(r["features"]) @ k for r in d["robots"].values())
        bytes_ = sum(d["sizes"].values())
        est_b = f * (coop + gcode) + sum(v for key, v in d["sizes"].items() if not key.startswith("robots/"))
        est_t = start + sl[0] * lay + sl[1] * f + (prog + wr) * f
        est_m = mem_base + job_cmd * f + (chunk_cmd * sum(sorted(
            (np.array(x) @ k for x in d.get("chunk_features", {}).values()), reverse=True)[:default_cores() + 1])
            if chunk_cmd else 0.0)
        print(f"{d['name']:<10} {bytes_ / 1e6:8.0f}M {est_b / 1e6:8.0f}M {pk / 1e9:8.2f} {est_m / 1e9:6.2f} "
              f"{rs:7.1f} {est_t:6.1f}  ({s_:.1f}, {p_:.1f}, {w_:.1f}); wall {d['wall_s']:.0f} s")


def check_bundle(folder: str) -> None:
    """The estimate of an existing ``cooprint run`` bundle (its chunk STLs, job.json's settings and
    sequences) against its files and the commands job.json counts: a check on a part too large to
    calibrate on (the 600 x 4000 x 400 mm beam)."""
    from types import SimpleNamespace

    import trimesh

    from cooprint.config import load_settings
    from cooprint.io.estimate import estimate_job

    root = Path(folder)
    job = json.loads((root / "job.json").read_text())
    settings = load_settings(tables=[("job.json", job["settings"])])
    chunks = []
    for c in job["chunks"]:
        mesh = trimesh.load(root / c["file"], process=False)
        chunks.append(SimpleNamespace(id=c["id"], vertices=np.asarray(mesh.vertices), faces=np.asarray(mesh.faces)))
    est = estimate_job(SimpleNamespace(chunks=chunks), settings, {r["name"]: r["chunks"] for r in job["robots"]})
    real = sum(p.stat().st_size for p in root.rglob("*") if p.is_file() and "sim" not in p.relative_to(root).parts)
    print(est.describe())
    for r in job["robots"]:
        n = r["stats"]["commands"]
        if n:
            print(f"  robot {r['name']}: {n:,} commands, estimated {est.commands[r['name']]:,} "
                  f"({est.commands[r['name']] / n - 1:+.1%})")
    print(f"  bundle {real / 1e9:.3f} GB, estimated {est.bytes / 1e9:.3f} GB ({est.bytes / real - 1:+.1%})")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--parts", nargs="+", choices=list(parts()), help="parts to run (default: all)")
    p.add_argument("--refit", action="store_true", help="fit the results saved by earlier runs, run nothing")
    p.add_argument("--check", metavar="BUNDLE", help="estimate an existing bundle and compare, run nothing")
    p.add_argument("--child", nargs=4, metavar=("MESH", "OUT", "OVERRIDES", "RESULT"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        child(*args.child)
        return 0
    if args.check:
        check_bundle(args.check)
        return 0
    todo = parts()
    names = args.parts or list(todo)
    results = []
    for name in names:
        saved = WORK / name / "result.json"
        if args.refit:
            if saved.exists() and "peak_bytes" in json.loads(saved.read_text()):
                results.append(json.loads(saved.read_text()))
            continue
        make, overrides = todo[name]
        results.append(measure(name, make, overrides))
    if not results:
        print("nothing to fit")
        return 1
    fit(results)
    return 0


if __name__ == "__main__":
    sys.exit(main())
