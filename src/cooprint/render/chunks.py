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
    all_v = np.vstack([c.vertices for c in chunks.chunks])
    extent = float(np.ptp(all_v @ axis)) or 1.0
    total_tris = sum(len(c.faces) for c in chunks.chunks)
    keep_every = max(1, math.ceil(total_tris / MAX_TRIANGLES))

    tris, colours, labels = [], [], []
    for ch in chunks.chunks:
        sgn = {"centre": 0.0, "left": -1.0, "right": 1.0}[ch.role]
        shift = axis * sgn * ch.index * explode * extent
        faces = ch.faces
        if keep_every > 1:  # keep the biggest triangles: they carry the silhouette and shading
            area = np.linalg.norm(np.cross(*(ch.vertices[faces[:, 1:]] - ch.vertices[faces[:, :1]])
                                           .transpose(1, 0, 2)), axis=1)
            faces = faces[np.argsort(area)[::-1][: max(len(faces) // keep_every, 1)]]
        t = ch.vertices[faces] + shift
        tris.append(t)
        colours.append(np.tile(chunk_colour(ch.role, ch.index), (len(t), 1)))
        labels.append((ch.id, ch.vertices.mean(axis=0) + shift))
    tri = np.concatenate(tris)
    col = np.concatenate(colours).astype(np.float64)

    basis = _view_basis(azimuth_deg, elevation_deg)
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nlen = np.linalg.norm(normals, axis=1)
    ok = nlen > 0
    normals[ok] /= nlen[ok, None]
    facing = (normals @ basis[2] > 0) & ok
    tri, col, normals = tri[facing], col[facing], normals[facing]

    light = basis[2] * 0.6 + np.array([0.3, -0.2, 0.75])
    light /= np.linalg.norm(light)
    shade = 0.35 + 0.65 * np.clip(normals @ light, 0.0, 1.0)
    rgb = np.clip(col * shade[:, None], 0, 255).astype(np.uint8)

    proj = tri @ basis.T  # (n, 3, 3): screen x, screen y, depth
    order = np.argsort(proj[:, :, 2].mean(axis=1))  # far (small depth) first
    w, h = size
    margin, top = 40, 70
    xy = proj[:, :, :2].reshape(-1, 2)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    scale = min((w - 2 * margin) / max(hi[0] - lo[0], 1e-9), (h - margin - top) / max(hi[1] - lo[1], 1e-9))
    off = np.array([(w - scale * (hi[0] - lo[0])) / 2, top + (h - top - margin - scale * (hi[1] - lo[1])) / 2])
    px = (proj[:, :, :2] - lo) * scale
    px[:, :, 1] = scale * (hi[1] - lo[1]) - px[:, :, 1]
    px += off

    img = Image.new("RGB", size, BACKGROUND)
    draw = ImageDraw.Draw(img)
    pts = px[order].round(1).tolist()
    fills = [tuple(c) for c in rgb[order].tolist()]
    for p, f in zip(pts, fills):
        draw.polygon([tuple(q) for q in p], fill=f)

    font = _font(18)
    for cid, centroid in labels:
        anchor = centroid @ basis.T
        x = (anchor[0] - lo[0]) * scale + off[0]
        y = scale * (hi[1] - lo[1]) - (anchor[1] - lo[1]) * scale + off[1]
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
