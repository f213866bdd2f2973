"""Scheduler: which robot prints which chunk, in what order (seed §4.1).

Strategies are functions ``(ChunkSet, robot names) -> Assignment`` registered in ``STRATEGIES``;
N-robot strategies plug in there.
"""

from cooprint.scheduling.assign import STRATEGIES, Assignment, assign, seed_two_robots

__all__ = ["STRATEGIES", "Assignment", "assign", "seed_two_robots"]
