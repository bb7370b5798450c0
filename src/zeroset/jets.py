"""A smooth surface without curvature bias: blended quadric fits (jets) of adaptive support.

Hoppe's tangent plane passes through the neighbourhood centroid, which lies about r^2/4R
on the concave side of a surface of radius R: every convex surface shrinks. A jet (a
quadric height function over the local PCA frame, Cazals & Pouget 2005) carries the
curvature, so its value at its centre is unbiased to second order. The surface function is
a partition-of-unity blend of the nearest jets (Ohtake et al. 2003), smooth where the
nearest-plane function jumps.

Each jet's support is chosen by a bias-variance rule in the spirit of Mitra & Nguyen
(2003): the variance of a jet's value falls as 1/(points in the support), while its bias,
the quartic term of the surface that a quadric cannot follow, grows as kappa^3 h^4. The
support minimising ``16 bias^2 + variance`` (bias weighted 16 times: a systematic offset is
what an inspection reports as a defect) is

    h^10 = c_v sigma^2 / (beta^2 kappa^6 pi D)

with sigma the noise, D the points per unit area and kappa the largest principal
curvature, all measured by pilot fits. The points in a support grow with density (as
D^0.8), so the error falls as points are added. Jets whose residuals exceed the noise by
far (creases, a second sheet inside the support) are refitted on half the support.

Real objects carry detail that no quadric of the pilots' support follows, and a plane's or
a wide jet's residuals count it as noise. So sigma is measured by jets of support rho+delta
(`quadric_noise`), each residual divided by the share of the noise its fit leaves, and the
pilots are fitted at two supports: noise leaves them the same corrected residual, detail a
residual that grows with the support. Where that growth marks detail well above the noise,
the support shrinks to where the detail's error and the jet's variance balance.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ._kernels.jets import blend_rows, fit_rows
from ._kernels.linalg import eigh_rows
from ._kernels.normals import centroid_covariance
from ._validate import as_points, positive
from .neighbours import build_tree, query_workers
from .prepare import cell_labels, group_means
from .surface import Surface
from .thresholds import (
    BLEND_K,
    CELLS_PER_SUPPORT,
    DETAIL_MARGIN,
    DETAIL_SUPPORT,
    FIT_K,
    JET_BIAS,
    JET_VARIANCE,
    MAX_SUPPORT,
    MIN_CELLS,
    MIN_SUPPORT,
    MISFIT_HALVINGS,
    MISFIT_LIMIT,
    NOISE_K,
    ORIENT_K,
    PILOT_SUPPORT,
    REACH,
    SHEET,
    SHEET_NOISE,
)
from .types import Frozen

#: Coefficients of a jet's quadric, a0 ... a5: the parameters its height is fitted with.
QUADRIC_TERMS = 6

__all__ = [
    "Jets",
    "evaluate_jets",
    "fit_jets",
    "orient_jets",
    "quadric_noise",
]

#: Rows of jets checked at a time for neighbours on another sheet (`SHEET`).
SHEET_CHUNK = 16_384


@dataclass(frozen=True, eq=False)
class Jets(Frozen, Surface):
    """Oriented quadric height fits (jets) whose blend is the surface (`evaluate_jets`).

    Jet j is the height function ``h(u, v) = a0 + a1 u + a2 v + a3 u^2 + a4 u v + a5 v^2``
    plus a quartic over the frame at ``centres[j]`` whose rows are e1, e2 and the normal n:
    a point x has ``u = (x - c) . e1``, ``v = (x - c) . e2`` and height ``w = (x - c) . n``.

    Attributes
    ----------
    centres : (J, 3) float64
        Weighted centroid of each jet's support.
    frames : (J, 3, 3) float64
        Rows e1, e2, n; n is oriented like the tangent planes.
    coefficients : (J, 10) float64
        a0 ... a5, in data units, then the quartic's k1, k2, cos t, sin t
        (`zeroset._kernels.jets.COEFFICIENTS`).
    radii : (J,) float64
        Support radius of each jet, in data units.
    mass : (J,) float64
        Points within each jet's support (their weights summed).
    notes : tuple of str
        How the supports were chosen.
    """

    reach = REACH
    smooth = True

    centres: np.ndarray
    frames: np.ndarray
    coefficients: np.ndarray
    radii: np.ndarray
    mass: np.ndarray
    notes: tuple[str, ...] = field(default=())

    @property
    def curvature(self) -> np.ndarray:
        """(J,) largest absolute principal curvature, in 1 / data units: the largest
        absolute eigenvalue of the Hessian [[2 a3, a4], [a4, 2 a5]]."""
        a3, a4, a5 = self.coefficients[:, 3], self.coefficients[:, 4], self.coefficients[:, 5]
        return np.abs(a3 + a5) + np.sqrt((a3 - a5) ** 2 + a4**2)

    @property
    def support(self) -> float:
        """Median support radius, in data units."""
        return float(np.median(self.radii))

    @classmethod
    def fit(cls, points, owner, planes, parameters, config) -> Jets:
        """`fit_jets` on the points whose cell was kept, with their cells' planes and the
        noise of `zeroset.types.Parameters.quadric_noise`."""
        rows = owner >= 0
        return fit_jets(
            points[rows],
            owner[rows],
            planes.centroids,
            planes.normals,
            noise=parameters.quadric_noise,
            rho_delta=parameters.rho_delta,
            support=config.fit_support,
        )

    def oriented(self, centroids, normals, *, tree=None) -> Jets:
        """`orient_jets`."""
        return orient_jets(self, centroids, normals, tree=tree)

    def evaluate(self, positions) -> tuple[np.ndarray, np.ndarray]:
        """`evaluate_jets`."""
        return evaluate_jets(self, positions)

    def uncertainty(self, noise: float) -> float:
        """The standard error of a jet's height, median over the jets, in data units:
        ``noise sqrt(6 / n)`` for a quadric's six coefficients fitted to n points of noise
        `noise` (the mean leverage of a least-squares fit is its parameters over its
        points, so its heights at the points vary by ``noise^2 6 / n`` on average)."""
        return float(noise) * float(np.sqrt(QUADRIC_TERMS / np.median(self.mass)))

    def curvature_at(self, positions) -> np.ndarray:
        """The curvature of the jet nearest each position (M, 3)."""
        return self.curvature[self.tree.query(positions, workers=query_workers())[1]]

    def select(self, rows) -> Jets:
        """The jets of `rows` (a mask or indices)."""
        return replace(
            self,
            centres=self.centres[rows],
            frames=self.frames[rows],
            coefficients=self.coefficients[rows],
            radii=self.radii[rows],
            mass=self.mass[rows],
        )

    @classmethod
    def concatenate(cls, parts: list[Jets]) -> Jets:
        """One Jets of several, in order; the notes are the first part's."""
        return cls(
            centres=np.concatenate([j.centres for j in parts]),
            frames=np.concatenate([j.frames for j in parts]),
            coefficients=np.concatenate([j.coefficients for j in parts]),
            radii=np.concatenate([j.radii for j in parts]),
            mass=np.concatenate([j.mass for j in parts]),
            notes=parts[0].notes,
        )

    def describe(self) -> dict:
        """How many jets make the surface, their median support and how it was chosen."""
        notes = "; ".join(self.notes)
        return {
            "surface_function": f"blended jets: {self.centres.shape[0]:,} quadric fits, {notes}",
            "jets": self.centres.shape[0],
            "fit_support": self.support,
            "fit_notes": notes,
        }


