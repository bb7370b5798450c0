"""Signed distance to the tangent planes on a sparse lattice band (Hoppe et al. 1992, §3.4)."""

from __future__ import annotations

import math

import numpy as np

from . import _lattice
from ._mc_table import CORNER_OFFSETS
from ._validate import as_points, as_vector3, positive
from .neighbours import build_tree
from .types import DistanceField

__all__ = ["signed_distance"]

#: Values closer to zero than this fraction of the cube size are pushed off zero, so no
#: contour vertex lands on a grid vertex (an exact zero makes degenerate triangles).
ZERO_NUDGE = 1e-3

#: Nearest tangent planes tried, in order, until one's foot point lies near the data; a
#: single badly fitted plane then cannot open a hole.
CANDIDATES = 3


def signed_distance(
    points, centroids, normals, *, cube_size: float, radius: float, origin=None
) -> DistanceField:
    """Evaluate the signed distance f on the grid vertices near the data.

    ``f(p) = (p - o_i) . n_i`` with o_i the centroid nearest to p. f is undefined (NaN)
    when the foot point ``z = p - f(p) n_i`` lies farther than `radius` from every data
    point: there the data say nothing, so holes and open ends stay open. Where the nearest
    plane's foot point fails that test, the next nearest planes are tried (up to
    ``CANDIDATES``), so one badly fitted plane does not punch a hole. Only the cubes
    within `radius` of a centroid and their neighbours are evaluated, never the bounding box.

    Parameters
    ----------
    points : (N, 3) array_like of float
        Data points, for the undefined test.
    centroids : (M, 3) array_like of float
        Tangent-plane origins o_i.
    normals : (M, 3) array_like of float
        Consistently oriented unit normals n_i.
    cube_size : float
        Lattice spacing, in data units.
    radius : float
        rho+delta: the largest distance from a foot point to the data.
    origin : (3,) array_like of float, optional
        Lattice origin; zero by default, so clouds in one frame share one lattice.

    Returns
    -------
    DistanceField
        ``vertices_ijk`` (V, 3) sorted, ``values`` (V,) with NaN where undefined,
        ``origin`` (3,), ``cube_size``.

    See Also
    --------
    zeroset.contour.marching_cubes : contours the field.

    Notes
    -----
    Hoppe et al. 1992, §3.4 (signed distance function and its undefined region); thesis
    §3.2.5. Values within ``ZERO_NUDGE * cube_size`` of zero are set to that margin with
    their sign (zero counts as positive).
    """
    points = as_points(points)
    centroids = as_points(centroids, "centroids")
    normals = as_points(normals, "normals")
    cube_size = positive(cube_size, "cube_size")
    radius = positive(radius, "radius")
    origin = np.zeros(3) if origin is None else as_vector3(origin, "origin")

    vertex_keys = _band_vertices(centroids, origin, cube_size, radius)
    ijk = _lattice.decode(vertex_keys)
    positions = origin + cube_size * ijk
    _, nearest = build_tree(centroids).query(positions, k=CANDIDATES, workers=-1)
    data_tree = build_tree(points)
    values = np.full(positions.shape[0], np.nan)
    pending = np.arange(positions.shape[0])
    for rank in range(CANDIDATES):
        plane = nearest[pending, rank]
        f = np.einsum("ij,ij->i", positions[pending] - centroids[plane], normals[plane])
        feet = positions[pending] - f[:, None] * normals[plane]
        foot_distance, _ = data_tree.query(feet, distance_upper_bound=radius, workers=-1)
        found = np.isfinite(foot_distance)
        values[pending[found]] = f[found]
        pending = pending[~found]
    margin = ZERO_NUDGE * cube_size
    values = np.where(np.abs(values) < margin, np.where(values < 0.0, -margin, margin), values)
    return DistanceField(vertices_ijk=ijk, values=values, origin=origin, cube_size=cube_size)


def _band_vertices(centroids: np.ndarray, origin: np.ndarray, cube_size: float, radius: float):
    """Sorted (V,) int64 keys of the corners of every cube near a centroid."""
    cells = np.floor((centroids - origin) / cube_size).astype(np.int64)
    cell_keys = np.unique(_lattice.encode(cells))
    reach = max(1, math.ceil(radius / cube_size))
    steps = np.arange(-reach, reach + 1)
    dilation = np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), axis=-1).reshape(-1, 3)
    band = np.unique((cell_keys[:, None] + _lattice.offset_keys(dilation)[None, :]).reshape(-1))
    return np.unique((band[:, None] + _lattice.offset_keys(CORNER_OFFSETS)[None, :]).reshape(-1))
