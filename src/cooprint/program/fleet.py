"""Programs for N robots from a schedule, safe at any real speeds (issue 14, item 4).

The schedule (:class:`~cooprint.scheduling.Schedule`) says who prints which chunk in which order;
this module turns it into each robot's MOVE/TOOL stream with the NOTIFY/WAIT pairs that keep the
plan dependency-correct and collision-free **whatever each robot's real speed**.

The plan is cut into *items*, each a stretch of one robot's time with the XY area it may cover:

* ``pose``: the robot standing still (at home, at the end of a print), from when it arrives until it
  moves on;
* ``leg``: a straight travel move of the nozzle, in one facing, lifted above printed material;
* ``turn``: a turn about the nozzle (the disc of the outline's radius around it);
* ``print``: a piece of a chunk's commands (:func:`~cooprint.program.build.layer_program`; a
  chunk is up to ``PIECES`` items cut after a TOOL OFF, so that two robots whose chunks meet only
  in places print the rest at the same time).

Each item's area is given per part of the robot's outline (body, frame, printhead:
:func:`cooprint.config.outline_rects`) by its support values in ``NDIR`` fixed directions: the
exact support of the part swept over the item's nozzle positions (a leg's two ends, a print's
printed points, a turn's disc). Two items are apart when some direction separates them by the
clearance: a separating axis of the true swept shapes, so the test never calls apart what is not
(it may call near what is not, which only adds a wait).

A robot does *jobs*: from where it stands, travel to a chunk and print it (or travel home). Jobs
are placed one at a time in an event-driven replay at nominal speeds (the simulator's timing),
all items of a job at once, each right before it waiting (WAIT) for what it must follow:

* an item that comes within the clearance of an item of another robot placed before waits for
  that item's end (its NOTIFY);
* a chunk's first print item waits for the chunk's :meth:`ChunkDAG.preds` and for every placed
  item whose body swept over its footprint;
* a job whose way crosses the spot where another robot stands (a pose not yet ended) cannot be
  placed until that robot has moved on; a print whose footprint lies in the way out of a robot
  standing at the end of its print cannot either, and a robot may not end a job in another's way
  out (so every standing robot can always back out to the highway);
* travel never drives a body over a chunk placed before (material that may be there at any speed),
  choosing the first clear one of: straight; back off, across, in; out to the *highway* (a ring
  around the part where the robot's whole outline is clear of the part and of every robot over
  it), along it, and in. Turns happen on the highway.

A robot stopped between two items of a job stands where both of them sweep: an item placed
before that could meet it there meets the item before (and was waited for), one placed after
meets the item after (and waits for it). Every wait goes from an item placed earlier to an item
placed later, so the WAIT graph is acyclic: no deadlock, whatever the speeds; and every pair of
items that could meet is ordered by a WAIT, so no collision and no body on material, whatever the
speeds. The replay places first the job that could start soonest with all its waits before it;
when no job can be placed (a robot stands in the way of the work another one waits for), a robot
standing in the way goes home to wait there.

Robots start and end on a *parking ring* outside the highway, where no working robot ever comes:
robots with work on the inner ring, each near its first chunk on the side it faces it from,
idle robots on the rest of it and on rings further out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from cooprint.config import RobotProfile, SlicingSettings
from cooprint.errors import InfeasibleError
from cooprint.geometry import unit_xy
from cooprint.program.build import MaterialIndex, RobotPlacement, facing_deg
from cooprint.program.commands import MOVE, NOTIFY, TOOL_OFF, WAIT, Program, make_program, quantize
from cooprint.program.gcode import Feeds
from cooprint.program.stream import ChunkPiece, ChunkStore, RobotStream
from cooprint.scheduling.dag import ChunkDAG
from cooprint.scheduling.schedule import Schedule
from cooprint.slicing.paths import LayerPaths

#: Directions of the support values (every 22.5 degrees: the axes and the diagonals among them).
NDIR = 16
_ANG = 2 * np.pi * np.arange(NDIR) / NDIR
DIRS = np.column_stack([np.cos(_ANG), np.sin(_ANG)])
OPP = (np.arange(NDIR) + NDIR // 2) % NDIR
#: The four axis directions (+x, +y, -x, -y) among DIRS: a cheap box prefilter.
BOX = np.array([0, NDIR // 4, NDIR // 2, 3 * NDIR // 4])
PARTS = ("body", "frame", "printhead")
#: A chunk's print is cut into at most this many items (pieces of about as many moves): two
#: robots whose chunks meet only in places print the rest of them at the same time.
PIECES = 12


class FleetError(InfeasibleError):
    """The fleet's programs cannot be made: a body would have to stand on printed material, a
    robot is walled in, a parked robot is in the way (one line naming the robots and chunks)."""


# ------------------------------------------------------------------------------------------------
# support values


def rect_support(rect: np.ndarray, facing: np.ndarray) -> np.ndarray:
    """(NDIR,) the support of a part's rectangle ``u_lo, u_hi, v_lo, v_hi`` (robot frame, from the
    nozzle) for a robot facing ``facing``."""
    f = unit_xy(facing)
    left = np.array([-f[1], f[0]])
    a, b = DIRS @ f, DIRS @ left
    return np.maximum(rect[0] * a, rect[1] * a) + np.maximum(rect[2] * b, rect[3] * b)


def point_support(pts: np.ndarray) -> np.ndarray:
    """(NDIR,) the support of a set of XY points (k, 2)."""
    return (np.asarray(pts, dtype=np.float64)[:, :2] @ DIRS.T).max(axis=0)


def apart(a: np.ndarray, b: np.ndarray, gap: float) -> np.ndarray:
    """Broadcast: shapes with supports ``a`` (..., NDIR) and ``b`` (..., NDIR) are more than ``gap``
    apart along some direction."""
    return ((a + b[..., OPP]) < -gap).any(axis=-1)


@dataclass(frozen=True)
class Body:
    """One robot's outline: the three rectangles, their radius around the nozzle, its speeds (the
    slicer's per path role under its profile's caps: :meth:`Feeds.of_robot`, its G-code's)."""

    rects: np.ndarray  # (3, 4)
    radius: float
    nozzle_depth: float
    build_depth: float
    feeds: Feeds

    @staticmethod
    def of(p: RobotProfile, slicing: SlicingSettings) -> "Body":
        return Body(np.array(list(p.outline().values())), p.outline_radius(), p.nozzle_depth, p.build_depth,
                    Feeds.of_robot(p, slicing))

    def parts(self, nozzle: np.ndarray, facing: np.ndarray) -> np.ndarray:
        """(3, NDIR) the parts' supports over the nozzle positions ``nozzle`` (k, 2) (their hull)."""
        return point_support(nozzle)[None] + self.rect_parts(facing)

    def rect_parts(self, facing: np.ndarray) -> np.ndarray:
        """(3, NDIR) the parts' supports around a nozzle at the origin, facing ``facing``."""
        key = (round(float(facing[0]), 9), round(float(facing[1]), 9))
        cache = self.__dict__.setdefault("_cache", {})
        if key not in cache:
            cache[key] = np.stack([rect_support(r, np.asarray(key)) for r in self.rects])
        return cache[key]

    def disc(self, at: np.ndarray) -> np.ndarray:
        """(3, NDIR) every part within the outline's radius of ``at``: a robot turning there."""
        s = DIRS @ np.asarray(at, dtype=np.float64)[:2] + self.radius
        return np.stack([s, s, s])


