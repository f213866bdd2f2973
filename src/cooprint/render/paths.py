"""Pictures of tool paths, like the seed's Fig. 7 and 9: one layer from above, roles coloured,
and a whole sliced model in 3D. Pillow lines on numpy-projected segments."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
from PIL import Image, ImageDraw

from cooprint.render.chunks import BACKGROUND, _font, _view_basis
from cooprint.slicing.paths import (BRIDGE, GAP_FILL, INFILL, OVERHANG, PERIMETER_INNER, PERIMETER_OUTER,
                                    ROLE_NAMES, SKIN, TOP_SKIN, TRAVEL, LayerPaths)

#: One colour per path role (near PrusaSlicer's preview legend: walls warm, solid fills purple and
#: red, sparse infill dark red, bridges blue, gap fill white-grey).
ROLE_COLOURS = {PERIMETER_OUTER: (255, 125, 56), PERIMETER_INNER: (255, 230, 77), SKIN: (150, 84, 204),
                INFILL: (176, 48, 41), TRAVEL: (170, 170, 170), TOP_SKIN: (240, 64, 64), BRIDGE: (77, 128, 186),
                GAP_FILL: (120, 120, 120), OVERHANG: (0, 0, 255)}


def _segments(layer: LayerPaths) -> tuple[np.ndarray, np.ndarray]:
    """All segments of a layer (k, 2, 3) and their roles (k,), travel included."""
    pts = layer.points
    seg_path = np.repeat(np.arange(len(layer)), np.diff(layer.offsets))
    same = seg_path[1:] == seg_path[:-1]
    a, b = pts[:-1][same], pts[1:][same]
    zz = np.full((len(a), 1), layer.z)
    seg = np.stack([np.hstack([a, zz]), np.hstack([b, zz])], axis=1)
    return seg, layer.role[seg_path[:-1][same]]


def _fit(xy: np.ndarray, size: tuple[int, int], margin: int, top: int) -> tuple[np.ndarray, float, np.ndarray]:
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    w, h = size
    scale = min((w - 2 * margin) / max(hi[0] - lo[0], 1e-9), (h - margin - top) / max(hi[1] - lo[1], 1e-9))
    off = np.array([(w - scale * (hi[0] - lo[0])) / 2, top + (h - top - margin - scale * (hi[1] - lo[1])) / 2])
    return lo, scale, off + np.array([0.0, scale * (hi[1] - lo[1])])


def _legend(draw: ImageDraw.ImageDraw, roles: Sequence[int], x: int, y: int) -> None:
    font = _font(16)
    for role in roles:
        draw.line([(x, y + 8), (x + 30, y + 8)], fill=ROLE_COLOURS[role], width=4)
        draw.text((x + 38, y), ROLE_NAMES[role], fill=(30, 30, 30), font=font)
        x += 60 + int(draw.textlength(ROLE_NAMES[role], font=font))


def render_layer(layer: LayerPaths, path: str | Path, size: tuple[int, int] = (900, 900),
                 title: str = "", travel: bool = True) -> Path:
    """One layer seen from above, each role in its colour (Fig. 7d)."""
    seg, role = _segments(layer)
    if not travel:
        seg, role = seg[role != TRAVEL], role[role != TRAVEL]
    img = Image.new("RGB", size, BACKGROUND)
    draw = ImageDraw.Draw(img)
    if len(seg):
        lo, scale, off = _fit(seg[:, :, :2].reshape(-1, 2), size, 40, 80)
        px = (seg[:, :, :2] - lo) * scale * np.array([1, -1]) + off
        width = max(1, int(round(float(layer.width.max(initial=0.45)) * scale)))
        for r in (TRAVEL, INFILL, SKIN, TOP_SKIN, BRIDGE, GAP_FILL, PERIMETER_INNER, PERIMETER_OUTER, OVERHANG):
            lines = px[role == r].round(1).tolist()
            for (x0, y0), (x1, y1) in lines:
                draw.line([(x0, y0), (x1, y1)], fill=ROLE_COLOURS[r], width=1 if r == TRAVEL else width)
    draw.text((40, 20), title or f"layer at z = {layer.z:.2f} mm", fill=(20, 20, 20), font=_font(20))
    _legend(draw, [r for r in (PERIMETER_OUTER, PERIMETER_INNER, SKIN, INFILL, TRAVEL) if r in set(role.tolist())],
            40, 50)
    path = Path(path)
    img.save(path)
    return path


def render_model(layers: Sequence[LayerPaths], path: str | Path, size: tuple[int, int] = (1200, 800),
                 azimuth_deg: float = -35.0, elevation_deg: float = 25.0, title: str = "",
                 max_segments: int = 400_000) -> Path:
    """All extrusions of a sliced model in 3D, each role in its colour, far-to-near (Fig. 9)."""
    parts = [_segments(layer) for layer in layers]
    seg = np.concatenate([p[0] for p in parts]) if parts else np.zeros((0, 2, 3))
    role = np.concatenate([p[1] for p in parts]) if parts else np.zeros(0, dtype=np.uint8)
    keep = role != TRAVEL
    seg, role = seg[keep], role[keep]
    if len(seg) > max_segments:  # thin evenly: the picture keeps its look
        pick = np.linspace(0, len(seg) - 1, max_segments).astype(np.int64)
        seg, role = seg[pick], role[pick]
    basis = _view_basis(azimuth_deg, elevation_deg)
    proj = seg @ basis.T
    order = np.argsort(proj[:, :, 2].mean(axis=1), kind="stable")
    img = Image.new("RGB", size, BACKGROUND)
    draw = ImageDraw.Draw(img)
    if len(seg):
        lo, scale, off = _fit(proj[:, :, :2].reshape(-1, 2), size, 40, 80)
        px = (proj[order, :, :2] - lo) * scale * np.array([1, -1]) + off
        depth = proj[order, :, 2].mean(axis=1)
        shade = 0.6 + 0.4 * (depth - depth.min()) / max(float(np.ptp(depth)), 1e-9)
        colours = (np.array([ROLE_COLOURS[int(r)] for r in range(len(ROLE_NAMES))])[role[order]] * shade[:, None]).astype(int)
        for ((x0, y0), (x1, y1)), c in zip(px.round(1).tolist(), colours.tolist()):
            draw.line([(x0, y0), (x1, y1)], fill=tuple(c), width=1)
    n = len(layers)
    draw.text((40, 20), title or f"{n} layers", fill=(20, 20, 20), font=_font(20))
    _legend(draw, [PERIMETER_OUTER, PERIMETER_INNER, SKIN, INFILL], 40, 50)
    path = Path(path)
    img.save(path)
    return path


