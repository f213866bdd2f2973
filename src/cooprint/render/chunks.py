"""Picture of a chunked object, like the seed's Fig. 5: chunks in 3D, centre chunk yellow; or,
given a schedule, each chunk in its robot's colour with its robot and place in that robot's order
("B3": robot B's third chunk), for any number of robots and chunks (issue 14).

A small orthographic painter's renderer on numpy + Pillow: project all triangles once, cull back
faces, shade by the angle to the light, sort far-to-near, draw. Chunks are pulled apart so each
one reads as its own solid: the seed2 layout's along the chunking axis, by side and index;
other layouts (a grid of rows and columns) away from the object's centre in XY, in proportion to
their distance from it. Chunks are drawn one after the other, far to near (seed2: in an order
that is exact for it; a grid: by their centres, right for chunks that planes separate once
pulled apart), each one's triangles far to near.

The triangles are drawn as numbers (an id buffer: which triangle, so which chunk, each pixel
shows) and coloured from it, so the picture knows where every chunk is visible: each label goes
where its frame lies wholly on its own chunk's visible pixels, as far from that chunk's edges as
it can (so no label sits in a torus's hole or on a neighbour, and no two labels overlap), smaller
where the chunk is small; a chunk too small for the smallest label is named in a footnote.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from cooprint.chunking import ChunkSet
from cooprint.render.palette import robot_colour, robot_colours

if TYPE_CHECKING:
    from cooprint.scheduling import Assignment

CENTRE_COLOUR = (242, 197, 49)
#: The sides' colours without a schedule: tints and shades of the first robot's colour on the left
#: (the seed's robot A prints the left side) and of the second's on the right (robot B), so that
#: they never contradict the robots' colours of the other pictures (render/palette.py).
LEFT_COLOURS = [robot_colour(0), (232, 140, 120), (170, 70, 55), (240, 170, 150)]
RIGHT_COLOURS = [robot_colour(1), (110, 175, 220), (45, 110, 160), (150, 200, 235)]
BACKGROUND = (250, 250, 252)
#: Above this many triangles in all, chunks are simplified for the picture only.
MAX_TRIANGLES = 300_000


def chunk_colour(role: str, index: int) -> tuple[int, int, int]:
    if role == "centre":
        return CENTRE_COLOUR
    pal = LEFT_COLOURS if role == "left" else RIGHT_COLOURS
    return pal[(index - 1) % len(pal)]


def _view_basis(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """Rows: screen right, screen up, direction towards the camera."""
    a, e = math.radians(azimuth_deg), math.radians(elevation_deg)
    to_cam = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    right = np.cross([0.0, 0.0, 1.0], to_cam)
    right /= np.linalg.norm(right)
    up = np.cross(to_cam, right)
    return np.vstack([right, up, to_cam])


def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1
        return ImageFont.load_default()


def _subdivide_shaded(tri: np.ndarray, max_edge: float, rounds: int = 3,
                      budget: int = 120_000) -> np.ndarray:
    """Split triangles (n, 3, 4: xyz + shade) with an edge longer than ``max_edge`` into four, up to
    ``rounds`` times and while the count stays within ``budget``, so that depth-sorting by centroid
    is right for long thin triangles (fans, slivers)."""
    for _ in range(rounds):
        xyz = tri[:, :, :3]
        edge = np.linalg.norm(xyz - np.roll(xyz, -1, axis=1), axis=2).max(axis=1)
        big = edge > max_edge
        if not big.any() or len(tri) + 3 * int(big.sum()) > budget:
            break
        a, b, c = tri[big, 0], tri[big, 1], tri[big, 2]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        split = np.stack([np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
        tri = np.concatenate([tri[~big], split.reshape(-1, 3, tri.shape[2])])
    return tri


def _draw_order(chunks: ChunkSet, to_cam: np.ndarray) -> list[int]:
    """Chunks far-to-near. Consecutive chunks on a side are separated by parallel planes, and
    plane R_0 (L_0) separates the right (left) side from the rest, so this order is exact."""
    plan = chunks.plan
    idx = {c.id: i for i, c in enumerate(chunks.chunks)}
    out: list[int] = []
    sides = {}
    for side, role in (("R", "right"), ("L", "left")):
        seq = sorted((c for c in chunks.chunks if c.role == role), key=lambda c: c.index)
        near_outer = float(np.dot(plan.plane(side, 0).normal, to_cam)) > 0
        sides[side] = ([idx[c.id] for c in seq], near_outer)
    centre = [idx["C"]] if "C" in idx else []
    left, left_outer_near = sides["L"]
    group = centre + left if left_outer_near else left[::-1] + centre
    right, right_outer_near = sides["R"]
    out = group + right if right_outer_near else right[::-1] + group
    return out


#: Radial explosion of the layouts other than seed2: a chunk moves away from the object's centre
#: (XY) by this many times ``explode`` times its distance from it (neighbours then stand apart by
#: 15% of their pitch at the default ``explode``).
RADIAL_EXPLODE = 6.0
#: Label font sizes by the number of chunks: fewer chunks, larger labels (the largest tried first).
LABEL_SIZES = ((20, 18), (80, 14), (10**9, 11))
#: The smallest label font size tried where a chunk is small in the picture, pixels.
MIN_LABEL_SIZE = 8


#: A chunk the schedule gives to no robot (drawn anyway, so that the gap shows).
UNASSIGNED_COLOUR = (170, 170, 170)


def order_label(robot: str, order: int) -> str:
    """A chunk's label: its robot and its place in that robot's order, from 1 ("B3": robot B's
    third chunk); a ``#`` between them when the robot's name ends in a digit ("R27#3", not
    "R273")."""
    return f"{robot}{'#' if robot[-1:].isdigit() else ''}{order + 1}"


def _robot_of(schedule: "Assignment | None", cid: str) -> str | None:
    if schedule is None:
        return None
    try:
        return schedule.robot_of(cid)
    except KeyError:
        return None


@dataclass(frozen=True)
class ChunkPicture:
    """A drawn chunk picture and where its chunks and labels are.

    Attributes
    ----------
    image
        The picture (RGB).
    ids
        ``(height, width)`` int array: the index (in ``chunks.chunks``) of the chunk drawn at
        each pixel (under the labels too), -1 where none (background, title, legend, footnote).
    labels
        The labels drawn: ``(chunk id, text, (x0, y0, x1, y1))``, the frame's pixel box (inclusive).
    left_out
        The labels of the chunks too small in the picture (or hidden) for one; the footnote names them.
    """

    image: Image.Image
    ids: np.ndarray
    labels: list[tuple[str, str, tuple[int, int, int, int]]]
    left_out: list[str]


def render_chunks(chunks: ChunkSet, path: str | Path, size: tuple[int, int] = (1200, 800),
                  azimuth_deg: float = -35.0, elevation_deg: float = 22.0,
                  explode: float = 0.025, title: str | None = None,
                  schedule: "Assignment | None" = None) -> Path:
    """Draw ``chunks`` to a PNG at ``path`` (:func:`chunk_picture`, which see for the parameters)."""
    path = Path(path)
    chunk_picture(chunks, size, azimuth_deg, elevation_deg, explode, title, schedule).image.save(path)
    return path


def chunk_picture(chunks: ChunkSet, size: tuple[int, int] = (1200, 800),
                  azimuth_deg: float = -35.0, elevation_deg: float = 22.0,
                  explode: float = 0.025, title: str | None = None,
                  schedule: "Assignment | None" = None) -> ChunkPicture:
    """Draw ``chunks``.

    Parameters
    ----------
    size
        Image width and height, pixels (the height grows by the lines of a long robot legend).
    azimuth_deg, elevation_deg
        Camera direction (from +X towards +Y, and above the horizon).
    explode
        Gap between neighbouring chunks as a fraction of the object's extent along the axis
        (seed2), or of their distance from the object's centre (other layouts, times
        ``RADIAL_EXPLODE``).
    schedule
        An :class:`~cooprint.scheduling.Assignment` (or ``Schedule``): every chunk is drawn in
        its robot's colour (:func:`~cooprint.render.palette.robot_colours` of the robots in the
        order of ``sequences``, which is the plan's robot order: job.json's "robots" and the
        simulation's robots are listed in it) and labelled with the robot and its place in that
        robot's order, from 1, after the chunk's id as the Gantt chart and the viewer name it
        ("R1 · B3"; the id alone where the chunk is too small for that), and a legend names the
        robots in that order. Without it,
        chunks are coloured by side and labelled with their ids. Each label lies wholly on its
        own chunk's visible pixels, as far inside as it fits, smaller (down to
        ``MIN_LABEL_SIZE``) where the chunk is small; labels that fit nowhere are left out and
        named in a footnote.
    """
    plan = chunks.plan
    axis = np.asarray(plan.axis)
    basis = _view_basis(azimuth_deg, elevation_deg)
    all_v = np.vstack([c.vertices for c in chunks.chunks])
    extent = float(np.ptp(all_v @ axis)) or 1.0
    diag = float(np.linalg.norm(np.ptp(all_v, axis=0))) or 1.0
    total_tris = sum(len(c.faces) for c in chunks.chunks)
    keep_every = max(1, math.ceil(total_tris / MAX_TRIANGLES))
    light = basis[2] * 0.6 + np.array([0.3, -0.2, 0.75])
    light /= np.linalg.norm(light)
    seed2 = chunks.layout == "seed2" and all(c.role in ("centre", "left", "right") for c in chunks.chunks)
    centre = (all_v.min(axis=0) + all_v.max(axis=0)) / 2
    robots = list(schedule.sequences) if schedule is not None else []
    colours = robot_colours(robots)
    # a subdivided triangle is about a fifteenth of the object's diagonal: over 200 chunks, the
    # budget for the whole picture is shared (each chunk its part) so that drawing stays fast
    budget = max(2_000, 120_000 // max(1, len(chunks.chunks) // 8))

    polys, fills, owner, labels = [], [], [], []
    mids = np.array([(c.vertices.min(axis=0) + c.vertices.max(axis=0)) / 2 for c in chunks.chunks])
    if seed2:
        sgn = np.array([{"centre": 0.0, "left": -1.0, "right": 1.0}[c.role] * c.index for c in chunks.chunks])
        shifts = sgn[:, None] * axis * explode * extent
        draw_order = _draw_order(chunks, basis[2])
    else:  # pulled apart, the chunks of a grid are separated by planes: far-to-near by their centres
        shifts = (mids - centre) * np.array([1.0, 1.0, 0.0]) * RADIAL_EXPLODE * explode
        draw_order = np.argsort((mids + shifts) @ basis[2], kind="stable").tolist()
    for i in draw_order:
        ch = chunks.chunks[i]
        shift = shifts[i]
        faces = ch.faces
        if keep_every > 1:  # keep the biggest triangles: they carry the silhouette and shading
            e1 = ch.vertices[faces[:, 1]] - ch.vertices[faces[:, 0]]
            e2 = ch.vertices[faces[:, 2]] - ch.vertices[faces[:, 0]]
            area = np.linalg.norm(np.cross(e1, e2), axis=1)
            faces = faces[np.argsort(area)[::-1][: max(len(faces) // keep_every, 1)]]
        tri = ch.vertices[faces] + shift
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        nlen = np.linalg.norm(normals, axis=1)
        facing = (nlen > 0) & (normals @ basis[2] > 0)
        tri, normals = tri[facing], normals[facing] / nlen[facing, None]
        shade = 0.35 + 0.65 * np.clip(normals @ light, 0.0, 1.0)
        tri = np.concatenate([tri, shade[:, None, None].repeat(3, axis=1)], axis=2)  # carry shade along
        tri = _subdivide_shaded(tri, diag / 15, budget=budget)
        proj = tri[:, :, :3] @ basis.T
        depth = proj[:, :, 2].mean(axis=1)
        order = np.argsort(depth, kind="stable")  # far (small depth) first
        robot = _robot_of(schedule, ch.id)
        if robot is not None:
            colour = np.asarray(colours[robot], dtype=np.float64)
            text = f"{ch.id} · {order_label(robot, schedule.order_of(ch.id))}"  # type: ignore[union-attr]
        elif schedule is not None:  # a chunk no robot prints: grey, by its id
            colour, text = np.asarray(UNASSIGNED_COLOUR, dtype=np.float64), ch.id
        else:
            robot, colour, text = None, np.asarray(chunk_colour(ch.role, ch.index), dtype=np.float64), ch.id
        polys.append(proj[order, :, :2])
        fills.append(np.clip(colour * tri[order, 0, 3:4], 0, 255).astype(np.uint8))
        owner.append(np.full(len(order), i, dtype=np.int32))
        labels.append((i, text, robot))

    all_polys = np.concatenate(polys) if polys else np.zeros((0, 3, 2))
    all_fills = np.concatenate(fills) if fills else np.zeros((0, 3), np.uint8)

    w, h = size
    margin = 40
    font = _font(16)
    legend = _legend_lines(robots, schedule, w - 2 * margin, font) if schedule is not None else []
    top = 70 + 26 * len(legend)
    if legend and size[1] - top - margin < 0.6 * (size[1] - 70 - margin):  # a long legend: a taller picture
        h = size[1] + 26 * len(legend)
    xy = all_polys.reshape(-1, 2)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    scale = min((w - 2 * margin) / max(hi[0] - lo[0], 1e-9), (h - margin - top) / max(hi[1] - lo[1], 1e-9))
    off = np.array([(w - scale * (hi[0] - lo[0])) / 2, top + (h - top - margin - scale * (hi[1] - lo[1])) / 2])

    def to_px(p: np.ndarray) -> np.ndarray:
        q = (p - lo) * scale
        q[..., 1] = scale * (hi[1] - lo[1]) - q[..., 1]
        return q + off

    # the triangles drawn as their numbers from 1 (0: nothing), far to near, then coloured by number
    drawn = Image.new("I", (w, h), 0)
    ink = ImageDraw.Draw(drawn)
    for k, p in enumerate(to_px(all_polys).round(1).tolist(), start=1):
        ink.polygon([tuple(q) for q in p], fill=k, outline=k)
    tri_id = np.asarray(drawn)
    rgb = np.vstack([np.asarray(BACKGROUND, np.uint8)[None], all_fills])
    ids = np.concatenate([[-1], np.concatenate(owner) if owner else np.zeros(0, np.int32)]).astype(np.int32)[tri_id]
    img = Image.fromarray(rgb[tri_id], "RGB")
    draw = ImageDraw.Draw(img)

    n = len(chunks.chunks)
    first = next(size_ for most, size_ in LABEL_SIZES if n <= most)
    boxes = _chunk_boxes(ids, n)
    placed: list[tuple[str, str, tuple[int, int, int, int]]] = []
    left_out: list[str] = []
    for i, text, robot in sorted(labels, key=lambda lab: lab[0]):  # in the chunks' order
        spot = _label_spot(draw, ids, i, boxes[i], text, first) if boxes[i] is not None else None
        cid = chunks.chunks[i].id
        if spot is None and text != cid and boxes[i] is not None:  # too small for "R1 · B3": "R1" alone
            text, spot = cid, _label_spot(draw, ids, i, boxes[i], cid, first)
        if spot is None:
            left_out.append(text)
            continue
        at, label_font, pad, frame = spot
        placed.append((chunks.chunks[i].id, text, frame))
        edge = colours[robot] if robot is not None else (60, 60, 60)
        draw.rectangle(frame, fill=(255, 255, 255), outline=edge, width=2 if robot is not None and pad > 2 else 1)
        draw.text(at, text, fill=(20, 20, 20), font=label_font, anchor="mm")
    if left_out:
        _footnote(draw, left_out, margin, w - 2 * margin, h - 28)
    if title is None:
        title = (f"{_count(n, 'chunk')}   theta {plan.theta_deg:.1f} deg   shift {plan.shift:.1f} mm"
                 f"   centre base {2 * plan.half_base:.1f} mm   build depth {plan.build_depth:g} mm")
        if schedule is not None:
            title = schedule_title(n, len(robots), schedule)
    draw.text((margin, 24), title, fill=(20, 20, 20), font=_font(20))
    for j, line in enumerate(legend):
        for x, robot, text in line:
            y = 58 + 26 * j
            draw.rectangle([x, y, x + 16, y + 16], fill=colours[robot])
            draw.text((x + 22, y - 1), text, fill=(40, 40, 40), font=font)
    return ChunkPicture(img, ids, placed, left_out)


def schedule_title(chunks: int, robots: int, schedule: "Assignment") -> str:
    """The chunk picture's title with a schedule: the counts, the strategy and, when the schedule
    has one, its makespan and lower bound as the Gantt chart writes times (``0:00:43``,
    ``2 d 11:12:52``), not in hours (a 43 s plan was "0.01 h")."""
    from cooprint.render.sim import _hms  # the Gantt chart's clock (sim.py draws on this module)

    return f"{_count(chunks, 'chunk')}, {_count(robots, 'robot')}, schedule {schedule.strategy}" + (
        f", makespan {_hms(schedule.makespan)} (LB {_hms(schedule.lower_bound)})"
        if getattr(schedule, "makespan", 0.0) else "")


def _label_spot(draw: ImageDraw.ImageDraw, ids: np.ndarray, i: int, box: tuple[int, int, int, int], text: str,
                first: int) -> tuple[tuple[int, int], ImageFont.ImageFont | ImageFont.FreeTypeFont, int,
                                     tuple[int, int, int, int]] | None:
    """Where chunk ``i``'s label ``text`` goes: at the largest font size from ``first`` down to
    ``MIN_LABEL_SIZE`` whose framed text lies wholly on the chunk's visible pixels (``ids == i``
    in ``box``, its pixels' box), as far inside as it can (:func:`_inside`). Returns the text's
    centre, the font, the frame's padding and the frame ``(x0, y0, x1, y1)`` (inclusive), or None."""
    x0, y0, x1, y1 = box
    mask = ids[y0:y1 + 1, x0:x1 + 1] == i
    for size in range(first, MIN_LABEL_SIZE - 1, -2):
        font, pad = _font(size), 4 if size >= 14 else 2
        l, t, r, b = draw.textbbox((0, 0), text, font=font, anchor="mm")
        rel = (l - pad, t - pad + 1, r + pad, b + pad - 1)  # the frame around the text centred at (0, 0)
        corner = _inside(mask, rel[2] - rel[0] + 1, rel[3] - rel[1] + 1)
        if corner is not None:
            fx, fy = x0 + corner[0], y0 + corner[1]
            return (fx - rel[0], fy - rel[1]), font, pad, (fx, fy, fx + rel[2] - rel[0], fy + rel[3] - rel[1])
    return None