# ------------------------------------------------------------------------------------------------
# the rings


@dataclass(frozen=True)
class Rings:
    """The part's box, the highway around it and the parking spots.

    ``lo, hi``: the XY box of every chunk's material; ``lane``: how far outside it the highway runs
    (the largest outline radius plus the clearance: a robot on it, in any facing, is clear of the
    part); ``spots``: ``{robot: (xy (2,), facing (2,))}``."""

    lo: np.ndarray
    hi: np.ndarray
    lane: float
    spots: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)

    @property
    def hlo(self) -> np.ndarray:
        return self.lo - self.lane

    @property
    def hhi(self) -> np.ndarray:
        return self.hi + self.lane

    def exit(self, p: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Where the ray from ``p`` along ``d`` meets the highway (``p`` inside it: on the way out;
        outside: on the way in)."""
        p, d = np.asarray(p, float)[:2], unit_xy(d)
        lo, hi = self.hlo, self.hhi
        inside = bool(np.all(p >= lo - 1e-9) and np.all(p <= hi + 1e-9))
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (lo - p) / d, (hi - p) / d
        tn = np.where(d != 0, np.minimum(t1, t2), -np.inf)
        tf = np.where(d != 0, np.maximum(t1, t2), np.inf)
        if inside:
            t = float(tf.min())
        else:
            t = float(tn.max())
            if t > float(tf.min()) + 1e-9 or t < 0:
                raise FleetError(f"the way from {p.round(3).tolist()} along {d.round(3).tolist()} misses the highway")
        return self._snap(p + t * d)

    def _snap(self, q: np.ndarray) -> np.ndarray:
        """``q`` put exactly on the highway's nearest side."""
        lo, hi = self.hlo, self.hhi
        q = np.clip(q, lo, hi)
        dist = [q[0] - lo[0], q[1] - lo[1], hi[0] - q[0], hi[1] - q[1]]
        k = int(np.argmin(dist))
        q = q.copy()
        q[k % 2] = (lo if k < 2 else hi)[k % 2]
        return q

    def _param(self, q: np.ndarray) -> float:
        lo, hi = self.hlo, self.hhi
        w, h = hi - lo
        x, y = q - lo
        if abs(y) < 1e-6:
            return float(x)
        if abs(x - w) < 1e-6:
            return float(w + y)
        if abs(y - h) < 1e-6:
            return float(w + h + (w - x))
        return float(2 * w + h + (h - y))

    def along(self, a: np.ndarray, b: np.ndarray) -> list[np.ndarray]:
        """The corners passed going round the highway from ``a`` to ``b`` (both on it), the
        shorter way, ``b`` last."""
        lo, hi = self.hlo, self.hhi
        w, h = hi - lo
        per = 2 * (w + h)
        corners = [(0.0, lo), (w, np.array([hi[0], lo[1]])), (w + h, hi), (2 * w + h, np.array([lo[0], hi[1]]))]
        sa, sb = self._param(a), self._param(b)
        fwd = (sb - sa) % per
        out = []
        if fwd <= per - fwd:
            for s, c in sorted(corners, key=lambda sc: (sc[0] - sa) % per):
                if 1e-6 < (s - sa) % per < fwd - 1e-6:
                    out.append(c)
        else:
            back = per - fwd
            for s, c in sorted(corners, key=lambda sc: (sa - sc[0]) % per):
                if 1e-6 < (sa - s) % per < back - 1e-6:
                    out.append(c)
        return out + [np.asarray(b, float)]


_SIDES = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])  # inward normals: left, bottom, right, top


