"""Move durations with acceleration: trapezoidal speed profiles joined at junction speeds limited
by per-axis jerk (Marlin's classic jerk planner, as PrusaSlicer's time estimate models it).

Whole-array: the planner's backward pass ``u_i = min(m_i, u_(i+1) + 2 a_i L_i)`` (squared entry
speeds) is a min-plus recurrence, solved as a suffix minimum of ``m_j + S_j`` minus ``S_i`` with
``S`` the prefix sums of ``2 a L``; the forward pass likewise as a prefix minimum. Then every
block's time is the closed form of its trapezoid (or triangle).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from cooprint import jit

jit.setup()  # Ctrl-C held while numba compiles; LLVM calls untimed (cooprint.jit)


@dataclass(frozen=True)
class MachineLimits:
    """Acceleration, speed and jerk limits, mm/s^2 and mm/s, axes X, Y, Z, E.

    The defaults are PrusaSlicer 2.5's machine limits, normal mode (those its G-code states).
    """

    acceleration_extruding: float = 1500.0
    acceleration_retracting: float = 1500.0
    acceleration_travel: float = 1500.0
    max_acceleration: tuple[float, float, float, float] = (9000.0, 9000.0, 500.0, 10000.0)
    max_feedrate: tuple[float, float, float, float] = (500.0, 500.0, 12.0, 120.0)
    max_jerk: tuple[float, float, float, float] = (10.0, 10.0, 0.2, 2.5)

    @staticmethod
    def planar(acceleration: float, jerk: float) -> "MachineLimits":
        """A robot that drives in XY and lifts in Z: one acceleration, one jerk, no other limit."""
        big = 1e9
        return MachineLimits(acceleration, acceleration, acceleration, (big, big, big, big), (big, big, big, big),
                             (jerk, jerk, jerk, big))


def trapezoid_durations(delta: np.ndarray, feed: np.ndarray, limits: MachineLimits) -> np.ndarray:
    """Durations (k,) of consecutive moves with acceleration.

    Parameters
    ----------
    delta : (k, 4) float
        Each move's X, Y, Z and E change, mm.
    feed : (k,) float
        Each move's requested speed, mm/s.
    """
    d = np.ascontiguousarray(delta, dtype=np.float64).reshape(-1, 4)
    accel = np.array([limits.acceleration_extruding, limits.acceleration_retracting, limits.acceleration_travel])
    return _plan(d, np.ascontiguousarray(feed, dtype=np.float64), accel, np.asarray(limits.max_acceleration, float),
                 np.asarray(limits.max_feedrate, float), np.asarray(limits.max_jerk, float))


@numba.njit(cache=True, nogil=True)
def _plan(d, feed, accel, max_acc, max_feed, jerk):
    """The planner of :func:`trapezoid_durations`, move by move: each block's nominal speed,
    acceleration and safe speed and the junction speed with the block before (classic jerk, as
    Marlin 1.1 and PrusaSlicer's estimator), the backward and forward passes over the squared
    entry speeds, then every block's trapezoid (or triangle)."""
    k = len(d)
    length = np.empty(k)
    v = np.empty(k)
    acc = np.empty(k)
    m = np.empty(k + 1)  # entry speed limits, squared; the last: the end of the last block
    prev_axis = np.zeros(4)
    axis = np.zeros(4)
    prev_v, prev_safe = 0.0, 0.0
    for i in range(k):
        xyz = np.sqrt(d[i, 0] ** 2 + d[i, 1] ** 2 + d[i, 2] ** 2)
        n = xyz if xyz > 0 else abs(d[i, 3])  # an E-only move's length is its E
        length[i] = n
        cap, acap = np.inf, np.inf
        for a in range(4):
            share = abs(d[i, a] / n) if n > 0 else 0.0  # the axis' share of the move
            if share > 0:
                cap = min(cap, max_feed[a] / share)
                acap = min(acap, max_acc[a] / share)
        vi = min(feed[i], cap)
        v[i] = vi
        base = accel[0] if (d[i, 3] > 0 and xyz > 0) else (accel[1] if xyz == 0 else accel[2])
        acc[i] = min(base, acap)
        safe = vi  # the speed it may start from or stop to at once: no axis over its jerk
        for a in range(4):
            axis[a] = (d[i, a] / n if n > 0 else 0.0) * vi
            if abs(axis[a]) > jerk[a]:
                safe = min(safe, jerk[a])
        if i == 0:
            m[0] = safe * safe
        else:  # the junction with the block before: the slower nominal speed, scaled by the jerk
            larger = prev_v > vi
            ratio = (vi / (prev_v if prev_v > 0 else 1.0)) if larger else 1.0
            junction = vi if larger else prev_v
            factor, limited = 1.0, False
            for a in range(4):
                scale = factor if limited else 1.0
                v_exit, v_entry = prev_axis[a] * ratio * scale, axis[a] * scale
                if v_exit > v_entry:
                    change = v_exit - v_entry if (v_entry > 0 or v_exit < 0) else max(v_exit, -v_entry)
                else:
                    change = v_entry - v_exit if (v_entry < 0 or v_exit > 0) else max(-v_exit, v_entry)
                if change > jerk[a]:
                    factor *= jerk[a] / change
                    limited = True
            if limited:
                junction *= factor
            if (prev_safe > 0.99 * junction and safe > 0.99 * junction) or prev_v <= 0:
                junction = safe  # not coasting: from the safe speed
            m[i] = junction * junction
        for a in range(4):
            prev_axis[a] = axis[a]
        prev_v, prev_safe = vi, safe
    if k:
        m[k] = prev_safe * prev_safe  # the last block ends at its safe speed
    for i in range(k - 1, -1, -1):  # backward: every block can slow down to the next one's entry
        m[i] = min(m[i], m[i + 1] + 2.0 * acc[i] * length[i])
    for i in range(k):  # forward: and speed up from its own
        m[i + 1] = min(m[i + 1], m[i] + 2.0 * acc[i] * length[i])
    out = np.zeros(k)
    for i in range(k):
        n, a = length[i], acc[i]
        if not n > 0:
            continue
        v0, v1 = np.sqrt(max(m[i], 0.0)), np.sqrt(max(m[i + 1], 0.0))
        vmax = max(v[i], v0, v1)
        d_acc, d_dec = (vmax * vmax - v0 * v0) / (2 * a), (vmax * vmax - v1 * v1) / (2 * a)
        if d_acc + d_dec <= n:
            out[i] = (vmax - v0) / a + (vmax - v1) / a + (n - d_acc - d_dec) / (vmax if vmax > 0 else 1.0)
        else:
            peak = np.sqrt(max((2 * a * n + v0 * v0 + v1 * v1) / 2, 0.0))
            out[i] = (peak - v0) / a + (peak - v1) / a
    return out


__all__ = ["MachineLimits", "trapezoid_durations"]
