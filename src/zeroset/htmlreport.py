"""One self-contained HTML file: an interactive 3D viewer of a reconstruction or a pipe
inspection, and its numbers.

The page opens offline from a file: three.js (a pinned build, shipped as package data and
made by ``tools/viewer``), the viewer's own script, the numbers as JSON, every array as
gzip-compressed, base64-encoded binary and the pictures as PNG data URIs are all inside it.
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
from .errors import InputError
from .inspect import Inspection, inspection_summary
from .io import atomic_target, check_output
from .pipeline import Reconstruction
from .report import reconstruction_report
from .topology import boundary_edges
from .types import Mesh
from .viz import vertex_distances

__all__ = ["write_html_report", "write_inspection_report"]

#: At most this many points are embedded (a seeded random subset beyond).
MAX_POINTS = 200_000
#: At most this many tangent planes are shown as normals.
MAX_NORMALS = 20_000
#: The first bytes of every PNG file.
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def write_html_report(
    path: str | os.PathLike,
    result: Reconstruction,
    *,
    points=None,
    source: str | None = None,
    report: dict | None = None,
    inspection: Inspection | None = None,
    pictures: dict[str, bytes] | None = None,
    rng=0,
) -> Path:
    """Write the report of a reconstruction as one HTML file with a 3D viewer.

    The viewer (rotate, zoom, pan) shows the points, the phase-1 mesh, the phase-2 mesh
    when phase 2 ran, the tangent-plane normals and the boundary edges, each of which can
    be switched on and off, and colours a mesh by how far the data lie from it. Beside it
    are the parameters chosen and why, the counts, boundary loops, stage timings, the
    distances from the points to the mesh and phase 2's energies, moves and history.

    With an `inspection` of the inspected mesh the viewer colours that mesh by its deviation
    from the nominal pipe (blue inward, red outward, at the 99th percentile of |deviation|
    the deepest; on at first), and the page shows the inspection's numbers
    (:func:`zeroset.inspect.inspection_summary`, also under ``"inspection"`` in the
    embedded report) and its `pictures`.

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
    inspection : zeroset.inspect.Inspection, optional
        The inspection of phase 2's mesh when phase 2 ran, else of phase 1's dense mesh
        (``result.dense_mesh``, as the CLI inspects it), which the page then shows as
        phase 1's.
    pictures : dict of str to bytes, optional
        PNG files by caption, shown in that order (e.g. from `zeroset.inspect`'s pictures).
    rng : numpy.random.Generator or int or None
        Chooses the points and normals embedded when there are more than
        ``MAX_POINTS`` / ``MAX_NORMALS``, and the fit sample of the report.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    InputError
        If `path` cannot be written (`zeroset.io.check_output`), or `inspection` is of a
        mesh with another number of vertices.
    TypeError
        If a picture is not PNG bytes.
    """
    target = check_output(path)
    rng = require_rng(rng)
    figures = _figures(pictures)
    meshes = {"phase 1": result.initial_mesh}
    if result.optimization is not None:
        meshes["phase 2"] = result.mesh
    elif inspection is not None:  # the inspection measures the dense mesh
        meshes["phase 1"] = result.dense_mesh
    final = list(meshes)[-1]
    deviation = _vertex_deviation(inspection, meshes[final])
    if report is None:
        report = reconstruction_report(result, source=source, points=points, rng=rng)
    if inspection is not None:
        report = {**report, "inspection": inspection_summary(inspection)}
    centre = result.offset  # everything is shown relative to it, so float32 loses nothing
    shown = None if points is None else _subset(as_points(points), MAX_POINTS, rng)
    layers = _points_layer(shown, centre)
    for name, mesh in meshes.items():
        layers[name] = _mesh_layers(mesh, centre, shown, deviation if name == final else None)
    normals = _subset(np.arange(result.points.shape[0]), MAX_NORMALS, rng)
    layers["normals"] = {
        "origins": _array(result.planes.centroids[normals], np.float32),
        "directions": _array(result.normals[normals], np.float32),
    }
    title = f"zeroset: {Path(source).name}" if source else "zeroset reconstruction"
    _write_page(target, title, report, layers, figures)
    return target


def write_inspection_report(
    path: str | os.PathLike,
    mesh: Mesh,
    inspection: Inspection,
    *,
    points=None,
    pictures: dict[str, bytes] | None = None,
    source: str | None = None,
    rng=0,
) -> Path:
    """Write the inspection of a pipe's mesh as one HTML file with a 3D viewer.

    The page of :func:`write_html_report` for a mesh that was not reconstructed here (one
    read from a file): the viewer shows the mesh, coloured by its deviation from the
    nominal pipe, with its boundary edges, and the points when given; beside it are the
    inspection's numbers only (:func:`zeroset.inspect.inspection_summary`, the embedded report's
    ``"inspection"``), and below it the `pictures`. The numbers are tables: the pipe, with
    the fitted centreline's length beside the data's extent (marked where they disagree)
    and the defect threshold with its basis; the diameters and ovality over the stations;
    the unreliable stretches; the defects, with their depth in mm and in % of the diameter
    and those B31.8 would assess marked; the joints; the branches.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write, atomically.
    mesh : Mesh
        The inspected mesh.
    inspection : zeroset.inspect.Inspection
        Its inspection.
    points : (N, 3) array_like of float, optional
        The scan: shown, and used to colour the mesh by how far the data lie from it.
    pictures : dict of str to bytes, optional
        PNG files by caption, shown in that order.
    source : str, optional
        Where the mesh came from, for the title.
    rng : numpy.random.Generator or int or None
        Chooses the points embedded when there are more than ``MAX_POINTS``.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    InputError
        If `path` cannot be written, or `inspection` is of a mesh with another number of
        vertices.
    TypeError
        If a picture is not PNG bytes.
    """
    target = check_output(path)
    rng = require_rng(rng)
    figures = _figures(pictures)
    deviation = _vertex_deviation(inspection, mesh)
    centre = 0.5 * (mesh.vertices.min(axis=0) + mesh.vertices.max(axis=0))
    shown = None if points is None else _subset(as_points(points), MAX_POINTS, rng)
    layers = _points_layer(shown, centre)
    layers["inspected"] = _mesh_layers(mesh, centre, shown, deviation)
    report = {"source": source, "inspection": inspection_summary(inspection)}
    title = f"zeroset inspection: {Path(source).name}" if source else "zeroset inspection"
    _write_page(target, title, report, layers, figures)
    return target


def _vertex_deviation(inspection: Inspection | None, mesh: Mesh) -> np.ndarray | None:
    """The inspection's (V,) vertex deviations, checked to belong to `mesh`; None without."""
    if inspection is None:
        return None
    deviation = inspection.vertex_deviation
    if deviation.shape[0] != mesh.n_vertices:
        raise InputError(
            f"the inspection has deviations of {deviation.shape[0]} vertices; the mesh shown "
            f"has {mesh.n_vertices} (inspect phase 2's mesh when phase 2 ran, else the "
            "dense mesh)"
        )
    return deviation


