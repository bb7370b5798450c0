"""Local sampling density: the neighbourhood radius each point needs (laser scans).

A rotating laser scanner samples unevenly: points lie millimetres apart along a scan line
and centimetres apart between lines, and both spacings grow with range. One radius for the
whole cloud is either too small where the scan is sparse (the surface tears) or too large
where it is dense. Each point instead gets the radius that reaches neighbours on most sides
of it, never less than the cloud's rho+delta (`point_radii`), with a noise margin that grows
with range where the sensor positions are known (`range_noise`). Gaps between well-sampled
bands, which no point's own neighbourhood sees, are crossed by chords (`gap_bridges`).
"""

from __future__ import annotations

import numpy as np

from ._kernels.density import sector_nearest
from ._kernels.linalg import eigh_rows
from ._kernels.normals import centroid_covariance
from .neighbours import build_tree, off_plane, query_workers, step_cosines
from .thresholds import (
    ALONG,
    BRIDGE_LENGTH,
    BRIDGE_STEP,
    CROSSING,
    EDGE_K,
    RADIUS_CAP,
    RANGE_BINS,
    SECTORS,
    SECTORS_NEEDED,
    SMOOTH_K,
)

__all__ = [
    "gap_bridges",
    "local_spacing",
    "point_radii",
    "range_noise",
    "sector_distances",
    "sector_radius",
]


def sector_distances(points, indices, distances) -> tuple[np.ndarray, np.ndarray]:
    """Nearest neighbour in each of SECTORS directions around each row.

    Directions are angular sectors in the plane of the neighbourhood's two largest principal
    axes.

    Parameters
    ----------
    points : (N, 3) float64
    indices : (R, k) int64
        Nearest neighbours of R points, each row's point first; -1 for none.
    distances : (R, k) float64
        Their distances, ascending; inf for none.

    Returns
    -------
    distance : (R, SECTORS) float64
        Distance to the nearest neighbour in each direction; inf where there is none.
    column : (R, SECTORS) int64
        Its column in `indices`; -1 where there is none.
    """
    distances = np.ascontiguousarray(distances, dtype=np.float64)
    valid = np.isfinite(distances)
    indices = np.ascontiguousarray(indices, dtype=np.int64)
    if not valid.all():
        indices = np.where(valid, indices, -1)
    n_rows = indices.shape[0]
    _, covariances, _ = centroid_covariance(points, indices, distances, np.full(n_rows, np.inf))
    axes = eigh_rows(covariances)[1]
    return sector_nearest(
        points,
        indices,
        distances,
        np.ascontiguousarray(axes[:, :, 2]),
        np.ascontiguousarray(axes[:, :, 1]),
        SECTORS,
    )


def sector_radius(points, indices, distances, needed: int = SECTORS_NEEDED) -> np.ndarray:
    """Radius (R,) reaching neighbours in `needed` of SECTORS directions around each row.

    Directions are angular sectors in the plane of the neighbourhood's two largest principal
    axes. The radius is inf where fewer sectors hold one of the row's neighbours: the point
    lies on a boundary, or its neighbourhood is too small to tell.

    Parameters
    ----------
    points : (N, 3) float64
    indices : (R, k) int64
        Nearest neighbours of R points, each row's point first.
    distances : (R, k) float64
        Their distances, ascending; inf for none.
    needed : int
        Directions that must hold a neighbour, at most SECTORS.
    """
    distance, _ = sector_distances(points, indices, distances)
    return np.sort(distance, axis=1)[:, needed - 1]


def point_radii(spacing, *, rho_delta: float, margin) -> np.ndarray:
    """Neighbourhood radius (N,) of every point: the spacing around it plus the noise margin.

    The radius is the point's spacing (`local_spacing`) plus `margin` (delta), at least
    `rho_delta`; where it would exceed ``RADIUS_CAP rho_delta`` the point keeps `rho_delta`
    (it is an outlier or lies at an edge).

    Parameters
    ----------
    spacing : (N,) float64
        Spacing around each point (`local_spacing`).
    rho_delta : float
        The cloud's radius: the smallest one returned.
    margin : float or (N,) float64
        delta, the noise margin added to the spacing.
    """
    radii = np.asarray(spacing, dtype=np.float64) + margin
    return np.where(radii <= RADIUS_CAP * rho_delta, np.maximum(radii, rho_delta), rho_delta)


