"""``cooprint`` command line: thin wrappers over :mod:`cooprint.jobs`.

Exit codes: 0 success; 1 a plan whose own simulation (``run --simulate``, ``simulate``) finds
error-level findings (bodies on material, robots colliding, the printhead meeting material,
deadlocks), or with ``--strict`` (``--fail-on warnings``) any finding (overhang warnings too): one
line on stderr says so,
even with ``--quiet``; also 1 when ``info`` finds the part not feasible; 2 bad input (one line on stderr, no traceback unless ``--verbose``);
130 interrupted.
"""

from __future__ import annotations

import errno
import functools
import os
import signal
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator

import click

from cooprint import __version__, allocator
from cooprint.errors import UserError
from cooprint.interrupts import blocked_sigint, check_interrupt, held_imports, interrupted, sticky_sigint

@contextmanager
def stage_progress(enabled: bool, console: Any = None) -> Iterator[Any]:
    """A ``progress(stage, done, total)`` callback drawing one bar per stage on stderr when it is
    a terminal (a log or a pipe gets no bars: a failed run's stderr is its one error line), or,
    not ``enabled``, drawing nothing. Each bar shows the stage's rate in its unit (layers/s,
    chunks/s, MB/s; :mod:`cooprint.progress`) and the time left. ``console``: draw on this rich
    Console instead (tests); ``COOPRINT_PROGRESS=1`` in the environment draws on stderr even when
    it is not a terminal. Either way it raises a Ctrl-C that some code swallowed
    (:func:`cooprint.interrupts.check_interrupt`): the stages call it as they advance. Its
    ``say(text)`` prints a line for the user: above the bars, or on stdout when there are none."""
    forced = os.environ.get("COOPRINT_PROGRESS", "") not in ("", "0")
    if not enabled or (console is None and not forced and not sys.stderr.isatty()):
        def quiet(stage: str, done: int, total: int) -> None:
            check_interrupt()

        quiet.say = click.echo  # type: ignore[attr-defined]
        yield quiet
        return
    from cooprint.progress import rich_bars

    if console is None:
        from rich.console import Console  # rich costs ~80 ms to import: only when bars are drawn

        console = Console(stderr=True, force_terminal=True if forced else None)
    bars, draw = rich_bars(console)
    with blocked_sigint():  # its refresh thread starts with SIGINT blocked: Ctrl-C goes to the main thread
        bars.start()
    with bars:
        def update(stage: str, done: int, total: int) -> None:
            check_interrupt()
            draw(stage, done, total)

        # a line for the user while the bars are drawn goes above them (printed on stdout, the
        # next redraw of the bars on stderr would erase it)
        update.say = lambda text: console.print(text, markup=False, highlight=False)  # type: ignore[attr-defined]
        yield update


def _settings(config: tuple[str, ...], overrides: dict[str, Any]) -> Any:
    from cooprint.config import load_settings

    return load_settings(*config, overrides=overrides)


class Interrupted(Exception):
    """Ctrl-C, carried past click (which would print a blank line for it) to :func:`main`."""


class _Group(click.Group):
    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt:
            raise Interrupted() from None


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
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

#: Command-line flags that set one settings field: (flag, destination, field, click type, help).
SETTING_FLAGS: tuple[tuple[str, str, str, Any, str], ...] = (
    ("--layer-height", "layer_height", "slicing.layer_height", float, "Layer height, mm [0.2; 0.05 to nozzle]."),
    ("--first-layer-height", "first_layer_height", "slicing.first_layer_height", float,
     "First layer height, mm [0.2; 0.05 to nozzle]."),
    ("--nozzle", "nozzle", "slicing.nozzle_diameter", float, "Nozzle diameter, mm [0.4]."),
    ("--extrusion-width", "extrusion_width", "slicing.extrusion_width", float,
     "Line width, mm [0.45; 1 to 3 x nozzle]."),
    ("--infill", "infill", "slicing.infill_density", str, "Sparse infill density: 0.2 or 20% [20%]."),
    ("--infill-pattern", "infill_pattern", "slicing.infill_pattern",
     click.Choice(["rectilinear", "grid", "triangles", "gyroid"]), "Infill pattern [rectilinear]."),
    ("--perimeters", "perimeters", "slicing.perimeters", int, "Perimeters [2]."),
    ("--top-layers", "top_layers", "slicing.top_layers", int, "Solid top layers [4]."),
    ("--bottom-layers", "bottom_layers", "slicing.bottom_layers", int, "Solid bottom layers [4]."),
    ("--units", "units", "mesh.units", click.Choice(["mm", "cm", "m", "in"]), "Unit of the mesh file [mm]."),
    ("--scale", "scale", "mesh.scale", float, "Scale the mesh by FACTOR (after --units) [1]."),
)
#: The chunking flags of ``info``, ``chunk`` and ``run``.
CHUNK_FLAGS: tuple[tuple[str, str, str, Any, str], ...] = (
    ("--theta", "theta", "chunking.theta_deg", float, "Slope of the chunk interfaces, degrees [theta_max]."),
    ("--shift", "shift", "chunking.shift", float, "Distance between cutting planes, mm [bd - h/tan(theta)]."),
    ("--top-width", "top_width", "chunking.top_width", float, "Width of the centre chunk at the top, mm [0 for one robot, 2 x nozzle_depth for two]."),
    ("--centre-angle", "centre_angle", "chunking.centre_angle_deg", float,
     "Direction of the centre line, degrees from +X [0]."),
    ("--layout", "layout", "chunking.layout", click.Choice(["auto", "seed2", "grid"]),
     "Chunk layout: seed2 (the seed's centre and side chunks, 1-2 robots), grid (rows of columns, any number) "
     "or auto [auto: seed2 for 1-2 robots, else grid]."),
    ("--column-width", "column_width", "chunking.column_width", float,
     "Grid layout: column width at half the part's height, mm [from the robots' outline and number]."),
    ("--schedule", "schedule", "scheduling.strategy", click.Choice(["auto", "seed", "list", "exact"]),
     "Scheduler: list (critical path first), exact (OR-Tools CP-SAT, proven bound), seed (seed2 only) "
     "[auto: seed for seed2, else list]."),
    ("--time-limit", "time_limit", "scheduling.time_limit_s", float, "Time limit of --schedule exact, s [10]."),
)


def _with_flags(flags: tuple[tuple[str, str, str, Any, str], ...], extra: list[Any], collect: Any) -> Any:
    """A decorator adding ``flags`` and ``extra`` options to a command; ``collect(kw, overrides)``
    moves their values out of the keyword arguments into ``kw["overrides"]``."""
    def decorate(command: Any) -> Any:
        @functools.wraps(command)
        def wrapper(*args: Any, **kw: Any) -> Any:
            overrides = kw.setdefault("overrides", {})
            collect(kw, overrides)
            for _, dest, field, _, _ in flags:
                value = kw.pop(dest)
                if value is not None:
                    overrides[field] = parse_fraction(value, "--infill") if dest == "infill" else value
            return command(*args, **kw)

        for flag, dest, _, kind, text in reversed(flags):
            wrapper = click.option(flag, dest, type=kind, default=None, help=text)(wrapper)
        for option in reversed(extra):
            wrapper = option(wrapper)
        return wrapper
    return decorate