def _figures(pictures: dict[str, bytes] | None) -> str:
    """HTML figures of PNG `pictures` by caption, as data URIs; empty without."""
    if not pictures:
        return ""
    figures = []
    for caption, png in pictures.items():
        if not isinstance(png, bytes) or not png.startswith(PNG_SIGNATURE):
            raise TypeError(
                f"pictures must map captions to PNG bytes; got {type(png).__name__} "
                f"for {caption!r}"
            )
        text = html.escape(str(caption))
        data = base64.b64encode(png).decode("ascii")
        figures.append(
            f'<figure><img src="data:image/png;base64,{data}" alt="{text}">'
            f"<figcaption>{text}</figcaption></figure>"
        )
    heading = '<section id="pictures"><h2>Inspection: pictures</h2>'
    return "\n".join([heading, *figures, "</section>"])


def _points_layer(shown: np.ndarray | None, centre: np.ndarray) -> dict:
    """The layers with the shown points relative to `centre`, or none."""
    return {} if shown is None else {"points": _array(shown - centre, np.float32)}


def _mesh_layers(mesh: Mesh, centre: np.ndarray, points, deviation=None) -> dict:
    """A mesh's vertices, faces and boundary edges, its per-vertex distances to `points`
    when given, and its (V,) per-vertex `deviation` (metres) when given."""
    layer = {
        "vertices": _array(mesh.vertices - centre, np.float32),
        "faces": _array(mesh.faces, np.uint32),
        "boundary": _array(boundary_edges(mesh.faces), np.uint32),
    }
    if points is not None:
        layer["distance"] = _array(vertex_distances(mesh, points), np.float32)
    if deviation is not None:
        layer["deviation"] = _array(deviation, np.float32)
    return layer


def _write_page(target: Path, title: str, report: dict, layers: dict, figures: str) -> None:
    """Write the page, atomically, with its report, layers and figures embedded."""
    page = _PAGE.format(
        title=html.escape(title),
        style=_asset("viewer.css"),
        report=_script_json(report),
        layers=_script_json(layers),
        figures=figures,
        three=_asset("three.min.js"),
        viewer=_asset("viewer.js"),
    )
    with atomic_target(target) as temporary:
        temporary.write_text(page, encoding="utf-8")


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
{figures}
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
