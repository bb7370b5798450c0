"""Tangent plane of every point: neighbourhood centroid and PCA normal (Hoppe et al. 1992,
§3.2), and the signed distance to the nearest one as a local surface (§3.4)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._kernels.linalg import eigh_rows
from ._kernels.normals import centroid_covariance
from ._validate import as_points, positive, positive_per_row
from .neighbours import build_tree, knn, query_workers
from .surface import Surface
from .types import Frozen, Neighbourhoods, TangentPlanes

__all__ = ["NearestPlanes", "tangent_planes"]


def tangent_planes(
    points,
    *,
    radius: float,
    k_min: int = 10,
    k_max: int = 16,
    neighbours: Neighbourhoods | None = None,
) -> TangentPlanes:
    """Fit a tangent plane to the neighbourhood of every point.

    The neighbourhood of x_i is the up to `k_max` nearest points within `radius` (x_i
    included), widened to the `k_min` nearest where the radius holds fewer: a plane
    through a handful of noisy points tilts at random. Its centroid o_i is the plane's
    origin, and the eigenvector of the smallest eigenvalue of its covariance is the plane's
    normal n_i, not yet oriented.

    Parameters
    ----------
    points : (N, 3) array_like of float
    radius : float or (N,) array_like of float
        Neighbourhood radius rho+delta, in data units, one for all points or one per point.
    k_min, k_max : int
        Smallest and largest neighbourhood, the point included.
    neighbours : Neighbourhoods, optional
        Precomputed nearest neighbours of `points` (at least `k_max` columns are used).

    Returns
    -------
    TangentPlanes
        ``centroids`` (N, 3), ``normals`` (N, 3), ``eigenvalues`` (N, 3) ascending and
        ``neighbour_count`` (N,).

    See Also
    --------
    zeroset.orientation.orient_normals : makes the normals consistent.

    Notes
    -----
    Hoppe et al. 1992, §3.2; thesis §3.2.2, eq. 3.4.

    Examples
    --------
    >>> from zeroset.synthetic import sample_sphere
    >>> planes = tangent_planes(sample_sphere(500, rng=0).points, radius=0.3)
    >>> planes.normals.shape
    (500, 3)
    """
    points = as_points(points)
    radius = positive_per_row(radius, "radius", points.shape[0])
    k_max = positive(k_max, "k_max", integer=True)
    k_min = min(positive(k_min, "k_min", integer=True), k_max)
    if neighbours is None:
        neighbours = knn(points, k_max)
    indices = np.ascontiguousarray(neighbours.indices[:, :k_max])
    distances = np.ascontiguousarray(neighbours.distances[:, :k_max])
    k_min = min(k_min, indices.shape[1])
    row_radius = np.maximum(
        radius, np.where(np.isfinite(distances[:, k_min - 1]), distances[:, k_min - 1], radius)
    )
    centroids, covariances, counts = centroid_covariance(points, indices, distances, row_radius)
    eigenvalues, eigenvectors = eigh_rows(covariances)
    normals = np.ascontiguousarray(eigenvectors[:, :, 0])
    return TangentPlanes(
        centroids=centroids,
        normals=normals,
        eigenvalues=np.maximum(eigenvalues, 0.0),
        neighbour_count=counts,
    )


@dataclass(frozen=True, eq=False)
class NearestPlanes(Frozen, Surface):
    """Hoppe's surface: ``f(p) = (p - o_i) . n_i`` with o_i the centroid nearest to p.

    Flat and only piecewise continuous, it has no curvature to size cells by and nothing to
    project vertices onto.

    Attributes
    ----------
    centres : (M, 3) float64
        The planes' centroids o_i.
    normals : (M, 3) float64
        Their unit normals n_i, oriented once `oriented` has been called.
    """

    #: The nearest plane lies within a radius of a defined value.
    reach = 1.0
    smooth = False

    centres: np.ndarray
    normals: np.ndarray

    @classmethod
    def fit(cls, points, owner, planes: TangentPlanes, parameters, config) -> NearestPlanes:
        """The tangent planes as they are."""
        return cls(centres=planes.centroids, normals=planes.normals)

    def oriented(self, centroids, normals, *, tree=None) -> NearestPlanes:
        """Each plane with the normal of the oriented plane at its centroid."""
        tree = build_tree(centroids) if tree is None else tree
        return NearestPlanes(self.centres, np.asarray(normals)[tree.query(self.centres)[1]])

    def evaluate(self, positions) -> tuple[np.ndarray, np.ndarray]:
        """Distance to the nearest plane, and its normal."""
        positions = as_points(positions, "positions", min_rows=0)
        nearest = self.tree.query(positions, workers=query_workers())[1]
        normals = self.normals[nearest]
        values = np.einsum("ij,ij->i", positions - self.centres[nearest], normals)
        return values, normals

    def curvature_at(self, positions) -> np.ndarray:
        """Zero: a plane is flat."""
        return np.zeros(np.shape(positions)[0])

    def select(self, rows) -> NearestPlanes:
        """The planes of `rows` (a mask or indices)."""
        return NearestPlanes(self.centres[rows], self.normals[rows])

    @classmethod
    def concatenate(cls, parts: list[NearestPlanes]) -> NearestPlanes:
        """One set of planes of several, in order."""
        return cls(
            np.concatenate([p.centres for p in parts]), np.concatenate([p.normals for p in parts])
        )

    def describe(self) -> dict:
        """The surface function's name."""
        return {"surface_function": "nearest tangent plane (Hoppe 1992)"}
