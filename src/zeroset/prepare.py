"""Preparation of a raw cloud: sub-sampling, cropping, averaging, outliers (thesis 3.2.1, 3.2.8).

The selections return row indices or a mask into the input, so that per-point data
(normals, viewpoints) follow the points.
"""

from __future__ import annotations

import numpy as np

from ._validate import as_vector3, positive, require_rng
from .errors import InputError
from .types import Neighbourhoods

__all__ = ["average_in_cells", "crop", "drop_outliers", "random_sample", "voxel_sample"]


def random_sample(n_points: int, fraction: float, *, rng=None) -> np.ndarray:
    """Choose a random `fraction` of `n_points` rows without replacement.

    Parameters
    ----------
    n_points : int
    fraction : float
        Share of rows to keep, in (0, 1].
    rng : numpy.random.Generator or int or None
        Seed or generator; the same seed gives the same rows.

    Returns
    -------
    (M,) int64
        Sorted row indices, ``M = round(fraction * n_points)`` (at least 1).
    """
    if not 0.0 < fraction <= 1.0:
        raise InputError(f"sample fraction must lie in (0, 1]; got {fraction!r}")
    count = max(1, round(fraction * n_points))
    chosen = require_rng(rng).choice(n_points, size=count, replace=False)
    return np.sort(chosen).astype(np.int64)


def voxel_sample(points: np.ndarray, voxel_size: float) -> np.ndarray:
    """Keep one point per occupied voxel: the one nearest to the voxel's centroid.

    Parameters
    ----------
    points : (N, 3) float64
    voxel_size : float
        Voxel edge length in data units.

    Returns
    -------
    (M,) int64
        Sorted row indices, one per occupied voxel.
    """
    voxel_size = positive(voxel_size, "voxel_size")
    cells = np.floor((points - points.min(axis=0)) / voxel_size).astype(np.int64)
    _, voxel, counts = np.unique(cells, axis=0, return_inverse=True, return_counts=True)
    voxel = voxel.reshape(-1)
    centroids = np.stack(
        [np.bincount(voxel, weights=points[:, d]) / counts for d in range(3)], axis=1
    )
    spread = np.einsum("ij,ij->i", points - centroids[voxel], points - centroids[voxel])
    order = np.lexsort((spread, voxel))
    first = np.ones(order.size, dtype=bool)
    first[1:] = voxel[order][1:] != voxel[order][:-1]
    return np.sort(order[first]).astype(np.int64)


def average_in_cells(
    points: np.ndarray, cell_size: float, *others: np.ndarray
) -> tuple[np.ndarray, ...]:
    """Replace the points in each occupied cubic cell by their mean.

    Averaging evens out the density (one point per cell, however many the scanner put
    there) and the noise (the mean of m points scatters sqrt(m) times less) before the
    tangent planes are fitted.

    Parameters
    ----------
    points : (N, 3) float64
    cell_size : float
        Cell edge length in data units; cells lie on the lattice ``cell_size * (i, j, k)``.
    *others : (N, ...) float64
        Per-point arrays (e.g. viewpoints) to average the same way.

    Returns
    -------
    tuple of arrays
        The (M, 3) cell means of `points`, then those of each of `others`, in cell order.
    """
    cell_size = positive(cell_size, "cell_size")
    cells = np.floor(points / cell_size).astype(np.int64)
    _, label, counts = np.unique(cells, axis=0, return_inverse=True, return_counts=True)
    label = label.reshape(-1)
    return tuple(
        np.stack(
            [np.bincount(label, weights=array[:, d]) / counts for d in range(array.shape[1])],
            axis=1,
        )
        for array in (points, *others)
    )


def crop(points: np.ndarray, lower, upper) -> np.ndarray:
    """Return the (N,) bool mask of points inside the axis-aligned box [lower, upper]."""
    lower, upper = as_vector3(lower, "crop lower corner"), as_vector3(upper, "crop upper corner")
    if np.any(lower > upper):
        raise InputError(f"crop box corners must satisfy lower <= upper; got {lower} and {upper}")
    return np.all((points >= lower) & (points <= upper), axis=1)


def drop_outliers(neighbours: Neighbourhoods, radius: float, min_neighbours: int) -> np.ndarray:
    """Return the (N,) bool mask of points with at least `min_neighbours` others within `radius`.

    A point far from all others is an outlier (thesis 3.2.1; Hoppe et al. 1992, §3).
    `neighbours` must have more than `min_neighbours` columns.
    """
    others = neighbours.distances[:, 1:]
    return np.count_nonzero(others <= radius, axis=1) >= min_neighbours