def fit_jets(
    points,
    owner=None,
    origins=None,
    normals=None,
    *,
    noise: float,
    rho_delta: float,
    support: float | None = None,
) -> Jets:
    """Fit the jets of `points`, averaged in surface cells that a support holds 20-40 of.

    A cubic cell that the noisy shell of points crosses near one of its faces holds only
    one side of the noise, and its mean is off the surface by up to a noise level however
    many points it holds. So points are put in cells by their feet on a surface (first a
    tangent plane, then the pilot fits), which carry no noise across the surface, and
    averaged where they are. Each cell's spread enters the fit, so averaging on a curved
    surface adds no bias either. Cell sizes come from a ladder of factor sqrt(2) on one
    global lattice each, so every jet depends only on the points within ``REACH``
    rho_delta of it (what tiles need to reproduce the untiled surface).

    Parameters
    ----------
    points : (N, 3) array_like of float
        Data points, in data units.
    owner : (N,) array_like of int, optional
        The tangent plane each point belongs to (its cell in phase 1), with the planes'
        `origins` and unit `normals` (M, 3); a point's foot is its projection onto its
        plane. By default every point is its own cell and its foot is itself at first.
    noise : float
        Noise level sigma (`zeroset.types.Parameters.quadric_noise`), in data units.
    rho_delta : float
        Neighbourhood radius; supports lie within [1, 6] rho_delta.
    support : float, optional
        One support radius for every jet instead of the bias-variance rule.

    Returns
    -------
    Jets
        ``centres``, ``frames``, ``coefficients``, ``radii``, ``curvature``, the chosen
        ``support`` (median) and a note on how it was chosen. The normals are not yet
        oriented (`orient_jets`).
    """
    points = as_points(points)
    if owner is None:
        owner, origins = np.arange(points.shape[0]), points
    else:
        owner = np.asarray(owner, dtype=np.int64)
        origins = as_points(origins, "origins")
        normals = as_points(normals, "normals")
    rho_delta = positive(rho_delta, "rho_delta")
    sigma = max(float(noise), 1e-6 * rho_delta)
    pilots, _, _ = _pilot_fits(points, _feet(points, owner, origins, normals), rho_delta)
    # Feet on the pilots' surface: the planes' feet still follow the noise where a plane
    # is tilted, and their cells again hold one side of the shell more than the other,
    # which the pilots' residuals would count as detail. Each plane is replaced by the
    # pilots' tangent plane at its origin, and the pilots are fitted again.
    values, gradients = evaluate_jets(pilots, origins, k=1)
    length = np.maximum(np.linalg.norm(gradients, axis=1), 0.5)
    normals = gradients / length[:, None]
    feet = _feet(points, owner, origins - (values / length)[:, None] * normals, normals)
    pilots, fits, pilot_of = _pilot_fits(
        points, feet, rho_delta, (PILOT_SUPPORT, DETAIL_SUPPORT * PILOT_SUPPORT)
    )
    extent = float(np.ptp(points, axis=0).max())
    pilot_h, note = _supports(pilots, *fits, sigma, rho_delta, extent)
    if support is not None:
        support = positive(support, "support")
        note = f"support = {support:.6g}: given"
        pilot_h = np.full(pilot_h.size, min(support, MAX_SUPPORT * rho_delta))
    pilot_tree = build_tree(pilots.centres)
    pilot_level = _level(_nearest_median(pilot_tree, pilot_h, pilots.centres), rho_delta)
    fits, halved = [], 0
    for level in np.unique(pilot_level):
        # The points that jets of this rung can reach: those of the pilots within the rung's
        # largest support (and two pilot cells) of a pilot on the rung.
        reach = rho_delta * (np.sqrt(2.0) ** (level + 1) + 4.0 * PILOT_SUPPORT)
        on_rung = build_tree(pilots.centres[pilot_level == level])
        used = np.isfinite(
            on_rung.query(pilots.centres, distance_upper_bound=reach, workers=query_workers())[0]
        )
        rows = slice(None) if used.all() else used[pilot_of]
        subset, subset_feet = points[rows], feet[rows]
        cells, counts, spread = group_means(
            subset, cell_labels(subset_feet, _cell(level, rho_delta))
        )
        radius = _nearest_median(pilot_tree, pilot_h, cells)
        rows = np.flatnonzero(_level(radius, rho_delta) == level)
        if rows.size == 0:
            continue
        k = min(FIT_K, cells.shape[0])
        distances, indices = build_tree(cells).query(cells[rows], k=k, workers=query_workers())
        distances, indices = _own_sheet(
            cells[rows],
            cells,
            indices,
            distances,
            pilots,
            pilot_tree,
            max(SHEET * rho_delta, SHEET_NOISE * sigma),
        )
        farthest = np.where(np.isfinite(distances), distances, 0.0).max(axis=1)
        radius = np.minimum(radius[rows], farthest)
        fit = fit_rows(cells, counts, spread, indices, distances, radius, min(MIN_CELLS, k))
        for _ in range(MISFIT_HALVINGS):
            bad = np.flatnonzero(fit[5] > MISFIT_LIMIT * sigma**2)
            bad = bad[fit[3][bad] > MIN_SUPPORT * rho_delta]
            if bad.size == 0:
                break
            halved += bad.size
            smaller = np.maximum(fit[3][bad] / 2.0, MIN_SUPPORT * rho_delta)
            redo = fit_rows(
                cells, counts, spread, indices[bad], distances[bad], smaller, min(MIN_CELLS, k)
            )
            for whole, part in zip(fit, redo, strict=True):
                whole[bad] = part
        fits.append(fit)
    if halved:
        note += (
            f"; {halved} refits on half the support (residuals above {MISFIT_LIMIT:g} x the "
            "noise variance)"
        )
    return _jets(tuple(np.concatenate(parts) for parts in zip(*fits, strict=True)), note)