def _collect_settings(kw: dict[str, Any], overrides: dict[str, Any]) -> None:
    from cooprint.config.settings import parse_assignment

    for text in kw.pop("set_values"):  # first: the named flags win over --set
        key, value = parse_assignment(text)
        overrides[key] = value
    if kw.pop("no_place"):
        overrides["mesh.place"] = False


def parse_fraction(text: str, option: str) -> float:
    from cooprint.config.settings import parse_fraction as parse

    return parse(text, option)


#: ``--robot/--config``, every slicing and mesh flag, ``--set`` and ``--no-place``: the settings of
#: ``info``, ``chunk``, ``run`` and ``slice``, defined once. The command receives ``config`` and
#: ``overrides`` (``{"section.field": value}``).
settings_options = _with_flags(SETTING_FLAGS, [
    config_option,
    click.option("--set", "set_values", multiple=True, metavar="SECTION.KEY=VALUE",
                 help="Set any field (VALUE read as TOML: 0.3, true, grid, \"my robot\"); repeatable."),
    click.option("--no-place", is_flag=True, help="Keep the mesh's own frame (no move to the floor / bed)."),
], _collect_settings)
chunking_options = _with_flags(CHUNK_FLAGS, [], lambda kw, overrides: None)


@cli.command()
@click.argument("mesh", type=click.Path(dir_okay=False))
@chunking_options
@settings_options
@click.option("--robots", type=click.IntRange(1, 64), default=2, show_default=True,
              help="Number of robots (1 to 64).")
def info(mesh: str, config: tuple[str, ...], overrides: dict[str, Any], robots: int) -> None:
    """Report a mesh (triangles, size, volume, repairs, placement) and whether the robot can print it:
    the feasibility rule of `chunk` and `run`, the largest printable height, the number of chunks.
    Exits 1 when the part is not feasible (0 when it is)."""
    from cooprint.chunking import layout_feasibility
    from cooprint.chunking.planes import mm
    from cooprint.io.mesh import fmt_report
    from cooprint.jobs import load_placed

    settings = _settings(config, overrides)
    solid, placement = load_placed(mesh, settings, note=False)
    click.echo(fmt_report(solid.report))
    click.echo(f"  {placement.describe()}")
    layout = settings.chunking.layout
    if layout == "auto":  # as `run` resolves it (the grid's rows are seed2's: one rule for both)
        layout = "seed2" if robots <= 2 else "grid"
    f = layout_feasibility(layout, solid.vertices, settings, robots)
    click.echo(f"  robot '{settings.robot.name}': theta_min {f.theta_min_deg:.2f} deg, theta_max {f.theta_max_deg:.2f} "
               f"deg, largest printable height {mm(f.max_height)} mm ({'one chunk' if f.mode == 'whole' else 'cut'})")
    if f.feasible:
        idle = f" ({robots - 1} robot idle)" if f.chunks == 1 and robots > 1 else ""
        click.echo(f"  feasible: {f.chunks} chunk{'s' if f.chunks != 1 else ''} for {robots} "
                   f"robot{'s' if robots > 1 else ''}{idle} ({layout} layout); {f.reason}")
    else:
        click.echo(f"  not feasible: {f.message()}")
        raise click.exceptions.Exit(1)  # as `chunk` refuses it; scripts test the exit code


def plan_options(command: Any) -> Any:
    """The options of the commands that plan a job (``chunk``, ``run``): output folder, chunking
    and settings flags, robots, --force, --no-picture, --quiet."""
    options = [
        click.argument("mesh", type=click.Path(dir_okay=False)),
        click.option("--out", "-o", required=True, type=click.Path(file_okay=False), help="Output folder."),
        chunking_options,
        settings_options,
        click.option("--robots", type=click.IntRange(1, 64), default=2, show_default=True,
                     help="Number of robots (1 to 64)."),
        click.option("--force", is_flag=True, help="Replace OUT if it exists."),
        click.option("--no-picture", is_flag=True, help="Skip chunks.png."),
        click.option("--quiet", "-q", is_flag=True, help="No progress bars or summary."),
    ]
    for option in reversed(options):
        command = option(command)
    return command


def executor_options(command: Any) -> Any:
    """``--executor inline|processes|dask`` and ``--scheduler ADDRESS`` (:mod:`cooprint.executors`),
    handed to ``command`` as ``executor`` and ``scheduler`` (``None`` when not given)."""
    command = click.option(
        "--scheduler", metavar="ADDRESS", default=None,
        help="With --executor dask: tcp://HOST:PORT of a running `dask scheduler`, or local:N to start N worker "
             "processes on this machine [local: one per CPU, at most 4].")(command)
    return click.option(
        "--executor", type=click.Choice(["inline", "processes", "dask"]), default=None,
        help="Where the work is done: inline (this process), processes (worker processes on this machine) or dask "
             "(a Dask cluster, see --scheduler; pip install 'cooprint[dask]') [processes]. Same output "
             "whichever.")(command)


def _plan(make: Any, mesh: str, out: str, config: tuple[str, ...], overrides: dict[str, Any],
          robots: int, force: bool, no_picture: bool, quiet: bool) -> dict[str, Any] | None:
    """Make a job and write its bundle (``make(mesh, settings, out, robots, force, picture,
    progress)``, returning the job record) with progress bars; print the plan unless ``quiet``
    (then return ``None``), else return the record."""
    from cooprint.io.bundle import check_destination
    from cooprint.io.outputs import estimate_bytes

    allocator.lean()  # (the module says why)
    settings = _settings(config, overrides)
    check_destination(out, force, inputs=(mesh, *config), need_bytes=estimate_bytes([mesh], 0.5))  # before the work
    with stage_progress(not quiet) as progress:
        record = make(mesh, settings, out, robots, force, not no_picture, progress)
    if quiet:
        return None
    st, plan = record["stats"], record["plan"]
    if record["mesh"].get("placement"):
        from cooprint.io.place import Placement

        click.echo(Placement.from_dict(record["mesh"]["placement"]).describe())
    if plan.get("mode") == "whole" and len(record["chunks"]) == 1:
        click.echo(f"1 chunk: the part is within the build depth {plan['build_depth_mm']:g} mm (no cut)")
    else:
        click.echo(f"{len(record['chunks'])} chunks ({plan.get('layout', 'seed2')} layout), theta "
                   f"{plan['theta_deg']:.2f} deg (limits {plan['theta_min_deg']:.2f}..{plan['theta_max_deg']:.2f}), "
                   f"shift {plan['shift_mm']:.1f} mm, volume error {st['volume_rel_error']:.1e}")
    line = schedule_line(record["schedule"])
    if line:
        click.echo(line)
    return record


