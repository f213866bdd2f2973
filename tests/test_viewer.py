"""The interactive viewer's page, without a browser (issue 16): ``write_viewer`` writes one file
that fetches nothing and carries three.js's licence; its buffers decode back to the material
the plan lays down (within the level of detail's tolerance) in time order; a plan above the
budget is thinned and says so; ``cooprint view`` on a bundle without a simulation simulates it
first, on a G-code ``simulate --out`` folder reads the G-code again, and refuses what it cannot
view in one line. The page in a real browser: tests/test_viewer_browser.py."""

from __future__ import annotations

import json
import os
import re
import shutil

import numpy as np
import pytest

import solids
from badinput import assert_rejected
from cooprint.cli import main
from cooprint.render.viewer import ASSETS, write_viewer
from cooprint.render.viewer.geometry import QMAX, build_geometry, decode, feature_edges, simplify
from cooprint.render.sim import BLOCK_MOVES
from cooprint.simulation import load_inputs, simulate, summary
from cooprint.simulation.inputs import read_chunk_meshes

built = pytest.mark.skipif(not (ASSETS / "viewer.js").exists(),
                           reason="the viewer's JavaScript is not built: run `make viewer` (Node.js and npm)")


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    return solids.bar_bundle(tmp_path_factory.mktemp("viewer"), 6)


@pytest.fixture(scope="module")
def plan(bundle):
    inp = load_inputs([str(bundle)], programs=False)
    return inp, simulate(inp)


def _page_parts(html: str) -> tuple[dict, str]:
    meta = re.search(r'<script type="application/json" id="cooprint-meta">(.*?)</script>', html, re.S).group(1)
    data = re.search(r'<script type="application/octet-stream" id="cooprint-geometry"[^>]*>(.*?)</script>', html,
                     re.S).group(1)
    return json.loads(meta.replace("<\\/", "</")), data


@built
def test_the_page_is_one_file_that_fetches_nothing_and_carries_the_licence(plan, tmp_path):
    inp, result = plan
    path = write_viewer(result, summary(result), tmp_path / "viewer.html", chunks=read_chunk_meshes(inp),
                        critical=inp.critical_path, lower_bound=inp.lower_bound, title="bar")
    html = path.read_text(encoding="utf-8")
    assert html.startswith("<!-- cooprint-viewer/1")
    # nothing to fetch: no external script, style, image or module; the only URLs are XML
    # namespaces and documentation links in the bundled code's strings, never loaded
    assert not re.search(r"""<(script|link|img|iframe)[^>]*\s(src|href)\s*=""", html, re.I)
    assert not re.search(r"""(import\s*\(|from\s*)["']https?://|url\(\s*["']?https?://""", html)
    urls = set(re.findall(r"https?://[^\s\"'`<>)]+", html))
    assert all(u.startswith("http://www.w3.org/") for u in urls), urls
    licence = (ASSETS / "three-LICENSE.txt").read_text(encoding="utf-8")
    assert "Permission is hereby granted" in licence and licence.split("\n")[0] in html
    meta, data = _page_parts(html)
    assert meta["makespan"] == pytest.approx(result.makespan)
    assert [r["name"] for r in meta["robots"]] == [r.name for r in result.robots]
    assert decode(meta["geometry"], data)["0/material/pos"].shape[1] == 3


def _deposits(result, name):
    tl = result.timelines[name]
    on = np.asarray(tl.on)
    return tl.p0[on], tl.p1[on], tl.t0[on], tl.t1[on]


def test_the_buffers_decode_back_to_the_material_laid_down(plan):
    inp, result = plan
    geo = build_geometry(result, read_chunk_meshes(inp))
    d = decode(geo.header, geo.encoded())
    h = geo.header
    quantum = (np.array(h["hi"]) - np.array(h["lo"])) / QMAX
    slack = h["tolerance"] + np.linalg.norm(quantum) + 1e-9
    assert geo.thinned is None
    for i, r in enumerate(result.robots):
        p0, p1, t0, t1 = _deposits(result, r.name)
        pos, time, lengths = d[f"{i}/material/pos"], d[f"{i}/material/time"], d[f"{i}/material/lengths"]
        segs = len(time) - len(lengths)
        assert segs == h["robots"][i]["material"]["segments"] and 0 < segs <= len(p0)
        assert len(d[f"{i}/material/chunk"]) == segs
        assert np.all(np.diff(time) >= 0) and time[0] >= 0 and time[-1] <= result.makespan + 1e-3  # in time order
        ends = np.vstack([p0, p1])
        assert np.allclose(pos.min(axis=0), ends.min(axis=0), atol=slack)  # the same extent
        assert np.allclose(pos.max(axis=0), ends.max(axis=0), atol=slack)
        last = np.cumsum(lengths) - 1
        starts = np.setdiff1d(np.arange(len(time)), last)
        length = np.linalg.norm(pos[starts + 1] - pos[starts], axis=1).sum()
        assert length == pytest.approx(np.linalg.norm(p1 - p0, axis=1).sum(), rel=0.01)
        # at the middle of every move that deposits, the material shown ends within the tolerance of the nozzle
        tm = (t0 + t1) / 2
        k = np.clip(np.searchsorted(time[starts + 1], tm, side="left"), 0, len(starts) - 1)
        a, b = starts[k], starts[k] + 1
        f = np.clip((tm - time[a]) / np.maximum(time[b] - time[a], 1e-12), 0, 1)
        shown = pos[a] + f[:, None] * (pos[b] - pos[a])
        assert np.abs(shown - (p0 + p1) / 2).max() <= slack + 1e-3 * 60  # times kept to the ms
        chunk_ids = [h["chunks"][c] for c in np.unique(d[f"{i}/material/chunk"])]
        assert set(chunk_ids) == set(r.program.chunks)


