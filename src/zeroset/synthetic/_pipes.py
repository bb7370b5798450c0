"""Uniform samples of pipe fittings: a 90 degree elbow and a T-junction, with exact distances."""

from __future__ import annotations

import math

import numpy as np
from scipy import integrate, special

from .._validate import positive, require_rng
from ..errors import InputError
from . import _truth
from ._distance import circle_distance, curve_distance, query, wall_distance
from ._path import PipePath, _tube_sites
from ._sample import Sample, _count, _fraction, _noise, add_noise, finish

__all__ = ["sample_elbow", "sample_tee"]


def _elbow_axis(radius_b: float, leg: float):
    """Return ``axis(part, q)``: axis points and in-plane unit normals of the elbow's parts.

    Part 0 is the first leg along +z from the origin, part 1 the bend (centre
    ``(R_b, 0, leg)``, turning towards +x), part 2 the second leg along +x; `q` is the
    arc length along the axis within the part. The in-plane normal points towards the
    bend's centre; with ``e_y`` it spans each cross-section.
    """

    def axis(part: int, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        zero, one = np.zeros_like(q), np.ones_like(q)
        if part == 0:
            return np.stack([zero, zero, q], -1), np.stack([one, zero, zero], -1)
        if part == 1:
            t = q / radius_b
            centre = np.stack(
                [radius_b - radius_b * np.cos(t), zero, leg + radius_b * np.sin(t)], -1
            )
            return centre, np.stack([np.cos(t), zero, -np.sin(t)], -1)
        centre = np.stack([radius_b + q, zero, np.full_like(q, leg + radius_b)], -1)
        return centre, np.stack([zero, zero, -one], -1)

    return axis


def _elbow_path(bend_radius: float, leg: float) -> PipePath:
    """Return the elbow's centreline: a leg along +z from the origin, a 90 degree bend
    towards +x (clock 270 of up = +y), a leg along +x."""
    pieces = [("straight", leg), ("bend", bend_radius, 90.0, 270.0), ("straight", leg)]
    return PipePath.build(pieces, direction=(0.0, 0.0, 1.0), up=(0.0, 1.0, 0.0))


def _elbow_frame(axis, bend_radius: float, leg: float, s: np.ndarray):
    """Return the axis points (M, 3) and in-plane normals (M, 3) at arc lengths `s` (M,)
    along the whole elbow axis, from the per-part `axis` of `_elbow_axis`."""
    bend = 0.5 * np.pi * bend_radius
    centre, e_n = np.zeros((s.size, 3)), np.zeros((s.size, 3))
    part = np.searchsorted([leg, leg + bend], s, side="right")
    for index, start in enumerate((0.0, leg, leg + bend)):
        chosen = part == index
        centre[chosen], e_n[chosen] = axis(index, s[chosen] - start)
    return centre, e_n


def _branch_area(big: float, small: float, x_end: float) -> float:
    """Return the area a branch of radius `small`, its open end `x_end` from the main pipe's
    axis, adds to a main pipe of radius `big`: its wall outside the main pipe less the
    hole it cuts (exact: a 1-D quadrature and an elliptic integral)."""
    hole_area = integrate.quad(
        lambda t: 2.0 * big * math.asin(math.sqrt(max(small**2 - t * t, 0.0)) / big),
        -small,
        small,
        epsabs=1e-13,
        epsrel=1e-12,
    )[0]
    return (
        small * (2.0 * np.pi * x_end - 4.0 * big * special.ellipe((small / big) ** 2)) - hole_area
    )


def sample_elbow(
    n: int,
    *,
    radius: float = 0.25,
    bend_radius: float = 0.6,
    leg: float = 0.5,
    noise: float = 0.0,
    outliers: float = 0.0,
    rng=None,
) -> Sample:
    """Sample a 90 degree pipe elbow uniformly: straight leg, quarter-torus bend, straight leg.

    The first leg runs along +z from z = 0 to ``leg`` on the z axis; the bend (centre
    ``(bend_radius, 0, leg)``, in the x-z plane) turns it towards +x; the second leg runs
    along +x from ``x = bend_radius`` at height ``leg + bend_radius``. Both ends are open.

    Parameters
    ----------
    n : int
    radius : float
        Pipe radius, in metres.
    bend_radius : float
        Radius of the bend's axis, ``> radius``.
    leg : float
        Length of each straight leg.
    noise : float
        Standard deviation of Gaussian noise per axis.
    outliers : float in [0, 1)
        Share of uniform outliers among the returned points (see `add_outliers`).
    rng : numpy.random.Generator or int or None

    Returns
    -------
    Sample
        ``normals`` point away from the pipe axis; ``area`` is ``2 pi radius`` times the
        axis length ``2 leg + pi bend_radius / 2`` (Pappus); ``truth_mesh`` is one tube
        grid along the axis with two boundary loops.

    Notes
    -----
    Points are uniform in area: an axis position is drawn uniformly along the axis and an
    angle around it, and bend samples are kept with probability proportional to the area
    element ``bend_radius - radius cos(phi)`` (legs with the matching constant). ``distance``
    is exact: the minimum of the exact distances to each leg's finite open wall and to the
    bend's quarter torus, which for queries outside its angular range is the distance to the
    nearer of its end circles.

    Examples
    --------
    >>> sample_elbow(2000, rng=0).points.shape
    (2000, 3)
    """
    n, radius = _count(n), positive(radius, "radius")
    bend_radius, leg = positive(bend_radius, "bend_radius"), positive(leg, "leg")
    noise, outliers = _noise(noise), _fraction(outliers, "outliers")
    if bend_radius <= radius:
        raise InputError(
            f"bend_radius must exceed radius; got bend_radius={bend_radius!r}, radius={radius!r}"
        )
    rng = require_rng(rng)
    s, phi = _tube_sites(_elbow_path(bend_radius, leg), radius, n, rng)
    axis = _elbow_axis(bend_radius, leg)
    centre, e_n = _elbow_frame(axis, bend_radius, leg, s)
    total = 2.0 * leg + 0.5 * np.pi * bend_radius
    normals = np.cos(phi)[:, None] * e_n + np.sin(phi)[:, None] * np.array([0.0, 1.0, 0.0])
    bend_centre = np.array([bend_radius, 0.0, leg])

    def distance(x: np.ndarray) -> np.ndarray:
        x = query(x)
        first = wall_distance(np.hypot(x[:, 0], x[:, 1]), x[:, 2], 0.0, leg, radius)
        second = wall_distance(
            np.hypot(x[:, 1], x[:, 2] - (leg + bend_radius)),
            x[:, 0] - bend_radius,
            0.0,
            leg,
            radius,
        )
        w = x - bend_centre
        azimuth = np.arctan2(w[:, 2], -w[:, 0])  # 0 at the first leg, pi/2 at the second
        torus = np.abs(np.hypot(np.hypot(w[:, 0], w[:, 2]) - bend_radius, w[:, 1]) - radius)
        ends = np.minimum(
            circle_distance(x, (0.0, 0.0, leg), (0.0, 0.0, 1.0), radius),
            circle_distance(x, (bend_radius, 0.0, leg + bend_radius), (1.0, 0.0, 0.0), radius),
        )
        inside = (azimuth >= 0.0) & (azimuth <= 0.5 * np.pi)
        return np.minimum.reduce([first, second, np.where(inside, torus, ends)])

    area = 2.0 * np.pi * radius * total

    def build(spacing: float | None):
        extent = (bend_radius + leg + radius, 2.0 * radius, leg + bend_radius + radius)
        h = _truth.resolve_spacing(spacing, diagonal=math.hypot(*extent), area=area)
        return _truth.elbow_mesh(radius, bend_radius, leg, h, axis)

    points = add_noise(centre + radius * normals, noise, rng=rng)
    return finish(points, normals, distance, area, build, outliers=outliers, rng=rng)


def sample_tee(
    n: int,
    *,
    radius: float = 0.25,
    branch_radius: float = 0.15,
    length: float = 1.2,
    branch_length: float = 0.5,
    noise: float = 0.0,
    outliers: float = 0.0,
    rng=None,
) -> Sample:
    """Sample a pipe T-junction uniformly: a main pipe along z with a branch along +x.

    The main pipe's axis is the z axis from z = 0 to ``length``; the branch's axis runs
    along +x at height ``length / 2`` and the branch ends ``branch_length`` beyond the main
    pipe's outermost line, at ``x = radius + branch_length``. The main wall has a hole where
    the branch enters, the branch wall ends on the main wall, and the three pipe ends are
    open.

    Parameters
    ----------
    n : int
    radius : float
        Main pipe radius, in metres.
    branch_radius : float
        Branch radius, ``< radius`` and ``< length / 2``.
    length : float
        Main pipe length.
    branch_length : float
        Branch length beyond the main pipe (from ``x = radius``).
    noise : float
        Standard deviation of Gaussian noise per axis.
    outliers : float in [0, 1)
        Share of uniform outliers among the returned points (see `add_outliers`).
    rng : numpy.random.Generator or int or None

    Returns
    -------
    Sample
        ``normals`` point away from each wall's own axis (outward of the union of the two
        solid pipes); ``truth_mesh`` joins both walls along their exact intersection curve
        (shared vertices) and has three boundary loops. Its wall grid also carries the seam,
        so keep an explicit ``spacing`` well below `branch_radius` (the default is).

    Notes
    -----
    Sampling draws candidates uniformly on the full main wall and on the branch wall from
    ``x = sqrt(radius^2 - branch_radius^2)`` to its end, in proportion to their areas, and
    rejects those inside the other pipe. ``distance`` is exact: for each wall it is the
    distance to the untrimmed wall when the nearest point there is kept, else the nearest of
    the wall's other critical point, its end circles and the intersection curve (a 1-D
    minimisation, exact to rounding). The area is exact: ``2 pi R L`` less the hole (a 1-D
    quadrature), plus ``r (2 pi x_end - 4 R E(r^2 / R^2))`` for the branch, with E the
    complete elliptic integral of the second kind.

    Examples
    --------
    >>> sample_tee(2000, rng=0).points.shape
    (2000, 3)
    """
    n, big = _count(n), positive(radius, "radius")
    small, length = positive(branch_radius, "branch_radius"), positive(length, "length")
    branch_length = positive(branch_length, "branch_length")
    noise, outliers = _noise(noise), _fraction(outliers, "outliers")
    if not (small < big and small < 0.5 * length):
        raise InputError(
            "branch_radius must be below radius and below length / 2; got "
            f"branch_radius={small!r}, radius={big!r}, length={length!r}"
        )
    rng = require_rng(rng)
    z_c = 0.5 * length
    x_end = big + branch_length
    x_in = math.sqrt(big**2 - small**2)
    main_area = 2.0 * np.pi * big * length
    branch_area = 2.0 * np.pi * small * (x_end - x_in)
    p_main = main_area / (main_area + branch_area)
    kept = np.zeros((0, 3))
    normals = np.zeros((0, 3))
    while kept.shape[0] < n:
        batch = int(1.1 * (n - kept.shape[0])) + 64
        on_main = rng.uniform(0.0, 1.0, batch) < p_main
        angle = rng.uniform(0.0, 2.0 * np.pi, batch)
        along = np.where(on_main, rng.uniform(0.0, length, batch), rng.uniform(x_in, x_end, batch))
        c, s = np.cos(angle), np.sin(angle)
        main_point = np.stack([big * c, big * s, along], -1)
        branch_point = np.stack([along, small * c, z_c + small * s], -1)
        point = np.where(on_main[:, None], main_point, branch_point)
        normal = np.where(
            on_main[:, None],
            np.stack([c, s, np.zeros_like(c)], -1),
            np.stack([np.zeros_like(c), c, s], -1),
        )
        inside_branch = (point[:, 0] > 0) & (point[:, 1] ** 2 + (point[:, 2] - z_c) ** 2 < small**2)
        inside_main = point[:, 0] ** 2 + point[:, 1] ** 2 < big**2
        accept = np.where(on_main, ~inside_branch, ~inside_main)
        kept = np.concatenate([kept, point[accept]])
        normals = np.concatenate([normals, normal[accept]])
    kept, normals = kept[:n], normals[:n]

    def seam(phi: np.ndarray) -> np.ndarray:
        c, s = np.cos(phi), np.sin(phi)
        return np.stack([np.sqrt(big**2 - (small * c) ** 2), small * c, z_c + small * s], -1)

    def distance(x: np.ndarray) -> np.ndarray:
        x = query(x)
        rho = np.hypot(x[:, 0], x[:, 1])
        main = wall_distance(rho, x[:, 2], 0.0, length, big)
        azimuth = np.arctan2(x[:, 1], x[:, 0])
        foot_y = big * np.sin(azimuth)
        main_cut = (
            (np.cos(azimuth) > 0.0)
            & (foot_y**2 + (x[:, 2] - z_c) ** 2 < small**2)
            & (x[:, 2] >= 0.0)
            & (x[:, 2] <= length)
        )
        rho_b = np.hypot(x[:, 1], x[:, 2] - z_c)
        branch = wall_distance(rho_b, x[:, 0], -np.inf, x_end, small)
        foot_yb = small * np.cos(np.arctan2(x[:, 2] - z_c, x[:, 1]))
        branch_cut = (x[:, 0] <= x_end) & ((x[:, 0] <= 0.0) | (x[:, 0] ** 2 + foot_yb**2 < big**2))
        # Where a wall's nearest point is cut away, its other candidates but the seam: the
        # far side and the end circles of the main wall, the far end circle of the branch.
        main_alt = np.minimum.reduce(
            [rho + big, np.hypot(rho - big, x[:, 2]), np.hypot(rho - big, x[:, 2] - length)]
        )
        best = np.minimum(
            np.where(main_cut, main_alt, main),
            np.where(branch_cut, np.hypot(rho_b - small, x[:, 0] - x_end), branch),
        )
        # The seam lies on both untrimmed walls (the branch's between x_in and x_end), so it
        # is no nearer than either; measure it only where that bound is below the best.
        bound = np.maximum(main, wall_distance(rho_b, x[:, 0], x_in, x_end, small))
        need = (main_cut | branch_cut) & (bound < best)
        if need.any():
            best[need] = np.minimum(best[need], curve_distance(x[need], seam))
        return best

    area = main_area + _branch_area(big, small, x_end)

    def build(spacing: float | None):
        diagonal = math.sqrt((x_end + big) ** 2 + 4.0 * big**2 + length**2)
        h = _truth.resolve_spacing(spacing, diagonal=diagonal, area=area)
        return _truth.tee_mesh(big, small, length, x_end, h)

    points = add_noise(kept, noise, rng=rng)
    return finish(points, normals, distance, area, build, outliers=outliers, rng=rng)
