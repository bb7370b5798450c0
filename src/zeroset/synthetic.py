"""Seeded samples of analytic surfaces with their exact distance functions, for tests and demos."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ._validate import positive, require_rng

__all__ = ["Sample", "add_noise", "sample_cylinder", "sample_sphere", "sample_torus", "two_spheres"]


@dataclass(frozen=True, eq=False)
class Sample:
    """Points on a known surface.

    Attributes
    ----------
    points : (N, 3) float64
        Samples, noise included.
    normals : (N, 3) float64
        Outward unit normals of the true surface at the noise-free samples.
    distance : callable
        ``distance(x)`` maps (M, 3) positions to (M,) unsigned distances to the true surface.
    area : float
        Area of the true surface.
    """

    points: np.ndarray
    normals: np.ndarray
    distance: Callable[[np.ndarray], np.ndarray]
    area: float


def add_noise(points: np.ndarray, sigma: float, *, rng=None) -> np.ndarray:
    """Return `points` (N, 3) plus Gaussian noise of standard deviation `sigma` on each axis."""
    if sigma == 0:
        return points.copy()
    return points + require_rng(rng).normal(0.0, positive(sigma, "sigma"), size=points.shape)


def sample_cylinder(
    n: int,
    *,
    radius: float = 0.25,
    length: float = 1.0,
    noise: float = 0.0,
    hole: tuple[float, float, float] | None = None,
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
        `angle` (radians) and height `z` is below `hole_radius`.
    rng : numpy.random.Generator or int or None

    Returns
    -------
    Sample

    Examples
    --------
    >>> sample_cylinder(1000, noise=0.002, rng=0).points.shape
    (1000, 3)
    """
    rng = require_rng(rng)
    theta = rng.uniform(0.0, 2.0 * np.pi, n)
    z = rng.uniform(0.0, length, n)
    if hole is not None:
        angle, z0, hole_radius = hole
        arc = radius * (np.mod(theta - angle + np.pi, 2.0 * np.pi) - np.pi)
        outside = np.hypot(arc, z - z0) >= hole_radius
        theta, z = theta[outside], z[outside]
    normals = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=1)
    clean = np.stack([radius * normals[:, 0], radius * normals[:, 1], z], axis=1)

    def distance(x: np.ndarray) -> np.ndarray:
        beyond = np.maximum(0.0, np.maximum(x[:, 2] - length, -x[:, 2]))
        return np.hypot(np.hypot(x[:, 0], x[:, 1]) - radius, beyond)

    return Sample(
        add_noise(clean, noise, rng=rng), normals, distance, 2.0 * np.pi * radius * length
    )


def sample_sphere(
    n: int, *, radius: float = 1.0, centre=(0.0, 0.0, 0.0), noise: float = 0.0, rng=None
) -> Sample:
    """Sample a sphere uniformly.

    Examples
    --------
    >>> sample_sphere(500, rng=0).points.shape
    (500, 3)
    """
    rng = require_rng(rng)
    centre = np.asarray(centre, dtype=np.float64)
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)

    def distance(x: np.ndarray) -> np.ndarray:
        return np.abs(np.linalg.norm(x - centre, axis=1) - radius)

    points = add_noise(centre + radius * normals, noise, rng=rng)
    return Sample(points, normals, distance, 4.0 * np.pi * radius**2)


def sample_torus(
    n: int, *, major: float = 1.0, minor: float = 0.35, noise: float = 0.0, rng=None
) -> Sample:
    """Sample a z-axis torus uniformly (rejection on the area element R + r cos v)."""
    rng = require_rng(rng)
    u = np.empty(0)
    v = np.empty(0)
    while u.size < n:
        uu = rng.uniform(0.0, 2.0 * np.pi, 2 * n)
        vv = rng.uniform(0.0, 2.0 * np.pi, 2 * n)
        accept = rng.uniform(0.0, major + minor, 2 * n) < major + minor * np.cos(vv)
        u, v = np.concatenate([u, uu[accept]]), np.concatenate([v, vv[accept]])
    u, v = u[:n], v[:n]
    normals = np.stack([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)], axis=1)
    ring = np.stack([major * np.cos(u), major * np.sin(u), np.zeros(n)], axis=1)

    def distance(x: np.ndarray) -> np.ndarray:
        return np.abs(np.hypot(np.hypot(x[:, 0], x[:, 1]) - major, x[:, 2]) - minor)

    points = add_noise(ring + minor * normals, noise, rng=rng)
    return Sample(points, normals, distance, 4.0 * np.pi**2 * major * minor)


def two_spheres(n: int, *, noise: float = 0.0, rng=None) -> Sample:
    """Sample two disjoint spheres (radius 1 and 0.6, centres 3 apart) in one cloud."""
    rng = require_rng(rng)
    big = sample_sphere(n - n // 3, radius=1.0, noise=noise, rng=rng)
    small = sample_sphere(n // 3, radius=0.6, centre=(3.0, 0.0, 0.0), noise=noise, rng=rng)

    def distance(x: np.ndarray) -> np.ndarray:
        return np.minimum(big.distance(x), small.distance(x))

    return Sample(
        np.concatenate([big.points, small.points]),
        np.concatenate([big.normals, small.normals]),
        distance,
        big.area + small.area,
    )