def schedule_line(sched: dict[str, Any]) -> str:
    """One line on the schedule: strategy, estimated makespan, the lower bound and the gap to it,
    idle robots, and the scheduler's note (a fallback, a time limit)."""
    if "makespan_s" not in sched:
        return ""
    text = (f"schedule ({sched['strategy']}): makespan estimate {sched['makespan_s'] / 3600:.2f} h, lower bound "
            f"{sched['lower_bound_s'] / 3600:.2f} h (+{100 * sched['gap']:.1f}%)")
    if sched.get("bound_s"):
        text += f", proven bound {sched['bound_s'] / 3600:.2f} h (+{100 * (sched.get('bound_gap') or 0):.1f}%)"
    idle = sched.get("idle_robots") or []
    if idle:
        text += f"; {len(idle)} robot{'s' if len(idle) > 1 else ''} idle ({', '.join(idle[:8])}{', ...' if len(idle) > 8 else ''}): more robots than the part has room or work for"
    if sched.get("note"):
        text += f"; {sched['note']}"
    return text


@cli.command()
@plan_options
def chunk(mesh: str, out: str, robots: int, config: tuple[str, ...], overrides: dict[str, Any], force: bool,
          no_picture: bool, quiet: bool) -> None:
    """Cut MESH into watertight sloped chunks (seed §3) and write them to OUT.

    Writes OUT/job.json (chunk table, planes, dependencies, robots), OUT/chunks/<id>.stl and
    OUT/chunks.png.
    """
    from cooprint.jobs import chunk_job, write_chunk_bundle

    def make(mesh: str, settings: Any, out: str, robots: int, force: bool, picture: bool, progress: Any) -> Any:
        return write_chunk_bundle(chunk_job(mesh, settings, robots, progress), out, force, picture, progress)

    record = _plan(make, mesh, out, config, overrides, robots, force, no_picture, quiet)
    if record is None:
        return
    for r in record["robots"]:
        if r["chunks"]:
            click.echo(f"  robot {r['name']}: {' -> '.join(r['chunks'])}")
    _idle_line(record)
    click.echo(f"wrote {out}/job.json, {out}/chunks/*.stl" + ("" if no_picture else f", {out}/chunks.png"))


@cli.command(name="slice")
@click.argument("mesh", type=click.Path(dir_okay=False))
@click.option("--out", "-o", required=True, type=click.Path(dir_okay=False), help="G-code file to write.")
@settings_options
@click.option("--center", "center", metavar="X,Y", help="Put the centre of the part's bounding box at X,Y mm "
              "[the bed centre: build_x/2, build_y/2].")
@click.option("--force", is_flag=True, help="Replace OUT if it exists.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bars or summary.")
@executor_options
def slice_cmd(mesh: str, out: str, config: tuple[str, ...], overrides: dict[str, Any], center: str | None,
              force: bool, quiet: bool, executor: str | None, scheduler: str | None) -> None:
    """Slice MESH for one printer and write Marlin G-code to OUT (a plain slicer run).

    The part is put on the bed: on the floor, centred at the bed centre or --center (PrusaSlicer's
    --center); --no-place keeps its own frame. The same slicer turns every chunk of a cooperative
    job into tool paths.
    """
    from cooprint.executors import check_executor_options, make_executor
    from cooprint.io.bundle import check_file_destination
    from cooprint.io.outputs import estimate_bytes
    from cooprint.io.place import parse_center
    from cooprint.jobs import slice_to_gcode

    check_executor_options(executor, scheduler)
    allocator.lean()  # (the module says why)
    settings = _settings(config, overrides)
    if center is not None and not settings.mesh.place:  # one would be ignored
        raise UserError(f"--center {center[:40]} puts the part on the bed, --no-place (mesh.place = false) keeps "
                        "the file's frame: give one")
    xy = None if center is None else parse_center(center)
    check_file_destination(out, force, inputs=(mesh, *config), need_bytes=estimate_bytes([mesh], 0.5))  # before the work
    where: list[Any] = []
    with make_executor(executor, scheduler) as ex, stage_progress(not quiet) as progress:
        n_layers, used = slice_to_gcode(mesh, out, settings, progress, force=True, center=xy, placed=where.append,
                                        executor=ex)
    if not quiet:
        click.echo(f"{where[0].describe()}; {n_layers} layers, filament {used / 1000:.2f} m; wrote {out}")


def _judge(sim: dict[str, Any], strict: bool, quiet: bool, what: str, summary_path: Path) -> None:
    """Exit 1 if a plan's simulation summary ``sim`` fails it (:func:`cooprint.simulation.verdict`):
    the findings line on stderr when ``quiet`` hid it, then one line on stderr saying that the
    plan is invalid (errors) or fails ``--strict`` (warnings only), what found it and where the
    summary is."""
    from cooprint.simulation import failures, findings_line, verdict

    bad = verdict(sim, strict)
    if bad is None:
        return
    if quiet:
        click.echo(f"findings: {findings_line(sim['finding_counts'])}", err=True)
    state = "is INVALID" if failures(sim) else "fails --strict"
    click.echo(f"cooprint: the plan {state}: {what} found {bad}; see {summary_path}", err=True)
    raise click.exceptions.Exit(1)


def strict_option(command: Any) -> Any:
    """``--strict`` (a flag: warnings fail the plan too) and ``--fail-on errors|warnings`` (the
    same choice spelled out: ``errors``, the default, fails only on error-level findings;
    ``warnings`` is ``--strict``), handed to ``command`` as one ``strict`` bool. Conflicting
    values, or either on ``run`` without ``--simulate``, are refused."""

    @functools.wraps(command)
    def wrapper(*args: Any, strict: bool, fail_on: str | None, **kwargs: Any) -> Any:
        if strict and fail_on == "errors":
            raise UserError("--strict fails on warnings, --fail-on errors only on errors: give one")
        if fail_on is not None and kwargs.get("then_simulate") is False:
            raise UserError(f"--fail-on {fail_on} needs --simulate (it says which findings of the plan's simulation "
                            "fail it)")
        return command(*args, strict=strict or fail_on == "warnings", **kwargs)

    wrapper = click.option(
        "--fail-on", type=click.Choice(["errors", "warnings"]), default=None,
        help="Which findings exit with code 1: errors (the default: a body on material, robots colliding, the "
             "printhead or nozzle meeting material, material laid twice, out of order or outside the part, a "
             "deadlock) or warnings too (overhangs; the same as --strict).")(wrapper)
    return click.option("--strict", is_flag=True,
                        help="Exit with code 1 on warnings (overhangs) too (--fail-on warnings); errors always "
                             "exit 1.")(wrapper)


@cli.command(name="run")
@plan_options
@click.option("--simulate", "then_simulate", is_flag=True,
              help="Then simulate the plan: OUT/sim/summary.json, gantt.png, snapshot.png and viewer.html (the "
                   "interactive viewer); exit 1 if the simulation finds errors.")
