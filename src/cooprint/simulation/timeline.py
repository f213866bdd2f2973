"""Every robot's program in time (seed §5.2): when each move starts and ends, where, and whether
it deposits; when each NOTIFY is announced and how long each WAIT blocks.

Times come from the command stream, not from stepping a clock: a move's duration is its length
over its speed (the robot's :class:`~cooprint.program.gcode.Feeds`: the slicer's speed of the
move's path role with the tool on, at most the first-layer speed on layer 0, the travel speed
with it off, each under the robot's caps; or a G-code file's own feed rate), so the state at any
instant is exact and does not drift. WAITs are
resolved by walking all robots forward together: a robot runs until a WAIT whose events are not
all announced yet; a WAIT ends at the latest announcement of its events (or at once). Robots that
can never go on are a deadlock, found from the commands alone, before any geometry is looked at.
"""

from __future__ import annotations

import math

from dataclasses import dataclass, field, replace

import numpy as np

from typing import TYPE_CHECKING, Callable, Iterable, Mapping

from cooprint.geometry import unit_deg, unit_xy
from cooprint.program.commands import MOVE, NOTIFY, WAIT, Program

if TYPE_CHECKING:
    from cooprint.config import RobotProfile
    from cooprint.program.gcode import Feeds
    from cooprint.simulation.kinematics import MachineLimits


@dataclass(frozen=True)
class SimRobot:
    """A robot to simulate: its program and where it stands.

    Attributes
    ----------
    name : str
    program : Program
    start : (3,) float
        Nozzle position before the first command, mm (``None``: at the first MOVE's target).
    facing : (2,) float
        Unit XY vector from the body to the nozzle (the body stands ``build_depth`` behind), at
        the start; the program's ``;@facing`` turns (:attr:`Program.turns`) change it on the way
        (:meth:`facing_spans`).
    speed : (n,) float or None
        Per-command speed of MOVEs, mm/s (a G-code file's feed rates); ``None``: the robot's
        :class:`~cooprint.program.gcode.Feeds` (given to :func:`schedule` and the others).
    de : (n,) float or None
        Filament pushed by each command, mm (a G-code file's E): a move of filament alone takes
        ``|E| / speed``, and the acceleration model limits the E axis too.
    notes : tuple of str
        What the reader found and did not act on (a G-code file's operator pauses), for the summary.
    profile : RobotProfile or None
        This robot's own profile (speed caps, body, printhead: a mixed fleet); ``None``: the input's
        (:meth:`SimInput.fleet` fills it in, so that every check sees each robot's own geometry).
    """

    name: str
    program: Program
    start: np.ndarray | None
    facing: np.ndarray
    speed: np.ndarray | None = None
    de: np.ndarray | None = None
    notes: tuple[str, ...] = ()
    profile: "RobotProfile | None" = None

    def facing_spans(self, tl: "Timeline") -> list["FacingSpan"]:
        """The robot's timeline cut where its facing changes: one span per facing in force, in
        order. A turn before command ``i`` takes effect from the first move at or after ``i``,
        at that move's start (where and when the robot turns); two turns at the same place give
        a span without moves (the robot passes through that facing while turning there)."""
        spans = [FacingSpan(0, len(tl.t0), unit_xy(self.facing), 0.0 if not len(tl.t0) else float(tl.t0[0]),
                            self._start_position(tl))]
        for i, deg in self.program.turns:
            k = int(np.searchsorted(tl.index, i, side="left"))
            if k < len(tl.t0):
                when, where = float(tl.t0[k]), tl.p0[k]
            elif len(tl.t0):
                when, where = float(tl.t1[-1]), tl.p1[-1]
            else:
                when, where = 0.0, self._start_position(tl)
            last = spans[-1]
            spans[-1] = FacingSpan(last.start, k, last.facing, last.time, last.position)
            spans.append(FacingSpan(k, len(tl.t0), unit_deg(deg), when, np.asarray(where, dtype=np.float64)))
        return spans

    def facing_at(self, tl: "Timeline", t: np.ndarray | float) -> np.ndarray:
        """(..., 2) the facing in force at time(s) ``t`` (a turn at time T is in force from T on)."""
        spans = self.facing_spans(tl)
        start = np.array([sp.time for sp in spans])
        k = np.clip(np.searchsorted(start[1:], np.asarray(t, dtype=np.float64), side="right"), 0, len(spans) - 1)
        return np.stack([sp.facing for sp in spans])[k]

    def _start_position(self, tl: "Timeline") -> np.ndarray:
        if self.start is not None:
            return np.asarray(self.start, dtype=np.float64)
        return tl.p0[0].astype(np.float64) if len(tl.t0) else np.zeros(3)

    def bead(self, index: np.ndarray, width: float, height: float) -> tuple[np.ndarray, np.ndarray]:
        """Width and height of the material laid by commands ``index``: their annotations, or
        ``width`` and ``height`` (the slicing settings') where a program has none."""
        return _or_default(self.program.width, index, width), self.layer_heights(index, height)

    def layer_heights(self, index: np.ndarray, height: float) -> np.ndarray:
        """The height of the material laid by commands ``index`` (:meth:`bead`'s second half)."""
        return _or_default(self.program.height, index, height)


