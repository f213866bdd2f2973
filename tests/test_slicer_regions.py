"""The slicer's regions as PrusaSlicer 2.5 types them (issue 17): solid layers under tops and over
bottoms, bridges over air printed across the gap with a round thread, gap fill and thin walls,
solid under every exposed step of a sloped top, and the per-role volumes read back from the
G-code by a reader of this file's own."""

import math

import manifold3d as m3d
import numpy as np
import pytest

from cooprint.config import SlicingSettings
from cooprint.io.mesh import solid_from_arrays
from cooprint.program.build import layer_pieces
from cooprint.program.gcode import gcode_text
from cooprint.slicing import slice_solid
from cooprint.slicing.paths import (BRIDGE, GAP_FILL, INFILL, OVERHANG, PERIMETER_INNER, PERIMETER_OUTER, SKIN,
                                    TOP_SKIN, TRAVEL, flow_area)

from solids import box, to_trimesh

SOLID = (SKIN, TOP_SKIN, BRIDGE)


def solid(man):
    tm = to_trimesh(man)
    return solid_from_arrays(tm.vertices, tm.faces)


def fill_roles(layer):
    return set(layer.role.tolist()) - {PERIMETER_OUTER, PERIMETER_INNER, TRAVEL, GAP_FILL}


@pytest.mark.parametrize("bottom, top", [(4, 4), (2, 5)])
def test_a_cube_has_bottom_layers_solid_at_the_bottom_top_layers_at_the_top_and_sparse_between(bottom, top):
    s = SlicingSettings(bottom_layers=bottom, top_layers=top)
    layers = slice_solid(solid(box(20, 20, 6)), s).layers
    assert len(layers) == 30
    roles = [fill_roles(layer) for layer in layers]
    assert all(r <= set(SOLID) and r for r in roles[:bottom]), roles[:bottom]
    assert roles[bottom:30 - top] == [{INFILL}] * (30 - top - bottom)
    assert all(r <= set(SOLID) and r for r in roles[30 - top:])
    assert roles[-1] == {TOP_SKIN}  # the top surface itself (0.4 mm lines, top solid infill)
    assert roles[30 - top] == {BRIDGE}  # the first solid layer over sparse infill: bridged
    top_widths = {float(w) for L in layers[-1:] for w, r in zip(L.width, L.role) if r == TOP_SKIN}
    assert min(top_widths) >= 0.4 - 1e-9 and max(top_widths) <= 0.4 * 1.2


def test_infill_joins_lie_beside_the_inner_perimeter_and_solid_lines_are_one_snake():
    def points(layer, role):
        idx = np.flatnonzero(layer.role == role)
        return np.concatenate([layer.points[layer.offsets[k]:layer.offsets[k + 1]] for k in idx])

    mid = slice_solid(solid(box(20, 20, 6)), SlicingSettings()).layers[15]
    inner, infill = points(mid, PERIMETER_INNER), points(mid, INFILL)
    # PrusaSlicer: line ends 0.4 spacing and joins 0.5 spacing inside the fill region (whose edge
    # is 0.1 mm inside the inner perimeter's centre), not on the perimeter
    gap = np.abs(inner).max() - np.abs(infill).max(axis=1).max()
    assert 0.25 < gap < 0.35
    # a flat plate: every layer's solid lines joined into one polyline (PrusaSlicer: one per layer)
    for layer in slice_solid(solid(box(40, 40, 1.2)), SlicingSettings()).layers:
        fills = [k for k, r in enumerate(layer.role) if r in (SKIN, TOP_SKIN)]
        assert len(fills) == 1 and (layer.role == TRAVEL).sum() <= 2


def towers():
    """Two 8 x 8 mm towers 10 mm high, 16 mm apart, joined by a 2 mm slab on top."""
    left = m3d.Manifold.cube([8, 8, 10]).translate([0, 0, 0])
    right = m3d.Manifold.cube([8, 8, 10]).translate([24, 0, 0])
    slab = m3d.Manifold.cube([32, 8, 2]).translate([0, 0, 10])
    return (left + right + slab).translate([-16, -4, 0])


