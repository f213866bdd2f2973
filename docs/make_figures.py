"""Regenerate the pictures in docs/img (run: .venv/bin/python docs/make_figures.py).

The seed's Fig. 5 cases, on models cooprint generates: a cylinder and a car, each with a short
build depth and a steep slope, and with a deep build depth and a moderate slope.
"""

from __future__ import annotations

from pathlib import Path

from cooprint.chunking import cut_chunks, plan_chunks
from cooprint.config import ChunkingSettings, RobotProfile
from cooprint.models import car, cylinder
from cooprint.render.chunks import render_chunks

IMG = Path(__file__).parent / "img"

CASES = {
    "fig5a_cylinder_short_steep": (lambda: cylinder(150, 80), RobotProfile(build_depth=120), None),
    "fig5b_cylinder_deep_moderate": (lambda: cylinder(150, 80), RobotProfile(build_depth=300), 45.0),
    "fig5c_car_short_steep": (lambda: car(700), RobotProfile(build_depth=180), None),
    "fig5d_car_deep_moderate": (lambda: car(700), RobotProfile(build_depth=400), 50.0),
}


def main() -> None:
    IMG.mkdir(exist_ok=True)
    for name, (make, robot, theta) in CASES.items():
        solid = make()
        plan = plan_chunks(solid.vertices, robot, ChunkingSettings(theta_deg=theta))
        chunks = cut_chunks(solid, plan)
        render_chunks(chunks, IMG / f"{name}.png", size=(900, 560))
        print(f"{name}: {len(chunks.chunks)} chunks, theta {plan.theta_deg:.1f} deg, "
              f"shift {plan.shift:.1f} mm, build depth {robot.build_depth:g} mm")


if __name__ == "__main__":
    main()
