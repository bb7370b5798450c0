"""A raised-cosine bump on the unrolled wall, and the distance to it along a scanner's
beams: the shape a defect's depth and a bead's height are fitted with."""

from __future__ import annotations

import numpy as np

__all__ = ["along_beams", "at_most", "beam_reach", "bump", "covariance", "raised_cosine"]

#: `along_beams` searches for the wall over this many steps of its reach, which is this
#: many robust deviations of the range noise (a hit beyond is an outlier), and refines
#: each hit this many times.
BEAM_GRID = 32
REACH = 6.0
REFINE = 3


def raised_cosine(q, a, b) -> np.ndarray:
    """The unit bump ``cos^2(pi sqrt(u) / 2)``, ``u = (a - q[2])^2 / exp(2 q[4]) + (b -
    q[3])^2 / exp(2 q[5])`` (a along the pipe, b round it, metres; 0 beyond u = 1), at
    (a, b). `q` = (c, d, a0, b0, log half-widths) is a bump ``c + d bump`` of residual."""
    u = (a - q[2]) ** 2 / np.exp(2 * q[4]) + (b - q[3]) ** 2 / np.exp(2 * q[5])
    return np.cos(0.5 * np.pi * np.sqrt(np.minimum(u, 1.0))) ** 2


def bump(q):
    """The wall ``q[0] + q[1] raised_cosine(q, a, b)`` as a function of (a, b)."""
    return lambda a, b: q[0] + q[1] * raised_cosine(q, a, b)


def along_beams(wall, a, b, values, steps, reach: float) -> np.ndarray:
    """Signed distance (m) along each sample's beam from the sample to where the beam
    first meets the wall, coming from the scanner: ``wall(a, b)`` is its residual (m) at
    positions a along and b round the pipe (m), such as `bump`'s.

    A sample at (a, b) with residual `values` moves by t along its beam to (a + t s_a,
    b + t s_b) and residual ``values + t s_r``, `steps` = (s_a, s_b, s_r) being the beam's
    components along, round and away from the pipe. t is the first crossing from inside
    the bore to beyond the wall within `reach` metres either way, searched on a grid of
    `BEAM_GRID` steps and refined `REFINE` times by regula falsi; where there is none it is
    -`reach` (the beam met the wall before) or `reach` (not yet). At grazing incidence
    a beam can meet a bump two or three times, and a bump's far flank (a recess's far
    edge) hides its near one: the first hit is the range the scanner measured, whatever
    the shape, so the misfit is the range noise.
    """
    s_a, s_b, s_r = steps

    def gap(t):  # < 0 inside the bore, > 0 beyond the wall
        return values + t * s_r - wall(a + t * s_a, b + t * s_b)

    grid = np.linspace(-reach, reach, BEAM_GRID + 1)[:, None]
    gaps = gap(grid)
    inside = gaps < 0.0
    cross = inside[:-1] & ~inside[1:]
    first = np.argmax(cross, axis=0)
    column = np.arange(values.size)
    low, high = grid[first, 0], grid[first + 1, 0]
    g_low, g_high = gaps[first, column], gaps[first + 1, column]
    for _ in range(REFINE):  # regula falsi within the bracket: a smooth misfit to fit
        hit = low - g_low * (high - low) / (g_high - g_low)
        g_hit = gap(hit)
        below = g_hit < 0.0
        low, g_low = np.where(below, hit, low), np.where(below, g_hit, g_low)
        high, g_high = np.where(below, high, hit), np.where(below, g_high, g_hit)
    hit = low - g_low * (high - low) / (g_high - g_low)
    missed = np.where(inside[0], reach, -reach)  # all inside, or beyond from the start
    return np.where(cross.any(axis=0) & inside[0], hit, missed)


def beam_reach(values, steps) -> float:
    """How far (m) `along_beams` looks for the wall: `REACH` robust deviations of the
    residuals `values` (m) measured along the beams `steps` (their radial components
    held at 0.1 at least)."""
    along = np.abs(values - np.median(values)) / np.maximum(np.abs(steps[2]), 0.1)
    return float(REACH * 1.4826 * np.median(along))


def at_most(indices: np.ndarray, count: int) -> np.ndarray:
    """Every k-th of `indices`, evenly, so that at most `count` remain: past that a fit's
    cost grows and its error hardly shrinks."""
    return indices[:: max(1, -(-indices.size // count))]


def covariance(found) -> np.ndarray:
    """The covariance of the parameters of a least-squares fit `found`
    (`scipy.optimize.least_squares`): the misfits' variance times ``(J^T J)^-1``."""
    variance = float(found.fun @ found.fun) / max(found.fun.size - found.x.size, 1)
    return variance * np.linalg.pinv(found.jac.T @ found.jac)
