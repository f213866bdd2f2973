"""``cooprint`` command line: thin wrappers over :mod:`cooprint.jobs`.

Exit codes: 0 success, 2 bad input (one line on stderr, no traceback unless ``--verbose``),
130 interrupted.
"""

from __future__ import annotations

import os
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import click

from cooprint import __version__
from cooprint.errors import UserError

STAGE_NAMES = {"load": "reading mesh", "cut": "cutting chunks", "write": "writing files",
               "render": "drawing picture", "slice": "slicing layers", "program": "robot programs"}


@contextmanager
def stage_progress(enabled: bool) -> Iterator[Any]:
    """A ``progress(stage, done, total)`` callback drawing one bar per stage on stderr."""
    if not enabled:
        yield None
        return
    from rich.console import Console  # rich costs ~80 ms to import: only when bars are drawn
    from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeElapsedColumn

    console = Console(stderr=True)
    with Progress(TextColumn("{task.description:<16}"), BarColumn(), TaskProgressColumn(),
                  TimeElapsedColumn(), console=console, transient=False) as bars:
        tasks: dict[str, Any] = {}

        def update(stage: str, done: int, total: int) -> None:
            if stage not in tasks:
                tasks[stage] = bars.add_task(STAGE_NAMES.get(stage, stage), total=max(total, 1))
            bars.update(tasks[stage], completed=done, total=max(total, 1))

        yield update


def _settings(config: tuple[str, ...], overrides: dict[str, Any]) -> Any:
    from cooprint.config import load_settings

    return load_settings(*config, overrides=overrides)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="cooprint")
@click.option("-v", "--verbose", is_flag=True, help="Show tracebacks for errors.")
@click.pass_context
def cli(ctx: click.Context, verbose: bool) -> None:
    """Cooperative 3D printing: cut a mesh into chunks that a fleet of mobile printers can print.

    Units: mm, s, mm/s, degrees.
    """
    ctx.obj = {"verbose": verbose}


config_option = click.option(
    "--robot", "--config", "config", multiple=True, type=click.Path(dir_okay=False),
    help="TOML file with [robot], [chunking], [mesh], [slicing], [program] sections (repeatable; later "
         "files win).")


@cli.command()
@click.argument("mesh", type=click.Path(dir_okay=False))
@config_option
def info(mesh: str, config: tuple[str, ...]) -> None:
    """Report a mesh (triangles, size, volume, repairs) and the robot's slope limits for it."""
    from cooprint.chunking import slope_limits
    from cooprint.io.mesh import fmt_report, load_mesh

    settings = _settings(config, {})
    solid = load_mesh(mesh, settings.mesh)
    click.echo(fmt_report(solid.report))
    h = solid.bounds[1, 2] - solid.bounds[0, 2]
    lim = slope_limits(settings.robot, h)
    click.echo(f"  robot '{settings.robot.name}': theta_min {lim.theta_min_deg:.2f} deg, "
               f"theta_max {lim.theta_max_deg:.2f} deg" + ("" if lim.feasible else "  (infeasible)"))


def plan_options(command: Any) -> Any:
    """The options of the commands that plan a job (``chunk``, ``run``): output folder, chunking
    overrides, robots, settings files, --force, --no-picture, --quiet."""
    options = [
        click.argument("mesh", type=click.Path(dir_okay=False)),
        click.option("--out", "-o", required=True, type=click.Path(file_okay=False), help="Output folder."),
        click.option("--theta", type=float, help="Slope of the chunk interfaces, degrees [default: theta_max]."),
        click.option("--shift", type=float, help="Distance between cutting planes, mm [default: bd - h/tan(theta)]."),
        click.option("--top-width", type=float, help="Width of the centre chunk at the top, mm [default: 0]."),
        click.option("--centre-angle", type=float,
                     help="Direction of the centre line, degrees from +X [default: 0]."),
        click.option("--robots", type=click.IntRange(1, 2), default=2, show_default=True,
                     help="Number of robots (seed strategy)."),
        config_option,
        click.option("--force", is_flag=True, help="Replace OUT if it exists."),
        click.option("--no-picture", is_flag=True, help="Skip chunks.png."),
        click.option("--quiet", "-q", is_flag=True, help="No progress bars or summary."),
    ]
    for option in reversed(options):
        command = option(command)
    return command