def _or_default(column: "np.ndarray | Runs", index: np.ndarray, default: float) -> np.ndarray:
    """``column[index]`` where above 0, else ``default``: a new array (filled in place, no
    temporary of the size of ``index``)."""
    out = column[index]
    if isinstance(column, np.ndarray) and np.may_share_memory(out, column):  # a view (``index`` a slice)
        out = out.copy()
    np.copyto(out, default, where=~(out > 0))
    return out


class Runs:
    """A per-command column held as runs of equal values (a program's annotations change
    seldom: a chunk, a layer's height, a path's width hold for many commands): ``values[r]``
    from command ``starts[r]`` (``starts[0] == 0``, increasing) to the next run's start, ``n``
    commands in all. Indexed as the array it stands for (an index, a slice, an array of
    indices give what the array would: new arrays, never views); ``np.asarray`` makes the array."""

    def __init__(self, starts: np.ndarray, values: np.ndarray, n: int) -> None:
        self.starts, self.values, self.n = starts, values, n

    dtype = property(lambda self: self.values.dtype)
    shape = property(lambda self: (self.n,))
    ndim = 1

    @property
    def nbytes(self) -> int:
        return self.starts.nbytes + self.values.nbytes

    def __len__(self) -> int:
        return self.n

    def _runs(self, index: np.ndarray) -> np.ndarray:
        return np.searchsorted(self.starts, index, side="right") - 1

    def __getitem__(self, key):
        if isinstance(key, slice):
            return self.values[self._runs(np.arange(*key.indices(self.n)))]
        if isinstance(key, (int, np.integer)):
            i = int(key) + (self.n if key < 0 else 0)
            if not 0 <= i < self.n:
                raise IndexError(f"index {int(key)} out of {self.n}")
            return self.values[self._runs(i)]
        index = np.asarray(key)
        if index.dtype == bool:
            index = np.flatnonzero(index)
        if index.size and index.min() < 0:
            index = np.where(index < 0, index + self.n, index)
        if index.size and not (0 <= index.min() and index.max() < self.n):
            raise IndexError(f"an index out of {self.n}")
        return self.values[self._runs(index)]

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        out = np.repeat(self.values, np.diff(np.append(self.starts, self.n)))
        return out if dtype is None else out.astype(dtype)

    def segment_max(self, at: np.ndarray) -> np.ndarray:
        """``np.maximum.reduceat`` of the column at ``at`` (command indices, increasing or
        equal): the largest value of commands ``at[j]`` to ``at[j + 1] - 1`` (to the end for
        the last; the value at ``at[j]`` where ``at[j + 1] == at[j]``), from the runs."""
        at = np.asarray(at, dtype=np.int64)
        ends = np.append(at[1:], self.n)
        first = self._runs(at)
        last = np.maximum(self._runs(ends - 1), first)
        pairs = np.empty(2 * len(at), np.int64)
        pairs[0::2], pairs[1::2] = first, last + 1
        values = np.append(self.values, self.values[:1])  # room for an index one past the last run
        return np.maximum.reduceat(values, pairs)[0::2]


def segment_max(column: "np.ndarray | Runs", at: np.ndarray) -> np.ndarray:
    """``np.maximum.reduceat(column, at)`` of a program's column, an array or :class:`Runs`."""
    return column.segment_max(at) if isinstance(column, Runs) else np.maximum.reduceat(column, at)


def changes(column: "np.ndarray | Runs", index: np.ndarray) -> np.ndarray:
    """The positions ``m`` (from 1) where ``column[index[m]] != column[index[m - 1]]``
    (``index`` increasing: a timeline's moves' commands), as ``np.flatnonzero(c[1:] != c[:-1]) + 1``
    of ``c = column[index]`` gives them; from :class:`Runs`, looking only where a run begins."""
    if not isinstance(column, Runs):
        c = column[index]
        return np.flatnonzero(c[1:] != c[:-1]) + 1
    m = np.unique(np.searchsorted(index, column.starts[1:], side="left"))  # the first move of each run
    m = m[(m > 0) & (m < len(index))]
    return m[column[index[m]] != column[index[m - 1]]]


