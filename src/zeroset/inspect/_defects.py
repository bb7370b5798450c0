"""Defects: connected regions of the unrolled wall that leave the pipe's section."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage, optimize, special

from .._unique import distinct
from ._bump import FIT_EVALUATIONS, at_most, bump, covariance, fit_along_beams, raised_cosine
from ._centreline import Pipe
from ._measure import Ovality
from ._unrolled import WallMap

__all__ = ["Branch", "Defect", "Defects", "dispersion", "find_defects", "smallest_depth"]

#: Scan points: a cell is judged when its residual exceeds so many standard errors that
#: noise alone would make this many regions beyond them over the whole wall, on average.
FALSE_ALARMS = 0.05
#: A mesh alone, whose errors are its neighbours' errors too (a ripple beside a dent): a
#: cell is judged when its residual exceeds this many robust deviations of the whole wall.
MESH_SIGNIFICANCE = 6.0
#: A dent deeper than this share of the nominal diameter, in percent, is one that ASME
#: B31.8 (851.4.1) has assessed: a plain dent deeper than 6 % of the diameter.
ASSESSED_DENT = 6.0
#: Cells where at least this share of the samples lies outside the wall are a branch.
BRANCH = 0.5
#: Defects within this share of the radius of a branch's opening are part of the branch.
BRANCH_MARGIN = 0.25
#: Regions smaller than this many kernel areas (2 pi kernel^2) are not reported.
MIN_KERNELS = 0.5
#: Cells within this many kernels of a cell without data (an open end, an opening, a
#: shadow) are not judged: the kernel there sees one side only.
EDGE_KERNELS = 2.0
#: A bump is fitted to at most this many of the points around it (every k-th, in axial
#: order): past it the fit's cost grows and its error hardly shrinks.
MAX_BUMP_POINTS = 20_000


@dataclass(frozen=True)
class Defect:
    """A dent (inward) or bulge (outward) of the wall.

    Lengths are metres, angles degrees on the clock (0 at 12 o'clock, clockwise looking
    along the centreline).

    Attributes
    ----------
    kind : str
        ``"dent"`` (inward: a dent or a deposit) or ``"bulge"`` (outward: a bulge or wall
        loss).
    axial, clock : float
        Position of the deepest point.
    depth : float
        Signed deviation of the deepest point from the section fitted at its station (the
        pipe's local mean radius and ovality).
    uncertainty : float
        One standard deviation of `depth`.
    axial_start, axial_end : float
        Axial extent of the region beyond the threshold.
    clock_start, clock_end : float
        Its clock extent, clockwise from `clock_start` to `clock_end`.
    width : float
        Its circumferential extent, as arc length on the nominal wall.
    area : float
        Its area on the nominal wall, square metres.
    depth_percent : float
        ``|depth|`` in percent of the nominal diameter.
    assess : bool
        A dent deeper than `ASSESSED_DENT` percent of the nominal diameter: a plain dent
        that ASME B31.8 (851.4.1) would have assessed.
    """

    kind: str
    axial: float
    clock: float
    depth: float
    uncertainty: float
    axial_start: float
    axial_end: float
    clock_start: float
    clock_end: float
    width: float
    area: float
    depth_percent: float = float("nan")
    assess: bool = False


@dataclass(frozen=True)
class Branch:
    """Where a branch (a tee's, a lateral's) leaves the pipe: the axial and clock position
    (m, degrees) of the middle of its opening, and the opening's area on the nominal wall
    (m^2, with the cells where the branch's own wall is seen)."""

    axial: float
    clock: float
    area: float


@dataclass(frozen=True, eq=False)
class Defects:
    """Defects and branches found on a pipe's wall.

    Attributes
    ----------
    defects : tuple of Defect
        Deepest first.
    branches : tuple of Branch
    threshold : float
        The smallest depth reported, metres: given, or the median over the wall of the
        residual a cell needs to be significant.
    significance : float
        How many of its standard errors a cell's residual needed (see `find_defects`).
    labels : (A, C) int64
        Index into `defects` of each cell of the wall map, -1 for none.
    basis : str
        What the threshold came from, in words (with its figures in mm).
    texture : float
        How many times their standard errors the judged cells' residuals spread (robustly,
        at least 1): the wall's own texture beyond the points' noise, which every cell's
        error is taken times (see `find_defects`).
    """

    defects: tuple[Defect, ...]
    branches: tuple[Branch, ...]
    threshold: float
    significance: float
    labels: np.ndarray
    basis: str = ""
    texture: float = 1.0

    def __post_init__(self) -> None:
        self.labels.flags.writeable = False


def find_defects(
    wall: WallMap,
    pipe: Pipe,
    ovality: Ovality,
    samples: np.ndarray,
    *,
    threshold: float | None = None,
    located=None,
    beams=None,
    excluded=(),
) -> Defects:
    """Find the regions of the wall map whose residual is significant: dents and bulges.

    A cell is judged defective when its residual (the deviation from its station's fitted
    section) exceeds z standard errors (`_significance`: z grows with the wall's area so that
    noise alone makes `FALSE_ALARMS` regions over the whole wall). The errors come from the
    points' own noise about the local wall (`WallMap.noise`), never from the map's
    deviations, which hold real geometry (joints, ovality, deposits), taken times the
    wall's texture: the robust spread of the judged cells' residuals over their errors
    (`dispersion`, at least 1). A real wall is no smooth section: concrete's texture of
    half a millimetre leaves its cells spread twice their errors, and at z of those errors
    a fifth of a real sewer pipe's wall would be "defects"; a median over the wall is not
    moved by the few cells a defect takes. For a mesh's
    samples, `MESH_SIGNIFICANCE` robust deviations of the wall. Connected defective cells, all
    inward or all outward, make a region (the clock wraps round); regions smaller than
    `MIN_KERNELS` kernel areas are noise. Cells where the samples leave the wall outward
    (`BRANCH`) are a branch; with the cells without data next to them (its opening), the
    outward cells beyond the threshold joined to them (its seam) and `BRANCH_MARGIN` radii
    around, a region touching them is part of it. Cells within
    `EDGE_KERNELS` kernels of cells without data (the open ends, a branch's opening, a
    shadow) or of the stretches `excluded` are not judged.

    The depth and position of each defect come from a raised-cosine bump, plus a
    constant, fitted by least squares to the residuals of the `samples` (N, 3) around it;
    its uncertainty is that fit's standard error, and the section's own uncertainty there
    (`Ovality.section_error`). With the scanner's `beams` (`beam_steps` of
    the samples, a row of NaN where unknown) the bump is fitted along them, where the
    range noise lies (see `_BumpFit.bump`). Defects shallower than `threshold` (metres;
    default the median over the wall of the residual a cell needs to be significant) are
    not reported. `located` is ``pipe.locate(samples)`` when already computed. Cells in
    the axial stretches `excluded` ((start, end) pairs, metres: ring features, and
    stretches whose data do not go round the pipe) are not judged at all.
    """
    residual = wall.residual
    cell_axial = wall.axial_edges[1] - wall.axial_edges[0]
    cell_arc = np.radians(wall.clock_edges[1]) * pipe.radius
    judged, defined, skipped = _cells(wall, pipe, excluded)
    texture = _texture(wall, defined)
    error = np.where(judged, texture * wall.error, np.inf)
    significance, area, reported = _limit(wall, pipe, defined, texture)
    limit = significance * error
    basis = _basis(wall, defined, significance, area, reported, texture)
    if threshold is not None:
        reported = float(threshold)
        basis = (
            f"given: {1000 * reported:.2f} mm (cells still need {significance:.1f} standard errors)"
        )
    leaving = (wall.off_wall >= BRANCH) & ~skipped[:, None]
    openings = _wrapped_labels(leaving | ~np.isfinite(residual))
    branching = distinct(openings[leaving])
    branches = [_branch(wall, openings == label, cell_axial * cell_arc) for label in branching]
    # its seam: the outward cells beyond the threshold that join its opening (the branch's
    # own wall, seen within `OFF_WALL` of the pipe's, reaches a branch's radius or so)
    opening = np.isin(openings, branching)
    seam = _wrapped_labels(opening | (np.nan_to_num(residual) > reported))
    near_branch = ndimage.binary_dilation(
        np.isin(seam, distinct(seam[opening])),
        iterations=int(np.ceil(BRANCH_MARGIN * pipe.radius / cell_axial)),
    )
    located = pipe.locate(samples) if located is None else located
    fit = _BumpFit(pipe, ovality, located, beams)
    defects, members = [], []
    smallest = MIN_KERNELS * 2 * np.pi * wall.kernel**2
    for sign in (-1.0, 1.0):
        # regions over the skipped stretches too: one that reaches a branch through them
        # is its seam; of the others, only the cells outside them are judged
        labels = _wrapped_labels(judged & (sign * np.nan_to_num(residual) > limit))
        touching = distinct(labels[near_branch & (labels >= 0)])
        labels[~defined] = -1
        areas = np.bincount(labels[labels >= 0], minlength=labels.max() + 1) * cell_axial * cell_arc
        for label in np.setdiff1d(np.flatnonzero(areas >= smallest), touching):
            cells, area = labels == label, areas[label]
            found = _defect(sign, wall, cells, area, pipe, fit)
            if abs(found.depth) >= reported:
                defects.append(found)
                members.append(cells)
    order = np.argsort([-abs(d.depth) for d in defects], kind="stable")
    labels = np.full(residual.shape, -1, dtype=np.int64)
    for rank, index in enumerate(order):
        labels[members[index]] = rank
    return Defects(
        tuple(defects[i] for i in order),
        tuple(branches),
        reported,
        significance,
        labels,
        basis,
        texture,
    )


def smallest_depth(wall: WallMap, pipe: Pipe) -> float:
    """The threshold (m) `find_defects` reports on `wall` with nothing excluded: the
    smallest change of the wall the inspection tells from the noise there."""
    defined = _cells(wall, pipe, ())[1]
    return _limit(wall, pipe, defined, _texture(wall, defined))[2]


def dispersion(standardized: np.ndarray) -> float:
    """The robust spread of `standardized` values (residuals over their standard errors),
    at least 1: how much the errors understate what the values really scatter by (a real
    wall's texture, the centreline's and the sections' own errors, the scan's pattern).
    Features are sparse (a defect takes a few cells, a joint a ring every metre or more),
    so this median ignores them."""
    finite = np.abs(standardized[np.isfinite(standardized)])
    return max(1.4826 * float(np.median(finite)), 1.0) if finite.size else 1.0


def _texture(wall: WallMap, defined: np.ndarray) -> float:
    """The wall's texture (see `find_defects`): the `dispersion` of the `defined` cells'
    residuals over their errors, for scan points; 1 for a mesh's samples, whose limit is
    taken from the wall's spread itself (`MESH_SIGNIFICANCE`)."""
    if not (wall.independent and defined.any()):
        return 1.0
    return dispersion(wall.residual[defined] / wall.error[defined])


def _cells(wall: WallMap, pipe: Pipe, excluded) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, C) bool: the cells of `wall` that can be judged (data all round their kernel:
    `EDGE_KERNELS` from cells without data and the run's ends), and those that are (also
    that far from the axial stretches `excluded`); (A,) bool: the rows `excluded`."""
    cell_axial = wall.axial_edges[1] - wall.axial_edges[0]
    margin = int(np.ceil(EDGE_KERNELS * wall.kernel / cell_axial))
    middle = 0.5 * (wall.axial_edges[:-1] + wall.axial_edges[1:])
    beyond = (middle < 0.0) | (middle > pipe.length)  # the ends' rims are where data stop
    empty = np.pad(
        ~np.isfinite(wall.residual) | beyond[:, None], ((1, 1), (0, 0)), constant_values=True
    )
    near_edge = ndimage.binary_dilation(
        empty, structure=np.ones((3, 3)), iterations=margin, border_value=0
    )[1:-1]
    skipped = np.zeros(middle.shape, dtype=bool)
    for start, end in excluded:
        skipped |= (middle >= start) & (middle <= end)
    judged = np.isfinite(wall.residual) & ~near_edge
    # next to a stretch not judged, the kernel sees that wall too: an edge like the others
    defined = judged & ~ndimage.binary_dilation(skipped, iterations=margin)[:, None]
    return judged, defined, skipped


def _limit(
    wall: WallMap, pipe: Pipe, defined: np.ndarray, texture: float
) -> tuple[float, float, float]:
    """The standard errors a cell needs (`_significance`, or `MESH_SIGNIFICANCE` on a
    mesh), the area judged (m^2) and the threshold (m): the median over the `defined`
    cells of the residual they need, their errors taken `texture` times."""
    cell_axial = wall.axial_edges[1] - wall.axial_edges[0]
    area = np.count_nonzero(defined) * cell_axial * np.radians(wall.clock_edges[1]) * pipe.radius
    significance = MESH_SIGNIFICANCE
    if wall.independent and defined.any():
        significance = _significance(area, wall.kernel)
    reported = (
        float(np.median(significance * texture * wall.error[defined])) if defined.any() else 0.0
    )
    return significance, area, reported


def _basis(
    wall: WallMap, defined, significance: float, area: float, reported: float, texture: float
) -> str:
    """What the threshold `reported` (m) came from, in words with figures in mm."""
    if not defined.any():
        return "no cell of the wall is judged: too few samples, or all near an edge"
    noise = 1000 * float(np.median(wall.noise[defined]))
    error = 1000 * float(np.median(wall.error[defined]))
    if not wall.independent:
        return (
            f"{significance:.1f} x the mesh's roughness about the sections, {noise:.2f} mm "
            f"(no points given): {1000 * reported:.2f} mm"
        )
    textured = ""
    if texture > 1.0:
        spread = 1000 * 1.4826 * float(np.median(np.abs(wall.residual[defined])))
        textured = (
            f", times {texture:.2f}, the wall's texture (its cells' residuals spread "
            f"{texture:.2f} times their errors, {spread:.2f} mm about the sections)"
        )
    return (
        f"{significance:.1f} standard errors (so that noise alone makes {FALSE_ALARMS} false "
        f"regions over the {area:.1f} m2 judged) of a cell's mean, {error:.2f} mm: the "
        f"points' noise about the local wall, {noise:.2f} mm, over the points in a cell "
        f"(medians over the wall){textured}: {1000 * reported:.2f} mm"
    )


def _significance(area: float, kernel: float, false_alarms: float = FALSE_ALARMS) -> float:
    """The z beyond which white noise smoothed by a Gaussian `kernel` (standard deviation,
    m) makes `false_alarms` regions on average over `area` (m^2), above and below.

    The expected number of regions above z is the expected Euler characteristic of the
    excursion set of a smooth Gaussian field (Worsley et al. 1996), ``P(Z > z) + area
    lambda / (2 pi)^(3/2) z exp(-z^2 / 2)`` with ``lambda = 1 / (2 kernel^2)`` for smoothed
    white noise; a long pipe judges more cells than a short one and needs a larger z.
    """
    rate = area / (2.0 * kernel**2) / (2.0 * np.pi) ** 1.5

    def excess(z: float) -> float:
        return 2.0 * (special.ndtr(-z) + rate * z * np.exp(-0.5 * z * z)) - false_alarms

    return float(optimize.brentq(excess, 1.0, 40.0))


def _wrapped_labels(mask: np.ndarray) -> np.ndarray:
    """(A, C) labels 0, 1, ... of the 8-connected regions of `mask`, joined across the
    clock's wrap from the last column to the first; -1 outside."""
    labels, count = ndimage.label(mask, structure=np.ones((3, 3)))
    parent = np.arange(count + 1)

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    last, first = labels[:, -1], labels[:, 0]
    for shift in (-1, 0, 1):
        across = np.roll(first, shift)
        if shift:
            across[0 if shift > 0 else -1] = 0
        for a, b in zip(
            last[(last > 0) & (across > 0)], across[(last > 0) & (across > 0)], strict=True
        ):
            ra, rb = root(int(a)), root(int(b))
            parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([root(i) for i in range(count + 1)])
    _, dense = np.unique(roots, return_inverse=True)
    return dense[labels] - 1


def _clock_range(wall: WallMap, cells: np.ndarray, centre: float) -> tuple[float, float]:
    """Clockwise clock extent (degrees) of `cells`, read round the clock angle `centre`."""
    cols = np.flatnonzero(cells.any(axis=0))
    middle = 0.5 * (wall.clock_edges[cols] + wall.clock_edges[cols + 1])
    turn = (middle - centre + 180.0) % 360.0 - 180.0
    half = 0.5 * (wall.clock_edges[1] - wall.clock_edges[0])
    return (centre + turn.min() - half) % 360.0, (centre + turn.max() + half) % 360.0


def _defect(sign, wall: WallMap, cells, area, pipe: Pipe, fit: _BumpFit) -> Defect:
    """A Defect from its region's cells: a bump fitted around the region's extreme cell."""
    rows, cols = np.nonzero(cells)
    extreme = np.argmax(sign * wall.residual[rows, cols])
    peak_axial = 0.5 * (wall.axial_edges[rows[extreme]] + wall.axial_edges[rows[extreme] + 1])
    peak_clock = 0.5 * (wall.clock_edges[cols[extreme]] + wall.clock_edges[cols[extreme] + 1])
    start, end = wall.axial_edges[rows.min()], wall.axial_edges[rows.max() + 1]
    clock_start, clock_end = _clock_range(wall, cells, peak_clock)
    width = np.radians((clock_end - clock_start) % 360.0) * pipe.radius
    axial, clock, depth, uncertainty = fit.bump(
        peak_axial,
        peak_clock,
        float(wall.residual[rows[extreme], cols[extreme]]),
        extent=(end - start, width),
        kernel=wall.kernel,
    )
    # the depth is measured from the section, and is no surer than it
    uncertainty = float(np.hypot(uncertainty, fit.ovality.section_error(axial, clock)))
    return Defect(
        kind="dent" if sign < 0 else "bulge",
        axial=axial,
        clock=clock,
        depth=depth,
        uncertainty=uncertainty,
        axial_start=float(start),
        axial_end=float(end),
        clock_start=float(clock_start),
        clock_end=float(clock_end),
        width=float(width),
        area=float(area),
        depth_percent=100.0 * abs(depth) / (2.0 * pipe.radius),
        assess=bool(sign < 0 and 100.0 * abs(depth) / (2.0 * pipe.radius) > ASSESSED_DENT),
    )


def _branch(wall: WallMap, cells: np.ndarray, cell_area: float) -> Branch:
    """Where a branch's cells lie: their middle in axial position and (circular) clock."""
    rows, cols = np.nonzero(cells)
    angle = np.radians(0.5 * (wall.clock_edges[cols] + wall.clock_edges[cols + 1]))
    clock = np.degrees(np.arctan2(np.sin(angle).mean(), np.cos(angle).mean())) % 360.0
    axial = 0.5 * (wall.axial_edges[rows] + wall.axial_edges[rows + 1]).mean()
    return Branch(axial=float(axial), clock=float(clock), area=float(rows.size * cell_area))


class _BumpFit:
    """Residuals of samples on the unrolled wall (located on the pipe: axial, clock and
    distance), to fit a defect's bump to; with the components of the scanner's beams
    (`beam_steps`, NaN where unknown) when known."""

    def __init__(self, pipe: Pipe, ovality: Ovality, located, steps=None) -> None:
        axial, clock, distance = located
        keep = np.isfinite(distance)
        if steps is not None:
            keep &= np.isfinite(steps).all(axis=1)
        keep = np.flatnonzero(keep)
        order = keep[np.argsort(axial[keep])]
        self.axial, self.clock = axial[order], clock[order]
        self.residual = distance[order] - ovality.section_at(self.axial, self.clock, pipe.radius)
        self.steps = None if steps is None else steps[order]
        self.pipe, self.ovality = pipe, ovality

    def bump(self, axial, clock, peak, *, extent, kernel) -> tuple[float, float, float, float]:
        """Axial, clock, depth and its standard error of a bump fitted to the residuals
        within the region's extent and three kernels of it.

        The bump is a raised cosine, ``c + d cos^2(pi sqrt(u) / 2)`` for u < 1 and c beyond,
        with ``u = (a - a0)^2 / wa^2 + (b - b0)^2 / wb^2`` (a axial, b arc length): the
        smooth, flat-bottomed, compact shape of a dent, whose bottom it meets. It is first
        fitted to the radial residuals. A scanner's range noise lies along its beams, and
        along an oblique beam it also shifts a point along the wall: that blurs the bump,
        and, as a bump bunches the beams on its near flank, biases the residuals at each
        place (errors in the variables); at grazing incidence a bulge's far flank also
        hides its near one, so the samples over it are those measured short. With the
        beams known, the bump is therefore fitted again where the noise is, along the
        beams: each sample's misfit is the distance along its beam to where the beam first
        meets the bump (`along_beams`), which is the range noise. Without
        them the depth is corrected for the blur to second order, ``d pi^2 / 4 (s_a^2 /
        wa^2 + s_b^2 / wb^2)``, taking the noise as isotropic: s_a^2 and s_b^2, the
        variances of the shifts along and round the wall, are both the variance of the
        fit's radial misfit.
        """
        reach_a = 0.5 * extent[0] + 3 * kernel
        reach_b = 0.5 * extent[1] + 3 * kernel
        lo, hi = np.searchsorted(self.axial, [axial - reach_a, axial + reach_a])
        a = self.axial[lo:hi] - axial
        b = np.radians((self.clock[lo:hi] - clock + 180.0) % 360.0 - 180.0) * self.pipe.radius
        near = np.flatnonzero(np.abs(b) <= reach_b)
        near = at_most(near, MAX_BUMP_POINTS)
        a, b, values = a[near], b[near], self.residual[lo:hi][near]
        start = np.array([0.0, peak * 2.0, 0.0, 0.0, np.log(reach_a), np.log(reach_b)])
        if values.size <= 2 * start.size:
            return float(axial), float(clock), float(peak), float("nan")

        def misfit(q):
            return values - bump(q)(a, b)

        scale = 3 * np.std(values)
        found = optimize.least_squares(
            misfit, start, loss="soft_l1", f_scale=scale, max_nfev=FIT_EVALUATIONS
        )
        blurred = self.steps is None
        if found.success and not blurred:
            found = fit_along_beams(bump, found.x, a, b, values, self.steps[lo:hi][near].T)
        q = found.x
        centred = abs(q[2]) <= reach_a and abs(q[3]) <= reach_b
        plausible = np.sign(q[1]) == np.sign(peak) and abs(q[0] + q[1]) <= 4 * abs(peak)
        if not (found.success and centred and plausible):
            return float(axial), float(clock), float(peak), float("nan")
        spread = covariance(found)
        depth = q[0] + q[1]
        if blurred:
            inside = raised_cosine(q, a, b) > 0
            blur = float(np.var(found.fun[inside])) if np.count_nonzero(inside) > 1 else 0.0
            depth += q[1] * 0.25 * np.pi**2 * blur * (np.exp(-2 * q[4]) + np.exp(-2 * q[5]))
        error = np.sqrt(max(spread[0, 0] + spread[1, 1] + 2 * spread[0, 1], 0.0))
        turn = np.degrees(q[3] / self.pipe.radius)
        return float(axial + q[2]), float((clock + turn) % 360.0), float(depth), float(error)