def _chunk_boxes(ids: np.ndarray, n: int) -> list[tuple[int, int, int, int] | None]:
    """Each chunk's box of visible pixels ``(x0, y0, x1, y1)``, inclusive; None for a hidden chunk."""
    ys, xs = np.nonzero(ids >= 0)
    which = ids[ys, xs]
    out: list[tuple[int, int, int, int] | None] = [None] * n
    order = np.argsort(which, kind="stable")
    which, ys, xs = which[order], ys[order], xs[order]
    starts = np.flatnonzero(np.r_[True, which[1:] != which[:-1]]) if len(which) else np.zeros(0, int)
    for a, b in zip(starts, np.r_[starts[1:], len(which)]):
        out[int(which[a])] = (int(xs[a:b].min()), int(ys[a:b].min()), int(xs[a:b].max()), int(ys[a:b].max()))
    return out


def _inside(mask: np.ndarray, bw: int, bh: int) -> tuple[int, int] | None:
    """The top-left corner ``(x, y)`` of a ``bw`` x ``bh`` box lying wholly on ``mask``'s True
    pixels, as far inside as can be: the box still fits grown by the largest margin ``m`` on
    every side, and of the places where it does, the one nearest their mean. None if it fits
    nowhere. Box sums on a summed-area table, the margin by bisection."""
    height, width = mask.shape
    sat = np.zeros((height + 1, width + 1), np.int32)
    sat[1:, 1:] = mask.cumsum(axis=0, dtype=np.int32).cumsum(axis=1, dtype=np.int32)

    def fits(m: int) -> np.ndarray | None:
        bx, by = bw + 2 * m, bh + 2 * m
        if bx > width or by > height:
            return None
        full = sat[by:, bx:] - sat[:-by, bx:] - sat[by:, :-bx] + sat[:-by, :-bx] == bx * by
        return full if full.any() else None

    best = fits(0)
    if best is None:
        return None
    m, top = 0, (min(width - bw, height - bh)) // 2 + 1  # fits(m) holds, fits(top) does not
    while top - m > 1:
        mid = (m + top) // 2
        grown = fits(mid)
        if grown is None:
            top = mid
        else:
            m, best = mid, grown
    ys, xs = np.nonzero(best)
    k = int(np.argmin((xs - xs.mean()) ** 2 + (ys - ys.mean()) ** 2))
    return int(xs[k]) + m, int(ys[k]) + m