@strict_option
@click.option("--compress", is_flag=True,
              help="Write the robots' programs gzip-compressed: OUT/robots/<robot>.coop.gz and .gcode.gz "
                   "(simulate and render read them as they are).")
@executor_options
def run_cmd(mesh: str, out: str, robots: int, config: tuple[str, ...], overrides: dict[str, Any], force: bool,
            no_picture: bool, quiet: bool, then_simulate: bool, strict: bool, compress: bool, executor: str | None,
            scheduler: str | None) -> None:
    """Plan a cooperative print of MESH for a fleet and write the bundle to OUT.

    Chunks, assigns, slices every chunk and writes OUT/job.json, OUT/chunks/<id>.stl,
    OUT/robots/<robot>.coop (MOVE/TOOL/NOTIFY/WAIT) and OUT/robots/<robot>.gcode, atomically
    (with --compress, .coop.gz and .gcode.gz). With --simulate, a plan whose own simulation
    finds errors is reported INVALID (exit 1).
    """
    from cooprint.executors import check_executor_options, make_executor
    from cooprint.jobs import run_job

    if strict and not then_simulate:  # --strict judges a simulation: without one it would be ignored
        raise UserError("--strict needs --simulate (it makes warnings of the plan's simulation fail it)")
    check_executor_options(executor, scheduler)

    def make(mesh: str, settings: Any, out: str, robots: int, force: bool, picture: bool, progress: Any) -> Any:
        # the executor starts after the settings' and the destination's checks, before the work
        with make_executor(executor, scheduler) as ex:
            return run_job(mesh, settings, out, robots, force=force, picture=picture, progress=progress,
                           executor=ex, on_estimate=estimate_reporter(out, quiet, progress, compress), compress=compress)

    record = _plan(make, mesh, out, config, overrides, robots, force, no_picture, quiet)
    sim = None
    if then_simulate:
        from cooprint.jobs import simulate_bundle

        with stage_progress(not quiet) as progress:
            sim = simulate_bundle(out, progress=progress)
        if not quiet:
            from cooprint.simulation import bound_line, findings_line

            bound = bound_line(sim)  # "makespan X h, lower bound Y h (+Z%)...", when job.json states a bound
            click.echo(f"simulated: {bound or 'makespan {:.2f} h'.format(sim['makespan_s'] / 3600)}; findings: "
                       f"{findings_line(sim['finding_counts'])}; wrote {out}/sim/summary.json, gantt.png, snapshot.png"
                       + (", viewer.html" if (Path(out) / "sim" / "viewer.html").exists() else ""))
    if record is not None:
        _report_run(record, out, no_picture)
    if sim is not None:
        _judge(sim, strict, quiet, "its own simulation", Path(out) / "sim" / "summary.json")


def estimate_reporter(out: str, quiet: bool, progress: Any = None, compress: bool = False) -> Any:
    """``coop_job``'s ``on_estimate`` for ``cooprint run``: refuse the run when the estimated
    output does not fit in the free space of OUT's file system (before slicing: a clear line, not
    a full disk an hour later; with ``compress`` the programs' bytes compressed, and the spool
    beside them), then say the estimate unless ``quiet`` (``progress.say``: above the bars)."""
    def report(estimate: Any) -> None:
        from cooprint.io.estimate import check_room

        if compress:
            estimate = estimate.compressed()
        check_room(out, estimate)
        if not quiet:  # above the bars on a terminal; else on stdout, with the plan's lines (stderr is a
            # failed run's one error line)
            getattr(progress, "say", click.echo)(estimate.describe())
    return report


def _idle_line(record: dict[str, Any]) -> None:
    """One line for the robots with no chunk (parked off the part all along), if any."""
    idle = [r["name"] for r in record["robots"] if not r["chunks"]]
    if idle:
        click.echo(f"  idle ({len(idle)}): {', '.join(idle)}")


def _report_run(record: dict[str, Any], out: str, no_picture: bool) -> None:
    """The lines ``cooprint run`` prints about the plan it wrote."""
    for r in record["robots"]:
        if not r["chunks"]:
            continue
        st = r["stats"]
        click.echo(f"  robot {r['name']} ({'both sides' if r['side'] == 'both' else r['side'] + ' side'}): {' -> '.join(r['chunks']) or '(idle)'}; "
                   f"{st['commands']:,} commands, {st['print_mm'] / 1000:.1f} m printed, "
                   f"{st['volume_mm3'] / 1000:.1f} cm3, {st['wait']} WAIT, {st['notify']} NOTIFY")
    _idle_line(record)
    gz = ".gz" if any(str(r.get("program", "")).endswith(".gz") for r in record["robots"]) else ""
    click.echo(f"wrote {out}/job.json, {out}/chunks/*.stl, {out}/robots/*.coop{gz}, {out}/robots/*.gcode{gz}"
               + ("" if no_picture else f", {out}/chunks.png"))


#: Free space a summary or a picture needs at the least, bytes.
_SMALL_OUTPUT = 1 << 16


def _need_inputs(inputs: tuple[str, ...], manifest: str | None) -> None:
    """Some inputs, each there (a missing one is named before any question of where the output goes)."""
    if not inputs and not manifest:
        raise UserError("nothing to simulate: give a `cooprint run` folder, G-code files, .coop files, "
                        "or --manifest FILE.toml")
    for x in filter(None, inputs):  # (an empty path: the reader words it)
        try:
            os.lstat(x)
        except FileNotFoundError:
            raise UserError(f"{x}: no such file or folder") from None
        except (OSError, ValueError):  # a name too long, a loop, a NUL: the reader words it
            pass


def _sim_folder(inputs: tuple[str, ...], out: str | None) -> Path:
    """Where simulation output goes: ``DIR/sim`` of a bundle, or ``OUT/sim`` for files."""
    if out is not None:
        if not out:
            raise UserError("--out '': an empty path; give a folder name")
        return Path(out) / "sim"
    if len(inputs) == 1 and Path(inputs[0]).is_dir():
        return Path(inputs[0]) / "sim"
    folders = [x for x in inputs if Path(x).is_dir()]
    if folders:
        raise UserError(f"{folders[0]}: a bundle folder is simulated alone (one bundle at a time), "
                        f"not with other inputs (got {len(inputs)} inputs)")
    raise UserError("simulating files: give --out DIR for the results (DIR/sim/summary.json)")


@cli.command()
@click.argument("inputs", nargs=-1, type=click.Path())
@click.option("--manifest", type=click.Path(dir_okay=False), help="TOML naming .coop files, starts, facings.")
@click.option("--out", "-o", type=click.Path(file_okay=False), help="Folder for sim/ (default: the bundle).")
@strict_option
@click.option("--accel", is_flag=True, help="Moves accelerate (robot profile's acceleration and jerk; "
              "G-code: PrusaSlicer's machine limits) instead of keeping their speed.")
@click.option("--frames", "frame_step", type=float, default=None, metavar="SECONDS",
              help="Also write sim/frames.npz: every robot's position and material every SECONDS (seed Fig. 15).")
