"""Neighbourhood centroids and covariances (Hoppe et al. 1992, §3.2; thesis eq. 3.4)."""

import numpy as np

from ._jit import inputs, jit, over_rows


@jit
def _centroid_covariance_rows(
    start, stop, points, indices, distances, radius, centroids, covariances, counts
):
    # Centroid o_i and covariance CV_i = (1/m) sum (p_j - o_i)(p_j - o_i)^T over the
    # neighbours j of i within radius[i]; -1 marks a missing neighbour.
    k = indices.shape[1]
    for i in range(start, stop):
        m = 0
        c0 = 0.0
        c1 = 0.0
        c2 = 0.0
        for s in range(k):
            j = indices[i, s]
            if j >= 0 and distances[i, s] <= radius[i]:
                c0 += points[j, 0]
                c1 += points[j, 1]
                c2 += points[j, 2]
                m += 1
        c0 /= m
        c1 /= m
        c2 /= m
        centroids[i, 0] = c0
        centroids[i, 1] = c1
        centroids[i, 2] = c2
        s00 = s01 = s02 = s11 = s12 = s22 = 0.0
        for s in range(k):
            j = indices[i, s]
            if j >= 0 and distances[i, s] <= radius[i]:
                d0 = points[j, 0] - c0
                d1 = points[j, 1] - c1
                d2 = points[j, 2] - c2
                s00 += d0 * d0
                s01 += d0 * d1
                s02 += d0 * d2
                s11 += d1 * d1
                s12 += d1 * d2
                s22 += d2 * d2
        covariances[i, 0, 0] = s00 / m
        covariances[i, 0, 1] = covariances[i, 1, 0] = s01 / m
        covariances[i, 0, 2] = covariances[i, 2, 0] = s02 / m
        covariances[i, 1, 1] = s11 / m
        covariances[i, 1, 2] = covariances[i, 2, 1] = s12 / m
        covariances[i, 2, 2] = s22 / m
        counts[i] = m


def centroid_covariance(points, indices, distances, radius):
    """Return centroids (N, 3), covariances (N, 3, 3) and counts (N,) within radius (N,) per row."""
    n = indices.shape[0]
    points, indices, distances, radius = inputs(points, indices, distances, radius)
    centroids = np.zeros((n, 3))
    covariances = np.zeros((n, 3, 3))
    counts = np.zeros(n, dtype=np.int64)
    over_rows(
        _centroid_covariance_rows,
        n,
        *(points, indices, distances, radius, centroids, covariances, counts),
    )
    return centroids, covariances, counts
