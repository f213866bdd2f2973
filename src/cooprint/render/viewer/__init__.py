"""The interactive viewer: one self-contained HTML file per simulated plan (``sim/viewer.html``),
three.js drawing the material laid down by time t in the browser; see docs/viewer.md.

``meta.py``: the panels' record (summary, findings, events, Gantt bars); ``geometry.py``: the
material, travel and robot tracks as binary buffers; the page is assembled from those and the
JavaScript bundle ``assets/viewer.js`` (built by ``make`` from ``viewer/`` at the repository's
root, three.js from npm).
"""
