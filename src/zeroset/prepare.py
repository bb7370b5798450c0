"""Preparation of a raw cloud: sub-sampling, cropping, averaging, outliers (thesis 3.2.1, 3.2.8).

The selections return row indices or a mask into the input, so that per-point data
(normals, viewpoints) follow the points.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from . import _lattice
from ._validate import as_vector3, positive
from .errors import InputError, ReconstructionError
from .thresholds import SPLIT_VIEW
from .types import Neighbourhoods

__all__ = [
    "CHUNK_POINTS",
    "Reduction",
    "cell_labels",
    "group_means",
    "group_viewpoints",
    "crop",
    "drop_outliers",
    "random_sample",
    "reduce_chunks",
    "voxel_sample",
]


#: Points per chunk when a cloud is reduced while it is read.
CHUNK_POINTS = 4_000_000

_CELL_LIMIT = 2.0**62  # |coordinate / voxel_size| must stay below this to floor into int64


@dataclass(frozen=True, eq=False)
class Reduction:
    """The rows `reduce_chunks` kept, their per-point columns, and what each step removed.

    Attributes
    ----------
    rows : (M,) int64
        Ascending indices of the kept rows among all rows of the input.
    columns : dict of str to ndarray
        ``points`` (M, 3) float64 and every other per-point column the chunks carried.
    counts : dict of str to int
        ``input_points``, and ``cropped``, ``sampled_out``, ``voxel_merged`` for the steps
        that ran.
    """

    rows: np.ndarray
    columns: dict
    counts: dict


def reduce_chunks(
    chunks: Callable[[], Iterable[dict]],
    *,
    crop_box=None,
    sample: float | None = None,
    voxel_size: float | None = None,
    seed=0,
) -> Reduction:
    """Crop, randomly sample and voxel-sample a cloud that arrives in chunks.

    The result does not depend on how the rows are cut into chunks, so a file read a few
    million points at a time gives the same points as the whole cloud in memory, which is
    how `zeroset.reconstruct` prepares its input.

    - Crop keeps the points inside the box ``crop_box = (xmin, ymin, zmin, xmax, ymax, zmax)``.
    - Sampling draws one uniform number per input row from ``default_rng(seed)``, in row
      order, and keeps the rows whose number is below `sample`, so about ``sample * N`` rows.
    - Voxel sampling keeps, in every occupied cell of the lattice ``voxel_size * (i, j, k)``,
      the point nearest to the cell's centroid (the lowest row on a tie). It reads the chunks
      twice: once for the centroids, once to choose.

    Parameters
    ----------
    chunks : callable
        Returns a new iterable of dicts ``{name: (n, ...) array or None}`` with at least
        ``points`` (n, 3); every call must give the same rows in the same order.
    crop_box : sequence of 6 floats, optional
    sample : float, optional
        Share of rows to keep, in (0, 1].
    voxel_size : float, optional
        Cell edge length in data units.
    seed : int or None
        Seed of the sampling.

    Returns
    -------
    Reduction

    Raises
    ------
    InputError
        If a chunk's points are not finite, an option is out of range, or the cells of
        `voxel_size` are too small for the cloud's extent.
    """
    if sample is not None:
        _check_fraction(sample)
    if crop_box is not None:
        crop_box = (as_vector3(crop_box[:3], "crop box"), as_vector3(crop_box[3:], "crop box"))
    voxel_size = None if voxel_size is None else positive(voxel_size, "voxel_size")

    def selected():
        """Yield (first row, chunk, rows inside the crop, rows kept by crop and sample)."""
        rng, start = np.random.default_rng(seed), 0
        for chunk in chunks():
            points = chunk["points"]
            _check_finite(points, start)
            inside = np.ones(len(points), dtype=bool)
            if crop_box is not None:
                inside = crop(points, *crop_box)
            keep = inside if sample is None else inside & (rng.random(len(points)) < sample)
            yield start, chunk, inside, keep
            start += len(points)

    counts = {"input_points": 0}
    if crop_box is not None:
        counts["cropped"] = 0
    if sample is not None:
        counts["sampled_out"] = 0
    if voxel_size is None:
        kept = []
        for start, chunk, inside, keep in selected():
            _count(counts, inside, keep)
            kept.append((start + np.flatnonzero(keep), _rows_of(chunk, keep)))
        if not kept:
            return Reduction(np.zeros(0, np.int64), {"points": np.zeros((0, 3))}, counts)
        rows = np.concatenate([r for r, _ in kept])
        columns = {name: np.concatenate([c[name] for _, c in kept]) for name in kept[0][1]}
        return Reduction(rows=rows, columns=columns, counts=counts)
    cells = _VoxelCells(voxel_size)
    for _, chunk, inside, keep in selected():
        _count(counts, inside, keep)
        cells.add(chunk["points"][keep])
    best = _VoxelChoice(cells)
    for start, chunk, _, keep in selected():
        best.offer(start + np.flatnonzero(keep), _rows_of(chunk, keep))
    rows, columns = best.result()
    counts["voxel_merged"] = (
        counts["input_points"]
        - sum(counts.get(name, 0) for name in ("cropped", "sampled_out"))
        - rows.size
    )
    return Reduction(rows=rows, columns=columns, counts=counts)


def random_sample(n_points: int, fraction: float, *, seed=None) -> np.ndarray:
    """Choose each of `n_points` rows with probability `fraction`, as `reduce_chunks` does.

    Parameters
    ----------
    n_points : int
    fraction : float
        Share of rows to keep, in (0, 1].
    seed : int or None
        The same seed gives the same rows.

    Returns
    -------
    (M,) int64
        Ascending row indices, ``M`` about ``fraction * n_points``.
    """
    _check_fraction(fraction)
    return np.flatnonzero(np.random.default_rng(seed).random(n_points) < fraction)


def _check_fraction(fraction: float) -> None:
    """Reject a sampling fraction outside (0, 1]."""
    if not 0.0 < fraction <= 1.0:
        raise InputError(f"sample fraction must lie in (0, 1]; got {fraction!r}")


def voxel_sample(points: np.ndarray, voxel_size: float) -> np.ndarray:
    """Keep one point per occupied voxel: the one nearest to the voxel's centroid.

    Parameters
    ----------
    points : (N, 3) float64
    voxel_size : float
        Voxel edge length in data units; voxels are the cells of the lattice
        ``voxel_size * (i, j, k)``.

    Returns
    -------
    (M,) int64
        Ascending row indices, one per occupied voxel.
    """
    return reduce_chunks(lambda: [{"points": points}], voxel_size=voxel_size).rows


def _check_finite(points: np.ndarray, start: int) -> None:
    """Reject a chunk whose points hold NaN or inf, naming the first such row."""
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        raise InputError(
            f"points contain non-finite values in {int(bad.sum())} rows (first at row "
            f"{start + int(np.argmax(bad))}); drop or impute them first"
        )


def _count(counts: dict, inside: np.ndarray, keep: np.ndarray) -> None:
    """Add one chunk's rows to the input, cropped and sampled-out counts."""
    counts["input_points"] += len(inside)
    if "cropped" in counts:
        counts["cropped"] += len(inside) - int(np.count_nonzero(inside))
    if "sampled_out" in counts:
        counts["sampled_out"] += int(np.count_nonzero(inside)) - int(np.count_nonzero(keep))


