"""Pictures of a simulated plan (thin, on the timelines): the fleet at an instant, like the seed's
Fig. 14 and 16, and in time (MP4, GIF): the material as lines coloured per robot over a floor
grid, each robot whole (body, frame, printhead, nozzle) as shaded boxes hidden where the print
is nearer to the camera (the pixels: :mod:`cooprint.render.kernels`); and a Gantt chart of who
prints, travels and waits when."""

from __future__ import annotations

import errno
import functools
import math
import os
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
from PIL import Image, ImageDraw

from cooprint.errors import UserError
from cooprint.render.chunks import BACKGROUND, _font, _view_basis
from cooprint.render.kernels import NO_DEPTH, draw_dot, draw_faces, draw_lines
from cooprint.render.palette import FIXED, robot_colour
from cooprint.simulation import SimResult
from cooprint.simulation.checks import outline_corners

ROBOT_COLOURS = FIXED  # the first robots' colours (render/palette.py)
WAIT_COLOUR = (235, 200, 60)
TRAVEL_COLOUR = (185, 185, 185)
#: The frame of a chunk on the schedule's critical path, and the lower bound's line, in the Gantt chart.
CRITICAL_COLOUR = (204, 0, 0)
BOUND_COLOUR = (40, 40, 40)


def _colour(i: int) -> tuple[int, int, int]:
    return robot_colour(i)


#: Seconds in a day: times from one day on are written in days.
DAY = 86400.0


def _hms(t: float) -> str:
    """``H:MM:SS``, from one day on ``D d HH:MM:SS`` (a 375-day plan is ``375 d 00:00:00``, not
    ``9000:00:00``)."""
    d, s = divmod(int(round(t)), int(DAY))
    hms = f"{s // 3600:02d}:{s % 3600 // 60:02d}:{s % 60:02d}"
    return f"{d} d {hms}" if d else hms.removeprefix("0")


#: The floor grid's lines, and the labels of their coordinates, mm.
GRID_COLOUR = (214, 218, 226)
GRID_LABEL_COLOUR = (120, 125, 138)
#: A robot's heights that its profile does not give (the outline checks compare its parts in XY
#: only), mm: the frame's thickness and the printhead's height over the printhead's underside, and
#: the nozzle's width (drawn from its tip up to the printhead's underside, ``nozzle_height``).
FRAME_THICKNESS, HEAD_HEIGHT, NOZZLE_WIDTH = 30.0, 80.0, 3.0
#: How much white each part's colour takes (the body palest, the printhead the robot's own
#: colour): a robot stands apart from the material laid in its colour.
PART_TINT = {"body": 0.6, "frame": 0.35, "printhead": 0.0}
NOZZLE_COLOUR = (70, 70, 76)
#: Towards the light on the robots' faces: from above, from the left front.
LIGHT = np.array([-0.35, -0.45, 0.82]) / np.linalg.norm([-0.35, -0.45, 0.82])
#: How much of a robot's colour covers the material behind it (the rest: the material's, so that a
#: robot over the print, as a frame seen from above, does not hide it: at 0.45 a 5 mm cube under
#: its robot's frame was a faint trace; the faces' outlines still draw the robot).
ROBOT_ALPHA = 0.2
#: ... and of a face that covers material somewhere, over the floor (so that the gaps between a
#: small part's lines are not the frame's colour: the part stays visible under a robot's frame).
OVER_PART_ALPHA = 0.35
#: ... and of a nozzle's rod over the material behind it (drawn over the robots' frames).
NOZZLE_ALPHA = 0.6
#: ... and of its outline over the material behind it.
EDGE_ALPHA = 0.7
#: The nozzle's tip is marked with a dot unless material nearer than this (mm) hides it.
TIP_TOLERANCE = 3.0


