"""A simulated in-pipe laser scan: a rotating 2D scanner (Hokuyo URG-04LX-like) in a pipe."""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass

import numpy as np

from .._validate import positive, require_rng
from ..errors import InputError
from . import _truth
from ._distance import query, wall_distance
from ._sample import Sample, _fraction, finish

__all__ = ["hokuyo_accuracy", "scan_pipe", "scan_pipe_size"]

#: URG-04LX: 0.36 degree steps over 240 degrees, ranges 0.02-5.6 m.
HOKUYO_STEP = 0.36
HOKUYO_FIELD = 240.0
HOKUYO_RANGE = (0.02, 5.6)


def hokuyo_accuracy(r: np.ndarray) -> np.ndarray:
    """Stated range accuracy a(r) of the URG-04LX: 10 mm up to 1 m, 1 % of the range beyond."""
    return np.where(np.asarray(r) <= 1.0, 0.01, 0.01 * np.asarray(r))


@dataclass(frozen=True)
class _Geometry:
    """A validated scan set-up: pipe, scanner pose and scanner model (angles in degrees)."""

    radius: float
    length: float
    offset: float
    z0: float
    rotation_step: float
    angular_step: float
    field_of_view: float
    range_limits: tuple[float, float]


def _geometry(radius, length, offset, z0, rotation_step, angular_step, field_of_view, limits):
    """Validate the scan set-up, resolving z0 = None to the pipe's middle."""
    radius, length = positive(radius, "radius"), positive(length, "length")
    rotation_step = positive(rotation_step, "rotation_step")
    angular_step = positive(angular_step, "angular_step")
    field_of_view = positive(field_of_view, "field_of_view")
    if rotation_step > 360.0 or field_of_view > 360.0:
        raise InputError(
            "rotation_step and field_of_view are degrees in (0, 360]; got "
            f"rotation_step={rotation_step!r}, field_of_view={field_of_view!r}"
        )
    if not (isinstance(offset, numbers.Real) and 0.0 <= offset < radius):
        raise InputError(f"offset must be in [0, radius={radius!r}); got {offset!r}")
    z0 = 0.5 * length if z0 is None else z0
    if not (isinstance(z0, numbers.Real) and 0.0 <= z0 <= length):
        raise InputError(f"z0 must be in [0, length={length!r}]; got {z0!r}")
    lo, hi = (float(v) for v in limits)
    if not (0.0 <= lo < hi and math.isfinite(hi)):
        raise InputError(f"range_limits must be (min, max) with 0 <= min < max; got {limits!r}")
    return _Geometry(
        radius,
        length,
        float(offset),
        float(z0),
        rotation_step,
        angular_step,
        field_of_view,
        (lo, hi),
    )


def _beams(g: _Geometry) -> tuple[np.ndarray, np.ndarray]:
    """Return the beam angles (K,) in radians that return a range, and the ranges (K,).

    The scan plane contains the pipe axis. A beam at angle beta leaves the scanner (at
    ``offset`` from the axis) along ``cos(beta) e_r + sin(beta) e_z``; it meets the wall
    where the radial coordinate ``offset + t cos(beta)`` reaches +radius (cos > 0) or
    -radius (cos < 0), and returns if that point is within the pipe's length and the range
    t within the limits. Every scan line has the same profile.
    """
    beta = _beam_angles(g)
    cos_b, sin_b = np.cos(beta), np.sin(beta)
    side = np.where(cos_b >= 0.0, 1.0, -1.0)
    with np.errstate(divide="ignore"):
        t = (g.radius - side * g.offset) / np.abs(cos_b)
    z = g.z0 + t * sin_b
    lo, hi = g.range_limits
    hit = np.isfinite(t) & (t >= lo) & (t <= hi) & (z >= 0.0) & (z <= g.length)
    return beta[hit], t[hit]


def _beam_angles(g: _Geometry) -> np.ndarray:
    """Return the angles (K,) in radians of every beam of a scan line, returning or not."""
    half = math.floor(0.5 * g.field_of_view / g.angular_step + 1e-9)
    return np.radians(g.angular_step * np.arange(-half, half + 1))