def test_a_plan_above_the_budget_is_thinned_evenly_and_says_so(plan, tmp_path):
    _, result = plan
    total = sum(int(np.count_nonzero(result.timelines[r.name].on)) for r in result.robots)
    geo = build_geometry(result, max_segments=50, tolerance=0.0)
    assert geo.thinned == {"shown": geo.header["segments"]["shown"], "total": total}
    assert 40 <= geo.thinned["shown"] <= 50
    d = decode(geo.header, geo.encoded())
    shown = [len(d[f"{i}/material/time"]) - len(d[f"{i}/material/lengths"]) for i in range(len(result.robots))]
    assert sum(shown) == geo.thinned["shown"]
    assert all(s > 0 for s, r in zip(shown, result.robots) if np.any(result.timelines[r.name].on))  # spread over all


def test_the_level_of_detail_merges_a_straight_run_but_keeps_a_change_of_speed():
    p = np.column_stack([np.linspace(0, 100, 101), np.zeros(101), np.zeros(101)])
    keep = np.empty(101, bool)
    simplify(p, np.linspace(0, 10, 101), np.zeros(101, bool), 0.05, 128, keep)
    assert np.flatnonzero(keep).tolist() == [0, 100]
    t = np.concatenate([np.linspace(0, 5, 51), 5 + np.linspace(0, 50, 51)[1:]])  # 10x slower past 50 mm
    simplify(p, t, np.zeros(101, bool), 0.05, 128, keep)
    assert np.flatnonzero(keep).tolist() == [0, 50, 100]
    wiggle = p.copy()
    wiggle[1::2, 1] = 0.2  # off the line by more than the tolerance: every vertex kept
    simplify(wiggle, np.linspace(0, 10, 101), np.zeros(101, bool), 0.05, 128, keep)
    assert keep.all()


def test_chunk_outlines_are_the_meshes_feature_edges():
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    edges = feature_edges(corners[faces].reshape(-1, 3), np.arange(36).reshape(-1, 3))  # a soup, welded
    assert len(edges) == 12  # a cube's edges, not its faces' diagonals
    assert np.allclose(np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1), 1.0)