class _Scene:
    """The projection of a simulated plan, fitted once so that every frame lines up: on the
    material (the whole plan's, so a part fills the picture below the overlay however far the
    robots stand; robots beyond the border are cut by it), with a floor grid under it.

    Pictures are numpy arrays drawn with a depth picture beside them (:meth:`canvas`;
    :mod:`cooprint.render.kernels`): each material pixel holds the depth of the material drawn
    there (along the direction towards the camera, larger is nearer), so that the robots, drawn
    after the material, are hidden where the material is in front of them (:meth:`robots`)."""

    def __init__(self, result: SimResult, size: tuple[int, int], azimuth_deg: float, elevation_deg: float):
        self.result, self.size = result, size
        self.basis = _view_basis(azimuth_deg, elevation_deg)
        #: The picture's size against 1280 x 720: fonts, dots and the overlay scale with it.
        self.k = min(size[0] / 1280, size[1] / 720)
        # the material's ends a block at a time (all moves' if nothing is printed, the nozzles'
        # starts if nothing moves): the least and the most of each axis, projected and in space,
        # all that the fit, the shading and the grid's labels take
        proj, space = [], []
        for printed in (True, False):
            for tl in result.timelines.values():
                for a in range(0, len(tl.p0), BLOCK_MOVES):
                    sel = tl.on[a:a + BLOCK_MOVES] if printed else slice(None)
                    for p in (tl.p0[a:a + BLOCK_MOVES][sel], tl.p1[a:a + BLOCK_MOVES][sel]):
                        if len(p):
                            proj += [f(p @ self.basis.T, axis=0) for f in (np.min, np.max)]
                            space += [f(p, axis=0) for f in (np.min, np.max)]
            if proj:
                break
        if not proj:
            space = [self.nozzle(r, 0.0) for r in result.robots] or [np.zeros(3)]
            proj = [p @ self.basis.T for p in space]
        proj_lo, proj_hi = np.min(proj, axis=0), np.max(proj, axis=0)
        self.space_lo, self.space_hi = np.min(space, axis=0), np.max(space, axis=0)
        self.palette = np.array([_colour(i) for i in range(len(result.robots))])
        self.layout = overlay_layout([r.name for r in result.robots], size,
                                     f"t = {_hms(result.makespan)} / {_hms(result.makespan)}")
        mid, half = (proj_lo[:2] + proj_hi[:2]) / 2, np.maximum((proj_hi[:2] - proj_lo[:2]) / 2, 10.0)
        # the part below the overlay, above the grid's labels and the scale bar
        margin = max(12, round(0.06 * min(size)))
        top, bottom = self.layout.bottom + margin // 2, margin + round(40 * self.k)
        self.scale = min((size[0] - 2 * margin) / (2 * half[0]), (size[1] - top - bottom) / (2 * half[1]))
        self.lo = mid - half
        self.off = np.array([size[0] / 2 - self.scale * half[0], (top + size[1] - bottom) / 2 + self.scale * half[1]])
        self.d_lo, self.d_span = float(proj_lo[2]), max(float(proj_hi[2] - proj_lo[2]), 1e-9)  # for shading
        #: The floor grid's step and the scale bar's length, mm: round numbers of about 70 and
        #: 150 pixels (of a 1280 x 720 picture).
        self.grid_step = _nice_length(70 * self.k / self.scale)
        self.bar_length = _nice_length(150 * self.k / self.scale)
        # per robot, for its progress bar: the printing time done before each block of moves
        self.printing = {}
        for r in result.robots:
            tl = result.timelines[r.name]
            done = [_printing(tl, a, min(a + BLOCK_MOVES, len(tl.t0))) for a in range(0, len(tl.t0), BLOCK_MOVES)]
            self.printing[r.name] = np.concatenate([[0.0], np.cumsum(done)])

    def printed(self, robot: str, t: float) -> tuple[float, float]:
        """Seconds of printing robot ``robot`` has done by ``t``, and in all."""
        tl, before = self.result.timelines[robot], self.printing[robot]
        k = int(np.searchsorted(tl.t1, t, side="right"))  # moves finished by t
        b = k // BLOCK_MOVES
        done = before[b] + (_printing(tl, b * BLOCK_MOVES, k) if k > b * BLOCK_MOVES else 0.0)
        under_way = t - tl.t0[k] if k < len(tl.t0) and tl.on[k] and tl.t0[k] < t else 0.0  # a print under way
        return float(done + under_way), float(before[-1])

    def nozzle(self, r, t: float) -> np.ndarray:
        """(3,) robot ``r``'s nozzle at ``t``: on its timeline, or where it starts if it never moves."""
        tl = self.result.timelines[r.name]
        if len(tl.t0):
            return tl.position(t)
        return np.zeros(3) if r.start is None else np.asarray(r.start, dtype=np.float64)

    def px(self, p: np.ndarray) -> np.ndarray:
        return ((p @ self.basis.T)[..., :2] - self.lo) * self.scale * np.array([1, -1]) + self.off

    def unproject(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates back to the view's right and up coordinates, mm (:meth:`px` inverted)."""
        return (x - self.off[0]) / self.scale + self.lo[0], (self.off[1] - y) / self.scale + self.lo[1]

    def canvas(self) -> tuple[np.ndarray, np.ndarray]:
        """A new picture (h, w, 3) uint8 with the floor grid (:meth:`floor`) and its depth
        picture (h, w) float32, without material (:data:`NO_DEPTH`)."""
        img = Image.new("RGB", self.size, BACKGROUND)
        self.floor(ImageDraw.Draw(img))
        return np.array(img), np.full(self.size[::-1], NO_DEPTH, np.float32)

    def material(self, rgb: np.ndarray, depth: np.ndarray | None, seg: np.ndarray, col: np.ndarray,
                 sort: bool) -> None:
        """Segments (k, 2, 3) into picture ``rgb`` in their robots' colours, shaded by depth
        (far to near if ``sort``), their depths into ``depth`` (the same pixels; ``None``: not kept)."""
        if not len(seg):
            return
        ends = seg @ self.basis[2]  # (k, 2) the ends' depths
        near = ends.mean(axis=1)
        order = np.argsort(near, kind="stable") if sort else np.arange(len(seg))
        shade = 0.65 + 0.35 * np.clip((near[order] - self.d_lo) / self.d_span, 0, 1)
        colours = (self.palette[col[order]] * shade[:, None]).astype(np.uint8)
        draw_lines(rgb, rgb[:1, :1, 0].astype(np.float32) if depth is None else depth,
                   self.px(seg[order]).round(1).reshape(-1, 4), colours, ends[order].astype(np.float32),
                   depth is not None)

    def floor(self, draw: ImageDraw.ImageDraw) -> None:
        """The floor grid at every ``grid_step`` mm over the floor in sight, and the lines'
        coordinates (mm) written along the material's near sides (none when the floor is seen
        edge on)."""
        right, up, cam = self.basis
        if cam[2] < 0.05:
            return
        w, h = self.size
        x, y = self.unproject(np.array([0.0, w, 0.0, w]), np.array([0.0, 0.0, h, h]))
        d = -(right[2] * x + up[2] * y) / cam[2]  # the picture's corners cast onto z = 0
        seen = np.outer(x, right) + np.outer(y, up) + np.outer(d, cam)
        lo, hi = seen[:, :2].min(axis=0), seen[:, :2].max(axis=0)
        step = self.grid_step
        while ((hi - lo) / step).max() > 400:  # a floor seen nearly edge on: fewer lines
            step *= 2
        for axis in (0, 1):
            for v in np.arange(math.ceil(lo[axis] / step), math.floor(hi[axis] / step) + 1) * step:
                a, b = np.zeros(3), np.zeros(3)
                a[axis] = b[axis] = v
                a[1 - axis], b[1 - axis] = lo[1 - axis], hi[1 - axis]
                draw.line([tuple(q) for q in self.px(np.array([a, b])).tolist()], fill=GRID_COLOUR, width=1)
        font = _cached_font(max(8, round(13 * self.k)))
        placed: list[tuple[float, float, float, float]] = []
        step = self.grid_step
        for axis in (0, 1):
            other = 1 - axis  # labels along the material's side nearest the camera, across the lines
            at = (self.space_hi[other] + 0.6 * step) if cam[other] > 0 else (self.space_lo[other] - 0.6 * step)
            first, last = math.floor(self.space_lo[axis] / step), math.ceil(self.space_hi[axis] / step)
            for v in np.arange(first, last + 1) * step:
                p = np.zeros(3)
                p[axis], p[other] = v, at
                cx, cy = self.px(p).tolist()
                box = draw.textbbox((cx, cy), f"{v:g}", font=font, anchor="mm")
                if (box[0] < 2 or box[2] > w - 2 or box[1] < self.layout.bottom or box[3] > h - 2
                        or any(box[0] < q[2] + 4 and q[0] < box[2] + 4 and box[1] < q[3] and q[1] < box[3]
                               for q in placed)):
                    continue
                draw.text((cx, cy), f"{v:g}", fill=GRID_LABEL_COLOUR, font=font, anchor="mm")
                placed.append(box)

    def robots(self, rgb: np.ndarray, depth: np.ndarray, t: float) -> None:
        """Every robot as it stands at ``t``, drawn into picture ``rgb`` over its material: its
        body, frame and printhead as shaded boxes (where they are known: not for G-code
        printers), its nozzle down to the tip and a dot at the tip.

        The boxes' faces are drawn far to near (each box by its centre; the nozzles' rods last,
        over the robots' see-through frames, so that a printhead reads as attached to its tip; a
        face over the material is see-through over the floor too, :data:`OVER_PART_ALPHA`),
        each pixel against the material's ``depth`` there (:func:`cooprint.render.kernels.draw_faces`): behind the
        material it is left out; in front of it, the material shows through (:data:`ROBOT_ALPHA`).
        The dot at a tip marks where the robot prints: drawn over the robots, left out only
        where material in front of it hides the tip (:data:`TIP_TOLERANCE`)."""
        solids = sorted((s for i, r in enumerate(self.result.robots) for s in self._solids(i, r, t)),
                        key=lambda s: s.depth)
        material = depth[::4, ::4] > NO_DEPTH / 2  # where material is, a pixel in 16
        for on_top in (False, True):  # the rods over the rest
            faces = [f for s in solids if s.on_top == on_top for f in s.faces(self)]
            if not faces:
                continue
            quads, planes, fills, edges = (np.array([f[k] for f in faces]) for k in range(4))
            alpha = np.full(len(faces), NOZZLE_ALPHA if on_top else ROBOT_ALPHA)
            # a face over the material lets it show through everywhere (a 5 mm cube under a frame)
            over = np.array([_covers(material, q / 4) for q in quads]) & (not on_top)
            back = np.where(over, OVER_PART_ALPHA, 1.0)
            draw_faces(rgb, rgb.copy(), depth, quads, planes, fills.astype(np.uint8), edges.astype(np.uint8),
                       alpha, EDGE_ALPHA, back)
        radius = max(4.0, 6.0 * self.k)
        for i, r in enumerate(self.result.robots):
            tip = self.nozzle(r, t)
            x, y = self.px(tip).tolist()
            col, row = int(round(x)), int(round(y))
            if 0 <= col < self.size[0] and 0 <= row < self.size[1] and \
                    depth[row, col] > float(tip @ self.basis[2]) + TIP_TOLERANCE:
                continue  # the tip is behind the material
            draw_dot(rgb, x, y, radius, np.array(_colour(i), np.uint8), np.array((30, 30, 30), np.uint8))

    def _solids(self, i: int, r, t: float) -> list["_Solid"]:
        """Robot ``r``'s parts at ``t`` as boxes: the body on the floor up to the printhead's
        underside (``nozzle_height`` above the tip), the frame and the printhead from there up
        (:data:`FRAME_THICKNESS`, :data:`HEAD_HEIGHT`), in XY the outline the checks use; and the
        nozzle from the tip up to the printhead. A G-code printer (``result.placed`` false) has
        the nozzle only: where its body stands is not known."""
        tip = self.nozzle(r, t)
        under = float(tip[2]) + (r.profile or self.result.profile).nozzle_height
        out = []
        if self.result.placed:
            parts = _outline_at(self.result, r, tip, t)
            colour = np.array(_colour(i), float)
            for part, z0, z1 in (("body", 0.0, under), ("frame", under, under + FRAME_THICKNESS),
                                 ("printhead", under, under + HEAD_HEIGHT)):
                if z1 > z0:
                    out.append(_Solid(parts[part], z0, z1, colour + PART_TINT[part] * (255 - colour)))
        rod = tip[:2] + NOZZLE_WIDTH / 2 * np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
        if under > tip[2]:
            out.append(_Solid(rod, float(tip[2]), under, np.array(NOZZLE_COLOUR, float), on_top=True))
        for s in out:
            s.depth = float(s.corners.mean(axis=0) @ self.basis[2])
        return out


def _covers(mask: np.ndarray, quad: np.ndarray) -> bool:
    """Whether the convex ``quad`` (4, 2) pixels (of ``mask``'s scale) covers a True pixel of ``mask``."""
    h, w = mask.shape
    x0, y0 = np.floor(quad.min(axis=0)).astype(int)
    x1, y1 = np.ceil(quad.max(axis=0)).astype(int)
    x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w - 1), min(y1, h - 1)
    if x0 > x1 or y0 > y1 or not mask[y0:y1 + 1, x0:x1 + 1].any():
        return False
    inside = Image.new("1", (x1 - x0 + 1, y1 - y0 + 1), 0)
    ImageDraw.Draw(inside).polygon([(x - x0, y - y0) for x, y in quad.tolist()], fill=1, outline=1)
    return bool((np.asarray(inside) & mask[y0:y1 + 1, x0:x1 + 1]).any())


