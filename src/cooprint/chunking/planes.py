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

Feasibility (:func:`feasibility`, the one rule of ``info``, ``chunk`` and ``run``): a part whose
extent along ``c`` fits the build depth is one chunk, no cut, printable up to ``robot.max_z``
(unless a slope or shift is set); otherwise the limits above, which bound the part's height by
``(bd - top_width) tan(theta_max) / 2``. The record states that largest printable height and the
changes that would make a refused part printable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

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
    mode : str
        ``cut`` (the seed's planes) or ``whole`` (the part fits the build depth: one chunk C, no
        cut; ``theta_deg`` is then theta_max and ``shift`` the build depth, for the record only).
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
    mode: str = "cut"

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
            "mode": self.mode,
        }


#: Most chunks a plan may have (the shift is at least 5 mm, so a part 5 m across stays below).
MAX_CHUNKS = 1000


@dataclass(frozen=True)
class Feasibility:
    """Whether and how a robot can print a part: the one rule ``info``, ``chunk`` and ``run``
    share (:func:`feasibility`).

    Attributes
    ----------
    feasible
        The part can be planned with these settings.
    mode
        ``whole`` (one chunk, no cut: the part fits the build depth) or ``cut`` (the seed's
        sloped planes).
    reason
        One sentence with the numbers: why it is (not) feasible.
    height, extent
        The part's height and its extent along the chunking axis, mm.
    max_height
        The largest part height this robot can print in this mode with these settings, mm.
    chunks
        Number of chunks the plan gives (0 when infeasible).
    theta_deg, theta_min_deg, theta_max_deg
        The slope used and the seed's limits (eq. 1-2) for this part.
    hints
        Changes that would make it feasible, each actually possible (the robot field or setting
        and the value it needs).
    """

    feasible: bool
    mode: str
    reason: str
    height: float
    extent: float
    max_height: float
    chunks: int
    theta_deg: float
    theta_min_deg: float
    theta_max_deg: float
    hints: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, object]:
        return {"feasible": self.feasible, "mode": self.mode, "reason": self.reason, "height_mm": self.height,
                "extent_mm": self.extent, "max_height_mm": self.max_height, "chunks": self.chunks,
                "theta_deg": self.theta_deg, "theta_min_deg": self.theta_min_deg,
                "theta_max_deg": self.theta_max_deg, "hints": list(self.hints)}

    def message(self) -> str:
        """The refusal line: reason, largest printable height, hints."""
        text = f"{self.reason}; largest printable height {mm(self.max_height)} mm (part {self.height:.1f})"
        hints = list(self.hints)
        while hints and len(text) + len("; fix: " + " or ".join(hints)) > MAX_MESSAGE:
            hints.pop()  # the first hints are the nearest changes; the line stays whole
        return text + (f"; fix: {' or '.join(hints)}" if hints else "")


#: Longest refusal line (reason, largest height, hints): a message a terminal shows whole.
MAX_MESSAGE = 230  # and "cooprint: error: " before it: under 250 characters


def mm(x: float) -> str:
    """A length for a message: one decimal, or 3 significant digits below 1 mm (0.00550, not 0.0)."""
    return f"{x:.1f}" if abs(x) >= 1 or x == 0 else f"{x:.3g}"


def _bound(x: float, up: bool) -> str:
    """``x`` to 4 significant digits, rounded up (a ``>=`` hint) or down (a ``<=`` hint) so that
    the value shown satisfies the hint; small values keep their digits (0.00916, not 0.0)."""
    if x == 0 or not math.isfinite(x):
        return f"{x:g}"
    e = math.floor(math.log10(abs(x))) - 3
    q = 10.0 ** e
    v = (math.ceil(x / q - 1e-9) if up else math.floor(x / q + 1e-9)) * q
    return f"{v:.10g}"


def _in_range(cls: type, name: str, value: float) -> bool:
    """Whether ``value`` is a valid value of settings field ``name`` of ``cls`` (its metadata
    range): a fix hint outside it could not be followed."""
    meta = next(f.metadata for f in fields(cls) if f.name == name)
    lo, hi = meta.get("lo"), meta.get("hi")
    if lo is not None and (value <= lo if meta.get("lo_open") else value < lo):
        return False
    return hi is None or value <= hi


