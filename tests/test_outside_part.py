"""The outside-part check (issue 13, item 4): material outside the part (the union of a bundle's
chunks) or outside every chunk of the robot that lays it, with a tolerance of half a line width."""

from __future__ import annotations

import json
import re
import shutil

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from badinput import assert_rejected
from cooprint.simulation import KINDS, kernels, load_inputs, simulate
from cooprint.simulation.checks import OUTSIDE_SLACK

from solids import bar_bundle

MOVE = re.compile(r"MOVE (-?[0-9.]+), (-?[0-9.]+), (-?[0-9.]+)")


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    """A real two-robot bundle of a 40 x 420 x 12 mm bar: A prints C then L1 (y < 0), B prints R1."""
    return bar_bundle(tmp_path_factory.mktemp("outside"), 12)


def _copy(bundle, tmp_path):
    out = tmp_path / "job"
    shutil.copytree(bundle, out)
    return out


def _edit_chunk(path, chunk, change):
    """Rewrite the MOVE lines of ``chunk`` in the .coop file ``path`` with ``change(x, y, z)``."""
    lines, inside = [], False
    for line in path.read_text().splitlines(keepends=True):
        if line.startswith(";@chunk "):
            inside = line.split()[1] == chunk
        m = MOVE.match(line)
        if inside and m:
            x, y, z = change(*(float(v) for v in m.groups()))
            line = f"MOVE {x:.3f}, {y:.3f}, {z:.3f}\n"
        lines.append(line)
    path.write_text("".join(lines))


def _deposit_heights(path):
    """The heights of the moves that deposit (between TOOL ON and TOOL OFF) in a .coop file."""
    tool, out = False, []
    for line in path.read_text().splitlines():
        tool = True if line == "TOOL ON" else False if line == "TOOL OFF" else tool
        m = MOVE.match(line)
        if tool and m:
            out.append(float(m.group(3)))
    return out


def _outside(res):
    return [f for f in res.findings if f.kind == "outside-part"]


def test_the_plan_as_written_lies_inside_its_chunks(bundle):
    res = simulate(load_inputs([str(bundle)]))
    assert "outside-part" in res.checked and "outside-part" in KINDS
    assert _outside(res) == []


def test_a_chunk_shifted_into_empty_space_is_outside_the_part(bundle, tmp_path):
    job = _copy(bundle, tmp_path)
    _edit_chunk(job / "robots" / "A.coop", "L1", lambda x, y, z: (x + 50.0, y, z))
    found = _outside(simulate(load_inputs([str(job)])))
    assert len(found) == 1
    f = found[0]
    assert f.robot == "A" and f.chunk == "L1" and f.severity == "error"
    assert "outside the part" in f.detail
    assert f.position[0] > 20.0 + 0.8  # beyond the bar's side (x = 20) by more than half a line
    assert f.count > 100


def test_material_of_one_robot_in_the_others_chunk_is_named(bundle, tmp_path):
    """A's chunk L1 (y < 0) mirrored onto B's R1 (y > 0): inside the part, in the wrong chunk."""
    job = _copy(bundle, tmp_path)
    _edit_chunk(job / "robots" / "A.coop", "L1", lambda x, y, z: (x, -y, z))
    found = _outside(simulate(load_inputs([str(job)])))
    assert len(found) == 1
    f = found[0]
    assert f.robot == "A" and f.chunk == "L1"
    assert "another robot's chunk" in f.detail and "chunk R1" in f.detail and "printed by B" in f.detail
    assert "outside the part" not in f.detail
    assert f.position[1] > 0


