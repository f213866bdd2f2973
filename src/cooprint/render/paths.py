"""Pictures of tool paths, like the seed's Fig. 7 and 9: one layer from above, roles coloured,
and a whole sliced model in 3D. Pillow lines on numpy-projected segments."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from cooprint.render.chunks import BACKGROUND, _font, _view_basis
from cooprint.slicing.paths import (BRIDGE, GAP_FILL, INFILL, OVERHANG, PERIMETER_INNER, PERIMETER_OUTER,
                                    ROLE_NAMES, SKIN, TOP_SKIN, TRAVEL, LayerPaths)

#: One colour per path role, PrusaSlicer's preview legend's made readable on the pictures' light
#: background: walls warm (outer orange, inner a deeper yellow than PrusaSlicer's, which is for a
#: dark background), overhang perimeters blue, solid infill purple, top solid infill red, sparse
#: infill a darker red than PrusaSlicer's (apart from the top's), bridges steel blue, gap fill dark
#: grey (PrusaSlicer's white, inverted for a light background; travel is a thin light grey). Every
#: two at least 29 apart in CIELAB, every wall and fill at least 1.8:1 against the background
#: (tests/test_render_paths.py).
ROLE_COLOURS = {PERIMETER_OUTER: (255, 125, 56), PERIMETER_INNER: (230, 180, 0), SKIN: (150, 84, 204),
                INFILL: (130, 30, 25), TRAVEL: (170, 170, 170), TOP_SKIN: (240, 64, 64), BRIDGE: (77, 128, 186),
                GAP_FILL: (60, 60, 60), OVERHANG: (0, 0, 255)}
#: The order of the legends (PrusaSlicer's: walls, then fills, then travel).
LEGEND_ORDER = (PERIMETER_INNER, PERIMETER_OUTER, OVERHANG, INFILL, SKIN, TOP_SKIN, BRIDGE, GAP_FILL, TRAVEL)
#: The order roles are drawn in (later on top: walls over fills, travel under everything).
DRAW_ORDER = (TRAVEL, INFILL, SKIN, TOP_SKIN, BRIDGE, GAP_FILL, PERIMETER_INNER, PERIMETER_OUTER, OVERHANG)


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
    scale = min(max(w - 2 * margin, 1) / max(hi[0] - lo[0], 1e-9), max(h - margin - top, 1) / max(hi[1] - lo[1], 1e-9))
    off = np.array([(w - scale * (hi[0] - lo[0])) / 2, top + (h - top - margin - scale * (hi[1] - lo[1])) / 2])
    return lo, scale, off + np.array([0.0, scale * (hi[1] - lo[1])])


@dataclass(frozen=True)
class Legend:
    """Where a picture's title and legend go, measured with the picture's fonts: the title's
    place, each entry (role, swatch box, text position) and its whole box (swatch and text),
    and the first row free below them (``bottom``), where the drawing may start."""

    title_font: ImageFont.ImageFont | ImageFont.FreeTypeFont
    font: ImageFont.ImageFont | ImageFont.FreeTypeFont
    title_at: tuple[int, int]
    entries: tuple[tuple[int, tuple[int, int, int, int], tuple[int, int]], ...]
    boxes: tuple[tuple[int, int, int, int], ...]
    bottom: int


def legend_layout(draw: ImageDraw.ImageDraw, roles: Sequence[int], size: tuple[int, int], title: str) -> Legend:
    """The title and a legend of ``roles`` (each once, in :data:`LEGEND_ORDER`) laid out in rows
    across a picture of ``size``: each entry a swatch and the role's name, as wide as its text
    measures; an entry that would cross the right margin starts the next row, so entries never
    overlap or leave the picture (fonts scale down with small pictures; an entry wider than the
    picture has a row of its own)."""
    w, h = size
    scale = max(0.5, min(1.0, min(w, h) / 700))
    title_font, font = _font(max(9, round(20 * scale))), _font(max(8, round(16 * scale)))
    x0, y = min(40, max(2, w // 25)), max(2, round(20 * scale))
    title_at = (x0, y)
    y += draw.textbbox((0, 0), title or "Ag", font=title_font)[3] + max(4, round(10 * scale))
    box_h = draw.textbbox((0, 0), "Ag", font=font)[3]
    swatch, gap = max(12, round(30 * scale)), max(4, round(8 * scale))
    x, entries, boxes, row_bottom = x0, [], [], y
    for role in [r for r in LEGEND_ORDER if r in set(int(r) for r in roles)]:
        width = swatch + gap + int(np.ceil(draw.textlength(ROLE_NAMES[role], font=font)))
        if x > x0 and x + width > w - x0:  # the next row
            x, y = x0, row_bottom + gap
        mid = y + box_h // 2
        entries.append((role, (x, mid - 2, x + swatch, mid + 2), (x + swatch + gap, y)))
        boxes.append((x, y, x + width, y + box_h))
        row_bottom = max(row_bottom, y + box_h)
        x += width + 3 * gap
    return Legend(title_font, font, title_at, tuple(entries), tuple(boxes), row_bottom + max(6, round(14 * scale)))


def _draw_legend(draw: ImageDraw.ImageDraw, legend: Legend, title: str) -> None:
    """The title and the legend where :func:`legend_layout` put them."""
    draw.text(legend.title_at, title, fill=(20, 20, 20), font=legend.title_font)
    for role, swatch, at in legend.entries:
        draw.rectangle(swatch, fill=ROLE_COLOURS[role])
        draw.text(at, ROLE_NAMES[role], fill=(30, 30, 30), font=legend.font)


def render_layer(layer: LayerPaths, path: str | Path, size: tuple[int, int] = (900, 900),
                 title: str = "", travel: bool = True) -> Path:
    """One layer seen from above, each role in its colour, with a legend of the roles drawn
    (Fig. 7d; PrusaSlicer's preview legend)."""
    seg, role = _segments(layer)
    if not travel:
        seg, role = seg[role != TRAVEL], role[role != TRAVEL]
    img = Image.new("RGB", size, BACKGROUND)
    draw = ImageDraw.Draw(img)
    title = title or f"layer at z = {layer.z:.2f} mm"
    legend = legend_layout(draw, np.unique(role).tolist(), size, title)
    if len(seg):
        lo, scale, off = _fit(seg[:, :, :2].reshape(-1, 2), size, legend.title_at[0], legend.bottom)
        px = (seg[:, :, :2] - lo) * scale * np.array([1, -1]) + off
        width = max(1, int(round(float(layer.width.max(initial=0.45)) * scale)))
        for r in DRAW_ORDER:
            lines = px[role == r].round(1).tolist()
            for (x0, y0), (x1, y1) in lines:
                draw.line([(x0, y0), (x1, y1)], fill=ROLE_COLOURS[r], width=1 if r == TRAVEL else width)
    _draw_legend(draw, legend, title)
    path = Path(path)
    img.save(path)
    return path


def render_model(layers: Sequence[LayerPaths], path: str | Path, size: tuple[int, int] = (1200, 800),
                 azimuth_deg: float = -35.0, elevation_deg: float = 25.0, title: str = "",
                 max_segments: int = 400_000) -> Path:
    """All extrusions of a sliced model in 3D, each role in its colour, far-to-near, with a legend
    of the roles present (Fig. 9)."""
    parts = [_segments(layer) for layer in layers]
    seg = np.concatenate([p[0] for p in parts]) if parts else np.zeros((0, 2, 3))
    role = np.concatenate([p[1] for p in parts]) if parts else np.zeros(0, dtype=np.uint8)
    keep = role != TRAVEL
    seg, role = seg[keep], role[keep]
    present = np.unique(role).tolist()  # before thinning: a role of a few segments is still named
    if len(seg) > max_segments:  # thin evenly: the picture keeps its look
        pick = np.linspace(0, len(seg) - 1, max_segments).astype(np.int64)
        seg, role = seg[pick], role[pick]
    basis = _view_basis(azimuth_deg, elevation_deg)
    proj = seg @ basis.T
    order = np.argsort(proj[:, :, 2].mean(axis=1), kind="stable")
    img = Image.new("RGB", size, BACKGROUND)
    draw = ImageDraw.Draw(img)
    title = title or f"{len(layers)} layers"
    legend = legend_layout(draw, present, size, title)
    if len(seg):
        lo, scale, off = _fit(proj[:, :, :2].reshape(-1, 2), size, legend.title_at[0], legend.bottom)
        px = (proj[order, :, :2] - lo) * scale * np.array([1, -1]) + off
        depth = proj[order, :, 2].mean(axis=1)
        shade = 0.6 + 0.4 * (depth - depth.min()) / max(float(np.ptp(depth)), 1e-9)
        table = np.array([ROLE_COLOURS[r] for r in range(len(ROLE_NAMES))])
        colours = (table[role[order]] * shade[:, None]).astype(int)
        for ((x0, y0), (x1, y1)), c in zip(px.round(1).tolist(), colours.tolist()):
            draw.line([(x0, y0), (x1, y1)], fill=tuple(c), width=1)
    _draw_legend(draw, legend, title)
    path = Path(path)
    img.save(path)
    return path