class _Solid:
    """A box drawn for a robot's part: a rectangle in XY (corners (4, 2) in order round it) from
    height ``z0`` up to ``z1``, in ``colour`` (shaded per face by :data:`LIGHT`).

    Corner ``iu + 2 iv + 4 iz`` (each index 0 or 1) is the rectangle's first corner, plus ``iu``
    times its first side and ``iv`` times its last, at ``z0`` or ``z1``; ``axes`` (3, 3) are the
    unit directions of the first side, the last side and up."""

    #: Each face's corners in order round it, by (axis, side).
    FACES = {(0, 0): (0, 2, 6, 4), (0, 1): (1, 3, 7, 5), (1, 0): (0, 1, 5, 4), (1, 1): (2, 3, 7, 6),
             (2, 0): (0, 1, 3, 2), (2, 1): (4, 5, 7, 6)}

    def __init__(self, xy: np.ndarray, z0: float, z1: float, colour: np.ndarray, on_top: bool = False):
        du, dv = xy[1] - xy[0], xy[3] - xy[0]
        bits = np.array([[c & 1, (c >> 1) & 1, c >> 2] for c in range(8)], float)
        self.corners = np.column_stack([xy[0] + bits[:, :1] * du + bits[:, 1:2] * dv,
                                        np.where(bits[:, 2] > 0, z1, z0)])
        self.axes = np.array([[*du / np.linalg.norm(du), 0.0], [*dv / np.linalg.norm(dv), 0.0], [0.0, 0.0, 1.0]])
        self.colour = colour
        #: Drawn after every other box (a nozzle's rod: never lost behind a frame).
        self.on_top = on_top
        self.depth = 0.0  # of its centre, set by the scene (the order it is drawn in)

    def sides(self, scene: _Scene) -> list[tuple[int, int]]:
        """(axis, side) of the faces the camera sees (none along an axis it looks across)."""
        c = self.axes @ scene.basis[2]
        return [(a, int(c[a] > 0)) for a in range(3) if abs(c[a]) > 1e-9]

    def faces(self, scene: _Scene) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """The faces the camera sees: pixel corners (4, 2), the depth plane (3,) (a pixel
        ``(x, y)`` of the face lies at depth ``plane . (x, y, 1)``), the fill and the edge's colour."""
        corners = scene.px(self.corners)
        right, up, cam = scene.basis
        out = []
        for a, s in self.sides(scene):
            normal = (2 * s - 1) * self.axes[a]
            light = 0.72 + 0.28 * max(0.0, float(normal @ LIGHT))
            # on the face, normal . (X right + Y up + d cam) is the corner's: d from the pixel
            nr, nu, nc = normal @ right, normal @ up, normal @ cam
            at = normal @ self.corners[self.FACES[(a, s)][0]]
            plane = np.array([-nr / scene.scale, nu / scene.scale,
                              at - nr * (scene.lo[0] - scene.off[0] / scene.scale)
                              - nu * (scene.lo[1] + scene.off[1] / scene.scale)]) / nc
            out.append((corners[list(self.FACES[(a, s)])], plane, np.clip(self.colour * light, 0, 255),
                        self.colour * 0.55))
        return out


#: Moves looked at a block at a time (the scene's extent, the printing time, the material drawn).
BLOCK_MOVES = 1 << 20


def _printing(tl, a: int, e: int) -> float:
    """Seconds of printing in moves ``a:e`` of a timeline."""
    on = tl.on[a:e]
    return float((tl.t1[a:e][on] - tl.t0[a:e][on]).sum())


