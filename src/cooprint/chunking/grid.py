"""The grid layout (issue 14): the seed's rows, each cut into columns along the centre line.

Rows
----
Exactly the seed2 plan (:mod:`.planes`): a part whose extent along the chunking axis ``c`` fits
the build depth is one row (row 0); otherwise the centre row 0 between planes L_0 and R_0, and
rows -1, -2, ... (the -c side, seed2's L1, L2, ...) and +1, +2, ... (R1, R2, ...) outward. Every
row face recedes as it rises towards the centre at ``theta <= theta_max``; an outer row leans on
the row inside it and is printed from outside, towards the centre.

Columns
-------
Each row is cut along the centre line ``u = (cos a, sin a, 0)`` (``a = centre_angle_deg``) by
sloped planes that contain ``c``. Columns alternate from the part's ``-u`` end:

* **even** columns (0, 2, ...) have both faces receding as they rise (narrower at the top): they
  lean on nothing in their row and are printed first;
* **odd** columns (1, 3, ...) lean on both even neighbours (wider at the top).

Every column face rises at the plan's ``theta``, so the printhead printing an odd column clears
the even column's face exactly as it clears a row face (seed eq. 1), and the faces do not cross
within the part's height. With ``run = h / tan(theta)`` a pair (one even, one odd) of period
``P`` has bases ``P/2 + run`` (even) and ``P/2 - run`` (odd) and the same cross-section at mid
height, ``P/2``.

Widths come from the robots. A working robot needs a *lane* across ``u``:
``lane = max(body_width, frame_width, 2 nozzle_depth) + program.clearance``. Two even columns are
printed at the same time only when the odd column between them is at least a lane wide at its base
(the narrowest it gets), and two odd columns only when the even one between them is at least a
lane wide at its top: both say ``P/2 - run >= lane``, so ``P >= 2 (lane + run)``. Without
``chunking.column_width`` each row gets about one pair per robot, ``P = U / min(N, U // P_min)``
over the part's extent ``U`` along ``u`` (whole columns, never a period below the minimum); with
it ``P = 2 column_width`` from the ``-u`` end (the last column may be partial). A part shorter than
one period is one column per row.

Chunks are named ``<row>-<column>``: ``C-0, C-1, ...`` in row 0, ``L1-0``, ``R2-3`` (the row's
seed2 name, then the column counted from 0 at the ``-u`` end of the part, the same in every row,
so ``R1-3`` lies over ``C-3``); empty ones are dropped and the others keep their ids.

Facings: a robot faces from its body to its nozzle, towards the faces its chunk leans on: rows
< 0 face ``+c``, rows > 0 face ``-c``; row 0's columns alternate sides in pairs (``col // 2`` even:
``+c``, odd: ``-c``), so that the robots printing one phase of the centre row stand on both sides.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Callable

import numpy as np

from cooprint.chunking.cut import Chunk, ChunkSet, Piece, cut_pieces, row_pieces, split_ordered
from cooprint.chunking.planes import (MAX_CHUNKS, PLANE_EPS, ChunkPlan, Feasibility, Plane, _bound, _plan,
                                      safe_top_width)
from cooprint.config import JobSettings, RobotProfile
from cooprint.errors import InfeasibleError
from cooprint.io.mesh import Solid


def robot_width(robot: RobotProfile) -> float:
    """The width of a robot's outline across its facing axis, mm: the widest of the body, the
    frame and the printhead (``2 nozzle_depth``) (:meth:`RobotProfile.outline`)."""
    return max(robot.body_width, robot.resolved_frame_width, 2 * robot.nozzle_depth)


def lane_width(robot: RobotProfile, clearance: float) -> float:
    """The width a working robot needs along the centre line, mm: its outline's width
    (:func:`robot_width`) plus ``clearance`` (``program.clearance``)."""
    return robot_width(robot) + clearance


def centre_line(settings_angle_deg: float) -> np.ndarray:
    """(3,) unit ``u``: the centre line's direction for ``chunking.centre_angle_deg``
    (``c = z x u`` is the chunking axis, :func:`cooprint.chunking.planes._axis`)."""
    a = math.radians(settings_angle_deg)
    return np.array([math.cos(a), math.sin(a), 0.0])


@dataclass(frozen=True)
class ColumnPlan:
    """Where the grid layout cuts every row along the centre line.

    Attributes
    ----------
    direction : (3,) float
        ``u``, the centre line's direction (unit, horizontal).
    origin : (3,) float
        On the floor of the part (its lowest z) at its ``-u`` end: column 0's base starts here.
    theta_deg, run
        Slope of every column face (the rows' ``theta``) and its horizontal run over the part's
        height ``h / tan(theta)``, mm.
    lane
        :func:`lane_width`, mm.
    period
        ``P``: one even and one odd column, mm (``inf`` when the part is one column per row).
    count
        Columns across the part (1: no column cut).
    extent
        The part's extent along ``u``, mm.
    given
        ``P`` comes from ``chunking.column_width`` (else from the robots' number and lane).
    """

    direction: tuple[float, float, float]
    origin: tuple[float, float, float]
    theta_deg: float
    run: float
    lane: float
    period: float
    count: int
    extent: float
    given: bool = False

    @property
    def width(self) -> float:
        """A column's width at mid height, ``P / 2`` (even and odd alike), mm."""
        return self.period / 2

    @property
    def even_base(self) -> float:
        """An even column's base (its widest), ``P/2 + run``, mm; an odd column's top is as wide."""
        return self.width + self.run

    @property
    def odd_base(self) -> float:
        """An odd column's base (its narrowest), ``P/2 - run``, mm; an even column's top is as wide."""
        return self.width - self.run

    def boundary(self, j: int) -> float:
        """Where the face between columns ``j`` and ``j + 1`` meets the part's floor, as a
        distance along ``u`` from ``origin``, mm: an even column's right edge at ``(j/2) P + P/2 +
        run``, an odd column's right edge (the next even one's left) at ``((j+1)/2) P``."""
        if j % 2 == 0:
            return (j // 2) * self.period + self.even_base
        return ((j + 1) // 2) * self.period

    def plane(self, j: int) -> Plane:
        """The face between columns ``j`` and ``j + 1``, its normal towards ``+u`` (column ``j + 1``'s
        side). It contains the chunking axis and rises at ``theta`` into the even column of the
        two, so both faces of an even column recede as they rise: for even ``j`` the normal is
        ``sin(theta) u + cos(theta) z`` (the even column's outward normal), for odd ``j``
        ``sin(theta) u - cos(theta) z`` (the even column ``j + 1``'s outward normal, flipped)."""
        th = math.radians(self.theta_deg)
        u = np.asarray(self.direction)
        up = math.cos(th) if j % 2 == 0 else -math.cos(th)
        normal = math.sin(th) * u + np.array([0.0, 0.0, up])
        point = np.asarray(self.origin) + self.boundary(j) * u
        return Plane(tuple(float(x) for x in point), tuple(float(x) for x in normal))  # type: ignore[arg-type]

    def planes(self) -> list[Plane]:
        """The ``count - 1`` column faces, in order along ``u``."""
        return [self.plane(j) for j in range(self.count - 1)]

    def to_dict(self) -> dict[str, object]:
        finite = math.isfinite(self.period)
        return {"direction": list(self.direction), "origin": list(self.origin), "theta_deg": self.theta_deg,
                "run_mm": self.run, "lane_mm": self.lane, "period_mm": self.period if finite else None,
                "column_width_mm": self.width if finite else None,
                "even_base_mm": self.even_base if finite else None, "odd_base_mm": self.odd_base if finite else None,
                "columns": self.count, "extent_mm": self.extent, "from_setting": self.given}


@dataclass(frozen=True)
class GridPlan(ChunkPlan):
    """The seed2 rows (every :class:`ChunkPlan` field) and the columns cut in each of them."""

    columns: ColumnPlan | None = None

    @property
    def rows(self) -> int:
        return 1 + self.n_left + self.n_right

    def to_dict(self) -> dict[str, object]:
        return super().to_dict() | {"layout": "grid", "rows": self.rows,
                                    "columns": self.columns.to_dict() if self.columns else None}


def _columns(vertices: np.ndarray, rows: ChunkPlan, settings: JobSettings,
             robots: int) -> tuple[ColumnPlan | None, str, float, tuple[str, ...]]:
    """The column plan (module docstring), or ``None`` with the reason, the largest height the
    column width allows and a hint when ``chunking.column_width`` is too narrow for the robot."""
    robot, cw = settings.robot, settings.chunking.column_width
    clearance = settings.program.clearance
    lane, run = lane_width(robot, clearance), rows.run
    u = centre_line(settings.chunking.centre_angle_deg)
    t = np.asarray(vertices, dtype=np.float64) @ u
    lo, hi = float(t.min()), float(t.max())
    extent = hi - lo
    origin = np.asarray(rows.centre) + (lo - float(np.dot(rows.centre, u))) * u
    smallest = lane + run  # the narrowest column (mid height): P/2 - run >= lane
    tan_t = math.tan(math.radians(rows.theta_deg))
    if cw is not None:
        if cw - run < lane * (1 - 1e-9):
            reason = (f"chunking.column_width = {cw:g} mm is too narrow: smallest {smallest:.1f} mm "
                      f"= lane {lane:.1f} (body/frame/printhead width {robot_width(robot):g} + clearance "
                      f"{clearance:g}) + faces' run {run:.1f}")
            hint = (f"chunking.column_width >= {_bound(smallest, up=True)}",)
            return None, reason, max(cw - lane, 0.0) * tan_t, hint
        period = 2 * cw
    else:
        pairs = min(robots, math.floor(extent / (2 * smallest) * (1 + 1e-9)))
        period = extent / pairs if pairs >= 1 else math.inf
    plan = ColumnPlan(tuple(float(x) for x in u), tuple(float(x) for x in origin),  # type: ignore[arg-type]
                      rows.theta_deg, run, lane, period, 1, extent, cw is not None)
    if not math.isfinite(period) or extent < period * (1 - 1e-9):
        return replace(plan, count=1), "", math.inf, ()
    eps = PLANE_EPS * period
    count = 1
    # a face can cut the part if it reaches inside the part's extent at some height: an even
    # column's right face is furthest back (-u) at the top, an odd one's at the floor
    while plan.boundary(count - 1) - (run if (count - 1) % 2 == 0 else 0.0) < extent - eps:
        count += 1
    return replace(plan, count=count), "", math.inf, ()


def _grid_plan(vertices: np.ndarray, settings: JobSettings, robots: int) -> tuple[Feasibility, GridPlan | None]:
    """The rule behind :func:`grid_feasibility` and :func:`plan_grid`: seed2's rows
    (:func:`cooprint.chunking.planes._plan`, the same limits and hints), then the columns
    (:func:`_columns`), at most ``MAX_CHUNKS`` chunks."""
    record, rows = _plan(vertices, settings.robot, settings.chunking, robots)
    if rows is not None and settings.chunking.top_width is None and robots >= 2:
        # the centre row's top a clearance wider than seed2's where the part allows it: the
        # robots printing rows L1 and R1 side by side keep their printheads the programs'
        # clearance apart (seed2's top has them touch), so those rows are not exclusive and print
        # at the same time; a part too tall for that keeps seed2's top (L1 and R1 then take turns
        # where they meet: the exclusions say where)
        wider = replace(settings.chunking, top_width=safe_top_width(settings.robot, robots) + settings.program.clearance)
        record_w, rows_w = _plan(vertices, settings.robot, wider, robots)
        if rows_w is not None:
            record, rows = record_w, rows_w
    if rows is None:
        return record, None
    columns, why, max_h, hints = _columns(vertices, rows, settings, robots)
    if columns is None:
        return replace(record, feasible=False, reason=why, max_height=min(record.max_height, max_h),
                       chunks=0, hints=hints), None
    plan = GridPlan(**{f.name: getattr(rows, f.name) for f in fields(ChunkPlan)}, columns=columns)
    n = plan.rows * columns.count
    if n > MAX_CHUNKS:
        # face j meets the floor, at its furthest -u, (j + 1) column widths from the -u end: m
        # columns cover the part when m widths do
        need = max(columns.extent / (MAX_CHUNKS // plan.rows), columns.lane + columns.run)
        return replace(record, feasible=False, chunks=0,
                       reason=f"{plan.rows} rows x {columns.count} columns give {n:,} chunks, more than {MAX_CHUNKS:,}",
                       hints=(f"chunking.column_width >= {_bound(need, up=True)}",)), None
    bd = settings.robot.build_depth
    if rows.mode == "whole":
        text = (f"the part is {record.extent:.1f} mm deep along the chunking axis, within the build depth {bd:g} mm: "
                "one row")
    else:
        text = (f"{plan.rows} rows at theta {rows.theta_deg:.2f} deg (centre base {2 * rows.half_base:.1f} mm, side "
                f"reach {rows.shift + rows.run:.1f} mm within the build depth {bd:g} mm)")
    if columns.count == 1 and columns.given:
        text += (f"; {columns.extent:.1f} mm along the centre line, less than two columns of "
                 f"chunking.column_width = {columns.width:g} mm: one column per row")
    elif columns.count == 1:
        text += (f"; {columns.extent:.1f} mm along the centre line, less than two columns of "
                 f"{columns.lane + columns.run:.1f} mm (lane {columns.lane:.1f} + faces' run {columns.run:.1f}): "
                 "one column per row")
    else:
        text += (f"; {columns.count} columns {columns.width:.1f} mm wide (bases {columns.even_base:.1f} even, "
                 f"{columns.odd_base:.1f} odd; lane {columns.lane:.1f}): at most {n} chunks")
    return replace(record, reason=text, chunks=n), plan


def grid_feasibility(vertices: np.ndarray, settings: JobSettings, robots: int) -> Feasibility:
    """Whether ``robots`` robots like ``settings.robot`` can print the part with ``vertices`` in the
    grid layout: seed2's rule for the rows (:func:`cooprint.chunking.planes.feasibility`) and the
    column limit (``column_width - run >= lane``). ``chunks`` is rows x columns, an upper bound
    (exact for a part that fills its bounding box: empty chunks are dropped when cutting)."""
    return _grid_plan(vertices, settings, robots)[0]


def plan_grid(vertices: np.ndarray, settings: JobSettings, robots: int) -> GridPlan:
    """The rows and columns of the grid layout for a part with ``vertices`` (only their extent
    matters) and ``robots`` robots.

    Raises
    ------
    InfeasibleError
        One line (:meth:`Feasibility.message`): a row limit (as seed2's) or a column width too
        narrow for the robot, with the numbers and the fix.
    """
    record, plan = _grid_plan(vertices, settings, robots)
    if plan is None:
        raise InfeasibleError(record.message())
    return plan


def facing(plan: ChunkPlan, row: int, col: int) -> tuple[float, float]:
    """Unit XY direction the robot faces while printing the chunk at ``row``, ``col``: rows < 0
    along ``+c``, rows > 0 along ``-c`` (from outside towards the centre, onto the row it leans
    on); row 0 in pairs of columns, ``+c`` when ``col // 2`` is even, else ``-c``."""
    sign = 1.0 if row < 0 or (row == 0 and (col // 2) % 2 == 0) else -1.0
    return (sign * float(plan.axis[0]), sign * float(plan.axis[1]))


def _row_columns(kernel: object, row: Piece, plan: GridPlan) -> list[Piece]:
    """Cut one row into its columns (the even ones first, then the odd ones).

    Only the faces that cross the row are cut (its vertices lie on both sides, by more than
    ``PLANE_EPS`` of the period): the faces are ordered along ``u`` at every height of the part,
    so the ones wholly on the row's ``-u`` side are a prefix (the row starts at a later column)
    and the ones wholly beyond it a suffix."""
    cols = plan.columns
    assert cols is not None
    planes = cols.planes()
    pts = kernel.points(row.piece)  # type: ignore[attr-defined]
    if len(pts) == 0:
        return []
    eps = PLANE_EPS * cols.period
    first, used = 0, []
    for j, p in enumerate(planes):
        d = p.signed_distance(pts)
        if d.max() <= eps:  # the row ends before this face, and before every later one
            break
        if d.min() >= -eps and not used:  # the row starts after this face
            first = j + 1
        else:
            used.append(j)
    pieces = split_ordered(kernel, row.piece, [planes[j] for j in used])
    out = []
    for i, piece in enumerate(pieces):
        col = first + i
        bounds = row.planes + ((planes[used[i - 1]].flipped(),) if i > 0 else ()) + \
            ((planes[used[i]],) if i < len(used) else ())
        out.append(Piece(f"{row.id}-{col}", row.role, row.index, piece, bounds, row.row, col,
                         facing(plan, row.row, col)))
    return sorted(out, key=lambda p: p.col % 2)  # stable: even columns, then odd ones, each along u


def _contains(plane: Plane, direction: np.ndarray) -> bool:
    """Whether ``direction`` lies in ``plane`` (a row face contains the centre line, a column
    face the chunking axis)."""
    return abs(float(np.dot(plane.normal, direction))) < 1e-9


def grid_dependencies(chunks: tuple[Chunk, ...], direction: np.ndarray,
                      tol: float = 1e-6) -> dict[str, tuple[str, ...]]:
    """Precedence (a) from the geometry: every chunk after each chunk whose face it leans on.

    A chunk ``A`` leans on ``B`` across a cut plane when that plane bounds ``B`` with a face that
    recedes as it rises (``B``'s outward normal points up) and bounds ``A`` from the other side,
    and

    * for a column face (it contains the chunking axis): neither lies wholly beyond another face
      of the other, i.e. they are in the same row (an odd column leans on its two even
      neighbours; chunks of different rows meet on a column face at most along a line);
    * for a row face (it contains the centre line ``direction``): their extents along the centre
      line overlap by more than ``tol`` mm (over all heights). The outer chunk overhangs the
      inner row's face across its whole range, so every inner chunk it overhangs, and those
      beside it within a printhead's reach of its range, is printed first: the inner chunk in its
      column and the two next to it whose sloped faces reach into its range.

    Row 0's even columns lean on nothing. Ids are never parsed."""
    u = np.asarray(direction, dtype=np.float64)
    owners: dict[Plane, list[Chunk]] = {}
    for ch in chunks:
        for p in ch.planes:
            owners.setdefault(p, []).append(ch)
    span = {ch.id: (float((ch.vertices @ u).min()), float((ch.vertices @ u).max())) for ch in chunks}
    lowest: dict[tuple[Plane, str], float] = {}

    def beyond(q: Plane, ch: Chunk) -> bool:
        """Whether all of ``ch`` lies on the outer side of ``q`` (memoised: one pass per pair)."""
        key = (q, ch.id)
        if key not in lowest:
            lowest[key] = float(q.signed_distance(ch.vertices).min())
        return lowest[key] >= -tol

    def separated(a: Chunk, b: Chunk, across: Plane) -> bool:
        """Whether one of them lies wholly beyond another face of the other (then they meet on
        ``across`` at most along a line)."""
        return any(q != across and q != across.flipped() and beyond(q, y)
                   for x, y in ((a, b), (b, a)) for q in x.planes)

    deps: dict[str, tuple[str, ...]] = {}
    for a in chunks:
        found: list[str] = []
        for p in a.planes:
            if p.normal[2] >= 0:  # a's own receding face (or vertical): others lean on it
                continue
            for b in owners.get(p.flipped(), ()):
                if b is a or b.id in found:
                    continue
                if _contains(p, u):
                    (a0, a1), (b0, b1) = span[a.id], span[b.id]
                    if min(a1, b1) - max(a0, b0) > tol:
                        found.append(b.id)
                elif not separated(a, b, p):
                    found.append(b.id)
        deps[a.id] = tuple(found)
    return deps


def cut_grid(solid: Solid, plan: GridPlan, progress: Callable[[int, int], None] | None = None) -> ChunkSet:
    """Cut ``solid`` into the grid layout's watertight chunks: the rows with seed2's cuts
    (:func:`cooprint.chunking.cut.row_pieces`), then each row along its column faces, with the
    same exact kernels and fallback (:func:`cooprint.chunking.cut.cut_pieces`).

    Returns a :class:`ChunkSet` (``layout = "grid"``): non-empty chunks only, row by row (C, L1, L2,
    ..., R1, ...) and in each row the even columns then the odd ones (an order that respects
    ``deps``, :func:`grid_dependencies`)."""
    if plan.columns is None:
        raise ValueError("cut_grid needs a GridPlan with columns (plan_grid)")

    def make(kernel: object) -> list[Piece]:
        return [col for row in row_pieces(kernel, plan) for col in _row_columns(kernel, row, plan)]

    chunks = cut_pieces(solid, make, progress)
    tol = PLANE_EPS * max(plan.columns.extent, 1.0)
    deps = grid_dependencies(chunks, np.asarray(plan.columns.direction), tol)
    return ChunkSet(plan, chunks, deps, solid.volume, "grid")


def grid_layout(solid: Solid, settings: JobSettings, robots: int,
                progress: Callable[[int, int], None] | None = None) -> ChunkSet:
    """The grid layout of ``solid`` for ``robots`` robots: :func:`plan_grid` then
    :func:`cut_grid`."""
    return cut_grid(solid, plan_grid(solid.vertices, settings, robots), progress)
