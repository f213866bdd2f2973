"""The acceleration model: closed forms, and the compiled planner against the firmware loops written in Python."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cooprint.simulation.kinematics import MachineLimits, trapezoid_durations

LIM = MachineLimits()


def test_one_long_move_accelerates_cruises_and_stops():
    # 100 mm in X at 100 mm/s, 1500 mm/s2, starting and ending at the jerk speed (10 mm/s)
    t = trapezoid_durations(np.array([[100.0, 0, 0, 0]]), np.array([100.0]), LIM)
    ramp = (100 - 10) / 1500
    ramp_mm = (100 ** 2 - 10 ** 2) / (2 * 1500)
    assert t[0] == pytest.approx(2 * ramp + (100 - 2 * ramp_mm) / 100)


def test_a_short_move_never_reaches_its_speed():
    t = trapezoid_durations(np.array([[1.0, 0, 0, 0]]), np.array([100.0]), LIM)
    peak = math.sqrt((2 * 1500 * 1.0 + 2 * 10 ** 2) / 2)
    assert t[0] == pytest.approx(2 * (peak - 10) / 1500)


def test_straight_segments_keep_their_speed_and_corners_slow_down():
    straight = trapezoid_durations(np.array([[50.0, 0, 0, 0]] * 4), np.full(4, 100.0), LIM).sum()
    single = trapezoid_durations(np.array([[200.0, 0, 0, 0]]), np.array([100.0]), LIM)[0]
    assert straight == pytest.approx(single)
    square = trapezoid_durations(np.array([[50.0, 0, 0, 0], [0, 50, 0, 0], [-50, 0, 0, 0], [0, -50, 0, 0]]),
                                 np.full(4, 100.0), LIM).sum()
    assert square > straight
    assert square == pytest.approx(4 * trapezoid_durations(np.array([[50.0, 0, 0, 0]]), np.array([100.0]),
                                                           LIM)[0], rel=0.02)  # 10 mm/s corners: near full stops


def _reference(delta, feed, lim):
    """The planner written as the loops of a firmware (per block, backward then forward)."""
    k = len(delta)
    length = np.array([np.linalg.norm(d[:3]) or abs(d[3]) for d in delta])
    unit = delta / length[:, None]
    mf, ma, mj = map(np.asarray, (lim.max_feedrate, lim.max_acceleration, lim.max_jerk))
    v = np.array([min(feed[i], *(mf[a] / abs(unit[i, a]) for a in range(4) if unit[i, a])) for i in range(k)])
    acc = []
    for i in range(k):
        base = lim.acceleration_extruding if (delta[i, 3] > 0 and np.linalg.norm(delta[i, :3]) > 0) else (
            lim.acceleration_retracting if np.linalg.norm(delta[i, :3]) == 0 else lim.acceleration_travel)
        acc.append(min(base, *(ma[a] / abs(unit[i, a]) for a in range(4) if unit[i, a])))
    axis_v = unit * v[:, None]
    safe = [min([v[i]] + [mj[a] for a in range(4) if abs(axis_v[i, a]) > mj[a]]) for i in range(k)]
    m = [safe[0] ** 2]
    for i in range(1, k):
        pv, cv = v[i - 1], v[i]
        larger = pv > cv
        vj = cv if larger else pv
        f, lim_ = 1.0, False
        for a in range(4):
            ve = axis_v[i - 1, a] * (cv / pv if larger else 1.0)
            vn = axis_v[i, a]
            if lim_:
                ve, vn = ve * f, vn * f
            if ve > vn:
                j = ve - vn if (vn > 0 or ve < 0) else max(ve, -vn)
            else:
                j = vn - ve if (vn < 0 or ve > 0) else max(-ve, vn)
            if j > mj[a]:
                f *= mj[a] / j
                lim_ = True
        if lim_:
            vj *= f
        if safe[i - 1] > 0.99 * vj and safe[i] > 0.99 * vj:
            vj = safe[i]
        m.append(vj ** 2)
    m.append(safe[-1] ** 2)
    u = m[:]
    for i in range(k - 1, -1, -1):
        u[i] = min(m[i], u[i + 1] + 2 * acc[i] * length[i])
    for i in range(k):
        u[i + 1] = min(u[i + 1], u[i] + 2 * acc[i] * length[i])
    out = []
    for i in range(k):
        v0, v1, a = math.sqrt(u[i]), math.sqrt(u[i + 1]), acc[i]
        vm = max(v[i], v0, v1)
        da, dd = (vm ** 2 - v0 ** 2) / (2 * a), (vm ** 2 - v1 ** 2) / (2 * a)
        if da + dd <= length[i]:
            out.append((vm - v0) / a + (vm - v1) / a + (length[i] - da - dd) / vm)
        else:
            p = math.sqrt((2 * a * length[i] + v0 ** 2 + v1 ** 2) / 2)
            out.append((p - v0) / a + (p - v1) / a)
    return np.array(out)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 60), st.integers(0, 2**32 - 1))
def test_the_planner_equals_the_firmware_loops(n, seed):
    rng = np.random.default_rng(seed)
    delta = np.column_stack([rng.normal(size=(n, 2)) * rng.choice([0.3, 5, 60], size=(n, 1)),
                             rng.choice([0, 0, 0.2], size=n), rng.choice([0, 0.05, -0.8], size=n)])
    delta[np.linalg.norm(delta, axis=1) == 0, 0] = 1.0
    feed = rng.choice([20.0, 45.0, 80.0, 130.0], size=n)
    np.testing.assert_allclose(trapezoid_durations(delta, feed, LIM), _reference(delta, feed, LIM), rtol=1e-9)
