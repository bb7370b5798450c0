"""Uniform samples of analytic surfaces: cylinder (optionally with a hole), sphere, torus."""

from __future__ import annotations

import math

import numpy as np

from .._validate import as_vector3, positive, require_rng
from ..errors import InputError
from . import _truth
from ._distance import curve_distance, query, wall_distance
from ._sample import Sample, _count, _fraction, _noise, add_noise, finish

__all__ = ["sample_cylinder", "sample_sphere", "sample_torus", "two_spheres"]


def _wrap(angle: np.ndarray) -> np.ndarray:
    """Map angles to [-pi, pi)."""
    return np.mod(angle + np.pi, 2.0 * np.pi) - np.pi


def sample_cylinder(
    n: int,
    *,
    radius: float = 0.25,
    length: float = 1.0,
    noise: float = 0.0,
    hole: tuple[float, float, float] | None = None,
    outliers: float = 0.0,
    rng=None,
) -> Sample:
    """Sample the open side wall of a z-axis cylinder, optionally with a round hole cut out.

    Parameters
    ----------
    n : int
        Points drawn before the hole is cut.
    radius, length : float
        Cylinder radius and length along z (from z = 0), in metres.
    noise : float
        Standard deviation of Gaussian noise per axis.
    hole : (angle, z, hole_radius), optional
        Remove the points whose geodesic distance on the wall to the point at polar angle
        `angle` (radians) and height `z` is below `hole_radius`. The hole must lie inside
        the wall: ``hole_radius < z < length - hole_radius`` and
        ``hole_radius < 0.9 pi radius``.
    outliers : float in [0, 1)
        Share of uniform outliers among the returned points (see `add_outliers`).
    rng : numpy.random.Generator or int or None

    Returns
    -------
    Sample
        ``normals`` point away from the axis; ``truth_mesh`` has two boundary loops (three
        with a hole); ``area`` is ``2 pi radius length`` less the hole's ``pi hole_radius^2``.

    Notes
    -----
    ``distance`` is exact. With a hole, a query whose nearest wall point falls into the
    hole is measured to the nearest of: the hole's rim (a 1-D minimisation, exact to
    rounding), the end circles, and the opposite side of the wall.

    Examples
    --------
    >>> sample_cylinder(1000, noise=0.002, rng=0).points.shape
    (1000, 3)
    """
    n, radius, length = _count(n), positive(radius, "radius"), positive(length, "length")
    noise, outliers = _noise(noise), _fraction(outliers, "outliers")
    if hole is not None:
        angle, z0, hole_radius = (float(v) for v in hole)
        positive(hole_radius, "hole radius")
        if not (hole_radius < z0 < length - hole_radius and hole_radius < 0.9 * np.pi * radius):
            raise InputError(
                "hole must lie inside the wall (hole_radius < z < length - hole_radius and "
                f"hole_radius < 0.9 pi radius); got hole={hole!r}"
            )
    rng = require_rng(rng)
    theta = rng.uniform(0.0, 2.0 * np.pi, n)
    z = rng.uniform(0.0, length, n)
    area = 2.0 * np.pi * radius * length
    if hole is not None:
        arc = radius * _wrap(theta - angle)
        outside = np.hypot(arc, z - z0) >= hole_radius
        theta, z = theta[outside], z[outside]
        area -= np.pi * hole_radius**2
    normals = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=1)
    clean = np.stack([radius * normals[:, 0], radius * normals[:, 1], z], axis=1)

    def distance(x: np.ndarray) -> np.ndarray:
        x = query(x)
        rho = np.hypot(x[:, 0], x[:, 1])
        d = wall_distance(rho, x[:, 2], 0.0, length, radius)
        if hole is None:
            return d
        azimuth = np.arctan2(x[:, 1], x[:, 0])
        foot_in_hole = np.hypot(radius * _wrap(azimuth - angle), x[:, 2] - z0) < hole_radius
        if not foot_in_hole.any():
            return d
        sub = x[foot_in_hole]
        rho, azimuth, z = rho[foot_in_hole], azimuth[foot_in_hole], sub[:, 2]
        other_side_in_hole = np.hypot(radius * _wrap(azimuth + np.pi - angle), z - z0) < hole_radius
        candidates = [
            np.hypot(rho - radius, z),
            np.hypot(rho - radius, z - length),
            np.where(other_side_in_hole, np.inf, rho + radius),
            curve_distance(sub, rim),
        ]
        d[foot_in_hole] = np.minimum.reduce(candidates)
        return d

    def rim(phi: np.ndarray) -> np.ndarray:
        polar = angle + hole_radius * np.cos(phi) / radius
        return np.stack(
            [radius * np.cos(polar), radius * np.sin(polar), z0 + hole_radius * np.sin(phi)],
            axis=-1,
        )

    def build(spacing: float | None):
        diagonal = math.sqrt(8.0 * radius**2 + length**2)
        h = _truth.resolve_spacing(spacing, diagonal=diagonal, area=area)
        if hole is None:
            return _truth.tube_mesh(radius, length, h)[0]

        def rim_distance(alpha: np.ndarray, limit: np.ndarray) -> np.ndarray:
            return np.full_like(alpha, hole_radius)  # a circle in the unrolled wall

        shape = (angle, z0, hole_radius, hole_radius, rim_distance)
        return _truth.tube_mesh(radius, length, h, hole=shape)[0]

    points = add_noise(clean, noise, rng=rng)
    return finish(points, normals, distance, area, build, outliers=outliers, rng=rng)


