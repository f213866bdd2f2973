"""Hand-made chunk layouts for the fleet programs' tests (tests/test_fleet_programs.py): boxes
side by side, sliced in one layer grid, a ChunkDAG and a Schedule made by hand."""

from __future__ import annotations

import dataclasses

import numpy as np

from cooprint.chunking.cut import Chunk, ChunkSet
from cooprint.config import RobotProfile, SlicingSettings
from cooprint.jobs import chunk_job
from cooprint.models import car
from cooprint.program.build import MaterialIndex
from cooprint.program.gcode import Feeds
from cooprint.scheduling.dag import ChunkDAG
from cooprint.scheduling.schedule import Schedule
from cooprint.slicing import iter_layers
from cooprint.slicing.paths import TRAVEL

import solids
from speeds import UNIFORM_SPEEDS

#: A small robot (all lengths a quarter of the default's or so) so that the parts stay small; it
#: extrudes at 40 mm/s and travels at 120 (its caps: the slicer's speeds are higher), and
#: :func:`scaled` makes it up to 3 times faster or slower.
SMALL = RobotProfile(name="small", build_depth=80.0, nozzle_height=40.0, nozzle_depth=10.0, body_width=80.0,
                     body_length=90.0, max_print_speed=40.0, max_travel_speed=120.0)
#: Thick, few layers; every role at 120 mm/s and travel at 360 (3 x SMALL's caps).
SLICING = SlicingSettings(layer_height=1.5, first_layer_height=1.5, extrusion_width=2.0, nozzle_diameter=1.6,
                          perimeters=1, top_layers=1, bottom_layers=1, infill_density=0.1,
                          **{k: 3 * v for k, v in UNIFORM_SPEEDS.items()})


def box_chunk(cid: str, lo, hi, facing, row: int = 0, col: int = 0) -> Chunk:
    tm = solids.to_trimesh(solids.box(hi[0] - lo[0], hi[1] - lo[1], hi[2]))
    v = np.asarray(tm.vertices, float) + [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, 0.0]
    return Chunk(cid, "centre", 0, v, np.asarray(tm.faces, np.int64), float(tm.volume), (), row, col,
                 tuple(float(x) for x in facing))


def layout(chunks: list[Chunk], deps: dict[str, tuple[str, ...]], sequences: dict[str, tuple[str, ...]],
           slicing: SlicingSettings = SLICING, profile: RobotProfile = SMALL):
    """Slice the chunks, time them at the profile's speeds, and make the DAG and a schedule whose
    times follow the sequences (each chunk after its robot's previous one and its deps)."""
    feeds = Feeds.of_robot(profile, slicing)
    layers = {}
    for c in chunks:
        first = int(round(c.bounds[0, 2] / slicing.layer_height))
        layers[c.id] = list(enumerate(iter_layers(c.as_solid(), slicing, workers=1, base=0.0), start=first))
    work, start, end, foot = [], [], [], []
    for c in chunks:
        pts = np.concatenate([la.points for _, la in layers[c.id] if len(la)])
        work.append(sum(float((la.lengths() / feeds.move_speeds(la.role, np.full(len(la), i), la.role != TRAVEL)).sum())
                        for i, la in layers[c.id]))
        start.append(np.r_[pts[0], 0.0])
        end.append(np.r_[pts[-1], 0.0])
        foot.append(np.r_[pts.min(0), pts.max(0)])
    ids = tuple(c.id for c in chunks)
    dag = ChunkDAG(ids, np.array(work), np.array([c.facing for c in chunks], float), np.array(start), np.array(end),
                   np.array(foot), {c: tuple(deps.get(c, ())) for c in ids}, travel_speed=feeds.travel)
    w = dict(zip(ids, work))
    t0, t1 = {}, {}
    free = {r: 0.0 for r in sequences}
    pending = {r: list(seq) for r, seq in sequences.items()}
    while any(pending.values()):
        for r, seq in pending.items():
            if seq and all(d in t1 for d in dag.preds(seq[0])):
                c = seq.pop(0)
                t0[c] = max([free[r]] + [t1[d] for d in dag.preds(c)])
                t1[c] = free[r] = t0[c] + w[c]
    sched = Schedule({r: tuple(s) for r, s in sequences.items()}, "hand", t0, t1, max(t1.values(), default=0.0),
                     dag.lower_bound(len(sequences)))
    material = MaterialIndex.of(chunks, margin=slicing.layer_height)
    return dag, sched, layers, material


def scaled(profile: RobotProfile, speed: float) -> RobotProfile:
    """``profile`` ``speed`` times as fast (its caps scaled: at most 3 x, :data:`SLICING`'s speeds)."""
    return dataclasses.replace(profile, max_print_speed=profile.max_print_speed * speed,
                               max_travel_speed=profile.max_travel_speed * speed)


