"""The loader's repairs (cooprint.io.repair): non-manifold edges split, fins dropped, flipped
patches turned back, holes closed without repeating an edge; the solid's volume and sections are
those of the intended part, and what cannot be repaired is refused in one line."""

import manifold3d as m3d
import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st

from cooprint.config import JobSettings, MeshSettings
from cooprint.errors import MeshError
from cooprint.geometry import is_closed
from cooprint.io.mesh import solid_from_arrays, solid_from_trimesh
from cooprint.io.repair import fill_loop
from cooprint.jobs import load_placed
from cooprint.slicing.sections import LayerSlicer

from solids import box, to_trimesh


def _cube_soup(lo, size=10.0) -> np.ndarray:
    """(36, 3) corners of an axis-aligned cube's 12 triangles, outward."""
    tm = trimesh.creation.box(extents=(size, size, size))
    tm.apply_translation(np.asarray(lo, dtype=float) + size / 2)
    return tm.vertices[tm.faces].reshape(-1, 3)


def _section_area(solid, z: float) -> float:
    rings = LayerSlicer(solid.vertices, solid.faces).sections(np.array([z]))
    return rings[0].area()


def test_two_cubes_sharing_an_edge_are_split_apart_and_slice():
    """Two cubes touching along one vertical edge: that edge has four triangles. The solid is
    both cubes (volume 2000), its edge split so every edge has two faces, and a section is two
    squares of 100 mm2."""
    soup = np.vstack([_cube_soup((0, 0, 0)), _cube_soup((10, 10, 0))])
    s = solid_from_arrays(soup, None, path="two.stl", fmt="stl")
    assert is_closed(s.faces)
    assert s.volume == pytest.approx(2000.0, rel=1e-12)
    assert s.report.triangles == 24
    assert s.report.vertices == 16  # the two shared corners once per cube
    assert any(r.startswith("split 1 non-manifold edges") for r in s.report.repairs)
    assert _section_area(s, 5.0) == pytest.approx(200.0, rel=1e-9)


def test_a_fin_on_an_edge_is_dropped():
    """A lone triangle hanging off a cube's edge (three faces on the edge): removed, the cube
    kept whole."""
    cube = to_trimesh(box(20, 30, 10))
    v = cube.vertices
    a, b = next((i, j) for i, j in cube.edges_unique if abs(v[i, 2] - v[j, 2]) > 5)  # a vertical edge
    fin = np.vstack([v, [v[a] + (v[a] - v.mean(axis=0)) * [1, 1, 0]]])  # sticking out sideways
    faces = np.vstack([cube.faces, [[a, b, len(v)]]])
    s = solid_from_arrays(fin, faces, path="fin.obj", fmt="obj")
    assert s.volume == pytest.approx(6000.0, rel=1e-12)
    assert s.report.triangles == 12
    assert any("non-manifold" in r or "unconnected" in r for r in s.report.repairs)


def test_a_sheet_inside_the_solid_is_cut_loose_and_dropped():
    """Two triangles through a box, sharing its edge (four faces there): the box is kept."""
    cube = to_trimesh(box(20, 30, 10))
    faces = np.vstack([cube.faces, [[0, 1, 7]], [[1, 0, 6]]])
    s = solid_from_trimesh(trimesh.Trimesh(cube.vertices, faces, process=False), path="nm.stl")
    assert s.volume == pytest.approx(6000.0, rel=1e-12)
    assert s.report.triangles == 12
    assert s.report.repairs == ("split 1 non-manifold edges (shared by more than two triangles)",
                                "removed 2 unconnected triangles (sharing no edge, or cut loose by the split)")


def test_a_flipped_patch_is_turned_back():
    """A connected patch of a sphere wound the wrong way: turned back, counted, volume kept."""
    man = m3d.Manifold.sphere(20, 64)
    tm = to_trimesh(man)
    centre = tm.triangles_center
    patch = centre[:, 0] > 12  # a cap of the sphere
    faces = tm.faces.copy()
    faces[patch] = faces[patch][:, ::-1]
    s = solid_from_arrays(tm.vertices, faces, path="flip.obj", fmt="obj")
    assert s.volume == pytest.approx(man.volume(), rel=1e-12)
    assert 0 < patch.sum() < len(faces) / 2
    assert s.report.repairs == (f"made triangle winding consistent ({int(patch.sum())} triangles turned over)",)