@click.option("--perturb", "perturb", type=float, default=None, metavar="F",
              help="Also play the plan --runs times, each robot's speed scaled per chunk (and per travel between "
                   "chunks) by a random factor in [1-F, 1+F], 0 < F < 1; report the makespans and every finding.")
@click.option("--runs", type=int, default=None, help="How many perturbed runs (1 to 10000) [default: 20].")
@click.option("--seed", type=int, default=None, help="Seed of the perturbed runs' factors [default: 0].")
@click.option("--force", is_flag=True, help="Replace an earlier sim/summary.json (and frames.npz).")
@click.option("--quiet", "-q", is_flag=True, help="No summary on stdout.")
@config_option
@executor_options
def simulate(inputs: tuple[str, ...], manifest: str | None, out: str | None, strict: bool, accel: bool,
             frame_step: float | None, perturb: float | None, runs: int | None, seed: int | None, force: bool,
             quiet: bool, config: tuple[str, ...], executor: str | None, scheduler: str | None) -> None:
    """Play a plan in true time and check it: INPUTS is a `cooprint run` folder, G-code files (one
    robot each, M118 NOTIFY / M0 WAIT host lines honoured), or .coop files (one robot each, named by
    the file, the default or --robot profile; or named, placed and profiled by --manifest). Writes
    sim/summary.json; exits 1 if the checks find errors (with --strict: any finding)."""
    import math

    import numpy as np

    from cooprint.io.bundle import atomic_file, check_file_destination, write_json
    from cooprint.jobs import inputs_record, read_with_progress
    from cooprint.simulation import findings_line, frames, simulate as run_sim, summary
    from cooprint.simulation.perturb import check_perturb_options, perturb_runs

    from cooprint.executors import check_executor_options, make_executor

    _need_inputs(inputs, manifest)
    monte_carlo = check_perturb_options(perturb, runs, seed)
    if monte_carlo is None and (executor is not None or scheduler is not None):
        raise UserError(f"{'--executor' if executor is not None else '--scheduler'} runs the --perturb runs; "
                        "without --perturb there is nothing to send to it")
    check_executor_options(executor, scheduler)
    if frame_step is not None and not (math.isfinite(frame_step) and frame_step > 0):
        raise UserError(f"--frames {frame_step:g}: expected a positive number of seconds")
    folder = _sim_folder(inputs, out)
    targets = [folder / "summary.json"] + ([folder / "frames.npz"] if frame_step is not None else [])
    sources = (*inputs, manifest)
    for target in targets:  # before the work; cooprint's own earlier results need no --force
        check_file_destination(target, force, sources, need_bytes=_SMALL_OUTPUT, create_parents=2)
    target = targets[0]
    allocator.heap()  # (the module says why)
    perturbed = None
    with stage_progress(not quiet) as progress:  # bars on a terminal; Ctrl-C between runs
        # a bundle's programs read piece by piece while they are timed (held whole for the Monte-Carlo runs)
        inp = read_with_progress(list(inputs), manifest, _settings(config, {}) if config else None, progress,
                                 programs=bool(monte_carlo))
        result = run_sim(inp, accel=accel, progress=progress)
        if monte_carlo:
            with make_executor(executor, scheduler) as ex:
                perturbed = perturb_runs(inp, *monte_carlo, accel=accel,
                                         progress=lambda done, total: progress("perturbed runs", done, total),
                                         executor=ex)
    record = summary(result, perturbed)
    record["inputs"] = inputs_record(inputs, manifest, config, accel, inp)
    if frame_step is not None:
        if result.makespan / frame_step > 10_000_000:
            raise UserError(f"--frames {frame_step:g}: more than 10 million frames over {result.makespan:.0f} s; "
                            "take a longer step")
        fr = frames(result, frame_step)
        with atomic_file(targets[1], force=True, inputs=sources, create_parents=2) as tmp, open(tmp, "wb") as f:
            np.savez_compressed(f, t=fr.t, robots=np.array(fr.robots), position=fr.position, done=fr.done,
                                material=fr.material, facing=fr.facing)
    with atomic_file(target, force=True, inputs=sources, create_parents=2) as tmp:
        write_json(tmp, record)
    if not quiet:
        report_simulation(record)
        if perturbed is not None:
            click.echo(perturbed_line(record["perturb"]))
            click.echo("perturbed findings: " + findings_line(record["perturb"]["finding_counts"]))
            listed = [(r, f) for r in perturbed.runs for f in r.findings][:10]
            for r, f in listed:  # the first ten (summary.json has them all)
                click.echo(f"  run {r.run} (seed {r.seed}): {_finding_text(f)}")
        click.echo("wrote " + ", ".join(map(str, targets)))
    if perturbed is not None:  # the constant-speed findings and every run's, judged together
        both = {k: v + record["perturb"]["finding_counts"].get(k, 0) for k, v in record["finding_counts"].items()}
        _judge({"finding_counts": both}, strict, quiet, f"the simulation and its {len(perturbed.runs)} perturbed runs",
               target)
    else:
        _judge(record, strict, quiet, "the simulation", target)


def report_simulation(record: dict[str, Any]) -> None:
    """The lines ``simulate`` prints about a simulation summary (sim/summary.json's record):
    makespan, each robot's times and material, the bound, the findings line, the notes and the
    first ten findings (``view`` prints them too when it simulates)."""
    from cooprint.simulation import bound_line, findings_line

    click.echo(f"makespan {record['makespan_s'] / 3600:.2f} h ({record['makespan_s']:.0f} s)")
    for r in record["robots"]:
        click.echo(f"  robot {r['name']}: printing {r['printing_s']:.0f} s, travelling {r['travelling_s']:.0f} s, "
                   f"waiting {r['waiting_s']:.0f} s, idle {r['idle_s']:.0f} s, {r['material_mm3'] / 1000:.1f} cm3")
    if bound_line(record):
        click.echo(bound_line(record))
    click.echo("findings: " + findings_line(record["finding_counts"]))
    for note in record.get("notes") or ():
        click.echo(f"note: {note}")
    for f in record["findings"][:10]:
        click.echo(f"  {_finding_text(f)}")


def _finding_text(f: Any) -> str:
    """A finding (a Finding, or its record in summary.json) in one line: kind, severity, robot,
    time, place, chunk, detail, count."""
    if not isinstance(f, dict):
        f = f.to_dict()
    x, y, z = f["position"]
    return (f"{f['kind']} ({f['severity']}): robot {f['robot']} at {f['time_s']:.1f} s, "
            f"({x:.1f}, {y:.1f}, {z:.1f}) mm, chunk {f['chunk'] or '-'}: "
            f"{f['detail']}" + (f" ({f['count']:,} {f['count_of']})" if f["count"] > 1 else ""))


