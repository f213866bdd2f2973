"""Placement: where a loaded part stands before anything is planned or sliced.

Rules (every command: ``info``, ``chunk``, ``run``, ``slice``):

* units first: the file's coordinates times ``UNITS[mesh.units]`` times ``mesh.scale``;
* the part is put on the floor: its lowest point to z = 0 (a part below the floor would give
  negative Z, one floating at z = 50 would print its first layer in the air);
* ``cooprint slice`` also centres it on the bed, as PrusaSlicer's ``--center``: the centre of its
  bounding box in XY goes to the bed centre (``build_x / 2, build_y / 2``, or ``--center X,Y``),
  and the placed part must lie within ``[0, build_x] x [0, build_y]``;
* ``mesh.place = false`` (``--no-place``) keeps the file's frame: a part below z = 0 is refused,
  a floating one is printed where it is with a warning.

Size checks, after scaling (they catch files in other units):

* a part narrower than ``MIN_LINES`` (3) extrusion widths in both X and Y (its largest XY extent),
  or lower than the first layer, is refused: nothing meaningful can be printed from it (a 0.2 mm
  cube is a 200 mm cube in metres). A thin wall (100 x 0.5 x 20 mm) is a part: the slicer prints
  it as one line, or nothing where it is thinner than a line. The units hint comes only with a
  part small in all directions (below ``SUSPECT_MM``): a thin wall or a flat sheet is not a file
  in other units;
* a part whose largest extent is below ``SUSPECT_MM`` (10 mm) in a file read as millimetres is
  printed with a warning that names ``--units`` and ``--scale`` (an inch or centimetre file
  looks like that).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Sequence

import numpy as np

from cooprint.config import MeshSettings, SlicingSettings
from cooprint.errors import MeshError, UserError, warn
from cooprint.io.mesh import Solid

#: Millimetres per unit of a file's coordinates.
UNITS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "in": 25.4}
#: A part narrower than this many extrusion widths (X or Y) is refused.
MIN_LINES = 3
#: A millimetre file whose largest extent is below this, mm, gets a units warning.
SUSPECT_MM = 10.0
#: A lowest point within this of z = 0 is on the floor, mm.
FLOOR_TOL = 1e-3


@dataclass(frozen=True)
class Placement:
    """What was done to the part's coordinates: ``new = old * scale + moved``.

    Attributes
    ----------
    units, scale
        The file's unit and the total factor applied (unit x ``mesh.scale``).
    mode
        ``floor`` (lowest point to z = 0), ``bed`` (also centred on the bed) or ``none``
        (the file's frame kept).
    moved : (3,) float
        Translation applied after scaling, mm.
    size : (3,) float
        The part's bounding-box size after scaling, mm.
    warnings
        What the user was warned about (also printed on stderr).
    """

    units: str
    scale: float
    mode: str
    moved: tuple[float, float, float]
    size: tuple[float, float, float]
    warnings: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, object]:
        return {"units": self.units, "scale": self.scale, "mode": self.mode, "moved_mm": list(self.moved),
                "size_mm": list(self.size), "warnings": list(self.warnings)}

    @classmethod
    def from_dict(cls, d: dict) -> "Placement":
        """The record of :meth:`to_dict` (job.json's ``mesh.placement``)."""
        return cls(d["units"], d["scale"], d["mode"], tuple(d["moved_mm"]), tuple(d["size_mm"]),  # type: ignore[arg-type]
                   tuple(d.get("warnings", ())))

    def describe(self) -> str:
        """One line: ``placed on the floor: moved by (0, 0, +50) mm``."""
        parts = []
        if self.scale != 1.0:
            parts.append(f"scaled x{self.scale:g} ({self.units})")
        if self.mode == "none":
            parts.append("kept in the file's frame (--no-place)")
        else:
            where = "on the floor and centred on the bed" if self.mode == "bed" else "on the floor"
            dx, dy, dz = self.moved
            moved = "not moved" if not any(self.moved) else f"moved by ({dx:+.3f}, {dy:+.3f}, {dz:+.3f}) mm"
            parts.append(f"placed {where}: {moved}")
        return "; ".join(parts)


def _fmt_size(size: np.ndarray) -> str:
    return " x ".join(f"{x:.4g}" for x in size) + " mm"


def _units_hint(size: np.ndarray, units: str) -> str:
    if units != "mm":
        return "use --units mm|cm|m|in or --scale FACTOR if the file is in another unit"
    alts = ", ".join(f"{u}: {_fmt_size(size * f)}" for u, f in UNITS.items() if u != "mm")
    return f"if the file is not in millimetres use --units cm|m|in or --scale FACTOR ({alts})"


def place(solid: Solid, mesh: MeshSettings, slicing: SlicingSettings, *, bed: bool = False,
          center: Sequence[float] | None = None, own: bool = False) -> tuple[Solid, Placement]:
    """Scale and place ``solid`` (module rules); return the placed solid and what was done.

    Parameters
    ----------
    bed
        Centre the part on the bed (``cooprint slice``): at ``center`` (X, Y mm) or the bed
        centre ``build_x / 2, build_y / 2``, and refuse a part that does not lie on the bed.
    own
        The caller hands ``solid`` over: its vertices are moved in place (no copy of a large mesh).

    Raises
    ------
    MeshError
        A part too small to print (with the units hint), below the floor with ``place = false``,
        or off the bed.
    """
    path = solid.report.path
    factor = UNITS[mesh.units] * mesh.scale
    lo, hi = solid.bounds * factor
    if not np.isfinite([lo, hi]).all() or np.abs([lo, hi]).max() > 1e7:
        raise MeshError(f"{path}: scaled x{factor:g} the part reaches {np.abs([lo, hi]).max():.3g} mm; "
                        "check --units / --scale")
    size = hi - lo
    min_xy = MIN_LINES * slicing.extrusion_width
    narrow, low = max(size[0], size[1]) < min_xy, size[2] < slicing.first_layer_height
    if narrow or low:
        why = " and ".join(([f"narrower than {MIN_LINES} line widths ({min_xy:g} mm) in both X and Y"] if narrow else [])
                           + ([f"lower than the first layer ({slicing.first_layer_height:g} mm)"] if low else []))
        hint = f"; {_units_hint(size, mesh.units)}" if size.max() < SUSPECT_MM else ""
        raise MeshError(f"{path}: the part is {_fmt_size(size)}, too small to print: {why}{hint}")
    warnings = []
    if mesh.units == "mm" and mesh.scale == 1.0 and size.max() < SUSPECT_MM:
        warnings.append(f"{path}: the part is only {_fmt_size(size)}; {_units_hint(size, mesh.units)}")
    if not mesh.place:
        if lo[2] < -FLOOR_TOL:
            raise MeshError(f"{path}: with --no-place the part reaches z = {lo[2]:.3f} mm, below the floor; "
                            "drop --no-place to put it on the floor")
        if lo[2] > FLOOR_TOL:
            warnings.append(f"{path}: with --no-place the part floats at z = {lo[2]:.3f} mm: its first layer is "
                            f"printed at z = {lo[2] + slicing.first_layer_height:.3f} mm, in the air")
        moved = np.zeros(3)
        mode = "none"
    else:
        moved = np.array([0.0, 0.0, -lo[2]])
        mode = "floor"
        if bed:
            c = (slicing.build_x / 2, slicing.build_y / 2) if center is None else center
            moved[:2] = np.asarray(c, dtype=np.float64) - (lo[:2] + hi[:2]) / 2
            mode = "bed"
        moved[np.abs(moved) < 1e-12] = 0.0
    if bed and size[0] <= slicing.build_x and size[1] <= slicing.build_y:  # larger: the build volume check says so
        plo, phi = lo + moved, hi + moved
        if plo[0] < -1e-6 or plo[1] < -1e-6 or phi[0] > slicing.build_x + 1e-6 or phi[1] > slicing.build_y + 1e-6:
            raise MeshError(f"{path}: placed at x {plo[0]:.1f}..{phi[0]:.1f}, y {plo[1]:.1f}..{phi[1]:.1f} mm, the part "
                            f"is off the bed [0, {slicing.build_x:g}] x [0, {slicing.build_y:g}] mm "
                            "([slicing] build_x, build_y); use --center X,Y inside the bed")
    for w in warnings:
        warn(w)
    record = Placement(mesh.units, float(factor), mode, tuple(float(x) for x in moved),  # type: ignore[arg-type]
                       tuple(float(x) for x in size), tuple(warnings))  # type: ignore[arg-type]
    if factor == 1.0 and not moved.any():
        return solid, record
    verts = solid.vertices if own and solid.vertices.dtype == np.float64 else solid.vertices.astype(np.float64)
    if factor != 1.0:
        verts *= factor
    verts += moved
    report = replace(solid.report, bbox_min=tuple(float(x) for x in lo + moved),
                     bbox_max=tuple(float(x) for x in hi + moved), volume_mm3=solid.report.volume_mm3 * factor ** 3)
    return Solid(verts, solid.faces, report), record


def parse_center(text: str) -> tuple[float, float]:
    """``--center X,Y`` (mm) into a pair of finite numbers."""
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        x, y = (float(p) for p in parts)
        if not (np.isfinite(x) and np.isfinite(y)):
            raise ValueError
    except ValueError:
        raise UserError(f"--center {text[:40]!r}: expected X,Y in mm, e.g. --center 125,105") from None
    return x, y


__all__ = ["MIN_LINES", "Placement", "SUSPECT_MM", "UNITS", "parse_center", "place"]
