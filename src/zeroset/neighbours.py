"""k-nearest-neighbour queries: one k-d tree wrapper reused by every stage."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .types import Neighbourhoods

__all__ = ["build_tree", "knn", "restrict", "spatial_order"]


def build_tree(points: np.ndarray) -> cKDTree:
    """Build a k-d tree over (N, 3) float64 `points` (unbalanced: quick to build)."""
    return cKDTree(points, balanced_tree=False, compact_nodes=False)


def spatial_order(points: np.ndarray) -> np.ndarray:
    """Return a permutation (N,) int64 that puts nearby points next to each other.

    Queries over points in this order touch memory locally; on a million-point scan
    they run two to three times faster than in scan order.
    """
    return np.asarray(build_tree(points).indices, dtype=np.int64)


def knn(points: np.ndarray, k: int, *, tree: cKDTree | None = None) -> Neighbourhoods:
    """Find the `k` nearest points of every point, the point itself first.

    Parameters
    ----------
    points : (N, 3) float64
    k : int
        Neighbours per point including itself; clipped to N.
    tree : cKDTree, optional
        A tree over `points`, to reuse one already built.

    Returns
    -------
    Neighbourhoods
        ``indices`` (N, k) int64 and ``distances`` (N, k) float64.
    """
    tree = build_tree(points) if tree is None else tree
    k = min(k, points.shape[0])
    distances, indices = tree.query(points, k=k, workers=-1)
    return Neighbourhoods(
        indices=np.ascontiguousarray(indices.reshape(-1, k), dtype=np.int64),
        distances=np.ascontiguousarray(distances.reshape(-1, k), dtype=np.float64),
    )


def restrict(neighbours: Neighbourhoods, keep: np.ndarray) -> Neighbourhoods:
    """Keep the rows where `keep` (N,) is true and renumber; dropped neighbours become -1, inf."""
    new_index = np.full(keep.shape[0], -1, dtype=np.int64)
    new_index[keep] = np.arange(int(keep.sum()))
    indices = new_index[neighbours.indices[keep]]
    distances = np.where(indices >= 0, neighbours.distances[keep], np.inf)
    return Neighbourhoods(indices=indices, distances=distances)
