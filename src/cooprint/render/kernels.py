"""Compiled loops of the fleet's pictures (numba, one core): lines and faces drawn into numpy
pictures with a depth beside the colour.

A snapshot or a frame of an animation is an (h, w, 3) uint8 picture and an (h, w) float32 depth
picture: each pixel of material holds the depth of the segment drawn there, at that pixel
(towards the camera, mm; larger is nearer; :data:`NO_DEPTH` where there is none). The material is drawn as 1-pixel
lines (an animation adds a frame's new segments to the picture it keeps); the robots' boxes as
flat faces, far to near, each pixel of a face against the material's depth there: behind the
material it is left out, in front of it the material shows through. Per-pixel loops in Python
or whole-array passes (a temporary of every pixel for every face) would cost more than a frame
has; these run in a few milliseconds.
"""

from __future__ import annotations

import numba
import numpy as np

from cooprint import jit

jit.setup()  # Ctrl-C held while numba compiles; LLVM calls untimed (cooprint.jit)

_jit = numba.njit(cache=True, nogil=True)
_inline = numba.njit(cache=True, nogil=True, inline="always")

#: The depth of a pixel without material (all material is nearer).
NO_DEPTH = np.float32(-1e30)


@_inline
def _clip(x0, y0, x1, y1, w, h):
    """The part of segment ``(x0, y0)``-``(x1, y1)`` within the picture's pixel centres
    (Liang-Barsky on ``[-0.5, w - 0.5] x [-0.5, h - 0.5]``): ``(ta, tb)`` along it, ``ta > tb``
    when it misses the picture."""
    ta, tb = 0.0, 1.0
    dx, dy = x1 - x0, y1 - y0
    for p, q in ((-dx, x0 + 0.5), (dx, w - 0.5 - x0), (-dy, y0 + 0.5), (dy, h - 0.5 - y0)):
        if p == 0.0:
            if q < 0.0:
                return 1.0, 0.0
        else:
            r = q / p
            if p < 0.0:
                ta = max(ta, r)
            else:
                tb = min(tb, r)
    return ta, tb


@_jit
def draw_lines(rgb, depth, ends, colours, near, write_depth):
    """Segments ``ends`` (k, 4) float64 (pixel ``x0, y0, x1, y1``) as 1-pixel lines, in order
    (a later one over an earlier), each in ``colours`` (k, 3) uint8; with ``write_depth``, the
    depth under each pixel into ``depth``: from ``near[s, 0]`` at the segment's start to
    ``near[s, 1]`` at its end (k, 2) float32, linearly. A line's pixels: its points at unit steps
    along its longer axis, rounded (its part within the picture)."""
    h, w = depth.shape
    for s in range(len(ends)):
        x0, y0, x1, y1 = ends[s, 0], ends[s, 1], ends[s, 2], ends[s, 3]
        ta, tb = _clip(x0, y0, x1, y1, w, h)
        if ta > tb:
            continue
        dx, dy = x1 - x0, y1 - y0
        xa, ya, xb, yb = x0 + ta * dx, y0 + ta * dy, x0 + tb * dx, y0 + tb * dy
        da, db = near[s, 0] + ta * (near[s, 1] - near[s, 0]), near[s, 0] + tb * (near[s, 1] - near[s, 0])
        steps = int(max(abs(np.floor(xb + 0.5) - np.floor(xa + 0.5)), abs(np.floor(yb + 0.5) - np.floor(ya + 0.5))))
        r, g, b = colours[s, 0], colours[s, 1], colours[s, 2]
        for k in range(steps + 1):
            f = k / steps if steps else 0.0
            x = int(np.floor(xa + f * (xb - xa) + 0.5))
            y = int(np.floor(ya + f * (yb - ya) + 0.5))
            if 0 <= x < w and 0 <= y < h:
                row = rgb[y]
                row[x, 0], row[x, 1], row[x, 2] = r, g, b
                if write_depth:
                    depth[y, x] = da + f * (db - da)


@_inline
def _paint(out, base, depth, x, y, d, r, g, b, alpha):
    """Pixel ``(x, y)`` of a robot's face at depth ``d``: left out where the material is in
    front; ``alpha`` of the colour ``(r, g, b)`` over the material (``base``) where it is
    behind; else the colour."""
    m = depth[y, x]
    if m > d:
        return
    if m > -1e29:
        out[y, x, 0] = np.uint8(alpha * r + (1.0 - alpha) * base[y, x, 0] + 0.5)
        out[y, x, 1] = np.uint8(alpha * g + (1.0 - alpha) * base[y, x, 1] + 0.5)
        out[y, x, 2] = np.uint8(alpha * b + (1.0 - alpha) * base[y, x, 2] + 0.5)
    else:
        out[y, x, 0], out[y, x, 1], out[y, x, 2] = r, g, b


