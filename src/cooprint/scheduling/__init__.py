"""Scheduler: which robot prints which chunk, in what order and when (seed §4.1, issue 14).

Strategies are functions over one record: ``(ChunkDAG, robot names, settings) -> Schedule``
(:mod:`.dag`, :mod:`.schedule`), by name in :data:`SCHEDULERS` (``list``: critical-path list
scheduling, :mod:`.listsched`; ``exact``: OR-Tools CP-SAT, :mod:`.exact`);
:func:`make_schedule` picks one from the settings and checks its result. The seed's two-robot
order (``seed2``) is the special case kept for the seed2 layout (:func:`seed_schedule`).
"""

from cooprint.scheduling.assign import Assignment, seed_two_robots
from cooprint.scheduling.dag import ChunkDAG
from cooprint.scheduling.exact import exact_schedule
from cooprint.scheduling.listsched import list_schedule, seed_schedule, timed
from cooprint.scheduling.schedule import Schedule, check_schedule
from cooprint.scheduling.schedulers import SCHEDULERS, make_schedule

__all__ = ["SCHEDULERS", "Assignment", "ChunkDAG", "Schedule", "check_schedule",
           "exact_schedule", "list_schedule", "make_schedule", "seed_schedule", "seed_two_robots", "timed"]