def parking(robots: list[str], first: dict[str, tuple[np.ndarray, np.ndarray]], bodies: dict[str, Body],
            lo: np.ndarray, hi: np.ndarray, clearance: float) -> Rings:
    """The highway and every robot's spot (see :class:`Rings`).

    ``first``: for each robot with work, the first point and facing of its first chunk. The
    highway runs ``2 r + clearance`` outside the part's box (``r`` the largest outline radius): a
    robot on it, in any facing, is clear of every robot whose nozzle is over the part. A spot
    faces the part across one of its four sides, its nozzle ``r + reach + clearance`` outside the
    highway (``reach``: how far the outline reaches ahead of the nozzle), so that no robot on the
    highway or inside it comes within the clearance of a parked one. Along a side, spots are
    packed by the outlines' widths (plus the clearance) within the highway's span: a robot goes
    straight in from its spot to the highway, and two sides' spots never meet at a corner (one of
    the two is always more than ``r`` further out than the other reaches). Every robot with work
    is on the inner ring, on the side it faces its first chunk from, near its first point (a side
    too full passes robots to the side with most room; the highway moves out until all fit), so
    nobody ever passes between parked robots. Idle robots take the room left and then rings
    further out, each wider by as much as it is further out."""
    rmax = max(b.radius for b in bodies.values())
    half = {r: max(bodies[r].rects[:, 3].max(), -bodies[r].rects[:, 2].min()) for r in robots}  # half width
    depth = max(float(b.rects[:, 1].max() - b.rects[:, 0].min()) for b in bodies.values())
    reach_in = max(float(b.rects[:, 1].max()) for b in bodies.values())
    gap = clearance + 0.01  # the spacing: the clearance and a little for the 1 um grid
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)

    def side_of(f: np.ndarray) -> int:
        return int(np.argmax(_SIDES @ unit_xy(f)))

    def along(side: int) -> np.ndarray:
        n = _SIDES[side]
        return np.abs(np.array([-n[1], n[0]]))

    def span(rings: Rings, side: int, extra: float) -> tuple[float, float]:
        t = along(side)
        return float(rings.hlo @ t) - extra, float(rings.hhi @ t) + extra

    def room(rings: Rings, side: int, members: list[tuple[str, float]]) -> float:
        a, b = span(rings, side, 0.0)
        return (b - a + gap) - sum(2 * half[r] + gap for r, _ in members)

    def pack(rings: Rings, members: list[tuple[str, float]], side: int, extra: float) -> dict[str, float] | None:
        """Positions along the side of ``members`` (robot, preferred position), or None."""
        a, b = span(rings, side, extra)
        members = sorted(members, key=lambda m: m[1])
        if sum(2 * half[r] + gap for r, _ in members) > b - a + gap:
            return None
        pos, prev = {}, a - gap
        for r, pref in members:
            pos[r] = prev = max(pref, prev + gap + half[r])
            prev += half[r]
        nxt = b + gap
        for r, _ in reversed(members):
            pos[r] = min(pos[r], nxt - gap - half[r])
            nxt = pos[r] - half[r]
        return pos

    def put(rings: Rings, side: int, extra: float, r: str, x: float) -> None:
        n = _SIDES[side]
        base = rings.lane + rmax + reach_in + gap + extra
        coord = float(lo @ np.abs(n)) - base if side < 2 else float(hi @ np.abs(n)) + base
        rings.spots[r] = (along(side) * x + np.abs(n) * coord, n.copy())

    working = [r for r in robots if r in first]
    idle = [r for r in robots if r not in first]
    lane = 2 * rmax + gap
    while True:  # the inner ring: each robot with work on the side it faces its first chunk from
        rings = Rings(lo, hi, lane)
        wanted: dict[int, list[tuple[str, float]]] = {s: [] for s in range(4)}
        for r in working:
            p, f = first[r]
            s = side_of(f)
            wanted[s].append((r, float(p[:2] @ along(s))))
        for s in range(4):  # a side too full passes its outermost robots to the side with most room
            while wanted[s] and pack(rings, wanted[s], s, 0.0) is None:
                o = max((k for k in range(4) if k != s), key=lambda k: room(rings, k, wanted[k]))
                mid = sum(span(rings, s, 0.0)) / 2
                r, _ = max(wanted[s], key=lambda m: abs(m[1] - mid))
                if room(rings, o, wanted[o]) < 2 * half[r] + gap:
                    break
                wanted[s] = [m for m in wanted[s] if m[0] != r]
                wanted[o].append((r, sum(span(rings, o, 0.0)) / 2))
        placed = {s: pack(rings, wanted[s], s, 0.0) for s in range(4)}
        if all(p is not None for p in placed.values()):
            break
        lane += depth + clearance  # no room: the highway (and the ring) further out
    taken: dict[int, list[tuple[str, float]]] = {}
    for s, pos in placed.items():
        assert pos is not None
        taken[s] = list(pos.items())
        for r, x in pos.items():
            put(rings, s, 0.0, r, x)
    ring = 0
    while idle:  # idle robots (they never move): what room is left on this ring, then rings further out
        e = ring * (depth + clearance)
        for s in range(4):
            while idle:
                trial = taken[s] + [(idle[0], span(rings, s, e)[1])]
                pos = pack(rings, trial, s, e)
                if pos is None:
                    break
                idle.pop(0)
                taken[s] = [(m, pos[m]) for m, _ in trial]
                for m, x in pos.items():
                    put(rings, s, e, m, x)
        ring += 1
        taken = {s: [] for s in range(4)}
        if ring > 1000:
            raise FleetError("no room for the idle robots on 1000 parking rings")
    return rings


# ------------------------------------------------------------------------------------------------
# items and the replay


@dataclass
class Item:
    """A stretch of one robot's plan (see the module doc)."""

    robot: str
    kind: str  # pose, leg, turn, print
    parts: np.ndarray  # (3, NDIR)
    start: float = 0.0
    end: float = math.inf  # before it is placed: its duration
    ended: bool = True  # a pose is not, until the robot moves on
    permanent: bool = False  # a robot's last pose
    chunk: str | None = None
    program: Program | ChunkPiece | None = None
    end_at: np.ndarray | None = None  # a print: where its last move ends (None: it has none)
    escape: np.ndarray | None = None  # a pose at a print's end: its way out to the highway (3, NDIR)
    seq: int = -1  # index among the robot's items
    index: int = -1  # index among all items
    to: np.ndarray | None = None  # a leg: where it goes
    last: bool = False  # a print: the chunk's last piece (its end is the chunk's)
    start_at: np.ndarray | None = None  # a print: where the nozzle is before it
    notify: str | None = None  # the event its end is announced by, once someone waits for it


@dataclass
class Job:
    """What a robot does next: the items, and before them the items of others it waits for."""

    robot: str
    items: list[Item]
    pose: Item  # where it stands afterwards
    start: float
    waits: list[dict[int, Item]]  # per item: the items of others it follows
    target: str | None  # chunk id, None: home
    turns: list[tuple[str, float]]
    facing: np.ndarray  # the way it faces afterwards
    stay: bool = False  # an empty chunk: it does not move

    @property
    def key(self) -> float:
        """What the replay places first: the job that could start soonest with all its waits
        before it (its end less its work), so that a job that would stop half-way for long does
        not hold its ways meanwhile."""
        return self.items[-1].end - sum(it.end - it.start for it in self.items if it.end > it.start) \
            if self.items else self.start