def sample_sphere(
    n: int,
    *,
    radius: float = 1.0,
    centre=(0.0, 0.0, 0.0),
    noise: float = 0.0,
    outliers: float = 0.0,
    rng=None,
) -> Sample:
    """Sample a sphere uniformly.

    Parameters
    ----------
    n : int
    radius : float
    centre : (3,) array_like of float
    noise : float
        Standard deviation of Gaussian noise per axis.
    outliers : float in [0, 1)
        Share of uniform outliers among the returned points (see `add_outliers`).
    rng : numpy.random.Generator or int or None

    Returns
    -------
    Sample
        Outward normals; ``truth_mesh`` is a geodesic icosahedron (closed); exact distance.

    Examples
    --------
    >>> sample_sphere(500, rng=0).points.shape
    (500, 3)
    """
    n, radius = _count(n), positive(radius, "radius")
    noise, outliers = _noise(noise), _fraction(outliers, "outliers")
    centre = as_vector3(centre, "centre")
    rng = require_rng(rng)
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)

    def distance(x: np.ndarray) -> np.ndarray:
        return np.abs(np.linalg.norm(query(x) - centre, axis=1) - radius)

    area = 4.0 * np.pi * radius**2

    def build(spacing: float | None):
        h = _truth.resolve_spacing(spacing, diagonal=2.0 * math.sqrt(3.0) * radius, area=area)
        return _truth.sphere_mesh(radius, centre, h)

    points = add_noise(centre + radius * normals, noise, rng=rng)
    return finish(points, normals, distance, area, build, outliers=outliers, rng=rng)


def sample_torus(
    n: int,
    *,
    major: float = 1.0,
    minor: float = 0.35,
    noise: float = 0.0,
    outliers: float = 0.0,
    rng=None,
) -> Sample:
    """Sample a z-axis torus uniformly (rejection on the area element R + r cos v).

    Parameters
    ----------
    n : int
    major, minor : float
        Radius of the tube's centre circle and of the tube, ``minor < major``.
    noise : float
        Standard deviation of Gaussian noise per axis.
    outliers : float in [0, 1)
        Share of uniform outliers among the returned points (see `add_outliers`).
    rng : numpy.random.Generator or int or None

    Returns
    -------
    Sample
        Outward normals; ``truth_mesh`` is a closed (u, v) grid; exact distance.
    """
    n, major, minor = _count(n), positive(major, "major"), positive(minor, "minor")
    noise, outliers = _noise(noise), _fraction(outliers, "outliers")
    if minor >= major:
        raise InputError(f"minor must be below major; got minor={minor!r}, major={major!r}")
    rng = require_rng(rng)
    u = np.zeros(0)
    v = np.zeros(0)
    while u.size < n:
        uu = rng.uniform(0.0, 2.0 * np.pi, 2 * n)
        vv = rng.uniform(0.0, 2.0 * np.pi, 2 * n)
        accept = rng.uniform(0.0, major + minor, 2 * n) < major + minor * np.cos(vv)
        u, v = np.concatenate([u, uu[accept]]), np.concatenate([v, vv[accept]])
    u, v = u[:n], v[:n]
    normals = np.stack([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)], axis=1)
    ring = np.stack([major * np.cos(u), major * np.sin(u), np.zeros(n)], axis=1)

    def distance(x: np.ndarray) -> np.ndarray:
        x = query(x)
        return np.abs(np.hypot(np.hypot(x[:, 0], x[:, 1]) - major, x[:, 2]) - minor)

    area = 4.0 * np.pi**2 * major * minor

    def build(spacing: float | None):
        diagonal = 2.0 * math.sqrt(2.0 * (major + minor) ** 2 + minor**2)
        h = _truth.resolve_spacing(spacing, diagonal=diagonal, area=area)
        return _truth.torus_mesh(major, minor, h)

    points = add_noise(ring + minor * normals, noise, rng=rng)
    return finish(points, normals, distance, area, build, outliers=outliers, rng=rng)


def two_spheres(n: int, *, noise: float = 0.0, outliers: float = 0.0, rng=None) -> Sample:
    """Sample two disjoint spheres (radius 1 and 0.6, centres 3 apart) in one cloud.

    The first ``n - n // 3`` points lie on the big sphere at the origin, the rest on the
    small one at (3, 0, 0). The truth mesh is the two geodesic spheres; exact distance.
    """
    n, noise, outliers = _count(n), _noise(noise), _fraction(outliers, "outliers")
    if n < 3:
        raise InputError(f"two_spheres needs n >= 3 (a third on the small sphere); got n={n}")
    rng = require_rng(rng)
    big = sample_sphere(n - n // 3, radius=1.0, noise=noise, rng=rng)
    small = sample_sphere(n // 3, radius=0.6, centre=(3.0, 0.0, 0.0), noise=noise, rng=rng)

    def distance(x: np.ndarray) -> np.ndarray:
        x = query(x)
        return np.minimum(big.distance(x), small.distance(x))

    area = big.area + small.area

    def build(spacing: float | None):
        # One spacing for both, from the pair's bounding box (x from -1 to 3.6).
        h = _truth.resolve_spacing(spacing, diagonal=math.sqrt(4.6**2 + 8.0), area=area)
        return _truth.join(big.truth_mesh(h), small.truth_mesh(h))

    points = np.concatenate([big.points, small.points])
    normals = np.concatenate([big.normals, small.normals])
    return finish(points, normals, distance, area, build, outliers=outliers, rng=rng)