def _rotations(rotation_step: float) -> int:
    """Return the number of scan lines in a full turn."""
    return max(1, math.floor(360.0 / rotation_step + 1e-9))


def _line_angles(g: _Geometry) -> np.ndarray:
    """Return the rotation psi (P,) in radians of every scan line."""
    return np.radians(g.rotation_step * np.arange(_rotations(g.rotation_step)))


def _noise_scale(value) -> float:
    """Return the range-noise scale: a finite number >= 0."""
    if not (isinstance(value, numbers.Real) and 0.0 <= value < math.inf):
        raise InputError(f"noise_scale must be a number >= 0; got {value!r}")
    return float(value)


def _measure(true_range: np.ndarray, noise_scale: float, rng: np.random.Generator) -> np.ndarray:
    """Return measured ranges: `true_range` plus the URG-04LX range noise times `noise_scale`."""
    if noise_scale == 0:
        return true_range
    sigma = 0.5 * noise_scale * hokuyo_accuracy(true_range)
    return true_range + sigma * rng.standard_normal(true_range.shape)


def _beam_points(psi, beta, ranges, offset: float, z0: float) -> np.ndarray:
    """Return the points (..., 3) at `ranges` along beams (psi, beta), all broadcast together."""
    radial = offset + ranges * np.cos(beta)  # signed coordinate along e_r(psi)
    return np.stack([radial * np.cos(psi), radial * np.sin(psi), z0 + ranges * np.sin(beta)], -1)


def _origins(psi: np.ndarray, offset: float, z0: float) -> np.ndarray:
    """Return the scanner's origin (P, 3) at each rotation psi (P,)."""
    return np.stack([offset * np.cos(psi), offset * np.sin(psi), np.full(psi.size, z0)], -1)


def scan_pipe_size(
    *,
    radius: float = 0.25,
    length: float = 2.0,
    offset: float = 0.05,
    z0: float | None = None,
    rotation_step: float = 1.0,
    angular_step: float = HOKUYO_STEP,
    field_of_view: float = HOKUYO_FIELD,
    range_limits: tuple[float, float] = HOKUYO_RANGE,
) -> int:
    """Return how many points `scan_pipe` returns with these keywords (before outliers).

    The count is ``floor(360 / rotation_step)`` scan lines times the beams per line that hit
    the wall within range; it does not depend on noise or the seed. With the defaults that is
    511 per line: 4 degrees give 45,990 points, 1 degree 183,960, 0.25 degrees 735,840, and
    about 0.0368 degrees 5 million.

    Examples
    --------
    >>> scan_pipe_size(rotation_step=1.0)
    183960
    """
    g = _geometry(
        radius, length, offset, z0, rotation_step, angular_step, field_of_view, range_limits
    )
    return _rotations(g.rotation_step) * _beams(g)[0].size


