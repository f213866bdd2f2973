"""Progress bars of the long commands: one bar per stage, with its rate and the time left.

The stages call a ``progress(stage, done, total)`` callback (:data:`cooprint.jobs.Progress`) in
units of their own work, named in :data:`STAGES`: the mesh and the files in bytes (the bar shows
MB/s), slicing in layers, cutting, scheduling and programs in chunks, the simulator's timelines
in robots and its checks one by one. :func:`rich_bars` draws them with rich (the CLI draws them
on a terminal only: a log or a pipe gets no bars); :class:`ByteMeter` counts the bytes a writer
writes, for the ``write`` stage.
"""

from __future__ import annotations

from contextlib import contextmanager
from typing import Any, Callable, Iterator

#: stage -> (label, unit of ``done`` and ``total``): ``bytes`` is shown as MB/s.
STAGES: dict[str, tuple[str, str]] = {
    "load": ("reading mesh", "bytes"),
    "cut": ("cutting chunks", "chunks"),
    "schedule": ("scheduling", "chunks"),
    "slice": ("slicing layers", "layers"),
    "program": ("robot programs", "chunks"),
    "write": ("writing files", "bytes"),
    "render": ("drawing picture", "pictures"),
    "read": ("reading programs", "bytes"),
    "timelines": ("timelines", "robots"),
    "checks": ("checks", "checks"),
    "pictures": ("pictures", "pictures"),
    "frames": ("animation frames", "frames"),
    "perturbed runs": ("perturbed runs", "runs"),
}


def stage_label(stage: str) -> str:
    """The bar's label of ``stage`` (unknown stages are shown by their name)."""
    return STAGES.get(stage, (stage, ""))[0]


def stage_unit(stage: str) -> str:
    """What ``done`` and ``total`` of ``stage`` count (``items`` when unknown)."""
    return STAGES.get(stage, ("", "items"))[1]


def rate_text(speed: float | None, unit: str) -> str:
    """``12.3 MB/s`` for bytes, ``250 layers/s``, ``0.5 chunks/s``; ``-`` before a rate is known."""
    if speed is None:
        return f"- {'MB' if unit == 'bytes' else unit}/s"
    if unit == "bytes":
        return f"{speed / 1e6:.1f} MB/s"
    return f"{speed:.0f} {unit}/s" if speed >= 10 else f"{speed:.2g} {unit}/s"


def rich_bars(console: Any) -> tuple[Any, Callable[[str, int, int], None]]:
    """A rich ``Progress`` on ``console`` (not started) and the ``progress(stage, done, total)``
    callback that adds a bar per stage as it first reports: label, bar, percentage, rate (the
    stage's unit per second), time elapsed and time remaining (rich's estimate from the rate)."""
    from rich.progress import (BarColumn, Progress, ProgressColumn, TaskProgressColumn, TextColumn,
                               TimeElapsedColumn, TimeRemainingColumn)
    from rich.text import Text

    class RateColumn(ProgressColumn):
        """The stage's rate in its own unit (finished: its average over the whole stage)."""

        def render(self, task: Any) -> Text:
            speed = task.speed
            if task.finished:  # the stage's average (a stage that reported once has no samples)
                speed = task.completed / task.finished_time if task.finished_time else task.finished_speed
            return Text(rate_text(speed, task.fields.get("unit", "items")), style="progress.data.speed")

    bars = Progress(TextColumn("{task.description:<18}"), BarColumn(), TaskProgressColumn(), RateColumn(),
                    TimeElapsedColumn(), TextColumn("eta"), TimeRemainingColumn(), console=console,
                    transient=False)
    tasks: dict[str, Any] = {}

    def update(stage: str, done: int, total: int) -> None:
        if stage not in tasks:
            tasks[stage] = bars.add_task(stage_label(stage), total=max(total, 1), unit=stage_unit(stage))
        bars.update(tasks[stage], completed=done, total=max(total, 1))

    return bars, update


class ByteMeter:
    """Counts the bytes written through :meth:`wrap`-ped files and reports them as
    ``progress(stage, bytes so far, total)`` every ``step`` bytes or more (``total``: the
    expected bytes, e.g. from the estimate; raised if the files turn out longer).
    :meth:`finish` reports the end."""

    def __init__(self, progress: Callable[[str, int, int], None] | None, total: int, stage: str = "write",
                 step: int = 1 << 22):
        self.progress, self.total, self.stage, self.step = progress, max(int(total), 1), stage, step
        self.done = 0
        self._reported = 0
        if progress:
            progress(stage, 0, self.total)

    def add(self, n: int) -> None:
        """``n`` more bytes written."""
        self.done += n
        if self.progress and self.done - self._reported >= self.step:
            self._reported = self.done
            self.total = max(self.total, self.done)
            self.progress(self.stage, self.done, self.total)

    def wrap(self, fh: Any) -> "_Counted":
        """``fh`` with its ``write`` counted (everything else passed through)."""
        return _Counted(fh, self)

    def finish(self) -> None:
        """Report the stage done (its total is what was written)."""
        if self.progress:
            self.total = max(self.done, 1)
            self.progress(self.stage, self.total, self.total)


class _Counted:
    """A file whose ``write`` counts its bytes into a :class:`ByteMeter`."""

    def __init__(self, fh: Any, meter: ByteMeter):
        self._fh, self._meter = fh, meter

    def write(self, data: Any) -> int:
        n = self._fh.write(data)
        self._meter.add(len(data))  # ASCII text: characters are bytes
        return n

    def __getattr__(self, name: str) -> Any:
        return getattr(self._fh, name)


@contextmanager
def bars_on(console: Any) -> Iterator[Callable[[str, int, int], None]]:
    """:func:`rich_bars` on ``console``, started and stopped around the block."""
    bars, update = rich_bars(console)
    with bars:
        yield update


def program_bytes(inputs: list[str]) -> int:
    """Bytes of the programs that ``cooprint simulate`` reads from ``inputs``: a bundle's
    ``robots/*.coop`` (and their ``.gz``), or the files given (at least 1: an empty bar is full)."""
    import os
    from pathlib import Path

    total = 0
    for x in inputs:
        p = Path(x)
        try:
            if p.is_dir():
                total += sum(f.stat().st_size for f in (p / "robots").glob("*.coop*") if f.is_file())
            elif p.is_file():
                total += os.path.getsize(p)
        except OSError:
            continue
    return max(total, 1)