def _plan(make: Any, write: Any, mesh: str, out: str, config: tuple[str, ...], theta: float | None,
          shift: float | None, top_width: float | None, centre_angle: float | None, robots: int, force: bool,
          no_picture: bool, quiet: bool) -> dict[str, Any] | None:
    """Make a job (``make(mesh, settings, robots, progress)``) and write its bundle
    (``write(job, out, force, picture, progress)``) with progress bars; print the plan unless
    ``quiet`` (then return ``None``), else return the record."""
    from cooprint.io.bundle import check_destination

    _lean_malloc()
    settings = _settings(config, {"chunking.theta_deg": theta, "chunking.shift": shift,
                                  "chunking.top_width": top_width, "chunking.centre_angle_deg": centre_angle})
    check_destination(Path(out), force)  # before the work, not after
    with stage_progress(not quiet) as progress:
        record = write(make(mesh, settings, robots, progress), out, force, not no_picture, progress)
    if quiet:
        return None
    st, plan = record["stats"], record["plan"]
    click.echo(f"{len(record['chunks'])} chunks, theta {plan['theta_deg']:.2f} deg "
               f"(limits {plan['theta_min_deg']:.2f}..{plan['theta_max_deg']:.2f}), shift {plan['shift_mm']:.1f} mm, "
               f"volume error {st['volume_rel_error']:.1e}")
    return record


@cli.command()
@plan_options
def chunk(mesh: str, out: str, theta: float | None, shift: float | None, top_width: float | None,
          centre_angle: float | None, robots: int, config: tuple[str, ...], force: bool,
          no_picture: bool, quiet: bool) -> None:
    """Cut MESH into watertight sloped chunks (seed §3) and write them to OUT.

    Writes OUT/job.json (chunk table, planes, dependencies, robots), OUT/chunks/<id>.stl and
    OUT/chunks.png.
    """
    from cooprint.jobs import chunk_job, write_chunk_bundle

    record = _plan(chunk_job, write_chunk_bundle, mesh, out, config, theta, shift, top_width, centre_angle,
                   robots, force, no_picture, quiet)
    if record is None:
        return
    for r in record["robots"]:
        click.echo(f"  robot {r['name']}: {' -> '.join(r['chunks']) or '(idle)'}")
    click.echo(f"wrote {out}/job.json, {out}/chunks/*.stl" + ("" if no_picture else f", {out}/chunks.png"))


@cli.command(name="slice")
@click.argument("mesh", type=click.Path(dir_okay=False))
@click.option("--out", "-o", required=True, type=click.Path(dir_okay=False), help="G-code file to write.")
@config_option
@click.option("--layer-height", type=float, help="Layer height, mm [default: 0.2].")
@click.option("--infill", type=float, help="Sparse infill density, 0..1 [default: 0.2].")
@click.option("--force", is_flag=True, help="Replace OUT if it exists.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bars or summary.")
def slice_cmd(mesh: str, out: str, config: tuple[str, ...], layer_height: float | None,
              infill: float | None, force: bool, quiet: bool) -> None:
    """Slice MESH for one printer and write Marlin G-code to OUT (a plain slicer run).

    The same slicer turns every chunk of a cooperative job into tool paths.
    """
    from cooprint.io.bundle import check_file_destination
    from cooprint.jobs import slice_to_gcode

    _lean_malloc()
    settings = _settings(config, {"slicing.layer_height": layer_height, "slicing.infill_density": infill})
    check_file_destination(Path(out), force)  # before the work, not after
    with stage_progress(not quiet) as progress:
        n_layers, used = slice_to_gcode(mesh, out, settings, progress, force=True)
    if not quiet:
        click.echo(f"{n_layers} layers, filament {used / 1000:.2f} m; wrote {out}")


@cli.command(name="run")
@plan_options
@click.option("--simulate", "then_simulate", is_flag=True,
              help="Then simulate the plan: OUT/sim/summary.json, gantt.png and snapshot.png.")
