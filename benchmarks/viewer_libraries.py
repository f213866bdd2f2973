"""The measurements behind docs/viewer.md's "Why three.js": what each candidate library adds to a
page, and how a page of 100,000 line segments (a small plan's material) loads in headless chromium.

    .venv/bin/python benchmarks/viewer_libraries.py      # after `make` (the viewer's bundle, viewer/node_modules)

Candidates: three.js from npm bundled by esbuild (our bundle, src/cooprint/render/viewer/assets/viewer.js,
and the whole library for reference), meshcat's bundled viewer and plotly's plotly.min.js, both
fetched with ``pip download`` into a temporary folder (never installed). The same 100,000 random
segments are written as a plotly ``Scatter3d`` page (``write_html``, plotly.js inline) and as a page
that draws them with three.js from a base64 Float32Array; each is loaded three times from file://
in Debian's chromium (software WebGL) and timed to its first drawing. Prints a Markdown summary.
"""
from __future__ import annotations

import base64
import gzip
import json
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from browser import launch_chromium  # noqa: E402  (the browser tests' chromium set-up)

REPO = Path(__file__).resolve().parents[1]
VIEWER = REPO / "viewer"
BUNDLE = REPO / "src" / "cooprint" / "render" / "viewer" / "assets" / "viewer.js"
SEGMENTS = 100_000
FRAMES = 20  # a plotly animation of the segments growing in FRAMES steps
LOADS = 3

PLOTLY_PAGES = """
import sys
import numpy as np
import plotly.graph_objects as go
xyz, out = np.load(sys.argv[1]), sys.argv[2]
def trace(m, conv=lambda v: v):
    return go.Scatter3d(x=conv(xyz[:3 * m, 0]), y=conv(xyz[:3 * m, 1]), z=conv(xyz[:3 * m, 2]), mode="lines")
n = len(xyz) // 3
go.Figure(trace(n)).write_html(out + "/plotly_float32.html", include_plotlyjs=True)
as_list = lambda v: [None if x != x else float(x) for x in v.astype(float)]
go.Figure(trace(n, as_list)).write_html(out + "/plotly_lists.html", include_plotlyjs=True)
k = int(sys.argv[3])
frames = [go.Frame(data=[trace(n * (i + 1) // k)], name=str(i)) for i in range(k)]
steps = [dict(method="animate", args=[[str(i)]], label=str(i)) for i in range(k)]
go.Figure(trace(n // k), frames=frames, layout=dict(sliders=[dict(steps=steps)])).write_html(
    out + "/plotly_animated.html", include_plotlyjs=True)
import plotly
print(plotly.__version__)
"""


def segments() -> np.ndarray:
    """SEGMENTS random 0-4 mm segments in a 200 mm cube: (2 * SEGMENTS, 3) float32 end points."""
    rng = np.random.default_rng(0)
    a = rng.uniform(0, 200, (SEGMENTS, 3))
    return np.stack([a, a + rng.uniform(-2, 2, (SEGMENTS, 3))], axis=1).reshape(-1, 3).astype(np.float32)


def sizes(path: Path) -> dict:
    """Bytes of a file and of its gzip."""
    data = path.read_bytes()
    return {"bytes": len(data), "gzip_bytes": len(gzip.compress(data, 9))}


def fetch(tmp: Path, packages: list[str]) -> Path:
    """``pip download --no-deps`` the packages and unzip their wheels into ``tmp/site``."""
    subprocess.run([sys.executable, "-m", "pip", "download", "--no-deps", "--quiet", "-d", str(tmp / "wheels"),
                    *packages], check=True)
    site = tmp / "site"
    for wheel in (tmp / "wheels").glob("*.whl"):
        zipfile.ZipFile(wheel).extractall(site)
    return site


