"""Draw docs/img/robot_outline.png: the robot's outline as the simulator models it (run:
PYTHONPATH=src .venv/bin/python docs/make_outline_figure.py).

The boxes come from :func:`cooprint.simulation.checks.outline_boxes` (no tolerance), so the
picture is the code's model: a top view (u along the facing, from the body to the nozzle; v to
the robot's left) and a side view (u and height), each part labelled, each length named by its
profile field. The default robot, with ``frame_width`` 200 mm so that it differs from
``body_width``.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from PIL import Image, ImageDraw

from cooprint.config import load_settings
from cooprint.render.chunks import _font
from cooprint.simulation.checks import outline_boxes

OUT = Path(__file__).parent / "img" / "robot_outline.png"
COLOURS = {"body": (120, 150, 200), "frame": (150, 190, 120), "printhead": (220, 120, 90)}
INK, DIM, BG = (30, 30, 30), (90, 90, 90), (255, 255, 255)
SCALE = 0.9  # px per mm
#: Heights of the side view, mm: only for the picture (the simulator compares the parts in XY).
PRINT_TOP = 60.0  # the nozzle tip, on the top of the print
BODY_HEIGHT = 250.0
FRAME_HEIGHT = 40.0  # the frame's beam, above the printhead's underside
HEAD_HEIGHT = 120.0


def _arrow(draw: ImageDraw.ImageDraw, a: tuple[float, float], b: tuple[float, float], label: str,
           above: bool = True) -> None:
    """A dimension line from ``a`` to ``b`` with end ticks and ``label`` beside its middle."""
    draw.line([a, b], fill=DIM, width=1)
    horizontal = abs(a[1] - b[1]) < abs(a[0] - b[0])
    for p, q in ((a, b), (b, a)):
        if horizontal:
            draw.line([(p[0], p[1] - 5), (p[0], p[1] + 5)], fill=DIM, width=1)
        else:
            draw.line([(p[0] - 5, p[1]), (p[0] + 5, p[1])], fill=DIM, width=1)
        # an arrowhead at each end, pointing out to the tick: a dimension, not an edge of a part
        length = max(abs(q[0] - p[0]), abs(q[1] - p[1]))
        if length > 16:
            ex, ey = (q[0] - p[0]) / length, (q[1] - p[1]) / length
            draw.polygon([p, (p[0] + 7 * ex - 3 * ey, p[1] + 7 * ey + 3 * ex),
                          (p[0] + 7 * ex + 3 * ey, p[1] + 7 * ey - 3 * ex)], fill=DIM)
    font = _font(15)
    w = draw.textlength(label, font=font)
    mx, my = (a[0] + b[0]) / 2, (a[1] + b[1]) / 2
    if horizontal:
        draw.text((mx - w / 2, my - 24 if above else my + 6), label, fill=DIM, font=font)
    else:
        draw.text((mx + 6, my - 8), label, fill=DIM, font=font)


def main() -> None:
    robot = dataclasses.replace(load_settings().robot, frame_width=200.0)
    boxes = outline_boxes(robot, 0.0)
    bd, bl, nd, nh = robot.build_depth, robot.body_length, robot.nozzle_depth, robot.nozzle_height
    img = Image.new("RGB", (1500, 640), BG)
    draw = ImageDraw.Draw(img)
    title = _font(20)

    # top view: u to the right (the facing), v up; the nozzle at (ox, oy)
    ox, oy = 60 + (bd + bl) * SCALE, 330

    def top(u: float, v: float) -> tuple[float, float]:
        return ox + u * SCALE, oy - v * SCALE

    draw.text((40, 20), "top view (u: facing, v: left)", fill=INK, font=title)
    for part in ("body", "frame", "printhead"):
        u0, u1, v0, v1 = boxes[part]
        draw.rectangle([top(u0, v1), top(u1, v0)], fill=COLOURS[part], outline=INK, width=2)
    font = _font(17)
    draw.text(top(-bd - bl / 2, 60), "body", fill=INK, font=font)
    draw.text(top(-bd * 0.75, 8), "frame", fill=INK, font=font)
    draw.text(top(-nd - 20, -nd - 6), "printhead", fill=INK, font=font)
    nx, ny = top(0, 0)
    draw.ellipse([nx - 4, ny - 4, nx + 4, ny + 4], fill=INK)  # the nozzle
    draw.line([top(nd + 15, 0), top(nd + 70, 0)], fill=INK, width=2)  # the facing
    draw.polygon([top(nd + 70, 8), top(nd + 85, 0), top(nd + 70, -8)], fill=INK)
    draw.text(top(nd + 20, 25), "facing", fill=DIM, font=_font(15))
    bw, fw = robot.body_width, robot.resolved_frame_width
    _arrow(draw, top(-bd, bw / 2 + 25), top(0, bw / 2 + 25), "build_depth")
    _arrow(draw, top(-bd - bl, bw / 2 + 25), top(-bd, bw / 2 + 25), "body_length")
    _arrow(draw, top(-bd - bl + 40, -bw / 2), top(-bd - bl + 40, bw / 2), "body_width")
    _arrow(draw, top(-bd * 0.5, -fw / 2), top(-bd * 0.5, fw / 2), "frame_width")
    _arrow(draw, top(0, nd + 15), top(nd, nd + 15), "nozzle_depth")
    draw.text((40, 600), "the dot: the nozzle; the printhead is a square of half-side nozzle_depth around it",
              fill=DIM, font=_font(14))

    # side view: u to the right, height up; the floor at y = fy
    sx, fy = 1330, 540  # the nozzle's u, the floor

    def side(u: float, z: float) -> tuple[float, float]:
        return sx + u * SCALE * 0.75, fy - z * SCALE * 0.75

    draw.text((760, 20), "side view (u: facing, z: up)", fill=INK, font=title)
    draw.line([side(-bd - bl - 40, 0), side(nd + 60, 0)], fill=INK, width=2)  # the floor
    draw.text(side(-bd - bl - 40, -8), "floor", fill=DIM, font=_font(14))
    print_u0 = -bd + 10  # the print under the frame, up to the nozzle tip
    draw.rectangle([side(print_u0, PRINT_TOP), side(0, 0)], fill=(235, 225, 200), outline=DIM)
    draw.text(side(print_u0 + 10, PRINT_TOP / 2 + 6), "print", fill=DIM, font=_font(14))
    under = PRINT_TOP + nh  # the printhead's underside
    u0, u1, _, _ = boxes["body"]
    draw.rectangle([side(u0, BODY_HEIGHT), side(u1, 0)], fill=COLOURS["body"], outline=INK, width=2)
    draw.text(side((u0 + u1) / 2 - 20, BODY_HEIGHT / 2 + 8), "body", fill=INK, font=_font(17))
    u0, u1, _, _ = boxes["frame"]
    draw.rectangle([side(u0, under + HEAD_HEIGHT), side(u1, under + HEAD_HEIGHT - FRAME_HEIGHT)],
                   fill=COLOURS["frame"], outline=INK, width=2)
    draw.text(side((u0 + u1) / 2 - 20, under + HEAD_HEIGHT + 28), "frame", fill=INK, font=_font(17))
    u0, u1, _, _ = boxes["printhead"]
    draw.rectangle([side(u0, under + HEAD_HEIGHT), side(u1, under)], fill=COLOURS["printhead"], outline=INK, width=2)
    draw.text(side(u1 + 8, under + HEAD_HEIGHT / 2 + 8), "printhead", fill=INK, font=_font(17))
    draw.line([side(0, under), side(0, PRINT_TOP)], fill=INK, width=3)  # the nozzle
    tip = side(0, PRINT_TOP)
    draw.ellipse([tip[0] - 4, tip[1] - 4, tip[0] + 4, tip[1] + 4], fill=INK)
    _arrow(draw, side(nd + 25, PRINT_TOP), side(nd + 25, under), "nozzle_height")
    _arrow(draw, side(-bd, -25), side(0, -25), "build_depth", above=False)
    draw.text((760, 600), "heights in the side view are illustrative: the parts are vertical prisms compared in XY",
              fill=DIM, font=_font(14))
    OUT.parent.mkdir(exist_ok=True)
    img.save(OUT, format="PNG", optimize=True)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