def perturbed_line(rec: dict[str, Any]) -> str:
    """summary.json's ``perturb`` object in one line: the variation, runs, seed and the makespans'
    distribution (h)."""
    m = rec["makespan_s"]
    return (f"perturbed +-{rec['fraction']:.0%} x {rec['runs']} runs (seed {rec['seed']}): makespan min "
            f"{m['min'] / 3600:.2f} h, median {m['median'] / 3600:.2f} h, p95 {m['p95'] / 3600:.2f} h, "
            f"max {m['max'] / 3600:.2f} h")


@cli.command()
@click.argument("inputs", nargs=-1, type=click.Path())
@click.option("--format", "fmt", type=click.Choice(["png", "mp4", "gif", "gantt"]),
              help="A snapshot at --at, an animation, or the Gantt chart [default: from --out's suffix, .mp4 or "
                   ".gif; else png].")
@click.option("--at", "at", type=float, help="Time of the snapshot, s [default: the end].")
@click.option("--fps", type=click.FloatRange(1, 120), default=24.0, show_default=True,
              help="Animation frames per second (a GIF: at most 50).")
@click.option("--duration", type=click.FloatRange(0.5, 3600), help="Animation length, s [default: 20].")
@click.option("--speedup", type=click.FloatRange(min=1e-3),
              help="Animation speed over real time (instead of --duration; at most a 10 min animation).")
@click.option("--accel/--no-accel", default=None,
              help="Moves accelerate, as in `simulate --accel` (the times drawn are those of its summary) "
                   "[default: as DIR's simulation was (its sim/summary.json), else --no-accel].")
@click.option("--manifest", type=click.Path(dir_okay=False), help="TOML naming .coop files, starts, facings.")
@click.option("--out", "-o", type=click.Path(dir_okay=False), help="File to write [default: DIR/sim/...].")
@click.option("--force", is_flag=True, help="Replace the file if it exists.")
def render(inputs: tuple[str, ...], fmt: str | None, at: float | None, fps: float, duration: float | None,
           speedup: float | None, accel: bool | None, manifest: str | None, out: str | None, force: bool) -> None:
    """Draw a simulated plan: the fleet at a time (png), in motion (mp4, gif), or who works when (gantt).

    INPUTS: .coop / G-code files, a `cooprint run` bundle, or a folder written by `cooprint
    simulate FILES --out DIR` (the files its sim/summary.json names are read again)."""
    from cooprint.io.bundle import atomic_file, check_file_destination, check_sim_folder
    from cooprint.render.sim import (animation_length, frame_count, length_text, render_animation, render_gantt,
                                     render_snapshot)
    from cooprint.jobs import read_summary, read_with_progress, sim_sources
    from cooprint.simulation import simulate as run_sim

    _need_inputs(inputs, manifest)  # each input there
    if duration is not None and speedup is not None:
        raise UserError("give --duration or --speedup, not both")
    fmt, inferred = _render_format(fmt, out)
    _check_render_options(fmt, inferred, at, duration, speedup)
    folder = Path(inputs[0]) if len(inputs) == 1 and Path(inputs[0]).is_dir() and manifest is None else None
    record = None
    if folder is not None:
        try:
            record = read_summary(folder / "sim" / "summary.json")
        except UserError:  # unreadable, or not cooprint's: the inputs are read as given
            record = None
    paths, config = list(inputs), ()
    if record is not None:  # timed as it was simulated; a `simulate --out` folder's files
        recorded = sim_sources(folder, record)  # type: ignore[arg-type]
        paths, manifest, config = list(recorded.paths), recorded.manifest, recorded.config
        if accel is None:
            accel = recorded.accel
    accel = bool(accel)
    sources = (*paths, manifest)
    if out is not None:  # before the work; the name of a snapshot in sim/ is known only after it
        check_file_destination(out, force, sources, need_bytes=_SMALL_OUTPUT)
    elif len(inputs) == 1 and Path(inputs[0]).is_dir():  # a bundle: DIR/sim/<picture>
        check_sim_folder(_sim_folder(inputs, None), need_bytes=_SMALL_OUTPUT)
    else:
        raise UserError("rendering files: give --out FILE for the picture or animation")
    allocator.heap()  # (the module says why)
    with stage_progress(True) as progress:  # bars on a terminal only
        inp = read_with_progress(paths, manifest, _settings(config, {}) if config else None, progress,
                                 programs=False)
        result = run_sim(inp, checks=False, accel=accel, progress=progress)
    t = result.makespan if at is None else at
    if not 0 <= t <= result.makespan + 1e-9:
        raise UserError(f"--at {t:g}: expected a time from 0 to the makespan, {result.makespan:.1f} s")
    if fmt in ("mp4", "gif"):  # the options must not ask for unbounded work: refused before anything is written
        n = frame_count(result.makespan, fps, duration, speedup, gif=fmt == "gif")
        length = animation_length(result.makespan, duration, speedup)
        click.echo(f"animation: {length_text(length)}, {n:,} frames at {fps:g} fps, the plan "
                   f"{result.makespan / length:,.3g} times faster than real time")
    name = {"gantt": "gantt.png", "mp4": "animation.mp4", "gif": "animation.gif"}.get(fmt, f"snapshot_{t:.0f}s.png")
    target = Path(out) if out is not None else _sim_folder(inputs, None) / name
    # a bundle's sim/ is made if missing; cooprint's earlier pictures there need no --force
    with atomic_file(target, force, inputs=sources, create_parents=0 if out is not None else 1) as tmp, \
            stage_progress(True) as progress:
        if fmt in ("mp4", "gif"):  # the temporary file keeps the suffix the encoder names its format from
            render_animation(result, tmp, fps=fps, duration=duration, speedup=speedup,
                             progress=lambda done, total: progress("frames", done, total))
        elif fmt == "gantt":
            render_gantt(result, tmp, critical=inp.critical_path, lower_bound=inp.lower_bound)
        else:
            render_snapshot(result, t, tmp)
    click.echo(f"wrote {target}")