def run_cmd(mesh: str, out: str, theta: float | None, shift: float | None, top_width: float | None,
            centre_angle: float | None, robots: int, config: tuple[str, ...], force: bool,
            no_picture: bool, quiet: bool, then_simulate: bool) -> None:
    """Plan a cooperative print of MESH for a fleet and write the bundle to OUT.

    Chunks, assigns, slices every chunk and writes OUT/job.json, OUT/chunks/<id>.stl,
    OUT/robots/<robot>.coop (MOVE/TOOL/NOTIFY/WAIT) and OUT/robots/<robot>.gcode, atomically.
    """
    from cooprint.jobs import coop_job, write_coop_bundle

    record = _plan(coop_job, write_coop_bundle, mesh, out, config, theta, shift, top_width, centre_angle,
                   robots, force, no_picture, quiet)
    if then_simulate:
        from cooprint.jobs import simulate_bundle

        sim = simulate_bundle(out)
        if not quiet:
            from cooprint.simulation import findings_line

            click.echo(f"simulated: makespan {sim['makespan_s'] / 3600:.2f} h, findings: "
                       f"{findings_line(sim['finding_counts'])}; wrote {out}/sim/summary.json, gantt.png, snapshot.png")
    if record is None:
        return
    for r in record["robots"]:
        st = r["stats"]
        click.echo(f"  robot {r['name']} ({r['side']} side): {' -> '.join(r['chunks']) or '(idle)'}; "
                   f"{st['commands']:,} commands, {st['print_mm'] / 1000:.1f} m printed, "
                   f"{st['volume_mm3'] / 1000:.1f} cm3, {st['wait']} WAIT, {st['notify']} NOTIFY")
    click.echo(f"wrote {out}/job.json, {out}/chunks/*.stl, {out}/robots/*.coop, {out}/robots/*.gcode"
               + ("" if no_picture else f", {out}/chunks.png"))


def _need_inputs(inputs: tuple[str, ...], manifest: str | None) -> None:
    if not inputs and not manifest:
        raise UserError("nothing to simulate: give a `cooprint run` folder, G-code files, or --manifest FILE.toml")


def _sim_folder(inputs: tuple[str, ...], out: str | None) -> Path:
    """Where simulation output goes: ``DIR/sim`` of a bundle, or ``OUT/sim`` for files."""
    if out:
        return Path(out) / "sim"
    if len(inputs) == 1 and Path(inputs[0]).is_dir():
        return Path(inputs[0]) / "sim"
    raise UserError("simulating files: give --out DIR for the results (DIR/sim/summary.json)")


@cli.command()
@click.argument("inputs", nargs=-1, type=click.Path())
@click.option("--manifest", type=click.Path(dir_okay=False), help="TOML naming .coop files, starts, facings.")
@click.option("--out", "-o", type=click.Path(file_okay=False), help="Folder for sim/ (default: the bundle).")
@click.option("--strict", is_flag=True, help="Exit with code 1 if any check finds a problem (overhang warnings too).")
@click.option("--accel", is_flag=True, help="Moves accelerate (robot profile's acceleration and jerk; "
              "G-code: PrusaSlicer's machine limits) instead of keeping their speed.")
@click.option("--frames", "frame_step", type=float, default=None, metavar="SECONDS",
              help="Also write sim/frames.npz: every robot's position and material every SECONDS (seed Fig. 15).")