def quadric_noise(points, rows, radius: float, *, tree=None) -> float:
    """Noise level sigma (data units) left by jets of support `radius` at sample points.

    A plane's residuals hold the surface's curvature; a jet's hold only what a quadric
    cannot follow, and at a small support that is little more than the noise. The jet at
    each point of `points` (N, 3) named by `rows` weighs its neighbours by their distance
    in the neighbourhood's plane, not in space, which would favour those on the point's
    own side of the noise. Each misfit is divided by 1 - freedom, the share of the noise
    the fit leaves, and sigma is the square root of the median.
    """
    tree = build_tree(points) if tree is None else tree
    k = min(NOISE_K, points.shape[0])
    distances, indices = tree.query(points[rows], k=k, workers=query_workers())
    _, covariances, _ = centroid_covariance(
        points, indices, distances, np.full(indices.shape[0], np.inf)
    )
    normals = eigh_rows(covariances)[1][:, :, 0]
    offsets = points[indices] - points[rows][:, None, :]
    across = np.einsum("rkd,rd->rk", offsets, normals)
    along = np.sqrt(np.maximum(np.einsum("rkd,rkd->rk", offsets, offsets) - across**2, 0.0))
    order = np.argsort(along, axis=1)
    along = np.take_along_axis(along, order, axis=1)
    indices = np.take_along_axis(indices, order, axis=1)
    used, local = np.unique(indices, return_inverse=True)
    m = used.size
    fit = fit_rows(
        np.ascontiguousarray(points[used], dtype=np.float64),
        np.ones(m),
        np.zeros((m, 3, 3)),
        local.reshape(indices.shape),
        along,
        np.full(indices.shape[0], float(radius)),
        min(MIN_CELLS, k),
    )
    return float(np.sqrt(np.median(_noise_variance(fit))))


