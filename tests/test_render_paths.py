import itertools

import numpy as np
import pytest
from PIL import Image, ImageDraw

from cooprint.config import SlicingSettings
from cooprint.io.mesh import solid_from_arrays
from cooprint.render.chunks import BACKGROUND
from cooprint.render.paths import LEGEND_ORDER, ROLE_COLOURS, legend_layout, render_layer, render_model
from cooprint.slicing import (BRIDGE, GAP_FILL, INFILL, OVERHANG, PERIMETER_INNER, PERIMETER_OUTER, ROLE_NAMES, SKIN,
                              TOP_SKIN, TRAVEL, LayerPaths, slice_solid)

from solids import box, to_trimesh


def test_layer_and_model_pictures_show_each_role(tmp_path):
    tm = to_trimesh(box(20, 20, 4))
    sliced = slice_solid(solid_from_arrays(tm.vertices, tm.faces), SlicingSettings(top_layers=2, bottom_layers=2))
    for layer_index, roles in ((0, (PERIMETER_OUTER, SKIN)), (8, (PERIMETER_OUTER, INFILL))):
        img = np.asarray(Image.open(render_layer(sliced.layers[layer_index], tmp_path / "l.png")).convert("RGB"))
        body = img[90:]  # below the title and legend
        for role in roles:
            assert (np.abs(body.astype(int) - ROLE_COLOURS[role]).sum(axis=2) == 0).sum() > 200, role
    img = np.asarray(Image.open(render_model(sliced.layers, tmp_path / "m.png")).convert("RGB"))
    assert img.shape == (800, 1200, 3) and (img[90:] != img[-1, -1]).any(axis=2).sum() > 10_000


def _every_role_layer() -> LayerPaths:
    """A layer with a patch of every role, a travel between each two."""
    def zigzag(x0, y0, step):
        ys = np.arange(y0, y0 + 10 + 1e-9, step)
        return np.vstack([np.array([[x0, y], [x0 + 10, y]])[::1 - 2 * (k % 2)] for k, y in enumerate(ys)])

    square = np.array([[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], float)
    patches = [(zigzag(0, 0, 1.0), INFILL, 0.45), (zigzag(12, 0, 0.45), SKIN, 0.45),
               (zigzag(24, 0, 0.45), TOP_SKIN, 0.4), (zigzag(0, 12, 0.45), BRIDGE, 0.45),
               (zigzag(12, 12, 1.0), GAP_FILL, 0.3), (square + [24, 12], PERIMETER_OUTER, 0.45),
               (square * 0.8 + [25, 13], PERIMETER_INNER, 0.45), (np.array([[0, 24], [34, 24]], float), OVERHANG, 0.45)]
    paths = [patches[0]]
    for p in patches[1:]:
        paths += [(np.array([paths[-1][0][-1], p[0][0]]), TRAVEL, 0.0), p]
    return LayerPaths.build(1.0, 0.2, paths)


def _lab(rgb) -> np.ndarray:
    c = np.asarray(rgb, float) / 255
    c = np.where(c > 0.04045, ((c + 0.055) / 1.055) ** 2.4, c / 12.92)
    xyz = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]]) @ c
    f = np.where(xyz / [0.95047, 1, 1.08883] > 0.008856, np.cbrt(xyz / [0.95047, 1, 1.08883]),
                 7.787 * xyz / [0.95047, 1, 1.08883] + 16 / 116)
    return np.array([116 * f[1] - 16, 500 * (f[0] - f[1]), 200 * (f[1] - f[2])])


def _luminance(rgb) -> float:
    c = np.asarray(rgb, float) / 255
    return float(np.array([0.2126, 0.7152, 0.0722]) @ np.where(c > 0.04045, ((c + 0.055) / 1.055) ** 2.4, c / 12.92))


