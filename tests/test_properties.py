"""Property tests: invariants of the chunker over slopes, shifts, centre lines and shapes."""

import math

import numpy as np
import pytest

from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from cooprint.chunking import cut_chunks, plan_chunks
from cooprint.config import ChunkingSettings, RobotProfile
from cooprint.io.mesh import solid_from_trimesh

from solids import box, car, cylinder, lying_tube, thin_walls, to_trimesh, tube
from test_chunking import assert_valid_chunkset, check_physics

ROBOT = RobotProfile(build_depth=500.0, nozzle_height=100.0, nozzle_depth=20.0)
SHAPES = {
    "box": lambda: box(40, 300, 30), "car": car, "cylinder": lambda: cylinder(40, 80),
    "tube": lambda: tube(50, 30, 60), "lying_tube": lying_tube, "thin_walls": thin_walls,
}


@pytest.fixture(scope="module")
def solids():
    """Solids built once per module, released at its end (manifold3d objects must not outlive it)."""
    cache: dict = {}

    def get(name):
        if name not in cache:
            cache[name] = solid_from_trimesh(to_trimesh(SHAPES[name]()))
        return cache[name]

    yield get
    cache.clear()


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.sampled_from(sorted(SHAPES)), theta_frac=st.floats(0.05, 1.0),
       shift_frac=st.floats(0.05, 1.0), angle=st.sampled_from([0.0, 30.0, 90.0, -45.0]),
       offset=st.floats(-60, 60), top=st.floats(0, 30))
# a plane grazing the tube's end face: a cap triangle and a face wound both ways (found by hypothesis)
@example(name="lying_tube", theta_frac=0.15, shift_frac=0.05128074276867614, angle=30.0,
         offset=25.57892294401853, top=9.431640625)
def test_chunking_invariants(solids, name, theta_frac, shift_frac, angle, offset, top):
    s = solids(name)
    h = s.bounds[1, 2] - s.bounds[0, 2]
    tmin = math.degrees(math.atan2(h, ROBOT.build_depth))
    tmax = math.degrees(math.atan2(ROBOT.nozzle_height, ROBOT.nozzle_depth))
    theta = tmin + (tmax - tmin) * theta_frac
    run = h / math.tan(math.radians(theta))
    if 2 * run + top > ROBOT.build_depth:
        top = 0.0
    if 2 * run > ROBOT.build_depth:
        theta = tmax
        run = h / math.tan(math.radians(theta))
    shift = max((ROBOT.build_depth - run) * shift_frac, 15.0)
    ang = math.radians(angle)  # the centre line stays within the part's extent along the axis (the rule)
    extent = float(np.ptp(s.vertices[:, :2] @ np.array([-math.sin(ang), math.cos(ang)])))
    offset = max(-extent, min(extent, offset))
    cfg = ChunkingSettings(theta_deg=theta, shift=shift, top_width=top, centre_angle_deg=angle,
                           centre_offset=offset)
    cs = cut_chunks(s, plan_chunks(s.vertices, ROBOT, cfg))
    assert_valid_chunkset(s, cs)
    check_physics(cs, ROBOT, tol=1e-6)
