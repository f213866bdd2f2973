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
from typing import Iterable, Iterator, NamedTuple, Sequence

import numpy as np

from cooprint.program.commands import MOVE, NOTIFY, TOOL_OFF, TOOL_ON, WAIT, Program, make_program, quantize
from cooprint.slicing.paths import TRAVEL, LayerPaths


def layer_program(layer: LayerPaths, here: np.ndarray, *, robot: str = "", index: int = 0,
                  chunk: str | None = None) -> tuple[Program, np.ndarray]:
    """One layer's commands, starting from the nozzle position ``here`` (3,); returns the
    program piece and the position where it ends.

    The moves are the layer's points after each path's first (the nozzle is there already); a
    move that goes nowhere (on the 1 µm grid) is left out.
    """
    z = float(quantize(layer.z))
    m = len(layer)
    if m == 0:
        return Program.empty(robot), here
    pts, off, role = layer.points, layer.offsets, layer.role
    n_pts = np.diff(off)
    extr = role != TRAVEL
    prev_extr = np.r_[False, extr[:-1]]
    next_extr = np.r_[extr[1:], False]
    on = extr & ~prev_extr
    offc = extr & ~next_extr
    count = on + (n_pts - 1) + offc
    start = np.r_[0, np.cumsum(count)[:-1]]
    total = int(count.sum())
    kind = np.full(total, MOVE, dtype=np.uint8)
    kind[start[on]] = TOOL_ON
    kind[(start + count - 1)[offc]] = TOOL_OFF
    moving = kind == MOVE
    keep_pt = np.ones(len(pts), dtype=bool)
    keep_pt[off[:-1]] = False  # each path's first point: the nozzle is there
    xyz = np.zeros((total, 3))
    xyz[moving, :2] = pts[keep_pt]
    xyz[:, 2] = z
    # a travel takes the role and width of the path it leads to (of the one before, at the end):
    # the tool is off on it anyway, and the annotations change only where the printing does
    k = np.arange(m)
    nxt = np.minimum.accumulate(np.where(extr, k, m)[::-1])[::-1]
    before = np.maximum.accumulate(np.where(extr, k, -1))
    owner = np.where(nxt < m, nxt, before)
    owner = np.where(owner >= 0, owner, k)
    path_of = np.repeat(owner, count)
    width = np.where(extr, layer.width, 0.0)[path_of]
    # the way in: up to the layer's height, then over to its first point (either is left out
    # below when the nozzle is there already)
    lead = [np.r_[here[:2], z], np.r_[pts[0], z]] if np.isfinite(here).all() else [np.r_[pts[0], z]]
    kind = np.r_[np.full(len(lead), MOVE, np.uint8), kind]
    xyz = np.vstack([*lead, xyz])
    path_of = np.r_[np.full(len(lead), owner[0]), path_of]
    width = np.r_[np.full(len(lead), width[0] if len(width) else 0.0), width]
    xyz = quantize(xyz)
    # drop moves to where the nozzle already is
    mv = np.flatnonzero(kind == MOVE)
    prev = np.vstack([quantize(here)[None], xyz[mv[:-1]]])
    still = np.zeros(len(kind), dtype=bool)
    still[mv[(xyz[mv] == prev).all(axis=1)]] = True
    keep = ~still
    roles = role[path_of]
    prog = make_program(robot, kind[keep], xyz[keep], role=roles[keep], width=width[keep], layer=index,
                        height=layer.height, chunk=0 if chunk is not None else -1,
                        chunks=(chunk,) if chunk is not None else ())
    last = xyz[mv[-1]] if len(mv) else here
    return prog, last