def local_spacing(sectors, neighbours) -> np.ndarray:
    """(N,) spacing around every point: the radius reaching neighbours in SECTORS_NEEDED of
    SECTORS directions, smoothed by the median over its SMOOTH_K nearest neighbours.

    `sectors` (N, SECTORS) as `sector_distances` gives; `neighbours` with itself first.
    """
    spacing = np.sort(sectors, axis=1)[:, SECTORS_NEEDED - 1]
    columns = neighbours.indices[:, :SMOOTH_K]
    columns = np.where(columns >= 0, columns, np.arange(columns.shape[0])[:, None])
    return np.median(spacing[columns], axis=1)


def gap_bridges(points, sectors, *, rho_delta: float, tree=None, normals=None) -> np.ndarray:
    """Points (B, 3) along the chords that cross narrow gaps in the sampling.

    A scan's sampling can leave gaps wider than the cloud's radius between well-sampled
    bands (far down a pipe, each ring of beams is smeared by range noise into a band). A
    point at the edge of a band has a direction with no neighbour within rho_delta; where
    the nearest point in that direction lies within ``BRIDGE_LENGTH rho_delta``, the chord
    to it crosses a gap, and points are placed along it every ``BRIDGE_STEP rho_delta``. The signed
    distance counts the surface as defined within ``BRIDGE_REACH rho_delta`` of them.
    Chords are straight: a round hole keeps its centre, which only chords longer than the
    limit cross, so holes wider than about ``BRIDGE_LENGTH rho_delta`` stay open, as do
    open ends (nothing lies beyond). A chord must leave its first point on the side away
    from that point's neighbours (cosine at least ``CROSSING``): it crosses the gap, and
    does not run along the edge of an open end. With `normals`, a chord must also lie
    within ``ALONG`` degrees of both its ends' tangent planes: one across the gap between two
    sheets (two plates, a pipe inside a pipe) runs along neither.

    Parameters
    ----------
    points : (N, 3) float64
    sectors : (N, SECTORS) float64
        Distance to the nearest neighbour in each direction among each point's nearest
        (`sector_distances`); an inf marks an edge point.
    rho_delta : float
    tree : cKDTree, optional
        A tree over `points`, to reuse one already built.
    normals : (N, 3) float64, optional
        Unit normals of `points`, either sign.
    """
    edge = np.flatnonzero(~np.isfinite(sectors).all(axis=1))
    if edge.size == 0:
        return np.zeros((0, 3))
    tree = build_tree(points) if tree is None else tree
    distances, indices = tree.query(
        points[edge],
        k=min(EDGE_K, points.shape[0]),
        distance_upper_bound=BRIDGE_LENGTH * rho_delta,
        workers=query_workers(),
    )
    length, column = sector_distances(points, indices, distances)
    gap = np.isfinite(length) & (length > rho_delta)
    rows, direction = np.nonzero(gap)
    start = points[edge[rows]]
    partner = indices[rows, column[rows, direction]]
    end = points[partner]
    # The side of each edge point away from its neighbours within rho_delta: a chord
    # across a gap leaves that way; one along the edge of the data does not.
    close = distances <= rho_delta
    centre = np.einsum("ij,ijk->ik", close, points[np.where(close, indices, 0)])
    away = points[edge] - centre / close.sum(axis=1)[:, None]
    chord = end - start
    leaves = np.einsum("ij,ij->i", chord, away[rows]) >= CROSSING * np.linalg.norm(
        chord, axis=1
    ) * np.linalg.norm(away[rows], axis=1)
    if normals is not None:
        cos_start, cos_end = step_cosines(chord, normals[edge[rows]], normals[partner])
        leaves &= np.maximum(off_plane(cos_start), off_plane(cos_end)) <= ALONG
    rows, direction, start, end = rows[leaves], direction[leaves], start[leaves], end[leaves]
    # Each chord is cut into `steps` pieces; its steps - 1 inner cut points are bridges.
    steps = np.ceil(length[rows, direction] / (BRIDGE_STEP * rho_delta)).astype(np.int64)
    inner = steps - 1
    chord = np.repeat(np.arange(rows.size), inner)
    first = np.cumsum(inner) - inner
    fraction = (np.arange(chord.size) - first[chord] + 1) / steps[chord]
    return start[chord] + fraction[:, None] * (end[chord] - start[chord])


