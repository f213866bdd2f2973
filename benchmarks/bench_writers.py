"""Writer speed (issue 15, "writing >= 100 MB/s of G-code"): the .coop and G-code writers on a
large program, plain and gzip-compressed (``run --compress``).

The program is robot A's of a real plan, a 300 x 700 x 12 mm slab with the default robot
(about 165k commands), repeated ``--reps`` times. Each writer writes it whole to a file
(``--out``, default a temporary folder) ``--tries`` times; the best wall and CPU times are
reported as MB/s of text (wall time counts waiting for a core on a busy machine, CPU time does
not)::

    PYTHONPATH=src python benchmarks/bench_writers.py --reps 25 --tries 3
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=25)
    ap.add_argument("--tries", type=int, default=3)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()

    from solids import box, to_trimesh

    from cooprint.config import load_settings
    from cooprint.io.bundle import open_output
    from cooprint.jobs import coop_job
    from cooprint.program.commands import Program, write_coop
    from cooprint.program.gcode import Feeds, Heating, write_gcode

    out = args.out or Path(tempfile.mkdtemp(prefix="bench_writers."))
    out.mkdir(parents=True, exist_ok=True)
    to_trimesh(box(300, 700, 12)).export(out / "slab.stl")
    settings = load_settings()
    one = coop_job(out / "slab.stl", settings, robots=2).programs["A"]
    p = Program.concat("A", [one] * args.reps)
    s = settings.slicing
    feeds = Feeds.of_robot(settings.robot, s)
    heat = Heating.of_robot(settings.robot, s, settings.program.heater_idle_limit_s, [10.0] * 100000)
    print(f"{len(p):,} commands ({len(one):,} x {args.reps})")
    for compress in (False, True):
        for what in ("coop", "gcode"):
            path = out / (f"A.{what}" + (".gz" if compress else ""))
            wall = cpu = float("inf")
            for _ in range(args.tries):
                t, c = time.perf_counter(), time.process_time()
                with open_output(path, compress) as fh:
                    if what == "coop":
                        write_coop(fh, p, ["bench"])
                    else:
                        write_gcode(fh, [p], s, feeds, "bench", home=False, heating=heat)
                wall, cpu = min(wall, time.perf_counter() - t), min(cpu, time.process_time() - c)
            text = os.path.getsize(out / f"A.{what}") / 1e6  # the plain file: MB of text
            print(f"{what}{' --compress' if compress else ''}: {text:.1f} MB of text "
                  f"({os.path.getsize(path) / 1e6:.1f} MB written): wall {wall:.2f} s = {text / wall:.0f} MB/s, "
                  f"CPU {cpu:.2f} s = {text / cpu:.0f} MB/s")


if __name__ == "__main__":
    main()
