"""From chunks' tool paths to each robot's command stream (seed §4.2.2-4.3, Fig. 6, 10-13).

* A layer becomes: a move up to its height, a move to its first point, then per run of
  extruding paths ``TOOL ON``, the moves, ``TOOL OFF``, with travel moves between runs
  (:func:`layer_program`, whole-array).
* Between two chunks of a robot, the transition of the seed's Fig. 10-11: from the end of the
  chunk ``p1`` straight up to ``p2``, a clearance above the highest material that may be printed
  within the printhead's reach (``nozzle_depth``) of the way over, across to ``p3`` above the
  next chunk's first point, and down to it, ``p4``, with the tool off (:func:`transition_height`).
* Every dependency between chunks of different robots becomes a ``NOTIFY <chunk>`` right after
  the last move of the chunk depended on and a ``WAIT <chunk>`` right before the moves that lead
  into the dependent chunk (its transition); chunks of one robot are simply in order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Iterator, Sequence

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


def _moves(robot: str, points: Sequence[np.ndarray]) -> Program:
    pts = np.array(points, dtype=np.float64).reshape(-1, 3)
    return make_program(robot, np.full(len(pts), MOVE, np.uint8), pts)


def _sync(robot: str, kind: int, events: Sequence[str]) -> Program:
    return make_program(robot, np.array([kind], np.uint8), events=(tuple(events),))


@dataclass(frozen=True)
class RobotPlacement:
    """Where a robot works from: the side of the centre line it stays on, the direction it
    faces (towards the chunks it prints), and its start position (the nozzle above the first
    point of its first chunk, a clearance up)."""

    name: str
    side: str  # "left" or "right" (-axis or +axis of the chunking direction); "both" for one robot
    facing: tuple[float, float]  # unit XY vector from the body to the nozzle
    start: tuple[float, float, float]

    @property
    def facing_deg(self) -> float:
        return math.degrees(math.atan2(self.facing[1], self.facing[0]))

    def to_dict(self) -> dict[str, object]:
        return {"name": self.name, "side": self.side, "facing_deg": self.facing_deg,
                "facing": list(self.facing), "start": list(self.start)}


def robot_programs(sequences: dict[str, tuple[str, ...]], layers: dict[str, Sequence[LayerPaths]],
                   deps: dict[str, tuple[str, ...]], material: MaterialIndex, *, reach: float,
                   clearance: float, axis: Sequence[float], roles: dict[str, str]) -> tuple[dict[str, Program],
                                                                                          dict[str, RobotPlacement]]:
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
    """
    owner = {c: r for r, seq in sequences.items() for c in seq}
    notify_after = {d for c, ds in deps.items() for d in ds if owner[d] != owner[c]}
    programs, placements = {}, {}
    ax = np.asarray(axis, dtype=np.float64)[:2]
    for robot, seq in sequences.items():
        pieces: list[Program] = []
        sides = {roles[c] for c in seq} - {"centre"}
        side = "both" if len(sides) != 1 else sides.pop()
        facing = tuple(float(x) for x in (ax if side != "right" else -ax))
        first_point = _first_point(layers, seq)
        if first_point is None:  # a robot with nothing to print parks off the part, on the +axis side
            programs[robot] = Program.empty(robot)
            placements[robot] = RobotPlacement(robot, "right", tuple(float(x) for x in -ax),  # type: ignore[arg-type]
                                               _parking(layers, ax, clearance))
            continue
        printed_before = [c for r, s in sequences.items() if r != robot for c in s]
        start = quantize(first_point + [0.0, 0.0, clearance])
        pieces.append(_moves(robot, [start]))
        here = start
        for j, cid in enumerate(seq):
            waits = [d for d in deps.get(cid, ()) if owner[d] != robot]
            if waits:
                pieces.append(_sync(robot, WAIT, waits))
            p4 = _first_point(layers, (cid,))
            if p4 is None:
                continue
            if j > 0:
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
        placements[robot] = RobotPlacement(robot, side, facing, tuple(float(x) for x in start))  # type: ignore[arg-type]
    return programs, placements


def _parking(layers: dict, ax: np.ndarray, clearance: float) -> tuple[float, float, float]:
    """Where an idle robot stands (a part that is one chunk leaves the second robot without
    work): facing the part from the +axis side, its nozzle ``clearance`` beyond the farthest
    printed point along ``ax``, level with the middle of the part across it, so that its body
    (behind the nozzle) is clear of the part and of the robot that prints it."""
    pts = [layer.points for chunk in layers.values() for _, layer in chunk if len(layer)]
    if not pts:
        return (0.0, 0.0, 0.0)
    allp = np.concatenate(pts)
    along = allp @ ax
    across = np.array([-ax[1], ax[0]])
    side = allp @ across
    p = ax * (float(along.max()) + clearance) + across * (float(side.min() + side.max()) / 2)
    return (float(p[0]), float(p[1]), float(clearance))


def _first_point(layers: dict, seq: Iterable[str]) -> np.ndarray | None:
    """(3,) where the first of ``seq``'s chunks with anything to print starts."""
    for cid in seq:
        for _, layer in layers[cid]:
            if len(layer):
                return quantize(np.r_[layer.points[0], layer.z])
    return None


__all__ = ["MaterialIndex", "layer_pieces", "RobotPlacement", "layer_program", "robot_programs", "transition_height"]
