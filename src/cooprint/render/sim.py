"""Pictures of a simulated plan (thin, on the timelines): the fleet at an instant, like the seed's
Fig. 14 and 16 (material as lines coloured per robot, robots as their footprints with the
nozzle), and a Gantt chart of who prints, travels and waits when."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from cooprint.render.chunks import BACKGROUND, _font, _view_basis
from cooprint.render.paths import _fit
from cooprint.simulation import SimResult
from cooprint.simulation.checks import _frame, body_box

ROBOT_COLOURS = [(214, 96, 77), (67, 147, 195), (90, 170, 90), (200, 150, 40), (150, 100, 190), (120, 120, 120)]
WAIT_COLOUR = (235, 200, 60)
TRAVEL_COLOUR = (185, 185, 185)


def _colour(i: int) -> tuple[int, int, int]:
    return ROBOT_COLOURS[i % len(ROBOT_COLOURS)]


def _hms(t: float) -> str:
    t = int(round(t))
    return f"{t // 3600}:{t % 3600 // 60:02d}:{t % 60:02d}"


def render_snapshot(result: SimResult, t: float, path: str | Path, size: tuple[int, int] = (1280, 720),
                    azimuth_deg: float = -35.0, elevation_deg: float = 30.0, max_segments: int = 300_000) -> Path:
    """The fleet at time ``t``: material laid down so far (per robot colour, far to near), each
    robot's footprint on the floor and its nozzle, a clock and each robot's progress."""
    basis = _view_basis(azimuth_deg, elevation_deg)
    segs, cols = [], []
    for i, r in enumerate(result.robots):
        seg, _ = result.timelines[r.name].deposited(t)
        segs.append(seg)
        cols.append(np.full(len(seg), i))
    seg = np.concatenate(segs) if segs else np.zeros((0, 2, 3))
    col = np.concatenate(cols) if cols else np.zeros(0, np.int64)
    if len(seg) > max_segments:
        pick = np.linspace(0, len(seg) - 1, max_segments).astype(np.int64)
        seg, col = seg[pick], col[pick]
    # the frame fits everything the plan ever covers, so that frames of an animation line up
    extent = [np.vstack([tl.p0, tl.p1]) for tl in result.timelines.values() if len(tl.p0)]
    feet = [_footprint(result, r, result.timelines[r.name].position(t)) for r in result.robots]
    every = np.vstack(extent + [f for f in feet]) if extent else np.zeros((1, 3))
    proj_all = every @ basis.T
    img = Image.new("RGB", size, BACKGROUND)
    draw = ImageDraw.Draw(img)
    lo, scale, off = _fit(proj_all[:, :2], size, 40, 90)

    def px(p: np.ndarray) -> np.ndarray:
        return ((p @ basis.T)[..., :2] - lo) * scale * np.array([1, -1]) + off

    for i, foot in enumerate(feet):  # footprints on the floor, under the material
        c = tuple(int(0.5 * x + 0.5 * 255) for x in _colour(i))
        draw.polygon([tuple(q) for q in px(foot).round(1).tolist()], fill=c, outline=_colour(i))
    if len(seg):
        proj = seg @ basis.T
        order = np.argsort(proj[:, :, 2].mean(axis=1), kind="stable")
        depth = proj[order, :, 2].mean(axis=1)
        shade = 0.6 + 0.4 * (depth - depth.min()) / max(float(np.ptp(depth)), 1e-9)
        palette = np.array([_colour(i) for i in range(len(result.robots))])
        colours = (palette[col[order]] * shade[:, None]).astype(int).tolist()
        lines = px(seg[order]).round(1).tolist()
        for ((x0, y0), (x1, y1)), c in zip(lines, colours):
            draw.line([(x0, y0), (x1, y1)], fill=tuple(c), width=1)
    for i, r in enumerate(result.robots):  # nozzles: a mast from the floor and a dot
        n = result.timelines[r.name].position(t)
        a, b = px(np.array([n[0], n[1], 0.0])), px(n)
        draw.line([tuple(a), tuple(b)], fill=(60, 60, 60), width=2)
        draw.ellipse([b[0] - 5, b[1] - 5, b[0] + 5, b[1] + 5], fill=_colour(i), outline=(30, 30, 30))
    _overlay(draw, result, t, size)
    path = Path(path)
    img.save(path, format="PNG")
    return path


def _footprint(result: SimResult, r, nozzle: np.ndarray) -> np.ndarray:
    """(4, 3) corners of a robot's body on the floor with its nozzle at ``nozzle``."""
    u_lo, u_hi, v_lo, v_hi = body_box(result.profile)
    frame = _frame(r.facing)
    box = np.array([[u_lo, v_lo], [u_hi, v_lo], [u_hi, v_hi], [u_lo, v_hi]]) @ frame
    xy = nozzle[:2] + box
    return np.column_stack([xy, np.zeros(4)])


