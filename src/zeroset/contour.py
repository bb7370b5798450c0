"""Marching cubes on a sparse band, skipping every cube with an undefined corner."""

from __future__ import annotations

import numpy as np

from . import _lattice
from ._mc_table import CORNER_OFFSETS, EDGE_AXIS, EDGE_CORNER, case_table
from .types import DistanceField, Mesh

__all__ = ["marching_cubes"]

#: A sign change whose two values differ by more than this many cube sizes is not a zero
#: crossing of a distance function (|grad f| = 1): it is where the nearest tangent plane
#: jumps, and the cube is skipped.
MAX_JUMP = 2.0


def marching_cubes(field: DistanceField) -> Mesh:
    """Extract the zero set of a sparse signed distance field as a triangle mesh.

    Every cube whose eight corners are evaluated and defined, and whose values change
    sign, is triangulated; cubes with a missing or undefined corner are skipped, so the
    surface ends where the data end. Vertices on shared cube edges are shared, so the
    mesh is welded, edge-manifold and consistently oriented, with faces turned towards
    positive values (outside).

    Parameters
    ----------
    field : DistanceField
        From :func:`zeroset.distance.signed_distance`.

    Returns
    -------
    Mesh
        ``vertices`` (M, 3) float64 and ``faces`` (F, 3) int64.

    See Also
    --------
    zeroset.distance.signed_distance : builds the field.

    Notes
    -----
    Lorensen & Cline 1987, with the case table of :mod:`zeroset._mc_table`, which joins
    crossings face by face so that neighbouring cubes always agree (no cracks); Hoppe et
    al. 1992, §3.5 (cubes with undefined corners are skipped).
    """
    keys = _lattice.encode(field.vertices_ijk)
    corner_keys = keys[:, None] + _lattice.offset_keys(CORNER_OFFSETS)[None, :]
    slot = np.minimum(np.searchsorted(keys, corner_keys), keys.size - 1)
    values = np.where(keys[slot] == corner_keys, field.values[slot], np.nan)

    positive = values > 0.0
    defined = ~np.isnan(values).any(axis=1)
    crossing = defined & positive.any(axis=1) & ~positive.all(axis=1)
    cubes = np.flatnonzero(crossing)
    spread = np.nanmax(values[cubes], axis=1) - np.nanmin(values[cubes], axis=1)
    cubes = cubes[spread <= MAX_JUMP * np.sqrt(3.0) * field.cube_size]

    config = (positive[cubes] << np.arange(8)).sum(axis=1)
    table, counts = case_table()
    per_cube = counts[config]
    cube_of_tri = np.repeat(np.arange(cubes.size), per_cube)
    rank = np.arange(cube_of_tri.size) - np.repeat(np.cumsum(per_cube) - per_cube, per_cube)
    edges = table[config[cube_of_tri], rank]  # (T, 3) cube edge ids
    # Global edge key: key of the edge's lower lattice vertex, shifted, with its axis.
    lower = (
        keys[cubes][cube_of_tri][:, None] + _lattice.offset_keys(CORNER_OFFSETS)[EDGE_CORNER[edges]]
    )
    edge_keys = (lower << 2) | EDGE_AXIS[edges]
    unique_edges, faces = np.unique(edge_keys, return_inverse=True)

    vertices = _edge_points(unique_edges, keys, field)
    return Mesh(vertices=vertices, faces=faces.reshape(-1, 3).astype(np.int64))


def _edge_points(edge_keys: np.ndarray, keys: np.ndarray, field: DistanceField) -> np.ndarray:
    """Linearly interpolated zero crossing (E, 3) on each lattice edge."""
    lower, axis = edge_keys >> 2, edge_keys & 3
    upper = lower + _lattice.offset_keys(np.eye(3, dtype=np.int64))[axis]
    f0 = field.values[np.searchsorted(keys, lower)]
    f1 = field.values[np.searchsorted(keys, upper)]
    t = f0 / (f0 - f1)
    ijk = _lattice.decode(lower).astype(np.float64)
    ijk[np.arange(ijk.shape[0]), axis] += t
    return field.origin + field.cube_size * ijk
