"""The unrolled wall: deviations binned by axial position and clock angle, and smoothed."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from ._centreline import Pipe
from ._measure import Ovality

__all__ = ["WallMap", "unroll"]

#: Standard deviation of the smoothing kernel, as a share of the radius.
KERNEL = 0.04
#: Cells per kernel standard deviation.
CELLS_PER_KERNEL = 2.0
#: A sample further than this share of the radius from the nominal wall is off the wall.
OFF_WALL = 0.3
#: A sample's residual about the smoothed wall counts towards the local noise up to this
#: many robust deviations of the whole wall's (a Gaussian's variance loses 0.3 % to it).
CLIP = 4.0
#: A cell's spread is at least this share of the wall's robust standard deviation (a few
#: samples can agree by chance).
LOCAL_FLOOR = 0.5
#: Cells whose smoothed mean rests on fewer effective samples are left undefined.
MIN_SAMPLES = 5.0


@dataclass(frozen=True, eq=False)
class WallMap:
    """Deviations on the unrolled wall, on a grid of axial position by clock angle.

    Attributes
    ----------
    axial_edges : (A + 1,) float64
        Cell edges along the centreline, metres.
    clock_edges : (C + 1,) float64
        Cell edges around it, degrees from 0 to 360.
    deviation : (A, C) float64
        Smoothed deviation from the nominal pipe, metres (NaN where undefined).
    residual : (A, C) float64
        Smoothed deviation from the fitted section (its mean radius and ovality, see
        `Ovality.section_at`): what defects are judged on.
    error : (A, C) float64
        Standard error of `residual`, metres: with scan points, their noise over the root
        of their effective number, and the section's own uncertainty
        (`Ovality.section_error`).
    noise : (A, C) float64
        The samples' spread about the local surface, metres: with scan points, their
        residuals about the smoothed wall (the range noise as the radius sees it); with a
        mesh's samples, their roughness about the sections.
    off_wall : (A, C) float64
        Smoothed share of the samples more than `OFF_WALL` radii outside the wall.
    kernel : float
        Standard deviation of the smoothing kernel on the wall, metres.
    independent : bool
        Whether the samples' errors were independent (scan points), so that `error`
        shrinks with their number, or not (samples of a mesh).
    """

    axial_edges: np.ndarray
    clock_edges: np.ndarray
    deviation: np.ndarray
    residual: np.ndarray
    error: np.ndarray
    noise: np.ndarray
    off_wall: np.ndarray
    kernel: float
    independent: bool

    def __post_init__(self) -> None:
        for name in ("axial_edges", "clock_edges", "deviation", "residual", "error", "noise",
                     "off_wall"):  # fmt: skip
            getattr(self, name).flags.writeable = False

    def noise_along(self, axial) -> np.ndarray:
        """(N,) the samples' noise about the local wall (m) at axial positions `axial`
        (N,) (m): the median round the pipe of `noise`'s rows, interpolated (its scanner's
        range noise along the radius changes with the distance from the scanner)."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a row without data
            rows = np.nanmedian(self.noise, axis=1)
        middle = 0.5 * (self.axial_edges[:-1] + self.axial_edges[1:])
        known = np.isfinite(rows)
        if not known.any():
            return np.full(np.shape(axial), np.nan)
        return np.interp(axial, middle[known], rows[known])

    def cells(self, axial: np.ndarray, clock: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Row and column of the cells holding `axial` (m) and `clock` (degrees); -1 rows
        off the map."""
        rows = np.searchsorted(self.axial_edges, axial, side="right") - 1
        rows = np.where((rows >= 0) & (rows < self.axial_edges.size - 1), rows, -1)
        step = self.clock_edges[1] - self.clock_edges[0]
        cols = np.clip((np.nan_to_num(clock) / step).astype(np.int64), 0, self.clock_edges.size - 2)
        return rows, cols


def unroll(
    pipe: Pipe,
    ovality: Ovality,
    samples: np.ndarray,
    *,
    independent: bool,
    kernel=None,
    located=None,
    beams=None,
) -> WallMap:
    """Bin `samples` (N, 3) on the unrolled wall and smooth them with a Gaussian kernel.

    Each cell holds the kernel-weighted mean of the samples' deviations, and the
    standard error of that mean. When the samples are `independent` (scan points), the
    error is the points' own noise about the local surface (`_local_noise`: their
    residuals about the smoothed wall, which follows joints, ovality and dents, so real
    geometry does not count as noise) over the square root of the effective number of
    samples, and the uncertainty of the section the residual is measured from
    (`Ovality.section_error`), in quadrature; when they are not (a mesh's vertices, smooth
    by construction, whose errors are neighbours' errors too) it is the robust spread of
    all the samples' residuals.
    `kernel` is the kernel's standard deviation in metres, default `KERNEL` radii;
    `located` is ``pipe.locate(samples)`` when already computed.

    With the scanner's `beams` (`beam_steps` of the samples, NaN rows where unknown) each
    point is binned where its beam meets the smoothed wall of a first map, not where the range
    noise put it: noise along an oblique beam also moves a point along the wall, and
    where the scan's density changes (scan lines piling onto one side of a bend) points
    binned where they were measured bias the mean (errors in the variables). The
    deviations binned are the measured ones.
    """
    kernel = KERNEL * pipe.radius if kernel is None else float(kernel)
    axial, clock, distance = pipe.locate(samples) if located is None else located
    deviation = distance - pipe.radius
    keep = np.isfinite(deviation)
    axial, clock, deviation = axial[keep], clock[keep], deviation[keep]
    residual = distance[keep] - ovality.section_at(axial, clock, pipe.radius)
    wall = _map(pipe, axial, clock, deviation, residual, kernel, independent)
    if beams is None:
        return _with_section_error(wall, ovality)
    s_a, s_b, s_r = beams[keep].T
    rows, cols = wall.cells(axial, clock)
    smoothed = np.where(rows >= 0, wall.residual[rows, cols], np.nan)
    # the step along the beam to the smoothed wall, where the beam meets it squarely enough
    step = -(residual - smoothed) / s_r
    step = np.where(np.isfinite(step) & (np.abs(s_r) > 0.2), step, 0.0)
    moved_axial = axial + step * s_a
    moved_clock = (clock + np.degrees(step * s_b / pipe.radius)) % 360.0
    wall = _map(pipe, moved_axial, moved_clock, deviation, residual, kernel, independent)
    return _with_section_error(wall, ovality)


def _with_section_error(wall: WallMap, ovality: Ovality) -> WallMap:
    """`wall` with the section's own uncertainty (`Ovality.section_error`) added to each
    cell's error of scan points, in quadrature: the residual is measured from the section,
    and is no surer than it. (A mesh's error, the whole wall's spread about the sections,
    holds it already.)"""
    if not wall.independent:
        return wall
    axial = 0.5 * (wall.axial_edges[:-1] + wall.axial_edges[1:])
    clock = 0.5 * (wall.clock_edges[:-1] + wall.clock_edges[1:])
    section = ovality.section_error(axial[:, None], clock[None, :])
    return replace(wall, error=np.hypot(wall.error, section))


def _map(pipe, axial, clock, deviation, residual, kernel, independent) -> WallMap:
    """The WallMap of samples at `axial` (m) and `clock` (degrees) with their `deviation`
    and `residual` (m), smoothed with a Gaussian `kernel` (m)."""
    cell = kernel / CELLS_PER_KERNEL
    n_clock = max(8, int(np.ceil(2 * np.pi * pipe.radius / cell)))
    n_axial = max(1, int(np.ceil((pipe.axial[-1] - pipe.axial[0]) / cell)))
    axial_edges = pipe.axial[0] + cell * np.arange(n_axial + 1)
    clock_edges = np.linspace(0.0, 360.0, n_clock + 1)
    rows = np.clip(((axial - pipe.axial[0]) / cell).astype(np.int64), 0, n_axial - 1)
    cols = np.minimum((clock / 360.0 * n_clock).astype(np.int64), n_clock - 1)
    flat = rows * n_clock + cols
    on = np.abs(residual) < OFF_WALL * pipe.radius
    off = residual >= OFF_WALL * pipe.radius

    def grid(weights, mask) -> np.ndarray:
        return np.bincount(flat[mask], weights[mask], n_axial * n_clock).reshape(n_axial, n_clock)

    ones = np.ones_like(residual)
    sigma = (CELLS_PER_KERNEL, CELLS_PER_KERNEL * 2 * np.pi * pipe.radius / (cell * n_clock))

    def blur(values: np.ndarray, scale: float = 1.0) -> np.ndarray:
        return ndimage.gaussian_filter(
            values, (sigma[0] * scale, sigma[1] * scale), mode=("constant", "wrap"), truncate=3.0
        )

    count = blur(grid(ones, on))
    total = blur(grid(ones, on | off))
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_dev = blur(grid(deviation, on)) / count
        mean = blur(grid(residual, on)) / count
        squares = blur(grid(ones, on), 1.0 / np.sqrt(2.0)) / (4.0 * np.pi * sigma[0] * sigma[1])
        effective = count**2 / squares
        share = blur(grid(ones, off)) / total
    if independent:
        surface = _bilinear(
            mean, (axial - pipe.axial[0]) / cell - 0.5, clock / 360.0 * n_clock - 0.5
        )
        noise = _local_noise(residual - surface, on, grid, blur, effective)
        error = np.sqrt(noise**2 / effective)
    else:  # a mesh's samples: their roughness about the sections, all over the wall
        spread = 1.4826 * np.median(np.abs(residual[on])) if on.any() else 0.0
        noise = np.full_like(mean, spread)
        error = noise.copy()
    undefined = ~(effective >= MIN_SAMPLES)
    for value in (mean_dev, mean, error, noise):
        value[undefined] = np.nan
    share[~(total > 0)] = 0.0
    return WallMap(
        axial_edges, clock_edges, mean_dev, mean, error, noise, share, kernel, independent
    )


def _bilinear(values: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """(N,) `values` (A, C) interpolated bilinearly at fractional `rows` and `cols` (cell
    centres at whole numbers), the columns wrapping round the clock; NaN next to NaN."""
    padded = np.concatenate([values[:, -1:], values, values[:, :1]], axis=1)
    return ndimage.map_coordinates(
        padded, [rows, cols + 1.0], order=1, mode="nearest", cval=np.nan, prefilter=False
    )


def _local_noise(about, on, grid, blur, effective) -> np.ndarray:
    """(A, C) standard deviation of the samples' residuals `about` the smoothed wall
    where each lies (the local surface), kernel-weighted per cell: the range noise as the
    wall's radius sees it, which real geometry (joints, ovality, dents, deposits) does not
    raise, since the smoothed wall follows it.

    Residuals beyond `CLIP` robust deviations of the whole wall (a joint's gap, narrower
    than the kernel; an outlier) are clipped there, and the spread is at least
    `LOCAL_FLOOR` of the wall's (a few samples can agree by chance). A sample weighs in
    its own cell's mean, which shrinks its residual's variance by about ``1 - 1 /
    effective``; that is undone.
    """
    usable = on & np.isfinite(about)
    if not usable.any():
        return np.full(effective.shape, np.nan)
    overall = 1.4826 * float(np.median(np.abs(about[usable])))
    squared = np.where(usable, np.minimum(about**2, (CLIP * overall) ** 2), 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        variance = blur(grid(squared, usable)) / blur(grid(np.ones_like(about), usable))
        variance /= np.clip(1.0 - 1.0 / effective, 0.5, 1.0)
    return np.sqrt(np.maximum(variance, (LOCAL_FLOOR * overall) ** 2))