def _deposited(result: SimResult, t: float, most: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The segments (m, 2, 3) of material laid down by ``t`` (each robot's in order, the last
    one of each cut at ``t``) and the robot of each; with ``most``, at most that many of them,
    evenly spread over all (``linspace`` over their order), gathered a block of moves at a time
    (never all of a big plan's segments at once)."""
    counts = []  # per robot: its moves that may have started by t, and its deposits in each block of them
    for r in result.robots:
        tl = result.timelines[r.name]
        k = int(np.searchsorted(tl.t0, t, side="left"))
        counts.append((k, np.array([int(np.count_nonzero(tl.on[a:min(a + BLOCK_MOVES, k)]))
                                    for a in range(0, k, BLOCK_MOVES)], dtype=np.int64)))
    total = int(sum(int(c.sum()) for _, c in counts))
    pick = np.linspace(0, total - 1, most).astype(np.int64) if most is not None and total > most else None
    segs, cols = [], []
    first = 0  # the robot's first segment among all
    for i, (r, (k, blocks)) in enumerate(zip(result.robots, counts)):
        tl = result.timelines[r.name]
        mine = int(blocks.sum())
        want = None if pick is None else pick[np.searchsorted(pick, first):np.searchsorted(pick, first + mine)] - first
        starts = np.concatenate([[0], np.cumsum(blocks)])
        full = np.flatnonzero(blocks)  # the robot's last deposit by t: the last of the last block that has one
        last = (int(np.flatnonzero(tl.on[full[-1] * BLOCK_MOVES:min((full[-1] + 1) * BLOCK_MOVES, k)])[-1])
                + int(full[-1]) * BLOCK_MOVES) if len(full) else -1
        for j, a in enumerate(range(0, k, BLOCK_MOVES)):
            idx = np.flatnonzero(tl.on[a:min(a + BLOCK_MOVES, k)]) + a  # the block's deposits
            if want is not None:
                idx = idx[want[np.searchsorted(want, starts[j]):np.searchsorted(want, starts[j + 1])] - starts[j]]
            seg = np.stack([tl.p0[idx], tl.p1[idx]], axis=1)
            if len(idx) and idx[-1] == last and tl.t1[last] > t:  # its last deposit, under way: up to the nozzle
                seg[-1, 1] = tl.position(t)
            segs.append(seg)
            cols.append(np.full(len(seg), i))
        first += mine
    return (np.concatenate(segs) if segs else np.zeros((0, 2, 3)),
            np.concatenate(cols) if cols else np.zeros(0, np.int64))


def render_snapshot(result: SimResult, t: float, path: str | Path, size: tuple[int, int] = (1280, 720),
                    azimuth_deg: float = -35.0, elevation_deg: float = 30.0, max_segments: int = 300_000) -> Path:
    """The fleet at time ``t``: the floor grid, the material laid down so far (per robot
    colour, far to near), each robot as it stands (:meth:`_Scene.robots`: hidden where the
    material is in front), a clock, each robot's progress and a scale."""
    scene = _Scene(result, size, azimuth_deg, elevation_deg)
    seg, col = _deposited(result, t, max_segments)  # at most max_segments, spread over all
    rgb, depth = scene.canvas()
    scene.material(rgb, depth, seg, col, sort=True)
    scene.robots(rgb, depth, t)
    _overlay(rgb, scene, t)
    path = Path(path)
    Image.fromarray(rgb).save(path, format="PNG")
    return path


#: The most frames an animation may have: an MP4 is streamed (20,000 frames are 14 min at 24
#: fps and take about as many seconds to draw), a GIF's frames are all held until it is written
#: (1,000 of 640 x 360 are 230 MB).
MAX_FRAMES = 20_000
MAX_GIF_FRAMES = 1_000
#: An animation's length without --duration or --speedup, s.
DEFAULT_LENGTH = 20.0
#: The longest animation --speedup may make, s: a longer one is asked for by its length
#: (--duration), never made by a speed-up that happens to be too small for a long plan
#: (``--speedup 100`` on a 24 h plan would be a 14 min, 60 MB MP4).
MAX_SPEEDUP_LENGTH = 600.0
#: A GIF's most frames per second: its delays are whole hundredths of a second and browsers
#: play a delay of 0 or 1 as 10 (50 fps is 2 each).
MAX_GIF_FPS = 50.0


def animation_length(makespan: float, duration: float | None = None, speedup: float | None = None) -> float:
    """Seconds an animation of a ``makespan`` s plan lasts: ``duration``, or the plan played
    ``speedup`` times faster than real time, or :data:`DEFAULT_LENGTH`."""
    return makespan / speedup if speedup is not None else (duration or DEFAULT_LENGTH)


def length_text(seconds: float) -> str:
    """An animation's length for people: ``20.0 s``, ``14 min 24 s``, ``10 min``, ``2 h 05 min``."""
    if seconds < 60:
        return f"{seconds:.1f} s"
    s = int(round(seconds))
    if s >= 3600:
        return f"{s // 3600} h {s % 3600 // 60:02d} min"
    return f"{s // 60} min" + (f" {s % 60:02d} s" if s % 60 else "")


def frame_count(makespan: float, fps: float, duration: float | None = None, speedup: float | None = None,
                gif: bool = False) -> int:
    """How many frames an animation ``duration`` s long (or played ``speedup`` times faster than
    real time) at ``fps`` has; a :class:`~cooprint.errors.UserError` naming the options when
    that is not a finite count of at most ``MAX_FRAMES`` (``MAX_GIF_FRAMES`` for a GIF): the
    options alone must not ask for unbounded work (``--speedup 0.001 --fps 120`` over a 50 min
    plan is 360,000 frames); when ``speedup`` makes it longer than :data:`MAX_SPEEDUP_LENGTH`
    (the length it would have, the speed-up that keeps it within, and --duration to ask for
    it); and for a GIF over :data:`MAX_GIF_FPS`."""
    for name, v in (("--fps", fps), ("--duration", duration), ("--speedup", speedup)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise UserError(f"{name} {v:g}: expected a positive number")
    if gif and fps > MAX_GIF_FPS:
        raise UserError(f"--fps {fps:g}: a GIF plays at most {MAX_GIF_FPS:g} frames/s (its delays are whole "
                        f"hundredths of a second); take a lower --fps or --format mp4")
    length = animation_length(makespan, duration, speedup)
    frames = length * fps
    if speedup is not None and length > MAX_SPEEDUP_LENGTH:
        x = makespan / MAX_SPEEDUP_LENGTH
        need = math.ceil(x) if x >= 1 else math.ceil(x * 1000) / 1000
        raise UserError(f"--speedup {speedup:g} over the {_hms(makespan)} plan makes an animation of "
                        f"{length_text(length)} ({frames:,.0f} frames at {fps:g} fps), longer than "
                        f"{length_text(MAX_SPEEDUP_LENGTH)}: take --speedup {need:g} or more, or give the "
                        f"length you want with --duration")
    limit = MAX_GIF_FRAMES if gif else MAX_FRAMES
    if not frames <= limit:
        how = (f"--speedup {speedup:g} over the {makespan:.3g} s plan is {length:.3g} s" if speedup is not None
               else f"--duration {length:g} s")
        raise UserError(f"{how} at --fps {fps:g}: {frames:,.0f} frames, more than {limit:,} for "
                        f"{'a GIF' if gif else 'an animation'}; take a shorter --duration, a larger --speedup "
                        f"or a lower --fps")
    return max(2, int(round(frames)))


def frame_times(makespan: float, fps: float, duration: float | None = None, speedup: float | None = None,
                gif: bool = False) -> np.ndarray:
    """Times of the frames of an animation ``duration`` s long (or played ``speedup`` times
    faster than real time), the last frame at the end of the plan (at most ``MAX_FRAMES``,
    :func:`frame_count`)."""
    return np.linspace(0.0, makespan, frame_count(makespan, fps, duration, speedup, gif))


def gif_delays(frames: int, length: float) -> list[int]:
    """Each GIF frame's delay, ms, so that ``frames`` of them last ``length`` s: a GIF holds
    whole hundredths of a second, so frame k lasts from the k-th boundary to the next, each
    boundary ``k * length / frames`` rounded to a hundredth (24 fps: 40, 40, 50, 40, ... ms,
    the sum within 10 ms of ``length``, not 41 ms written as 40 each, 4 % short). At least 20 ms
    each (browsers play shorter delays as 100 ms)."""
    bounds = np.round(np.arange(frames + 1) * (100.0 * length / frames)).astype(np.int64)
    return (np.maximum(np.diff(bounds), 2) * 10).tolist()


class Mp4Encoder:
    """ffmpeg (from imageio-ffmpeg) encoding raw RGB frames from its stdin into an H.264 MP4.

    Quiet: ffmpeg runs at log level ``error`` and its stderr goes to a temporary file, never to
    the user's terminal (a 2-frame video would otherwise print a warning, a full disk six
    lines). A failure (ffmpeg gone, a broken pipe, a non-zero exit) becomes one ``OSError``
    whose text is ffmpeg's last error line, with the errno of a full disk, a read-only file
    system, a permission or quota problem when ffmpeg names one; the atomic writer turns it
    into ``OUT: cannot write: ...`` naming the user's file."""

    #: x264's speed preset: ``faster`` encodes benchy's 120 frames (the part filling the picture,
    #: the floor grid, the robots' faces) in 1.7 s where ``medium`` (the default) takes 2.7 s,
    #: for a file 8 % larger at the same quality (crf); the encoder is what an MP4 waits for.
    PRESET = "faster"
    #: The OS errors ffmpeg reports by their text (``No space left on device``).
    ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EFBIG, errno.EIO)

    def __init__(self, path: str | Path, size: tuple[int, int], fps: float, crf: int = 15):
        import imageio_ffmpeg

        w, h = size
        cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-f", "rawvideo", "-vcodec", "rawvideo",
               "-s", f"{w}x{h}", "-pix_fmt", "rgb24", "-r", f"{fps:.02f}", "-i", "-", "-an",
               "-vcodec", "libx264", "-pix_fmt", "yuv420p", "-crf", str(crf), "-preset", self.PRESET]
        if w % 8 or h % 8:  # players want whole macro blocks (as imageio-ffmpeg's default)
            cmd += ["-vf", f"scale={-(-w // 8) * 8}:{-(-h // 8) * 8}"]
        cmd += ["-v", "error", "-f", "mp4", str(path)]
        self.log = tempfile.TemporaryFile()
        try:  # its own session: a Ctrl-C reaches cooprint, which stops it, not ffmpeg half-way
            self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                         stderr=self.log, start_new_session=True)
        except OSError as exc:
            self.log.close()
            raise OSError(exc.errno, f"cannot start ffmpeg ({exc.strerror or exc})") from None

    def send(self, frame: bytes) -> None:
        """Encode one frame (``w * h * 3`` bytes, RGB)."""
        try:
            self.proc.stdin.write(frame)  # type: ignore[union-attr]
        except OSError as exc:  # ffmpeg stopped (a full disk): its own reason is the better one
            self._fail(exc)

    def close(self) -> None:
        """Finish the file; an ``OSError`` if ffmpeg did not."""
        try:
            self.proc.stdin.close()  # type: ignore[union-attr]
        except OSError as exc:
            self._fail(exc)
        if self.proc.wait() != 0:
            self._fail(None)
        self.log.close()

    def abort(self) -> None:
        """Stop ffmpeg (on an error or a Ctrl-C elsewhere); the caller removes the file."""
        self._stop(kill=True)
        self.log.close()

    def _stop(self, kill: bool) -> None:
        """Close ffmpeg's input and wait for it (killed at once with ``kill``, else after 10 s)."""
        try:
            self.proc.stdin.close()  # type: ignore[union-attr]
        except OSError:  # a broken pipe: ffmpeg is gone already
            pass
        if kill and self.proc.poll() is None:
            self.proc.kill()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()

    def _fail(self, exc: OSError | None) -> None:
        """Raise ffmpeg's own last error line as one ``OSError`` (see the class docstring)."""
        self._stop(kill=False)
        self.log.seek(0)
        lines = [ln.strip() for ln in self.log.read().decode("utf-8", "replace").splitlines() if ln.strip()]
        self.log.close()
        said = lines[-1][:200] if lines else None
        for code in self.ERRNOS:
            if said and os.strerror(code) in said:
                raise OSError(code, os.strerror(code)) from None
        if exc is not None and said is None:
            raise OSError(exc.errno, f"ffmpeg stopped ({exc.strerror or exc})") from None
        raise OSError(None, f"ffmpeg failed (exit {self.proc.returncode}): {said or 'no message'}") from None