def threads_of(layer, k, longer=6.0):
    """The segments of paths ``k`` longer than ``longer`` mm, as (2, 2) arrays."""
    out = []
    for j in k:
        p = layer.path(j)
        out += [p[i:i + 2] for i in np.flatnonzero(np.hypot(*np.diff(p, axis=0).T) > longer)]
    return out


def test_a_bridge_between_two_towers_is_printed_across_the_gap_with_a_round_thread():
    s = SlicingSettings()
    layers = slice_solid(solid(towers()), s).layers
    first = next(i for i, L in enumerate(layers) if L.z > 10.0 + 1e-6)  # the slab's first layer
    layer = layers[first]
    k = np.flatnonzero(layer.role == BRIDGE)
    assert len(k), "no bridge over the gap"
    # the threads: the bridge paths' long segments (the short ones join them along the towers)
    threads = threads_of(layer, k)
    assert len(threads) >= (8 - 1.5) / 0.49  # side by side across the slab's fill area (8 mm wide)
    for p in threads:
        d = p[1] - p[0]
        assert abs(d[1]) < 0.05 * abs(d[0])  # along x: from tower to tower
        assert p[:, 0].min() < -8 + 0.5 and p[:, 0].max() > 8 - 0.5  # resting on both towers
    # a round thread of the nozzle's diameter (bridge_flow_ratio 1), spacing widened by <= 20%
    w = layer.width[k]
    assert w.min() >= 0.4 - 1e-9 and w.max() <= 1.2 * 0.45 - 0.05 + 1e-9
    lengths = layer.lengths()[k]
    vol = float((flow_area(w, layer.height, BRIDGE) * lengths).sum())
    assert vol == pytest.approx(float((np.pi * w ** 2 / 4 * lengths).sum()))
    # the slab's outer perimeter over the gap is an overhang perimeter
    assert OVERHANG in set(layer.role.tolist())
    # the bridge (grown 3 mm onto the towers) and the bottom_layers - 1 layers over it are solid
    for L in layers[first:first + s.bottom_layers]:
        sparse = [L.path(j) for j in range(len(L)) if L.role[j] == INFILL]
        assert all(np.abs(p[:, 0]).min() > 8 + 3 - 0.01 for p in sparse)
    assert BRIDGE not in fill_roles(layers[first + 1])


def test_the_bridge_direction_setting_wins():
    s = SlicingSettings(bridge_angle_deg=90.0)
    layers = slice_solid(solid(towers()), s).layers
    layer = next(L for L in layers if L.z > 10.0 + 1e-6)
    threads = threads_of(layer, np.flatnonzero(layer.role == BRIDGE))
    d = np.array([p[1] - p[0] for p in threads])
    assert len(d) and np.all(np.abs(d[:, 0]) < 0.05 * np.abs(d[:, 1]) + 1e-9)


def test_a_wall_too_narrow_for_a_third_loop_gets_gap_fill_along_its_middle():
    """A 2.2 mm wall: two loops each side (their bands 0.86 mm), 0.49 mm left in the middle, too
    narrow for another loop (PrusaSlicer's classic generator: the next loop's region opened by
    0.12 mm is empty) and for a fill area: gap fill there, and the layer's material is the
    wall's section within 10%."""
    layers = slice_solid(solid(box(2.2, 30, 2)), SlicingSettings()).layers
    for layer in layers[1:]:
        k = np.flatnonzero(layer.role == GAP_FILL)
        assert len(k), "no gap fill"
        pts = np.concatenate([layer.path(j) for j in k])
        assert np.abs(pts[:, 0]).max() < 0.35  # along the wall's middle
        printing = layer.role != TRAVEL
        vol = float((flow_area(layer.width, layer.height, layer.role) * layer.lengths())[printing].sum())
        assert vol == pytest.approx(2.2 * 30 * layer.height, rel=0.10)