@cli.command()
@click.argument("folder", type=click.Path())
@click.option("--open", "open_page", is_flag=True, help="Then open the page in the system's web browser.")
@click.option("--force", is_flag=True, help="Replace a DIR/sim/viewer.html that cooprint did not write.")
def view(folder: str, open_page: bool, force: bool) -> None:
    """Write FOLDER/sim/viewer.html: the plan in 3D and in true time, one self-contained page.

    FOLDER is a `cooprint run` bundle (simulated first when it has no sim/summary.json yet) or
    a folder written by `cooprint simulate FILES --out FOLDER` (its inputs are read again).
    The page needs no network: open it from disk, mail it, attach it to a report.
    A simulation it runs (no sim/summary.json yet, or inputs changed since) prints its summary
    as `simulate` does and exits 1 on errors, after writing the page."""
    from cooprint.errors import OutputError
    from cooprint.io.bundle import atomic_file, is_derived_output, write_json
    from cooprint.jobs import (SummaryUnreadable, inputs_record, read_summary, read_with_progress, sim_sources,
                               simulate_bundle, simulated_as_bundle)
    from cooprint.render.viewer import check_assets, write_viewer
    from cooprint.simulation import simulate as run_sim, summary
    from cooprint.simulation.inputs import read_chunk_meshes

    root = Path(folder)
    if not root.is_dir():
        raise UserError(f"{folder}: {'not a folder' if root.exists() else 'no such folder'}; expected a `cooprint run` "
                        "bundle or a folder written by `cooprint simulate ... --out`")
    summary_path = root / "sim" / "summary.json"
    target = root / "sim" / "viewer.html"
    unreadable = None
    try:
        record = read_summary(summary_path)
    except SummaryUnreadable as exc:
        record, unreadable = None, exc
    bundle = simulated_as_bundle(root, record)
    if not bundle and record is None:
        if unreadable is not None:
            raise UserError(f"{unreadable}; run `cooprint simulate FILES --out {folder}` again")
        raise UserError(f"{folder}: neither a cooprint bundle (job.json) nor a simulated folder (sim/summary.json); "
                        "run `cooprint run MESH --out FOLDER` or `cooprint simulate FILES --out FOLDER` first")
    check_assets()
    sources = None if record is None else sim_sources(root, record)
    inputs = (str(root),) if sources is None else sources.paths
    manifest, config = (None, ()) if sources is None else (sources.manifest, sources.config)
    _view_destination(target, force, (*inputs, manifest))
    if record is None:
        why = (f"{unreadable}; simulating again" if unreadable is not None else
               f"{folder} has no simulation yet (sim/summary.json): simulating it first")
    else:
        why = None if sources.changed is None else (f"{folder}: {sources.changed} since sim/summary.json was "
                                                    "written: simulating again")
    accel = bool(sources is not None and sources.accel)  # timed as it was simulated (else at constant speed)
    allocator.heap()  # (the module says why)
    if why is not None and bundle:
        inp = read_with_progress([str(root)], None, None, None, programs=False)  # job.json refused before a word
        click.echo(why)
        users = target.exists() and not is_derived_output(target)  # replaced below (--force)
        with stage_progress(True) as progress:
            record = simulate_bundle(root, progress=progress, viewer=not users, inp=inp, accel=accel)
        report_simulation(record)
        if not users:
            _viewer_done(target, open_page)
            _judge(record, False, False, "the simulation", summary_path)
            return
    checked = why is not None and not bundle  # a simulated folder's inputs changed: its summary too
    if checked:
        click.echo(why)
    with stage_progress(True) as progress:
        inp = read_with_progress(list(inputs), manifest, _settings(config, {}) if config else None, progress,
                                 programs=False)
        result = run_sim(inp, checks=checked, accel=accel, progress=progress)
    if checked:
        record = summary(result)
        record["inputs"] = inputs_record(inputs, manifest, config, accel, inp)
        with atomic_file(summary_path, force=True, inputs=(*inputs, manifest), create_parents=1) as tmp:
            write_json(tmp, record)
        report_simulation(record)
    try:
        with atomic_file(target, force, inputs=(*inputs, manifest), create_parents=1) as tmp:
            write_viewer(result, record, tmp, chunks=read_chunk_meshes(inp), critical=inp.critical_path,
                         lower_bound=inp.lower_bound, title=root.resolve().name)
    except OutputError as exc:
        raise OutputError(_view_wording(str(exc))) from None
    _viewer_done(target, open_page)
    if why is not None:
        _judge(record, False, False, "the simulation", summary_path)


def _view_wording(message: str) -> str:
    """An output check's message worded for ``view``, which has no ``--out`` and writes one fixed
    file (``sim/viewer.html``): what the user can do is move the entry in the way."""
    for old, new in ((", or choose another --out", ""), (" or choose another --out", ""),
                     ("; choose another --out", "; move it away"),
                     ("; give a file name", "; move it away (cooprint writes its page sim/viewer.html there)")):
        message = message.replace(old, new)
    return message


def _view_destination(target: Path, force: bool, sources: tuple[Any, ...]) -> None:
    """``check_file_destination`` of the page, its errors worded for ``view``."""
    from cooprint.errors import OutputError
    from cooprint.io.bundle import check_file_destination

    try:
        check_file_destination(target, force, sources, need_bytes=_SMALL_OUTPUT, create_parents=1)
    except OutputError as exc:
        raise OutputError(_view_wording(str(exc))) from None


def _viewer_done(target: Path, open_page: bool) -> None:
    """Say where the viewer is; with ``open_page``, ask a graphical web browser to open it if this
    machine has a display that answers (never a text browser in the terminal), else say that it
    could not. Python's ``webbrowser`` reports a browser command started, not a page shown: the
    line says it asked."""
    size = target.stat().st_size
    click.echo(f"wrote {target} ({size / 1e6:.1f} MB)")
    if not open_page:
        return
    import webbrowser

    uri = target.resolve().as_uri()
    why = None if sys.platform in ("darwin", "win32") else _no_display()
    asked = False
    if why is None:
        try:
            asked = webbrowser.open(uri)
        except webbrowser.Error:
            asked = False
        why = None if asked else "no web browser found"
    if asked:
        click.echo(f"asked the system's web browser to open {uri}")
    else:
        click.echo(f"could not open a web browser here ({why}); open {uri} in one")


def _no_display() -> str | None:
    """Why no graphical browser can open a page here (Linux and the like), or ``None``: neither
    DISPLAY nor WAYLAND_DISPLAY set, or set to a server whose socket does not answer (a
    DISPLAY left over from a closed session). One connection attempt each, at most 0.5 s."""
    import re
    import socket

    wayland, display = os.environ.get("WAYLAND_DISPLAY"), os.environ.get("DISPLAY")
    if not wayland and not display:
        return "no display"
    if wayland:
        path = wayland if wayland.startswith("/") else os.path.join(os.environ.get("XDG_RUNTIME_DIR", ""), wayland)
        if _answers(socket.AF_UNIX, path):
            return None
    if display:
        m = re.fullmatch(r"(?:unix)?(?P<host>[^:/]*):(?P<n>\d+)(?:\.\d+)?", display)
        if m is None:
            return None  # a form not known here (e.g. launchd's path): let the browser try
        n, host = int(m.group("n")), m.group("host")
        if host and host != "localhost":
            if _answers(socket.AF_INET, (host, 6000 + n)):
                return None
        elif (_answers(socket.AF_UNIX, f"/tmp/.X11-unix/X{n}") or _answers(socket.AF_UNIX, f"\0/tmp/.X11-unix/X{n}")
              or (host == "localhost" and _answers(socket.AF_INET, ("localhost", 6000 + n)))):
            return None
        return f"no X server answers at DISPLAY={display}"
    return f"no Wayland compositor answers at WAYLAND_DISPLAY={wayland}"


def _answers(family: int, address: Any) -> bool:
    """Whether a server accepts a connection at ``address`` (a socket path or (host, port))."""
    import socket

    try:
        with socket.socket(family, socket.SOCK_STREAM) as sock:
            sock.settimeout(0.5)
            sock.connect(address)
        return True
    except (OSError, ValueError):
        return False