class Blocked(str):
    """Why a job cannot be placed now, and the robot whose standing is the reason (``by``; None:
    anything placed may change it)."""

    by: str | None

    def __new__(cls, reason: str, by: str | None = None) -> "Blocked":
        out = super().__new__(cls, reason)
        out.by = by
        return out


class _Fleet:
    """The replay's state: every robot's items, jobs, where it stands and what it has left to do
    (:meth:`run` places the jobs, :meth:`programs` writes them out)."""

    def __init__(self, schedule: Schedule, dag: ChunkDAG, store: ChunkStore, material: MaterialIndex,
                 profiles: Mapping[str, RobotProfile], clearance: float, slicing: SlicingSettings):
        self.sched, self.dag, self.store, self.material = schedule, dag, store, material
        self.clearance = float(clearance)
        self.robots = list(schedule.sequences)
        self.bodies = {r: Body.of(profiles[r], slicing) for r in self.robots}
        self.idx = dag.index
        self.owner = {c: r for r, seq in schedule.sequences.items() for c in seq}
        self.pts, self.first = {}, {}
        for cid in dag.ids:  # a chunk's printed points by their hull: only their extremes count
            s = store.summaries.get(cid)
            if s is not None and s.first is not None:
                self.pts[cid], self.first[cid] = s.hull, s.first
        self.foot = {c: point_support(p) for c, p in self.pts.items()}
        boxes = {c: b for c, b in material.boxes.items() if len(b)}
        self.box = {c: np.r_[b[:, 0].min(), b[:, 1].min(), b[:, 2].max(), b[:, 3].max(),
                             b[:, 4].max() + material.margin] for c, b in boxes.items()}
        allp = [p for p in self.pts.values()] + [b[[0, 1]][None] for b in self.box.values()] + \
            [b[[2, 3]][None] for b in self.box.values()]
        allp = np.concatenate(allp) if allp else np.zeros((1, 2))
        firsts = {}
        for r, seq in schedule.sequences.items():
            c = next((c for c in seq if c in self.pts), None)
            if c is not None:
                firsts[r] = (self.first[c], dag.facing[self.idx[c]])
        self.rings = parking(self.robots, firsts, self.bodies, allp.min(0), allp.max(0), self.clearance)
        self.items: list[Item] = []
        self._feet = np.zeros((0, NDIR))  # the footprints of the placed prints, in self.printed's order
        self._boxes = np.zeros((0, 5))  # and their material boxes (xmin, ymin, xmax, ymax, top)
        self._parts = np.zeros((0, 3, NDIR))
        self._robot = np.zeros(0, int)
        self._ended = np.zeros(0, bool)
        self._box = np.zeros((0, 4))  # each item's box: its support along +x, +y, -x, -y
        self.per_robot: dict[str, list[Item]] = {r: [] for r in self.robots}
        self.jobs: dict[str, list[Job]] = {r: [] for r in self.robots}
        self.pose: dict[str, Item] = {}
        self.here: dict[str, np.ndarray] = {}
        self.facing: dict[str, np.ndarray] = {}
        self.at_home: dict[str, bool] = {}
        self.todo: dict[str, list[str | None]] = {}
        self.printed: list[str] = []  # placed prints, in order
        self._printed: set[str] = set()
        self.done_chunks: dict[str, Item] = {}
        for r in self.robots:
            xy, n = self.rings.spots[r]
            home = quantize(np.r_[xy, self.clearance])
            b = self.bodies[r]
            idle = r not in firsts
            it = Item(r, "pose", b.parts(home[None, :2], n), 0.0, math.inf, ended=False, permanent=idle)
            self._add(it)
            self.pose[r], self.here[r], self.facing[r], self.at_home[r] = it, home, n, True
            # a robot without anything to print still keeps its word: its empty chunks, where it stands
            self.todo[r] = list(schedule.sequences[r]) + ([] if idle else [None])

    def _add(self, it: Item) -> None:
        it.seq = len(self.per_robot[it.robot])
        it.index = len(self.items)
        self.per_robot[it.robot].append(it)
        self.items.append(it)
        n = len(self.items)
        if n > len(self._parts):  # the placed items' supports, in arrays that grow by doubling
            grow = max(64, len(self._parts))
            self._parts = np.concatenate([self._parts, np.zeros((grow, 3, NDIR))])
            self._robot = np.concatenate([self._robot, np.full(grow, -1)])
            self._ended = np.concatenate([self._ended, np.zeros(grow, bool)])
            self._box = np.concatenate([self._box, np.zeros((grow, 4))])
        self._parts[n - 1] = it.parts
        self._box[n - 1] = it.parts.max(axis=0)[BOX]
        self._robot[n - 1] = self.robots.index(it.robot)
        self._ended[n - 1] = it.ended

    # --- geometry of a way ---------------------------------------------------------------------

    def _height(self, pts: np.ndarray, reach: float, base: float) -> float:
        """The travel height over ``pts`` (k, 2): the clearance above every placed chunk's material
        box within ``reach`` of their box, and above ``base``."""
        lo, hi = pts.min(0) - reach, pts.max(0) + reach
        b = self._boxes[:len(self.printed)]
        near = (b[:, 0] <= hi[0]) & (b[:, 2] >= lo[0]) & (b[:, 1] <= hi[1]) & (b[:, 3] >= lo[1])
        top = max(base, float(b[near, 4].max())) if near.any() else base
        return float(quantize(top + self.clearance))

    def _ways(self, r: str, target: str | None) -> list[tuple[str, list]]:
        """Candidate ways from where ``r`` stands to above the target's first point (``None``:
        its home), each a list of ``("go", xy)`` and ``("turn", facing)`` steps."""
        p, f = self.here[r][:2], self.facing[r]
        if target is None:
            goal, g = self.rings.spots[r]
        else:
            goal, g = self.first[target][:2], unit_xy(self.dag.facing[self.idx[target]])
        out: list[tuple[str, list]] = []
        same = bool(np.allclose(f, g, atol=1e-9))
        if same:
            out.append(("straight", [("go", goal)]))
            if not self.at_home[r]:
                bd = self.bodies[r].build_depth
                feet = self._feet[:len(self.printed)]
                s_lo = float(-feet[:, OPP[int(np.argmax(DIRS @ f))]].max(initial=-math.inf))
                s1 = min(float(p @ f), s_lo + bd - self.clearance)
                left = np.array([-f[1], f[0]])
                q0, q4 = float(p @ left), float(goal @ left)
                steps = []
                if s1 < float(p @ f) - 1e-9:
                    steps.append(("go", s1 * f + q0 * left))
                steps += [("go", s1 * f + q4 * left), ("go", goal)]
                out.append(("around", steps))
        a = self.rings.exit(p, f if self.at_home[r] else -f)
        b = self.rings.exit(goal, g if target is None else -g)
        steps = [("go", a)]
        if not same:
            steps.append(("turn", g))
        steps += [("go", x) for x in self.rings.along(a, b)] + [("go", goal)]
        out.append(("highway", steps))
        return out

    def _legs(self, r: str, steps: list, target: str | None) -> tuple[list[Item], list[tuple[str, float]], np.ndarray]:
        """The items of a way (legs lifted to one travel height, turns) and the facings turned to."""
        b = self.bodies[r]
        here, f = self.here[r], self.facing[r]
        path = [here[:2]] + [np.asarray(x, float) for k, x in steps if k == "go"]
        path = np.array(path)
        base = float(here[2]) if target is None else max(float(here[2]), float(self.first[target][2]))
        z = self._height(path, b.nozzle_depth, base)
        items, turns = [], []
        pos = here.copy()
        if pos[2] != z:
            up = quantize(np.r_[pos[:2], z])
            items.append(self._leg(r, pos, up, f))
            pos = up
        for kind, x in steps:
            if kind == "turn":
                g = unit_xy(x)
                via = _via(f, g)
                degs = [facing_deg(v) for v in via] + [facing_deg(g)]
                it = Item(r, "turn", b.disc(pos[:2]), end=0.0)
                it.program = make_program(r, np.zeros(0), turns=tuple((0, d) for d in degs))
                items.append(it)
                turns.append(facing_deg(g))
                f = g
            else:
                nxt = quantize(np.r_[x, z])
                if np.array_equal(nxt, pos):
                    continue
                items.append(self._leg(r, pos, nxt, f))
                pos = nxt
        return items, turns, pos

    def _leg(self, r: str, a: np.ndarray, b: np.ndarray, f: np.ndarray) -> Item:
        body = self.bodies[r]
        it = Item(r, "leg", point_support(np.array([a[:2], b[:2]]))[None] + body.rect_parts(f))
        it.to = np.asarray(b, float)
        it.end = float(np.linalg.norm(np.asarray(b) - np.asarray(a))) / body.feeds.travel  # duration, for now
        return it

    def _pieces(self, r: str, cid: str) -> list[tuple[ChunkPiece, np.ndarray, float, np.ndarray | None]]:
        """Chunk ``cid``'s commands for robot ``r`` (every layer, from above its first point) cut
        into at most ``PIECES`` pieces of about as many moves, each cut right after a TOOL OFF
        (a robot that waits between two pieces does so with its tool off): each piece, the
        support of its nozzle positions (from where the piece before ends), its nominal time and
        where its last move ends. Kept in the store for every robot
        of the same speeds (the chunk's commands are read once)."""
        b = self.bodies[r]
        key = ("fleet-pieces", cid, b.feeds)
        if key not in self.store.memo:
            prog = self.store.program(cid)
            mv = np.flatnonzero(prog.kind == MOVE)
            xyz = prog.xyz[mv]
            length = np.r_[0.0, np.linalg.norm(np.diff(xyz, axis=0), axis=1)]
            dur = length / b.feeds.speeds(prog)[mv]
            ends = np.flatnonzero(prog.kind == TOOL_OFF) + 1  # where a piece may end
            step = max(1.0, len(mv) / PIECES)
            cuts, moves_before = [0], np.searchsorted(mv, ends)
            for e, m in zip(ends.tolist(), moves_before.tolist()):
                if m - np.searchsorted(mv, cuts[-1]) >= step and e < len(prog):
                    cuts.append(e)
            cuts.append(len(prog))
            out = []
            for c0, c1 in zip(cuts[:-1], cuts[1:]):
                k0, k1 = np.searchsorted(mv, c0), np.searchsorted(mv, c1)
                pts = xyz[max(k0 - 1, 0):max(k1, 1), :2]  # from where the piece before ends
                last = xyz[k1 - 1].copy() if k1 > k0 else None
                out.append((ChunkPiece(cid, int(c0), int(c1)), point_support(pts), float(dur[k0:k1].sum()), last))
            self.store.memo[key] = out
        return self.store.memo[key]  # type: ignore[return-value]

    def _prints(self, r: str, cid: str, here: np.ndarray, f: np.ndarray) -> tuple[list[Item], np.ndarray]:
        """The print items of chunk ``cid`` (its pieces: a robot away from a piece of another's
        chunk may print beside it meanwhile), and where the nozzle ends."""
        b = self.bodies[r]
        rects = b.rect_parts(f)
        pieces = self._pieces(r, cid)
        first = self.first[cid]
        items = []
        for k, (piece, support, dur, end_at) in enumerate(pieces):
            it = Item(r, "print", support[None] + rects, chunk=cid, program=piece, end_at=end_at)
            it.end = dur + (float(np.linalg.norm(np.asarray(here, float) - first)) / b.feeds.travel if k == 0 else 0.0)
            items.append(it)
        items[-1].last = True
        end_at = pieces[-1][3]
        return items, end_at if end_at is not None else np.asarray(here, float)

    # --- a job ---------------------------------------------------------------------------------

    def _others_poses(self, r: str) -> list[Item]:
        return [self.pose[o] for o in self.robots if o != r and not self.pose[o].ended]

    def job(self, r: str, target: str | None) -> "Job | Blocked":
        """The job of ``r`` to ``target`` (``None``: home), or why it cannot be placed now."""
        if target is not None:
            for d in self.dag.preds(target):
                if d not in self.done_chunks:
                    return Blocked(f"chunk {d} is not placed")
            if target not in self.pts:  # nothing to print: done where it stands, once its preds are
                now = self.pose[r]
                it = Item(r, "print", now.parts, chunk=target, end=0.0)
                it.start_at = self.here[r]
                it.last = True
                waits = {self.done_chunks[d].index: self.done_chunks[d] for d in self.dag.preds(target)
                         if self.owner[d] != r}
                it.start = it.end = max([now.start] + [w.end for w in waits.values()])
                pose = Item(r, "pose", now.parts, ended=False, permanent=not self.todo[r][1:], escape=now.escape)
                return Job(r, [it], pose, it.start, [waits], target, [], self.facing[r], stay=True)
        poses = self._others_poses(r)
        pose_parts = np.stack([p.parts for p in poses]) if poses else np.zeros((0, 3, NDIR))
        placed = self.printed
        feet = self._feet[:len(placed)]
        reason = "no way"
        for name, steps in self._ways(r, target):
            items, turns, pos = self._legs(r, steps, target)
            if not items:
                break
            mine = np.stack([it.parts for it in items])
            if len(feet):
                hit = ~apart(mine[:, None, 0], feet[None], 0.0)  # (k, m)
                if hit.any():
                    reason = f"its way {name} drives its body over chunk {placed[int(np.nonzero(hit)[1][0])]}"
                    continue
            if len(poses):
                near = ~apart(mine[:, None, :, None], pose_parts[None, :, None], self.clearance).all(axis=(2, 3))
                if near.any():
                    q = poses[int(np.nonzero(near)[1][0])]
                    reason = Blocked(f"robot {q.robot} stands in its way", q.robot)
                    if name == "highway":
                        if q.permanent:
                            raise FleetError(self._parked(r, q.robot, target))
                        return reason
                    continue
            break
        else:
            return Blocked(reason)
        f = unit_xy(self.dag.facing[self.idx[target]]) if target is not None else self.rings.spots[r][1]
        first_print = None
        if target is not None:
            prints, pos = self._prints(r, target, pos, f)
            whole = self.foot[target][None] + self.bodies[r].rect_parts(f)  # the whole chunk's print
            ways = [p for p in poses if p.escape is not None]
            if ways:
                over = ~apart(np.stack([p.escape[0] for p in ways]), self.foot[target][None], 0.0)
                if over.any():
                    q = ways[int(np.argmax(over))]
                    return Blocked(f"robot {q.robot} must back out over it", q.robot)
            own = [c for c, h in zip(placed, ~apart(whole[0][None], feet, 0.0)) if h and c != target] \
                if len(feet) else []
            if own:
                raise FleetError(f"robot {r} prints {target} with its body over chunk {own[0]}, printed before "
                                 f"(the chunk rules must put {own[0]} after {target})")
            if len(poses):
                near = (~apart(whole[None, :, None], pose_parts[:, None], self.clearance)).any(axis=(1, 2))
                if near.any():
                    q = poses[int(np.argmax(near))]
                    if q.permanent:
                        raise FleetError(self._parked(r, q.robot, target))
                    return Blocked(f"robot {q.robot} stands in the way of its print", q.robot)
            first_print = len(items)
            items += prints
        # the items placed before that each must follow: a box prefilter, then the exact test
        waits: list[dict[int, Item]] = [{} for _ in items]
        if first_print is not None:
            for d in self.dag.preds(target):
                if self.owner[d] != r:
                    w = self.done_chunks[d]
                    waits[first_print][w.index] = w
        mine = np.stack([it.parts for it in items])  # (k, 3, NDIR)
        n = len(self.items)
        reach = mine.max(axis=(0, 1))[BOX]  # the job's box
        box = self._box[:n]
        near = ~((reach[None] + box[:, [2, 3, 0, 1]]) < -self.clearance).any(-1)
        sel = np.flatnonzero(near & (self._robot[:n] != self.robots.index(r)) & self._ended[:n])
        if len(sel):
            theirs = self._parts[sel]  # (m, 3, NDIR)
            whole_m, whole_t = mine.max(1)[:, BOX], box[sel]
            close = ~((whole_m[:, None] + whole_t[None][..., [2, 3, 0, 1]]) < -self.clearance).any(-1)  # (k, m)
            ii, jj = np.nonzero(close)
            if len(ii):
                hit = ~apart(mine[ii][:, :, None], theirs[jj][:, None], self.clearance).all(axis=(1, 2))
                for i, j in zip(ii[hit].tolist(), jj[hit].tolist()):
                    w = self.items[int(sel[j])]
                    waits[i][w.index] = w
            if first_print is not None:  # whatever body went over the chunk goes first
                hit = ~apart(theirs[:, 0], self.foot[target][None], 0.0)
                for j in np.flatnonzero(hit):
                    w = self.items[int(sel[j])]
                    waits[first_print][w.index] = w
        # in time: each item as soon as the one before and those it follows are done
        t = self.pose[r].start
        for it, w in zip(items, waits):
            dur = it.end
            it.start = max([t] + [x.end for x in w.values()])
            it.end = t = it.start + dur
        start = items[0].start
        end_pose_at = pos
        b = self.bodies[r]
        pose = Item(r, "pose", b.parts(end_pose_at[None, :2], f), ended=False, permanent=target is None
                    and not self.todo[r][1:])
        if target is not None:
            # the way out it keeps free: no robot may stop in it, no chunk may be printed under it
            out = self.rings.exit(end_pose_at[:2], -f)
            pose.escape = b.parts(np.array([end_pose_at[:2], out]), f)
            if len(poses):
                near = ~apart(pose.escape[None, :, None], pose_parts[:, None], self.clearance).all(axis=(1, 2))
                if near.any():
                    q = poses[int(np.argmax(near))]
                    return Blocked(f"robot {q.robot} stands in its way out from {target}", q.robot)
                ways = [(p, p.escape) for p in poses if p.escape is not None]
                if ways:
                    esc = np.stack([e for _, e in ways])
                    near = ~apart(pose.parts[None, :, None], esc[:, None], self.clearance).all(axis=(1, 2))
                    if near.any():
                        q = ways[int(np.argmax(near))][0]
                        return Blocked(f"it would stop in robot {q.robot}'s way out", q.robot)
        return Job(r, items, pose, start, waits, target, [(target or "", t) for t in turns], f)

    def _parked(self, r: str, q: str, target: str | None) -> str:
        where = f"chunk {target}" if target else "its spot"
        at = self.rings.spots[q][0].round(1).tolist()
        return (f"robot {r} cannot get to {where}: robot {q}, parked for good at {at}, is in its way "
                "(the parking ring should keep parked robots out of every way; a bug)")

    def place(self, job: Job) -> None:
        r = job.robot
        old = self.pose[r]
        old.end, old.ended = job.start, True
        self._ended[old.index] = True
        t = job.start
        for it in job.items:
            if it.kind == "leg":
                it.program = make_program(r, np.array([MOVE], np.uint8), it.to[None])
            t = it.end
            self._add(it)
            if it.kind == "print":
                if it.chunk in self.foot and it.chunk not in self._printed:
                    if len(self.printed) >= len(self._feet):
                        self._feet = np.concatenate([self._feet, np.zeros((max(64, len(self._feet)), NDIR))])
                        self._boxes = np.concatenate([self._boxes, np.full((max(64, len(self._boxes)), 5), np.nan)])
                    self._feet[len(self.printed)] = self.foot[it.chunk]
                    box = self.box.get(it.chunk)
                    self._boxes[len(self.printed)] = box if box is not None else np.nan
                    self.printed.append(it.chunk)
                    self._printed.add(it.chunk)
                if it.last:
                    self.done_chunks[it.chunk] = it
        pose = job.pose
        pose.start = t
        pose.end = math.inf
        self._add(pose)
        self.pose[r] = pose
        last = next((it for it in reversed(job.items) if it.program is not None and _length(it.program)), None)
        if last is not None:
            if isinstance(last.program, ChunkPiece):
                if last.end_at is not None:
                    self.here[r] = quantize(last.end_at)
            else:
                mv = np.flatnonzero(last.program.kind == MOVE)
                if len(mv):
                    self.here[r] = quantize(last.program.xyz[mv[-1]])
        self.facing[r] = job.facing
        self.jobs[r].append(job)
        self.at_home[r] = job.target is None or (job.stay and self.at_home[r])

    def run(self) -> None:
        """Place every robot's jobs (see the module doc). A robot's next job, once worked out, is
        kept until a job placed near it (or a pose that blocked it) may have changed it."""
        cache: dict[str, Job | Blocked] = {}
        margin = self.clearance + max(b.nozzle_depth for b in self.bodies.values()) + 1.0
        while any(self.todo[r] for r in self.robots):
            best, why = None, {}
            for fresh in (False, True):  # nothing to place with what is kept: work every job out anew
                if fresh:
                    cache.clear()
                for r in self.robots:
                    if not self.todo[r]:
                        continue
                    if r not in cache:
                        cache[r] = self.job(r, self.todo[r][0])
                    j = cache[r]
                    if isinstance(j, str):
                        why[r] = j
                    elif best is None or j.key < best[1].key:
                        best = (r, j, False)
                if best is not None:
                    break
            if best is None:  # a standoff: someone standing in the way goes home to wait
                for r in self.robots:
                    if self.todo[r] and not self.at_home[r] and self.todo[r][0] is not None:
                        j = self.job(r, None)
                        if not isinstance(j, str) and (best is None or j.key < best[1].key):
                            best = (r, j, True)
            if best is None:
                raise FleetError("the robots cannot go on: " + "; ".join(f"{r}: {w}" for r, w in why.items()))
            r, j, home = best
            self.place(j)
            if not home:
                self.todo[r].pop(0)
            new = _whole(j)
            for o in list(cache):
                c = cache[o]
                # a job blocked by a robot standing somewhere stays blocked until that one moves
                if o == r or (isinstance(c, Blocked) and c.by in (None, r)) or \
                        (isinstance(c, Job) and not apart(_whole(c), new, margin)):
                    del cache[o]

    # --- the programs ----------------------------------------------------------------------------

    def programs(self) -> tuple[dict[str, RobotStream], dict[str, RobotPlacement]]:
        # which waits to keep: per robot pair, only one beyond the last kept (transitive reduction)
        keep: dict[int, list[Item]] = {}  # item index -> the items it waits for
        needed: set[int] = set()
        for r in self.robots:
            last: dict[str, int] = {}
            for j in self.jobs[r]:
                for item, waits in zip(j.items, j.waits):
                    top: dict[str, Item] = {}
                    for it in waits.values():
                        if it.kind == "turn":  # a turn takes effect with the move after it: wait for that
                            it = self.per_robot[it.robot][it.seq + 1]
                            assert it.kind != "pose", "a turn ends a job"  # ways go on after turning
                        if it.seq > last.get(it.robot, -1) and (it.robot not in top or it.seq > top[it.robot].seq):
                            top[it.robot] = it
                    for o, it in top.items():
                        last[o] = it.seq
                        needed.add(it.index)
                    keep[item.index] = sorted(top.values(), key=lambda it: (it.robot, it.seq))
        depended = {d for c in self.dag.ids for d in self.dag.preds(c)
                    if c in self.owner and d in self.owner and self.owner[d] != self.owner[c]}
        for r in self.robots:  # name the events
            n = 0
            for it in self.per_robot[r]:
                if it.kind == "print" and it.last and (it.index in needed or it.chunk in depended):
                    it.notify = it.chunk
                    n += 1
                elif it.index in needed:
                    n += 1
                    it.notify = f"{r}:{n}"
        programs, placements = {}, {}
        for r in self.robots:
            pieces: list[Program | ChunkPiece] = []
            items = self.per_robot[r]
            for j in self.jobs[r]:
                for k, it in enumerate(j.items):
                    if keep[it.index]:
                        pieces.append(_sync(r, WAIT, [w.notify for w in keep[it.index]]))  # type: ignore[misc]
                    before = items[it.seq - 1]  # the pose it leaves, as it starts the job
                    if k == 0 and before.notify:
                        pieces.append(_sync(r, NOTIFY, [before.notify]))
                    if it.program is not None:
                        pieces.append(it.program)
                    if it.notify:
                        pieces.append(_sync(r, NOTIFY, [it.notify]))
            programs[r] = RobotStream(r, pieces)
            xy, n = self.rings.spots[r]
            seq = self.sched.sequences[r]
            faces = {tuple(np.round(unit_xy(self.dag.facing[self.idx[c]]), 9)) for c in seq}
            # job.json's record: the facing at the start, and each chunk it turned round for (turns
            # on the way home are the program's ;@facing annotations alone)
            facings = [(seq[0], facing_deg(n))] if seq else []
            facings += [j.turns[-1] for j in self.jobs[r] if j.turns and j.target is not None]
            side = _side(faces, n)
            placements[r] = RobotPlacement(r, side, (float(n[0]), float(n[1])),
                                           (float(xy[0]), float(xy[1]), float(quantize(self.clearance))),
                                           tuple(facings))
        return programs, placements