def layer_pieces(layers: Iterable[LayerPaths], robot: str = "") -> Iterator[Program]:
    """The commands of consecutive layers of one model (``cooprint slice``), layer by layer as
    they come: layer ``i`` of the iterable is layer ``i`` of the model."""
    here = np.full(3, np.nan)
    for i, layer in enumerate(layers):
        piece, here = layer_program(layer, here, robot=robot, index=i)
        yield piece


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
    (along the facing), ``length`` behind the front, ``width`` across."""

    build_depth: float
    length: float
    width: float


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
    2. goes across to the side of the box nearer to its way, until the body is ``m`` clear of
       ``[q_lo, q_hi]`` (nozzle ``width / 2 + m`` outside): there it turns round about the
       nozzle, via the facing that points across, at the print, so that the body swings on the
       outside: at every angle of the turn it stays beyond ``q_lo - m`` (or ``q_hi + m``);
    3. now facing ``-facing``, body ahead of the nozzle along ``+facing``: goes along the side
       until the body's front is ``m`` beyond ``s_hi`` (or to ``p4``'s ``s`` if that is further),
    4. across to ``p4``'s ``q``, and along to above ``p4``: the robot prints the next chunk from
       there with its body on the unprinted side, as a robot that only prints that side would.

    So the body never overlaps the box in either facing; only the last leg (when ``p4`` lies
    within ``build_depth`` of the box) brings it back towards the print, where the next chunk
    needs it anyway.
    """
    a = np.asarray(facing, dtype=np.float64)[:2]
    a = a / np.linalg.norm(a)
    p = np.array([-a[1], a[0]])
    printed = list(printed)
    s_lo, s_hi, q_lo, q_hi = _extent(material, printed, a, p)
    if not np.isfinite(s_lo):  # nothing printed: the ends alone
        s_lo = s_hi = float(here[:2] @ a)
        q_lo = q_hi = float(here[:2] @ p)
    bd, length, width = body
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
                   body: BodySize | None = None) -> tuple[dict[str, Program], dict[str, RobotPlacement]]:
    """Each robot's command stream and placement.

    Parameters
    ----------
    sequences
        ``{robot: (chunk id, ...)}`` in print order (the scheduler's assignment).
    layers
        ``{chunk id: [(layer index, LayerPaths), ...]}``, the index in the object's layer grid
        (shared by all chunks, so that their layers line up).
    deps
        ``{chunk id: chunk ids it waits for}``.
    reach, clearance
        The printhead's horizontal extent around the nozzle (``nozzle_depth``) and the lift
        above material of a transition, mm.
    axis
        The chunking direction (unit XY(Z)); ``roles`` maps chunk ids to centre/left/right.
    body
        The robot's body, for the way around the print of a robot that prints both sides
        (:func:`turn_round`); needed only then.
    """
    owner = {c: r for r, seq in sequences.items() for c in seq}
    notify_after = {d for c, ds in deps.items() for d in ds if owner[d] != owner[c]}
    programs, placements = {}, {}
    ax = np.asarray(axis, dtype=np.float64)[:2]
    for robot, seq in sequences.items():
        pieces: list[Program] = []
        sides = {roles[c] for c in seq} - {"centre"}
        # the side its body stands on: a robot that prints only the centre chunk faces +axis, from the left
        side = "left" if not sides else ("both" if len(sides) > 1 else sides.pop())
        faces = chunk_facings(seq, roles, ax)
        printing = [c for c in seq if _first_point(layers, (c,)) is not None]
        current = faces[printing[0]] if printing else (ax if side != "right" else -ax)
        facing = tuple(float(x) for x in current)
        first_point = _first_point(layers, seq)
        if first_point is None:  # a robot with nothing to print parks off the part, on its own side,
            # and keeps its word (the WAITs and NOTIFYs of its empty chunks)
            programs[robot] = Program.concat(robot, [_sync(robot, k, ev) for k, ev in _syncs(seq, deps, owner, robot,
                                                                                            notify_after)])
            idle = _idle_side(robot, list(sequences), seq, roles)
            placements[robot] = RobotPlacement(robot, idle,  # type: ignore[arg-type]
                                               tuple(float(x) for x in (ax if idle == "left" else -ax)),
                                               _parking(layers, material, ax, clearance, idle))
            continue
        facings = [(printing[0], facing_deg(current))]
        printed_before = [c for r, s in sequences.items() if r != robot for c in s]
        start = quantize(first_point + [0.0, 0.0, clearance])
        pieces.append(_moves(robot, [start]))
        here = start
        for j, cid in enumerate(seq):
            waits = [d for d in deps.get(cid, ()) if owner[d] != robot]
            if waits:
                pieces.append(_sync(robot, WAIT, waits))
            p4 = _first_point(layers, (cid,))
            if p4 is None:  # nothing to print: done at once, and said so if another robot waits for it
                if cid in notify_after:
                    pieces.append(_sync(robot, NOTIFY, [cid]))
                continue
            if j > 0 and not np.array_equal(faces[cid], current):
                if body is None:
                    raise ValueError(f"robot {robot} turns round before {cid}: robot_programs needs its body")
                way = turn_round(here, p4, current, material, printed_before + list(seq[:j]), body, reach,
                                 clearance)
                current = faces[cid]
                turns = ((0, facing_deg(way.via)), (0, facing_deg(current)))
                pieces += [_moves(robot, _distinct(here, way.before)), make_program(robot, np.zeros(0), turns=turns),
                           _moves(robot, _distinct(way.before[-1], way.after))]
                facings.append((cid, facing_deg(current)))
                here = way.after[-1]
            elif j > 0:
                z = transition_height(here, p4, material, printed_before + list(seq[:j]), reach, clearance)
                pieces.append(_moves(robot, [np.r_[here[:2], z], np.r_[p4[:2], z]]))
                here = quantize(np.r_[p4[:2], z])
            for li, layer in layers[cid]:
                piece, here = layer_program(layer, here, robot=robot, index=li, chunk=cid)
                pieces.append(piece)
            if cid in notify_after:
                pieces.append(_sync(robot, NOTIFY, [cid]))
        pieces.append(_moves(robot, [here + [0.0, 0.0, clearance]]))  # lift off the last chunk
        programs[robot] = Program.concat(robot, pieces)
        placements[robot] = RobotPlacement(robot, side, facing, tuple(float(x) for x in start),  # type: ignore[arg-type]
                                           tuple(facings))
    return programs, placements


