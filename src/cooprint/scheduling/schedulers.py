"""The scheduling strategies by name, and the one entry point the pipeline calls (issue 14).

``[scheduling] strategy`` (``--schedule``) picks one:

* ``list``: critical-path list scheduling (:func:`~cooprint.scheduling.listsched.list_schedule`);
* ``exact``: OR-Tools CP-SAT within ``time_limit_s`` (:func:`~cooprint.scheduling.exact.exact_schedule`),
  falling back to ``list`` with a note;
* ``seed``: the seed's two-robot order, timed (:func:`~cooprint.scheduling.listsched.seed_schedule`);
  only for a ``seed2`` chunk set and 1 or 2 robots;
* ``auto``: ``seed`` for a ``seed2`` chunk set with 1 or 2 robots (the settings' documented
  rule: the programs of that layout were built around it), ``list`` otherwise.

Every result is checked (:func:`~cooprint.scheduling.schedule.check_schedule`) before it is
returned: a schedule that breaks a rule is a bug, never a plan.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Sequence

from cooprint.errors import ConfigError
from cooprint.scheduling.dag import ChunkDAG
from cooprint.scheduling.exact import exact_schedule
from cooprint.scheduling.listsched import Scheduler, list_schedule, seed_schedule
from cooprint.scheduling.schedule import Schedule, check_schedule

if TYPE_CHECKING:
    from cooprint.chunking import ChunkSet
    from cooprint.config.settings import SchedulingSettings

#: The most robots a schedule is made for (issue 14).
MAX_ROBOTS = 64

SCHEDULERS: dict[str, Scheduler] = {
    "list": list_schedule,
    "exact": exact_schedule,
}


def make_schedule(dag: ChunkDAG, robots: Sequence[str], settings: "SchedulingSettings | None" = None,
                  chunks: "ChunkSet | None" = None) -> Schedule:
    """Schedule ``dag`` for ``robots`` with ``settings.strategy`` (module docstring) and check
    the result. ``chunks`` (the chunk set the DAG was built from) is needed by ``seed`` and
    ``auto``. Raises :class:`~cooprint.errors.ConfigError` for a robot count outside 1..64 or
    ``seed`` on a job it cannot schedule."""
    from cooprint.config.settings import SchedulingSettings

    settings = settings or SchedulingSettings()
    robots = list(robots)
    if not 1 <= len(robots) <= MAX_ROBOTS:
        raise ConfigError(f"robots = {len(robots)}: expected 1 to {MAX_ROBOTS}")
    if len(set(robots)) != len(robots):
        raise ConfigError(f"robots = {robots}: expected distinct names")
    strategy = settings.strategy
    seedable = chunks is not None and chunks.layout == "seed2" and len(robots) <= 2
    if strategy == "auto":
        strategy = "seed" if seedable else "list"
    if strategy == "seed":
        if not seedable:
            layout = chunks.layout if chunks is not None else "unknown"
            raise ConfigError(f"scheduling.strategy = 'seed': the seed's order schedules the seed2 layout for "
                              f"1 or 2 robots, not layout {layout} with {len(robots)} robots (use list or exact)")
        assert chunks is not None
        sched = seed_schedule(dag, robots, chunks)
    elif strategy in SCHEDULERS:
        sched = SCHEDULERS[strategy](dag, robots, settings)
    else:
        raise ConfigError(f"scheduling.strategy = {strategy!r}: expected one of auto, seed, "
                          f"{', '.join(SCHEDULERS)}")
    check_schedule(dag, sched)
    return sched