def _length(program: Program | ChunkPiece) -> int:
    """Commands in a program or a chunk piece (whose end is known)."""
    if isinstance(program, ChunkPiece):
        assert program.stop is not None
        return program.stop - program.start
    return len(program)


def _whole(job: Job) -> np.ndarray:
    """(NDIR,) the support of everything a job covers: its items, the pose it ends in, and the
    pose's way out."""
    parts = [it.parts for it in job.items] + [job.pose.parts]
    if job.pose.escape is not None:
        parts.append(job.pose.escape)
    return np.concatenate(parts).max(axis=0)


def _via(f: np.ndarray, g: np.ndarray) -> list[np.ndarray]:
    """The facings a turn from ``f`` to ``g`` passes through first: a quarter turn when it is a
    half turn (the simulator turns the shorter way, which a half turn does not say)."""
    if float(f @ g) < -1 + 1e-9:
        return [np.array([-f[1], f[0]])]
    return []


def _side(faces: set, n: np.ndarray) -> str:
    """``left`` / ``right``: the robot prints facing one way along the main axis of its facings
    (+: it stands on the -axis side, as the seed's left chunks), ``both``: either way."""
    if not faces:
        return "left" if (n @ np.array([1.0, 1.0])) > 0 else "right"
    arr = np.array(sorted(faces))
    axis = 1 if np.abs(arr[:, 1]).sum() >= np.abs(arr[:, 0]).sum() else 0
    signs = {float(np.sign(a[axis])) for a in arr if abs(a[axis]) > 1e-9}
    if len(signs) > 1:
        return "both"
    return "left" if signs == {1.0} or not signs else "right"


