"""Automatic choice of the scale parameters rho+delta and the cube size (thesis 3.2.8)."""

from __future__ import annotations

import numpy as np

from ._kernels.normals import centroid_covariance
from ._validate import positive, require_rng
from .errors import InputError, ReconstructionError
from .neighbours import build_tree
from .types import Parameters

__all__ = ["estimate_parameters"]

#: Points, and neighbours of each, used to measure the noise level.
NOISE_ROWS = 2_000
NOISE_K = 64


def estimate_parameters(
    points: np.ndarray,
    *,
    tree=None,
    k: int = 12,
    quantile: float = 0.9,
    noise_factor: float = 3.0,
    cube_factor: float = 1.5,
    k_max: int = 16,
    rho_delta: float | None = None,
    cube_size: float | None = None,
    phase1_fraction: float | None = None,
    min_neighbours: int = 4,
    max_samples: int = 20_000,
    rng=None,
) -> Parameters:
    """Choose rho+delta, the cube size and the share of points phase 1 needs.

    rho (sampling density) is the `quantile` of the distance from a point to its `k`-th
    nearest neighbour: nine points in ten (by default) have `k` neighbours within it.
    delta (noise) is `noise_factor` times the noise level sigma, the median RMS distance of
    those neighbourhoods from their best-fit plane. rho+delta is their sum, and the cube
    size `cube_factor` times it. Where a ball of radius rho+delta holds far more than
    `k_max` points (noisy, dense scans), a random share of the points is enough for the
    tangent planes; `phase1_fraction` is that share.

    Parameters
    ----------
    points : (N, 3) float64
    tree : cKDTree, optional
        A k-d tree over `points`, to reuse one already built.
    k : int
        Rank of the neighbour whose distance measures the density.
    quantile : float
        Quantile of those distances, in (0, 1]; the thesis found 0.85-0.95 good.
    noise_factor : float
        delta over sigma (3: nearly all noise lies within delta of the surface).
    cube_factor : float
        Cube size over rho+delta when `cube_size` is not given (thesis: 1.5).
    k_max : int
        Largest neighbourhood used for a tangent plane.
    rho_delta, cube_size, phase1_fraction : float, optional
        Given values, used as they are.
    min_neighbours : int
        Outlier threshold: fewer other points within rho+delta make a point an outlier.
    max_samples : int
        Points whose neighbourhoods are measured (a seeded random subset).
    rng : numpy.random.Generator or int or None

    Returns
    -------
    Parameters
        ``rho_delta``, ``cube_size``, ``min_neighbours``, ``spacing``, ``noise``,
        ``phase1_fraction`` and a note on each.

    Raises
    ------
    ReconstructionError
        If the points coincide, so that no radius can be estimated.

    Notes
    -----
    Hoppe et al. 1992, §3: the data are rho-dense and delta-noisy, and neighbourhoods have
    radius rho+delta. Thesis §3.2.8 estimates it from a quantile of sampled neighbour
    distances and sets the cube size to 1.5 (rho+delta).
    """
    if not 0.0 < quantile <= 1.0:
        raise InputError(f"quantile must lie in (0, 1]; got {quantile!r}")
    k = positive(k, "k", integer=True)
    k_max = positive(k_max, "k_max", integer=True)
    noise_factor = float(noise_factor)
    if not noise_factor >= 0.0:
        raise InputError(f"noise_factor must be >= 0; got {noise_factor!r}")
    cube_factor = positive(cube_factor, "cube_factor")
    min_neighbours = positive(min_neighbours, "min_neighbours", integer=True)
    tree = build_tree(points) if tree is None else tree
    n = points.shape[0]
    rows = (
        np.arange(n)
        if n <= max_samples
        else np.sort(require_rng(rng).choice(n, max_samples, replace=False))
    )
    kk = min(k + 1, n)
    distances, indices = tree.query(points[rows], k=kk, workers=-1)
    kth = distances[:, -1]
    spacing = float(np.quantile(kth, quantile))
    noise = _plane_residual(points, indices, distances, np.inf)
    if noise_factor > 0.0:
        # Small neighbourhoods absorb noise into the plane fit and underestimate it; widen
        # the neighbourhood to the radius the noise calls for until the estimate settles.
        wide_distances, wide_indices = tree.query(
            points[rows[:NOISE_ROWS]], k=min(NOISE_K, n), workers=-1
        )
        for _ in range(4):
            radius = spacing + noise_factor * noise
            wider = _plane_residual(points, wide_indices, wide_distances, radius)
            settled = wider <= 1.05 * noise
            noise = max(noise, wider)
            if settled:
                break
    notes = [
        f"spacing = {spacing:.6g}: {quantile:g} quantile of the distance to the "
        f"{kk - 1}-th nearest neighbour (median {np.median(kth):.6g})",
        f"noise = {noise:.6g}: median RMS distance of neighbourhoods of radius "
        f"spacing + {noise_factor:g} x noise from their plane",
    ]
    if rho_delta is None:
        rho_delta = spacing + noise_factor * noise
        if not rho_delta > 0.0:
            raise ReconstructionError(
                f"rho_delta estimated as {rho_delta}: most points have {kk - 1} coincident "
                "neighbours; remove duplicates or pass rho_delta"
            )
        notes.append(f"rho_delta = {rho_delta:.6g}: spacing + {noise_factor:g} x noise")
    else:
        rho_delta = positive(rho_delta, "rho_delta")
        notes.append(f"rho_delta = {rho_delta:.6g}: given")
    if cube_size is None:
        cube_size = cube_factor * rho_delta
        notes.append(f"cube_size = {cube_size:.6g}: {cube_factor:g} x rho_delta")
    else:
        cube_size = positive(cube_size, "cube_size")
        notes.append(f"cube_size = {cube_size:.6g}: given")
    if phase1_fraction is None:
        # A ball of radius r holds about kk (r / median kth)^2 points of a surface.
        expected = kk * (rho_delta / max(float(np.median(kth)), 1e-300)) ** 2
        phase1_fraction = float(min(1.0, 1.5 * k_max / expected))
        notes.append(
            f"phase1_fraction = {phase1_fraction:.3g}: a ball of radius rho_delta holds "
            f"~{expected:.0f} points; tangent planes need ~{1.5 * k_max:.0f}"
        )
    else:
        if not 0.0 < phase1_fraction <= 1.0:
            raise InputError(f"phase1_fraction must lie in (0, 1]; got {phase1_fraction!r}")
        notes.append(f"phase1_fraction = {phase1_fraction:.3g}: given")
    notes.append(f"min_neighbours = {min_neighbours}: fewer others within rho_delta is an outlier")
    return Parameters(
        rho_delta=rho_delta,
        cube_size=cube_size,
        min_neighbours=min_neighbours,
        spacing=spacing,
        noise=noise,
        phase1_fraction=phase1_fraction,
        notes=tuple(notes),
    )


def _plane_residual(points, indices, distances, radius) -> float:
    """Median RMS plane-fit residual of the neighbourhoods: rows of `indices` within `radius`."""
    radius = np.full(indices.shape[0], radius, dtype=np.float64)
    _, covariances, counts = centroid_covariance(
        points, indices.astype(np.int64), distances, radius
    )
    # A plane fitted to m points absorbs 3 of their m degrees of freedom.
    residual = (
        np.linalg.eigvalsh(covariances)[:, 0].clip(min=0.0) * counts / np.maximum(counts - 3, 1)
    )
    return float(np.sqrt(np.median(residual)))
