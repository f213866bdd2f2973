"""Move durations with acceleration: trapezoidal speed profiles joined at junction speeds limited
by per-axis jerk (Marlin's classic jerk planner, as PrusaSlicer's time estimate models it).

Whole-array: the planner's backward pass ``u_i = min(m_i, u_(i+1) + 2 a_i L_i)`` (squared entry
speeds) is a min-plus recurrence, solved as a suffix minimum of ``m_j + S_j`` minus ``S_i`` with
``S`` the prefix sums of ``2 a L``; the forward pass likewise as a prefix minimum. Then every
block's time is the closed form of its trapezoid (or triangle).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
    k = len(delta)
    if k == 0:
        return np.zeros(0)
    d = np.asarray(delta, dtype=np.float64)
    xyz = np.linalg.norm(d[:, :3], axis=1)
    length = np.where(xyz > 0, xyz, np.abs(d[:, 3]))  # an E-only move's length is its E
    moving = length > 0
    safe_len = np.where(moving, length, 1.0)
    unit = d / safe_len[:, None]  # per-axis share of the move
    mf = np.asarray(limits.max_feedrate)
    share = np.abs(unit)
    with np.errstate(divide="ignore"):
        axis_cap = np.where(share > 0, mf / np.where(share > 0, share, 1.0), np.inf).min(axis=1)
    v = np.minimum(np.asarray(feed, dtype=np.float64), axis_cap)
    extruding = (d[:, 3] > 0) & (xyz > 0)
    retracting = xyz == 0
    acc = np.where(extruding, limits.acceleration_extruding,
                   np.where(retracting, limits.acceleration_retracting, limits.acceleration_travel))
    ma = np.asarray(limits.max_acceleration)
    with np.errstate(divide="ignore"):
        acc = np.minimum(acc, np.where(share > 0, ma / np.where(share > 0, share, 1.0), np.inf).min(axis=1))
    jerk = np.asarray(limits.max_jerk)
    axis_v = unit * v[:, None]  # signed per-axis speed at the nominal speed
    # the speed a block may start from or stop to at once: no axis over its jerk
    safe = np.minimum(v, np.where(np.abs(axis_v) > jerk, jerk, np.inf).min(axis=1))
    # junction speeds (classic jerk, as Marlin 1.1 and PrusaSlicer's estimator): the slower of the
    # two nominal speeds, the faster block's exit scaled down to it, then scaled by how far each
    # axis' change of speed exceeds its jerk (axis after axis, each scaling the next)
    prev_v, cur_v = v[:-1], v[1:]
    prev_larger = prev_v > cur_v
    ratio = np.where(prev_larger, cur_v / np.where(prev_v > 0, prev_v, 1.0), 1.0)
    junction = np.where(prev_larger, cur_v, prev_v)
    factor = np.ones(k - 1)
    limited = np.zeros(k - 1, dtype=bool)
    for ax in range(4):
        v_exit = axis_v[:-1, ax] * ratio * np.where(limited, factor, 1.0)
        v_entry = axis_v[1:, ax] * np.where(limited, factor, 1.0)
        change = np.where(v_exit > v_entry,
                          np.where((v_entry > 0) | (v_exit < 0), v_exit - v_entry, np.maximum(v_exit, -v_entry)),
                          np.where((v_entry < 0) | (v_exit > 0), v_entry - v_exit, np.maximum(-v_exit, v_entry)))
        over = change > jerk[ax]
        factor = np.where(over, factor * jerk[ax] / np.where(over, change, 1.0), factor)
        limited |= over
    junction = np.where(limited, junction * factor, junction)
    stop_anyway = (safe[:-1] > 0.99 * junction) & (safe[1:] > 0.99 * junction)  # not coasting
    junction = np.where(stop_anyway | (prev_v <= 0), safe[1:], junction)
    # entry speed limits (squared): the first block starts at its safe speed
    m = np.empty(k + 1)
    m[0] = safe[0] ** 2
    m[1:k] = junction ** 2
    m[k] = safe[-1] ** 2  # the last block ends at its safe speed
    c = 2.0 * acc * length
    s = np.concatenate([[0.0], np.cumsum(c)])
    u = np.minimum.accumulate((m + s)[::-1])[::-1] - s  # backward pass
    u = np.minimum(u, m)
    w = np.minimum.accumulate(u - s) + s  # forward pass
    v0, v1 = np.sqrt(np.maximum(w[:-1], 0.0)), np.sqrt(np.maximum(w[1:], 0.0))
    vmax = np.maximum(v, np.maximum(v0, v1))
    d_acc = (vmax ** 2 - v0 ** 2) / (2 * acc)
    d_dec = (vmax ** 2 - v1 ** 2) / (2 * acc)
    cruise = d_acc + d_dec <= length
    peak = np.sqrt(np.maximum((2 * acc * length + v0 ** 2 + v1 ** 2) / 2, 0.0))
    t_trap = (vmax - v0) / acc + (vmax - v1) / acc + (length - d_acc - d_dec) / np.where(vmax > 0, vmax, 1.0)
    t_tri = (peak - v0) / acc + (peak - v1) / acc
    return np.where(moving, np.where(cruise, t_trap, t_tri), 0.0)


__all__ = ["MachineLimits", "trapezoid_durations"]
