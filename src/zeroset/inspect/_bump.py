"""A raised-cosine bump on the unrolled wall, the distance to a wall along a scanner's
beams, and the fit of a wall to samples along their beams: the shape and the fit a
defect's depth is measured with (a bead's height with the shape)."""

from __future__ import annotations

import numpy as np
from scipy import optimize

__all__ = [
    "along_beams",
    "at_most",
    "bump",
    "covariance",
    "fit_along_beams",
    "raised_cosine",
    "range_deviation",
]

#: `along_beams` searches for the wall over this many steps of its reach, which is this
#: many robust deviations of the range noise (a hit beyond is an outlier), and refines
#: each hit this many times.
BEAM_GRID = 32
REACH = 6.0
REFINE = 3
#: A fit along the beams weighs its misfits with the Cauchy loss of this many robust
#: deviations, 95 % as efficient as least squares under Gaussian noise (Holland and
#: Welsch 1977).
CAUCHY = 2.385
#: A beam's slope into the wall (the sine of the angle it meets it at) is held at this
#: much at least: nearer grazing, a hit moves by more than the range noise measures.
GRAZING = 0.1
#: A bump's fit stops after this many evaluations of its misfit (a bump converges in a few
#: tens; noise shaped like none may wander for hundreds, and is left unfitted).
FIT_EVALUATIONS = 100


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


def range_deviation(values, steps) -> float:
    """A robust standard deviation (m) of the misfits `values` (m, radial) measured along
    the beams `steps` (their radial components held at `GRAZING` at least): the range
    noise where `values` are misfits about the wall."""
    along = np.abs(values - np.median(values)) / np.maximum(np.abs(steps[2]), GRAZING)
    return float(1.4826 * np.median(along))


def fit_along_beams(model, start, a, b, values, steps):
    """The robust fit (`scipy.optimize.least_squares`) of the wall ``model(q)`` (a function
    of (a, b), as `bump`'s) to samples at (a, b) with residuals `values` (m), each misfit
    taken along the sample's beam (`along_beams`, `steps` its components); `start` is q's
    first guess. The search reaches `REACH` robust deviations of the range noise
    (`range_deviation` about the wall ``model(start)``), and the misfits are weighed with
    the Cauchy loss of `CAUCHY` of them.

    A beam that grazes a rim meets it or passes it as the wall moves a little, and its
    first hit jumps to the far flank: its misfit is a step. Under least squares (or a soft
    L1 loss, which still grows without bound) those few steps make the cost a staircase
    whose treads hold the fit far from its minimum: an 8 mm bulge whose near rim every
    beam from afar grazes read 7.4 mm, spread half as far again as its error said. The
    Cauchy loss bounds each step's weight, and where the trust-region fit stops on a
    tread's edge, the Nelder-Mead simplex, which takes no derivatives, goes on down the
    stairs. The result is the trust-region fit's, with the simplex's
    parameters where they cost less, their misfits and their Jacobian (unweighted).

    Each misfit's derivatives are those of the hit it measures, by the implicit function
    theorem: ``dt/dq = (d wall / dq) / g'``, the wall's change with q at the hit over g',
    the rate the beam goes into the wall there (held at `GRAZING` at least). Finite
    differences of the misfits would take the steps for slopes a million times steeper
    than any."""
    start = np.asarray(start, dtype=float)
    deviation = range_deviation(values - model(start)(a, b), steps)
    reach = REACH * deviation
    s_a, s_b, s_r = steps
    small = np.sqrt(np.finfo(float).eps)

    def misfit(q):
        return along_beams(model(q), a, b, values, steps, reach)

    def jacobian(q):
        wall = model(q)
        t = along_beams(wall, a, b, values, steps, reach)
        at_a, at_b, h = a + t * s_a, b + t * s_b, small * reach
        rise = (wall(at_a + h * s_a, at_b + h * s_b) - wall(at_a - h * s_a, at_b - h * s_b)) / (
            2 * h
        )
        slope = np.maximum(s_r - rise, GRAZING)
        here = wall(at_a, at_b)
        columns = []
        for k in range(q.size):
            dq = small * max(1.0, abs(q[k]))
            moved = q.copy()
            moved[k] += dq
            columns.append((model(moved)(at_a, at_b) - here) / dq)
        hit = np.abs(t) < reach
        return np.where(hit[:, None], np.stack(columns, axis=1) / slope[:, None], 0.0)

    scale = CAUCHY * deviation
    found = optimize.least_squares(
        misfit, start, jac=jacobian, loss="cauchy", f_scale=scale, max_nfev=FIT_EVALUATIONS
    )

    def cost(q):
        return float(np.sum(np.log1p((misfit(q) / scale) ** 2)))

    polished = optimize.minimize(
        cost, found.x, method="Nelder-Mead", options={"maxfev": FIT_EVALUATIONS * start.size}
    )
    if polished.fun < cost(found.x):
        found.x, found.fun, found.jac = polished.x, misfit(polished.x), jacobian(polished.x)
    return found


def at_most(indices: np.ndarray, count: int) -> np.ndarray:
    """Every k-th of `indices`, evenly, so that at most `count` remain: past that a fit's
    cost grows and its error hardly shrinks."""
    return indices[:: max(1, -(-indices.size // count))]


def covariance(found) -> np.ndarray:
    """The covariance of the parameters of a least-squares fit `found`
    (`scipy.optimize.least_squares`): the misfits' variance times ``(J^T J)^-1``."""
    variance = float(found.fun @ found.fun) / max(found.fun.size - found.x.size, 1)
    return variance * np.linalg.pinv(found.jac.T @ found.jac)
