"""Weighted quadric height fits (jets) and their smooth blend (Cazals & Pouget 2005)."""

import numpy as np

from ._jit import inputs, jit, over_rows
from .linalg import cholesky_solve, eigh3

#: Ridge added to the normal equations, relative to their trace (in support-scaled units).
RIDGE = 1e-9
#: Coefficients per jet: a0..a5 of the quadric, then k1, k2, cos t, sin t of the quartic
#: ``(k1^3 s^4 + k2^3 t^4 + k1 k2 (k1 + k2) s^2 t^2) / 8`` in the principal frame (s, t),
#: the quartic of a circle of each principal curvature (exact for spheres and cylinders).
COEFFICIENTS = 10


@jit
def _quartic(x, u, v):
    # The quartic term and its derivatives in u and v.
    k1, k2, cs, sn = x[6], x[7], x[8], x[9]
    s = cs * u + sn * v
    t = -sn * u + cs * v
    cross = k1 * k2 * (k1 + k2)
    q = (k1**3 * s**4 + k2**3 * t**4 + cross * s * s * t * t) / 8.0
    qs = (4.0 * k1**3 * s**3 + 2.0 * cross * s * t * t) / 8.0
    qt = (4.0 * k2**3 * t**3 + 2.0 * cross * s * s * t) / 8.0
    return q, qs * cs - qt * sn, qs * sn + qt * cs


@jit
def _frame_coordinates(point, centre, frame):
    # (u, v, h) of a point in the frame (rows e1, e2, n) at centre.
    u = v = h = 0.0
    for d in range(3):
        y = point[d] - centre[d]
        u += y * frame[0, d]
        v += y * frame[1, d]
        h += y * frame[2, d]
    return u, v, h


@jit
def _height(x, u, v):
    q, _, _ = _quartic(x, u, v)
    return x[0] + x[1] * u + x[2] * v + x[3] * u * u + x[4] * u * v + x[5] * v * v + q


@jit
def _set_quartic(x):
    # Principal curvatures and directions of the Hessian [[2 a3, a4], [a4, 2 a5]].
    a3, a4, a5 = x[3], x[4], x[5]
    mean = a3 + a5
    spread = np.sqrt((a3 - a5) ** 2 + a4 * a4)
    x[6] = mean + spread
    x[7] = mean - spread
    angle = 0.5 * np.arctan2(a4, a3 - a5)
    x[8] = np.cos(angle)
    x[9] = np.sin(angle)


@jit
def _solve_quadric(points, weights, spreads, indices, distances, i, r, c, frame, x):
    # Weighted least squares for a0..a5 of the heights less the quartic of x (support-scaled).
    # A row standing for points of covariance S has mean height h(mean) + tr(H S) / 2, so
    # its quadratic terms are the second moments u^2 + S_uu, u v + S_uv, v^2 + S_vv.
    # Returns the freedom the fit absorbs, tr(A^-1 B) with A = X^T W X,
    # B = X^T W K X (W the weights times the kernel K): the expected weighted squared
    # residual of rows of noise variance sigma^2 / weight is sigma^2 (sum K - tr(A^-1 B)).
    k = indices.shape[1]
    normal = np.zeros((6, 6))
    solved = np.zeros((6, 7))  # [rhs | B], then A^-1 [rhs | B]
    row = np.empty(6)
    for s in range(k):
        q = distances[i, s] / r
        if q < 1.0:
            j = indices[i, s]
            kern = (1.0 - q * q) ** 2
            w = weights[j] * kern
            u, v, h = _frame_coordinates(points[j], c, frame)
            h -= _quartic(x, u, v)[0]
            suu = suv = svv = 0.0
            for a in range(3):
                for b in range(3):
                    sab = spreads[j, a, b]
                    suu += frame[0, a] * sab * frame[0, b]
                    suv += frame[0, a] * sab * frame[1, b]
                    svv += frame[1, a] * sab * frame[1, b]
            u /= r
            v /= r
            row[0] = 1.0
            row[1] = u
            row[2] = v
            row[3] = u * u + suu / (r * r)
            row[4] = u * v + suv / (r * r)
            row[5] = v * v + svv / (r * r)
            for a in range(6):
                wa = w * row[a]
                solved[a, 0] += wa * h
                for b in range(a, 6):
                    normal[a, b] += wa * row[b]
                for b in range(a, 6):
                    solved[a, b + 1] += wa * kern * row[b]
    for a in range(6):
        for b in range(a):
            normal[a, b] = normal[b, a]
            solved[a, b + 1] = solved[b, a + 1]
    ridge = RIDGE * (normal[0, 0] + normal[1, 1] + normal[2, 2] + normal[3, 3])
    for a in range(6):
        normal[a, a] += ridge
    # With the ridge, the normal equations are positive definite unless they hold a NaN.
    if not cholesky_solve(normal, solved):
        for a in range(6):
            for b in range(7):
                solved[a, b] = 0.0
    x[0] = solved[0, 0]
    x[1] = solved[1, 0] / r
    x[2] = solved[2, 0] / r
    x[3] = solved[3, 0] / (r * r)
    x[4] = solved[4, 0] / (r * r)
    x[5] = solved[5, 0] / (r * r)
    return (
        solved[0, 1] + solved[1, 2] + solved[2, 3] + solved[3, 4] + solved[4, 5] + solved[5, 6]
    )