def scan_pipe(
    *,
    radius: float = 0.25,
    length: float = 2.0,
    offset: float = 0.05,
    z0: float | None = None,
    rotation_step: float = 1.0,
    noise_scale: float = 1.0,
    angular_step: float = HOKUYO_STEP,
    field_of_view: float = HOKUYO_FIELD,
    range_limits: tuple[float, float] = HOKUYO_RANGE,
    outliers: float = 0.0,
    rng=None,
) -> Sample:
    """Simulate the scan a pipe robot takes with a rotating 2D laser scanner.

    The pipe is the open wall ``x^2 + y^2 = radius^2``, ``0 <= z <= length``. A scanner
    like the Hokuyo URG-04LX sits at height `z0`, `offset` from the axis, its scan plane
    containing the axis. It turns about the axis in steps of `rotation_step` degrees through
    a full turn, its origin circling the axis. At rotation psi the origin is
    ``(offset cos psi, offset sin psi, z0)`` and the beam at angle beta points along
    ``cos(beta) e_r(psi) + sin(beta) e_z``: beta = 0 is radially outward, towards the
    nearest wall, +-90 degrees along the axis, beyond that back across the axis to the far
    wall. Beams leaving through an open end, or whose range is outside `range_limits`,
    return nothing.

    Parameters
    ----------
    radius, length : float
        Pipe radius and length, in metres.
    offset : float
        Distance of the scanner's origin from the axis, in ``[0, radius)``.
    z0 : float, optional
        Height of the scanner on the axis; default ``length / 2``.
    rotation_step : float
        Degrees between scan lines, in (0, 360]; ``floor(360 / rotation_step)`` lines.
        This sets the size: see `scan_pipe_size` (1 degree gives 183,960 points with the
        defaults, 0.0368 degrees about 5 million).
    noise_scale : float
        Multiplies the range noise; 0 gives exact ranges.
    angular_step, field_of_view : float
        Degrees between beams and the scanned sector, centred on beta = 0
        (URG-04LX: 0.36 and 240, so 667 beams).
    range_limits : (float, float)
        Shortest and longest range that return, in metres (URG-04LX: 0.02 and 5.6).
    outliers : float in [0, 1)
        Share of uniform outliers among the returned points (see `add_outliers`); each
        gets the viewpoint of a random scan point.
    rng : numpy.random.Generator or int or None
        Draws the range noise (and outliers); unused when both are off.

    Returns
    -------
    Sample
        ``points`` (N, 3), ordered by scan line then by beam angle; ``viewpoints`` (N, 3),
        each point's scanner origin; ``normals`` (N, 3) away from the axis (orienting
        towards the viewpoints gives the opposite, inward sign); ``distance`` exact;
        ``truth_mesh`` the whole pipe wall (two boundary loops), seen or not.

    Raises
    ------
    InputError
        If a length is not positive, `offset` is not in ``[0, radius)``, `z0` is not in
        ``[0, length]``, an angle is not in (0, 360] or the range limits are not ordered.

    See Also
    --------
    scan_pipe_size, hokuyo_accuracy, add_outliers

    Notes
    -----
    Range noise follows the URG-04LX data sheet: accuracy a(r) = 10 mm for r <= 1 m and
    1 % of r beyond, read as two standard deviations, so the noise along the beam is
    Gaussian with sigma = noise_scale * a(r) / 2 and about 95 % of readings fall within the
    stated accuracy. Whether a beam returns is decided on its true range. The density is
    that of a real scan: along a scan line, points near the scanner are
    ``angular_step (radius - offset)`` apart (1.26 mm with the defaults) and the spacing
    grows as ``angular_step ((radius - offset) + dz^2 / (radius - offset))`` at axial
    distance dz; between scan lines it is ``radius rotation_step`` (the step in radians).

    Examples
    --------
    >>> scan = scan_pipe(rotation_step=30.0, rng=0)
    >>> scan.points.shape, scan.viewpoints.shape
    ((6132, 3), (6132, 3))
    """
    g = _geometry(
        radius, length, offset, z0, rotation_step, angular_step, field_of_view, range_limits
    )
    radius, length, offset, z0 = g.radius, g.length, g.offset, g.z0
    noise_scale = _noise_scale(noise_scale)
    outliers = _fraction(outliers, "outliers")
    rng = require_rng(rng)
    beta, true_range = _beams(g)
    psi = _line_angles(g)
    shape = (psi.size, beta.size)
    measured = _measure(np.broadcast_to(true_range, shape), noise_scale, rng)
    points = _beam_points(psi[:, None], beta, measured, offset, z0).reshape(-1, 3)
    cos_p, sin_p = np.cos(psi)[:, None], np.sin(psi)[:, None]
    side = np.where(np.cos(beta) >= 0.0, 1.0, -1.0)
    normals = np.stack([side * cos_p, side * sin_p, np.zeros(shape)], axis=-1).reshape(-1, 3)
    viewpoints = np.repeat(_origins(psi, offset, z0), beta.size, axis=0)

    def distance(x: np.ndarray) -> np.ndarray:
        x = query(x)
        return wall_distance(np.hypot(x[:, 0], x[:, 1]), x[:, 2], 0.0, length, radius)

    area = 2.0 * np.pi * radius * length

    def build(spacing: float | None):
        diagonal = math.sqrt(8.0 * radius**2 + length**2)
        h = _truth.resolve_spacing(spacing, diagonal=diagonal, area=area)
        return _truth.tube_mesh(radius, length, h)[0]

    return finish(
        points, normals, distance, area, build, outliers=outliers, rng=rng, viewpoints=viewpoints
    )
