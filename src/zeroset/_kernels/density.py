"""Nearest neighbour in each direction around a point (zeroset.density)."""

import math

import numpy as np

from ._jit import inputs, jit, over_rows


@jit
def _sector_nearest_rows(start, stop, points, indices, distances, u, v, sectors, nearest, column):
    # Direction of each neighbour j of row i: the angle of p_j - p_i in the plane spanned by
    # u[i] (x) and v[i] (y), cut into `sectors` equal sectors from -pi. Columns ascend in
    # distance, so the first one met in a sector is its nearest.
    k = indices.shape[1]
    for i in range(start, stop):
        p = indices[i, 0]
        for c in range(1, k):
            j = indices[i, c]
            if j < 0 or not math.isfinite(distances[i, c]):
                continue
            d0 = points[j, 0] - points[p, 0]
            d1 = points[j, 1] - points[p, 1]
            d2 = points[j, 2] - points[p, 2]
            x = d0 * u[i, 0] + d1 * u[i, 1] + d2 * u[i, 2]
            y = d0 * v[i, 0] + d1 * v[i, 1] + d2 * v[i, 2]
            s = int(math.floor((math.atan2(y, x) + math.pi) / (2.0 * math.pi) * sectors))
            s %= sectors
            if column[i, s] < 0:
                nearest[i, s] = distances[i, c]
                column[i, s] = c


def sector_nearest(points, indices, distances, u, v, sectors):
    """Return the distance (R, sectors) to the nearest neighbour in each direction (inf for
    none) and its column (-1 for none), directions measured in the (u, v) plane of each row."""
    n = indices.shape[0]
    points, indices, distances, u, v = inputs(points, indices, distances, u, v)
    nearest = np.full((n, sectors), np.inf)
    column = np.full((n, sectors), -1, dtype=np.int64)
    over_rows(_sector_nearest_rows, n, points, indices, distances, u, v, sectors, nearest, column)
    return nearest, column