def _parking(layers: dict, material: MaterialIndex, ax: np.ndarray, clearance: float,
             side: str) -> tuple[float, float, float]:
    """Where an idle robot stands (a part that is one chunk leaves the second robot without
    work): on its own ``side`` of the part, facing it (from the -axis side along ``+ax`` for
    ``"left"``, from the +axis side against it for ``"right"``), its nozzle ``clearance`` beyond
    the printed point farthest towards that side, level with the middle of the part across it.
    Its body (behind the nozzle) then stays clear of the part and of the robots that print it,
    whose bodies stand on their own sides. With nothing printed at all, the part's own extent
    (the chunks' triangle boxes) stands in for the printed points, so that two idle robots
    still park apart, one on each side."""
    pts = [layer.points[:, :2] for chunk in layers.values() for _, layer in chunk if len(layer)]
    if not pts:  # nothing printed: the corners of the part's triangle boxes
        pts = [b[:, [0, 1]] for b in material.boxes.values() if len(b)] + \
              [b[:, [2, 3]] for b in material.boxes.values() if len(b)]
    if not pts:
        return (0.0, 0.0, float(clearance))
    allp = np.concatenate(pts)
    along = allp @ ax
    across = np.array([-ax[1], ax[0]])
    mid = allp @ across
    edge = float(along.min()) - clearance if side == "left" else float(along.max()) + clearance
    p = ax * edge + across * (float(mid.min() + mid.max()) / 2)
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


def _first_point(layers: dict, seq: Iterable[str]) -> np.ndarray | None:
    """(3,) where the first of ``seq``'s chunks with anything to print starts."""
    for cid in seq:
        for _, layer in layers[cid]:
            if len(layer):
                return quantize(np.r_[layer.points[0], layer.z])
    return None


__all__ = ["BodySize", "MaterialIndex", "RobotPlacement", "TurnRound", "chunk_facings", "facing_deg", "layer_pieces",
           "layer_program", "robot_programs", "transition_height", "turn_round"]
