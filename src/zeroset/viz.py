"""Preview pictures of meshes, drawn with Matplotlib (imported when called)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .errors import InputError
from .io import atomic_target
from .types import Mesh

__all__ = ["preview"]


def preview(
    mesh: Mesh,
    path: str | os.PathLike,
    *,
    title: str | None = None,
    max_faces: int = 40_000,
    rng=0,
) -> Path:
    """Draw `mesh` shaded from two viewpoints and save it as a PNG.

    Parameters
    ----------
    mesh : Mesh
    path : str or os.PathLike
        The picture to write (atomically).
    title : str, optional
    max_faces : int
        Larger meshes are drawn from a random subset of this many faces.
    rng : numpy.random.Generator or int or None
        Chooses that subset.

    Returns
    -------
    pathlib.Path
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    target = Path(path)
    if not target.parent.is_dir():
        raise InputError(f"{target}: directory {target.parent} does not exist")
    faces = mesh.faces
    if faces.shape[0] > max_faces:
        faces = faces[
            np.sort(np.random.default_rng(rng).choice(faces.shape[0], max_faces, replace=False))
        ]
    triangles = mesh.vertices[faces]
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    centre, half = (lo + hi) / 2.0, max(float((hi - lo).max()) / 2.0, 1e-12)

    figure = plt.figure(figsize=(10, 5), dpi=110)
    for column, (elevation, azimuth) in enumerate(((25, -60), (70, 30))):
        axes = figure.add_subplot(1, 2, column + 1, projection="3d")
        light = _view_direction(elevation + 20, azimuth - 30)
        shade = 0.25 + 0.75 * np.abs(normals @ light)  # two-sided: inside of a pipe is lit too
        colours = np.c_[0.35 * shade, 0.55 * shade, 0.85 * shade, np.ones_like(shade)]
        axes.add_collection3d(Poly3DCollection(triangles, facecolors=colours, linewidths=0))
        for setter, c in zip((axes.set_xlim, axes.set_ylim, axes.set_zlim), centre, strict=True):
            setter(c - half, c + half)
        axes.set_box_aspect((1, 1, 1), zoom=1.35)
        axes.view_init(elev=elevation, azim=azimuth)
        axes.set_axis_off()
    figure.suptitle(title or f"{mesh.n_vertices:,} vertices, {mesh.n_faces:,} triangles")
    figure.tight_layout()
    with atomic_target(target) as temp:
        figure.savefig(temp, format="png")
    plt.close(figure)
    return target


def _view_direction(elevation: float, azimuth: float) -> np.ndarray:
    """Unit vector towards a viewer at the given angles in degrees."""
    e, a = np.radians(elevation), np.radians(azimuth)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