def plane_variance(points, indices, distances, radius) -> np.ndarray:
    """Mean squared distance (R,) of each neighbourhood from its best-fit plane.

    The neighbourhood of row r is its columns of `indices` within `radius` (one for all
    rows, or one per row). A plane fitted to m points absorbs 3 of their m degrees of
    freedom, so the sum of squares is divided by m - 3.
    """
    n_rows = indices.shape[0]
    _, covariances, counts = centroid_covariance(
        points,
        np.ascontiguousarray(indices, dtype=np.int64),
        np.ascontiguousarray(distances, dtype=np.float64),
        np.broadcast_to(np.asarray(radius, dtype=np.float64), (n_rows,)).copy(),
    )
    smallest = np.linalg.eigvalsh(covariances)[:, 0].clip(min=0.0)
    return smallest * counts / np.maximum(counts - 3, 1)


def range_noise(
    points, neighbours, viewpoints, *, noise: float, model=None
) -> tuple[np.ndarray, tuple]:
    """Noise level (N,) of every point as a straight-line function of its range.

    A laser's noise grows with range. The RMS distance of each point's neighbourhood from
    its best-fit plane is measured, its median taken in RANGE_BINS bins of equal count, and
    ``sigma(r) = a + b r`` fitted to the medians (least squares, b >= 0). No point gets less
    than half the cloud's `noise`.

    Parameters
    ----------
    points : (N, 3) float64
    neighbours : Neighbourhoods
        Nearest neighbours of every point, itself first (the first 16 columns are used).
    viewpoints : (3,) or (N, 3) float64
        Sensor position, one for all or one per point; rows of NaN (sensor not known) get
        the cloud's `noise`, as do all points when fewer than RANGE_BINS have a sensor.
    noise : float
        The cloud's noise level (`Parameters.noise`).
    model : (intercept, slope), optional
        Use this model instead of fitting one (`Parameters.noise_model`).

    Returns
    -------
    sigma : (N,) float64
    model : (a, b)
        Intercept (data units) and slope (per unit of range).
    """
    ranges = np.linalg.norm(points - viewpoints, axis=1)
    known = np.isfinite(ranges)
    if model is None:
        model = _fitted_model(points, neighbours, ranges, known, noise)
    intercept, slope = (float(v) for v in model)
    sigma = np.where(known, np.maximum(intercept + slope * ranges, 0.5 * noise), noise)
    return sigma, (intercept, slope)


def _fitted_model(points, neighbours, ranges, known, noise: float) -> tuple[float, float]:
    """(intercept, slope) of `range_noise`'s line through the binned median residuals;
    (`noise`, 0) where fewer than RANGE_BINS points have a sensor."""
    order = np.argsort(ranges)[: np.count_nonzero(known)]
    if order.size < RANGE_BINS:
        return noise, 0.0
    residual = np.sqrt(
        plane_variance(
            points,
            neighbours.indices[:, :SMOOTH_K],
            neighbours.distances[:, :SMOOTH_K],
            np.inf,
        )
    )
    bins = np.array_split(order, RANGE_BINS)
    centre = np.array([np.median(ranges[b]) for b in bins])
    level = np.array([np.median(residual[b]) for b in bins])
    slope, intercept = np.polyfit(centre, level, 1)
    if slope < 0.0:
        slope, intercept = 0.0, float(np.mean(level))
    return float(intercept), float(slope)
