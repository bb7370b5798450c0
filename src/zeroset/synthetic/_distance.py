"""Exact unsigned distances to pieces of pipes: open walls, circles, trimmed walls, curves."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .._validate import as_points

__all__ = ["circle_distance", "curve_distance", "query", "wall_distance"]

_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def query(x) -> np.ndarray:
    """Validate query positions: (M, 3) float64, finite, possibly empty."""
    return as_points(x, "x", min_rows=0)


def wall_distance(rho: np.ndarray, axial: np.ndarray, lo: float, hi: float, radius: float):
    """Distance (M,) to the open wall of a cylinder, axial extent [lo, hi].

    `rho` and `axial` are the query's distance from the axis and coordinate along it. The
    nearest point of the wall is at the query's own azimuth: at its height when that lies
    within [lo, hi], else on the nearer end circle.
    """
    beyond = np.maximum(0.0, np.maximum(axial - hi, lo - axial))
    return np.hypot(rho - radius, beyond)


def circle_distance(x: np.ndarray, centre, normal, radius: float) -> np.ndarray:
    """Distance (M,) from `x` (M, 3) to the circle of `radius` about `centre` normal to `normal`."""
    w = x - np.asarray(centre, dtype=np.float64)
    normal = np.asarray(normal, dtype=np.float64)
    along = w @ normal
    across = np.linalg.norm(w - along[:, None] * normal, axis=1)
    return np.hypot(along, across - radius)


def curve_distance(
    x: np.ndarray,
    curve: Callable[[np.ndarray], np.ndarray],
    *,
    samples: int = 512,
    chunk: int = 8192,
) -> np.ndarray:
    """Distance (M,) from `x` (M, 3) to the closed curve ``curve(phi)``, phi in [0, 2 pi).

    The curve is sampled at `samples` parameters; around the best sample and the best other
    local minimum the distance is minimised by golden-section search to ~1e-14 in phi, so
    the result is exact to rounding unless a third, separate local minimum comes within the
    sampling error of the two refined ones.
    """
    out = np.zeros(x.shape[0])
    phi = 2.0 * math.pi * np.arange(samples) / samples
    points = curve(phi)
    step = 2.0 * math.pi / samples
    for start in range(0, x.shape[0], chunk):
        part = x[start : start + chunk]
        d2 = (
            np.einsum("ij,ij->i", part, part)[:, None]
            - 2.0 * part @ points.T
            + np.einsum("ij,ij->i", points, points)[None, :]
        )
        best = np.argmin(d2, axis=1)
        local = (d2 <= np.roll(d2, 1, axis=1)) & (d2 <= np.roll(d2, -1, axis=1))
        local[np.arange(part.shape[0]), best] = False
        second = np.argmin(np.where(local, d2, np.inf), axis=1)
        out[start : start + chunk] = np.minimum(
            _golden(part, curve, phi[best] - step, phi[best] + step),
            _golden(part, curve, phi[second] - step, phi[second] + step),
        )
    return out


def _golden(x: np.ndarray, curve, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Minimise |x - curve(phi)| over phi in [lo, hi] per row by golden-section search."""

    def dist(phi):
        return np.linalg.norm(x - curve(phi), axis=1)

    a, b = lo, hi
    for _ in range(70):
        c = b - _GOLDEN * (b - a)
        d = a + _GOLDEN * (b - a)
        left = dist(c) < dist(d)
        a, b = np.where(left, a, c), np.where(left, d, b)
    return np.minimum(dist(0.5 * (a + b)), np.minimum(dist(lo), dist(hi)))