def _sync(robot: str, kind: int, events: list[str]) -> Program:
    return make_program(robot, np.array([kind], np.uint8), events=(tuple(events),))


def fleet_programs(schedule: Schedule, dag: ChunkDAG, layers: dict[str, list[tuple[int, LayerPaths]]],
                   material: MaterialIndex, profiles: Mapping[str, RobotProfile], clearance: float,
                   slicing: SlicingSettings) -> tuple[dict[str, Program], dict[str, RobotPlacement]]:
    """:func:`fleet_streams` of chunks sliced into ``layers`` (``{chunk id: [(layer index,
    LayerPaths), ...]}`` in the object's layer grid), each robot's program made whole."""
    store = ChunkStore()
    for cid, chunk_layers in layers.items():
        store.put(cid, chunk_layers)
    streams, placements = fleet_streams(schedule, dag, store, material, profiles, clearance, slicing)
    return {r: s.program(store) for r, s in streams.items()}, placements


def fleet_streams(schedule: Schedule, dag: ChunkDAG, store: ChunkStore, material: MaterialIndex,
                  profiles: Mapping[str, RobotProfile], clearance: float, slicing: SlicingSettings
                  ) -> tuple[dict[str, RobotStream], dict[str, RobotPlacement]]:
    """Every robot's program (as a stream of pieces: a chunk's commands stay in ``store``) and
    placement for ``schedule`` (see the module doc).

    Parameters
    ----------
    schedule
        Who prints which chunk in which order (its times are not used: the replay makes its own).
    dag
        The chunks' facings and :meth:`~ChunkDAG.preds`.
    store
        The chunks' commands and summaries (:class:`~cooprint.program.stream.ChunkStore`).
    material
        The chunks' triangle boxes (travel heights).
    profiles
        ``{robot: RobotProfile}``: each robot's outline and speed caps.
    clearance
        How far apart two robots' outlines stay, and the lift above material of a travel, mm.
    slicing
        The slicer's settings: its speeds per path role, which the replay times the robots'
        moves at (under each profile's caps, :meth:`Feeds.of_robot`).

    Raises :class:`FleetError` when the robots cannot go on (a body would have to stand on printed
    material, a robot is walled in) or a parked robot is in the way (a bug of the ring rule).
    """
    missing = [r for r in schedule.sequences if r not in profiles]
    if missing:
        raise ValueError(f"fleet_programs: no profile for robot {missing[0]}")
    idx = dag.index
    for r, seq in schedule.sequences.items():
        for c in seq:
            f = dag.facing[idx[c]]
            if not (np.isfinite(f).all() and np.hypot(*f[:2]) > 1e-9):
                raise ValueError(f"fleet_programs: chunk {c} (robot {r}) has no facing ({list(f)}): the DAG must "
                                 "say which way its robot faces")
    fleet = _Fleet(schedule, dag, store, material, profiles, clearance, slicing)
    fleet.run()
    return fleet.programs()


__all__ = ["FleetError", "fleet_programs", "fleet_streams", "parking"]