def render_animation(result: SimResult, path: str | Path, fps: float = 24.0, duration: float | None = None,
                     speedup: float | None = None, size: tuple[int, int] = (1280, 720),
                     azimuth_deg: float = -35.0, elevation_deg: float = 30.0,
                     progress: "Callable[[int, int], None] | None" = None) -> Path:
    """MP4 (``.mp4``, through imageio-ffmpeg) or GIF (``.gif``, through Pillow) of the plan in
    time: each frame draws only the material laid down since the one before onto a kept canvas
    (the floor grid under it, its depth picture beside it), then the robots, the clock and the
    progress bars on a copy, as :func:`render_snapshot` draws them (seed Fig. 15-16).
    ``progress(frames done, frames)`` after each frame."""
    path = Path(path)
    gif = path.suffix.lower() == ".gif"
    if gif:
        size = (min(size[0], 640), min(size[1], 360))
    scene = _Scene(result, size, azimuth_deg, elevation_deg)
    times = frame_times(result.makespan, fps, duration, speedup, gif)
    canvas, depth = scene.canvas()  # the floor, then the material drawn so far, and its depth
    done = {r.name: 0 for r in result.robots}  # moves drawn whole so far
    frames: list[Image.Image] = []
    writer = None
    if not gif:
        writer = Mp4Encoder(path, size, fps)
    try:
        for n_done, t in enumerate(times.tolist()):
            if progress:
                progress(n_done, len(times))
            partial = []
            for i, r in enumerate(result.robots):
                tl = result.timelines[r.name]
                k = int(np.searchsorted(tl.t1, t, side="right"))  # moves finished by t
                new = np.flatnonzero(tl.on[done[r.name]:k]) + done[r.name]
                scene.material(canvas, depth, np.stack([tl.p0[new], tl.p1[new]], axis=1), np.full(len(new), i),
                               sort=False)
                done[r.name] = k
                if k < len(tl.t0) and tl.on[k] and tl.t0[k] < t:  # the move under way, up to the nozzle
                    partial.append((np.array([[tl.p0[k], tl.position(t)]]), np.array([i])))
            frame = canvas.copy()
            for seg, col in partial:
                scene.material(frame, None, seg, col, sort=False)
            scene.robots(frame, depth, t)
            _overlay(frame, scene, t)
            if gif:
                frames.append(Image.fromarray(frame).quantize(colors=128))
            else:
                writer.send(frame.tobytes())  # type: ignore[union-attr]
        if writer is not None:
            writer.close()
            writer = None
        if progress:
            progress(len(times), len(times))
    finally:
        if writer is not None:  # an error or a Ctrl-C while drawing: ffmpeg stops, the file is removed
            writer.abort()
    if gif:
        frames[0].save(path, format="GIF", save_all=True, append_images=frames[1:], loop=0,
                       duration=gif_delays(len(frames), animation_length(result.makespan, duration, speedup)))
    return path


def _outline_at(result: SimResult, r, nozzle: np.ndarray, t: float) -> dict[str, np.ndarray]:
    """Part -> (4, 2) world XY corners of a robot's outline (:func:`outline_corners`, no
    tolerance) with its nozzle at ``nozzle`` at time ``t``, in the facing in force then (a robot
    that turns round is drawn as it stands)."""
    facing = r.facing_at(result.timelines[r.name], t) if r.program.turns else r.facing
    return {part: nozzle[:2] + c for part, c in outline_corners(r.profile or result.profile, facing, 0.0).items()}


@dataclass(frozen=True)
class OverlayCell:
    """One robot's place in the overlay: ``text`` (its name) written at ``at`` (left, top) in a
    font of ``font`` pixels, covering ``box``; its progress bar ``bar``; where its state is
    written (``state_at``, left and middle, in ``state_font``; ``None`` in a compact layout with
    no room for it). A waiting robot's bar is framed in the Gantt chart's yellow in every layout.
    Boxes are ``(x0, y0, x1, y1)``, pixels."""

    text: str
    at: tuple[int, int]
    font: int
    box: tuple[int, int, int, int]
    bar: tuple[int, int, int, int]
    state_at: tuple[int, int] | None
    state_font: int


@dataclass(frozen=True)
class OverlayLayout:
    """Where the clock and each robot's name and progress bar go at the top of a picture
    (:func:`overlay_layout`); ``bottom``: the first pixel row below all of it."""

    clock_at: tuple[int, int]
    clock_font: int
    clock_box: tuple[int, int, int, int]
    cells: tuple[OverlayCell, ...]
    bottom: int


#: The states a robot's progress is told by (the widest sets the wide layout's cells).
STATES = ("100% printed", "waiting", "done", "idle")


def overlay_layout(names: Sequence[str], size: tuple[int, int], clock: str) -> OverlayLayout:
    """The overlay of a picture of ``size`` for robots ``names`` and the clock text ``clock``
    (its widest): everything inside the picture at any size, fonts and bars scaled with it
    (with the picture's size to the power 0.75: a 640 x 360 picture's text is 0.59 of a 1280 x 720's).

    Few robots get a wide cell each in one row right of the clock ("robot A", the bar and the
    state), shrunk to 85 % if need be; when those do not fit, every robot gets a compact
    cell (name and bar) in rows of as many as fit, beside the clock or, in a narrow picture,
    under it, names cut short (ending in "…") only when one cell is wider than the picture.
    Fonts shrink (down to 7 px) while the rows would take more than 40 % of the picture's height."""
    base = min(size[0] / 1280, size[1] / 720) ** 0.75  # text in a small picture shrinks less
    for shrink in (1.0, 0.85):
        lay = _overlay_wide(list(names), size, clock, base * shrink)
        if lay is not None:
            return lay
    for shrink in (1.0, 0.85, 0.7, 0.6, 0.5, 0.4, 0.3):
        lay = _overlay_compact(list(names), size, clock, base * shrink)
        if lay.bottom <= 0.4 * size[1]:
            break
    return lay


def _clock(clock: str, k: float) -> tuple[int, int, tuple[int, int], int, tuple[int, int, int, int]]:
    """At scale ``k`` (1: the sizes of a 1280 x 720 picture): the padding, the gap between cells,
    where the clock is written, its font and its box."""
    pad, gap = max(3, round(16 * k)), max(3, round(10 * k))
    at, font = (pad, max(2, round(12 * k))), max(8, round(22 * k))
    return pad, gap, at, font, _text_box(clock, at, font)