#: Each format's file suffix (an animation's encoder is chosen by it).
FORMAT_SUFFIX = {"png": ".png", "gantt": ".png", "mp4": ".mp4", "gif": ".gif"}
#: What a file of each picture or video suffix is (a --out so named and written in another format
#: would be misread).
PICTURE_SUFFIXES = {".png": "a PNG", ".mp4": "an MP4", ".gif": "a GIF", ".jpg": "a JPEG", ".jpeg": "a JPEG",
                    ".webp": "a WebP", ".apng": "an APNG", ".bmp": "a BMP", ".tif": "a TIFF", ".tiff": "a TIFF",
                    ".svg": "an SVG", ".pdf": "a PDF", ".webm": "a WebM", ".mkv": "a Matroska video",
                    ".mov": "a QuickTime video", ".avi": "an AVI", ".m4v": "an MP4"}


def _render_format(fmt: str | None, out: str | None) -> tuple[str, bool]:
    """The format ``render`` draws and whether --out's suffix chose it: --format, else the one
    --out's suffix names (``.mp4``, ``.gif``; else png). A --out whose suffix names another picture or
    video format is refused (``--format mp4 --out anim.gif`` would write an MP4 named .gif), as is
    an animation's --out without its suffix (the encoder is chosen by it)."""
    suffix = Path(out).suffix.lower() if out else ""
    named = fmt is not None
    if fmt is None:
        fmt = {".mp4": "mp4", ".gif": "gif"}.get(suffix, "png")
    want = FORMAT_SUFFIX[fmt]
    if out is None or suffix == want or (suffix not in PICTURE_SUFFIXES and fmt in ("png", "gantt")):
        return fmt, not named and fmt != "png"
    name = Path(out).name
    if not named:
        raise UserError(f"--out {name}: cooprint draws .png (--format png or gantt), .mp4 or .gif, not "
                        f"{PICTURE_SUFFIXES[suffix]}")
    what = {"png": "a PNG", "gantt": "a PNG", "mp4": "an MP4", "gif": "a GIF"}[fmt]
    if suffix in PICTURE_SUFFIXES:
        other = {".png": " or --format png", ".mp4": " or --format mp4", ".gif": " or --format gif"}.get(suffix, "")
        raise UserError(f"--format {fmt} writes {what} but --out {name} is named as {PICTURE_SUFFIXES[suffix]}: "
                        f"give --out {Path(name).stem}{want}{other}")
    raise UserError(f"--format {fmt} writes {what}: give --out {name}{want}")


def _check_render_options(fmt: str, inferred: bool, at: float | None, duration: float | None,
                          speedup: float | None) -> None:
    """No option that the format ignores: ``--at`` is the png snapshot's time; ``--duration``,
    ``--speedup`` and ``--fps`` (given on the command line) shape an mp4 / gif animation.
    ``inferred``: --out's suffix chose the format (the message says so)."""
    label = f"--format {fmt}" + (" (from --out's suffix)" if inferred else "")
    if at is not None and fmt != "png":
        raise UserError(f"--at is the time of a png snapshot; {label} does not use it")
    fps_given = click.get_current_context().get_parameter_source("fps") == click.core.ParameterSource.COMMANDLINE
    given = [o for o, v in (("--duration", duration), ("--speedup", speedup), ("--fps", fps_given or None))
             if v is not None]
    if given and fmt not in ("mp4", "gif"):
        raise UserError(f"{given[0]} shapes an animation (--format mp4 or gif); {label} does not use it")


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
        rest = [a for a in args if a not in ("-v", "--verbose")]
        args = ["--verbose"] + rest if rest else []  # `cooprint -v` alone: the help, as `cooprint` alone
    try:
        # Ctrl-C while a compiled library loads: after it, not inside it; and never lost
        with held_imports(), sticky_sigint():
            code = cli.main(args=args, prog_name="cooprint", standalone_mode=False)
        if isinstance(code, int):  # click returns the code of an Exit (simulate --strict)
            return code
    except UserError as exc:
        if verbose:
            raise
        click.echo(f"cooprint: error: {one_line(str(exc))}", err=True)
        return exc.exit_code
    except (Interrupted, click.exceptions.Abort, KeyboardInterrupt):
        return _interrupted()
    except click.exceptions.NoArgsIsHelpError as exc:  # `cooprint` alone: the help, as asked for
        click.echo(exc.ctx.get_help() if exc.ctx is not None else cli.get_help(click.Context(cli)))
        return 0
    except click.ClickException as exc:  # a bad option or argument: one line too, no usage block
        if verbose:
            raise
        click.echo(f"cooprint: error: {one_line(exc.format_message())}", err=True)
        return 2
    except ValueError as exc:  # a path with a NUL character (only from Python: argv cannot hold one)
        if interrupted(exc):
            return _interrupted()
        if verbose or "null byte" not in str(exc):
            raise
        click.echo("cooprint: error: a path with a NUL character", err=True)
        return 2
    except OSError as exc:  # no space, no permission, read-only: the machine's state, not a bug; one line
        if interrupted(exc):
            return _interrupted()
        if verbose or exc.errno not in _WRITE_ERRNOS:
            raise
        where = f"{exc.filename}: " if exc.filename else ""
        click.echo(f"cooprint: error: {one_line(f'{where}{exc.strerror} ({errno.errorcode[exc.errno]})')}", err=True)
        return 2
    except Exception as exc:
        if interrupted(exc):  # a Ctrl-C wrapped by Python or a library
            return _interrupted()
        raise
    return 0


#: OS errors that mean "not possible on this machine, here", not a bug (a path too long or a
#: symlink loop is the user's path, not cooprint's).
_WRITE_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG,
                 errno.ENAMETOOLONG, errno.ELOOP}


def _interrupted() -> int:
    """Ctrl-C: one line, exit code 130; a second Ctrl-C while leaving is ignored (the atomic
    writers have already removed their temporary files, the slicer its worker processes)."""
    previous = _ignore_sigint()
    try:
        tty = sys.stderr.isatty()  # a terminal has echoed ^C: the line starts on a line of its own
        click.echo(("\n" if tty else "") + "cooprint: interrupted", err=True)
    except (OSError, ValueError):
        pass
    if previous is not None:  # in-process callers (tests, a REPL) get their Ctrl-C back
        signal.signal(signal.SIGINT, previous)
    return 130


def _ignore_sigint() -> Any:
    """Ignore Ctrl-C from now on; return the handler it had (None if not ours to set)."""
    try:
        return signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread: signals are not ours to set
        return None


def entry() -> None:
    """The ``cooprint`` command: :func:`main`, then out of the process without tearing the
    interpreter down. Everything a command writes is closed by then; what is left is unloading
    numba's compiled code one function at a time, 0.15-0.25 s for nothing."""
    code = main()
    _ignore_sigint()  # done: a Ctrl-C now must not turn into a traceback while leaving
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a reader that went away (`| head`), a closed stream
            pass
    os._exit(code)


if __name__ == "__main__":
    entry()