def test_a_wall_too_thin_for_a_loop_is_one_line_along_its_middle():
    """0.675 mm (1.5 line widths): too thin for the outer loop's two sides; a thin wall line
    (PrusaSlicer: an external perimeter of variable width) fills it."""
    layers = slice_solid(solid(box(0.675, 30, 2)), SlicingSettings()).layers
    for layer in layers[1:]:
        k = np.flatnonzero(layer.role != TRAVEL)
        assert len(k) and set(layer.role[k].tolist()) == {PERIMETER_OUTER}
        pts = np.concatenate([layer.path(j) for j in k])
        assert np.abs(pts[:, 0]).max() < 0.1
        vol = float((flow_area(layer.width[k], layer.height, layer.role[k]) * layer.lengths()[k]).sum())
        # the bead fills the thickness (width = thickness + h (1 - pi / 4), PrusaSlicer's)
        assert vol == pytest.approx(0.675 * 30 * layer.height, rel=0.03)


def ziggurat():
    """Five square steps, each 1 mm high and 3 mm narrower on every side than the one below."""
    parts = [m3d.Manifold.cube([40 - 6 * k, 40 - 6 * k, 1.0]).translate([3 * k - 20, 3 * k - 20, k]) for k in range(5)]
    return m3d.Manifold.batch_boolean(parts, m3d.OpType.Add)


def test_every_exposed_step_of_a_sloped_top_has_top_layers_solid_under_it():
    s = SlicingSettings()
    layers = slice_solid(solid(ziggurat()), s).layers
    assert len(layers) == 25
    for k in range(4):  # the step k exposes a ring 3 mm wide around step k + 1
        top = 5 * k + 4  # its top layer
        mid = 20 - 3 * k - 1.5  # the ring's middle line: |x| or |y| = mid
        t = np.linspace(-mid, mid, 41)
        probes = np.concatenate([np.stack([t, np.full_like(t, sy * mid)], 1) for sy in (-1, 1)]
                                + [np.stack([np.full_like(t, sx * mid), t], 1) for sx in (-1, 1)])
        for i in range(top - s.top_layers + 1, top + 1):
            layer = layers[i]
            segs = [layer.path(j) for j in range(len(layer)) if layer.role[j] in SOLID]
            assert segs, (k, i)
            a = np.concatenate([p[:-1] for p in segs])
            b = np.concatenate([p[1:] for p in segs])
            # every probe on the ring's middle line is within a line spacing of a solid line
            ab = b - a
            u = np.clip(((probes[:, None] - a) * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12), 0, 1)
            dist = np.linalg.norm(probes[:, None] - (a + u[..., None] * ab), axis=-1).min(axis=1)
            assert dist.max() < 0.5, (k, i, dist.max())
            if i == top:
                assert TOP_SKIN in set(layer.role.tolist())


def read_volumes(text):
    """An independent reader: extruded volume per ``;TYPE:`` (absolute XYZ, relative E, 1.75 mm
    filament), the moves that retract or unretract in place left out."""
    vol, typ, x, y = {}, None, 0.0, 0.0
    area = math.pi * 1.75 ** 2 / 4
    for raw in text.splitlines():
        if raw.startswith(";TYPE:"):
            typ = raw[6:].strip()
            continue
        line = raw.split(";", 1)[0].split()
        if not line or line[0] not in ("G0", "G1"):
            continue
        w = {t[0]: float(t[1:]) for t in line[1:]}
        nx, ny = w.get("X", x), w.get("Y", y)
        if w.get("E", 0.0) > 0 and (nx, ny) != (x, y):
            vol[typ] = vol.get(typ, 0.0) + w["E"] * area
        x, y = nx, ny
    return vol