@_jit
def draw_faces(out, base, depth, quads, planes, fills, edges, alpha, edge_alpha, back):
    """Convex faces ``quads`` (m, 4, 2) float64 (pixel corners in order round each) into ``out``,
    in order (far to near), each filled in ``fills`` (m, 3) uint8 and outlined in ``edges`` (m, 3),
    pixel by pixel at its depth ``planes[f] . (x, y, 1)`` against the material's ``depth``
    (:func:`_paint`: over the material ``alpha[f]`` (m,) of a fill, ``edge_alpha`` of an outline;
    elsewhere ``back[f]`` (m,) of a fill (1: opaque); the rest from ``base``, the picture before
    any face, so that a nearer face replaces a farther one).
    A face's pixels: the pixel centres of each row within half a pixel of it."""
    h, w = depth.shape
    for f in range(len(quads)):
        a, b, c0 = planes[f, 0], planes[f, 1], planes[f, 2]
        fr, fg, fb = fills[f, 0], fills[f, 1], fills[f, 2]
        fa, bk = alpha[f], back[f]
        lo_y, hi_y = quads[f, :, 1].min(), quads[f, :, 1].max()
        for y in range(max(int(np.ceil(lo_y)), 0), min(int(np.floor(hi_y)), h - 1) + 1):
            xl, xr = np.inf, -np.inf
            for e in range(4):
                px, py = quads[f, e, 0], quads[f, e, 1]
                qx, qy = quads[f, (e + 1) % 4, 0], quads[f, (e + 1) % 4, 1]
                if min(py, qy) <= y <= max(py, qy):
                    if py == qy:
                        xl, xr = min(xl, px, qx), max(xr, px, qx)
                    else:
                        x = px + (y - py) * (qx - px) / (qy - py)
                        xl, xr = min(xl, x), max(xr, x)
            at = b * y + c0
            orow, brow, drow = out[y], base[y], depth[y]  # rows: faster than 3-d indexing
            for x in range(max(int(np.ceil(xl - 0.5)), 0), min(int(np.floor(xr + 0.5)), w - 1) + 1):
                m = drow[x]
                if m > a * x + at:  # the material in front
                    continue
                k = fa if m > -1e29 else bk
                if k < 1.0:
                    orow[x, 0] = np.uint8(k * fr + (1.0 - k) * brow[x, 0] + 0.5)
                    orow[x, 1] = np.uint8(k * fg + (1.0 - k) * brow[x, 1] + 0.5)
                    orow[x, 2] = np.uint8(k * fb + (1.0 - k) * brow[x, 2] + 0.5)
                else:
                    orow[x, 0], orow[x, 1], orow[x, 2] = fr, fg, fb
        er, eg, eb = edges[f, 0], edges[f, 1], edges[f, 2]
        for e in range(4):
            x0, y0 = quads[f, e, 0], quads[f, e, 1]
            x1, y1 = quads[f, (e + 1) % 4, 0], quads[f, (e + 1) % 4, 1]
            ta, tb = _clip(x0, y0, x1, y1, w, h)
            if ta > tb:
                continue
            xa, ya, xb, yb = x0 + ta * (x1 - x0), y0 + ta * (y1 - y0), x0 + tb * (x1 - x0), y0 + tb * (y1 - y0)
            steps = int(max(abs(np.floor(xb + 0.5) - np.floor(xa + 0.5)), abs(np.floor(yb + 0.5) - np.floor(ya + 0.5))))
            for k in range(steps + 1):
                t = k / steps if steps else 0.0
                x = int(np.floor(xa + t * (xb - xa) + 0.5))
                y = int(np.floor(ya + t * (yb - ya) + 0.5))
                if 0 <= x < w and 0 <= y < h:
                    _paint(out, base, depth, x, y, a * x + b * y + c0, er, eg, eb, edge_alpha)


@_jit
def draw_dot(out, cx, cy, radius, fill, ring):
    """A dot of ``radius`` pixels at ``(cx, cy)``: ``fill`` inside a 1-pixel ``ring``."""
    h, w = out.shape[:2]
    for y in range(max(int(np.floor(cy - radius)), 0), min(int(np.ceil(cy + radius)), h - 1) + 1):
        for x in range(max(int(np.floor(cx - radius)), 0), min(int(np.ceil(cx + radius)), w - 1) + 1):
            r = np.hypot(x - cx, y - cy)
            if r <= radius:
                colour = fill if r <= radius - 1.2 else ring
                for c in range(3):
                    out[y, x, c] = colour[c]
