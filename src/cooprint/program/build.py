"""From chunks' tool paths to each robot's command stream (seed §4.2.2-4.3, Fig. 6, 10-13).

* A layer becomes: a move up to its height, a move to its first point, then per run of
  extruding paths ``TOOL ON``, the moves, ``TOOL OFF``, with travel moves between runs
  (:func:`layer_program`, whole-array).
* Between two chunks of a robot, the transition of the seed's Fig. 10-11: from the end of the
  chunk ``p1`` straight up to ``p2``, a clearance above the highest material that may be printed
  within the printhead's reach (``nozzle_depth``) of the way over, across to ``p3`` above the
  next chunk's first point, and down to it, ``p4``, with the tool off (:func:`transition_height`).
* A robot faces the centre line from the side of the chunk it prints (left chunks and the centre
  along the chunking axis, right chunks against it). A robot that prints both sides (one robot
  alone) turns round between them, driving around the print (:func:`turn_round`): the turn is a
  ``;@facing`` annotation of its program (:attr:`Program.turns`).
* Every dependency between chunks of different robots becomes a ``NOTIFY <chunk>`` right after
  the last move of the chunk depended on and a ``WAIT <chunk>`` right before the moves that lead
  into the dependent chunk (its transition); chunks of one robot are simply in order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Iterator, Mapping, NamedTuple, Sequence

import numba
import numpy as np

from cooprint import jit
from cooprint.config import outline_rects
from cooprint.geometry import unit_deg, unit_xy
from cooprint.program.commands import MOVE, NOTIFY, TOOL_OFF, TOOL_ON, WAIT, Program, make_program, quantize
from cooprint.program.stream import ChunkPiece, ChunkStore, RobotStream
from cooprint.slicing.paths import TRAVEL, LayerPaths

jit.setup()  # Ctrl-C held while numba compiles; LLVM calls untimed (cooprint.jit)


def layer_program(layer: LayerPaths, here: np.ndarray, *, robot: str = "", index: int = 0,
                  chunk: str | None = None) -> tuple[Program, np.ndarray]:
    """One layer's commands, starting from the nozzle position ``here`` (3,); returns the
    program piece and the position where it ends.

    The moves are the layer's points after each path's first (the nozzle is there already); a
    move that goes nowhere (on the 1 µm grid) is left out. One compiled pass
    (:func:`_layer_rows`) makes the rows.
    """
    if len(layer) == 0:
        return Program.empty(robot), here
    extr = layer.role != TRAVEL
    kind, xyz, path_of, n_in, lead, last = _layer_rows(layer.points, layer.offsets.astype(np.int64), extr,
                                                       np.asarray(here, dtype=np.float64), float(quantize(layer.z)))
    widths = np.where(extr, layer.width, 0.0)
    width = widths[path_of]
    width[:n_in] = widths[lead] if lead >= 0 else 0.0
    prog = make_program(robot, kind, xyz, role=layer.role[path_of], width=width, layer=index,
                        height=layer.height, chunk=0 if chunk is not None else -1,
                        chunks=(chunk,) if chunk is not None else ())
    return prog, last


@numba.njit(cache=True, nogil=True)
def _layer_rows(pts, off, extr, here, z):
    """The rows of :func:`layer_program` for paths ``off`` (m + 1 offsets into ``pts``), of
    which ``extr`` extrude, at height ``z`` (on the 1 µm grid), from ``here``: per command its
    kind, its position (on the grid; NaN but for MOVEs) and the path whose role and width it
    takes; the number of moves of the way in, the path whose width they take (that of the
    first command after them; -1: none), and the last move's position.

    The way in comes first: up to the layer's height where the nozzle is, then over to the first
    point (only the latter when ``here`` is not known). Then path by path: ``TOOL ON`` before the
    first path of each run of extruding paths, a move to each point after the path's first,
    ``TOOL OFF`` after the run's last path. A travel takes the role and width of the next
    extruding path (of the one before when none follows): the tool is off on it anyway, and the
    annotations change only where the printing does. A move to where the nozzle already is is
    left out."""
    m = len(off) - 1
    owner = np.empty(m, np.int64)
    follow = m
    for p in range(m - 1, -1, -1):
        if extr[p]:
            follow = p
        owner[p] = follow
    before = -1
    for p in range(m):
        if extr[p]:
            before = p
        elif owner[p] == m:
            owner[p] = before if before >= 0 else p
    known = np.isfinite(here[0]) and np.isfinite(here[1]) and np.isfinite(here[2])
    n_lead = 2 if known else 1
    total = n_lead
    first_path = -1  # the first path with a command: the way in takes its owner's width
    for p in range(m):
        c = off[p + 1] - off[p] - 1
        if extr[p]:
            c += (p == 0 or not extr[p - 1]) + (p == m - 1 or not extr[p + 1])
        if c > 0 and first_path < 0:
            first_path = p
        total += c
    kind = np.empty(total, np.uint8)
    xyz = np.full((total, 3), np.nan)
    path_of = np.empty(total, np.int64)
    px, py = np.nan, np.nan  # the nozzle (on the grid) before the next move
    pz = np.nan
    if known:
        px, py, pz = np.rint(here[0] * 1000.0) / 1000.0, np.rint(here[1] * 1000.0) / 1000.0, np.rint(here[2] * 1000.0) / 1000.0
    lead_path = owner[first_path] if first_path >= 0 else -1
    w = 0
    lx, ly, lz = np.nan, np.nan, np.nan
    for k in range(n_lead):
        if k == 0 and known:
            x, y = here[0], here[1]
        else:
            x, y = pts[off[0], 0], pts[off[0], 1]
        x, y = np.rint(x * 1000.0) / 1000.0, np.rint(y * 1000.0) / 1000.0
        lx, ly, lz = x, y, z
        if not (x == px and y == py and z == pz):
            kind[w] = MOVE
            xyz[w, 0], xyz[w, 1], xyz[w, 2] = x, y, z
            path_of[w] = owner[0]
            w += 1
        px, py, pz = x, y, z
    n_in = w
    for p in range(m):
        if extr[p] and (p == 0 or not extr[p - 1]):
            kind[w] = TOOL_ON
            path_of[w] = owner[p]
            w += 1
        for i in range(off[p] + 1, off[p + 1]):
            x, y = np.rint(pts[i, 0] * 1000.0) / 1000.0, np.rint(pts[i, 1] * 1000.0) / 1000.0
            lx, ly, lz = x, y, z
            if not (x == px and y == py and z == pz):
                kind[w] = MOVE
                xyz[w, 0], xyz[w, 1], xyz[w, 2] = x, y, z
                path_of[w] = owner[p]
                w += 1
            px, py, pz = x, y, z
        if extr[p] and (p == m - 1 or not extr[p + 1]):
            kind[w] = TOOL_OFF
            path_of[w] = owner[p]
            w += 1
    return kind[:w], xyz[:w], path_of[:w], n_in, lead_path, np.array([lx, ly, lz])


#: Layers per program piece of :func:`layer_pieces`: a writer's call costs about 0.5 ms besides
#: its commands (benchy's 240 layers one by one: 0.2 s of G-code writing, 0.1 s of it after the
#: last block was sliced).
LAYERS_PER_PIECE = 16
#: ... unless fewer layers already make this many commands: a piece is built whole, then written,
#: so its size is memory held at once. With layers alone the OCCT housing's parent process
#: peaked at 247 MB instead of 202 (16 of its layers of solid infill: tens of MB of commands and
#: text); a piece of 16,384 commands already takes the writer ~15 ms, the call's cost is 3% of it.
COMMANDS_PER_PIECE = 16_384


def layer_pieces(layers: Iterable[LayerPaths], robot: str = "", group: int = LAYERS_PER_PIECE,
                 commands: int = COMMANDS_PER_PIECE) -> Iterator[Program]:
    """The commands of consecutive layers of one model (``cooprint slice``), as they come, in
    pieces of ``group`` layers or of fewer whole layers that reach ``commands`` commands (the
    last piece the rest): layer ``i`` of the iterable is layer ``i`` of the model. A writer
    writes the same bytes for any split into pieces."""
    here = np.full(3, np.nan)
    parts: list[Program] = []
    held = 0
    for i, layer in enumerate(layers):
        piece, here = layer_program(layer, here, robot=robot, index=i)
        parts.append(piece)
        held += len(piece)
        if len(parts) >= group or held >= commands:
            yield Program.concat(robot, parts)
            parts, held = [], 0
    if parts:
        yield Program.concat(robot, parts)


@dataclass(frozen=True)
class MaterialIndex:
    """Where material may stand: per chunk, the XY box and top of every triangle of its mesh
    (the paths stay inside the chunk; a layer's top may reach half a layer above the mesh, so
    ``margin`` is added)."""

    boxes: dict[str, np.ndarray]  # chunk id -> (m, 5): xmin, ymin, xmax, ymax, zmax
    margin: float

    @staticmethod
    def of(chunks: Iterable, margin: float) -> "MaterialIndex":
        boxes = {}
        for c in chunks:
            tri = c.vertices[c.faces]
            boxes[c.id] = np.column_stack([tri[:, :, 0].min(1), tri[:, :, 1].min(1), tri[:, :, 0].max(1),
                                           tri[:, :, 1].max(1), tri[:, :, 2].max(1)])
        return MaterialIndex(boxes, margin)

    def highest(self, ids: Iterable[str], a: np.ndarray, b: np.ndarray, reach: float) -> float:
        """Highest material of chunks ``ids`` within ``reach`` of the XY segment a-b (box test:
        never lower than the truth), mm; ``-inf`` if none."""
        lo = np.minimum(a[:2], b[:2]) - reach
        hi = np.maximum(a[:2], b[:2]) + reach
        top = -math.inf
        for cid in ids:
            t = self.boxes[cid]
            near = (t[:, 2] >= lo[0]) & (t[:, 0] <= hi[0]) & (t[:, 3] >= lo[1]) & (t[:, 1] <= hi[1])
            if near.any():
                top = max(top, float(t[near, 4].max()) + self.margin)
        return top


def transition_height(p1: np.ndarray, p4: np.ndarray, material: MaterialIndex, printed: Iterable[str],
                      reach: float, clearance: float) -> float:
    """z of p2 and p3: ``clearance`` above the highest material of the ``printed`` chunks within
    ``reach`` of the way from p1 to p4, and above both ends."""
    top = material.highest(printed, p1, p4, reach)
    return float(quantize(max(top, p1[2], p4[2]) + clearance))


class BodySize(NamedTuple):
    """A robot's body as the planner sees it, mm: its front ``build_depth`` behind the nozzle
    (along the facing), ``length`` behind the front, ``width`` across; ``frame_width``: the
    width of the frame that carries the printhead over the print (``None``: the body's)."""

    build_depth: float
    length: float
    width: float
    frame_width: float | None = None

    def outline(self, reach: float) -> "Outline":
        """The whole robot with a printhead of half-side ``reach`` (``nozzle_depth``)."""
        fw = self.width if self.frame_width is None else self.frame_width
        return Outline(self.build_depth, self.length, self.width, fw, reach)


class Outline(NamedTuple):
    """A robot's outline in XY (issue 13, seed Fig. 1 and 3), in its own frame: ``u`` along its
    facing (from the body to the nozzle), ``v`` to its left, both from the nozzle, mm. Three
    vertical prisms, so that two robots meet where their rectangles overlap in XY:

    * body ``u in [-build_depth - body_length, -build_depth]``, ``|v| <= body_width / 2``;
    * frame ``u in [-build_depth, -nozzle_depth]``, ``|v| <= frame_width / 2``;
    * printhead ``u in [-nozzle_depth, nozzle_depth]``, ``|v| <= nozzle_depth``.
    """

    build_depth: float
    body_length: float
    body_width: float
    frame_width: float
    nozzle_depth: float

    @staticmethod
    def printhead(reach: float) -> "Outline":
        """A printhead alone (when the planner is not told the body)."""
        return Outline(reach, 0.0, 0.0, 0.0, reach)

    def rects(self) -> np.ndarray:
        """(3, 4): ``u_lo, u_hi, v_lo, v_hi`` of the body, the frame and the printhead
        (:func:`cooprint.config.outline_rects`, the simulator's outline too)."""
        return np.array(list(outline_rects(*self).values()))

    def corners(self, facing: Sequence[float]) -> np.ndarray:
        """(12, 2): the corners of the three rectangles in XY, from the nozzle, for a robot
        facing ``facing``."""
        a = unit_xy(facing)
        left = np.array([-a[1], a[0]])
        r = self.rects()
        u = r[:, [0, 0, 1, 1]].ravel()
        v = r[:, [2, 3, 2, 3]].ravel()
        return u[:, None] * a + v[:, None] * left

    def reach(self, facing: Sequence[float], direction: Sequence[float]) -> float:
        """How far the outline of a robot facing ``facing`` reaches beyond its nozzle in the XY
        ``direction`` (a unit vector), mm: the largest of its corners' components along it."""
        return float((self.corners(facing) @ unit_xy(direction)).max())


@dataclass(frozen=True)
class TurnRound:
    """The way of a robot that turns round between two chunks (:func:`turn_round`): nozzle
    positions (k, 3) driven ``before`` the turn in the old facing, the facing ``via`` which it
    turns (a unit XY vector a quarter turn from both), and the positions ``after`` in the new
    facing. The turn happens at ``before[-1]``."""

    before: np.ndarray
    via: np.ndarray
    after: np.ndarray


def _extent(material: MaterialIndex, ids: Iterable[str], a: np.ndarray, p: np.ndarray) -> np.ndarray:
    """``(s_lo, s_hi, q_lo, q_hi)``: the box, along ``a`` and across it (``p``), of the XY boxes of
    the triangles of chunks ``ids`` (never smaller than the material)."""
    boxes = [material.boxes[c] for c in ids]
    t = np.vstack(boxes) if boxes else np.zeros((0, 5))
    if len(t) == 0:
        return np.array([np.inf, -np.inf, np.inf, -np.inf])
    corners = np.stack([t[:, [0, 1]], t[:, [0, 3]], t[:, [2, 1]], t[:, [2, 3]]])  # (4, m, 2)
    s, q = corners @ a, corners @ p
    return np.array([s.min(), s.max(), q.min(), q.max()])


def turn_round(here: np.ndarray, p4: np.ndarray, facing: np.ndarray, material: MaterialIndex,
               printed: Iterable[str], body: BodySize, reach: float, clearance: float) -> TurnRound:
    """The way from ``here`` (the end of the last chunk printed facing ``facing``) to above
    ``p4`` (the first point of the next chunk, printed facing ``-facing``), driving around what
    is printed (chunks ``printed``), and the turn on the way.

    In the frame of the old facing (``s`` along it, ``q`` across it) the material printed so far
    lies in a box ``[s_lo, s_hi] x [q_lo, q_hi]`` (the triangles of its chunks). The nozzle rises
    ``clearance`` above the highest material within the printhead's ``reach`` of the whole way,
    then, ``m = clearance`` the margin:

    1. backs off along ``-facing`` until the body's front is ``m`` behind ``s_lo`` (if it is not
       already): the body, behind the nozzle, is then clear of the box whatever ``q``;
    2. goes across to the side of the box nearer to its way, until its whole outline is ``m``
       clear of ``[q_lo, q_hi]`` (nozzle ``w / 2 + m`` outside, ``w`` the widest of the body, the
       frame and the printhead's diagonal ``2 * sqrt(2) * reach``): there it turns round about
       the nozzle, via the facing that points across, at the print, so that the body and the
       frame swing on the outside: at every angle of the turn they stay beyond ``q_lo - m`` (or
       ``q_hi + m``), and the printhead, within ``sqrt(2) * reach <= w / 2`` of the nozzle, too;
    3. now facing ``-facing``, body ahead of the nozzle along ``+facing``: goes along the side
       until the body's front is ``m`` beyond ``s_hi`` (or to ``p4``'s ``s`` if that is further),
    4. across to ``p4``'s ``q``, and along to above ``p4``: the robot prints the next chunk from
       there with its body on the unprinted side, as a robot that only prints that side would.

    So the body never overlaps the box in either facing, and where the robot turns its whole
    outline is clear of it; the frame and the printhead pass over the print on legs 1, 2 and 4,
    as they do while printing, at the transition height (the printhead ``nozzle_height`` above
    the nozzle). Only the last leg (when ``p4`` lies within ``build_depth`` of the box) brings
    the body back towards the print, where the next chunk needs it anyway.
    """
    a = unit_xy(facing)
    p = np.array([-a[1], a[0]])
    printed = list(printed)
    s_lo, s_hi, q_lo, q_hi = _extent(material, printed, a, p)
    if not np.isfinite(s_lo):  # nothing printed: the ends alone
        s_lo = s_hi = float(here[:2] @ a)
        q_lo = q_hi = float(here[:2] @ p)
    bd = body.build_depth
    outline = body.outline(reach)
    width = max(outline.body_width, outline.frame_width, 2 * math.sqrt(2) * reach)
    m = clearance
    s0, q0 = float(here[:2] @ a), float(here[:2] @ p)
    st, qt = float(p4[:2] @ a), float(p4[:2] @ p)
    s1 = min(s0, s_lo - m + bd)
    low, high = q_lo - width / 2 - m, q_hi + width / 2 + m
    qs = low if abs(q0 - low) + abs(qt - low) <= abs(q0 - high) + abs(qt - high) else high
    s2 = max(st, s_hi + m - bd)
    via = p if qs == low else -p  # towards the print: the body swings on the outside

    def at(pts: list[tuple[float, float]]) -> np.ndarray:
        return np.array([s * a + q * p for s, q in pts])

    before, after = at([(s0, q0), (s1, q0), (s1, qs)]), at([(s2, qs), (s2, qt), (st, qt)])
    way = np.vstack([before, after])
    z = max(transition_height(np.r_[u, here[2]], np.r_[v, p4[2]], material, printed, reach, clearance)
            for u, v in zip(way[:-1], way[1:]))
    before, after = (quantize(np.column_stack([w, np.full(len(w), z)])) for w in (before, after))
    return TurnRound(before, via, after)


def facing_deg(facing: Sequence[float]) -> float:
    """Degrees from +X of an XY direction."""
    return math.degrees(math.atan2(facing[1], facing[0]))


def _moves(robot: str, points: Sequence[np.ndarray]) -> Program:
    pts = np.array(points, dtype=np.float64).reshape(-1, 3)
    return make_program(robot, np.full(len(pts), MOVE, np.uint8), pts)


def _sync(robot: str, kind: int, events: Sequence[str]) -> Program:
    return make_program(robot, np.array([kind], np.uint8), events=(tuple(events),))


@dataclass(frozen=True)
class RobotPlacement:
    """Where a robot works from: the side of the centre line it stays on, the direction it
    faces (towards the chunks it prints) at the start, and its start position (the nozzle above
    the first point of its first chunk, a clearance up); ``facings``: from which chunk on it
    faces which way (the first entry is the start's facing; a robot that prints both sides turns
    round once)."""

    name: str
    side: str  # "left" or "right" (-axis or +axis of the chunking direction); "both" for one robot
    facing: tuple[float, float]  # unit XY vector from the body to the nozzle
    start: tuple[float, float, float]
    facings: tuple[tuple[str, float], ...] = ()  # (chunk id, degrees) where the facing changes

    @property
    def facing_deg(self) -> float:
        return facing_deg(self.facing)

    def to_dict(self) -> dict[str, object]:
        return {"name": self.name, "side": self.side, "facing_deg": self.facing_deg,
                "facing": list(self.facing), "start": list(self.start),
                "facings": [{"from_chunk": c, "facing_deg": d} for c, d in self.facings]}


def chunk_facings(seq: Sequence[str], roles: dict[str, str], axis: np.ndarray) -> dict[str, np.ndarray]:
    """The direction a robot faces while it prints each chunk of ``seq``: a left chunk along
    ``axis`` (the body on the -axis side, outside the chunks printed before), a right chunk
    against it; the centre chunk as the robot's first side chunk (along ``axis`` if none)."""
    sides = [roles[c] for c in seq if roles[c] != "centre"]
    centre = -axis if sides and sides[0] == "right" else axis
    return {c: -axis if roles[c] == "right" else (axis if roles[c] == "left" else centre) for c in seq}


def robot_programs(sequences: dict[str, tuple[str, ...]], layers: dict[str, Sequence[LayerPaths]],
                   deps: dict[str, tuple[str, ...]], material: MaterialIndex, *, reach: float,
                   clearance: float, axis: Sequence[float], roles: dict[str, str],
                   body: BodySize | Mapping[str, BodySize] | None = None
                   ) -> tuple[dict[str, Program], dict[str, RobotPlacement]]:
    """:func:`robot_streams` of chunks sliced into ``layers`` (``{chunk id: [(layer index,
    LayerPaths), ...]}``), each robot's program made whole in memory."""
    store = ChunkStore()
    for cid in dict.fromkeys(c for seq in sequences.values() for c in seq):
        store.put(cid, layers[cid])
    streams, placements = robot_streams(sequences, store, deps, material, reach=reach, clearance=clearance,
                                        axis=axis, roles=roles, body=body)
    return {r: s.program(store) for r, s in streams.items()}, placements


def robot_streams(sequences: dict[str, tuple[str, ...]], store: ChunkStore,
                  deps: dict[str, tuple[str, ...]], material: MaterialIndex, *, reach: float,
                  clearance: float, axis: Sequence[float], roles: dict[str, str],
                  body: BodySize | Mapping[str, BodySize] | None = None
                  ) -> tuple[dict[str, RobotStream], dict[str, RobotPlacement]]:
    """Each robot's command stream and placement.

    Parameters
    ----------
    sequences
        ``{robot: (chunk id, ...)}`` in print order (the scheduler's assignment).
    store
        The chunks' commands (:class:`~cooprint.program.stream.ChunkStore`: sliced in the
        object's layer grid, shared by all chunks, so that their layers line up); a chunk's
        commands are referenced (:class:`ChunkPiece`), not copied.
    deps
        ``{chunk id: chunk ids it waits for}``.
    reach, clearance
        The printhead's horizontal extent around the nozzle (``nozzle_depth``) and the lift
        above material of a transition, mm; ``clearance`` is also the margin between the
        outlines of a robot that waits and of the robots it waits for (:func:`park`).
    axis
        The chunking direction (unit XY(Z)); ``roles`` maps chunk ids to centre/left/right.
    body
        The robots' body and frame (one for all, or ``{robot: BodySize}``): for the way around
        the print of a robot that prints both sides (:func:`turn_round`, needed then) and for
        the outlines kept apart where a robot waits (without it: the printheads alone).

    Where a robot waits for chunks of other robots it parks (:func:`park`): at the start (its
    ``start``, when its first chunk waits) or, later, lifted and backed off from where it is,
    so that its whole outline stays clear of the outlines of the robots printing what it waits
    for; after the WAIT it goes to its next chunk at the transition height.
    """
    owner = {c: r for r, seq in sequences.items() for c in seq}
    notify_after = {d for c, ds in deps.items() for d in ds if owner[d] != owner[c]}
    programs, placements = {}, {}
    ax = np.asarray(axis, dtype=np.float64)[:2]
    bodies = body if isinstance(body, Mapping) else {r: body for r in sequences}
    outlines = {r: (bodies[r].outline(reach) if bodies.get(r) is not None else Outline.printhead(reach))
                for r in sequences}
    faces = {r: chunk_facings(seq, roles, ax) for r, seq in sequences.items()}
    points = _PrintedPoints(store)

    def occupants(robot: str, waits: Iterable[str]) -> list[tuple[np.ndarray, np.ndarray, Outline]]:
        """Where the robots that print ``waits`` may be while ``robot`` waits for them: each
        one's nozzle on every chunk it prints up to the one waited for, in its facing there."""
        out = []
        for d in waits:
            x = owner[d]
            seq = sequences[x]
            for c in seq[:seq.index(d) + 1]:
                if points(c) is not None:
                    out.append((points(c), faces[x][c], outlines[x]))
        return out

    idle_robots = []
    for robot, seq in sequences.items():
        pieces: list[Program | ChunkPiece] = []
        sides = {roles[c] for c in seq} - {"centre"}
        # the side its body stands on: a robot that prints only the centre chunk faces +axis, from the left
        side = "left" if not sides else ("both" if len(sides) > 1 else sides.pop())
        printing = [c for c in seq if _first_point(store, (c,)) is not None]
        if not printing:  # a robot with nothing to print parks once the others' ways are known
            idle_robots.append(robot)
            continue
        outline = outlines[robot]
        current = faces[robot][printing[0]]
        facing = tuple(float(x) for x in current)
        facings = [(printing[0], facing_deg(current))]
        printed_before = [c for r, s in sequences.items() if r != robot for c in s]
        first = seq.index(printing[0])
        first_point = _first_point(store, seq)
        assert first_point is not None
        # the start: above the first point, or parked clear of what the first chunk waits for
        start_waits = [d for c in seq[:first + 1] for d in deps.get(c, ()) if owner[d] != robot]
        spot = park(first_point[:2], current, occupants(robot, start_waits), outline, clearance)
        if np.array_equal(quantize(spot), first_point[:2]):
            start = quantize(first_point + [0.0, 0.0, clearance])
        else:
            z = transition_height(np.r_[spot, first_point[2]], first_point, material, printed_before, reach,
                                  clearance)
            start = quantize(np.r_[spot, z])
        pieces.append(_moves(robot, [start]))
        here = start
        parked = not np.array_equal(start[:2], first_point[:2])  # up at a travel height, off its way
        for j, cid in enumerate(seq):
            waits = [d for d in deps.get(cid, ()) if owner[d] != robot]
            if waits and j > first:  # on the way: lift and back off out of the others' way
                spot = quantize(park(here[:2], current, occupants(robot, waits), outline, clearance))
                if not np.array_equal(spot, here[:2]):
                    z = transition_height(here, np.r_[spot, here[2]], material, printed_before + list(seq[:j]),
                                          reach, clearance)
                    pieces.append(_moves(robot, _distinct(here, quantize(np.array([np.r_[here[:2], z],
                                                                                   np.r_[spot, z]])))))
                    here = quantize(np.r_[spot, z])
                    parked = True
            if waits:
                pieces.append(_sync(robot, WAIT, waits))
            p4 = _first_point(store, (cid,))
            if p4 is None:  # nothing to print: done at once, and said so if another robot waits for it
                if cid in notify_after:
                    pieces.append(_sync(robot, NOTIFY, [cid]))
                continue
            if j > first and not np.array_equal(faces[robot][cid], current):
                b = bodies.get(robot)
                if b is None:
                    raise ValueError(f"robot {robot} turns round before {cid}: robot_programs needs its body")
                way = turn_round(here, p4, current, material, printed_before + list(seq[:j]), b, reach,
                                 clearance)
                current = faces[robot][cid]
                turns = ((0, facing_deg(way.via)), (0, facing_deg(current)))
                pieces += [_moves(robot, _distinct(here, way.before)), make_program(robot, np.zeros(0), turns=turns),
                           _moves(robot, _distinct(way.before[-1], way.after))]
                facings.append((cid, facing_deg(current)))
                here = way.after[-1]
            elif j > 0 or parked:
                # parked: already up at a travel height (from it, no lift by another clearance)
                low = np.r_[here[:2], p4[2]] if parked else here
                z = transition_height(low, p4, material, printed_before + list(seq[:j]), reach, clearance)
                z = max(z, float(here[2])) if parked else z
                way = quantize(np.array([np.r_[here[:2], z], np.r_[p4[:2], z]]))
                pieces.append(_moves(robot, _distinct(here, way)))
                here = quantize(np.r_[p4[:2], z])
            parked = False
            pieces.append(ChunkPiece(cid, entry=(float(here[0]), float(here[1]), float(here[2]))))
            here = store.summary(cid).last
            if cid in notify_after:
                pieces.append(_sync(robot, NOTIFY, [cid]))
        pieces.append(_moves(robot, [here + [0.0, 0.0, clearance]]))  # lift off the last chunk
        programs[robot] = RobotStream(robot, pieces)
        placements[robot] = RobotPlacement(robot, side, facing, tuple(float(x) for x in start),  # type: ignore[arg-type]
                                           tuple(facings))
    for robot in idle_robots:  # parks off the part, on its own side, and keeps its word (the WAITs and
        # NOTIFYs of its empty chunks)
        seq = sequences[robot]
        programs[robot] = RobotStream(robot, [_sync(robot, k, ev) for k, ev in _syncs(seq, deps, owner, robot,
                                                                                       notify_after)])
        idle = _idle_side(robot, list(sequences), seq, roles)
        f = ax if idle == "left" else -ax
        others = [o for r in sequences if r not in idle_robots
                  for o in _stream_occupants(programs[r], store, placements[r].facing, outlines[r])]
        placements[robot] = RobotPlacement(robot, idle,  # type: ignore[arg-type]
                                           tuple(float(x) for x in f),
                                           _parking(others, material, f, outlines[robot], clearance))
    return {r: programs[r] for r in sequences}, {r: placements[r] for r in sequences}


def clear_limit(facing: Sequence[float], occupants: Iterable[tuple[np.ndarray, Sequence[float], Outline]],
                outline: Outline, margin: float) -> float:
    """The farthest along ``facing`` (a unit XY vector, the robot's own) that the nozzle of a
    robot with ``outline`` may stand, facing that way, with its whole outline ``margin`` short
    of the outline of every occupant, mm (a coordinate along ``facing``; ``inf``: no occupant).

    An occupant ``(points, facing, outline)`` is a robot whose nozzle may be at any of the XY
    ``points`` (k, 2) while it faces its ``facing``. Its outline comes no nearer, along
    ``facing``, than the least of its points less its outline's reach backwards
    (:meth:`Outline.reach`); ours reaches its own reach ahead of our nozzle. A line across
    ``facing`` between the two then separates the outlines, whatever their positions across
    it: a separating axis, so the rule holds for any facings and any outline sizes.
    """
    f = unit_xy(facing)
    near = math.inf
    for pts, g, o in occupants:
        if len(pts):
            near = min(near, float((np.asarray(pts)[:, :2] @ f).min()) - o.reach(g, -f))
    return near - outline.reach(f, f) - margin


def park(here: np.ndarray, facing: Sequence[float], occupants: Iterable[tuple[np.ndarray, Sequence[float], Outline]],
         outline: Outline, margin: float) -> np.ndarray:
    """Where a robot waits (XY, (2,)): at ``here`` if its whole outline, facing ``facing``, is
    ``margin`` clear of every occupant's there (:func:`clear_limit`), or else backed off from
    ``here`` straight along ``-facing``, towards its body's side, just as far as that takes.

    The occupants are the robots that print what it waits for, on every chunk they print until
    then (so the outlines stay apart for as long as it waits, whichever they print meanwhile).
    Backing off moves the body and the frame away from the print the robot works on, over the
    floor on its own side, and the nozzle off the chunks it waits for: material lies only
    where their nozzles go, more than ``margin`` + two printhead reaches ahead of it.
    """
    here = np.asarray(here, dtype=np.float64)[:2]
    f = unit_xy(facing)
    limit = clear_limit(f, occupants, outline, margin)
    s = float(here @ f)
    return here if s <= limit else here - (s - limit) * f


class _PrintedPoints:
    """The XY points whose convex hull holds every point a chunk's paths go through (where its
    printer's nozzle is while it prints it; the moves between them stay in that hull: only the
    extremes of linear functions over them are used); ``None`` for a chunk with nothing to print."""

    def __init__(self, store: ChunkStore) -> None:
        self.store = store

    def __call__(self, cid: str) -> np.ndarray | None:
        s = self.store.summary(cid)
        return None if s.first is None else s.hull


def _stream_occupants(stream: RobotStream, store: ChunkStore, facing: Sequence[float], outline: Outline
                      ) -> list[tuple[np.ndarray, np.ndarray, Outline]]:
    """Every nozzle position of a whole program (its MOVEs' XY, the way in straight lines
    between them; a chunk's by the hull of its points and where the nozzle comes from), grouped
    by the facing in force (``facing`` at the start, then each of the turns: the place of a turn
    counts in each facing it passes through)."""
    out: list[tuple[np.ndarray, np.ndarray, Outline]] = []
    group: list[np.ndarray] = []
    at = np.zeros((0, 2))  # the last position so far
    g = unit_xy(facing)
    for part in stream.parts:
        if isinstance(part, ChunkPiece):
            s = store.summary(part.chunk)
            group += [s.hull] + ([np.asarray(part.entry, float)[None, :2]] if part.entry is not None else [])
            if s.last is not None:
                at = s.last[None, :2]
            continue
        mv = part.kind == MOVE
        xy = part.xyz[:, :2]
        k = 0
        for i, deg in part.turns:
            group.append(xy[k:i][mv[k:i]])
            before = xy[:i][mv[:i]][-1:]
            at = before if len(before) else at
            out.append((np.vstack(group + [at]), g, outline))
            g, k, group = unit_deg(deg), i, []
            out.append((at, g, outline))
        group.append(xy[k:][mv[k:]])
        moved = xy[mv][-1:]
        at = moved if len(moved) else at
    out.append((np.vstack(group) if group else np.zeros((0, 2)), g, outline))
    return [o for o in out if len(o[0])]


def _parking(others: list[tuple[np.ndarray, np.ndarray, Outline]], material: MaterialIndex, facing: np.ndarray,
             outline: Outline, clearance: float) -> tuple[float, float, float]:
    """Where an idle robot stands (a part that is one chunk leaves the second robot without
    work): on its own side of the part, facing it (``facing``: from the -axis side along
    ``+axis`` for ``"left"``, from the +axis side against it for ``"right"``), level with the
    middle of the part across it, as near as its whole outline can be to the other robots'
    while they print their chunks ``others`` (``clearance`` apart, :func:`clear_limit`): its
    body and frame stand over the floor, its printhead off the part. With nothing printed at
    all, the part's own extent (the chunks' triangle boxes, as if printed by a robot facing
    this one) stands in, so that two idle robots still park apart, one on each side."""
    f = unit_xy(facing)
    if not others:  # nothing printed: the corners of the part's triangle boxes
        corners = [b[:, [0, 1]] for b in material.boxes.values() if len(b)] + \
                  [b[:, [2, 3]] for b in material.boxes.values() if len(b)]
        if not corners:
            return (0.0, 0.0, float(clearance))
        others = [(np.concatenate(corners), -f, outline)]
    allp = np.concatenate([pts for pts, _, _ in others])
    across = np.array([-f[1], f[0]])
    mid = allp @ across
    p = f * clear_limit(f, others, outline, clearance) + across * (float(mid.min() + mid.max()) / 2)
    return (float(p[0]), float(p[1]), float(clearance))


def _idle_side(robot: str, robots: Sequence[str], seq: Sequence[str], roles: dict[str, str]) -> str:
    """The side an idle robot parks on: the side of the (empty) chunks it was given if they are
    all on one side; otherwise its own by order, the first robot (A) on the -axis side
    ("left"), the others on the +axis side ("right"), as the scheduler hands out the sides."""
    sides = {roles[c] for c in seq} - {"centre"}
    if len(sides) == 1:
        return sides.pop()
    return "left" if robots and robot == robots[0] else "right"


def _syncs(seq: Sequence[str], deps: dict[str, tuple[str, ...]], owner: dict[str, str], robot: str,
           notify_after: set[str]) -> list[tuple[int, list[str]]]:
    """The WAITs and NOTIFYs of a robot's chunks alone, in order (``(kind, events)``): what a
    robot with nothing to print still owes the fleet."""
    out: list[tuple[int, list[str]]] = []
    for cid in seq:
        waits = [d for d in deps.get(cid, ()) if owner[d] != robot]
        if waits:
            out.append((WAIT, waits))
        if cid in notify_after:
            out.append((NOTIFY, [cid]))
    return out


def _distinct(here: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``points`` without those where the nozzle already is (the one before, or ``here``)."""
    prev = np.vstack([quantize(here)[None], points[:-1]])
    return points[(points != prev).any(axis=1)]


def _first_point(store: ChunkStore, seq: Iterable[str]) -> np.ndarray | None:
    """(3,) where the first of ``seq``'s chunks with anything to print starts."""
    for cid in seq:
        first = store.summary(cid).first
        if first is not None:
            return first
    return None


__all__ = ["BodySize", "MaterialIndex", "Outline", "RobotPlacement", "TurnRound", "chunk_facings", "clear_limit",
           "facing_deg", "layer_pieces", "layer_program", "park", "robot_programs", "robot_streams", "transition_height", "turn_round"]
