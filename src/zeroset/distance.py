"""Signed distance to the tangent planes on a sparse lattice band (Hoppe et al. 1992, §3.4)."""

from __future__ import annotations

import numpy as np

from . import _lattice
from ._mc_table import CORNER_OFFSETS
from ._unique import distinct
from ._validate import as_points, as_vector3, positive, positive_per_row
from .neighbours import build_tree, query_workers
from .thresholds import CANDIDATES, ZERO_NUDGE
from .types import DistanceField

__all__ = ["signed_distance"]


def signed_distance(
    points,
    centroids,
    normals,
    *,
    cube_size: float,
    radius,
    origin=None,
    bridges=None,
    bridge_reach: float | None = None,
    surface=None,
    tree=None,
    centroid_tree=None,
) -> DistanceField:
    """Evaluate the signed distance f on the grid vertices near the data.

    ``f(p) = (p - o_i) . n_i`` with o_i the centroid nearest to p. f is undefined (NaN)
    when the foot point ``z = p - f(p) n_i`` lies farther than `radius` from every data
    point: there the data say nothing, so holes and open ends stay open. Where the nearest
    plane's foot point fails that test, the next nearest planes are tried (up to
    ``CANDIDATES``), so one badly fitted plane does not punch a hole. Only the cubes
    within `radius` of a centroid or a bridge point and their neighbours are evaluated,
    never the bounding box.

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
    radius : float or (M,) array_like of float
        rho+delta, one for all planes or one per plane (`zeroset.density.point_radii`): the
        largest distance from a plane's foot points to the data.
    origin : (3,) array_like of float, optional
        Lattice origin; zero by default, so clouds in one frame share one lattice.
    bridges : (B, 3) array_like of float, optional
        Points along chords across gaps in the sampling (`zeroset.density.gap_bridges`).
    bridge_reach : float, optional
        A foot point within this distance of a bridge point is near the data; needed with
        `bridges`.
    surface : callable, optional
        ``surface(positions (M, 3)) -> (M,)`` signed distance: where it is given, the
        planes only decide where f is defined and `surface` gives its values (the blended
        jets of `zeroset.jets`).
    tree, centroid_tree : cKDTree, optional
        Trees over `points` and over `centroids`, to reuse those already built.

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
    radius = positive_per_row(radius, "radius", centroids.shape[0])
    origin = np.zeros(3) if origin is None else as_vector3(origin, "origin")

    if bridges is None or np.size(bridges) == 0:
        bridges = np.zeros((0, 3))
    else:
        bridges = as_points(bridges, "bridges")
        bridge_reach = positive(bridge_reach, "bridge_reach")
    vertex_keys = _band_vertices(
        np.concatenate([centroids, bridges]),
        origin,
        cube_size,
        np.concatenate([radius, np.full(bridges.shape[0], bridge_reach)]),
    )
    ijk = _lattice.decode(vertex_keys)
    positions = origin + cube_size * ijk
    data_tree = build_tree(points) if tree is None else tree
    centroid_tree = build_tree(centroids) if centroid_tree is None else centroid_tree
    _, nearest = centroid_tree.query(positions, k=CANDIDATES, workers=query_workers())
    nearest = nearest.reshape(-1, CANDIDATES)
    bridge_tree = build_tree(bridges) if bridges.shape[0] else None
    values = np.full(positions.shape[0], np.nan)
    pending = np.arange(positions.shape[0])
    for rank in range(CANDIDATES):
        plane = nearest[pending, rank]
        f = np.einsum("ij,ij->i", positions[pending] - centroids[plane], normals[plane])
        feet = positions[pending] - f[:, None] * normals[plane]
        reach = radius[plane]
        foot_distance, _ = data_tree.query(
            feet, distance_upper_bound=float(reach.max(initial=0.0)), workers=query_workers()
        )
        found = foot_distance <= reach
        if bridge_tree is not None:
            found[~found] = np.isfinite(
                bridge_tree.query(
                    feet[~found], distance_upper_bound=bridge_reach, workers=query_workers()
                )[0]
            )
        values[pending[found]] = f[found]
        pending = pending[~found]
    if surface is not None:
        defined = np.flatnonzero(np.isfinite(values))
        values[defined] = surface(positions[defined])
    margin = ZERO_NUDGE * cube_size
    values = np.where(np.abs(values) < margin, np.where(values < 0.0, -margin, margin), values)
    return DistanceField(vertices_ijk=ijk, values=values, origin=origin, cube_size=cube_size)


def _band_vertices(centroids: np.ndarray, origin: np.ndarray, cube_size: float, radius):
    """Sorted (V,) int64 keys of the corners of every cube within `radius` (M,) of a centroid."""
    cell_keys = _lattice.encode(np.floor((centroids - origin) / cube_size).astype(np.int64))
    reach = np.maximum(1, np.ceil(radius / cube_size).astype(np.int64))
    bands = []
    for r in np.unique(reach):
        steps = np.arange(-r, r + 1)
        dilation = np.stack(np.meshgrid(steps, steps, steps, indexing="ij"), -1).reshape(-1, 3)
        cells = distinct(cell_keys[reach == r])
        bands.append((cells[:, None] + _lattice.offset_keys(dilation)[None, :]).reshape(-1))
    band = distinct(np.concatenate(bands))
    return distinct((band[:, None] + _lattice.offset_keys(CORNER_OFFSETS)[None, :]).reshape(-1))