def _overlay(draw: ImageDraw.ImageDraw, result: SimResult, t: float, size: tuple[int, int]) -> None:
    """Clock and per-robot progress bars at the top."""
    font = _font(18)
    span = max(result.makespan, 1e-9)
    draw.text((20, 15), f"t = {_hms(t)} / {_hms(span)}", fill=(20, 20, 20), font=_font(22))
    x = 320
    for i, r in enumerate(result.robots):
        tl = result.timelines[r.name]
        total = float((tl.t1 - tl.t0)[tl.on].sum()) or 1.0
        done = float(np.clip(np.minimum(tl.t1, t) - tl.t0, 0, None)[tl.on].sum())
        draw.text((x, 12), f"robot {r.name}", fill=_colour(i), font=font)
        draw.rectangle([x, 40, x + 160, 54], outline=(90, 90, 90))
        draw.rectangle([x, 40, x + int(160 * done / total), 54], fill=_colour(i))
        waiting = any(a <= t < b for a, b, _ in tl.waits)
        label = "waiting" if waiting else ("done" if t >= tl.end else f"{100 * done / total:.0f}% printed")
        draw.text((x + 170, 38), label, fill=(60, 60, 60), font=_font(14))
        x += 300
        if x > size[0] - 200:
            break


def render_gantt(result: SimResult, path: str | Path, size: tuple[int, int] = (1200, 0)) -> Path:
    """Per robot, when it prints (its colour), travels (grey) and waits (yellow), on one time axis."""
    rows = len(result.robots)
    h = size[1] or 120 + 60 * rows
    w = size[0]
    img = Image.new("RGB", (w, h), BACKGROUND)
    draw = ImageDraw.Draw(img)
    left, right, top = 110, w - 30, 60
    span = max(result.makespan, 1e-9)

    def x(t: np.ndarray | float) -> np.ndarray:
        return left + (np.asarray(t) / span) * (right - left)

    font = _font(16)
    draw.text((left, 15), f"makespan {_hms(span)} ({span:.0f} s)", fill=(20, 20, 20), font=_font(20))
    for i, r in enumerate(result.robots):
        tl = result.timelines[r.name]
        y0, y1 = top + 60 * i, top + 60 * i + 40
        draw.text((15, y0 + 10), f"robot {r.name}", fill=_colour(i), font=font)
        for on, colour in ((False, TRAVEL_COLOUR), (True, _colour(i))):
            sel = tl.on == on
            a, b = x(tl.t0[sel]), x(tl.t1[sel])
            # merge touching bars (a print is millions of moves): draw runs at pixel resolution
            for xa, xb in _runs(a, b):
                draw.rectangle([xa, y0, max(xb, xa + 1), y1], fill=colour)
        for a, b, _ in tl.waits:
            if b > a:
                draw.rectangle([float(x(a)), y0, float(x(b)), y1], fill=WAIT_COLOUR)
    # time axis
    y = top + 60 * rows
    draw.line([(left, y), (right, y)], fill=(60, 60, 60))
    step = _nice_step(span / 8)
    for k in range(int(span // step) + 1):
        t = k * step
        draw.line([(float(x(t)), y), (float(x(t)), y + 6)], fill=(60, 60, 60))
        draw.text((float(x(t)) - 20, y + 8), _hms(t), fill=(60, 60, 60), font=_font(13))
    lx = left
    for label, colour in (("printing", _colour(0)), ("travelling", TRAVEL_COLOUR), ("waiting", WAIT_COLOUR)):
        draw.rectangle([lx + 250, 20, lx + 268, 34], fill=colour)
        draw.text((lx + 274, 17), label, fill=(40, 40, 40), font=font)
        lx += 130
    path = Path(path)
    img.save(path, format="PNG")
    return path


def _runs(a: np.ndarray, b: np.ndarray) -> list[tuple[float, float]]:
    """Intervals [a, b] (sorted by a) merged where they touch within a pixel."""
    if len(a) == 0:
        return []
    gap = np.flatnonzero(a[1:] > np.maximum.accumulate(b)[:-1] + 1.0)
    starts = np.r_[0, gap + 1]
    ends = np.r_[gap, len(a) - 1]
    hi = np.maximum.accumulate(b)
    return list(zip(a[starts].tolist(), hi[ends].tolist()))


def _nice_step(raw: float) -> float:
    for s in (1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200, 10800, 21600, 43200, 86400):
        if s >= raw:
            return float(s)
    return 86400.0 * np.ceil(raw / 86400.0)


__all__ = ["render_gantt", "render_snapshot"]