class _RunsBuilder:
    """A :class:`Runs` column made piece by piece: each piece's values cut where they change
    (by their bits: 0.0 and -0.0 are two runs, as they are two values)."""

    def __init__(self, dtype) -> None:
        self.dtype = np.dtype(dtype)
        self.starts: list[np.ndarray] = []
        self.values: list[np.ndarray] = []
        self.last: np.ndarray | None = None
        self.n = 0

    def add(self, v: np.ndarray) -> None:
        v = np.ascontiguousarray(v, dtype=self.dtype)
        if not len(v):
            return
        bits = v.view(np.dtype(f"u{self.dtype.itemsize}"))
        cut = np.flatnonzero(bits[1:] != bits[:-1]) + 1
        if self.last is None or self.last != bits[0]:
            cut = np.r_[0, cut]
        self.starts.append(cut + self.n)
        self.values.append(v[cut])
        self.last, self.n = bits[-1], self.n + len(v)

    def runs(self) -> Runs:
        starts = np.concatenate(self.starts) if self.starts else np.zeros(0, np.int64)
        values = np.concatenate(self.values) if self.values else np.zeros(0, self.dtype)
        return Runs(starts.astype(np.int64), values, self.n)


@dataclass(frozen=True)
class FacingSpan:
    """A stretch of a robot's timeline with one facing: moves ``start:stop`` of the timeline
    (possibly none), the ``facing`` (unit XY, from the body to the nozzle), and the ``time`` and
    nozzle ``position`` (3,) where it comes into force (the turn; the start for the first)."""

    start: int
    stop: int
    facing: np.ndarray
    time: float
    position: np.ndarray


class Lengths:
    """A timeline's moves' lengths, mm, not held but computed from its ends when asked (an
    index, a slice, an array of indices or a mask; ``np.asarray`` for all): with the move
    table's operations (``sqrt(dx*dx + dy*dy + dz*dz)``), so the same numbers as the array it
    stands for; ``sum()`` is numpy's sum of that array to the last bit (a block at a time). A
    timeline timed piece by piece keeps this instead of 8 bytes a move."""

    def __init__(self, p0: np.ndarray, p1: np.ndarray) -> None:
        self.p0, self.p1 = p0, p1

    dtype = np.dtype(np.float64)
    ndim = 1
    shape = property(lambda self: (len(self.p0),))

    def __len__(self) -> int:
        return len(self.p0)

    def __getitem__(self, key):
        if not isinstance(key, slice):
            key = np.asarray(key)
            if key.dtype == bool:
                key = np.flatnonzero(key)
        d = self.p1[key] - self.p0[key]
        out = d[..., 0] * d[..., 0]
        out += d[..., 1] * d[..., 1]
        out += d[..., 2] * d[..., 2]
        return np.sqrt(out, out=out) if isinstance(out, np.ndarray) else np.sqrt(out)

    def __array__(self, dtype=None, copy=None) -> np.ndarray:
        out = self[:]
        return out if dtype is None else out.astype(dtype)

    def sum(self) -> float:
        from cooprint.simulation.checks import block_sum

        return block_sum(lambda a, e: self[a:e], len(self))