def test_a_small_shift_within_half_a_line_is_tolerated(bundle, tmp_path):
    """The outer perimeter's centre lies half a line inside the outline: a shift of a line puts it
    half a line outside (the tolerance: no finding), 0.1 mm more is a finding."""
    w = json.loads((bundle / "job.json").read_text())["settings"]["slicing"]["extrusion_width"]
    for shift, expect in ((w, 0), (w + 0.1, 1)):
        job = _copy(bundle, tmp_path / str(shift))
        _edit_chunk(job / "robots" / "B.coop", "R1", lambda x, y, z: (x + shift, y, z))
        found = _outside(simulate(load_inputs([str(job)])))
        assert len(found) == expect, (shift, found)
        if expect:
            assert found[0].robot == "B" and "outside the part" in found[0].detail
            assert found[0].position[0] > 20.0 + w / 2 + OUTSIDE_SLACK


def test_the_top_layer_of_a_chunk_is_inside(bundle, tmp_path):
    """Material points are at the bead's top; the top layer of a chunk lies at its top face. Moved
    up one more layer, it is above the part."""
    job = _copy(bundle, tmp_path)
    top = max(_deposit_heights(job / "robots" / "B.coop"))
    assert top == pytest.approx(12.0)
    _edit_chunk(job / "robots" / "B.coop", "R1", lambda x, y, z: (x, y, z + 1.0 if z == top else z))
    found = _outside(simulate(load_inputs([str(job)])))
    assert len(found) == 1 and found[0].position[2] == pytest.approx(13.0)


def test_without_chunk_meshes_the_check_is_not_claimed(bundle, tmp_path):
    job = _copy(bundle, tmp_path)
    record = json.loads((job / "job.json").read_text())
    for c in record["chunks"]:
        del c["file"]
    (job / "job.json").write_text(json.dumps(record))
    res = simulate(load_inputs([str(job)]))
    assert "outside-part" not in res.checked and _outside(res) == []


def test_a_missing_or_broken_chunk_mesh_is_a_clear_error(bundle, tmp_path, capsys):
    job = _copy(bundle, tmp_path)
    (job / "chunks" / "L1.stl").unlink()
    line = assert_rejected(["simulate", job], capsys, [job])
    assert "chunks[1].file" in line and "no such chunk mesh" in line and "chunks/L1.stl" in line

    job = _copy(bundle, tmp_path / "broken")
    (job / "chunks" / "R1.stl").write_bytes(b"solid nothing\nendsolid\n")
    line = assert_rejected(["simulate", job], capsys, [job])
    assert "chunks[2].file" in line and "R1.stl" in line

    job = _copy(bundle, tmp_path / "folder")
    record = json.loads((job / "job.json").read_text())
    record["chunks"][0]["file"] = "../elsewhere.stl"
    (job / "job.json").write_text(json.dumps(record))
    line = assert_rejected(["simulate", job], capsys, [job])
    assert "chunks[0].file" in line and "inside the bundle" in line


# ----------------------------------------------------------------------------------------------
# the point test against a plain definition


def _brute(points, segs, tol):
    """Inside by the parity of a ray's crossings over every segment, or within ``tol`` of one."""
    px, py = points[:, 0:1], points[:, 1:2]
    x0, y0, x1, y1 = (segs[:, k][None, :] for k in range(4))
    spans = (y0 > py) != (y1 > py)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = x0 + (py - y0) * (x1 - x0) / (y1 - y0)
    inside = (spans & (x < px)).sum(axis=1) % 2 == 1
    dx, dy = x1 - x0, y1 - y0
    ll = dx * dx + dy * dy
    f = np.clip(((px - x0) * dx + (py - y0) * dy) / np.where(ll > 0, ll, 1), 0, 1)
    d2 = (x0 + f * dx - px) ** 2 + (y0 + f * dy - py) ** 2
    return inside | (d2.min(axis=1) <= tol * tol), d2.min(axis=1)


