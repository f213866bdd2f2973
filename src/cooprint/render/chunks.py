"""Picture of a chunked object, like the seed's Fig. 5: chunks in 3D, centre chunk yellow.

A small orthographic painter's renderer on numpy + Pillow: project all triangles once, cull back
faces, shade by the angle to the light, sort far-to-near, draw. Chunks are pulled apart along the
chunking axis by a small gap so each one reads as its own solid.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from cooprint.chunking import ChunkSet

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


def render_chunks(chunks: ChunkSet, path: str | Path, size: tuple[int, int] = (1200, 800),
                  azimuth_deg: float = -35.0, elevation_deg: float = 22.0,
                  explode: float = 0.025, title: str | None = None) -> Path:
    """Draw ``chunks`` to a PNG at ``path``.

    Parameters
    ----------
    size
        Image width and height, pixels.
    azimuth_deg, elevation_deg
        Camera direction (from +X towards +Y, and above the horizon).
    explode
        Gap between neighbouring chunks as a fraction of the object's extent along the axis.
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

    polys, fills, labels = [], [], []
    for i in _draw_order(chunks, basis[2]):
        ch = chunks.chunks[i]
        sgn = {"centre": 0.0, "left": -1.0, "right": 1.0}[ch.role]
        shift = axis * sgn * ch.index * explode * extent
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
        tri = _subdivide_shaded(tri, diag / 15)
        proj = tri[:, :, :3] @ basis.T
        order = np.argsort(proj[:, :, 2].mean(axis=1), kind="stable")  # far (small depth) first
        colour = np.asarray(chunk_colour(ch.role, ch.index), dtype=np.float64)
        polys.append(proj[order, :, :2])
        fills.append(np.clip(colour * tri[order, 0, 3:4], 0, 255).astype(np.uint8))
        ztop = ch.vertices[:, 2].max()
        top = ch.vertices[ch.vertices[:, 2] >= ztop - 0.02 * (ztop - ch.vertices[:, 2].min())]
        labels.append((ch.id, top.mean(axis=0) + shift))  # on the chunk's top: visible from above

    w, h = size
    margin, top = 40, 70
    xy = np.concatenate(polys).reshape(-1, 2)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    scale = min((w - 2 * margin) / max(hi[0] - lo[0], 1e-9), (h - margin - top) / max(hi[1] - lo[1], 1e-9))
    off = np.array([(w - scale * (hi[0] - lo[0])) / 2, top + (h - top - margin - scale * (hi[1] - lo[1])) / 2])

    def to_px(p: np.ndarray) -> np.ndarray:
        q = (p - lo) * scale
        q[..., 1] = scale * (hi[1] - lo[1]) - q[..., 1]
        return q + off

    img = Image.new("RGB", size, BACKGROUND)
    draw = ImageDraw.Draw(img)
    for poly, fill in zip(polys, fills):
        for p, f in zip(to_px(poly).round(1).tolist(), fill.tolist()):
            draw.polygon([tuple(q) for q in p], fill=tuple(f), outline=tuple(f))

    font = _font(18)
    for cid, centroid in labels:
        x, y = to_px((centroid @ basis.T)[:2])
        y -= 16
        box = draw.textbbox((x, y), cid, font=font, anchor="mm")
        draw.rectangle((box[0] - 4, box[1] - 3, box[2] + 4, box[3] + 3), fill=(255, 255, 255),
                       outline=(60, 60, 60))
        draw.text((x, y), cid, fill=(20, 20, 20), font=font, anchor="mm")
    if title is None:
        title = (f"{len(chunks.chunks)} chunks   theta {plan.theta_deg:.1f} deg   shift {plan.shift:.1f} mm"
                 f"   centre base {2 * plan.half_base:.1f} mm   build depth {plan.build_depth:g} mm")
    draw.text((margin, 24), title, fill=(20, 20, 20), font=_font(20))
    path = Path(path)
    img.save(path)
    return path