@jit
def _fit_rows(start, stop, points, weights, spreads, indices, distances, radius, min_count,
              centres, frames, coefficients, radii, mass, misfit, freedom):
    # Row i: weights c_j (1 - (d/r)^2)^2 over the neighbours within r = max(radius[i], the
    # distance to its min_count-th neighbour); centroid and PCA frame (e1, e2, n); then
    # w = a0 + a1 u + a2 v + a3 u^2 + a4 u v + a5 v^2 by weighted least squares in
    # coordinates scaled by r. misfit = sum c k r^2 / sum k, the kernel k = (1 - (d/r)^2)^2;
    # freedom = tr(A^-1 B) / sum k, so that pure noise has misfit sigma^2 (1 - freedom).
    k = indices.shape[1]
    for i in range(start, stop):
        r = max(radius[i], distances[i, min(min_count, k) - 1] * (1.0 + 1e-9))
        radii[i] = r
        sw = 0.0
        sk = 0.0
        m = 0.0
        c = np.zeros(3)
        for s in range(k):
            q = distances[i, s] / r
            if q < 1.0:
                j = indices[i, s]
                kern = (1.0 - q * q) ** 2
                w = weights[j] * kern
                sw += w
                sk += kern
                m += weights[j]
                for d in range(3):
                    c[d] += w * points[j, d]
        for d in range(3):
            c[d] /= sw
        cov = np.zeros((3, 3))
        for s in range(k):
            q = distances[i, s] / r
            if q < 1.0:
                j = indices[i, s]
                w = weights[j] * (1.0 - q * q) ** 2
                for a in range(3):
                    for b in range(3):
                        cov[a, b] += w * (
                            (points[j, a] - c[a]) * (points[j, b] - c[b]) + spreads[j, a, b]
                        )
        vectors = np.empty((3, 3))
        eigh3(cov, vectors)
        frame = np.empty((3, 3))
        for d in range(3):
            frame[0, d] = vectors[d, 2]
            frame[1, d] = vectors[d, 1]
            frame[2, d] = vectors[d, 0]
        x = np.zeros(COEFFICIENTS)
        _solve_quadric(points, weights, spreads, indices, distances, i, r, c, frame, x)
        _set_quartic(x)  # then the quadric under the quartic of its curvatures
        absorbed = _solve_quadric(points, weights, spreads, indices, distances, i, r, c, frame, x)
        res = 0.0
        for s in range(k):
            q = distances[i, s] / r
            if q < 1.0:
                j = indices[i, s]
                u, v, h = _frame_coordinates(points[j], c, frame)
                e = h - _height(x, u, v)
                res += weights[j] * (1.0 - q * q) ** 2 * e * e
        for d in range(3):
            centres[i, d] = c[d]
            for e in range(3):
                frames[i, d, e] = frame[d, e]
        for d in range(COEFFICIENTS):
            coefficients[i, d] = x[d]
        mass[i] = m
        misfit[i] = res / sk
        freedom[i] = absorbed / sk


