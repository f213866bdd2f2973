"""The interactive viewer: one self-contained HTML file per simulated plan (``sim/viewer.html``),
three.js drawing the material laid down by time t in the browser; see docs/viewer.md.

``meta.py``: the panels' record (summary, findings, events, Gantt bars); ``geometry.py``: the
material, travel and chunk outlines as binary buffers; the page is assembled from those and the
JavaScript bundle ``assets/viewer.js`` (built by ``make`` from ``viewer/`` at the repository's
root, three.js from npm), with three.js's licence. The page fetches nothing: it works from disk.
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any, Mapping, Sequence

from cooprint.errors import UserError
from cooprint.io.bundle import VIEWER_MARKER, jsonable
from cooprint.render.viewer.geometry import MAX_SEGMENTS, ViewerGeometry, build_geometry
from cooprint.render.viewer.meta import viewer_meta
from cooprint.simulation import SimResult

ASSETS = Path(__file__).parent / "assets"
#: The page says whose it is in its first bytes (cooprint replaces its own viewer.html, never a user's).
MARKER = VIEWER_MARKER.decode("ascii") + "1"


def _asset(name: str) -> str:
    path = ASSETS / name
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{path}: the viewer's JavaScript is not built; run `make viewer` (needs Node.js and npm) "
                        "in cooprint's source folder") from None


def check_assets() -> None:
    """A :class:`UserError` when the JavaScript bundle is not built (``make viewer``)."""
    _asset("viewer.js")
    _asset("three-LICENSE.txt")


def _script_text(text: str) -> str:
    """``text`` safe inside a ``<script>`` element (no ``</script`` or ``<!--`` in it)."""
    return text.replace("</", "<\\/").replace("<!--", "<\\!--")


def page(meta: Mapping[str, Any], geometry: ViewerGeometry) -> str:
    """The viewer's HTML: the panels' record and the geometry's header as JSON, the geometry's
    buffers base64, the JavaScript bundle, three.js's licence (in a comment and the page's
    about box)."""
    bundle, licence = _asset("viewer.js"), _asset("three-LICENSE.txt")
    title = html.escape(str(meta.get("title", "")) or "plan")
    record = json.dumps(jsonable({**meta, "geometry": geometry.header}), separators=(",", ":"), allow_nan=False)
    comment = licence.replace("--", "- -")
    return "\n".join([
        f"{MARKER}: cooprint's plan viewer, one file: no network needed. -->",
        "<!doctype html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="generator" content="cooprint-viewer/1">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{title} - cooprint viewer</title>",
        f"<!-- three.js (the npm package three), bundled in this page under its licence:\n{comment}\n-->",
        "</head><body>",
        f'<script type="application/json" id="cooprint-meta">{_script_text(record)}</script>',
        f'<script type="text/plain" id="cooprint-licence">{html.escape(licence)}</script>',
        f'<script type="application/octet-stream" id="cooprint-geometry" data-encoding="gzip+base64">'
        f"{geometry.encoded()}</script>",
        f"<script>{_script_text(bundle)}</script>",
        "</body></html>",
        ""])


def write_viewer(result: SimResult, record: Mapping[str, Any], path: str | Path, *,
                 chunks: Mapping[str, Any] | None = None, critical: Sequence[str] | None = None,
                 lower_bound: float | None = None, title: str = "", max_segments: int = MAX_SEGMENTS) -> Path:
    """Write the viewer of a simulated plan to ``path`` (one HTML file).

    ``record``: the simulation's summary (what sim/summary.json holds: its findings are listed);
    ``chunks``: the bundle's chunk meshes by id (:func:`cooprint.simulation.inputs.read_chunk_meshes`)
    for their outlines; ``critical``, ``lower_bound``: the schedule's critical path (given when
    the plan has one: the Gantt chart then frames the chain that sets the simulated makespan,
    :func:`cooprint.render.sim.simulated_critical_path`, as the PNG chart does) and lower bound; ``max_segments``: the most material segments the page holds
    (above, thinned evenly, and the page says so). A :class:`UserError` when the JavaScript
    bundle is not built."""
    check_assets()  # before the work
    geometry = build_geometry(result, chunks, max_segments=max_segments)
    meta = viewer_meta(result, dict(record), critical, lower_bound, title)
    path = Path(path)
    path.write_text(page(meta, geometry), encoding="utf-8")
    return path


__all__ = ["MARKER", "check_assets", "page", "write_viewer"]
