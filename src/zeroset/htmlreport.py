"""One self-contained HTML file: an interactive 3D viewer of a reconstruction, and its numbers.

The page opens offline from a file: three.js (a pinned build, shipped as package data and
made by ``tools/viewer``), the viewer's own script, the numbers as JSON and every array as
gzip-compressed, base64-encoded binary are all inside it.
"""

from __future__ import annotations

import base64
import gzip
import html
import json
import os
from importlib import resources
from pathlib import Path

import numpy as np

from ._validate import as_points, require_rng
from .io import atomic_target, check_output
from .pipeline import Reconstruction
from .report import reconstruction_report
from .topology import boundary_edges
from .types import Mesh
from .viz import vertex_distances

__all__ = ["write_html_report"]

#: At most this many points are embedded (a seeded random subset beyond).
MAX_POINTS = 200_000
#: At most this many tangent planes are shown as normals.
MAX_NORMALS = 20_000


def write_html_report(
    path: str | os.PathLike,
    result: Reconstruction,
    *,
    points=None,
    source: str | None = None,
    report: dict | None = None,
    rng=0,
) -> Path:
    """Write the report of a reconstruction as one HTML file with a 3D viewer.

    The viewer (rotate, zoom, pan) shows the points, the phase-1 mesh, the phase-2 mesh
    when phase 2 ran, the tangent-plane normals and the boundary edges, each of which can
    be switched on and off, and colours a mesh by how far the data lie from it. Beside it
    are the parameters chosen and why, the counts, boundary loops, stage timings, the
    distances from the points to the mesh and phase 2's energies, moves and history.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write, atomically.
    result : Reconstruction
    points : (N, 3) array_like of float, optional
        The input points, in the input's coordinates: shown, and used for the distances.
    source : str, optional
        Where the points came from, for the title.
    report : dict, optional
        The numbers, when :func:`zeroset.report.reconstruction_report` has already made them.
    rng : numpy.random.Generator or int or None
        Chooses the points and normals embedded when there are more than
        ``MAX_POINTS`` / ``MAX_NORMALS``, and the fit sample of the report.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    InputError
        If `path` cannot be written (`zeroset.io.check_output`).
    """
    target = check_output(path)
    rng = require_rng(rng)
    if report is None:
        report = reconstruction_report(result, source=source, points=points, rng=rng)
    centre = result.offset  # everything is shown relative to it, so float32 loses nothing
    layers: dict = {}
    meshes = {"phase 1": result.initial_mesh}
    if result.optimization is not None:
        meshes["phase 2"] = result.mesh
    shown = None
    if points is not None:
        points = as_points(points)
        shown = _subset(points, MAX_POINTS, rng)
        layers["points"] = _array(shown - centre, np.float32)
    for name, mesh in meshes.items():
        layers[name] = _mesh_layers(mesh, centre, shown)
    normals = _subset(np.arange(result.points.shape[0]), MAX_NORMALS, rng)
    layers["normals"] = {
        "origins": _array(result.planes.centroids[normals], np.float32),
        "directions": _array(result.normals[normals], np.float32),
    }
    title = f"zeroset: {Path(source).name}" if source else "zeroset reconstruction"
    page = _PAGE.format(
        title=html.escape(title),
        style=_asset("viewer.css"),
        report=_script_json(report),
        layers=_script_json(layers),
        three=_asset("three.min.js"),
        viewer=_asset("viewer.js"),
    )
    with atomic_target(target) as temporary:
        temporary.write_text(page, encoding="utf-8")
    return target


def _mesh_layers(mesh: Mesh, centre: np.ndarray, points) -> dict:
    """A mesh's vertices, faces, boundary edges and (with points) per-vertex distances."""
    layer = {
        "vertices": _array(mesh.vertices - centre, np.float32),
        "faces": _array(mesh.faces, np.uint32),
        "boundary": _array(boundary_edges(mesh.faces), np.uint32),
    }
    if points is not None:
        layer["distance"] = _array(vertex_distances(mesh, points), np.float32)
    return layer


def _subset(rows: np.ndarray, most: int, rng: np.random.Generator) -> np.ndarray:
    """`rows`, or a random subset of `most` of them in their order."""
    if rows.shape[0] <= most:
        return rows
    return rows[np.sort(rng.choice(rows.shape[0], most, replace=False))]


def _array(values: np.ndarray, dtype) -> dict:
    """An array as JSON: dtype, shape and its little-endian bytes, gzipped and base64-encoded."""
    data = np.ascontiguousarray(values, dtype=np.dtype(dtype).newbyteorder("<"))
    packed = gzip.compress(data.tobytes(), compresslevel=6, mtime=0)
    return {
        "dtype": np.dtype(dtype).name,
        "shape": list(data.shape),
        "gzip": base64.b64encode(packed).decode("ascii"),
    }


def _script_json(data) -> str:
    """JSON that is safe inside a <script> element."""
    return json.dumps(data, allow_nan=False, default=_plain).replace("</", "<\\/")


def _plain(value):
    """NumPy scalars as Python numbers."""
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot put {type(value).__name__} in the report")


def _asset(name: str) -> str:
    """A file shipped in zeroset/_viewer."""
    return resources.files("zeroset").joinpath("_viewer", name).read_text(encoding="utf-8")


_PAGE = """<!doctype html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>
{style}
</style>
</head>
<body>
<header><h1>{title}</h1></header>
<main>
<section id="view">
<canvas id="canvas"></canvas>
<form id="layers" aria-label="layers"></form>
<div id="legend"></div>
</section>
<section id="numbers"></section>
</main>
<script type="application/json" id="zeroset-report">{report}</script>
<script type="application/json" id="zeroset-layers">{layers}</script>
<script>
{three}
</script>
<script>
{viewer}
</script>
</body>
</html>
"""
