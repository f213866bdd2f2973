import gzip

import manifold3d as m3d
import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from cooprint.config import MeshSettings
from cooprint.errors import MeshError
from cooprint.io.mesh import _merge_vertices, load_mesh, solid_from_trimesh

from solids import box, car, to_trimesh, with_hole

CUBE_VOLUME = 20.0 * 30.0 * 10.0


@pytest.fixture
def cube_tm():
    return to_trimesh(box(20, 30, 10))


@pytest.mark.parametrize("name", ["a.stl", "a_ascii.stl", "a.obj", "a.ply", "a.3mf",
                                  "a.stl.gz", "a.obj.gz", "a.ply.gz", "a.3mf.gz"])
def test_every_format_loads_the_same_solid(tmp_path, cube_tm, name):
    path = tmp_path / name
    base = name.removesuffix(".gz")
    if base == "a_ascii.stl":
        data = trimesh.exchange.stl.export_stl_ascii(cube_tm).encode()
    else:
        data = cube_tm.export(file_type=base.rsplit(".", 1)[1])
        data = data.encode() if isinstance(data, str) else data
    path.write_bytes(gzip.compress(data) if name.endswith(".gz") else data)
    s = load_mesh(path)
    assert s.volume == pytest.approx(CUBE_VOLUME, rel=1e-6)
    assert s.report.triangles == 12
    assert s.report.watertight_as_read
    np.testing.assert_allclose(s.bounds, [[-10, -15, 0], [10, 15, 10]], atol=1e-5)


def test_report_counts_and_no_repairs_on_clean_mesh(cube_tm):
    s = solid_from_trimesh(cube_tm, fmt="stl")
    assert s.report.repairs == ()
    assert s.report.vertices == 8


def test_inverted_mesh_is_turned_outward(cube_tm):
    cube_tm.invert()
    s = solid_from_trimesh(cube_tm)
    assert s.volume == pytest.approx(CUBE_VOLUME)
    assert any("inside-out" in r for r in s.report.repairs)


def test_inconsistent_winding_is_fixed():
    tm = to_trimesh(car())
    faces = tm.faces.copy()
    faces[::7] = faces[::7, ::-1]
    s = solid_from_trimesh(trimesh.Trimesh(tm.vertices, faces, process=False))
    assert s.volume == pytest.approx(car().volume(), rel=1e-9)
    assert any("winding" in r for r in s.report.repairs)


def test_duplicate_and_degenerate_triangles_are_dropped(cube_tm):
    faces = np.vstack([cube_tm.faces, cube_tm.faces[:2], [[0, 0, 1]]])
    s = solid_from_trimesh(trimesh.Trimesh(cube_tm.vertices, faces, process=False))
    assert s.report.triangles == 12
    assert any("degenerate or duplicate" in r for r in s.report.repairs)


@pytest.mark.parametrize("n_faces", [1, 2, 5])
def test_small_hole_is_closed_and_reported(n_faces):
    man = m3d.Manifold.sphere(30, 96)
    s = solid_from_trimesh(with_hole(man, n_faces))
    assert s.volume == pytest.approx(man.volume(), rel=1e-3)
    assert any("closed" in r and "hole" in r for r in s.report.repairs)


def test_big_hole_is_refused_with_the_setting_named():
    tm = to_trimesh(box(20, 30, 10))
    tm.update_faces(np.arange(len(tm.faces)) >= 2)  # drop one whole side
    with pytest.raises(MeshError, match=r"too large to close .*mesh.max_hole_fraction"):
        solid_from_trimesh(tm, MeshSettings(max_hole_fraction=0.01), path="open.stl")


def _write(tmp_path, name, data: bytes):
    p = tmp_path / name
    p.write_bytes(data)
    return p