def test_role_colours_are_distinct_and_readable_on_the_background():
    """Every role has its colour, every two at least 25 apart in CIELAB (gap fill and travel
    too), and every extrusion role at least 1.8:1 against the pictures' background."""
    assert set(ROLE_COLOURS) == set(range(len(ROLE_NAMES))) == set(LEGEND_ORDER)
    for a, b in itertools.combinations(ROLE_COLOURS, 2):
        assert np.linalg.norm(_lab(ROLE_COLOURS[a]) - _lab(ROLE_COLOURS[b])) >= 25, (ROLE_NAMES[a], ROLE_NAMES[b])
    for role, rgb in ROLE_COLOURS.items():
        if role != TRAVEL:  # travel is a thin guide line
            assert (_luminance(BACKGROUND) + 0.05) / (_luminance(rgb) + 0.05) >= 1.8, ROLE_NAMES[role]


@pytest.mark.parametrize("size", [(900, 900), (300, 300), (160, 600), (1200, 400), (2000, 1400)])
def test_the_layer_picture_draws_every_role_in_its_colour_under_a_legend_of_them(tmp_path, size):
    """Each role's colour where the role is drawn (below the legend), the legend naming each
    role present once (PrusaSlicer's order), its entries apart from each other and inside the
    picture at any size, each swatch in its role's colour."""
    layer = _every_role_layer()
    img = np.asarray(Image.open(render_layer(layer, tmp_path / "l.png", size=size)).convert("RGB"))
    assert img.shape == (size[1], size[0], 3)
    legend = legend_layout(ImageDraw.Draw(Image.new("RGB", size)), layer.role.tolist(), size, "layer at z = 1.00 mm")
    assert [e[0] for e in legend.entries] == list(LEGEND_ORDER)  # every role is in this layer
    for i, (a, b) in enumerate(itertools.combinations(legend.boxes, 2)):
        apart = a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]
        assert apart, (a, b)
    assert all(0 <= x0 and x1 <= size[0] and 0 <= y0 and y1 <= legend.bottom for x0, y0, x1, y1 in legend.boxes)
    body = img[legend.bottom:]
    for role, (x0, y0, x1, y1), _ in legend.entries:
        exact = (np.abs(body.astype(int) - ROLE_COLOURS[role]).sum(axis=2) == 0).sum()
        assert exact > (5 if role in (TRAVEL, OVERHANG) else 20), ROLE_NAMES[role]
        assert (img[y0 + 1:y1, x0 + 1:x1] == ROLE_COLOURS[role]).all(axis=2).mean() > 0.9, ROLE_NAMES[role]


def test_the_model_picture_names_the_roles_present(tmp_path):
    """render_model's legend lists the roles of the model's extrusions (not travel), however few."""
    layer = _every_role_layer()
    size = (1200, 800)
    render_model([layer], tmp_path / "m.png", size=size)
    extruded = [r for r in layer.role.tolist() if r != TRAVEL]
    legend = legend_layout(ImageDraw.Draw(Image.new("RGB", size)), extruded, size, "1 layers")
    assert [e[0] for e in legend.entries] == [r for r in LEGEND_ORDER if r != TRAVEL]
    img = np.asarray(Image.open(tmp_path / "m.png").convert("RGB"))
    for role, (x0, y0, x1, y1), _ in legend.entries:
        assert (img[y0 + 1:y1, x0 + 1:x1] == ROLE_COLOURS[role]).all(axis=2).mean() > 0.9, ROLE_NAMES[role]
    only = LayerPaths.build(1.0, 0.2, [(np.array([[0, 0], [10, 0]], float), BRIDGE, 0.45)])
    assert [e[0] for e in legend_layout(ImageDraw.Draw(Image.new("RGB", size)), [BRIDGE], size, "").entries] == [BRIDGE]
    render_model([only], tmp_path / "b.png", size=size)  # one role: one entry, the bridge's colour in it
    img = np.asarray(Image.open(tmp_path / "b.png").convert("RGB"))
    assert (img == ROLE_COLOURS[BRIDGE]).all(axis=2).sum() > 30
