"""k-nearest-neighbour queries: one k-d tree wrapper reused by every stage."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from .types import Neighbourhoods

__all__ = [
    "ball_pairs",
    "build_tree",
    "knn",
    "off_plane",
    "query_workers",
    "restrict",
    "spatial_order",
    "step_cosines",
]


def build_tree(points: np.ndarray) -> cKDTree:
    """Build a k-d tree over (N, 3) float64 `points` (unbalanced: quick to build)."""
    return cKDTree(points, balanced_tree=False, compact_nodes=False)


def query_workers() -> int:
    """Threads a k-d tree query runs on: as many as the compiled kernels share their rows
    among (`zeroset._kernels._jit.threads`), so that one setting, ``NUMBA_NUM_THREADS`` or
    ``numba.set_num_threads``, bounds both (a tiled run's workers get their share of the
    cores that way)."""
    from ._kernels._jit import threads

    return threads()


#: Bits per axis of the Morton (Z-order) key: 3 x 21 bits fit in int64.
_MORTON_BITS = 21
#: The 7-bit numbers with two zero bits inserted after each bit (bit b moves to bit 3b).
_SPREAD_7 = np.array(
    [sum(((v >> b) & 1) << (3 * b) for b in range(7)) for v in range(128)], dtype=np.int64
)


def ball_pairs(tree: cKDTree, positions: np.ndarray, radius) -> tuple[np.ndarray, ...]:
    """Every pair of a position (P, 3) and a point of `tree` within `radius` (one, or (P,))
    of it: the position's row (M,) and the point's index (M,), grouped by row, and the
    pairs per row (P,)."""
    members = tree.query_ball_point(positions, radius, workers=query_workers(), return_sorted=False)
    counts = np.fromiter((len(m) for m in members), dtype=np.int64, count=len(members))
    rows = np.repeat(np.arange(len(members)), counts)
    flat = np.fromiter((i for m in members for i in m), dtype=np.int64, count=int(counts.sum()))
    return rows, flat, counts


def step_cosines(step, normals_a, normals_b) -> tuple[np.ndarray, np.ndarray]:
    """Cosines (M,), (M,) between each `step` (M, 3) and the unit normals at its two ends:
    near 0 where the step runs along a tangent plane, near 1 where it crosses it."""
    unit_step = step / np.maximum(np.linalg.norm(step, axis=1), 1e-300)[:, None]
    return (
        np.einsum("ij,ij->i", unit_step, normals_a),
        np.einsum("ij,ij->i", unit_step, normals_b),
    )


def off_plane(cosines) -> np.ndarray:
    """The angle (degrees) of a step from a tangent plane, given its cosine to the plane's
    unit normal (`step_cosines`, either sign): 0 along the plane, 90 straight across it.
    The same-surface tests compare it with their limits: a step within a limit of both
    its ends' planes runs along one surface."""
    return np.degrees(np.arcsin(np.minimum(np.abs(cosines), 1.0)))


def spatial_order(points: np.ndarray) -> np.ndarray:
    """Return a permutation (N,) int64 that puts nearby points next to each other.

    Queries over points in this order touch memory locally; on a million-point scan
    they run two to three times faster than in scan order.

    The order is the Z-order (Morton) curve over the bounding box, cut into 2^21 cells
    per axis, with points in one cell ordered by x, then y, then z. It depends only on the
    points, not on the order they come in: reordered input gives the same sequence of
    points, so seeded samples of rows in that sequence are the same points. Translating
    the cloud or scaling it by a power of two, where that is exact, keeps the order.
    """
    n = points.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    low = points.min(axis=0)
    extent = float((points.max(axis=0) - low).max())
    cells = np.zeros(points.shape, dtype=np.int64)
    if 0.0 < extent < np.inf:  # else the points coincide, or are ordered by coordinates alone
        top = (1 << _MORTON_BITS) - 1
        cells = np.minimum(((points - low) / extent * (top + 1)).astype(np.int64), top)
    key = np.zeros(n, dtype=np.int64)
    for axis in range(3):
        for chunk in range(3):
            bits = _SPREAD_7[(cells[:, axis] >> (7 * chunk)) & 127]
            key |= bits << (21 * chunk + 2 - axis)
    order = np.argsort(key, kind="stable")
    same = key[order[1:]] == key[order[:-1]]
    tied = np.zeros(n, dtype=bool)
    tied[1:] |= same
    tied[:-1] |= same
    if tied.any():
        # Points sharing a cell: order them by their coordinates, not by their rows.
        rows = order[tied]
        order[tied] = rows[np.lexsort((*points[rows].T[::-1], key[rows]))]
    return order.astype(np.int64)


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
    distances, indices = tree.query(points, k=k, workers=query_workers())
    return Neighbourhoods(
        indices=np.ascontiguousarray(indices.reshape(-1, k), dtype=np.int64),
        distances=np.ascontiguousarray(distances.reshape(-1, k), dtype=np.float64),
    )


def restrict(neighbours: Neighbourhoods, keep: np.ndarray) -> Neighbourhoods:
    """Keep the rows where `keep` (N,) is true and renumber; dropped neighbours become -1, inf."""
    if keep.all():
        return neighbours
    new_index = np.full(keep.shape[0], -1, dtype=np.int64)
    new_index[keep] = np.arange(int(keep.sum()))
    indices = new_index[neighbours.indices[keep]]
    distances = np.where(indices >= 0, neighbours.distances[keep], np.inf)
    return Neighbourhoods(indices=indices, distances=distances)