@pytest.mark.parametrize("name, data, needle", [
    ("empty.stl", b"", "file is empty"),
    ("blank.obj", b"   \n\n", "file is empty"),
    ("garbage.stl", b"\x00\xff" * 300, "truncated or not an STL"),
    ("short.stl", b"abc", "too short for a binary STL"),
    ("noend.stl", b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n", "no 'endsolid'"),
    ("garbage.3mf", b"PK\x03\x04 not really a zip", "not a 3MF file"),
    ("garbage.ply", b"ply\nformat nonsense\n", "not a PLY file"),
    ("noface.obj", b"v 0 0 0\nv 1 0 0\n", "no triangles"),
    ("bad.stl.gz", b"\x1f\x8b\x08\x00garbage", "cannot read gzip"),
    ("model.xyz", b"1 2 3", "unknown mesh format 'xyz'; expected one of .stl, .obj, .ply, .3mf"),
])
def test_hostile_files_give_one_line_errors(tmp_path, name, data, needle):
    p = _write(tmp_path, name, data)
    with pytest.raises(MeshError) as err:
        load_mesh(p)
    assert needle in str(err.value)
    assert str(p) in str(err.value)
    assert "\n" not in str(err.value)


def test_truncated_binary_stl(tmp_path, cube_tm):
    data = cube_tm.export(file_type="stl")
    p = _write(tmp_path, "cut.stl", data[:-30])
    with pytest.raises(MeshError, match=r"header says 12 triangles \(684 bytes\) but the file has 654"):
        load_mesh(p)


def test_absurd_triangle_count_header_does_not_allocate(tmp_path):
    data = b"x" * 80 + np.uint32(4_000_000_000).tobytes() + b"\0" * 100
    with pytest.raises(MeshError, match="header says 4000000000 triangles"):
        load_mesh(_write(tmp_path, "huge.stl", data))


@pytest.mark.parametrize("value, needle", [(np.nan, "NaN or infinite"), (np.inf, "NaN or infinite"),
                                            (1e12, "wrong units")])
def test_non_finite_and_absurd_coordinates(tmp_path, cube_tm, value, needle):
    v = cube_tm.vertices.copy()
    v[3, 1] = value
    tm = trimesh.Trimesh(v, cube_tm.faces, process=False)
    p = _write(tmp_path, "bad.obj", tm.export(file_type="obj").encode())
    with pytest.raises(MeshError, match=needle):
        load_mesh(p)


def test_missing_file(tmp_path):
    with pytest.raises(MeshError, match="nope.stl: no such mesh file"):
        load_mesh(tmp_path / "nope.stl")


def test_streamed_binary_stl_equals_the_in_memory_parse(tmp_path):
    tm = to_trimesh(car())
    data = tm.export(file_type="stl")
    plain, packed = _write(tmp_path, "car.stl", data), _write(tmp_path, "car.stl.gz", gzip.compress(data))
    ref = solid_from_trimesh(tm, fmt="stl")
    for p in (plain, packed):
        s = load_mesh(p)
        assert s.faces.dtype == np.int32
        assert s.report.triangles == len(tm.faces) and s.report.vertices == ref.report.vertices
        assert s.volume == pytest.approx(ref.volume, rel=1e-6)
        # the same triangles, corner for corner (float32 precision of the file)
        np.testing.assert_allclose(np.sort(s.vertices[s.faces].reshape(-1, 9), axis=0),
                                   np.sort(tm.vertices[tm.faces].reshape(-1, 9), axis=0), atol=1e-4)


def test_padded_binary_stl_is_refused(tmp_path, cube_tm):
    data = cube_tm.export(file_type="stl") + b"\0" * 50
    with pytest.raises(MeshError, match=r"header says 12 triangles \(684 bytes\) but the file has 734"):
        load_mesh(_write(tmp_path, "pad.stl", data))
    with pytest.raises(MeshError, match=r"header says 12 triangles"):
        load_mesh(_write(tmp_path, "pad.stl.gz", gzip.compress(data)))


@settings(max_examples=40, deadline=None)
@given(st.integers(1, 400), st.integers(0, 2**32 - 1))
def test_merging_a_soup_keeps_every_corner_and_leaves_no_duplicate(n_points, seed):
    rng = np.random.default_rng(seed)
    # few distinct points (some -0.0, some on a grid) used many times: a soup with repeats
    pts = np.round(rng.normal(size=(n_points, 3)) * 4) / 2
    pts[rng.random(pts.shape) < 0.1] = -0.0
    soup = pts[rng.integers(0, n_points, size=3 * 200)].astype(np.float32)
    verts, faces = _merge_vertices(soup.copy(), None)
    assert faces.dtype == np.int32
    np.testing.assert_array_equal(verts[faces.ravel()], soup.astype(np.float64) + 0.0)
    assert len(np.unique(verts, axis=0)) == len(verts) == len(np.unique(soup + 0.0, axis=0))


def test_a_box_missing_one_triangle_names_the_fraction_that_closes_it():
    """The hole of one missing triangle of a 40 x 30 x 20 box's 40 x 20 side has a perimeter of
    104.7 mm, 1.94 x the diagonal (53.9 mm): the refusal names the fraction that closes it, and
    that fraction (allowed up to 10) closes it."""
    tm = to_trimesh(box(40, 30, 20))
    side = np.flatnonzero(np.abs(tm.face_normals[:, 1]) > 0.99)[0]
    tm.update_faces(np.arange(len(tm.faces)) != side)
    with pytest.raises(MeshError, match=r"largest perimeter 104\.7 mm.*set mesh\.max_hole_fraction >= 1\.95 "
                                        r"\(--set mesh\.max_hole_fraction=2\) to close it"):
        solid_from_trimesh(tm, MeshSettings(), path="box.stl")
    s = solid_from_trimesh(tm, MeshSettings(max_hole_fraction=2.0), path="box.stl")
    assert s.volume == pytest.approx(40 * 30 * 20)
    from cooprint.io.mesh import _hole_hint

    assert "more than mesh.max_hole_fraction allows (10)" in _hole_hint(12.0)  # beyond the field: no setting helps
    assert _hole_hint(10.0).startswith("set mesh.max_hole_fraction >= 10.00 (--set mesh.max_hole_fraction=10)")



def _cube_3mf(path, edit_model):
    """A 2 mm cube as a 3MF file at ``path``, its model part's bytes passed through ``edit_model``."""
    import io
    import zipfile

    from solids import box, to_trimesh

    src = zipfile.ZipFile(io.BytesIO(to_trimesh(box(2, 2, 2)).export(file_type="3mf")))
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        for name in src.namelist():
            data = src.read(name)
            z.writestr(name, edit_model(data) if name.endswith(".model") else data)
    path.write_bytes(out.getvalue())
    return path


@pytest.mark.parametrize("unit, mm", [("inch", 25.4), ("centimeter", 10.0), ("millimeter", 1.0), (None, 1.0)])
def test_a_3mf_is_read_in_its_own_unit(tmp_path, unit, mm):
    """A 3MF states its unit on <model> (millimeter when absent): an inch model was read as mm."""
    import re

    attr = b"" if unit is None else b' unit="%s"' % unit.encode()
    solid = load_mesh(_cube_3mf(tmp_path / "m.3mf", lambda d: re.sub(rb'\sunit="[^"]*"', attr, d)))
    assert np.ptp(solid.bounds, axis=0) == pytest.approx([2 * mm] * 3)
    assert solid.volume == pytest.approx(8 * mm ** 3)


def test_a_3mf_in_an_unknown_unit_is_refused(tmp_path):
    path = _cube_3mf(tmp_path / "m.3mf", lambda d: d.replace(b'unit="millimeter"', b'unit="furlong"'))
    with pytest.raises(MeshError, match="3MF model unit 'furlong'; expected one of micron, millimeter"):
        load_mesh(path)