def _noise_variance(fit) -> np.ndarray:
    """(J,) the noise variance the residuals of `fit_rows` output imply: the misfit over
    1 - freedom, the share of the noise each fit leaves (at least 0.1)."""
    return fit[5] / np.maximum(1.0 - fit[6], 0.1)


def _feet(points, owner, origins, normals) -> np.ndarray:
    """(N, 3) every point projected onto the plane of its owner; the points without normals."""
    if normals is None:
        return points
    n = normals[owner]
    return points - np.einsum("ij,ij->i", points - origins[owner], n)[:, None] * n


def _level(support: np.ndarray, rho_delta: float) -> np.ndarray:
    """Rung of the cell ladder for each support: supports in [sqrt(2)^s, sqrt(2)^(s+1)) rho."""
    ratio = np.maximum(support / rho_delta, 1.0)
    return np.floor(2.0 * np.log2(ratio) + 1e-9).astype(np.int64)


def _cell(level: int, rho_delta: float) -> float:
    """Cell size of a rung: the top support of the rung holds CELLS_PER_SUPPORT cells."""
    return float(rho_delta * np.sqrt(2.0) ** (level + 1) * np.sqrt(np.pi / CELLS_PER_SUPPORT))


def _jets(fit, note: str) -> Jets:
    """A Jets of the output of `fit_rows`."""
    centres, frames, coefficients, radii, mass, *_ = fit
    return Jets(
        centres=centres,
        frames=frames,
        coefficients=coefficients,
        radii=radii,
        mass=mass,
        notes=(note,),
    )


