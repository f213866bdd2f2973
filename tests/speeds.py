"""Uniform speeds for tests whose hand-made programs are timed in round numbers: every extrusion
at 40 mm/s and travel at 120 mm/s (a robot's speeds before the per-role speeds of issue 17)."""

from __future__ import annotations

from cooprint.config import SlicingSettings
from cooprint.program.gcode import ROLE_SPEEDS, Feeds

#: The [slicing] speed fields set to 40 mm/s (every role, the first layer) and travel to 120.
UNIFORM_SPEEDS = {**dict.fromkeys(ROLE_SPEEDS.values(), 40.0), "first_layer_speed": 40.0, "travel_speed": 120.0}
#: Default slicing settings but for those speeds.
UNIFORM_SLICING = SlicingSettings(**UNIFORM_SPEEDS)
#: Their feed rates (:meth:`Feeds.of_slicer` of :data:`UNIFORM_SLICING`).
UNIFORM = Feeds.of_slicer(UNIFORM_SLICING)
#: :data:`UNIFORM_SPEEDS` as a manifest's (or a settings file's) ``[slicing]`` table.
UNIFORM_TOML = "[slicing]\n" + "".join(f"{k} = {v}\n" for k, v in UNIFORM_SPEEDS.items())


def expected_times(program, slicing: SlicingSettings, start=None) -> tuple[float, float]:
    """(printing s, travelling s) of a robot's program at constant speed (from ``start``; None:
    from its first move), worked out here without :class:`Feeds`: each move's length over the
    [slicing] speed of its path role (PrusaSlicer's meaning of each field), every extrusion of
    layer 0 at ``first_layer_speed``."""
    import numpy as np

    from cooprint.program.commands import MOVE, ROLE_WORDS

    s = slicing
    by_word = {"outer-perimeter": s.external_perimeter_speed, "perimeter": s.perimeter_speed,
               "skin": s.solid_infill_speed, "infill": s.infill_speed, "top-skin": s.top_solid_infill_speed,
               "bridge": s.bridge_speed, "overhang-perimeter": s.bridge_speed, "gap-fill": s.gap_fill_speed,
               "travel": s.infill_speed}
    speed = np.array([by_word[ROLE_WORDS[r]] for r in range(len(ROLE_WORDS))])
    mv = np.flatnonzero(program.kind == MOVE)
    xyz = program.xyz[mv]
    here = xyz[:1] if start is None else np.asarray(start, float)[None]
    length = np.linalg.norm(np.diff(np.vstack([here, xyz]), axis=0), axis=1)
    on = program.tool_on()[mv] & (length > 0)
    v = speed[program.role[mv]]
    v = np.where(program.layer[mv] == 0, s.first_layer_speed, v)
    return float((length[on] / v[on]).sum()), float(length[~on].sum()) / s.travel_speed
