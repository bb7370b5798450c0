"""Distances between points and meshes, for tests, reports and benchmarks."""

from __future__ import annotations

import numpy as np

from ._validate import as_points
from .neighbours import build_tree
from .types import Mesh

__all__ = ["closest_points_on_triangles", "points_to_mesh_distance"]


def closest_points_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray):
    """Return the closest point (N, 3) on triangle (a_i, b_i, c_i) to each p_i.

    All inputs are (N, 3) float64. Vectorised form of the region test in Ericson,
    *Real-Time Collision Detection* (2005), §5.1.5: the closest point is a vertex, a point
    on an edge, or the projection into the interior, decided by barycentric signs.
    """
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    bp, cp = p - b, p - c
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = va + vb + vc
        v_in, w_in = vb / denom, vc / denom
        t_ab = d1 / (d1 - d3)
        t_ac = d2 / (d2 - d6)
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    result = a + v_in[:, None] * ab + w_in[:, None] * ac
    # Apply the regions from the most general to the most specific, so the last match wins.
    for mask, point in (
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), b + t_bc[:, None] * (c - b)),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), a + t_ac[:, None] * ac),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), a + t_ab[:, None] * ab),
        ((d6 >= 0) & (d5 <= d6), c),
        ((d3 >= 0) & (d4 <= d3), b),
        ((d1 <= 0) & (d2 <= 0), a),
    ):
        result = np.where(mask[:, None], point, result)
    return result


def points_to_mesh_distance(points, mesh: Mesh, *, candidates: int = 16) -> np.ndarray:
    """Return the distance (N,) from each point to the nearest of its candidate triangles.

    The candidates are the `candidates` triangles whose centroids are nearest to the point;
    on meshes of even triangles (as contouring makes) the nearest triangle is among them.

    Parameters
    ----------
    points : (N, 3) array_like of float
    mesh : Mesh
    candidates : int

    Returns
    -------
    (N,) float64
    """
    points = as_points(points)
    triangles = mesh.vertices[mesh.faces]
    k = min(candidates, mesh.n_faces)
    _, nearest = build_tree(triangles.mean(axis=1)).query(points, k=k, workers=-1)
    nearest = nearest.reshape(points.shape[0], k)
    best = np.full(points.shape[0], np.inf)
    for column in range(k):
        tri = triangles[nearest[:, column]]
        foot = closest_points_on_triangles(points, tri[:, 0], tri[:, 1], tri[:, 2])
        best = np.minimum(best, np.linalg.norm(points - foot, axis=1))
    return best


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.einsum("ij,ij->i", u, v)