def _hint(cls: type, field_name: str, section: str, op: str, value: float, now: float | None = None,
          unit: str = "") -> tuple[str, ...]:
    """``("robot.build_depth >= 751",)``, or ``()`` when the bound shown lies outside
    the field's valid range (no hint that cannot be followed)."""
    text = _bound(value, up=op == ">=")
    if not math.isfinite(value) or not _in_range(cls, field_name, float(text)):
        return ()
    return (f"{section}.{field_name} {op} {text}{unit}",)  # (the value now: in the reason or the settings)


def _scale_hint(max_h: float, h: float) -> tuple[str, ...]:
    """``--scale F`` that brings a part ``h`` tall down to ``max_h`` (F rounded down, 3 digits)."""
    if not 0 < max_h < h:
        return ()
    text = _bound(max_h / h, up=False)
    return (f"--scale {text}",) if float(text) > 0 else ()


def _axis(settings: ChunkingSettings) -> np.ndarray:
    ang = math.radians(settings.centre_angle_deg)
    return np.array([-math.sin(ang), math.cos(ang), 0.0])


def top_width(robot: RobotProfile, settings: ChunkingSettings, robots: int) -> float:
    """The centre chunk's width at the object's top, mm: ``chunking.top_width`` when set; else 0
    for one robot (the seed's wedge: one robot prints the chunks one after another) and
    ``2 nozzle_depth`` for two or more. Two robots print the centre chunk's two neighbours at the
    same time, each with its nozzle at least half a line inside its own chunk, so at any height
    their nozzles are at least the centre chunk's width at that height apart, and that width is
    smallest (``top_width``) at the top: a wedge would bring their printheads (``nozzle_depth``
    around each nozzle) into each other near the top, whatever their speeds; ``2 nozzle_depth``
    keeps them apart at every instant and every speed. Their frames and bodies stand behind
    their nozzles, on opposite sides, so they cannot meet."""
    return settings.top_width if settings.top_width is not None else safe_top_width(robot, robots)


def safe_top_width(robot: RobotProfile, robots: int) -> float:
    """The narrowest top of the centre chunk at which ``robots`` robots like ``robot`` cannot meet
    (:func:`top_width`): ``2 nozzle_depth`` for two or more, 0 for one."""
    return 2 * robot.nozzle_depth if robots >= 2 else 0.0


