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
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from cooprint.chunking import ChunkSet
from cooprint.render.palette import robot_colour

if TYPE_CHECKING:
    from cooprint.scheduling import Assignment

CENTRE_COLOUR = (242, 197, 49)
LEFT_COLOURS = [(64, 120, 200), (110, 160, 225), (40, 90, 160), (140, 190, 240)]
RIGHT_COLOURS = [(200, 80, 70), (230, 130, 110), (160, 55, 50), (240, 160, 140)]
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
#: Label font sizes by the number of chunks: fewer chunks, larger labels.
LABEL_SIZES = ((20, 18), (80, 14), (10**9, 11))


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


def render_chunks(chunks: ChunkSet, path: str | Path, size: tuple[int, int] = (1200, 800),
                  azimuth_deg: float = -35.0, elevation_deg: float = 22.0,
                  explode: float = 0.025, title: str | None = None,
                  schedule: "Assignment | None" = None) -> Path:
    """Draw ``chunks`` to a PNG at ``path``.

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
        its robot's colour (:func:`~cooprint.render.palette.robot_colour`, by the robot's place
        in ``sequences``) and labelled with the robot and its place in that robot's order, from
        1 ("B3"), and a legend names the robots. Without it, chunks are coloured by side and
        labelled with their ids. Labels that would overlap one already drawn are left out
        (larger chunks first), and get smaller the more chunks there are, so 200+ chunks stay
        readable.
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
    # a subdivided triangle is about a fifteenth of the object's diagonal: over 200 chunks, the
    # budget for the whole picture is shared (each chunk its part) so that drawing stays fast
    budget = max(2_000, 120_000 // max(1, len(chunks.chunks) // 8))

    polys, fills, labels = [], [], []
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
            colour = np.asarray(robot_colour(robots.index(robot)), dtype=np.float64)
            text = order_label(robot, schedule.order_of(ch.id))  # type: ignore[union-attr]
        elif schedule is not None:  # a chunk no robot prints: grey, by its id
            colour, text = np.asarray(UNASSIGNED_COLOUR, dtype=np.float64), ch.id
        else:
            robot, colour, text = None, np.asarray(chunk_colour(ch.role, ch.index), dtype=np.float64), ch.id
        polys.append(proj[order, :, :2])
        fills.append(np.clip(colour * tri[order, 0, 3:4], 0, 255).astype(np.uint8))
        ztop = ch.vertices[:, 2].max()
        top = ch.vertices[ch.vertices[:, 2] >= ztop - 0.02 * (ztop - ch.vertices[:, 2].min())]
        labels.append((text, top.mean(axis=0) + shift, robot, ch.volume))  # on the chunk's top: visible from above

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

    img = Image.new("RGB", (w, h), BACKGROUND)
    draw = ImageDraw.Draw(img)
    for p, f in zip(to_px(all_polys).round(1).tolist(), all_fills.tolist()):
        f = tuple(f)
        draw.polygon([tuple(q) for q in p], fill=f, outline=f)

    n = len(chunks.chunks)
    label_font = _font(next(size_ for most, size_ in LABEL_SIZES if n <= most))
    pad = 4 if n <= 80 else 2
    placed: list[tuple[float, float, float, float]] = []
    for k in sorted(range(len(labels)), key=lambda k: -labels[k][3]):  # larger chunks first
        text, centroid, robot, _ = labels[k]
        x, y = to_px((centroid @ basis.T)[:2])
        y -= 16 if n <= 80 else 8
        box = draw.textbbox((x, y), text, font=label_font, anchor="mm")
        frame = (box[0] - pad, box[1] - pad + 1, box[2] + pad, box[3] + pad - 1)
        if any(frame[0] < b[2] and b[0] < frame[2] and frame[1] < b[3] and b[1] < frame[3] for b in placed):
            continue  # would cover a label already drawn
        placed.append(frame)
        edge = robot_colour(robots.index(robot)) if robot is not None else (60, 60, 60)
        draw.rectangle(frame, fill=(255, 255, 255), outline=edge, width=2 if robot is not None else 1)
        draw.text((x, y), text, fill=(20, 20, 20), font=label_font, anchor="mm")
    if title is None:
        title = (f"{n} chunks   theta {plan.theta_deg:.1f} deg   shift {plan.shift:.1f} mm"
                 f"   centre base {2 * plan.half_base:.1f} mm   build depth {plan.build_depth:g} mm")
        if schedule is not None:
            title = f"{n} chunks, {len(robots)} robots, schedule {schedule.strategy}" + (
                f", makespan {schedule.makespan / 3600:.2f} h (LB {schedule.lower_bound / 3600:.2f} h)"
                if getattr(schedule, "makespan", 0.0) else "")
    draw.text((margin, 24), title, fill=(20, 20, 20), font=_font(20))
    for j, line in enumerate(legend):
        for x, robot, text in line:
            y = 58 + 26 * j
            draw.rectangle([x, y, x + 16, y + 16], fill=robot_colour(robots.index(robot)))
            draw.text((x + 22, y - 1), text, fill=(40, 40, 40), font=font)
    path = Path(path)
    img.save(path)
    return path


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
        text = f"robot {r}: {k} chunk{'s' if k != 1 else ''}" if len(robots) <= 12 else r
        step = 22 + probe.textlength(text, font=font) + 18
        if lines[-1] and x + step > width:
            lines.append([])
            x = 0.0
        lines[-1].append((40 + x, r, text))
        x += step
    return lines if lines[0] else []
