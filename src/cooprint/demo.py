"""``make demo``: plan a cooperative print of a generated car for two robots, simulate it, and
show where everything went (programs, G-code, summary, Gantt chart, animation, the interactive
viewer).

Run as ``python -m cooprint.demo OUTDIR``. The folder is the demo's own and is replaced on each run.
"""

from __future__ import annotations

import sys
from pathlib import Path

from cooprint.cli import stage_progress
from cooprint.config import load_settings
from cooprint.io.bundle import write_stl
from cooprint.jobs import coop_job, simulate_bundle, write_coop_bundle
from cooprint.models import car
from cooprint.simulation import findings_line


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    out = Path(args[0] if args else "out/demo")
    out.parent.mkdir(parents=True, exist_ok=True)
    solid = car(700.0)
    settings = load_settings()
    print(f"demo: a generated car, {solid.report.triangles:,} triangles, "
          f"{solid.volume / 1000:.0f} cm3; robot '{settings.robot.name}' (build depth "
          f"{settings.robot.build_depth:g} mm)", file=sys.stderr)
    (out / "model.stl").unlink(missing_ok=True)  # the demo's own copy of the model, beside its bundle
    with stage_progress(True) as progress:
        job = coop_job(solid, settings, robots=2, progress=progress)
        record = write_coop_bundle(job, out, force=True, progress=progress)
    write_stl(out / "model.stl", solid.vertices, solid.faces, name="demo car")
    print("simulating the plan and drawing it ...", file=sys.stderr)
    sim = simulate_bundle(out, animation=True)
    plan = record["plan"]
    print(f"{len(record['chunks'])} chunks at theta {plan['theta_deg']:.2f} deg, shift {plan['shift_mm']:.1f} mm, "
          f"volume error {record['stats']['volume_rel_error']:.1e}")
    for r in record["robots"]:
        st = r["stats"]
        print(f"  robot {r['name']} ({r['side']} side): {' -> '.join(r['chunks'])}; {st['commands']:,} commands, "
              f"{st['print_mm'] / 1000:.0f} m of paths, {st['volume_mm3'] / 1000:.0f} cm3, "
              f"{st['wait']} WAIT, {st['notify']} NOTIFY")
    print(f"simulated: makespan {sim['makespan_s'] / 3600:.1f} h; robot B waits "
          f"{sim['robots'][1]['waiting_s'] / 3600:.1f} h for C; findings: {findings_line(sim['finding_counts'])}")
    belly = sorted({round(f["position"][2], 1) for f in sim["findings"] if f["kind"] == "overhang"})
    if belly:
        print(f"  (overhang warnings, first at z {', '.join(f'{z:g}' for z in belly)} mm: the car's belly hangs "
              "above the floor between its wheels, so its first layer is laid over air: a slicer would add supports)")
    print(f"outputs in {out}/:")
    for name in ("model.stl", "job.json", "chunks/", "chunks.png", "robots/A.coop", "robots/A.gcode",
                 "robots/B.coop", "robots/B.gcode", "sim/summary.json", "sim/gantt.png", "sim/snapshot.png",
                 "sim/animation.mp4", "sim/viewer.html"):
        print(f"  {out / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