def _rows_of(chunk: dict, keep: np.ndarray) -> dict:
    """The kept rows of every per-point column of a chunk (None columns dropped)."""
    return {name: values[keep] for name, values in chunk.items() if values is not None}


class _VoxelCells:
    """Running per-cell point counts and sums, offsets from each cell's lower corner."""

    def __init__(self, voxel_size: float) -> None:
        self.size = voxel_size
        self.anchor: np.ndarray | None = None
        self.keys = np.zeros(0, dtype=np.int64)
        self.sums = np.zeros((0, 3))
        self.counts = np.zeros(0, dtype=np.int64)

    def locate(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(n,) int64 cell keys and (n, 3) offsets of `points` from their cell's corner."""
        scaled = points / self.size
        if np.abs(scaled).max(initial=0.0) >= _CELL_LIMIT:
            raise InputError(f"voxel_size {self.size:g} is too small for coordinates this large")
        cells = np.floor(scaled).astype(np.int64)
        if self.anchor is None and len(cells):
            self.anchor = cells[0]
        try:
            keys = _lattice.encode(cells - self.anchor) if len(cells) else self.keys[:0]
        except ReconstructionError:
            raise InputError(
                f"voxel_size {self.size:g} is too small for the cloud's extent: more than "
                f"{2 * _lattice.LIMIT} voxels along one axis"
            ) from None
        return keys, points - cells * self.size

    def add(self, points: np.ndarray) -> None:
        """Count `points` into their cells."""
        keys, offsets = self.locate(points)
        keys = np.concatenate([self.keys, keys])
        offsets = np.concatenate([self.sums, offsets])
        counts = np.concatenate([self.counts, np.ones(len(points), dtype=np.int64)])
        self.keys, label = np.unique(keys, return_inverse=True)
        self.counts = np.bincount(label, weights=counts).astype(np.int64)
        self.sums = np.stack([np.bincount(label, weights=offsets[:, d]) for d in range(3)], axis=1)


class _VoxelChoice:
    """Running choice, per cell, of the row nearest to the cell's centroid."""

    def __init__(self, cells: _VoxelCells) -> None:
        self.cells = cells
        self.centroids = cells.sums / cells.counts[:, None]
        self.spread = np.full(len(cells.keys), np.inf)
        self.rows = np.full(len(cells.keys), -1, dtype=np.int64)
        self.columns: dict[str, np.ndarray] = {}

    def offer(self, rows: np.ndarray, columns: dict) -> None:
        """Let the chunk's kept `rows` (with their `columns`) replace cells' current choice."""
        if not len(rows):
            return
        keys, offsets = self.cells.locate(columns["points"])
        order = np.argsort(keys, kind="stable")  # by cell, then by row
        keys, offsets = keys[order], offsets[order]
        starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
        sizes = np.diff(np.r_[starts, len(keys)])
        cell = np.searchsorted(self.cells.keys, keys[starts])
        delta = offsets - np.repeat(self.centroids[cell], sizes, axis=0)
        spread = np.einsum("ij,ij->i", delta, delta)
        nearest = np.flatnonzero(spread == np.repeat(np.minimum.reduceat(spread, starts), sizes))
        group = np.repeat(np.arange(len(starts)), sizes)[nearest]
        first = nearest[np.r_[True, group[1:] != group[:-1]]]  # the lowest row of each cell
        better = spread[first] < self.spread[cell]
        target, chosen = cell[better], order[first[better]]
        self.spread[target], self.rows[target] = spread[first[better]], rows[chosen]
        for name, values in columns.items():
            if name not in self.columns:
                self.columns[name] = np.zeros((len(self.rows), *values.shape[1:]), values.dtype)
            self.columns[name][target] = values[chosen]

    def result(self) -> tuple[np.ndarray, dict]:
        """Chosen rows in ascending order, and their columns."""
        order = np.argsort(self.rows, kind="stable")
        return self.rows[order], {name: c[order] for name, c in self.columns.items()}


def cell_labels(points: np.ndarray, cell_size: float) -> np.ndarray:
    """(N,) int64 cubic cell of every point, numbered 0, 1, ... in cell order.

    Cells lie on the lattice ``cell_size * (i, j, k)``; `cell_size` is in data units.
    """
    cell_size = positive(cell_size, "cell_size")
    cells = np.floor(points / cell_size).astype(np.int64)
    return np.unique(_row_keys(cells), return_inverse=True)[1].reshape(-1)


def group_means(
    points: np.ndarray, labels: np.ndarray, *others: np.ndarray
) -> tuple[np.ndarray, ...]:
    """Replace the points of each group by their mean, keeping the group's spread.

    Averaging evens out the density (one point per group, however many the scanner put
    there) and the noise (the mean of m points scatters sqrt(m) times less).

    On a curved surface the mean of a group lies off the surface by half the curvature
    times the group's spread; a fit that knows the spread can take it out (`zeroset.jets`).

    Parameters
    ----------
    points : (N, 3) float64
    labels : (N,) int64
        Group of every point, numbered 0 .. M-1 with every number used
        (`cell_labels` makes such labels).
    *others : (N, ...) float64
        Per-point arrays (e.g. viewpoints) to average the same way.

    Returns
    -------
    tuple of arrays
        The (M, 3) group means of `points`, the (M,) float64 point counts, the (M, 3, 3)
        covariance of each group (in squared data units), then the means of each of
        `others`.
    """
    total = np.bincount(labels).astype(np.float64)

    def mean(values):
        return np.bincount(labels, weights=values) / total

    means = np.stack([mean(points[:, d]) for d in range(3)], axis=1)
    x = points - means[labels]
    spread = np.empty((total.size, 3, 3))
    for a in range(3):
        for b in range(a, 3):
            spread[:, a, b] = spread[:, b, a] = mean(x[:, a] * x[:, b])
    averaged = (
        np.stack([mean(array[:, d]) for d in range(array.shape[1])], axis=1) for array in others
    )
    return (means, total, spread, *averaged)


def _row_keys(cells: np.ndarray):
    """(N,) keys of (N, 3) int64 rows that sort as the rows do, lexicographically.

    Rows packed into one int64 (mixed radix over their bounding box) sort ten times faster
    than ``np.unique(axis=0)`` sorts rows; rows spanning more than 2**62 values fall back to
    a structured view, which sorts the same way.
    """
    if not len(cells):
        return np.zeros(0, dtype=np.int64)
    low = cells.min(axis=0)
    span = cells.max(axis=0) - low + 1
    if float(np.prod(span.astype(np.float64))) >= 2.0**62:
        return np.ascontiguousarray(cells).view([("i", "<i8"), ("j", "<i8"), ("k", "<i8")])[:, 0]
    shifted = cells - low
    return (shifted[:, 0] * span[1] + shifted[:, 1]) * span[2] + shifted[:, 2]


def crop(points: np.ndarray, lower, upper) -> np.ndarray:
    """Return the (N,) bool mask of points inside the axis-aligned box [lower, upper]."""
    lower, upper = as_vector3(lower, "crop lower corner"), as_vector3(upper, "crop upper corner")
    if np.any(lower > upper):
        raise InputError(f"crop box corners must satisfy lower <= upper; got {lower} and {upper}")
    return np.all((points >= lower) & (points <= upper), axis=1)


def drop_outliers(neighbours: Neighbourhoods, radius, min_neighbours: int) -> np.ndarray:
    """Return the (N,) bool mask of points with at least `min_neighbours` others within `radius`.

    A point far from all others is an outlier (thesis 3.2.1; Hoppe et al. 1992, §3).
    `radius` is one float for all points or (N,) floats, one per point.
    `neighbours` must have more than `min_neighbours` columns.
    """
    others = neighbours.distances[:, 1:]
    radius = np.asarray(radius, dtype=np.float64).reshape(-1, 1)
    return np.count_nonzero(others <= radius, axis=1) >= min_neighbours


def group_viewpoints(points: np.ndarray, viewpoints: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """One sensor (M, 3) for each group of points: at the group's mean range from its mean
    point, along the mean of its points' unit directions to their sensors.

    The mean of the sensors' positions can lie anywhere between them: two sensors on either
    side of a wall put it in the wall, at a range that neither measured. The mean direction
    faces where the sensors looked from, and the mean range is the one the range noise grows
    with. A group whose mean direction is shorter than ``SPLIT_VIEW`` (seen from opposite
    sides) or none of whose sensors is known gets a row of NaN: its normals follow the tree.

    Parameters
    ----------
    points : (N, 3) float64
    viewpoints : (N, 3) float64
        Each point's sensor; a row of NaN where it is not known.
    labels : (N,) int64
        Group of every point, 0 .. M-1 with every number used (`cell_labels`).
    """
    towards = viewpoints - points
    ranges = np.linalg.norm(towards, axis=1)
    known = np.isfinite(ranges) & (ranges > 0.0)
    directions = np.where(known[:, None], towards / np.where(known, ranges, 1.0)[:, None], 0.0)
    count = np.bincount(labels, weights=known.astype(np.float64))
    seen = np.maximum(count, 1.0)

    def mean(values):
        return np.bincount(labels, weights=values) / seen

    direction = np.stack([mean(directions[:, d]) for d in range(3)], axis=1)
    length = np.linalg.norm(direction, axis=1)
    centre = np.stack([mean(np.where(known, points[:, d], 0.0)) for d in range(3)], axis=1)
    reach = mean(np.where(known, ranges, 0.0))
    sensors = centre + direction * (reach / np.maximum(length, 1e-300))[:, None]
    sensors[(count == 0) | (length < SPLIT_VIEW)] = np.nan
    return sensors
