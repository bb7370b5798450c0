"""A raised-cosine bump on the unrolled wall, and the distance to it along a scanner's
beams: the shape a defect's depth and a bead's height are fitted with."""

from __future__ import annotations

import numpy as np

__all__ = ["along_beams", "at_most", "covariance", "raised_cosine"]


def raised_cosine(q, a, b) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The unit bump ``cos^2(pi sqrt(u) / 2)``, ``u = (a - q[2])^2 / exp(2 q[4]) + (b -
    q[3])^2 / exp(2 q[5])`` (a along the pipe, b round it, metres; 0 beyond u = 1), at
    (a, b), and its derivatives along a and b. `q` = (c, d, a0, b0, log half-widths) is a
    bump ``c + d bump`` of residual."""
    wa, wb = np.exp(2 * q[4]), np.exp(2 * q[5])
    u = (a - q[2]) ** 2 / wa + (b - q[3]) ** 2 / wb
    root = np.sqrt(np.minimum(u, 1.0))
    # d/du cos^2(pi sqrt(u) / 2) = -(pi^2 / 4) sinc(sqrt(u)), and 0 beyond u = 1
    slope = np.where(u < 1.0, -0.25 * np.pi**2 * np.sinc(root), 0.0)
    return np.cos(0.5 * np.pi * root) ** 2, 2 * slope * (a - q[2]) / wa, 2 * slope * (b - q[3]) / wb


def along_beams(q, a, b, values, steps, iterations: int = 4) -> np.ndarray:
    """Signed distance (m) along each sample's beam from the sample to the wall
    ``residual = q[0] + q[1] bump(a, b)``.

    A sample at (a, b) with residual `values` moves by t along its beam to (a + t s_a,
    b + t s_b) and residual ``values + t s_r``, `steps` = (s_a, s_b, s_r) being the beam's
    components along, round and away from the pipe; t is found by Newton's method from 0.
    Where a beam grazes the bump its slope is held at 0.1 at least.
    """
    s_a, s_b, s_r = steps
    t = np.zeros_like(values)
    for _ in range(iterations):
        bump, d_a, d_b = raised_cosine(q, a + t * s_a, b + t * s_b)
        gap = values + t * s_r - q[0] - q[1] * bump
        slope = s_r - q[1] * (d_a * s_a + d_b * s_b)
        t -= gap / np.where(np.abs(slope) < 0.1, np.copysign(0.1, slope), slope)
    return t


def at_most(indices: np.ndarray, count: int) -> np.ndarray:
    """Every k-th of `indices`, evenly, so that at most `count` remain: past that a fit's
    cost grows and its error hardly shrinks."""
    return indices[:: max(1, -(-indices.size // count))]


def covariance(found) -> np.ndarray:
    """The covariance of the parameters of a least-squares fit `found`
    (`scipy.optimize.least_squares`): the misfits' variance times ``(J^T J)^-1``."""
    variance = float(found.fun @ found.fun) / max(found.fun.size - found.x.size, 1)
    return variance * np.linalg.pinv(found.jac.T @ found.jac)
