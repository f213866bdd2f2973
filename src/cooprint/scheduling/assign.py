"""The ordered chunk lists per robot (:class:`Assignment`, which :class:`~cooprint.scheduling.Schedule`
extends with times) and the seed's two-robot order."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from cooprint.chunking import ChunkSet
from cooprint.errors import ConfigError


@dataclass(frozen=True)
class Assignment:
    """Ordered chunk lists per robot.

    Attributes
    ----------
    sequences : dict
        ``{robot name: (chunk id, ...)}`` in printing order.
    strategy : str
        Name of the strategy that made it.
    """

    sequences: dict[str, tuple[str, ...]]
    strategy: str

    def robot_of(self, cid: str) -> str:
        for robot, seq in self.sequences.items():
            if cid in seq:
                return robot
        raise KeyError(cid)

    def order_of(self, cid: str) -> int:
        """Position of the chunk in its robot's sequence, from 0."""
        return self.sequences[self.robot_of(cid)].index(cid)

    def cross_robot_deps(self, deps: dict[str, tuple[str, ...]]) -> list[tuple[str, str]]:
        """``(before, after)`` pairs where ``after`` waits for another robot's ``before``:
        the synchronisation points (NOTIFY/WAIT) of the program."""
        return [(d, cid) for cid, ds in deps.items() for d in ds
                if self.robot_of(d) != self.robot_of(cid)]


def seed_two_robots(chunks: ChunkSet, robots: Sequence[str] = ("A", "B")) -> Assignment:
    """Seed eq. (6)-(7): robot A prints the centre chunk then the left chunks outwards,
    robot B the right chunks outwards (one robot: all of them, centre, left, then right)."""
    ids = chunks.ids
    centre = [c for c in ids if c == "C"]
    left = [c.id for c in chunks.chunks if c.role == "left"]
    right = [c.id for c in chunks.chunks if c.role == "right"]
    if len(robots) == 1:
        return Assignment({robots[0]: tuple(centre + left + right)}, "seed2")
    if len(robots) != 2:
        raise ConfigError(f"robots = {len(robots)}: the seed strategy schedules 1 or 2 robots")
    return Assignment({robots[0]: tuple(centre + left), robots[1]: tuple(right)}, "seed2")
