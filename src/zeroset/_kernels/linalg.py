"""Small dense linear algebra inside kernels, without LAPACK's per-call allocations."""

import numpy as np

from ._jit import inputs, jit, over_rows

#: Cyclic Jacobi sweeps of `eigh3`; each squares the off-diagonal remainder.
SWEEPS = 8


@jit
def eigh3(a, vectors):
    """Eigen-decomposition of the symmetric 3 x 3 `a` (left unchanged) by Jacobi rotations.

    Writes the unit eigenvectors into the columns of `vectors` (3, 3), eigenvalues
    ascending, as ``np.linalg.eigh`` orders them, and returns the three eigenvalues.
    """
    m = a.copy()
    for r in range(3):
        for c in range(3):
            vectors[r, c] = 1.0 if r == c else 0.0
    for _ in range(SWEEPS):
        off = m[0, 1] * m[0, 1] + m[0, 2] * m[0, 2] + m[1, 2] * m[1, 2]
        scale = m[0, 0] * m[0, 0] + m[1, 1] * m[1, 1] + m[2, 2] * m[2, 2]
        if off <= 1e-30 * scale or off == 0.0:
            break
        for p, q in ((0, 1), (0, 2), (1, 2)):
            if m[p, q] == 0.0:
                continue
            theta = (m[q, q] - m[p, p]) / (2.0 * m[p, q])
            t = np.sign(theta) / (abs(theta) + np.sqrt(theta * theta + 1.0))
            if theta == 0.0:
                t = 1.0
            cs = 1.0 / np.sqrt(t * t + 1.0)
            sn = t * cs
            for k in range(3):  # columns p, q of m R
                mkp, mkq = m[k, p], m[k, q]
                m[k, p] = cs * mkp - sn * mkq
                m[k, q] = sn * mkp + cs * mkq
            for k in range(3):  # rows p, q of R^T m R
                mpk, mqk = m[p, k], m[q, k]
                m[p, k] = cs * mpk - sn * mqk
                m[q, k] = sn * mpk + cs * mqk
            for k in range(3):
                vkp, vkq = vectors[k, p], vectors[k, q]
                vectors[k, p] = cs * vkp - sn * vkq
                vectors[k, q] = sn * vkp + cs * vkq
    values = np.array([m[0, 0], m[1, 1], m[2, 2]])
    for i in range(2):  # selection sort, ascending, columns along
        low = i
        for j in range(i + 1, 3):
            if values[j] < values[low]:
                low = j
        if low != i:
            values[i], values[low] = values[low], values[i]
            for k in range(3):
                vectors[k, i], vectors[k, low] = vectors[k, low], vectors[k, i]
    return values


@jit
def cholesky_solve(a, b):
    """Solve a x = b in place for the symmetric positive definite n x n `a` (overwritten by
    its Cholesky factor) and the n x m `b` (overwritten by x). Returns False if `a` is not
    positive definite."""
    n = a.shape[0]
    for j in range(n):
        d = a[j, j]
        for k in range(j):
            d -= a[j, k] * a[j, k]
        if not d > 0.0:
            return False
        d = np.sqrt(d)
        a[j, j] = d
        for i in range(j + 1, n):
            s = a[i, j]
            for k in range(j):
                s -= a[i, k] * a[j, k]
            a[i, j] = s / d
    for c in range(b.shape[1]):
        for i in range(n):  # L y = b
            s = b[i, c]
            for k in range(i):
                s -= a[i, k] * b[k, c]
            b[i, c] = s / a[i, i]
        for i in range(n - 1, -1, -1):  # L^T x = y
            s = b[i, c]
            for k in range(i + 1, n):
                s -= a[k, i] * b[k, c]
            b[i, c] = s / a[i, i]
    return True


@jit
def _eigh_rows(start, stop, matrices, values, vectors):
    matrix = np.empty((3, 3))  # writeable, as `zeroset._kernels.jets` passes its own
    for i in range(start, stop):
        for r in range(3):
            for c in range(3):
                matrix[r, c] = matrices[i, r, c]
        row = eigh3(matrix, vectors[i])
        for d in range(3):
            values[i, d] = row[d]


def eigh_rows(matrices):
    """Eigenvalues (N, 3), ascending, and unit eigenvectors (N, 3, 3), in columns, of the
    symmetric (N, 3, 3) `matrices`: ``np.linalg.eigh`` for a stack of 3 x 3 matrices."""
    (matrices,) = inputs(np.asarray(matrices, dtype=np.float64))
    values = np.empty((matrices.shape[0], 3))
    vectors = np.empty_like(matrices)
    over_rows(_eigh_rows, matrices.shape[0], matrices, values, vectors)
    return values, vectors