@click.option("--force", is_flag=True, help="Replace an earlier sim/summary.json (and frames.npz).")
@click.option("--quiet", "-q", is_flag=True, help="No summary on stdout.")
def simulate(inputs: tuple[str, ...], manifest: str | None, out: str | None, strict: bool, accel: bool,
             frame_step: float | None, force: bool, quiet: bool) -> None:
    """Play a plan in true time and check it: INPUTS is a `cooprint run` folder, G-code files (one
    robot each), or .coop files with --manifest. Writes sim/summary.json."""
    import math

    import numpy as np

    from cooprint.io.bundle import atomic_file, write_json
    from cooprint.simulation import findings_line, frames, load_inputs, simulate as run_sim, summary

    _need_inputs(inputs, manifest)
    if frame_step is not None and not (math.isfinite(frame_step) and frame_step > 0):
        raise UserError(f"--frames {frame_step:g}: expected a positive number of seconds")
    folder = _sim_folder(inputs, out)
    targets = [folder / "summary.json"] + ([folder / "frames.npz"] if frame_step is not None else [])
    for target in targets:
        if target.exists() and not force:
            raise UserError(f"{target}: exists; use --force to replace it")
    target = targets[0]
    _heap_malloc()
    result = run_sim(load_inputs(list(inputs), manifest), accel=accel)
    record = summary(result)
    folder.mkdir(parents=True, exist_ok=True)
    if frame_step is not None:
        if result.makespan / frame_step > 10_000_000:
            raise UserError(f"--frames {frame_step:g}: more than 10 million frames over {result.makespan:.0f} s; "
                            "take a longer step")
        fr = frames(result, frame_step)
        with atomic_file(targets[1], force=True) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(f, t=fr.t, robots=np.array(fr.robots), position=fr.position, done=fr.done,
                                material=fr.material)
    with atomic_file(target, force=True) as tmp:
        write_json(tmp, record)
    if not quiet:
        click.echo(f"makespan {record['makespan_s'] / 3600:.2f} h ({record['makespan_s']:.0f} s)")
        for r in record["robots"]:
            click.echo(f"  robot {r['name']}: printing {r['printing_s']:.0f} s, travelling {r['travelling_s']:.0f} s, "
                       f"waiting {r['waiting_s']:.0f} s, idle {r['idle_s']:.0f} s, {r['material_mm3'] / 1000:.1f} cm3")
        click.echo("findings: " + findings_line(record["finding_counts"]))
        for f in result.findings[:10]:
            click.echo(f"  {f.kind} ({f.severity}): robot {f.robot} at {f.time:.1f} s, "
                       f"({f.position[0]:.1f}, {f.position[1]:.1f}, {f.position[2]:.1f}) mm, chunk {f.chunk or '-'}: "
                       f"{f.detail}" + (f" ({f.count} samples)" if f.count > 1 else ""))
        click.echo("wrote " + ", ".join(map(str, targets)))
    if strict and result.findings:
        raise click.exceptions.Exit(1)


@cli.command()
@click.argument("inputs", nargs=-1, type=click.Path())
@click.option("--format", "fmt", type=click.Choice(["png", "mp4", "gif", "gantt"]), default="png", show_default=True,
              help="A snapshot at --at, an animation, or the Gantt chart.")
@click.option("--at", "at", type=float, help="Time of the snapshot, s [default: the end].")
@click.option("--fps", type=click.FloatRange(1, 120), default=24.0, show_default=True, help="Animation frames per second.")
@click.option("--duration", type=click.FloatRange(0.5, 3600), help="Animation length, s [default: 20].")
@click.option("--speedup", type=click.FloatRange(min=1e-3), help="Animation speed over real time (instead of --duration).")
@click.option("--manifest", type=click.Path(dir_okay=False), help="TOML naming .coop files, starts, facings.")
@click.option("--out", "-o", type=click.Path(dir_okay=False), help="File to write [default: DIR/sim/...].")
@click.option("--force", is_flag=True, help="Replace the file if it exists.")
def render(inputs: tuple[str, ...], fmt: str, at: float | None, fps: float, duration: float | None,
           speedup: float | None, manifest: str | None, out: str | None, force: bool) -> None:
    """Draw a simulated plan: the fleet at a time (png), in motion (mp4, gif), or who works when (gantt)."""
    from cooprint.io.bundle import atomic_file, check_file_destination
    from cooprint.render.sim import frame_count, render_animation, render_gantt, render_snapshot
    from cooprint.simulation import load_inputs, simulate as run_sim

    _need_inputs(inputs, manifest)
    if duration is not None and speedup is not None:
        raise UserError("give --duration or --speedup, not both")
    _heap_malloc()
    result = run_sim(load_inputs(list(inputs), manifest), checks=False)
    t = result.makespan if at is None else at
    if not 0 <= t <= result.makespan + 1e-9:
        raise UserError(f"--at {t:g}: expected a time from 0 to the makespan, {result.makespan:.1f} s")
    if fmt in ("mp4", "gif"):  # the options must not ask for unbounded work: refused before anything is written
        frame_count(result.makespan, fps, duration, speedup, gif=fmt == "gif")
    name = {"gantt": "gantt.png", "mp4": "animation.mp4", "gif": "animation.gif"}.get(fmt, f"snapshot_{t:.0f}s.png")
    target = Path(out) if out else _sim_folder(inputs, None) / name
    check_file_destination(target, force)
    target.parent.mkdir(parents=True, exist_ok=True)
    if fmt in ("mp4", "gif"):  # the encoder names its format from the suffix: write beside, then rename
        tmp = target.with_name(f".{target.stem}.tmp{target.suffix}")
        try:
            render_animation(result, tmp, fps=fps, duration=duration, speedup=speedup)
            tmp.replace(target)
        finally:
            tmp.unlink(missing_ok=True)
    else:
        with atomic_file(target, force) as tmp:
            if fmt == "gantt":
                render_gantt(result, tmp)
            else:
                render_snapshot(result, t, tmp)
    click.echo(f"wrote {target}")