def three_pages(tmp: Path, xyz: np.ndarray) -> tuple[dict, Path]:
    """The whole of three.js bundled and minified by esbuild (as our build does), and a page drawing
    the segments with it."""
    entry = tmp / "all.js"
    entry.write_text(f"import * as T from '{VIEWER / 'node_modules' / 'three'}'; window.T = T;\n")
    out = tmp / "three.min.js"
    subprocess.run([str(VIEWER / "node_modules" / ".bin" / "esbuild"), str(entry), "--bundle", "--minify",
                    "--format=iife", "--legal-comments=eof", "--target=es2020", f"--outfile={out}",
                    "--log-level=error"], check=True)
    pos = base64.b64encode(xyz.tobytes()).decode()
    page = tmp / "three_segments.html"
    page.write_text(f"""<!doctype html><html><body style="margin:0"><script>{out.read_text()}</script>
<script id="pos" type="application/octet-stream">{pos}</script><script>
const bin = atob(document.getElementById('pos').textContent), u8 = new Uint8Array(bin.length);
for (let i = 0; i < bin.length; i++) u8[i] = bin.charCodeAt(i);
const T = window.T, r = new T.WebGLRenderer({{antialias: true}});
r.setSize(innerWidth, innerHeight); document.body.appendChild(r.domElement);
const scene = new T.Scene(), cam = new T.PerspectiveCamera(45, innerWidth / innerHeight, 1, 5000);
cam.up.set(0, 0, 1); cam.position.set(300, -300, 300); cam.lookAt(100, 100, 100);
const g = new T.BufferGeometry(); g.setAttribute('position', new T.BufferAttribute(new Float32Array(u8.buffer), 3));
scene.add(new T.LineSegments(g, new T.LineBasicMaterial({{color: 0xd6604d}}))); r.render(scene, cam);
</script></body></html>""")
    return sizes(out), page


def load_times(pages: dict[str, Path]) -> dict[str, float]:
    """Median seconds from navigation to the first drawing (a WebGL canvas, then two animation frames)."""
    from playwright.sync_api import sync_playwright

    drawn = "() => document.querySelector('canvas') && (!window.Plotly || document.querySelector('.js-plotly-plot')._fullLayout)"
    out = {}
    with sync_playwright() as p:
        browser = launch_chromium(p)
        for name, page_path in pages.items():
            runs = []
            for _ in range(LOADS):
                context = browser.new_context(viewport={"width": 1280, "height": 720})
                page = context.new_page()
                t = time.perf_counter()
                page.goto(page_path.as_uri(), timeout=300_000)
                page.wait_for_function(drawn, timeout=300_000)
                page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
                runs.append(time.perf_counter() - t)
                context.close()
            out[name] = round(statistics.median(runs), 2)
        browser.close()
    return out


def main() -> int:
    if not BUNDLE.exists() or not (VIEWER / "node_modules" / "three").is_dir():
        print("viewer_libraries: run `make` first (the viewer's bundle and viewer/node_modules)")
        return 1
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        xyz = segments()
        three_lib, three_page = three_pages(tmp, xyz)
        site = fetch(tmp, ["meshcat", "plotly", "narwhals"])
        meshcat_js = site / "meshcat" / "viewer" / "dist" / "main.min.js"
        meshcat_three = next(d["version"] for d in json.loads(
            meshcat_js.with_name("main.min.js.THIRD_PARTY_LICENSES.json").read_text()) if d["name"] == "three")
        nan = np.full((SEGMENTS, 1, 3), np.nan, dtype=np.float32)
        np.save(tmp / "xyz.npy", np.concatenate([xyz.reshape(SEGMENTS, 2, 3), nan], axis=1).reshape(-1, 3))
        plotly_version = subprocess.run([sys.executable, "-c", PLOTLY_PAGES, str(tmp / "xyz.npy"), str(tmp), str(FRAMES)],
                                        env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"}, check=True,
                                        capture_output=True, text=True).stdout.strip()
        result = {
            "our bundle (three.js " + (VIEWER / "node_modules" / "three" / "package.json").read_text().split(
                '"version": "')[1].split('"')[0] + " + viewer, esbuild --minify)": sizes(BUNDLE),
            "three.js whole library (esbuild --minify)": three_lib,
            f"meshcat {next(site.glob('meshcat-*.dist-info')).name.removesuffix('.dist-info').split('-')[1]} viewer main.min.js "
            f"(three.js {meshcat_three})": sizes(meshcat_js),
            f"plotly {plotly_version} plotly.min.js": sizes(site / "plotly" / "package_data" / "plotly.min.js"),
        }
        pages = {"three.js, positions as base64 float32": three_page,
                 "plotly Scatter3d, numpy float32 (base64 typed arrays)": tmp / "plotly_float32.html",
                 "plotly Scatter3d, Python lists of floats": tmp / "plotly_lists.html"}
        times = load_times(pages)
        print("| library file | bytes | gzip bytes |\n|---|---:|---:|")
        for name, s in result.items():
            print(f"| {name} | {s['bytes']:,} | {s['gzip_bytes']:,} |")
        print(f"\n| page of {SEGMENTS:,} line segments | HTML MB | first drawing s (median of {LOADS}) |\n|---|---:|---:|")
        for name, path in pages.items():
            print(f"| {name} | {path.stat().st_size / 1e6:.1f} | {times[name]:.2f} |")
        print(f"| plotly, the segments growing in {FRAMES} animation frames (float32) | "
              f"{(tmp / 'plotly_animated.html').stat().st_size / 1e6:.1f} | — |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
