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


def closest_points_on_triangles(p, a, b, c):
    """Closest point (N, 3) on triangle (a_i, b_i, c_i) to each p_i: the projection onto
    the plane where its barycentric coordinates (from the 2 x 2 normal equations) are
    all >= 0, else the nearest of the closest points on the three edges; a triangle whose
    height is below 1e-8 of its longest edge counts as its edges."""
    ab, ac, ap = b - a, c - a, p - a
    gram = np.stack(
        [np.stack([_dot(ab, ab), _dot(ab, ac)], -1), np.stack([_dot(ab, ac), _dot(ac, ac)], -1)],
        -2,
    )
    longest2 = np.max([_dot(ab, ab), _dot(c - b, c - b), _dot(ac, ac)], axis=0)
    flat = np.linalg.norm(np.cross(ab, ac), axis=1) <= 1e-8 * longest2
    gram[flat] = np.eye(2)
    v, w = np.linalg.solve(gram, np.stack([_dot(ap, ab), _dot(ap, ac)], -1)[..., None])[..., 0].T
    result = a + v[:, None] * ab + w[:, None] * ac
    outside = flat | (v < 0) | (w < 0) | (v + w > 1)
    feet = np.stack([_closest_on_segments(p, u, x) for u, x in ((a, b), (b, c), (c, a))])
    nearest = np.argmin(np.linalg.norm(feet - p, axis=2), axis=0)
    result[outside] = feet[nearest, np.arange(p.shape[0])][outside]
    return result


def _closest_on_segments(p, a, b):
    """Closest point (N, 3) on segment (a_i, b_i) to each p_i."""
    ab = b - a
    length2 = _dot(ab, ab)
    t = np.divide(_dot(p - a, ab), length2, out=np.zeros_like(length2), where=length2 > 0)
    return a + np.clip(t, 0.0, 1.0)[:, None] * ab


def _dot(u, v):
    return np.einsum("ij,ij->i", u, v)


def closest_points_on_mesh(points, vertices, faces, degenerate):
    """Closest point, face and distance by testing every face; flagged faces as three edges."""
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


def _quartic(x, u, v):
    k1, k2, cs, sn = x[6:10]
    s, t = cs * u + sn * v, -sn * u + cs * v
    cross = k1 * k2 * (k1 + k2)
    q = (k1**3 * s**4 + k2**3 * t**4 + cross * s**2 * t**2) / 8.0
    qs = (4 * k1**3 * s**3 + 2 * cross * s * t**2) / 8.0
    qt = (4 * k2**3 * t**3 + 2 * cross * s**2 * t) / 8.0
    return q, qs * cs - qt * sn, qs * sn + qt * cs


def fit_jet_rows(points, weights, spreads, indices, distances, radius, min_count):
    """Jets by weighted least squares, one row at a time (see zeroset._kernels.jets)."""
    n, k = indices.shape
    out = [np.zeros((n, 3)), np.zeros((n, 3, 3)), np.zeros((n, 10)), np.zeros(n), np.zeros(n),
           np.zeros(n), np.zeros(n)]
    for i in range(n):
        r = max(radius[i], distances[i, min(min_count, k) - 1] * (1 + 1e-9))
        inside = distances[i] / r < 1.0
        j = indices[i][inside]
        kern = (1 - (distances[i][inside] / r) ** 2) ** 2
        w = weights[j] * kern
        c = (w[:, None] * points[j]).sum(0) / w.sum()
        d = points[j] - c
        cov = np.einsum("m,mi,mj->ij", w, d, d) + np.einsum("m,mij->ij", w, spreads[j])
        frame = np.linalg.eigh(cov)[1][:, ::-1].T
        u, v, h = (d @ frame.T).T
        s_uv = np.einsum("ai,mij,bj->mab", frame[:2], spreads[j], frame[:2])
        x = np.zeros(10)
        for rnd in range(2):
            y = h - _quartic(x, u, v)[0]
            design = np.stack([np.ones_like(u), u / r, v / r, (u * u + s_uv[:, 0, 0]) / r**2,
                               (u * v + s_uv[:, 0, 1]) / r**2, (v * v + s_uv[:, 1, 1]) / r**2], 1)
            normal = design.T @ (w[:, None] * design)
            normal += 1e-9 * np.trace(normal[:4, :4]) * np.eye(6)
            a = np.linalg.solve(normal, design.T @ (w * y))
            x[:6] = a / np.array([1, r, r, r * r, r * r, r * r])
            if rnd == 0:
                a3, a4, a5 = x[3:6]
                spread = np.hypot(a3 - a5, a4)
                angle = 0.5 * np.arctan2(a4, a3 - a5)
                x[6:10] = a3 + a5 + spread, a3 + a5 - spread, np.cos(angle), np.sin(angle)
        height = x[0] + x[1] * u + x[2] * v + x[3] * u * u + x[4] * u * v + x[5] * v * v
        residual = h - height - _quartic(x, u, v)[0]
        # The residuals are (I - H) e with H = X A^-1 X^T W: E[sum w r^2] = sigma^2 (sum kern
        # - tr(A^-1 X^T W K X)) for noise e of variance sigma^2 / weights.
        absorbed = np.trace(np.linalg.solve(normal, design.T @ ((w * kern)[:, None] * design)))
        for array, value in zip(out, (c, frame, x, r, weights[j].sum(),
                                      (w * residual**2).sum() / kern.sum(),
                                      absorbed / kern.sum()), strict=True):
            array[i] = value
    return tuple(out)


def blend_jet_rows(positions, indices, distances, centres, frames, coefficients):
    """Blended jet distance and gradient, one position at a time."""
    m, k = indices.shape
    values, gradients = np.zeros(m), np.zeros((m, 3))
    for i in range(m):
        reach = distances[i, -1]
        weight = np.clip(1 - (distances[i, :-1] / reach) ** 2, 0, None) ** 2
        if weight[0] == 0:
            weight[0] = 1.0
        f, g = 0.0, np.zeros(3)
        for s in np.flatnonzero(weight):
            j = indices[i, s]
            u, v, h = frames[j] @ (positions[i] - centres[j])
            x = coefficients[j]
            q, qu, qv = _quartic(x, u, v)
            hu = x[1] + 2 * x[3] * u + x[4] * v + qu
            hv = x[2] + x[4] * u + 2 * x[5] * v + qv
            height = x[0] + x[1] * u + x[2] * v + x[3] * u * u + x[4] * u * v + x[5] * v * v + q
            scale = 1 / np.sqrt(1 + hu * hu + hv * hv)
            f += weight[s] * (h - height) * scale
            g += weight[s] * (frames[j, 2] - hu * frames[j, 0] - hv * frames[j, 1]) * scale
        values[i], gradients[i] = f / weight.sum(), g / weight.sum()
    return values, gradients
