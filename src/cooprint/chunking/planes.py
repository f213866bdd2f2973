"""Where to cut: slope limits (seed eq. 1-2) and the chunking planes (seed eq. 3-5).

Frame
-----
The centre line runs horizontally in direction ``u`` (default +X) through ``p_c`` (the bounding-box
centre at the object's lowest z, moved by ``centre_offset`` along ``c``). Chunks follow the
horizontal normal ``c = z x u`` (default +Y). For a point ``x`` let ``t = (x - p_c) . c`` and
``z' = x_z - z_min``; with ``cot = 1 / tan(theta)``:

* right side (+c):  ``g_R(x) = t + z' cot``,   left side (-c):  ``g_L(x) = -t + z' cot``.
* plane R_k is ``g_R = a + k s`` and plane L_k is ``g_L = a + k s`` (k = 0, 1, ...), with
  ``a = h cot + top_width / 2``. Planes R_0 and L_0 bound the centre chunk C (seed eq. 3-4);
  the shifted planes (seed eq. 5: ``p_{i+1} = p_i + s c``) cut R1, R2, ... and L1, L2, ...

Every plane contains ``u`` and rises at ``theta`` towards the centre, so every sloped face
*recedes as it rises*: the centre chunk is ``2a`` wide at its base and ``top_width`` wide at the
object's top, and each side chunk leans on the face of the chunk before it. This is the
orientation in which the next chunk's printhead clears the face (``theta <= theta_max``), which a
literal reading of the signs in eq. (3)-(4) does not give.

Reach: a robot prints a chunk from its unprinted (outer) side, its body's front no closer than the
chunk's outer base edge, so everything it deposits lies within ``build_depth`` of that edge:
``2a <= bd`` for the centre chunk and ``s + h cot <= bd`` for a side chunk (hence the default
``s = bd - h cot``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from cooprint.config import ChunkingSettings, RobotProfile
from cooprint.errors import InfeasibleError

#: Relative slack when deciding whether the mesh reaches past a plane (avoids sliver chunks).
PLANE_EPS = 1e-6


@dataclass(frozen=True)
class SlopeLimits:
    """Seed eq. (1)-(2), degrees."""

    theta_min_deg: float
    theta_max_deg: float

    @property
    def feasible(self) -> bool:
        return self.theta_min_deg <= self.theta_max_deg


def slope_limits(robot: RobotProfile, height: float) -> SlopeLimits:
    """``theta_max = atan(nh / nd)`` (printhead clears printed material) and
    ``theta_min = atan(h / bd)`` (front wheels stay off printed material), degrees."""
    return SlopeLimits(
        theta_min_deg=math.degrees(math.atan2(height, robot.build_depth)),
        theta_max_deg=math.degrees(math.atan2(robot.nozzle_height, robot.nozzle_depth)),
    )


@dataclass(frozen=True)
class Plane:
    """An oriented plane: ``point`` (3,) on it and unit ``normal`` (3,), mm."""

    point: tuple[float, float, float]
    normal: tuple[float, float, float]

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """(n,) float64 distance of (n, 3) points along the normal."""
        return (np.asarray(points, dtype=np.float64) - self.point) @ np.asarray(self.normal)

    @property
    def offset(self) -> float:
        """Distance of the plane from the origin along its normal (manifold3d's convention)."""
        return float(np.dot(self.point, self.normal))

    def flipped(self) -> Plane:
        return Plane(self.point, tuple(-x for x in self.normal))  # type: ignore[arg-type]

    def to_dict(self) -> dict[str, list[float]]:
        return {"point": list(self.point), "normal": list(self.normal)}


@dataclass(frozen=True)
class ChunkPlan:
    """The geometry of a chunking job, before any cut is made.

    Attributes
    ----------
    theta_deg, shift, top_width, height
        Slope (deg), plane spacing ``s``, centre chunk top width and object height, mm.
    limits
        Seed eq. (1)-(2) for this robot and object.
    centre : (3,) float
        ``p_c``, on the centre line at the object's lowest z.
    axis : (3,) float
        ``c``, the horizontal chunking direction (unit).
    half_base : float
        ``a = h cot(theta) + top_width / 2``.
    n_right, n_left : int
        Number of side chunks on each side (0 when the object does not reach past the centre chunk).
    """

    theta_deg: float
    shift: float
    top_width: float
    height: float
    limits: SlopeLimits
    centre: tuple[float, float, float]
    axis: tuple[float, float, float]
    half_base: float
    n_right: int
    n_left: int
    build_depth: float

    @property
    def run(self) -> float:
        """Horizontal run of a sloped face over the object's height, ``h / tan(theta)``."""
        return self.height / math.tan(math.radians(self.theta_deg))

    def plane(self, side: str, k: int) -> Plane:
        """Plane R_k (``side='R'``) or L_k (``side='L'``), normal pointing away from the centre chunk."""
        th = math.radians(self.theta_deg)
        c = np.asarray(self.axis)
        sgn = 1.0 if side == "R" else -1.0
        normal = sgn * math.sin(th) * c + np.array([0.0, 0.0, math.cos(th)])
        point = np.asarray(self.centre) + sgn * (self.half_base + k * self.shift) * c
        return Plane(tuple(float(x) for x in point), tuple(float(x) for x in normal))  # type: ignore[arg-type]

    def side_coordinate(self, side: str, points: np.ndarray) -> np.ndarray:
        """``g_R`` or ``g_L`` of (n, 3) points: which plane index a point falls between."""
        p = np.asarray(points, dtype=np.float64) - self.centre
        t = p @ np.asarray(self.axis)
        cot = 1.0 / math.tan(math.radians(self.theta_deg))
        return (t if side == "R" else -t) + p[:, 2] * cot

    def to_dict(self) -> dict[str, object]:
        return {
            "theta_deg": self.theta_deg, "shift_mm": self.shift, "top_width_mm": self.top_width,
            "height_mm": self.height, "theta_min_deg": self.limits.theta_min_deg,
            "theta_max_deg": self.limits.theta_max_deg, "centre": list(self.centre),
            "axis": list(self.axis), "half_base_mm": self.half_base,
            "centre_base_width_mm": 2 * self.half_base, "side_reach_mm": self.shift + self.run,
            "build_depth_mm": self.build_depth, "n_left": self.n_left, "n_right": self.n_right,
        }


def plan_chunks(vertices: np.ndarray, robot: RobotProfile, settings: ChunkingSettings) -> ChunkPlan:
    """Choose the slope, the shift and the number of chunks for a mesh and a robot.

    Parameters
    ----------
    vertices : (n, 3) float64
        The solid's vertices, mm (only their extent matters).

    Raises
    ------
    InfeasibleError
        With the numbers: slope outside [theta_min, theta_max], a robot for which
        theta_min > theta_max, a centre chunk wider than the build depth, or a shift that does
        not fit the build depth.
    """
    v = np.asarray(vertices, dtype=np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    h = float(hi[2] - lo[2])
    if h <= 0:
        raise InfeasibleError("the object has no height (all vertices at one z)")
    lim = slope_limits(robot, h)
    bd = robot.build_depth
    formula = (f"theta_min = atan(h/bd) = atan({h:.1f}/{bd:g}) = {lim.theta_min_deg:.2f} deg, "
               f"theta_max = atan(nh/nd) = atan({robot.nozzle_height:g}/{robot.nozzle_depth:g}) = "
               f"{lim.theta_max_deg:.2f} deg")
    if not lim.feasible:
        raise InfeasibleError(f"robot '{robot.name}' cannot print this object: {formula}; "
                              "theta_min > theta_max (a deeper build depth or a taller nozzle is needed)")
    theta = lim.theta_max_deg if settings.theta_deg is None else settings.theta_deg
    if not lim.theta_min_deg < theta <= lim.theta_max_deg + 1e-9:
        raise InfeasibleError(f"chunking.theta_deg = {theta:g} is outside the printable range "
                              f"({lim.theta_min_deg:.2f}, {lim.theta_max_deg:.2f}] deg: {formula}")
    run = h / math.tan(math.radians(theta))
    a = run + settings.top_width / 2
    if 2 * a > bd * (1 + 1e-9):
        raise InfeasibleError(
            f"centre chunk base width 2*h/tan(theta) + top_width = 2*{run:.1f} + {settings.top_width:g} "
            f"= {2 * a:.1f} mm exceeds build depth {bd:g} mm; use a steeper slope (theta up to "
            f"{lim.theta_max_deg:.2f} deg), a smaller top_width, or a robot with a deeper build depth")
    s = bd - run if settings.shift is None else settings.shift
    if s <= 0:
        raise InfeasibleError(f"shift s = bd - h/tan(theta) = {bd:g} - {run:.1f} = {s:.2f} mm: no room "
                              f"for side chunks; use a steeper slope (up to {lim.theta_max_deg:.2f} deg)")
    if s + run > bd * (1 + 1e-9):
        raise InfeasibleError(f"chunking.shift = {s:g} mm: a side chunk would need reach s + h/tan(theta) "
                              f"= {s + run:.1f} mm > build depth {bd:g} mm; use shift <= {bd - run:.1f}")

    ang = math.radians(settings.centre_angle_deg)
    axis = np.array([-math.sin(ang), math.cos(ang), 0.0])
    centre = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]]) + settings.centre_offset * axis
    plan = ChunkPlan(theta, s, settings.top_width, h, lim, tuple(float(x) for x in centre),  # type: ignore[arg-type]
                     tuple(float(x) for x in axis), a, 0, 0, bd)  # type: ignore[arg-type]
    counts = {}
    for side in ("R", "L"):
        reach = float(plan.side_coordinate(side, v).max()) - a
        counts[side] = max(0, math.ceil(reach / s - PLANE_EPS)) if reach > PLANE_EPS * s else 0
    return replace(plan, n_right=counts["R"], n_left=counts["L"])