def _overlay_wide(names: list[str], size: tuple[int, int], clock: str, k: float) -> OverlayLayout | None:
    """One row of wide cells right of the clock at scale ``k`` (:func:`overlay_layout`); ``None``
    if they do not fit in the picture's width."""
    w = size[0]
    pad, gap, clock_at, clock_font, clock_box = _clock(clock, k)
    top, x0 = clock_at[1], clock_box[2] + 2 * pad
    name_font, state_font = max(7, round(18 * k)), max(7, round(14 * k))
    bar_w, bar_h = max(20, round(160 * k)), max(4, round(14 * k))
    texts = [f"robot {n}" for n in names]
    state_w = max(_cached_font(state_font).getlength(s) for s in STATES)
    cell_w = math.ceil(max([_cached_font(name_font).getlength(s) for s in texts] + [bar_w + gap + state_w])) + 2 * gap
    if x0 + len(names) * cell_w - 2 * gap > w - pad:
        return None
    cells = []
    for j, text in enumerate(texts):
        at = (x0 + j * cell_w, top)
        box = _text_box(text, at, name_font)
        y = box[3] + max(2, round(6 * k))
        cells.append(OverlayCell(text, at, name_font, box, (at[0], y, at[0] + bar_w, y + bar_h),
                                 (at[0] + bar_w + gap, y + bar_h // 2), state_font))
    bottom = max([clock_box[3]] + [c.bar[3] for c in cells]) + pad // 2
    return OverlayLayout(clock_at, clock_font, clock_box, tuple(cells), bottom)


def _overlay_compact(names: list[str], size: tuple[int, int], clock: str, k: float) -> OverlayLayout:
    """Rows of compact cells (name and bar) at scale ``k`` (:func:`overlay_layout`)."""
    w = size[0]
    pad, gap, clock_at, clock_font, clock_box = _clock(clock, k)
    top, x0 = clock_at[1], clock_box[2] + 2 * pad
    font = max(7, round(15 * k))
    bar_w, bar_h = max(16, round(60 * k)), max(4, round(10 * k))
    widths = [_cached_font(font).getlength(n) for n in names]
    cell_w = math.ceil(max(widths)) + 3 * gap + bar_w
    if w - pad - x0 < cell_w:  # not even one beside the clock: under it
        x0, top = pad, clock_box[3] + gap
    room = w - pad - x0
    per_row = max(1, (room + 2 * gap) // cell_w)
    if cell_w - 2 * gap > room:  # one cell wider than the picture: the names cut short
        names = [_cut(n, room - gap - bar_w, font) for n in names]
        widths = [_cached_font(font).getlength(n) for n in names]
        cell_w = room + 2 * gap
    name_w = math.ceil(max(widths))
    # the state after the bar where the rows stay within 15 % of the picture's height, or add none
    state_w = math.ceil(gap + max(_cached_font(font).getlength(t) for t in STATES))
    pitch = font + max(3, round(8 * k))
    rows = -(-len(names) // per_row)
    more = -(-len(names) // max(1, (room + 2 * gap) // (cell_w + state_w)))
    stated = cell_w + state_w - 2 * gap <= room and (more == rows or top + pitch * more <= 0.15 * size[1])
    if stated:
        cell_w += state_w
        per_row = max(1, (room + 2 * gap) // cell_w)
    cells = []
    for j, name in enumerate(names):
        at = (x0 + cell_w * (j % per_row), top + pitch * (j // per_row))
        box = _text_box(name, at, font)
        bx = at[0] + name_w + gap
        mid = (box[1] + box[3]) // 2
        cells.append(OverlayCell(name, at, font, box, (bx, mid - bar_h // 2, bx + bar_w, mid - bar_h // 2 + bar_h),
                                 (bx + bar_w + gap, mid) if stated else None, font))
    bottom = max([clock_box[3]] + [max(c.box[3], c.bar[3]) for c in cells]) + pad // 2
    return OverlayLayout(clock_at, clock_font, clock_box, tuple(cells), bottom)


def _text_box(text: str, at: tuple[int, int], font: int) -> tuple[int, int, int, int]:
    """The pixels ``text`` covers written at ``at`` (left, top) in a font of ``font`` pixels."""
    x0, y0, x1, y1 = _cached_font(font).getbbox(text)
    return (at[0] + math.floor(x0), at[1] + math.floor(y0), at[0] + math.ceil(x1), at[1] + math.ceil(y1))


def _cut(text: str, width: float, font: int) -> str:
    """``text`` cut short with "…" to at most ``width`` pixels in a font of ``font`` pixels."""
    f = _cached_font(font)
    while len(text) > 1 and f.getlength(text) > width:
        text = text[:-2] + "…" if len(text) > 2 else text[:1]
    return text


def _overlay(rgb: np.ndarray, scene: _Scene, t: float) -> None:
    """The clock and per-robot progress bars at the top (:func:`overlay_layout`, on a pale
    band: robots reaching up there do not hide it), the scale bar and the grid's step at the
    bottom left, into picture ``rgb``."""
    result, lay = scene.result, scene.layout
    band = _pale(rgb, (0, 0, scene.size[0], lay.bottom))
    draw = ImageDraw.Draw(band)
    span = max(result.makespan, 1e-9)
    draw.text(lay.clock_at, f"t = {_hms(t)} / {_hms(span)}", fill=(20, 20, 20), font=_cached_font(lay.clock_font))
    for i, (r, cell) in enumerate(zip(result.robots, lay.cells)):
        tl = result.timelines[r.name]
        done, total = scene.printed(r.name, t)
        frac = done / (total or 1.0)
        waiting = any(a <= t < b for a, b, _ in tl.waits)
        draw.text(cell.at, cell.text, fill=_colour(i), font=_cached_font(cell.font))
        x0, y0, x1, y1 = cell.bar
        draw.rectangle(cell.bar, outline=(90, 90, 90))
        if frac > 0:  # the robot's colour in every layout
            draw.rectangle([x0, y0, x0 + round((x1 - x0) * frac), y1], fill=_colour(i))
        if waiting:  # the Gantt chart's yellow, around the bar
            draw.rectangle(cell.bar, outline=WAIT_COLOUR, width=max(2, (y1 - y0) // 4))
        if cell.state_at is not None:
            label = ("waiting" if waiting else "idle" if not total else "done" if t >= tl.end
                     else f"{100 * frac:.0f}% printed")
            draw.text(cell.state_at, label, fill=(60, 60, 60), font=_cached_font(cell.state_font), anchor="lm")
    rgb[:lay.bottom] = np.asarray(band)
    # the scale: a bar of bar_length mm across the view (true at any depth: the view is parallel)
    w, h = scene.size
    k = scene.k
    font = _cached_font(max(8, round(14 * k)))
    tick, x0, y = max(3, round(5 * k)), max(6, round(20 * k)), h - max(6, round(14 * k))
    x1 = x0 + scene.bar_length * scene.scale
    grid = f"grid {scene.grid_step:g} mm"
    right = min(w, math.ceil(x1 + 3 * tick + font.getlength(grid)) + tick)
    top = y - tick - 4 - font.size - tick
    box = _pale(rgb, (0, top, right, h))
    draw = ImageDraw.Draw(box)
    x0, x1, y = x0, x1, y - top
    draw.line([(x0, y), (x1, y)], fill=(50, 50, 50), width=max(1, round(2 * k)))
    for x in (x0, x1):
        draw.line([(x, y - tick), (x, y + 1)], fill=(50, 50, 50), width=1)
    draw.text(((x0 + x1) / 2, y - tick - 2), f"{scene.bar_length:g} mm", fill=(50, 50, 50), font=font, anchor="md")
    draw.text((x1 + 3 * tick, y), grid, fill=GRID_LABEL_COLOUR, font=font, anchor="lm")
    rgb[top:h, 0:right] = np.asarray(box)


def _pale(rgb: np.ndarray, box: tuple[int, int, int, int]) -> Image.Image:
    """The part ``box`` (x0, y0, x1, y1) of picture ``rgb`` faded three quarters to the background,
    as a Pillow picture to write on."""
    x0, y0, x1, y1 = box
    part = (rgb[y0:y1, x0:x1].astype(np.uint16) + 3 * np.array(BACKGROUND, np.uint16)) // 4
    return Image.fromarray(part.astype(np.uint8))


def _nice_length(raw: float) -> float:
    """The least of 1, 2, 5 times a power of ten at least ``raw`` (> 0)."""
    p = 10.0 ** math.floor(math.log10(raw))
    return next(m * p for m in (1, 2, 5, 10) if m * p >= raw * (1 - 1e-9))


#: Fonts by size, loaded once (a frame writes a dozen texts).
_cached_font = functools.lru_cache(maxsize=64)(_font)


#: Gantt rows: the pitch (pixels from one robot's row to the next) for few robots, the least for
#: many; the picture grows with the count rather than squeezing rows below the least.
ROW_PITCH, MIN_ROW_PITCH = 60, 18
#: Least height of the Gantt chart's header (title and legend; a title or legend that wraps
#: makes it taller, :func:`gantt_header`) and the height of its time axis, pixels.
GANTT_TOP, GANTT_AXIS = 80, 60
#: The Gantt chart's margins, pixels: the robots' names left of the bars, room for the last
#: time label right of them.
GANTT_LEFT, GANTT_RIGHT = 110, 30
#: Where a Gantt row's label starts, and the least gap between it and the bars, pixels.
GANTT_NAME_X, GANTT_NAME_GAP = 15, 10


def gantt_height(robots: int, header: int = GANTT_TOP) -> int:
    """Height of the Gantt chart of ``robots`` rows under a header ``header`` pixels tall (the
    least, :data:`GANTT_TOP`, unless its title or legend wraps): the header, one row per robot,
    the axis."""
    return header + _row_pitch(robots) * robots + GANTT_AXIS


def _row_pitch(robots: int) -> int:
    """Row pitch for ``robots`` rows: 60 px up to 8 robots, then shrinking so that the chart stays
    under about 1000 px, never below ``MIN_ROW_PITCH`` (64 robots: 18 px rows, 1.3k px tall)."""
    return max(MIN_ROW_PITCH, min(ROW_PITCH, 960 // max(robots, 1)))


Box = tuple[float, float, float, float]


@dataclass(frozen=True)
class GanttHeader:
    """Where the Gantt chart's title and legend go: each measured (``textbbox``) and placed below
    or beside the one before, never over it; a title or legend too wide for the picture wraps.

    ``title``: lines ``(x, y, text, font size)``; ``legend``: items ``(key, label, swatch box,
    label's x, y)``, key one of ``printing``, ``travelling``, ``waiting``, ``critical``, ``bound``;
    ``boxes``: the ink box of every line, swatch and label; ``bottom``: where the rows may start."""

    title: list[tuple[float, float, str, int]]
    legend: list[tuple[str, str, Box, float, float]]
    boxes: list[Box]
    bottom: int


def gantt_title(makespan: float, lower_bound: float | None = None) -> list[str]:
    """The Gantt chart's title, in parts that may go on lines of their own: the makespan (and
    the lower bound and how far above it the makespan is), in days from one day on."""
    parts = [f"makespan {_hms(makespan)} ({makespan:.0f} s)"]
    if lower_bound:
        parts.append(f"lower bound {_hms(lower_bound)} ({lower_bound:.0f} s; makespan "
                     f"{makespan / lower_bound - 1:+.1%})")
    return parts


#: The legend's labels.
LEGEND = {"printing": "printing", "travelling": "travelling (strip: share of the time)", "waiting": "waiting",
          "critical": "critical path", "bound": "lower bound"}


def gantt_header(title: Sequence[str], robots: int, width: int, critical: bool = False,
                 bound: bool = False) -> GanttHeader:
    """Lay out the Gantt chart's header in a picture ``width`` pixels wide: the ``title``'s parts
    on one line if they fit, else a line each (a part too wide alone in a smaller font, down to
    11 px), then the legend below it, its items left to right, wrapping. The printing swatch holds
    each of the ``robots``' colours; the critical path's and the lower bound's items are there
    when the chart draws them."""
    draw = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    left, right = GANTT_LEFT, width - GANTT_RIGHT
    boxes: list[Box] = []
    lines: list[tuple[float, float, str, int]] = []
    y = 10.0
    parts = list(title)
    while parts:  # as many parts on a line as fit at 20 px
        k = len(parts)
        while k > 1 and draw.textlength("   ".join(parts[:k]), font=_font(20)) > right - left:
            k -= 1
        text, parts = "   ".join(parts[:k]), parts[k:]
        size = 20
        while size > 11 and draw.textlength(text, font=_font(size)) > right - left:
            size -= 1
        box = draw.textbbox((left, y), text, font=_font(size))
        lines.append((left, y, text, size))
        boxes.append(box)
        y = box[3] + 8
    keys = ["printing", "travelling", "waiting"] + ["critical"] * critical + ["bound"] * bound
    font = _font(16)
    legend = []
    x, row_bottom = float(left), y
    for key in keys:
        sw = _swatch_width(robots) if key == "printing" else 18
        text_w = draw.textlength(LEGEND[key], font=font)
        if x > left and x + sw + 6 + text_w > right:  # the next line of the legend
            x, y = float(left), row_bottom + 6
        swatch = (x, y + 2, x + sw, y + 16)
        label = draw.textbbox((x + sw + 6, y), LEGEND[key], font=font)
        legend.append((key, LEGEND[key], swatch, x + sw + 6, y))
        boxes += [swatch, label]
        row_bottom = max(row_bottom, swatch[3], label[3])
        x = label[2] + 24
    return GanttHeader(lines, legend, boxes, int(math.ceil(row_bottom)) + 12)


def _swatch_width(robots: int) -> int:
    """Width of the printing swatch, pixels: a 14 px square per robot (2 px apart) up to 8
    robots, then stripes of at least 2 px."""
    return 16 * robots - 2 if robots <= 8 else max(2, 112 // robots) * robots


def _legend(draw: ImageDraw.ImageDraw, header: GanttHeader, colours: list[tuple[int, int, int]]) -> None:
    """Draw the header's legend: each robot's colour for printing, the travel strip, the wait,
    the critical path's frame, the lower bound's dashes."""
    font = _font(16)
    for key, label, (x0, y0, x1, y1), tx, ty in header.legend:
        if key == "printing":
            n = len(colours)
            step = 16 if n <= 8 else (x1 - x0) / n
            for i, c in enumerate(colours):
                draw.rectangle([x0 + i * step, y0, x0 + i * step + (14 if n <= 8 else step) - 1, y1], fill=c)
        elif key == "travelling":  # as in the rows: a strip under the bar
            draw.rectangle([x0, y1 - 5, x1, y1], fill=TRAVEL_COLOUR)
            draw.line([(x0, y1 - 7), (x1, y1 - 7)], fill=(215, 215, 215))
        elif key == "waiting":
            draw.rectangle([x0, y0, x1, y1], fill=WAIT_COLOUR)
        elif key == "critical":
            draw.rectangle([x0, y0 - 1, x1, y1 + 1], outline=CRITICAL_COLOUR, width=3)
        else:
            for ya in (y0, y0 + 10):
                draw.line([((x0 + x1) / 2, ya), ((x0 + x1) / 2, ya + 5)], fill=BOUND_COLOUR, width=2)
        draw.text((tx, ty), label, fill=(40, 40, 40), font=font)


def render_gantt(result: SimResult, path: str | Path, size: tuple[int, int] = (1200, 0),
                 critical: Sequence[str] | None = None, lower_bound: float | None = None) -> Path:
    """Per robot, when it prints (its colour), travels (a grey strip under the bar, as tall as
    the share of the time it travels) and waits (yellow), on one time axis.

    One row per robot (any count; rows get thinner from 9 robots on, down to ``MIN_ROW_PITCH``,
    and the picture taller, see :func:`gantt_height`). A row's upper part is the printing, at
    pixel resolution (a column is coloured where the robot printed at all); its lower strip is
    the travel, each column's grey as tall as the share of that column's time spent travelling,
    so that travel between short prints shows instead of vanishing under them. Each chunk's
    printing is labelled with its id where the bar is wide enough. The time axis is in days
    from one day on (``1 d 12:00``); the title (also the PNG's ``Title`` text) is the makespan.

    Parameters
    ----------
    size
        Width and height, pixels; height 0: :func:`gantt_height` (taller when the header wraps).
    critical
        The schedule's critical path (job.json ``schedule.critical_path``), given when the plan
        has a schedule: the printing of each chunk on the chain that set the simulated makespan
        (:func:`simulated_critical_path`, which the precedence chain alone misses where a robot's
        own order or a wait set it) is framed in red.
    lower_bound
        The schedule's lower bound LB, s (job.json ``schedule.lower_bound_s``): a dashed vertical
        line, so the distance from the simulated makespan to the best possible can be seen.
    """
    from PIL.PngImagePlugin import PngInfo

    rows = len(result.robots)
    pitch = _row_pitch(rows)
    bar = max(10, int(pitch * 2 / 3))
    strip = max(3, round(bar / 4))  # the travel strip at the bottom of the bar
    lane = bar - strip - 1  # the printing above it
    w = size[0]
    marked = set(simulated_critical_path(result)) if critical else set()
    title = gantt_title(result.makespan, lower_bound)
    header = gantt_header(title, rows, w, critical=bool(marked), bound=bool(lower_bound))
    top = max(GANTT_TOP, header.bottom)
    h = size[1] or gantt_height(rows, top)
    img = Image.new("RGB", (w, h), BACKGROUND)
    draw = ImageDraw.Draw(img)
    row_font = _font(min(16, max(10, bar - 2)))
    names, left = gantt_names([r.name for r in result.robots], row_font.size, w)
    right = w - GANTT_RIGHT
    cols = right - left
    span = max(result.makespan, lower_bound or 0.0, 1e-9)

    def x(t: np.ndarray | float) -> np.ndarray:
        return left + (np.asarray(t) / span) * cols

    for tx, ty, text, fs in header.title:
        draw.text((tx, ty), text, fill=(20, 20, 20), font=_font(fs))
    _legend(draw, header, [_colour(i) for i in range(rows)])
    label_font = _font(min(13, max(9, lane - 4)))
    for i, r in enumerate(result.robots):
        tl = result.timelines[r.name]
        y0 = top + pitch * i
        y1 = y0 + bar
        draw.text((GANTT_NAME_X, y0 + (bar - 16) / 2 if bar >= 16 else y0), names[i], fill=_colour(i), font=row_font)
        printing, travel = _column_shares(tl, span, cols)
        for a, b in _true_runs(printing > 0):
            draw.rectangle([left + a, y0, left + b - 1, y0 + lane - 1], fill=_colour(i))
        tall = np.ceil(np.minimum(travel, 1.0) * strip - 1e-9).astype(int)  # the travel's share, pixels
        if tall.any():
            band = np.arange(strip)[:, None] >= strip - tall[None, :]
            img.paste(Image.fromarray(np.where(band[..., None], np.array(TRAVEL_COLOUR, np.uint8),
                                               np.array(BACKGROUND, np.uint8)).astype(np.uint8)),
                      (left, y1 - strip))
        for a, b, _ in tl.waits:
            if b > a:
                draw.rectangle([float(x(a)), y0, float(x(b)), y1 - 1], fill=WAIT_COLOUR)
        for cid, t_a, t_b in _chunk_spans(r, tl):
            xa, xb = float(x(t_a)), float(x(t_b))
            if cid in marked:  # around the bar and its travel strip, a white line apart from a red robot's bar
                frame = [xa - 3, y0 - 3, max(xb, xa + 1) + 2, y1 + 2]
                draw.rectangle(frame, outline=CRITICAL_COLOUR, width=2)
                draw.rectangle([frame[0] + 2, frame[1] + 2, frame[2] - 2, frame[3] - 2], outline=(255, 255, 255))
            box = draw.textbbox((0, 0), cid, font=label_font)
            if xb - xa > box[2] - box[0] + 6 and lane >= 12:
                draw.text(((xa + xb) / 2, y0 + lane / 2), cid, fill=(255, 255, 255), font=label_font, anchor="mm")
    # time axis: labels centred on their ticks, the last kept inside the picture
    y = top + pitch * rows
    draw.line([(left, y), (right, y)], fill=(60, 60, 60))
    axis_font = _font(13)
    step = _nice_step(span / 8)  # about 8 labels, fewer where they would touch (a narrow picture)
    while step < span and step / span * cols < 16 + max(
            draw.textlength(_axis_label(k * step, span), font=axis_font) for k in range(int(span // step) + 1)):
        step = _nice_step(step * 1.001)
    for k in range(int(span // step) + 1):
        t = k * step
        xt = float(x(t))
        draw.line([(xt, y), (xt, y + 6)], fill=(60, 60, 60))
        text = _axis_label(t, span)
        half = draw.textlength(text, font=axis_font) / 2
        draw.text((min(max(xt, half + 2), w - half - 2), y + 8), text, fill=(60, 60, 60), font=axis_font,
                  anchor="ma")
    if lower_bound:
        xb = float(x(lower_bound))
        for ya in range(top - 6, y, 12):  # dashed
            draw.line([(xb, ya), (xb, min(ya + 6, y))], fill=BOUND_COLOUR, width=2)
    info = PngInfo()
    info.add_text("Title", "   ".join(title))
    path = Path(path)
    img.save(path, format="PNG", pnginfo=info)
    return path


def gantt_names(names: Sequence[str], font: int, width: int) -> tuple[list[str], int]:
    """The Gantt rows' labels ("robot A") in a font of ``font`` pixels and where the bars start
    (``left``, pixels) in a chart ``width`` pixels wide: :data:`GANTT_LEFT`, or further right as far
    as the widest label needs, up to a third of the picture; a label wider than that is cut short
    with "…" (never under the bars)."""
    texts = [f"robot {n}" for n in names]
    f = _cached_font(font)
    room = max(GANTT_LEFT, width // 3) - GANTT_NAME_X - GANTT_NAME_GAP
    need = max([f.getlength(t) for t in texts] + [0.0])
    left = max(GANTT_LEFT, min(math.ceil(need), room) + GANTT_NAME_X + GANTT_NAME_GAP)
    return [_cut(t, room, font) for t in texts], left


def simulated_critical_path(result: SimResult, slack: float = 1e-6) -> list[str]:
    """The chunk ids of the chain that sets the simulated makespan, last first: from the robot
    that ends last, its chunks back in time, and where it waited before a chunk for another
    robot's NOTIFY, that robot's chunks before the notice, and so on. With one robot it is all its
    chunks (its work alone sets the makespan), where the schedule's precedence chain (job.json
    ``critical_path``) would leave out a chunk that depends on no other."""
    spans = {r.name: _chunk_spans(r, result.timelines[r.name]) for r in result.robots}
    notices: dict[str, list[tuple[float, str]]] = {}
    for r in result.robots:
        for tn, event in result.timelines[r.name].notifies:
            notices.setdefault(str(event), []).append((float(tn), r.name))
    live = [r.name for r in result.robots if spans[r.name]]
    if not live:
        return []
    robot = max(live, key=lambda n: result.timelines[n].end)
    t, chain, seen = result.timelines[robot].end + slack, [], set()
    while True:
        done = [s for s in spans[robot] if s[2] <= t and s[0] not in seen]
        if not done:
            return chain
        cid, start, _ = max(done, key=lambda s: s[2])
        chain.append(cid)
        seen.add(cid)
        earlier = max([s[2] for s in spans[robot] if s[2] <= start + slack and s[0] not in seen], default=-np.inf)
        waits = [(b, ev) for a, b, ev in result.timelines[robot].waits if earlier - slack <= b <= start + slack
                 and b - a > slack]
        t = start + slack
        if waits:  # it went on when told: the chain goes on in the robot that told it
            b, events = max(waits, key=lambda w: w[0])
            told = [(tn, n) for ev in ([events] if isinstance(events, str) else list(events))
                    for tn, n in notices.get(str(ev), []) if tn <= b + slack and n != robot]
            if told:
                tn, robot = max(told)
                t = tn + slack


def _column_shares(tl, span: float, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel column of a Gantt row (``cols`` columns over ``span`` s): the share of its time
    the robot printed, and travelled (moves with the tool off), a block of moves at a time."""
    shares = np.zeros((2, cols))
    scale = cols / span
    for c in range(0, len(tl.t0), BLOCK_MOVES):
        a, b = tl.t0[c:c + BLOCK_MOVES] * scale, tl.t1[c:c + BLOCK_MOVES] * scale
        on = tl.on[c:c + BLOCK_MOVES]
        for k, sel in enumerate((on, ~on)):
            shares[k] += _coverage(a[sel], b[sel], cols)
    return shares[0], shares[1]


def _coverage(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """How much of each unit column ``[c, c + 1)``, ``c < n``, the intervals ``[a, b]`` (within
    ``[0, n]``) cover: an interval inside one column adds its length there; one across several
    adds its part to its first and last column and 1 to each between (a difference array)."""
    a, b = np.clip(a, 0, n), np.clip(b, 0, n)
    ia = np.minimum(np.floor(a), n - 1).astype(np.int64)
    ib = np.minimum(np.floor(b), n - 1).astype(np.int64)
    same = ia == ib
    out = np.zeros(n)  # (bincount of nothing is of integers)
    out += np.bincount(ia[same], weights=b[same] - a[same], minlength=n)
    ia, ib, a, b = ia[~same], ib[~same], a[~same], b[~same]
    out += np.bincount(ia, weights=ia + 1 - a, minlength=n) + np.bincount(ib, weights=b - ib, minlength=n)
    between = np.bincount(ia + 1, minlength=n + 1) - np.bincount(ib, minlength=n + 1)
    return out + np.cumsum(between)[:n]


def _true_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(start, end)`` of each run of True in ``mask`` (end exclusive)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[False], mask, [False]]).astype(np.int8)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _chunk_spans(robot, tl) -> list[tuple[str, float, float]]:
    """``(chunk id, first print start, last print end)`` of each chunk the robot prints, from its
    program's chunk column (the moves between chunks, chunk -1, belong to none)."""
    prog = robot.program
    if not len(tl.index) or not prog.chunks:
        return []
    first, last = {}, {}  # per chunk: its earliest print start and latest print end, a block of moves at a time
    for a in range(0, len(tl.index), BLOCK_MOVES):
        chunk = prog.chunk[tl.index[a:a + BLOCK_MOVES]]
        sel = tl.on[a:a + BLOCK_MOVES] & (chunk >= 0)
        k, t0, t1 = chunk[sel], tl.t0[a:a + BLOCK_MOVES][sel], tl.t1[a:a + BLOCK_MOVES][sel]
        for c in np.unique(k).tolist():
            m = k == c
            first[c] = min(first.get(c, np.inf), float(t0[m].min()))
            last[c] = max(last.get(c, -np.inf), float(t1[m].max()))
    return [(prog.chunks[c], first[c], last[c]) for c in sorted(first)]


def _runs(bars) -> list[tuple[float, float]]:
    """Intervals ``[a, b]`` (``bars``: pairs of arrays ``a``, ``b``, one after the other, sorted
    by ``a``) merged where they touch within a pixel: a run ends where the next interval starts
    more than a pixel after the furthest end so far."""
    out: list[tuple[float, float]] = []
    lo, hi = None, -np.inf  # the run under way: its start; the furthest end so far
    for a, b in bars:
        if not len(a):
            continue
        top = np.maximum(np.maximum.accumulate(b), hi)  # the furthest end up to each interval
        before = np.concatenate([[hi], top[:-1]])  # ... and before it
        for s in np.flatnonzero(a > before + 1.0).tolist():  # intervals that start a run
            if lo is not None:
                out.append((lo, float(before[s])))
            lo = float(a[s])
        hi = top[-1]
    if lo is not None:
        out.append((lo, float(hi)))
    return out


def _nice_step(raw: float) -> float:
    """The time axis's step, s: the first of 1 s ... 12 h at least ``raw``, then 1, 2, 5, 10, 20,
    50 ... days."""
    for s in (1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200, 10800, 21600, 43200, 86400):
        if s >= raw:
            return float(s)
    days = raw / DAY
    mag = 10 ** math.floor(math.log10(days))
    return DAY * next(m * mag for m in (1, 2, 5, 10) if m * mag >= days)


def _axis_label(t: float, span: float) -> str:
    """A time axis label: ``H:MM:SS`` on an axis shorter than a day, else days: ``15 d``,
    ``1 d 12:00`` (seconds only when there are any)."""
    if span < DAY:
        return _hms(t)
    d, s = divmod(int(round(t)), int(DAY))
    if not s:
        return f"{d} d"
    return f"{d} d {s // 3600:02d}:{s % 3600 // 60:02d}" + (f":{s % 60:02d}" if s % 60 else "")


__all__ = ["GanttHeader", "frame_times", "gantt_header", "gantt_height", "gantt_title", "gif_delays",
           "render_animation", "render_gantt", "render_snapshot"]