def _own_sheet(centres, cells, indices, distances, pilots: Jets, pilot_tree, margin: float):
    """The neighbour `cells` of each of `centres` (R, 3) (`indices`, `distances` (R, K), by
    distance) on its own sheet first, by distance; those on another sheet after them, at an
    infinite distance, so that no fit reaches them.

    A neighbour is on another sheet when it lies further from the tangent plane of the
    pilot nearest the centre than that pilot's curvature bends the surface at its distance,
    plus `margin` (data units): a second wall a few rho+delta away (two plates, the walls of
    a jacketed pipe). A fit that counted it would pass between the two walls; the fewest
    cells a fit takes (`MIN_CELLS`) would otherwise stretch a support across. A centre with
    fewer than `MIN_CELLS` neighbours on its own sheet keeps them all.
    """
    _, pilot = pilot_tree.query(centres, workers=query_workers())
    normal, curvature = pilots.frames[pilot, 2], pilots.curvature[pilot]
    other = np.zeros(indices.shape, dtype=bool)
    for start in range(0, indices.shape[0], SHEET_CHUNK):
        part = slice(start, start + SHEET_CHUNK)
        offset = cells[indices[part]] - centres[part, None, :]
        height = np.abs(np.einsum("rkd,rd->rk", offset, normal[part]))
        along = np.maximum(distances[part] ** 2 - height**2, 0.0)
        other[part] = height > 0.5 * curvature[part, None] * along + margin
    other[(~other).sum(axis=1) < min(MIN_CELLS, indices.shape[1])] = False
    distances = np.where(other, np.inf, distances)
    order = np.argsort(distances, axis=1, kind="stable")
    return np.take_along_axis(distances, order, 1), np.take_along_axis(indices, order, 1)


