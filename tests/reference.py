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


def closest_points_on_mesh(points, vertices, faces, degenerate):
    """Closest point, face and distance by testing every face; flagged faces as three edges."""
    from zeroset.evaluate import closest_points_on_triangles

    n = points.shape[0]
    best = np.full(n, np.inf)
    closest, face = np.zeros((n, 3)), np.full(n, -1)
    for f, (a, b, c) in enumerate(vertices[faces]):
        if degenerate[f]:
            feet = []
            for u, v in ((a, b), (b, c), (c, a)):
                length2 = (v - u) @ (v - u)
                t = np.zeros(n) if length2 == 0 else np.clip((points - u) @ (v - u) / length2, 0, 1)
                feet.append(u + t[:, None] * (v - u))
            feet = np.stack(feet)
            foot = feet[np.argmin(np.linalg.norm(feet - points, axis=2), axis=0), np.arange(n)]
        else:
            corners = (np.broadcast_to(corner, points.shape) for corner in (a, b, c))
            foot = closest_points_on_triangles(points, *corners)
        distance = np.linalg.norm(points - foot, axis=1)
        better = distance < best
        best[better], closest[better], face[better] = distance[better], foot[better], f
    return closest, face, best


def sector_nearest(points, indices, distances, u, v, sectors):
    """Nearest neighbour per direction, vectorised over rows and columns."""
    n, k = indices.shape
    valid = (indices[:, 1:] >= 0) & np.isfinite(distances[:, 1:])
    offsets = points[indices[:, 1:]] - points[indices[:, :1]]
    angle = np.arctan2(np.einsum("rkd,rd->rk", offsets, v), np.einsum("rkd,rd->rk", offsets, u))
    sector = np.floor((angle + np.pi) / (2.0 * np.pi) * sectors).astype(np.int64) % sectors
    nearest = np.full((n, sectors), np.inf)
    column = np.full((n, sectors), -1, dtype=np.int64)
    for i, c in zip(*np.nonzero(valid), strict=True):
        s = sector[i, c]
        if column[i, s] < 0:
            nearest[i, s], column[i, s] = distances[i, c + 1], c + 1
    return nearest, column
