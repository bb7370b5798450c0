"""Automatic choice of the scale parameters rho+delta and the cube size (thesis 3.2.8)."""

from __future__ import annotations

import numpy as np

from ._validate import positive, require_rng
from .density import plane_variance, sector_radius
from .errors import InputError, ReconstructionError
from .jets import quadric_noise
from .neighbours import build_tree, query_workers
from .thresholds import NOISE_K, SECTORS, SECTORS_NEEDED, SPACING_K, WIDE_ROWS
from .types import Parameters

__all__ = ["estimate_parameters", "neighbours_read"]


def neighbours_read(k: int = 12) -> int:
    """How many nearest points of each measured point `estimate_parameters` reads."""
    return max(k + 1, SPACING_K, NOISE_K)


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
    averaging_cell: float | None = None,
    min_neighbours: int = 4,
    max_samples: int = 20_000,
    rows=None,
    rng=None,
) -> Parameters:
    """Choose rho+delta, the cube size and the cell the points are averaged in.

    rho (sampling density) must be large enough that a ball of that radius reaches
    neighbours on every side of a point. Two measures are taken on a seeded sample of
    points and the larger `quantile` wins: the distance to the `k`-th nearest neighbour
    (isotropic sampling), and the radius that reaches a neighbour in 6 of 8 directions
    around the point in its tangent plane (laser scans: points a millimetre apart along a
    scan line and centimetres apart between lines). delta (noise) is `noise_factor` times
    the noise level sigma, the median RMS distance of neighbourhoods of radius rho+delta
    from their best-fit plane. The cube size is `cube_factor` (rho+delta). Where a ball of
    radius rho+delta holds far more points than a plane fit needs (dense, noisy or
    anisotropic scans), points are averaged in cubic cells first; `averaging_cell` is the
    cell size (0: no averaging).

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
    rho_delta, cube_size, averaging_cell : float, optional
        Given values, used as they are.
    min_neighbours : int
        Outlier threshold: fewer other points within rho+delta make a point an outlier.
    max_samples : int
        Points whose neighbourhoods are measured (a seeded random subset).
    rows : (S,) array_like of int, optional
        Those points, instead of a random subset (the first `max_samples`); their nearest
        ``neighbours_read(k)`` must be among `points`.
    rng : numpy.random.Generator or int or None

    Returns
    -------
    Parameters
        ``rho_delta``, ``cube_size``, ``min_neighbours``, ``spacing``, ``noise``,
        ``quadric_noise``, ``averaging_cell`` and a note on each.

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
    # A seeded random order: the first rows of it are spread over the whole cloud.
    if rows is None:
        rows = require_rng(rng).permutation(n)
    rows = np.asarray(rows, dtype=np.int64)[:max_samples]
    kk = min(k + 1, n)
    distances, indices = tree.query(points[rows], k=kk, workers=query_workers())
    kth = distances[:, -1]
    wide_distances, wide_indices = tree.query(
        points[rows[:WIDE_ROWS]], k=min(SPACING_K, n), workers=query_workers()
    )
    isotropic = float(np.quantile(kth, quantile))
    # A direction with no neighbour among the SPACING_K counts as the farthest one.
    balanced = np.minimum(
        sector_radius(points, wide_indices, wide_distances), wide_distances[:, -1]
    )
    balanced = float(np.quantile(balanced, quantile))
    spacing = max(isotropic, balanced)
    noise = float(np.sqrt(np.median(plane_variance(points, indices, distances, np.inf))))
    if noise_factor > 0.0:
        # Small neighbourhoods absorb noise into the plane fit and underestimate it; widen
        # the neighbourhood to the radius the noise calls for until the estimate settles.
        for _ in range(4):
            radius = spacing + noise_factor * noise
            wider = plane_variance(points, wide_indices, wide_distances, radius)
            wider = float(np.sqrt(np.median(wider)))
            settled = wider <= 1.05 * noise
            noise = max(noise, wider)
            if settled:
                break
    notes = [
        f"spacing = {spacing:.6g}: {quantile:g} quantile of the larger of the distance to the "
        f"{kk - 1}-th neighbour ({isotropic:.6g}) and the radius reaching neighbours in "
        f"{SECTORS_NEEDED} of {SECTORS} directions ({balanced:.6g})",
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
    fine = quadric_noise(points, rows[:WIDE_ROWS], rho_delta, tree=tree)
    notes.append(
        f"quadric_noise = {fine:.6g}: median RMS residual of quadric fits of radius rho_delta, "
        "over the share of the noise they leave"
    )
    if cube_size is None:
        cube_size = cube_factor * rho_delta
        notes.append(f"cube_size = {cube_size:.6g}: {cube_factor:g} x rho_delta")
    else:
        cube_size = positive(cube_size, "cube_size")
        notes.append(f"cube_size = {cube_size:.6g}: given")
    if averaging_cell is None:
        # A ball of radius rho+delta meets about pi (rho+delta / cell)^2 cells of a surface.
        wanted = 1.5 * k_max
        averaging_cell = rho_delta * float(np.sqrt(np.pi / wanted))
        notes.append(
            f"averaging_cell = {averaging_cell:.6g}: rho_delta x sqrt(pi / {wanted:g}), so that a "
            f"ball of radius rho_delta meets ~{wanted:g} cells"
        )
    else:
        averaging_cell = float(averaging_cell)
        if not averaging_cell >= 0.0:
            raise InputError(f"averaging_cell must be >= 0; got {averaging_cell!r}")
        notes.append(f"averaging_cell = {averaging_cell:.6g}: given")
    notes.append(f"min_neighbours = {min_neighbours}: fewer others within its radius is an outlier")
    return Parameters(
        rho_delta=rho_delta,
        cube_size=cube_size,
        min_neighbours=min_neighbours,
        spacing=spacing,
        noise=noise,
        quadric_noise=fine,
        averaging_cell=averaging_cell,
        notes=tuple(notes),
    )