def _footnote(draw: ImageDraw.ImageDraw, texts: list[str], x: float, width: float, y: float) -> None:
    """"labels left out: A3, B7, ..." at ``(x, y)``, cut to ``width`` pixels with the count of the rest."""
    font = _font(14)
    line = "labels left out (chunks too small in the picture): "
    for k, text in enumerate(texts):
        more = f" ... ({len(texts)} in all)"
        candidate = line + (", " if k else "") + text
        if draw.textlength(candidate + (more if k < len(texts) - 1 else ""), font=font) > width:
            line += more
            break
        line = candidate
    draw.text((x, y), line, fill=(90, 90, 90), font=font)


def _count(k: int, thing: str) -> str:
    """"1 chunk", "3 chunks"."""
    return f"{k} {thing}{'s' if k != 1 else ''}"


def _legend_lines(robots: list[str], schedule: "Assignment", width: float,
                  font: ImageFont.ImageFont | ImageFont.FreeTypeFont) -> list[list[tuple[float, str, str]]]:
    """The robot legend, wrapped into lines of at most ``width`` pixels: per line ``(x offset
    from the margin, robot, text)``; each entry a swatch and "A: 5 chunks" (few robots) or the
    name alone (over 12)."""
    probe = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    lines: list[list[tuple[float, str, str]]] = [[]]
    x = 0.0
    for r in robots:
        k = len(schedule.sequences[r])
        text = f"robot {r}: {_count(k, 'chunk')}" if len(robots) <= 12 else r
        step = 22 + probe.textlength(text, font=font) + 18
        if lines[-1] and x + step > width:
            lines.append([])
            x = 0.0
        lines[-1].append((40 + x, r, text))
        x += step
    return lines if lines[0] else []
