import numpy as np
from PIL import Image

from cooprint.config import SlicingSettings
from cooprint.io.mesh import solid_from_arrays
from cooprint.render.paths import ROLE_COLOURS, render_layer, render_model
from cooprint.slicing import INFILL, PERIMETER_OUTER, SKIN, slice_solid

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