@dataclass(frozen=True)
class Timeline:
    """One robot's moves in time (only MOVE commands; ``index`` maps them back).

    Attributes
    ----------
    t0, t1 : (k,) float64
        Start and end of each move, s.
    p0, p1 : (k, 3) float64
        Nozzle position at its start and end, mm.
    on : (k,) bool
        The move deposits material (tool on and it goes somewhere).
    index : (k,) int64
        The move's command index in the program.
    waits : list of (start, end, events)
        Each WAIT: when the robot got there, when it went on, what it waited for.
    notifies : list of (time, event)
    length : (k,) float64 or Lengths
        Length of each move, mm (computed when not given; a timeline timed piece by piece
        computes them from its ends when asked, :class:`Lengths`).
    """

    robot: str
    t0: np.ndarray
    t1: np.ndarray
    p0: np.ndarray
    p1: np.ndarray
    on: np.ndarray
    index: np.ndarray
    waits: list = field(default_factory=list)
    notifies: list = field(default_factory=list)
    length: np.ndarray = field(default=None, repr=False)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if self.length is None:
            d = self.p1 - self.p0
            object.__setattr__(self, "length", np.sqrt(np.einsum("ij,ij->i", d, d)))

    @property
    def end(self) -> float:
        ends = [float(self.t1[-1])] if len(self.t1) else [0.0]
        ends += [w[1] for w in self.waits] + [n[0] for n in self.notifies]
        return max(ends)

    def position(self, t: np.ndarray | float) -> np.ndarray:
        """(..., 3) nozzle position at time(s) ``t``: the move under way, interpolated."""
        t = np.asarray(t, dtype=np.float64)
        if len(self.t1) == 0:
            return np.zeros(t.shape + (3,))
        k = np.clip(np.searchsorted(self.t1, t, side="left"), 0, len(self.t1) - 1)
        span = self.t1[k] - self.t0[k]
        f = np.clip(np.where(span > 0, (t - self.t0[k]) / np.where(span > 0, span, 1.0), 1.0), 0.0, 1.0)
        return self.p0[k] + f[..., None] * (self.p1[k] - self.p0[k])

    def deposited(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Segments (m, 2, 3) of material laid down by time ``t`` (the last one cut at ``t``) and
        the move index of each."""
        k = int(np.searchsorted(self.t0, t, side="left"))
        idx = np.flatnonzero(self.on[:k])
        seg = np.stack([self.p0[idx], self.p1[idx]], axis=1)
        if len(idx) and self.t1[idx[-1]] > t:
            seg[-1, 1] = self.position(t)
        return seg, idx


#: Finding kinds that are warnings: the plan can still be printed (every other kind is an error).
WARNING_KINDS = frozenset({"overhang"})


#: What a finding's ``count`` counts, by kind (each check counts what it looks at).
COUNT_UNITS = {"body-on-material": "nozzle samples", "printhead-hits-material": "nozzle samples",
               "robots-collide": "instants", "nozzle-in-material": "cells", "double-deposit": "cells",
               "chunk-order": "unfinished dependencies", "outside-part": "material points",
               "deadlock": "WAITs", "below-lower-bound": "makespans", "below-floor": "moves", "overhang": "material points"}


def severity(kind: str) -> str:
    """``warning`` or ``error``: how bad a finding of ``kind`` is."""
    return "warning" if kind in WARNING_KINDS else "error"


@dataclass(frozen=True)
class Finding:
    """A physical problem of a plan: what, which robot, when, where, in which chunk."""

    kind: str  # one of simulation.KINDS: body-on-material, robots-collide, printhead-hits-material, ...
    robot: str
    time: float
    position: tuple[float, float, float]
    chunk: str | None
    detail: str
    count: int = 1  # how many instants or places of the same kind it stands for

    @property
    def severity(self) -> str:
        """``warning`` for an overhang (the plan can still be printed), else ``error``."""
        return severity(self.kind)

    def to_dict(self) -> dict[str, object]:
        return {"kind": self.kind, "severity": self.severity, "robot": self.robot, "time_s": self.time,
                "position": list(self.position), "chunk": self.chunk, "detail": self.detail, "count": self.count,
                "count_of": self.count_of}

    @property
    def count_of(self) -> str:
        """What ``count`` counts (:data:`COUNT_UNITS`): instants, cells, points, samples..."""
        return COUNT_UNITS.get(self.kind, "places")


#: Moves whose speeds :func:`move_durations` works out at a time (its work space: about 30 bytes
#: a move of a block, not of the program).
SPEED_BLOCK = 1 << 16


def robot_feeds(feeds: "Feeds | Mapping[str, Feeds]", name: str) -> "Feeds":
    """Robot ``name``'s speeds: ``feeds`` itself (one for all), or its entry (per robot name)."""
    return feeds[name] if isinstance(feeds, Mapping) else feeds


def move_durations(r: SimRobot, feeds: "Feeds", limits: "MachineLimits | None" = None
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per MOVE of robot ``r``: start and end positions, whether it deposits, and its duration:
    length / speed, or with ``limits`` the trapezoidal profile of :mod:`.kinematics`. The speeds
    are ``r.speed`` (a G-code file's), else ``feeds``' of each move's role and layer
    (:meth:`Feeds.move_speeds`: the robot's own speeds, its profile's caps applied).

    Returns ``(index (k,), p0 (k, 3), p1 (k, 3), on (k,), length (k,), duration (k,))``: the
    moves' command indices, ends, whether they deposit, lengths and durations.
    """
    from cooprint.simulation.kernels import move_table  # numba: on first use

    program = r.program
    start = np.zeros(3) if r.start is None else np.asarray(r.start, dtype=np.float64)
    k = int(np.count_nonzero(program.kind == MOVE))
    # the moves' ends in one array, move j from row j to row j + 1 (each move starts where the one
    # before ends): start and end positions are two views of it, not two copies
    ends = np.empty((k + 1, 3))
    p0, p1 = ends[:-1], ends[1:]
    mv, on, length = np.empty(k, np.int64), np.empty(k, bool), np.empty(k)
    move_table(program.kind, program.xyz, start, r.start is not None, mv, p0, p1, on, length)
    if r.speed is None:  # each move's speed of its role and layer, a block at a time (bounded work space)
        v = np.empty(k)
        for a in range(0, k, SPEED_BLOCK):
            m = mv[a:a + SPEED_BLOCK]
            v[a:a + SPEED_BLOCK] = feeds.move_speeds(program.role[m], program.layer[m], on[a:a + SPEED_BLOCK])
    else:
        v = r.speed[mv]
    if limits is None and r.de is None:  # length / speed, in place
        dur = np.divide(length, v, out=v if v.dtype == np.float64 else None)
        return mv, p0, p1, on, length, dur
    de = np.zeros(len(mv)) if r.de is None else r.de[mv]
    if limits is None:
        dur = np.abs(de)  # a move of filament alone takes |E| / speed
        np.copyto(dur, length, where=length > 0)
        dur /= v
    else:
        from cooprint.simulation.kinematics import trapezoid_durations

        dur = trapezoid_durations(np.column_stack([p1 - p0, de]), v, limits)
    return mv, p0, p1, on, length, dur


def _resolve(syncs: dict[str, list[tuple[int, float, bool, tuple[str, ...]]]]):
    """WAITs resolved against the NOTIFYs of all robots: ``syncs`` gives each robot's NOTIFY and
    WAIT commands in order as ``(command index, time it gets there without waiting, is a
    NOTIFY, events)``. Returns ``(announced {event: s}, pos {robot: syncs passed}, waited
    {robot: s waited in all}, delay {robot: [(command index, s waited there)]}, waits, notifies)``;
    a robot whose ``pos`` is short of its syncs is stuck at that WAIT."""
    announced: dict[str, float] = {}
    pos = {name: 0 for name in syncs}  # next sync command
    waited = {name: 0.0 for name in syncs}  # total time spent waiting so far
    delay: dict[str, list] = {name: [] for name in syncs}  # (command index, extra wait)
    waits: dict[str, list] = {name: [] for name in syncs}
    notifies: dict[str, list] = {name: [] for name in syncs}
    progress = True
    while progress:
        progress = False
        for name, sync in syncs.items():
            while pos[name] < len(sync):
                i, before, notify, events = sync[pos[name]]
                t = before + waited[name]
                if notify:
                    for e in events:
                        announced[e] = min(announced.get(e, np.inf), t)
                    notifies[name].append((t, events[0]))
                else:
                    if not all(e in announced for e in events):
                        break
                    go = max([t] + [announced[e] for e in events])
                    delay[name].append((i, go - t))
                    waits[name].append((t, go, events))
                    waited[name] += go - t
                pos[name] += 1
                progress = True
    return announced, pos, waited, delay, waits, notifies


def schedule(robots: list[SimRobot], feeds: "Feeds | Mapping[str, Feeds]",
             limits: "MachineLimits | dict[str, MachineLimits] | None" = None
             ) -> tuple[dict[str, Timeline], list[Finding]]:
    """Every robot's :class:`Timeline`, WAITs resolved against the NOTIFYs of all robots
    (``feeds``, the speeds per role, and ``limits``: one for all, or per robot name).

    A robot stuck at a WAIT that can never end (its events are never announced, or only by
    robots stuck themselves) is a ``deadlock`` finding; its timeline stops there.
    """
    prep = {}
    for r in robots:
        mv, p0, p1, on, length, dur = move_durations(r, robot_feeds(feeds, r.name),
                                                     limits.get(r.name) if isinstance(limits, dict) else limits)
        kind = r.program.kind
        # each move's start without waits: the durations of the moves before it added in order
        # (the other commands take no time), and the total last
        starts = np.empty(len(mv) + 1)
        starts[0] = 0.0
        np.cumsum(dur, out=starts[1:])
        sync = np.flatnonzero(kind >= NOTIFY).tolist()  # NOTIFY and WAIT
        # the time at each NOTIFY and WAIT, without waits (by command index)
        before = dict(zip(sync, starts[np.searchsorted(mv, sync)]))
        prep[r.name] = (r, p0, p1, on, length, dur, mv, starts, before, sync)
    return _timelines(prep)


def _timelines(prep: dict) -> tuple[dict[str, Timeline], list[Finding]]:
    """:func:`schedule`'s second half: each robot's moves timed without waits (``prep``: per
    robot ``(robot, p0, p1, on, length, duration, command index, starts without waits (k + 1,),
    {sync command: time without waits}, sync commands)``; lengths ``None``: :class:`Lengths`
    of the ends), the WAITs resolved and added in."""
    syncs = {name: [(i, float(before[i]), r.program.kind[i] == NOTIFY, r.program.events[r.program.event[i]])
                    for i in sync] for name, (r, *_, before, sync) in prep.items()}
    announced, pos, waited, delay, waits, notifies = _resolve(syncs)
    out, findings = {}, []
    for name, (r, p0, p1, on, length, dur, mv, starts, before, sync) in prep.items():
        # the waits' delays so far before each command: of the WAITs above it (in program order)
        at = np.array([i for i, _ in delay[name]], dtype=np.int64)
        waited_before = np.concatenate([[0.0], np.cumsum([d for _, d in delay[name]])])
        runs = np.searchsorted(mv, at, side="right").tolist()  # the first move after each WAIT
        keep = len(mv)
        if pos[name] < len(sync):  # stuck: nothing after the WAIT happens
            i = sync[pos[name]]
            keep = int(np.searchsorted(mv, i))
            prog = r.program
            missing = [e for e in prog.events[prog.event[i]] if e not in announced]
            t = float(before[i] + waited[name])
            where = p1[keep - 1] if keep else (r.start if r.start is not None else np.zeros(3))
            chunk = _chunk_at(prog, i)
            findings.append(Finding("deadlock", name, t, tuple(float(x) for x in where), chunk,
                                    f"WAIT {', '.join(prog.events[prog.event[i]])} (command {i + 1}) never ends: "
                                    f"{', '.join(missing)} is never announced by a robot that can still move"))
        # each move's start: its start without waits plus the delays of the WAITs above it, one
        # addition per run of moves between two WAITs, in place
        for a, e, w in zip([0] + runs, runs + [len(mv)], waited_before.tolist()):
            if w:
                starts[a:e] += w
        t0 = starts[:keep]
        out[name] = Timeline(name, t0, np.add(t0, dur[:keep], out=dur[:keep]), p0[:keep], p1[:keep], on[:keep],
                             mv[:keep], waits[name], notifies[name],
                             length[:keep] if length is not None else Lengths(p0[:keep], p1[:keep]))
    return out, findings


#: The per-command columns a robot timed from pieces keeps (:func:`schedule_pieces`): what the
#: timeline's resolution, the checks and the pictures read of a program after it is timed (the
#: paths' roles: for the viewer's colours per role).
KEPT_COLUMNS = ("kind", "role", "width", "height", "chunk", "event")


def schedule_pieces(robots: list[SimRobot], pieces: dict[str, Callable[[], Iterable[Program]]],
                    feeds: "Feeds | Mapping[str, Feeds]", room: dict[str, int] | None = None
                    ) -> tuple[list[SimRobot], dict[str, Timeline], list[Finding]]:
    """:func:`schedule` at constant speed (``feeds``: one for all, or per robot name) for robots
    whose programs come piece by piece
    (``pieces[name]()``: the program's pieces in order, e.g. :func:`~cooprint.program.commands.iter_coop`;
    ``room``: at least as many commands as a robot's program holds, by name, where known, so that
    its columns grow in place): the same timelines and findings to the last bit, without the
    whole programs. Returns the robots with programs that keep only :data:`KEPT_COLUMNS` (the
    kinds an array, the others :class:`Runs`; their targets and layers are constant
    arrays that take no memory: ``xyz`` NaN), which
    every check and picture reads, but which cannot be timed again (a perturbed or accelerated
    run reads the programs whole)."""
    prep, slim = {}, []
    for r in robots:
        r2, prep[r.name] = _piece_prep(r, pieces[r.name](), robot_feeds(feeds, r.name).speeds,
                                       (room or {}).get(r.name, 0))
        slim.append(r2)
    timelines, findings = _timelines(prep)
    return slim, timelines, findings


def _grown(a: np.ndarray, n: int) -> np.ndarray:
    """``a`` with room for at least ``n`` rows (in place where it can: pages never written are
    never backed by memory)."""
    if n <= len(a):
        return a
    a.resize((max(n, 2 * len(a)),) + a.shape[1:], refcheck=False)
    return a


#: A robot timed piece by piece keeps its moves' command indices in int32 below this many commands.
INT32_COMMANDS = 2**31 - 1


def _constant(dtype, value, shape: tuple[int, ...]) -> np.ndarray:
    """A read-only array of ``shape`` holding ``value`` everywhere, in one element of memory."""
    return np.broadcast_to(np.array(value, dtype), shape)


def _timed_pieces(pieces: Iterable[Program], start: np.ndarray, speed: Callable[[Program, bool], np.ndarray]):
    """A program's pieces in order, each with its moves timed as :func:`move_durations` times the
    whole program: the moves' table continued from piece to piece (the first move from
    ``start``, the tool as the pieces before leave it), each duration ``length / speed``
    (``speed(piece, tool on before it)[move]``: :meth:`Feeds.speeds`, the same speeds as
    :meth:`Feeds.move_speeds` of the whole program), the starts one running sum, the same
    additions in the same order as the whole program's. Yields ``(at, k, piece, mv, ends, on, dur, starts)``:
    the commands and moves before the piece, the piece, its moves' command indices in it,
    their ends ``(m + 1, 3)`` (move j from row j to row j + 1), whether they deposit, their
    durations and the time each starts without waits ``(m + 1,)`` (the last: the piece's end)."""
    from cooprint.simulation.kernels import move_table  # numba: on first use

    at = k = 0
    t, tool = 0.0, False
    pos = np.asarray(start, dtype=np.float64)
    for piece in pieces:
        m = int(np.count_nonzero(piece.kind == MOVE))
        ends, mv, on, length = np.empty((m + 1, 3)), np.empty(m, np.int64), np.empty(m, bool), np.empty(m)
        ends[0] = pos
        move_table(piece.kind, piece.xyz, pos, True, mv, ends[:-1], ends[1:], on, length)
        tool_on = piece.tool_on(tool)
        np.logical_and(tool_on[mv], length > 0, out=on)
        dur = length / speed(piece, tool)[mv]
        starts = np.cumsum(np.r_[t, dur])
        yield at, k, piece, mv, ends, on, dur, starts
        t, pos = float(starts[-1]), ends[-1].copy()
        if len(piece):
            tool = bool(tool_on[-1])
        at, k = at + len(piece), k + m


def _piece_prep(r: SimRobot, pieces: Iterable[Program], speed: Callable[[Program, bool], np.ndarray], room: int):
    """One robot of :func:`schedule_pieces`: its slim program and ``_timelines``' tuple, built a
    piece at a time with :func:`move_durations`' operations (the moves' table continued from
    piece to piece, each duration ``length / speed``, the starts one running sum): the same
    numbers as of the whole program."""
    if r.start is None:
        raise ValueError(f"robot {r.name}: a program timed piece by piece needs its start")
    room = max(room, 1)
    kind = np.empty(room, np.uint8)  # changes nearly every command: an array
    cols = {"role": _RunsBuilder(np.uint8), "width": _RunsBuilder(np.float64), "height": _RunsBuilder(np.float64),
            "chunk": _RunsBuilder(np.int16), "event": _RunsBuilder(np.int32)}  # change seldom: runs
    # the moves' command indices in 4 bytes while they fit (in 8 past 2^31 commands)
    ends, mv = np.empty((room + 1, 3)), np.empty(room, np.int32 if room < INT32_COMMANDS else np.int64)
    on, dur, starts = np.empty(room, bool), np.empty(room), np.empty(room + 1)
    ends[0] = np.asarray(r.start, dtype=np.float64)
    starts[0] = 0.0
    commands = moves = 0  # in all
    chunks: list[str] = []
    events: list[tuple[str, ...]] = []
    turns: list[tuple[int, float]] = []
    sync: list[int] = []
    before: dict[int, float] = {}
    for at, k, piece, pm, p_ends, p_on, p_dur, p_starts in _timed_pieces(pieces, r.start, speed):
        n, m = len(piece), len(pm)
        commands, moves = at + n, k + m
        chunks += [c for c in piece.chunks if c not in chunks]  # in the order they first appear (read_coop's)
        turns += [(i + at, deg) for i, deg in piece.turns]  # (a piece without commands may hold a turn)
        if n == 0:
            continue
        kind = _grown(kind, at + n)
        if mv.dtype == np.int32 and at + n >= INT32_COMMANDS:
            mv = mv.astype(np.int64)
        remap = np.array([chunks.index(c) for c in piece.chunks] + [-1], dtype=np.int16)
        kind[at:at + n] = piece.kind
        cols["role"].add(piece.role)
        cols["width"].add(piece.width)
        cols["height"].add(piece.height)
        cols["chunk"].add(remap[piece.chunk])  # -1 indexes the appended -1
        cols["event"].add(np.where(piece.event >= 0, piece.event + len(events), -1))
        events += piece.events
        ends, starts = _grown(ends, k + m + 1), _grown(starts, k + m + 1)
        mv, on, dur = (_grown(a, k + m) for a in (mv, on, dur))
        mv[k:k + m], on[k:k + m], dur[k:k + m] = pm + at, p_on, p_dur
        ends[k + 1:k + m + 1], starts[k + 1:k + m + 1] = p_ends[1:], p_starts[1:]
        for j in np.flatnonzero(piece.kind >= NOTIFY).tolist():  # NOTIFY and WAIT
            sync.append(at + j)
            before[at + j] = p_starts[int(np.searchsorted(pm, j))]
    at, k = commands, moves
    kind.resize(at, refcheck=False)  # in place: the rest goes back
    cols = {f: b.runs() for f, b in cols.items()}
    ends.resize((k + 1, 3), refcheck=False)
    starts.resize(k + 1, refcheck=False)
    for a in (mv, on, dur):
        a.resize(k, refcheck=False)
    program = Program(r.name, kind, _constant(np.float64, np.nan, (at, 3)), cols["role"], cols["width"],
                      _constant(np.int32, -1, (at,)), cols["height"], cols["chunk"], cols["event"],
                      chunks=tuple(chunks), events=tuple(events), turns=tuple(turns))
    r2 = replace(r, program=program)
    return r2, (r2, ends[:-1], ends[1:], on, None, dur, mv, starts, before, sync)  # lengths: computed when asked


def wait_estimates(robots: list[SimRobot], feeds: "Feeds | Mapping[str, Feeds]") -> dict[str, list[float]]:
    """How long each WAIT of each robot is expected to block, s, in program order: the
    constant-speed schedule of the plan (every move at its robot's ``speed``, a G-code's feed
    rates, or at ``feeds``' speed of its role; ``cooprint simulate`` without ``--accel``). A
    WAIT that never ends is ``inf``. The G-code writer turns a robot's nozzle off across the waits
    longer than its idle limit."""
    timelines, _ = schedule(robots, feeds)
    out = {}
    for r in robots:
        n = int(np.count_nonzero(r.program.kind == WAIT))
        got = [float(end - start) for start, end, _ in timelines[r.name].waits]
        out[r.name] = got + [math.inf] * (n - len(got))
    return out


@dataclass(frozen=True)
class PieceRobot:
    """A robot whose program comes piece by piece (a big plan's stream, issue 15): ``pieces()``
    gives its :class:`Program` pieces in order, each time it is called; it starts at ``start``;
    it moves at ``speed(piece, tool on before it)`` (mm/s per command: the G-code's feed rates,
    :meth:`Feeds.speeds`)."""

    name: str
    start: np.ndarray
    pieces: Callable[[], Iterable[Program]]
    speed: Callable[[Program, bool], np.ndarray]


@dataclass(frozen=True)
class EventTimes:
    """What :func:`event_times` finds: when each robot is done (:attr:`Timeline.end`) and how long
    each of its WAITs lasts, s, in program order (``inf``: it never ends)."""

    ends: dict[str, float]
    waits: dict[str, list[float]]

    @property
    def makespan(self) -> float:
        return max(self.ends.values(), default=0.0)


def event_times(robots: list[PieceRobot]) -> EventTimes:
    """The constant-speed times of :func:`schedule` for programs given piece by piece, one piece
    in memory at a time: each robot's end and its WAITs' durations, the same numbers as
    :func:`schedule` of the whole programs (the times add up in the same order)."""
    syncs: dict[str, list] = {}
    lasts: dict[str, list] = {}  # per robot: the last move before each sync, and the last of all
    counts: dict[str, int] = {}
    for r in robots:
        n_waits = 0
        sync: list = []
        last_before: list = []
        last = None  # (command index, time at its start without waits, duration)
        for at, _, piece, mv, _, _, dur, starts in _timed_pieces(r.pieces(), r.start, r.speed):
            kind = piece.kind
            for j in np.flatnonzero((kind == NOTIFY) | (kind == WAIT)).tolist():
                m = int(np.searchsorted(mv, j))  # moves before it
                if m:
                    last = (at + int(mv[m - 1]), float(starts[m - 1]), float(dur[m - 1]))
                sync.append((at + j, float(starts[m]), kind[j] == NOTIFY, piece.events[piece.event[j]]))
                last_before.append(last)
                n_waits += int(kind[j] == WAIT)
            if len(mv):
                last = (at + int(mv[-1]), float(starts[-2]), float(dur[-1]))
        syncs[r.name], lasts[r.name], counts[r.name] = sync, last_before + [last], n_waits
    announced, pos_, waited, delay, waits, notifies = _resolve(syncs)
    ends, durations = {}, {}
    for name, sync in syncs.items():
        at = [i for i, _ in delay[name]]
        waited_before = np.concatenate([[0.0], np.cumsum([d for _, d in delay[name]])])
        last = lasts[name][pos_[name]]  # stuck: the last move before the WAIT; else the last of all
        out = [0.0]
        if last is not None:
            i, t0, d = last
            out = [(t0 + waited_before[int(np.searchsorted(at, i, side="left"))]) + d]
        out += [w[1] for w in waits[name]] + [n[0] for n in notifies[name]]
        ends[name] = max(out)
        got = [float(end - start) for start, end, _ in waits[name]]
        durations[name] = got + [math.inf] * (counts[name] - len(got))
    return EventTimes(ends, durations)


def _chunk_at(program: Program, i: int) -> str | None:
    """The chunk of command ``i``, or of the next command that has one (a WAIT leads into it)."""
    after = np.flatnonzero(program.chunk[i:] >= 0)
    return program.chunks[program.chunk[i + after[0]]] if len(after) else None


__all__ = ["COUNT_UNITS", "EventTimes", "FacingSpan", "Finding", "Lengths", "PieceRobot", "Runs", "SimRobot", "Timeline",
           "WARNING_KINDS", "changes", "event_times", "move_durations", "robot_feeds", "schedule", "schedule_pieces", "segment_max",
           "severity"]