def _lean_malloc() -> None:
    """Large arrays straight from the OS and back (glibc's malloc otherwise raises its mmap
    threshold after the first large free and keeps later freed arrays in its heap: 30 MB more
    resident memory after loading a 200k-triangle STL). For the commands that cut and slice
    meshes; the simulator's arrays are fewer and larger, and fresh pages from the OS cost it time
    (nefertiti: 130k more page faults, +0.5 s). Not on glibc: nothing to do."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6").mallopt(-3, 1 << 17)  # M_MMAP_THRESHOLD = 128 KiB, fixed
    except (OSError, AttributeError):
        pass


def _heap_malloc() -> None:
    """Every array from glibc's heap, kept there when freed, for the next one (the simulator
    makes and drops arrays of millions of samples stage after stage; each fresh page from the OS
    costs a fault and zeroing: nefertiti 200k -> 145k page faults, 0.3-0.9 s less). Not on
    glibc: nothing to do."""
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt(-4, 0)  # M_MMAP_MAX = 0: no allocation gets pages of its own
        libc.mallopt(-1, 1 << 40)  # M_TRIM_THRESHOLD: the heap is not given back
    except (OSError, AttributeError):
        pass


def one_line(message: str, limit: int = 300) -> str:
    """A message as one line of at most ``limit`` characters: whitespace runs (newlines
    included) become one space, and a long message keeps its start and end (a 10 MB token in
    an input is never echoed whole)."""
    text = " ".join(message.split())
    if len(text) <= limit:
        return text
    half = (limit - 5) // 2
    return f"{text[:half]} ... {text[-half:]}"


def main(argv: list[str] | None = None) -> int:
    """Entry point: runs the CLI and maps errors to exit codes."""
    args = list(sys.argv[1:] if argv is None else argv)
    verbose = "-v" in args or "--verbose" in args
    if verbose:  # accepted anywhere on the line, not only before the subcommand
        args = ["--verbose"] + [a for a in args if a not in ("-v", "--verbose")]
    try:
        code = cli.main(args=args, prog_name="cooprint", standalone_mode=False)
        if isinstance(code, int):  # click returns the code of an Exit (simulate --strict)
            return code
    except UserError as exc:
        if verbose:
            raise
        click.echo(f"cooprint: error: {one_line(str(exc))}", err=True)
        return exc.exit_code
    except click.exceptions.Abort:
        click.echo("cooprint: interrupted", err=True)
        return 130
    except click.ClickException as exc:  # a bad option or argument: one line too, no usage block
        if verbose:
            raise
        click.echo(f"cooprint: error: {one_line(exc.format_message())}", err=True)
        return 2
    except KeyboardInterrupt:
        click.echo("cooprint: interrupted", err=True)
        return 130
    return 0


def entry() -> None:
    """The ``cooprint`` command: :func:`main`, then out of the process without tearing the
    interpreter down. Everything a command writes is closed by then; what is left is unloading
    numba's compiled code one function at a time, 0.15-0.25 s for nothing."""
    code = main()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a reader that went away (`| head`), a closed stream
            pass
    os._exit(code)


if __name__ == "__main__":
    entry()
