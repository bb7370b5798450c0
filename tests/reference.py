"""Plain NumPy references for the compiled kernels."""

import numpy as np


def centroid_covariance(points, indices, distances, radius):
    """Centroid, covariance and count of the neighbours within radius[i] of each row."""
    n = indices.shape[0]
    centroids, covariances, counts = np.zeros((n, 3)), np.zeros((n, 3, 3)), np.zeros(n, int)
    for i in range(n):
        members = indices[i][(indices[i] >= 0) & (distances[i] <= radius[i])]
        neighbourhood = points[members]
        centroids[i] = neighbourhood.mean(axis=0)
        covariances[i] = np.cov(neighbourhood.T, bias=True)
        counts[i] = members.size
    return centroids, covariances, counts


def propagate_signs(order, predecessors, normals, root_sign):
    """Signs making each normal agree with its parent's, roots taking root_sign."""
    signs = np.ones(normals.shape[0])
    for v in order:
        if v >= normals.shape[0]:
            continue
        p = predecessors[v]
        if p < 0 or p >= normals.shape[0]:
            signs[v] = root_sign[v]
        else:
            signs[v] = signs[p] * (1.0 if normals[p] @ normals[v] >= 0 else -1.0)
    return signs