def _nearest_median(tree, values: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """(M,) median of `values` (P,) over the 8 points of `tree` nearest each position."""
    k = min(8, values.size)
    _, nearest = tree.query(positions, k=k, workers=query_workers())
    return np.median(values[nearest.reshape(-1, k)], axis=1)


def orient_jets(jets: Jets, centroids, normals, *, tree=None) -> Jets:
    """Turn every jet's normal (and height) to agree with the nearest oriented planes.

    The planes vote, ``ORIENT_K`` nearest the jet's centre, each with the cosine between
    its normal and the jet's: one plane turned the wrong way cannot turn a jet, whose
    wrong sign would bend the blend over its whole support.

    Parameters
    ----------
    jets : Jets
    centroids, normals : (M, 3) array_like of float
        Tangent-plane origins and consistently oriented normals
        (`zeroset.orientation.orient_normals`).
    tree : cKDTree, optional
        A tree over `centroids`, to reuse one already built.
    """
    centroids = as_points(centroids, "centroids")
    normals = as_points(normals, "normals")
    k = min(ORIENT_K, centroids.shape[0])
    tree = build_tree(centroids) if tree is None else tree
    _, plane = tree.query(jets.centres, k=k, workers=query_workers())
    plane = plane.reshape(-1, k)
    vote = np.einsum("ij,ikj->i", jets.frames[:, 2], normals[plane])
    sign = np.where(vote < 0.0, -1.0, 1.0)
    frames = jets.frames.copy()
    frames[:, 2] *= sign[:, None]
    return replace(jets, frames=frames, coefficients=jets.coefficients * sign[:, None])


def evaluate_jets(jets: Jets, positions, *, k: int = BLEND_K) -> tuple[np.ndarray, np.ndarray]:
    """Blended signed distance and its gradient at `positions`.

    ``f(p) = sum_j w_j f_j(p) / sum_j w_j`` over the `k` nearest jets, with f_j the
    first-order distance to jet j's quadric, ``(w - h(u, v)) / |(-h_u, -h_v, 1)|``, and
    ``w_j = (1 - (d_j / d_{k+1})^2)^2``, so f is continuous where the set of nearest jets
    changes.

    Parameters
    ----------
    jets : Jets
    positions : (M, 3) array_like of float
    k : int
        Jets blended per position.

    Returns
    -------
    values : (M,) float64
        Signed distance, positive on the side the normals point to, in data units.
    gradients : (M, 3) float64
        Blend of the jets' unit normals at the foot points (the gradient where the weights
        vary slowly).
    """
    positions = as_points(positions, "positions", min_rows=0)
    if positions.shape[0] == 0:
        return np.zeros(0), np.zeros((0, 3))
    kk = min(k + 1, jets.centres.shape[0])
    distances, indices = jets.tree.query(positions, k=kk, workers=query_workers())
    distances, indices = distances.reshape(-1, kk), indices.reshape(-1, kk)
    return blend_rows(positions, indices, distances, jets.centres, jets.frames, jets.coefficients)


def _pilot_fits(points, feet, rho_delta, supports=(PILOT_SUPPORT,)):
    """Pilot jets (P), one per cell of a support of PILOT_SUPPORT rho_delta over `feet`,
    the output of `fit_rows` for them at each of `supports` (in rho_delta), and the pilot
    of every point (N,)."""
    cell = PILOT_SUPPORT * rho_delta * np.sqrt(np.pi / CELLS_PER_SUPPORT)
    pilot_of = cell_labels(feet, cell)
    cells, counts, spread = group_means(points, pilot_of)
    k = min(FIT_K, cells.shape[0])
    distances, indices = build_tree(cells).query(cells, k=k, workers=query_workers())
    fits = [
        fit_rows(
            cells,
            counts,
            spread,
            indices,
            distances,
            np.minimum(support * rho_delta, distances[:, -1]),
            min(max(round(MIN_CELLS * (support / PILOT_SUPPORT) ** 2), MIN_CELLS // 2), k),
        )
        for support in supports
    ]
    return _jets(fits[0], "pilot fits"), fits, pilot_of


def _supports(pilots, fit, small, sigma, rho_delta, extent):
    """Support (P,) of a jet at each pilot by the bias-variance rule, and a note.

    `fit` and `small` are the pilots' fits (`fit_rows`) at their support and at
    DETAIL_SUPPORT of it."""
    # The planes' noise holds what curvature their neighbourhoods had; the pilots' residuals
    # do not, and on a detailed object they are the smaller, truer measure. Taken over the
    # 8 nearest pilots, so that it stays local (and tiles see the same).
    tree = build_tree(pilots.centres)
    residual = _nearest_median(tree, _noise_variance(fit), pilots.centres)
    sigma = np.minimum(sigma, np.sqrt(residual))
    density = fit[4] / (np.pi * pilots.radii**2)
    kappa = np.maximum(pilots.curvature, 1.0 / extent)
    # In units of rho_delta, so that scaling the cloud by a power of two scales h exactly.
    ratio = (sigma / rho_delta) ** 2 / (
        JET_BIAS**2 * (kappa * rho_delta) ** 6 * np.pi * density * rho_delta**2
    )
    h = (JET_VARIANCE * ratio) ** 0.1
    # Detail a quadric cannot follow. Corrected for the freedom the fits absorb, the noise
    # leaves the same residual at every support, and detail one that grows as h^4 (as
    # measured on real scans), so two supports separate them: the detail e at the pilots'
    # support is the growth of the residual over 1 - (small / support)^4. It counts where it
    # exceeds DETAIL_MARGIN times the noise variance. A jet of support x h_p then errs by
    # e x^4 in square and varies by V sigma^2 / (n_p x^2): the sum is least at
    # x^6 = V sigma^2 / (2 e n_p).
    growth = 1.0 - (small[3] / fit[3]) ** 4
    detail = _nearest_median(
        tree, (_noise_variance(fit) - _noise_variance(small)) / growth, pilots.centres
    )
    excess = detail - DETAIL_MARGIN * sigma**2
    detailed = excess > 0.0
    best = pilots.radii[detailed] * (
        JET_VARIANCE * sigma[detailed] ** 2 / (2.0 * excess[detailed] * fit[4][detailed])
    ) ** (1.0 / 6.0)
    shrunk = int(np.count_nonzero(best / rho_delta < h[detailed]))
    h[detailed] = np.minimum(h[detailed], best / rho_delta)
    h = rho_delta * np.clip(h, MIN_SUPPORT, MAX_SUPPORT)
    note = (
        f"support = {np.median(h):.6g} (median; 10-90 %: {np.quantile(h, 0.1):.4g}-"
        f"{np.quantile(h, 0.9):.4g}): bias-variance rule h^10 = {JET_VARIANCE:g} sigma^2 / "
        f"({JET_BIAS:g}^2 kappa^6 pi D) on {h.size} pilot fits, median curvature "
        f"{np.median(kappa):.4g}, density {np.median(density):.4g} points per unit area, "
        f"noise {np.median(sigma):.4g} (median), within [{MIN_SUPPORT:g}, {MAX_SUPPORT:g}] "
        f"rho_delta; {shrunk} pilots shrunk to follow detail above {DETAIL_MARGIN:g} x the "
        "noise variance"
    )
    return h, note