def _plan(vertices: np.ndarray, robot: RobotProfile, settings: ChunkingSettings,
          robots: int = 2) -> tuple[Feasibility, ChunkPlan | None]:
    """The rule behind :func:`feasibility` and :func:`plan_chunks` (``robots``: how many print the
    part, for the centre chunk's :func:`top_width`).

    1. A part taller than ``robot.max_z`` cannot be printed.
    2. A part whose extent along the chunking axis fits the build depth is one chunk, printed by
       one robot from one side (its body never reaches the part; everything already printed is
       below the nozzle), at any height up to ``max_z``, unless a slope or a shift is set, which
       asks for the seed's cut.
    3. Otherwise the seed's planes: ``theta_min < theta <= theta_max`` (eq. 1-2), the centre chunk's
       base ``2 h / tan(theta) + top_width <= bd``, so ``h <= (bd - top_width) tan(theta) / 2``,
       largest at ``theta_max``; and ``theta_min <= theta_max`` gives ``h <= bd nh / nd`` (never the
       tighter bound when ``top_width >= 0``, kept for the record); the side chunks' reach
       ``s + h / tan(theta) <= bd``; at most ``MAX_CHUNKS`` chunks.
    """
    v = np.asarray(vertices, dtype=np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    h = float(hi[2] - lo[2])
    bd, nh, nd, tw = robot.build_depth, robot.nozzle_height, robot.nozzle_depth, top_width(robot, settings, robots)
    lim = slope_limits(robot, max(h, 0.0))
    axis = _axis(settings)
    extent = float(np.ptp(v @ axis))
    theta_max = lim.theta_max_deg
    tan_max = nh / nd
    cut_height = min(max(bd - tw, 0.0) * tan_max / 2, bd * tan_max, robot.max_z)

    def result(ok: bool, mode: str, reason: str, max_h: float, n: int = 0, theta: float = theta_max,
               hints: tuple[str, ...] = ()) -> Feasibility:
        return Feasibility(ok, mode, reason, h, extent, max_h, n, theta, lim.theta_min_deg, theta_max, hints)

    if h <= 0:
        return result(False, "whole", "the object has no height (all vertices at one z)", robot.max_z), None
    whole = settings.theta_deg is None and settings.shift is None
    if h > robot.max_z * (1 + 1e-9):
        # the mode the part would be printed in decides the largest height: one chunk up to max_z,
        # a cut part up to the planes' bound (which max_z also caps)
        one = whole and extent <= bd * (1 + 1e-9)
        top = robot.max_z if one else cut_height
        raise_z = _hint(RobotProfile, "max_z", "robot", ">=", h, robot.max_z, " mm") \
            if one or h <= min(max(bd - tw, 0.0) * tan_max / 2, bd * tan_max) else ()
        return result(False, "whole" if one else "cut", f"the part is {h:.1f} mm tall, higher than robot "
                      f"'{robot.name}' prints (robot.max_z = {robot.max_z:g} mm)", top,
                      hints=raise_z + _scale_hint(top, h)), None
    if abs(settings.centre_offset) > extent:
        return result(False, "whole" if whole and extent <= bd * (1 + 1e-9) else "cut",
                      f"chunking.centre_offset = {settings.centre_offset:g} mm puts the centre beyond the part "
                      f"({extent:.1f} mm along the chunking axis)", robot.max_z if extent <= bd else cut_height,
                      hints=(f"chunking.centre_offset within +-{math.floor(extent * 10) / 10:g} mm",)), None
    centre = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]]) + settings.centre_offset * axis
    if whole and extent <= bd * (1 + 1e-9):
        plan = ChunkPlan(theta_max, bd, 0.0, h, lim, tuple(float(x) for x in centre),  # type: ignore[arg-type]
                         tuple(float(x) for x in axis), extent / 2, 0, 0, bd, "whole")  # type: ignore[arg-type]
        return result(True, "whole", f"the part is {extent:.1f} mm deep along the chunking axis, within the build "
                      f"depth {bd:g} mm: one chunk, no cut", robot.max_z, 1), plan

    theta = theta_max if settings.theta_deg is None else settings.theta_deg
    tan_t = math.tan(math.radians(theta))
    max_h = min(cut_height, max(bd - tw, 0.0) * tan_t / 2) if theta <= theta_max + 1e-9 else cut_height
    formula = f"theta_min {lim.theta_min_deg:.3g} > theta_max atan({nh:g}/{nd:g}) = {theta_max:.3g} deg"
    fits = extent <= bd * (1 + 1e-9)
    drop = (f"no --theta/--shift ({extent:.1f} mm deep: one chunk)",) if fits else ()
    need_bd = 2 * h / tan_max + tw
    need_nh = 2 * h * nd / (bd - tw) if bd > tw else math.inf
    robot_hints = _hint(RobotProfile, "build_depth", "robot", ">=", need_bd, bd) + (
        (_hint(RobotProfile, "nozzle_height", "robot", ">=", need_nh, nh) +
         _hint(RobotProfile, "nozzle_depth", "robot", "<=", nh * (bd - tw) / (2 * h), nd))
        if math.isfinite(need_nh) else ()) + _scale_hint(cut_height, h)
    if not lim.feasible:
        return result(False, "cut", f"robot '{robot.name}' cannot print it: {formula}",
                      max_h, theta=theta, hints=drop + robot_hints), None
    if not lim.theta_min_deg < theta <= theta_max + 1e-9:
        return result(False, "cut", f"chunking.theta_deg = {theta:g} is outside the printable range "
                      f"({lim.theta_min_deg:.2f}, {theta_max:.2f}] deg", max_h, theta=theta,
                      hints=drop + (f"chunking.theta_deg in ({lim.theta_min_deg:.2f}, {theta_max:.2f}]",)), None
    run = h / tan_t
    a = run + tw / 2
    if 2 * a > bd * (1 + 1e-9):
        hints = list(drop)
        if theta < theta_max - 1e-9 and 2 * h / tan_max + tw <= bd:
            hints.append(f"chunking.theta_deg >= {math.degrees(math.atan2(2 * h, bd - tw)):.2f} "
                         f"(theta_max {theta_max:.2f})")
        if tw > 0 and 2 * run < bd:
            # the two robots' width (2 x nozzle_depth) is not given up: one robot prints a wedge
            hints.append(f"chunking.top_width <= {bd - 2 * run:.1f} (now {tw:g})" if settings.top_width is not None
                         else "--robots 1 (one robot prints a wedge-topped centre chunk)")
        hints += robot_hints
        at = f"theta_max {theta:.2f}" if theta >= theta_max - 1e-9 else f"theta {theta:.2f}"
        return result(False, "cut", f"centre chunk base {2 * a:.1f} mm > build depth "
                      f"{bd:g} mm at {at} deg", max_h, theta=theta, hints=tuple(hints)), None
    s = bd - run if settings.shift is None else settings.shift
    if s + run > bd * (1 + 1e-9):
        return result(False, "cut", f"chunking.shift = {s:g} mm: a side chunk would need reach s + h/tan(theta) = "
                      f"{s + run:.1f} mm > build depth {bd:g} mm", max_h, theta=theta,
                      hints=drop + (f"chunking.shift <= {bd - run:.1f} mm",)), None
    plan = ChunkPlan(theta, s, tw, h, lim, tuple(float(x) for x in centre),  # type: ignore[arg-type]
                     tuple(float(x) for x in axis), a, 0, 0, bd)  # type: ignore[arg-type]
    counts = {}
    for side in ("R", "L"):
        reach = float(plan.side_coordinate(side, v).max()) - a
        counts[side] = max(0, math.ceil(reach / s - PLANE_EPS)) if reach > PLANE_EPS * s else 0
    n = 1 + counts["R"] + counts["L"]
    if n > MAX_CHUNKS:
        return result(False, "cut", f"a shift of {s:g} mm over {extent:.1f} mm gives {n:,} chunks, more than "
                      f"{MAX_CHUNKS:,}", max_h, theta=theta,
                      hints=tuple(f"chunking.shift >= {_bound(extent / MAX_CHUNKS, up=True)} mm"
                                  for _ in (0,) if extent / MAX_CHUNKS <= bd - run)), None
    plan = replace(plan, n_right=counts["R"], n_left=counts["L"])
    return result(True, "cut", f"cut at theta {theta:.2f} deg into {n} chunks: centre chunk base {2 * a:.1f} mm and "
                  f"side reach {s + run:.1f} mm within the build depth {bd:g} mm", max_h, n, theta), plan


def feasibility(vertices: np.ndarray, robot: RobotProfile, settings: ChunkingSettings,
                robots: int = 2) -> Feasibility:
    """Whether ``robots`` robots like ``robot`` can print the part with ``vertices`` (only their
    extent matters) under ``settings``, why, the largest printable height and the number of
    chunks (rules: :func:`_plan`). The one rule of ``info``, ``chunk`` and ``run``."""
    return _plan(vertices, robot, settings, robots)[0]


def plan_chunks(vertices: np.ndarray, robot: RobotProfile, settings: ChunkingSettings, robots: int = 2) -> ChunkPlan:
    """Choose the slope, the shift and the number of chunks for a mesh and ``robots`` robots
    like ``robot``.

    Parameters
    ----------
    vertices : (n, 3) float64
        The solid's vertices, mm (only their extent matters).

    Raises
    ------
    InfeasibleError
        :meth:`Feasibility.message`: why (with the numbers), the largest printable height and
        the changes that would make it printable.
    """
    record, plan = _plan(vertices, robot, settings, robots)
    if plan is None:
        raise InfeasibleError(record.message())
    return plan
