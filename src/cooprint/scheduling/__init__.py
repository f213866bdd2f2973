"""Scheduler: which robot prints which chunk, in what order and when (seed §4.1, issue 14).

Strategies are functions over one record: ``(ChunkDAG, robot names, settings) -> Schedule``
(:mod:`.dag`, :mod:`.schedule`); the seed's two-robot order (``seed2``) is the special case
kept for the seed2 layout.
"""

from cooprint.scheduling.assign import STRATEGIES, Assignment, assign, seed_two_robots
from cooprint.scheduling.dag import ChunkDAG
from cooprint.scheduling.schedule import Schedule, check_schedule

__all__ = ["STRATEGIES", "Assignment", "ChunkDAG", "Schedule", "assign", "check_schedule", "seed_two_robots"]