@pytest.mark.parametrize("n_faces", [1, 3, 8])
def test_a_small_hole_is_closed_and_slices(n_faces):
    man = m3d.Manifold.sphere(30, 96)
    tm = to_trimesh(man)
    keep = np.ones(len(tm.faces), dtype=bool)
    keep[len(keep) // 2:len(keep) // 2 + n_faces] = False
    s = solid_from_arrays(tm.vertices, tm.faces[keep], MeshSettings(max_hole_fraction=0.5), path="hole.obj",
                          fmt="obj")
    assert is_closed(s.faces)
    assert s.volume == pytest.approx(man.volume(), rel=2e-3)
    assert any(r.startswith("closed") for r in s.report.repairs)
    assert _section_area(s, 30.0) == pytest.approx(m3d.Manifold.sphere(30, 96).slice(30.0).area(), rel=1e-3)


def test_an_open_bottom_is_refused_by_default_and_closed_with_the_setting_named():
    """A cylinder without its bottom (perimeter 1.62 x its diagonal): the default rule refuses
    it naming the setting; with that setting it closes flat and keeps the cylinder's volume."""
    man = m3d.Manifold.cylinder(40, 15, 15, 72)
    tm = to_trimesh(man)
    bottom = (tm.vertices[tm.faces][:, :, 2] < 1e-9).all(axis=1)
    with pytest.raises(MeshError, match=r"--set mesh\.max_hole_fraction=1\.7\) to close it"):
        solid_from_arrays(tm.vertices, tm.faces[~bottom], path="cup.obj", fmt="obj")
    s = solid_from_arrays(tm.vertices, tm.faces[~bottom], MeshSettings(max_hole_fraction=1.7), path="cup.obj",
                          fmt="obj")
    assert s.volume == pytest.approx(man.volume(), rel=1e-9)
    assert _section_area(s, 0.1) == pytest.approx(man.slice(0.1).area(), rel=1e-9)


def test_a_cap_never_repeats_an_edge_of_the_mesh():
    """A square hole whose corners 0 and 2 are joined by an edge of the mesh already: the cap
    takes the other diagonal (a second 0-2 edge would be non-manifold)."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], dtype=float)
    loop = np.array([0, 1, 2, 3])
    new_v, cap = fill_loop(v, loop, np.array([0 * 4 + 2]))
    assert len(new_v) == 0
    edges = {tuple(sorted(e)) for t in cap.tolist() for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))}
    assert (1, 3) in edges and (0, 2) not in edges
    # against the loop: the cap holds b -> a for each loop edge a -> b
    directed = {(t[i], t[(i + 1) % 3]) for t in cap.tolist() for i in range(3)}
    assert {(1, 0), (2, 1), (3, 2), (0, 3)} <= directed


def test_a_moebius_strip_is_refused_in_one_line():
    """Not orientable: no winding makes it a solid's boundary, whatever the hole setting."""
    n = 24
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    centre = np.c_[np.cos(t), np.sin(t), 0 * t] * 30
    across = np.c_[np.cos(t) * np.cos(t / 2), np.sin(t) * np.cos(t / 2), np.sin(t / 2)] * 5
    v = np.vstack([centre + across, centre - across])
    i = np.arange(n)
    j = (i + 1) % n
    top, bot = i, i + n
    top_j = np.where(j == 0, n, j)  # after a turn the strip comes back upside down
    bot_j = np.where(j == 0, 0, j + n)
    faces = np.vstack([np.c_[top, bot, top_j], np.c_[bot, bot_j, top_j]])
    with pytest.raises(MeshError) as exc:
        solid_from_arrays(v, faces, MeshSettings(max_hole_fraction=10), path="moebius.obj", fmt="obj")
    assert "\n" not in str(exc.value) and "moebius.obj" in str(exc.value)


def test_slice_notes_the_repairs_on_stderr(tmp_path, capsys):
    soup = np.vstack([_cube_soup((0, 0, 0)), _cube_soup((10, 10, 0))])
    path = tmp_path / "two.stl"
    trimesh.Trimesh(soup, np.arange(len(soup)).reshape(-1, 3), process=False).export(path)
    solid, _ = load_placed(path, JobSettings())
    err = capsys.readouterr().err
    assert err.strip() == f"cooprint: note: {path}: repaired: split 1 non-manifold edges (shared by more than " \
                          "two triangles)"
    assert solid.volume == pytest.approx(2000.0, rel=1e-6)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.integers(0, 1151), min_size=1, max_size=12, unique=True))
def test_any_few_missing_triangles_close_to_the_same_solid(missing):
    """Triangles dropped anywhere from a sphere (holes touching at corners included): the
    repaired mesh is closed, every edge has two faces, and the volume is the sphere's within
    the area of the holes' flattening (0.5 %)."""
    man = m3d.Manifold.sphere(30, 24)
    tm = to_trimesh(man)
    keep = np.ones(len(tm.faces), dtype=bool)
    keep[[i % len(keep) for i in missing]] = False
    s = solid_from_arrays(tm.vertices, tm.faces[keep], MeshSettings(max_hole_fraction=10), path="holes.obj",
                          fmt="obj")
    assert is_closed(s.faces)
    assert s.volume == pytest.approx(man.volume(), rel=5e-3)


def test_the_loaders_fast_checks_agree_with_the_general_ones():
    """The compiled triangle check and the sorted-key search for faces sharing no edge find
    what the whole-array definitions find: repeats (in any corner order), zero-area and
    collapsed triangles, and stray faces."""
    from cooprint.geometry import distinct_corners
    from cooprint.io.mesh import _proper_faces
    from cooprint.io.repair import _edge_groups, _lone, _lone_unless_split

    tm = trimesh.creation.icosphere(subdivisions=2)
    v = np.vstack([tm.vertices, [[5.0, 0, 0], [6.0, 0, 0], [7.0, 0, 0], [5.0, 1.0, 0]]])
    n = len(tm.vertices)
    extra = [tm.faces[3][[1, 2, 0]], tm.faces[7][::-1], [n, n + 1, n + 2], [0, 0, 1], [n, n + 1, n + 3]]
    f = np.vstack([tm.faces, extra]).astype(np.int32)
    cross = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    unique = np.zeros(len(f), dtype=bool)
    unique[first] = True
    want = distinct_corners(f) & (np.linalg.norm(cross, axis=1) > 0) & unique
    assert np.array_equal(_proper_faces(v, f), want)
    assert (~want).sum() == 4  # the two repeats, the flat triangle and the collapsed one
    kept = f[want]
    order, _, runs = _edge_groups(kept)
    assert np.array_equal(_lone_unless_split(kept), _lone(order, runs))
    assert _lone_unless_split(kept).sum() == 1  # the stray triangle off the sphere
    assert _lone_unless_split(np.vstack([kept, kept[:1]])) is None  # three faces on an edge
