"""The closest point of a triangle to a point, exact, with its barycentric coordinates.

A triangle is a row of 15 floats: its corners a, b, c, then the dual vectors
``e_b = (ac x n) / |n|^2`` and ``e_c = (n x ab) / |n|^2`` with ``n = ab x ac``. The
barycentric coordinates of the projection of p onto the plane are then
``w_b = e_b . (p - a)``, ``w_c = e_c . (p - a)`` and ``w_a = 1 - w_b - w_c``, exact to the
last few bits even for a sliver (Ericson 2005, §3.4), where the differences of dot
products of §5.1.5 lose all accuracy. A row is built once per triangle and serves every
query. A degenerate triangle (zero area up to rounding, see ``DEGENERATE_RATIO``) has
zero dual vectors and counts as its three edges.
"""

import numpy as np

from ._jit import jit

# A face is degenerate when twice its area is at most this share of its longest edge
# squared, i.e. its height is below 1e-8 (about the square root of the float64 epsilon) of
# its length: its normal is then known to no better than 1e-8 radians, and its three edges
# are the more accurate model of it.
DEGENERATE_RATIO = 1e-8


@jit
def set_triangle(t, ax, ay, az, bx, by, bz, cx, cy, cz):
    # Fill row t (15,) with the corners and the dual vectors; returns whether the
    # triangle is degenerate (then the dual vectors are zero).
    t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], t[8] = ax, ay, az, bx, by, bz, cx, cy, cz
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = cx - ax, cy - ay, cz - az
    nx, ny, nz = uy * wz - uz * wy, uz * wx - ux * wz, ux * wy - uy * wx
    length2 = nx * nx + ny * ny + nz * nz
    longest2 = max(
        ux * ux + uy * uy + uz * uz,
        (cx - bx) ** 2 + (cy - by) ** 2 + (cz - bz) ** 2,
        wx * wx + wy * wy + wz * wz,
    )
    degenerate = np.sqrt(length2) <= DEGENERATE_RATIO * longest2
    scale = 0.0 if degenerate else 1.0 / length2
    t[9], t[10], t[11] = (
        (wy * nz - wz * ny) * scale,
        (wz * nx - wx * nz) * scale,
        (wx * ny - wy * nx) * scale,
    )
    t[12], t[13], t[14] = (
        (ny * uz - nz * uy) * scale,
        (nz * ux - nx * uz) * scale,
        (nx * uy - ny * ux) * scale,
    )
    return degenerate


@jit
def _closest_on_edge(px, py, pz, rows, r, i, j):
    # Projection of p onto the line through corners i and j of row r, clamped to the
    # segment: its parameter s (the foot is (1 - s) corner_i + s corner_j) and the
    # squared distance.
    ax, ay, az = rows[r, 3 * i], rows[r, 3 * i + 1], rows[r, 3 * i + 2]
    ux, uy, uz = rows[r, 3 * j] - ax, rows[r, 3 * j + 1] - ay, rows[r, 3 * j + 2] - az
    length2 = ux * ux + uy * uy + uz * uz
    s = 0.0
    if length2 > 0.0:
        s = min(max(((px - ax) * ux + (py - ay) * uy + (pz - az) * uz) / length2, 0.0), 1.0)
    qx, qy, qz = ax + s * ux, ay + s * uy, az + s * uz
    return s, (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2


@jit
def closest_point_on_triangle(px, py, pz, rows, r, degenerate):
    # Closest point to p of the triangle in row r of rows (see set_triangle): its squared
    # distance and barycentric coordinates (u, v, w), foot = u a + v b + w c, all >= 0,
    # sum 1. The row is read in place: a view of it would cost a reference count, taken
    # and dropped atomically, on every call.
    # Inside the triangle the projection onto the plane is the closest point; outside,
    # it lies on an edge opposite a negative coordinate (Ericson 2005, §3.4 and §5.1.5).
    # A degenerate triangle is its three edges.
    check_a = check_b = check_c = True
    if not degenerate:
        apx, apy, apz = px - rows[r, 0], py - rows[r, 1], pz - rows[r, 2]
        wb = rows[r, 9] * apx + rows[r, 10] * apy + rows[r, 11] * apz
        wc = rows[r, 12] * apx + rows[r, 13] * apy + rows[r, 14] * apz
        wa = 1.0 - wb - wc
        if wa >= 0.0 and wb >= 0.0 and wc >= 0.0:
            qx = rows[r, 0] + wb * (rows[r, 3] - rows[r, 0]) + wc * (rows[r, 6] - rows[r, 0])
            qy = rows[r, 1] + wb * (rows[r, 4] - rows[r, 1]) + wc * (rows[r, 7] - rows[r, 1])
            qz = rows[r, 2] + wb * (rows[r, 5] - rows[r, 2]) + wc * (rows[r, 8] - rows[r, 2])
            return (px - qx) ** 2 + (py - qy) ** 2 + (pz - qz) ** 2, wa, wb, wc
        check_a, check_b, check_c = wa < 0.0, wb < 0.0, wc < 0.0
    # The nearest of the edges to check: 0 is b -> c, 1 is c -> a, 2 is a -> b.
    # Typed corners: literal ones would compile _closest_on_edge once for each pair.
    c0, c1, c2 = np.int64(0), np.int64(1), np.int64(2)
    best, edge, s_best = np.inf, 0, 0.0
    if check_a:
        s_best, best = _closest_on_edge(px, py, pz, rows, r, c1, c2)
    if check_b:
        s, d2 = _closest_on_edge(px, py, pz, rows, r, c2, c0)
        if d2 < best:
            best, edge, s_best = d2, 1, s
    if check_c:
        s, d2 = _closest_on_edge(px, py, pz, rows, r, c0, c1)
        if d2 < best:
            best, edge, s_best = d2, 2, s
    if edge == 0:
        return best, 0.0, 1.0 - s_best, s_best
    if edge == 1:
        return best, s_best, 0.0, 1.0 - s_best
    return best, 1.0 - s_best, s_best, 0.0


@jit
def triangle_rows(a, b, c, rows, degenerate):
    # set_triangle for every row of the (F, 3) corners; fills (F, 15) and (F,).
    for f in range(a.shape[0]):
        degenerate[f] = set_triangle(
            rows[f], a[f, 0], a[f, 1], a[f, 2], b[f, 0], b[f, 1], b[f, 2], c[f, 0], c[f, 1], c[f, 2]
        )


@jit
def closest_point_rows(points, a, b, c, distance2, bary):
    # closest_point_on_triangle of p_n and triangle (a_n, b_n, c_n) for every row of the
    # (N, 3) arrays; fills (N,) squared distances and (N, 3) barycentric coordinates.
    t = np.zeros((1, 15))
    row = t[0]
    for n in range(points.shape[0]):
        degenerate = set_triangle(
            row, a[n, 0], a[n, 1], a[n, 2], b[n, 0], b[n, 1], b[n, 2], c[n, 0], c[n, 1], c[n, 2]
        )
        d2, u, v, w = closest_point_on_triangle(
            points[n, 0], points[n, 1], points[n, 2], t, np.int64(0), degenerate
        )
        distance2[n] = d2
        bary[n, 0], bary[n, 1], bary[n, 2] = u, v, w