def fit_rows(points, weights, spreads, indices, distances, radius, min_count):
    """Fit one jet per row of `indices` (J, K) over `points` (N, 3) weighted by `weights` (N,),
    each standing for points of covariance `spreads` (N, 3, 3).

    Returns centres (J, 3), frames (J, 3, 3) with rows e1, e2, n, coefficients (J, 10)
    (``COEFFICIENTS``) in data units, radii (J,), mass (J,)
    (summed weights within the radius), misfit (J,) (kernel-weighted mean of
    weight x residual^2) and freedom (J,): where each row is noise of variance
    sigma^2 / weight about the quadric, the expected misfit is sigma^2 (1 - freedom).
    """
    n = indices.shape[0]
    points, weights, spreads, indices, distances, radius = inputs(
        points, weights, spreads, indices, distances, np.asarray(radius, dtype=np.float64)
    )
    centres, frames = np.zeros((n, 3)), np.zeros((n, 3, 3))
    coefficients = np.zeros((n, COEFFICIENTS))
    radii, mass, misfit, freedom = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    over_rows(_fit_rows, n, points, weights, spreads, indices, distances, radius, min_count,
              centres, frames, coefficients, radii, mass, misfit, freedom)
    return centres, frames, coefficients, radii, mass, misfit, freedom


@jit
def _blend_rows(start, stop, positions, indices, distances, centres, frames, coefficients, values,
                gradients):
    # Partition of unity over the k - 1 nearest jets: weight (1 - (d / d_k)^2)^2, with d_k
    # the distance to the k-th nearest, so a jet's weight falls to zero as it leaves the set.
    # Each jet is copied into arrays of the kernel's own, as `_fit_rows` holds its jet: the
    # helpers then compile once for both.
    k = indices.shape[1]
    centre, frame, a = np.empty(3), np.empty((3, 3)), np.empty(COEFFICIENTS)
    for i in range(start, stop):
        reach = distances[i, k - 1]
        total = 0.0
        f = 0.0
        g0 = g1 = g2 = 0.0
        for s in range(max(k - 1, 1)):  # a single jet stands alone
            q = distances[i, s] / reach if reach > 0.0 else 0.0
            w = (1.0 - q * q) ** 2 if q < 1.0 else 0.0
            if s == 0 and w == 0.0:
                w = 1.0  # all jets equally far: the nearest one alone
            if w == 0.0:
                continue
            j = indices[i, s]
            for d in range(3):
                centre[d] = centres[j, d]
                for e in range(3):
                    frame[d, e] = frames[j, d, e]
            for d in range(COEFFICIENTS):
                a[d] = coefficients[j, d]
            u, v, h = _frame_coordinates(positions[i], centre, frame)
            q, qu, qv = _quartic(a, u, v)
            height = a[0] + a[1] * u + a[2] * v + a[3] * u * u + a[4] * u * v + a[5] * v * v + q
            hu = a[1] + 2.0 * a[3] * u + a[4] * v + qu
            hv = a[2] + a[4] * u + 2.0 * a[5] * v + qv
            scale = 1.0 / np.sqrt(1.0 + hu * hu + hv * hv)
            f += w * (h - height) * scale
            g0 += w * (frames[j, 2, 0] - hu * frames[j, 0, 0] - hv * frames[j, 1, 0]) * scale
            g1 += w * (frames[j, 2, 1] - hu * frames[j, 0, 1] - hv * frames[j, 1, 1]) * scale
            g2 += w * (frames[j, 2, 2] - hu * frames[j, 0, 2] - hv * frames[j, 1, 2]) * scale
            total += w
        values[i] = f / total
        gradients[i, 0] = g0 / total
        gradients[i, 1] = g1 / total
        gradients[i, 2] = g2 / total


def blend_rows(positions, indices, distances, centres, frames, coefficients):
    """Blended signed distance (M,) and its gradient (M, 3) at `positions` (M, 3).

    `indices` and `distances` (M, k) are each position's k nearest jet centres, ascending.
    """
    m = positions.shape[0]
    positions, indices, distances, centres, frames, coefficients = inputs(
        positions, indices, distances, centres, frames, coefficients
    )
    values, gradients = np.zeros(m), np.zeros((m, 3))
    over_rows(_blend_rows, m, positions, indices, distances, centres, frames, coefficients,
              values, gradients)
    return values, gradients