def test_timelines_are_read_a_block_at_a_time(plan, monkeypatch):
    """Blocks of a few moves give the same buffers as one block (what keeps a big plan's memory bounded)."""
    _, result = plan
    whole = build_geometry(result)
    monkeypatch.setattr("cooprint.render.viewer.geometry.BLOCK_MOVES", 97)
    small = build_geometry(result)
    assert BLOCK_MOVES > 97
    dw, ds = decode(whole.header, whole.encoded()), decode(small.header, small.encoded())
    for i in range(len(result.robots)):
        a, b = dw[f"{i}/material/pos"], ds[f"{i}/material/pos"]
        assert abs(len(a) - len(b)) <= 2 * (len(result.timelines[result.robots[i].name].t0) // 97 + 1)
        assert np.allclose(a.min(axis=0), b.min(axis=0)) and np.allclose(a.max(axis=0), b.max(axis=0))


@built
def test_view_simulates_a_bundle_first_and_replaces_only_its_own_page(bundle, tmp_path, capsys):
    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    shutil.rmtree(job / "sim", ignore_errors=True)
    assert main(["view", str(job)]) == 0
    out = capsys.readouterr().out
    assert "has no simulation yet" in out and "simulating it first" in out
    page = job / "sim" / "viewer.html"
    assert (job / "sim" / "summary.json").exists() and page.read_text().startswith("<!-- cooprint-viewer/")
    assert main(["view", str(job)]) == 0  # its own page: replaced without --force
    assert "simulating" not in capsys.readouterr().out
    page.write_text("<html>my notes</html>")
    assert_rejected(["view", job], capsys, watch=[job], contains="use --force")
    assert main(["view", str(job), "--force"]) == 0
    assert page.read_text().startswith("<!-- cooprint-viewer/")


@built
def test_view_of_a_simulated_gcode_folder(bundle, tmp_path, capsys):
    out = tmp_path / "g"
    assert main(["simulate", str(bundle / "robots" / "A.gcode"), "--out", str(out), "-q"]) in (0, 1)
    record = json.loads((out / "sim" / "summary.json").read_text())
    assert record["inputs"]["paths"] == [str((bundle / "robots" / "A.gcode").resolve())]
    assert main(["view", str(out)]) == 0
    meta, data = _page_parts((out / "sim" / "viewer.html").read_text())
    assert meta["placed"] is False and [r["name"] for r in meta["robots"]] == ["A"]
    assert meta["makespan"] == pytest.approx(record["makespan_s"])
    time = decode(meta["geometry"], data)["0/material/time"]
    assert 0 < time[-1] <= record["makespan_s"] + 1e-3


def test_view_refuses_a_missing_or_foreign_folder_in_one_line(tmp_path, capsys):
    assert_rejected(["view", tmp_path / "nowhere"], capsys, contains="no such folder")
    (tmp_path / "plain").mkdir()
    assert_rejected(["view", tmp_path / "plain"], capsys, watch=[tmp_path], contains="neither a cooprint bundle")


@built
def test_a_bundles_simulation_keeps_a_users_viewer_html(bundle, tmp_path, capsys):
    from cooprint.jobs import simulate_bundle

    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    (job / "sim").mkdir(exist_ok=True)
    (job / "sim" / "viewer.html").write_text("<html>my notes</html>")
    simulate_bundle(job)
    assert (job / "sim" / "viewer.html").read_text() == "<html>my notes</html>"
    assert (job / "sim" / "summary.json").exists()
    assert "which cooprint did not write; no viewer written" in capsys.readouterr().err


@built
def test_view_open_starts_a_graphical_browser_or_says_it_could_not(bundle, tmp_path, capsys, monkeypatch):
    import webbrowser

    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    opened = []
    monkeypatch.setattr(webbrowser, "open", lambda uri: opened.append(uri) or True)
    monkeypatch.setattr("sys.platform", "linux")
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", str(job), "--open"]) == 0
    assert "could not open a web browser here (no display)" in capsys.readouterr().out and not opened
    monkeypatch.setenv("DISPLAY", ":987")  # a DISPLAY left over, no X server behind it
    assert main(["view", str(job), "--open"]) == 0
    assert "could not open a web browser here (no X server answers at DISPLAY=:987)" in capsys.readouterr().out
    assert not opened
    import socket

    with socket.socket() as server:  # an X server's port (6000 + display) that answers
        server.bind(("127.0.0.1", 0))
        server.listen()
        monkeypatch.setenv("DISPLAY", f"127.0.0.1:{server.getsockname()[1] - 6000}")
        assert main(["view", str(job), "--open"]) == 0
    assert opened == [(job / "sim" / "viewer.html").resolve().as_uri()]
    assert f"asked the system's web browser to open {opened[0]}" in capsys.readouterr().out


# --- trial 16: what view says, and a simulation it never hides or mixes -------------------------

def _deadlocked(job):
    """Robot B of bundle ``job`` waits for an event nobody announces (job.json's counts edited to match)."""
    path = job / "robots" / "B.coop"
    lines = path.read_text().splitlines(keepends=True)
    half = next(i for i in range(len(lines) // 2, len(lines)) if lines[i].startswith("MOVE"))
    path.write_text("".join(lines[:half] + ["WAIT nobody:7\n"] + lines[half:]))
    record = json.loads((job / "job.json").read_text())
    stats = record["robots"][1]["stats"]
    stats["commands"], stats["wait"] = stats["commands"] + 1, stats["wait"] + 1
    (job / "job.json").write_text(json.dumps(record))


@built
def test_view_that_simulates_prints_the_findings_and_exits_1_on_errors(bundle, tmp_path, capsys):
    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    shutil.rmtree(job / "sim", ignore_errors=True)
    _deadlocked(job)
    assert main(["view", str(job)]) == 1
    out, err = capsys.readouterr()
    assert "findings: deadlock 1" in out and "  deadlock (error): robot B" in out and "makespan" in out
    assert "the plan is INVALID: the simulation found errors (deadlock 1)" in err
    assert (job / "sim" / "viewer.html").read_text().startswith("<!-- cooprint-viewer/")  # written first
    assert main(["view", str(job)]) == 0  # the same simulation: the page again, nothing judged
    assert "simulating" not in capsys.readouterr().out


@built
def test_view_simulates_again_when_the_programs_changed_and_refuses_one_cut_short(bundle, tmp_path, capsys):
    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    shutil.rmtree(job / "sim", ignore_errors=True)
    assert main(["view", str(job)]) == 0
    inputs = json.loads((job / "sim" / "summary.json").read_text())["inputs"]
    assert set(inputs["fingerprint"]) >= {"job.json", "robots/A.coop", "robots/B.coop"}
    capsys.readouterr()
    _deadlocked(job)
    assert main(["view", str(job)]) == 1
    out = capsys.readouterr().out
    assert "changed (its size or modification time) since sim/summary.json was written: simulating again" in out
    assert "findings: deadlock 1" in out
    assert json.loads((job / "sim" / "summary.json").read_text())["finding_counts"]["deadlock"] == 1
    program = job / "robots" / "A.coop"
    program.write_text("".join(program.read_text().splitlines(keepends=True)[:100]))  # cut short at a line
    line = assert_rejected(["view", job], capsys, watch=[job], contains=f"{program}: ")
    assert " commands, job.json says " in line
    assert "truncated or replaced" in line


@built
def test_view_of_an_unreadable_or_foreign_summary(bundle, tmp_path, capsys):
    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    (job / "sim").mkdir(exist_ok=True)
    (job / "sim" / "summary.json").write_text("{broken")
    assert main(["view", str(job)]) == 0
    assert "sim/summary.json: unreadable (not JSON at line 1, column 2); simulating again" in capsys.readouterr().out
    assert json.loads((job / "sim" / "summary.json").read_text())["format"].startswith("cooprint-sim/")
    (job / "sim" / "summary.json").write_text('{"mine": 1}')
    assert_rejected(["view", job], capsys, watch=[job], contains="not a cooprint simulation summary")


@built
def test_view_messages_name_the_right_file_and_no_option_view_lacks(bundle, tmp_path, capsys):
    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    assert main(["view", str(job)]) == 0
    capsys.readouterr()
    (job / "job.json").write_text('{"format": "x"')
    assert_rejected(["view", job], capsys, watch=[job], contains=f"{job / 'job.json'}: not a valid job.json")
    shutil.copy(bundle / "job.json", job / "job.json")
    page = job / "sim" / "viewer.html"
    page.unlink()
    page.mkdir()
    line = assert_rejected(["view", job], capsys, watch=[job], contains="is a folder; move it away")
    page.rmdir()
    page.symlink_to(tmp_path / "elsewhere.html")
    for line in (line, assert_rejected(["view", job], capsys, watch=[job], contains="symlink")):
        assert "--out" not in line and "file name" not in line


def test_simulate_of_a_missing_path_says_so(tmp_path, capsys):
    assert_rejected(["simulate", tmp_path / "nowhere"], capsys, watch=[tmp_path],
                    contains=f"{tmp_path / 'nowhere'}: no such file or folder")


@built
def test_view_of_a_gcode_folder_simulates_again_when_the_gcode_changed(bundle, tmp_path, capsys):
    import os

    gcode = tmp_path / "A.gcode"
    shutil.copy(bundle / "robots" / "A.gcode", gcode)
    out = tmp_path / "g"
    main(["simulate", str(gcode), "--out", str(out), "-q"])
    assert main(["view", str(out)]) == 0
    assert "simulating" not in capsys.readouterr().out
    st = gcode.stat()
    os.utime(gcode, ns=(st.st_atime_ns, st.st_mtime_ns + 10 ** 9))
    assert main(["view", str(out)]) == 0
    assert f"{gcode} changed (its size or modification time) since sim/summary.json was written: simulating again" \
        in capsys.readouterr().out
    stamp = json.loads((out / "sim" / "summary.json").read_text())["inputs"]["fingerprint"]
    assert stamp[str(gcode)] == [st.st_size, st.st_mtime_ns + 10 ** 9]


@built
def test_view_simulates_again_as_the_bundle_was_simulated_with_acceleration(bundle, tmp_path, capsys):
    """A bundle simulated with --accel whose programs changed since is simulated again with
    acceleration too (its page and summary keep the time model the user chose)."""
    job = tmp_path / "job"
    shutil.copytree(bundle, job)
    assert main(["simulate", str(job), "--accel", "--force", "-q"]) == 0
    accel = json.loads((job / "sim" / "summary.json").read_text())
    assert accel["inputs"]["accel"] and accel["time_model"].startswith("trapezoidal")
    program = job / "robots" / "A.coop"
    st = program.stat()
    os.utime(program, ns=(st.st_atime_ns, st.st_mtime_ns + 10 ** 9))  # touched: the fingerprint no longer matches
    assert main(["view", str(job)]) == 0
    assert "simulating again" in capsys.readouterr().out
    again = json.loads((job / "sim" / "summary.json").read_text())
    assert again["inputs"]["accel"] and again["time_model"] == accel["time_model"]
    assert again["makespan_s"] == pytest.approx(accel["makespan_s"], rel=1e-9)