def test_the_gcode_has_the_per_role_volumes_of_the_paths():
    sliced = slice_solid(solid(towers()), SlicingSettings())
    text = gcode_text(layer_pieces(sliced.layers), sliced.settings, name="towers")
    names = {PERIMETER_OUTER: "External perimeter", PERIMETER_INNER: "Perimeter", SKIN: "Solid infill",
             INFILL: "Internal infill", TOP_SKIN: "Top solid infill", BRIDGE: "Bridge infill", GAP_FILL: "Gap fill",
             OVERHANG: "Overhang perimeter"}
    expected: dict[str, float] = {}
    for L in sliced.layers:
        v = flow_area(L.width, L.height, L.role) * L.lengths()
        for role, name in names.items():
            if (L.role == role).any():
                expected[name] = expected.get(name, 0.0) + float(v[L.role == role].sum())
    got = read_volumes(text)
    assert {"External perimeter", "Perimeter", "Solid infill", "Internal infill", "Top solid infill",
            "Bridge infill", "Overhang perimeter"} <= set(got)
    assert set(got) == set(expected)
    for name in expected:
        assert got[name] == pytest.approx(expected[name], rel=2e-3), name


def test_ensure_vertical_shell_thickness_makes_solid_where_the_wall_below_is_thinner():
    """A cylinder with a conical hole narrowing upwards (its wall thicker on every layer): each
    layer's fill area reaches over the hole of the layers under it, where their walls are only
    perimeters. With the option on, that ring is solid (PrusaSlicer's discover_vertical_shells);
    off (the default, as PrusaSlicer's CLI), it is sparse: the overhang rings are too narrow to
    be bottom surfaces that reach the fill area."""
    body = m3d.Manifold.cylinder(12, 12, 12, 96) - m3d.Manifold.cylinder(12, 10, 0.5, 96)
    vols = {}
    for on in (False, True):
        layers = slice_solid(solid(body), SlicingSettings(ensure_vertical_shell_thickness=on)).layers
        v = {r: 0.0 for r in (SKIN, BRIDGE, INFILL)}
        for L in layers[10:-10]:
            for r in v:
                k = L.role == r
                v[r] += float((flow_area(L.width[k], L.height, r) * L.lengths()[k]).sum())
        vols[on] = v
    assert vols[False][SKIN] + vols[False][BRIDGE] < 0.05 * vols[False][INFILL]
    assert vols[True][SKIN] > 0.3 * vols[False][INFILL]
    # the solid ring took sparse area: about a fifth of its volume (20% infill) less sparse
    assert vols[True][INFILL] < vols[False][INFILL] - 0.12 * vols[True][SKIN]


@pytest.mark.parametrize("shape", [towers, ziggurat])
def test_every_extrusion_lies_inside_the_model(shape):
    """Every point of every extruding path lies inside its layer's section shrunk by half the
    path's width (50 um of tolerance): bridges, overhangs, gap fill and anchors included."""
    from cooprint.slicing.polysplit import _inside
    from cooprint.slicing.sections import LayerSlicer

    sol = solid(shape())
    layers = slice_solid(sol, SlicingSettings()).layers
    slicer = LayerSlicer(sol.vertices, sol.faces)
    sections = slicer.sections(np.array([L.z - L.height / 2 for L in layers]))
    for L, cs in zip(layers, sections):
        for w in np.unique(L.width[L.role != TRAVEL]):
            rings = [np.asarray(r) for r in cs.offset(-(w / 2 - 0.05), m3d.JoinType.Miter).to_polygons()]
            a0 = np.concatenate(rings)
            a1 = np.concatenate([np.roll(r, -1, axis=0) for r in rings])
            k = np.flatnonzero((L.role != TRAVEL) & (L.width == w))
            pts = np.concatenate([L.path(j) for j in k])
            assert _inside(pts, a0, a1).all(), (L.z, w)