def _ring(cx, cy, radii, turn):
    a = np.linspace(0, 2 * np.pi, len(radii), endpoint=False) + turn
    pts = np.column_stack([cx + radii * np.cos(a), cy + radii * np.sin(a)])
    return np.column_stack([pts, np.roll(pts, -1, axis=0)])


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(3, 120), tol=st.floats(0.05, 3.0))
def test_the_section_test_agrees_with_every_segment(seed, n, tol):
    """Random star-shaped outlines with a hole, points all over their box: the grid's answer is
    the plain one (points within 1e-9 mm of the tolerance left out)."""
    rng = np.random.default_rng(seed)
    outer = _ring(0.0, 0.0, rng.uniform(20, 60, n), rng.uniform(0, 6))
    hole = _ring(rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(4, 12, max(3, n // 3)), 0.0)[:, [2, 3, 0, 1]]
    segs = np.vstack([outer, hole])
    pts = rng.uniform(-70, 70, (3000, 3)).astype(np.float32)
    near = segs[rng.integers(0, len(segs), 1000)]  # and points near the outline
    f = rng.uniform(0, 1, (1000, 1))
    pts[:1000, :2] = near[:, :2] + f * (near[:, 2:] - near[:, :2]) + rng.normal(0, tol, (1000, 2))
    want, d2 = _brute(pts.astype(np.float64), segs, tol)
    got = np.zeros(len(pts), dtype=bool)
    half = len(pts) // 2  # two runs of one section
    kernels.inside_sections(pts, np.array([0, half]), np.array([half, len(pts)]), np.zeros(2, np.int64),
                            np.array([tol, tol / 2]), np.array([0, len(segs)]), segs, got)
    clear = np.abs(np.sqrt(d2) - tol) > 1e-9
    assert np.array_equal(got[clear], want[clear])


def test_sections_of_a_mesh_are_its_outline_at_each_height():
    """A box's sections: four segments at each height inside it, none above."""
    from solids import box, to_trimesh

    tm = to_trimesh(box(40, 60, 10))
    heights = np.array([0.5, 5.0, 9.5, 10.5])
    counts = kernels.section_counts(np.asarray(tm.vertices), np.asarray(tm.faces), heights)
    assert counts[3] == 0 and counts[:3].min() >= 4
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    segs = np.empty((offsets[-1], 4))
    kernels.section_segments(np.asarray(tm.vertices), np.asarray(tm.faces), heights, offsets, segs)
    ends = segs.reshape(-1, 2)
    assert np.allclose(np.abs(ends[:, 0]).max(), 20) and np.allclose(np.abs(ends[:, 1]).max(), 30)
    assert np.all(np.isclose(np.abs(ends[:, 0]), 20) | np.isclose(np.abs(ends[:, 1]), 30))


def test_sections_made_a_few_at_a_time_give_the_same_findings(bundle, tmp_path, monkeypatch):
    """The sections are made in blocks of at most SECTION_SEGMENTS segments: blocks of one
    section each find what one block of all of them finds."""
    from cooprint.simulation import checks

    job = _copy(bundle, tmp_path)
    _edit_chunk(job / "robots" / "B.coop", "R1", lambda x, y, z: (x + 0.3 * z, y, z))  # a leaning chunk
    whole = _outside(simulate(load_inputs([str(job)])))
    monkeypatch.setattr(checks, "SECTION_SEGMENTS", 1)
    assert _outside(simulate(load_inputs([str(job)]))) == whole
    assert len(whole) == 1 and whole[0].robot == "B" and whole[0].count > 0


def test_the_cli_fails_a_plan_with_material_outside_the_part(bundle, tmp_path, capsys):
    from cooprint.cli import main

    job = _copy(bundle, tmp_path)
    _edit_chunk(job / "robots" / "B.coop", "R1", lambda x, y, z: (x - 50.0, y, z))
    assert main(["simulate", str(job), "-q"]) == 1
    s = json.loads((job / "sim" / "summary.json").read_text())
    assert s["finding_counts"]["outside-part"] > 0 and "outside-part" in s["checked"]
    assert {f["kind"] for f in s["findings"] if f["severity"] == "error"} >= {"outside-part"}
    assert "outside-part" in capsys.readouterr().err