def seed2_bar(length: float = 900.0, robots_seq: dict[str, tuple[str, ...]] | None = None,
              slicing: SlicingSettings = SLICING, profile: RobotProfile = SMALL, height: float = 6.0):
    """The seed's two-sided cut (``cut_chunks``) of a bar along y, 40 mm wide and ``height`` tall, for
    ``profile``; the centre chunk faced like the first side chunk of its robot. Returns the chunk
    set and :func:`layout` of it for ``robots_seq`` (``{robot: chunk ids}``, a callable of the ids
    too)."""
    from cooprint.chunking import cut_chunks, plan_chunks
    from cooprint.config import ChunkingSettings
    from cooprint.io.mesh import MeshReport, Solid

    tm = solids.to_trimesh(solids.box(40.0, length, height))

    lo, hi = tm.bounds
    report = MeshReport(path="<bar>", format="test", triangles_read=len(tm.faces), triangles=len(tm.faces),
                        vertices=len(tm.vertices), bbox_min=tuple(lo), bbox_max=tuple(hi), volume_mm3=float(tm.volume),
                        watertight_as_read=True, repairs=())
    solid = Solid(np.asarray(tm.vertices, float), np.asarray(tm.faces, np.int64), report)
    plan = plan_chunks(solid.vertices, profile, ChunkingSettings(), 2)
    cs = cut_chunks(solid, plan)
    seqs = robots_seq(cs.ids) if callable(robots_seq) else robots_seq
    axis = np.asarray(plan.axis, float)[:2]
    chunks = []
    for c in cs.chunks:
        f = c.facing
        if f is None:  # the centre: as its robot's first side chunk
            r = next(r for r, s in seqs.items() if c.id in s)
            side = next((cs[x].role for x in seqs[r] if cs[x].role != "centre"), "left")
            f = tuple(-axis if side == "right" else axis)
        chunks.append(dataclasses.replace(c, facing=tuple(float(x) for x in f)))
    return cs, layout(chunks, dict(cs.deps), seqs, slicing, profile)


def grid_boxes(rows: int, cols: int, robots: tuple[str, ...], width: float = 120.0, depth: float = 60.0,
               profile: RobotProfile = SMALL, slicing: SlicingSettings = SLICING):
    """A grid of ``rows`` x ``cols`` boxes (one box sliced once, its layers moved to each place):
    row 0 and the rows below it printed facing +y, the rows above facing -y, every chunk leaning on
    its neighbour towards row 0 and after the chunks under its robot's body (three rows out, the
    columns beside), columns dealt round-robin to the robots, rows from the centre out. Returns
    ``(dag, schedule, layers, material)`` (the schedule's times are placeholders)."""
    proto = box_chunk("P", (0, 0, 0), (width, depth, 3.0), (0, 1))
    base = list(enumerate(iter_layers(proto.as_solid(), slicing, workers=1, base=0.0)))
    chunks, layers, deps, body = [], {}, {}, {}
    half = rows // 2
    span = range(-half, rows - half)
    for k in span:
        for c in range(cols):
            cid = f"r{k}c{c}"
            f = (0.0, -1.0) if k > 0 else (0.0, 1.0)
            chunks.append(box_chunk(cid, (c * width, k * depth, 0), (c * width + width, k * depth + depth, 3.0),
                                    f, k, c))
            off = np.array([c * width, k * depth])
            layers[cid] = [(i, dataclasses.replace(la, points=la.points + off)) for i, la in base]
            if k != 0:
                deps[cid] = (f"r{k + 1 if k < 0 else k - 1}c{c}",)
            for kk in ([k - j for j in (1, 2, 3)] if k <= 0 else [k + j for j in (1, 2, 3)]):
                for cc in (c - 1, c + 1):
                    if kk in span and 0 <= cc < cols:
                        body.setdefault(f"r{kk}c{cc}", []).append(cid)
    ids = tuple(c.id for c in chunks)
    order = sorted(span, key=lambda k: (abs(k), k))
    seqs = {r: tuple(f"r{k}c{c}" for k in order for c in range(i, cols, len(robots))) for i, r in enumerate(robots)}
    n = len(ids)
    dag = ChunkDAG(ids, np.ones(n), np.array([c.facing for c in chunks]), np.zeros((n, 3)), np.zeros((n, 3)),
                   np.zeros((n, 4)), {c: deps.get(c, ()) for c in ids}, {c: tuple(body.get(c, ())) for c in ids})
    sched = Schedule(seqs, "hand", {c: 0.0 for c in ids}, {c: 1.0 for c in ids}, 1.0, 1.0)
    return dag, sched, layers, MaterialIndex.of(chunks, margin=slicing.layer_height)


def box_grid(nx: int, ny: int, size: float = 100.0, tiny: tuple[int, int] | None = None) -> ChunkSet:
    """A grid of ``nx`` x ``ny`` box chunks (a layout other than seed2, for the pictures' tests)
    over the car's plan; the ``tiny`` one (column, row) a 2 mm cube."""
    plan = chunk_job(car(420.0), robots=1).chunks.plan
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    faces = np.array([[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                      [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]])
    chunks = []
    for i in range(nx):
        for j in range(ny):
            dims = [2.0, 2.0, 2.0] if (i, j) == tiny else [size * 0.9, size * 0.9, 40.0 + 10 * ((i + j) % 3)]
            v = corners * dims + [i * size, j * size, 0.0]
            chunks.append(Chunk(f"r{j}c{i}", "right", j + 1, v, faces, float(np.prod(np.ptp(v, axis=0))), (),
                                row=j, col=i))
    return ChunkSet(plan, tuple(chunks), {c.id: () for c in chunks}, sum(c.volume for c in chunks), layout="grid")
